//! Mesh attributes (`mesh_attribute` on PLY vertex and face properties), `rawconstant`,
//! and textured lights (`area` with a texture as radiance, `spot` with a `texture`),
//! against hand-computed values and closed forms.

use crate::common;

use glam::{Vec2, Vec3};
use tstat::lights::Emitter;
use tstat::materials::Bsdf;
use tstat::math::rng::Pcg32;
use tstat::scene::{Overrides, Scene};
use tstat::textures::{MeshAttributeTexture, TexPoint, Texture};

/// Loads `xml` from a folder that also holds `files` (name, contents).
fn load_with(xml: &str, files: &[(&str, &str)]) -> Scene {
    let dir = tempfile::tempdir().unwrap();
    for (name, text) in files {
        std::fs::write(dir.path().join(name), text).unwrap();
    }
    let path = dir.path().join("scene.xml");
    std::fs::write(&path, xml).unwrap();
    Scene::load(&path, &Overrides::default()).unwrap()
}

const HEAD: &str = r#"<scene version="3.0.0">
    <integrator type="transient_path"><integer name="max_depth" value="2"/></integrator>
    <sensor type="orthographic">
        <transform name="to_world"><scale x="1" y="1"/><lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/></transform>
        <sampler type="independent"><integer name="sample_count" value="SPP"/></sampler>
        <film type="transient_hdr_film">
            <integer name="width" value="8"/><integer name="height" value="8"/>
            <integer name="temporal_bins" value="4"/>
            <float name="start_opl" value="0"/><float name="bin_width_opl" value="20"/>
        </film>
    </sensor>"#;

/// A PLY quad (one 4-gon, split into two triangles) and a triangle: vertex colours as
/// `uchar red green blue` (Mitsuba 3.9.1 keeps them 0..255), a float `w_0`, and per
/// face `float c_r c_g c_b` and `ushort k_0` (normalised and sRGB-decoded).
const PLY: &str = "ply
format ascii 1.0
element vertex 5
property float x
property float y
property float z
property uchar red
property uchar green
property uchar blue
property float w_0
element face 2
property list uchar int vertex_indices
property float c_r
property float c_g
property float c_b
property ushort k_0
end_header
0 0 0 0 10 20 1
1 0 0 255 10 20 2
1 1 0 0 100 20 4
0 1 0 0 10 200 8
2 2 0 1 1 1 16
4 0 1 2 3 0.1 0.2 0.3 65535
3 1 4 2 0.5 0.25 0.125 1
";

fn attribute_scene() -> Scene {
    let xml = format!(
        r#"{}
    <shape type="ply"><string name="filename" value="m.ply"/>
        <bsdf type="diffuse"><texture type="mesh_attribute" name="reflectance">
            <string name="name" value="vertex_color"/><float name="scale" value="0.5"/>
        </texture></bsdf>
    </shape>
    <emitter type="point"><point name="position" x="0" y="0" z="3"/></emitter>
</scene>"#,
        HEAD.replace("SPP", "4")
    );
    load_with(&xml, &[("m.ply", PLY)])
}

fn attr(name: &str, scale: f32) -> Texture {
    Texture::MeshAttribute(MeshAttributeTexture {
        name: name.into(),
        scale,
    })
}

