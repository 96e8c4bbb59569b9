//! Pictures for people: tone-mapped frames with one global exposure, GIF animations,
//! streak images, maximum-intensity projections of NLOS reconstructions, and the
//! polarization pictures of Stokes volumes.

pub mod frames;
pub mod mip;
pub mod polarization;
pub mod tonemap;
pub mod view;

use std::path::PathBuf;

/// Errors of the pictures: their files, and the requests.
#[derive(Debug, thiserror::Error)]
pub enum VizError {
    /// Writing or encoding a picture (through a temporary file and a rename).
    #[error(transparent)]
    Write(#[from] crate::bundle::BundleError),
    #[error("{}: {error}", .path.display())]
    CreateDir {
        path: PathBuf,
        error: std::io::Error,
    },
    #[error("streak row {row}: the image has {height} rows")]
    StreakRow { row: usize, height: usize },
    /// Drawing the streak image failed (the plotting library's reason, as text: its
    /// errors are not `Send`).
    #[error("drawing {}: {reason}", .path.display())]
    Drawing { path: PathBuf, reason: String },
}
