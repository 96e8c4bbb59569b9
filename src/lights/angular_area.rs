//! mitransient's `angulararea` (`mitransient/emitters/angulararea.py`, 1.3.1): an area
//! light on a shape whose emission is restricted to a cone of directions about the
//! surface normal.
//!
//! | parameter | type | default | meaning |
//! |-----------|------|---------|---------|
//! | radiance | rgb/float/spectrum | 1 | emitted radiance on the normal (front side only) |
//! | cutoff_angle | float | 10 | degrees; no light at or beyond it from the normal |
//! | beam_width | float | cutoff_angle | degrees; full radiance within it |
//!
//! With theta the angle between the surface normal and the outgoing direction, the
//! radiance is `radiance * falloff(theta)`: 1 for `cos theta >= cos beam_width`, 0 for
//! `cos theta <= cos cutoff_angle`, and `(cutoff - theta) / (cutoff - beam_width)`
//! between (mitransient's `_fallof_curve`, not clamped: the ramp lies in [0, 1]).
//!
//! Sampling is the shape's area sampling, as mitransient's (`shape.sample_direction`,
//! uniform by area, not restricted to the cone); the pdf the integrator's MIS uses on a
//! hit is that solid-angle pdf where the falloff is positive and 0 elsewhere
//! (mitransient's `pdf_direction`). A light sample outside the cone carries nothing and
//! is dropped.
//!
//! One deliberate difference: mitransient 1.3.1's `sample_direction` weights a light
//! sample by `radiance * falloff / dist^2 / pdf`, with `pdf` already the solid-angle
//! density (its comment treats it as an area density), so its next-event estimate is
//! `1 / dist^2` times the radiance its own `eval` returns on a hit (measured: at
//! distance 3.056 the sample weight is 0.1125 where the `area` emitter's is 1.051, with
//! the same pdf). tstat emits `radiance * falloff` for both strategies, the radiance the
//! plugin documents (energy per unit area per unit steradian), so both estimators agree
//! and the emitted power is `radiance * area * 2 pi * int falloff cos sin dtheta`.

use crate::math::Rgb;

/// The angular profile of an `angulararea` light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AngularFalloff {
    /// Angles in radians.
    pub cutoff: f32,
    pub beam_width: f32,
    cos_cutoff: f32,
    cos_beam: f32,
    /// 1 / (cutoff - beam_width); infinite when they are equal (never used then).
    inv_transition: f32,
}

impl AngularFalloff {
    /// From angles in degrees (checked by the caller: 0 < cutoff <= 180,
    /// 0 <= beam_width <= cutoff). Constants are computed in double precision, as
    /// mitransient computes them from the Python floats it reads.
    pub fn new(cutoff_deg: f64, beam_width_deg: f64) -> Self {
        let (c, b) = (cutoff_deg.to_radians(), beam_width_deg.to_radians());
        let diff = c - b;
        AngularFalloff {
            cutoff: c as f32,
            beam_width: b as f32,
            cos_cutoff: c.cos() as f32,
            cos_beam: b.cos() as f32,
            inv_transition: if diff == 0.0 {
                f32::INFINITY
            } else {
                (1.0 / diff) as f32
            },
        }
    }

    /// The fraction of the radiance emitted at cosine `cos_theta` from the normal.
    #[inline]
    pub fn eval(&self, cos_theta: f32) -> f32 {
        if cos_theta <= self.cos_cutoff {
            return 0.0;
        }
        if cos_theta >= self.cos_beam {
            return 1.0;
        }
        (self.cutoff - cos_theta.clamp(-1.0, 1.0).acos()) * self.inv_transition
    }

    /// `2 pi int_0^pi falloff(theta) cos(theta) sin(theta) dtheta` over the front
    /// hemisphere, in closed form: the emitted power per unit area and unit radiance
    /// (`pi sin^2 cutoff` without a ramp).
    pub fn projected_solid_angle(&self) -> f64 {
        let (c, b) = (
            (self.cutoff as f64).min(std::f64::consts::FRAC_PI_2),
            self.beam_width as f64,
        );
        if b >= c {
            return std::f64::consts::PI * c.sin().powi(2);
        }
        // int_b^c (cutoff - t) sin t cos t dt, with the antiderivative
        // -(cutoff - t) cos(2t) / 4 - sin(2t) / 8.
        let cut = self.cutoff as f64;
        let anti = |t: f64| -(cut - t) * (2.0 * t).cos() / 4.0 - (2.0 * t).sin() / 8.0;
        let ramp = (anti(c) - anti(b)) / (cut - b);
        2.0 * std::f64::consts::PI * (b.sin().powi(2) / 2.0 + ramp)
    }
}

/// Radiance of an angular light towards cosine `cos_l` from its normal (front side).
#[inline]
pub fn angular_radiance(radiance: Rgb, falloff: &AngularFalloff, cos_l: f32) -> Option<Rgb> {
    let f = falloff.eval(cos_l);
    (f > 0.0).then(|| radiance * f)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn falloff_is_mitransients_ramp() {
        let f = AngularFalloff::new(35.0, 20.0);
        let at = |deg: f32| f.eval(deg.to_radians().cos());
        assert_eq!(at(0.0), 1.0);
        assert_eq!(at(19.9), 1.0);
        assert!((at(27.5) - 0.5).abs() < 1e-4, "{}", at(27.5));
        assert!((at(32.0) - 0.2).abs() < 1e-4);
        assert_eq!(at(35.1), 0.0);
        assert_eq!(at(90.0), 0.0);
        // No ramp: a step at the cutoff.
        let s = AngularFalloff::new(50.0, 50.0);
        assert_eq!(s.eval(49.9f32.to_radians().cos()), 1.0);
        assert_eq!(s.eval(50.1f32.to_radians().cos()), 0.0);
    }

    #[test]
    fn projected_solid_angle_matches_quadrature() {
        for (c, b) in [
            (35.0, 20.0),
            (50.0, 50.0),
            (10.0, 0.0),
            (120.0, 60.0),
            (90.0, 90.0),
        ] {
            let f = AngularFalloff::new(c, b);
            // Midpoint rule in theta over the front hemisphere, piece by piece between
            // the profile's kinks (the f32 angles the falloff holds), in f64.
            let half_pi = std::f64::consts::FRAC_PI_2;
            let (cr, br) = (f.cutoff as f64, f.beam_width as f64);
            let w = |t: f64| {
                if t <= br {
                    1.0
                } else if t >= cr {
                    0.0
                } else {
                    (cr - t) / (cr - br)
                }
            };
            let mut edges = vec![0.0, br.min(half_pi), cr.min(half_pi), half_pi];
            edges.dedup();
            let n = 20_000;
            let q: f64 = edges
                .windows(2)
                .map(|e| {
                    let h = (e[1] - e[0]) / n as f64;
                    (0..n)
                        .map(|i| {
                            let t = e[0] + (i as f64 + 0.5) * h;
                            w(t) * t.cos() * t.sin()
                        })
                        .sum::<f64>()
                        * h
                })
                .sum::<f64>()
                * 2.0
                * std::f64::consts::PI;
            let exact = f.projected_solid_angle();
            assert!((q - exact).abs() < 1e-8, "{c} {b}: {q} vs {exact}");
        }
        assert!(
            (AngularFalloff::new(90.0, 90.0).projected_solid_angle() - std::f64::consts::PI).abs()
                < 1e-6
        );
    }
}
