//! `plastic`: a diffuse base under a smooth dielectric coating (Mitsuba 3's
//! `SmoothPlastic`): a delta specular reflection off the coating plus the base's
//! diffuse light, refracted in and out, with the coating's internal reflections
//! accounted for in closed form.
//!
//! | parameter | type | default | meaning |
//! |-----------|------|---------|---------|
//! | int_ior | float or name | polypropylene (1.49) | IOR of the coating |
//! | ext_ior | float or name | air (1.000277) | IOR outside |
//! | diffuse_reflectance | rgb/float | 0.5 | the base's albedo |
//! | specular_reflectance | rgb/float | 1 | scales the coating's reflection (not physical) |
//! | nonlinear | boolean | false | account for the colour shift of repeated internal reflections |
//!
//! With F(cos) the coating's Fresnel reflectance and F_dr the diffuse Fresnel
//! reflectance of its inside (`fresnel_diffuse_reflectance(1 / eta)`),
//! f_diffuse(wo, wi) = d / (1 - F_dr) / pi / eta^2 (1 - F(cos wo)) (1 - F(cos wi))
//! (`nonlinear`: 1 - d F_dr in the denominator). Sampling picks the specular lobe with
//! probability proportional to F(cos wo) times the specular weight
//! s / (mean(d) + s). One-sided.

use super::fresnel::{fresnel_dielectric, fresnel_diffuse_reflectance};
use super::{BsdfFlags, BsdfModel, BsdfSample};
use crate::math::sampling::{cosine_hemisphere, cosine_hemisphere_pdf};
use crate::math::Rgb;
use glam::Vec3;

#[derive(Clone, Debug, PartialEq)]
pub struct Plastic {
    /// int_ior / ext_ior.
    eta: f32,
    /// The inputs as given (textures set them per hit through [`Self::new`]).
    diffuse_reflectance: Rgb,
    nonlinear: bool,
    specular_reflectance: Rgb,
    /// The diffuse reflectance after the coating's internal reflections.
    base: Rgb,
    /// The hemispherical Fresnel average of light leaving the coating.
    fdr_ext: f32,
    /// s / (mean(d) + s): steers lobe selection towards the brighter lobe.
    specular_weight: f32,
}

impl Plastic {
    /// Precomputes everything that does not depend on the directions.
    pub fn new(
        eta: f32,
        diffuse_reflectance: Rgb,
        specular_reflectance: Rgb,
        nonlinear: bool,
    ) -> Self {
        let fdr_int = fresnel_diffuse_reflectance(1.0 / eta);
        let d = diffuse_reflectance;
        let base = if nonlinear {
            d / (Rgb::ONE - d * fdr_int)
        } else {
            d / (1.0 - fdr_int)
        };
        let d_mean = d.element_sum() / 3.0;
        let s_mean = specular_reflectance.element_sum() / 3.0;
        Plastic {
            eta,
            diffuse_reflectance,
            nonlinear,
            specular_reflectance,
            base,
            fdr_ext: fresnel_diffuse_reflectance(eta),
            specular_weight: s_mean / (d_mean + s_mean),
        }
    }

    /// The diffuse and specular reflectances as given (before the coating's internal
    /// reflections).
    pub fn reflectances(&self) -> (Rgb, Rgb) {
        (self.diffuse_reflectance, self.specular_reflectance)
    }

    /// The same coating over another base (a texture's value at a hit).
    pub fn with_diffuse_reflectance(&self, d: Rgb) -> Self {
        Self::new(self.eta, d, self.specular_reflectance, self.nonlinear)
    }

    /// The same plastic with another specular scale.
    pub fn with_specular_reflectance(&self, s: Rgb) -> Self {
        Self::new(self.eta, self.diffuse_reflectance, s, self.nonlinear)
    }

    /// The probability of sampling the specular lobe, given F(cos wo).
    #[inline(always)]
    fn specular_probability(&self, f_i: f32) -> f32 {
        let ps = f_i * self.specular_weight;
        let pd = (1.0 - f_i) * (1.0 - self.specular_weight);
        ps / (ps + pd)
    }
}

impl BsdfModel for Plastic {
    #[inline(always)]
    fn flags(&self, _wo: Vec3) -> BsdfFlags {
        BsdfFlags::DELTA_REFLECTION | BsdfFlags::DIFFUSE_REFLECTION
    }

    #[inline(always)]
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Rgb::ZERO;
        }
        let f_i = fresnel_dielectric(wo.z, self.eta).0;
        let f_o = fresnel_dielectric(wi.z, self.eta).0;
        self.base
            * (cosine_hemisphere_pdf(wi.z) / (self.eta * self.eta) * (1.0 - f_i) * (1.0 - f_o))
    }

    #[inline(always)]
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        let f_i = fresnel_dielectric(wo.z, self.eta).0;
        cosine_hemisphere_pdf(wi.z) * (1.0 - self.specular_probability(f_i))
    }

    /// `eval` and `pdf` with their shared test and F(cos wo) computed once.
    #[inline(always)]
    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return (Rgb::ZERO, 0.0);
        }
        let f_i = fresnel_dielectric(wo.z, self.eta).0;
        let f_o = fresnel_dielectric(wi.z, self.eta).0;
        let cos_pdf = cosine_hemisphere_pdf(wi.z);
        let value = self.base * (cos_pdf / (self.eta * self.eta) * (1.0 - f_i) * (1.0 - f_o));
        let pdf = cos_pdf * (1.0 - self.specular_probability(f_i));
        (value, pdf)
    }

    #[inline(always)]
    fn sample(&self, wo: Vec3, u1: f32, u2: [f32; 2]) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let f_i = fresnel_dielectric(wo.z, self.eta).0;
        let ps = self.specular_probability(f_i);
        if u1 < ps {
            return Some(BsdfSample {
                wi: Vec3::new(-wo.x, -wo.y, wo.z),
                weight: self.specular_reflectance * (f_i / ps),
                pdf: ps,
                lobe: BsdfFlags::DELTA_REFLECTION,
                eta: 1.0,
            });
        }
        let wi = cosine_hemisphere(u2);
        if wi.z <= 0.0 {
            return None;
        }
        let pd = 1.0 - ps;
        let f_o = fresnel_dielectric(wi.z, self.eta).0;
        Some(BsdfSample {
            wi,
            weight: self.base * ((1.0 - f_i) * (1.0 - f_o) / (self.eta * self.eta) / pd),
            pdf: pd * cosine_hemisphere_pdf(wi.z),
            lobe: BsdfFlags::DIFFUSE_REFLECTION,
            eta: 1.0,
        })
    }

    /// The expected sample weight from `wo`: F specular + (1 - F) base (1 - F_dr,ext) /
    /// eta^2, with the hemispherical Fresnel average F_dr,ext of light leaving the
    /// coating (`fresnel_diffuse_reflectance(eta)`, a fit accurate to 0.1-0.6 %).
    fn albedo(&self, wo: Vec3) -> Rgb {
        if wo.z <= 0.0 {
            return Rgb::ZERO;
        }
        let f_i = fresnel_dielectric(wo.z, self.eta).0;
        self.specular_reflectance * f_i
            + self.base * ((1.0 - f_i) * (1.0 - self.fdr_ext) / (self.eta * self.eta))
    }
}
