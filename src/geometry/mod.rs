//! Geometry: shapes in world space, ray-primitive intersection, and the BVH.

pub mod accel;
mod bvh_simd;
pub mod curve;
pub mod cylinder;
pub mod disk;
pub mod error;
pub mod flat;
mod flat_simd;
pub mod mesh_attributes;
pub mod sdfgrid;
pub mod shadow;
pub mod shape;
pub mod sphere;
pub mod triangle;

pub use error::GeometryError;
