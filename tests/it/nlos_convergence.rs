//! `report convergence --reconstruct` on an NLOS scene: every capture (noisy, denoised,
//! the reference) reconstructed, the reconstruction's error against the reference's,
//! and the capture handed to the reconstructions as a bundle would hand it.

use std::path::{Path, PathBuf};
use std::process::Command;
use tstat::nlos::capture::Capture;
use tstat::nlos::reconstruct::bp::{backproject, VoxelGrid};
use tstat::nlos::reconstruct::Reconstruction;
use tstat::render::{render, PixelSampling, RenderSettings};
use tstat::report::convergence::noisy_mean;
use tstat::report::reconstruction::{NlosPlan, Reconstructor};
use tstat::scene::{Overrides, Scene};
use tstat::stats::Transform;

fn tstat(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_tstat"))
        .args(args)
        .output()
        .unwrap()
}

fn scene(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name)
}

const GRID: VoxelGrid = VoxelGrid {
    first: [-1.0, -1.0, 0.5],
    last: [1.0, 1.0, 1.5],
    n: [11, 11, 6],
};

/// The capture the reconstructions see is the bundle's (`Capture::from_bundle`): the
/// same backprojection to f32 rounding of the channel sums; the reference measured
/// against itself has error 0, and a noisier capture a positive one.
#[test]
fn reconstructions_see_the_bundles_capture() {
    let xml = scene("nlos_T.xml");
    let overrides = Overrides {
        spp: Some(16),
        ..Overrides::default()
    };
    let s = Scene::load(&xml, &overrides).unwrap();
    let settings = RenderSettings {
        spp: 16,
        seed: 5,
        transform: Transform::Identity,
        pixel_sampling: PixelSampling::Independent,
        replicates: 0,
        pixel_spp: None,
    };
    let out = render(&s, &settings, &|_| {});
    let v = noisy_mean(&out, 16).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let b = dir.path().join("b.tstats");
    let meta = tstat::bundle::write::BundleMeta {
        seed: 5,
        transform: Transform::Identity,
        unit_m: 1.0,
        pixel_sampling: PixelSampling::Independent,
        replicates: 0,
        job: None,
        adaptive: None,
    };
    tstat::bundle::write::write_bundle(&b, true, &s, &meta, out).unwrap();
    let bundle = tstat::bundle::Bundle::open(&b).unwrap();
    let from_bundle = backproject(&Capture::from_bundle(&bundle).unwrap(), &GRID);

    let plan = NlosPlan {
        methods: vec![Reconstruction::Bp],
        grid: GRID,
        max_memory: 1 << 30,
    };
    let mut r = Reconstructor::new(&s, plan).unwrap();
    r.set_reference(&v).unwrap();
    let top = from_bundle.iter().fold(0f32, |a, &b| a.max(b.abs()));
    assert!(top > 0.0);
    let diff = r
        .reference(0)
        .iter()
        .zip(&from_bundle)
        .map(|(a, b)| (a - b).abs())
        .fold(0f32, f32::max);
    assert!(diff <= 1e-5 * top, "max diff {diff} of {top}");
    let (errors, volumes) = r.measure(&v).unwrap();
    assert_eq!(errors[0].error, 0.0);
    assert_eq!(volumes[0], r.reference(0));
    let noisier = v.mapv(|x| x * 1.5);
    assert!((r.measure(&noisier).unwrap().0[0].error - 0.5).abs() < 1e-6);
}

/// The CSV's column `name` of the row (spp, method).
fn cell(csv: &str, spp: u32, method: &str, name: &str) -> f64 {
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = header.iter().position(|h| *h == name).unwrap();
    let row = lines
        .map(|l| l.split(',').collect::<Vec<_>>())
        .find(|r| r[0] == spp.to_string() && r[1] == method)
        .unwrap();
    row[col].parse().unwrap()
}

