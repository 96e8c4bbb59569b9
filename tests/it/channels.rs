//! The readers of a bundle on films of C = 1 (mono) and C = 4 (Stokes S0..S3)
//! channels: the denoiser (library and `tstat denoise`, with per-bin EXRs), `frames`
//! (grey pictures, and a Stokes volume's polarization pictures), `view` and `report`.
//!
//! The invariant the denoiser is held to: a film whose channels are copies of one
//! mono film's channel, each multiplied by a signed power of two, denoises each
//! channel exactly (bit for bit) as the mono film times that factor. The joint test
//! over channels then equals the mono test (d^2 / V is the same in every channel), the
//! estimates are odd and homogeneous under such factors, and the sums scale exactly.

use crate::common::bundled;
use std::path::Path;
use std::process::{Command, Output};
use tstat::bundle::write::{write_bundle, BundleMeta};
use tstat::denoise::base_filter::BaseKind;
use tstat::denoise::critical::Threshold;
use tstat::denoise::estimates::SumsView;
use tstat::denoise::gbuffers::GBuffers;
use tstat::denoise::{denoise_sums, DenoiseParams, Method};
use tstat::render::{render, PixelSampling, RenderOutput, RenderSettings};
use tstat::scene::mode::RenderMode;
use tstat::scene::{Overrides, Scene};
use tstat::stats::accumulators::Accumulators;
use tstat::stats::Transform;

fn tstat(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_tstat"))
        .args(args)
        .output()
        .unwrap()
}

fn ok(o: &Output) {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// The Cornell box in mono, small.
fn mono_scene() -> Scene {
    bundled(
        "cbox.xml",
        &Overrides {
            width: Some(16),
            height: Some(16),
            bins: Some(48),
            mode: RenderMode::Mono,
            ..Overrides::default()
        },
    )
}

fn mono_render(scene: &Scene, spp: u32) -> RenderOutput {
    assert_eq!(scene.film.channels, 1);
    let settings = RenderSettings {
        spp,
        seed: 7,
        transform: Transform::Identity,
        pixel_sampling: PixelSampling::Independent,
        replicates: 0,
        pixel_spp: None,
    };
    render(scene, &settings, &|_| {})
}

/// The sums of a C-channel film whose channel c is the mono film's times `f[c]` (z
/// scales by f, so X1 by f, X2 by f^2, X3 by f^3; the counts are shared).
fn widen(a: &Accumulators, f: &[f64]) -> Accumulators {
    assert_eq!(a.channels, 1);
    let c = f.len();
    let mut w = Accumulators::new(a.height, a.width, a.bins, c, &Transform::Identity);
    for (v, ((&x1, &x2), &x3)) in a.x1.iter().zip(&a.x2).zip(&a.x3).enumerate() {
        for (k, &s) in f.iter().enumerate() {
            w.x1[v * c + k] = s * x1;
            w.x2[v * c + k] = s * s * x2;
            w.x3[v * c + k] = s * s * s * x3;
        }
    }
    w.nonzero.clone_from(&a.nonzero);
    w
}

fn view<'a>(a: &'a Accumulators, spp: u32) -> SumsView<'a> {
    SumsView {
        height: a.height,
        width: a.width,
        bins: a.bins,
        channels: a.channels,
        bin_width: 0.1,
        spp: u64::from(spp),
        stratified: false,
        image_rows: a.height,
        z0: 0.0,
        x1: &a.x1,
        x2: &a.x2,
        x3: &a.x3,
        sum: &a.x1,
        nonzero: &a.nonzero,
        replicates: None,
        pixel_spp: None,
    }
}

fn methods() -> Vec<(&'static str, DenoiseParams)> {
    let d = DenoiseParams::default();
    let published = Method::Published(Threshold::Auto);
    vec![
        ("tstat", d),
        (
            "published",
            DenoiseParams {
                method: published,
                radius: published.default_radius(),
                ..d
            },
        ),
        (
            "published, zero borders",
            DenoiseParams {
                method: published,
                radius: 2,
                border: tstat::denoise::Border::Zero,
                ..d
            },
        ),
        (
            "base only, gaussian",
            DenoiseParams {
                method: Method::BaseOnly,
                base: BaseKind::Gaussian,
                radius: 2,
                ..d
            },
        ),
    ]
}

