//! `BsdfModel::eval_pdf` against its reference, `(eval(wo, wi), pdf(wo, wi))`, bit for
//! bit: every model kind (built here across its lobes and parameters, and every
//! material of every bundled scene, textured ones at many uv, perturbed ones at many
//! hits), over random direction pairs on the whole sphere, grazing and normal
//! directions, mirror and refraction pairs and the models' own samples. Next-event
//! estimation uses `eval_pdf` where it used the two calls, so renders stay bit-identical
//! only if this holds.
//!
//! Rust gives no guarantee on the bits of a NaN produced by arithmetic, so two NaNs
//! compare equal (no pair here produces one; the count is printed). Broken overrides
//! (a density or a value rounded differently) must be rejected, so the check is not
//! vacuous.

use glam::{Vec2, Vec3};
use std::collections::BTreeSet;
use std::f32::consts::{FRAC_1_PI, PI};
use std::path::Path;
use tstat::materials::perturbed::HitGeometry;
use tstat::materials::{
    Blend, Bsdf, BsdfModel, BsdfSample, Circular, Composed, Conductor, Dielectric, Diffuse, Mask,
    Microfacet, MicrofacetKind, Null, OneSided, PPlastic, Perturbation, Perturbed, Plastic,
    Polarizer, Principled, PrincipledThin, Retarder, RoughConductor, RoughDielectric, RoughPlastic,
    Separable, TemporalProfile, ThinDielectric, TwoSided,
};
use tstat::materials::{BsdfFlags, Material};
use tstat::math::frame::Frame;
use tstat::math::rng::Pcg32;
use tstat::math::Rgb;
use tstat::scene::{Overrides, Scene};
use tstat::textures::Texture;

// ---------------------------------------------------------------- the check

/// Equal bits, or both NaN.
fn same(a: f32, b: f32) -> bool {
    a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
}

#[derive(Default, Debug)]
struct Tally {
    pairs: usize,
    /// Pairs with a non-zero value and a positive density (the lobes were evaluated).
    live: usize,
    nans: usize,
    mismatches: usize,
    first: Option<String>,
}

/// Compares `eval_pdf` with `eval` and `pdf` on every pair.
fn check(b: &dyn BsdfModel, pairs: &[(Vec3, Vec3)], t: &mut Tally) {
    for &(wo, wi) in pairs {
        let (value, pdf) = b.eval_pdf(wo, wi);
        let (want_value, want_pdf) = (b.eval(wo, wi), b.pdf(wo, wi));
        t.pairs += 1;
        if value != Rgb::ZERO && pdf > 0.0 {
            t.live += 1;
        }
        if pdf.is_nan() || value.is_nan() {
            t.nans += 1;
        }
        let ok = (0..3).all(|c| same(value[c], want_value[c])) && same(pdf, want_pdf);
        if !ok {
            t.mismatches += 1;
            t.first.get_or_insert_with(|| {
                format!(
                    "wo {wo:?} wi {wi:?}: eval_pdf ({value:?}, {pdf:e}) vs eval {want_value:?}, pdf {want_pdf:e}"
                )
            });
        }
    }
}

// ---------------------------------------------------------------- the directions

fn sphere(u: [f32; 2]) -> Vec3 {
    let z = 1.0 - 2.0 * u[0];
    let r = (1.0 - z * z).max(0.0).sqrt();
    let (s, c) = (2.0 * PI * u[1]).sin_cos();
    Vec3::new(r * c, r * s, z)
}

/// A unit direction with the cosine `z` and a random azimuth.
fn at_cosine(z: f32, rng: &mut Pcg32) -> Vec3 {
    let r = (1.0 - z * z).max(0.0).sqrt();
    let (s, c) = (2.0 * PI * rng.next_f32()).sin_cos();
    Vec3::new(r * c, r * s, z)
}

