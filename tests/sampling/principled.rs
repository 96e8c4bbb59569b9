//! `principled` and `principledthin`: weights, energy against quadrature,
//! reciprocity, white-furnace bounds, Burley's diffuse and retro-reflection in closed
//! form.

use crate::broken::PrincipledWithoutRadianceScale;
use crate::harness::{
    asymmetry, dir, furnace, refraction_asymmetry, scattered_energy, weight_mismatch,
};
use std::f64::consts::PI;
use tstat::materials::{BsdfModel, Principled, PrincipledThin};
use tstat::math::rng::Pcg32;
use tstat::math::Rgb;

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
pub(crate) fn principled_models() -> Vec<(&'static str, Box<dyn BsdfModel>, f64, f32)> {
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
