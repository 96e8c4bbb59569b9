//! The sampling harness every BSDF and emitter goes through (after pbrt-v4's `Chi2Test`
//! and Mitsuba 3's chi2 tests; written from their descriptions):
//!
//! - chi-square of sampled directions against the pdf integrated over a theta x phi
//!   grid on the sphere (adaptive Simpson per cell, cells with a small expected count
//!   pooled, fixed seeds), for the non-delta lobes;
//! - for delta lobes: every direction equals the analytic reflection or refraction,
//!   and the reflect/refract choice frequency matches the Fresnel reflectance
//!   (two-sided binomial test), Fresnel and Snell computed here in f64, independently;
//! - sample weight == eval / pdf and sample pdf == pdf (eval includes |cos|);
//! - the pdf integrates to 1 over the sphere;
//! - white furnace: the mean energy weight equals `albedo(wo)`, is <= 1, and is 1 for
//!   lossless models;
//! - reciprocity of f = eval / |cos wi| for reflection, and for refraction up to the
//!   IORs squared (f(wo, wi) / n(wo)^2 = f(wi, wo) / n(wi)^2);
//! - rough models: the mean sample energy equals quadrature of `eval` (rough glass over
//!   the whole sphere, transmission times eta^2), which never exceeds 1;
//! - emitters: the solid-angle pdf of a light sample equals the pdf the integrator's
//!   MIS computes when it hits the same point (or, for the environment, when a ray
//!   leaves the scene in the same direction), area samples are uniform by area, and
//!   environment samples (envmap, constant) follow their pdf by the same chi-square as
//!   the BSDFs.
//!
//! All statistical tests of this test binary (every module of `tests/sampling/`) form
//! one family: each is held to `ALPHA / FAMILY` (Bonferroni), so the whole binary fails
//! by chance with probability below `ALPHA`. Broken models defined in `broken.rs` must
//! be rejected, so the harness is not vacuous.
//!
//! Layout (one test target, `cargo test --release --test sampling`):
//! - `harness.rs`: the shared machinery: the theta x phi grid, its quadrature and
//!   chi-square, the Fresnel reference and binomial test of delta lobes, the weight,
//!   furnace and reciprocity measures, energy quadratures, basic model constructors;
//! - `all_models.rs`: the case lists and the checks every model goes through
//!   (chi-square, pdf integral, weights, white furnace, reciprocity of reflection);
//! - `smooth.rs`: delta models (dielectric, conductor, `thindielectric`, `polarizer`)
//!   and `mask`;
//! - `rough.rs`: microfacet conductors and dielectrics;
//! - `plastic.rs`: `plastic`, `roughplastic`, `pplastic`;
//! - `blend_and_perturbed.rs`: `blendbsdf`, normal and bump maps;
//! - `phase.rs`: phase functions as whole-sphere models;
//! - `principled.rs`: `principled`, `principledthin`;
//! - `broken.rs`: the broken models and the tests that must reject them;
//! - `emitters.rs`, `angular.rs`, `environment.rs`: area lights, `angulararea` lights,
//!   infinitely distant emitters.

mod all_models;
mod angular;
mod blend_and_perturbed;
mod broken;
mod emitters;
mod environment;
mod harness;
mod phase;
mod plastic;
mod principled;
mod rough;
mod smooth;

use crate::all_models::non_delta_cases;
use crate::angular::ANGULAR_CASES;
use crate::emitters::LIGHT_CASES;
use crate::smooth::{delta_cases, THIN_CASES};

/// Overall significance of the statistical tests of every module.
const ALPHA: f64 = 0.01;
/// Chi-square BSDF cases + delta cases + light cases (checked in each test).
const FAMILY: usize = 94;
/// The Bonferroni-corrected level of one test.
const LEVEL: f64 = ALPHA / FAMILY as f64;

#[test]
fn the_family_size_is_the_number_of_tests() {
    assert_eq!(
        non_delta_cases().len()
            + delta_cases().len()
            + THIN_CASES.len()
            + LIGHT_CASES
            + ANGULAR_CASES,
        FAMILY
    );
}
