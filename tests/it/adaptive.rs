//! Adaptive sampling (`render/adaptive.rs`): per-pixel counts render exactly the
//! samples a plain loop traces, the same bits at 1 and 2 threads, uniform counts are
//! today's render bit for bit; the pilot's allocation leaves the means unbiased
//! (Welch tests over seeds against uniform sampling), and the test catches the
//! mutation that lets the pilot's samples into the estimate. Through the binary: the
//! bundle's `pixel_spp.npy`, and every reader dividing by each pixel's own count.

use std::path::Path;
use std::process::Command;
use std::sync::Arc;
use tstat::render::adaptive::{allocate, pilot, weights, AdaptiveOptions, ErrorMeasure};
use tstat::render::deposits::PathDeposits;
use tstat::render::path_common::PathTally;
use tstat::render::tracer::trace_path;
use tstat::render::{render, PixelSampling, RenderOutput, RenderSettings};
use tstat::scene::{Overrides, Scene};
use tstat::stats::Transform;

use crate::common;
use common::bundled;

fn settings(spp: u32, seed: u64, sampling: PixelSampling) -> RenderSettings {
    RenderSettings {
        spp,
        seed,
        transform: Transform::Identity,
        pixel_sampling: sampling,
        replicates: 0,
        pixel_spp: None,
    }
}

fn small_cbox(width: usize, bins: usize, spp: u32) -> Scene {
    bundled(
        "cbox.xml",
        &Overrides {
            width: Some(width),
            bins: Some(bins),
            spp: Some(spp),
            bin_width_opl: Some(0.25),
            ..Default::default()
        },
    )
}

/// The counts adaptive sampling gives `scene` at mean `spp` (pilot seed `pilot_seed`).
fn counts(scene: &Scene, spp: u32, pilot_seed: u64, s: &RenderSettings) -> Arc<[u32]> {
    counts_with(
        scene,
        AdaptiveOptions::new(spp, ErrorMeasure::Mse, 1, 2),
        pilot_seed,
        s,
    )
}

fn counts_with(
    scene: &Scene,
    o: AdaptiveOptions,
    pilot_seed: u64,
    s: &RenderSettings,
) -> Arc<[u32]> {
    let ps = RenderSettings {
        seed: pilot_seed,
        ..s.clone()
    };
    let (m, _) = pilot(scene, &ps, &o, &|_| {});
    allocate(&weights(&m, scene.film.width), &o).into()
}

fn with_threads<T: Send>(n: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(n)
        .build()
        .unwrap()
        .install(f)
}

#[test]
fn per_pixel_counts_trace_what_a_plain_loop_traces() {
    let scene = small_cbox(10, 12, 8);
    let mut s = settings(8, 5, PixelSampling::Independent);
    let n = counts(&scene, 8, AdaptiveOptions::pilot_seed(5), &s);
    assert!(n.iter().any(|&k| k != 8), "the allocation is not uniform");
    assert_eq!(n.iter().map(|&k| k as u64).sum::<u64>(), 8 * 100);
    s.pixel_spp = Some(n.clone());
    let out = render(&scene, &s, &|_| {});
    let (w, bins) = (scene.film.width, scene.film.time.bins);
    let mut deposits = PathDeposits::default();
    for p in 0..scene.film.pixels() {
        let mut x1 = vec![0.0f64; bins * 3];
        let mut tally = PathTally::default();
        for k in 0..n[p] {
            let mut rng = tstat::math::rng::Pcg32::for_path(5, p as u64, k as u64);
            let [u, v] = rng.next_2d();
            let d = scene
                .camera
                .direction((p % w) as f32 + u, (p / w) as f32 + v);
            trace_path(&scene, d, &mut rng, &mut deposits, &mut tally);
            for (bin, c) in deposits.drain() {
                // A deposit is MAX_CHANNELS wide; an RGB film reads its first three.
                for (ch, v) in c.iter().take(3).enumerate() {
                    x1[bin as usize * 3 + ch] += v;
                }
            }
        }
        assert_eq!(
            &out.accum.x1[p * bins * 3..(p + 1) * bins * 3],
            &x1[..],
            "pixel {p}"
        );
        for c in 0..3 {
            let want = tally.steady[c] / f64::from(n[p]);
            assert_eq!(out.steady[p * 3 + c], want, "pixel {p} steady");
        }
    }
}

