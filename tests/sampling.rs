//! The sampling harness every BSDF and emitter goes through (after pbrt-v4's `Chi2Test`
//! and Mitsuba 3's chi2 tests; written from their descriptions):
//!
//! - chi-square of sampled directions against the pdf integrated over a theta x phi
//!   grid on the sphere (adaptive Simpson per cell, cells with a small expected count
//!   pooled, fixed seeds), for the non-delta lobes;
//! - for delta lobes: every direction equals the analytic reflection or refraction,
//!   and the reflect/refract choice frequency matches the Fresnel reflectance
//!   (two-sided binomial test), Fresnel and Snell computed here in f64, independently;
//! - sample weight == eval / pdf and sample pdf == pdf (eval includes |cos|);
//! - the pdf integrates to 1 over the sphere;
//! - white furnace: the mean energy weight equals `albedo(wo)`, is <= 1, and is 1 for
//!   lossless models;
//! - reciprocity of f = eval / |cos wi| for reflection, and for refraction up to the
//!   IORs squared (f(wo, wi) / n(wo)^2 = f(wi, wo) / n(wi)^2);
//! - rough models: the mean sample energy equals quadrature of `eval` (rough glass over
//!   the whole sphere, transmission times eta^2), which never exceeds 1;
//! - emitters: the solid-angle pdf of a light sample equals the pdf the integrator's
//!   MIS computes when it hits the same point (or, for the environment, when a ray
//!   leaves the scene in the same direction), area samples are uniform by area, and
//!   environment samples (envmap, constant) follow their pdf by the same chi-square as
//!   the BSDFs.
//!
//! All statistical tests of this file form one family: each is held to
//! `ALPHA / FAMILY` (Bonferroni), so the whole file fails by chance with probability
//! below `ALPHA`. Broken BSDFs defined here must be rejected, so the harness is not
//! vacuous.

use glam::Vec3;
use statrs::distribution::{Binomial, ChiSquared, ContinuousCDF, DiscreteCDF};
use std::f64::consts::PI;
use std::sync::Arc;
use tstat::geometry::shape::ShapeGeom;
use tstat::lights::envmap::EnvMap;
use tstat::lights::scene_sphere::SceneSphere;
use tstat::lights::Emitter;
use tstat::materials::perturbed::{shadow_terminator, IDENTITY};
use tstat::materials::{Blend, PPlastic, Perturbation, Perturbed, Polarizer, RoughPlastic};
use tstat::materials::{
    Bsdf, BsdfFlags, BsdfModel, BsdfSample, Conductor, Dielectric, Diffuse, Mask, Microfacet,
    MicrofacetKind, OneSided, Plastic, RoughConductor, RoughDielectric, ThinDielectric, TwoSided,
};
use tstat::materials::{Principled, PrincipledThin};
use tstat::math::frame::Frame;
use tstat::math::rng::Pcg32;
use tstat::math::sampling::{cosine_hemisphere, cosine_hemisphere_pdf};
use tstat::math::Rgb;
use tstat::media::Phase;
use tstat::textures::Texture;

/// Overall significance of the file's statistical tests.
const ALPHA: f64 = 0.01;
/// Chi-square BSDF cases + delta cases + light cases (checked in each test).
const FAMILY: usize = 94;
/// The Bonferroni-corrected level of one test.
const LEVEL: f64 = ALPHA / FAMILY as f64;

const THETA_CELLS: usize = 16;
const PHI_CELLS: usize = 32;
const CHI2_SAMPLES: usize = 1_000_000;
/// Cells expecting fewer samples are pooled (the chi-square approximation needs ~5).
const MIN_EXPECTED: f64 = 5.0;

fn rgb(v: f32) -> Rgb {
    Rgb::splat(v)
}

fn diffuse(r: f32) -> Diffuse {
    Diffuse {
        reflectance: rgb(r),
    }
}

fn glass(eta: f32) -> Dielectric {
    Dielectric {
        eta,
        specular_reflectance: Rgb::ONE,
        specular_transmittance: Rgb::ONE,
    }
}

fn gold() -> Conductor {
    Conductor {
        eta: Rgb::new(0.143119, 0.374957, 1.44248),
        k: Rgb::new(3.98316, 2.38572, 1.60322),
        specular_reflectance: Rgb::ONE,
    }
}

fn mirror() -> Conductor {
    Conductor {
        eta: Rgb::ZERO,
        k: Rgb::ONE,
        specular_reflectance: Rgb::ONE,
    }
}

/// Gold's optical constants on a rough surface.
fn rough(kind: MicrofacetKind, alpha_u: f32, alpha_v: f32, sample_visible: bool) -> RoughConductor {
    RoughConductor {
        distribution: Microfacet {
            kind,
            alpha_u,
            alpha_v,
            sample_visible,
        },
        eta: gold().eta,
        k: gold().k,
        specular_reflectance: Rgb::ONE,
    }
}

/// Rough conductors across distributions, roughness, anisotropy and samplers.
fn rough_models() -> Vec<(&'static str, RoughConductor)> {
    use MicrofacetKind::{Beckmann, Ggx};
    vec![
        ("beckmann 0.3", rough(Beckmann, 0.3, 0.3, true)),
        ("beckmann 0.4 x 0.15", rough(Beckmann, 0.4, 0.15, true)),
        ("ggx 0.3 visible", rough(Ggx, 0.3, 0.3, true)),
        ("ggx 0.2 x 0.5 visible", rough(Ggx, 0.2, 0.5, true)),
        ("ggx 0.5 all normals", rough(Ggx, 0.5, 0.5, false)),
        ("ggx 0.15 x 0.6 all normals", rough(Ggx, 0.15, 0.6, false)),
    ]
}

/// A clear rough glass (`roughdielectric`).
fn rough_glass(
    kind: MicrofacetKind,
    alpha: f32,
    eta: f32,
    sample_visible: bool,
) -> RoughDielectric {
    RoughDielectric {
        distribution: Microfacet {
            kind,
            alpha_u: alpha,
            alpha_v: alpha,
            sample_visible,
        },
        eta,
        specular_reflectance: Rgb::ONE,
        specular_transmittance: Rgb::ONE,
    }
}

/// Rough glasses across distributions, roughness 0.1 / 0.3 / 0.6, eta 1.5 and 1 / 1.5
/// (glass seen from the inside of its normal) and both samplers, each with the polar
/// angle of `wo` its chi-square case uses: normal, oblique, grazing (80-100 deg) and
/// from inside (> 90 deg, 125 and 150 past the critical angle of 1.5).
fn rough_glass_models() -> Vec<(String, RoughDielectric, f64)> {
    use MicrofacetKind::{Beckmann, Ggx};
    let inv = 1.0 / 1.5;
    [
        (Beckmann, 0.1, 1.5, true, 30.0),
        (Beckmann, 0.1, inv, false, 140.0),
        (Beckmann, 0.3, 1.5, false, 80.0),
        (Beckmann, 0.3, inv, true, 60.0),
        (Beckmann, 0.6, 1.5, true, 125.0),
        (Beckmann, 0.6, inv, false, 0.0),
        (Ggx, 0.1, 1.5, false, 45.0),
        (Ggx, 0.1, inv, true, 170.0),
        (Ggx, 0.3, 1.5, true, 0.0),
        (Ggx, 0.3, inv, false, 100.0),
        (Ggx, 0.6, 1.5, false, 150.0),
        (Ggx, 0.6, inv, true, 88.0),
    ]
    .into_iter()
    .map(|(kind, alpha, eta, visible, theta)| {
        let sampler = if visible { "visible" } else { "all normals" };
        (
            format!("{kind:?} {alpha} eta {eta:.3} {sampler}"),
            rough_glass(kind, alpha, eta, visible),
            theta,
        )
    })
    .collect()
}

fn rough_plastic(
    kind: MicrofacetKind,
    alpha: f32,
    eta: f32,
    d: Rgb,
    nonlinear: bool,
    sample_visible: bool,
) -> RoughPlastic {
    let distribution = Microfacet {
        kind,
        alpha_u: alpha,
        alpha_v: alpha,
        sample_visible,
    };
    RoughPlastic::new(distribution, eta, d, Rgb::ONE, nonlinear)
}

/// Rough plastics across distributions, roughness 0.1 and 0.4, eta 1.49 and 1.9, bright
/// and dark bases, each with the polar angle of a `wo` (grazing ones included) for the
/// chi-square test.
fn rough_plastic_models() -> Vec<(&'static str, RoughPlastic, f64)> {
    use MicrofacetKind::{Beckmann, Ggx};
    let bright = Rgb::new(0.8, 0.6, 0.4);
    let dark = Rgb::new(0.05, 0.1, 0.02);
    vec![
        (
            "beckmann 0.1, eta 1.49, bright",
            rough_plastic(Beckmann, 0.1, 1.49, bright, false, true),
            30.0,
        ),
        (
            "beckmann 0.4, eta 1.9, dark",
            rough_plastic(Beckmann, 0.4, 1.9, dark, false, true),
            60.0,
        ),
        (
            "ggx 0.1, eta 1.9, bright",
            rough_plastic(Ggx, 0.1, 1.9, bright, false, true),
            85.0,
        ),
        (
            "ggx 0.4, eta 1.49, dark",
            rough_plastic(Ggx, 0.4, 1.49, dark, false, true),
            10.0,
        ),
        (
            "ggx 0.1, eta 1.49, dark, nonlinear",
            rough_plastic(Ggx, 0.1, 1.49, dark, true, true),
            75.0,
        ),
        (
            "beckmann 0.1, eta 1.9, bright, nonlinear",
            rough_plastic(Beckmann, 0.1, 1.9, bright, true, true),
            88.0,
        ),
        (
            "ggx 0.4, eta 1.9, bright, all normals",
            rough_plastic(Ggx, 0.4, 1.9, bright, false, false),
            45.0,
        ),
        (
            "beckmann 0.4, eta 1.49, white",
            rough_plastic(Beckmann, 0.4, 1.49, Rgb::ONE, false, true),
            0.0,
        ),
    ]
}

fn two_sided(front: OneSided, back: OneSided) -> Bsdf {
    Bsdf::TwoSided(TwoSided { front, back })
}

/// Unit direction at polar angle `theta_deg` from +z, azimuth `phi_deg`.
fn dir(theta_deg: f64, phi_deg: f64) -> Vec3 {
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    Vec3::new(
        (t.sin() * p.cos()) as f32,
        (t.sin() * p.sin()) as f32,
        t.cos() as f32,
    )
}

// ---------------------------------------------------------------- broken BSDFs

/// A Lambertian whose `pdf` reports twice the density `sample` uses.
struct PdfOffByTwo(Diffuse);

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
struct NoRadianceScaling(Dielectric);

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
struct NonReciprocal(Diffuse);

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
struct RoughGlassWithoutRadianceScale(RoughDielectric);

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

// ---------------------------------------------------------------- the cases

type Case = (String, Box<dyn BsdfModel>, Vec3);

/// A delta case and, for a dielectric, its relative IOR (a conductor always reflects).
type DeltaCase = (String, Box<dyn BsdfModel>, Vec3, Option<f64>);

/// Models with non-delta lobes, each with a `wo` from which they scatter.
fn non_delta_cases() -> Vec<Case> {
    let d = || OneSided::Diffuse(diffuse(0.7));
    let cases: Vec<(&str, Box<dyn BsdfModel>, Vec3)> = vec![
        (
            "diffuse, normal incidence",
            Box::new(diffuse(0.7)),
            dir(0.0, 0.0),
        ),
        ("diffuse, 45 deg", Box::new(diffuse(0.7)), dir(45.0, 30.0)),
        ("diffuse, 85 deg", Box::new(diffuse(1.0)), dir(85.0, 200.0)),
        (
            "twosided diffuse, front",
            Box::new(two_sided(d(), d())),
            dir(30.0, 10.0),
        ),
        (
            "twosided diffuse, back",
            Box::new(two_sided(d(), d())),
            dir(120.0, 10.0),
        ),
        (
            "twosided conductor/diffuse, back",
            Box::new(two_sided(OneSided::Conductor(gold()), d())),
            dir(160.0, 300.0),
        ),
    ];
    let angles = [30.0, 60.0, 45.0, 20.0, 70.0, 50.0];
    cases
        .into_iter()
        .map(|(n, b, wo)| (n.to_string(), b, wo))
        .chain(
            rough_models()
                .into_iter()
                .zip(angles)
                .map(|((n, b), theta)| {
                    let model: Box<dyn BsdfModel> = Box::new(b);
                    (
                        format!("roughconductor {n}, {theta} deg"),
                        model,
                        dir(theta, 40.0),
                    )
                }),
        )
        .chain(rough_glass_models().into_iter().map(|(n, b, theta)| {
            let model: Box<dyn BsdfModel> = Box::new(b);
            (
                format!("roughdielectric {n}, {theta} deg"),
                model,
                dir(theta, 110.0),
            )
        }))
        .chain(mask_cases())
        .chain(rough_plastic_cases())
        .chain(blend_cases())
        .chain(perturbed_cases())
        .chain(pplastic_models().into_iter().map(|(n, b, theta)| {
            let model: Box<dyn BsdfModel> = Box::new(b);
            (
                format!("pplastic {n}, {theta} deg"),
                model,
                dir(theta, 50.0),
            )
        }))
        .chain(phase_cases())
        .chain(
            principled_models()
                .into_iter()
                .map(|(n, b, theta, _)| (format!("{n}, {theta} deg"), b, dir(theta, 70.0))),
        )
        .collect()
}

fn blend(weight: f32, first: Bsdf, second: Bsdf) -> Blend {
    Blend {
        weight,
        first: Box::new(first),
        second: Box::new(second),
    }
}

/// `blendbsdf` of non-delta models (and one with a delta lobe, whose delta samples
/// the chi-square test leaves out).
fn blend_cases() -> Vec<Case> {
    vec![
        (
            "blendbsdf 0.3 of diffuse and roughconductor ggx 0.2, 35 deg".into(),
            Box::new(blend(
                0.3,
                Bsdf::Diffuse(diffuse(0.6)),
                Bsdf::RoughConductor(rough(MicrofacetKind::Ggx, 0.2, 0.2, true)),
            )),
            dir(35.0, 60.0),
        ),
        (
            "blendbsdf 0.8 of roughplastic and plastic, 65 deg".into(),
            Box::new(blend(
                0.8,
                Bsdf::RoughPlastic(rough_plastic(
                    MicrofacetKind::Beckmann,
                    0.3,
                    1.49,
                    Rgb::new(0.3, 0.5, 0.7),
                    false,
                    true,
                )),
                Bsdf::Plastic(Plastic::new(1.49, Rgb::new(0.8, 0.3, 0.1), Rgb::ONE, false)),
            )),
            dir(65.0, 200.0),
        ),
    ]
}

