//! `principled`: Mitsuba 3's Disney BSDF (Burley 2012, 2015), transcribed from
//! `src/bsdfs/principled.cpp` with its parameters, defaults and sampler.
//!
//! | parameter | type | default | meaning |
//! |-----------|------|---------|---------|
//! | base_color | rgb or texture | 0.5 | colour of the diffuse, metallic and transmitted light |
//! | roughness | float or texture | 0.5 | main specular roughness (alpha = roughness^2) and retro-reflection |
//! | anisotropic | float or texture | 0 | stretches alpha along the tangent (dp/du) |
//! | metallic | float or texture | 0 | blends towards a Schlick conductor of F0 = base_color |
//! | spec_trans | float or texture | 0 | share of the rough glass lobe in the dielectric part |
//! | eta | float | (from specular) | relative IOR int/ext (1 becomes 1.001 with spec_trans) |
//! | specular | float | 0.5 | eta = 2 / (1 - sqrt(0.08 specular)) - 1 (not with eta; 0 becomes 1e-3 with spec_trans) |
//! | spec_tint | float or texture | 0 | tints the dielectric reflection towards base_color's hue |
//! | sheen, sheen_tint | float or texture | 0 | grazing sheen lobe and its tint |
//! | flatness | float or texture | 0 | blends the diffuse lobe towards the fake subsurface one |
//! | clearcoat, clearcoat_gloss | float or texture | 0 | GTR1 coat lobe (alpha 0.1 to 0.001) |
//! | diffuse_reflectance_sampling_rate, main_specular_sampling_rate, clearcoat_sampling_rate | float | 1 | lobe selection weights |
//!
//! Weights: `brdf = (1 - metallic)(1 - spec_trans)` for the diffuse lobes, `bsdf =
//! (1 - metallic) spec_trans` for the transmissive one. With `m` the half vector (turned
//! up; for transmission Walter's `wo + eta_path wi`), F the dielectric Fresnel of
//! `wo . m`, D and G GGX's (visible normals sampled):
//!
//! - front side (`wo.z > 0`): specular reflection `F_p D G / (4 |cos wo|)` with F_p
//!   [`principled_fresnel`]; transmission `sqrt(base) bsdf |(1 - F) D G eta_path^2
//!   (wo.m)(wi.m) / (eta_path^2 cos wo (wo.m + eta_path wi.m)^2)|` (the radiance scale
//!   1 / eta_path^2 of Mitsuba's radiance mode included); clearcoat `clearcoat / 4
//!   F_schlick(0.04) D_gtr1 G_ggx1(0.25) |cos wi|`; diffuse-retro-flatness times `brdf`
//!   and sheen times `sheen (1 - metallic)` ([`diffuse_retro`], [`sheen`]), all times
//!   |cos wi| as `eval` returns;
//! - back side (`wo.z < 0`, inside the object): reflection with `F_p = bsdf F` and
//!   transmission; without transmission (`bsdf = 0`) the back is black.
//!
//! Sampling picks the diffuse (cosine), clearcoat (GTR1 normals), transmission or
//! specular reflection lobe with probabilities `brdf r_d`, `clearcoat r_c / 4`,
//! `r_s bsdf (1 - F)` and `r_s (1 - bsdf (1 - F))` (back side: `1 - F` and `F`), F at
//! the sampled normal; `pdf` is the same mixture at `wi`'s half vector, so the weight is
//! `eval / pdf` exactly. Directions a lobe's sample sends to the wrong side (or whose
//! normal faces away: `mac_mic_compatible`) are dropped, as Mitsuba zeroes them.
//!
//! Deviation: Mitsuba's `pdf` seen from the back of a model without transmission is the
//! specular reflection's although `sample` returns nothing there and `eval` is 0; it is
//! 0 here (no image changes: nothing is ever weighted by it). Textured parameters are
//! clamped to their documented range at the hit (`Material::at`).

use super::fresnel::fresnel_dielectric;
use super::principled_common::{
    calc_schlick, diffuse_retro, ggx, mac_mic_compatible, mulsign, principled_fresnel, sheen,
    smith_ggx1, Gtr1,
};
use super::{BsdfFlags, BsdfModel, BsdfSample};
use crate::math::sampling::cosine_hemisphere;
use crate::math::Rgb;
use glam::Vec3;
use std::f32::consts::FRAC_1_PI;

