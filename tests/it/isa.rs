//! The tracer is compiled once per instruction set (`cpu`): every level this
//! CPU has must trace every path to the same bits as the portable baseline, on a flat
//! scene (triangle packets), one with spheres, one with a BVH (the bunny), one with
//! anisotropic materials (frames from dp/du on a cube and a sphere), one with a
//! participating medium (the path loop's media rules, `render/tracer.rs`) and the
//! `null` and `thindielectric` surfaces.
//! A separate test binary, since it switches the process-wide level.

use crate::common;

use tstat::cpu::{self, Isa};
use tstat::math::rng::Pcg32;
use tstat::render::deposits::PathDeposits;
use tstat::render::path_common::PathTally;
use tstat::render::tracer::trace_path;
use tstat::scene::{Overrides, Scene};

fn scene(name: &str) -> Scene {
    let o = Overrides {
        width: Some(24),
        bins: Some(64),
        ..Default::default()
    };
    common::bundled(name, &o)
}

/// Every path of a 24 x 24 image, 4 per pixel: deposits, steady sums, G-buffer samples
/// and ray counts, as bits.
fn trace_all(scene: &Scene) -> Vec<u64> {
    let mut out = Vec::new();
    let mut deposits = PathDeposits::default();
    let (w, h) = (scene.film.width, scene.film.height);
    for y in 0..h {
        for x in 0..w {
            let pixel = (y * w + x) as u64;
            for s in 0..4u64 {
                let mut rng = Pcg32::for_path(7, pixel, s);
                let [u, v] = rng.next_2d();
                let d = scene.camera.direction(x as f32 + u, y as f32 + v);
                let mut tally = PathTally::default();
                let g = trace_path(scene, d, &mut rng, &mut deposits, &mut tally);
                for (bin, c) in deposits.drain() {
                    out.push(bin as u64);
                    out.extend(c.iter().map(|v| v.to_bits()));
                }
                out.extend(tally.steady.iter().map(|v| v.to_bits()));
                out.push(tally.rays);
                out.extend(g.albedo.to_array().iter().map(|v| v.to_bits() as u64));
                out.extend(g.normal.to_array().iter().map(|v| v.to_bits() as u64));
                out.push(g.depth.map_or(u64::MAX, |d| d.to_bits() as u64));
                out.push(g.emitter as u64);
                out.push(g.medium as u64);
            }
        }
    }
    out
}

#[test]
fn every_instruction_set_traces_the_same_bits() {
    let levels: Vec<Isa> = [Isa::Avx2, Isa::Avx512]
        .into_iter()
        .filter(|i| i.supported())
        .collect();
    for name in [
        "cbox.xml",
        "cbox_spheres.xml",
        "bunny.xml",
        "cbox_aniso.xml",
        "cbox_fog.xml",
        "cbox_null.xml",
        "cbox_thin.xml",
    ] {
        let scene = scene(name);
        cpu::force(Isa::Baseline).unwrap();
        let reference = trace_all(&scene);
        assert!(
            reference.len() > 24 * 24 * 4 * 12,
            "{name}: paths deposited nothing"
        );
        for &isa in &levels {
            cpu::force(isa).unwrap();
            assert!(
                trace_all(&scene) == reference,
                "{name}: {isa:?} differs from baseline"
            );
        }
    }
    cpu::force(Isa::best()).unwrap();
    assert_eq!(cpu::current(), Isa::best());
}

/// Runs the binary with `TSTAT_ISA=isa`; panics with its stderr when it fails.
fn tstat_at(isa: &str, args: &[&str]) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_tstat"))
        .env("TSTAT_ISA", isa)
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "TSTAT_ISA={isa} tstat {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn floats(path: &std::path::Path) -> Vec<f32> {
    let a: ndarray::ArrayD<f32> = ndarray_npy::read_npy(path).unwrap();
    a.iter().copied().collect()
}