/// A frame tilted by `deg` degrees about the shading frame's t axis and turned by `turn`
/// degrees about the new normal (what `Perturbed::resolve` sets at a hit).
fn tilted_frame(deg: f32, turn: f32) -> Frame {
    let (a, b) = (deg.to_radians(), turn.to_radians());
    let n = Vec3::new(a.sin(), 0.0, a.cos());
    let s0 = Vec3::new(a.cos(), 0.0, -a.sin());
    let t0 = n.cross(s0);
    let s = s0 * b.cos() + t0 * b.sin();
    Frame {
        s,
        t: n.cross(s),
        n,
    }
}

fn perturbed(nested: Bsdf, frame: Frame, shadowing: bool) -> Perturbed {
    Perturbed {
        perturbation: Perturbation::NormalMap(Texture::Constant(Vec3::new(0.5, 0.5, 1.0))),
        flip_invalid_normals: true,
        use_shadowing_function: shadowing,
        nested: Box::new(nested),
        frame,
    }
}

/// `normalmap`/`bumpmap` with their frame set (a tilted normal), over a diffuse, an
/// anisotropic rough conductor and a rough plastic; the tilt makes part of the nested
/// lobe fall below the surface, where eval, pdf and samples are cut.
fn perturbed_cases() -> Vec<Case> {
    vec![
        (
            "normal map 30 deg over diffuse, 40 deg".into(),
            Box::new(perturbed(
                Bsdf::Diffuse(diffuse(0.8)),
                tilted_frame(30.0, 0.0),
                true,
            )),
            dir(40.0, 10.0),
        ),
        (
            "normal map 50 deg over diffuse, no shadowing, 70 deg".into(),
            Box::new(perturbed(
                Bsdf::Diffuse(diffuse(0.8)),
                tilted_frame(-50.0, 0.0),
                false,
            )),
            dir(70.0, 160.0),
        ),
        (
            "bump 20 deg, turned 40 deg, over anisotropic ggx, 50 deg".into(),
            Box::new(perturbed(
                Bsdf::RoughConductor(rough(MicrofacetKind::Ggx, 0.1, 0.4, true)),
                tilted_frame(20.0, 40.0),
                true,
            )),
            dir(50.0, 300.0),
        ),
        (
            "bump 25 deg over roughplastic, 60 deg".into(),
            Box::new(perturbed(
                Bsdf::RoughPlastic(rough_plastic(
                    MicrofacetKind::Ggx,
                    0.2,
                    1.6,
                    Rgb::new(0.6, 0.4, 0.2),
                    false,
                    true,
                )),
                tilted_frame(25.0, 90.0),
                true,
            )),
            dir(60.0, 30.0),
        ),
    ]
}

fn pplastic(
    kind: MicrofacetKind,
    alpha_u: f32,
    alpha_v: f32,
    eta: f32,
    d: Rgb,
    s: Rgb,
) -> PPlastic {
    let (dm, sm) = (d.element_sum() / 3.0, s.element_sum() / 3.0);
    PPlastic {
        distribution: Microfacet {
            kind,
            alpha_u,
            alpha_v,
            sample_visible: true,
        },
        eta,
        diffuse_reflectance: d,
        specular_reflectance: s,
        specular_weight: sm / (dm + sm),
    }
}

/// `pplastic` across distributions and roughness, one anisotropic, one with a dark
/// specular scale, each with the polar angle of a `wo`.
fn pplastic_models() -> Vec<(&'static str, PPlastic, f64)> {
    use MicrofacetKind::{Beckmann, Ggx};
    vec![
        (
            "ggx 0.06, eta 1.49",
            pplastic(Ggx, 0.06, 0.06, 1.49, Rgb::new(0.05, 0.03, 0.1), Rgb::ONE),
            30.0,
        ),
        (
            "beckmann 0.3, eta 1.9",
            pplastic(Beckmann, 0.3, 0.3, 1.9, Rgb::new(0.8, 0.6, 0.4), Rgb::ONE),
            70.0,
        ),
        (
            "ggx 0.1 x 0.4, eta 1.3",
            pplastic(Ggx, 0.1, 0.4, 1.3, Rgb::new(0.3, 0.5, 0.2), Rgb::splat(0.5)),
            50.0,
        ),
        (
            "ggx 0.2, no specular",
            pplastic(Ggx, 0.2, 0.2, 1.49, Rgb::new(0.5, 0.5, 0.9), Rgb::ZERO),
            10.0,
        ),
    ]
}

/// A phase function seen as a BSDF over the whole sphere: the BSDF's `wo` is the
/// phase function's `wi` (back along the incoming ray) and the BSDF's sampled `wi` its
/// `wo`; eval = pdf = the phase function, weight 1, nothing absorbed.
struct PhaseAsBsdf(Phase);

impl BsdfModel for PhaseAsBsdf {
    fn flags(&self, _wo: Vec3) -> BsdfFlags {
        BsdfFlags::DIFFUSE
    }
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        Rgb::splat(self.0.eval(wo, wi))
    }
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.0.eval(wo, wi)
    }
    fn sample(&self, wo: Vec3, _u1: f32, u2: [f32; 2]) -> Option<BsdfSample> {
        let s = self.0.sample(wo, u2);
        Some(BsdfSample {
            wi: s.wo,
            weight: Rgb::ONE,
            pdf: s.pdf,
            lobe: if s.wo.z >= 0.0 {
                BsdfFlags::DIFFUSE_REFLECTION
            } else {
                BsdfFlags::DIFFUSE_TRANSMISSION
            },
            eta: 1.0,
        })
    }
    fn albedo(&self, _wo: Vec3) -> Rgb {
        Rgb::ONE
    }
}

/// The media's phase functions (`isotropic`, `hg` forward and backward).
fn phase_cases() -> Vec<Case> {
    [
        ("phase isotropic", Phase::Isotropic, dir(30.0, 20.0)),
        ("phase hg 0.7", Phase::Hg { g: 0.7 }, dir(50.0, 80.0)),
        ("phase hg -0.4", Phase::Hg { g: -0.4 }, dir(120.0, 250.0)),
    ]
    .into_iter()
    .map(|(n, p, wo)| {
        let model: Box<dyn BsdfModel> = Box::new(PhaseAsBsdf(p));
        (n.to_string(), model, wo)
    })
    .collect()
}

/// `mask` over a few models: the nested lobes scaled by the opacity, plus a
/// straight-through delta lobe that the chi-square test leaves out.
fn mask(opacity: f32, nested: Bsdf) -> Mask {
    Mask {
        opacity,
        nested: Box::new(nested),
    }
}

fn mask_cases() -> Vec<Case> {
    let d = |r| OneSided::Diffuse(diffuse(r));
    vec![
        (
            "mask 0.3 over diffuse, 40 deg".into(),
            Box::new(mask(0.3, Bsdf::Diffuse(diffuse(0.8)))),
            dir(40.0, 70.0),
        ),
        (
            "mask 0.7 over twosided diffuse, back".into(),
            Box::new(mask(0.7, two_sided(d(0.8), d(0.2)))),
            dir(130.0, 250.0),
        ),
        (
            "mask 0.5 over roughconductor ggx 0.3, 55 deg".into(),
            Box::new(mask(
                0.5,
                Bsdf::RoughConductor(rough(MicrofacetKind::Ggx, 0.3, 0.3, true)),
            )),
            dir(55.0, 20.0),
        ),
    ]
}

/// The rough plastics, and one inside `twosided` seen from the back.
fn rough_plastic_cases() -> Vec<Case> {
    let mut cases: Vec<Case> = rough_plastic_models()
        .into_iter()
        .map(|(n, b, theta)| {
            let model: Box<dyn BsdfModel> = Box::new(b);
            (
                format!("roughplastic {n}, {theta} deg"),
                model,
                dir(theta, 40.0),
            )
        })
        .collect();
    let back = rough_plastic(
        MicrofacetKind::Ggx,
        0.2,
        1.6,
        Rgb::new(0.3, 0.5, 0.7),
        false,
        true,
    );
    cases.push((
        "twosided diffuse/roughplastic, back".into(),
        Box::new(two_sided(
            OneSided::Diffuse(diffuse(0.5)),
            OneSided::RoughPlastic(back),
        )),
        dir(130.0, 250.0),
    ));
    cases
}

/// Delta-only models and a `wo`.
fn delta_cases() -> Vec<DeltaCase> {
    let mut cases: Vec<DeltaCase> = Vec::new();
    for (name, eta) in [
        ("glass 1.5", 1.5f32),
        ("water 1.333", 1.333),
        ("diamond 2.419", 2.419),
        ("eta 0.7 (< 1)", 0.7),
    ] {
        for theta in [0.0, 40.0, 75.0, 150.0, 125.0] {
            // 150 and 125 deg: from inside; 125 deg is past the critical angle for
            // eta >= 1.333 (total internal reflection), not for eta 0.7.
            cases.push((
                format!("{name}, {theta} deg"),
                Box::new(glass(eta)),
                dir(theta, 77.0),
                Some(eta as f64),
            ));
        }
    }
    cases.push(("gold".into(), Box::new(gold()), dir(60.0, 10.0), None));
    cases.push(("mirror".into(), Box::new(mirror()), dir(20.0, 100.0), None));
    cases.push((
        "twosided gold, back".into(),
        Box::new(two_sided(
            OneSided::Diffuse(diffuse(0.5)),
            OneSided::Conductor(gold()),
        )),
        dir(110.0, 45.0),
        None,
    ));
    cases
}

/// Every model, for the checks that apply to all (furnace, reciprocity, weights).
fn all_models() -> Vec<(&'static str, Box<dyn BsdfModel>)> {
    let d = |r| OneSided::Diffuse(diffuse(r));
    vec![
        ("white diffuse", Box::new(diffuse(1.0))),
        ("grey diffuse", Box::new(diffuse(0.4))),
        ("glass 1.5", Box::new(glass(1.5))),
        ("glass 0.7", Box::new(glass(0.7))),
        (
            "tinted glass",
            Box::new(Dielectric {
                eta: 1.33,
                specular_reflectance: Rgb::new(1.0, 0.5, 0.2),
                specular_transmittance: Rgb::new(0.3, 0.9, 1.0),
            }),
        ),
        ("gold", Box::new(gold())),
        ("mirror", Box::new(mirror())),
        (
            "plastic",
            Box::new(Plastic::new(1.49, Rgb::new(0.8, 0.3, 0.1), Rgb::ONE, false)),
        ),
        (
            "plastic, nonlinear, eta 0.8",
            Box::new(Plastic::new(
                0.8,
                Rgb::new(0.2, 0.9, 0.5),
                Rgb::new(0.5, 0.5, 1.0),
                true,
            )),
        ),
        ("twosided diffuse", Box::new(two_sided(d(1.0), d(0.3)))),
        (
            "twosided diffuse/gold",
            Box::new(two_sided(d(0.8), OneSided::Conductor(gold()))),
        ),
        (
            "twosided mirror/white diffuse",
            Box::new(two_sided(OneSided::Conductor(mirror()), d(1.0))),
        ),
        (
            "mask 0.4 over grey diffuse",
            Box::new(mask(0.4, Bsdf::Diffuse(diffuse(0.4)))),
        ),
        (
            "mask 0.6 over glass",
            Box::new(mask(0.6, Bsdf::Dielectric(glass(1.5)))),
        ),
        (
            "mask 0.8 over twosided gold/diffuse",
            Box::new(mask(0.8, two_sided(OneSided::Conductor(gold()), d(0.5)))),
        ),
        // (Mitsuba's blend of a delta lobe with a density in its direction is biased:
        // not here; a mask's pass-through meets no density of a diffuse reflection.)
        (
            "blendbsdf 0.3 of grey diffuse and mask 0.4 over diffuse",
            Box::new(blend(
                0.3,
                Bsdf::Diffuse(diffuse(0.4)),
                Bsdf::Mask(mask(0.4, Bsdf::Diffuse(diffuse(0.9)))),
            )),
        ),
        (
            "blendbsdf 0.5 of glass and gold",
            Box::new(blend(
                0.5,
                Bsdf::Dielectric(glass(1.5)),
                Bsdf::Conductor(gold()),
            )),
        ),
        (
            "blendbsdf 1 of diffuse and twosided diffuse",
            Box::new(blend(
                1.0,
                Bsdf::Diffuse(diffuse(0.9)),
                two_sided(d(0.2), d(0.7)),
            )),
        ),
    ]
}

#[test]
fn the_family_size_is_the_number_of_tests() {
    assert_eq!(
        non_delta_cases().len()
            + delta_cases().len()
            + THIN_CASES.len()
            + LIGHT_CASES
            + ANGULAR_CASES,
        FAMILY
    );
}

// ---------------------------------------------------------------- the spherical grid

fn cell_of(w: Vec3) -> usize {
    let w = w.as_dvec3().normalize();
    let theta = w.z.clamp(-1.0, 1.0).acos();
    let phi = w.y.atan2(w.x).rem_euclid(2.0 * PI);
    let t = ((theta / PI * THETA_CELLS as f64) as usize).min(THETA_CELLS - 1);
    let p = ((phi / (2.0 * PI) * PHI_CELLS as f64) as usize).min(PHI_CELLS - 1);
    t * PHI_CELLS + p
}

/// Adaptive Simpson on [a, b] to absolute tolerance `eps`.
fn simpson(f: &mut dyn FnMut(f64) -> f64, a: f64, b: f64, eps: f64) -> f64 {
    fn rec(
        f: &mut dyn FnMut(f64) -> f64,
        (a, fa): (f64, f64),
        (m, fm): (f64, f64),
        (b, fb): (f64, f64),
        whole: f64,
        eps: f64,
        depth: u32,
    ) -> f64 {
        let (lm, rm) = (0.5 * (a + m), 0.5 * (m + b));
        let (flm, frm) = (f(lm), f(rm));
        let left = (m - a) / 6.0 * (fa + 4.0 * flm + fm);
        let right = (b - m) / 6.0 * (fm + 4.0 * frm + fb);
        let delta = left + right - whole;
        if depth == 0 || delta.abs() <= 15.0 * eps {
            return left + right + delta / 15.0;
        }
        rec(f, (a, fa), (lm, flm), (m, fm), left, eps / 2.0, depth - 1)
            + rec(f, (m, fm), (rm, frm), (b, fb), right, eps / 2.0, depth - 1)
    }
    let m = 0.5 * (a + b);
    let (fa, fm, fb) = (f(a), f(m), f(b));
    let whole = (b - a) / 6.0 * (fa + 4.0 * fm + fb);
    rec(f, (a, fa), (m, fm), (b, fb), whole, eps, 12)
}

