//! `circular`: Mitsuba 3's `CircularPolarizer` (`src/bsdfs/circular.cpp`), an ideal
//! right (default) or left circular polarizer. Without polarization (Mitsuba's RGB
//! variants) it passes half of unpolarized light straight through: a `null`-like
//! surface with weight 0.5 * transmittance, as `polarizer`.
//!
//! | parameter | type | default | meaning |
//! |-----------|------|---------|---------|
//! | transmittance | rgb/float or texture | 1 | scales what passes |
//! | left_handed | boolean | false | a left circular polarizer; no effect without polarization |
//!
//! The polarized behaviour is in `mueller.rs`. As `null` in Mitsuba's `path`
//! integrator, the crossing is a vertex of the path (it counts towards `max_depth`)
//! and shadow rays are blocked by the surface.

use crate::math::Rgb;

#[derive(Clone, Debug, PartialEq)]
pub struct Circular {
    pub transmittance: Rgb,
    /// A left circular polarizer (used only by the polarized mode).
    pub left_handed: bool,
}

super::pane::straight_through_pane!(Circular, |c: &Circular| c.transmittance * 0.5);
