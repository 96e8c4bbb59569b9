//! Small math shared by every stage: random streams, frames, sampling warps.

pub mod frame;
pub mod rng;
pub mod sampling;

/// RGB radiance or throughput (linear, scene-referred).
pub type Rgb = glam::Vec3;
