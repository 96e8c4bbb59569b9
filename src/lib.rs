//! tstat: statistical transient rendering.
//!
//! The pipeline, one module per stage: [`scene`] (Mitsuba XML -> [`scene::Scene`]) ->
//! [`render`] (transient path tracing into [`stats`] accumulators) -> [`bundle`] (the
//! statistics on disk). See ARCHITECTURE.md.

pub mod bundle;
pub mod cli;
pub mod cluster;
pub mod cpu;
pub mod denoise;
pub mod geometry;
pub mod io;
pub mod job;
pub mod lights;
pub mod materials;
pub mod math;
pub mod media;
pub mod nlos;
pub mod polarization;
pub mod render;
pub mod report;
pub mod scene;
pub mod sensors;
pub mod spectral;
pub mod stats;
pub mod textures;
pub mod viz;
