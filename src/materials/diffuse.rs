//! `diffuse`: an ideal Lambertian reflector.
//!
//! | parameter   | type           | default | meaning                  |
//! |-------------|----------------|---------|--------------------------|
//! | reflectance | rgb/spectrum/float | 0.5 | albedo in [0, 1] per channel |

use super::{BsdfFlags, BsdfModel, BsdfSample};
use crate::math::sampling::{cosine_hemisphere, cosine_hemisphere_pdf};
use crate::math::Rgb;
use glam::Vec3;
use std::f32::consts::FRAC_1_PI;

#[derive(Clone, Debug, PartialEq)]
pub struct Diffuse {
    pub reflectance: Rgb,
}

impl BsdfModel for Diffuse {
    #[inline(always)]
    fn flags(&self, _wo: Vec3) -> BsdfFlags {
        BsdfFlags::DIFFUSE_REFLECTION
    }

    #[inline(always)]
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Rgb::ZERO;
        }
        self.reflectance * (FRAC_1_PI * wi.z)
    }

    #[inline(always)]
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        cosine_hemisphere_pdf(wi.z)
    }

    /// `eval` and `pdf` behind one test of the sides.
    #[inline(always)]
    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return (Rgb::ZERO, 0.0);
        }
        (
            self.reflectance * (FRAC_1_PI * wi.z),
            cosine_hemisphere_pdf(wi.z),
        )
    }

    #[inline(always)]
    fn sample(&self, wo: Vec3, _u1: f32, u: [f32; 2]) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let wi = cosine_hemisphere(u);
        let pdf = cosine_hemisphere_pdf(wi.z);
        if pdf <= 0.0 {
            return None;
        }
        Some(BsdfSample {
            wi,
            weight: self.reflectance,
            pdf,
            lobe: BsdfFlags::DIFFUSE_REFLECTION,
            eta: 1.0,
        })
    }

    /// The reflectance: cosine-weighted sampling makes every sample's weight equal to it.
    fn albedo(&self, wo: Vec3) -> Rgb {
        if wo.z > 0.0 {
            self.reflectance
        } else {
            Rgb::ZERO
        }
    }
}
