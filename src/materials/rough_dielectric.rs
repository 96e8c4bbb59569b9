//! `roughdielectric`: a rough interface between two dielectrics (ground or etched glass),
//! the microfacet model of Walter et al. 2007 ("Microfacet Models for Refraction through
//! Rough Surfaces") with Mitsuba 3's parameters, defaults and sampling. Both sides are
//! seen (no one-sidedness), as for the smooth `dielectric`.
//!
//! | parameter | type | default | meaning |
//! |-----------|------|---------|---------|
//! | distribution | string | beckmann | `beckmann` or `ggx` |
//! | alpha, or alpha_u and alpha_v | float or texture | 0.1 | roughness: isotropic, or `alpha_u` along the shading frame's s axis (Mitsuba's dp/du, `Shape::dpdu`) and `alpha_v` along t |
//! | sample_visible | boolean | true | GGX samples the visible normals (see `microfacet.rs`) |
//! | int_ior | float or name | bk7 (1.5046) | IOR inside (the side opposite the normal) |
//! | ext_ior | float or name | air (1.000277) | IOR outside; must differ from int_ior |
//! | specular_reflectance | rgb/float | 1 | scales reflection (not physical) |
//! | specular_transmittance | rgb/float | 1 | scales transmission (not physical) |
//!
//! With `eta = eta_it`, the IOR of `wi`'s side over that of `wo`'s side, and `m` the
//! microfacet normal that turns `wo` into `wi` (turned into the upper hemisphere):
//!
//! - reflection (`wo`, `wi` on one side): `m = normalize(wo + wi)`,
//!   f = F(wo . m) D(m) G(wo, wi, m) / (4 |cos wo| |cos wi|);
//! - transmission: `m = normalize(wo + eta wi)`,
//!   f = (1 - F) D G |wo . m| |wi . m| / (|cos wo| |cos wi| (wo . m + eta wi . m)^2).
//!
//! Walter's transmission term carries `eta^2` in the numerator; the radiance transport
//! scale `eta_ti^2 = 1 / eta^2` (solid-angle compression across the interface, the
//! factor the smooth `dielectric` puts on its transmitted weight) cancels it, which is
//! the form above. Sampling (Mitsuba's): a microfacet normal from `wo` turned into the
//! upper hemisphere (`-wo` from below), reflection with probability F(wo . m), else
//! refraction about `m`; the density is the normal's times F or 1 - F times the
//! Jacobian `|dm/dwi|` (`1 / (4 |wi . m|)` for reflection, `eta^2 |wi . m| /
//! (wo . m + eta wi . m)^2` for refraction). Without visible-normal sampling the
//! roughness is widened by `1.2 - 0.2 sqrt(|cos wo|)` for sampling only (Walter et al.'s
//! trick, as Mitsuba); the weight is always eval / pdf, so this changes noise, not the
//! mean. (Mitsuba 3.9.1's weight there omits D / D_widened: its weight differs from its
//! own eval / pdf by -11 % to +12 % for GGX 0.3 seen at 60 deg; with the default
//! `sample_visible` it is exact, and the two renderers agree.) Directions whose normal lies on the wrong side of `wo` or `wi` (masked by
//! Smith's G) are never returned and have no density.

use super::fresnel::fresnel_dielectric;
use super::microfacet::Microfacet;
use super::{BsdfFlags, BsdfModel, BsdfSample};
use crate::math::Rgb;
use glam::Vec3;

#[derive(Clone, Debug, PartialEq)]
pub struct RoughDielectric {
    pub distribution: Microfacet,
    /// Relative IOR int_ior / ext_ior (never 1: there would be no interface).
    pub eta: f32,
    pub specular_reflectance: Rgb,
    pub specular_transmittance: Rgb,
}

impl RoughDielectric {
    /// The distribution `sample` draws normals from for `wo`: the model's, widened by
    /// Walter et al.'s factor when normals are not sampled by visibility (Mitsuba's
    /// `scale_alpha(1.2 - 0.2 sqrt(|cos wo|))`).
    #[inline(always)]
    fn sampling_distribution(&self, cos_wo: f32) -> Microfacet {
        let mut d = self.distribution;
        if !d.sample_visible {
            let s = 1.2 - 0.2 * cos_wo.abs().sqrt();
            d.alpha_u *= s;
            d.alpha_v *= s;
        }
        d
    }
}