/// Cosines at and near grazing (both sides, signed zeros) and near the normal.
const GRAZING: [f32; 16] = [
    0.0, -0.0, 1e-7, -1e-7, 1e-5, -1e-5, 1e-3, -1e-3, 0.02, -0.02, 0.08, -0.08, 0.9999, -0.9999,
    1.0, -1.0,
];

/// IORs whose refraction pairs are tried (the models' and a few others).
const ETAS: [f32; 6] = [1.5, 1.0 / 1.5, 1.33, 1.4, 0.8, 1.5046 / 1.000277];

/// Snell refraction of `wo` about the normal for the relative IOR `eta` (of the far
/// side over `wo`'s), `None` under total internal reflection.
fn refract(wo: Vec3, eta: f32) -> Option<Vec3> {
    let cos_o = wo.z;
    let eta = if cos_o > 0.0 { eta } else { 1.0 / eta };
    let sin2_t = (1.0 - cos_o * cos_o) / (eta * eta);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt() * -cos_o.signum();
    Some(Vec3::new(-wo.x / eta, -wo.y / eta, cos_t).normalize())
}

/// The outgoing directions: random on the sphere, grazing and normal ones.
fn outgoing(rng: &mut Pcg32, random: usize) -> Vec<Vec3> {
    let mut v: Vec<Vec3> = (0..random).map(|_| sphere(rng.next_2d())).collect();
    for z in GRAZING {
        v.push(at_cosine(z, rng));
    }
    v.extend([Vec3::Z, -Vec3::Z, Vec3::X, Vec3::new(0.0, 0.6, 0.8)]);
    v
}

/// Direction pairs for `b`: for each outgoing direction, random and grazing incident
/// ones, the mirror, straight-through and refracted directions and the model's samples
/// (exactly, and mirrored through the surface).
fn pairs_for(
    b: &dyn BsdfModel,
    rng: &mut Pcg32,
    wos: &[Vec3],
    random_wi: usize,
) -> Vec<(Vec3, Vec3)> {
    let mut pairs = Vec::new();
    for &wo in wos {
        for _ in 0..random_wi {
            pairs.push((wo, sphere(rng.next_2d())));
        }
        for z in GRAZING {
            pairs.push((wo, at_cosine(z, rng)));
        }
        let mirror = Vec3::new(-wo.x, -wo.y, wo.z);
        for wi in [
            mirror,
            -wo,
            wo,
            Vec3::new(wo.x, wo.y, -wo.z),
            Vec3::Z,
            -Vec3::Z,
        ] {
            pairs.push((wo, wi));
        }
        for eta in ETAS {
            if let Some(wt) = refract(wo, eta) {
                pairs.push((wo, wt));
                // Near the refraction: where rough transmission lobes peak.
                let jitter = (sphere(rng.next_2d()) * 0.05 + wt).normalize();
                pairs.push((wo, jitter));
            }
        }
        for _ in 0..8 {
            let (u1, u2) = (rng.next_f32(), rng.next_2d());
            let sampled: Option<BsdfSample> = b.sample(wo, u1, u2);
            if let Some(s) = sampled {
                pairs.push((wo, s.wi));
                pairs.push((wo, Vec3::new(s.wi.x, s.wi.y, -s.wi.z)));
            }
        }
    }
    pairs
}

// ---------------------------------------------------------------- the models

fn rgb(r: f32, g: f32, b: f32) -> Rgb {
    Rgb::new(r, g, b)
}

fn microfacet(kind: MicrofacetKind, alpha_u: f32, alpha_v: f32, visible: bool) -> Microfacet {
    Microfacet {
        kind,
        alpha_u,
        alpha_v,
        sample_visible: visible,
    }
}

