//! `homogeneous`: a medium of constant extinction (Mitsuba 3's `homogeneous`).
//!
//! | parameter | type | default | meaning |
//! |-----------|------|---------|---------|
//! | sigma_t | float, rgb or constvolume | 1 | extinction coefficient, 1 / scene unit (constant: a `gridvolume` here is refused, Mitsuba would read it at the origin only) |
//! | albedo | float, rgb or volume | 0.75 | single-scattering albedo sigma_s / sigma_t, in [0, 1]; a `<volume>` (`gridvolume`, `constvolume`) makes it vary in space, as Mitsuba allows |
//! | sigma_a, sigma_s | float or rgb | — | extension (Mitsuba 0.6's names, refused by Mitsuba 3): instead of sigma_t and albedo, sigma_t = sigma_a + sigma_s |
//! | scale | float | 1 | multiplies the extinction (sigma_t, or sigma_a and sigma_s) |
//! | sample_emitters | boolean | true | next-event estimation from scattering points |
//! | has_spectral_extinction | boolean | true | accepted; an optimisation hint in Mitsuba |
//! | (nested) | phase | isotropic | the phase function |
//!
//! Free-flight distances: the transmittance over a length `s` is `exp(-sigma_t s)` per
//! channel, and a real scattering happens with density `sigma_t exp(-sigma_t s)`, of
//! which `sigma_s = albedo sigma_t` scatters and the rest is absorbed.

use super::heterogeneous::Tracked;
use super::volume::Volume;
use super::Phase;
use crate::math::Rgb;
use glam::Vec3;

#[derive(Clone, Debug, PartialEq)]
pub struct Homogeneous {
    /// Extinction per channel (scale applied), 1 / scene unit, finite and >= 0.
    pub sigma_t: Rgb,
    /// Single-scattering albedo per channel, in [0, 1] (when `albedo_volume` is
    /// given: its value at the origin, unused by the tracer).
    pub albedo: Rgb,
    /// A spatially varying albedo (Mitsuba's `<volume name="albedo">`), values in [0, 1].
    pub albedo_volume: Option<Volume>,
    pub phase: Phase,
    pub sample_emitters: bool,
}

impl Homogeneous {
    /// Scattering coefficient sigma_s = albedo sigma_t.
    #[inline]
    pub fn sigma_s(&self) -> Rgb {
        self.sigma_t * self.albedo
    }

    /// Single-scattering albedo at `p`.
    #[inline]
    pub fn albedo_at(&self, p: Vec3) -> Rgb {
        match &self.albedo_volume {
            None => self.albedo,
            Some(v) => v.eval(p),
        }
    }

    /// Transmittance over a length `s` (infinite lengths give 0 where sigma_t > 0).
    #[inline]
    pub fn transmittance(&self, s: f32) -> Rgb {
        if s == f32::INFINITY {
            return Rgb::select(self.sigma_t.cmpgt(Rgb::ZERO), Rgb::ZERO, Rgb::ONE);
        }
        (-self.sigma_t * s).exp()
    }

    /// A free flight along unit `d` from `o` towards a surface at `s_surf`: a distance
    /// from channel `h`'s extinction with the uniform number `u`. `event(f, p)` receives
    /// the per-channel integrand and density factors of the collision, or the
    /// transmittance to the surface twice.
    #[inline(always)]
    pub fn free_flight(
        &self,
        o: Vec3,
        d: Vec3,
        s_surf: f32,
        h: usize,
        u: f32,
        mut event: impl FnMut(Rgb, Rgb),
    ) -> Tracked {
        let st = self.sigma_t;
        let sh = st[h];
        let t = if sh > 0.0 {
            -(1.0 - u).ln() / sh
        } else {
            f32::INFINITY
        };
        if t < s_surf {
            let tr = (-st * t).exp();
            let sigma_s = match &self.albedo_volume {
                None => self.sigma_s(),
                Some(v) => st * v.eval(o + d * t),
            };
            event(tr * sigma_s, st * tr);
            Tracked::Real { t }
        } else {
            let tr = self.transmittance(s_surf);
            event(tr, tr);
            Tracked::Through
        }
    }
}
