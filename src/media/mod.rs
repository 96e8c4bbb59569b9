//! Participating media (SPEC 7): Mitsuba 3's `homogeneous` medium with a phase function
//! (`phase.rs`), attached to shapes as `interior` / `exterior` and to the sensor, and
//! rendered by `transient_prbvolpath` (`render/volpath.rs`). `parse.rs` reads
//! `<medium>` and `<phase>`.

pub mod homogeneous;
pub mod parse;
pub mod phase;

pub use homogeneous::Homogeneous;
pub use phase::Phase;

/// A participating medium. Only homogeneous media exist (see `homogeneous.rs`).
pub type Medium = Homogeneous;
