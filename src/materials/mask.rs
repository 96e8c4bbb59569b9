//! `mask`: a cut-out (leaves, fences) -- Mitsuba 3's `MaskBSDF`. With probability
//! `opacity` the surface behaves as the nested BSDF, otherwise light passes straight
//! through as through `null`.
//!
//! | parameter | type | default | meaning |
//! |-----------|------|---------|---------|
//! | opacity | float or texture | 0.5 | in [0, 1] (clamped, as Mitsuba clips it) |
//! | (nested) | bsdf | required | the material where the surface is opaque |
//!
//! eval = opacity * nested eval, pdf = opacity * nested pdf. Sampling picks the nested
//! BSDF with probability `opacity` (its sample weight unchanged, its pdf times
//! `opacity`), otherwise the straight-through lobe (`wi = -wo`, weight 1: the
//! probability 1 - opacity cancels the transmitted fraction 1 - opacity). As for `null`
//! in Mitsuba's `path` integrator, the crossing is a vertex of the path and shadow rays
//! are blocked by the surface.

use super::{Bsdf, BsdfFlags, BsdfModel, BsdfSample};
use crate::math::Rgb;
use glam::Vec3;

#[derive(Clone, Debug, PartialEq)]
pub struct Mask {
    pub opacity: f32,
    pub nested: Box<Bsdf>,
}

impl Mask {
    /// Below half opacity the G-buffer looks through the surface (as it does through
    /// glass): a binary cut-out's holes show what lies behind them.
    #[inline(always)]
    pub fn mostly_transparent(&self) -> bool {
        self.opacity < 0.5
    }
}

impl BsdfModel for Mask {
    #[inline(never)]
    fn flags(&self, wo: Vec3) -> BsdfFlags {
        let nested = if self.opacity > 0.0 {
            self.nested.flags(wo)
        } else {
            BsdfFlags::EMPTY
        };
        if self.opacity < 1.0 {
            nested | BsdfFlags::DELTA_TRANSMISSION
        } else {
            nested
        }
    }

    #[inline(never)]
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        if self.opacity <= 0.0 {
            return Rgb::ZERO;
        }
        self.nested.eval(wo, wi) * self.opacity
    }

    #[inline(never)]
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if self.opacity <= 0.0 {
            return 0.0;
        }
        self.nested.pdf(wo, wi) * self.opacity
    }

    #[inline(never)]
    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
        if self.opacity <= 0.0 {
            return (Rgb::ZERO, 0.0);
        }
        let (e, p) = self.nested.eval_pdf(wo, wi);
        (e * self.opacity, p * self.opacity)
    }

    #[inline(never)]
    fn sample(&self, wo: Vec3, u1: f32, u2: [f32; 2]) -> Option<BsdfSample> {
        if u1 < self.opacity {
            // Reuse u1 within [0, opacity): still uniform in [0, 1) after rescaling.
            let u = (u1 / self.opacity).min(1.0 - f32::EPSILON / 2.0);
            let s = self.nested.sample(wo, u, u2)?;
            return Some(BsdfSample {
                pdf: s.pdf * self.opacity,
                ..s
            });
        }
        Some(BsdfSample {
            wi: -wo,
            weight: Rgb::ONE,
            pdf: 1.0 - self.opacity,
            lobe: BsdfFlags::DELTA_TRANSMISSION,
            eta: 1.0,
        })
    }

    /// opacity * nested albedo + (1 - opacity): what passes through is not lost.
    fn albedo(&self, wo: Vec3) -> Rgb {
        let passed = Rgb::splat(1.0 - self.opacity);
        if self.opacity <= 0.0 {
            return passed;
        }
        self.nested.albedo(wo) * self.opacity + passed
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::materials::Diffuse;

    fn mask(opacity: f32) -> Mask {
        Mask {
            opacity,
            nested: Box::new(Bsdf::Diffuse(Diffuse {
                reflectance: Rgb::splat(0.6),
            })),
        }
    }

    #[test]
    fn opacity_splits_between_the_nested_bsdf_and_straight_through() {
        let wo = Vec3::new(0.3, 0.1, 0.9).normalize();
        let m = mask(0.25);
        let through = m.sample(wo, 0.25, [0.3, 0.7]).unwrap();
        assert_eq!((through.wi, through.weight), (-wo, Rgb::ONE));
        assert!(through.lobe.is_delta());
        let nested = m.sample(wo, 0.2, [0.3, 0.7]).unwrap();
        assert!(nested.wi.z > 0.0);
        // Same weight as the diffuse alone; pdf scaled by the opacity.
        assert!((nested.weight - Rgb::splat(0.6)).abs().max_element() < 1e-6);
        let wi = nested.wi;
        assert!((nested.pdf - 0.25 * wi.z / std::f32::consts::PI).abs() < 1e-6);
        assert!(
            (m.eval(wo, wi) - Rgb::splat(0.25 * 0.6 * wi.z / std::f32::consts::PI))
                .abs()
                .max_element()
                < 1e-6
        );
        assert!(
            (m.albedo(wo) - Rgb::splat(0.25 * 0.6 + 0.75))
                .abs()
                .max_element()
                < 1e-6
        );
        // Opaque: no straight-through lobe; transparent: nothing but it.
        assert!(!mask(1.0).flags(wo).contains(BsdfFlags::DELTA_TRANSMISSION));
        assert_eq!(mask(0.0).flags(wo), BsdfFlags::DELTA_TRANSMISSION);
        assert_eq!(mask(0.0).eval(wo, wi), Rgb::ZERO);
        assert!(mask(0.4).mostly_transparent() && !mask(0.5).mostly_transparent());
    }
}
