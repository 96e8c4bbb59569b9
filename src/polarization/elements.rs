//! Mueller matrices of ideal optical elements, each in its own local frame (the
//! element's axis along the frame's basis vector). Sources: Collett, "Polarized
//! Light", ch. 5; Goldstein, "Polarized Light", 3rd ed., eq. 6.43 (the retarder's
//! fast axis horizontal); Chipman et al., "Polarized Light and Optical Systems",
//! table 6.2 (circular polarizers).

use super::mueller_rows;
use glam::Mat4;

/// An ideal depolarizer: keeps `value` times S0 and nothing else (Mitsuba's
/// unpolarized BSDFs in polarized modes).
pub fn depolarizer(value: f32) -> Mat4 {
    let mut m = Mat4::ZERO;
    m.x_axis.x = value;
    m
}

/// A linear polarizer transmitting light polarized along the basis vector, with
/// attenuation `value` (1: ideal).
pub fn linear_polarizer(value: f32) -> Mat4 {
    let a = 0.5 * value;
    mueller_rows([[a, a, 0.0, 0.0], [a, a, 0.0, 0.0], [0.0; 4], [0.0; 4]])
}

/// A linear retarder with its fast axis along the basis vector and retardance
/// `phase` (pi/2: quarter-wave plate, pi: half-wave plate).
pub fn linear_retarder(phase: f32) -> Mat4 {
    let (s, c) = phase.sin_cos();
    mueller_rows([
        [1.0, 0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0, c, s],
        [0.0, 0.0, -s, c],
    ])
}

/// A linear diattenuator scaling the field components along and across the basis
/// vector by amplitudes whose squares are `x` and `y`.
pub fn diattenuator(x: f32, y: f32) -> Mat4 {
    let (a, b, c) = (0.5 * (x + y), 0.5 * (x - y), (x * y).sqrt());
    mueller_rows([
        [a, b, 0.0, 0.0],
        [b, a, 0.0, 0.0],
        [0.0, 0.0, c, 0.0],
        [0.0, 0.0, 0.0, c],
    ])
}

/// An ideal right (`right = true`) or left circular polarizer.
pub fn circular_polarizer(right: bool) -> Mat4 {
    let e = if right { 0.5 } else { -0.5 };
    mueller_rows([[0.5, 0.0, 0.0, e], [0.0; 4], [0.0; 4], [e, 0.0, 0.0, 0.5]])
}

/// Rotates the reference frame of a Stokes vector counter-clockwise by `theta`
/// (seen from the sensor): horizontal light (1, 1, 0, 0) becomes (1, 0, -1, 0) under
/// `rotator(pi/4)`.
pub fn rotator(theta: f32) -> Mat4 {
    let (s, c) = (2.0 * theta).sin_cos();
    mueller_rows([
        [1.0, 0.0, 0.0, 0.0],
        [0.0, c, s, 0.0],
        [0.0, -s, c, 0.0],
        [0.0, 0.0, 0.0, 1.0],
    ])
}

/// Element `m` turned counter-clockwise by `theta` about the beam:
/// `R(-theta) M R(theta)`.
pub fn rotated_element(theta: f32, m: Mat4) -> Mat4 {
    let r = rotator(theta);
    r.transpose() * m * r
}