#[test]
fn convergence_reconstructs_every_capture_and_denoised_captures_reconstruct_better() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("conv");
    let o = out.to_str().unwrap();
    let xml = scene("nlos_T.xml");
    let r = tstat(&[
        "report",
        "convergence",
        xml.to_str().unwrap(),
        "--spp",
        "2,8",
        "--reference-spp",
        "256",
        "--pixel-sampling",
        "independent",
        "--reconstruct",
        "bp,fbp",
        "--volume=-1,1,-1,1,0.5,1.5",
        "--voxels",
        "11,11,6",
        "--wl-mean",
        "0.2",
        "--out",
        o,
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let csv = std::fs::read_to_string(out.join("results.csv")).unwrap();
    for m in ["bp", "fbp"] {
        let e = |spp, method| cell(&csv, spp, method, &format!("{m}_rel_l2"));
        // More samples, a closer reconstruction; the denoised capture's (NLOS defaults:
        // radius 1) at least twice as close at 2 spp (measured: bp 4.0x, fbp 3.3x), and
        // closer at 8.
        assert!(e(8, "noisy") < e(2, "noisy"), "{m}");
        assert!(
            e(2, "tstat") * 2.0 < e(2, "noisy"),
            "{m}: {} vs {}",
            e(2, "tstat"),
            e(2, "noisy")
        );
        assert!(e(8, "tstat") < e(8, "noisy"), "{m}");
        assert!(cell(&csv, 2, "noisy", &format!("{m}_s")) > 0.0);
        for suffix in ["error_vs_seconds", "error_vs_spp", "mip"] {
            assert!(out
                .join(format!("reconstruction_{m}_{suffix}.png"))
                .is_file());
        }
        // Reference, noisy and tstat side by side: 11 x 11 voxels at 23 px each, two
        // 4-px gaps.
        let mip = image::open(out.join(format!("reconstruction_{m}_mip.png"))).unwrap();
        assert_eq!((mip.width(), mip.height()), (3 * 11 * 23 + 8, 11 * 23));
    }
    let md = std::fs::read_to_string(out.join("results.md")).unwrap();
    assert!(md.contains("## Reconstructions") && md.contains("fbp: wl_mean 0.2"));
    // `--denoise-with`'s rows: at 8 spp only (halves of 1 sample are not rendered),
    // closer than the noisy capture for both methods, b in [0, 1].
    let section = md
        .split("### Denoised for the reconstruction")
        .nth(1)
        .expect("the --denoise-with section");
    let rows: Vec<Vec<&str>> = section
        .lines()
        .filter(|l| l.starts_with("| ") && !l.starts_with("| spp"))
        .map(|l| l.trim_matches('|').split('|').map(str::trim).collect())
        .collect();
    assert_eq!(rows.len(), 1, "{section}");
    assert_eq!(rows[0][0], "8");
    for k in 0..2 {
        let gain: f64 = rows[0][4 + 3 * k].parse().unwrap();
        let b: f64 = rows[0][5 + 3 * k].parse().unwrap();
        assert!(gain > 1.0, "method {k}: gain {gain}");
        assert!((0.0..=1.0).contains(&b), "method {k}: b {b}");
    }
    assert!(md.contains("tstat: r = 1"), "the NLOS defaults: {md}");
}

#[test]
fn convergence_refuses_bad_reconstruction_requests_before_rendering() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("conv");
    let o = out.to_str().unwrap();
    let t = scene("nlos_T.xml");
    let t = t.to_str().unwrap();
    let cbox = scene("cbox.xml");
    let grid = ["--volume=-1,1,-1,1,0.5,1.5", "--voxels", "5,5,3"];
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            [&[cbox.to_str().unwrap(), "--reconstruct", "bp"][..], &grid].concat(),
            "need an NLOS scene",
        ),
        (
            vec![t, "--reconstruct", "bp"],
            "needs --volume and --voxels",
        ),
        (
            [&[t, "--reconstruct", "bp,xx"][..], &grid].concat(),
            "'xx' is none of",
        ),
        (
            [&[t, "--reconstruct", "bp,bp"][..], &grid].concat(),
            "'bp' twice",
        ),
        (
            [&[t, "--reconstruct", "bp", "--wl-mean", "0.2"][..], &grid].concat(),
            "belong to the methods fbp and pf",
        ),
        (
            [&[t, "--reconstruct", "fbp"][..], &grid].concat(),
            "needs --wl-mean",
        ),
        (
            [&[t, "--reconstruct", "bp", "--snr", "0.5"][..], &grid].concat(),
            "belongs to the method lct",
        ),
        (
            [
                &[t, "--reconstruct", "lct", "--max-memory", "1K"][..],
                &grid,
            ]
            .concat(),
            "working memory",
        ),
        (vec![t, "--volume=0,1,0,1,0,1"], "--reconstruct"),
    ];
    for (args, want) in cases {
        let mut all = vec!["report", "convergence", "--spp", "2", "--out", o];
        all.extend(&args);
        let r = tstat(&all);
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(!r.status.success(), "{args:?}");
        assert!(err.contains(want), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
        // Refused before the reference was rendered.
        let cached = std::fs::read_dir(&out)
            .map(|d| d.flatten().count())
            .unwrap_or(0);
        assert_eq!(cached, 0, "{args:?}");
    }
}

