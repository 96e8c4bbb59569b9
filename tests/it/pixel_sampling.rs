//! Stratified sub-pixel sampling (`render::pixel_sampling`) against independent sampling:
//! unbiased (same means), lower error at edges, deterministic across thread counts,
//! independent mode unchanged, and the `pixel_sampling` manifest field through render,
//! run, merge and info.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use tstat::math::rng::Pcg32;
use tstat::render::deposits::PathDeposits;
use tstat::render::path_common::PathTally;
use tstat::render::tracer::trace_path;
use tstat::render::{pixel_positions, render, PixelSampling, RenderOutput, RenderSettings};
use tstat::scene::{Overrides, Scene};
use tstat::stats::Transform;

/// A grey plane (rotated so its border is not pixel-aligned) lit by a point light, with
/// a small rotated card in front of it casting a hard shadow. `max_depth` 2 is direct
/// lighting only: with a point light there is nothing random after the primary ray, so
/// every path's radiance is a function of its sub-pixel position alone, and all the
/// noise comes from the pixel sampler (the most sensitive case for these tests).
const EDGES: &str = r#"<scene version="3.0.0">
  <default name="spp" value="16"/>
  <default name="res" value="24"/>
  <default name="sampler" value="independent"/>
  <integrator type="transient_path"><integer name="max_depth" value="2"/></integrator>
  <sensor type="perspective">
    <float name="fov" value="34"/>
    <transform name="to_world"><lookat origin="0,0,4" target="0,0,0" up="0,1,0"/></transform>
    <sampler type="$sampler"><integer name="sample_count" value="$spp"/></sampler>
    <film type="transient_hdr_film">
      <integer name="width" value="$res"/><integer name="height" value="$res"/>
      <integer name="temporal_bins" value="40"/>
      <float name="start_opl" value="5"/><float name="bin_width_opl" value="0.1"/>
    </film>
  </sensor>
  <bsdf type="diffuse" id="grey"><rgb name="reflectance" value="0.6, 0.5, 0.4"/></bsdf>
  <shape type="rectangle">
    <transform name="to_world"><scale value="0.9"/><rotate z="1" angle="11"/></transform>
    <ref id="grey"/>
  </shape>
  <shape type="rectangle">
    <transform name="to_world"><scale value="0.3"/><rotate z="1" angle="27"/><translate x="-0.2" y="0.1" z="0.8"/></transform>
    <ref id="grey"/>
  </shape>
  <emitter type="point"><point name="position" x="0.6" y="0.4" z="3"/><rgb name="intensity" value="8, 8, 8"/></emitter>
</scene>"#;

fn load(xml: &str, overrides: &Overrides) -> Scene {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("scene.xml");
    std::fs::write(&path, xml).unwrap();
    Scene::load(&path, overrides).unwrap()
}

fn with_spp(spp: u32) -> Overrides {
    Overrides {
        spp: Some(spp),
        ..Overrides::default()
    }
}

fn settings(spp: u32, seed: u64, pixel_sampling: PixelSampling) -> RenderSettings {
    RenderSettings {
        spp,
        seed,
        transform: Transform::Identity,
        pixel_sampling,
        replicates: 0,
        pixel_spp: None,
    }
}

fn run(scene: &Scene, seed: u64, mode: PixelSampling) -> RenderOutput {
    render(scene, &settings(scene.spp, seed, mode), &|_| {})
}

/// Per pixel, the steady radiance summed over the three channels.
fn steady_luminance(out: &RenderOutput) -> Vec<f64> {
    out.steady.chunks(3).map(|c| c.iter().sum()).collect()
}

fn mean_var(xs: &[f64]) -> (f64, f64) {
    let n = xs.len() as f64;
    let m = xs.iter().sum::<f64>() / n;
    let v = xs.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (n - 1.0);
    (m, v)
}