/// The microfacet distributions every rough model is built with.
fn distributions() -> Vec<Microfacet> {
    use MicrofacetKind::{Beckmann, Ggx};
    vec![
        microfacet(Beckmann, 0.1, 0.1, true),
        microfacet(Beckmann, 0.4, 0.15, true),
        microfacet(Beckmann, 0.3, 0.3, false),
        microfacet(Ggx, 0.3, 0.3, true),
        microfacet(Ggx, 0.2, 0.5, true),
        microfacet(Ggx, 0.05, 0.05, false),
        microfacet(Ggx, 0.001, 0.001, true),
        microfacet(Ggx, 1.0, 1.0, true),
    ]
}

fn diffuse(r: f32) -> Diffuse {
    Diffuse {
        reflectance: Rgb::splat(r),
    }
}

fn gold() -> (Rgb, Rgb) {
    (
        rgb(0.143119, 0.374957, 1.44248),
        rgb(3.98316, 2.38572, 1.60322),
    )
}

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

/// A frame tilted by `deg` about t and turned by `turn` about the new normal.
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

fn perturbed(nested: Bsdf, frame: Frame, shadowing: bool) -> Bsdf {
    Bsdf::Perturbed(Perturbed {
        perturbation: Perturbation::NormalMap(Texture::Constant(Vec3::new(0.5, 0.5, 1.0))),
        flip_invalid_normals: true,
        use_shadowing_function: shadowing,
        nested: Box::new(nested),
        frame,
    })
}

/// The plain models (those `twosided` can hold, and the others) across their parameters.
fn plain_models() -> Vec<(String, Bsdf)> {
    let (eta, k) = gold();
    let mut v: Vec<(String, Bsdf)> = vec![
        ("diffuse".into(), Bsdf::Diffuse(diffuse(0.7))),
        (
            "conductor".into(),
            Bsdf::Conductor(Conductor {
                eta,
                k,
                specular_reflectance: Rgb::ONE,
            }),
        ),
        (
            "dielectric".into(),
            Bsdf::Dielectric(Dielectric {
                eta: 1.5,
                specular_reflectance: Rgb::ONE,
                specular_transmittance: Rgb::ONE,
            }),
        ),
        (
            "thindielectric".into(),
            Bsdf::ThinDielectric(ThinDielectric {
                eta: 1.5,
                specular_reflectance: Rgb::ONE,
                specular_transmittance: Rgb::ONE,
            }),
        ),
        ("null".into(), Bsdf::Null(Null)),
        (
            "polarizer".into(),
            Bsdf::Polarizer(Polarizer {
                transmittance: Rgb::splat(0.5),
                theta: 30.0,
                polarizing: true,
            }),
        ),
        (
            "retarder".into(),
            Bsdf::Retarder(Retarder {
                transmittance: rgb(0.9, 0.8, 0.7),
                theta: 20.0,
                delta: 90.0,
            }),
        ),
        (
            "circular".into(),
            Bsdf::Circular(Circular {
                transmittance: rgb(0.9, 0.8, 0.7),
                left_handed: true,
            }),
        ),
        (
            "plastic".into(),
            Bsdf::Plastic(Plastic::new(1.49, rgb(0.8, 0.3, 0.1), Rgb::ONE, false)),
        ),
        (
            "plastic nonlinear eta 0.8".into(),
            Bsdf::Plastic(Plastic::new(
                0.8,
                rgb(0.2, 0.9, 0.5),
                rgb(0.5, 0.5, 1.0),
                true,
            )),
        ),
    ];
    for (i, d) in distributions().into_iter().enumerate() {
        v.push((
            format!("roughconductor {i} {d:?}"),
            Bsdf::RoughConductor(RoughConductor {
                distribution: d,
                eta,
                k,
                specular_reflectance: rgb(1.0, 0.9, 0.8),
            }),
        ));
        for ior in [1.5, 0.7] {
            v.push((
                format!("roughdielectric {i} eta {ior} {d:?}"),
                Bsdf::RoughDielectric(RoughDielectric {
                    distribution: d,
                    eta: ior,
                    specular_reflectance: Rgb::ONE,
                    specular_transmittance: rgb(0.9, 1.0, 0.8),
                }),
            ));
        }
        let ps = if i % 2 == 0 { 0.5 } else { 0.2 };
        v.push((
            format!("pplastic {i} {d:?}"),
            Bsdf::PPlastic(PPlastic {
                distribution: d,
                eta: 1.49,
                diffuse_reflectance: rgb(0.6, 0.3, 0.2),
                specular_reflectance: Rgb::ONE,
                specular_weight: ps,
            }),
        ));
        // roughplastic is isotropic.
        if d.alpha_u == d.alpha_v && d.alpha_u >= 0.01 {
            for (ior, nonlinear) in [(1.49, false), (1.9, true), (0.8, false)] {
                v.push((
                    format!("roughplastic {i} eta {ior} {d:?}"),
                    Bsdf::RoughPlastic(RoughPlastic::new(
                        d,
                        ior,
                        rgb(0.1, 0.25, 0.8),
                        rgb(0.5, 0.7, 1.0),
                        nonlinear,
                    )),
                ));
            }
        }
    }
    v
}