/// Relative L2 distance of two .npy reconstructions.
fn rel_l2(path: &Path, reference: &[f32]) -> f64 {
    let v: ndarray::Array3<f32> = ndarray_npy::read_npy(path).unwrap();
    let (mut d, mut n) = (0f64, 0f64);
    for (&a, &b) in v.iter().zip(reference) {
        d += (a as f64 - b as f64).powi(2);
        n += (b as f64).powi(2);
    }
    (d / n).sqrt()
}

/// `nlos reconstruct A --denoise-with B` (the merge of two independent half captures,
/// denoised and shrunk toward its noisy capture by the cross-validated b): for every
/// method, at least twice as close to a high-spp reference as the noisy merge at 4
/// spp, and never farther at 256 spp, where the filter alone (`--denoised`) is farther
/// for fbp. Forcing b = 0 (the filter alone) fails the second check; b = 1 (no
/// denoising) the first.
#[test]
fn denoise_with_never_reconstructs_worse_than_the_noisy_capture() {
    let dir = tempfile::tempdir().unwrap();
    let d = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    let xml = scene("nlos_T.xml");
    let xml = xml.to_str().unwrap();
    let render = |out: &str, spp: u32, seed: u32| {
        let r = tstat(&[
            "render",
            xml,
            "-D",
            "res=16",
            "-D",
            "bins=256",
            "--spp",
            &spp.to_string(),
            "--seed",
            &seed.to_string(),
            "--out",
            out,
        ]);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    };
    render(&d("ref.tstats"), 2048, 1);
    let vol = ["--volume=-1,1,-1,1,0.5,1.5", "--voxels", "21,21,11"];
    let recon = |capture: &str, method: &str, out: &str, extra: &[&str]| -> String {
        let mut args = vec!["nlos", "reconstruct", capture, "--method", method];
        if method == "fbp" || method == "pf" {
            args.extend(["--wl-mean", "0.25"]);
        }
        args.extend(vol);
        args.extend(["--out", out]);
        args.extend(extra);
        let r = tstat(&args);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        String::from_utf8_lossy(&r.stderr).into_owned()
    };
    let methods = ["bp", "fbp", "pf", "fk", "lct"];
    let mut reference = Vec::new();
    for m in methods {
        let out = d(&format!("ref_{m}.npy"));
        recon(&d("ref.tstats"), m, &out, &[]);
        let v: ndarray::Array3<f32> = ndarray_npy::read_npy(&out).unwrap();
        reference.push(v.into_raw_vec_and_offset().0);
    }
    for (spp, seed) in [(4u32, 10u32), (256, 20)] {
        let (a, b, f) = (
            d(&format!("a{spp}")),
            d(&format!("b{spp}")),
            d(&format!("f{spp}")),
        );
        render(&a, spp / 2, seed);
        render(&b, spp / 2, seed + 1);
        let r = tstat(&["merge", &a, &b, "--out", &f]);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        let den = d(&format!("den{spp}.npy"));
        let r = tstat(&["denoise", &f, "--out", &den]);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        for (m, reference) in methods.iter().zip(&reference) {
            let out = d("v.npy");
            recon(&f, m, &out, &["--force"]);
            let noisy = rel_l2(Path::new(&out), reference);
            recon(&f, m, &out, &["--force", "--denoised", &den]);
            let plain = rel_l2(Path::new(&out), reference);
            let said = recon(&a, m, &out, &["--force", "--denoise-with", &b]);
            let cv = rel_l2(Path::new(&out), reference);
            assert!(said.contains("b = "), "{said}");
            eprintln!("{spp} spp {m}: noisy {noisy:.4} denoised {plain:.4} cv {cv:.4}");
            if spp == 4 {
                assert!(cv * 2.0 < noisy, "{m} at 4 spp: {cv} against noisy {noisy}");
            } else {
                assert!(cv <= noisy, "{m} at 256 spp: {cv} against noisy {noisy}");
                if *m == "fbp" {
                    assert!(
                        plain > noisy,
                        "fbp at 256 spp: the filter alone {plain}, noisy {noisy}"
                    );
                }
            }
        }
    }
    // The merge is removed; nothing else is left beside the output.
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.'))
        .collect();
    assert!(left.is_empty(), "{left:?}");
}

