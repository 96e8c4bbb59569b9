//! Spectra given as `wavelength:value` lists (`<spectrum value="400:0.1, 500:0.5"/>`)
//! and uniform spectra, converted to linear sRGB as Mitsuba 3's RGB variants do
//! (`spectrum_list_to_srgb` and `Properties::get_texture`):
//!
//! - a list is integrated against the CIE 1931 2-degree colour matching functions on
//!   1000 evenly spaced wavelengths over [360, 830] nm (zero outside the listed range,
//!   linear between listed points), for reflectances weighted by the D65 illuminant,
//!   normalised by `CIE_Y_NORMALIZATION`, then taken from XYZ to sRGB; reflectances
//!   are clamped to [0, 1], emission only to >= 0;
//! - a uniform spectrum is a grey for reflectances, and `value * xyz_to_srgb(1, 1, 1)`
//!   (slightly purple: D65 is sRGB's white, not the equal-energy spectrum) for emission.
//!
//! The tables (CIE 1931 2-degree observer, D65) are in `spectral::cie`; `tests` check
//! the conversion against values computed by Mitsuba 3.9.1.

// The tests keep the digits of Mitsuba's f32 results (printed in f64).
#![allow(clippy::excessive_precision)]

use crate::spectral::cie::{
    lookup, xyz_to_srgb, CIE1931_XYZ, CIE_MAX, CIE_MIN, CIE_Y_NORMALIZATION, D65_ROWS,
};
use crate::spectral::curve::blackbody;

/// Whether the spectrum is emission (radiance, intensity) or a reflectance-like value.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpectrumUse {
    Reflectance,
    Emission,
    /// Optical constants (`eta`, `k`, `int_ior`, `ext_ior`: Mitsuba 3.9.1's
    /// `is_unbounded_spectrum`): D65-weighted as reflectances, never clamped.
    Unbounded,
}

/// The parameter names Mitsuba 3.9.1 converts as unbounded spectra.
pub const UNBOUNDED_SPECTRA: [&str; 4] = ["eta", "k", "int_ior", "ext_ior"];

/// Mitsuba's RGB for a `wavelength:value` list (wavelengths increasing, in nm).
/// Returns the colour and whether it was clamped (out of gamut).
pub fn list_to_srgb(wavelengths: &[f64], values: &[f64], usage: SpectrumUse) -> ([f32; 3], bool) {
    let steps = 1000;
    let (first, last) = (
        wavelengths[0] as f32,
        wavelengths[wavelengths.len() - 1] as f32,
    );
    let mut xyz = [0.0f32; 3];
    for i in 0..steps {
        let w = CIE_MIN + (i as f32 / (steps - 1) as f32) * (CIE_MAX - CIE_MIN);
        if w < first || w > last {
            continue;
        }
        // The last listed wavelength <= w, and the next one.
        let idx = wavelengths
            .partition_point(|&x| x as f32 <= w)
            .saturating_sub(1)
            .min(wavelengths.len().saturating_sub(2));
        let (w0, w1) = (
            wavelengths[idx] as f32,
            wavelengths[(idx + 1).min(wavelengths.len() - 1)] as f32,
        );
        let (v0, v1) = (
            values[idx] as f32,
            values[(idx + 1).min(values.len() - 1)] as f32,
        );
        let v = if w1 == w0 {
            v0
        } else {
            ((w - w1) * v0 + (w0 - w) * v1) / (w0 - w1)
        };
        let cmf = lookup(&CIE1931_XYZ, w);
        let d65 = match usage {
            SpectrumUse::Reflectance | SpectrumUse::Unbounded => lookup(&D65_ROWS, w)[0],
            SpectrumUse::Emission => 1.0,
        };
        for c in 0..3 {
            xyz[c] += cmf[c] * v * d65;
        }
    }
    let scale = ((CIE_MAX - CIE_MIN) as f64 * CIE_Y_NORMALIZATION / steps as f64) as f32;
    let rgb = xyz_to_srgb(xyz.map(|v| v * scale));
    match usage {
        SpectrumUse::Reflectance => {
            let clamped = rgb.map(|v| v.clamp(0.0, 1.0));
            (clamped, clamped != rgb)
        }
        SpectrumUse::Emission => {
            let clamped = rgb.map(|v| v.max(0.0));
            (clamped, clamped != rgb)
        }
        SpectrumUse::Unbounded => (rgb, false),
    }
}

