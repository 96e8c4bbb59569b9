//! Broken models the harness must reject (so it is not vacuous), and the tests that
//! reject the ones no other test uses.

use crate::harness::{chi2_p_value, delta_p_value, diffuse, dir, glass};
use crate::plastic::rough_plastic_models;
use crate::LEVEL;
use glam::Vec3;
use tstat::materials::{
    BsdfFlags, BsdfModel, BsdfSample, Dielectric, Diffuse, Perturbed, Principled, RoughDielectric,
    RoughPlastic,
};
use tstat::math::sampling::cosine_hemisphere_pdf;
use tstat::math::Rgb;

/// A Lambertian whose `pdf` reports twice the density `sample` uses.
pub(crate) struct PdfOffByTwo(pub(crate) Diffuse);

impl BsdfModel for PdfOffByTwo {
    fn flags(&self, wo: Vec3) -> BsdfFlags {
        self.0.flags(wo)
    }
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        self.0.eval(wo, wi)
    }
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        2.0 * self.0.pdf(wo, wi)
    }
    fn sample(&self, wo: Vec3, u1: f32, u2: [f32; 2]) -> Option<BsdfSample> {
        self.0.sample(wo, u1, u2)
    }
    fn albedo(&self, wo: Vec3) -> Rgb {
        self.0.albedo(wo)
    }
}

/// A Lambertian that samples the hemisphere uniformly but reports the cosine density.
struct SkewedSampling(Diffuse);

impl BsdfModel for SkewedSampling {
    fn flags(&self, wo: Vec3) -> BsdfFlags {
        self.0.flags(wo)
    }
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        self.0.eval(wo, wi)
    }
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.0.pdf(wo, wi)
    }
    fn sample(&self, wo: Vec3, _u1: f32, u2: [f32; 2]) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let z = u2[0];
        let r = (1.0 - z * z).max(0.0).sqrt();
        let phi = 2.0 * std::f32::consts::PI * u2[1];
        let wi = Vec3::new(r * phi.cos(), r * phi.sin(), z);
        let pdf = cosine_hemisphere_pdf(wi.z);
        (pdf > 0.0).then_some(BsdfSample {
            wi,
            weight: self.0.reflectance,
            pdf,
            lobe: BsdfFlags::DIFFUSE_REFLECTION,
            eta: 1.0,
        })
    }
    fn albedo(&self, wo: Vec3) -> Rgb {
        self.0.albedo(wo)
    }
}

/// A glass that reflects with the normal-incidence reflectance at every angle.
struct FresnelAtNormal(Dielectric);

impl BsdfModel for FresnelAtNormal {
    fn flags(&self, wo: Vec3) -> BsdfFlags {
        self.0.flags(wo)
    }
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        self.0.eval(wo, wi)
    }
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.0.pdf(wo, wi)
    }
    fn sample(&self, wo: Vec3, u1: f32, u2: [f32; 2]) -> Option<BsdfSample> {
        let r0 = ((self.0.eta - 1.0) / (self.0.eta + 1.0)).powi(2);
        self.0
            .sample(wo, if u1 < r0 { 0.0 } else { 1.0 - 1e-7 }, u2)
    }
    fn albedo(&self, wo: Vec3) -> Rgb {
        self.0.albedo(wo)
    }
}

/// A glass that forgets the eta^2 radiance scaling of refraction.
pub(crate) struct NoRadianceScaling(pub(crate) Dielectric);

impl BsdfModel for NoRadianceScaling {
    fn flags(&self, wo: Vec3) -> BsdfFlags {
        self.0.flags(wo)
    }
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        self.0.eval(wo, wi)
    }
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.0.pdf(wo, wi)
    }
    fn sample(&self, wo: Vec3, u1: f32, u2: [f32; 2]) -> Option<BsdfSample> {
        let s = self.0.sample(wo, u1, u2)?;
        Some(BsdfSample {
            weight: self.0.specular_transmittance,
            ..s
        })
    }
    fn albedo(&self, wo: Vec3) -> Rgb {
        self.0.albedo(wo)
    }
}

/// f = 2 R cos(wo) / pi: integrates to R over wi for normal incidence, but is not
/// symmetric in wo and wi.
pub(crate) struct NonReciprocal(pub(crate) Diffuse);

impl BsdfModel for NonReciprocal {
    fn flags(&self, wo: Vec3) -> BsdfFlags {
        self.0.flags(wo)
    }
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        self.0.eval(wo, wi) * (2.0 * wo.z)
    }
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.0.pdf(wo, wi)
    }
    fn sample(&self, wo: Vec3, u1: f32, u2: [f32; 2]) -> Option<BsdfSample> {
        let s = self.0.sample(wo, u1, u2)?;
        Some(BsdfSample {
            weight: s.weight * (2.0 * wo.z),
            ..s
        })
    }
    fn albedo(&self, wo: Vec3) -> Rgb {
        self.0.albedo(wo) * (2.0 * wo.z).max(0.0)
    }
}

