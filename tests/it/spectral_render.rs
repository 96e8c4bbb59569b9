//! The spectral render mode (`--mode spectral`, src/scene/mode.rs, src/spectral/lift.rs)
//! end to end: a spectrum given as a list reaches the film as its sRGB integral
//! (computed here by an independent quadrature); a grey world renders as in RGB (grey
//! reflectances are flat, a grey emitter is D65, sRGB's white); the G-buffer stays
//! RGB; same seed, same bits on any thread count; and what the mode does not model is
//! refused with one message.

#![allow(clippy::needless_range_loop)] // channels index several arrays at once

use crate::common::{bundled, bundled_error, bundled_path, load, tstat};
use tstat::render::RenderOutput;
use tstat::scene::mode::RenderMode;
use tstat::scene::spectrum::{list_to_srgb, uniform_to_srgb, SpectrumUse};
use tstat::scene::{Overrides, Scene};
use tstat::spectral::cie::{cie1931_xyz, xyz_to_srgb, CIE_Y_NORMALIZATION};

fn spectral() -> Overrides {
    Overrides {
        mode: RenderMode::Spectral,
        ..Default::default()
    }
}

fn run(scene: &Scene, spp: u32, seed: u64) -> RenderOutput {
    crate::common::run_spp(scene, spp, seed)
}

/// A camera looking straight at an area light 4 units away whose radiance is
/// `radiance` (an XML element), all of it in bin 0.
fn light_scene(radiance: &str) -> String {
    format!(
        r#"<scene version="3.0.0">
  <integrator type="transient_path"><integer name="max_depth" value="2"/></integrator>
  <sensor type="perspective">
    <float name="fov" value="0.5"/>
    <transform name="to_world"><lookat origin="0,0,0" target="0,0,-1" up="0,1,0"/></transform>
    <sampler type="independent"><integer name="sample_count" value="4"/></sampler>
    <film type="transient_hdr_film">
      <integer name="width" value="1"/><integer name="height" value="1"/>
      <integer name="temporal_bins" value="2"/>
      <float name="start_opl" value="3.975"/><float name="bin_width_opl" value="0.05"/>
    </film>
  </sensor>
  <shape type="rectangle">
    <transform name="to_world"><scale value="3"/><translate z="-4"/></transform>
    <emitter type="area">{radiance}</emitter>
  </shape>
</scene>"#
    )
}