/// The whole pipeline through the binary at the baseline and at the widest level this
/// CPU has (`TSTAT_ISA`, which every kernel's dispatch obeys): a render, both denoisers
/// and backprojection give the same bits; the FFT-based reconstructions (fbp, pf, fk,
/// lct) round differently (rustfft's AVX kernels against its scalar ones, and pf's
/// single-precision sums eight lanes wide with fused multiply-adds) and agree to 1e-6. `scripts/isa_qemu.sh` runs the same on an emulated CPU without
/// AVX2.
#[test]
fn every_instruction_set_gives_the_pipeline_the_same_bits() {
    // On a CPU with no wider level this compares two baseline runs (determinism only);
    // scripts/isa_qemu.sh covers the levels such a CPU lacks.
    let best = Isa::best();
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let dir = tempfile::tempdir().unwrap();
    let volume = "--volume=-1,1,-1,1,0.5,1.5";
    let methods = ["bp", "fbp", "pf", "fk", "lct"];
    // Each run in its own folder (named by its place: both are "baseline" on a CPU
    // without AVX2).
    for (k, isa) in ["baseline", best.name()].into_iter().enumerate() {
        let d = dir.path().join(k.to_string());
        std::fs::create_dir(&d).unwrap();
        let p = |name: &str| d.join(name).display().to_string();
        let scene = |name: &str| root.join(name).display().to_string();
        tstat_at(
            isa,
            &["render", &scene("cbox_spheres.xml"), "--spp", "8"]
                .into_iter()
                .chain(["--width", "24", "--bins", "40", "--out", &p("r.tstats")])
                .collect::<Vec<_>>(),
        );
        tstat_at(isa, &["denoise", &p("r.tstats"), "--out", &p("tstat.npy")]);
        tstat_at(
            isa,
            &[
                "denoise",
                &p("r.tstats"),
                "--method",
                "published",
                "--out",
                &p("published.npy"),
            ],
        );
        tstat_at(
            isa,
            &[
                "render",
                &scene("nlos_T.xml"),
                "--spp",
                "4",
                "--out",
                &p("T.tstats"),
            ],
        );
        for m in methods {
            let out = p(&format!("{m}.npy"));
            let args = [
                "nlos",
                "reconstruct",
                &p("T.tstats"),
                "--method",
                m,
                "--wl-mean",
                "0.2",
                volume,
                "--voxels",
                "15,15,9",
                "--out",
                &out,
            ];
            // Only fbp and pf take a wavelength.
            let args: Vec<&str> = if m == "fbp" || m == "pf" {
                args.to_vec()
            } else {
                args.iter()
                    .copied()
                    .filter(|a| *a != "--wl-mean" && *a != "0.2")
                    .collect()
            };
            tstat_at(isa, &args);
        }
    }
    let at = |k: usize, file: &str| dir.path().join(k.to_string()).join(file);
    for file in [
        "r.tstats/x1.npy",
        "r.tstats/x2.npy",
        "r.tstats/x3.npy",
        "T.tstats/x1.npy",
    ] {
        let (a, b) = (
            std::fs::read(at(0, file)).unwrap(),
            std::fs::read(at(1, file)).unwrap(),
        );
        assert!(a == b, "{file} differs at {}", best.name());
    }
    for file in ["tstat.npy", "published.npy", "bp.npy"] {
        let (a, b) = (floats(&at(0, file)), floats(&at(1, file)));
        assert!(a.iter().any(|&v| v != 0.0), "{file} is all zero");
        let same = a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits());
        assert!(
            same && a.len() == b.len(),
            "{file} differs at {}",
            best.name()
        );
    }
    let norm = |v: &[f32]| v.iter().map(|&x| (x as f64).powi(2)).sum::<f64>().sqrt();
    for file in ["fbp.npy", "pf.npy", "fk.npy", "lct.npy"] {
        let (a, b) = (floats(&at(0, file)), floats(&at(1, file)));
        let diff: Vec<f32> = a.iter().zip(&b).map(|(x, y)| x - y).collect();
        let rel = norm(&diff) / norm(&a);
        assert!(
            a.len() == b.len() && norm(&a) > 0.0 && rel <= 1e-6,
            "{file}: {rel:e}"
        );
    }
}
