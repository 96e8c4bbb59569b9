//! `conductor`: a smooth metal with per-channel complex Fresnel reflectance.
//!
//! | parameter | type | default | meaning |
//! |-----------|------|---------|---------|
//! | material | string | none | Mitsuba's named conductors (`Au`, `Cu`, `Ag`, `Al`, ... in `conductor_presets.rs`, Mitsuba 3's RGB values), or `none` (a perfect mirror, eta = 0, k = 1) |
//! | eta, k | rgb/float | 0, 1 | real and imaginary part of the IOR per channel |
//! | specular_reflectance | rgb/float | 1 | scales the reflectance |
//!
//! One-sided: light arriving at the back is absorbed.

use super::fresnel::fresnel_conductor;
use super::{BsdfFlags, BsdfModel, BsdfSample};
use crate::math::Rgb;
use glam::Vec3;

#[derive(Clone, Debug, PartialEq)]
pub struct Conductor {
    pub eta: Rgb,
    pub k: Rgb,
    pub specular_reflectance: Rgb,
}

impl BsdfModel for Conductor {
    #[inline(always)]
    fn flags(&self, _wo: Vec3) -> BsdfFlags {
        BsdfFlags::DELTA_REFLECTION
    }

    #[inline(always)]
    fn eval(&self, _wo: Vec3, _wi: Vec3) -> Rgb {
        Rgb::ZERO
    }

    #[inline(always)]
    fn pdf(&self, _wo: Vec3, _wi: Vec3) -> f32 {
        0.0
    }

    #[inline(always)]
    fn sample(&self, wo: Vec3, _u1: f32, _u2: [f32; 2]) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        Some(BsdfSample {
            wi: Vec3::new(-wo.x, -wo.y, wo.z),
            weight: fresnel_conductor(wo.z, self.eta, self.k) * self.specular_reflectance,
            pdf: 1.0,
            lobe: BsdfFlags::DELTA_REFLECTION,
            eta: 1.0,
        })
    }

    /// The Fresnel reflectance at `wo` (times `specular_reflectance`), the weight every
    /// sample from `wo` carries. Not the value at normal incidence: the guide then
    /// agrees with what the surface does at this pixel (metals brighten towards grazing),
    /// and one definition (the expected sample weight) serves every model.
    fn albedo(&self, wo: Vec3) -> Rgb {
        if wo.z > 0.0 {
            fresnel_conductor(wo.z, self.eta, self.k) * self.specular_reflectance
        } else {
            Rgb::ZERO
        }
    }
}