fn principled_models() -> Vec<(String, Bsdf)> {
    let p = |name: &str, b: Principled| (format!("principled {name}"), Bsdf::Principled(b));
    let t =
        |name: &str, b: PrincipledThin| (format!("principledthin {name}"), Bsdf::PrincipledThin(b));
    vec![
        p("defaults", Principled::default()),
        p(
            "metallic anisotropic",
            principled(|b| {
                b.metallic = 0.8;
                b.anisotropic = 0.6;
                b.roughness = 0.4;
                b.base_color = rgb(0.9, 0.5, 0.2);
            }),
        ),
        p(
            "glass",
            principled(|b| {
                b.spec_trans = 0.7;
                b.has_spec_trans = true;
                b.roughness = 0.3;
                b.metallic = 0.1;
                b.base_color = rgb(0.8, 0.9, 1.0);
                b.eta = 1.4;
            }),
        ),
        p(
            "full glass eta 0.8",
            principled(|b| {
                b.spec_trans = 1.0;
                b.has_spec_trans = true;
                b.eta = 0.8;
                b.base_color = rgb(0.5, 0.7, 0.9);
            }),
        ),
        p(
            "clearcoat sheen spec_tint flatness",
            principled(|b| {
                b.clearcoat = 0.8;
                b.clearcoat_gloss = 0.3;
                b.sheen = 0.6;
                b.sheen_tint = 0.5;
                b.spec_tint = 0.4;
                b.flatness = 0.5;
                b.roughness = 0.6;
                b.base_color = rgb(0.2, 0.8, 0.1);
            }),
        ),
        p(
            "everything, smooth",
            principled(|b| {
                b.clearcoat = 1.0;
                b.clearcoat_gloss = 1.0;
                b.sheen = 1.0;
                b.spec_tint = 1.0;
                b.metallic = 0.3;
                b.spec_trans = 0.4;
                b.has_spec_trans = true;
                b.roughness = 0.02;
                b.anisotropic = 0.9;
            }),
        ),
        p(
            "rates",
            principled(|b| {
                b.diffuse_rate = 0.0;
                b.specular_rate = 2.0;
                b.clearcoat_rate = 0.5;
                b.clearcoat = 0.5;
                b.roughness = 1.0;
            }),
        ),
        t("defaults", PrincipledThin::default()),
        t(
            "spec and diffuse transmission",
            principled_thin(|b| {
                b.spec_trans = 0.5;
                b.has_spec_trans = true;
                b.diff_trans = 0.8;
                b.has_diff_trans = true;
                b.eta = 1.33;
                b.roughness = 0.45;
            }),
        ),
        t(
            "anisotropic sheen tint",
            principled_thin(|b| {
                b.anisotropic = 0.5;
                b.spec_trans = 0.3;
                b.has_spec_trans = true;
                b.diff_trans = 1.4;
                b.has_diff_trans = true;
                b.sheen = 0.4;
                b.spec_tint = 0.5;
                b.flatness = 0.7;
                b.base_color = rgb(0.7, 0.1, 0.1);
            }),
        ),
        t(
            "all specular",
            principled_thin(|b| {
                b.spec_trans = 1.0;
                b.has_spec_trans = true;
                b.roughness = 0.4;
                b.base_color = rgb(0.9, 0.6, 0.3);
            }),
        ),
        t(
            "smooth, rates",
            principled_thin(|b| {
                b.spec_trans = 0.6;
                b.has_spec_trans = true;
                b.roughness = 0.01;
                b.spec_reflect_rate = 0.0;
                b.diffuse_trans_rate = 3.0;
                b.diff_trans = 2.0;
                b.has_diff_trans = true;
            }),
        ),
    ]
}

