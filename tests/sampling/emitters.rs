//! Area lights: the sampled pdf = the MIS pdf on a hit, samples uniform by area; the
//! number of light cases in the family.

use crate::LEVEL;
use glam::Vec3;
use statrs::distribution::{ChiSquared, ContinuousCDF};
use std::f64::consts::PI;
use tstat::geometry::shape::ShapeGeom;
use tstat::lights::Emitter;
use tstat::math::rng::Pcg32;

/// Light cases in the family: per area emitter, the area-uniformity chi-square test;
/// the envmap's and the constant emitter's direction chi-square tests.
pub(crate) const LIGHT_CASES: usize = AREA_LIGHT_CASES + ENVIRONMENT_CASES;
const AREA_LIGHT_CASES: usize = 5;
pub(crate) const ENVIRONMENT_CASES: usize = 2;

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
                        unreachable!("the light scene has no infinitely distant or textured lights (see tests/it/textured.rs)")
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
