//! The mono and mono-polarized render modes (`--mode mono|mono_polarized`,
//! src/scene/mode.rs, src/render/polarized.rs) end to end: Malus's law through two
//! ideal polarizers and a quarter-wave retarder turning linear into circular light,
//! both in closed form (every sample is exact: the expected values are met to f32
//! rounding); an unpolarizing world renders S0 bit for bit as the mono mode and
//! S1..S3 as exact zeros; a dielectric mirror polarizes reflected light as Fresnel's
//! equations say; same seed, same bits on any thread count; the bundle's four Stokes
//! channels; what the modes do not model is refused.

use crate::common::{bundled, bundled_error, load, tstat};
use tstat::render::RenderOutput;
use tstat::scene::mode::RenderMode;
use tstat::scene::{Overrides, Scene};

pub(crate) fn mode(m: RenderMode) -> Overrides {
    Overrides {
        mode: m,
        ..Default::default()
    }
}

pub(crate) fn run(scene: &Scene, spp: u32, seed: u64) -> RenderOutput {
    crate::common::run_spp(scene, spp, seed)
}

/// The film's per-channel totals over all bins and pixels.
pub(crate) fn totals(out: &RenderOutput, channels: usize) -> Vec<f64> {
    let mut t = vec![0.0; channels];
    for (i, v) in out.accum.x1.iter().enumerate() {
        t[i % channels] += v;
    }
    t
}

/// A camera looking down -z (up +y, a 1 degree field of view) at an area light of
/// radiance 1 four units away, through `filters` (XML shapes between them).
pub(crate) fn filter_scene(filters: &str) -> String {
    format!(
        r#"<scene version="3.0.0">
  <integrator type="transient_path"><integer name="max_depth" value="6"/></integrator>
  <sensor type="perspective">
    <float name="fov" value="1"/>
    <transform name="to_world"><lookat origin="0,0,0" target="0,0,-1" up="0,1,0"/></transform>
    <sampler type="independent"><integer name="sample_count" value="4"/></sampler>
    <film type="transient_hdr_film">
      <integer name="width" value="4"/><integer name="height" value="4"/>
      <integer name="temporal_bins" value="4"/>
      <float name="start_opl" value="3.9"/><float name="bin_width_opl" value="0.1"/>
    </film>
  </sensor>
  {filters}
  <shape type="rectangle">
    <transform name="to_world"><scale value="3"/><translate z="-4"/></transform>
    <emitter type="area"><float name="radiance" value="1"/></emitter>
  </shape>
</scene>"#
    )
}

/// A filter sheet at depth `z` (facing the camera) with the BSDF `bsdf`.
pub(crate) fn sheet(z: f32, bsdf: &str) -> String {
    format!(
        r#"<shape type="rectangle">
    <transform name="to_world"><scale value="0.5"/><translate z="{z}"/></transform>
    {bsdf}
  </shape>"#
    )
}

