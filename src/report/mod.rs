//! Reports (SPEC 10): error metrics against a reference, the convergence experiment
//! (error against spp and against seconds, equal-error speed-up), parameter sweeps,
//! and their tables and plots.

pub mod convergence;
pub mod metrics;
pub mod nlos;
pub mod plot;
pub mod region;
pub mod speedup;
pub mod sweep;
pub mod table;
pub mod volume;