/// Unbiasedness. K = 128 renders per mode (different seeds, so all renders are
/// independent); for every pixel, Welch's t of the difference between the two modes'
/// means over the K renders. Under "same expectation" each t is (approximately)
/// Student's t with at least K - 1 = 127 degrees of freedom, so E[t^2] <= 127/125 =
/// 1.016 and Var[t^2] ~ 2.1; pixels are independent (their random streams are hashed
/// from the pixel), so the mean of t^2 over the ~340 pixels that vary has a standard
/// deviation of ~0.08, and the bound 1.4 is five of those above the expectation.
/// Measured: 0.91-1.23 over 16 sets of seeds. Sensitivity, measured by editing
/// `PixelPattern::position`: a sampler that leaves out the last 3% of every pixel
/// (u in [0, 0.97)) gives 2.8, the last 10% gives 22, the lower half of v 160+; 1% is
/// not detected (1.12). Also the whole image's mean, a z-test with |z| < 4.
#[test]
fn stratified_and_independent_renders_agree_in_the_mean() {
    const K: u64 = 128;
    let scene = load(EDGES, &with_spp(16));
    let renders = |mode: PixelSampling, seed0: u64| -> Vec<Vec<f64>> {
        (0..K)
            .map(|k| steady_luminance(&run(&scene, seed0 + k, mode)))
            .collect()
    };
    let strat = renders(PixelSampling::Stratified, 1000);
    let indep = renders(PixelSampling::Independent, 2000);
    let pixels = strat[0].len();
    let (mut t2_sum, mut tested) = (0.0, 0usize);
    for p in 0..pixels {
        let s: Vec<f64> = strat.iter().map(|r| r[p]).collect();
        let i: Vec<f64> = indep.iter().map(|r| r[p]).collect();
        let ((ms, vs), (mi, vi)) = (mean_var(&s), mean_var(&i));
        let se2 = (vs + vi) / K as f64;
        if se2 == 0.0 {
            // Constant in both modes (background, fully in shadow): equal.
            assert!((ms - mi).abs() <= 1e-12 * ms.abs().max(1.0), "pixel {p}");
            continue;
        }
        t2_sum += (ms - mi) * (ms - mi) / se2;
        tested += 1;
    }
    assert!(tested > pixels / 2, "only {tested} of {pixels} pixels vary");
    let mean_t2 = t2_sum / tested as f64;
    eprintln!("mean t^2 over {tested} pixels: {mean_t2:.3}");
    assert!(mean_t2 < 1.4, "mean t^2 {mean_t2:.3} over {tested} pixels");
    // Far below 1 would mean the renders are not independent draws (or the variances
    // are wrong): the test would then have no power.
    assert!(mean_t2 > 0.5, "mean t^2 {mean_t2:.3}: suspiciously small");

    let image = |r: &Vec<f64>| r.iter().sum::<f64>() / pixels as f64;
    let (ms, vs) = mean_var(&strat.iter().map(image).collect::<Vec<_>>());
    let (mi, vi) = mean_var(&indep.iter().map(image).collect::<Vec<_>>());
    let z = (ms - mi) / ((vs + vi) / K as f64).sqrt();
    eprintln!("image mean: stratified {ms:.6}, independent {mi:.6}, z {z:.2}");
    assert!(z.abs() < 4.0, "image means differ: z = {z:.2}");
}

fn rmse(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    let se: f64 = a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum();
    (se / a.len() as f64).sqrt()
}

fn volume_mean(out: &RenderOutput, spp: u32) -> Vec<f64> {
    out.accum.x1.iter().map(|s| s / spp as f64).collect()
}

