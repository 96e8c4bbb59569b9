//! Statistics of the path samples: the transform applied to each sample, the
//! accumulators filled while rendering, and the estimators derived from them (SPEC 5).

pub mod accumulators;
pub mod estimators;
pub mod transform;

pub use transform::Transform;
