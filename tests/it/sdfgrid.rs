//! `sdfgrid` (Mitsuba 3's SDF grid shape): a `.vol` grid written here sampling the
//! signed distance of a sphere, placed by a rotating, scaling and translating
//! `to_world`. Intersections are checked against a slow reference written here (the
//! trilinear SDF marched densely along the ray in world space, sign changes bisected),
//! normals against the sphere's, and a render against the analytic sphere.

use glam::{DMat4, DQuat, DVec3, Vec3};
use std::path::Path;
use tstat::geometry::accel::Accel;
use tstat::geometry::shape::ShapeGeom;
use tstat::math::rng::Pcg32;
use tstat::scene::{Overrides, Scene};

use crate::common;
use common::run;

/// The sphere in object space ([0, 1]^3).
const CENTER: f64 = 0.5;
const RADIUS: f64 = 0.3;

/// `n^3` samples of the sphere's signed distance at the grid points (x fastest).
fn sphere_values(n: usize) -> Vec<f32> {
    let mut v = Vec::with_capacity(n * n * n);
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                let p = DVec3::new(x as f64, y as f64, z as f64) / (n - 1) as f64;
                v.push(((p - DVec3::splat(CENTER)).length() - RADIUS) as f32);
            }
        }
    }
    v
}

/// A Mitsuba `.vol` file (version 3, float32, one channel), written out by hand.
fn write_vol(path: &Path, n: [usize; 3], values: &[f32]) {
    let mut b = b"VOL\x03".to_vec();
    for v in [1, n[0] as i32, n[1] as i32, n[2] as i32, 1] {
        b.extend(v.to_le_bytes());
    }
    for v in [0.0f32, 0.0, 0.0, 1.0, 1.0, 1.0] {
        b.extend(v.to_le_bytes());
    }
    for v in values {
        b.extend(v.to_le_bytes());
    }
    std::fs::write(path, b).unwrap();
}

/// The test's placement of the grid: scale 2, a rotation, a translation.
const TO_WORLD_XML: &str = r#"<scale value="2"/><rotate x="0.6" y="0.8" z="0" angle="40"/><translate x="1" y="-0.5" z="0.3"/>"#;

fn to_world() -> DMat4 {
    DMat4::from_translation(DVec3::new(1.0, -0.5, 0.3))
        * DMat4::from_quat(DQuat::from_axis_angle(
            DVec3::new(0.6, 0.8, 0.0),
            40f64.to_radians(),
        ))
        * DMat4::from_scale(DVec3::splat(2.0))
}

fn scene_xml(shape: &str, film: u32, spp: u32) -> String {
    format!(
        r#"<scene version="3.0.0">
  <integrator type="transient_path"><integer name="max_depth" value="2"/></integrator>
  <sensor type="perspective">
    <float name="fov" value="30"/>
    <transform name="to_world"><lookat origin="2,-5,1.5" target="2,0,1" up="0,0,1"/></transform>
    <sampler type="independent"><integer name="sample_count" value="{spp}"/></sampler>
    <film type="transient_hdr_film">
      <integer name="width" value="{film}"/><integer name="height" value="{film}"/>
      <integer name="temporal_bins" value="8"/><float name="start_opl" value="4"/><float name="bin_width_opl" value="1"/>
    </film>
  </sensor>
  <emitter type="point"><point name="position" x="0" y="-4" z="4"/><rgb name="intensity" value="30"/></emitter>
  {shape}
</scene>"#
    )
}

fn sdf_shape(vol: &Path, normals: &str) -> String {
    format!(
        r#"<shape type="sdfgrid"><string name="filename" value="{}"/><string name="normals" value="{normals}"/>
             <transform name="to_world">{TO_WORLD_XML}</transform></shape>"#,
        vol.display()
    )
}

fn load_text(dir: &Path, xml: &str) -> Scene {
    let path = dir.join("scene.xml");
    std::fs::write(&path, xml).unwrap();
    Scene::load(&path, &Overrides::default()).unwrap()
}