/// The pdf integrated over every grid cell (solid angle: sin(theta) dtheta dphi).
fn cell_integrals(b: &dyn BsdfModel, wo: Vec3) -> Vec<f64> {
    pdf_cell_integrals(&|w| b.pdf(wo, w) as f64)
}

/// A solid-angle density integrated over every grid cell.
fn pdf_cell_integrals(pdf: &dyn Fn(Vec3) -> f64) -> Vec<f64> {
    let (dt, dp) = (PI / THETA_CELLS as f64, 2.0 * PI / PHI_CELLS as f64);
    let mut out = Vec::with_capacity(THETA_CELLS * PHI_CELLS);
    for t in 0..THETA_CELLS {
        for p in 0..PHI_CELLS {
            let (t0, p0) = (t as f64 * dt, p as f64 * dp);
            let mut outer = |theta: f64| {
                let mut inner = |phi: f64| {
                    let w = Vec3::new(
                        (theta.sin() * phi.cos()) as f32,
                        (theta.sin() * phi.sin()) as f32,
                        theta.cos() as f32,
                    );
                    pdf(w) * theta.sin()
                };
                simpson(&mut inner, p0, p0 + dp, 1e-8)
            };
            out.push(simpson(&mut outer, t0, t0 + dt, 1e-8));
        }
    }
    out
}

/// Chi-square p-value of `CHI2_SAMPLES` non-delta samples against the integrated pdf.
/// A sample in a cell whose expected count is zero gives p = 0 (pbrt's rule).
fn chi2_p_value(b: &dyn BsdfModel, wo: Vec3, seed: u64) -> f64 {
    let expected = cell_integrals(b, wo);
    chi2_of_samples(expected, seed, &mut |rng| {
        let (u1, u2) = (rng.next_f32(), rng.next_2d());
        b.sample(wo, u1, u2)
            .filter(|s| !s.lobe.is_delta())
            .map(|s| s.wi)
    })
}

/// Chi-square p-value of `CHI2_SAMPLES` directions drawn by `sample` (`None`: no
/// direction) against the integrated pdf per grid cell, `integrals`.
fn chi2_of_samples(
    integrals: Vec<f64>,
    seed: u64,
    sample: &mut dyn FnMut(&mut Pcg32) -> Option<Vec3>,
) -> f64 {
    let expected: Vec<f64> = integrals
        .into_iter()
        .map(|v| v * CHI2_SAMPLES as f64)
        .collect();
    let mut observed = vec![0u64; expected.len()];
    let mut rng = Pcg32::new(seed, 0xb5df);
    for _ in 0..CHI2_SAMPLES {
        if let Some(w) = sample(&mut rng) {
            observed[cell_of(w)] += 1;
        }
    }
    let mut order: Vec<usize> = (0..expected.len()).collect();
    order.sort_by(|&i, &j| expected[i].total_cmp(&expected[j]));
    let (mut stat, mut cells) = (0.0, 0usize);
    let (mut pool_e, mut pool_o) = (0.0, 0.0);
    for i in order {
        let (e, o) = (expected[i], observed[i] as f64);
        if e == 0.0 && o > 0.0 {
            return 0.0;
        }
        if e < MIN_EXPECTED {
            pool_e += e;
            pool_o += o;
            continue;
        }
        stat += (o - e) * (o - e) / e;
        cells += 1;
    }
    // The pooled cells; a remainder still below MIN_EXPECTED joins nothing (dropped
    // along with its observations, as pbrt does).
    if pool_e >= MIN_EXPECTED {
        stat += (pool_o - pool_e) * (pool_o - pool_e) / pool_e;
        cells += 1;
    }
    assert!(cells >= 2, "too few cells for a chi-square test");
    ChiSquared::new((cells - 1) as f64).unwrap().sf(stat)
}

// ---------------------------------------------------------------- (a) distributions

