//! Wavelength sampling and the per-sample spectral-to-sRGB conversion
//! (src/spectral/wavelengths.rs) against closed forms and independent quadrature.

use tstat::scene::spectrum::{list_to_srgb, uniform_to_srgb, SpectrumUse};
use tstat::spectral::cie::{linear_rgb_rec, CIE_Y_NORMALIZATION};
use tstat::spectral::wavelengths::{
    pdf_rgb_spectrum, sample_rgb_spectrum, sample_wavelengths, spectrum_to_srgb, WAVELENGTHS,
};

/// The density's CDF on [360, l] in closed form: `c (tanh(a (l - 538)) - tanh(a (360 -
/// 538))) / a`, with c = 0.003939804229326285 and a = 0.0072.
fn cdf(l: f64) -> f64 {
    let a = 0.0072;
    0.003939804229326285 * (((l - 538.0) * a).tanh() - ((360.0 - 538.0) * a).tanh()) / a
}

#[test]
fn the_wavelength_density_is_normalised_and_inverted_exactly() {
    assert!((cdf(830.0) - 1.0).abs() < 1e-4, "{}", cdf(830.0));
    // Quadrature of the density itself.
    let n = 47_000;
    let h = 470.0 / n as f64;
    let total: f64 = (0..n)
        .map(|i| f64::from(pdf_rgb_spectrum((360.0 + (i as f64 + 0.5) * h) as f32)) * h)
        .sum();
    assert!((total - 1.0).abs() < 1e-4, "{total}");
    assert_eq!(pdf_rgb_spectrum(359.0), 0.0);
    assert_eq!(pdf_rgb_spectrum(831.0), 0.0);
    // The sample is the inverse CDF of u, and its weight is 1 / p.
    for k in 0..=100 {
        let u = (k as f32 / 100.0).min(0.999_999);
        let (l, w) = sample_rgb_spectrum(u);
        assert!((360.0 - 0.05..=830.05).contains(&l), "{u}: {l}");
        assert!(
            (cdf(f64::from(l)) - f64::from(u)).abs() < 2e-4,
            "{u}: cdf {}",
            cdf(f64::from(l))
        );
        let p = pdf_rgb_spectrum(l.clamp(360.0, 830.0));
        assert!((w * p - 1.0).abs() < 2e-4, "{u}: w p = {}", w * p);
    }
    // Three wavelengths per path, a third of the range apart in u.
    let (l, _) = sample_wavelengths(0.9);
    let (a, _) = sample_rgb_spectrum(0.9);
    let (b, _) = sample_rgb_spectrum(0.9 + 1.0 / 3.0 - 1.0);
    assert_eq!(l.len(), WAVELENGTHS);
    assert!((l[0] - a).abs() < 1e-3 && (l[1] - b).abs() < 1e-2, "{l:?}");
}

/// `spectrum_to_srgb` averaged over stratified path samples of the spectrum `s`.
fn estimate(s: impl Fn(f32) -> f32, paths: usize) -> [f64; 3] {
    let mut acc = [0.0f64; 3];
    for i in 0..paths {
        let (l, w) = sample_wavelengths((i as f32 + 0.5) / paths as f32);
        let values = std::array::from_fn(|k| s(l[k]) * w[k]);
        let rgb = spectrum_to_srgb(values, l);
        for c in 0..3 {
            acc[c] += f64::from(rgb[c]) / paths as f64;
        }
    }
    acc
}

#[test]
fn a_narrow_band_emitter_gives_the_integral_of_its_colour_matching() {
    // A box spectrum of 1 on [550, 560] nm: the sampled estimate must equal the
    // integral of linear_rgb_rec over the band (midpoint rule, 0.001 nm steps).
    let band = |l: f32| {
        if (550.0..560.0).contains(&l) {
            1.0
        } else {
            0.0
        }
    };
    let got = estimate(band, 200_000);
    let mut want = [0.0f64; 3];
    let n = 10_000;
    for i in 0..n {
        let l = 550.0 + (i as f64 + 0.5) * 10.0 / n as f64;
        let r = linear_rgb_rec(l as f32);
        for c in 0..3 {
            want[c] += f64::from(r[c]) * 10.0 / n as f64 * CIE_Y_NORMALIZATION;
        }
    }
    for c in 0..3 {
        assert!(
            (got[c] - want[c]).abs() <= 2e-3 * want[c].abs().max(0.02),
            "channel {c}: {} vs {}",
            got[c],
            want[c]
        );
    }
    // Green dominates a 555 nm line; red is positive, blue negative (outside sRGB).
    assert!(
        want[1] > want[0] && want[0] > 0.0 && want[2] < 0.0,
        "{want:?}"
    );
}

#[test]
fn spectra_render_to_the_colour_the_scene_reader_gives_them() {
    // A constant emission of 1: the scene reader's RGB (Mitsuba's conversion).
    let got = estimate(|_| 1.0, 50_000);
    let want = uniform_to_srgb(1.0, SpectrumUse::Emission);
    for c in 0..3 {
        assert!(
            (got[c] - f64::from(want[c])).abs() < 3e-3,
            "{c}: {got:?} vs {want:?}"
        );
    }
    // A sloped emission spectrum: the same RGB as `list_to_srgb` (1000-step quadrature).
    let (wl, vals) = ([400.0, 700.0], [0.2, 1.4]);
    let (want, _) = list_to_srgb(&wl, &vals, SpectrumUse::Emission);
    let slope = |l: f32| {
        if (400.0..=700.0).contains(&l) {
            0.2 + (l - 400.0) / 300.0 * 1.2
        } else {
            0.0
        }
    };
    let got = estimate(slope, 50_000);
    for c in 0..3 {
        assert!(
            (got[c] - f64::from(want[c])).abs() < 3e-3 * f64::from(want[c].abs()).max(0.1),
            "{c}: {got:?} vs {want:?}"
        );
    }
}
