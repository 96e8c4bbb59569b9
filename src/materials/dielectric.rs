//! `dielectric`: a smooth interface between two dielectrics (glass, water), with exact
//! Fresnel reflection and refraction. Both sides are seen (no one-sidedness).
//!
//! | parameter | type | default | meaning |
//! |-----------|------|---------|---------|
//! | int_ior | float or name | bk7 (1.5046) | IOR inside (the side opposite the normal) |
//! | ext_ior | float or name | air (1.000277) | IOR outside |
//! | specular_reflectance | rgb/float | 1 | scales reflection (not physical) |
//! | specular_transmittance | rgb/float | 1 | scales transmission (not physical) |
//!
//! In radiance transport the transmitted weight is scaled by `eta_ti^2` (solid-angle
//! compression), and the sample reports `eta = eta_it` so the integrator can track the
//! current IOR for the optical path length and Russian roulette.

use super::fresnel::fresnel_dielectric;
use super::{BsdfFlags, BsdfModel, BsdfSample};
use crate::math::Rgb;
use glam::Vec3;

#[derive(Clone, Debug, PartialEq)]
pub struct Dielectric {
    /// Relative IOR int_ior / ext_ior.
    pub eta: f32,
    pub specular_reflectance: Rgb,
    pub specular_transmittance: Rgb,
}

impl BsdfModel for Dielectric {
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

    /// `u` chooses reflection with the Fresnel probability R; `u2` is unused.
    #[inline(always)]
    fn sample(&self, wo: Vec3, u: f32, _u2: [f32; 2]) -> Option<BsdfSample> {
        let (r, cos_theta_t, eta_it, eta_ti) = fresnel_dielectric(wo.z, self.eta);
        if u < r {
            Some(BsdfSample {
                wi: Vec3::new(-wo.x, -wo.y, wo.z),
                weight: self.specular_reflectance,
                pdf: r,
                lobe: BsdfFlags::DELTA_REFLECTION,
                eta: 1.0,
            })
        } else {
            Some(BsdfSample {
                wi: Vec3::new(-eta_ti * wo.x, -eta_ti * wo.y, cos_theta_t),
                weight: self.specular_transmittance * (eta_ti * eta_ti),
                pdf: 1.0 - r,
                lobe: BsdfFlags::DELTA_TRANSMISSION,
                eta: eta_it,
            })
        }
    }

    /// R * specular_reflectance + (1 - R) * specular_transmittance with R the Fresnel
    /// reflectance at `wo`: the energy that leaves, reflected or refracted. A clear
    /// glass is white (1) from either side and at every angle, what a user expects of
    /// a lossless material; the radiance weight `eta_ti^2` of refraction is a change of
    /// solid-angle measure, not a loss, so it is not part of the guide.
    fn albedo(&self, wo: Vec3) -> Rgb {
        let r = fresnel_dielectric(wo.z, self.eta).0;
        self.specular_reflectance * r + self.specular_transmittance * (1.0 - r)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refraction_obeys_snell_and_flips_side() {
        let d = Dielectric {
            eta: 1.5,
            specular_reflectance: Rgb::ONE,
            specular_transmittance: Rgb::ONE,
        };
        let wo = Vec3::new(0.6, 0.0, 0.8);
        // u = 0.999 > R: transmission.
        let s = d.sample(wo, 0.999, [0.5; 2]).unwrap();
        assert!(s.wi.z < 0.0);
        assert!((s.wi.length() - 1.0).abs() < 1e-5);
        // sin_t = sin_i / 1.5
        assert!((s.wi.x.abs() - 0.6 / 1.5).abs() < 1e-6);
        assert!((s.weight.x - 1.0 / 2.25).abs() < 1e-6);
        assert_eq!(s.eta, 1.5);
        // u = 0 < R: mirror reflection.
        let s = d.sample(wo, 0.0, [0.5; 2]).unwrap();
        assert_eq!(s.wi, Vec3::new(-0.6, 0.0, 0.8));
        assert_eq!(s.eta, 1.0);
    }
}
