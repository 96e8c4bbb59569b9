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

use crate::math::Rgb;
use glam::Vec3;

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
}