/// Every kind of model: the plain ones, `principled`, and the wrappers around them.
fn all_models() -> Vec<(String, Bsdf)> {
    let plain = plain_models();
    let mut v = plain.clone();
    v.extend(principled_models());
    let one_sided: Vec<(String, OneSided)> = plain
        .iter()
        .filter_map(|(n, b)| OneSided::try_from(b.clone()).ok().map(|o| (n.clone(), o)))
        .collect();
    // twosided: each one-sided model with a diffuse and a rough back.
    let rough_back = one_sided
        .iter()
        .find(|(n, _)| n.starts_with("roughconductor"))
        .unwrap()
        .1
        .clone();
    for (n, o) in &one_sided {
        v.push((
            format!("twosided {n} / diffuse"),
            Bsdf::TwoSided(TwoSided {
                front: o.clone(),
                back: OneSided::Diffuse(diffuse(0.3)),
            }),
        ));
        v.push((
            format!("twosided roughconductor / {n}"),
            Bsdf::TwoSided(TwoSided {
                front: rough_back.clone(),
                back: o.clone(),
            }),
        ));
    }
    // The wrappers around a selection of models (rough, layered, principled, delta).
    let inner: Vec<(String, Bsdf)> = v
        .iter()
        .filter(|(n, _)| {
            n.starts_with("roughconductor 3")
                || n.starts_with("roughdielectric 1 eta 1.5")
                || n.starts_with("roughdielectric 2 eta 0.7")
                || n.starts_with("roughplastic 3 eta 1.49")
                || n.starts_with("pplastic 4")
                || n == "plastic"
                || n == "diffuse"
                || n == "dielectric"
                || n == "principled glass"
                || n == "principled clearcoat sheen spec_tint flatness"
                || n == "principledthin spec and diffuse transmission"
                || n == "twosided plastic / diffuse"
        })
        .cloned()
        .collect();
    assert_eq!(inner.len(), 12, "the wrapped selection");
    let rough = |k: usize| inner[k % inner.len()].1.clone();
    for (k, (n, b)) in inner.iter().enumerate() {
        for opacity in [0.0, 0.4, 1.0] {
            v.push((
                format!("mask {opacity} over {n}"),
                Bsdf::Mask(Mask {
                    opacity,
                    nested: Box::new(b.clone()),
                }),
            ));
        }
        v.push((
            format!("separable over {n}"),
            Bsdf::Separable(Separable {
                inner: Box::new(b.clone()),
                profile: TemporalProfile::Exponential { lambda: 2.0 },
            }),
        ));
        for weight in [0.0, 0.3, 1.0] {
            v.push((
                format!("blend {weight} of {n} and the next"),
                Bsdf::Blend(Blend {
                    weight,
                    first: Box::new(b.clone()),
                    second: Box::new(rough(k + 1)),
                }),
            ));
            v.push((
                format!("composed {weight} of {n} and the next"),
                Bsdf::Composed(Composed {
                    weight,
                    first: Box::new(b.clone()),
                    second: Box::new(rough(k + 1)),
                }),
            ));
        }
        for (deg, turn, shadowing) in [(0.0, 0.0, true), (30.0, 40.0, true), (-55.0, 10.0, false)] {
            v.push((
                format!("perturbed {deg} {turn} {shadowing} over {n}"),
                perturbed(b.clone(), tilted_frame(deg, turn), shadowing),
            ));
        }
    }
    // Nested wrappers.
    v.push((
        "mask over blend over perturbed twosided".into(),
        Bsdf::Mask(Mask {
            opacity: 0.7,
            nested: Box::new(Bsdf::Blend(Blend {
                weight: 0.6,
                first: Box::new(perturbed(
                    Bsdf::TwoSided(TwoSided {
                        front: rough_back.clone(),
                        back: OneSided::Diffuse(diffuse(0.5)),
                    }),
                    tilted_frame(20.0, 70.0),
                    true,
                )),
                second: Box::new(rough(5)),
            })),
        }),
    ));
    v.push((
        "composed of separables (chlorophyll)".into(),
        Bsdf::Composed(Composed {
            weight: 0.35,
            first: Box::new(Bsdf::Separable(Separable {
                inner: Box::new(Bsdf::Diffuse(Diffuse {
                    reflectance: rgb(0.1, 0.8, 0.1),
                })),
                profile: TemporalProfile::Constant { delay: 0.0 },
            })),
            second: Box::new(Bsdf::Separable(Separable {
                inner: Box::new(rough(3)),
                profile: TemporalProfile::Epanechnikov {
                    mu: 1.0,
                    sigma: 0.2,
                },
            })),
        }),
    ));
    v
}

