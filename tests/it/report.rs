//! Reports, pictures and the one-command job: real experiments on small scenes, and
//! clear errors for bad report input.

use image::AnimationDecoder;
use ndarray::Array4;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use tstat::denoise::DenoiseParams;
use tstat::render::PixelSampling;
use tstat::report::convergence::{run_convergence, ConvergenceConfig, ReferenceSource};
use tstat::report::region::Region;
use tstat::report::speedup::Speedup;
use tstat::scene::Overrides;
use tstat::sensors::time_axis::TimeAxis;
use tstat::stats::Transform;
use tstat::viz::frames::{write_all, FramesRequest, TimeLabels};
use tstat::viz::tonemap::srgb8;

fn tstat(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_tstat"))
        .args(args)
        .output()
        .unwrap()
}

fn cbox() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cbox.xml")
}

#[test]
fn tstat_denoising_beats_the_noisy_render_in_every_region_at_every_spp_and_converges() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = ConvergenceConfig {
        scene: cbox(),
        overrides: Overrides {
            width: Some(32),
            bins: Some(40),
            bin_width_opl: Some(0.15),
            ..Default::default()
        },
        spp_list: vec![8, 16, 32, 64, 128],
        seed: 3,
        transform: Transform::Identity,
        pixel_sampling: PixelSampling::Independent,
        replicates: 0,
        denoise: DenoiseParams::default(),
        method_radii: true,
        radius_chosen: false,
        depth_align_asked: false,
        adaptive: false,
        nlos: None,
        base_by_scene: false,
        reference: ReferenceSource::Render { spp: 4096 },
    };
    let r = run_convergence(&cfg, dir.path(), &|m| eprintln!("{m}")).unwrap();
    assert_eq!(r.methods, ["noisy", "base-only", "published", "tstat"]);
    assert_eq!(r.rows.len(), 5 * 4);
    let rows = |method: &'static str| r.rows.iter().filter(move |x| x.method == method);
    let rmse = |method: &'static str, region: Region| -> Vec<f64> {
        rows(method)
            .map(|x| x.error.get(region).expect("the reference is a render").rmse)
            .collect()
    };
    for region in Region::ALL {
        let (noisy, stat) = (rmse("noisy", region), rmse("tstat", region));
        eprintln!("{region:?}: noisy {noisy:?}\ntstat {stat:?}");
        for (k, (s, n)) in stat.iter().zip(&noisy).enumerate() {
            assert!(s < n, "{region:?} spp index {k}: tstat {s} >= noisy {n}");
        }
        // Four times the samples lower the error (one seed: a doubling can be lost in
        // the noise of the few light pixels that hold most of the error).
        for (a, b) in stat.iter().zip(&stat[2..]) {
            assert!(b < a, "{region:?}: tstat RMSE does not fall: {stat:?}");
        }
    }
    // The regions split the squared error: all^2 = (n_l light^2 + n_r rest^2) / n.
    let x = rows("tstat").next().unwrap();
    let (a, l, re) = (
        x.error.all.rmse.powi(2),
        x.error.light.unwrap().rmse.powi(2),
        x.error.rest.unwrap().rmse.powi(2),
    );
    assert!(a > l.min(re) && a < l.max(re), "{a} {l} {re}");
    // Speed-ups: none for the noisy rows; every other row has one per region, exact
    // where its error lies inside the noisy curve's range (and then consistent with the
    // interpolation), a bound outside it.
    assert!(rows("noisy").all(|x| x.speedup == [None; 3]));
    for x in r.rows.iter().filter(|x| x.method != "noisy") {
        assert!(x.evaluations_per_s > 0.0, "{}", x.method);
        for region in Region::ALL {
            let curve: Vec<(f64, f64)> = rows("noisy")
                .map(|n| (n.total_s, n.error.get(region).unwrap().rmse))
                .collect();
            let e = x.error.get(region).unwrap().rmse;
            let (lo, hi) = curve
                .iter()
                .fold((f64::MAX, 0.0f64), |(l, h), p| (l.min(p.1), h.max(p.1)));
            match x.speedup(region).unwrap() {
                Speedup::Exact(v) => {
                    let t = tstat::report::speedup::time_to_reach(&curve, e).unwrap();
                    assert!((v - t / x.total_s).abs() < 1e-9 * v);
                }
                Speedup::AtLeast(_) => assert!(e < lo),
                Speedup::AtMost(_) => assert!(e > hi),
            }
        }
    }
    // The reference is cached: a second run reuses it (and a changed scene does not).
    let cached: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .flatten()
        .map(|e| e.file_name())
        .collect();
    assert_eq!(cached.len(), 2, "{cached:?}");
    let again = run_convergence(
        &ConvergenceConfig {
            spp_list: vec![8],
            ..cfg
        },
        dir.path(),
        &|_| {},
    )
    .unwrap();
    assert!(again.reference_note.contains("cached ") && !again.reference_note.contains("render,"));
    assert_eq!(again.rows[0].error, r.rows[0].error);
}

