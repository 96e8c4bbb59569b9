//! Phase functions, in Mitsuba 3's convention: `wi` points back along the incoming ray
//! (`wi = -d`), `wo` is the scattered direction, both away from the scattering point;
//! the value equals the pdf (weight 1), in 1/sr.
//!
//! `isotropic`: no parameters, `1 / (4 pi)`.
//!
//! `hg` (Henyey-Greenstein):
//! | parameter | type | default | meaning |
//! |-----------|------|---------|---------|
//! | g | float | 0.8 | mean cosine of the scattering angle, in (-1, 1); g > 0 forward |
//!
//! `p(wi, wo) = (1 - g^2) / (4 pi (1 + g^2 + 2 g cos)^(3/2))` with `cos = wi . wo`
//! (Mitsuba's `eval_hg(dot(wo, wi))`: forward scattering, `wo = -wi`, is `cos = -1`).

use crate::math::frame::Frame;
use crate::math::sampling::uniform_sphere;
use glam::Vec3;

const INV_FOUR_PI: f32 = 0.25 * std::f32::consts::FRAC_1_PI;

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Phase {
    Isotropic,
    Hg { g: f32 },
}

/// A sampled direction and its density (the phase function's value there).
#[derive(Clone, Copy, Debug)]
pub struct PhaseSample {
    pub wo: Vec3,
    pub pdf: f32,
}

impl Phase {
    #[inline]
    fn eval_hg(g: f32, cos_theta: f32) -> f32 {
        let temp = 1.0 + g * g + 2.0 * g * cos_theta;
        INV_FOUR_PI * (1.0 - g * g) / (temp * temp.sqrt())
    }

    /// The phase function's value (= pdf) for unit `wi`, `wo`.
    #[inline]
    pub fn eval(&self, wi: Vec3, wo: Vec3) -> f32 {
        match *self {
            Phase::Isotropic => INV_FOUR_PI,
            Phase::Hg { g } => Self::eval_hg(g, wo.dot(wi)),
        }
    }

    /// Samples `wo` for unit `wi` (Mitsuba's inversion for `hg`, its uniform sphere for
    /// `isotropic`).
    #[inline]
    pub fn sample(&self, wi: Vec3, u: [f32; 2]) -> PhaseSample {
        match *self {
            Phase::Isotropic => PhaseSample {
                wo: uniform_sphere(u),
                pdf: INV_FOUR_PI,
            },
            Phase::Hg { g } => {
                let cos_theta = if g.abs() < f32::EPSILON {
                    1.0 - 2.0 * u[0]
                } else {
                    let sqr = (1.0 - g * g) / (1.0 - g + 2.0 * g * u[0]);
                    ((1.0 + g * g - sqr * sqr) / (2.0 * g)).clamp(-1.0, 1.0)
                };
                let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
                let (sin_phi, cos_phi) = (2.0 * std::f32::consts::PI * u[1]).sin_cos();
                let local = Vec3::new(sin_theta * cos_phi, sin_theta * sin_phi, -cos_theta);
                let wo = Frame::from_normal(wi).to_world(local).normalize();
                PhaseSample {
                    wo,
                    pdf: Self::eval_hg(g, -cos_theta),
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Midpoint quadrature over cos: 2 pi * integral p d cos = 1, and the mean cosine
    /// of the scattering angle (between the incoming direction -wi and wo) is g.
    #[test]
    fn hg_integrates_to_one_with_mean_cosine_g() {
        for g in [-0.7f32, -0.2, 0.0, 0.3, 0.8, 0.95] {
            let n = 200_000;
            let (mut total, mut mean) = (0.0f64, 0.0f64);
            for i in 0..n {
                let c = -1.0 + 2.0 * (i as f64 + 0.5) / n as f64;
                let p = Phase::eval_hg(g, -c as f32) as f64;
                let w = 2.0 * std::f64::consts::PI * p * 2.0 / n as f64;
                total += w;
                mean += w * c;
            }
            assert!((total - 1.0).abs() < 1e-4, "g {g}: {total}");
            assert!((mean - g as f64).abs() < 1e-3, "g {g}: {mean}");
        }
    }

    #[test]
    fn sampled_pdf_is_the_value() {
        let wi = Vec3::new(0.3, -0.5, 0.8).normalize();
        for phase in [
            Phase::Isotropic,
            Phase::Hg { g: 0.6 },
            Phase::Hg { g: -0.4 },
        ] {
            for k in 0..50 {
                let u = [(k as f32 + 0.3) / 50.0, (k as f32 * 0.37) % 1.0];
                let s = phase.sample(wi, u);
                assert!((s.wo.length() - 1.0).abs() < 1e-5);
                let e = phase.eval(wi, s.wo);
                assert!((s.pdf - e).abs() <= 1e-3 * e, "{phase:?}: {} vs {e}", s.pdf);
            }
        }
    }
}