/// The kinds in `b` and the models inside it (an exhaustive match: a new kind must be
/// added here, and covered).
fn kinds(b: &Bsdf, out: &mut BTreeSet<&'static str>) {
    let one = |o: &OneSided| match o {
        OneSided::Diffuse(_) => "diffuse",
        OneSided::Conductor(_) => "conductor",
        OneSided::RoughConductor(_) => "roughconductor",
        OneSided::Plastic(_) => "plastic",
        OneSided::RoughPlastic(_) => "roughplastic",
        OneSided::PPlastic(_) => "pplastic",
    };
    let k = match b {
        Bsdf::Diffuse(_) => "diffuse",
        Bsdf::Dielectric(_) => "dielectric",
        Bsdf::Conductor(_) => "conductor",
        Bsdf::RoughConductor(_) => "roughconductor",
        Bsdf::RoughDielectric(_) => "roughdielectric",
        Bsdf::ThinDielectric(_) => "thindielectric",
        Bsdf::Plastic(_) => "plastic",
        Bsdf::RoughPlastic(_) => "roughplastic",
        Bsdf::Null(_) => "null",
        Bsdf::TwoSided(t) => {
            out.insert(one(&t.front));
            out.insert(one(&t.back));
            "twosided"
        }
        Bsdf::Mask(m) => {
            kinds(&m.nested, out);
            "mask"
        }
        Bsdf::Separable(s) => {
            kinds(&s.inner, out);
            "separable"
        }
        Bsdf::Composed(c) => {
            kinds(&c.first, out);
            kinds(&c.second, out);
            "composed"
        }
        Bsdf::Blend(c) => {
            kinds(&c.first, out);
            kinds(&c.second, out);
            "blend"
        }
        Bsdf::Perturbed(p) => {
            kinds(&p.nested, out);
            "perturbed"
        }
        Bsdf::PPlastic(_) => "pplastic",
        Bsdf::Polarizer(_) => "polarizer",
        Bsdf::Principled(_) => "principled",
        Bsdf::PrincipledThin(_) => "principledthin",
        Bsdf::Retarder(_) => "retarder",
        Bsdf::Circular(_) => "circular",
    };
    out.insert(k);
}

const ALL_KINDS: [&str; 21] = [
    "blend",
    "circular",
    "composed",
    "conductor",
    "dielectric",
    "diffuse",
    "mask",
    "null",
    "perturbed",
    "plastic",
    "polarizer",
    "pplastic",
    "principled",
    "principledthin",
    "retarder",
    "roughconductor",
    "roughdielectric",
    "roughplastic",
    "separable",
    "thindielectric",
    "twosided",
];