#[derive(Clone, Debug, PartialEq)]
pub struct Principled {
    pub base_color: Rgb,
    pub roughness: f32,
    pub anisotropic: f32,
    pub metallic: f32,
    pub spec_trans: f32,
    pub spec_tint: f32,
    pub sheen: f32,
    pub sheen_tint: f32,
    pub flatness: f32,
    pub clearcoat: f32,
    pub clearcoat_gloss: f32,
    /// Relative IOR int / ext (already 1.001 for 1 with transmission, as Mitsuba).
    pub eta: f32,
    /// Sampling rates of the diffuse, main specular and clearcoat lobes.
    pub diffuse_rate: f32,
    pub specular_rate: f32,
    pub clearcoat_rate: f32,
    /// `spec_trans` was given (and not as the float 0): the glossy transmission lobe
    /// exists (Mitsuba's `m_has_spec_trans`, which sets the flags).
    pub has_spec_trans: bool,
}

impl Default for Principled {
    /// Mitsuba's defaults (specular 0.5: eta 1.5).
    fn default() -> Self {
        Principled {
            base_color: Rgb::splat(0.5),
            roughness: 0.5,
            anisotropic: 0.0,
            metallic: 0.0,
            spec_trans: 0.0,
            spec_tint: 0.0,
            sheen: 0.0,
            sheen_tint: 0.0,
            flatness: 0.0,
            clearcoat: 0.0,
            clearcoat_gloss: 0.0,
            eta: specular_to_eta(0.5),
            diffuse_rate: 1.0,
            specular_rate: 1.0,
            clearcoat_rate: 1.0,
            has_spec_trans: false,
        }
    }
}

/// Mitsuba's `specular` -> eta mapping: 2 / (1 - sqrt(0.08 specular)) - 1.
pub fn specular_to_eta(specular: f32) -> f32 {
    2.0 / (1.0 - (0.08 * specular).sqrt()) - 1.0
}

/// Lobe selection probabilities (diffuse, clearcoat, transmission, reflection),
/// normalised; `None` when they sum to zero (all rates zero).
#[inline]
fn lobe_probabilities(
    b: &Principled,
    front: bool,
    f: f32,
    brdf: f32,
    bsdf: f32,
) -> Option<[f32; 4]> {
    let (reflect, trans, coat, diffuse) = if front {
        (
            b.specular_rate * (1.0 - bsdf * (1.0 - f)),
            b.specular_rate * bsdf * (1.0 - f),
            0.25 * b.clearcoat * b.clearcoat_rate,
            brdf * b.diffuse_rate,
        )
    } else {
        (f, 1.0 - f, 0.0, 0.0)
    };
    let total = reflect + trans + coat + diffuse;
    if !(total.is_finite() && total > 0.0) {
        return None;
    }
    let r = 1.0 / total;
    Some([diffuse * r, coat * r, trans * r, reflect * r])
}

impl Principled {
    /// The weights of the diffuse (`brdf`) and transmissive (`bsdf`) lobes; spec_trans
    /// counts only where the lobe exists (Mitsuba reads it as 0 otherwise).
    #[inline]
    fn weights(&self) -> (f32, f32) {
        let spec_trans = if self.has_spec_trans {
            self.spec_trans
        } else {
            0.0
        };
        let brdf = (1.0 - self.metallic) * (1.0 - spec_trans);
        let bsdf = (1.0 - self.metallic) * spec_trans;
        (brdf, bsdf)
    }

    /// Walter's half vector of (wo, wi) turned up, and `eta_path` (the IOR of wi's side
    /// over wo's); `None` when the directions cancel.
    #[inline]
    fn half_vector(&self, wo: Vec3, wi: Vec3, reflect: bool) -> Option<(Vec3, f32)> {
        let eta_path = if wo.z > 0.0 { self.eta } else { 1.0 / self.eta };
        let wh = (wo + wi * if reflect { 1.0 } else { eta_path }).try_normalize()?;
        Some((if wh.z < 0.0 { -wh } else { wh }, eta_path))
    }

