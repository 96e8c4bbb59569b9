//! The spectral polarized render mode (`--mode spectral_polarized`, src/scene/mode.rs,
//! src/render/polarized.rs): three wavelengths per path, each with its own Mueller
//! matrix, and the four Stokes components of each sRGB channel (12 channels,
//! RGB-major). A world of depolarizers renders S0 bit for bit as the spectral mode;
//! Malus's law and Fresnel's equations hold per colour (the filters here treat every
//! wavelength alike, so each sample's ratios are exact); a conductor whose optical
//! constants differ per wavelength polarizes each wavelength by its own Fresnel
//! matrix; same seed, same bits on any thread count; the bundle exports
//! (H, W, T, 3, 4) and an EXR with Mitsuba's channel names.

use crate::common::{bundled, bundled_error, bundled_path, load, tstat};
use crate::polarized_render::{
    dielectric_mirror_scene, filter_scene, mode, polarizer, run, totals,
};
use tstat::scene::mode::RenderMode;
use tstat::scene::Overrides;

/// Channel of Stokes component `j` of colour `c` (RGB-major).
fn ch(c: usize, j: usize) -> usize {
    4 * c + j
}

/// A world of depolarizers (cbox: diffuse walls, a diffuse light) renders S0.R, S0.G,
/// S0.B bit for bit as the spectral mode's R, G, B (the same wavelengths, the same
/// samples, and every Mueller step keeps S0 and drops the rest), with every other
/// component exactly 0.
#[test]
fn an_unpolarizing_world_renders_s0_as_the_spectral_mode() {
    let o = |m| Overrides {
        width: Some(8),
        bins: Some(30),
        ..mode(m)
    };
    let pol = run(
        &bundled("cbox.xml", &o(RenderMode::SpectralPolarized)),
        8,
        2,
    );
    let spec = run(&bundled("cbox.xml", &o(RenderMode::Spectral)), 8, 2);
    assert_eq!(pol.accum.channels, 12);
    assert_eq!(spec.accum.channels, 3);
    for (arr_p, arr_s) in [
        (&pol.accum.x1, &spec.accum.x1),
        (&pol.accum.x2, &spec.accum.x2),
        (&pol.accum.x3, &spec.accum.x3),
    ] {
        let s0: Vec<f64> = arr_p
            .chunks_exact(12)
            .flat_map(|v| [v[ch(0, 0)], v[ch(1, 0)], v[ch(2, 0)]])
            .collect();
        assert_eq!(&s0, arr_s);
        for v in arr_p.chunks_exact(12) {
            for c in 0..3 {
                for j in 1..4 {
                    assert_eq!(v[ch(c, j)], 0.0);
                }
            }
        }
    }
    assert!(spec.accum.x1.iter().any(|&v| v > 0.0));
    assert_eq!(pol.accum.nonzero, spec.accum.nonzero);
}

/// Malus's law per colour: unpolarized white light through ideal linear polarizers at
/// angles a and b arrives polarized along b, so in every colour S1 = S0 cos 2b,
/// S2 = -S0 sin 2b (Mitsuba's sign, as the mono test) and S3 = 0; every sample meets
/// these ratios exactly (the polarizers treat every wavelength alike), so the totals do
/// to f32 rounding. S0 against the spectral render of the open light: cos^2(a - b) / 2
/// of it, per path and exactly (the same wavelengths).
#[test]
fn malus_law_holds_in_every_colour() {
    let open = {
        let scene = load(&filter_scene(""), &mode(RenderMode::Spectral));
        totals(&run(&scene, 8, 3), 3)
    };
    assert!(open.iter().all(|&v| v > 0.0), "{open:?}");
    for (a, b) in [(0.0f32, 30.0f32), (20.0, 65.0), (45.0, 120.0)] {
        let xml = filter_scene(&(polarizer(-2.0, a) + &polarizer(-1.0, b)));
        let scene = load(&xml, &mode(RenderMode::SpectralPolarized));
        let s = totals(&run(&scene, 8, 3), 12);
        let (ar, br) = (f64::from(a).to_radians(), f64::from(b).to_radians());
        let pass = 0.5 * (ar - br).cos().powi(2);
        for c in 0..3 {
            let s0 = s[ch(c, 0)];
            assert!(
                (s0 / open[c] - pass).abs() < 1e-4,
                "a {a} b {b} colour {c}: S0 {s0} of {} against {pass}",
                open[c]
            );
            let want = [(2.0 * br).cos(), -(2.0 * br).sin(), 0.0];
            for j in 1..4 {
                assert!(
                    (s[ch(c, j)] / s0 - want[j - 1]).abs() < 2e-4,
                    "a {a} b {b} colour {c}: S{j}/S0 {} against {}",
                    s[ch(c, j)] / s0,
                    want[j - 1]
                );
            }
        }
    }
}

