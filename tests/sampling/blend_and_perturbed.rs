//! `blendbsdf`'s cases, normal and bump maps (`Perturbed` with a tilted frame set by
//! hand): their weights and energy with `pplastic`'s, the shadowing term in closed form.

use crate::broken::ShadowlessSample;
use crate::harness::{diffuse, dir, furnace, reflected_energy, weight_mismatch, Case};
use crate::plastic::{pplastic_models, rough_plastic};
use crate::rough::rough;
use glam::Vec3;
use tstat::materials::perturbed::{shadow_terminator, IDENTITY};
use tstat::materials::{Blend, Bsdf, BsdfModel, MicrofacetKind, Perturbation, Perturbed, Plastic};
use tstat::math::frame::Frame;
use tstat::math::rng::Pcg32;
use tstat::math::Rgb;
use tstat::textures::Texture;

pub(crate) fn blend(weight: f32, first: Bsdf, second: Bsdf) -> Blend {
    Blend {
        weight,
        first: Box::new(first),
        second: Box::new(second),
    }
}

/// `blendbsdf` of non-delta models (and one with a delta lobe, whose delta samples
/// the chi-square test leaves out).
pub(crate) fn blend_cases() -> Vec<Case> {
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
pub(crate) fn perturbed_cases() -> Vec<Case> {
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