#[test]
fn vertex_attributes_interpolate_and_face_attributes_are_per_polygon() {
    let scene = attribute_scene();
    let shape = &scene.shapes[0];
    let a = shape.attributes().unwrap();
    assert_eq!(a.names(), "vertex_color, vertex_w, face_c_color, face_k");
    // Triangle 0 = (0, 1, 2), triangle 1 = (0, 2, 3) (the quad's fan), 2 = (1, 4, 2).
    let (b1, b2) = (0.25f32, 0.5f32);
    let p = TexPoint::on(shape, 0, b1, b2, Vec3::ZERO);
    // vertex_w: 1 * 0.25 + 2 * 0.25 + 4 * 0.5 = 2.75.
    assert_eq!(attr("vertex_w", 1.0).eval_float_at(&p), 2.75);
    assert_eq!(attr("vertex_w", 2.0).eval_rgb_at(&p), Vec3::splat(5.5));
    // A 3-channel attribute has no scalar value (Mitsuba's LLVM variants: 0).
    assert_eq!(attr("vertex_color", 1.0).eval_float_at(&p), 0.0);
    // vertex_color, raw uchar values: red 0 * .25 + 255 * .25 + 0 * .5 = 63.75, ...
    let c = attr("vertex_color", 1.0).eval_rgb_at(&p);
    assert!(
        (c - Vec3::new(63.75, 55.0, 20.0)).abs().max_element() < 1e-4,
        "{c}"
    );
    // Through the material (scale 0.5).
    let Bsdf::Diffuse(d) = scene.bsdfs[shape.bsdf as usize].at_point(&p) else {
        panic!()
    };
    assert!((d.reflectance - c * 0.5).abs().max_element() < 1e-4);
    // Face attributes: the quad's value on both of its triangles.
    for face in [0, 1] {
        let q = TexPoint::on(shape, face, 0.3, 0.1, Vec3::ZERO);
        assert_eq!(
            attr("face_c_color", 1.0).eval_rgb_at(&q),
            Vec3::new(0.1, 0.2, 0.3)
        );
        assert_eq!(attr("face_k", 1.0).eval_float_at(&q), 1.0);
    }
    let q = TexPoint::on(shape, 2, 0.3, 0.1, Vec3::ZERO);
    assert_eq!(
        attr("face_c_color", 1.0).eval_rgb_at(&q),
        Vec3::new(0.5, 0.25, 0.125)
    );
    // ushort 1: (1 / 65535) / 12.92.
    let k = attr("face_k", 1.0).eval_float_at(&q);
    assert!((k - 1.0 / 65535.0 / 12.92).abs() < 1e-12, "{k}");
    // On a point without attributes (uv-only lookups) a mesh attribute reads 0.
    assert_eq!(attr("vertex_w", 1.0).eval_rgb(Vec2::ZERO), Vec3::ZERO);
}

#[test]
fn rawconstant_is_its_value_in_every_channel_or_its_vector() {
    let xml = format!(
        r#"{}
    <shape type="rectangle"><bsdf type="diffuse"><texture type="rawconstant" name="reflectance"><float name="value" value="0.25"/></texture></bsdf></shape>
    <shape type="sphere"><point name="center" x="0" y="0" z="-5"/>
        <bsdf type="diffuse"><texture type="rawconstant" name="reflectance"><vector name="value" x="0.1" y="0.2" z="0.3"/></texture></bsdf></shape>
    <emitter type="point"><point name="position" x="0" y="0" z="3"/></emitter>
</scene>"#,
        HEAD.replace("SPP", "4")
    );
    let scene = load_with(&xml, &[]);
    let refl = |i: usize| match &scene.bsdfs[scene.shapes[i].bsdf as usize].bsdf {
        Bsdf::Diffuse(d) => d.reflectance,
        _ => panic!(),
    };
    assert_eq!(refl(0), Vec3::splat(0.25));
    assert_eq!(refl(1), Vec3::new(0.1, 0.2, 0.3));
}

/// A unit quad in z = 0 with vertex colours linear in x, lit straight down by a
/// directional light of irradiance E: a diffuse surface's radiance is rho(x) E / pi,
/// and with rho linear in x a pixel's mean is rho at the pixel's centre.
#[test]
fn a_vertex_coloured_quad_renders_rho_e_over_pi() {
    let ply = "ply
format ascii 1.0
element vertex 4
property float x
property float y
property float z
property float color_0
property float color_1
property float color_2
element face 2
property list uchar int vertex_indices
end_header
-1 -1 0 0.2 0.9 0.5
1 -1 0 0.8 0.1 0.5
1 1 0 0.8 0.1 0.5
-1 1 0 0.2 0.9 0.5
3 0 1 2
3 0 2 3
";
    let e = 2.0f32;
    let xml = format!(
        r#"{}
    <shape type="ply"><string name="filename" value="q.ply"/>
        <bsdf type="diffuse"><texture type="mesh_attribute" name="reflectance"><string name="name" value="vertex_color"/></texture></bsdf>
    </shape>
    <emitter type="directional"><vector name="direction" x="0" y="0" z="-1"/><rgb name="irradiance" value="{e}"/></emitter>
</scene>"#,
        HEAD.replace("SPP", "64")
    );
    let scene = load_with(&xml, &[("q.ply", ply)]);
    let out = common::run(&scene, 7);
    let (w, h) = (8usize, 8usize);
    let mut worst = 0.0f64;
    for y in 0..h {
        for x in 0..w {
            // Where the pixel's centre ray meets the quad.
            let (o, d) = scene
                .camera
                .ray(x as f32 + 0.5, y as f32 + 0.5, || [0.5, 0.5]);
            let hit = scene
                .accel
                .intersect(&scene.shapes, o, d, f32::INFINITY)
                .unwrap();
            let t = (hit.surface.p.x + 1.0) / 2.0;
            let rho = Vec3::new(0.2, 0.9, 0.5).lerp(Vec3::new(0.8, 0.1, 0.5), t);
            let want = rho * e / std::f32::consts::PI;
            for c in 0..3 {
                let got = out.steady[(y * w + x) * 3 + c];
                // The sub-pixel positions spread a linear ramp: the mean of 64 i.i.d.
                // positions over a pixel 1/4 wide has sd 0.6 * 0.25 / sqrt(12 * 64)
                // per unit of rho' ... at most 0.0054 E / pi here; 5 sd.
                let tol =
                    5.0 * 0.6 / 4.0 / (12.0f64 * 64.0).sqrt() * (e as f64) / std::f64::consts::PI;
                worst = worst.max((got - want[c] as f64).abs() / tol);
            }
        }
    }
    assert!(worst < 1.0, "worst error {worst} tolerances");
}

