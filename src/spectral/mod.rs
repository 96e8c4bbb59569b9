//! Spectral quantities for the spectral render mode (`--mode spectral`,
//! docs/spectral.md): the CIE tables (`cie`), Mitsuba 3's wavelength sampling and
//! per-sample conversion to linear sRGB (`wavelengths`), Jakob and Hanika's
//! RGB-to-spectrum model (`rgb2spec`, its table computed by `build.rs` with
//! `rgb2spec_fit`), spectra as a scene gives them (`curve`), and a
//! path's wavelengths with the rules that lift a scene's RGB to them (`lift`). RGB
//! renders read scenes' spectra as RGB through `cie` and use nothing else here.

pub mod cie;
pub mod curve;
pub mod lift;
/// Jakob & Hanika's RGB-to-spectrum model for sRGB, as Mitsuba 3's; table computed lazily.
pub mod rgb2spec;
mod rgb2spec_fit;
pub mod wavelengths;
