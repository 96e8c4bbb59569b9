//! `conductor`: a smooth metal with per-channel complex Fresnel reflectance.
//!
//! | parameter | type | default | meaning |
//! |-----------|------|---------|---------|
//! | material | string | none | only `none` (a perfect mirror, eta = 0, k = 1); spectral presets are not built in: give `eta` and `k` |
//! | eta, k | rgb/float | 0, 1 | real and imaginary part of the IOR per channel |
//! | specular_reflectance | rgb/float | 1 | scales the reflectance |
//!
//! One-sided: light arriving at the back is absorbed.

use super::fresnel::fresnel_conductor;
use super::BsdfSample;
use crate::math::Rgb;
use glam::Vec3;

#[derive(Clone, Debug, PartialEq)]
pub struct Conductor {
    pub eta: Rgb,
    pub k: Rgb,
    pub specular_reflectance: Rgb,
}

impl Conductor {
    #[inline]
    pub fn sample(&self, wo: Vec3) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        Some(BsdfSample {
            wi: Vec3::new(-wo.x, -wo.y, wo.z),
            weight: fresnel_conductor(wo.z, self.eta, self.k) * self.specular_reflectance,
            pdf: 1.0,
            delta: true,
            eta: 1.0,
        })
    }
}
