//! Reading input files defensively: only regular files (after following links), with a
//! size limit checked before anything is read, and a read that stops at the limit even
//! when the file grows meanwhile. `/dev/zero`, FIFOs, directories and links to them are
//! refused with one clear reason instead of being read until memory runs out.

use std::io::Read;
use std::path::Path;

/// Scene XML (and the files it includes): far above any real scene.
pub const MAX_SCENE_BYTES: u64 = 256 << 20;
/// Bundle manifests (JSON): a few kB in practice.
pub const MAX_MANIFEST_BYTES: u64 = 16 << 20;
/// Meshes (PLY, OBJ, serialized): 16 GiB, more than this machine's users render.
pub const MAX_MESH_BYTES: u64 = 16 << 30;
/// Texture images (PNG, JPEG, BMP, HDR, EXR): compressed data of the largest texture accepted.
pub const MAX_IMAGE_BYTES: u64 = 4 << 30;

/// Why a file could not be read: a short reason without the path (callers name the
/// file in their own error type).
#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    #[error("is a directory")]
    Directory,
    #[error("is not a regular file (a device, FIFO or socket)")]
    NotRegular,
    #[error("is {size} bytes, above the limit of {limit} bytes for this kind of file")]
    TooLarge { size: u64, limit: u64 },
    #[error("is {size} bytes, more than can be allocated to read it")]
    Unallocatable { size: u64 },
    #[error("grew beyond {limit} bytes while being read")]
    Grew { limit: u64 },
    #[error("is not UTF-8 text")]
    NotUtf8,
    /// The operating system's error (not exposed as a `source`: the message already
    /// says it, and callers print error chains).
    #[error("{0}")]
    Io(std::io::Error),
}

impl From<std::io::Error> for ReadError {
    fn from(e: std::io::Error) -> Self {
        ReadError::Io(e)
    }
}

/// The reason as text, for the layers whose errors are still messages (scene files,
/// textures, media read through this module).
impl From<ReadError> for String {
    fn from(e: ReadError) -> String {
        e.to_string()
    }
}

/// Opens a regular file of at most `max_bytes` for reading in place (seeking), with
/// the same checks as [`read_regular`]; returns it with its size.
pub fn open_regular(path: &Path, max_bytes: u64) -> Result<(std::fs::File, u64), ReadError> {
    let meta = check_regular(path, max_bytes)?;
    let file = std::fs::File::open(path)?;
    Ok((file, meta.len()))
}

/// The metadata of a regular file (after links) of at most `max_bytes`.
fn check_regular(path: &Path, max_bytes: u64) -> Result<std::fs::Metadata, ReadError> {
    let meta = std::fs::metadata(path)?;
    if !meta.is_file() {
        return Err(if meta.is_dir() {
            ReadError::Directory
        } else {
            ReadError::NotRegular
        });
    }
    if meta.len() > max_bytes {
        return Err(ReadError::TooLarge {
            size: meta.len(),
            limit: max_bytes,
        });
    }
    Ok(meta)
}

/// Reads a whole regular file of at most `max_bytes`. The error is a short reason
/// (without the path: callers name the file in their own error type).
pub fn read_regular(path: &Path, max_bytes: u64) -> Result<Vec<u8>, ReadError> {
    let meta = check_regular(path, max_bytes)?;
    let file = std::fs::File::open(path)?;
    let mut bytes = Vec::new();
    // A file within the limit may still not fit in memory (or under `ulimit -v`):
    // that is an error, not an abort.
    bytes
        .try_reserve_exact(meta.len() as usize)
        .map_err(|_| ReadError::Unallocatable { size: meta.len() })?;
    file.take(max_bytes + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > max_bytes {
        return Err(ReadError::Grew { limit: max_bytes });
    }
    Ok(bytes)
}

/// [`read_regular`] as UTF-8 text.
pub fn read_regular_text(path: &Path, max_bytes: u64) -> Result<String, ReadError> {
    String::from_utf8(read_regular(path, max_bytes)?).map_err(|_| ReadError::NotUtf8)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refuses_what_is_not_a_small_regular_file() {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("a.txt");
        std::fs::write(&f, "hello").unwrap();
        assert_eq!(read_regular(&f, 5).unwrap(), b"hello");
        assert!(read_regular(&f, 4)
            .unwrap_err()
            .to_string()
            .contains("above the limit"));
        assert!(read_regular(dir.path(), 100)
            .unwrap_err()
            .to_string()
            .contains("a directory"));
        assert!(read_regular(Path::new("/dev/zero"), 100)
            .unwrap_err()
            .to_string()
            .contains("not a regular file"));
        #[cfg(unix)]
        {
            let link = dir.path().join("zero");
            std::os::unix::fs::symlink("/dev/zero", &link).unwrap();
            assert!(read_regular(&link, 100)
                .unwrap_err()
                .to_string()
                .contains("not a regular file"));
        }
        assert!(matches!(
            read_regular(&dir.path().join("missing"), 100),
            Err(ReadError::Io(ref e)) if e.kind() == std::io::ErrorKind::NotFound
        ));
        std::fs::write(&f, [0xff, 0xfe]).unwrap();
        assert!(read_regular_text(&f, 10)
            .unwrap_err()
            .to_string()
            .contains("UTF-8"));
    }
}