/// The linear sRGB of Planck's law at `temperature` kelvin within `range` nm
/// (`spectral::curve::blackbody`), integrated as [`list_to_srgb`] integrates an
/// emission list (1000 wavelengths over [360, 830] nm, no D65, clamped to >= 0).
/// Mitsuba's RGB variants refuse a blackbody; tstat uses this colour only in the
/// spectral mode, where the emitter's RGB stands for the spectrum (G-buffer, the
/// factor `EmitterSpectrum::at` divides by). `Err(lambda)`: Planck's law is not
/// finite in single precision at `lambda` nm (a temperature above about 3e11 K).
pub fn blackbody_to_srgb(temperature: f32, range: [f32; 2]) -> Result<[f32; 3], f32> {
    let steps = 1000;
    let mut xyz = [0.0f32; 3];
    for i in 0..steps {
        let w = CIE_MIN + (i as f32 / (steps - 1) as f32) * (CIE_MAX - CIE_MIN);
        let v = blackbody(w, temperature, range);
        if !v.is_finite() {
            return Err(w);
        }
        let cmf = lookup(&CIE1931_XYZ, w);
        for c in 0..3 {
            xyz[c] += cmf[c] * v;
        }
    }
    // The longest wavelength sampled in the range: where `exp(c1 / (l T)) - 1` is
    // smallest (it rounds to 0 first there).
    let top = range[1].min(CIE_MAX);
    if top >= CIE_MIN && !blackbody(top, temperature, range).is_finite() {
        return Err(top);
    }
    let scale = ((CIE_MAX - CIE_MIN) as f64 * CIE_Y_NORMALIZATION / steps as f64) as f32;
    let rgb = xyz_to_srgb(xyz.map(|v| v * scale)).map(|v| v.max(0.0));
    if rgb.iter().all(|v| v.is_finite()) {
        Ok(rgb)
    } else {
        Err(top)
    }
}

