//! The polarized Fresnel equations: complex reflection amplitudes of the s and p
//! components at a dielectric or conductor interface, and the Mueller matrices of
//! specular reflection and transmission built from them (Mitsuba's
//! `fresnel_polarized`, `mueller::specular_reflection`, `specular_transmission`).
//!
//! `cos_theta_i` is the cosine between the surface normal and the direction towards
//! the incident light; negative means the light arrives from inside (the side the
//! normal points away from), where the relative index is `1 / eta`. Each matrix is in
//! the s/p frame of the interaction: the basis vector of both the incident and the
//! outgoing beam is the s direction (normal to the plane of incidence).
//! Computed in f64, returned in f32.

use super::mueller_rows;
use glam::Mat4;
use num_complex::Complex64 as C64;

/// What [`amplitudes`] returns.
#[derive(Clone, Copy, Debug)]
pub struct Amplitudes {
    /// Reflection amplitude of the s component.
    pub a_s: C64,
    /// Reflection amplitude of the p component (Verdet convention).
    pub a_p: C64,
    /// Cosine of the transmitted direction with the normal, signed opposite to
    /// `cos_theta_i`; 0 under total internal reflection.
    pub cos_theta_t: f64,
    /// Relative index (transmitted over incident side) and its inverse.
    pub eta_it: C64,
    pub eta_ti: C64,
}

/// The Fresnel amplitudes for relative index `eta = n_inside / n_outside` (real for a
/// dielectric; `eta + i k` for a conductor, with `k >= 0` as scenes give it).
pub fn amplitudes(cos_theta_i: f64, eta: C64) -> Amplitudes {
    // The amplitude formulas assume k <= 0 (the physics sign).
    let eta = if eta.im > 0.0 { eta.conj() } else { eta };
    let outside = cos_theta_i >= 0.0;
    let (eta_it, eta_ti) = if outside {
        (eta, eta.inv())
    } else {
        (eta.inv(), eta)
    };
    let cos_i = cos_theta_i.abs();
    let cos_t_sqr = C64::new(1.0, 0.0) - eta_ti * eta_ti * (1.0 - cos_i * cos_i);
    let mut cos_t = cos_t_sqr.sqrt();
    if eta.im == 0.0 {
        // Dielectric: under total internal reflection cos_t = -i sqrt(-cos_t_sqr),
        // the root whose sign gives the right phase (Clarke, "Stellar Polarimetry",
        // appendix A.2).
        if cos_t_sqr.re < 0.0 {
            cos_t = C64::new(0.0, -(-cos_t_sqr.re).sqrt());
        }
    } else if cos_t.im > 0.0 {
        cos_t = cos_t.conj();
    }
    let a_s = (cos_i - eta_it * cos_t) / (cos_i + eta_it * cos_t);
    let a_p = (eta_it * cos_i - cos_t) / (eta_it * cos_i + cos_t);
    let matched = eta.norm_sqr() == 1.0 && eta.im == 0.0;
    let (a_s, a_p) = if matched || eta.norm_sqr() == 0.0 {
        (C64::new(0.0, 0.0), C64::new(0.0, 0.0))
    } else {
        (a_s, a_p)
    };
    let cos_theta_t = if cos_t_sqr.re >= 0.0 {
        -cos_t.re.abs() * cos_theta_i.signum()
    } else {
        0.0
    };
    Amplitudes {
        a_s,
        a_p,
        cos_theta_t,
        eta_it,
        eta_ti,
    }
}

/// Mueller matrix of specular reflection: `R_s = |a_s|^2`, `R_p = |a_p|^2` on the
/// diagonal blocks, and the retardance `delta = arg(a_p) - arg(a_s)` mixing S2 and S3.
pub fn specular_reflection(cos_theta_i: f64, eta: C64) -> Mat4 {
    let f = amplitudes(cos_theta_i, eta);
    let (r_s, r_p) = (f.a_s.norm_sqr(), f.a_p.norm_sqr());
    let (a, b, c) = (0.5 * (r_s + r_p), 0.5 * (r_s - r_p), (r_s * r_p).sqrt());
    let (sin_d, cos_d) = if c > 0.0 {
        let z = f.a_p * f.a_s.conj();
        (z.im / z.norm(), z.re / z.norm())
    } else {
        (0.0, 0.0)
    };
    let m = [
        [a, b, 0.0, 0.0],
        [b, a, 0.0, 0.0],
        [0.0, 0.0, c * cos_d, -c * sin_d],
        [0.0, 0.0, c * sin_d, c * cos_d],
    ];
    mueller_rows(m.map(|r| r.map(|v| v as f32)))
}

/// Mueller matrix of specular transmission through a dielectric interface (real
/// `eta`): the power transmittances `T = (eta_it cos_t / cos_i) |t|^2` of each
/// component, with `t_s = 1 + a_s` and `t_p = (1 + a_p) eta_ti`, so that `R + T = 1`
/// for s and for p. (The radiance scaling by the squared index ratio is the BSDF's.)
pub fn specular_transmission(cos_theta_i: f64, eta: f64) -> Mat4 {
    let f = amplitudes(cos_theta_i, C64::new(eta, 0.0));
    let factor = if cos_theta_i.abs() > 1e-8 {
        -f.eta_it.re * f.cos_theta_t / cos_theta_i
    } else {
        0.0
    };
    let t_s = (1.0 + f.a_s.re).powi(2);
    let t_p = ((1.0 + f.a_p.re) * f.eta_ti.re).powi(2);
    let (a, b, c) = (
        0.5 * factor * (t_s + t_p),
        0.5 * factor * (t_s - t_p),
        factor * (t_s * t_p).sqrt(),
    );
    let m = [
        [a, b, 0.0, 0.0],
        [b, a, 0.0, 0.0],
        [0.0, 0.0, c, 0.0],
        [0.0, 0.0, 0.0, c],
    ];
    mueller_rows(m.map(|r| r.map(|v| v as f32)))
}
