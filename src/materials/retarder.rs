//! `retarder`: Mitsuba 3's `LinearRetarder` (`src/bsdfs/retarder.cpp`), a wave plate: a
//! pane that light passes straight through, delaying the field component along one
//! axis against the other. Without polarization (Mitsuba's RGB variants) it passes
//! `transmittance` unchanged, a `null`-like surface with a colour.
//!
//! | parameter | type | default | meaning |
//! |-----------|------|---------|---------|
//! | theta | float or texture | 0 | the fast axis angle in degrees; no effect without polarization |
//! | delta | float or texture | 90 | the retardance in degrees (90: quarter-wave, 180: half-wave); no effect without polarization |
//! | transmittance | rgb/float or texture | 1 | scales what passes |
//!
//! The polarized behaviour is in `mueller.rs`. As `null` in Mitsuba's `path`
//! integrator, the crossing is a vertex of the path (it counts towards `max_depth`)
//! and shadow rays are blocked by the surface.

use crate::math::Rgb;

#[derive(Clone, Debug, PartialEq)]
pub struct Retarder {
    pub transmittance: Rgb,
    /// The fast axis angle in degrees (used only by the polarized mode).
    pub theta: f32,
    /// The retardance in degrees (used only by the polarized mode).
    pub delta: f32,
}

super::pane::straight_through_pane!(Retarder, |r: &Retarder| r.transmittance);
