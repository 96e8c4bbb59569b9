//! The polarized path (`--mode mono_polarized`, issue 45): what a path adds to the
//! mono path to carry polarization, in Mitsuba 3's conventions (`crate::polarization`,
//! `materials::mueller`).
//!
//! The path keeps its scalar throughput `beta` for every sampling decision (lobe
//! choice, Russian roulette, MIS), exactly as the mono path. Beside it, it carries the
//! product `M` of the Mueller matrices of its vertices, each normalised by its [0][0]
//! element: a BSDF's matrix `B` (`Bsdf::mueller`) has `B[0][0]` equal to the scalar
//! value that `beta` already holds (eval, or a delta lobe's weight times its choice
//! probability), so the step is `B / B[0][0]`. Emitters are unpolarized: a
//! contribution `c` (what the mono path would record) becomes the Stokes vector
//! `c * M e0`, the first column of `M` scaled. This is Mitsuba's estimator (its
//! throughput is the unnormalised product) with the same samples; only Russian
//! roulette reads the scalar `beta` instead of the matrix's [0][0] element, which
//! changes no expectation.
//!
//! Frames: a Stokes vector travelling along `w` is expressed in Mitsuba's implicit
//! basis `stokes_basis(w)`; each step re-expresses the BSDF's local matrix in the
//! implicit bases of its world directions (`to_world_mueller`). The camera's matrix
//! starts as the rotation from the implicit basis of the camera ray's reversed
//! direction into the sensor's frame (basis `d x up`: Mitsuba's `stokes` integrator),
//! so S1 > 0 is light polarized along the image's horizontal axis.
//!
//! Cost: 64 bytes per path (`M`), a 4 x 4 product per BSDF sample and a
//! matrix-vector product per contribution; paths of other modes carry `None`.

use crate::materials::mueller::to_world_mueller;
use crate::materials::{Bsdf, BsdfFlags};
use crate::math::frame::Frame;
use crate::polarization::elements::depolarizer;
use crate::polarization::frames::{rotate_stokes_basis, stokes_basis};
use glam::{Mat4, Vec3};

/// The camera's matrix of a ray along unit `d` from a sensor whose up axis is `up`:
/// from the implicit basis of `-d` (the direction light arrives in) into the sensor's
/// frame, basis `d x up` (Mitsuba's `stokes` integrator).
#[inline]
pub fn camera(d: Vec3, up: Vec3) -> Mat4 {
    let target = d.cross(up);
    if target.length_squared() == 0.0 {
        return Mat4::IDENTITY;
    }
    rotate_stokes_basis(-d, stokes_basis(-d), target)
}

/// The normalised world-basis Mueller matrix of the scattering from `-wi` to `wo`
/// (local directions in `frame`) at `bsdf` (`delta`: the delta lobe a sample came
/// through, as `Bsdf::mueller` takes it): `B / B[0][0]`, or an ideal depolarizer where
/// `B[0][0]` is not positive (then the scalar path carries no light either, or the
/// two differ by rounding at a grazing direction).
#[inline]
pub fn step(bsdf: &Bsdf, frame: &Frame, wo: Vec3, wi: Vec3, delta: Option<BsdfFlags>) -> Mat4 {
    let local = bsdf.mueller(wo, wi, delta);
    let a = local.x_axis.x;
    if !(a > 0.0 && a.is_finite()) {
        return depolarizer(1.0);
    }
    let mut n = local * (1.0 / a);
    // Exactly 1: a depolarizing step then keeps S0 bit for bit (the mono mode's).
    n.x_axis.x = 1.0;
    to_world_mueller(frame, n, -wi, wo)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec4;

    /// Horizontal light (along the sensor's x axis) reads S1 = S0 for a camera looking
    /// down -z with up +y, whatever the implicit basis of the ray is.
    #[test]
    fn the_camera_matrix_expresses_stokes_vectors_in_the_sensor_frame() {
        for d in [
            Vec3::new(0.0, 0.0, -1.0),
            Vec3::new(0.3, -0.2, -1.0).normalize(),
            Vec3::new(-0.5, 0.4, -0.8).normalize(),
        ] {
            let up = Vec3::Y;
            // Light travelling along -d polarized along the sensor's horizontal,
            // d x up, written in the implicit basis of -d: rotate it there.
            let horizontal = d.cross(up).normalize();
            let to_implicit = rotate_stokes_basis(-d, horizontal, stokes_basis(-d));
            let s_implicit = to_implicit * Vec4::new(1.0, 1.0, 0.0, 0.0);
            let s = camera(d, up) * s_implicit;
            assert!(
                (s - Vec4::new(1.0, 1.0, 0.0, 0.0)).abs().max_element() < 1e-5,
                "{d} {s}"
            );
            // Vertical light reads S1 = -S0.
            let v = camera(d, up) * (to_implicit * Vec4::new(1.0, -1.0, 0.0, 0.0));
            assert!((v - Vec4::new(1.0, -1.0, 0.0, 0.0)).abs().max_element() < 1e-5);
        }
    }
}