/// `--denoise-with` refuses, with one message and nothing written, a second capture
/// of another scene or settings, a y-tal file, and the flag beside `--denoised`.
#[test]
fn denoise_with_refuses_what_it_cannot_cross_validate() {
    let dir = tempfile::tempdir().unwrap();
    let d = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    let xml = scene("nlos_T.xml");
    let xml = xml.to_str().unwrap();
    for (out, bins, seed) in [
        ("a", "64", "1"),
        ("b", "64", "1"),
        ("c", "32", "2"),
        ("e", "64", "3"),
    ] {
        let r = tstat(&[
            "render",
            xml,
            "-D",
            "res=4",
            "-D",
            &format!("bins={bins}"),
            "--spp",
            "4",
            "--seed",
            seed,
            "--out",
            &d(out),
        ]);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    }
    let base = |b: &str| {
        tstat(&[
            "nlos",
            "reconstruct",
            &d("a"),
            "--method",
            "bp",
            "--volume=-1,1,-1,1,0.5,1.5",
            "--voxels",
            "3,3,3",
            "--out",
            &d("v.npy"),
            "--denoise-with",
            b,
        ])
    };
    let cases = [
        (base(&d("c")), "bins"),
        (base(&d("b")), "seed"),
        (base(&d("missing")), "missing"),
    ];
    for (r, why) in cases {
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(!r.status.success(), "{why}");
        assert!(err.contains("--denoise-with"), "{why}: {err}");
        assert!(
            !r.stderr.is_empty() && !err.contains("panicked"),
            "{why}: {err}"
        );
        assert!(!Path::new(&d("v.npy")).exists(), "{why}");
    }
    std::fs::write(d("x.hdf5"), b"not hdf5").unwrap();
    let r = tstat(&[
        "nlos",
        "reconstruct",
        &d("a"),
        "--method",
        "bp",
        "--volume=-1,1,-1,1,0.5,1.5",
        "--voxels",
        "3,3,3",
        "--out",
        &d("v.npy"),
        "--denoise-with",
        &d("x.hdf5"),
    ]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        !r.status.success() && err.contains("not a tstat bundle"),
        "{err}"
    );
    let r = tstat(&[
        "nlos",
        "reconstruct",
        &d("a"),
        "--method",
        "bp",
        "--volume=-1,1,-1,1,0.5,1.5",
        "--voxels",
        "3,3,3",
        "--out",
        &d("v.npy"),
        "--denoise-with",
        &d("e"),
        "--denoised",
        &d("v0.npy"),
    ]);
    assert!(!r.status.success());
    assert!(!Path::new(&d("v.npy")).exists());
    // The two that merge give a volume, and no merge is left behind.
    let r = base(&d("e"));
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(Path::new(&d("v.npy")).is_file());
    let hidden = std::fs::read_dir(dir.path())
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .unwrap()
                .file_name()
                .to_string_lossy()
                .starts_with('.')
        })
        .count();
    assert_eq!(hidden, 0);
}