#[test]
fn frames_gif_and_streak_share_one_exposure() {
    let (h, w, t) = (6usize, 5usize, 7usize);
    let mut v = Array4::<f32>::zeros((h, w, t, 3));
    // Bin 2 is bright (1.0), bin 5 is dim (0.25): the dim frame must stay dim.
    v.slice_mut(ndarray::s![.., .., 2, ..]).fill(1.0);
    v.slice_mut(ndarray::s![.., .., 5, ..]).fill(0.25);
    let dir = tempfile::tempdir().unwrap();
    let req = FramesRequest {
        every: 1,
        gif: true,
        streak_row: 3,
        exposure: 1.0,
        axis: Some(TimeLabels {
            time: TimeAxis {
                start_opl: 3.0,
                bin_width_opl: 0.1,
                bins: t,
            },
            unit_m: 1.0,
            origin: Some("the near-clip plane"),
        }),
        caption: "streak".into(),
    };
    assert_eq!(write_all(dir.path(), v.view(), &req).unwrap(), t);
    let frame = |k: usize| {
        image::open(dir.path().join(format!("frames/frame_{k:04}.png")))
            .unwrap()
            .to_rgb8()
    };
    let (bright, dim) = (frame(2), frame(5));
    assert_eq!(bright.dimensions(), (w as u32, h as u32));
    assert_eq!(bright.get_pixel(0, 0).0, [255; 3]);
    assert_eq!(dim.get_pixel(0, 0).0, [srgb8(0.25); 3]);
    assert!(srgb8(0.25) < 200);
    assert_eq!(frame(0).get_pixel(1, 1).0, [0; 3]);
    let gif = std::fs::File::open(dir.path().join("propagation.gif")).unwrap();
    let frames = image::codecs::gif::GifDecoder::new(std::io::BufReader::new(gif))
        .unwrap()
        .into_frames()
        .collect_frames()
        .unwrap();
    assert_eq!(frames.len(), t);
    assert_eq!(frames[0].buffer().dimensions(), (w as u32, h as u32));
    let streak = image::open(dir.path().join("streak.png")).unwrap();
    assert!(streak.width() > t as u32 && streak.height() > w as u32);
    // Every second bin.
    let dir2 = tempfile::tempdir().unwrap();
    let n = write_all(
        dir2.path(),
        v.view(),
        &FramesRequest {
            every: 2,
            gif: false,
            ..req
        },
    )
    .unwrap();
    assert_eq!(n, 4);
    assert!(!dir2.path().join("propagation.gif").exists());
}

