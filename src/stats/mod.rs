//! Statistics of the path samples: the transform applied to each sample, the
//! accumulators filled while rendering, and the estimators derived from them (SPEC 5).

pub mod accumulators;
pub mod estimators;
pub mod transform;

pub use transform::Transform;

use transform::{ACCEPTED_FORMS, BOX_COX_MIN, MAX_LAMBDA};

/// Errors of the statistics layer: sample counts that give no variance, transform
/// parameters out of range, transform names that do not parse.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum StatsError {
    #[error("spp = {0} is too small: the per-voxel statistics need at least 2 samples per pixel (the unbiased variance divides by spp - 1, and the denoiser's test needs a variance); use spp >= 2")]
    TooFewSamples(u64),
    #[error("box-cox lambda must be finite, got {0}")]
    BoxCoxNotFinite(f64),
    #[error("box-cox lambda must be > 0, got {0} (use yeo-johnson:0 for a log transform)")]
    BoxCoxNotPositive(f64),
    #[error("box-cox lambda must be in [{min:e}, {max}], got {0:e} (for a log transform use yeo-johnson:0)", min = BOX_COX_MIN, max = MAX_LAMBDA)]
    BoxCoxRange(f64),
    #[error("yeo-johnson lambda must be finite, got {0}")]
    YeoJohnsonNotFinite(f64),
    #[error("yeo-johnson lambda must be in [-{max}, {max}], got {0:e}", max = MAX_LAMBDA)]
    YeoJohnsonRange(f64),
    /// A transform (`input`, as given) of kind `kind` without its lambda.
    #[error("transform {input:?}: {kind} needs a lambda, as in \"{kind}:0.5\"; {forms}", forms = ACCEPTED_FORMS)]
    NoLambda { input: String, kind: &'static str },
    #[error("transform {input:?}: lambda {lambda:?} is not a number; {forms}", forms = ACCEPTED_FORMS)]
    LambdaNotANumber { input: String, lambda: String },
    #[error("transform {0:?}: identity takes no lambda; {forms}", forms = ACCEPTED_FORMS)]
    IdentityLambda(String),
    #[error("unknown transform {0:?}; {forms}", forms = ACCEPTED_FORMS)]
    UnknownTransform(String),
    /// A transform that parses but whose lambda is out of range (`error`, one of the
    /// lambda variants above).
    #[error("transform {input:?}: {error}; {forms}", forms = ACCEPTED_FORMS)]
    BadLambda {
        input: String,
        error: Box<StatsError>,
    },
}
