//! `pplastic`: Mitsuba 3's `PolarizedPlastic` in its unpolarized form (what the RGB
//! variants render, `src/bsdfs/pplastic.cpp`): a rough specular reflection off a
//! dielectric interface plus a diffuse base seen through it, with no internal
//! reflections (unlike `roughplastic`).
//!
//! | parameter | type | default | meaning |
//! |-----------|------|---------|---------|
//! | diffuse_reflectance | rgb/float or texture | 0.5 | d, the base's albedo |
//! | specular_reflectance | rgb/float or texture | 1 | s, scales the specular lobe |
//! | int_ior, ext_ior | float or name | polypropylene (1.49), air | must differ |
//! | eta | float or texture | int_ior / ext_ior | the relative IOR (instead of int_ior/ext_ior) |
//! | distribution | string | beckmann | `beckmann` or `ggx` |
//! | alpha, or alpha_u and alpha_v | float or texture | 0.1 | roughness (anisotropic along dp/du, dp/dv) |
//! | sample_visible | boolean | true | GGX samples the visible normals |
//!
//! With h = normalize(wo + wi) and F the dielectric Fresnel reflectance,
//! f cos(wi) = s F(wo . h) D(h) G(wo, wi, h) / (4 cos wo)
//!           + d (1 - F(cos wo)) (1 - F(cos wi)) cos(wi) / pi,
//! for wo and wi above the surface (one-sided). Sampling picks the specular lobe with
//! probability p_s = mean(s) / (mean(d) + mean(s)) (the textures' means, Mitsuba's
//! `Texture::mean`; mean(s) = 1 without `specular_reflectance`), else the cosine
//! hemisphere; the pdf is the mixture p_s pdf_spec + (1 - p_s) cos(wi) / pi.

use super::fresnel::fresnel_dielectric;
use super::microfacet::Microfacet;
use super::{BsdfFlags, BsdfModel, BsdfSample};
use crate::math::sampling::{cosine_hemisphere, cosine_hemisphere_pdf};
use crate::math::Rgb;
use glam::Vec3;

#[derive(Clone, Debug, PartialEq)]
pub struct PPlastic {
    pub distribution: Microfacet,
    /// The relative IOR int / ext.
    pub eta: f32,
    pub diffuse_reflectance: Rgb,
    pub specular_reflectance: Rgb,
    /// p_s, from the parameters' means (fixed per material, as Mitsuba).
    pub specular_weight: f32,
}

impl BsdfModel for PPlastic {
    #[inline]
    fn flags(&self, _wo: Vec3) -> BsdfFlags {
        BsdfFlags::GLOSSY_REFLECTION | BsdfFlags::DIFFUSE_REFLECTION
    }

    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        self.eval_pdf(wo, wi).0
    }

    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.eval_pdf(wo, wi).1
    }

    /// f cos(wi) and the pdf of `sample` for `wi` (D and G1(wo) computed once).
    #[inline]
    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return (Rgb::ZERO, 0.0);
        }
        let r = |c: f32| fresnel_dielectric(c, self.eta).0;
        let diffuse = self.diffuse_reflectance
            * ((1.0 - r(wo.z)) * (1.0 - r(wi.z)) * wi.z * std::f32::consts::FRAC_1_PI);
        let p_diffuse = cosine_hemisphere_pdf(wi.z);
        let ps = self.specular_weight;
        let Some(h) = (wo + wi).try_normalize() else {
            return (diffuse, (1.0 - ps) * p_diffuse);
        };
        let distr = &self.distribution;
        let d = distr.d(h);
        // G1(wo, h): computed for the value where D > 0, reused by the density.
        let mut g1_wo = None;
        let specular = if d > 0.0 {
            let g1 = distr.g1(wo, h);
            g1_wo = Some(g1);
            let g = distr.g1(wi, h) * g1;
            self.specular_reflectance * (r(wo.dot(h)) * d * g / (4.0 * wo.z))
        } else {
            Rgb::ZERO
        };
        let p_specular = if wo.dot(h) <= 0.0 || wi.dot(h) <= 0.0 || d == 0.0 {
            0.0
        } else {
            let g1 = g1_wo.unwrap_or_else(|| distr.g1(wo, h));
            distr.pdf_with(wo, h, d, g1) / (4.0 * wo.dot(h))
        };
        (specular + diffuse, ps * p_specular + (1.0 - ps) * p_diffuse)
    }

    fn sample(&self, wo: Vec3, u1: f32, u2: [f32; 2]) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let (wi, lobe) = if u1 < self.specular_weight {
            let m = self.distribution.sample(wo, u2);
            (2.0 * wo.dot(m) * m - wo, BsdfFlags::GLOSSY_REFLECTION)
        } else {
            (cosine_hemisphere(u2), BsdfFlags::DIFFUSE_REFLECTION)
        };
        let (value, pdf) = self.eval_pdf(wo, wi);
        if pdf.is_nan() || pdf <= 0.0 || value == Rgb::ZERO {
            return None;
        }
        Some(BsdfSample {
            wi,
            weight: value / pdf,
            pdf,
            lobe,
            eta: 1.0,
        })
    }

    /// For the G-buffer: s F(cos wo) + d (1 - F(cos wo)) (the rough lobe's shadowing
    /// and the base's exit Fresnel are left out).
    fn albedo(&self, wo: Vec3) -> Rgb {
        if wo.z <= 0.0 {
            return Rgb::ZERO;
        }
        let f = fresnel_dielectric(wo.z, self.eta).0;
        self.specular_reflectance * f + self.diffuse_reflectance * (1.0 - f)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::materials::MicrofacetKind;

    /// The diffuse term alone (a black specular scale), against its closed form.
    #[test]
    fn diffuse_term_is_the_base_through_two_fresnel_transmissions() {
        let b = PPlastic {
            distribution: Microfacet {
                kind: MicrofacetKind::Ggx,
                alpha_u: 0.2,
                alpha_v: 0.2,
                sample_visible: true,
            },
            eta: 1.5,
            diffuse_reflectance: Rgb::new(0.2, 0.5, 0.8),
            specular_reflectance: Rgb::ZERO,
            specular_weight: 0.5,
        };
        let wo = Vec3::new(0.3, 0.1, 0.9).normalize();
        let wi = Vec3::new(-0.6, 0.2, 0.5).normalize();
        // Schlick is not Fresnel: compute R exactly in f64 at normal-ish angles.
        let fr = |c: f64| {
            let s2 = 1.0 - c * c;
            let ct = (1.0 - s2 / (1.5 * 1.5)).sqrt();
            let rs = ((c - 1.5 * ct) / (c + 1.5 * ct)).powi(2);
            let rp = ((1.5 * c - ct) / (1.5 * c + ct)).powi(2);
            0.5 * (rs + rp)
        };
        let k =
            (1.0 - fr(wo.z as f64)) * (1.0 - fr(wi.z as f64)) * wi.z as f64 / std::f64::consts::PI;
        let v = b.eval(wo, wi);
        for (c, d) in [(v.x, 0.2), (v.y, 0.5), (v.z, 0.8)] {
            assert!((c as f64 - d * k).abs() < 1e-6, "{c} vs {}", d * k);
        }
        assert_eq!(b.eval(-wo, wi), Rgb::ZERO);
        assert_eq!(b.eval(wo, -wi), Rgb::ZERO);
    }
}
