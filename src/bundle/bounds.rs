//! The bounds of a manifest's numbers (docs/bundle.md, "Bounds") and the checks that
//! name a value breaking them: shared by the manifest's reader (`read.rs`) and the
//! capture record (`capture.rs`), so that neither imports the other.

use super::npy::show;
use super::Problem;

/// The largest magnitude of a length, coordinate or OPL in a manifest, in scene units
/// (docs/bundle.md, "Bounds"): far beyond any scene (f32 geometry is meaningless long
/// before), small enough that squares and sums of a few stay finite in f32 (1e30)
/// and f64, so no reader turns a valid manifest into infinities or NaN.
pub const MAX_MAGNITUDE: f64 = 1e15;

/// How far from 1 the length of a unit vector of the capture record may be (it is an
/// f32 normal written as f64).
pub const UNIT_TOLERANCE: f64 = 1e-3;

/// `v` as a manifest shows it (NaN and infinities by name, as JSON cannot hold them).
pub fn show_f64(v: f64) -> String {
    if v.is_finite() {
        format!("{v:e}")
    } else {
        show(v)
    }
}

/// A [`Problem::Value`].
pub fn bad_value(at: impl Into<String>, v: f64, rule: impl Into<String>) -> Problem {
    Problem::Value {
        at: at.into(),
        value: show_f64(v),
        rule: rule.into(),
    }
}

/// A length or coordinate: finite, of magnitude below [`MAX_MAGNITUDE`].
pub fn check_magnitude(at: &str, v: f64) -> Result<(), Problem> {
    if v.is_finite() && v.abs() < MAX_MAGNITUDE {
        Ok(())
    } else {
        Err(bad_value(
            at,
            v,
            format!("must be finite and of magnitude below {MAX_MAGNITUDE:e} scene units"),
        ))
    }
}

/// A point or vector: each component as [`check_magnitude`].
pub fn check_point(at: &str, p: [f64; 3]) -> Result<(), Problem> {
    p.iter()
        .enumerate()
        .try_for_each(|(i, &v)| check_magnitude(&format!("{at}[{i}]"), v))
}
