//! `roughconductor`: a rough metal (Cook-Torrance microfacet reflection with per-channel
//! complex Fresnel), Mitsuba 3's parameters and defaults.
//!
//! | parameter | type | default | meaning |
//! |-----------|------|---------|---------|
//! | distribution | string | beckmann | `beckmann` or `ggx` |
//! | alpha, or alpha_u and alpha_v | float or texture | 0.1 | roughness: isotropic, or `alpha_u` along the shading frame's s axis (Mitsuba's dp/du, `Shape::dpdu`) and `alpha_v` along t |
//! | sample_visible | boolean | true | GGX samples the visible normals (see `microfacet.rs`) |
//! | material | string | none | Mitsuba's named conductors (`conductor_presets.rs`), `none` a perfect mirror (Mitsuba 3's code default; its docs say copper) |
//! | eta, k | rgb/float | 0, 1 | real and imaginary IOR per channel (instead of `material`) |
//! | specular_reflectance | rgb/float | 1 | scales the reflectance |
//!
//! f(wo, wi) = F(wi . m) D(m) G(wi, wo, m) / (4 cos(wo) cos(wi)), m = normalize(wo + wi).
//! One-sided: light arriving at the back is absorbed.

use super::fresnel::fresnel_conductor;
use super::microfacet::Microfacet;
use super::{BsdfFlags, BsdfModel, BsdfSample};
use crate::math::Rgb;
use glam::Vec3;

#[derive(Clone, Debug, PartialEq)]
pub struct RoughConductor {
    pub distribution: Microfacet,
    pub eta: Rgb,
    pub k: Rgb,
    pub specular_reflectance: Rgb,
}

impl BsdfModel for RoughConductor {
    #[inline(always)]
    fn flags(&self, _wo: Vec3) -> BsdfFlags {
        BsdfFlags::GLOSSY_REFLECTION
    }

    #[inline(always)]
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        self.eval_pdf(wo, wi).0
    }

    #[inline(always)]
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.eval_pdf(wo, wi).1
    }

    /// f * cos(wi) and the density of sampling `wi`, for a reflection pair; D and
    /// G1(wo) are shared by both.
    #[inline(always)]
    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return (Rgb::ZERO, 0.0);
        }
        let Some(m) = (wo + wi).try_normalize() else {
            return (Rgb::ZERO, 0.0);
        };
        let distr = &self.distribution;
        let d = distr.d(m);
        if d == 0.0 {
            return (Rgb::ZERO, 0.0);
        }
        let g1_wo = distr.g1(wo, m);
        let g = distr.g1(wi, m) * g1_wo;
        let f = fresnel_conductor(wi.dot(m), self.eta, self.k) * self.specular_reflectance;
        let value = f * (d * g / (4.0 * wo.z));
        let pdf = distr.pdf_with(wo, m, d, g1_wo) / (4.0 * wo.dot(m));
        (value, pdf)
    }

    #[inline(always)]
    fn sample(&self, wo: Vec3, _u1: f32, u2: [f32; 2]) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let m = self.distribution.sample(wo, u2);
        let wi = 2.0 * wo.dot(m) * m - wo;
        if wi.z <= 0.0 {
            return None;
        }
        let (value, pdf) = self.eval_pdf(wo, wi);
        if pdf.is_nan() || pdf <= 0.0 || value == Rgb::ZERO {
            return None;
        }
        Some(BsdfSample {
            wi,
            weight: value / pdf,
            pdf,
            lobe: BsdfFlags::GLOSSY_REFLECTION,
            eta: 1.0,
        })
    }

    /// The Fresnel reflectance at `wo` (times `specular_reflectance`): what the metal
    /// reflects, as for the smooth `conductor` (the energy lost to shadowing, a few
    /// per cent at these roughnesses, is not subtracted).
    fn albedo(&self, wo: Vec3) -> Rgb {
        if wo.z > 0.0 {
            fresnel_conductor(wo.z, self.eta, self.k) * self.specular_reflectance
        } else {
            Rgb::ZERO
        }
    }
}
