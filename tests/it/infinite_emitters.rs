//! Infinitely distant emitters (`envmap`, `constant`, `directional`) through the
//! renderer: closed forms, Mitsuba's orientation of the environment image, the time of
//! arrival (2 R after the last vertex), and what camera rays that leave the scene see.
//! The sampling itself is in `tests/sampling/environment.rs`; agreement with
//! mitransient in `tests/it/render_physics.rs`.

use std::f64::consts::PI;
use std::path::Path;
use tstat::render::RenderOutput;
use tstat::scene::{Overrides, Scene};

use crate::common;
use common::run;

/// Loads scene text from `dir` (where its image files are).
fn load_in(dir: &Path, xml: &str) -> Scene {
    let path = dir.join("scene.xml");
    std::fs::write(&path, xml).unwrap();
    Scene::load(&path, &Overrides::default()).unwrap()
}

fn scene(integrator: &str, sensor: &str, film: &str, body: &str) -> String {
    format!(
        r#"<scene version="3.0.0">
  <integrator type="transient_path">{integrator}</integrator>
  <sensor type="perspective">
    {sensor}
    <film type="transient_hdr_film">{film}</film>
  </sensor>
  {body}
</scene>"#
    )
}

/// Per-pixel steady values of channel `c`.
fn channel(out: &RenderOutput, c: usize) -> Vec<f64> {
    out.steady.iter().skip(c).step_by(3).copied().collect()
}

/// A diffuse sphere (albedo a) inside a constant environment of radiance L, nothing
/// else: convex, so it never sees itself, and its radiance is exactly a L everywhere
/// (the integral of a / pi cos over the hemisphere times L). Pixels that see only the
/// environment are exactly L. Every bin sum is the steady value.
#[test]
fn white_furnace_a_diffuse_sphere_under_constant_radiance_is_albedo_times_radiance() {
    let xml = scene(
        "",
        r#"<float name="fov" value="30"/>
    <transform name="to_world"><lookat origin="0,0,5" target="0,0,0" up="0,1,0"/></transform>
    <sampler type="independent"><integer name="sample_count" value="64"/></sampler>"#,
        r#"<integer name="width" value="16"/><integer name="height" value="16"/>
    <integer name="temporal_bins" value="60"/>
    <float name="start_opl" value="0"/><float name="bin_width_opl" value="0.5"/>"#,
        r#"<emitter type="constant"><rgb name="radiance" value="1, 2, 3"/></emitter>
  <shape type="sphere"><float name="radius" value="1"/>
    <bsdf type="diffuse"><rgb name="reflectance" value="0.5, 0.25, 0.8"/></bsdf></shape>"#,
    );
    let dir = tempfile::tempdir().unwrap();
    let scene = load_in(dir.path(), &xml);
    let out = run(&scene, 5);
    let px = scene.film.pixels();
    let l = [1.0, 2.0, 3.0];
    let a = [0.5, 0.25, 0.8];
    let on_sphere: Vec<usize> = (0..px).filter(|&p| out.gbuffer[p].emitter == 0.0).collect();
    let background: Vec<usize> = (0..px).filter(|&p| out.gbuffer[p].emitter == 1.0).collect();
    assert!(on_sphere.len() > 40 && background.len() > 40);
    for c in 0..3 {
        let v = channel(&out, c);
        // Pixel means are i.i.d.: their spread gives the error of their mean.
        let m = on_sphere.iter().map(|&p| v[p]).sum::<f64>() / on_sphere.len() as f64;
        let var = on_sphere.iter().map(|&p| (v[p] - m).powi(2)).sum::<f64>()
            / (on_sphere.len() - 1) as f64;
        let se = (var / on_sphere.len() as f64).sqrt();
        let want = a[c] * l[c];
        assert!(
            (m - want).abs() <= 4.0 * se + 1e-5 * want,
            "channel {c}: {m} vs {want} (se {se})"
        );
        assert!(se < 0.02 * want, "too noisy to say: se {se}");
        for &p in &background {
            assert!((v[p] - l[c]).abs() <= 1e-6 * l[c], "pixel {p}: {}", v[p]);
        }
    }
    // Every arrival is inside the window: the bins sum to the steady image.
    let t = scene.film.time.bins;
    let n = scene.spp as f64;
    for p in 0..px {
        for c in 0..3 {
            let sum: f64 = (0..t).map(|k| out.accum.x1[(p * t + k) * 3 + c] / n).sum();
            let steady = out.steady[p * 3 + c];
            assert!(
                (sum - steady).abs() <= 1e-12 * steady,
                "pixel {p}: {sum} vs {steady}"
            );
        }
    }
}