/// On an exhaustive scan of 8 x 8 points (0.29 apart), `tstat denoise`'s NLOS defaults
/// take no spatial neighbours (`DenoiseParams::adapt_to_nlos`): at 4 spp the denoised
/// capture's bp is closer to a high-spp reference than the noisy one's by more than
/// 1.4x and its fbp is no farther (within 5%), where radius 1 (the confocal default,
/// the mutation) makes fbp farther than noisy.
#[test]
fn exhaustive_scans_are_denoised_without_spatial_neighbours() {
    let dir = tempfile::tempdir().unwrap();
    let d = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    let xml = scene("nlos_T_exhaustive.xml");
    let xml = xml.to_str().unwrap();
    let run = |args: &[&str]| -> String {
        let r = tstat(args);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        String::from_utf8_lossy(&r.stdout).into_owned() + &String::from_utf8_lossy(&r.stderr)
    };
    let (reference, noisy) = (d("ref.tstats"), d("noisy.tstats"));
    for (out, spp, seed) in [(&reference, "1024", "1"), (&noisy, "4", "7")] {
        run(&[
            "render", xml, "-D", "bins=256", "--spp", spp, "--seed", seed, "--out", out,
        ]);
    }
    let recon = |capture: &str, method: &str, out: &str, extra: &[&str]| {
        let mut args = vec!["nlos", "reconstruct", capture, "--method", method];
        if method == "fbp" {
            args.extend(["--wl-mean", "0.2"]);
        }
        args.extend(["--volume=-1,1,-1,1,0.5,1.5", "--voxels", "21,21,11"]);
        args.extend(["--force", "--out", out]);
        args.extend(extra);
        run(&args);
    };
    let (d0, d1) = (d("d0.npy"), d("d1.npy"));
    let said = run(&["denoise", &noisy, "--out", &d0]);
    assert!(said.contains("halo 0"), "{said}");
    run(&["denoise", &noisy, "--out", &d1, "--radius", "1"]);
    let v = d("v.npy");
    for m in ["bp", "fbp"] {
        recon(&reference, m, &v, &[]);
        let r: ndarray::Array3<f32> = ndarray_npy::read_npy(&v).unwrap();
        let r = r.into_raw_vec_and_offset().0;
        let error = |extra: &[&str]| {
            recon(&noisy, m, &v, extra);
            rel_l2(Path::new(&v), &r)
        };
        let (e_noisy, e0, e1) = (
            error(&[]),
            error(&["--denoised", &d0]),
            error(&["--denoised", &d1]),
        );
        eprintln!("{m}: noisy {e_noisy:.4} radius 0 {e0:.4} radius 1 {e1:.4}");
        if m == "bp" {
            assert!(
                e0 * 1.4 < e_noisy,
                "bp: denoised {e0} against noisy {e_noisy}"
            );
        } else {
            assert!(
                e0 <= 1.05 * e_noisy,
                "fbp: denoised {e0} against noisy {e_noisy}"
            );
            assert!(e1 > e_noisy, "fbp, radius 1: {e1} against noisy {e_noisy}");
        }
    }
}