/// The reference SDF: the grid's trilinear interpolant at a world point (None outside
/// the grid's [0, 1]^3).
struct Reference {
    n: usize,
    values: Vec<f32>,
    to_object: DMat4,
}

impl Reference {
    fn f(&self, w: DVec3) -> Option<f64> {
        let q = self.to_object.transform_point3(w) * (self.n - 1) as f64;
        let top = (self.n - 1) as f64;
        // (Rounding at the box's faces: a point a hair outside is on the face.)
        if q.min_element() < -1e-9 || q.max_element() > top + 1e-9 {
            return None;
        }
        let q = q.clamp(DVec3::ZERO, DVec3::splat(top));
        let i = q.floor().min(DVec3::splat(top - 1.0));
        let t = q - i;
        let at = |dx: usize, dy: usize, dz: usize| {
            let (x, y, z) = (i.x as usize + dx, i.y as usize + dy, i.z as usize + dz);
            self.values[x + self.n * (y + self.n * z)] as f64
        };
        let mut s = 0.0;
        for c in 0..8 {
            let (dx, dy, dz) = (c & 1, c >> 1 & 1, c >> 2);
            let w = (if dx == 1 { t.x } else { 1.0 - t.x })
                * (if dy == 1 { t.y } else { 1.0 - t.y })
                * (if dz == 1 { t.z } else { 1.0 - t.z });
            s += w * at(dx, dy, dz);
        }
        Some(s)
    }

    /// The first zero of F along the ray beyond t = 0: march in steps of `h`, bisect
    /// the first sign change (or take an exact zero).
    fn first_hit(&self, o: DVec3, d: DVec3, h: f64) -> Option<f64> {
        // The ray's stretch inside the grid, in object space.
        let (lo, ld) = (
            self.to_object.transform_point3(o),
            self.to_object.transform_vector3(d),
        );
        let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
        for a in 0..3 {
            let (ta, tb) = ((0.0 - lo[a]) / ld[a], (1.0 - lo[a]) / ld[a]);
            t0 = t0.max(ta.min(tb));
            t1 = t1.min(ta.max(tb));
        }
        if t0 >= t1 {
            return None;
        }
        let at = |t: f64| self.f(o + d * t);
        let mut a = t0;
        let mut fa = at(a)?;
        if fa == 0.0 && a > 0.0 {
            return Some(a);
        }
        while a < t1 {
            let b = (a + h).min(t1);
            let Some(fb) = at(b) else { break };
            if fb == 0.0 {
                return Some(b);
            }
            if fa * fb < 0.0 {
                let (mut x, mut y) = (a, b);
                for _ in 0..80 {
                    let m = 0.5 * (x + y);
                    if at(m).unwrap() * fa > 0.0 {
                        x = m;
                    } else {
                        y = m;
                    }
                }
                return Some(0.5 * (x + y));
            }
            (a, fa) = (b, fb);
        }
        None
    }
}

fn sphere_scene(dir: &Path, n: usize, normals: &str) -> (Scene, Reference) {
    let values = sphere_values(n);
    let vol = dir.join(format!("sphere{n}.vol"));
    write_vol(&vol, [n; 3], &values);
    let scene = load_text(dir, &scene_xml(&sdf_shape(&vol, normals), 8, 4));
    let ShapeGeom::Sdf(g) = &scene.shapes[0].geom else {
        panic!("not an sdfgrid")
    };
    // The XML transform is the one the reference uses.
    assert!(
        g.to_world.abs_diff_eq(to_world(), 1e-12),
        "{}\n{}",
        g.to_world,
        to_world()
    );
    let reference = Reference {
        n,
        values,
        to_object: to_world().inverse(),
    };
    (scene, reference)
}

fn world_center() -> DVec3 {
    to_world().transform_point3(DVec3::splat(CENTER))
}