/// Mitsuba's RGB for a uniform spectrum of `value`.
pub fn uniform_to_srgb(value: f64, usage: SpectrumUse) -> [f32; 3] {
    match usage {
        SpectrumUse::Reflectance | SpectrumUse::Unbounded => [value as f32; 3],
        SpectrumUse::Emission => xyz_to_srgb([1.0; 3]).map(|c| c * value as f32),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// (wavelengths, values, reflectance?, Mitsuba 3.9.1's `spectrum_list_to_srgb`).
    #[allow(clippy::type_complexity)]
    const MITSUBA: &[(&[f64], &[f64], bool, [f32; 3])] = &[
        (
            &[460.0, 720.0, 750.0],
            &[0.37, 0.604, 0.626],
            true,
            [0.5086377859115601, 0.47104522585868835, 0.10511239618062973],
        ),
        (
            &[460.0, 720.0, 750.0],
            &[0.37, 0.604, 0.626],
            false,
            [0.6110358238220215, 0.44834429025650024, 0.0832921713590622],
        ),
        (
            &[380.0, 760.0],
            &[0.909, 0.469],
            true,
            [0.6044673919677734, 0.7194894552230835, 0.8373255133628845],
        ),
        (
            &[380.0, 760.0],
            &[0.909, 0.469],
            false,
            [0.73907470703125, 0.6822526454925537, 0.765575110912323],
        ),
        (
            &[500.0, 520.0, 680.0, 720.0, 730.0, 760.0],
            &[0.397, 0.861, 0.232, 0.152, 0.926, 0.39],
            true,
            [0.4618437886238098, 0.7266300320625305, 0.0],
        ),
        (
            &[500.0, 520.0, 680.0, 720.0, 730.0, 760.0],
            &[0.397, 0.861, 0.232, 0.152, 0.926, 0.39],
            false,
            [0.556859016418457, 0.6960034370422363, 0.0],
        ),
        (
            &[420.0, 480.0],
            &[0.758, 0.591],
            true,
            [0.02477293647825718, 0.0, 0.6344238519668579],
        ),
        (
            &[420.0, 480.0],
            &[0.758, 0.591],
            false,
            [0.026764627546072006, 0.0, 0.5822936296463013],
        ),
        (
            &[390.0, 550.0, 680.0, 760.0],
            &[0.719, 0.879, 0.714, 0.921],
            true,
            [0.7835257053375244, 0.8628709316253662, 0.7730600237846375],
        ),
        (
            &[390.0, 550.0, 680.0, 760.0],
            &[0.719, 0.879, 0.714, 0.921],
            false,
            [0.9476572275161743, 0.8203769326210022, 0.7009359002113342],
        ),
        (
            &[440.0, 460.0, 610.0, 660.0, 740.0],
            &[0.036, 0.495, 0.258, 0.672, 0.779],
            true,
            [0.3063836395740509, 0.3836485743522644, 0.26242831349372864],
        ),
        (
            &[440.0, 460.0, 610.0, 660.0, 740.0],
            &[0.036, 0.495, 0.258, 0.672, 0.779],
            false,
            [0.38882970809936523, 0.3621270954608917, 0.22010815143585205],
        ),
    ];

    #[test]
    fn optical_constants_are_d65_weighted_and_never_clamped() {
        // Mitsuba 3.9.1, `mi.traverse` of a conductor with these `<spectrum>`s
        // (docs/scenes/bsdf_blendbsdf.xml's gold): eta and k out of [0, 1] kept.
        let w = [300.0, 400.0, 500.0, 600.0, 700.0, 800.0];
        for (v, want) in [
            (
                [1.8, 1.65, 0.9, 0.2, 0.16, 0.18],
                [0.0452341, 0.585709, 1.33692],
            ),
            (
                [1.92, 1.95, 1.95, 2.97, 3.8, 5.12],
                [3.38869, 2.34904, 1.87516],
            ),
        ] {
            let (got, clamped) = list_to_srgb(&w, &v, SpectrumUse::Unbounded);
            assert!(!clamped);
            for c in 0..3 {
                assert!(
                    (got[c] - want[c]).abs() <= 2e-5 * want[c].abs().max(1.0),
                    "{got:?} vs {want:?}"
                );
            }
            // As a reflectance the same list is clamped (Mitsuba's diffuse does so).
            let (r, clamped) = list_to_srgb(&w, &v, SpectrumUse::Reflectance);
            assert!(clamped && r.iter().all(|&x| (0.0..=1.0).contains(&x)));
        }
    }

    #[test]
    fn lists_convert_as_mitsuba_does() {
        for (w, v, reflectance, want) in MITSUBA {
            let usage = if *reflectance {
                SpectrumUse::Reflectance
            } else {
                SpectrumUse::Emission
            };
            let (got, _) = list_to_srgb(w, v, usage);
            for c in 0..3 {
                assert!(
                    (got[c] - want[c]).abs() <= 2e-6 + 2e-5 * want[c].abs(),
                    "{w:?} {v:?}: {got:?} vs {want:?}"
                );
            }
        }
    }

    #[test]
    fn a_flat_reflectance_is_grey_and_uniform_emission_is_mitsubas_purple() {
        // 1 everywhere under D65 is sRGB white (to the tables' precision).
        let (white, _) = list_to_srgb(&[360.0, 830.0], &[1.0, 1.0], SpectrumUse::Reflectance);
        for c in white {
            assert!((c - 1.0).abs() < 0.01, "{white:?}");
        }
        let p = uniform_to_srgb(2.0, SpectrumUse::Emission);
        let want = [1.20479, 0.948291, 0.908916].map(|v| 2.0 * v);
        for c in 0..3 {
            assert!((p[c] - want[c]).abs() < 1e-5, "{p:?}");
        }
        assert_eq!(uniform_to_srgb(0.3, SpectrumUse::Reflectance), [0.3; 3]);
    }
}