impl BsdfModel for RoughDielectric {
    #[inline(always)]
    fn flags(&self, _wo: Vec3) -> BsdfFlags {
        BsdfFlags::GLOSSY_REFLECTION | BsdfFlags::GLOSSY_TRANSMISSION
    }

    #[inline(always)]
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        self.eval_pdf(wo, wi).0
    }

    #[inline(always)]
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.eval_pdf(wo, wi).1
    }

    /// f * |cos wi| and the density with which `sample` returns `wi`.
    #[inline(always)]
    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
        let (cos_o, cos_i) = (wo.z, wi.z);
        if cos_o == 0.0 || cos_i == 0.0 {
            return (Rgb::ZERO, 0.0);
        }
        let reflect = cos_o * cos_i > 0.0;
        // The IOR of wi's side over wo's side (when it is transmitted).
        let eta = if cos_o > 0.0 {
            self.eta
        } else {
            1.0 / self.eta
        };
        let Some(m) = (wo + wi * if reflect { 1.0 } else { eta }).try_normalize() else {
            return (Rgb::ZERO, 0.0);
        };
        // The microfacet normal points into the upper hemisphere, as the macro normal.
        let m = if m.z < 0.0 { -m } else { m };
        let (dot_o, dot_i) = (wo.dot(m), wi.dot(m));
        // A normal facing away from either direction is masked (Smith's G is 0 there);
        // it has no density either.
        if dot_o * cos_o <= 0.0 || dot_i * cos_i <= 0.0 {
            return (Rgb::ZERO, 0.0);
        }
        let distr = &self.distribution;
        let d = distr.d(m);
        if d == 0.0 {
            return (Rgb::ZERO, 0.0);
        }
        let g1_wo = distr.g1(wo, m);
        let g = distr.g1(wi, m) * g1_wo;
        let f = fresnel_dielectric(dot_o, self.eta).0;
        // With visible normals sampled the sampling distribution is the model's
        // (bit for bit): its D(m), and from above its G1(wo, m), are the ones computed.
        let prob_m = if !distr.sample_visible {
            let sd = self.sampling_distribution(cos_o);
            sd.pdf(if cos_o > 0.0 { wo } else { -wo }, m)
        } else if cos_o > 0.0 {
            distr.pdf_with(wo, m, d, g1_wo)
        } else {
            distr.pdf_with(-wo, m, d, distr.g1(-wo, m))
        };
        if reflect {
            let value = self.specular_reflectance * (f * d * g / (4.0 * cos_o.abs()));
            let pdf = prob_m * f / (4.0 * dot_i.abs());
            (value, pdf)
        } else {
            let denom = dot_o + eta * dot_i;
            let denom2 = denom * denom;
            let value = self.specular_transmittance
                * ((1.0 - f) * d * g * (dot_o * dot_i / (cos_o * denom2)).abs());
            let pdf = prob_m * (1.0 - f) * (eta * eta * dot_i / denom2).abs();
            (value, pdf)
        }
    }

    /// `eta_it` when `wi` lies on the other side from `wo`, else 1: `sample`'s `eta`.
    #[inline(always)]
    fn eta(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z * wi.z >= 0.0 {
            1.0
        } else if wo.z > 0.0 {
            self.eta
        } else {
            1.0 / self.eta
        }
    }

    /// `u2` picks the microfacet normal, `u1` reflection (below F(wo . m)) or refraction.
    #[inline(always)]
    fn sample(&self, wo: Vec3, u1: f32, u2: [f32; 2]) -> Option<BsdfSample> {
        let cos_o = wo.z;
        if cos_o == 0.0 {
            return None;
        }
        let m = self
            .sampling_distribution(cos_o)
            .sample(if cos_o > 0.0 { wo } else { -wo }, u2);
        let dot_o = wo.dot(m);
        // A normal facing away from wo (possible unless the visible normals are
        // sampled) is masked: G1(wo, m) = 0, a zero weight in Mitsuba. It would also
        // refract with the IORs of the wrong side.
        if dot_o * cos_o <= 0.0 {
            return None;
        }
        let (f, cos_t, eta_it, eta_ti) = fresnel_dielectric(dot_o, self.eta);
        let (wi, lobe, eta) = if u1 < f {
            (2.0 * dot_o * m - wo, BsdfFlags::GLOSSY_REFLECTION, 1.0)
        } else {
            // Snell about m; cos_t is signed to the far side of m.
            (
                m * (dot_o * eta_ti + cos_t) - wo * eta_ti,
                BsdfFlags::GLOSSY_TRANSMISSION,
                eta_it,
            )
        };
        // A reflection that left through the surface, or a refraction that came back,
        // is masked (Smith's G1(wi, m) = 0, a zero weight in Mitsuba): not returned, and
        // not part of the density either.
        let same_side = wi.z * cos_o > 0.0;
        if same_side != (lobe == BsdfFlags::GLOSSY_REFLECTION) {
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
            lobe,
            eta,
        })
    }

    /// R * specular_reflectance + (1 - R) * specular_transmittance with R the Fresnel
    /// reflectance at `wo` about the macro normal, the smooth `dielectric`'s albedo: a
    /// clear rough glass is white (1) from either side, what a user expects of a
    /// lossless material. The energy its samples carry is a little lower (what
    /// shadowing and masking block, a few per cent at moderate roughness, up to ~30 %
    /// at grazing angles and alpha 0.6) and F varies over the microfacets: this is the
    /// G-buffer's guide, not the exact expectation.
    fn albedo(&self, wo: Vec3) -> Rgb {
        let r = fresnel_dielectric(wo.z, self.eta).0;
        self.specular_reflectance * r + self.specular_transmittance * (1.0 - r)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::materials::MicrofacetKind;

    fn glass(kind: MicrofacetKind, alpha: f32, eta: f32) -> RoughDielectric {
        RoughDielectric {
            distribution: Microfacet {
                kind,
                alpha_u: alpha,
                alpha_v: alpha,
                sample_visible: true,
            },
            eta,
            specular_reflectance: Rgb::ONE,
            specular_transmittance: Rgb::ONE,
        }
    }

    #[test]
    fn samples_refract_across_and_report_the_ior_crossed() {
        let b = glass(MicrofacetKind::Ggx, 0.05, 1.5);
        let wo = Vec3::new(0.6, 0.0, 0.8);
        // u1 close to 1: refraction. Near-smooth, so close to Snell's direction.
        let s = b.sample(wo, 0.999, [0.3, 0.6]).unwrap();
        assert_eq!(s.lobe, BsdfFlags::GLOSSY_TRANSMISSION);
        assert!(s.wi.z < 0.0 && (s.wi.length() - 1.0).abs() < 1e-5);
        assert!((s.wi.x + 0.6 / 1.5).abs() < 0.1, "{}", s.wi);
        assert_eq!(s.eta, 1.5);
        // From inside the opposite IOR is crossed.
        let s = b.sample(-wo, 0.999, [0.3, 0.6]).unwrap();
        assert_eq!(s.lobe, BsdfFlags::GLOSSY_TRANSMISSION);
        assert!(s.wi.z > 0.0);
        assert_eq!(s.eta, 1.0 / 1.5);
        // u1 = 0: reflection on wo's side, no IOR change.
        let s = b.sample(wo, 0.0, [0.3, 0.6]).unwrap();
        assert_eq!(s.lobe, BsdfFlags::GLOSSY_REFLECTION);
        assert!(s.wi.z > 0.0);
        assert_eq!(s.eta, 1.0);
    }

    #[test]
    fn transmission_is_reciprocal_up_to_the_ior_squared() {
        // In radiance transport f(wo, wi) / n(wo)^2 = f(wi, wo) / n(wi)^2.
        let b = glass(MicrofacetKind::Beckmann, 0.3, 1.5);
        let wo = Vec3::new(0.3, 0.1, 0.9).normalize();
        let wi = Vec3::new(-0.25, -0.05, -0.95).normalize();
        let f = b.eval(wo, wi) / wi.z.abs();
        let g = b.eval(wi, wo) / wo.z.abs();
        assert!(f.x > 0.1, "{f}");
        assert!((f.x * 1.5 * 1.5 - g.x).abs() < 1e-4 * g.x, "{f} vs {g}");
    }
}