#[test]
fn run_gives_a_new_user_everything_in_one_command() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("job");
    let r = tstat(&[
        "run",
        "--out",
        out.to_str().unwrap(),
        "--width",
        "16",
        "--spp",
        "8",
        "--bins",
        "24",
        "--every",
        "2",
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    for f in [
        "scene.tstats/manifest.json",
        "noisy.npy",
        "denoised.npy",
        "propagation.gif",
        "streak.png",
        "frames/frame_0000.png",
        "frames/frame_0022.png",
    ] {
        assert!(out.join(f).exists(), "{f} missing");
    }
    assert!(!out.join("frames/frame_0001.png").exists());
    let den: Array4<f32> = ndarray_npy::read_npy(out.join("denoised.npy")).unwrap();
    assert_eq!(den.shape(), &[16, 16, 24, 3]);
    // Side by side: noisy | 2-px seam | denoised.
    let f = image::open(out.join("frames/frame_0010.png")).unwrap();
    assert_eq!((f.width(), f.height()), (34, 16));
    assert!(String::from_utf8_lossy(&r.stdout).contains("propagation.gif"));
    // With a bundle as the reference, compare splits the pixels that see the light
    // from the rest; the noisy volume is the bundle's own mean: zero error everywhere.
    let path = |f: &str| out.join(f).display().to_string();
    let c = tstat(&[
        "report",
        "compare",
        "--reference",
        &path("scene.tstats"),
        "--input",
        &format!("noisy={}", path("noisy.npy")),
        "--input",
        &format!("denoised={}", path("denoised.npy")),
        "--out",
        &path("cmp"),
    ]);
    assert!(c.status.success(), "{}", String::from_utf8_lossy(&c.stderr));
    let csv = std::fs::read_to_string(out.join("cmp/metrics.csv")).unwrap();
    let cells: Vec<Vec<&str>> = csv.lines().map(|l| l.split(',').collect()).collect();
    assert_eq!(
        cells[1][..],
        ["noisy", "0", "0", "inf", "0", "0", "inf", "0", "0", "inf"]
    );
    // The denoised volume differs from the noisy one off the light; on a stratified
    // render the light pixels have no neighbours by default (see docs/commands.md), so there
    // it equals the noisy mean.
    let v = |k: usize| -> f64 { cells[2][k].parse().unwrap_or_else(|_| panic!("{csv}")) };
    assert!(v(1) > 0.0 && v(7) > 0.0 && v(4) == 0.0, "{csv}");
    // Existing output without --force is refused and kept.
    let again = tstat(&[
        "run",
        "--out",
        out.to_str().unwrap(),
        "--width",
        "16",
        "--spp",
        "4",
        "--bins",
        "24",
    ]);
    assert_eq!(again.status.code(), Some(1));
    assert!(out.join("noisy.npy").exists());
}

fn write_volume(path: &Path, shape: (usize, usize, usize, usize), value: f32) {
    ndarray_npy::write_npy(path, &Array4::<f32>::from_elem(shape, value)).unwrap();
}

#[test]
fn compare_reports_metrics_and_refuses_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).display().to_string();
    write_volume(Path::new(&p("ref.npy")), (2, 3, 4, 3), 1.0);
    write_volume(Path::new(&p("a.npy")), (2, 3, 4, 3), 1.5);
    write_volume(Path::new(&p("small.npy")), (2, 3, 3, 3), 1.0);
    let r = tstat(&[
        "report",
        "compare",
        "--reference",
        &p("ref.npy"),
        "--input",
        &format!("a={}", p("a.npy")),
        "--out",
        &p("out"),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let csv = std::fs::read_to_string(dir.path().join("out/metrics.csv")).unwrap();
    // RMSE 0.5; relMSE 0.25 / 1.01.
    assert!(
        csv.lines().nth(1).unwrap().starts_with("a,0.5,0.2475,"),
        "{csv}"
    );
    // Without a bundle the light / rest split is unknown: those cells say so.
    assert_eq!(
        csv.lines().next().unwrap(),
        "input,rmse_all,relmse_all,psnr_db_all,rmse_light,relmse_light,psnr_db_light,rmse_rest,relmse_rest,psnr_db_rest"
    );
    assert!(
        csv.lines().nth(1).unwrap().ends_with(",-,-,-,-,-,-"),
        "{csv}"
    );
    for f in ["metrics.md", "per_bin.csv", "per_bin.png"] {
        assert!(dir.path().join("out").join(f).is_file(), "{f}");
    }
    let fails = |args: &[&str], want: &str| {
        let r = tstat(args);
        let err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(1), "{args:?}");
        assert!(err.contains(want), "expected '{want}' in {err}");
        assert!(!err.contains("panicked"));
    };
    fails(
        &[
            "report",
            "compare",
            "--reference",
            &p("ref.npy"),
            "--input",
            &format!("s={}", p("small.npy")),
        ],
        "does not match the reference",
    );
    fails(
        &[
            "report",
            "compare",
            "--reference",
            &p("missing.npy"),
            "--input",
            &format!("a={}", p("a.npy")),
        ],
        "missing.npy",
    );
    fails(
        &[
            "report",
            "compare",
            "--reference",
            &p("ref.npy"),
            "--input",
            &p("a.npy"),
        ],
        "LABEL=FILE",
    );
    fails(
        &[
            "report",
            "compare",
            "--reference",
            &p("ref.npy"),
            "--input",
            &format!("a={}", p("a.npy")),
            "--out",
            &p("out"),
        ],
        "already exists",
    );
    let scene = cbox().display().to_string();
    fails(
        &[
            "report",
            "convergence",
            &scene,
            "--spp",
            "",
            "--out",
            &p("c"),
        ],
        "--spp",
    );
    fails(
        &[
            "report",
            "convergence",
            &scene,
            "--spp",
            "8,1",
            "--out",
            &p("c"),
        ],
        "below 2",
    );
    fails(
        &[
            "report",
            "convergence",
            &scene,
            "--spp",
            "8",
            "--out",
            &p("c2"),
            "--reference",
            &p("small.npy"),
            "--width",
            "8",
            "--bins",
            "5",
        ],
        "shape",
    );
    fails(
        &[
            "report",
            "sweep",
            &p("nothere.tstats"),
            "--reference",
            &p("ref.npy"),
            "--out",
            &p("s"),
        ],
        "nothere.tstats",
    );
    fails(
        &[
            "report",
            "sweep",
            &p("nothere.tstats"),
            "--reference",
            &p("ref.npy"),
            "--out",
            &p("s"),
            "--method",
            "published",
            "--gamma",
            "0.7",
        ],
        "--gamma 0.7",
    );
    fails(
        &[
            "report",
            "sweep",
            &p("nothere.tstats"),
            "--reference",
            &p("ref.npy"),
            "--out",
            &p("s"),
            "--gamma",
            "0.1",
        ],
        "--method published",
    );
}

