//! What `principled` and `principledthin` share, transcribed from Mitsuba 3's
//! `principledhelpers.h`: Schlick's Fresnel approximation and its weight, the GTR1
//! distribution of the clearcoat lobe with its separable Smith GGX masking, the
//! macro/micro-surface compatibility test, the blended Fresnel terms of both models, the
//! Disney roughness mapping, and the diffuse-retro-flatness-sheen lobe both evaluate.
//!
//! Symbols (SPEC.md's): `wo` is the direction towards the camera side (Mitsuba's
//! `si.wi`), `wi` the scattered one (Mitsuba's `wo`); all in the local shading frame.

use super::microfacet::{Microfacet, MicrofacetKind};
use crate::math::Rgb;
use crate::textures::luminance;
use glam::Vec3;
use std::f32::consts::{FRAC_1_PI, PI};

/// Schlick's weight `(1 - cos)^5`, the cosine clipped to [0, 1].
#[inline]
pub fn schlick_weight(cos: f32) -> f32 {
    let m = (1.0 - cos).clamp(0.0, 1.0);
    let m2 = m * m;
    m2 * m2 * m
}

/// Mitsuba's `calc_schlick`: `R0 + (1 - R0) w` with Schlick's weight of the incident
/// cosine when entering the denser side (`eta_it > 1`), else of the transmitted cosine
/// (no reflectance jump at the critical angle, 1 beyond it).
#[inline]
pub fn calc_schlick(r0: Rgb, cos_theta_i: f32, eta: f32) -> Rgb {
    let outside = cos_theta_i >= 0.0;
    let (eta_it, eta_ti) = if outside {
        (eta, 1.0 / eta)
    } else {
        (1.0 / eta, eta)
    };
    let cos_t_sqr = 1.0 - (1.0 - cos_theta_i * cos_theta_i) * (eta_ti * eta_ti);
    let cos_t = cos_t_sqr.max(0.0).sqrt();
    let w = if eta_it > 1.0 {
        schlick_weight(cos_theta_i.abs())
    } else {
        schlick_weight(cos_t)
    };
    r0 + (Rgb::ONE - r0) * w
}

/// Reflectance at normal incidence of relative IOR `eta`: ((eta - 1) / (eta + 1))^2.
#[inline]
pub fn schlick_r0_eta(eta: f32) -> f32 {
    let r = (eta - 1.0) / (eta + 1.0);
    r * r
}

/// `m` with the sign of `s` (Mitsuba's `mulsign`; `s` is never 0 here).
#[inline]
pub fn mulsign(m: Vec3, s: f32) -> Vec3 {
    if s < 0.0 {
        -m
    } else {
        m
    }
}

/// Mitsuba's `mac_mic_compatibility`: the microfacet normal `m` (turned to the side of
/// `wo`, whose cosine is `cos_o`) faces `wo`, and faces `wi` for a reflection or faces
/// away from it for a transmission.
#[inline]
pub fn mac_mic_compatible(m: Vec3, wo: Vec3, wi: Vec3, cos_o: f32, reflection: bool) -> bool {
    let m = mulsign(m, cos_o);
    wo.dot(m) > 0.0
        && if reflection {
            wi.dot(m) > 0.0
        } else {
            wi.dot(-m) > 0.0
        }
}

/// Disney's roughness mapping (`calc_dist_params`): alpha = roughness^2, stretched by
/// `aspect = sqrt(1 - 0.9 anisotropic)` along the tangent (u) and shrunk along v, both
/// at least 0.001. (With anisotropic 0 this is Mitsuba's isotropic branch exactly.)
#[inline]
pub fn dist_params(anisotropic: f32, roughness: f32) -> (f32, f32) {
    let r2 = roughness * roughness;
    if anisotropic == 0.0 {
        let a = r2.max(0.001);
        return (a, a);
    }
    let aspect = (1.0 - 0.9 * anisotropic).sqrt();
    ((r2 / aspect).max(0.001), (r2 * aspect).max(0.001))
}

/// The main specular lobes' distribution: GGX, visible normals sampled (Mitsuba's
/// `MicrofacetDistribution(GGX, ax, ay)` default).
#[inline]
pub fn ggx(anisotropic: f32, roughness: f32) -> Microfacet {
    let (alpha_u, alpha_v) = dist_params(anisotropic, roughness);
    Microfacet {
        kind: MicrofacetKind::Ggx,
        alpha_u,
        alpha_v,
        sample_visible: true,
    }
}

/// Burley's GTR1 (Berry) distribution of the clearcoat lobe, isotropic, sampled as
/// `D(m) cos(theta_m)` (no visible-normal sampling, as Mitsuba).
#[derive(Clone, Copy, Debug)]
pub struct Gtr1 {
    pub alpha: f32,
}

