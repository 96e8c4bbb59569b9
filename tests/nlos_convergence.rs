//! `report convergence --reconstruct` on an NLOS scene: every capture (noisy, denoised,
//! the reference) reconstructed, the reconstruction's error against the reference's,
//! and the capture handed to the reconstructions as a bundle would hand it.

use std::path::{Path, PathBuf};
use std::process::Command;
use tstat::nlos::bp::{backproject, VoxelGrid};
use tstat::nlos::capture::Capture;
use tstat::nlos::reconstruct::Reconstruction;
use tstat::render::{render, PixelSampling, RenderSettings};
use tstat::report::convergence::noisy_mean;
use tstat::report::nlos::{NlosPlan, Reconstructor};
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