#[test]
fn frames_command_on_bundles_and_arrays() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).display().to_string();
    let scene = cbox().display().to_string();
    let r = tstat(&[
        "render",
        &scene,
        "--out",
        &p("b.tstats"),
        "--width",
        "10",
        "--spp",
        "2",
        "--bins",
        "12",
    ]);
    assert!(r.status.success());
    let r = tstat(&[
        "frames",
        &p("b.tstats"),
        "--out",
        &p("f"),
        "--every",
        "3",
        "--gif",
        "--streak-row",
        "9",
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert_eq!(
        std::fs::read_dir(dir.path().join("f/frames"))
            .unwrap()
            .count(),
        4
    );
    assert!(
        dir.path().join("f/propagation.gif").is_file() && dir.path().join("f/streak.png").is_file()
    );
    // An .npy volume without a time axis is labelled in bins, and says so.
    write_volume(Path::new(&p("v.npy")), (4, 5, 6, 3), 0.5);
    let r = tstat(&["frames", &p("v.npy"), "--out", &p("g")]);
    assert!(r.status.success());
    assert!(String::from_utf8_lossy(&r.stdout).contains("time axis unknown"));
    let fails = |args: &[&str], want: &str| {
        let r = tstat(args);
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(matches!(r.status.code(), Some(1 | 2)), "{args:?}");
        assert!(err.contains(want), "expected '{want}' in {err}");
    };
    fails(
        &["frames", &p("v.npy"), "--out", &p("h"), "--streak-row", "4"],
        "--streak-row 4",
    );
    fails(
        &["frames", &p("v.npy"), "--out", &p("h"), "--every", "0"],
        "--every",
    );
    fails(&["frames", &p("v.npy"), "--out", &p("g")], "already exists");
    fails(
        &["frames", &p("nothing.npy"), "--out", &p("h")],
        "nothing.npy",
    );
    assert!(!dir.path().join("h").exists());
}

#[test]
fn the_reference_cache_key_follows_scene_defaults() {
    let dir = tempfile::tempdir().unwrap();
    let xml = std::fs::read_to_string(cbox())
        .unwrap()
        .replace(
            r#"<rgb name="radiance" value="18.387, 13.9873, 6.75357"/>"#,
            r#"<rgb name="radiance" value="$rad"/>"#,
        )
        .replace(
            r#"<default name="spp" value="64"/>"#,
            r#"<default name="spp" value="64"/><default name="rad" value="10"/>"#,
        );
    let scene = dir.path().join("s.xml");
    std::fs::write(&scene, xml).unwrap();
    let cfg = |rad: &str| ConvergenceConfig {
        scene: scene.clone(),
        overrides: Overrides {
            width: Some(8),
            bins: Some(6),
            defaults: vec![("rad".into(), rad.into())],
            ..Default::default()
        },
        spp_list: vec![4],
        seed: 1,
        transform: Transform::Identity,
        pixel_sampling: PixelSampling::Independent,
        replicates: 0,
        denoise: DenoiseParams::default(),
        method_radii: true,
        radius_chosen: false,
        depth_align_asked: false,
        adaptive: false,
        nlos: None,
        base_by_scene: false,
        reference: ReferenceSource::Render { spp: 8 },
    };
    let first = run_convergence(&cfg("10"), dir.path(), &|_| {}).unwrap();
    assert!(
        first.reference_note.contains("render,"),
        "{}",
        first.reference_note
    );
    let same = run_convergence(&cfg("10"), dir.path(), &|_| {}).unwrap();
    assert!(same.reference_note.contains("cached ") && !same.reference_note.contains("render,"));
    let other = run_convergence(&cfg("20"), dir.path(), &|_| {}).unwrap();
    assert!(
        other.reference_note.contains("render,"),
        "{}",
        other.reference_note
    );
    // A damaged cache is an error naming the file, not a panic or a silent NaN.
    for e in std::fs::read_dir(dir.path()).unwrap().flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        if name.starts_with("reference-") && name.ends_with("-emitter.npy") {
            let mut b = std::fs::read(e.path()).unwrap();
            let n = b.len();
            b[n - 4..].copy_from_slice(&f32::NAN.to_le_bytes());
            std::fs::write(e.path(), b).unwrap();
        }
    }
    let err = run_convergence(&cfg("10"), dir.path(), &|_| {})
        .err()
        .expect("a damaged cache is refused")
        .to_string();
    assert!(err.contains("-emitter.npy") && err.contains("NaN"), "{err}");
}

