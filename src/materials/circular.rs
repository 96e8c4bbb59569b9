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

use super::{BsdfFlags, BsdfModel, BsdfSample};
use crate::math::Rgb;
use glam::Vec3;

#[derive(Clone, Debug, PartialEq)]
pub struct Circular {
    pub transmittance: Rgb,
    /// A left circular polarizer (used only by the polarized mode).
    pub left_handed: bool,
}

impl BsdfModel for Circular {
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