/// Copies of a mono film's channel (RGB-wide and Stokes-wide, signed and scaled by
/// powers of two) denoise channel by channel exactly as the mono film does, under every
/// membership test.
#[test]
fn copies_of_a_mono_channel_denoise_as_the_mono_film() {
    let scene = mono_scene();
    let spp = 24;
    let out = mono_render(&scene, spp);
    let g = GBuffers::from_pixels(out.accum.height, out.accum.width, &out.gbuffer);
    let features = g.features();
    for (name, params) in methods() {
        let mono = denoise_sums(&view(&out.accum, spp), &features, &params, &|_| {});
        let m = mono.volume;
        assert_eq!(m.dim().3, 1);
        assert!(
            m.iter().any(|&v| v > 0.0),
            "{name}: the mono film denoised to zero"
        );
        for f in [
            vec![1.0, 1.0, 1.0],
            vec![1.0, 1.0, 1.0, 1.0],
            vec![1.0, -1.0, 0.5, -2.0],
        ] {
            let wide = widen(&out.accum, &f);
            let d = denoise_sums(&view(&wide, spp), &features, &params, &|_| {});
            assert_eq!(d.volume.dim().3, f.len());
            assert_eq!(d.evaluations, mono.evaluations, "{name} {f:?}");
            for ((y, x, t, c), &v) in d.volume.indexed_iter() {
                let want = (f64::from(m[[y, x, t, 0]]) * f[c]) as f32;
                // Bit for bit (a zero times -1 is a zero of either sign).
                assert!(
                    v.to_bits() == want.to_bits() || (v == 0.0 && want == 0.0),
                    "{name}, factors {f:?}: ({y}, {x}, {t}) channel {c}: {v} vs {want}"
                );
            }
        }
    }
}

/// A channel that disagrees keeps neighbours out: in a Stokes film whose S0 is the
/// mono film's but whose S1 differs between the image's halves (+S0 on the left,
/// -S0 on the right: light polarized at 0 and at 90 degrees), the joint test does not
/// mix the halves where the mono film would, so S0 differs from the mono film's
/// output near the seam and S1 stays of one sign on each side.
#[test]
fn a_disagreeing_stokes_channel_keeps_neighbours_apart() {
    let scene = mono_scene();
    // Enough samples that a difference of 2 S0 in S1 is significant in most lit voxels.
    let spp = 1024;
    let out = mono_render(&scene, spp);
    let (h, w, t) = (out.accum.height, out.accum.width, out.accum.bins);
    let g = GBuffers::from_pixels(h, w, &out.gbuffer);
    let features = g.features();
    let mut wide = widen(&out.accum, &[1.0, 1.0, 0.0, 0.0]);
    for y in 0..h {
        for x in w / 2..w {
            for k in 0..t {
                let i = ((y * w + x) * t + k) * 4 + 1;
                wide.x1[i] = -wide.x1[i];
                wide.x3[i] = -wide.x3[i];
            }
        }
    }
    let params = DenoiseParams {
        method: Method::BaseOnly,
        ..DenoiseParams::default()
    };
    // Without a test the halves mix: S1 near the seam is pulled toward 0 from both sides.
    let base = denoise_sums(&view(&wide, spp), &features, &params, &|_| {}).volume;
    let params = DenoiseParams::default();
    let d = denoise_sums(&view(&wide, spp), &features, &params, &|_| {}).volume;
    let mono = denoise_sums(&view(&out.accum, spp), &features, &params, &|_| {}).volume;
    // The weight of the other half in each voxel's average: (S0 - |S1|) / (2 S0) on the
    // side S1 should have (0: none of it, 1/2: as much as of its own).
    let other = |v: &ndarray::Array4<f32>, y: usize, x: usize, k: usize| {
        let sign = if x < w / 2 { 1.0 } else { -1.0 };
        let s0 = f64::from(v[[y, x, k, 0]]);
        (s0 > 0.0).then(|| (s0 - sign * f64::from(v[[y, x, k, 1]])) / (2.0 * s0))
    };
    let (mut joint, mut alone, mut voxels, mut s0_differs) = (0.0, 0.0, 0, 0);
    for y in 0..h {
        for x in 0..w {
            for k in 0..t {
                if let (Some(a), Some(b)) = (other(&d, y, x, k), other(&base, y, x, k)) {
                    joint += a;
                    alone += b;
                    voxels += 1;
                }
                if d[[y, x, k, 0]] != mono[[y, x, k, 0]] {
                    s0_differs += 1;
                }
                // S2 and S3 are zero throughout.
                assert_eq!((d[[y, x, k, 2]], d[[y, x, k, 3]]), (0.0, 0.0));
            }
        }
    }
    let (joint, alone) = (joint / f64::from(voxels), alone / f64::from(voxels));
    eprintln!("weight of the other half: joint test {joint:.4}, base filter {alone:.4}; S0 differs at {s0_differs}");
    assert!(voxels > 1000 && alone > 0.01, "{voxels} voxels, {alone}");
    assert!(
        joint < alone / 2.0,
        "joint test {joint}, base filter {alone}"
    );
    assert!(s0_differs > 0, "S1 changed nothing about S0's neighbours");
}

