//! Infinitely distant emitters: envmap and constant directions by chi-square against
//! the escape pdf, light samples = the density, radiance and distance of an escaping
//! ray.

use crate::emitters::ENVIRONMENT_CASES;
use crate::harness::{chi2_of_samples, pdf_cell_integrals};
use crate::LEVEL;
use glam::Vec3;
use std::sync::Arc;
use tstat::lights::envmap::EnvMap;
use tstat::lights::scene_sphere::SceneSphere;
use tstat::lights::Emitter;
use tstat::math::rng::Pcg32;
use tstat::math::Rgb;

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