/// At 16 and 64 spp on the edge scene, stratified sampling's error against an 8192-spp
/// reference (independent sampling, so it favours neither mode) is well below
/// independent sampling's, for the steady image and for the transient volume (x1 / n).
/// Theory for a pixel crossed by an edge: jittered sampling's variance falls as
/// n^-1.5 against n^-1, an RMSE ratio near n^-0.25 (0.5 at 16 spp, 0.35 at 64).
/// Measured RMSE ratios (stratified / independent, MSE pooled over 4 seeds), over 21
/// sets of seeds: 16 spp steady 0.41-0.50, volume 0.41-0.49; 64 spp steady 0.27-0.37,
/// volume 0.29-0.34. Bounds: 0.6 and 0.45 (independent sampling in both modes gives 1).
#[test]
fn stratified_error_at_edges_is_lower_than_independent() {
    let reference_scene = load(EDGES, &with_spp(8192));
    let reference = run(&reference_scene, 7, PixelSampling::Independent);
    let (ref_steady, ref_volume) = (reference.steady.clone(), volume_mean(&reference, 8192));
    // (spp, bound on the RMSE ratio, steady and volume alike).
    for (spp, max_ratio) in [(16u32, 0.6), (64, 0.45)] {
        let scene = load(EDGES, &with_spp(spp));
        let mut mse = [[0.0f64; 2]; 2]; // [mode][steady, volume]
        for (m, mode) in [PixelSampling::Stratified, PixelSampling::Independent]
            .into_iter()
            .enumerate()
        {
            for seed in 0..4 {
                let out = run(&scene, 100 + seed, mode);
                mse[m][0] += rmse(&out.steady, &ref_steady).powi(2) / 4.0;
                mse[m][1] += rmse(&volume_mean(&out, spp), &ref_volume).powi(2) / 4.0;
            }
        }
        let steady = (mse[0][0] / mse[1][0]).sqrt();
        let volume = (mse[0][1] / mse[1][1]).sqrt();
        eprintln!(
            "{spp} spp: RMSE ratio stratified/independent: steady {steady:.3}, volume {volume:.3}"
        );
        assert!(steady < max_ratio, "{spp} spp: steady ratio {steady:.3}");
        assert!(volume < max_ratio, "{spp} spp: volume ratio {volume:.3}");
    }
}

/// Independent mode is the original sampler: the position is the first two numbers of
/// the path's own stream. And in both modes only the position differs: the renderer's
/// output equals a plain re-implementation of the per-pixel loop (trace each sample
/// from `pixel_positions`, sum its deposits in sample order), bit for bit.
#[test]
fn only_the_sub_pixel_position_depends_on_the_mode() {
    let cbox = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cbox.xml");
    let overrides = Overrides {
        spp: Some(5),
        width: Some(8),
        bins: Some(30),
        ..Overrides::default()
    };
    let scene = Scene::load(&cbox, &overrides).unwrap();
    let (w, h, bins) = (scene.film.width, scene.film.height, scene.film.time.bins);
    for mode in [PixelSampling::Independent, PixelSampling::Stratified] {
        let set = settings(scene.spp, 42, mode);
        let out = render(&scene, &set, &|_| {});
        let mut x1 = vec![0.0f64; w * h * bins * 3];
        let mut nonzero = vec![0u32; w * h * bins];
        let mut steady = vec![0.0f64; w * h * 3];
        let mut deposits = PathDeposits::default();
        for y in 0..h {
            for x in 0..w {
                let pixel = (y * w + x) as u64;
                let positions = pixel_positions(&set, pixel);
                let mut tally = PathTally::default();
                for s in 0..set.spp {
                    let mut rng = Pcg32::for_path(set.seed, pixel, s as u64);
                    let jitter = rng.next_2d();
                    let [u, v] = positions[s as usize];
                    if mode == PixelSampling::Independent {
                        assert_eq!([u, v], jitter, "pixel {pixel} sample {s}");
                    }
                    let d = scene.camera.direction(x as f32 + u, y as f32 + v);
                    trace_path(&scene, d, &mut rng, &mut deposits, &mut tally);
                    for (bin, c) in deposits.drain() {
                        let vx = pixel as usize * bins + bin as usize;
                        nonzero[vx] += 1;
                        for (k, ck) in c.iter().enumerate() {
                            x1[vx * 3 + k] += ck;
                        }
                    }
                }
                for c in 0..3 {
                    steady[pixel as usize * 3 + c] = tally.steady[c] / set.spp as f64;
                }
            }
        }
        assert!(x1.iter().any(|&v| v > 0.0));
        assert!(out.accum.x1 == x1, "{mode}: x1 differs from the plain loop");
        assert!(out.accum.nonzero == nonzero, "{mode}: counts differ");
        assert!(out.steady == steady, "{mode}: steady differs");
    }
    // The modes do differ, and only in position: the stratified positions are not the
    // path stream's.
    let a = pixel_positions(&settings(5, 42, PixelSampling::Stratified), 3);
    let b = pixel_positions(&settings(5, 42, PixelSampling::Independent), 3);
    assert_ne!(a, b);
}

// ---- The binary ----

fn tstat(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_tstat"))
        .args(args)
        .output()
        .unwrap()
}