#[test]
fn sampled_directions_follow_the_pdf() {
    let mut ps = Vec::new();
    for (i, (name, b, wo)) in non_delta_cases().into_iter().enumerate() {
        let p = chi2_p_value(b.as_ref(), wo, 1000 + i as u64);
        assert!(p > LEVEL, "{name}: chi-square p = {p:.3e} <= {LEVEL:.1e}");
        ps.push(p);
    }
    let (lo, hi) = ps
        .iter()
        .fold((1.0f64, 0.0f64), |(a, b), &p| (a.min(p), b.max(p)));
    eprintln!(
        "chi-square p-values of {} cases in [{lo:.3}, {hi:.3}]",
        ps.len()
    );
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

/// Fresnel reflectance and refracted direction in f64, from Snell's law directly.
fn reference_fresnel(wo: Vec3, eta: f64) -> (f64, Option<[f64; 3]>) {
    let wo = wo.as_dvec3();
    let (n1, n2) = if wo.z > 0.0 { (1.0, eta) } else { (eta, 1.0) };
    let ci = wo.z.abs();
    let si = (1.0 - ci * ci).max(0.0).sqrt();
    let st = n1 / n2 * si;
    if st >= 1.0 {
        return (1.0, None);
    }
    let ct = (1.0 - st * st).sqrt();
    let rs = ((n1 * ci - n2 * ct) / (n1 * ci + n2 * ct)).powi(2);
    let rp = ((n1 * ct - n2 * ci) / (n1 * ct + n2 * ci)).powi(2);
    let scale = n1 / n2;
    let t = [-scale * wo.x, -scale * wo.y, -wo.z.signum() * ct];
    (0.5 * (rs + rp), Some(t))
}

fn close(a: Vec3, b: [f64; 3], tol: f64) -> bool {
    (0..3).all(|i| (a[i] as f64 - b[i]).abs() <= tol)
}

/// Two-sided binomial p-value of `k` successes in `n` trials with probability `p`.
fn binomial_p_value(k: u64, n: u64, p: f64) -> f64 {
    if p <= 0.0 || p >= 1.0 {
        let certain = if p <= 0.0 { 0 } else { n };
        return if k == certain { 1.0 } else { 0.0 };
    }
    let d = Binomial::new(p, n).unwrap();
    let lower = d.cdf(k);
    let upper = if k == 0 { 1.0 } else { d.sf(k - 1) };
    (2.0 * lower.min(upper)).min(1.0)
}

/// Checks the delta lobes of `b` from `wo` against Fresnel (`eta`: `None` for a
/// conductor, which always reflects); returns the binomial p-value of the choice.
fn delta_p_value(b: &dyn BsdfModel, wo: Vec3, eta: Option<f64>, seed: u64) -> f64 {
    const N: u64 = 20_000;
    let reflected = [-wo.x as f64, -wo.y as f64, wo.z as f64];
    let (r, refracted) = match eta {
        Some(e) => reference_fresnel(wo, e),
        None => (1.0, None),
    };
    let mut rng = Pcg32::new(seed, 0xde17a);
    let mut n_reflect = 0;
    for _ in 0..N {
        let s = b
            .sample(wo, rng.next_f32(), rng.next_2d())
            .expect("a delta BSDF always scatters");
        assert!(s.lobe.is_delta(), "a delta model sampled {:?}", s.lobe);
        if s.lobe == BsdfFlags::DELTA_REFLECTION {
            assert!(
                close(s.wi, reflected, 1e-6),
                "reflection {} from {wo}",
                s.wi
            );
            n_reflect += 1;
        } else {
            assert_eq!(s.lobe, BsdfFlags::DELTA_TRANSMISSION);
            let t = refracted.expect("refraction past the critical angle");
            assert!(close(s.wi, t, 1e-5), "refraction {} from {wo}", s.wi);
            let e = eta.expect("only dielectrics refract");
            let eta_it = if wo.z > 0.0 { e } else { 1.0 / e };
            assert!(
                (s.eta as f64 - eta_it).abs() < 1e-6,
                "eta {} from {wo}",
                s.eta
            );
        }
    }
    binomial_p_value(n_reflect, N, r)
}

#[test]
fn delta_lobes_are_exact_and_chosen_with_fresnel_probability() {
    let mut ps = Vec::new();
    for (i, (name, b, wo, eta)) in delta_cases().into_iter().enumerate() {
        assert!(b.flags(wo).is_delta(), "{name}");
        assert_eq!(b.eval(wo, -wo), Rgb::ZERO, "{name}");
        assert_eq!(b.pdf(wo, Vec3::new(-wo.x, -wo.y, wo.z)), 0.0, "{name}");
        let p = delta_p_value(b.as_ref(), wo, eta, 2000 + i as u64);
        assert!(p > LEVEL, "{name}: binomial p = {p:.3e} <= {LEVEL:.1e}");
        ps.push(p);
    }
    let (lo, hi) = ps
        .iter()
        .fold((1.0f64, 0.0f64), |(a, b), &p| (a.min(p), b.max(p)));
    eprintln!(
        "binomial p-values of {} delta cases in [{lo:.3}, {hi:.3}]",
        ps.len()
    );
}

/// Thin dielectric cases (eta, theta of wo in degrees), each a binomial test.
const THIN_CASES: [(f32, f64); 4] = [(1.5, 0.0), (1.5, 70.0), (1.333, 130.0), (2.419, 85.0)];

/// `thindielectric`: reflection exact, transmission straight through (-wo) with the
/// current IOR unchanged, the reflect/transmit choice with the slab reflectance
/// R' = R + T^2 R / (1 - R^2) computed here in f64 from Snell's law, and a clear pane
/// lossless.
#[test]
fn thin_dielectric_reflects_the_slab_series_and_passes_straight_through() {
    for (i, &(eta, theta)) in THIN_CASES.iter().enumerate() {
        let b = ThinDielectric {
            eta,
            specular_reflectance: Rgb::ONE,
            specular_transmittance: Rgb::ONE,
        };
        let wo = dir(theta, 33.0);
        // One interface from outside, at the pane's angle.
        let (r, _) = reference_fresnel(Vec3::new(wo.x, wo.y, wo.z.abs()), eta as f64);
        let t = 1.0 - r;
        let r_slab = r + t * t * r / (1.0 - r * r);
        const N: u64 = 20_000;
        let mut rng = Pcg32::new(40 + i as u64, 0x7417);
        let mut n_reflect = 0;
        for _ in 0..N {
            let s = b.sample(wo, rng.next_f32(), rng.next_2d()).unwrap();
            assert_eq!(s.eta, 1.0);
            assert_eq!(s.weight, Rgb::ONE);
            if s.lobe == BsdfFlags::DELTA_REFLECTION {
                assert!(close(s.wi, [-wo.x as f64, -wo.y as f64, wo.z as f64], 1e-6));
                n_reflect += 1;
            } else {
                assert_eq!(s.lobe, BsdfFlags::DELTA_TRANSMISSION);
                assert_eq!(s.wi, -wo);
            }
        }
        let p = binomial_p_value(n_reflect, N, r_slab);
        assert!(
            p > LEVEL,
            "eta {eta} at {theta} deg: p = {p:.3e}, R' = {r_slab}"
        );
        assert!((b.albedo(wo) - Rgb::ONE).abs().max_element() < 1e-6);
    }
    // The series matters: a pane reflecting only one interface's R is rejected.
    let wo = dir(70.0, 0.0);
    let (r, _) = reference_fresnel(wo, 1.5);
    let b = ThinDielectric {
        eta: 1.5,
        specular_reflectance: Rgb::ONE,
        specular_transmittance: Rgb::ONE,
    };
    let mut rng = Pcg32::new(1, 2);
    let k = (0..20_000)
        .filter(|_| {
            b.sample(wo, rng.next_f32(), rng.next_2d()).unwrap().lobe == BsdfFlags::DELTA_REFLECTION
        })
        .count() as u64;
    assert!(
        binomial_p_value(k, 20_000, r) < LEVEL,
        "R' indistinguishable from R"
    );
}

/// `plastic` mixes a delta and a diffuse lobe: its pdf (the diffuse lobe's) integrates
/// to the fraction of samples that take the diffuse lobe, and those samples carry
/// weight eval / pdf (checked with every model above).
#[test]
fn plastic_pdf_integrates_to_its_diffuse_share() {
    let b = Plastic::new(1.49, Rgb::new(0.8, 0.3, 0.1), Rgb::ONE, false);
    for (i, theta) in [10.0, 60.0, 85.0].into_iter().enumerate() {
        let wo = dir(theta, 15.0);
        let total: f64 = cell_integrals(&b, wo).iter().sum();
        let n = 200_000;
        let mut rng = Pcg32::new(90, i as u64);
        let diffuse = (0..n)
            .filter(|_| {
                b.sample(wo, rng.next_f32(), rng.next_2d())
                    .is_some_and(|s| s.lobe == BsdfFlags::DIFFUSE_REFLECTION)
            })
            .count();
        let f = diffuse as f64 / n as f64;
        let tol = PDF_INTEGRAL_TOL + 5.0 * (f * (1.0 - f) / n as f64).sqrt();
        assert!((total - f).abs() < tol, "{theta} deg: {total} vs {f}");
        assert!(
            f > 0.05 && f < 0.999,
            "{theta} deg: both lobes are sampled ({f})"
        );
    }
}

#[test]
fn binomial_test_rejects_a_wrong_fresnel_choice() {
    // At 75 deg R = 0.15 while R0 = 0.04.
    let p = delta_p_value(&FresnelAtNormal(glass(1.5)), dir(75.0, 0.0), Some(1.5), 3);
    assert!(p < LEVEL, "reflection with R0 at 75 deg passed: p = {p}");
}

// ---------------------------------------------------------------- (b) weights, (c) pdf

/// Largest relative mismatch of weight vs eval / pdf and of sample pdf vs pdf over
/// `n` samples of `b` from `wo` (non-delta samples only).
fn weight_mismatch(b: &dyn BsdfModel, wo: Vec3, n: usize, seed: u64) -> f32 {
    let mut rng = Pcg32::new(seed, 0x3e16);
    let mut worst = 0.0f32;
    for _ in 0..n {
        let Some(s) = b.sample(wo, rng.next_f32(), rng.next_2d()) else {
            continue;
        };
        if s.lobe.is_delta() {
            continue;
        }
        let pdf = b.pdf(wo, s.wi);
        let want = b.eval(wo, s.wi) / pdf;
        let rel = |a: f32, b: f32| (a - b).abs() / b.abs().max(1e-6);
        worst = worst.max(rel(s.pdf, pdf));
        for c in 0..3 {
            worst = worst.max(rel(s.weight[c], want[c]));
        }
    }
    worst
}

#[test]
fn sample_weight_is_eval_over_pdf() {
    let mut rng = Pcg32::new(11, 1);
    for (name, b) in all_models() {
        for i in 0..32 {
            let wo = tstat::math::sampling::uniform_sphere(rng.next_2d());
            let m = weight_mismatch(b.as_ref(), wo, 256, i);
            assert!(m < 1e-5, "{name} from {wo}: relative mismatch {m}");
        }
    }
    for (name, b) in rough_models() {
        for i in 0..32 {
            let mut wo = tstat::math::sampling::uniform_sphere(rng.next_2d());
            wo.z = wo.z.abs();
            let m = weight_mismatch(&b, wo, 256, 50 + i);
            assert!(m < 1e-4, "{name} from {wo}: relative mismatch {m}");
        }
    }
    for (name, b, _) in rough_glass_models() {
        for i in 0..32 {
            // Both sides: a rough dielectric scatters from either.
            let wo = tstat::math::sampling::uniform_sphere(rng.next_2d());
            let m = weight_mismatch(&b, wo, 256, 90 + i);
            assert!(m < 1e-4, "{name} from {wo}: relative mismatch {m}");
        }
    }
    let m = weight_mismatch(&PdfOffByTwo(diffuse(0.5)), dir(10.0, 0.0), 256, 0);
    assert!(m > 0.4, "pdf off by two passed the weight check: {m}");
}

/// Tolerance on the integral of the pdf: each of the 512 cells is integrated to an
/// absolute 1e-8 (Simpson's error estimate), so quadrature contributes < 1e-5; the f32
/// pdf and direction carry relative errors ~1e-7. 1e-4 leaves room for the kink of a
/// one-sided lobe at the horizon, which lies on a cell edge, and still rejects any pdf
/// wrong by more than 0.01 %.
const PDF_INTEGRAL_TOL: f64 = 1e-4;

#[test]
fn pdf_integrates_to_one() {
    let mut worst = 0.0f64;
    for (i, (name, b, wo)) in non_delta_cases().into_iter().enumerate() {
        let total: f64 = cell_integrals(b.as_ref(), wo).iter().sum();
        // The pdf integrates to the probability that `sample` returns a direction
        // through a non-delta lobe: 1, except for microfacet models, whose reflections
        // about a sampled normal can point below the horizon (those samples are
        // dropped, as in Mitsuba), and models that also have a delta lobe (`mask`).
        let n = 200_000;
        let mut rng = Pcg32::new(77, i as u64);
        let kept = (0..n)
            .filter(|_| {
                b.sample(wo, rng.next_f32(), rng.next_2d())
                    .is_some_and(|s| !s.lobe.is_delta())
            })
            .count();
        let f = kept as f64 / n as f64;
        let tol = PDF_INTEGRAL_TOL + 5.0 * (f * (1.0 - f) / n as f64).sqrt();
        assert!((total - f).abs() < tol, "{name}: {total} vs kept {f}");
        worst = worst.max((total - f).abs());
    }
    eprintln!("largest |integral of pdf - fraction of samples kept| = {worst:.2e}");
    // The back of a one-sided model: no density and no samples.
    let back = dir(120.0, 0.0);
    let total: f64 = cell_integrals(&diffuse(0.5), back).iter().sum();
    assert_eq!(total, 0.0);
    assert!(diffuse(0.5).sample(back, 0.5, [0.5; 2]).is_none());
    let total: f64 = cell_integrals(&PdfOffByTwo(diffuse(0.5)), dir(20.0, 0.0))
        .iter()
        .sum();
    assert!(
        (total - 1.0).abs() > PDF_INTEGRAL_TOL,
        "pdf off by two integrated to {total}"
    );
}

// ---------------------------------------------------------------- (d) furnace

/// Mean energy weight (transmission times eta^2, undoing the radiance compression)
/// and its standard error, per channel.
fn furnace(b: &dyn BsdfModel, wo: Vec3, n: usize, seed: u64) -> (Rgb, Rgb) {
    let mut rng = Pcg32::new(seed, 0xf0);
    let (mut sum, mut sum2) = (glam::DVec3::ZERO, glam::DVec3::ZERO);
    for _ in 0..n {
        if let Some(s) = b.sample(wo, rng.next_f32(), rng.next_2d()) {
            let e = if s.lobe.intersects(BsdfFlags::TRANSMISSION) {
                s.weight * (s.eta * s.eta)
            } else {
                s.weight
            };
            let e = e.as_dvec3();
            sum += e;
            sum2 += e * e;
        }
    }
    let mean = sum / n as f64;
    let var = (sum2 / n as f64 - mean * mean).max(glam::DVec3::ZERO);
    (mean.as_vec3(), (var / n as f64).sqrt().as_vec3())
}

/// Five standard errors (two-sided normal p ~ 6e-7, far below `LEVEL`), plus f32
/// rounding.
fn within(a: Rgb, b: Rgb, se: Rgb) -> bool {
    (0..3).all(|c| (a[c] - b[c]).abs() <= 5.0 * se[c] + 1e-5)
}

#[test]
fn white_furnace() {
    let mut rng = Pcg32::new(5, 5);
    for (name, b) in all_models() {
        for i in 0..48 {
            let wo = tstat::math::sampling::uniform_sphere(rng.next_2d());
            let (mean, se) = furnace(b.as_ref(), wo, 2048, i);
            let albedo = b.albedo(wo);
            assert!(
                within(mean, albedo, se),
                "{name} from {wo}: mean {mean}, albedo {albedo}"
            );
            assert!(
                albedo.max_element() <= 1.0 + 1e-6,
                "{name} from {wo}: albedo {albedo}"
            );
        }
    }
    // Lossless: white diffuse from the front, clear glass from anywhere, a perfect
    // mirror, a white twosided diffuse from either side.
    let lossless: Vec<(&str, Box<dyn BsdfModel>, bool)> = vec![
        ("white diffuse", Box::new(diffuse(1.0)), true),
        ("glass 1.5", Box::new(glass(1.5)), false),
        ("glass 0.7", Box::new(glass(0.7)), false),
        ("mirror", Box::new(mirror()), true),
        (
            "white twosided",
            Box::new(two_sided(
                OneSided::Diffuse(diffuse(1.0)),
                OneSided::Diffuse(diffuse(1.0)),
            )),
            false,
        ),
        (
            "mask 0.3 over white diffuse",
            Box::new(mask(0.3, Bsdf::Diffuse(diffuse(1.0)))),
            true,
        ),
    ];
    for (name, b, front_only) in lossless {
        for i in 0..48 {
            let mut wo = tstat::math::sampling::uniform_sphere(rng.next_2d());
            if front_only {
                wo.z = wo.z.abs();
            }
            let (mean, se) = furnace(b.as_ref(), wo, 2048, 100 + i);
            assert!(within(mean, Rgb::ONE, se), "{name} from {wo}: {mean}");
            assert!(within(b.albedo(wo), Rgb::ONE, Rgb::ZERO), "{name}: albedo");
        }
    }
    let (mean, _) = furnace(&NoRadianceScaling(glass(1.5)), dir(10.0, 0.0), 2048, 0);
    assert!(
        mean.max_element() > 1.5,
        "glass without eta^2 passed the furnace: {mean}"
    );
}

// ---------------------------------------------------------------- (e) reciprocity

/// Largest relative asymmetry of f = eval / |cos wi| over same-side direction pairs.
fn asymmetry(b: &dyn BsdfModel, seed: u64) -> f32 {
    let mut rng = Pcg32::new(seed, 0x5e);
    let mut worst = 0.0f32;
    for _ in 0..2000 {
        let wo = tstat::math::sampling::uniform_sphere(rng.next_2d());
        let mut wi = cosine_hemisphere(rng.next_2d());
        wi.z *= wo.z.signum();
        let f = b.eval(wo, wi) / wi.z.abs();
        let g = b.eval(wi, wo) / wo.z.abs();
        for c in 0..3 {
            let scale = f[c].abs().max(g[c].abs());
            if scale > 0.0 {
                worst = worst.max((f[c] - g[c]).abs() / scale);
            }
        }
    }
    worst
}

#[test]
fn reflection_is_reciprocal() {
    for (i, (name, b)) in all_models().into_iter().enumerate() {
        let a = asymmetry(b.as_ref(), i as u64);
        assert!(
            a < 1e-5,
            "{name}: eval(wo, wi) != eval(wi, wo), relative {a}"
        );
    }
    for (i, (name, b)) in rough_models().into_iter().enumerate() {
        let a = asymmetry(&b, 100 + i as u64);
        assert!(
            a < 1e-4,
            "{name}: eval(wo, wi) != eval(wi, wo), relative {a}"
        );
    }
    for (i, (name, b, _)) in rough_glass_models().into_iter().enumerate() {
        let a = asymmetry(&b, 200 + i as u64);
        assert!(
            a < 1e-4,
            "{name}: eval(wo, wi) != eval(wi, wo), relative {a}"
        );
    }
    let a = asymmetry(&NonReciprocal(diffuse(0.5)), 0);
    assert!(a > 0.1, "a non-reciprocal model passed: {a}");
}

/// Largest relative violation of the reciprocity of refraction in radiance transport,
/// f(wo, wi) / n(wo)^2 = f(wi, wo) / n(wi)^2 (Veach 1997, 5.2; n the IOR on a
/// direction's side: 1 above, `eta` below), over direction pairs on opposite sides,
/// and the number of values compared. Pairs whose microfacet (Walter's generalized
/// half vector, here in f64) meets a direction within 6 deg of grazing are skipped:
/// there one side's Fresnel transmittance is that of the other near the critical
/// angle, 1 - eta^2 sin^2 in f32 cancels, and both evaluations lose about a per cent.
fn refraction_asymmetry(b: &dyn BsdfModel, eta: f32, seed: u64) -> (f32, usize) {
    let n = |w: Vec3| if w.z > 0.0 { 1.0 } else { eta as f64 };
    let mut rng = Pcg32::new(seed, 0x7e);
    let (mut worst, mut compared) = (0.0f32, 0);
    for _ in 0..4000 {
        let wo = tstat::math::sampling::uniform_sphere(rng.next_2d());
        let mut wi = cosine_hemisphere(rng.next_2d());
        wi.z *= -wo.z.signum();
        let h = (wo.as_dvec3() * n(wo) + wi.as_dvec3() * n(wi)).normalize();
        if h.dot(wo.as_dvec3()).abs().min(h.dot(wi.as_dvec3()).abs()) < 0.1 {
            continue;
        }
        let f = b.eval(wo, wi) / (wi.z.abs() * (n(wo) * n(wo)) as f32);
        let g = b.eval(wi, wo) / (wo.z.abs() * (n(wi) * n(wi)) as f32);
        for c in 0..3 {
            let scale = f[c].abs().max(g[c].abs());
            // Far in a lobe's tail D is a few ulps above f32's smallest normal.
            if scale > 1e-20 {
                worst = worst.max((f[c] - g[c]).abs() / scale);
                compared += 1;
            }
        }
    }
    (worst, compared)
}

/// Rough glass refracts reciprocally up to the IORs squared (radiance is compressed by
/// n^2 entering a denser medium); Walter's f without Mitsuba's `eta_ti^2` radiance
/// scale is rejected.
#[test]
fn refraction_is_reciprocal_up_to_the_ior_squared() {
    for (i, (name, b, _)) in rough_glass_models().into_iter().enumerate() {
        let (a, compared) = refraction_asymmetry(&b, b.eta, 300 + i as u64);
        assert!(compared > 300, "{name}: only {compared} values to compare");
        assert!(
            a < 2e-3,
            "{name}: f(wo, wi) / n(wo)^2 != f(wi, wo) / n(wi)^2, relative {a}"
        );
    }
    let b = RoughGlassWithoutRadianceScale(rough_glass(MicrofacetKind::Ggx, 0.3, 1.5, true));
    let (a, _) = refraction_asymmetry(&b, 1.5, 0);
    assert!(
        a > 0.5,
        "rough glass without the radiance scale passed: {a}"
    );
}

/// The reflected energy from `wo` by quadrature of `eval` over the upper hemisphere
/// (midpoint rule in f64 on a 600 x 1200 (theta, phi) grid: cells of 0.15 deg resolve
/// lobes of roughness >= 0.1), independent of the sampler.
fn reflected_energy(b: &dyn BsdfModel, wo: Vec3) -> glam::DVec3 {
    let (nt, np) = (600usize, 1200usize);
    let (dt, dp) = (0.5 * PI / nt as f64, 2.0 * PI / np as f64);
    let mut sum = glam::DVec3::ZERO;
    for i in 0..nt {
        let t = (i as f64 + 0.5) * dt;
        let w = t.sin() * dt * dp;
        for j in 0..np {
            let p = (j as f64 + 0.5) * dp;
            let wi = Vec3::new(
                (t.sin() * p.cos()) as f32,
                (t.sin() * p.sin()) as f32,
                t.cos() as f32,
            );
            sum += b.eval(wo, wi).as_dvec3() * w;
        }
    }
    sum
}

/// Rough conductors: the mean sample weight equals the reflected energy integrated from
/// `eval` (so sampling, pdf and eval agree in absolute terms, not only in shape: a
/// missing 4 or a cosine too many fails here), which never exceeds 1, and a perfect
/// conductor of roughness 0.1 loses only what shadowing and masking block (a few per
/// cent; 3.1 % for GGX at 60 deg, computed independently).
#[test]
fn rough_conductors_conserve_energy() {
    let perfect = |kind| RoughConductor {
        eta: Rgb::ZERO,
        k: Rgb::ONE,
        ..rough(kind, 0.1, 0.1, true)
    };
    let mut models: Vec<(String, RoughConductor)> = rough_models()
        .into_iter()
        .map(|(n, b)| (n.to_string(), b))
        .collect();
    models.push((
        "perfect beckmann 0.1".into(),
        perfect(MicrofacetKind::Beckmann),
    ));
    models.push(("perfect ggx 0.1".into(), perfect(MicrofacetKind::Ggx)));
    for (i, (name, b)) in models.iter().enumerate() {
        for theta in [0.0, 45.0, 75.0] {
            let wo = dir(theta, 20.0 + 30.0 * i as f64);
            let quad = reflected_energy(b, wo);
            let (mean, se) = furnace(b, wo, 20_000, 300 + i as u64);
            for c in 0..3 {
                let (q, m, e) = (quad[c], mean[c] as f64, se[c] as f64);
                assert!(
                    (q - m).abs() <= 5.0 * e + 2e-3 * q,
                    "{name} at {theta} deg: quadrature {q}, sampled {m} +- {e}"
                );
                assert!(q <= 1.0 + 1e-3, "{name} at {theta} deg: reflects {q}");
            }
            if name.starts_with("perfect") && theta < 60.0 {
                assert!(quad.min_element() > 0.95, "{name} at {theta} deg: {quad}");
            }
        }
    }
}

/// The energy leaving a rough glass from `wo` by quadrature of `eval` over the whole
/// sphere (midpoint rule in f64 on a 1200 x 1200 (theta, phi) grid, cells of 0.15 deg;
/// a transmission lobe is narrower than the reflection one by about (eta - 1) / eta, a
/// few degrees at roughness 0.1), transmitted values times `eta_it^2` (energy, not
/// radiance), independent of the sampler.
fn scattered_energy(b: &dyn BsdfModel, eta: f32, wo: Vec3) -> glam::DVec3 {
    let eta_it = if wo.z > 0.0 { eta } else { 1.0 / eta } as f64;
    let (nt, np) = (1200usize, 1200usize);
    let (dt, dp) = (PI / nt as f64, 2.0 * PI / np as f64);
    let mut sum = glam::DVec3::ZERO;
    for i in 0..nt {
        let t = (i as f64 + 0.5) * dt;
        let mut w = t.sin() * dt * dp;
        if (t.cos() > 0.0) != (wo.z > 0.0) {
            w *= eta_it * eta_it;
        }
        for j in 0..np {
            let p = (j as f64 + 0.5) * dp;
            let wi = Vec3::new(
                (t.sin() * p.cos()) as f32,
                (t.sin() * p.sin()) as f32,
                t.cos() as f32,
            );
            sum += b.eval(wo, wi).as_dvec3() * w;
        }
    }
    sum
}

/// Rough dielectrics: the mean sample energy (transmitted weights times eta^2, as the
/// furnace counts the smooth glass) equals the energy integrated from `eval` over the
/// sphere (so sampling, pdf, eval and the Jacobians of both lobes agree in absolute
/// terms), never exceeds `albedo(wo)` (1 for clear glass: shadowing and masking only
/// lose energy), and a glass of roughness 0.1 seen within 45 deg of its normal loses
/// little (what Smith's G blocks). Walter's f without the radiance scale creates
/// energy entering the glass, and is rejected.
#[test]
fn rough_dielectrics_conserve_energy() {
    let mut models: Vec<(String, RoughDielectric)> = rough_glass_models()
        .into_iter()
        .map(|(n, b, _)| (n, b))
        .collect();
    models.push((
        "tinted ggx 0.2".into(),
        RoughDielectric {
            specular_reflectance: Rgb::new(1.0, 0.5, 0.2),
            specular_transmittance: Rgb::new(0.3, 0.9, 1.0),
            ..rough_glass(MicrofacetKind::Ggx, 0.2, 1.33, true)
        },
    ));
    let mut lowest_smooth = f64::INFINITY;
    for (i, (name, b)) in models.iter().enumerate() {
        for theta in [0.0, 45.0, 80.0, 135.0, 170.0] {
            let wo = dir(theta, 20.0 + 30.0 * i as f64);
            let quad = scattered_energy(b, b.eta, wo);
            let (mean, se) = furnace(b, wo, 20_000, 500 + i as u64);
            if b.specular_reflectance == Rgb::ONE && b.specular_transmittance == Rgb::ONE {
                assert!(
                    (b.albedo(wo) - Rgb::ONE).abs().max_element() < 1e-6,
                    "{name}"
                );
            }
            for c in 0..3 {
                let (q, m, e) = (quad[c], mean[c] as f64, se[c] as f64);
                assert!(
                    (q - m).abs() <= 5.0 * e + 2e-3 * q,
                    "{name} at {theta} deg: quadrature {q}, sampled {m} +- {e}"
                );
                // Microfacets reflect and refract in other proportions than the macro
                // surface, so a tinted glass may exceed its albedo in one channel; it
                // never exceeds its larger tint (1 for clear glass, its albedo).
                let tint = b.specular_reflectance[c].max(b.specular_transmittance[c]) as f64;
                assert!(
                    q <= tint + 1e-3,
                    "{name} at {theta} deg: scatters {q} > {tint}"
                );
            }
            if b.distribution.alpha_u == 0.1 && wo.z.abs() > 0.7 {
                lowest_smooth = lowest_smooth.min(quad.min_element());
                assert!(quad.min_element() > 0.97, "{name} at {theta} deg: {quad}");
            }
        }
    }
    eprintln!("roughness 0.1 within 45 deg of the normal: energy >= {lowest_smooth:.4}");
    let broken = RoughGlassWithoutRadianceScale(rough_glass(MicrofacetKind::Ggx, 0.3, 1.5, true));
    let (mean, _) = furnace(&broken, dir(10.0, 0.0), 20_000, 0);
    assert!(
        mean.max_element() > 1.5,
        "rough glass without the radiance scale conserved energy: {mean}"
    );
}

/// Rough glass samples: a reflection stays on `wo`'s side and crosses no IOR
/// (`eta` 1), a refraction crosses to the other side and reports `eta_it` (the IOR of
/// its side over `wo`'s, what the integrator multiplies into the current IOR, and
/// what `eta(wo, wi)` gives next-event estimation for that direction), and both lobes
/// are sampled.
#[test]
fn rough_glass_samples_report_the_ior_they_cross() {
    for (i, (name, b, _)) in rough_glass_models().into_iter().enumerate() {
        let mut rng = Pcg32::new(600 + i as u64, 3);
        for theta in [10.0, 60.0, 89.0, 120.0, 175.0] {
            let wo = dir(theta, 33.0);
            let eta_it = if wo.z > 0.0 { b.eta } else { 1.0 / b.eta };
            let (mut reflected, mut refracted) = (0, 0);
            for _ in 0..4000 {
                let Some(s) = b.sample(wo, rng.next_f32(), rng.next_2d()) else {
                    continue;
                };
                assert!((s.wi.length() - 1.0).abs() < 1e-4, "{name}: {}", s.wi);
                if s.lobe == BsdfFlags::GLOSSY_REFLECTION {
                    assert!(s.wi.z * wo.z > 0.0 && s.eta == 1.0, "{name} from {wo}");
                    reflected += 1;
                } else {
                    assert_eq!(s.lobe, BsdfFlags::GLOSSY_TRANSMISSION, "{name}");
                    assert!(s.wi.z * wo.z < 0.0 && s.eta == eta_it, "{name} from {wo}");
                    // What next-event estimation uses for a light in that direction.
                    assert_eq!(b.eta(wo, s.wi), s.eta, "{name} from {wo}");
                    refracted += 1;
                }
            }
            assert!(reflected > 0, "{name} at {theta} deg never reflects");
            // Total internal reflection may leave (almost) nothing to refract from inside.
            if wo.z > 0.0 && b.eta > 1.0 {
                assert!(
                    refracted > 100,
                    "{name} at {theta} deg: {refracted} refractions"
                );
            }
        }
    }
}

// ---------------------------------------------------------------- roughplastic

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

/// The rough plastics, with more parameters than the chi-square cases (eta < 1 and
/// coloured specular reflectance).
fn rough_plastic_all() -> Vec<(String, RoughPlastic)> {
    let mut models: Vec<(String, RoughPlastic)> = rough_plastic_models()
        .into_iter()
        .map(|(n, b, _)| (n.to_string(), b))
        .collect();
    let distribution = Microfacet {
        kind: MicrofacetKind::Ggx,
        alpha_u: 0.3,
        alpha_v: 0.3,
        sample_visible: true,
    };
    models.push((
        "ggx 0.3, eta 0.8, tinted specular".into(),
        RoughPlastic::new(
            distribution,
            0.8,
            Rgb::new(0.2, 0.9, 0.5),
            Rgb::new(0.5, 0.5, 1.0),
            true,
        ),
    ));
    models.push((
        "beckmann 0.2, eta 1.6, black base".into(),
        RoughPlastic::new(
            Microfacet {
                kind: MicrofacetKind::Beckmann,
                alpha_u: 0.2,
                alpha_v: 0.2,
                ..distribution
            },
            1.6,
            Rgb::ZERO,
            Rgb::ONE,
            false,
        ),
    ));
    models
}

/// Weights, furnace and reciprocity of the rough plastics. The furnace compares the
/// mean sample weight with `albedo(wo)` within 5 standard errors plus 2e-3, the
/// accuracy of its tabulated specular energy (linear interpolation near grazing).
/// The model is reciprocal: both transmittance factors of its diffuse term come from
/// the same table, and the specular term is symmetric (f32 rounding only).
#[test]
fn rough_plastic_weights_furnace_and_reciprocity() {
    let mut rng = Pcg32::new(17, 3);
    let mut worst_furnace = 0.0f32;
    for (i, (name, b)) in rough_plastic_all().iter().enumerate() {
        for j in 0..32 {
            let mut wo = tstat::math::sampling::uniform_sphere(rng.next_2d());
            wo.z = wo.z.abs();
            let m = weight_mismatch(b, wo, 256, 600 + j);
            assert!(m < 1e-4, "{name} from {wo}: relative mismatch {m}");
            let (mean, se) = furnace(b, wo, 4096, 700 + j);
            let albedo = b.albedo(wo);
            for c in 0..3 {
                let dev = (mean[c] - albedo[c]).abs();
                assert!(
                    dev <= 5.0 * se[c] + 2e-3,
                    "{name} from {wo}: mean {mean} +- {se}, albedo {albedo}"
                );
                worst_furnace = worst_furnace.max(dev / (se[c] + 1e-6));
            }
            assert!(albedo.max_element() <= 1.0, "{name}: albedo {albedo}");
        }
        let a = asymmetry(b, 800 + i as u64);
        assert!(
            a < 1e-4,
            "{name}: eval(wo, wi) != eval(wi, wo), relative {a}"
        );
        // Seen from the back: black, no samples.
        let back = dir(120.0, 0.0);
        assert!(b.sample(back, 0.5, [0.5; 2]).is_none());
        assert_eq!(b.albedo(back), Rgb::ZERO);
    }
    eprintln!("roughplastic furnace: largest |mean - albedo| = {worst_furnace:.2} standard errors");
}

/// Energy: the mean sample weight equals the reflected energy integrated from `eval`
/// (independently of the sampler and of the pdf) and `albedo(wo)`, and a white base
/// under a coating of eta > 1 reflects at most what arrives. A coating that forgets the
/// eta^-2 of the light leaving it (the same model as a base d eta^2, without
/// `nonlinear`) creates energy and is rejected.
#[test]
fn rough_plastic_conserves_energy() {
    let mut models = rough_plastic_all();
    for (kind, alpha, eta) in [
        (MicrofacetKind::Beckmann, 0.1, 1.49),
        (MicrofacetKind::Ggx, 0.1, 1.9),
        (MicrofacetKind::Ggx, 0.4, 1.2),
    ] {
        models.push((
            format!("white {kind:?} {alpha}, eta {eta}"),
            rough_plastic(kind, alpha, eta, Rgb::ONE, false, true),
        ));
    }
    let mut report = Vec::new();
    for (i, (name, b)) in models.iter().enumerate() {
        for theta in [0.0, 45.0, 80.0] {
            let wo = dir(theta, 20.0 + 30.0 * i as f64);
            let quad = reflected_energy(b, wo);
            let (mean, se) = furnace(b, wo, 20_000, 900 + i as u64);
            let albedo = b.albedo(wo);
            for c in 0..3 {
                let (q, m, e, a) = (quad[c], mean[c] as f64, se[c] as f64, albedo[c] as f64);
                assert!(
                    (q - m).abs() <= 5.0 * e + 2e-3 * q,
                    "{name} at {theta} deg: quadrature {q}, sampled {m} +- {e}"
                );
                assert!(
                    (q - a).abs() <= 2e-3,
                    "{name} at {theta} deg: quadrature {q}, albedo {a}"
                );
                assert!(q <= 1.0 + 1e-3, "{name} at {theta} deg: reflects {q}");
            }
            if name.starts_with("white") {
                report.push(format!("{name} at {theta} deg: {:.4}", quad[0]));
            }
        }
    }
    eprintln!("white rough plastics reflect: {}", report.join("; "));
    let eta: f32 = 1.49;
    let forgot = rough_plastic(
        MicrofacetKind::Beckmann,
        0.1,
        eta,
        Rgb::splat(eta * eta),
        false,
        true,
    );
    let q = reflected_energy(&forgot, dir(20.0, 0.0));
    assert!(q.min_element() > 1.1, "no eta^-2 passed: reflects {q}");
}

#[test]
fn chi_square_rejects_a_wrong_lobe_choice() {
    // At 70 deg a dark base makes both lobes likely.
    let (_, b, _) = rough_plastic_models().swap_remove(4);
    let p = chi2_p_value(&SkewedLobeChoice(b), dir(70.0, 0.0), 5);
    assert!(p < LEVEL, "a skewed lobe choice passed: p = {p}");
}

// ---------------------------------------------------------------- emitters

/// Light cases in the family: per area emitter, the area-uniformity chi-square test;
/// the envmap's and the constant emitter's direction chi-square tests.
const LIGHT_CASES: usize = AREA_LIGHT_CASES + ENVIRONMENT_CASES;
const AREA_LIGHT_CASES: usize = 5;
const ENVIRONMENT_CASES: usize = 2;

const LIGHT_SCENE: &str = r#"<scene version="3.0.0">
    <integrator type="transient_path"><integer name="max_depth" value="4"/></integrator>
    <sensor type="perspective">
        <float name="fov" value="40"/>
        <transform name="to_world"><lookat origin="0, 0, 3" target="0, 0, 0" up="0, 1, 0"/></transform>
        <film type="transient_hdr_film">
            <integer name="width" value="8"/><integer name="height" value="8"/>
            <integer name="temporal_bins" value="4"/>
            <float name="start_opl" value="0"/><float name="bin_width_opl" value="1"/>
        </film>
    </sensor>
    <shape type="rectangle">
        <transform name="to_world">
            <scale x="0.5" y="0.3" z="1"/><rotate x="1" angle="90"/><translate x="0" y="0.9" z="0"/>
        </transform>
        <emitter type="area"><rgb name="radiance" value="1"/></emitter>
    </shape>
    <shape type="sphere">
        <point name="center" x="0.6" y="0" z="-0.6"/><float name="radius" value="0.2"/>
        <emitter type="area"><rgb name="radiance" value="2"/></emitter>
    </shape>
    <shape type="cube">
        <transform name="to_world">
            <scale x="0.1" y="0.2" z="0.3"/><rotate y="1" angle="30"/><translate x="-0.6" y="0" z="-0.6"/>
        </transform>
        <emitter type="area"><rgb name="radiance" value="3"/></emitter>
    </shape>
    <shape type="disk">
        <transform name="to_world">
            <scale x="0.3" y="0.15"/><rotate z="1" angle="25"/><rotate y="1" angle="20"/><translate z="-1.2"/>
        </transform>
        <emitter type="area"><rgb name="radiance" value="4"/></emitter>
    </shape>
    <shape type="cylinder">
        <point name="p0" x="-0.3" y="-0.9" z="-0.3"/><point name="p1" x="0.3" y="-0.85" z="-0.35"/>
        <float name="radius" value="0.1"/>
        <transform name="to_world"><rotate y="1" angle="10"/></transform>
        <emitter type="area"><rgb name="radiance" value="5"/></emitter>
    </shape>
    <emitter type="point"><point name="position" x="0" y="0.5" z="0.5"/><rgb name="intensity" value="1"/></emitter>
    <shape type="rectangle">
        <transform name="to_world">
            <scale x="0.4" y="0.4" z="1"/><rotate x="1" angle="-90"/><translate x="0" y="-0.9" z="0"/>
        </transform>
        <emitter type="angulararea">
            <rgb name="radiance" value="4"/>
            <float name="cutoff_angle" value="60"/><float name="beam_width" value="30"/>
        </emitter>
    </shape>
    <emitter type="projector">
        <float name="fov" value="120"/>
        <transform name="to_world"><lookat origin="0, 0.2, 2" target="0, 0, 0" up="0, 1, 0"/></transform>
    </emitter>
</scene>"#;

fn light_scene() -> tstat::scene::Scene {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("lights.xml");
    std::fs::write(&path, LIGHT_SCENE).unwrap();
    tstat::scene::Scene::load(&path, &Default::default()).unwrap()
}

#[test]
fn light_sample_pdf_matches_the_pdf_mis_uses_on_a_hit() {
    let scene = light_scene();
    let select_pdf = 1.0 / scene.emitters.len() as f32;
    let refs = [
        Vec3::new(0.0, -0.5, 0.0),
        Vec3::new(0.2, -0.3, 0.4),
        Vec3::new(-0.1, 0.2, 0.3),
    ];
    let mut rng = Pcg32::new(21, 0);
    let (mut matched, mut area_lights, mut points) = (0, 0, 0);
    for emitter in &scene.emitters {
        for x in refs {
            let mut hits = 0;
            for _ in 0..2000 {
                let Some(ls) =
                    emitter.sample(&scene.shapes, x, select_pdf, rng.next_f32(), rng.next_2d())
                else {
                    continue;
                };
                match emitter {
                    Emitter::Point { .. } | Emitter::Projector(_) | Emitter::TexturedSpot(_) => {
                        assert!(ls.delta && ls.pdf == select_pdf);
                        assert_eq!(emitter.pdf_area_hit(select_pdf, ls.dist, 1.0), 0.0);
                        points += 1;
                    }
                    Emitter::Envmap { .. }
                    | Emitter::Constant { .. }
                    | Emitter::Directional { .. }
                    | Emitter::TexturedArea(_) => {
                        unreachable!("the light scene has no infinitely distant or textured lights (see tests/textured.rs)")
                    }
                    Emitter::Area { shape, .. } | Emitter::AngularArea { shape, .. } => {
                        assert!(!ls.delta);
                        let Some(hit) =
                            scene
                                .accel
                                .intersect(&scene.shapes, x, ls.wi, f32::INFINITY)
                        else {
                            continue;
                        };
                        if hit.shape != *shape || (hit.t - ls.dist).abs() > 1e-3 * ls.dist {
                            continue; // another light is in the way, or the far side
                        }
                        let cos_l = hit.surface.ns.dot(-ls.wi);
                        if cos_l < 0.05 {
                            // Grazing: an f32 ray-sphere hit is ill-conditioned there
                            // (its cosine is off by ~2e-5 absolute, 1 % of the pdf at
                            // cos 0.002), which says nothing about the two pdfs.
                            continue;
                        }
                        let mis = emitter.pdf_area_hit(select_pdf, hit.t, cos_l);
                        assert!(
                            (mis - ls.pdf).abs() <= 1e-3 * ls.pdf,
                            "sampled pdf {} vs MIS pdf {mis} (cos {cos_l}, t {}, dist {})",
                            ls.pdf,
                            hit.t,
                            ls.dist
                        );
                        hits += 1;
                    }
                }
            }
            if matches!(emitter, Emitter::Area { .. } | Emitter::AngularArea { .. }) {
                assert!(hits > 100, "too few visible light samples from {x}: {hits}");
                matched += hits;
                area_lights += 1;
            }
        }
    }
    // The area lights of the family's cases and the angulararea light.
    assert_eq!(area_lights, (AREA_LIGHT_CASES + 1) * refs.len());
    assert!(matched > 0 && points > 0);
}

/// Chi-square p-value of points sampled on an area light against uniform density by
/// area: spheres in equal-area cells of (z, phi) about the centre, disks in cells of
/// (r^2, phi) and cylinders of (z, phi) of their object-space points (an affine map
/// keeps area ratios), meshes in cells
/// (triangle, equal-area band of b0, equal slice of b1 / (b1 + b2)).
/// `skew` maps the sampler's 2D numbers (the identity for the real sampler).
fn area_uniformity_p_value(
    scene: &tstat::scene::Scene,
    emitter: &Emitter,
    seed: u64,
    skew: fn([f32; 2]) -> [f32; 2],
) -> f64 {
    const N: usize = 60_000;
    const K: usize = 4;
    let Emitter::Area { shape, sampler, .. } = emitter else {
        unreachable!("area lights only")
    };
    let shape_ref = &scene.shapes[*shape as usize];
    let mut rng = Pcg32::new(seed, 0xa4ea);
    let (counts, expected): (Vec<u64>, Vec<f64>) = match &shape_ref.geom {
        ShapeGeom::Sphere(s, _) => {
            let mut counts = vec![0u64; K * 2 * K];
            for _ in 0..N {
                let p = sampler
                    .sample(shape_ref, rng.next_f32(), skew(rng.next_2d()))
                    .p;
                let d = ((p - s.center) / s.radius).as_dvec3();
                assert!((d.length() - 1.0).abs() < 1e-4, "point off the sphere");
                let zb = (((d.z + 1.0) / 2.0 * K as f64) as usize).min(K - 1);
                let phi = d.y.atan2(d.x).rem_euclid(2.0 * PI);
                let pb = ((phi / (2.0 * PI) * (2 * K) as f64) as usize).min(2 * K - 1);
                counts[zb * 2 * K + pb] += 1;
            }
            let n = counts.len();
            (counts, vec![N as f64 / n as f64; n])
        }
        ShapeGeom::Disk(_) | ShapeGeom::Cylinder(_) => {
            let mut counts = vec![0u64; K * 2 * K];
            for _ in 0..N {
                let p = sampler
                    .sample(shape_ref, rng.next_f32(), skew(rng.next_2d()))
                    .p;
                let (band, l) = match &shape_ref.geom {
                    ShapeGeom::Disk(g) => {
                        let l = g.to_local(p).as_dvec3();
                        assert!(l.z.abs() < 1e-5, "point off the disk's plane");
                        (l.x * l.x + l.y * l.y, l)
                    }
                    ShapeGeom::Cylinder(g) => {
                        let l = g.to_local(p).as_dvec3();
                        assert!(
                            ((l.x * l.x + l.y * l.y).sqrt() - 1.0).abs() < 1e-4,
                            "point off the tube"
                        );
                        (l.z, l)
                    }
                    _ => unreachable!(),
                };
                assert!((-1e-6..=1.0 + 1e-6).contains(&band), "band {band}");
                let zb = ((band * K as f64) as usize).min(K - 1);
                let phi = l.y.atan2(l.x).rem_euclid(2.0 * PI);
                let pb = ((phi / (2.0 * PI) * (2 * K) as f64) as usize).min(2 * K - 1);
                counts[zb * 2 * K + pb] += 1;
            }
            let n = counts.len();
            (counts, vec![N as f64 / n as f64; n])
        }
        ShapeGeom::Curve(_) => unreachable!("curves cannot emit"),
        ShapeGeom::Mesh { triangles, .. } => {
            let tris: Vec<_> = (0..triangles.len() as u32)
                .map(|f| shape_ref.triangle(f))
                .collect();
            let areas: Vec<f64> = tris.iter().map(|t| t.area() as f64).collect();
            let total: f64 = areas.iter().sum();
            let mut counts = vec![0u64; tris.len() * K * K];
            for _ in 0..N {
                let p = sampler
                    .sample(shape_ref, rng.next_f32(), skew(rng.next_2d()))
                    .p;
                // The triangle holding p: barycentrics in [0, 1] and p in its plane.
                let (face, b1, b2) = tris
                    .iter()
                    .enumerate()
                    .map(|(f, t)| {
                        let (e1, e2, q) = (t.e1.as_dvec3(), t.e2.as_dvec3(), (p - t.v0).as_dvec3());
                        let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
                        let (q1, q2) = (q.dot(e1), q.dot(e2));
                        let det = d11 * d22 - d12 * d12;
                        let b1 = (d22 * q1 - d12 * q2) / det;
                        let b2 = (d11 * q2 - d12 * q1) / det;
                        let off = (q - e1 * b1 - e2 * b2).length()
                            + (-b1).max(0.0)
                            + (-b2).max(0.0)
                            + (b1 + b2 - 1.0).max(0.0);
                        (off, f, b1, b2)
                    })
                    .min_by(|a, b| a.0.total_cmp(&b.0))
                    .map(|(_, f, b1, b2)| (f, b1, b2))
                    .unwrap();
                let b0 = (1.0 - b1 - b2).clamp(0.0, 1.0);
                // P(b0 < t) = 1 - (1 - t)^2, so 1 - (1 - b0)^2 is uniform.
                let band = (((1.0 - (1.0 - b0).powi(2)) * K as f64) as usize).min(K - 1);
                let s = b1 / (b1 + b2).max(1e-12);
                let slice = ((s.clamp(0.0, 1.0) * K as f64) as usize).min(K - 1);
                counts[(face * K + band) * K + slice] += 1;
            }
            let expected = areas
                .iter()
                .flat_map(|a| std::iter::repeat_n(N as f64 * a / total / (K * K) as f64, K * K))
                .collect();
            (counts, expected)
        }
        ShapeGeom::Sdf(_) => unreachable!("an sdfgrid cannot emit"),
    };
    let stat: f64 = counts
        .iter()
        .zip(&expected)
        .map(|(&o, &e)| (o as f64 - e).powi(2) / e)
        .sum();
    ChiSquared::new((counts.len() - 1) as f64).unwrap().sf(stat)
}

#[test]
fn area_lights_sample_uniformly_by_area() {
    let scene = light_scene();
    let mut ps = Vec::new();
    for (i, emitter) in scene.emitters.iter().enumerate() {
        if let Emitter::Area { .. } = emitter {
            let p = area_uniformity_p_value(&scene, emitter, 300 + i as u64, |u| u);
            assert!(p > LEVEL, "emitter {i}: area chi-square p = {p:.3e}");
            ps.push(p);
        }
    }
    assert_eq!(ps.len(), AREA_LIGHT_CASES);
    eprintln!("area-uniformity p-values {ps:.3?}");
    // Squaring one number crowds the points towards one edge of each triangle (and
    // one pole of a sphere): every light must fail.
    for (i, emitter) in scene.emitters.iter().enumerate() {
        if let Emitter::Area { .. } = emitter {
            let p = area_uniformity_p_value(&scene, emitter, 400 + i as u64, |[a, b]| [a * a, b]);
            assert!(
                p < LEVEL,
                "emitter {i}: skewed sampling passed, p = {p:.3e}"
            );
        }
    }
}

// ------------------------------------------------------- angular area lights

/// Tests of the `angulararea` light in the family: the chi-square of its light samples
/// against its MIS pdf, and its emitted power against the closed form.
const ANGULAR_CASES: usize = 2;

/// A 2 x 2 `angulararea` rectangle in the plane y = 1 facing -y (cone 40 degrees, full
/// radiance within 25), and nothing else that emits.
const ANGULAR_SCENE: &str = r#"<scene version="3.0.0">
    <sensor type="perspective">
        <float name="fov" value="40"/>
        <transform name="to_world"><lookat origin="0, 0, 3" target="0, 0, 0" up="0, 1, 0"/></transform>
        <film type="transient_hdr_film">
            <integer name="width" value="8"/><integer name="height" value="8"/>
            <integer name="temporal_bins" value="4"/>
            <float name="start_opl" value="0"/><float name="bin_width_opl" value="1"/>
        </film>
    </sensor>
    <shape type="rectangle">
        <transform name="to_world"><rotate x="1" angle="90"/><translate y="1"/></transform>
        <emitter type="angulararea">
            <rgb name="radiance" value="3, 2, 1"/>
            <float name="cutoff_angle" value="40"/><float name="beam_width" value="25"/>
        </emitter>
    </shape>
</scene>"#;

fn angular_scene() -> tstat::scene::Scene {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("angular.xml");
    std::fs::write(&path, ANGULAR_SCENE).unwrap();
    tstat::scene::Scene::load(&path, &Default::default()).unwrap()
}

/// Chi-square p-value of `sampler`'s light samples seen from the origin (1 below the
/// light's centre) against the area density `pdf`'s MIS pdf implies
/// (`pdf_area_hit * cos_l / dist^2`), in cells of equal area about the foot point
/// (rings equal in r^2 up to r = 1, inside the light, times sectors), plus one cell
/// for the samples that carry nothing (`sample` gives None) and fall outside the rings.
fn angular_p_value(
    scene: &tstat::scene::Scene,
    sampler: &Emitter,
    pdf: &Emitter,
    seed: u64,
) -> f64 {
    const N: usize = 200_000;
    const RINGS: usize = 10;
    const SECTORS: usize = 8;
    let x = Vec3::ZERO;
    let mut counts = vec![0u64; RINGS * SECTORS + 1];
    let mut rng = Pcg32::new(seed, 0xa9);
    for _ in 0..N {
        let ls = sampler.sample(&scene.shapes, x, 1.0, rng.next_f32(), rng.next_2d());
        let cell = ls.and_then(|ls| {
            assert!((ls.p.y - 1.0).abs() < 1e-6 && !ls.delta);
            let r2 = (ls.p.x * ls.p.x + ls.p.z * ls.p.z) as f64;
            (r2 < 1.0).then(|| {
                let ring = ((r2 * RINGS as f64) as usize).min(RINGS - 1);
                let phi = (ls.p.z as f64).atan2(ls.p.x as f64).rem_euclid(2.0 * PI);
                let sector = ((phi / (2.0 * PI) * SECTORS as f64) as usize).min(SECTORS - 1);
                ring * SECTORS + sector
            })
        });
        counts[cell.unwrap_or(RINGS * SECTORS)] += 1;
    }
    // The area density of a point at radius r: the MIS pdf at the hit, back to area.
    let area_pdf = |r: f64| -> f64 {
        let dist = (1.0 + r * r).sqrt();
        let cos_l = (1.0 / dist) as f32;
        let solid = pdf.pdf_area_hit(1.0, dist as f32, cos_l) as f64;
        solid * cos_l as f64 / (dist * dist)
    };
    // Midpoint rule in r^2 (area is pi d(r^2) per full ring), fine enough that the
    // pdf's step at the cutoff costs well under one expected count per cell.
    const STEPS: usize = 4000;
    let mut expected = vec![0.0; RINGS * SECTORS + 1];
    for ring in 0..RINGS {
        let mut mass = 0.0;
        for k in 0..STEPS {
            let r2 = (ring as f64 + (k as f64 + 0.5) / STEPS as f64) / RINGS as f64;
            mass += area_pdf(r2.sqrt()) * PI / (RINGS * STEPS) as f64;
        }
        for sector in 0..SECTORS {
            expected[ring * SECTORS + sector] = N as f64 * mass / SECTORS as f64;
        }
    }
    let inside: f64 = expected.iter().sum();
    expected[RINGS * SECTORS] = N as f64 - inside;
    // Cells beyond the cone expect nothing: a sample there fails outright (p = 0).
    let mut stat = 0.0;
    let mut cells = 0;
    for (&o, &e) in counts.iter().zip(&expected) {
        if e > 0.0 {
            assert!(e > MIN_EXPECTED, "cell expecting {e}");
            stat += (o as f64 - e).powi(2) / e;
            cells += 1;
        } else if o > 0 {
            return 0.0;
        }
    }
    ChiSquared::new((cells - 1) as f64).unwrap().sf(stat)
}

#[test]
fn angular_light_samples_follow_its_mis_pdf() {
    let scene = angular_scene();
    let light = &scene.emitters[0];
    assert!(matches!(light, Emitter::AngularArea { .. }));
    let p = angular_p_value(&scene, light, light, 11);
    eprintln!("angular chi-square p = {p:.3e}");
    assert!(p > LEVEL, "angular light chi-square p = {p:.3e}");
    // A pdf with a wider cone than the sampler's (45 instead of 40 degrees) must fail.
    let Emitter::AngularArea {
        shape,
        radiance,
        sampler,
        ..
    } = light.clone()
    else {
        unreachable!()
    };
    let wider = Emitter::AngularArea {
        shape,
        radiance,
        sampler,
        falloff: tstat::lights::AngularFalloff::new(45.0, 25.0),
    };
    let p = angular_p_value(&scene, light, &wider, 12);
    assert!(p < LEVEL, "a wrong cone passed, p = {p:.3e}");
}

/// Two-sided p-value of the power estimate of an angular light (light samples from
/// points uniform on a receiving square under it) against `radiance * area * (2 pi int
/// falloff cos sin)`; `weight` maps a sample's (li, dist) to the weight used.
fn angular_power_p_value(seed: u64, weight: fn(Rgb, f32) -> Rgb) -> (f64, [f64; 3], [f64; 3]) {
    use statrs::distribution::Normal;
    const N: usize = 400_000;
    let scene = angular_scene();
    let light = &scene.emitters[0];
    let Emitter::AngularArea {
        radiance, falloff, ..
    } = light
    else {
        unreachable!()
    };
    // The receiving square y = 0, |x|, |z| <= 2, facing +y, holds every point within
    // 40 degrees of the light's normal below it (at most 1 + tan 40 = 1.84 out).
    let half = 2.0f32;
    let square = (2.0 * half as f64).powi(2);
    let mut rng = Pcg32::new(seed, 0x90);
    let (mut s1, mut s2) = ([0.0f64; 3], [0.0f64; 3]);
    for _ in 0..N {
        let x = Vec3::new(
            (2.0 * rng.next_f32() - 1.0) * half,
            0.0,
            (2.0 * rng.next_f32() - 1.0) * half,
        );
        let Some(ls) = light.sample(&scene.shapes, x, 1.0, rng.next_f32(), rng.next_2d()) else {
            continue;
        };
        let v = weight(ls.li, ls.dist) * (ls.wi.y / ls.pdf);
        for c in 0..3 {
            let v = v[c] as f64 * square;
            s1[c] += v;
            s2[c] += v * v;
        }
    }
    let area = 4.0;
    let psa = falloff.projected_solid_angle();
    let want = [0, 1, 2].map(|c| radiance[c] as f64 * area * psa);
    let mean = s1.map(|s| s / N as f64);
    let mut p = 1.0f64;
    for c in 0..3 {
        let var = (s2[c] / N as f64 - mean[c] * mean[c]) * N as f64 / (N - 1) as f64;
        let z = (mean[c] - want[c]) / (var / N as f64).sqrt();
        // The channels are one estimate scaled (radiance 3 : 2 : 1): one test.
        p = p.min(2.0 * Normal::standard().sf(z.abs()));
    }
    (p, mean, want)
}

#[test]
fn angular_light_emits_its_closed_form_power() {
    let (p, mean, want) = angular_power_p_value(5, |li, _| li);
    eprintln!("angular power {mean:?} vs {want:?}, p = {p:.3e}");
    assert!(
        p > LEVEL,
        "power {mean:?} vs closed form {want:?}: p = {p:.3e}"
    );
    // mitransient 1.3.1's light-sample weight (an extra 1 / dist^2) must fail.
    let (p, mean, _) = angular_power_p_value(6, |li, dist| li / (dist * dist));
    assert!(
        p < LEVEL,
        "the 1/dist^2 weight passed: {mean:?}, p = {p:.3e}"
    );
}

// ------------------------------------------------ blendbsdf, normal/bump maps, pplastic

/// A normal map whose samples forget the shadowing term (eval keeps it).
struct ShadowlessSample(Perturbed);

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

/// `pplastic` and the perturbed models (whose weights are not reciprocal, nor their
/// G-buffer albedos exact, so they are not in `all_models`): weight = eval / pdf from
/// random directions above the surface, and the mean sample energy equals quadrature
/// of `eval` over the upper hemisphere, at most 1. A normal map whose samples forget
/// the shadowing term fails the weight check.
#[test]
fn pplastic_and_perturbed_weights_and_energy() {
    let mut models: Vec<(String, Box<dyn BsdfModel>)> = pplastic_models()
        .into_iter()
        .map(|(n, b, _)| {
            let m: Box<dyn BsdfModel> = Box::new(b);
            (format!("pplastic {n}"), m)
        })
        .collect();
    models.extend(perturbed_cases().into_iter().map(|(n, b, _)| (n, b)));
    let mut rng = Pcg32::new(12, 3);
    for (i, (name, b)) in models.iter().enumerate() {
        for j in 0..16 {
            let mut wo = tstat::math::sampling::uniform_sphere(rng.next_2d());
            wo.z = wo.z.abs();
            let m = weight_mismatch(b.as_ref(), wo, 256, 700 + 16 * i as u64 + j);
            assert!(m < 1e-4, "{name} from {wo}: relative mismatch {m}");
        }
        for theta in [0.0, 45.0, 75.0] {
            let wo = dir(theta, 15.0 + 40.0 * i as f64);
            let quad = reflected_energy(b.as_ref(), wo);
            let (mean, se) = furnace(b.as_ref(), wo, 20_000, 900 + i as u64);
            for c in 0..3 {
                let (q, m, e) = (quad[c], mean[c] as f64, se[c] as f64);
                assert!(
                    (q - m).abs() <= 5.0 * e + 2e-3 * q,
                    "{name} at {theta} deg: quadrature {q}, sampled {m} +- {e}"
                );
                assert!(q <= 1.0 + 1e-3, "{name} at {theta} deg: reflects {q}");
            }
        }
    }
    let broken = ShadowlessSample(perturbed(
        Bsdf::Diffuse(diffuse(0.8)),
        tilted_frame(40.0, 0.0),
        true,
    ));
    let m = weight_mismatch(&broken, dir(60.0, 20.0), 256, 0);
    assert!(m > 0.01, "a sample without the shadowing term passed: {m}");
}

/// The shadowing term at a few closed-form points (Estevez et al.): 1 for an
/// unperturbed normal or a direction along the normal, 2 / (1 + sqrt(1 + a2 t2)).
#[test]
fn shadow_terminator_closed_form() {
    assert_eq!(shadow_terminator(Vec3::Z, dir(80.0, 0.0)), 1.0);
    let n = dir(40.0, 0.0);
    assert_eq!(shadow_terminator(n, Vec3::Z), 1.0);
    let a2 = (0.125 * (40f64.to_radians().tan().powi(2))).min(1.0);
    let t2 = 70f64.to_radians().tan().powi(2);
    let want = 2.0 / (1.0 + (1.0 + a2 * t2).sqrt());
    assert!((shadow_terminator(n, dir(70.0, 90.0)) as f64 - want).abs() < 1e-6);
    // Steep normals saturate a2 at 1.
    let want = 2.0 / (1.0 + (1.0 + t2).sqrt());
    assert!((shadow_terminator(dir(80.0, 0.0), dir(70.0, 0.0)) as f64 - want).abs() < 1e-6);
    // The identity frame changes nothing: the nested model's own values.
    let b = perturbed(Bsdf::Diffuse(diffuse(0.5)), IDENTITY, true);
    let (wo, wi) = (dir(30.0, 0.0), dir(50.0, 120.0));
    assert_eq!(b.eval(wo, wi), diffuse(0.5).eval(wo, wi));
}

/// `polarizer` without polarization: straight through, half the transmittance, nothing
/// to evaluate.
#[test]
fn polarizer_passes_half_the_transmittance_straight_through() {
    let p = Polarizer {
        transmittance: Rgb::new(1.0, 0.8, 0.2),
    };
    for wo in [dir(0.0, 0.0), dir(70.0, 30.0), dir(150.0, 200.0)] {
        let s = p.sample(wo, 0.4, [0.2, 0.9]).unwrap();
        assert_eq!(
            (s.wi, s.eta, s.lobe),
            (-wo, 1.0, BsdfFlags::DELTA_TRANSMISSION)
        );
        assert_eq!(s.weight, Rgb::new(0.5, 0.4, 0.1));
        assert!(p.flags(wo).is_delta());
        assert_eq!((p.eval(wo, -wo), p.pdf(wo, -wo)), (Rgb::ZERO, 0.0));
    }
}

// ------------------------------------------------------- infinitely distant emitters

/// A small non-uniform environment (6 x 5 texels over three decades, a bright texel, a
/// black patch whose sampling cells have zero density), turned about an oblique axis.
fn test_envmap(mis_compensation: bool) -> EnvMap {
    let (w, h) = (6usize, 5usize);
    let rgb: Vec<Vec3> = (0..w * h)
        .map(|k| match (k % w, k / w) {
            (4, 1) => Vec3::new(40.0, 30.0, 20.0),
            (1 | 2, 3 | 4) => Vec3::ZERO,
            (x, y) => Vec3::new(0.1 + 0.2 * x as f32, 0.05 * (1 + y) as f32, 0.3),
        })
        .collect();
    let to_world = glam::DMat3::from_axis_angle(glam::DVec3::new(1.0, 2.0, 0.5).normalize(), 0.7);
    EnvMap::new(w, h, rgb, 1.5, to_world, mis_compensation).unwrap()
}

fn infinite_emitters() -> Vec<(&'static str, Emitter)> {
    let sphere = SceneSphere {
        center: Vec3::new(0.3, -0.2, 0.1),
        radius: 2.5,
    };
    vec![
        (
            "envmap",
            Emitter::Envmap {
                map: Arc::new(test_envmap(false)),
                sphere,
            },
        ),
        (
            "constant",
            Emitter::Constant {
                radiance: Rgb::new(1.0, 2.0, 3.0),
                sphere,
            },
        ),
        (
            "directional",
            Emitter::Directional {
                direction: Vec3::new(0.2, -1.0, 0.3).normalize(),
                irradiance: Rgb::new(3.0, 2.0, 1.0),
                sphere,
            },
        ),
    ]
}

/// Chi-square p-value of an environment emitter's sampled directions against the
/// density a ray leaving the scene evaluates for MIS (`Emitter::escape`).
/// `skew` maps the sampler's 2D numbers (the identity for the real sampler).
fn environment_p_value(e: &Emitter, seed: u64, skew: fn([f32; 2]) -> [f32; 2]) -> f64 {
    let integrals = pdf_cell_integrals(&|w| e.escape(1.0, Vec3::ZERO, w).1 as f64);
    let total: f64 = integrals.iter().sum();
    assert!((total - 1.0).abs() < 1e-3, "the pdf integrates to {total}");
    chi2_of_samples(integrals, seed, &mut |rng| {
        let u1 = rng.next_f32();
        let u2 = skew(rng.next_2d());
        e.sample(&[], Vec3::ZERO, 1.0, u1, u2).map(|ls| ls.wi)
    })
}

#[test]
fn environment_samples_follow_the_escape_pdf() {
    let mut cases = 0;
    for (i, (name, e)) in infinite_emitters().into_iter().enumerate() {
        if !e.is_environment() {
            continue;
        }
        let p = environment_p_value(&e, 500 + i as u64, |u| u);
        assert!(p > LEVEL, "{name}: chi-square p = {p:.3e}");
        eprintln!("{name}: chi-square p = {p:.3}");
        cases += 1;
        // Squaring one number crowds the samples towards one end: must fail.
        let p = environment_p_value(&e, 600 + i as u64, |[a, b]| [a, b * b]);
        assert!(p < LEVEL, "{name}: skewed sampling passed, p = {p:.3e}");
    }
    assert_eq!(cases, ENVIRONMENT_CASES);
    // MIS compensation changes the density, and it still matches its samples; a sampler
    // drawing with the uncompensated table against the compensated pdf is rejected.
    let sphere = SceneSphere::default();
    let comp = Emitter::Envmap {
        map: Arc::new(test_envmap(true)),
        sphere,
    };
    let plain = Emitter::Envmap {
        map: Arc::new(test_envmap(false)),
        sphere,
    };
    let d = Vec3::new(0.1, 0.9, -0.3).normalize();
    assert_ne!(
        comp.escape(1.0, Vec3::ZERO, d).1,
        plain.escape(1.0, Vec3::ZERO, d).1
    );
    let integrals = pdf_cell_integrals(&|w| comp.escape(1.0, Vec3::ZERO, w).1 as f64);
    let p = chi2_of_samples(integrals, 700, &mut |rng| {
        let (u1, u2) = (rng.next_f32(), rng.next_2d());
        plain.sample(&[], Vec3::ZERO, 1.0, u1, u2).map(|ls| ls.wi)
    });
    assert!(p < LEVEL, "wrong table passed, p = {p:.3e}");
}

#[test]
fn infinite_light_samples_carry_the_pdf_and_radiance_of_an_escaping_ray() {
    let select_pdf = 0.25;
    let refs = [
        Vec3::new(0.0, -0.5, 0.0),
        Vec3::new(1.2, 0.3, -0.9),
        // Outside the bounding sphere (a camera): the distance grows with it.
        Vec3::new(0.0, 0.0, 8.0),
    ];
    let mut rng = Pcg32::new(33, 0);
    for (name, e) in infinite_emitters() {
        let (center, radius) = match &e {
            Emitter::Envmap { sphere, .. }
            | Emitter::Constant { sphere, .. }
            | Emitter::Directional { sphere, .. } => (sphere.center, sphere.radius),
            _ => unreachable!(),
        };
        for x in refs {
            let want_dist = 2.0 * radius.max((x - center).length());
            let mut n = 0;
            for _ in 0..2000 {
                let Some(ls) = e.sample(&[], x, select_pdf, rng.next_f32(), rng.next_2d()) else {
                    continue;
                };
                n += 1;
                assert!((ls.wi.length() - 1.0).abs() < 1e-5, "{name}");
                assert_eq!(ls.dist, want_dist, "{name}");
                assert!(
                    (ls.p - (x + ls.wi * ls.dist)).length() < 1e-5 * ls.dist,
                    "{name}"
                );
                let (li, pdf, dist) = e.escape(select_pdf, x, ls.wi);
                if let Emitter::Directional {
                    direction,
                    irradiance,
                    ..
                } = &e
                {
                    assert!(ls.delta && ls.pdf == select_pdf, "{name}");
                    assert_eq!((ls.wi, ls.li), (-*direction, *irradiance));
                    // Never met by a ray.
                    assert_eq!((li, pdf), (Rgb::ZERO, 0.0));
                } else {
                    assert!(!ls.delta && ls.pdf > 0.0, "{name}");
                    assert_eq!(ls.pdf, pdf, "{name}: sampled pdf vs MIS pdf");
                    assert_eq!(ls.li, li, "{name}: sampled radiance vs escape radiance");
                    assert_eq!(ls.dist, dist, "{name}");
                }
            }
            assert!(n > 1900, "{name}: only {n} samples");
        }
    }
}

// ------------------------------------------------ principled, principledthin

fn principled(set: impl FnOnce(&mut Principled)) -> Principled {
    let mut b = Principled::default();
    set(&mut b);
    b
}

fn principled_thin(set: impl FnOnce(&mut PrincipledThin)) -> PrincipledThin {
    let mut b = PrincipledThin::default();
    set(&mut b);
    b
}

/// `principled` and `principledthin` across their lobes: (name, model, theta of `wo`
/// in degrees, the IOR a transmitted direction enters (1 for the thin sheet)).
fn principled_models() -> Vec<(&'static str, Box<dyn BsdfModel>, f64, f32)> {
    let glass = principled(|b| {
        b.spec_trans = 0.7;
        b.has_spec_trans = true;
        b.roughness = 0.3;
        b.metallic = 0.1;
        b.base_color = Rgb::new(0.8, 0.9, 1.0);
        b.eta = 1.4;
    });
    let thin_back = principled_thin(|b| {
        b.anisotropic = 0.5;
        b.spec_trans = 0.3;
        b.has_spec_trans = true;
        b.diff_trans = 1.4;
        b.has_diff_trans = true;
        b.sheen = 0.4;
        b.spec_tint = 0.5;
        b.base_color = Rgb::new(0.7, 0.1, 0.1);
    });
    vec![
        (
            "principled defaults",
            Box::new(Principled::default()),
            30.0,
            1.5,
        ),
        (
            "principled metallic 0.8, anisotropic 0.6, roughness 0.4",
            Box::new(principled(|b| {
                b.metallic = 0.8;
                b.anisotropic = 0.6;
                b.roughness = 0.4;
                b.base_color = Rgb::new(0.9, 0.5, 0.2);
            })),
            50.0,
            1.5,
        ),
        (
            "principled spec_trans 0.7, eta 1.4, front",
            Box::new(glass.clone()),
            40.0,
            1.4,
        ),
        (
            "principled spec_trans 0.7, eta 1.4, inside",
            Box::new(glass),
            140.0,
            1.4,
        ),
        (
            "principled clearcoat, sheen, spec_tint, flatness",
            Box::new(principled(|b| {
                b.clearcoat = 0.8;
                b.clearcoat_gloss = 0.3;
                b.sheen = 0.6;
                b.sheen_tint = 0.5;
                b.spec_tint = 0.4;
                b.flatness = 0.5;
                b.roughness = 0.6;
                b.base_color = Rgb::new(0.2, 0.8, 0.1);
            })),
            60.0,
            1.5,
        ),
        (
            "principled spec_trans 1, eta 0.8, roughness 0.5",
            Box::new(principled(|b| {
                b.spec_trans = 1.0;
                b.has_spec_trans = true;
                b.eta = 0.8;
                b.base_color = Rgb::new(0.5, 0.7, 0.9);
            })),
            35.0,
            0.8,
        ),
        (
            "principledthin spec_trans 0.5, diff_trans 0.8, eta 1.33",
            Box::new(principled_thin(|b| {
                b.spec_trans = 0.5;
                b.has_spec_trans = true;
                b.diff_trans = 0.8;
                b.has_diff_trans = true;
                b.eta = 1.33;
                b.roughness = 0.45;
            })),
            35.0,
            1.0,
        ),
        (
            "principledthin anisotropic, from the back",
            Box::new(thin_back),
            120.0,
            1.0,
        ),
        (
            "principledthin spec_trans 1, roughness 0.4",
            Box::new(principled_thin(|b| {
                b.spec_trans = 1.0;
                b.has_spec_trans = true;
                b.roughness = 0.4;
                b.base_color = Rgb::new(0.9, 0.6, 0.3);
            })),
            65.0,
            1.0,
        ),
    ]
}

/// Both models: weight = eval / pdf from random directions on both sides; the mean
/// sample energy (transmission times eta^2) equals quadrature of `eval` over the
/// sphere (so sampling, pdf, eval and the Jacobians agree in absolute terms);
/// reflection is reciprocal, and principled's refraction up to the IORs squared (the
/// thin sheet's diffuse transmission exactly; its specular transmission masks the two
/// directions differently in Mitsuba, and is left out).
#[test]
fn principled_weights_energy_and_reciprocity() {
    let mut rng = Pcg32::new(21, 4);
    for (i, (name, b, _, eta)) in principled_models().into_iter().enumerate() {
        for j in 0..16 {
            let wo = tstat::math::sampling::uniform_sphere(rng.next_2d());
            let m = weight_mismatch(b.as_ref(), wo, 256, 1100 + 16 * i as u64 + j);
            assert!(m < 1e-4, "{name} from {wo}: relative mismatch {m}");
        }
        for theta in [10.0, 70.0, 115.0] {
            let wo = dir(theta, 25.0 + 40.0 * i as f64);
            let quad = scattered_energy(b.as_ref(), eta, wo);
            let (mean, se) = furnace(b.as_ref(), wo, 20_000, 1300 + i as u64);
            for c in 0..3 {
                let (q, m, e) = (quad[c], mean[c] as f64, se[c] as f64);
                assert!(
                    (q - m).abs() <= 5.0 * e + 2e-3 * q,
                    "{name} at {theta} deg: quadrature {q}, sampled {m} +- {e}"
                );
            }
        }
        let a = asymmetry(b.as_ref(), 1400 + i as u64);
        assert!(a < 1e-4, "{name}: reflection not reciprocal, relative {a}");
        if name.starts_with("principled spec_trans") {
            let (a, compared) = refraction_asymmetry(b.as_ref(), eta, 1500 + i as u64);
            assert!(compared > 300, "{name}: only {compared} values to compare");
            assert!(a < 2e-3, "{name}: refraction not reciprocal, relative {a}");
        }
    }
    let sheet = principled_thin(|b| {
        b.diff_trans = 1.2;
        b.has_diff_trans = true;
        b.roughness = 0.7;
    });
    let (a, compared) = refraction_asymmetry(&sheet, 1.0, 1600);
    assert!(
        compared > 300 && a < 1e-5,
        "thin diffuse transmission: {a} over {compared}"
    );
}

/// White furnace: the energy models made to be lossless stay within 1 (a white
/// metal, a clear white glass with its energy counted as eta^2 times the transmitted
/// radiance, Burley's diffuse without retro-reflection, a white diffusing sheet), and
/// lose little near normal incidence; a glass lobe without its radiance scale
/// 1 / eta^2 creates energy and is rejected.
#[test]
fn principled_white_furnace_bounds() {
    let white_metal = principled(|b| {
        b.metallic = 1.0;
        b.base_color = Rgb::ONE;
        b.roughness = 0.3;
    });
    let white_glass = principled(|b| {
        b.spec_trans = 1.0;
        b.has_spec_trans = true;
        b.base_color = Rgb::ONE;
        b.roughness = 0.3;
    });
    let smooth_diffuse = principled(|b| {
        b.base_color = Rgb::ONE;
        b.roughness = 0.0;
        b.eta = 1.0;
    });
    let white_sheet = principled_thin(|b| {
        b.diff_trans = 1.0;
        b.has_diff_trans = true;
        b.roughness = 0.0;
        b.base_color = Rgb::ONE;
    });
    let models: Vec<(&str, Box<dyn BsdfModel>, f32, f64)> = vec![
        ("white metal", Box::new(white_metal), 1.5, 0.93),
        ("white glass", Box::new(white_glass.clone()), 1.5, 0.93),
        ("Burley diffuse", Box::new(smooth_diffuse), 1.0, 0.85),
        ("white sheet", Box::new(white_sheet), 1.0, 0.85),
    ];
    for (i, (name, b, eta, floor)) in models.iter().enumerate() {
        for theta in [0.0, 30.0, 60.0, 80.0, 150.0] {
            let wo = dir(theta, 10.0 * i as f64);
            let (mean, se) = furnace(b.as_ref(), wo, 20_000, 1700 + i as u64);
            let q = scattered_energy(b.as_ref(), *eta, wo);
            for c in 0..3 {
                assert!(q[c] <= 1.0 + 1e-3, "{name} at {theta} deg: scatters {q}");
                assert!(
                    (mean[c] as f64) <= 1.0 + 5.0 * se[c] as f64,
                    "{name} at {theta} deg: mean {mean}"
                );
            }
            if theta <= 30.0 {
                assert!(q.min_element() > *floor, "{name} at {theta} deg: only {q}");
            }
        }
    }
    let (mean, _) = furnace(
        &PrincipledWithoutRadianceScale(white_glass),
        dir(10.0, 0.0),
        20_000,
        0,
    );
    assert!(
        mean.max_element() > 1.5,
        "principled glass without 1 / eta^2 passed the furnace: {mean}"
    );
}

/// A principled glass whose transmission forgets Mitsuba's radiance scale 1 / eta^2.
struct PrincipledWithoutRadianceScale(Principled);

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

/// Closed form: with specular 0 (eta 1, no specular lobe), metallic 0 and nothing
/// else, principled is Burley's diffuse plus retro-reflection, here in f64 from the
/// Disney notes: f = base / pi ((1 - Fi / 2)(1 - Fo / 2) + Rr (Fo + Fi + Fo Fi (Rr -
/// 1))), F = (1 - cos)^5, Rr = 2 roughness cos_d^2, cos_d the half vector's cosine
/// with either direction.
#[test]
fn principled_diffuse_and_retro_reflection_closed_form() {
    let base = [0.8f64, 0.4, 0.2];
    for roughness in [1.0f64, 0.35] {
        let b = principled(|b| {
            b.base_color = Rgb::new(0.8, 0.4, 0.2);
            b.roughness = roughness as f32;
            b.eta = tstat::materials::specular_to_eta(0.0);
        });
        assert_eq!(b.eta, 1.0);
        for (to, po, ti, pi) in [
            (30.0, 0.0, 60.0, 180.0),
            (75.0, 10.0, 80.0, 50.0),
            (0.0, 0.0, 45.0, 90.0),
            (85.0, 0.0, 85.0, 180.0),
        ] {
            let (wo, wi) = (dir(to, po), dir(ti, pi));
            let (o, i) = (wo.as_dvec3(), wi.as_dvec3());
            let h = (o + i).normalize();
            let cos_d = h.dot(i);
            let (fo, fi) = ((1.0 - i.z).powi(5), (1.0 - o.z).powi(5));
            let rr = 2.0 * roughness * cos_d * cos_d;
            let f = (1.0 - fi / 2.0) * (1.0 - fo / 2.0) + rr * (fo + fi + fo * fi * (rr - 1.0));
            let got = b.eval(wo, wi);
            for c in 0..3 {
                let want = base[c] / PI * f * i.z;
                assert!(
                    (got[c] as f64 - want).abs() <= 2e-6 * want.max(1e-3),
                    "roughness {roughness}, wo {to} deg, wi {ti} deg: {} vs {want}",
                    got[c]
                );
            }
        }
        // One-sided: black from below.
        assert_eq!(b.eval(dir(120.0, 0.0), dir(150.0, 30.0)), Rgb::ZERO);
    }
}
