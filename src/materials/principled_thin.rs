//! `principledthin`: Mitsuba 3's thin-surface Disney BSDF (Burley 2015, section 5),
//! transcribed from `src/bsdfs/principledthin.cpp`: a two-sided sheet with no
//! interior, so light crossing it keeps its direction's medium (eta 1 along the path).
//!
//! | parameter | type | default | meaning |
//! |-----------|------|---------|---------|
//! | base_color | rgb or texture | 0.5 | colour of the diffuse lobes and the specular transmission |
//! | roughness | float or texture | 0.5 | specular roughness (alpha = roughness^2) and retro-reflection |
//! | anisotropic | float or texture | 0 | stretches alpha along the tangent (dp/du) |
//! | spec_trans | float or texture | 0 | share of the specular (reflection + transmission) lobes |
//! | diff_trans | float or texture | 0 | diffuse transmission, in [0, 2] (halved: 2 transmits all diffuse light) |
//! | eta | float or texture | 1.5 | the sheet's IOR: Fresnel, and the transmission roughness `(0.65 eta - 0.35) roughness` |
//! | spec_tint | float or texture | 0 | tints the specular reflection towards base_color's hue |
//! | sheen, sheen_tint | float or texture | 0 | grazing sheen lobe and its tint |
//! | flatness | float or texture | 0 | blends the diffuse lobe towards the fake subsurface one |
//! | specular_reflectance_sampling_rate, specular_transmittance_sampling_rate, diffuse_reflectance_sampling_rate, diffuse_transmittance_sampling_rate | float | 1 | lobe selection weights |
//!
//! Both sides see the same model: `wo` and `wi` are mirrored through the sheet when
//! `wo.z < 0`. With `wi_r` = wi mirrored to wo's side and `m = normalize(wo + wi_r)`, F
//! the dielectric Fresnel of `wo . m` for `eta`, D and G GGX's:
//!
//! - reflection: `spec_trans F_thin D G / (4 cos wo)` ([`thin_fresnel`]) + `(1 -
//!   spec_trans)(1 - dt)` times the diffuse-retro-flatness and sheen lobes
//!   ([`diffuse_retro`], [`sheen`]), `dt = diff_trans / 2`;
//! - transmission: `spec_trans base (1 - F) D' G' / (4 cos wo)` (D', G' of the scaled
//!   roughness, evaluated at `m` and the unmirrored `wi`, as Mitsuba) + `(1 -
//!   spec_trans) dt base |cos wi| / pi`.
//!
//! Sampling picks specular reflection, specular transmission (reflection about a
//! normal of the scaled distribution, then mirrored through the sheet), cosine
//! reflection or cosine transmission with probabilities `spec_trans r_sr / 2`,
//! `spec_trans r_st / 2`, `(1 - spec_trans)(1 - dt) r_dr`, `(1 - spec_trans) dt r_dt`,
//! normalised; `pdf` is that mixture, so the weight is `eval / pdf`.

use super::fresnel::fresnel_dielectric;
use super::principled_common::{
    diffuse_retro, ggx, mac_mic_compatible, mulsign, sheen, thin_fresnel,
};
use super::{BsdfFlags, BsdfModel, BsdfSample};
use crate::math::sampling::cosine_hemisphere;
use crate::math::Rgb;
use glam::Vec3;
use std::f32::consts::FRAC_1_PI;

#[derive(Clone, Debug, PartialEq)]
pub struct PrincipledThin {
    pub base_color: Rgb,
    pub roughness: f32,
    pub anisotropic: f32,
    pub spec_trans: f32,
    /// As given, in [0, 2].
    pub diff_trans: f32,
    pub eta: f32,
    pub spec_tint: f32,
    pub sheen: f32,
    pub sheen_tint: f32,
    pub flatness: f32,
    /// Sampling rates: specular reflection and transmission, diffuse reflection and
    /// transmission.
    pub spec_reflect_rate: f32,
    pub spec_trans_rate: f32,
    pub diffuse_reflect_rate: f32,
    pub diffuse_trans_rate: f32,
    /// `spec_trans` / `diff_trans` given (not as the float 0): Mitsuba's
    /// `m_has_spec_trans` and `m_has_diff_trans`, which switch those lobes on.
    pub has_spec_trans: bool,
    pub has_diff_trans: bool,
}

impl Default for PrincipledThin {
    fn default() -> Self {
        PrincipledThin {
            base_color: Rgb::splat(0.5),
            roughness: 0.5,
            anisotropic: 0.0,
            spec_trans: 0.0,
            diff_trans: 0.0,
            eta: 1.5,
            spec_tint: 0.0,
            sheen: 0.0,
            sheen_tint: 0.0,
            flatness: 0.0,
            spec_reflect_rate: 1.0,
            spec_trans_rate: 1.0,
            diffuse_reflect_rate: 1.0,
            diffuse_trans_rate: 1.0,
            has_spec_trans: false,
            has_diff_trans: false,
        }
    }
}

