//! `Composed`: a mixture of two BSDFs (SPEC section 6), f = w f_1 + (1 - w) f_2, where
//! either child may delay (`Separable`). Chlorophyll is Composed(w = c_g,
//! Separable(green diffuse, constant 0), Separable(red diffuse, constant t0)).
//!
//! | parameter | type | default | meaning |
//! |-----------|------|---------|---------|
//! | weight | float in [0, 1] | 0.5 | w, the share of the first child |
//! | (nested) | two bsdfs | required | f_1, then f_2 |
//!
//! The integrator resolves a Composed vertex into one child ([`Composed::pick`], child
//! 1 with probability w): the vertex then scatters, samples lights and delays exactly
//! as that child, and the selection probability cancels the mixture weight. This keeps
//! each child's delay attached to its own light. As a [`BsdfModel`] (G-buffer albedo,
//! the sampling harness) it is the mixture itself: eval and pdf blend the children's,
//! sampling picks a child the same way and weighs non-delta directions by the
//! mixture's eval / pdf.

use super::{Bsdf, BsdfFlags, BsdfModel, BsdfSample};
use crate::math::Rgb;
use glam::Vec3;

#[derive(Clone, Debug, PartialEq)]
pub struct Composed {
    pub weight: f32,
    pub first: Box<Bsdf>,
    pub second: Box<Bsdf>,
}

impl Composed {
    /// The child chosen by `u` uniform in [0, 1): the first with probability `weight`.
    #[inline]
    pub fn pick(&self, u: f32) -> &Bsdf {
        if u < self.weight {
            &self.first
        } else {
            &self.second
        }
    }
}

impl BsdfModel for Composed {
    fn flags(&self, wo: Vec3) -> BsdfFlags {
        let mut f = BsdfFlags::EMPTY;
        if self.weight > 0.0 {
            f = f | self.first.flags(wo);
        }
        if self.weight < 1.0 {
            f = f | self.second.flags(wo);
        }
        f
    }

    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        let w = self.weight;
        let mut v = Rgb::ZERO;
        if w > 0.0 {
            v += self.first.eval(wo, wi) * w;
        }
        if w < 1.0 {
            v += self.second.eval(wo, wi) * (1.0 - w);
        }
        v
    }

    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let w = self.weight;
        let mut p = 0.0;
        if w > 0.0 {
            p += self.first.pdf(wo, wi) * w;
        }
        if w < 1.0 {
            p += self.second.pdf(wo, wi) * (1.0 - w);
        }
        p
    }

    /// Both mixtures at once, each child evaluated by its own `eval_pdf`.
    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
        let w = self.weight;
        let mut v = Rgb::ZERO;
        let mut p = 0.0;
        if w > 0.0 {
            let (e, q) = self.first.eval_pdf(wo, wi);
            v += e * w;
            p += q * w;
        }
        if w < 1.0 {
            let (e, q) = self.second.eval_pdf(wo, wi);
            v += e * (1.0 - w);
            p += q * (1.0 - w);
        }
        (v, p)
    }

    fn sample(&self, wo: Vec3, u1: f32, u2: [f32; 2]) -> Option<BsdfSample> {
        let w = self.weight;
        // Reuse u1 within the chosen interval, rescaled to [0, 1).
        let (child, u) = if u1 < w {
            (&self.first, u1 / w)
        } else {
            (&self.second, (u1 - w) / (1.0 - w))
        };
        let s = child.sample(wo, u.min(1.0 - f32::EPSILON / 2.0), u2)?;
        if s.lobe.is_delta() {
            // The choice probability cancels the mixture weight.
            return Some(s);
        }
        let (value, pdf) = self.eval_pdf(wo, s.wi);
        if pdf <= 0.0 {
            return None;
        }
        Some(BsdfSample {
            weight: value / pdf,
            pdf,
            ..s
        })
    }

    fn albedo(&self, wo: Vec3) -> Rgb {
        let w = self.weight;
        let mut a = Rgb::ZERO;
        if w > 0.0 {
            a += self.first.albedo(wo) * w;
        }
        if w < 1.0 {
            a += self.second.albedo(wo) * (1.0 - w);
        }
        a
    }
}