const LIGHTS_HEAD: &str = r#"<scene version="3.0.0">
    <integrator type="transient_path"><integer name="max_depth" value="1"/></integrator>
    <sensor type="orthographic">
        <transform name="to_world"><lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/></transform>
        <sampler type="independent"><integer name="sample_count" value="4"/></sampler>
        <film type="transient_hdr_film">
            <integer name="width" value="16"/><integer name="height" value="16"/>
            <integer name="temporal_bins" value="4"/>
            <float name="start_opl" value="0"/><float name="bin_width_opl" value="20"/>
        </film>
    </sensor>"#;

/// A rectangle emitting a 4 x 4 checkerboard (0.5 and 3), facing the camera.
const CHECKER_LIGHT: &str = r#"<shape type="rectangle">
        <emitter type="area"><texture type="checkerboard" name="radiance">
            <rgb name="color0" value="0.5, 0.5, 0.5"/><rgb name="color1" value="3, 2, 1"/>
            <transform name="to_uv"><scale x="2" y="2"/></transform>
        </texture></emitter>
    </shape>"#;

#[test]
fn a_checkerboard_area_light_seen_directly_renders_its_pattern() {
    let scene = load_with(&format!("{LIGHTS_HEAD}{CHECKER_LIGHT}</scene>"), &[]);
    let out = common::run(&scene, 3);
    let Emitter::TexturedArea(t) = &scene.emitters[0] else {
        panic!()
    };
    let (mut c0, mut c1) = (0, 0);
    for y in 0..16 {
        for x in 0..16 {
            // 16 pixels across the rectangle's 2 units: 4 per cell, so the pixel's
            // whole footprint lies in the cell of its centre.
            let (o, d) = scene
                .camera
                .ray(x as f32 + 0.5, y as f32 + 0.5, || [0.5, 0.5]);
            let hit = scene
                .accel
                .intersect(&scene.shapes, o, d, f32::INFINITY)
                .unwrap();
            let uv = scene.shapes[0].uv(hit.face, hit.b1, hit.b2, hit.surface.p);
            let want = t.radiance.eval_rgb(uv);
            if want.x == 0.5 {
                c0 += 1
            } else {
                c1 += 1
            }
            let got = &out.steady[(y * 16 + x) * 3..(y * 16 + x) * 3 + 3];
            for c in 0..3 {
                assert!(
                    (got[c] - want[c] as f64).abs() < 1e-6,
                    "pixel ({x}, {y}): {got:?} vs {want}"
                );
            }
        }
    }
    assert_eq!((c0, c1), (128, 128));
    // The pattern's orientation: uv (0.1, 0.1) is the corner at local (-1, -1), colour0.
    assert_eq!(t.radiance.eval_rgb(Vec2::new(0.1, 0.1)), Vec3::splat(0.5));
}

