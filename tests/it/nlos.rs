//! NLOS captures (SPEC 11): `transient_nlos_path` on an `nlos_capture_meter`.
//!
//! - A small hidden diffuse patch facing a one-point confocal capture: every bin
//!   against the closed-form three-bounce transient (a quadrature over the patch of
//!   `(rho_w / pi)^2 (rho_h / pi) I cos_l / r^2 * cos_p^2 cos_g^2 / d^4`, arriving at
//!   `2 d`, plus `2 r` with `account_first_and_last_bounces`), by a t-test per bin;
//! - exhaustive scans: the image of laser point l at sensor point l is the confocal
//!   capture's (two-sample t-tests per bin), and the rest obey the reciprocity of the
//!   diffuse three-bounce integral (`H[l][j] r_l^2 / cos_l` symmetric in l and j);
//! - the same bits at 1 and 2 threads;
//! - `export --tal`: the HDF5 file read back (H, shapes, grids, times) against the
//!   bundle;
//! - bad scenes and commands: one clear error.

use crate::common;

use std::path::Path;
use std::process::Command;
use tstat::render::{render, PixelSampling, RenderOutput, RenderSettings};
use tstat::scene::{Overrides, Scene};
use tstat::stats::Transform;

const RHO_W: f64 = 0.8;
const RHO_H: f64 = 0.6;
/// The projector's `irradiance` E: on-axis intensity I = pi E.
const E: f64 = 2.0;
/// Laser and sensor position.
const L: [f64; 3] = [0.3, 0.2, 0.5];
/// The patch's half side; it lies at z = 1 facing the wall.
const A: f64 = 0.1;

/// A relay wall [-1, 1]^2 at z = 0 measured on a `res` x `res` grid, a patch of half
/// side `half` at (0, 0, 1) facing it, a projector laser at `L`.
fn patch_scene(
    capture: &str,
    res: usize,
    half: f64,
    account: bool,
    bins: (f64, f64, usize),
    spp: u32,
) -> String {
    patch_scene_at(capture, res, half, 0.0, account, bins, spp)
}

/// [`patch_scene`] with the patch's centre at (cx, 0, 1).
fn patch_scene_at(
    capture: &str,
    res: usize,
    half: f64,
    cx: f64,
    account: bool,
    bins: (f64, f64, usize),
    spp: u32,
) -> String {
    let exhaustive = if capture == "exhaustive" {
        format!(
            r#"<boolean name="exhaustive_scan" value="true"/><integer name="laser_scan_width" value="{res}"/><integer name="laser_scan_height" value="{res}"/>"#
        )
    } else {
        String::new()
    };
    let [lx, ly, lz] = L;
    let (start, width, n) = bins;
    format!(
        r#"<scene version="3.0.0">
  <integrator type="transient_nlos_path">
    <string name="capture_type" value="{capture}"/>
    <boolean name="nlos_laser_sampling" value="true"/>
    <boolean name="nlos_hidden_geometry_sampling" value="true"/>
    <boolean name="account_first_and_last_bounces" value="{account}"/>
    <integer name="max_depth" value="-1"/>
  </integrator>
  <emitter type="projector">
    <rgb name="irradiance" value="{E}"/>
    <float name="fov" value="5"/>
    <transform name="to_world"><lookat origin="{lx}, {ly}, {lz}" target="0, 0, 0" up="0, 1, 0"/></transform>
  </emitter>
  <shape type="rectangle" id="wall">
    <bsdf type="diffuse"><rgb name="reflectance" value="{RHO_W}"/></bsdf>
    <sensor type="nlos_capture_meter">
      <point name="sensor_origin" x="{lx}" y="{ly}" z="{lz}"/>
      <sampler type="independent"><integer name="sample_count" value="{spp}"/></sampler>
      <film type="transient_hdr_film">
        <integer name="width" value="{res}"/>
        <integer name="height" value="{res}"/>
        <integer name="temporal_bins" value="{n}"/>
        <float name="start_opl" value="{start}"/>
        <float name="bin_width_opl" value="{width}"/>
        {exhaustive}
      </film>
    </sensor>
  </shape>
  <shape type="rectangle" id="patch">
    <bsdf type="diffuse"><rgb name="reflectance" value="{RHO_H}"/></bsdf>
    <transform name="to_world">
      <scale x="{half}" y="{half}"/>
      <rotate y="1" angle="180"/>
      <translate x="{cx}" z="1"/>
    </transform>
  </shape>
</scene>"#
    )
}

fn settings(scene: &Scene, seed: u64) -> RenderSettings {
    RenderSettings {
        spp: scene.spp,
        seed,
        transform: Transform::Identity,
        pixel_sampling: PixelSampling::Independent,
        replicates: 0,
        pixel_spp: None,
    }
}

fn run(scene: &Scene, seed: u64) -> RenderOutput {
    render(scene, &settings(scene, seed), &|_| {})
}

/// Mean and standard error of the mean of voxel (pixel, bin), channel 0.
fn mean_se(out: &RenderOutput, n: f64, pixel: usize, bin: usize) -> (f64, f64) {
    let a = &out.accum;
    let i = (pixel * a.bins + bin) * 3;
    let mean = a.x1[i] / n;
    let var = ((a.x2[i] / n - mean * mean) * n / (n - 1.0)).max(0.0);
    (mean, (var / n).sqrt())
}

/// The closed-form transient of the patch centred at (cx, 0, 1) (per bin), by a
/// midpoint quadrature.
fn closed_form(bins: (f64, f64, usize), shift: f64, cx: f64) -> Vec<f64> {
    let (start, width, n) = bins;
    let r2 = L.iter().map(|v| v * v).sum::<f64>();
    let cos_l = L[2] / r2.sqrt();
    let pi = std::f64::consts::PI;
    let k = (RHO_W / pi).powi(2) * (RHO_H / pi) * (pi * E) * cos_l / r2;
    let mut out = vec![0.0; n];
    let m = 1000;
    let h = 2.0 * A / m as f64;
    for i in 0..m {
        for j in 0..m {
            let x = cx - A + (i as f64 + 0.5) * h;
            let y = -A + (j as f64 + 0.5) * h;
            let d2 = x * x + y * y + 1.0;
            // cos_p = cos_g = 1 / d: integrand K cos_p^2 cos_g^2 / d^4 = K / d^8.
            let v = k / (d2 * d2 * d2 * d2) * h * h;
            let t = 2.0 * d2.sqrt() + shift;
            let b = ((t - start) / width).floor();
            if b >= 0.0 && (b as usize) < n {
                out[b as usize] += v;
            }
        }
    }
    out
}

