//! The critical value g of the membership test (SPEC 8): a pair of voxels is a member
//! when `d^2 <= g^2 V`.
//!
//! - from `gamma` (the literature's threshold on 1 - w*): `g^2 = 1 / (2 gamma) - 1`;
//! - from `alpha` (two-sided significance): g = the (1 - alpha/2) quantile of Student's
//!   t with `2n - 2` degrees of freedom (on estimates from replicates, each pair's
//!   Welch-Satterthwaite value instead: `pair_dof.rs`). statrs's quantile is accurate to ~1e-13 up to
//!   ~1e5 degrees of freedom but degrades above and never returns at 1e8, so above
//!   [`CF_DOF`] we use the normal quantile with the Cornish-Fisher expansion
//!   (Abramowitz & Stegun 26.7.5), accurate to ~1e-14 there.

use statrs::distribution::{ContinuousCDF, Normal, StudentsT};

/// Degrees of freedom above which the Cornish-Fisher expansion replaces statrs.
pub const CF_DOF: f64 = 1e5;

/// How the critical value is chosen on the command line.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Threshold {
    Gamma(f64),
    Alpha(f64),
    /// The default: gamma chosen from the sample count by measurement, see [`auto_gamma`].
    Auto,
}

/// The default gamma for `spp` samples per pixel: 0.25 below 16 spp, 0.15 below 64,
/// 0.1 from 64 on. Measured with `tstat report sweep` on cbox and cbox_spheres (48 x 48,
/// 100 bins of 0.06 OPL, r = 5, r_t = 1, three seeds, 8192-spp references): with few
/// samples the variance estimates are too uncertain for a permissive test, and bright
/// single-path outliers (e.g. a light's edge) leak into truly dark neighbours; the
/// best gamma falls from 0.25 at 8 spp to 0.1 at 64 spp and above (docs/denoiser.md, "Choosing
/// the denoiser's defaults").
pub fn auto_gamma(spp: u64) -> f64 {
    match spp {
        0..=15 => 0.25,
        16..=63 => 0.15,
        _ => 0.1,
    }
}

/// The published test's critical value resolved for a sample count ([`Threshold::resolve`]):
/// g^2, and the two-sided level g came from, if any; on estimates from replicates the
/// filter then takes g per pair at its Welch-Satterthwaite degrees of freedom
/// (`pair_dof.rs`) instead.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Welch {
    pub g2: f64,
    pub alpha: Option<f64>,
}

impl Threshold {
    /// g^2 and the level for a bundle of `spp` samples per pixel.
    pub fn resolve(&self, spp: u64) -> Welch {
        Welch {
            g2: self.g2(spp),
            alpha: self.alpha(),
        }
    }

    pub fn validate(&self) -> Result<(), super::DenoiseError> {
        match *self {
            Threshold::Gamma(g) if !(g > 0.0 && g < 0.5) => Err(super::DenoiseError::Gamma(g)),
            Threshold::Alpha(a) if !(a > 0.0 && a < 1.0) => Err(super::DenoiseError::Alpha(a)),
            _ => Ok(()),
        }
    }

    /// The two-sided level, when g comes from one.
    pub fn alpha(&self) -> Option<f64> {
        match *self {
            Threshold::Alpha(a) => Some(a),
            _ => None,
        }
    }

    /// g^2 for a bundle of `spp` samples per pixel.
    pub fn g2(&self, spp: u64) -> f64 {
        match *self {
            Threshold::Gamma(gamma) => 1.0 / (2.0 * gamma) - 1.0,
            Threshold::Auto => 1.0 / (2.0 * auto_gamma(spp)) - 1.0,
            Threshold::Alpha(alpha) => {
                let g = student_t_quantile(1.0 - alpha / 2.0, 2.0 * spp as f64 - 2.0);
                g * g
            }
        }
    }
}

/// Quantile `p` (in (0.5, 1)) of Student's t with `dof` degrees of freedom.
pub fn student_t_quantile(p: f64, dof: f64) -> f64 {
    if dof > CF_DOF {
        cornish_fisher(p, dof)
    } else {
        StudentsT::new(0.0, 1.0, dof)
            .expect("positive degrees of freedom")
            .inverse_cdf(p)
    }
}