/// A triangular spectrum 530-545-560 nm, peak 8, seen directly: each channel's mean is
/// `CIE_Y_NORMALIZATION * int L(l) sRGB(cmf(l)) dl` (emission: no D65), here by the
/// midpoint rule on 0.001 nm steps; the render's mean must lie within 4 standard
/// errors of it (the standard error from the render's own sums). The spectrum is out of
/// the sRGB gamut (red is negative): the spectral mode keeps the negative mean, as
/// mitransient's spectral variants do, while RGB mode reads the spectrum as its RGB
/// once, at load, clamped to >= 0 as Mitsuba's RGB variants do: within 0.5% of the
/// clamped integral.
#[test]
fn a_narrow_band_emitter_renders_as_the_integral_of_its_spectrum() {
    let tri = |l: f64| {
        if (530.0..=560.0).contains(&l) {
            8.0 * (1.0 - (l - 545.0).abs() / 15.0)
        } else {
            0.0
        }
    };
    let steps = 30_000;
    let h = 30.0 / steps as f64;
    let mut expected = [0.0f64; 3];
    for i in 0..steps {
        let l = 530.0 + (i as f64 + 0.5) * h;
        let rgb = xyz_to_srgb(cie1931_xyz(l as f32));
        for c in 0..3 {
            expected[c] += tri(l) * f64::from(rgb[c]) * h * CIE_Y_NORMALIZATION;
        }
    }
    let xml = light_scene(r#"<spectrum name="radiance" value="530:0, 545:8, 560:0"/>"#);
    let spp = 200_000;
    let out = run(&load(&xml, &spectral()), spp, 7);
    let stats = mean_and_se(&out, spp);
    for c in 0..3 {
        let (mean, se) = stats[c];
        assert!(
            (mean - expected[c]).abs() < 4.0 * se,
            "channel {c}: {mean} vs {} (se {se})",
            expected[c]
        );
        // A 4-sigma test that cannot tell the mean from twice the mean would be
        // worthless: the standard error is a small fraction of the value.
        assert!(se < 0.01 * expected[c].abs().max(0.05), "se {se}");
    }
    assert!(expected[0] < -0.1, "out of gamut: {expected:?}");
    let rgb = run(&load(&xml, &Overrides::default()), 4, 1);
    for c in 0..3 {
        let (v, want) = (rgb.accum.x1[c] / 4.0, expected[c].max(0.0));
        assert!(
            (v - want).abs() < 5e-3 * want.max(0.05),
            "rgb {c}: {v} vs {want}"
        );
    }
}

/// A uniform spectrum is flat in the spectral mode (Mitsuba's `uniform`), not D65:
/// seen directly its sRGB is `v * xyz_to_srgb(1, 1, 1)`, the purple-ish colour RGB
/// mode reads it as.
#[test]
fn a_uniform_emission_spectrum_is_flat() {
    let xml = light_scene(r#"<spectrum name="radiance" value="2"/>"#);
    let spp = 100_000;
    let out = run(&load(&xml, &spectral()), spp, 3);
    let want = xyz_to_srgb([1.0; 3]).map(|c| 2.0 * f64::from(c));
    let stats = mean_and_se(&out, spp);
    for c in 0..3 {
        let (mean, se) = stats[c];
        assert!(
            (mean - want[c]).abs() < 4.0 * se,
            "channel {c}: {mean} vs {} (se {se})",
            want[c]
        );
    }
}

/// Planck's law written out (f64, CODATA 2014 as Mitsuba), per nanometre:
/// `2 h c^2 / l^5 / (exp(h c / (l k T)) - 1) 1e-9` W m^-2 sr^-1 nm^-1.
fn planck(lambda_nm: f64, t: f64) -> f64 {
    let (c, h, k) = (2.99792458e8, 6.62607004e-34, 1.38064852e-23);
    let l = lambda_nm * 1e-9;
    2.0 * h * c * c / l.powi(5) / ((h * c / (l * k * t)).exp() - 1.0) * 1e-9
}

/// A blackbody area light seen directly (`<spectrum type="blackbody">`, Mitsuba's
/// `blackbody`): each channel's mean is `CIE_Y_NORMALIZATION * int B(l) sRGB(cmf(l))
/// dl` over the spectrum's range (emission: no D65), Planck's law written out in
/// f64 and integrated by the midpoint rule on 0.01 nm steps; the render's mean must lie
/// within 4 standard errors of it. At 2700 K the light is orange (red > green >
/// blue); a range cut to [500, 600] nm drops what lies outside it. RGB and mono
/// refuse the spectrum, naming `--mode spectral`, as Mitsuba's RGB and mono variants
/// refuse it.
#[test]
fn a_blackbody_emitter_renders_as_the_integral_of_plancks_law() {
    for (t, range, extra) in [
        (2700.0, [360.0, 830.0], ""),
        (
            6500.0,
            [500.0, 600.0],
            r#"<float name="wavelength_min" value="500"/><float name="wavelength_max" value="600"/>"#,
        ),
    ] {
        let steps = 47_000;
        let h = (range[1] - range[0]) / steps as f64;
        let mut expected = [0.0f64; 3];
        for i in 0..steps {
            let l = range[0] + (i as f64 + 0.5) * h;
            let rgb = xyz_to_srgb(cie1931_xyz(l as f32));
            for c in 0..3 {
                expected[c] += planck(l, t) * f64::from(rgb[c]) * h * CIE_Y_NORMALIZATION;
            }
        }
        let xml = light_scene(&format!(
            r#"<spectrum type="blackbody" name="radiance"><float name="temperature" value="{t}"/>{extra}</spectrum>"#
        ));
        let spp = 100_000;
        let out = run(&load(&xml, &spectral()), spp, 9);
        let stats = mean_and_se(&out, spp);
        for c in 0..3 {
            let (mean, se) = stats[c];
            assert!(
                (mean - expected[c]).abs() < 4.0 * se,
                "{t} K channel {c}: {mean} vs {} (se {se})",
                expected[c]
            );
            // Tight enough to tell the mean from a few percent off it.
            let scale = expected.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            assert!(
                se < 0.015 * scale,
                "{t} K channel {c}: se {se} of {expected:?}"
            );
        }
        if t == 2700.0 {
            assert!(
                expected[0] > expected[1] && expected[1] > expected[2],
                "{expected:?}"
            );
        }
        for mode in [RenderMode::Rgb, RenderMode::Mono, RenderMode::MonoPolarized] {
            let o = Overrides {
                mode,
                ..Default::default()
            };
            let dir = tempfile::tempdir().unwrap();
            let path = dir.path().join("scene.xml");
            std::fs::write(&path, &xml).unwrap();
            let e = Scene::load(&path, &o).err().expect("refused").to_string();
            assert!(
                e.contains("--mode spectral") && e.contains("blackbody"),
                "{e}"
            );
        }
    }
}

/// A plane of BSDF `bsdf` (an XML element) seen straight on, lit by a `constant`
/// environment of the flat spectrum 1 (`<spectrum value="1"/>`, not D65), one pixel and
/// one time bin that holds every path (the environment's segments included).
fn lit_plane_scene(bsdf: &str) -> String {
    format!(
        r#"<scene version="3.0.0">
  <integrator type="transient_path"><integer name="max_depth" value="2"/></integrator>
  <sensor type="perspective">
    <float name="fov" value="0.5"/>
    <transform name="to_world"><lookat origin="0,0,1" target="0,0,0" up="0,1,0"/></transform>
    <sampler type="independent"><integer name="sample_count" value="4"/></sampler>
    <film type="transient_hdr_film">
      <integer name="width" value="1"/><integer name="height" value="1"/>
      <integer name="temporal_bins" value="1"/>
      <float name="start_opl" value="0"/><float name="bin_width_opl" value="10000"/>
    </film>
  </sensor>
  <emitter type="constant"><spectrum name="radiance" value="1"/></emitter>
  <shape type="rectangle">
    <transform name="to_world"><scale value="50"/></transform>
    {bsdf}
  </shape>
</scene>"#
    )
}

/// `CIE_Y_NORMALIZATION * int f(l) sRGB(cmf(l)) dl` over [360, 830] nm, by the
/// midpoint rule on 0.01 nm steps.
fn srgb_integral(f: impl Fn(f64) -> f64) -> [f64; 3] {
    let steps = 47_000;
    let h = 470.0 / steps as f64;
    let mut out = [0.0f64; 3];
    for i in 0..steps {
        let l = 360.0 + (i as f64 + 0.5) * h;
        let rgb = xyz_to_srgb(cie1931_xyz(l as f32));
        for c in 0..3 {
            out[c] += f(l) * f64::from(rgb[c]) * h * CIE_Y_NORMALIZATION;
        }
    }
    out
}

/// The linear interpolation of `(wavelength, value)` points, zero outside them (as a
/// `<spectrum>` list is read), written out for the tests' integrals.
fn piecewise(points: &[(f64, f64)], l: f64) -> f64 {
    for w in points.windows(2) {
        let ((l0, v0), (l1, v1)) = (w[0], w[1]);
        if l >= l0 && l <= l1 {
            return v0 + (l - l0) / (l1 - l0) * (v1 - v0);
        }
    }
    0.0
}

/// The mean of a one-pixel, one-bin render and its standard error.
fn mean_and_se(out: &RenderOutput, spp: u32) -> [(f64, f64); 3] {
    let n = f64::from(spp);
    std::array::from_fn(|c| {
        let mean = out.accum.x1[c] / n;
        let var = (out.accum.x2[c] / n - mean * mean).max(0.0);
        (mean, (var / n).sqrt())
    })
}

/// Reflectances given as `<spectrum>` are used as given in the spectral mode (Mitsuba's
/// `irregular` spectrum at the path's wavelengths), not read as their RGB and lifted:
/// a diffuse plane under a flat white environment (radiance 1 at every wavelength)
/// reflects `rho(l) * 1`, so each channel's mean is `CIE_Y_NORMALIZATION * int rho(l)
/// sRGB(cmf(l)) dl`, computed here from the listed points. A narrow band at 545 nm has
/// a negative red (RGB, and lifting its RGB, would clamp it to >= 0), a step at 600 nm
/// is no smooth sigmoid; the step's plane is `twosided` (the spectrum reaches the
/// model through the wrapper) and read from a `.spd` file. RGB mode still reads the
/// spectra as their RGB: the product of the reflectance's and the light's RGB.
#[test]
fn reflectance_spectra_are_used_as_given() {
    let band = [(530.0, 0.0), (545.0, 0.9), (560.0, 0.0)];
    let step = [(360.0, 0.05), (599.0, 0.05), (601.0, 0.85), (830.0, 0.85)];
    let dir = tempfile::tempdir().unwrap();
    let spd: String = step.iter().map(|(l, v)| format!("{l} {v}\n")).collect();
    std::fs::write(dir.path().join("step.spd"), spd).unwrap();
    let band_bsdf = r#"<bsdf type="diffuse"><spectrum name="reflectance" value="530:0, 545:0.9, 560:0"/></bsdf>"#;
    let step_bsdf = r#"<bsdf type="twosided"><bsdf type="diffuse"><spectrum name="reflectance" filename="step.spd"/></bsdf></bsdf>"#;
    for (points, bsdf) in [(&band[..], band_bsdf), (&step[..], step_bsdf)] {
        let expected = srgb_integral(|l| piecewise(points, l));
        let path = dir.path().join("scene.xml");
        std::fs::write(&path, lit_plane_scene(bsdf)).unwrap();
        let scene = Scene::load(&path, &spectral()).unwrap();
        assert_eq!(
            scene.bsdfs[0].spectra.len(),
            if points.len() == 3 { 1 } else { 2 }
        );
        let spp = 100_000;
        let got = mean_and_se(&run(&scene, spp, 21), spp);
        let scale = expected.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for c in 0..3 {
            let (mean, se) = got[c];
            assert!(
                (mean - expected[c]).abs() < 4.0 * se,
                "channel {c}: {mean} vs {} (se {se})",
                expected[c]
            );
            assert!(se < 0.01 * scale, "se {se} of {expected:?}");
        }
        if points.len() == 3 {
            assert!(expected[0] < -0.1 * scale, "out of gamut: {expected:?}");
        }
        // RGB: the reflectance's RGB (D65-weighted, clamped) times the light's.
        let rgb = run(&Scene::load(&path, &Overrides::default()).unwrap(), 64, 1);
        let (w, v): (Vec<f64>, Vec<f64>) = points.iter().copied().unzip();
        let (refl, _) = list_to_srgb(&w, &v, SpectrumUse::Reflectance);
        let light = uniform_to_srgb(1.0, SpectrumUse::Emission);
        let got = mean_and_se(&rgb, 64);
        for c in 0..3 {
            let want = f64::from(refl[c]) * f64::from(light[c]);
            assert!(
                (got[c].0 - want).abs() < 4.0 * got[c].1 + 1e-5,
                "rgb {c}: {:?} vs {want}",
                got[c]
            );
        }
    }
}

/// A conductor whose `eta` and `k` are `<spectrum>` lists reflects, seen straight on,
/// the normal-incidence Fresnel reflectance `((n - 1)^2 + k^2) / ((n + 1)^2 + k^2)` of
/// the listed values at each wavelength (Mitsuba uses measured spectra as given): the
/// mean is the sRGB integral of that reflectance under the flat white environment.
#[test]
fn conductor_spectra_are_used_as_given() {
    let eta = [(360.0, 1.6), (500.0, 1.0), (560.0, 0.35), (830.0, 0.15)];
    let k = [(360.0, 1.9), (500.0, 1.9), (600.0, 3.0), (830.0, 5.0)];
    let list = |p: &[(f64, f64)]| {
        p.iter()
            .map(|(l, v)| format!("{l}:{v}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let bsdf = format!(
        r#"<bsdf type="conductor"><spectrum name="eta" value="{}"/><spectrum name="k" value="{}"/></bsdf>"#,
        list(&eta),
        list(&k)
    );
    let expected = srgb_integral(|l| {
        let (n, k) = (piecewise(&eta, l), piecewise(&k, l));
        ((n - 1.0) * (n - 1.0) + k * k) / ((n + 1.0) * (n + 1.0) + k * k)
    });
    let scene = load(&lit_plane_scene(&bsdf), &spectral());
    assert_eq!(scene.bsdfs[0].spectra.len(), 2);
    let spp = 100_000;
    let got = mean_and_se(&run(&scene, spp, 4), spp);
    for c in 0..3 {
        let (mean, se) = got[c];
        // The camera's rays leave within 0.25 degrees of the normal: Fresnel there is
        // the normal-incidence value to 1e-5.
        assert!(
            (mean - expected[c]).abs() < 4.0 * se + 1e-4 * expected[c].abs(),
            "channel {c}: {mean} vs {} (se {se})",
            expected[c]
        );
        assert!(se < 0.01 * expected[c].abs(), "se {se} of {expected:?}");
    }
}

/// A bilinear bitmap is lifted texel by texel before its filter, as Mitsuba's bitmap
/// (`interpolate_spectral`): a plane textured with a 2 x 1 image, red | green, seen
/// at uv (1/2, 1/2), halfway between the two texels, under the flat white
/// environment, has the reflectance `(s_red(l) + s_green(l)) / 2` (`s` the smooth
/// spectrum of a colour, `rgb2spec`), not the spectrum of the interpolated colour (1/2,
/// 1/2, 0). Its sRGB integral (midpoint rule) must hold within 4 standard errors, and
/// the other rule's integral must lie at least 10 standard errors away.
#[test]
fn bitmaps_are_lifted_texel_by_texel() {
    use tstat::spectral::rgb2spec::{eval, fetch};
    let dir = tempfile::tempdir().unwrap();
    let mut img = image::RgbImage::new(2, 1);
    img.put_pixel(0, 0, image::Rgb([255, 0, 0]));
    img.put_pixel(1, 0, image::Rgb([0, 255, 0]));
    img.save(dir.path().join("rg.png")).unwrap();
    let bsdf = r#"<bsdf type="diffuse"><texture type="bitmap" name="reflectance">
        <string name="filename" value="rg.png"/><string name="wrap_mode" value="clamp"/>
    </texture></bsdf>"#;
    let path = dir.path().join("scene.xml");
    std::fs::write(&path, lit_plane_scene(bsdf)).unwrap();
    let scene = Scene::load(&path, &spectral()).unwrap();
    let (red, green, mix) = (
        fetch([1.0, 0.0, 0.0]),
        fetch([0.0, 1.0, 0.0]),
        fetch([0.5, 0.5, 0.0]),
    );
    let expected = srgb_integral(|l| {
        0.5 * f64::from(eval(red, l as f32)) + 0.5 * f64::from(eval(green, l as f32))
    });
    let other = srgb_integral(|l| f64::from(eval(mix, l as f32)));
    let spp = 100_000;
    let got = mean_and_se(&run(&scene, spp, 13), spp);
    let mut apart = 0.0f64;
    for c in 0..3 {
        let (mean, se) = got[c];
        assert!(
            (mean - expected[c]).abs() < 4.0 * se,
            "channel {c}: {mean} vs {} (se {se}; lifting the filtered colour gives {})",
            expected[c],
            other[c]
        );
        apart = apart.max((other[c] - expected[c]).abs() / se);
    }
    assert!(
        apart > 10.0,
        "the two rules are {apart} standard errors apart"
    );
}

/// `tstat check` loads a scene for `--mode` (default rgb): the bundled blackbody scene
/// is one clear error in rgb, naming `--mode spectral`, and ok with it.
#[test]
fn check_takes_the_mode_a_blackbody_scene_needs() {
    let scene = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes/spectral/cbox_blackbody.xml")
        .display()
        .to_string();
    let rgb = tstat(&["check", &scene]);
    assert_eq!(rgb.status.code(), Some(1));
    let out = String::from_utf8_lossy(&rgb.stdout);
    assert!(out.contains("renders only with --mode spectral"), "{out}");
    let spectral = tstat(&["check", &scene, "--mode", "spectral"]);
    assert!(
        spectral.status.success(),
        "{}",
        String::from_utf8_lossy(&spectral.stdout)
    );
}

/// A grey diffuse plane lit by a grey area light: grey reflectances are flat and a
/// grey emitter is D65, whose sRGB is white, so the spectral render's mean is the RGB
/// render's (within its noise: 64 px x 2048 paths; RGB's only noise here is the
/// sub-pixel position). The G-buffer's albedo is the RGB one.
#[test]
fn a_grey_world_renders_as_in_rgb() {
    let xml = r#"<scene version="3.0.0">
  <integrator type="transient_path"><integer name="max_depth" value="3"/></integrator>
  <sensor type="perspective">
    <float name="fov" value="30"/>
    <transform name="to_world"><lookat origin="0,0,3" target="0,0,0" up="0,1,0"/></transform>
    <sampler type="independent"><integer name="sample_count" value="4"/></sampler>
    <film type="transient_hdr_film">
      <integer name="width" value="8"/><integer name="height" value="8"/>
      <integer name="temporal_bins" value="40"/>
      <float name="start_opl" value="3"/><float name="bin_width_opl" value="0.1"/>
    </film>
  </sensor>
  <shape type="rectangle">
    <bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf>
  </shape>
  <shape type="rectangle">
    <transform name="to_world"><scale value="0.3"/><rotate x="1" angle="180"/><translate z="2" x="0.5"/></transform>
    <emitter type="area"><rgb name="radiance" value="20"/></emitter>
  </shape>
</scene>"#;
    let spp = 2048;
    let s = run(&load(xml, &spectral()), spp, 5);
    let r = run(&load(xml, &Overrides::default()), spp, 5);
    let px = s.steady.len() / 3;
    for c in 0..3 {
        let mean = |o: &RenderOutput| (0..px).map(|p| o.steady[p * 3 + c]).sum::<f64>() / px as f64;
        let (ms, mr) = (mean(&s), mean(&r));
        assert!(mr > 0.01, "the plane is lit: {mr}");
        assert!(
            (ms - mr).abs() < 0.01 * mr,
            "channel {c}: spectral {ms} vs rgb {mr}"
        );
    }
    for (a, b) in s.gbuffer.iter().zip(&r.gbuffer) {
        assert_eq!(a.albedo, b.albedo);
    }
}

/// Same seed, same bits, on one thread or two.
#[test]
fn spectral_renders_do_not_depend_on_the_thread_count() {
    let o = Overrides {
        width: Some(8),
        bins: Some(20),
        ..spectral()
    };
    let scene = bundled("cbox.xml", &o);
    let on = |threads: usize| crate::common::on_threads(threads, || run(&scene, 8, 11));
    let (a, b) = (on(1), on(2));
    assert_eq!(a.accum.x1, b.accum.x1);
    assert_eq!(a.accum.x2, b.accum.x2);
    assert_eq!(a.steady, b.steady);
    let rgb = run(
        &bundled(
            "cbox.xml",
            &Overrides {
                mode: RenderMode::Rgb,
                ..o.clone()
            },
        ),
        8,
        11,
    );
    assert_ne!(a.accum.x1, rgb.accum.x1, "the paths carried wavelengths");
}

/// What the mode does not model is refused at load, naming it.
#[test]
fn the_spectral_mode_refuses_what_it_does_not_model() {
    for (name, says) in [
        ("cbox_fog.xml", "participating media"),
        ("cbox_principled.xml", "'principled' BSDF"),
        ("nlos_T.xml", "NLOS captures"),
    ] {
        let e = bundled_error(name, &spectral());
        assert!(e.contains(says), "{name}: {e}");
        assert!(Scene::load(&bundled_path(name), &Overrides::default()).is_ok());
    }
}

/// The binary: a spectral bundle (signed samples) goes through denoise, export, frames
/// and info; merging it with an RGB bundle, and Box-Cox with --mode spectral, are one
/// clear error each, with nothing written.
#[test]
fn a_spectral_bundle_goes_through_every_command_and_modes_do_not_mix() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).display().to_string();
    let scene = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cbox_showcase.xml");
    let scene = scene.display().to_string();
    let small = ["--width", "12", "--spp", "8", "--bins", "60"];
    let render = |out: &str, mode: &str, seed: &str| {
        let mut a = vec![
            "render", &scene, "--out", out, "--mode", mode, "--seed", seed,
        ];
        a.extend(small);
        tstat(&a)
    };
    let r = render(&p("s.tstats"), "spectral", "1");
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let m: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("s.tstats/manifest.json")).unwrap())
            .unwrap();
    assert_eq!(m["mode"], "spectral");
    // The showcase's sRGB samples include negative ones at 8 spp on this film.
    let x1: ndarray::Array4<f64> =
        ndarray_npy::read_npy(dir.path().join("s.tstats/x1.npy")).unwrap();
    assert!(
        x1.iter().any(|&v| v < 0.0),
        "no negative sum: the test would not test it"
    );
    for args in [
        vec!["denoise", &p("s.tstats")[..], "--out", &p("d.npy")[..]],
        vec!["export", &p("s.tstats")[..], "--out", &p("e.npy")[..]],
        vec!["frames", &p("s.tstats")[..], "--out", &p("fr")[..]],
        vec!["info", &p("s.tstats")[..]],
    ] {
        let o = tstat(&args);
        assert!(
            o.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
    let e: ndarray::Array4<f32> = ndarray_npy::read_npy(dir.path().join("e.npy")).unwrap();
    assert!(e.iter().any(|&v| v < 0.0));
    assert!(render(&p("r.tstats"), "rgb", "2").status.success());
    let o = tstat(&[
        "merge",
        &p("s.tstats"),
        &p("r.tstats"),
        "--out",
        &p("m.tstats"),
    ]);
    assert!(!o.status.success());
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("mode differs"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(!dir.path().join("m.tstats").exists());
    let mut a = vec![
        "render",
        &scene[..],
        "--out",
        "bc.tstats",
        "--mode",
        "spectral",
        "--transform",
        "box-cox:0.5",
    ];
    let bc = p("bc.tstats");
    a[3] = &bc;
    let o = tstat(&a);
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("Box-Cox is undefined below zero"));
    assert!(!dir.path().join("bc.tstats").exists());
}
