//! Reports (SPEC 10): error metrics against a reference, the convergence experiment
//! (error against spp and against seconds, equal-error speed-up), parameter sweeps,
//! and their tables and plots.

pub mod convergence;
pub mod metrics;
pub mod plot;
pub mod reconstruction;
pub mod region;
pub mod speedup;
pub mod sweep;
pub mod table;
pub mod text;
pub mod volume;

use crate::bundle::npy::NpyError;
use crate::bundle::BundleError;
use crate::nlos::NlosError;
use std::path::PathBuf;

/// Errors of the reports: the volumes they compare, the convergence experiment and its
/// reconstructions, and their outputs.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    #[error(transparent)]
    Bundle(#[from] BundleError),
    #[error(transparent)]
    Nlos(#[from] NlosError),
    /// A scene that does not load (kept whole, not as a `source`: the message already
    /// says it).
    #[error("{0}")]
    Scene(crate::scene::SceneError),

    // Volumes (`volume.rs`) and cached arrays.
    #[error("{}: no such file or bundle", .0.display())]
    NoSuchVolume(PathBuf),
    /// A `.npy` file that cannot be read, or a value in it.
    #[error("{}: {error}", .path.display())]
    Npy { path: PathBuf, error: NpyError },
    #[error("{}: expected a volume (H, W, T, C) with C = 3 (RGB), 1 (mono), 4 (Stokes S0..S3) or 12, or (H, W, T, 3, 4) (RGB x Stokes), the shape is {shape:?}", .path.display())]
    NotAVolume { path: PathBuf, shape: Vec<usize> },
    #[error("{}: holds no voxels (shape {shape:?})", .path.display())]
    EmptyVolume { path: PathBuf, shape: Vec<usize> },
    #[error("{}: dtype {dtype:?} is not a volume's f32 or f64 (\"<f4\" or \"<f8\")", .path.display())]
    VolumeDtype { path: PathBuf, dtype: String },
    /// A bundle of a sweep whose volume is not the reference's shape.
    #[error("{}: invalid bundle: shape {shape:?} does not match the reference's {reference:?}", .path.display())]
    SweepShape {
        path: PathBuf,
        shape: [usize; 4],
        reference: Vec<usize>,
    },

    // The convergence experiment (`convergence.rs`).
    #[error("the spp list is empty")]
    NoSpp,
    #[error("spp {0}: at least 2 samples per pixel are needed")]
    TooFewSamples(u32),
    #[error("the reference has shape {reference:?} but the renders have {renders:?}")]
    ReferenceShape {
        reference: Vec<usize>,
        renders: [usize; 4],
    },
    /// A render's mean S / n beyond f32 at a voxel.
    #[error("the render's mean {mean:e} at row {y}, column {x}, bin {t}, channel {c} does not fit in f32 (the volumes' type): scale the emitters down")]
    MeanBeyondF32 {
        mean: f64,
        y: usize,
        x: usize,
        t: usize,
        c: usize,
    },

    // Reconstructions (`nlos.rs`).
    #[error("reconstructions need an NLOS scene (its sensor an nlos_capture_meter)")]
    NotAnNlosScene,
    /// A reconstruction method that cannot run on the scene's capture.
    #[error("{method}: {error}")]
    Method {
        method: &'static str,
        error: Box<NlosError>,
    },
    #[error("{method} on {grid:?} voxels needs {need} bytes of working memory, over the {allowed} allowed")]
    ReconstructionMemory {
        method: &'static str,
        grid: [usize; 3],
        need: u64,
        allowed: u64,
    },
    #[error("the {0} reconstruction of the reference capture is zero everywhere: no error can be measured against it (does the volume hold the hidden scene?)")]
    ZeroReference(&'static str),

    // Pictures (`plot.rs`).
    /// Drawing a chart failed (the plotting library's reason, as text: its errors
    /// are not `Send`).
    #[error("drawing {}: {reason}", .path.display())]
    Drawing { path: PathBuf, reason: String },
}