impl PrincipledThin {
    /// spec_trans and diff_trans / 2 where their lobes exist, else 0 (as Mitsuba).
    #[inline]
    fn weights(&self) -> (f32, f32) {
        let st = if self.has_spec_trans {
            self.spec_trans
        } else {
            0.0
        };
        let dt = if self.has_diff_trans {
            self.diff_trans / 2.0
        } else {
            0.0
        };
        (st, dt)
    }

    /// Normalised probabilities of specular reflection, specular transmission, cosine
    /// reflection and cosine transmission; `None` when they sum to zero.
    #[inline]
    fn lobe_probabilities(&self, st: f32, dt: f32) -> Option<[f32; 4]> {
        let p = [
            st * self.spec_reflect_rate / 2.0,
            st * self.spec_trans_rate / 2.0,
            self.diffuse_reflect_rate * (1.0 - st) * (1.0 - dt),
            if self.has_diff_trans {
                self.diffuse_trans_rate * (1.0 - st) * dt
            } else {
                0.0
            },
        ];
        let total = p[0] + p[1] + p[2] + p[3];
        if !(total.is_finite() && total > 0.0) {
            return None;
        }
        let r = 1.0 / total;
        Some(p.map(|x| x * r))
    }

    /// The distribution of the specular transmission: roughness scaled by
    /// `0.65 eta - 0.35` (Burley 2015, figure 15).
    #[inline]
    fn transmission_distribution(&self) -> super::Microfacet {
        ggx(self.anisotropic, (0.65 * self.eta - 0.35) * self.roughness)
    }

    /// The body of `eval` (`VALUE`) and `pdf` (`DENSITY`), either or both: computed
    /// together they share the mirrored directions, the half vector and the specular
    /// lobe's D and G1(wo) (of the reflection's or the transmission's distribution,
    /// as `wi` lies), each the same operations either computes alone (so the same bits).
    #[inline(always)]
    fn eval_pdf_as<const VALUE: bool, const DENSITY: bool>(
        &self,
        wo: Vec3,
        wi: Vec3,
    ) -> (Rgb, f32) {
        if wo.z == 0.0 {
            return (Rgb::ZERO, 0.0);
        }
        let (st, dt) = self.weights();
        let base = self.base_color;
        // Seen from the front whatever the side.
        let (wo, wi) = (mulsign(wo, wo.z), mulsign(wi, wo.z));
        let (cos_o, cos_i) = (wo.z, wi.z);
        let reflect = cos_i > 0.0;
        let refract = cos_i < 0.0;
        let probabilities = if DENSITY {
            self.lobe_probabilities(st, dt)
        } else {
            None
        };
        if !VALUE && probabilities.is_none() {
            return (Rgb::ZERO, 0.0);
        }
        let wi_r = Vec3::new(wi.x, wi.y, wi.z.abs());
        let half = (wo + wi_r).try_normalize();
        // D(wh) and G1(wo, wh) of the specular lobe `wi` lies in, where the value
        // computed them (reflection and transmission exclude each other).
        let (mut d_wh, mut g1_wo) = (None, None);
        let mut value = Rgb::ZERO;
        if let (true, Some(wh)) = (VALUE, half) {
            if st > 0.0 {
                let f = fresnel_dielectric(wo.dot(wh), self.eta).0;
                if reflect && mac_mic_compatible(wh, wo, wi, cos_o, true) {
                    let distr = ggx(self.anisotropic, self.roughness);
                    let f_thin = thin_fresnel(f, self.spec_tint, base, wo.dot(wh), self.eta);
                    let (d, g1_o) = (distr.d(wh), distr.g1(wo, wh));
                    (d_wh, g1_wo) = (Some(d), Some(g1_o));
                    let dg = d * (g1_o * distr.g1(wi, wh));
                    value += f_thin * (st * dg / (4.0 * cos_o));
                }
                if refract && mac_mic_compatible(wh, wo, wi, cos_o, false) {
                    let distr = self.transmission_distribution();
                    let (d, g1_o) = (distr.d(wh), distr.g1(wo, wh));
                    (d_wh, g1_wo) = (Some(d), Some(g1_o));
                    let dg = d * (g1_o * distr.g1(wi, wh));
                    value += base * (st * (1.0 - f) * dg / (4.0 * cos_o));
                }
            }
            if reflect && st < 1.0 && dt < 1.0 {
                let cos_d = wh.dot(wi);
                let w = (1.0 - st) * (1.0 - dt);
                value +=
                    w * diffuse_retro(base, self.roughness, self.flatness, cos_o, cos_i, cos_d);
                if self.sheen > 0.0 {
                    value += (self.sheen * w) * sheen(base, self.sheen_tint, cos_i, cos_d);
                }
            }
            if refract && st < 1.0 && dt > 0.0 {
                value += base * ((1.0 - st) * dt * FRAC_1_PI * cos_i.abs());
            }
        }
        let mut pdf = 0.0;
        if let Some([p_sr, p_st, p_dr, p_dt]) = probabilities {
            if let (true, Some(wh)) = (self.has_spec_trans, half) {
                let dwh_dwi = (1.0 / (4.0 * wi_r.dot(wh))).abs();
                // `distr.pdf(wo, wh)` with the value's D and G1 reused.
                let normal_pdf = |distr: super::Microfacet| {
                    let d = d_wh.unwrap_or_else(|| distr.d(wh));
                    let g1 = g1_wo.unwrap_or_else(|| distr.g1(wo, wh));
                    distr.pdf_with(wo, wh, d, g1)
                };
                if reflect && mac_mic_compatible(wh, wo, wi, cos_o, true) {
                    let pm = normal_pdf(ggx(self.anisotropic, self.roughness));
                    pdf += p_sr * pm * dwh_dwi;
                }
                if refract && mac_mic_compatible(wh, wo, wi, cos_o, false) {
                    let pm = normal_pdf(self.transmission_distribution());
                    pdf += p_st * pm * dwh_dwi;
                }
            }
            if reflect {
                pdf += p_dr * FRAC_1_PI * cos_i;
            }
            if self.has_diff_trans && refract {
                pdf += p_dt * FRAC_1_PI * -cos_i;
            }
        }
        (value, pdf)
    }
}

