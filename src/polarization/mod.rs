//! Polarization calculus for the polarized render modes (issue 45): Stokes vectors,
//! Mueller matrices, their reference frames and the polarized Fresnel equations, in
//! Mitsuba 3's conventions (`include/mitsuba/render/mueller.h`, `fresnel.h`) so that
//! tstat's polarized output can be compared with mitransient's `*_polarized` variants
//! component by component.
//!
//! Conventions:
//! - A Stokes vector `S = (S0, S1, S2, S3)` is a `glam::Vec4`, a Mueller matrix a
//!   `glam::Mat4` acting on it (`M * S`). S1 > 0 is linear polarization along the
//!   frame's basis vector, S2 > 0 at +45 degrees from it, S3 > 0 right circular; the
//!   polarization ellipse is seen from the sensor, looking back along the beam.
//! - A Stokes vector means nothing without its reference basis, a unit vector
//!   orthogonal to the direction of travel. The basis of a beam travelling along `w`
//!   is implicit: [`frames::stokes_basis`]`(w)`, the `s` axis of
//!   `Frame::from_normal(w)` (Mitsuba's `coordinate_system(w).first`). Elements are
//!   written in their own local frames and moved between frames with
//!   [`frames::rotate_mueller_basis`].
//! - Fresnel amplitudes use the Verdet sign convention for `a_p`, and a conductor's
//!   complex index `eta + i k` is used with `k >= 0` as given in scenes (flipped to the
//!   physics sign inside, as Mitsuba does).
//!
//! Memory: 16 bytes per Stokes vector, 64 per Mueller matrix (f32).
//!
//! The renderer does not use this module yet: `--mode mono_polarized` is not offered
//! until the path tracer carries Mueller matrices end to end.

pub mod elements;
pub mod frames;
pub mod fresnel;

use glam::{Mat4, Vec4};

/// A 4 x 4 Mueller matrix from its rows (as printed in the optics literature).
#[inline]
pub fn mueller_rows(r: [[f32; 4]; 4]) -> Mat4 {
    Mat4::from_cols_array_2d(&r).transpose()
}

/// Unpolarized light of radiance `s0`.
#[inline]
pub fn unpolarized(s0: f32) -> Vec4 {
    Vec4::new(s0, 0.0, 0.0, 0.0)
}

/// Degree of linear polarization `sqrt(S1^2 + S2^2) / S0` (0 where S0 = 0).
pub fn dolp(s: Vec4) -> f32 {
    if s.x > 0.0 {
        (s.y * s.y + s.z * s.z).sqrt() / s.x
    } else {
        0.0
    }
}

/// Angle of linear polarization `0.5 atan2(S2, S1)`, radians in (-pi/2, pi/2], from
/// the frame's basis vector.
pub fn aolp(s: Vec4) -> f32 {
    0.5 * s.z.atan2(s.y)
}

/// Degree of polarization `sqrt(S1^2 + S2^2 + S3^2) / S0` (0 where S0 = 0).
pub fn dop(s: Vec4) -> f32 {
    if s.x > 0.0 {
        (s.y * s.y + s.z * s.z + s.w * s.w).sqrt() / s.x
    } else {
        0.0
    }
}
