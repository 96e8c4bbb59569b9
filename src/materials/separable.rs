//! `Separable`: a material that re-emits after a delay (SPEC section 6):
//! f(x, wo, wi, dt) = f_static(x, wo, wi) p(dt). Directions come from the nested BSDF,
//! the delay from the temporal profile, independently.
//!
//! | parameter | type | default | meaning |
//! |-----------|------|---------|---------|
//! | (nested) | bsdf | required | f_static |
//! | (nested) | `<TemporalProfile type=... name="tp">` | required | p(dt), see `temporal_profile.rs`; each parameter a float or a single-channel texture |
//!
//! As a [`BsdfModel`] it is its nested BSDF (the delay does not change directions,
//! weights or pdfs); the integrator asks [`Separable::sample_delay`] at every vertex on
//! it: once for next-event estimation and once for the continuation, each adding its
//! delay to the optical path length of what it carries.

use super::temporal_profile::TemporalProfile;
use super::{Bsdf, BsdfFlags, BsdfModel, BsdfSample};
use crate::math::Rgb;
use glam::Vec3;

#[derive(Clone, Debug, PartialEq)]
pub struct Separable {
    pub inner: Box<Bsdf>,
    pub profile: TemporalProfile,
}

impl Separable {
    /// A delay from one uniform number. Parameters set by textures are kept in the
    /// profile's domain here ([`TemporalProfile::clamped`]).
    #[inline]
    pub fn sample_delay(&self, u: f32) -> f32 {
        self.profile.clamped().sample(u)
    }
}

impl BsdfModel for Separable {
    #[inline(never)]
    fn flags(&self, wo: Vec3) -> BsdfFlags {
        self.inner.flags(wo)
    }

    #[inline(never)]
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        self.inner.eval(wo, wi)
    }

    #[inline(never)]
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.inner.pdf(wo, wi)
    }

    #[inline(never)]
    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
        self.inner.eval_pdf(wo, wi)
    }

    #[inline(never)]
    fn sample(&self, wo: Vec3, u1: f32, u2: [f32; 2]) -> Option<BsdfSample> {
        self.inner.sample(wo, u1, u2)
    }

    fn albedo(&self, wo: Vec3) -> Rgb {
        self.inner.albedo(wo)
    }
}