/// Writes a bundle of `scene` (its mode says the channels) from `out`.
fn write(dir: &Path, scene: &Scene, out: RenderOutput) {
    let meta = BundleMeta {
        seed: 7,
        transform: Transform::Identity,
        unit_m: 1.0,
        pixel_sampling: PixelSampling::Independent,
        replicates: 0,
        job: None,
        adaptive: None,
    };
    write_bundle(dir, false, scene, &meta, out).unwrap();
}

/// A mono bundle and a Stokes bundle whose S0..S3 are the mono channel times 1, -1,
/// 1/2 and -2, written as the renderer writes bundles.
fn mono_and_stokes_bundles(dir: &Path) -> (String, String) {
    let scene = mono_scene();
    let out = mono_render(&scene, 32);
    let f = [1.0, -1.0, 0.5, -2.0];
    let stokes = RenderOutput {
        accum: widen(&out.accum, &f),
        gbuffer: out.gbuffer.clone(),
        steady: out.steady.iter().flat_map(|&s| f.map(|k| k * s)).collect(),
        dropped_nonfinite: 0,
        rays: out.rays,
        paths: out.paths,
        seconds: out.seconds,
    };
    let mut polarized = mono_scene();
    polarized.set_mode(RenderMode::MonoPolarized).unwrap();
    assert_eq!(polarized.film.channels, 4);
    let (m, s) = (dir.join("mono.tstats"), dir.join("stokes.tstats"));
    write(&m, &scene, out);
    write(&s, &polarized, stokes);
    (m.display().to_string(), s.display().to_string())
}

fn read(path: &Path) -> ndarray::Array4<f32> {
    ndarray_npy::read_npy(path).unwrap()
}

/// `tstat denoise` on a Stokes bundle: each channel as the mono bundle's (times its
/// factor), for the default and the published method; per-bin EXRs named S0.Y .. S3.Y
/// (Y for the mono bundle).
#[test]
fn denoise_cli_on_mono_and_stokes_bundles() {
    let dir = tempfile::tempdir().unwrap();
    let (mono, stokes) = mono_and_stokes_bundles(dir.path());
    let f = [1.0f64, -1.0, 0.5, -2.0];
    for method in ["tstat", "published"] {
        let p = |name: &str| dir.path().join(format!("{name}-{method}.npy"));
        let exr = |name: &str| dir.path().join(format!("{name}-{method}-exr"));
        for (b, name) in [(&mono, "mono"), (&stokes, "stokes")] {
            ok(&tstat(&[
                "denoise",
                b,
                "--method",
                method,
                "--out",
                p(name).to_str().unwrap(),
                "--exr",
                exr(name).to_str().unwrap(),
            ]));
        }
        let (m, s) = (read(&p("mono")), read(&p("stokes")));
        assert_eq!(m.dim().3, 1);
        assert_eq!(s.dim().3, 4);
        for ((y, x, t, c), &v) in s.indexed_iter() {
            let want = (f64::from(m[[y, x, t, 0]]) * f[c]) as f32;
            assert!(
                v.to_bits() == want.to_bits() || (v == 0.0 && want == 0.0),
                "{method} ({y}, {x}, {t}, {c}): {v} vs {want}"
            );
        }
        // Channel names in the EXR headers.
        let names = |name: &str| -> Vec<String> {
            let path = exr(name).join("bin_0010.exr");
            let meta = exr::meta::MetaData::read_from_file(&path, false).unwrap();
            meta.headers[0]
                .channels
                .list
                .iter()
                .map(|c| c.name.to_string())
                .collect()
        };
        assert_eq!(names("stokes"), ["S0.Y", "S1.Y", "S2.Y", "S3.Y"]);
        assert_eq!(names("mono"), ["Y"]);
    }
}