pub(crate) fn polarizer(z: f32, theta: f32) -> String {
    sheet(
        z,
        &format!(r#"<bsdf type="polarizer"><float name="theta" value="{theta}"/></bsdf>"#),
    )
}

/// The Stokes vector per path of a film that sees a uniform light through filters:
/// the totals over every voxel divided by the number of paths.
fn stokes_per_path(xml: &str) -> [f64; 4] {
    let scene = load(xml, &mode(RenderMode::MonoPolarized));
    let spp = 8;
    let out = run(&scene, spp, 3);
    let t = totals(&out, 4);
    let paths = (spp as usize * scene.film.pixels()) as f64;
    [t[0] / paths, t[1] / paths, t[2] / paths, t[3] / paths]
}

/// Malus's law: unpolarized light of radiance 1 through ideal linear polarizers at
/// angles a (light side) and b (camera side) arrives with S0 = cos^2(a - b) / 2,
/// polarized along b: S1 = S0 cos 2b, S2 = -S0 sin 2b in the sensor's frame (x the
/// image's right; the sign of S2 is Mitsuba's for a `polarizer` whose `theta` is
/// given facing the camera, as mitransient renders it, docs/polarization.md), S3 = 0.
/// Each sample is exact.
#[test]
fn malus_law_through_two_polarizers() {
    for (a, b) in [
        (0.0f32, 0.0f32),
        (0.0, 30.0),
        (20.0, 65.0),
        (45.0, 135.0),
        (10.0, 100.0),
    ] {
        let xml = filter_scene(&(polarizer(-2.0, a) + &polarizer(-1.0, b)));
        let s = stokes_per_path(&xml);
        let (ar, br) = (f64::from(a).to_radians(), f64::from(b).to_radians());
        let s0 = 0.5 * (ar - br).cos().powi(2);
        let want = [s0, s0 * (2.0 * br).cos(), -s0 * (2.0 * br).sin(), 0.0];
        for c in 0..4 {
            assert!(
                (s[c] - want[c]).abs() < 2e-4,
                "a {a}, b {b}: S{c} {} against {}",
                s[c],
                want[c]
            );
        }
    }
    // Without polarization the same filters pass a quarter of the light.
    let xml = filter_scene(&(polarizer(-2.0, 0.0) + &polarizer(-1.0, 90.0)));
    let t = totals(&run(&load(&xml, &mode(RenderMode::Mono)), 8, 3), 1);
    assert!((t[0] / (8.0 * 16.0) - 0.25).abs() < 1e-5, "mono: {}", t[0]);
    assert!(
        stokes_per_path(&xml)[0].abs() < 1e-6,
        "crossed polarizers pass nothing"
    );
}

/// A quarter-wave retarder with its fast axis horizontal after a polarizer at 45
/// degrees turns the linear light into circular light: S1 = S2 = 0, |S3| = S0 = 1/2
/// (Mitsuba's retarder scales its retardance by |cos| of the incidence, which is
/// within 4e-5 of 1 in this field of view).
#[test]
fn a_quarter_wave_retarder_turns_linear_into_circular_light() {
    let retarder = sheet(
        -1.0,
        r#"<bsdf type="retarder"><float name="theta" value="0"/><float name="delta" value="90"/></bsdf>"#,
    );
    let s = stokes_per_path(&filter_scene(&(polarizer(-2.0, 45.0) + &retarder)));
    assert!((s[0] - 0.5).abs() < 1e-5, "S0 {}", s[0]);
    assert!(
        s[1].abs() < 2e-4 && s[2].abs() < 2e-4,
        "S1 {} S2 {}",
        s[1],
        s[2]
    );
    assert!((s[3].abs() - 0.5).abs() < 2e-4, "S3 {}", s[3]);
    // A half-wave plate instead mirrors the linear state: S2 = -S0 becomes +S0.
    let half = sheet(
        -1.0,
        r#"<bsdf type="retarder"><float name="theta" value="0"/><float name="delta" value="180"/></bsdf>"#,
    );
    let s = stokes_per_path(&filter_scene(&(polarizer(-2.0, 45.0) + &half)));
    assert!((s[2] - 0.5).abs() < 2e-4 && s[3].abs() < 2e-4, "{s:?}");
    // Without the plate: S2 = -S0.
    let s = stokes_per_path(&filter_scene(&polarizer(-2.0, 45.0)));
    assert!((s[2] + 0.5).abs() < 2e-4 && s[3].abs() < 2e-4, "{s:?}");
}

/// A camera looking at a smooth dielectric floor (eta 1.5) at incidence `theta_deg`,
/// whose mirror image is an area light of radiance `radiance` (XML) five units away
/// (the plane of incidence is vertical: s light is horizontal in the image).
pub(crate) fn dielectric_mirror_scene(theta_deg: f64, radiance: &str) -> String {
    let t = theta_deg.to_radians();
    let (d, r) = ([0.0, -t.cos(), -t.sin()], [0.0, t.cos(), -t.sin()]);
    let p = [0.0, -1.0, -t.tan()];
    let c: Vec<f64> = (0..3).map(|k| p[k] + 5.0 * r[k]).collect();
    format!(
        r#"<scene version="3.0.0">
  <integrator type="transient_path"><integer name="max_depth" value="3"/></integrator>
  <sensor type="perspective">
    <float name="fov" value="0.5"/>
    <transform name="to_world"><lookat origin="0,0,0" target="{},{},{}" up="0,1,0"/></transform>
    <sampler type="independent"><integer name="sample_count" value="4"/></sampler>
    <film type="transient_hdr_film">
      <integer name="width" value="2"/><integer name="height" value="2"/>
      <integer name="temporal_bins" value="1"/>
      <float name="start_opl" value="0"/><float name="bin_width_opl" value="1000"/>
    </film>
  </sensor>
  <shape type="rectangle">
    <transform name="to_world"><scale value="100"/><rotate x="1" angle="-90"/><translate y="-1"/></transform>
    <bsdf type="dielectric"><float name="int_ior" value="1.5"/><float name="ext_ior" value="1"/></bsdf>
  </shape>
  <shape type="rectangle">
    <transform name="to_world"><scale value="3"/><lookat origin="{},{},{}" target="{},{},{}" up="1,0,0"/></transform>
    <emitter type="area">{radiance}</emitter>
  </shape>
</scene>"#,
        d[0], d[1], d[2], c[0], c[1], c[2], p[0], p[1], p[2]
    )
}

/// Fresnel: light of an area emitter reflected once by a smooth dielectric mirror
/// (eta 1.5) at incidence theta (transmitted paths see nothing) arrives polarized as
/// the textbook formulas say: every reflected sample has S1 / S0 equal to
/// `(R_s - R_p) / (R_s + R_p)` in the sensor's frame, whose x axis is the s direction
/// here (the plane of incidence is vertical), and S2 = S3 = 0; S0 per path is
/// `(R_s + R_p) / 2`, the chance of choosing reflection, within 4 standard errors.
#[test]
fn a_dielectric_mirror_polarizes_as_fresnel_says() {
    for theta_deg in [20.0f64, 56.3, 75.0] {
        let t = theta_deg.to_radians();
        let xml = dielectric_mirror_scene(theta_deg, r#"<float name="radiance" value="1"/>"#);
        let scene = load(&xml, &mode(RenderMode::MonoPolarized));
        let spp = 4096;
        let out = run(&scene, spp, 5);
        let s = totals(&out, 4);
        let n = 1.5f64;
        let cos_i = t.cos();
        let cos_t = (1.0 - (t.sin() / n).powi(2)).sqrt();
        let rs = ((cos_i - n * cos_t) / (cos_i + n * cos_t)).powi(2);
        let rp = ((n * cos_i - cos_t) / (n * cos_i + cos_t)).powi(2);
        let ratio = s[1] / s[0];
        let want = (rs - rp) / (rs + rp);
        assert!(
            (ratio - want).abs() < 2e-4,
            "{theta_deg}: S1/S0 {ratio} against {want}"
        );
        assert!(
            s[2].abs() < 1e-4 * s[0] && s[3].abs() < 1e-4 * s[0],
            "{s:?}"
        );
        let paths = f64::from(spp) * scene.film.pixels() as f64;
        let f = 0.5 * (rs + rp);
        let se = (f * (1.0 - f) / paths).sqrt();
        assert!(
            (s[0] / paths - f).abs() < 4.0 * se,
            "{theta_deg}: S0 {} against {f}",
            s[0] / paths
        );
    }
}

/// A world of depolarizers (cbox: diffuse walls, a diffuse light) renders S0 bit for
/// bit as the mono mode (the same samples, and every Mueller step keeps S0 and drops
/// the rest), with S1 = S2 = S3 = 0 exactly.
#[test]
fn an_unpolarizing_world_renders_s0_as_the_mono_mode() {
    let o = |m| Overrides {
        width: Some(8),
        bins: Some(30),
        ..mode(m)
    };
    let pol = run(&bundled("cbox.xml", &o(RenderMode::MonoPolarized)), 8, 2);
    let mono = run(&bundled("cbox.xml", &o(RenderMode::Mono)), 8, 2);
    assert_eq!(pol.accum.channels, 4);
    assert_eq!(mono.accum.channels, 1);
    let s0: Vec<f64> = pol.accum.x1.iter().step_by(4).copied().collect();
    assert_eq!(s0, mono.accum.x1);
    assert!(mono.accum.x1.iter().any(|&v| v > 0.0));
    for (i, v) in pol.accum.x1.iter().enumerate() {
        if i % 4 != 0 {
            assert_eq!(*v, 0.0);
        }
    }
    assert_eq!(pol.accum.nonzero, mono.accum.nonzero);
}

/// Same seed, same bits, on one thread or two (the showcase: conductors and
/// dielectrics polarize).
#[test]
fn polarized_renders_do_not_depend_on_the_thread_count() {
    let o = Overrides {
        width: Some(8),
        bins: Some(200),
        ..mode(RenderMode::MonoPolarized)
    };
    let scene = bundled("cbox_polarizers.xml", &o);
    let on = |threads: usize| crate::common::on_threads(threads, || run(&scene, 8, 11));
    let (a, b) = (on(1), on(2));
    assert_eq!(a.accum.x1, b.accum.x1);
    assert_eq!(a.accum.x3, b.accum.x3);
    assert_eq!(a.steady, b.steady);
    assert!(
        a.accum.x1.iter().skip(1).step_by(4).any(|&v| v != 0.0),
        "S1 is not zero"
    );
}

/// What the mono modes do not model is refused at load, naming it.
#[test]
fn the_mono_modes_refuse_what_they_do_not_model() {
    for m in [RenderMode::Mono, RenderMode::MonoPolarized] {
        for (name, says) in [
            ("cbox_fog.xml", "participating media"),
            ("nlos_T.xml", "NLOS captures"),
        ] {
            let e = bundled_error(name, &mode(m));
            assert!(e.contains(says), "{name}: {e}");
        }
    }
}

/// The binary: a mono_polarized bundle has four Stokes channels in its manifest and
/// arrays, exports (H, W, T, 4) and an EXR with S0.Y..S3.Y; Box-Cox is refused with
/// the mode; merging with a mono bundle is refused.
#[test]
fn a_polarized_bundle_has_four_stokes_channels() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).display().to_string();
    let scene = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cbox_polarizers.xml");
    let scene = scene.display().to_string();
    let small = ["--width", "12", "--spp", "4", "--bins", "40"];
    let render = |out: &str, m: &str, extra: &[&str]| {
        let mut a = vec!["render", &scene, "--out", out, "--mode", m];
        a.extend(small);
        a.extend(extra);
        tstat(&a)
    };
    let r = render(&p("p.tstats"), "mono_polarized", &[]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let m: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("p.tstats/manifest.json")).unwrap())
            .unwrap();
    assert_eq!(m["mode"], "mono_polarized");
    assert_eq!(m["channels"], serde_json::json!(["S0", "S1", "S2", "S3"]));
    let r = tstat(&[
        "export",
        &p("p.tstats"),
        "--out",
        &p("v.npy"),
        "--steady",
        &p("s.exr"),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let v: ndarray::Array4<f32> = ndarray_npy::read_npy(dir.path().join("v.npy")).unwrap();
    assert_eq!(v.shape(), &[12, 12, 40, 4]);
    let exr = exr::prelude::read_all_flat_layers_from_file(dir.path().join("s.exr")).unwrap();
    let names: Vec<String> = exr.layer_data[0]
        .channel_data
        .list
        .iter()
        .map(|c| c.name.to_string())
        .collect();
    assert_eq!(names, ["S0.Y", "S1.Y", "S2.Y", "S3.Y"]);
    let r = render(
        &p("b.tstats"),
        "mono_polarized",
        &["--transform", "box-cox:0.5"],
    );
    assert!(!r.status.success());
    assert!(String::from_utf8_lossy(&r.stderr).contains("Box-Cox"));
    assert!(!dir.path().join("b.tstats").exists());
    let r = render(&p("m.tstats"), "mono", &["--seed", "2"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let r = tstat(&[
        "merge",
        &p("p.tstats"),
        &p("m.tstats"),
        "--out",
        &p("pm.tstats"),
    ]);
    assert!(!r.status.success());
    assert!(!dir.path().join("pm.tstats").exists());
}

/// The sensor's frame does not depend on how the camera is turned: a camera looking
/// along +x with up +z sees the glare of a horizontal glass floor polarized along the
/// image's horizontal (s light: S1 / S0 = (R_s - R_p) / (R_s + R_p) > 0), as Mitsuba's
/// own `stokes` integrator reports it for this scene (S1 / S0 = +0.964 at 256 spp,
/// llvm_ad_mono_polarized; docs/polarization.md).
#[test]
fn glare_off_a_floor_is_horizontal_for_a_camera_along_x_with_up_z() {
    let xml = r#"<scene version="3.0.0">
  <integrator type="transient_path"><integer name="max_depth" value="3"/></integrator>
  <sensor type="perspective">
    <float name="fov" value="0.2"/>
    <transform name="to_world"><lookat origin="0,0,0" target="1,0,-0.8" up="0,0,1"/></transform>
    <sampler type="independent"><integer name="sample_count" value="4"/></sampler>
    <film type="transient_hdr_film">
      <integer name="width" value="2"/><integer name="height" value="2"/>
      <integer name="temporal_bins" value="1"/>
      <float name="start_opl" value="0"/><float name="bin_width_opl" value="1000"/>
    </film>
  </sensor>
  <shape type="rectangle">
    <transform name="to_world"><scale value="100"/><translate z="-1"/></transform>
    <bsdf type="dielectric"><float name="int_ior" value="1.5"/><float name="ext_ior" value="1"/></bsdf>
  </shape>
  <shape type="rectangle">
    <transform name="to_world"><scale value="20"/><lookat origin="12.5,0,8" target="1.25,0,-1" up="0,0,1"/></transform>
    <emitter type="area"><float name="radiance" value="1"/></emitter>
  </shape>
</scene>"#;
    let scene = load(xml, &mode(RenderMode::MonoPolarized));
    let s = totals(&run(&scene, 256, 4), 4);
    let cos_i = 0.8 / (1.0f64 + 0.64).sqrt();
    let sin_i = (1.0 - cos_i * cos_i).sqrt();
    let n = 1.5f64;
    let cos_t = (1.0 - (sin_i / n).powi(2)).sqrt();
    let rs = ((cos_i - n * cos_t) / (cos_i + n * cos_t)).powi(2);
    let rp = ((n * cos_i - cos_t) / (n * cos_i + cos_t)).powi(2);
    let want = (rs - rp) / (rs + rp);
    assert!(want > 0.9);
    assert!(
        (s[1] / s[0] - want).abs() < 2e-3,
        "S1/S0 {} against {want}",
        s[1] / s[0]
    );
    assert!(s[2].abs() < 2e-3 * s[0], "{s:?}");
}