fn ok(args: &[&str]) -> String {
    let r = tstat(args);
    assert!(
        r.status.success(),
        "tstat {args:?}: {}",
        String::from_utf8_lossy(&r.stderr)
    );
    String::from_utf8_lossy(&r.stdout).into_owned()
}

fn s(p: &Path) -> String {
    p.display().to_string()
}

struct Dir {
    dir: tempfile::TempDir,
    scene: PathBuf,
}

impl Dir {
    fn new(xml: &str) -> Self {
        let dir = tempfile::tempdir().unwrap();
        let scene = dir.path().join("scene.xml");
        std::fs::write(&scene, xml).unwrap();
        Dir { dir, scene }
    }

    fn path(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }

    /// Renders the scene into `name` with `extra` flags (small: 10 x 10, 6 spp).
    fn render(&self, name: &str, extra: &[&str]) -> PathBuf {
        let out = self.path(name);
        let (scene, o) = (s(&self.scene), s(&out));
        let mut args = vec!["render", &scene, "--out", &o, "--width", "10", "--spp", "6"];
        args.extend_from_slice(extra);
        ok(&args);
        out
    }
}

const ARRAYS: [&str; 9] = [
    "x1.npy",
    "x2.npy",
    "x3.npy",
    "nonzero.npy",
    "albedo.npy",
    "normal.npy",
    "depth.npy",
    "emitter.npy",
    "steady.npy",
];

fn same_arrays(a: &Path, b: &Path) -> bool {
    ARRAYS
        .iter()
        .all(|f| std::fs::read(a.join(f)).unwrap() == std::fs::read(b.join(f)).unwrap())
}

fn manifest(bundle: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(bundle.join("manifest.json")).unwrap()).unwrap()
}

fn recorded(bundle: &Path) -> String {
    manifest(bundle)["pixel_sampling"]
        .as_str()
        .expect("pixel_sampling is a string")
        .to_string()
}

/// Stratified renders (at an spp that is not a power of two) are bit-identical with 1
/// and 2 threads, and so are Sobol' renders (the default); independent renders repeat
/// bit for bit too; and the flag changes the result.
#[test]
fn renders_are_deterministic_in_both_modes() {
    let d = Dir::new(EDGES);
    let s1 = d.render("s1.tstats", &["--threads", "1", "--seed", "9"]);
    let s2 = d.render("s2.tstats", &["--threads", "2", "--seed", "9"]);
    assert!(same_arrays(&s1, &s2), "sobol: 1 and 2 threads differ");
    let t1 = d.render(
        "t1.tstats",
        &["--threads", "1", "--seed", "9", "--sampler", "stratified"],
    );
    let t2 = d.render(
        "t2.tstats",
        &[
            "--threads",
            "2",
            "--seed",
            "9",
            "--pixel-sampling",
            "stratified",
        ],
    );
    assert!(same_arrays(&t1, &t2), "stratified: 1 and 2 threads differ");
    let i1 = d.render(
        "i1.tstats",
        &[
            "--threads",
            "1",
            "--seed",
            "9",
            "--pixel-sampling",
            "independent",
        ],
    );
    let i2 = d.render(
        "i2.tstats",
        &[
            "--threads",
            "2",
            "--seed",
            "9",
            "--pixel-sampling",
            "independent",
        ],
    );
    assert!(same_arrays(&i1, &i2), "independent: two renders differ");
    let x1 = |b: &Path| std::fs::read(b.join("x1.npy")).unwrap();
    assert!(x1(&t1) != x1(&i1), "the two modes gave the same sums");
}