/// Random rays: from a sphere of radius 3 around the grid towards points near its
/// centre (most hit, some graze or miss), and a fifth from inside the grid's box in
/// random directions (some start inside the SDF's sphere and leave it).
fn rays(count: usize, seed: u64) -> Vec<(Vec3, Vec3)> {
    let mut rng = Pcg32::new(seed, 3);
    let mut unit = || {
        let z = 2.0 * rng.next_f32() as f64 - 1.0;
        let phi = std::f64::consts::TAU * rng.next_f32() as f64;
        let r = (1.0 - z * z).sqrt();
        let u = rng.next_f32() as f64;
        (DVec3::new(r * phi.cos(), r * phi.sin(), z), u)
    };
    let c = world_center();
    (0..count)
        .map(|i| {
            let (a, _) = unit();
            let (b, u) = unit();
            let (o, target) = if i % 5 == 4 {
                let local = DVec3::new(0.5, 0.5, 0.5) + a * 0.45 * u.cbrt();
                (
                    to_world().transform_point3(local),
                    to_world().transform_point3(local) + b,
                )
            } else {
                (c + a * 3.0, c + b * 0.75 * u.cbrt())
            };
            let d = (target - o).normalize();
            (o.as_vec3(), d.as_vec3())
        })
        .collect()
}

#[test]
fn hits_are_the_first_zero_of_the_trilinear_sdf() {
    let dir = tempfile::tempdir().unwrap();
    let n = 17;
    let (scene, reference) = sphere_scene(dir.path(), n, "smooth");
    // March in 1/400 of a voxel (world voxel size 2 / (n - 1)).
    let h = 2.0 / (n - 1) as f64 / 400.0;
    let (mut hits, mut misses, mut from_inside) = (0, 0, 0);
    for (o, d) in rays(3000, 7) {
        let got = scene.accel.intersect(&scene.shapes, o, d, f32::INFINITY);
        let want = reference.first_hit(o.as_dvec3(), d.as_dvec3(), h);
        match (got, want) {
            (Some(g), Some(w)) => {
                assert!(
                    (g.t as f64 - w).abs() <= 2e-6 * w.max(1.0),
                    "o {o} d {d}: t {} vs reference {w}",
                    g.t
                );
                hits += 1;
                if reference.f(o.as_dvec3()).is_some_and(|f| f < 0.0) {
                    from_inside += 1;
                }
            }
            (None, None) => misses += 1,
            (g, w) => panic!("o {o} d {d}: tstat {:?}, reference {w:?}", g.map(|g| g.t)),
        }
    }
    assert!(
        hits > 1500 && misses > 300 && from_inside > 100,
        "{hits} {misses} {from_inside}"
    );
}

/// The BVH over the voxels' tight boxes finds what testing every voxel finds (the
/// boxes hide no surface), and shadow rays agree with the closest hit.
#[test]
fn tight_boxes_hide_nothing_and_shadow_rays_agree() {
    let dir = tempfile::tempdir().unwrap();
    let (scene, _) = sphere_scene(dir.path(), 17, "smooth");
    let bvh = &scene.accel;
    let every = Accel::build_with(&scene.shapes, usize::MAX);
    let mut hits = 0;
    for (o, d) in rays(3000, 13) {
        let (a, b) = (
            bvh.intersect(&scene.shapes, o, d, f32::INFINITY),
            every.intersect(&scene.shapes, o, d, f32::INFINITY),
        );
        assert_eq!(
            a.map(|h| (h.t, h.face)),
            b.map(|h| (h.t, h.face)),
            "o {o} d {d}"
        );
        if let Some(h) = a {
            assert!(bvh.occluded(o, d, h.t * 1.0001) && every.occluded(o, d, h.t * 1.0001));
            assert!(!bvh.occluded(o, d, h.t * 0.9999) && !every.occluded(o, d, h.t * 0.9999));
            hits += 1;
        }
    }
    assert!(hits > 1500, "{hits}");
}

