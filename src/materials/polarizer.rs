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

use super::{BsdfFlags, BsdfModel, BsdfSample};
use crate::math::Rgb;
use glam::Vec3;

#[derive(Clone, Debug, PartialEq)]
pub struct Polarizer {
    pub transmittance: Rgb,
    /// The axis angle in degrees (used only by the polarized mode).
    pub theta: f32,
    /// Whether it polarizes (used only by the polarized mode).
    pub polarizing: bool,
}

impl BsdfModel for Polarizer {
    #[inline]
    fn flags(&self, _wo: Vec3) -> BsdfFlags {
        BsdfFlags::DELTA_TRANSMISSION
    }

    #[inline]
    fn eval(&self, _wo: Vec3, _wi: Vec3) -> Rgb {
        Rgb::ZERO
    }

    #[inline]
    fn pdf(&self, _wo: Vec3, _wi: Vec3) -> f32 {
        0.0
    }

    #[inline]
    fn sample(&self, wo: Vec3, _u1: f32, _u2: [f32; 2]) -> Option<BsdfSample> {
        Some(BsdfSample {
            wi: -wo,
            weight: self.transmittance * 0.5,
            pdf: 1.0,
            lobe: BsdfFlags::DELTA_TRANSMISSION,
            eta: 1.0,
        })
    }

    fn albedo(&self, _wo: Vec3) -> Rgb {
        self.transmittance * 0.5
    }
}