    /// The body of `eval` (`VALUE`) and `pdf` (`DENSITY`), either or both: computed
    /// together they share the half vector, the Fresnel term, the lobe's D and G1(wo)
    /// and the clearcoat's D, each the same operations either computes alone (so the
    /// same bits; the density's G1 is of `wo` turned up, reused from the front only).
    #[inline(always)]
    fn eval_pdf_as<const VALUE: bool, const DENSITY: bool>(
        &self,
        wo: Vec3,
        wi: Vec3,
    ) -> (Rgb, f32) {
        let (cos_o, cos_i) = (wo.z, wi.z);
        if cos_o == 0.0 {
            return (Rgb::ZERO, 0.0);
        }
        let (brdf, bsdf) = self.weights();
        let front = cos_o > 0.0;
        // No density from the back of a model without transmission (the value goes on).
        let back_opaque = !front && bsdf <= 0.0;
        let density = DENSITY && !back_opaque;
        if !VALUE && !density {
            return (Rgb::ZERO, 0.0);
        }
        let reflect = cos_o * cos_i > 0.0;
        let refract = cos_o * cos_i < 0.0;
        if !reflect && !refract {
            return (Rgb::ZERO, 0.0);
        }
        let Some((wh, eta_path)) = self.half_vector(wo, wi, reflect) else {
            return (Rgb::ZERO, 0.0);
        };
        let distr = ggx(self.anisotropic, self.roughness);
        let (dot_o, dot_i) = (wo.dot(wh), wi.dot(wh));
        let f = fresnel_dielectric(dot_o, self.eta).0;
        // D(wh), G1(wo, wh) and the clearcoat's D(wh), where the value computed them.
        let (mut d_wh, mut g1_wo, mut d_coat) = (None, None, None);
        let mut value = Rgb::ZERO;
        if VALUE {
            let base = self.base_color;
            if reflect {
                let compatible = mac_mic_compatible(wh, wo, wi, cos_o, true);
                let d = distr.d(wh);
                let g1_o = distr.g1(wo, wh);
                let g = g1_o * distr.g1(wi, wh);
                (d_wh, g1_wo) = (Some(d), Some(g1_o));
                if compatible && f > 0.0 {
                    let fp = principled_fresnel(
                        f,
                        self.metallic,
                        self.spec_tint,
                        base,
                        dot_o,
                        front,
                        bsdf,
                        self.eta,
                    );
                    value += fp * (d * g / (4.0 * cos_o.abs()));
                }
                if front && compatible && self.clearcoat > 0.0 {
                    let fcc = calc_schlick(Rgb::splat(0.04), dot_o, self.eta).x;
                    let dcc = Gtr1::clearcoat(self.clearcoat_gloss).eval(wh);
                    d_coat = Some(dcc);
                    let gcc = smith_ggx1(wo, wh, 0.25) * smith_ggx1(wi, wh, 0.25);
                    value += Rgb::splat(self.clearcoat * 0.25 * fcc * dcc * gcc * cos_i.abs());
                }
                if front && brdf > 0.0 {
                    value += brdf
                        * diffuse_retro(base, self.roughness, self.flatness, cos_o, cos_i, dot_i);
                }
                // (Mitsuba's LLVM variants add the sheen whenever its own mask holds.)
                if front && self.sheen > 0.0 && 1.0 - self.metallic > 0.0 {
                    value += self.sheen
                        * (1.0 - self.metallic)
                        * sheen(base, self.sheen_tint, cos_i, dot_i);
                }
            } else if self.has_spec_trans
                && bsdf > 0.0
                && f < 1.0
                && mac_mic_compatible(wh, wo, wi, cos_o, false)
            {
                let d = distr.d(wh);
                let g1_o = distr.g1(wo, wh);
                let g = g1_o * distr.g1(wi, wh);
                (d_wh, g1_wo) = (Some(d), Some(g1_o));
                let scale = 1.0 / (eta_path * eta_path);
                let denom = dot_o + eta_path * dot_i;
                let t = (scale * (1.0 - f) * d * g * eta_path * eta_path * dot_o * dot_i
                    / (cos_o * denom * denom))
                    .abs();
                value += base.max(Rgb::ZERO).powf(0.5) * (bsdf * t);
            }
        }
        let mut pdf = 0.0;
        if density {
            let Some([p_diffuse, p_coat, p_trans, p_reflect]) =
                lobe_probabilities(self, front, f, brdf, bsdf)
            else {
                return (value, 0.0);
            };
            let dwh_dwi = if reflect {
                (1.0 / (4.0 * dot_i)).abs()
            } else {
                let denom = dot_o + eta_path * dot_i;
                (eta_path * eta_path * dot_i / (denom * denom)).abs()
            };
            // The density of wh seen from wo turned up: `distr.pdf(mulsign(wo, cos_o),
            // wh)` with D, and from the front (where wo is not turned) G1, reused.
            let normal_pdf = || {
                let wo_up = mulsign(wo, cos_o);
                let d = d_wh.unwrap_or_else(|| distr.d(wh));
                let g1 = match g1_wo {
                    Some(g1) if front => g1,
                    _ => distr.g1(wo_up, wh),
                };
                distr.pdf_with(wo_up, wh, d, g1)
            };
            if reflect {
                if mac_mic_compatible(wh, wo, wi, cos_o, true) {
                    let pm = normal_pdf();
                    pdf += p_reflect * pm * dwh_dwi;
                    if p_coat > 0.0 {
                        let coat = Gtr1::clearcoat(self.clearcoat_gloss);
                        let dcc = d_coat.unwrap_or_else(|| coat.eval(wh));
                        pdf += p_coat * coat.pdf_with(wh, dcc) * dwh_dwi;
                    }
                }
                pdf += p_diffuse * FRAC_1_PI * cos_i;
            } else if self.has_spec_trans && mac_mic_compatible(wh, wo, wi, cos_o, false) {
                pdf += p_trans * normal_pdf() * dwh_dwi;
            }
        }
        (value, pdf)
    }
}