fn png(path: &Path) -> image::RgbImage {
    image::open(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .to_rgb8()
}

/// `tstat frames` on a Stokes volume: S0 as grey frames, and per bin the AoLP/DoLP
/// picture and S1, S2, S3 / S0 in `polarization/`; on a mono volume grey frames and no
/// polarization pictures; a volume of another channel count is one clear error.
#[test]
fn frames_of_mono_and_stokes_volumes() {
    let dir = tempfile::tempdir().unwrap();
    let (mono, stokes) = mono_and_stokes_bundles(dir.path());
    let out = |n: &str| dir.path().join(n);
    // The Stokes bundle's noisy mean (the volume is a bundle: its noisy mean).
    let o = tstat(&[
        "frames",
        &stokes,
        "--out",
        out("sf").to_str().unwrap(),
        "--every",
        "8",
    ]);
    ok(&o);
    assert!(String::from_utf8_lossy(&o.stdout).contains("polarization"));
    let names: Vec<String> = (0..48).step_by(8).map(|k| format!("{k:04}")).collect();
    let (mut lit, mut coloured) = (0, 0);
    for k in &names {
        let frame = png(&out("sf").join(format!("frames/frame_{k}.png")));
        assert!(frame.pixels().all(|p| p[0] == p[1] && p[1] == p[2]));
        let hsv = png(&out("sf").join(format!("polarization/aolp_dolp_{k}.png")));
        let s1 = png(&out("sf").join(format!("polarization/s1_{k}.png")));
        let s2 = png(&out("sf").join(format!("polarization/s2_{k}.png")));
        let s3 = png(&out("sf").join(format!("polarization/s3_{k}.png")));
        for (((h, a), b), c) in hsv
            .pixels()
            .zip(s1.pixels())
            .zip(s2.pixels())
            .zip(s3.pixels())
        {
            if a.0 == [0, 0, 0] {
                continue; // no light
            }
            lit += 1;
            // S1 / S0 = -1: blue; S2 / S0 = 1/2: light red; S3 / S0 = -2: clamped, blue.
            assert_eq!(a.0, [0, 0, 255]);
            assert_eq!(b.0[0], 255);
            assert!(b.0[1] > 100 && b.0[1] < 160 && b.0[1] == b.0[2], "{b:?}");
            assert_eq!(c.0, [0, 0, 255]);
            // DoLP 1 at AoLP 0.5 atan2(1/2, -1) = 76.7 degrees: a saturated
            // green-cyan (hue 0.43), unless S0 tone-maps to black.
            if h.0 != [0, 0, 0] {
                coloured += 1;
                assert!(h.0[0] < h.0[1] && h.0[2] < h.0[1], "{h:?}");
            }
        }
    }
    assert!(lit > 50 && coloured > 50, "lit {lit}, coloured {coloured}");
    // A mono volume: grey, no polarization folder.
    ok(&tstat(&[
        "frames",
        &mono,
        "--out",
        out("mf").to_str().unwrap(),
        "--every",
        "8",
    ]));
    let frame = png(&out("mf").join("frames/frame_0016.png"));
    assert!(frame.pixels().all(|p| p[0] == p[1] && p[1] == p[2]));
    assert!(frame.pixels().any(|p| p[0] > 0));
    assert!(!out("mf").join("polarization").exists());
    // Two channels: refused, naming the shape.
    let bad = out("two.npy");
    ndarray_npy::write_npy(&bad, &ndarray::Array4::<f32>::ones((2, 2, 3, 2))).unwrap();
    let o = tstat(&[
        "frames",
        bad.to_str().unwrap(),
        "--out",
        out("bf").to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("[2, 2, 3, 2]") && err.contains("4 (Stokes"),
        "{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
}

/// `tstat view` and `tstat report compare` on mono and Stokes bundles and volumes.
#[test]
fn view_and_report_on_mono_and_stokes_bundles() {
    let dir = tempfile::tempdir().unwrap();
    let (mono, stokes) = mono_and_stokes_bundles(dir.path());
    let p = |n: &str| dir.path().join(n).display().to_string();
    for (b, c, names) in [
        (&mono, 1, vec!["Y"]),
        (&stokes, 4, vec!["S0", "S1", "S2", "S3"]),
    ] {
        let den = p(&format!("den{c}.npy"));
        ok(&tstat(&["denoise", b, "--out", &den]));
        let html = p(&format!("view{c}.html"));
        ok(&tstat(&[
            "view",
            b,
            "--denoised",
            &den,
            "--reference",
            b,
            "--out",
            &html,
        ]));
        let data = crate::common::page_data(&std::fs::read_to_string(&html).unwrap());
        assert_eq!(data["channels"], c);
        assert_eq!(data["channel_names"], serde_json::json!(names));
        // Three volumes and the band, each (H, W, T, C) f16: 16 x 16 x 48 x C x 2 bytes.
        let vols = data["volumes"].as_array().unwrap();
        assert_eq!(vols.len(), 4);
        for v in vols {
            let b64 = v["data"].as_str().unwrap();
            assert_eq!(b64.len(), (16 * 16 * 48 * c * 2usize).div_ceil(3) * 4);
        }
        // report compare: the denoised volume against the bundle's noisy mean.
        let o = tstat(&[
            "report",
            "compare",
            "--reference",
            b,
            "--input",
            &format!("denoised={den}"),
            "--out",
            &p(&format!("report{c}")),
        ]);
        ok(&o);
        let text = String::from_utf8_lossy(&o.stdout);
        assert!(text.contains("denoised"), "{text}");
        assert!(Path::new(&p(&format!("report{c}")))
            .join("metrics.csv")
            .is_file());
    }
    // A volume of the wrong channel count beside a bundle: refused.
    let o = tstat(&[
        "view",
        &mono,
        "--denoised",
        &p("den4.npy"),
        "--out",
        &p("bad.html"),
    ]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("does not match"), "{err}");
}