impl Gtr1 {
    /// The clearcoat's: alpha from 0.1 (gloss 0) to 0.001 (gloss 1).
    #[inline]
    pub fn clearcoat(gloss: f32) -> Self {
        Gtr1 {
            alpha: 0.001 * gloss + (0.1 - 0.1 * gloss),
        }
    }

    /// D(m) = (a^2 - 1) / (pi ln(a^2) (1 + (a^2 - 1) cos^2 theta_m)).
    #[inline]
    pub fn eval(&self, m: Vec3) -> f32 {
        let cos2 = m.z * m.z;
        let a2 = self.alpha * self.alpha;
        let r = (a2 - 1.0) / (PI * a2.ln() * (1.0 + (a2 - 1.0) * cos2));
        if r * m.z > 1e-20 {
            r
        } else {
            0.0
        }
    }

    /// The density of sampling `m`, D(m) cos(theta_m), given `d = self.eval(m)` (the
    /// lobe's value computes it too).
    #[inline]
    pub fn pdf_with(&self, m: Vec3, d: f32) -> f32 {
        if m.z < 0.0 {
            0.0
        } else {
            m.z * d
        }
    }

    #[inline]
    pub fn sample(&self, u: [f32; 2]) -> Vec3 {
        let (sin_phi, cos_phi) = (2.0 * PI * u[0]).sin_cos();
        let a2 = self.alpha * self.alpha;
        let cos2 = (1.0 - a2.powf(1.0 - u[1])) / (1.0 - a2);
        let sin_t = (1.0 - cos2).max(0.0).sqrt();
        let cos_t = cos2.max(0.0).sqrt();
        Vec3::new(cos_phi * sin_t, sin_phi * sin_t, cos_t)
    }
}

/// Separable Smith GGX masking of one direction (`smith_ggx1`), the clearcoat's G1.
#[inline]
pub fn smith_ggx1(v: Vec3, m: Vec3, alpha: f32) -> f32 {
    if v.dot(m) * v.z <= 0.0 {
        return 0.0;
    }
    if v.z == 1.0 {
        return 1.0;
    }
    let cos2 = v.z * v.z;
    let tan2 = (1.0 - cos2) / cos2;
    2.0 / (1.0 + (1.0 + alpha * alpha * tan2).sqrt())
}

/// `base / luminance(base)` (white when the luminance is not positive): the hue that
/// the tint parameters blend towards.
#[inline]
pub fn tint_colour(base: Rgb, lum: f32) -> Rgb {
    if lum > 0.0 {
        base / lum
    } else {
        Rgb::ONE
    }
}

/// Mitsuba's `principled_fresnel` (`cos` = wo . m): on the front side the dielectric
/// reflectance `f_dielectric` blended with Schlick's metallic response (F0 =
/// base_color) and the tinted dielectric one (F0 = tint R0(eta)); on the back side
/// (inside, only reached with transmission) `bsdf f_dielectric`, `bsdf` the weight of
/// the transmissive lobe.
#[allow(clippy::too_many_arguments)]
#[inline]
pub fn principled_fresnel(
    f_dielectric: f32,
    metallic: f32,
    spec_tint: f32,
    base: Rgb,
    cos: f32,
    front: bool,
    bsdf: f32,
    eta: f32,
) -> Rgb {
    if !front {
        return Rgb::splat(bsdf * f_dielectric);
    }
    let mut schlick = Rgb::ZERO;
    if metallic != 0.0 {
        schlick += metallic * calc_schlick(base, cos, eta);
    }
    if spec_tint != 0.0 {
        let eta_it = if cos >= 0.0 { eta } else { 1.0 / eta };
        let f0 = tint_colour(base, luminance(base)) * schlick_r0_eta(eta_it);
        schlick += (1.0 - metallic) * spec_tint * calc_schlick(f0, cos, eta);
    }
    Rgb::splat((1.0 - metallic) * (1.0 - spec_tint) * f_dielectric) + schlick
}

/// Mitsuba's `thin_fresnel`: the dielectric reflectance blended by `spec_tint` towards
/// Schlick's with the tinted F0.
#[inline]
pub fn thin_fresnel(f_dielectric: f32, spec_tint: f32, base: Rgb, cos: f32, eta: f32) -> Rgb {
    if spec_tint == 0.0 {
        return Rgb::splat(f_dielectric);
    }
    let f0 = tint_colour(base, luminance(base)) * schlick_r0_eta(eta);
    let schlick = calc_schlick(f0, cos, eta);
    schlick * spec_tint + Rgb::splat(f_dielectric - f_dielectric * spec_tint)
}

