//! `polarizer`: Mitsuba 3's `LinearPolarizer` in the unpolarized RGB variants
//! (`src/bsdfs/polarizer.cpp`): an ideal linear polarizer passes half of unpolarized
//! light, so without polarization state it is a `null`-like surface that passes light
//! straight through with weight 0.5 * transmittance.
//!
//! | parameter | type | default | meaning |
//! |-----------|------|---------|---------|
//! | theta | float or texture | 0 | the transmission axis angle in degrees: read, no effect without polarization |
//! | transmittance | rgb/float or texture | 1 | scales what passes |
//! | polarizing | boolean | true | no effect without polarization (both give 0.5 * transmittance) |
//!
//! As `null` in Mitsuba's `path` integrator, the crossing is a vertex of the path (it
//! counts towards `max_depth`) and shadow rays are blocked by the surface.

use super::{BsdfFlags, BsdfModel, BsdfSample};
use crate::math::Rgb;
use glam::Vec3;

#[derive(Clone, Debug, PartialEq)]
pub struct Polarizer {
    pub transmittance: Rgb,
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