#[test]
fn the_manifest_records_the_mode_and_merge_and_info_carry_it() {
    let d = Dir::new(EDGES);
    let strat = d.render(
        "s.tstats",
        &["--seed", "1", "--pixel-sampling", "stratified"],
    );
    let strat2 = d.render(
        "s2.tstats",
        &["--seed", "2", "--sampler", "stratified-pixel"],
    );
    let sobol = d.render("sobol.tstats", &["--seed", "4"]);
    assert_eq!(recorded(&sobol), "sobol", "the default");
    let indep = d.render(
        "i.tstats",
        &["--seed", "3", "--pixel-sampling", "independent"],
    );
    assert_eq!(recorded(&strat), "stratified");
    assert_eq!(recorded(&indep), "independent");
    let info = ok(&["info", &s(&strat)]);
    assert!(info.contains("stratified sub-pixel sampling"), "{info}");
    let info = ok(&["info", &s(&indep)]);
    assert!(info.contains("independent sub-pixel sampling"), "{info}");

    let merge = |name: &str, inputs: &[&Path]| -> PathBuf {
        let out = d.path(name);
        let mut args = vec!["merge".to_string()];
        args.extend(inputs.iter().map(|p| s(p)));
        args.extend(["--out".to_string(), s(&out)]);
        ok(&args.iter().map(String::as_str).collect::<Vec<_>>());
        out
    };
    let mixed = merge("mixed.tstats", &[&strat, &indep]);
    assert_eq!(recorded(&mixed), "mixed");
    assert_eq!(manifest(&mixed)["spp"], 12);
    let info = ok(&["info", &s(&mixed)]);
    assert!(info.contains("mixed sub-pixel sampling"), "{info}");
    let both = merge("both.tstats", &[&strat, &strat2]);
    assert_eq!(recorded(&both), "stratified");
    let info = ok(&["info", &s(&both)]);
    assert!(
        info.contains("stratified sub-pixel sampling (per merged render"),
        "{info}"
    );

    // A bundle written before the field existed reads as independent.
    let legacy = d.path("legacy.tstats");
    std::fs::create_dir(&legacy).unwrap();
    for e in std::fs::read_dir(&indep).unwrap().flatten() {
        std::fs::copy(e.path(), legacy.join(e.file_name())).unwrap();
    }
    let mut m = manifest(&legacy);
    m.as_object_mut().unwrap().remove("pixel_sampling").unwrap();
    m["seed"] = 4.into();
    std::fs::write(legacy.join("manifest.json"), m.to_string()).unwrap();
    let info = ok(&["info", &s(&legacy)]);
    assert!(info.contains("independent sub-pixel sampling"), "{info}");
    let parsed: tstat::bundle::manifest::Manifest = serde_json::from_value(m).unwrap();
    assert_eq!(
        parsed.pixel_sampling,
        tstat::bundle::manifest::SamplingRecord::Independent
    );
    assert_eq!(
        recorded(&merge("li.tstats", &[&legacy, &indep])),
        "independent"
    );
    assert_eq!(recorded(&merge("ls.tstats", &[&legacy, &strat])), "mixed");
    // Mixed stays mixed whatever is merged into it.
    assert_eq!(recorded(&merge("m3.tstats", &[&mixed, &strat2])), "mixed");
}

#[test]
fn run_takes_the_flag_and_records_it() {
    let d = Dir::new(EDGES);
    let out = d.path("run");
    ok(&[
        "run",
        &s(&d.scene),
        "--out",
        &s(&out),
        "--width",
        "8",
        "--spp",
        "4",
        "--every",
        "20",
        "--pixel-sampling",
        "independent",
    ]);
    assert_eq!(recorded(&out.join("scene.tstats")), "independent");
}

/// The scene's `<sampler>` type does not choose the sub-pixel sampling (the flag does):
/// Mitsuba's stratified-like samplers load as plain spp/seed requests and give the same
/// bits as the flag's default; other types are refused with a pointer to the flag.
#[test]
fn the_xml_sampler_type_does_not_choose_the_pixel_sampling() {
    let d = Dir::new(EDGES);
    let base = d.render("independent.tstats", &["--seed", "5"]);
    for kind in ["stratified", "multijitter", "orthogonal", "ldsampler"] {
        let def = format!("sampler={kind}");
        let out = d.render(&format!("{kind}.tstats"), &["--seed", "5", "-D", &def]);
        assert!(same_arrays(&base, &out), "sampler {kind}");
        assert_eq!(recorded(&out), "sobol", "sampler {kind}");
    }
    let r = tstat(&[
        "render",
        &s(&d.scene),
        "--out",
        &s(&d.path("x.tstats")),
        "-D",
        "sampler=sobol",
    ]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "{err}");
    assert!(
        err.contains("sampler 'sobol' is not supported") && err.contains("--pixel-sampling"),
        "{err}"
    );
}
