//! Wavelength sampling as Mitsuba 3's spectral variants do it (`sample_rgb_spectrum`,
//! `pdf_rgb_spectrum`, `sample_wavelength`, `spectrum_to_srgb`):
//!
//! - one wavelength from `u` by the inverse CDF of the density
//!   `p(l) = 0.003939804229326285 / cosh^2(0.0072 (l - 538))` on [360, 830] nm, which
//!   follows the sum of the sRGB curves (importance sampling of the visible range);
//! - a path carries [`WAVELENGTHS`] of them, from `u` shifted by `k / 3` (mod 1), so
//!   the three are stratified over the range. Mitsuba carries four; tstat carries three
//!   because they ride in the three lanes the RGB path uses for its channels
//!   (`spectral::lift`), so every BSDF, light and texture is the same code in both
//!   modes. The estimator is the same (each wavelength has the density `p`); a path
//!   just holds three samples of the spectrum instead of four;
//! - a path's spectral values (already divided by the density) become one linear
//!   sRGB sample as the mean over its wavelengths of `value * linear_rgb_rec(l)`,
//!   times `CIE_Y_NORMALIZATION`. The statistics of a spectral render are those of
//!   these per-sample RGB values.

use super::cie::{linear_rgb_rec, CIE_MAX, CIE_MIN, CIE_Y_NORMALIZATION};

/// Wavelengths per path.
pub const WAVELENGTHS: usize = 3;

/// One wavelength (nm) from `u` in [0, 1), and its weight `1 / p(l)`.
pub fn sample_rgb_spectrum(u: f32) -> (f32, f32) {
    let u = f64::from(u);
    let l = 538.0 - (0.8569106254698279 - 1.8275019724092267 * u).atanh() * 138.88888888888889;
    let c = (0.0072 * (l - 538.0)).cosh();
    (l as f32, (253.82 * c * c) as f32)
}

/// The density of [`sample_rgb_spectrum`] at `l` nm (0 outside [360, 830]).
pub fn pdf_rgb_spectrum(l: f32) -> f32 {
    if (CIE_MIN..=CIE_MAX).contains(&l) {
        let c = (0.0072 * (f64::from(l) - 538.0)).cosh();
        (0.003939804229326285 / (c * c)) as f32
    } else {
        0.0
    }
}

/// A path's wavelengths and their weights from one uniform `u`: `u + k / 3 (mod 1)`.
pub fn sample_wavelengths(u: f32) -> ([f32; WAVELENGTHS], [f32; WAVELENGTHS]) {
    let mut l = [0.0; WAVELENGTHS];
    let mut w = [0.0; WAVELENGTHS];
    for k in 0..WAVELENGTHS {
        let s = u + k as f32 / WAVELENGTHS as f32;
        let s = if s >= 1.0 { s - 1.0 } else { s };
        (l[k], w[k]) = sample_rgb_spectrum(s);
    }
    (l, w)
}

/// One linear sRGB sample from a path's spectral `values` (weights included) at its
/// `wavelengths`.
pub fn spectrum_to_srgb(values: [f32; WAVELENGTHS], wavelengths: [f32; WAVELENGTHS]) -> [f32; 3] {
    let mut rgb = [0.0f64; 3];
    for (v, l) in values.iter().zip(wavelengths) {
        let r = linear_rgb_rec(l);
        for c in 0..3 {
            rgb[c] += f64::from(r[c]) * f64::from(*v);
        }
    }
    rgb.map(|c| (c / WAVELENGTHS as f64 * CIE_Y_NORMALIZATION) as f32)
}