// ---------------------------------------------------------------- the tests

fn assert_clean(name: &str, t: &Tally) {
    assert_eq!(
        t.mismatches,
        0,
        "{name}: {} of {} pairs differ, first: {}",
        t.mismatches,
        t.pairs,
        t.first.as_deref().unwrap_or("")
    );
}

#[test]
fn every_constructed_model_agrees_bit_for_bit() {
    let mut rng = Pcg32::new(0x5eed, 1);
    let models = all_models();
    let mut seen = BTreeSet::new();
    let mut total = Tally::default();
    for (name, b) in &models {
        kinds(b, &mut seen);
        let wos = outgoing(&mut rng, 60);
        let pairs = pairs_for(b, &mut rng, &wos, 40);
        let mut t = Tally::default();
        check(b, &pairs, &mut t);
        assert_clean(name, &t);
        // Through the model's own type too, not only the enum's dispatch.
        let inner: &dyn BsdfModel = match b {
            Bsdf::RoughConductor(m) => m,
            Bsdf::RoughDielectric(m) => m,
            Bsdf::RoughPlastic(m) => m,
            Bsdf::PPlastic(m) => m,
            Bsdf::Plastic(m) => m,
            Bsdf::Principled(m) => m,
            Bsdf::PrincipledThin(m) => m,
            Bsdf::TwoSided(m) => m,
            Bsdf::Blend(m) => m,
            Bsdf::Mask(m) => m,
            Bsdf::Perturbed(m) => m,
            other => other,
        };
        check(inner, &pairs, &mut t);
        assert_clean(name, &t);
        // A model with a non-delta lobe was evaluated where it is not zero.
        if wos.iter().any(|&wo| b.flags(wo).has_non_delta()) {
            assert!(
                t.live * 200 > t.pairs,
                "{name}: only {} of {} pairs live",
                t.live,
                t.pairs
            );
        }
        total.pairs += t.pairs;
        total.live += t.live;
        total.nans += t.nans;
    }
    let missing: Vec<_> = ALL_KINDS.iter().filter(|k| !seen.contains(*k)).collect();
    assert!(missing.is_empty(), "kinds not built: {missing:?}");
    eprintln!(
        "{} models, {} pairs ({} live, {} NaN): eval_pdf == (eval, pdf) bit for bit",
        models.len(),
        total.pairs,
        total.live,
        total.nans
    );
}

/// A hit at which `normalmap`/`bumpmap` resolve their frame: a random shading frame,
/// tangents along it (scaled, and tilted off the surface), `wo` above.
fn random_hit(rng: &mut Pcg32, uv: Vec2) -> HitGeometry {
    let n = sphere(rng.next_2d());
    let shading = Frame::from_normal(n);
    let tilt = sphere(rng.next_2d()) * 0.3;
    let wo = sphere(rng.next_2d());
    HitGeometry {
        uv,
        shading,
        dpdu: shading.s * 1.7 + tilt,
        dpdv: shading.t * 0.6 - tilt,
        ng: (n + tilt * 0.2).normalize(),
        wo: Vec3::new(wo.x, wo.y, wo.z.abs()),
    }
}

/// The BSDFs a material gives at uv points over [0, 1]^2 (and outside, where textures
/// wrap), resolved at random hits where it perturbs the frame.
fn instances(m: &Material, rng: &mut Pcg32) -> Vec<Bsdf> {
    let mut uvs: Vec<Vec2> = Vec::new();
    if m.is_plain() {
        uvs.push(Vec2::new(0.5, 0.5));
    } else {
        for i in 0..5 {
            for j in 0..5 {
                uvs.push(Vec2::new(i as f32 / 4.0, j as f32 / 4.0));
            }
        }
        for _ in 0..15 {
            let [u, v] = rng.next_2d();
            uvs.push(Vec2::new(3.0 * u - 1.0, 3.0 * v - 1.0));
        }
    }
    let mut out = Vec::new();
    for uv in uvs {
        let b = m.at(uv);
        if b.perturbs() {
            for _ in 0..4 {
                let mut r = b.clone();
                r.resolve_frames(&random_hit(rng, uv));
                out.push(r);
            }
        } else {
            out.push(b);
        }
    }
    out
}