/// An instance of a grid is the grid under the composed transform: the same hits.
#[test]
fn an_instance_is_the_grid_under_the_composed_transform() {
    let dir = tempfile::tempdir().unwrap();
    let vol = dir.path().join("s.vol");
    write_vol(&vol, [9; 3], &sphere_values(9));
    let inner = r#"<rotate z="1" angle="25"/><translate x="0.1"/>"#;
    let outer = TO_WORLD_XML;
    let grid = |t: &str| {
        format!(
            r#"<shape type="sdfgrid"><string name="filename" value="{}"/><transform name="to_world">{t}</transform></shape>"#,
            vol.display()
        )
    };
    let instanced = format!(
        r#"<shape type="shapegroup" id="g">{}</shape><shape type="instance"><ref id="g"/><transform name="to_world">{outer}</transform></shape>"#,
        grid(inner)
    );
    let a = load_text(dir.path(), &scene_xml(&instanced, 8, 4));
    let b = load_text(
        dir.path(),
        &scene_xml(&grid(&format!("{inner}{outer}")), 8, 4),
    );
    let mut hits = 0;
    for (o, d) in rays(2000, 17) {
        let (x, y) = (
            a.accel.intersect(&a.shapes, o, d, f32::INFINITY),
            b.accel.intersect(&b.shapes, o, d, f32::INFINITY),
        );
        match (x, y) {
            (Some(x), Some(y)) => {
                assert!((x.t - y.t).abs() <= 1e-5 * x.t, "{} {}", x.t, y.t);
                assert!(x.surface.ng.dot(y.surface.ng) > 0.9999);
                assert!(x.surface.ns.dot(y.surface.ns) > 0.9999);
                hits += 1;
            }
            (None, None) => {}
            _ => panic!("o {o} d {d}: one hit, one miss"),
        }
    }
    assert!(hits > 300, "{hits}");
}

#[test]
fn normals_follow_the_sphere_within_the_grid_error() {
    let dir = tempfile::tempdir().unwrap();
    // Worst angle to the sphere's normal: [n = 17, n = 33] x [geometric, analytic
    // shading, smooth shading].
    let mut worst = [[0f64; 3]; 2];
    for (i, n) in [17, 33].into_iter().enumerate() {
        let h = 1.0 / (n - 1) as f64;
        for normals in ["analytic", "smooth"] {
            let (scene, _) = sphere_scene(dir.path(), n, normals);
            let c = world_center();
            let (mut count, mut worst_r) = (0, 0f64);
            for (o, d) in rays(2000, 11) {
                let Some(hit) = scene.accel.intersect(&scene.shapes, o, d, f32::INFINITY) else {
                    continue;
                };
                let p = hit.surface.p.as_dvec3();
                let truth = (p - c).normalize();
                let angle = |v: Vec3| v.as_dvec3().dot(truth).clamp(-1.0, 1.0).acos();
                worst[i][0] = worst[i][0].max(angle(hit.surface.ng));
                let k = if normals == "analytic" { 1 } else { 2 };
                worst[i][k] = worst[i][k].max(angle(hit.surface.ns));
                if normals == "analytic" {
                    assert_eq!(hit.surface.ng, hit.surface.ns);
                }
                // The hit lies on the trilinear surface, near the sphere: the
                // interpolation error of |x - c| - R is at most 3 h^2 / (8 r) (object
                // units: the linear interpolation error h^2 f'' / 8 along each of three
                // axes, f'' <= 1 / r for r >= R - h), the world scale being 2.
                worst_r = worst_r.max(((p - c).length() / 2.0 - RADIUS).abs());
                count += 1;
            }
            assert!(count > 1000, "{count}");
            assert!(
                worst_r <= 3.0 * h * h / (8.0 * (RADIUS - h)),
                "n {n}: {worst_r}"
            );
        }
        // The gradient of a linear interpolant is off by about h |f''| <= h / R: the
        // angle stays below h / R (12 degrees at n = 17, 6 at n = 33) for all three.
        for (k, w) in worst[i].iter().enumerate() {
            assert!(*w <= h / RADIUS, "n {n} normal {k}: {w}");
        }
        eprintln!(
            "n {n}: worst angles geometric / analytic / smooth {:.4?} (h/R {:.4})",
            worst[i],
            h / RADIUS
        );
    }
    // First order: halving the voxel halves the error (within 20%).
    for k in 0..2 {
        assert!(worst[1][k] < 0.6 * worst[0][k], "{worst:?}");
    }
    // Smooth normals (unit gradients blended between voxel centres) are second
    // order: well inside (h / R)^2, a quarter of it at half the voxel size.
    for (i, n) in [17, 33].into_iter().enumerate() {
        let h = 1.0 / (n - 1) as f64;
        assert!(worst[i][2] <= (h / RADIUS).powi(2) * 0.5, "{worst:?}");
    }
    assert!(worst[1][2] < 0.35 * worst[0][2], "{worst:?}");
}

