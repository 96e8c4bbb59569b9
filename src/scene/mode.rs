//! The render mode: what a path carries and what a bundle's channels are (issue 45).
//! `rgb` (the default) traces the three RGB channels; `spectral` traces three sampled
//! wavelengths per path and writes each path's linear sRGB (`spectral::lift`), so a
//! spectral bundle has the same three channels as an RGB one. `mono` traces one band,
//! the luminance of every colour (Mitsuba's `*_mono` variants); `mono_polarized`
//! traces that band with a Mueller matrix along the path and writes the four Stokes
//! components S0..S3 in the sensor's frame (`render/polarized.rs`);
//! `spectral_polarized` traces three wavelengths each with its own Mueller matrix and
//! writes the four Stokes components of each sRGB channel (12 channels, RGB-major:
//! `S0.R, S1.R, S2.R, S3.R, S0.G, ..`, so a volume reshapes to (H, W, T, 3, 4)).
//! [`Scene::set_mode`] refuses what a mode does not model, with one message.

use super::spectrum::{blackbody_to_srgb, list_to_srgb, uniform_to_srgb, SpectrumUse};
use super::Scene;
use crate::spectral::curve::Curve;
use glam::Vec3;

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RenderMode {
    #[default]
    Rgb,
    Spectral,
    Mono,
    #[serde(rename = "mono_polarized")]
    MonoPolarized,
    #[serde(rename = "spectral_polarized")]
    SpectralPolarized,
}

impl RenderMode {
    /// The name in the manifest and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            RenderMode::Rgb => "rgb",
            RenderMode::Spectral => "spectral",
            RenderMode::Mono => "mono",
            RenderMode::MonoPolarized => "mono_polarized",
            RenderMode::SpectralPolarized => "spectral_polarized",
        }
    }

    pub fn from_name(s: &str) -> Option<Self> {
        [
            RenderMode::Rgb,
            RenderMode::Spectral,
            RenderMode::Mono,
            RenderMode::MonoPolarized,
            RenderMode::SpectralPolarized,
        ]
        .into_iter()
        .find(|m| m.name() == s)
    }

    /// The names of the channels of a film in this mode (the manifest's `channels`).
    pub fn channel_names(self) -> &'static [&'static str] {
        match self {
            RenderMode::Rgb | RenderMode::Spectral => &["R", "G", "B"],
            RenderMode::Mono => &["Y"],
            RenderMode::MonoPolarized => &["S0", "S1", "S2", "S3"],
            RenderMode::SpectralPolarized => &[
                "S0.R", "S1.R", "S2.R", "S3.R", "S0.G", "S1.G", "S2.G", "S3.G", "S0.B", "S1.B",
                "S2.B", "S3.B",
            ],
        }
    }

    /// Channels C of a film in this mode.
    pub fn channels(self) -> usize {
        self.channel_names().len()
    }

    /// Whether a path carries one band: the luminance of every colour.
    pub fn is_mono(self) -> bool {
        matches!(self, RenderMode::Mono | RenderMode::MonoPolarized)
    }

    /// Whether a path carries sampled wavelengths (`spectral`, `spectral_polarized`).
    pub fn is_spectral(self) -> bool {
        matches!(self, RenderMode::Spectral | RenderMode::SpectralPolarized)
    }

    /// Whether a path carries Mueller matrices and the film Stokes vectors.
    pub fn is_polarized(self) -> bool {
        matches!(
            self,
            RenderMode::MonoPolarized | RenderMode::SpectralPolarized
        )
    }

    /// Whether a sample can be negative: a spectral path's sRGB (the matching curves
    /// are negative at some wavelengths) and the Stokes components S1..S3.
    pub fn signed(self) -> bool {
        self.is_spectral() || self.is_polarized()
    }
}

impl Scene {
    /// Renders the scene in `mode`. The spectral mode covers camera renders of
    /// surfaces lit by every emitter tstat reads, with every BSDF but the principled
    /// ones; it refuses NLOS captures, participating media and `principled` /
    /// `principledthin` (what it would need for them is in docs/spectral.md).
    pub fn set_mode(&mut self, mode: RenderMode) -> Result<(), String> {
        if mode.is_mono() {
            let name = mode.name();
            if self.nlos.is_some() {
                return Err(format!("--mode {name} renders camera films; NLOS captures (transient_nlos_path) are rendered in rgb"));
            }
            if !self.media.is_empty() {
                return Err(format!("--mode {name} does not render participating media; this scene has media (render it with --mode rgb)"));
            }
        }
        if mode.is_spectral() {
            let name = mode.name();
            if self.nlos.is_some() {
                return Err(format!("--mode {name} renders camera films; NLOS captures (transient_nlos_path) are rendered in rgb"));
            }
            if !self.media.is_empty() {
                return Err(format!("--mode {name} does not render participating media yet; this scene has media (render it with --mode rgb)"));
            }
            for m in &self.bsdfs {
                if let Err(bsdf) = m.bsdf.spectral_support() {
                    return Err(format!("--mode {name} does not render the '{bsdf}' BSDF (it tints by the luminance of its base colour); render this scene with --mode rgb"));
                }
            }
        }
        self.mode = mode;
        self.film.channels = mode.channels();
        Ok(())
    }
}

/// An emitter's colour given as a spectrum: the spectrum, and the largest channel of
/// the RGB it reads as in RGB (`scene::spectrum`), by which the emitter's RGB values
/// (the colour times its spatial and angular factors) are divided to recover those
/// factors.
#[derive(Clone, Debug, PartialEq)]
pub struct EmitterSpectrum {
    pub curve: Curve,
    pub rgb_max: f32,
}

impl EmitterSpectrum {
    pub fn new(curve: Curve) -> Self {
        let rgb = match &curve {
            Curve::Uniform(v) => uniform_to_srgb(f64::from(*v), SpectrumUse::Emission),
            Curve::Irregular {
                wavelengths,
                values,
            } => {
                let w: Vec<f64> = wavelengths.iter().map(|&x| f64::from(x)).collect();
                let v: Vec<f64> = values.iter().map(|&x| f64::from(x)).collect();
                list_to_srgb(&w, &v, SpectrumUse::Emission).0
            }
            // The colour the loader gave the emitter (`Props::emission`).
            Curve::Blackbody { temperature, range } => {
                blackbody_to_srgb(*temperature, *range).unwrap_or([0.0; 3])
            }
        };
        EmitterSpectrum {
            curve,
            rgb_max: rgb.into_iter().fold(0.0, f32::max),
        }
    }

    /// The spectrum at `lambda` of an emitted RGB value `rgb` of this emitter.
    #[inline]
    pub fn at(&self, rgb: Vec3, lambda: [f32; 3]) -> Vec3 {
        if self.rgb_max.is_nan() || self.rgb_max <= 0.0 {
            return Vec3::ZERO;
        }
        let scale = rgb.max_element() / self.rgb_max;
        Vec3::from_array(lambda.map(|l| scale * self.curve.eval(l)))
    }
}