#[test]
fn every_material_of_the_bundled_scenes_agrees_bit_for_bit() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "xml"))
        .collect();
    files.sort();
    assert!(files.len() >= 20, "{} scenes", files.len());
    let mut rng = Pcg32::new(0xb5df, 7);
    let mut seen = BTreeSet::new();
    let (mut materials, mut instances_checked, mut total) = (0, 0, Tally::default());
    for file in &files {
        let scene = Scene::load(file, &Overrides::default())
            .unwrap_or_else(|e| panic!("{}: {e}", file.display()));
        for (i, m) in scene.bsdfs.iter().enumerate() {
            materials += 1;
            for b in instances(m, &mut rng) {
                kinds(&b, &mut seen);
                let wos = outgoing(&mut rng, 12);
                let pairs = pairs_for(&b, &mut rng, &wos, 12);
                let mut t = Tally::default();
                check(&b, &pairs, &mut t);
                assert_clean(&format!("{} material {i}", file.display()), &t);
                instances_checked += 1;
                total.pairs += t.pairs;
                total.live += t.live;
                total.nans += t.nans;
            }
        }
    }
    // The scenes' materials cover every kind.
    let missing: Vec<_> = ALL_KINDS.iter().filter(|k| !seen.contains(*k)).collect();
    eprintln!(
        "{} scenes, {materials} materials, {instances_checked} instances, kinds {seen:?}, \
         {} pairs ({} live, {} NaN)",
        files.len(),
        total.pairs,
        total.live,
        total.nans
    );
    assert!(missing.is_empty(), "kinds in no scene: {missing:?}");
    assert!(
        total.live * 5 > total.pairs,
        "too few live pairs: {total:?}"
    );
}

/// A model whose `eval_pdf` returns the right numbers rounded differently: the density
/// as `cos / pi` instead of `cos * (1 / pi)` (off by an ulp at some cosines), or the
/// value with its product associated the other way.
struct Rounded {
    inner: Diffuse,
    value: bool,
}

impl BsdfModel for Rounded {
    fn flags(&self, wo: Vec3) -> BsdfFlags {
        self.inner.flags(wo)
    }
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        self.inner.eval(wo, wi)
    }
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.inner.pdf(wo, wi)
    }
    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return (Rgb::ZERO, 0.0);
        }
        if self.value {
            (self.inner.reflectance * FRAC_1_PI * wi.z, self.pdf(wo, wi))
        } else {
            (self.eval(wo, wi), wi.z / PI)
        }
    }
    fn sample(&self, wo: Vec3, u1: f32, u2: [f32; 2]) -> Option<BsdfSample> {
        self.inner.sample(wo, u1, u2)
    }
    fn albedo(&self, wo: Vec3) -> Rgb {
        self.inner.albedo(wo)
    }
}

#[test]
fn an_override_rounded_differently_is_rejected() {
    let mut rng = Pcg32::new(3, 3);
    for value in [false, true] {
        let b = Rounded {
            inner: Diffuse {
                reflectance: rgb(0.3, 0.7, 0.9),
            },
            value,
        };
        let wos = outgoing(&mut rng, 20);
        let pairs = pairs_for(&b, &mut rng, &wos, 20);
        let mut t = Tally::default();
        check(&b, &pairs, &mut t);
        assert!(t.mismatches > 0, "value {value}: {t:?}");
        eprintln!(
            "rounded differently (value {value}): {} of {} pairs caught",
            t.mismatches, t.pairs
        );
    }
}
