//! Participating media (SPEC 7): Mitsuba 3's `homogeneous` and `heterogeneous` media
//! with a phase function (`phase.rs`), attached to shapes as `interior` / `exterior`
//! and to the sensor, and rendered by `transient_prbvolpath` (`render/volpath.rs`).
//! `volume.rs` holds the `<volume>` plugins (`constvolume`, `gridvolume`) and
//! `vol_file.rs` Mitsuba's `.vol` grid files. `scene/media.rs` reads `<medium>`,
//! `<phase>` and `<volume>`.

pub mod heterogeneous;
pub mod homogeneous;
pub mod phase;
pub mod vol_file;
pub mod volume;

pub use heterogeneous::Heterogeneous;
pub use homogeneous::Homogeneous;
pub use phase::Phase;
pub use vol_file::VolError;
pub use volume::Volume;

pub use heterogeneous::Tracked;

use crate::math::rng::Pcg32;
use crate::math::Rgb;
use glam::Vec3;

/// The random numbers a free flight draws (implemented for the tracers' path
/// samplers in `render/sampler.rs`).
pub trait FlightNumbers {
    /// A homogeneous medium's one uniform number in [0, 1).
    fn flight_number(&mut self) -> f32;
    /// The path's own stream, for delta tracking (as many numbers as collisions).
    fn flight_stream(&mut self) -> &mut Pcg32;
}

/// A participating medium.
#[derive(Clone, Debug, PartialEq)]
pub enum Medium {
    Homogeneous(Homogeneous),
    Heterogeneous(Heterogeneous),
}

impl Medium {
    #[inline]
    pub fn phase(&self) -> &Phase {
        match self {
            Medium::Homogeneous(m) => &m.phase,
            Medium::Heterogeneous(m) => &m.phase,
        }
    }

    /// Whether scattering points sample emitters (next-event estimation).
    #[inline]
    pub fn sample_emitters(&self) -> bool {
        match self {
            Medium::Homogeneous(m) => m.sample_emitters,
            Medium::Heterogeneous(m) => m.sample_emitters,
        }
    }

    /// Single-scattering albedo at `p`.
    #[inline]
    pub fn albedo_at(&self, p: Vec3) -> Rgb {
        match self {
            Medium::Homogeneous(m) => m.albedo_at(p),
            Medium::Heterogeneous(m) => m.albedo_at(p),
        }
    }

    /// Samples a free flight along unit `d` from `o` towards a surface at `s_surf`,
    /// choosing with channel `h`'s coefficients; `event(f, p)` receives the
    /// per-channel integrand and density factors of each collision (and of reaching
    /// the surface in a homogeneous medium). Homogeneous: one number, the distance
    /// from the extinction; heterogeneous: delta tracking on the path's stream.
    #[inline(always)]
    pub fn free_flight<R: FlightNumbers>(
        &self,
        o: Vec3,
        d: Vec3,
        s_surf: f32,
        h: usize,
        rng: &mut R,
        event: impl FnMut(Rgb, Rgb),
    ) -> Tracked {
        match self {
            Medium::Homogeneous(m) => m.free_flight(o, d, s_surf, h, rng.flight_number(), event),
            Medium::Heterogeneous(m) => m.track(o, d, s_surf, h, rng.flight_stream(), event),
        }
    }

    /// Transmittance over `len` along unit `d` from `o` (heterogeneous: ratio tracking
    /// on `rng`).
    #[inline(always)]
    pub fn transmittance(&self, o: Vec3, d: Vec3, len: f32, rng: &mut Pcg32) -> Rgb {
        match self {
            Medium::Homogeneous(m) => m.transmittance(len),
            Medium::Heterogeneous(m) => m.transmittance(o, d, len, rng),
        }
    }
}