#[test]
fn adaptive_renders_are_the_same_bits_at_one_and_two_threads_and_uniform_counts_are_today() {
    let scene = small_cbox(12, 16, 16);
    for sampling in [PixelSampling::Sobol, PixelSampling::Stratified] {
        let base = settings(16, 9, sampling);
        let run = |threads: usize| -> (Arc<[u32]>, RenderOutput) {
            with_threads(threads, || {
                let n = counts(&scene, 16, AdaptiveOptions::pilot_seed(9), &base);
                let s = RenderSettings {
                    pixel_spp: Some(n.clone()),
                    ..base.clone()
                };
                (n, render(&scene, &s, &|_| {}))
            })
        };
        let (n1, a) = run(1);
        let (n2, b) = run(2);
        assert_eq!(n1, n2, "{sampling}: counts");
        assert!(a.accum.x1 == b.accum.x1 && a.accum.x2 == b.accum.x2 && a.accum.x3 == b.accum.x3);
        assert_eq!(a.accum.nonzero, b.accum.nonzero);
        assert_eq!(a.steady, b.steady);
        assert_eq!(a.paths, 16 * 144);
        // Every pixel at spp: the uniform render's bits.
        let uniform = render(&scene, &base, &|_| {});
        let flat = RenderSettings {
            pixel_spp: Some(vec![16u32; 144].into()),
            ..base.clone()
        };
        let same = render(&scene, &flat, &|_| {});
        assert!(uniform.accum.x1 == same.accum.x1 && uniform.accum.x3 == same.accum.x3);
        assert_eq!(uniform.steady, same.steady);
    }
}

/// Per pixel and channel, the steady means of `seeds` adaptive renders against as many
/// uniform ones: the largest |Welch t| over the pixels, and the number of pixels whose
/// |t| exceeds `crit`.
/// Seeds of each arm of the bias test.
const SEEDS: u64 = 2048;

fn welch_over_seeds(scene: &Scene, spp: u32, seeds: u64, mutated: bool, crit: f64) -> (f64, usize) {
    let pixels = scene.film.pixels();
    let mut acc = [vec![[0.0f64; 2]; pixels * 3], vec![[0.0f64; 2]; pixels * 3]];
    for seed in 0..seeds {
        let render_seed = 1000 + seed;
        let base = settings(spp, render_seed, PixelSampling::Independent);
        let o = AdaptiveOptions::new(spp, ErrorMeasure::Mse, 1, 2);
        let n = if mutated {
            // The mutation: the allocation from the render's own samples (a pilot of
            // all spp with the render's seed: the estimate's first spp samples).
            let o = AdaptiveOptions {
                pilot_spp: spp,
                ..o
            };
            counts_with(scene, o, render_seed, &base)
        } else {
            counts_with(scene, o, AdaptiveOptions::pilot_seed(render_seed), &base)
        };
        let adaptive = render(
            scene,
            &RenderSettings {
                pixel_spp: Some(n),
                ..base.clone()
            },
            &|_| {},
        );
        let uniform = render(
            scene,
            &settings(spp, 500_000 + seed, PixelSampling::Independent),
            &|_| {},
        );
        for (a, out) in acc.iter_mut().zip([&adaptive, &uniform]) {
            for (s, &v) in a.iter_mut().zip(&out.steady) {
                s[0] += v;
                s[1] += v * v;
            }
        }
    }
    let k = seeds as f64;
    let (mut worst, mut over) = (0.0f64, 0);
    for (a, u) in acc[0].iter().zip(&acc[1]) {
        let stat = |s: [f64; 2]| {
            let m = s[0] / k;
            (m, ((s[1] / k - m * m) * k / (k - 1.0)).max(0.0) / k)
        };
        let ((ma, va), (mu, vu)) = (stat(*a), stat(*u));
        if va + vu > 0.0 {
            let t = (ma - mu).abs() / (va + vu).sqrt();
            worst = worst.max(t);
            over += (t > crit) as usize;
        }
    }
    (worst, over)
}