impl BsdfModel for Principled {
    fn flags(&self, _wo: Vec3) -> BsdfFlags {
        let f = BsdfFlags::DIFFUSE_REFLECTION | BsdfFlags::GLOSSY_REFLECTION;
        if self.has_spec_trans {
            f | BsdfFlags::GLOSSY_TRANSMISSION
        } else {
            f
        }
    }

    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        self.eval_pdf_as::<true, false>(wo, wi).0
    }

    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.eval_pdf_as::<false, true>(wo, wi).1
    }

    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
        self.eval_pdf_as::<true, true>(wo, wi)
    }

    /// The transmitted IOR ratio: `eta` entering from the front, `1 / eta` leaving.
    fn eta(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z * wi.z >= 0.0 || !self.has_spec_trans {
            1.0
        } else if wo.z > 0.0 {
            self.eta
        } else {
            1.0 / self.eta
        }
    }

    /// `u1` picks the lobe (diffuse, clearcoat, transmission, reflection in that order,
    /// as Mitsuba), `u2` the direction within it.
    fn sample(&self, wo: Vec3, u1: f32, u2: [f32; 2]) -> Option<BsdfSample> {
        let cos_o = wo.z;
        if cos_o == 0.0 {
            return None;
        }
        let (brdf, bsdf) = self.weights();
        let front = cos_o > 0.0;
        if !front && bsdf <= 0.0 {
            return None;
        }
        let distr = ggx(self.anisotropic, self.roughness);
        let m = distr.sample(mulsign(wo, cos_o), u2);
        let dot_o = wo.dot(m);
        let (f, cos_t, eta_it, eta_ti) = fresnel_dielectric(dot_o, self.eta);
        let [p_diffuse, p_coat, p_trans, _] = lobe_probabilities(self, front, f, brdf, bsdf)?;
        let (wi, lobe, eta) = if u1 < p_diffuse {
            let wi = cosine_hemisphere(u2);
            if cos_o * wi.z <= 0.0 {
                return None;
            }
            (wi, BsdfFlags::DIFFUSE_REFLECTION, 1.0)
        } else if u1 < p_diffuse + p_coat {
            let mc = Gtr1::clearcoat(self.clearcoat_gloss).sample(u2);
            let wi = 2.0 * wo.dot(mc) * mc - wo;
            if !(mac_mic_compatible(mc, wo, wi, cos_o, true) && cos_o * wi.z > 0.0) {
                return None;
            }
            (wi, BsdfFlags::GLOSSY_REFLECTION, 1.0)
        } else if u1 < p_diffuse + p_coat + p_trans {
            let wi = m * (dot_o * eta_ti + cos_t) - wo * eta_ti;
            if !(mac_mic_compatible(m, wo, wi, cos_o, false) && cos_o * wi.z < 0.0) {
                return None;
            }
            (wi, BsdfFlags::GLOSSY_TRANSMISSION, eta_it)
        } else {
            let wi = 2.0 * dot_o * m - wo;
            if !(mac_mic_compatible(m, wo, wi, cos_o, true) && cos_o * wi.z > 0.0) {
                return None;
            }
            (wi, BsdfFlags::GLOSSY_REFLECTION, 1.0)
        };
        let (value, pdf) = self.eval_pdf(wo, wi);
        if !(pdf.is_finite() && pdf > 0.0) {
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

    /// The G-buffer's guide (not the exact expectation): from the front, the diffuse
    /// weight times base_color, plus the reflectance `F_p` about the macro normal, the
    /// transmitted energy `bsdf (1 - F) sqrt(base_color)` and the coat's `clearcoat / 4
    /// F_schlick(0.04)` (retro-reflection, sheen, roughness and masking left out);
    /// from the back `bsdf (F + (1 - F) sqrt(base_color))`; clamped to [0, 1].
    fn albedo(&self, wo: Vec3) -> Rgb {
        let cos_o = wo.z;
        let (brdf, bsdf) = self.weights();
        let f = fresnel_dielectric(cos_o, self.eta).0;
        let base = self.base_color.max(Rgb::ZERO);
        let trans = base.powf(0.5) * (bsdf * (1.0 - f));
        let a = if cos_o > 0.0 {
            let fp = principled_fresnel(
                f,
                self.metallic,
                self.spec_tint,
                base,
                cos_o,
                true,
                bsdf,
                self.eta,
            );
            let coat = 0.25 * self.clearcoat * calc_schlick(Rgb::splat(0.04), cos_o, self.eta).x;
            base * brdf + fp + trans + Rgb::splat(coat)
        } else if cos_o < 0.0 {
            Rgb::splat(bsdf * f) + trans
        } else {
            Rgb::ZERO
        };
        a.clamp(Rgb::ZERO, Rgb::ONE)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn specular_maps_to_eta_as_mitsuba() {
        assert!((specular_to_eta(0.5) - 1.5).abs() < 1e-6);
        assert_eq!(specular_to_eta(0.0), 1.0);
    }

    #[test]
    fn transmission_reports_the_ior_crossed() {
        let b = Principled {
            spec_trans: 1.0,
            has_spec_trans: true,
            roughness: 0.2,
            ..Principled::default()
        };
        let wo = Vec3::new(0.3, 0.1, 0.9).normalize();
        // u1 near 1 with spec_trans 1 and F small: transmission from the front...
        let mut found = false;
        for k in 0..64 {
            let u1 = 0.5 + k as f32 / 130.0;
            if let Some(s) = b.sample(wo, u1, [0.3, 0.7]) {
                if s.lobe == BsdfFlags::GLOSSY_TRANSMISSION {
                    assert!(s.wi.z < 0.0);
                    assert_eq!(s.eta, b.eta);
                    assert_eq!(b.eta(wo, s.wi), b.eta);
                    found = true;
                }
            }
        }
        assert!(found);
        // ...and no scattering at all from the back without transmission.
        let opaque = Principled::default();
        assert!(opaque.sample(-wo, 0.5, [0.3, 0.7]).is_none());
        assert_eq!(opaque.eval(-wo, Vec3::new(0.0, 0.0, -1.0)), Rgb::ZERO);
        assert_eq!(opaque.pdf(-wo, Vec3::new(0.0, 0.0, -1.0)), 0.0);
    }
}
