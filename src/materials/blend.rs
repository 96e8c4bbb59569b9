//! `blendbsdf`: Mitsuba 3's `BlendBSDF`, a plain mixture of two BSDFs,
//! f = (1 - w) f_0 + w f_1. Unlike `Composed` (SPEC section 6), the integrator does not
//! resolve it into a child: it is one BSDF whose eval and pdf blend both children's.
//!
//! | parameter | type | default | meaning |
//! |-----------|------|---------|---------|
//! | weight | float or texture | required | w, the share of the SECOND child (clipped to [0, 1], as Mitsuba) |
//! | (nested) | two bsdfs | required | f_0, then f_1 |
//!
//! Sampling, exactly Mitsuba's `sample`: with u1 <= w the second child is sampled with
//! u1 / w, else the first with (u1 - w) / (1 - w); with c the chosen child (share w_c,
//! sample weight r_c and pdf p_c) and o the other, evaluated in the sampled direction,
//! weight = (w_c r_c p_c + w_o eval_o) / (w_c p_c + w_o pdf_o), pdf the denominator.
//! For a non-delta direction that is the mixture's eval / pdf. For a delta lobe p_c is
//! the probability of having chosen it (`BsdfSample::pdf`), so where the other child
//! has a density in that direction Mitsuba adds a solid-angle density to a discrete
//! probability: the estimate is then biased (a mirror blended with a glossy lobe around
//! its reflection). We keep that, so that renders agree with Mitsuba's; blends of
//! non-delta models, of delta ones, or of a delta lobe with a model that has no density
//! there (a diffuse reflection and a transmission) are unbiased.

use super::{Bsdf, BsdfFlags, BsdfModel, BsdfSample};
use crate::math::Rgb;
use glam::Vec3;

#[derive(Clone, Debug, PartialEq)]
pub struct Blend {
    /// w in [0, 1]: the second child's share.
    pub weight: f32,
    pub first: Box<Bsdf>,
    pub second: Box<Bsdf>,
}

impl Blend {
    /// The children with their shares, skipping a child whose share is 0.
    #[inline]
    fn parts(&self) -> [(&Bsdf, f32); 2] {
        [
            (&self.first, 1.0 - self.weight),
            (&self.second, self.weight),
        ]
    }
}

impl BsdfModel for Blend {
    fn flags(&self, wo: Vec3) -> BsdfFlags {
        let mut f = BsdfFlags::EMPTY;
        for (b, w) in self.parts() {
            if w > 0.0 {
                f = f | b.flags(wo);
            }
        }
        f
    }

    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        let mut v = Rgb::ZERO;
        for (b, w) in self.parts() {
            if w > 0.0 {
                v += b.eval(wo, wi) * w;
            }
        }
        v
    }

    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let mut p = 0.0;
        for (b, w) in self.parts() {
            if w > 0.0 {
                p += b.pdf(wo, wi) * w;
            }
        }
        p
    }

    /// Both sums at once, each child evaluated by its own `eval_pdf`.
    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
        let mut v = Rgb::ZERO;
        let mut p = 0.0;
        for (b, w) in self.parts() {
            if w > 0.0 {
                let (e, q) = b.eval_pdf(wo, wi);
                v += e * w;
                p += q * w;
            }
        }
        (v, p)
    }

    fn sample(&self, wo: Vec3, u1: f32, u2: [f32; 2]) -> Option<BsdfSample> {
        let w = self.weight;
        // Mitsuba: the second child when u1 <= w (never when w = 0).
        let (child, u) = if w > 0.0 && u1 <= w {
            (&self.second, u1 / w)
        } else {
            (&self.first, (u1 - w) / (1.0 - w))
        };
        let s = child.sample(wo, u.clamp(0.0, 1.0 - f32::EPSILON / 2.0), u2)?;
        let (w_c, other, w_o) = if std::ptr::eq(child, &self.second) {
            (w, &self.first, 1.0 - w)
        } else {
            (1.0 - w, &self.second, w)
        };
        let (eval_o, pdf_o) = if w_o > 0.0 {
            other.eval_pdf(wo, s.wi)
        } else {
            (Rgb::ZERO, 0.0)
        };
        let pdf = w_c * s.pdf + w_o * pdf_o;
        if pdf.is_nan() || pdf <= 0.0 {
            return None;
        }
        Some(BsdfSample {
            weight: (s.weight * (w_c * s.pdf) + eval_o * w_o) / pdf,
            pdf,
            ..s
        })
    }

    /// The IOR crossed towards `wi`: a child's that crosses one (only rough
    /// dielectrics do; the parser refuses two with different IORs).
    fn eta(&self, wo: Vec3, wi: Vec3) -> f32 {
        let e = self.first.eta(wo, wi);
        if e != 1.0 {
            e
        } else {
            self.second.eta(wo, wi)
        }
    }

    fn albedo(&self, wo: Vec3) -> Rgb {
        let mut a = Rgb::ZERO;
        for (b, w) in self.parts() {
            if w > 0.0 {
                a += b.albedo(wo) * w;
            }
        }
        a
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::materials::{Conductor, Diffuse};

    #[test]
    fn weight_is_the_second_childs_share() {
        let b = |w| Blend {
            weight: w,
            first: Box::new(Bsdf::Diffuse(Diffuse {
                reflectance: Rgb::splat(0.2),
            })),
            second: Box::new(Bsdf::Diffuse(Diffuse {
                reflectance: Rgb::splat(0.8),
            })),
        };
        let wo = Vec3::new(0.3, 0.2, 0.9).normalize();
        let wi = Vec3::new(-0.1, 0.4, 0.8).normalize();
        let want = |r: f32| r * wi.z / std::f32::consts::PI;
        assert!((b(0.0).eval(wo, wi).x - want(0.2)).abs() < 1e-6);
        assert!((b(1.0).eval(wo, wi).x - want(0.8)).abs() < 1e-6);
        assert!((b(0.25).eval(wo, wi).x - want(0.35)).abs() < 1e-6);
        assert!((b(0.25).albedo(wo).x - 0.35).abs() < 1e-6);
        // A mirror's sample mixes in the diffuse child's eval and density at the
        // mirror direction, as Mitsuba does.
        let m = Blend {
            weight: 0.5,
            first: b(0.0).first,
            second: Box::new(Bsdf::Conductor(Conductor {
                eta: Rgb::ZERO,
                k: Rgb::ONE,
                specular_reflectance: Rgb::splat(0.6),
            })),
        };
        let s = m.sample(wo, 0.3, [0.5, 0.5]).unwrap();
        assert!(s.lobe.is_delta());
        // Mitsuba: (0.5 0.6 1 + 0.5 f_d cos) / (0.5 1 + 0.5 cos / pi) at the mirror
        // direction, f_d = 0.2 / pi.
        let c = s.wi.z;
        let pi = std::f32::consts::PI;
        let want = (0.5 * 0.6 + 0.5 * 0.2 * c / pi) / (0.5 + 0.5 * c / pi);
        assert!(
            (s.weight - Rgb::splat(want)).abs().max_element() < 1e-6,
            "{}",
            s.weight
        );
        assert!((s.pdf - (0.5 + 0.5 * c / pi)).abs() < 1e-6);
        assert!(m.sample(wo, 0.7, [0.5, 0.5]).unwrap().lobe == BsdfFlags::DIFFUSE_REFLECTION);
    }
}