/// The means of adaptive renders are those of uniform ones: over 2048 seeds, per
/// pixel and channel of a 6 x 6 film at 8 spp, no Welch t beyond the Bonferroni bound
/// of the 108 tests at 1%, on the box, the fog and an NLOS capture; the allocation
/// from the render's own samples (the mutation) gives a bias the same test finds in
/// several pixels of the box. (cbox_spheres is left out: its glass's caustic samples
/// are too heavy-tailed for the t-test's normal approximation at this size: uniform
/// renders against uniform renders of other seeds reach |t| 4.16 there too, the same
/// as adaptive against uniform.)
#[test]
fn the_pilot_leaves_the_means_unbiased_and_the_mutation_is_caught() {
    // Two-sided 1% over the family: |t| > z(1 - 0.005 / 108) = 3.9 (2048 seeds: the t
    // distribution's tails are the normal's), with 0.1 to spare.
    let crit = 4.0;
    let film = |name: &str| {
        bundled(
            name,
            &Overrides {
                width: Some(6),
                height: Some(6),
                bins: Some(4),
                spp: Some(8),
                ..Default::default()
            },
        )
    };
    for name in ["cbox.xml", "cbox_fog.xml", "nlos_T.xml"] {
        let scene = film(name);
        assert_eq!(scene.film.pixels() * 3, 108);
        let (worst, over) = welch_over_seeds(&scene, 8, SEEDS, false, crit);
        eprintln!("{name}: unbiased, worst |t| {worst:.2}");
        assert_eq!(over, 0, "{name}: unbiased allocation, worst |t| {worst}");
    }
    let scene = small_cbox(6, 4, 8);
    let (worst_m, over_m) = welch_over_seeds(&scene, 8, SEEDS, true, crit);
    eprintln!("mutation: worst |t| {worst_m:.2}, {over_m} of 108 over {crit}");
    assert!(
        over_m >= 3,
        "the mutation went unseen: worst |t| {worst_m}, {over_m} over"
    );
}

fn tstat(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_tstat"))
        .args(args)
        .output()
        .unwrap()
}

fn npy_u32(p: &Path) -> ndarray::ArrayD<u32> {
    ndarray_npy::read_npy(p).unwrap()
}

fn npy_f64(p: &Path) -> ndarray::ArrayD<f64> {
    ndarray_npy::read_npy(p).unwrap()
}