/// The patch centred at (cx, 0, 1): seen from the wall point at atan(cx) from the
/// normals of both.
fn check_patch(account: bool, cx: f64) {
    check_patch_with(account, cx, "");
}

/// [`check_patch`] with more integrator parameters (`extra`, XML).
fn check_patch_with(account: bool, cx: f64, extra: &str) {
    let r = L.iter().map(|v| v * v).sum::<f64>().sqrt();
    let shift = if account { 2.0 * r } else { 0.0 };
    let near = 2.0 * ((cx - A).max(0.0).powi(2) + 1.0).sqrt();
    let far = 2.0 * ((cx + A).powi(2) + A * A + 1.0).sqrt();
    let width = (far - near) / 8.0;
    let bins = (near - 0.5 * width + shift, width, 11);
    let spp = 1 << 18;
    let xml = patch_scene_at("confocal", 1, A, cx, account, bins, spp).replace(
        r#"<integer name="max_depth" value="-1"/>"#,
        &format!(r#"<integer name="max_depth" value="-1"/>{extra}"#),
    );
    let scene = common::load(&xml, &Overrides::default());
    let out = run(&scene, 7);
    let expected = closed_form(bins, shift, cx);
    let n = spp as f64;
    let mut total = (0.0, 0.0);
    for (bin, &want) in expected.iter().enumerate() {
        let (mean, se) = mean_se(&out, n, 0, bin);
        total.0 += mean;
        total.1 += want;
        if want == 0.0 {
            assert_eq!(mean, 0.0, "bin {bin}: nothing arrives there, got {mean:e}");
            continue;
        }
        let t = (mean - want) / se;
        assert!(
            t.abs() < 5.0,
            "bin {bin}: render {mean:e} +- {se:e}, closed form {want:e} (t = {t:.1})"
        );
    }
    // The whole echo: every bin and the steady image hold it, to 0.3%.
    assert!(expected.iter().filter(|&&v| v > 0.0).count() >= 6);
    let rel = (total.0 - total.1).abs() / total.1;
    assert!(
        rel < 3e-3,
        "echo energy {:e} vs closed form {:e}",
        total.0,
        total.1
    );
    let steady = out.steady[0];
    assert!(
        ((steady - total.1) / total.1).abs() < 3e-3,
        "steady {steady:e} vs {:e}",
        total.1
    );
}

#[test]
fn hidden_patch_matches_the_closed_form_three_bounce_transient() {
    check_patch(false, 0.0);
}

#[test]
fn first_and_last_bounces_shift_the_echo_by_both_laser_and_sensor_segments() {
    check_patch(true, 0.0);
}

/// The hidden-geometry variants stay unbiased: the relay wall among the hidden shapes
/// (its samples fail from a wall point, the patch's weigh by the whole area), a coin
/// flip against BSDF sampling (one-sample MIS; mitransient 1.3.1 divides each
/// technique by 1/2 and doubles this echo), sampling only at the first vertex.
#[test]
fn hidden_geometry_sampling_variants_keep_the_closed_form() {
    for extra in [
        "",
        r#"<boolean name="nlos_hidden_geometry_sampling_includes_relay_wall" value="true"/>"#,
        r#"<boolean name="nlos_hidden_geometry_sampling_do_rroulette" value="true"/>"#,
        r#"<integer name="nlos_hidden_geometry_sampling_max_depth" value="1"/>"#,
    ] {
        check_patch_with(false, 0.0, extra);
    }
}

/// Seen at 60 degrees from the normals: a shadow ray that ran beside its segment (from
/// the moved origin along the unmoved direction) met the wall short of the lit point
/// beyond 45 degrees and lost this echo entirely.
#[test]
fn a_patch_seen_at_grazing_angles_keeps_its_echo() {
    check_patch(false, 3f64.sqrt());
}

/// Welch's t between two renders' voxels (pixel, bin), channel 0.
fn welch(a: &RenderOutput, pa: usize, b: &RenderOutput, pb: usize, n: f64, bin: usize) -> f64 {
    let (ma, sa) = mean_se(a, n, pa, bin);
    let (mb, sb) = mean_se(b, n, pb, bin);
    let se = (sa * sa + sb * sb).sqrt();
    if se == 0.0 {
        assert_eq!(ma, mb, "bin {bin}: zero variance but different means");
        return 0.0;
    }
    (ma - mb) / se
}

#[test]
fn exhaustive_scans_hold_the_confocal_capture_on_their_diagonal_and_are_reciprocal() {
    let bins = (1.9, 0.02, 40);
    let spp = 1 << 14;
    let ex = common::load(
        &patch_scene("exhaustive", 2, 0.3, false, bins, spp),
        &Overrides::default(),
    );
    let co = common::load(
        &patch_scene("confocal", 2, 0.3, false, bins, spp),
        &Overrides::default(),
    );
    // 4 laser points, each a 2 x 2 sensor image, stacked.
    assert_eq!((ex.film.width, ex.film.height), (2, 8));
    assert_eq!((co.film.width, co.film.height), (2, 2));
    let (e, c) = (run(&ex, 3), run(&co, 4));
    let n = spp as f64;
    // Sensor j = (x, y) is confocal pixel y * 2 + x; under laser l it is exhaustive
    // pixel (l * 2 + y) * 2 + x.
    let exhaustive_pixel = |l: usize, j: usize| (l * 2 + j / 2) * 2 + j % 2;
    let mut worst: f64 = 0.0;
    for j in 0..4 {
        for bin in 0..bins.2 {
            worst = worst.max(welch(&e, exhaustive_pixel(j, j), &c, j, n, bin).abs());
        }
    }
    assert!(worst < 5.0, "diagonal vs confocal: worst |t| = {worst:.1}");
    // Reciprocity: H[l][j] r_l^2 / cos_l is symmetric (sums over the echo).
    let grid = [[-0.5, -0.5], [0.5, -0.5], [-0.5, 0.5], [0.5, 0.5]];
    let weight = |l: usize| {
        let d = [L[0] - grid[l][0], L[1] - grid[l][1], L[2]];
        let r2 = d.iter().map(|v| v * v).sum::<f64>();
        r2 / (d[2] / r2.sqrt())
    };
    let total = |l: usize, j: usize| -> (f64, f64) {
        (0..bins.2).fold((0.0, 0.0), |(m, v), bin| {
            let (mean, se) = mean_se(&e, n, exhaustive_pixel(l, j), bin);
            (m + mean, v + se * se)
        })
    };
    let mut checked = 0;
    for l in 0..4 {
        for j in (l + 1)..4 {
            let (a, va) = total(l, j);
            let (b, vb) = total(j, l);
            assert!(a > 0.0 && b > 0.0, "no echo between points {l} and {j}");
            let (a, b) = (a * weight(l), b * weight(j));
            let se = (va * weight(l).powi(2) + vb * weight(j).powi(2)).sqrt();
            let t = (a - b) / se;
            assert!(
                t.abs() < 5.0,
                "H[{l}][{j}] and H[{j}][{l}] weighted: {a:e} vs {b:e} (t = {t:.1})"
            );
            // The laser falloff is not symmetric: without the weights they differ.
            checked += 1;
        }
    }
    assert_eq!(checked, 6);
}

#[test]
fn captures_are_the_same_bits_at_one_and_two_threads() {
    let xml = patch_scene("exhaustive", 2, 0.3, false, (1.9, 0.02, 40), 64);
    let scene = common::load(&xml, &Overrides::default());
    let at = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| run(&scene, 11))
    };
    let (a, b) = (at(1), at(2));
    assert!(a.accum.x1.iter().any(|&v| v > 0.0));
    assert_eq!(a.accum.x1, b.accum.x1);
    assert_eq!(a.accum.x2, b.accum.x2);
    assert_eq!(a.accum.nonzero, b.accum.nonzero);
    assert_eq!(a.steady, b.steady);
}