/// Walter et al.'s rough glass without Mitsuba's radiance scale `eta_ti^2` on
/// transmission (the BSDF for importance, not radiance): transmitted values and weights
/// times `eta_it^2`.
pub(crate) struct RoughGlassWithoutRadianceScale(pub(crate) RoughDielectric);

impl RoughGlassWithoutRadianceScale {
    fn scale(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z * wi.z >= 0.0 {
            1.0
        } else if wo.z > 0.0 {
            self.0.eta * self.0.eta
        } else {
            1.0 / (self.0.eta * self.0.eta)
        }
    }
}

impl BsdfModel for RoughGlassWithoutRadianceScale {
    fn flags(&self, wo: Vec3) -> BsdfFlags {
        self.0.flags(wo)
    }
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        self.0.eval(wo, wi) * self.scale(wo, wi)
    }
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.0.pdf(wo, wi)
    }
    fn sample(&self, wo: Vec3, u1: f32, u2: [f32; 2]) -> Option<BsdfSample> {
        let s = self.0.sample(wo, u1, u2)?;
        Some(BsdfSample {
            weight: s.weight * self.scale(wo, s.wi),
            ..s
        })
    }
    fn albedo(&self, wo: Vec3) -> Rgb {
        self.0.albedo(wo)
    }
}

/// A rough plastic that picks the specular lobe more often than its pdf says (u1
/// squared), as a wrong lobe-selection probability would.
struct SkewedLobeChoice(RoughPlastic);

impl BsdfModel for SkewedLobeChoice {
    fn flags(&self, wo: Vec3) -> BsdfFlags {
        self.0.flags(wo)
    }
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        self.0.eval(wo, wi)
    }
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.0.pdf(wo, wi)
    }
    fn sample(&self, wo: Vec3, u1: f32, u2: [f32; 2]) -> Option<BsdfSample> {
        self.0.sample(wo, u1 * u1, u2)
    }
    fn albedo(&self, wo: Vec3) -> Rgb {
        self.0.albedo(wo)
    }
}

/// A normal map whose samples forget the shadowing term (eval keeps it).
pub(crate) struct ShadowlessSample(pub(crate) Perturbed);

impl BsdfModel for ShadowlessSample {
    fn flags(&self, wo: Vec3) -> BsdfFlags {
        self.0.flags(wo)
    }
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        self.0.eval(wo, wi)
    }
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.0.pdf(wo, wi)
    }
    fn sample(&self, wo: Vec3, u1: f32, u2: [f32; 2]) -> Option<BsdfSample> {
        let f = &self.0.frame;
        let s = self.0.nested.sample(f.to_local(wo), u1, u2)?;
        let wi = f.to_world(s.wi);
        (wi.z * s.wi.z > 0.0).then_some(BsdfSample { wi, ..s })
    }
    fn albedo(&self, wo: Vec3) -> Rgb {
        self.0.albedo(wo)
    }
}

/// A principled glass whose transmission forgets Mitsuba's radiance scale 1 / eta^2.
pub(crate) struct PrincipledWithoutRadianceScale(pub(crate) Principled);

impl PrincipledWithoutRadianceScale {
    fn scale(&self, wo: Vec3, wi: Vec3) -> f32 {
        let e = self.0.eta(wo, wi);
        e * e
    }
}

impl BsdfModel for PrincipledWithoutRadianceScale {
    fn flags(&self, wo: Vec3) -> BsdfFlags {
        self.0.flags(wo)
    }
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        self.0.eval(wo, wi) * self.scale(wo, wi)
    }
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.0.pdf(wo, wi)
    }
    fn sample(&self, wo: Vec3, u1: f32, u2: [f32; 2]) -> Option<BsdfSample> {
        let s = self.0.sample(wo, u1, u2)?;
        Some(BsdfSample {
            weight: s.weight * self.scale(wo, s.wi),
            ..s
        })
    }
    fn albedo(&self, wo: Vec3) -> Rgb {
        self.0.albedo(wo)
    }
}

#[test]
fn chi_square_rejects_broken_sampling() {
    let wo = dir(30.0, 0.0);
    let p = chi2_p_value(&PdfOffByTwo(diffuse(0.5)), wo, 1);
    assert!(p < LEVEL, "pdf off by two passed: p = {p}");
    let p = chi2_p_value(&SkewedSampling(diffuse(0.5)), wo, 2);
    assert!(
        p < LEVEL,
        "uniform sampling against a cosine pdf passed: p = {p}"
    );
}

#[test]
fn binomial_test_rejects_a_wrong_fresnel_choice() {
    // At 75 deg R = 0.15 while R0 = 0.04.
    let p = delta_p_value(&FresnelAtNormal(glass(1.5)), dir(75.0, 0.0), Some(1.5), 3);
    assert!(p < LEVEL, "reflection with R0 at 75 deg passed: p = {p}");
}

#[test]
fn chi_square_rejects_a_wrong_lobe_choice() {
    // At 70 deg a dark base makes both lobes likely.
    let (_, b, _) = rough_plastic_models().swap_remove(4);
    let p = chi2_p_value(&SkewedLobeChoice(b), dir(70.0, 0.0), 5);
    assert!(p < LEVEL, "a skewed lobe choice passed: p = {p}");
}
