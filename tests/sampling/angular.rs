//! `angulararea` lights: samples by chi-square against their MIS pdf, power against
//! the closed form.

use crate::harness::MIN_EXPECTED;
use crate::LEVEL;
use glam::Vec3;
use statrs::distribution::{ChiSquared, ContinuousCDF};
use std::f64::consts::PI;
use tstat::lights::Emitter;
use tstat::math::rng::Pcg32;
use tstat::math::Rgb;

/// Tests of the `angulararea` light in the family: the chi-square of its light samples
/// against its MIS pdf, and its emitted power against the closed form.
pub(crate) const ANGULAR_CASES: usize = 2;

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