/// Irradiance at a floor point under a textured rectangle: light samples
/// (`Emitter::sample`, uniform by area, weighted by the texture) against a midpoint
/// quadrature of `L(uv) cos cos' / d^2` over the rectangle; the sampled pdf equals the
/// MIS pdf of the hit along the sample, and the radiance a hit sees equals the sample's.
#[test]
fn a_textured_area_light_casts_the_quadrature_of_its_texture() {
    let light = r#"<shape type="rectangle">
        <transform name="to_world"><rotate x="1" angle="180"/><translate z="1"/></transform>
        <emitter type="area"><texture type="checkerboard" name="radiance">
            <rgb name="color0" value="0.5, 0.5, 0.5"/><rgb name="color1" value="3, 2, 1"/>
            <transform name="to_uv"><scale x="2" y="2"/></transform>
        </texture></emitter>
    </shape>"#;
    let scene = load_with(&format!("{LIGHTS_HEAD}{light}</scene>"), &[]);
    let emitter = &scene.emitters[0];
    let Emitter::TexturedArea(t) = emitter else {
        panic!()
    };
    let x = Vec3::new(0.3, -0.2, 0.0);
    let n = Vec3::Z;
    // Quadrature: the rectangle is z = 1 over [-1, 1]^2, facing down.
    let k = 800;
    let mut reference = [0.0f64; 3];
    for i in 0..k {
        for j in 0..k {
            let (px, py) = (
                -1.0 + (i as f64 + 0.5) * 2.0 / k as f64,
                -1.0 + (j as f64 + 0.5) * 2.0 / k as f64,
            );
            let p = Vec3::new(px as f32, py as f32, 1.0);
            let hit = scene
                .accel
                .intersect(
                    &scene.shapes,
                    Vec3::new(p.x, p.y, 2.0),
                    -Vec3::Z,
                    f32::INFINITY,
                )
                .unwrap();
            let uv = scene.shapes[0].uv(hit.face, hit.b1, hit.b2, hit.surface.p);
            let l = t.radiance.eval_rgb(uv);
            let d = (p - x).as_dvec3();
            let d2 = d.length_squared();
            let g = d.z * d.z / (d2 * d2); // cos at x = cos at the light = dz / |d|
            for c in 0..3 {
                reference[c] += l[c] as f64 * g * 4.0 / (k * k) as f64;
            }
        }
    }
    let mut rng = Pcg32::new(5, 1);
    let m = 400_000;
    let (mut sum, mut sum2) = ([0.0f64; 3], [0.0f64; 3]);
    let mut mismatched = 0;
    for _ in 0..m {
        let Some(ls) = emitter.sample(&scene.shapes, x, 1.0, rng.next_f32(), rng.next_2d()) else {
            continue;
        };
        let v = ls.li * (ls.wi.dot(n) / ls.pdf);
        for c in 0..3 {
            sum[c] += v[c] as f64;
            sum2[c] += (v[c] as f64).powi(2);
        }
        // MIS consistency on the hit along the sample.
        let hit = scene
            .accel
            .intersect(&scene.shapes, x, ls.wi, f32::INFINITY)
            .unwrap();
        let cos_l = hit.surface.ns.dot(-ls.wi);
        let mis = emitter.pdf_area_hit(1.0, hit.t, cos_l);
        assert!((mis - ls.pdf).abs() <= 1e-3 * ls.pdf, "{mis} vs {}", ls.pdf);
        let seen = emitter
            .emitted(cos_l, || {
                scene.shapes[0].uv(hit.face, hit.b1, hit.b2, hit.surface.p)
            })
            .unwrap();
        if seen != ls.li {
            mismatched += 1; // a hit within rounding of a cell edge
        }
    }
    assert!(
        mismatched < m / 1000,
        "{mismatched} samples see another colour on a hit"
    );
    for c in 0..3 {
        let mean = sum[c] / m as f64;
        let sd = ((sum2[c] / m as f64 - mean * mean) / m as f64).sqrt();
        assert!(
            (mean - reference[c]).abs() < 4.0 * sd + 1e-4 * reference[c],
            "channel {c}: {mean} vs quadrature {} (sd {sd})",
            reference[c]
        );
    }
}

