//! Reference frames of Stokes vectors: the implicit basis of a beam and the rotations
//! that re-express a vector or a Mueller matrix in another basis (Mitsuba's
//! `stokes_basis`, `rotate_stokes_basis`, `rotate_mueller_basis[_collinear]`).

use super::elements::rotator;
use crate::math::frame::Frame;
use glam::{Mat4, Vec3};

/// The reference basis of a beam travelling along unit `forward`.
pub fn stokes_basis(forward: Vec3) -> Vec3 {
    Frame::from_normal(forward).s
}

/// The Mueller matrix that re-expresses a Stokes vector travelling along `forward`
/// in `basis_target` instead of `basis_current` (both orthogonal to `forward`): a
/// rotator by the signed angle between them, positive when `current x target` points
/// along `forward`.
pub fn rotate_stokes_basis(forward: Vec3, basis_current: Vec3, basis_target: Vec3) -> Mat4 {
    let (a, b) = (basis_current.normalize(), basis_target.normalize());
    // Mitsuba's unit_angle: accurate also for nearly (anti)parallel vectors.
    let theta = if a.dot(b) < 0.0 {
        std::f32::consts::PI - 2.0 * (0.5 * (a + b).length()).clamp(-1.0, 1.0).asin()
    } else {
        2.0 * (0.5 * (b - a).length()).clamp(-1.0, 1.0).asin()
    };
    let sign = if forward.dot(basis_current.cross(basis_target)) < 0.0 {
        -1.0
    } else {
        1.0
    };
    rotator(sign * theta)
}

/// Re-expresses `m`, which maps Stokes vectors along `in_forward` in
/// `in_current` to vectors along `out_forward` in `out_current`, in the target bases:
/// `R_out M R_in^T`.
#[allow(clippy::too_many_arguments)]
pub fn rotate_mueller_basis(
    m: Mat4,
    in_forward: Vec3,
    in_current: Vec3,
    in_target: Vec3,
    out_forward: Vec3,
    out_current: Vec3,
    out_target: Vec3,
) -> Mat4 {
    let r_in = rotate_stokes_basis(in_forward, in_current, in_target);
    let r_out = rotate_stokes_basis(out_forward, out_current, out_target);
    r_out * m * r_in.transpose()
}

/// [`rotate_mueller_basis`] for an element whose input and output travel along the
/// same direction (filters, retarders).
pub fn rotate_mueller_basis_collinear(m: Mat4, forward: Vec3, current: Vec3, target: Vec3) -> Mat4 {
    let r = rotate_stokes_basis(forward, current, target);
    r * m * r.transpose()
}