#[test]
fn compare_of_identical_volumes_succeeds_without_a_plot() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).display().to_string();
    write_volume(Path::new(&p("r.npy")), (2, 2, 3, 3), 0.5);
    let r = tstat(&[
        "report",
        "compare",
        "--reference",
        &p("r.npy"),
        "--input",
        &format!("same={}", p("r.npy")),
        "--out",
        &p("o"),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(String::from_utf8_lossy(&r.stderr).contains("not written"));
    assert!(
        dir.path().join("o/metrics.csv").is_file() && !dir.path().join("o/per_bin.png").exists()
    );
}

#[test]
fn stratified_convergence_adds_the_independent_baseline() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = ConvergenceConfig {
        scene: cbox(),
        overrides: Overrides {
            width: Some(16),
            bins: Some(30),
            bin_width_opl: Some(0.2),
            ..Default::default()
        },
        spp_list: vec![8, 32, 128],
        seed: 5,
        transform: Transform::Identity,
        pixel_sampling: PixelSampling::Stratified,
        replicates: 0,
        denoise: DenoiseParams::default(),
        method_radii: true,
        radius_chosen: false,
        depth_align_asked: false,
        adaptive: false,
        nlos: None,
        base_by_scene: false,
        reference: ReferenceSource::Render { spp: 2048 },
    };
    let r = run_convergence(&cfg, dir.path(), &|m| eprintln!("{m}")).unwrap();
    assert_eq!(
        r.methods,
        [
            "noisy",
            "noisy-independent",
            "base-only",
            "published",
            "tstat"
        ]
    );
    let get = |m: &str, spp: u32| {
        r.rows
            .iter()
            .find(|x| x.method == m && x.spp == spp)
            .unwrap()
    };
    // Stratified positions lower the noisy error where the light's edge is (seeds differ).
    for spp in [32, 128] {
        let (st, ind) = (get("noisy", spp), get("noisy-independent", spp));
        assert!(
            st.error.light.unwrap().rmse < ind.error.light.unwrap().rmse,
            "{spp}: {:?} vs {:?}",
            st.error,
            ind.error
        );
        assert_eq!(ind.speedup_independent, [None; 3]);
    }
    // Speed-ups against the baseline are exact exactly where the error is inside the
    // baseline curve's range, bounds elsewhere.
    for t in r.rows.iter().filter(|x| x.method == "tstat") {
        for region in Region::ALL {
            let errs: Vec<f64> = r
                .rows
                .iter()
                .filter(|x| x.method == "noisy-independent")
                .map(|x| x.error.get(region).unwrap().rmse)
                .collect();
            let e = t.error.get(region).unwrap().rmse;
            let inside = errs.iter().any(|&b| b <= e) && errs.iter().any(|&b| b >= e);
            let v = t.speedup_independent[region as usize].unwrap();
            assert_eq!(
                matches!(v, Speedup::Exact(_)),
                inside,
                "{region:?} {t:?} {errs:?}"
            );
            assert!(v.value() > 0.0);
        }
    }
}