#[test]
fn the_bundle_holds_the_counts_and_every_reader_divides_by_them() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let p = |n: &str| d.join(n).display().to_string();
    let cbox = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cbox.xml");
    let sc = cbox.to_str().unwrap();
    let common = ["--width", "12", "--bins", "20", "--bin-width-opl", "0.2"];
    let render = |out: &str, extra: &[&str]| {
        let mut args = vec!["render", sc, "--out", out, "--spp", "16"];
        args.extend(common);
        args.extend(extra);
        let r = tstat(&args);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    };
    render(&p("a.tstats"), &["--adaptive", "--seed", "1"]);
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("a.tstats/manifest.json")).unwrap())
            .unwrap();
    assert_eq!(m["version"], 2);
    assert_eq!(m["spp"], 16);
    assert_eq!(m["adaptive"]["measure"], "mse");
    let n = npy_u32(&d.join("a.tstats/pixel_spp.npy"));
    assert_eq!(n.shape(), &[12, 12]);
    assert_eq!(n.iter().map(|&k| k as u64).sum::<u64>(), 16 * 144);
    assert!(n.iter().any(|&k| k != 16));
    assert_eq!(m["adaptive"]["min_spp"], *n.iter().min().unwrap());
    // export: X1 / n per pixel.
    assert!(tstat(&["export", &p("a.tstats"), "--out", &p("a.npy")])
        .status
        .success());
    let mean: ndarray::ArrayD<f32> = ndarray_npy::read_npy(d.join("a.npy")).unwrap();
    let x1 = npy_f64(&d.join("a.tstats/x1.npy"));
    for ((y, x), &k) in (0..12)
        .flat_map(|y| (0..12).map(move |x| (y, x)))
        .zip(n.iter())
    {
        for t in 0..20 {
            for c in 0..3 {
                let want = (x1[[y, x, t, c]] / k as f64) as f32;
                assert_eq!(mean[[y, x, t, c]], want, "({y}, {x}, {t}, {c})");
            }
        }
    }
    // Counts above a pixel's own samples are refused.
    let r = tstat(&["info", &p("a.tstats")]);
    assert!(String::from_utf8_lossy(&r.stdout).contains("per pixel (pixel_spp.npy)"));
    // denoise and view read it.
    assert!(tstat(&["denoise", &p("a.tstats"), "--out", &p("ad.npy")])
        .status
        .success());
    assert!(tstat(&["view", &p("a.tstats"), "--out", &p("a.html")])
        .status
        .success());
    // The page's band takes each pixel's own degrees of freedom, n_i - 1.
    let data = common::page_data(&std::fs::read_to_string(d.join("a.html")).unwrap());
    let tq: Vec<f64> = data["t_quantiles"]
        .as_array()
        .expect("an adaptive page has t_quantiles")
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert_eq!(tq.len(), 144);
    for (&t, &k) in tq.iter().zip(n.iter()) {
        let want = tstat::denoise::critical::student_t_quantile(0.975, f64::from(k) - 1.0);
        assert!(
            (t - want).abs() <= 5e-5,
            "{t} against {want} at {k} samples"
        );
    }
    assert_eq!(data["dof"], *n.iter().min().unwrap() - 1);
    // merge with a uniform render: the counts add, the steady image is weighted by them.
    render(&p("u.tstats"), &["--seed", "2"]);
    let r = tstat(&[
        "merge",
        &p("a.tstats"),
        &p("u.tstats"),
        "--out",
        &p("m.tstats"),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let nm = npy_u32(&d.join("m.tstats/pixel_spp.npy"));
    assert_eq!(nm, n.mapv(|k| k + 16));
    let (sa, su, sm) = (
        npy_f64(&d.join("a.tstats/steady.npy")),
        npy_f64(&d.join("u.tstats/steady.npy")),
        npy_f64(&d.join("m.tstats/steady.npy")),
    );
    for y in 0..12 {
        for x in 0..12 {
            let (ka, km) = (n[[y, x]] as f64, nm[[y, x]] as f64);
            for c in 0..3 {
                let want = (sa[[y, x, c]] * ka + su[[y, x, c]] * 16.0) / km;
                assert!((sm[[y, x, c]] - want).abs() <= 1e-12 * want.abs().max(1e-300));
            }
        }
    }
    assert!(tstat(&["export", &p("m.tstats"), "--out", &p("m.npy")])
        .status
        .success());
    // A bundle whose counts do not match its manifest is refused.
    let mut bad = npy_u32(&d.join("a.tstats/pixel_spp.npy"));
    bad[[0, 0]] += 2;
    ndarray_npy::write_npy(d.join("a.tstats/pixel_spp.npy"), &bad).unwrap();
    let r = tstat(&["info", &p("a.tstats")]);
    assert_eq!(r.status.code(), Some(1));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        err.contains("pixel_spp.npy sums to") && err.lines().count() == 1,
        "{err}"
    );
}