/// Writes an RGB f32 OpenEXR of `w x h` texels.
fn write_exr(path: &Path, w: usize, h: usize, f: impl Fn(usize, usize) -> [f32; 3] + Sync) {
    exr::prelude::write_rgb_file(path, w, h, |x, y| {
        let [r, g, b] = f(x, y);
        (r, g, b)
    })
    .unwrap();
}

/// Mitsuba's direction of the texel centre (x, y) of a `w x h` environment image, in
/// the emitter's frame (`envmap.cpp`: u = (x + 1/2) / w, v = y / (h - 1), phi = 2 pi u,
/// theta = pi v, d = (sin phi sin theta, cos theta, -cos phi sin theta)), then turned
/// by 90 degrees about +y (the scene's `to_world`).
fn texel_direction(x: usize, y: usize, w: usize, h: usize) -> [f64; 3] {
    let (u, v) = ((x as f64 + 0.5) / w as f64, y as f64 / (h - 1) as f64);
    let (phi, theta) = (2.0 * PI * u, PI * v);
    let d = [
        phi.sin() * theta.sin(),
        theta.cos(),
        -phi.cos() * theta.sin(),
    ];
    // rotate y by +90 degrees: (x, y, z) -> (z, y, -x)
    [d[2], d[1], -d[0]]
}

/// Renders the value a 1 x 1-pixel camera with a tiny field of view at the origin sees
/// looking along `d` at the environment `file` (scale 2, turned about +y).
fn look(dir: &Path, file: &str, d: [f64; 3]) -> [f64; 3] {
    let up = if d[1].abs() > 0.9 { "1,0,0" } else { "0,1,0" };
    let xml = scene(
        "",
        &format!(
            r#"<float name="fov" value="0.001"/>
    <transform name="to_world"><lookat origin="0,0,0" target="{},{},{}" up="{up}"/></transform>
    <sampler type="independent"><integer name="sample_count" value="4"/></sampler>"#,
            d[0], d[1], d[2]
        ),
        r#"<integer name="width" value="1"/><integer name="height" value="1"/>
    <integer name="temporal_bins" value="1"/><float name="bin_width_opl" value="100"/>"#,
        &format!(
            r#"<emitter type="envmap"><string name="filename" value="{file}"/>
    <float name="scale" value="2"/>
    <transform name="to_world"><rotate y="1" angle="90"/></transform></emitter>"#
        ),
    );
    let scene = load_in(dir, &xml);
    let out = run(&scene, 1);
    [out.steady[0], out.steady[1], out.steady[2]]
}