fn tstat(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_tstat"))
        .args(args)
        .output()
        .unwrap()
}

fn write(dir: &Path, name: &str, text: &str) -> String {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p.display().to_string()
}

#[test]
fn tal_export_holds_the_bundle_means_time_first_with_the_grids() {
    let dir = tempfile::tempdir().unwrap();
    let bins = (1.9, 0.02, 40);
    for (capture, res) in [("confocal", 3), ("exhaustive", 2)] {
        let xml = write(
            dir.path(),
            &format!("{capture}.xml"),
            &patch_scene(capture, res, 0.3, true, (bins.0 + 1.0, bins.1, bins.2), 32),
        );
        let bundle = dir.path().join(format!("{capture}.tstats"));
        let out = tstat(&["render", &xml, "--out", bundle.to_str().unwrap()]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let h5 = dir.path().join(format!("{capture}.hdf5"));
        // Blocks of 7 bins: the streamed path writes H in 6 pieces.
        let out = tstat(&[
            "export",
            bundle.to_str().unwrap(),
            "--tal",
            h5.to_str().unwrap(),
            "--max-memory",
            &format!("{}", 7 * 4 * res.pow(4)),
        ]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let file = hdf5_pure::File::open(&h5).unwrap();
        let names = file.root().datasets().unwrap();
        for want in [
            "H",
            "H_format",
            "sensor_grid_xyz",
            "sensor_grid_normals",
            "sensor_grid_format",
            "laser_grid_xyz",
            "laser_grid_normals",
            "laser_grid_format",
            "sensor_xyz",
            "laser_xyz",
            "delta_t",
            "t_start",
            "t_accounts_first_and_last_bounces",
            "scene_info",
        ] {
            assert!(
                names.iter().any(|n| n == want),
                "{capture}: no {want} in {names:?}"
            );
        }
        assert_eq!(names.len(), 14, "y-tal refuses unknown datasets: {names:?}");
        let h = file.dataset("H").unwrap();
        let shape = h.shape().unwrap();
        let hv = h.read_f32().unwrap();
        let x1: ndarray::Array4<f64> = ndarray_npy::read_npy(bundle.join("x1.npy")).unwrap();
        let spp = 32.0;
        let (t, s) = (bins.2, res);
        let (lx_n, ly_n) = if capture == "exhaustive" {
            (res, res)
        } else {
            (1, 1)
        };
        if capture == "exhaustive" {
            assert_eq!(
                shape,
                vec![t as u64, res as u64, res as u64, s as u64, s as u64]
            );
        } else {
            assert_eq!(shape, vec![t as u64, s as u64, s as u64]);
        }
        let mut nonzero = 0;
        for k in 0..t {
            for ly in 0..ly_n {
                for lx in 0..lx_n {
                    for sy in 0..s {
                        for sx in 0..s {
                            let row = (ly * lx_n + lx) * s + sy;
                            let want: f64 = (0..3).map(|c| x1[[row, sx, k, c]]).sum::<f64>() / spp;
                            let i = (((k * lx_n + lx) * ly_n + ly) * s + sx) * s + sy;
                            assert_eq!(
                                hv[i], want as f32,
                                "{capture}: H[{k}, {lx}, {ly}, {sx}, {sy}]"
                            );
                            nonzero += usize::from(want > 0.0);
                        }
                    }
                }
            }
        }
        assert!(nonzero > 10, "{capture}: an echo was rendered");
        let grid = file.dataset("sensor_grid_xyz").unwrap();
        assert_eq!(grid.shape().unwrap(), vec![s as u64, s as u64, 3]);
        let g = grid.read_f32().unwrap();
        // (sx, sy) = (0, 1): u = 1/2s, v = 3/2s on the wall [-1, 1]^2.
        let p = &g[3..6];
        let want = [-1.0 + 1.0 / s as f32, -1.0 + 3.0 / s as f32, 0.0];
        assert!(
            p.iter().zip(want).all(|(a, b)| (a - b).abs() < 1e-6),
            "{p:?} vs {want:?}"
        );
        let laser = file.dataset("laser_grid_xyz").unwrap();
        assert_eq!(laser.shape().unwrap(), vec![s as u64, s as u64, 3]);
        assert_eq!(laser.read_f32().unwrap(), g, "{capture}: equal grids");
        assert_eq!(
            file.dataset("delta_t").unwrap().read_f64().unwrap(),
            vec![bins.1]
        );
        assert_eq!(
            file.dataset("t_start").unwrap().read_f64().unwrap(),
            vec![bins.0 + 1.0]
        );
        let xyz = file.dataset("laser_xyz").unwrap().read_f32().unwrap();
        assert_eq!(xyz, L.map(|v| v as f32).to_vec());
    }
}

#[test]
fn bad_nlos_scenes_and_exports_fail_with_one_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let good = patch_scene("confocal", 2, 0.3, false, (1.9, 0.02, 40), 4);
    let cases: Vec<(String, &str)> = vec![
        (good.replace(r#"<shape type="rectangle" id="wall">"#, r#"<shape type="sphere" id="wall">"#), "attached to a sphere"),
        (good.replace("</scene>", r#"<emitter type="point"><point name="position" x="0" y="0" z="3"/></emitter></scene>"#), "exactly one emitter"),
        (good.replace(r#"value="confocal""#, r#"value="sideways""#), "capture_type 'sideways'"),
        (good.replace(r#"<integer name="width" value="2"/>"#, r#"<integer name="width" value="3000"/>"#).replace(r#"<integer name="height" value="2"/>"#, r#"<integer name="height" value="3000"/>"#), "more than the 4194304 points"),
        (good.replace(r#"value="confocal""#, r#"value="exhaustive""#), "exhaustive_scan"),
        (good.replace(r#"<point name="sensor_origin""#, r#"<boolean name="confocal" value="true"/><point name="sensor_origin""#), "capture_type"),
        (good.replace(r#"value="confocal""#, r#"value="single""#).replace(r#"target="0, 0, 0""#, r#"target="3, 3, 0.5""#), "meets nothing"),
        (good.replace(r#"<boolean name="nlos_hidden_geometry_sampling" value="true"/>"#, r#"<boolean name="nlos_hidden_geometry_sampling" value="true"/><integer name="nlos_hidden_geometry_sampling_max_depth" value="0"/>"#), "must be -1 or positive"),
        (good.replace(r#"<integer name="max_depth" value="-1"/>"#, r#"<integer name="max_depth" value="-1"/><boolean name="camera_unwarp" value="true"/>"#), "camera_unwarp"),
    ];
    for (i, (xml, want)) in cases.iter().enumerate() {
        let path = write(dir.path(), &format!("bad{i}.xml"), xml);
        let out = dir.path().join(format!("bad{i}.tstats"));
        let r = tstat(&["render", &path, "--out", out.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(!r.status.success(), "case {i} rendered");
        assert!(err.contains(want), "case {i}: wanted '{want}' in: {err}");
        assert_eq!(
            err.trim()
                .lines()
                .filter(|l| l.starts_with("error"))
                .count(),
            1,
            "{err}"
        );
        assert!(!out.exists(), "case {i} left an output");
    }
    // --tal on a camera render, a wrong extension, --max-memory without --tal.
    let bundle = dir.path().join("cbox.tstats");
    let cbox = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cbox.xml");
    let r = tstat(&[
        "render",
        cbox.to_str().unwrap(),
        "--out",
        bundle.to_str().unwrap(),
        "--spp",
        "2",
        "--width",
        "8",
    ]);
    assert!(r.status.success());
    let b = bundle.to_str().unwrap();
    let h5 = dir.path().join("x.hdf5");
    for (args, want) in [
        (
            vec!["export", b, "--tal", h5.to_str().unwrap()],
            "not an NLOS capture",
        ),
        (vec!["export", b, "--tal", "x.npy"], ".hdf5"),
        (
            vec!["export", b, "--out", "x.npy", "--max-memory", "1Mi"],
            "--max-memory bounds the --tal export",
        ),
    ] {
        let r = tstat(&args);
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(!r.status.success() && err.contains(want), "{args:?}: {err}");
    }
    assert!(!h5.exists());
}

#[test]
fn captures_merge_and_the_merged_bundle_exports() {
    let dir = tempfile::tempdir().unwrap();
    let xml = write(
        dir.path(),
        "ex.xml",
        &patch_scene("exhaustive", 2, 0.3, false, (1.9, 0.02, 40), 16),
    );
    let mut parts = Vec::new();
    for seed in ["1", "2"] {
        let out = dir.path().join(format!("s{seed}.tstats"));
        let r = tstat(&[
            "render",
            &xml,
            "--out",
            out.to_str().unwrap(),
            "--seed",
            seed,
        ]);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        parts.push(out);
    }
    let merged = dir.path().join("m.tstats");
    let r = tstat(&[
        "merge",
        parts[0].to_str().unwrap(),
        parts[1].to_str().unwrap(),
        "--out",
        merged.to_str().unwrap(),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(merged.join("manifest.json")).unwrap())
            .unwrap();
    assert_eq!(m["spp"], 32);
    assert_eq!(m["nlos"]["capture"], "exhaustive");
    assert_eq!(m["nlos"]["laser_grid"], serde_json::json!([2, 2]));
    let h5 = dir.path().join("m.hdf5");
    let r = tstat(&[
        "export",
        merged.to_str().unwrap(),
        "--tal",
        h5.to_str().unwrap(),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let info = tstat(&["info", merged.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&info.stdout);
    assert!(
        text.contains(
            "exhaustive capture: 2 x 2 relay-wall points under each of 2 x 2 laser points"
        ),
        "{text}"
    );
}

/// The rectangle's two triangles share the diagonal u = v, and rays aimed exactly at
/// grid points on it could slip between them (nlos_T's wall moved to x = 0.7: points
/// (6, 6) and (16, 16) of its 32 x 32 grid measured nothing): the relay wall is also
/// met analytically, so every point measures its echo.
#[test]
fn grid_points_on_the_relay_walls_diagonal_are_measured() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/nlos_T.xml");
    let text = std::fs::read_to_string(path).unwrap();
    for offset in ["0.7", "0.3", "-0.45"] {
        let xml = text.replace(
            r#"<shape type="rectangle" id="relay_wall">"#,
            &format!(
                r#"<shape type="rectangle" id="relay_wall"><transform name="to_world"><translate x="{offset}"/></transform>"#
            ),
        );
        let overrides = Overrides {
            spp: Some(8),
            bins: Some(64),
            bin_width_opl: Some(0.05),
            ..Overrides::default()
        };
        let scene = common::load(&xml, &overrides);
        assert!(
            !scene.warnings.iter().any(|w| w.contains("meet nothing")),
            "wall at x = {offset}: {:?}",
            scene.warnings
        );
        let setup = scene.nlos.as_ref().unwrap();
        let missed: Vec<usize> = (0..32 * 32)
            .filter(|&p| setup.sensor_hits[p].is_none())
            .collect();
        assert!(missed.is_empty(), "wall at x = {offset}: missed {missed:?}");
        // The diagonal's points the letter does not hide lie on the wall, where the
        // grid put them.
        let meter = setup.meter.as_ref().unwrap();
        let mut on_wall = 0;
        for i in 0..32 {
            let h = setup.sensor_hits[i * 32 + i].unwrap();
            if h.shape == meter.shape {
                let want = meter.wall.grid_point(i, i, 32, 32);
                let p = h.surface.p;
                assert!((p - want).length() < 1e-5, "{p:?} vs {want:?}");
                on_wall += 1;
            }
        }
        assert!(on_wall >= 24, "wall at x = {offset}: {on_wall} of 32");
    }
}

/// A synthetic capture of a point scatterer at `p`: H = 1 at the bin of each (laser,
/// sensor) path's length |l - p| + |p - s| (laser points `lasers`, or, paired, the
/// sensor points).
fn point_capture(
    p: [f32; 3],
    lasers: Vec<[f32; 3]>,
    paired: bool,
) -> tstat::nlos::capture::Capture {
    point_capture_on(p, lasers, paired, |i, j| [i, j])
}

/// [`point_capture`] with sensor point (i, j) of the 9 x 9 grid at the wall's cell
/// centre `cell(i, j)` of [-1, 1]^2 (z = 0).
fn point_capture_on(
    p: [f32; 3],
    lasers: Vec<[f32; 3]>,
    paired: bool,
    cell: impl Fn(usize, usize) -> [usize; 2],
) -> tstat::nlos::capture::Capture {
    let n = 9;
    let sensors: Vec<[f32; 3]> = (0..n)
        .flat_map(|i| (0..n).map(move |j| (i, j)))
        .map(|(i, j)| {
            let [a, b] = cell(i, j);
            let c = |k: usize| -1.0 + (2.0 * k as f32 + 1.0) / n as f32;
            [c(a), c(b), 0.0]
        })
        .collect();
    let (t_start, delta_t, bins) = (0.5, 0.01, 300);
    let nl = if paired { 1 } else { lasers.len() };
    let mut h = vec![0f32; bins * nl * sensors.len()];
    let d = |a: [f32; 3], b: [f32; 3]| {
        ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
    };
    for l in 0..nl {
        for (s, &sp) in sensors.iter().enumerate() {
            let lp = if paired { sp } else { lasers[l] };
            let len = d(lp, p) as f64 + d(p, sp) as f64;
            let t = ((len - t_start) / delta_t) as usize;
            h[(t * nl + l) * sensors.len() + s] = 1.0;
        }
    }
    tstat::nlos::capture::Capture {
        time: tstat::sensors::time_axis::TimeAxis {
            start_opl: t_start,
            bin_width_opl: delta_t,
            bins,
        },
        lasers: nl,
        sensors: sensors.len(),
        sensor_dims: [9, 9],
        laser_dims: [nl, 1],
        normal: [0.0, 0.0, 1.0],
        h,
        laser_grid: if paired { sensors.clone() } else { lasers },
        sensor_grid: sensors,
        paired,
        laser_xyz: None,
        sensor_xyz: None,
        accounts_first_and_last_bounces: false,
    }
}

/// The scatterer at (0.2, -0.1, 0.8), voxel (14, 8, 6) of the 21 x 21 x 11 grid, with its
/// confocal capture (81 pairs) and an exhaustive one of 3 laser points (243 pairs).
fn scatterer_cases() -> (
    tstat::nlos::reconstruct::bp::VoxelGrid,
    Vec<(tstat::nlos::capture::Capture, f32)>,
) {
    let grid = tstat::nlos::reconstruct::bp::VoxelGrid {
        first: [-0.5, -0.5, 0.5],
        last: [0.5, 0.5, 1.0],
        n: [21, 21, 11],
    };
    let p = [0.2, -0.1, 0.8];
    let lasers = vec![[-0.5, 0.5, 0.0], [0.5, 0.5, 0.0], [0.0, -0.5, 0.0]];
    let cases = vec![
        (point_capture(p, Vec::new(), true), 81.0),
        (point_capture(p, lasers, false), 243.0),
    ];
    (grid, cases)
}

/// Backprojection of a point scatterer: at the scatterer's voxel every (laser, sensor)
/// pair adds its 1 (the maximum, L S), and the peak lies there; confocal and exhaustive.
#[test]
fn backprojection_of_a_point_scatterer_peaks_at_its_voxel() {
    use tstat::nlos::reconstruct::bp::backproject;
    let (grid, cases) = scatterer_cases();
    for (capture, pairs) in cases {
        let v = backproject(&capture, &grid);
        let at = |i: usize, j: usize, k: usize| v[(i * 21 + j) * 11 + k];
        assert_eq!(
            at(14, 8, 6),
            pairs,
            "every pair meets the scatterer's voxel"
        );
        let (best, _) = v
            .iter()
            .enumerate()
            .fold((0, f32::MIN), |b, (i, &x)| if x > b.1 { (i, x) } else { b });
        let (i, j, k) = (best / (21 * 11), best / 11 % 21, best % 11);
        assert_eq!((i, j, k), (14, 8, 6), "peak at voxel {:?}", (i, j, k));
        // Away from the scatterer the pairs disagree on the bin.
        assert!(at(4, 16, 2) < 0.3 * pairs);
    }
}

/// Filtered backprojection of the same scatterer: the magnitude peaks at its voxel
/// (confocal and exhaustive), and the phasor-field filter of an impulse is the pulse,
/// its envelope's peak at the impulse's bin, linear in the input.
#[test]
fn filtered_backprojection_of_a_point_scatterer_peaks_at_its_voxel() {
    use tstat::nlos::filter::pf_filter;
    use tstat::nlos::reconstruct::bp::filtered_backproject;
    let (grid, cases) = scatterer_cases();
    for (capture, _) in cases {
        let v = filtered_backproject(&capture, &grid, 0.2, 0.2 / 2f64.sqrt());
        let best = (0..v.len()).max_by(|&a, &b| v[a].total_cmp(&v[b])).unwrap();
        let (i, j, k) = (best / (21 * 11), best / 11 % 21, best % 11);
        assert_eq!((i, j, k), (14, 8, 6));
    }
    // One series with an impulse at bin 140 (and twice the impulse at bin 40).
    let mut c = point_capture([0.2, -0.1, 0.8], Vec::new(), true);
    c.h.iter_mut().for_each(|x| *x = 0.0);
    let series = c.lasers * c.sensors;
    c.h[140 * series] = 1.0;
    let one = pf_filter(&c, 0.2, 0.2 / 2f64.sqrt());
    let mag =
        |f: &tstat::nlos::filter::Filtered, t: usize| f.re[t * series].hypot(f.im[t * series]);
    let peak = (0..c.time.bins)
        .max_by(|&a, &b| mag(&one, a).total_cmp(&mag(&one, b)))
        .unwrap();
    assert_eq!(peak, 140);
    assert!(mag(&one, 140) > 0.0 && mag(&one, 40) < 1e-6 * mag(&one, 140));
    c.h[40 * series] = 2.0;
    let two = pf_filter(&c, 0.2, 0.2 / 2f64.sqrt());
    assert!((mag(&two, 40) - 2.0 * mag(&one, 140)).abs() < 1e-5 * mag(&one, 140));
    // Other series stay zero.
    assert!(two.re[140 * series + 1] == 0.0 && two.im[140 * series + 1] == 0.0);
}

/// Phasor fields on the same scatterer: the magnitude peaks at its voxel, confocal and
/// exhaustive (the direct sum: the voxels are finer than the wall's grid).
#[test]
fn phasor_field_of_a_point_scatterer_peaks_at_its_voxel() {
    use tstat::nlos::reconstruct::pf::{convolves, phasor_field};
    let (grid, cases) = scatterer_cases();
    for (capture, _) in cases {
        assert!(!convolves(&capture, &grid));
        let v = phasor_field(&capture, &grid, 0.2, 0.2 / 2f64.sqrt()).unwrap();
        let best = (0..v.len()).max_by(|&a, &b| v[a].total_cmp(&v[b])).unwrap();
        let (i, j, k) = (best / (21 * 11), best / 11 % 21, best % 11);
        assert_eq!((i, j, k), (14, 8, 6), "paired {}", capture.paired);
    }
}

/// The capture's spectrum at the pulse's frequencies by direct sums over the bins is
/// the padded FFT's kept bins (to rounding), for short and long pulses, a capture not
/// starting at OPL 0 and one with its first and last bounces timed.
#[test]
fn phasor_field_spectrum_direct_equals_the_fft() {
    use tstat::nlos::reconstruct::pf::{pulse, spectrum_by, Dft};
    let lasers = vec![[-0.5, 0.5, 0.0], [0.0, -0.5, 0.0]];
    for (paired, wl) in [(true, 0.3), (false, 0.05), (false, 0.8)] {
        let mut c = point_capture_on([0.15, -0.1, 0.7], lasers.clone(), paired, |i, j| [i, j]);
        c.accounts_first_and_last_bounces = !paired;
        c.laser_xyz = Some([0.0, 0.0, -1.0]);
        c.sensor_xyz = Some([0.5, 0.0, -1.0]);
        let p = pulse(c.time.bins, c.time.bin_width_opl, wl, wl / 2f64.sqrt()).unwrap();
        let fft = spectrum_by(&c, &p, Dft::Fft);
        let direct = spectrum_by(&c, &p, Dft::Direct);
        let top = fft.iter().fold(0f64, |a, z| a.max(z.norm()));
        let worst = fft
            .iter()
            .zip(&direct)
            .fold(0f64, |a, (x, y)| a.max((x - y).norm()));
        assert!(
            top > 0.0 && worst <= 1e-10 * top,
            "wl {wl}: {worst} of {top}"
        );
    }
}

/// The FFT convolution of phasor fields equals the direct sum, whatever way the wall's
/// grid runs against the voxel axes (flipped, swapped), confocal and exhaustive; and
/// the vectorised complex dot product equals its reference.
#[test]
fn phasor_field_convolution_equals_the_direct_sum() {
    use tstat::nlos::reconstruct::bp::VoxelGrid;
    use tstat::nlos::reconstruct::pf::{
        convolves, dot, dot_reference, phasor_field_by, Propagation,
    };
    // Slices of 13 x 13 voxels at the wall's spacing 2/9, wider than the wall.
    let grid = VoxelGrid {
        first: [-4.0 / 3.0, -4.0 / 3.0, 0.6],
        last: [4.0 / 3.0, 4.0 / 3.0, 1.0],
        n: [13, 13, 5],
    };
    let p = [0.15, -0.1, 0.7];
    let lasers = vec![[-0.5, 0.5, 0.0], [0.5, 0.5, 0.0], [0.0, -0.5, 0.0]];
    type Cell = fn(usize, usize) -> [usize; 2];
    let cells: [(&str, Cell); 4] = [
        ("as is", |i, j| [i, j]),
        ("x flipped", |i, j| [8 - i, j]),
        ("swapped", |i, j| [j, i]),
        ("swapped, both flipped", |i, j| [8 - j, 8 - i]),
    ];
    for (name, cell) in cells {
        for paired in [true, false] {
            let c = point_capture_on(p, lasers.clone(), paired, cell);
            assert!(convolves(&c, &grid), "{name}");
            let fast =
                phasor_field_by(&c, &grid, 0.3, 0.3 / 2f64.sqrt(), Propagation::Fastest).unwrap();
            let slow =
                phasor_field_by(&c, &grid, 0.3, 0.3 / 2f64.sqrt(), Propagation::Direct).unwrap();
            let top = slow.iter().fold(0f32, |a, &b| a.max(b));
            let worst = fast
                .iter()
                .zip(&slow)
                .fold(0f32, |a, (x, y)| a.max((x - y).abs()));
            assert!(
                top > 0.0 && worst <= 1e-4 * top,
                "{name}, paired {paired}: {worst} of {top}"
            );
        }
    }
    // A slice step other than the wall's: no convolution.
    let finer = VoxelGrid {
        n: [25, 25, 5],
        ..grid
    };
    assert!(!convolves(&point_capture(p, Vec::new(), true), &finer));
    let n = 37;
    let v = |k: usize| {
        (0..n)
            .map(|s| ((s * 7 + k * 3) % 11) as f32 / 5.0 - 1.0)
            .collect::<Vec<_>>()
    };
    let (hr, hi, er, ei) = (v(0), v(1), v(2), v(3));
    let (a, b) = (dot(&hr, &hi, &er, &ei), dot_reference(&hr, &hi, &er, &ei));
    assert!((a - b).norm() <= 1e-5 * b.norm().max(1.0), "{a} vs {b}");
}

#[test]
fn reconstruct_reads_bundles_and_tal_files_alike_and_refuses_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let xml = write(
        dir.path(),
        "c.xml",
        &patch_scene("confocal", 4, 0.3, false, (1.9, 0.02, 40), 16),
    );
    let bundle = dir.path().join("c.tstats");
    let b = bundle.to_str().unwrap();
    assert!(tstat(&["render", &xml, "--out", b]).status.success());
    let h5 = dir.path().join("c.hdf5");
    assert!(tstat(&["export", b, "--tal", h5.to_str().unwrap()])
        .status
        .success());
    let mut outs = Vec::new();
    for (i, src) in [b, h5.to_str().unwrap()].into_iter().enumerate() {
        let out = dir.path().join(format!("v{i}.npy"));
        let r = tstat(&[
            "nlos",
            "reconstruct",
            src,
            "--method",
            "bp",
            "--volume=-0.5,0.5,-0.5,0.5,0.6,1.4",
            "--voxels",
            "11,11,9",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        let v: ndarray::Array3<f32> = ndarray_npy::read_npy(&out).unwrap();
        assert_eq!(v.shape(), &[11, 11, 9]);
        assert!(v.iter().any(|&x| x > 0.0));
        outs.push(v);
    }
    assert_eq!(outs[0], outs[1], "bundle and export reconstruct alike");
    let out = dir.path().join("bad.npy");
    let o = out.to_str().unwrap();
    let cbox = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cbox.xml");
    let cb = dir.path().join("cbox.tstats");
    assert!(tstat(&[
        "render",
        cbox.to_str().unwrap(),
        "--out",
        cb.to_str().unwrap(),
        "--spp",
        "2",
        "--width",
        "8"
    ])
    .status
    .success());
    // (capture, method, volume, voxels) and the message each must give.
    let cbox_bundle = cb.to_str().unwrap();
    for (capture, method, volume, voxels, want) in [
        (b, "bp", "0,1,0,1,0", "2,2,2", "6 comma-separated"),
        (b, "bp", "0,1,0,1,0,1", "2,0,2", "at least one voxel"),
        (b, "bp", "0,1,0,1,0,inf", "2,2,2", "finite"),
        (b, "bp", "0,1,0,1,0,1", "100000,100000,100", "more than"),
        (b, "xyz", "0,1,0,1,0,1", "2,2,2", "invalid value"),
        (b, "pf", "0,1,0,1,0,1", "2,2,2", "needs --wl-mean"),
        (b, "fbp", "0,1,0,1,0,1", "2,2,2", "needs --wl-mean"),
        (
            cbox_bundle,
            "bp",
            "0,1,0,1,0,1",
            "2,2,2",
            "not an NLOS capture",
        ),
        ("missing.hdf5", "bp", "0,1,0,1,0,1", "2,2,2", "missing.hdf5"),
        (
            xml.as_str(),
            "bp",
            "0,1,0,1,0,1",
            "2,2,2",
            "bundle directory or a y-tal",
        ),
    ] {
        let args = [
            "nlos",
            "reconstruct",
            capture,
            "--method",
            method,
            "--volume",
            volume,
            "--voxels",
            voxels,
            "--out",
            o,
        ];
        let r = tstat(&args);
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(!r.status.success() && err.contains(want), "{args:?}: {err}");
        assert!(!out.exists());
    }
    // Flags that belong to other methods, a pulse above the Nyquist frequency, a
    // memory budget too small.
    for (method, extra, want) in [
        ("bp", &["--snr", "1"][..], "--snr belongs to --method lct"),
        ("lct", &["--snr=-1"][..], "must be positive"),
        (
            "fk",
            &["--wl-mean", "0.1"][..],
            "belong to --method fbp and pf",
        ),
        ("pf", &["--wl-mean", "0.01"][..], "Nyquist"),
        ("fk", &["--max-memory", "1K"][..], "over --max-memory"),
    ] {
        let mut args = vec![
            "nlos",
            "reconstruct",
            b,
            "--method",
            method,
            "--volume=-0.5,0.5,-0.5,0.5,0.6,1.4",
            "--voxels",
            "11,11,9",
            "--out",
            o,
        ];
        args.extend_from_slice(extra);
        let r = tstat(&args);
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(!r.status.success() && err.contains(want), "{args:?}: {err}");
        assert!(!out.exists());
    }
    // The other methods run on the same capture through the CLI.
    for (method, extra) in [
        ("fbp", &["--wl-mean", "0.2"][..]),
        ("pf", &["--wl-mean", "0.2"][..]),
        ("fk", &[][..]),
        ("lct", &["--snr", "2"][..]),
    ] {
        let mut args = vec![
            "nlos",
            "reconstruct",
            b,
            "--method",
            method,
            "--volume=-0.5,0.5,-0.5,0.5,0.6,1.4",
            "--voxels",
            "11,11,9",
            "--out",
            o,
        ];
        args.extend_from_slice(extra);
        let r = tstat(&args);
        assert!(
            r.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&r.stderr)
        );
        let v: ndarray::Array3<f32> = ndarray_npy::read_npy(&out).unwrap();
        assert!(
            v.iter().all(|x| x.is_finite()) && v.iter().any(|&x| x > 0.0),
            "{method}"
        );
        std::fs::remove_file(&out).unwrap();
    }
    // An existing output is kept without --force.
    let kept = dir.path().join("v0.npy");
    let before = std::fs::read(&kept).unwrap();
    let r = tstat(&[
        "nlos",
        "reconstruct",
        b,
        "--method",
        "bp",
        "--volume",
        "0,1,0,1,0,1",
        "--voxels",
        "2,2,2",
        "--out",
        kept.to_str().unwrap(),
    ]);
    assert!(!r.status.success());
    assert_eq!(std::fs::read(&kept).unwrap(), before);
}

/// Maximum-intensity projections: a voxel lands where each view puts it (x right, y
/// up, depth right or up), the maximum wins along the ray, and `nlos mip` writes the
/// picture at the scale asked and refuses bad input.
#[test]
fn mip_projects_where_each_view_puts_a_voxel() {
    use tstat::viz::mip::{picture, project, ramp, Axis};
    let n = [4, 3, 5];
    let mut v = vec![0f32; 60];
    let at = |i: usize, j: usize, k: usize| (i * 3 + j) * 5 + k;
    v[at(3, 0, 1)] = 2.0;
    v[at(3, 0, 4)] = 5.0;
    v[at(0, 2, 0)] = f32::NAN;
    let z = project(&v, n, Axis::Z);
    assert_eq!((z.width, z.height), (4, 3));
    // x = 3 is the last column, y = 0 the bottom row; the larger of 2 and 5.
    assert_eq!(z.values[2 * 4 + 3], 5.0);
    assert_eq!(z.values[0], 0.0, "NaN counts as 0");
    let x = project(&v, n, Axis::X);
    assert_eq!((x.width, x.height), (5, 3));
    assert_eq!(x.values[2 * 5 + 4], 5.0);
    assert_eq!(x.values[2 * 5 + 1], 2.0);
    let y = project(&v, n, Axis::Y);
    assert_eq!((y.width, y.height), (4, 5));
    // Depth 4 is the top row, depth 1 the fourth.
    assert_eq!(y.values[3], 5.0);
    assert_eq!(y.values[3 * 4 + 3], 2.0);
    let (w, h, px) = picture(&z, 3);
    assert_eq!((w, h, px.len()), (12, 9, 12 * 9 * 3));
    let last = ((2 * 3) * 12 + 9) * 3;
    assert_eq!(&px[last..last + 3], &ramp(1.0));
    assert_eq!(&px[0..3], &ramp(0.0));

    let dir = tempfile::tempdir().unwrap();
    // The command refuses a volume with a NaN (tests/it/hostile_volumes.rs); this one has 0.
    v[at(0, 2, 0)] = 0.0;
    let npy = dir.path().join("v.npy");
    let arr = ndarray::Array3::from_shape_vec((4, 3, 5), v).unwrap();
    ndarray_npy::write_npy(&npy, &arr).unwrap();
    let png = dir.path().join("v.png");
    let (i, o) = (npy.to_str().unwrap(), png.to_str().unwrap());
    let r = tstat(&["nlos", "mip", i, "--axis", "x", "--scale", "2", "--out", o]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let img = image::open(&png).unwrap();
    assert_eq!((img.width(), img.height()), (10, 6));
    let before = std::fs::read(&png).unwrap();
    for (args, want) in [
        (vec!["nlos", "mip", i, "--out", o], "exists"),
        (
            vec!["nlos", "mip", i, "--scale", "0", "--out", o, "--force"],
            "at least one pixel",
        ),
        (
            vec!["nlos", "mip", "missing.npy", "--out", o, "--force"],
            "missing.npy",
        ),
        (vec!["nlos", "mip", i, "--out", i, "--force"], ".png"),
    ] {
        let r = tstat(&args);
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(!r.status.success() && err.contains(want), "{args:?}: {err}");
    }
    assert_eq!(std::fs::read(&png).unwrap(), before);
    // A 2-D array is no volume.
    let flat = dir.path().join("flat.npy");
    ndarray_npy::write_npy(&flat, &ndarray::Array2::<f32>::zeros((3, 3))).unwrap();
    let r = tstat(&[
        "nlos",
        "mip",
        flat.to_str().unwrap(),
        "--out",
        dir.path().join("f.png").to_str().unwrap(),
    ]);
    assert!(
        !r.status.success() && String::from_utf8_lossy(&r.stderr).contains("(NX, NY, NZ) volume")
    );
}

/// Denoising a capture: NLOS defaults (radius 1, no depth alignment) unless asked, and
/// `nlos reconstruct --denoised` reads a (rows, Sx, T, C) volume of the capture in place
/// of its noisy means (the noisy mean itself gives the bundle's reconstruction).
#[test]
fn denoised_captures_reconstruct_with_nlos_defaults() {
    let dir = tempfile::tempdir().unwrap();
    let xml = write(
        dir.path(),
        "c.xml",
        &patch_scene("confocal", 4, 0.3, false, (1.9, 0.02, 40), 16),
    );
    let bundle = dir.path().join("c.tstats");
    let b = bundle.to_str().unwrap();
    assert!(tstat(&["render", &xml, "--out", b]).status.success());
    let d = dir.path().join("d.npy");
    let r = tstat(&["denoise", b, "--out", d.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{err}");
    assert!(err.contains("spatial radius 1, bins not aligned"), "{err}");
    let r = tstat(&[
        "denoise",
        b,
        "--out",
        d.to_str().unwrap(),
        "--force",
        "--radius",
        "2",
        "--depth-align",
    ]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        r.status.success() && err.contains("spatial radius 2, bins aligned"),
        "{err}"
    );

    // The noisy mean as a "denoised" volume.
    let x1: ndarray::Array4<f64> = ndarray_npy::read_npy(bundle.join("x1.npy")).unwrap();
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(bundle.join("manifest.json")).unwrap())
            .unwrap();
    let spp = manifest["spp"].as_f64().unwrap();
    let mean = x1.mapv(|v| (v / spp) as f32);
    let m = dir.path().join("mean.npy");
    ndarray_npy::write_npy(&m, &mean).unwrap();
    let recon = |extra: &[&str], out: &str| {
        let mut args = vec![
            "nlos",
            "reconstruct",
            b,
            "--method",
            "bp",
            "--volume=-0.5,0.5,-0.5,0.5,0.6,1.4",
            "--voxels",
            "7,7,5",
            "--out",
            out,
        ];
        args.extend_from_slice(extra);
        tstat(&args)
    };
    let (o1, o2) = (dir.path().join("a.npy"), dir.path().join("b.npy"));
    assert!(recon(&[], o1.to_str().unwrap()).status.success());
    let r = recon(&["--denoised", m.to_str().unwrap()], o2.to_str().unwrap());
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let a: ndarray::Array3<f32> = ndarray_npy::read_npy(&o1).unwrap();
    let c: ndarray::Array3<f32> = ndarray_npy::read_npy(&o2).unwrap();
    let top = a.iter().fold(0f32, |x, &y| x.max(y));
    assert!(top > 0.0);
    for (x, y) in a.iter().zip(&c) {
        assert!((x - y).abs() <= 1e-5 * top, "{x} vs {y}");
    }
    // A volume of another shape, and one without its bundle.
    let wrong = dir.path().join("wrong.npy");
    ndarray_npy::write_npy(&wrong, &ndarray::Array4::<f32>::zeros((3, 4, 40, 3))).unwrap();
    let bad = dir.path().join("bad.npy");
    let r = recon(
        &["--denoised", wrong.to_str().unwrap()],
        bad.to_str().unwrap(),
    );
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        !r.status.success() && err.contains("capture's film is"),
        "{err}"
    );
    assert!(!bad.exists());
}
