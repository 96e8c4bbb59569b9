//! `thindielectric`: a thin slab of dielectric (a window pane), as Mitsuba 3 models it:
//! zero thickness, light passes straight through (no refraction offset) or reflects,
//! with the slab's internal reflections summed into the reflectance.
//!
//! | parameter | type | default | meaning |
//! |-----------|------|---------|---------|
//! | int_ior | float or name | bk7 (1.5046) | IOR of the slab |
//! | ext_ior | float or name | air (1.000277) | IOR around it |
//! | specular_reflectance | rgb/float | 1 | scales reflection (not physical) |
//! | specular_transmittance | rgb/float | 1 | scales transmission (not physical) |
//!
//! With R the Fresnel reflectance of one interface at the incident angle, the slab
//! reflects R' = R + T^2 R / (1 - R^2) (T = 1 - R) and transmits 1 - R'. Both sides are
//! seen. Time: the path inside the slab has zero length, so transmission adds no
//! optical path and leaves the current IOR unchanged (`eta` = 1).

use super::fresnel::fresnel_dielectric;
use super::{BsdfFlags, BsdfModel, BsdfSample};
use crate::math::Rgb;
use glam::Vec3;

#[derive(Clone, Debug, PartialEq)]
pub struct ThinDielectric {
    /// Relative IOR int_ior / ext_ior.
    pub eta: f32,
    pub specular_reflectance: Rgb,
    pub specular_transmittance: Rgb,
}

impl ThinDielectric {
    /// The slab's reflectance R' at `cos_theta` (either side).
    #[inline(always)]
    pub fn reflectance(&self, cos_theta: f32) -> f32 {
        let r = fresnel_dielectric(cos_theta.abs(), self.eta).0;
        if r < 1.0 {
            let t = 1.0 - r;
            r + t * t * r / (1.0 - r * r)
        } else {
            r
        }
    }
}

impl BsdfModel for ThinDielectric {
    #[inline(always)]
    fn flags(&self, _wo: Vec3) -> BsdfFlags {
        BsdfFlags::DELTA_REFLECTION | BsdfFlags::DELTA_TRANSMISSION
    }

    #[inline(always)]
    fn eval(&self, _wo: Vec3, _wi: Vec3) -> Rgb {
        Rgb::ZERO
    }

    #[inline(always)]
    fn pdf(&self, _wo: Vec3, _wi: Vec3) -> f32 {
        0.0
    }

    /// `u` chooses reflection with probability R'; the weight is then the
    /// reflectance or transmittance colour alone.
    #[inline(always)]
    fn sample(&self, wo: Vec3, u: f32, _u2: [f32; 2]) -> Option<BsdfSample> {
        let r = self.reflectance(wo.z);
        Some(if u < r {
            BsdfSample {
                wi: Vec3::new(-wo.x, -wo.y, wo.z),
                weight: self.specular_reflectance,
                pdf: r,
                lobe: BsdfFlags::DELTA_REFLECTION,
                eta: 1.0,
            }
        } else {
            BsdfSample {
                wi: -wo,
                weight: self.specular_transmittance,
                pdf: 1.0 - r,
                lobe: BsdfFlags::DELTA_TRANSMISSION,
                eta: 1.0,
            }
        })
    }

    /// R' * specular_reflectance + (1 - R') * specular_transmittance: 1 for a clear pane.
    fn albedo(&self, wo: Vec3) -> Rgb {
        let r = self.reflectance(wo.z);
        self.specular_reflectance * r + self.specular_transmittance * (1.0 - r)
    }
}
