//! The statistics bundle on disk (SPEC 9): a directory with `manifest.json` and NumPy
//! arrays. The only interface between rendering and everything after it.

pub mod capture;
pub mod manifest;
pub mod merge;
pub mod npy;
pub mod read;
pub mod shard;
pub mod write;

pub use manifest::Manifest;
pub use read::{Bundle, RowReader, RowSums, SumArray};
use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum BundleError {
    #[error("{}: already exists (use --force to replace it)", .0.display())]
    Exists(PathBuf),
    #[error("{path}: {msg}", path = .0.display(), msg = .1)]
    Io(PathBuf, String),
    #[error("{path}: invalid bundle: {msg}", path = .0.display(), msg = .1)]
    Invalid(PathBuf, String),
    #[error("{path}: {msg}", path = .0.display(), msg = .1)]
    Volume(PathBuf, String),
}