/// Student's t quantile from the normal quantile x (A&S 26.7.5, terms to 1/dof^4).
fn cornish_fisher(p: f64, dof: f64) -> f64 {
    let x = Normal::standard().inverse_cdf(p);
    let (x2, v) = (x * x, dof);
    let g1 = (x2 + 1.0) * x / 4.0;
    let g2 = ((5.0 * x2 + 16.0) * x2 + 3.0) * x / 96.0;
    let g3 = (((3.0 * x2 + 19.0) * x2 + 17.0) * x2 - 15.0) * x / 384.0;
    let g4 = ((((79.0 * x2 + 776.0) * x2 + 1482.0) * x2 - 1920.0) * x2 - 945.0) * x / 92160.0;
    x + g1 / v + g2 / (v * v) + g3 / (v * v * v) + g4 / (v * v * v * v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gamma_gives_the_documented_values() {
        assert!((Threshold::Gamma(0.05).g2(64) - 9.0).abs() < 1e-12);
        assert!((Threshold::Gamma(0.1).g2(64) - 4.0).abs() < 1e-12);
    }

    #[test]
    fn auto_gamma_steps_down_with_samples() {
        assert_eq!(auto_gamma(2), 0.25);
        assert_eq!(auto_gamma(15), 0.25);
        assert_eq!(auto_gamma(16), 0.15);
        assert_eq!(auto_gamma(63), 0.15);
        assert_eq!(auto_gamma(64), 0.1);
        assert_eq!(auto_gamma(u64::MAX), 0.1);
        assert!((Threshold::Auto.g2(8) - 1.0).abs() < 1e-12);
        assert!((Threshold::Auto.g2(1024) - 4.0).abs() < 1e-12);
    }

    #[test]
    fn alpha_matches_tables() {
        // SPEC 8: alpha = 0.005 at 64 spp (126 dof) gives g = 2.86.
        let g = Threshold::Alpha(0.005).g2(64).sqrt();
        assert!((g - 2.86).abs() < 0.005, "{g}");
        // t_{0.975, 10} = 2.228139 (tables).
        assert!((student_t_quantile(0.975, 10.0) - 2.228139).abs() < 1e-6);
    }

    #[test]
    fn huge_dof_is_guarded_and_continuous() {
        // Both sides of the switch agree, and the limit is the normal quantile.
        let below = StudentsT::new(0.0, 1.0, CF_DOF)
            .unwrap()
            .inverse_cdf(0.9975);
        let above = cornish_fisher(0.9975, CF_DOF);
        assert!((below - above).abs() < 1e-10, "{below} {above}");
        let z = Normal::standard().inverse_cdf(0.9975);
        for spp in [1u64 << 20, 1 << 30, 1 << 40, u64::MAX / 4] {
            let g = Threshold::Alpha(0.005).g2(spp).sqrt();
            assert!(g.is_finite() && g >= z && g - z < 1e-5, "{spp}: {g}");
        }
    }

    #[test]
    fn out_of_range_thresholds_are_refused() {
        for bad in [
            Threshold::Gamma(0.0),
            Threshold::Gamma(0.5),
            Threshold::Gamma(-1.0),
            Threshold::Alpha(0.0),
            Threshold::Alpha(1.0),
            Threshold::Gamma(f64::NAN),
        ] {
            let e = bad.validate();
            // The error names the flag and carries the value refused.
            let named = match (bad, &e) {
                (Threshold::Gamma(g), Err(crate::denoise::DenoiseError::Gamma(v))) => {
                    v.to_bits() == g.to_bits()
                }
                (Threshold::Alpha(a), Err(crate::denoise::DenoiseError::Alpha(v))) => {
                    v.to_bits() == a.to_bits()
                }
                _ => false,
            };
            assert!(named, "{bad:?}: {e:?}");
        }
        assert!(Threshold::Gamma(0.1).validate().is_ok());
    }
}
