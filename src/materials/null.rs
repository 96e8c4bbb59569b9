//! `null`: a surface that does not interact with light (Mitsuba 3's `null` BSDF, used
//! for the boundaries of participating media): a path continues straight through it.
//! As in Mitsuba's `path` integrator, the crossing is a vertex of the path (it counts
//! towards `max_depth`) and shadow rays are blocked by the surface; only the volumetric
//! integrator treats null surfaces as transparent to shadow rays. No parameters.

use super::{BsdfFlags, BsdfModel, BsdfSample};
use crate::math::Rgb;
use glam::Vec3;

#[derive(Clone, Debug, PartialEq)]
pub struct Null;

impl BsdfModel for Null {
    #[inline(always)]
    fn flags(&self, _wo: Vec3) -> BsdfFlags {
        BsdfFlags::DELTA_TRANSMISSION
    }

    #[inline(always)]
    fn eval(&self, _wo: Vec3, _wi: Vec3) -> Rgb {
        Rgb::ZERO
    }

    #[inline(always)]
    fn pdf(&self, _wo: Vec3, _wi: Vec3) -> f32 {
        0.0
    }

    #[inline(always)]
    fn sample(&self, wo: Vec3, _u1: f32, _u2: [f32; 2]) -> Option<BsdfSample> {
        Some(BsdfSample {
            wi: -wo,
            weight: Rgb::ONE,
            pdf: 1.0,
            lobe: BsdfFlags::DELTA_TRANSMISSION,
            eta: 1.0,
        })
    }

    /// Everything passes: 1.
    fn albedo(&self, _wo: Vec3) -> Rgb {
        Rgb::ONE
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn passes_straight_through_with_weight_one() {
        for wo in [Vec3::Z, Vec3::new(0.6, 0.0, -0.8), Vec3::new(0.0, 1.0, 0.0)] {
            let s = Null.sample(wo, 0.3, [0.1, 0.9]).unwrap();
            assert_eq!((s.wi, s.weight, s.eta), (-wo, Rgb::ONE, 1.0));
            assert!(s.lobe.is_delta() && !Null.flags(wo).has_non_delta());
            assert_eq!(Null.eval(wo, -wo), Rgb::ZERO);
        }
    }
}