/// Shards of an adaptive job share one pilot (the job's seed): each renders its share
/// of every pixel's count, and their merge holds the job's allocation.
#[test]
fn adaptive_shards_merge_to_the_job_allocation() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let p = |n: &str| d.join(n).display().to_string();
    let cbox = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cbox.xml");
    let sc = cbox.to_str().unwrap();
    let base = [
        "--width",
        "10",
        "--bins",
        "10",
        "--spp",
        "32",
        "--seed",
        "4",
        "--adaptive",
    ];
    for i in 0..2 {
        let shard = format!("{i}/2");
        let out = p(&format!("s{i}.tstats"));
        let mut args = vec!["render", sc, "--out", &out, "--shard", &shard];
        args.extend(base);
        let r = tstat(&args);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    }
    let r = tstat(&[
        "merge",
        &p("s0.tstats"),
        &p("s1.tstats"),
        "--out",
        &p("job.tstats"),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let whole_out = p("whole.tstats");
    let mut args = vec!["render", sc, "--out", &whole_out];
    args.extend(base);
    assert!(tstat(&args).status.success());
    let (s0, s1, job, whole) = (
        npy_u32(&d.join("s0.tstats/pixel_spp.npy")),
        npy_u32(&d.join("s1.tstats/pixel_spp.npy")),
        npy_u32(&d.join("job.tstats/pixel_spp.npy")),
        npy_u32(&d.join("whole.tstats/pixel_spp.npy")),
    );
    assert_eq!(s0, s1);
    assert_eq!(job, whole);
    assert_eq!(job, s0.mapv(|k| 2 * k));
}

/// An adaptive NLOS capture: each wall point's transient in H (what `nlos reconstruct`
/// and `export --tal` use) is its sums over its own count.
#[test]
fn an_adaptive_capture_divides_each_wall_point_by_its_count() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("c.tstats");
    let xml = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/nlos_T.xml");
    let r = tstat(&[
        "render",
        xml.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--spp",
        "16",
        "--width",
        "8",
        "--adaptive",
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let bundle = tstat::bundle::Bundle::open(&out).unwrap();
    let n = bundle.pixel_spp.clone().expect("adaptive counts");
    assert!(n.iter().any(|&k| k != 16));
    let cap = tstat::nlos::capture::Capture::from_bundle(&bundle).unwrap();
    let x1 = npy_f64(&out.join("x1.npy"));
    let (h, w, t) = (
        bundle.manifest.height,
        bundle.manifest.width,
        bundle.manifest.bins,
    );
    let s = cap.sensor_dims[1];
    for y in 0..h {
        for x in 0..w {
            let k = n[y * w + x] as f64;
            for b in 0..t {
                let want = (0..3).map(|c| x1[[y, x, b, c]]).sum::<f64>() / k;
                let got = cap.h[b * cap.sensors + x * s + y] as f64;
                assert!(
                    (got - want).abs() <= 1e-6 * want.abs() + 1e-30,
                    "({y}, {x}) bin {b}: {got} vs {want}"
                );
            }
        }
    }
}

/// `--target-error` and `--time-budget` choose the mean spp from the pilot and record
/// the goal; the error the manifest says was reached is the bundle's own estimate
/// (each voxel's variance of the mean from X1, X2 and its pixel's count).
#[test]
fn goals_choose_the_spp_and_the_reached_error_is_the_bundles_own() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let p = |n: &str| d.join(n).display().to_string();
    let cbox = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cbox.xml");
    let sc = cbox.to_str().unwrap();
    let film = [
        "--width",
        "24",
        "--bins",
        "30",
        "--bin-width-opl",
        "0.2",
        "--adaptive",
    ];
    let run = |out: &str, extra: &[&str]| {
        let mut args = vec!["render", sc, "--out", out];
        args.extend(film);
        args.extend(extra);
        tstat(&args)
    };
    let r = run(&p("e.tstats"), &["--target-error", "0.004"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("e.tstats/manifest.json")).unwrap())
            .unwrap();
    let a = &m["adaptive"];
    assert_eq!(a["goal"]["kind"], "target_error");
    assert_eq!(a["goal"]["value"], 0.004);
    assert!(a["goal"]["predicted_error"].as_f64().unwrap() <= 0.004);
    let spp = m["spp"].as_u64().unwrap();
    assert!(spp > 4, "{spp}");
    // The reached error, recomputed from the bundle.
    let (x1, x2) = (
        npy_f64(&d.join("e.tstats/x1.npy")),
        npy_f64(&d.join("e.tstats/x2.npy")),
    );
    let n = npy_u32(&d.join("e.tstats/pixel_spp.npy"));
    let mut total = 0.0;
    let sh = x1.shape().to_vec();
    for y in 0..sh[0] {
        for x in 0..sh[1] {
            let k = n[[y, x]] as f64;
            for t in 0..sh[2] {
                for c in 0..sh[3] {
                    let (s1, s2) = (x1[[y, x, t, c]], x2[[y, x, t, c]]);
                    total += ((s2 - s1 * s1 / k) / (k - 1.0)).max(0.0) / k;
                }
            }
        }
    }
    let voxels = (sh[0] * sh[1] * sh[2] * sh[3]) as f64;
    let reached = a["estimated_error"].as_f64().unwrap();
    assert!(
        (reached - (total / voxels).sqrt()).abs() <= 1e-9 * reached,
        "{reached}"
    );
    // The pilot's prediction is for the same samples: the estimate lands near it.
    assert!(reached > 0.004 / 2.0 && reached < 0.004 * 2.0, "{reached}");
    // A time budget records its goal too.
    let r = run(&p("t.tstats"), &["--time-budget", "1s"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("t.tstats/manifest.json")).unwrap())
            .unwrap();
    assert_eq!(m["adaptive"]["goal"]["kind"], "time_budget_seconds");
    // Refused: bad durations, goals with shards, goals without --adaptive.
    for (extra, want) in [
        (
            vec!["--time-budget", "5x"],
            "a duration is a number of seconds",
        ),
        (vec!["--time-budget", "-3"], "must be positive"),
        (vec!["--target-error", "0"], "--target-error"),
        (
            vec!["--target-error", "0.01", "--shard", "0/2"],
            "not with --shard",
        ),
    ] {
        let r = run(&p("x.tstats"), &extra);
        assert_eq!(r.status.code(), Some(1), "{extra:?}");
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(
            err.contains(want) && err.lines().count() == 1,
            "{extra:?}: {err}"
        );
        assert!(!d.join("x.tstats").exists());
    }
    let r = tstat(&[
        "render",
        sc,
        "--out",
        &p("y.tstats"),
        "--target-error",
        "0.01",
    ]);
    assert_eq!(r.status.code(), Some(1), "a goal without --adaptive");
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(
        err.trim(),
        "error: --target-error is an adaptive sampling option: not without --adaptive"
    );
    assert!(!d.join("y.tstats").exists());
}

/// `run` samples adaptively by default (the manifest says how) and `--no-adaptive`
/// gives the uniform render `render` gives, bit for bit; adaptive options are refused
/// with `--no-adaptive`, and leave no output.
#[test]
fn run_is_adaptive_unless_asked_not_to_be() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let p = |n: &str| d.join(n).display().to_string();
    let small = ["--width", "16", "--bins", "24", "--spp", "8", "--seed", "3"];
    let run = |out: &str, extra: &[&str]| {
        let mut args = vec!["run", "--out", out];
        args.extend(small);
        args.extend(extra);
        tstat(&args)
    };
    let manifest = |dir: &str| -> serde_json::Value {
        serde_json::from_str(
            &std::fs::read_to_string(d.join(dir).join("scene.tstats/manifest.json")).unwrap(),
        )
        .unwrap()
    };
    let r = run(&p("a"), &["--adaptive-measure", "relmse"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let m = manifest("a");
    assert_eq!(m["adaptive"]["measure"], "rel_mse");
    assert!(m["adaptive"]["estimated_error"].as_f64().unwrap() > 0.0);
    let n = npy_u32(&d.join("a/scene.tstats/pixel_spp.npy"));
    assert_eq!(n.iter().map(|&k| u64::from(k)).sum::<u64>(), 8 * 16 * 16);
    assert!(n.iter().any(|&k| k != 8), "some pixel got more or fewer");

    let r = run(&p("u"), &["--no-adaptive"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(manifest("u").get("adaptive").is_none());
    assert!(!d.join("u/scene.tstats/pixel_spp.npy").exists());
    let cbox = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cbox.xml");
    let mut args = vec!["render", cbox.to_str().unwrap(), "--out"];
    let plain = p("plain.tstats");
    args.push(&plain);
    args.extend(small);
    let r = tstat(&args);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    for f in ["x1", "x2", "x3", "nonzero", "steady"] {
        let name = format!("{f}.npy");
        assert_eq!(
            std::fs::read(d.join("u/scene.tstats").join(&name)).unwrap(),
            std::fs::read(d.join("plain.tstats").join(&name)).unwrap(),
            "{f}"
        );
    }

    let r = run(&p("x"), &["--no-adaptive", "--pilot-spp", "4"]);
    assert_eq!(r.status.code(), Some(1));
    assert_eq!(
        String::from_utf8_lossy(&r.stderr).trim(),
        "error: --pilot-spp is an adaptive sampling option: not with --no-adaptive"
    );
    assert!(!d.join("x").exists());
}

/// The variance each voxel claims (from its own X1, X2 and its pixel's count) is the
/// variance its mean shows over seeds, under adaptive counts: summed over the pixels
/// that got more samples than the mean and over those that got fewer, over 1024
/// seeds of a 6 x 6 box. Claiming with the mean spp instead of the pixel's own count
/// (the mutation) misses in both regions.
#[test]
fn the_claimed_variance_is_the_observed_one_under_adaptive_counts() {
    let scene = small_cbox(6, 4, 8);
    let (pixels, bins) = (scene.film.pixels(), scene.film.time.bins);
    let voxels = pixels * bins * 3;
    let seeds = 1024u64;
    // Per voxel-channel: sum of means, of squared means, of claimed variances (own
    // count, and the mutation's mean spp); and per pixel the counts seen.
    let (mut m1, mut m2) = (vec![0.0f64; voxels], vec![0.0f64; voxels]);
    let (mut claimed, mut claimed_mean_spp) = (vec![0.0f64; voxels], vec![0.0f64; voxels]);
    let mut seen = vec![0.0f64; pixels];
    for seed in 0..seeds {
        let base = settings(8, 7000 + seed, PixelSampling::Independent);
        let n = counts(&scene, 8, AdaptiveOptions::pilot_seed(7000 + seed), &base);
        let out = render(
            &scene,
            &RenderSettings {
                pixel_spp: Some(n.clone()),
                ..base.clone()
            },
            &|_| {},
        );
        for v in 0..voxels {
            let p = v / (bins * 3);
            let k = f64::from(n[p]);
            let (x1, x2) = (out.accum.x1[v], out.accum.x2[v]);
            let mean = x1 / k;
            m1[v] += mean;
            m2[v] += mean * mean;
            let var = |k: f64| ((x2 - x1 * x1 / k) / (k - 1.0)).max(0.0) / k;
            claimed[v] += var(k);
            claimed_mean_spp[v] += var(8.0);
        }
        for (c, &k) in seen.iter_mut().zip(n.iter()) {
            *c += f64::from(k);
        }
    }
    let s = seeds as f64;
    // Regions: pixels that got more than the mean on average, and the rest.
    let (mut obs, mut own, mut wrong) = ([0.0f64; 2], [0.0f64; 2], [0.0f64; 2]);
    for v in 0..voxels {
        let region = usize::from(seen[v / (bins * 3)] / s > 8.0);
        let mean = m1[v] / s;
        obs[region] += (m2[v] / s - mean * mean) * s / (s - 1.0);
        own[region] += claimed[v] / s;
        wrong[region] += claimed_mean_spp[v] / s;
    }
    for r in 0..2 {
        assert!(obs[r] > 0.0, "region {r} is empty");
        let (ratio, mutated) = (own[r] / obs[r], wrong[r] / obs[r]);
        eprintln!("region {r}: claimed / observed {ratio:.3}, with the mean spp {mutated:.3}");
        assert!(
            (ratio - 1.0).abs() < 0.1,
            "region {r}: claimed / observed {ratio}"
        );
        assert!(
            (mutated - 1.0).abs() > 0.2,
            "region {r}: the mutation passes ({mutated})"
        );
    }
}

/// A way to damage a bundle: what it does, the damage, a word of the error it must give.
type Damage<'a> = (&'a str, Box<dyn Fn(&Path) + 'a>, &'a str);

/// Hostile adaptive bundles: each is one clear error, never a panic.
#[test]
fn damaged_adaptive_bundles_are_one_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cbox = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cbox.xml");
    let good = d.join("good.tstats");
    let r = tstat(&[
        "render",
        cbox.to_str().unwrap(),
        "--out",
        good.to_str().unwrap(),
        "--width",
        "8",
        "--bins",
        "6",
        "--spp",
        "8",
        "--adaptive",
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let manifest = std::fs::read_to_string(good.join("manifest.json")).unwrap();
    let copy = |name: &str| {
        let to = d.join(name);
        std::fs::create_dir(&to).unwrap();
        for e in std::fs::read_dir(&good).unwrap() {
            let e = e.unwrap();
            std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
        }
        to
    };
    let counts = npy_u32(&good.join("pixel_spp.npy"));
    let cases: Vec<Damage> = vec![
        (
            "a pixel of 0 samples",
            Box::new(|b: &Path| {
                let mut n = counts.clone();
                n[[0, 0]] = 0;
                ndarray_npy::write_npy(b.join("pixel_spp.npy"), &n).unwrap();
            }),
            "a pixel has at least 2 samples",
        ),
        (
            "a count beyond u32's sum",
            Box::new(|b: &Path| {
                let mut n = counts.clone();
                n[[0, 0]] = u32::MAX;
                ndarray_npy::write_npy(b.join("pixel_spp.npy"), &n).unwrap();
            }),
            "does not match the manifest",
        ),
        (
            "no pixel_spp.npy",
            Box::new(|b: &Path| std::fs::remove_file(b.join("pixel_spp.npy")).unwrap()),
            "pixel_spp",
        ),
        (
            "version 1 with an adaptive record",
            Box::new(|b: &Path| {
                let m = manifest.replacen("\"version\": 2", "\"version\": 1", 1);
                std::fs::write(b.join("manifest.json"), m).unwrap();
            }),
            "format version",
        ),
        (
            "a pilot of 1 sample",
            Box::new(|b: &Path| {
                let m = manifest.replacen("\"pilot_spp\": 4", "\"pilot_spp\": 1", 1);
                std::fs::write(b.join("manifest.json"), m).unwrap();
            }),
            "adaptive record",
        ),
    ];
    assert!(manifest.contains("\"version\": 2") && manifest.contains("\"pilot_spp\": 4"));
    for (k, (what, damage, want)) in cases.iter().enumerate() {
        let b = copy(&format!("bad{k}.tstats"));
        damage(&b);
        let out = d.join(format!("out{k}.npy"));
        for cmd in [
            vec!["info", b.to_str().unwrap()],
            vec![
                "export",
                b.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
            ],
        ] {
            let r = tstat(&cmd);
            assert_eq!(r.status.code(), Some(1), "{what}: {cmd:?}");
            let err = String::from_utf8_lossy(&r.stderr);
            assert!(
                err.contains(want) && err.lines().count() == 1 && !err.contains("panicked"),
                "{what}: {err}"
            );
        }
        assert!(!out.exists(), "{what}: export left an output");
    }
}