/// The diffuse reflection lobes both models share, per unit of their weight: Burley's
/// diffuse `(1 - Fi / 2)(1 - Fo / 2)` plus retro-reflection `Rr (Fo + Fi + Fo Fi (Rr -
/// 1))`, `Rr = 2 roughness cos_d^2`, blended by `flatness` towards the Hanrahan-Krueger
/// fake subsurface `1.25 (Fss (1 / (|cos wi| + |cos wo|) - 1/2) + 1/2)`, all times
/// base_color / pi; with F the Schlick weights of the two cosines and `cos_d` = m . wi.
/// `cos_o` = wo.z and `cos_i` = wi.z (the lobe is symmetric in them). Returns f times
/// |cos wi| (the caller scales by the lobe's weight).
#[inline]
pub fn diffuse_retro(
    base: Rgb,
    roughness: f32,
    flatness: f32,
    cos_o: f32,
    cos_i: f32,
    cos_d: f32,
) -> Rgb {
    let (ao, ai) = (cos_o.abs(), cos_i.abs());
    let fo = schlick_weight(ai);
    let fi = schlick_weight(ao);
    let f_diff = (1.0 - 0.5 * fi) * (1.0 - 0.5 * fo);
    let rr = 2.0 * roughness * cos_d * cos_d;
    let f_retro = rr * (fo + fi + fo * fi * (rr - 1.0));
    let mut f = f_diff + f_retro;
    if flatness != 0.0 {
        let fss90 = rr / 2.0;
        let lerp = |a: f32, b: f32, t: f32| b * t + (a - a * t);
        let fss = lerp(1.0, fss90, fo) * lerp(1.0, fss90, fi);
        let f_ss = 1.25 * (fss * (1.0 / (ao + ai) - 0.5) + 0.5);
        f = lerp(f, f_ss, flatness);
    }
    base * (ai * FRAC_1_PI * f)
}

/// The sheen lobe per unit of `sheen` times its weight: Schlick's weight of `cos_d`
/// times the colour `lerp(1, tint, sheen_tint)`, times |cos wi|.
#[inline]
pub fn sheen(base: Rgb, sheen_tint: f32, cos_i: f32, cos_d: f32) -> Rgb {
    let fd = schlick_weight(cos_d.abs());
    let colour = if sheen_tint != 0.0 {
        let tint = tint_colour(base, luminance(base));
        tint * sheen_tint + Rgb::splat(1.0 - sheen_tint)
    } else {
        Rgb::ONE
    };
    colour * (fd * cos_i.abs())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// GTR1's density of normals, D(m) cos(theta_m), integrates to 1 over the
    /// hemisphere (midpoint rule in theta), and its sampler inverts its CDF.
    #[test]
    fn gtr1_is_normalised_and_sampled_by_its_cdf() {
        for alpha in [0.1f32, 0.03, 0.01] {
            let d = Gtr1 { alpha };
            let n = 200_000;
            let mut sum = 0.0f64;
            for k in 0..n {
                let t = (k as f64 + 0.5) / n as f64 * std::f64::consts::FRAC_PI_2;
                let m = Vec3::new(t.sin() as f32, 0.0, t.cos() as f32);
                sum += d.pdf_with(m, d.eval(m)) as f64 * t.sin() * 2.0 * std::f64::consts::PI;
            }
            sum *= std::f64::consts::FRAC_PI_2 / n as f64;
            assert!((sum - 1.0).abs() < 2e-3, "alpha {alpha}: {sum}");
            // The median of cos^2 theta: u = 0.5.
            let m = d.sample([0.0, 0.5]);
            let a2 = (alpha * alpha) as f64;
            let want = (1.0 - a2.powf(0.5)) / (1.0 - a2);
            assert!(((m.z * m.z) as f64 - want).abs() < 1e-5);
        }
    }

    #[test]
    fn schlick_is_r0_at_normal_incidence_and_one_at_grazing() {
        let r0 = Rgb::new(0.04, 0.5, 0.9);
        assert!((calc_schlick(r0, 1.0, 1.5) - r0).abs().max_element() < 1e-7);
        assert!((calc_schlick(r0, 1e-9, 1.5) - Rgb::ONE).abs().max_element() < 1e-6);
        // From the less dense side of eta 0.7 beyond the critical angle: 1.
        assert!((calc_schlick(r0, 0.3, 0.7) - Rgb::ONE).abs().max_element() < 1e-7);
        assert_eq!(dist_params(0.0, 0.5), (0.25, 0.25));
        let (ax, ay) = dist_params(0.5, 0.5);
        assert!((ax * ay - 0.0625).abs() < 1e-7 && ax > ay);
    }
}