/// The convergence report's adaptive pipeline: its rows come after the uniform ones,
/// timed pilot + render, and on the box they beat the uniform pipeline's all-voxel
/// RMSE at every spp, noisy and denoised (almost all of the error sits on the light's
/// pixels, where adaptive sampling puts its samples).
#[test]
fn the_adaptive_rows_beat_the_uniform_pipeline_on_the_box() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = ConvergenceConfig {
        scene: cbox(),
        overrides: Overrides {
            width: Some(32),
            bins: Some(40),
            bin_width_opl: Some(0.15),
            ..Default::default()
        },
        spp_list: vec![16, 64],
        seed: 5,
        transform: Transform::Identity,
        pixel_sampling: PixelSampling::Sobol,
        replicates: 0,
        denoise: DenoiseParams::default(),
        method_radii: true,
        radius_chosen: false,
        depth_align_asked: false,
        adaptive: true,
        nlos: None,
        base_by_scene: false,
        reference: ReferenceSource::Render { spp: 2048 },
    };
    let r = run_convergence(&cfg, dir.path(), &|m| eprintln!("{m}")).unwrap();
    assert_eq!(
        r.methods,
        [
            "noisy",
            "noisy-independent",
            "base-only",
            "published",
            "tstat",
            "adaptive",
            "adaptive tstat"
        ]
    );
    let rmse = |method: &str, spp: u32| {
        r.rows
            .iter()
            .find(|x| x.method == method && x.spp == spp)
            .map(|x| x.error.all.rmse)
            .unwrap()
    };
    for spp in [16, 64] {
        let (noisy, tstat) = (rmse("noisy", spp), rmse("tstat", spp));
        let (a, at) = (rmse("adaptive", spp), rmse("adaptive tstat", spp));
        eprintln!("spp {spp}: noisy {noisy:.3e} tstat {tstat:.3e} adaptive {a:.3e} adaptive tstat {at:.3e}");
        assert!(a < noisy && at < tstat && at < a, "spp {spp}");
    }
}
