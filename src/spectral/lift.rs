//! A path's wavelengths, and the scene's RGB values as spectra at them, by Mitsuba 3's
//! rules for spectral variants (`Properties::get_texture`, the `srgb` and `d65`
//! plugins):
//!
//! - a reflectance (any colour in [0, 1]) is the smooth spectrum of Jakob and Hanika
//!   (`rgb2spec::fetch`, then `eval` at each wavelength); a grey is exactly flat;
//! - an emitted colour `c` (radiance, intensity, irradiance; texels of emitting
//!   textures and environment maps) is `2 max(c) D65(l) s(l)`, where `s` is the smooth
//!   spectrum of `c / (2 max(c))` (the `d65` plugin: a colour whose largest component
//!   is 1/2 has a smooth spectrum), so that white light is D65, sRGB's white;
//! - an optical constant (`eta`, `k`) in [0, 1] is lifted as a reflectance (as
//!   Mitsuba). Above 1 it is scaled as an emitted colour without D65 (a grey stays
//!   exactly flat at any value): that is how tstat lifts the named conductors, which it
//!   keeps as Mitsuba's RGB values (Mitsuba's spectral variants read measured spectra).
//!   A scene's own `<rgb>` above 1 never gets here: Mitsuba clamps it to [0, 1], and
//!   so does the loader in the spectral mode (`scene::bsdfs`).
//!
//! A path carries [`WAVELENGTHS`] wavelengths in the three lanes the RGB path uses
//! for its channels, so every model computes with them as it computes with RGB.
//! Its contribution becomes one linear sRGB sample with the weights `1 / p(l)` of the
//! wavelengths' sampling ([`Wavelengths::to_srgb`]).

use super::cie::{lookup, D65_ROWS};
use super::rgb2spec::{eval, fetch};
use super::wavelengths::{sample_wavelengths, spectrum_to_srgb, WAVELENGTHS};
use glam::Vec3;

/// A path's wavelengths (nm) and the weights `1 / p(l)` of their sampling.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Wavelengths {
    pub lambda: [f32; WAVELENGTHS],
    pub weight: [f32; WAVELENGTHS],
}

impl Wavelengths {
    /// The wavelengths of one path from one uniform number (`sample_wavelengths`).
    pub fn sample(u: f32) -> Self {
        let (lambda, weight) = sample_wavelengths(u);
        Wavelengths { lambda, weight }
    }

    /// The smooth spectrum of a reflectance-like colour (clamped to [0, 1]).
    #[inline]
    pub fn reflectance(&self, rgb: Vec3) -> Vec3 {
        let c = fetch(rgb.to_array());
        Vec3::from_array(self.lambda.map(|l| eval(c, l)))
    }

    /// An optical constant: as a reflectance within [0, 1], else scaled.
    #[inline]
    pub fn unbounded(&self, rgb: Vec3) -> Vec3 {
        let rgb = rgb.max(Vec3::ZERO);
        if rgb.max_element() <= 1.0 {
            return self.reflectance(rgb);
        }
        let factor = 2.0 * rgb.max_element();
        self.reflectance(rgb / factor) * factor
    }

    /// An emitted colour: `2 max(c) D65(l) s(l)` (module docs).
    #[inline]
    pub fn illuminant(&self, rgb: Vec3) -> Vec3 {
        let rgb = rgb.max(Vec3::ZERO);
        let factor = 2.0 * rgb.max_element();
        if factor.is_nan() || factor <= 0.0 {
            return Vec3::ZERO;
        }
        let c = fetch((rgb / factor).to_array());
        Vec3::from_array(
            self.lambda
                .map(|l| factor * lookup(&D65_ROWS, l)[0] * eval(c, l)),
        )
    }

    /// D65 (normalised as Mitsuba) at the wavelengths.
    #[inline]
    pub fn d65(&self) -> Vec3 {
        Vec3::from_array(self.lambda.map(|l| lookup(&D65_ROWS, l)[0]))
    }

    /// A path's spectral contribution `v` (values at the wavelengths) as one linear
    /// sRGB sample: weighted by `1 / p(l)` and integrated against the sRGB curves.
    #[inline]
    pub fn to_srgb(&self, v: Vec3) -> Vec3 {
        let values = std::array::from_fn(|k| v[k] * self.weight[k]);
        Vec3::from_array(spectrum_to_srgb(values, self.lambda))
    }
}
