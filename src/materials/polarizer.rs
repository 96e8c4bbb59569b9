//! `polarizer`: Mitsuba 3's `LinearPolarizer` in the unpolarized RGB variants
//! (`src/bsdfs/polarizer.cpp`): an ideal linear polarizer passes half of unpolarized
//! light, so without polarization state it is a `null`-like surface that passes light
//! straight through with weight 0.5 * transmittance.
//!
//! | parameter | type | default | meaning |
//! |-----------|------|---------|---------|
//! | theta | float or texture | 0 | the transmission axis angle in degrees; no effect without polarization |
//! | transmittance | rgb/float or texture | 1 | scales what passes |
//! | polarizing | boolean | true | false: an absorber of 0.5 * transmittance also in the polarized mode; no effect without polarization |
//!
//! As `null` in Mitsuba's `path` integrator, the crossing is a vertex of the path (it
//! counts towards `max_depth`) and shadow rays are blocked by the surface.
//!
//! The polarized behaviour (`theta`, `polarizing`) is in `mueller.rs`: Mitsuba's axis
//! `(sin theta, cos theta, 0)` of the local frame, projected onto the plane orthogonal
//! to the beam (Korger et al. 2013, a tilted polarizer).

use crate::math::Rgb;

#[derive(Clone, Debug, PartialEq)]
pub struct Polarizer {
    pub transmittance: Rgb,
    /// The axis angle in degrees (used only by the polarized mode).
    pub theta: f32,
    /// Whether it polarizes (used only by the polarized mode).
    pub polarizing: bool,
}

super::pane::straight_through_pane!(Polarizer, |p: &Polarizer| p.transmittance * 0.5);