/// Fresnel per colour: light reflected once by a smooth dielectric mirror (eta 1.5,
/// the same at every wavelength) has S1 / S0 = (R_s - R_p) / (R_s + R_p) in every
/// colour, S2 = S3 = 0 (the sensor's x axis is the s direction; S2 is f32 rounding of
/// the frame rotations, which the sRGB weights of opposite signs magnify a little).
#[test]
fn a_dielectric_mirror_polarizes_every_colour_as_fresnel_says() {
    let theta = 56.3f64.to_radians();
    let xml = dielectric_mirror_scene(56.3, r#"<rgb name="radiance" value="1, 0.6, 0.3"/>"#);
    let scene = load(&xml, &mode(RenderMode::SpectralPolarized));
    let s = totals(&run(&scene, 1024, 5), 12);
    let n = 1.5f64;
    let cos_i = theta.cos();
    let cos_t = (1.0 - (theta.sin() / n).powi(2)).sqrt();
    let rs = ((cos_i - n * cos_t) / (cos_i + n * cos_t)).powi(2);
    let rp = ((n * cos_i - cos_t) / (n * cos_i + cos_t)).powi(2);
    let want = (rs - rp) / (rs + rp);
    for col in 0..3 {
        let s0 = s[ch(col, 0)];
        assert!(s0 > 0.0, "colour {col}: {s:?}");
        assert!(
            (s[ch(col, 1)] / s0 - want).abs() < 2e-4,
            "colour {col}: S1/S0 {} against {want}",
            s[ch(col, 1)] / s0
        );
        assert!(
            s[ch(col, 2)].abs() < 5e-4 * s0 && s[ch(col, 3)].abs() < 5e-4 * s0,
            "{s:?}"
        );
    }
}

/// Same seed, same bits, on one thread or two (cbox_polarizers: polarizers, a
/// retarder, glass and aluminium).
#[test]
fn spectral_polarized_renders_do_not_depend_on_the_thread_count() {
    let o = Overrides {
        width: Some(8),
        bins: Some(100),
        ..mode(RenderMode::SpectralPolarized)
    };
    let scene = bundled("cbox_polarizers.xml", &o);
    let on = |threads: usize| crate::common::on_threads(threads, || run(&scene, 8, 11));
    let (a, b) = (on(1), on(2));
    assert_eq!(a.accum.x1, b.accum.x1);
    assert_eq!(a.accum.x3, b.accum.x3);
    assert_eq!(a.steady, b.steady);
    for c in 0..3 {
        assert!(
            a.accum.x1.chunks_exact(12).any(|v| v[ch(c, 1)] != 0.0),
            "S1 of colour {c} is not zero"
        );
    }
}

/// The binary: a spectral_polarized bundle names its 12 channels, exports the volume
/// as (H, W, T, 3, 4) and the steady image as (H, W, 3, 4) (RGB x Stokes, `[.., c, j]`
/// = component j of colour c, the bundle's channel 4c + j) and as an EXR with
/// Mitsuba's `stokes` names S0.R .. S3.B; `denoise` writes (H, W, T, 3, 4) too, and
/// `frames` writes the polarization pictures.
#[test]
fn a_spectral_polarized_bundle_is_rgb_by_stokes() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).display().to_string();
    let scene = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cbox_polarizers.xml");
    let scene = scene.display().to_string();
    let r = tstat(&[
        "render",
        &scene,
        "--out",
        &p("p.tstats"),
        "--mode",
        "spectral_polarized",
        "--width",
        "12",
        "--spp",
        "4",
        "--bins",
        "40",
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let m: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("p.tstats/manifest.json")).unwrap())
            .unwrap();
    assert_eq!(m["mode"], "spectral_polarized");
    let names: Vec<String> = (0..3)
        .flat_map(|c| (0..4).map(move |j| format!("S{j}.{}", ["R", "G", "B"][c])))
        .collect();
    assert_eq!(m["channels"], serde_json::json!(names));
    let r = tstat(&[
        "export",
        &p("p.tstats"),
        "--out",
        &p("v.npy"),
        "--steady",
        &p("s.npy"),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let v: ndarray::Array5<f32> = ndarray_npy::read_npy(dir.path().join("v.npy")).unwrap();
    assert_eq!(v.shape(), &[12, 12, 40, 3, 4]);
    let s: ndarray::Array4<f32> = ndarray_npy::read_npy(dir.path().join("s.npy")).unwrap();
    assert_eq!(s.shape(), &[12, 12, 3, 4]);
    // The steady image against the bundle's own array, channel 4c + j at [c][j].
    let raw: ndarray::Array3<f64> =
        ndarray_npy::read_npy(dir.path().join("p.tstats/steady.npy")).unwrap();
    for c in 0..3 {
        for j in 0..4 {
            assert_eq!(s[[5, 7, c, j]], raw[[5, 7, ch(c, j)]] as f32);
        }
    }
    let r = tstat(&["export", &p("p.tstats"), "--steady", &p("s.exr")]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let exr = exr::prelude::read_all_flat_layers_from_file(dir.path().join("s.exr")).unwrap();
    let mut got: Vec<String> = exr.layer_data[0]
        .channel_data
        .list
        .iter()
        .map(|c| c.name.to_string())
        .collect();
    got.sort();
    let mut want = names.clone();
    want.sort();
    assert_eq!(got, want);
    let r = tstat(&["denoise", &p("p.tstats"), "--out", &p("d.npy")]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let d: ndarray::Array5<f32> = ndarray_npy::read_npy(dir.path().join("d.npy")).unwrap();
    assert_eq!(d.shape(), &[12, 12, 40, 3, 4]);
    let r = tstat(&["frames", &p("p.tstats"), "--out", &p("f"), "--every", "10"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(dir
        .path()
        .join("f/polarization/aolp_dolp_0000.png")
        .exists());
    // The denoised volume reads back where volumes are read (report, frames).
    let r = tstat(&["frames", &p("d.npy"), "--out", &p("fd"), "--every", "10"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(dir
        .path()
        .join("fd/polarization/aolp_dolp_0000.png")
        .exists());
}

/// What the mode does not model is refused at load, naming it (as the spectral
/// mode); Box-Cox is refused on the command line (S1..S3 are signed); a Yeo-Johnson
/// bundle of signed samples reads back (its negative branch is finite).
#[test]
fn the_spectral_polarized_mode_refuses_what_it_does_not_model() {
    for (name, says) in [
        ("cbox_fog.xml", "participating media"),
        ("nlos_T.xml", "NLOS captures"),
    ] {
        let e = bundled_error(name, &mode(RenderMode::SpectralPolarized));
        assert!(e.contains(says), "{name}: {e}");
        assert!(e.contains("spectral_polarized"), "{name}: {e}");
    }
    let dir = tempfile::tempdir().unwrap();
    let scene = bundled_path("cbox_polarizers.xml").display().to_string();
    let out = dir.path().join("b.tstats").display().to_string();
    let render = |t: &str| {
        tstat(&[
            "render",
            &scene,
            "--out",
            &out,
            "--mode",
            "spectral_polarized",
            "--transform",
            t,
            "--width",
            "8",
            "--spp",
            "4",
            "--bins",
            "20",
        ])
    };
    let r = render("box-cox:0.5");
    assert!(!r.status.success());
    assert!(String::from_utf8_lossy(&r.stderr).contains("Box-Cox"));
    assert!(!dir.path().join("b.tstats").exists());
    let r = render("yeo-johnson:0.5");
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let r = tstat(&["info", &out]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
}
