//! The one error type of scene loading: every message names the file, the line and the
//! element, so a user can fix the scene without reading our code.

use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
#[error("{}:{line}: <{element}>: {message}", file.display())]
pub struct SceneError {
    pub file: PathBuf,
    /// 1-based line of the offending element (0 when the whole file is at fault).
    pub line: u32,
    pub element: String,
    pub message: String,
}

impl SceneError {
    pub fn new(
        file: &Path,
        line: u32,
        element: impl Into<String>,
        message: impl Into<String>,
    ) -> Self {
        SceneError {
            file: file.to_path_buf(),
            line,
            element: element.into(),
            message: message.into(),
        }
    }
}