/// A textured spot's light on the plane z = 1 in front of it is its texture at
/// `0.5 + 0.5 (x, y) / tan(cutoff)`, times the untextured spot's intensity.
#[test]
fn a_textured_spot_projects_its_texture() {
    let spot = |texture: &str| {
        format!(
            r#"<emitter type="spot"><rgb name="intensity" value="5"/>
            <float name="cutoff_angle" value="30"/><float name="beam_width" value="20"/>
            <transform name="to_world"><lookat origin="0, 0, 0" target="0, 0, 1" up="0, 1, 0"/></transform>
            {texture}</emitter>"#
        )
    };
    let checker = r#"<texture type="checkerboard" name="texture"><rgb name="color0" value="1, 0.5, 0.25"/><rgb name="color1" value="0.1"/></texture>"#;
    let scene = load_with(&format!("{LIGHTS_HEAD}{}</scene>", spot(checker)), &[]);
    let plain = load_with(&format!("{LIGHTS_HEAD}{}</scene>", spot("")), &[]);
    let tan = 30f32.to_radians().tan();
    let mut checked = 0;
    for (px, py) in [
        (0.1f32, 0.1f32),
        (0.2, -0.15),
        (-0.3, 0.05),
        (-0.1, -0.2),
        (0.45, 0.3),
        (0.0, 0.6),
    ] {
        let x = Vec3::new(px, py, 1.0);
        let Some(ls) = scene.emitters[0].sample(&scene.shapes, x, 1.0, 0.5, [0.5, 0.5]) else {
            assert!(plain.emitters[0]
                .sample(&plain.shapes, x, 1.0, 0.5, [0.5, 0.5])
                .is_none());
            continue;
        };
        let base = plain.emitters[0]
            .sample(&plain.shapes, x, 1.0, 0.5, [0.5, 0.5])
            .unwrap();
        let uv = Vec2::new(0.5 + 0.5 * px / tan, 0.5 + 0.5 * py / tan);
        // Mitsuba's checkerboard: colour0 where both fractional parts are on one side.
        let want = if (uv.x > 0.5) == (uv.y > 0.5) {
            Vec3::new(1.0, 0.5, 0.25)
        } else {
            Vec3::splat(0.1)
        };
        assert!(
            (ls.li - base.li * want).abs().max_element() <= 1e-6 * base.li.max_element(),
            "{x}: {} vs {}",
            ls.li,
            base.li * want
        );
        assert!(ls.delta && ls.pdf == 1.0 && ls.wi == base.wi && ls.dist == base.dist);
        checked += 1;
    }
    assert_eq!(checked, 5, "one point lies outside the cone");
    // A texture of ones renders the untextured spot's bits.
    let ones = r#"<texture type="checkerboard" name="texture"><float name="color0" value="1"/><float name="color1" value="1"/></texture>"#;
    let floor = r#"<shape type="rectangle"><transform name="to_world"><scale value="3"/></transform></shape>"#;
    let spot = |t: &str| {
        spot(t).replace(
            r#"origin="0, 0, 0" target="0, 0, 1""#,
            r#"origin="0.1, 0, 2" target="0, 0, 0""#,
        )
    };
    let head = LIGHTS_HEAD.replace(
        r#"<integer name="max_depth" value="1"/>"#,
        r#"<integer name="max_depth" value="3"/>"#,
    );
    let a = load_with(&format!("{head}{floor}{}</scene>", spot(ones)), &[]);
    let b = load_with(&format!("{head}{floor}{}</scene>", spot("")), &[]);
    let (ra, rb) = (common::run(&a, 9), common::run(&b, 9));
    assert!(ra.steady.iter().any(|v| *v > 0.0));
    assert_eq!(ra.steady, rb.steady);
}

/// `AreaSampler::sample_with_uv` draws the same points as `sample` (which the
/// uniformity chi-square of tests/sampling/emitters.rs checks).
#[test]
fn textured_light_samples_are_the_untextured_samplers_points() {
    let scene = load_with(&format!("{LIGHTS_HEAD}{CHECKER_LIGHT}</scene>"), &[]);
    let Emitter::TexturedArea(t) = &scene.emitters[0] else {
        panic!()
    };
    let shape = &scene.shapes[0];
    let mut rng = Pcg32::new(1, 2);
    for _ in 0..1000 {
        let (u1, u2) = (rng.next_f32(), rng.next_2d());
        let (s, uv) = t.sampler.sample_with_uv(shape, u1, u2);
        let plain = t.sampler.sample(shape, u1, u2);
        assert_eq!(s.p, plain.p);
        // The rectangle's uv: ((x + 1) / 2, (y + 1) / 2).
        assert!(
            (uv - Vec2::new((s.p.x + 1.0) / 2.0, (s.p.y + 1.0) / 2.0))
                .abs()
                .max_element()
                < 1e-6
        );
    }
}