/// One bright texel in a grey image: the camera ray along the direction Mitsuba's
/// convention gives that texel's centre sees its value (times scale), and rays along
/// other texels' centres see grey. Also through PNG, decoded from sRGB.
#[test]
fn camera_rays_see_the_texel_mitsubas_convention_puts_in_their_direction() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (8, 6);
    let bright = (5, 2);
    write_exr(&dir.path().join("e.exr"), w, h, |x, y| {
        if (x, y) == bright {
            [7.0, 3.0, 1.0]
        } else {
            [0.1, 0.1, 0.1]
        }
    });
    let v = look(
        dir.path(),
        "e.exr",
        texel_direction(bright.0, bright.1, w, h),
    );
    let want = [14.0, 6.0, 2.0];
    for c in 0..3 {
        assert!((v[c] - want[c]).abs() < 1e-3 * want[c], "{v:?} vs {want:?}");
    }
    // Its neighbours, the texel mirrored in u, and the poles see grey.
    for (x, y) in [
        (4, 2),
        (6, 2),
        (5, 1),
        (5, 3),
        (w - 1 - 5, 2),
        (0, 0),
        (3, h - 1),
    ] {
        let v = look(dir.path(), "e.exr", texel_direction(x, y, w, h));
        assert!(
            v.iter().all(|&c| (c - 0.2).abs() < 1e-3),
            "texel ({x}, {y}): {v:?}"
        );
    }
    // Halfway between the bright texel and the next column: the bilinear mean.
    let mid = {
        let (u, v) = (
            (bright.0 as f64 + 1.0) / w as f64,
            bright.1 as f64 / (h - 1) as f64,
        );
        let (phi, theta) = (2.0 * PI * u, PI * v);
        let d = [
            phi.sin() * theta.sin(),
            theta.cos(),
            -phi.cos() * theta.sin(),
        ];
        [d[2], d[1], -d[0]]
    };
    let v = look(dir.path(), "e.exr", mid);
    assert!((v[0] - (14.0 + 0.2) / 2.0).abs() < 1e-2, "{v:?}");
    // An 8-bit PNG is sRGB: 128 decodes to 0.2158605.
    let mut png = image::RgbImage::from_pixel(w as u32, h as u32, image::Rgb([0, 0, 0]));
    png.put_pixel(bright.0 as u32, bright.1 as u32, image::Rgb([255, 128, 0]));
    png.save(dir.path().join("e.png")).unwrap();
    let v = look(
        dir.path(),
        "e.png",
        texel_direction(bright.0, bright.1, w, h),
    );
    let want = [2.0, 2.0 * 0.2158605, 0.0];
    for c in 0..3 {
        assert!((v[c] - want[c]).abs() < 1e-3, "{v:?} vs {want:?}");
    }
}

/// A diffuse plane under a directional light along its normal, seen head-on: every
/// path's one contribution is a E / pi, and it arrives at OPL = camera distance + 2 R,
/// R Mitsuba's bounding-sphere radius of the plane (its half diagonal times
/// 1 + 1500 2^-24), in one bin.
#[test]
fn a_directional_light_arrives_2r_after_the_surface_it_lights() {
    let xml = scene(
        "",
        r#"<float name="fov" value="2"/>
    <transform name="to_world"><lookat origin="0,0,4" target="0,0,0" up="0,1,0"/></transform>
    <sampler type="independent"><integer name="sample_count" value="32"/></sampler>"#,
        r#"<integer name="width" value="5"/><integer name="height" value="5"/>
    <integer name="temporal_bins" value="10"/>
    <float name="start_opl" value="12"/><float name="bin_width_opl" value="0.1"/>"#,
        r#"<emitter type="directional"><vector name="direction" value="0, 0, -1"/><rgb name="irradiance" value="2, 3, 4"/></emitter>
  <shape type="rectangle"><transform name="to_world"><scale value="3"/></transform>
    <bsdf type="diffuse"><rgb name="reflectance" value="0.5, 0.6, 0.7"/></bsdf></shape>"#,
    );
    let dir = tempfile::tempdir().unwrap();
    let scene = load_in(dir.path(), &xml);
    let out = run(&scene, 2);
    let r = 18f64.sqrt() * (1.0 + 1500.0 / 16_777_216.0);
    // Camera distances 4 .. 4 / cos(1.42 deg) = 4.0012: OPL 12.4853 .. 12.4865, bin 4.
    let bin = ((4.0 + 2.0 * r - 12.0) / 0.1) as usize;
    assert_eq!(bin, 4);
    let (t, n) = (scene.film.time.bins, scene.spp);
    for p in 0..scene.film.pixels() {
        assert_eq!(out.accum.nonzero[p * t + bin], n, "pixel {p}");
        for c in 0..3 {
            let want = [0.5, 0.6, 0.7][c] * [2.0, 3.0, 4.0][c] / PI;
            let v = out.accum.x1[(p * t + bin) * 3 + c] / n as f64;
            assert!(
                (v - want).abs() <= 1e-5 * want,
                "pixel {p} channel {c}: {v} vs {want}"
            );
            assert_eq!(out.steady[p * 3 + c], v);
            for k in (0..t).filter(|&k| k != bin) {
                assert_eq!(out.accum.x1[(p * t + k) * 3 + c], 0.0);
            }
        }
    }
}