/// The sdfgrid sphere renders as the analytic sphere of the same radius, up to the
/// grid's discretisation. With a point light and max_depth 2 each sample is one
/// camera ray and one deterministic light sample, and both scenes draw the same
/// sub-pixel positions (same seed): the images differ only by geometry.
#[test]
fn renders_as_the_analytic_sphere_within_the_discretisation() {
    let dir = tempfile::tempdir().unwrap();
    let c = world_center();
    let sphere = format!(
        r#"<shape type="sphere"><point name="center" x="{}" y="{}" z="{}"/><float name="radius" value="{}"/></shape>"#,
        c.x,
        c.y,
        c.z,
        2.0 * RADIUS
    );
    let film = 48;
    let analytic = run(&load_text(dir.path(), &scene_xml(&sphere, film, 4)), 5).steady;
    let interior = |i: usize| {
        let (y, x) = (
            (i / 3 / film as usize) as i64,
            (i / 3 % film as usize) as i64,
        );
        (-1..=1).all(|dy| {
            (-1..=1).all(|dx| {
                let (yy, xx) = (y + dy, x + dx);
                (0..film as i64).contains(&yy)
                    && (0..film as i64).contains(&xx)
                    && analytic[((yy * film as i64 + xx) * 3) as usize] > 0.0
            })
        })
    };
    let peak = analytic.iter().cloned().fold(0.0, f64::max);
    let mut worst = Vec::new();
    for n in [17, 33] {
        let vol = dir.path().join("s.vol");
        write_vol(&vol, [n; 3], &sphere_values(n));
        let sdf = run(
            &load_text(dir.path(), &scene_xml(&sdf_shape(&vol, "smooth"), film, 4)),
            5,
        )
        .steady;
        let (mut inner, mut edge) = (0f64, 0usize);
        for i in 0..sdf.len() {
            let diff = (sdf[i] - analytic[i]).abs() / peak;
            if interior(i) {
                inner = inner.max(diff);
            } else if diff > 0.0 {
                edge += 1;
            }
        }
        // Interior pixels: the smooth normal is within (h / R)^2 / 2 rad of the
        // sphere's (`normals_follow_the_sphere_within_the_grid_error`), so the cosine
        // moves by at most that; the hit moves by at most 3 h^2 / (8 (R - h)) (object
        // units, x2 in the world) along the normal, changing the 1 / r^2 falloff and
        // the cosine by less than 1% of it at the light's distance (> 4).
        let h = 1.0 / (n - 1) as f64;
        let bound = (h / RADIUS).powi(2) * 0.5 + 0.01;
        eprintln!(
            "n {n}: interior worst {inner:.5} (bound {bound:.5}), {edge} differing edge values"
        );
        assert!(inner <= bound, "n {n}: {inner} > {bound}");
        // Edge pixels: those with the silhouette or background in their 3x3 block.
        assert!(edge < 3 * 4 * film as usize, "{edge}");
        worst.push(inner);
    }
    // Second order, as the normals.
    assert!(worst[1] < 0.35 * worst[0], "{worst:?}");
}