impl BsdfModel for PrincipledThin {
    fn flags(&self, _wo: Vec3) -> BsdfFlags {
        let f = BsdfFlags::DIFFUSE_REFLECTION
            | BsdfFlags::DIFFUSE_TRANSMISSION
            | BsdfFlags::GLOSSY_REFLECTION;
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

    /// `u1` picks specular reflection, specular transmission, cosine reflection or
    /// cosine transmission (Mitsuba's order), `u2` the direction.
    fn sample(&self, wo: Vec3, u1: f32, u2: [f32; 2]) -> Option<BsdfSample> {
        let cos_o = wo.z;
        if cos_o == 0.0 {
            return None;
        }
        let (st, dt) = self.weights();
        let wo_f = mulsign(wo, cos_o);
        let [p_sr, p_st, p_dr, _] = self.lobe_probabilities(st, dt)?;
        let (w, lobe) = if self.has_spec_trans && u1 < p_sr {
            let m = ggx(self.anisotropic, self.roughness).sample(wo_f, u2);
            let w = 2.0 * wo_f.dot(m) * m - wo_f;
            if !(mac_mic_compatible(m, wo_f, w, wo_f.z, true) && w.z > 0.0) {
                return None;
            }
            (w, BsdfFlags::GLOSSY_REFLECTION)
        } else if self.has_spec_trans && u1 < p_sr + p_st {
            let m = self.transmission_distribution().sample(wo_f, u2);
            let r = 2.0 * wo_f.dot(m) * m - wo_f;
            let w = Vec3::new(r.x, r.y, -r.z);
            if !(mac_mic_compatible(m, wo_f, w, wo_f.z, false) && w.z < 0.0) {
                return None;
            }
            (w, BsdfFlags::GLOSSY_TRANSMISSION)
        } else if u1 >= p_sr + p_st && u1 < p_sr + p_st + p_dr {
            (cosine_hemisphere(u2), BsdfFlags::DIFFUSE_REFLECTION)
        } else if self.has_diff_trans && u1 >= p_sr + p_st + p_dr {
            (-cosine_hemisphere(u2), BsdfFlags::DIFFUSE_TRANSMISSION)
        } else {
            return None;
        };
        let wi = mulsign(w, cos_o);
        let (value, pdf) = self.eval_pdf(wo, wi);
        if !(pdf.is_finite() && pdf > 0.0) {
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

    /// The G-buffer's guide (not the exact expectation): `spec_trans (F + (1 - F)
    /// base_color) + (1 - spec_trans) base_color` with F the dielectric Fresnel of `wo`
    /// about the normal (retro-reflection, sheen, roughness and masking left out),
    /// clamped to [0, 1].
    fn albedo(&self, wo: Vec3) -> Rgb {
        if wo.z == 0.0 {
            return Rgb::ZERO;
        }
        let (st, _) = self.weights();
        let f = fresnel_dielectric(wo.z.abs(), self.eta).0;
        let base = self.base_color.max(Rgb::ZERO);
        let a = Rgb::splat(st * f) + base * (st * (1.0 - f) + (1.0 - st));
        a.clamp(Rgb::ZERO, Rgb::ONE)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sheet looks the same from both sides: eval and pdf are unchanged when both
    /// directions are mirrored through it.
    #[test]
    fn both_sides_are_the_same_sheet() {
        let b = PrincipledThin {
            spec_trans: 0.4,
            diff_trans: 0.6,
            has_spec_trans: true,
            has_diff_trans: true,
            roughness: 0.3,
            sheen: 0.5,
            ..PrincipledThin::default()
        };
        let flip = |v: Vec3| Vec3::new(v.x, v.y, -v.z);
        let wo = Vec3::new(0.3, -0.2, 0.8).normalize();
        for wi in [
            Vec3::new(-0.4, 0.1, 0.7).normalize(),
            Vec3::new(-0.2, 0.3, -0.9).normalize(),
        ] {
            assert_eq!(b.eval(wo, wi), b.eval(flip(wo), flip(wi)));
            assert_eq!(b.pdf(wo, wi), b.pdf(flip(wo), flip(wi)));
            assert!(b.pdf(wo, wi) > 0.0 && b.eval(wo, wi).min_element() > 0.0);
        }
    }
}