/// `scenes/envmap_spheres.xml` with its image by absolute path, and `extra` in the
/// integrator.
fn envmap_spheres(integrator_extra: &str, o: &Overrides) -> Scene {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let text = std::fs::read_to_string(root.join("envmap_spheres.xml"))
        .unwrap()
        .replace(
            "textures/sky.exr",
            root.join("textures/sky.exr").to_str().unwrap(),
        )
        .replace(
            r#"<integer name="rr_depth" value="5"/>"#,
            &format!(r#"<integer name="rr_depth" value="5"/>{integrator_extra}"#),
        );
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.xml");
    std::fs::write(&path, text).unwrap();
    Scene::load(&path, o).unwrap()
}

/// Light that leaves through the environment is timed like light sampled from it
/// (2 R after its last vertex; camera rays 2 max(R, |camera - c|)), so with a window
/// covering every arrival the bins sum to the steady image.
#[test]
fn with_an_environment_the_bins_sum_to_the_steady_image() {
    let scene = envmap_spheres(
        "",
        &Overrides {
            width: Some(16),
            spp: Some(16),
            bins: Some(120),
            start_opl: Some(0.0),
            bin_width_opl: Some(0.5),
            max_depth: Some(4),
            ..Default::default()
        },
    );
    let out = run(&scene, 9);
    let (t, n) = (scene.film.time.bins, scene.spp as f64);
    for p in 0..scene.film.pixels() {
        for c in 0..3 {
            let sum: f64 = (0..t).map(|k| out.accum.x1[(p * t + k) * 3 + c] / n).sum();
            let steady = out.steady[p * 3 + c];
            assert!(steady > 0.0);
            assert!(
                (sum - steady).abs() <= 1e-12 * steady,
                "pixel {p}: {sum} vs {steady}"
            );
        }
    }
}

/// `hide_emitters` blacks out the environment for camera rays only (Mitsuba and
/// mitransient): sky pixels become black and no longer count as seeing an emitter,
/// and every other pixel keeps the same bits (the escape draws no random numbers).
/// Without it, sky pixels see an emitter (G-buffer emitter fraction 1, no depth, no
/// normal), as pixels on an area light do.
#[test]
fn hide_emitters_hides_the_environment_from_camera_rays_only() {
    let o = Overrides {
        width: Some(16),
        spp: Some(8),
        bins: Some(50),
        ..Default::default()
    };
    let shown = run(&envmap_spheres("", &o), 4);
    let hidden = run(
        &envmap_spheres(r#"<boolean name="hide_emitters" value="true"/>"#, &o),
        4,
    );
    let (mut sky, mut rest) = (0, 0);
    for p in 0..16 * 16 {
        let g = &shown.gbuffer[p];
        if g.emitter == 1.0 {
            sky += 1;
            assert_eq!((g.depth, g.normal), (0.0, [0.0; 3]));
            assert!(shown.steady[p * 3] > 0.0);
            assert_eq!(&hidden.steady[p * 3..p * 3 + 3], &[0.0; 3]);
            assert_eq!(hidden.gbuffer[p].emitter, 0.0);
        } else if g.emitter == 0.0 {
            rest += 1;
            assert_eq!(
                &hidden.steady[p * 3..p * 3 + 3],
                &shown.steady[p * 3..p * 3 + 3]
            );
            assert_eq!(hidden.gbuffer[p], *g);
        }
    }
    assert!(sky > 30 && rest > 30, "sky {sky}, rest {rest}");
}
