//! Spectral quantities: the CIE tables (`cie`) and the wavelength sampling and
//! per-sample conversion to linear sRGB of Mitsuba 3's spectral variants
//! (`wavelengths`). Scenes' spectra are read as RGB through `cie` today; the spectral
//! render mode of issue 45 (`--mode spectral`) is not offered yet, and nothing in the
//! renderer samples wavelengths.

pub mod cie;
pub mod curve;
pub mod lift;
/// Jakob & Hanika's RGB-to-spectrum model for sRGB, as Mitsuba 3's; table computed lazily.
pub mod rgb2spec;
pub mod wavelengths;
