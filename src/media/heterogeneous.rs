//! `heterogeneous`: a medium whose extinction and albedo vary in space (Mitsuba 3's
//! `src/media/heterogeneous.cpp`).
//!
//! | parameter | type | default | meaning |
//! |-----------|------|---------|---------|
//! | sigma_t | float, rgb or volume | 1 | extinction, 1 / scene unit, >= 0 |
//! | albedo | float, rgb or volume | 0.75 | single-scattering albedo, in [0, 1] |
//! | scale | float | 1 | multiplies sigma_t |
//! | sample_emitters | boolean | true | next-event estimation from scattering points |
//! | has_spectral_extinction | boolean | true | accepted; an optimisation hint in Mitsuba |
//! | (nested) | phase | isotropic | the phase function |
//!
//! A float or rgb is Mitsuba's shorthand for a `constvolume` with the identity
//! `to_world` (so, as in Mitsuba, the medium then fills only the unit cube).
//!
//! The medium exists inside the bounding box of its `sigma_t` volume (Mitsuba's
//! `intersect_aabb`); outside it a ray crosses vacuum. Inside, with the majorant
//! `mu = scale * max(sigma_t)` (one value for every channel, Mitsuba's
//! `m_max_density`) and the null coefficient `sigma_n(x) = mu - sigma_t(x) >= 0`:
//! - free flights are sampled by delta tracking: tentative collisions at
//!   exponential(mu) steps; at x a real collision with probability
//!   `sigma_t,h(x) / mu` for the path's hero channel h, else a null one (the path goes
//!   on straight, and only the distance travelled counts towards its OPL). Each event
//!   reports channel k's integrand factor and density factor to the path's spectral
//!   MIS (`render/volpath.rs`): `(sigma_s,k(x), sigma_t,k(x))` for a real collision,
//!   `(sigma_n,k(x), sigma_n,k(x))` for a null one; the common `mu exp(-mu s)` terms
//!   cancel. Mitsuba's volpath weighs the same events by their mean over channels
//!   instead (`sigma_n / mean(sigma_n)` per null collision, unbounded along a path
//!   when the channels differ); both are unbiased for every channel.
//! - transmittance (next-event estimation) is estimated by ratio tracking: the product
//!   of `sigma_n,k(x) / mu` over the tentative collisions, per channel (Mitsuba's
//!   volpath shadow rays do the same).

use super::volume::Volume;
use super::Phase;
use crate::math::rng::Pcg32;
use crate::math::Rgb;
use glam::Vec3;

#[derive(Clone, Debug, PartialEq)]
pub struct Heterogeneous {
    /// Extinction before `scale`.
    pub sigma_t: Volume,
    pub albedo: Volume,
    pub scale: f32,
    /// `scale * sigma_t.max`, 1 / scene unit.
    pub majorant: f32,
    pub phase: Phase,
    pub sample_emitters: bool,
}

/// The outcome of a free flight towards a surface (delta tracking here, one distance
/// in `homogeneous.rs`).
pub enum Tracked {
    /// A real collision at distance `t`.
    Real { t: f32 },
    /// No real collision before the surface (or the box's far side).
    Through,
}

impl Heterogeneous {
    /// Extinction at `p` (scale applied).
    #[inline]
    pub fn sigma_t_at(&self, p: Vec3) -> Rgb {
        self.sigma_t.eval(p) * self.scale
    }

    /// Single-scattering albedo at `p`.
    #[inline]
    pub fn albedo_at(&self, p: Vec3) -> Rgb {
        self.albedo.eval(p)
    }

    /// Where the ray `o + t d`, `0 <= t <= tmax`, can collide: its part inside the
    /// bounding box, `None` if empty or if the medium is empty (`mu = 0`).
    #[inline]
    fn range(&self, o: Vec3, d: Vec3, tmax: f32) -> Option<(f32, f32)> {
        if self.majorant <= 0.0 {
            return None;
        }
        let (t0, t1) = self.sigma_t.ray_range(o, d)?;
        let t1 = t1.min(tmax);
        (t0 < t1).then_some((t0, t1))
    }

    /// Delta tracking along unit `d` from `o` towards a surface at `s_surf`, the real
    /// / null choice made with channel `h`'s coefficients. `event(f, p)` receives each
    /// collision's per-channel integrand and density factors (see the module
    /// documentation). Draws two numbers per tentative collision.
    #[inline]
    pub fn track(
        &self,
        o: Vec3,
        d: Vec3,
        s_surf: f32,
        h: usize,
        rng: &mut Pcg32,
        mut event: impl FnMut(Rgb, Rgb),
    ) -> Tracked {
        let Some((t0, t1)) = self.range(o, d, s_surf) else {
            return Tracked::Through;
        };
        let mu = self.majorant;
        let mut t = t0;
        loop {
            t += -(1.0 - rng.next_f32()).ln() / mu;
            let u = rng.next_f32();
            if t >= t1 {
                return Tracked::Through;
            }
            let p = o + d * t;
            let st = self.sigma_t_at(p);
            if u * mu < st[h] {
                event(st * self.albedo_at(p), st);
                return Tracked::Real { t };
            }
            let sn = (Rgb::splat(mu) - st).max(Rgb::ZERO);
            event(sn, sn);
        }
    }

    /// Ratio-tracking estimate of the transmittance along unit `d` from `o` over a
    /// length `len` (per channel, unbiased; one number per tentative collision).
    #[inline]
    pub fn transmittance(&self, o: Vec3, d: Vec3, len: f32, rng: &mut Pcg32) -> Rgb {
        let mut tr = Rgb::ONE;
        let Some((t0, t1)) = self.range(o, d, len) else {
            return tr;
        };
        let mu = self.majorant;
        let mut t = t0;
        loop {
            t += -(1.0 - rng.next_f32()).ln() / mu;
            if t >= t1 {
                return tr;
            }
            let st = self.sigma_t_at(o + d * t);
            tr *= (Rgb::ONE - st / mu).max(Rgb::ZERO);
            if tr == Rgb::ZERO {
                return tr;
            }
        }
    }
}
