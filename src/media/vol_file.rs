//! Mitsuba's binary volume format (`.vol`, version 3, as `src/render/volumegrid.cpp`
//! reads it), little-endian:
//!
//! | bytes | content |
//! |-------|---------|
//! | 0-2 | ASCII `VOL` |
//! | 3 | version, 3 |
//! | 4-7 | encoding (i32): 1 = float32 |
//! | 8-19 | cells along x, y, z (three i32) |
//! | 20-23 | channels (i32): 1 or 3 here (Mitsuba's 6-channel grids are no spectrum) |
//! | 24-47 | bounding box, f32: xmin, ymin, zmin, xmax, ymax, zmax |
//! | 48- | the values, f32, `data[((z * ny + y) * nx + x) * channels + c]` |
//!
//! Checked before anything is allocated: the header, positive sizes, and that the file
//! holds every value (a truncated file is an error, trailing bytes are ignored as
//! Mitsuba ignores them); then every value must be finite. The file is read in place
//! (`io::open_regular`) in bounded chunks, never twice in memory.

use std::io::Read;
use std::path::Path;

/// Largest `.vol` file read (values are 4 bytes each: a billion voxel-channels).
pub const MAX_VOL_BYTES: u64 = 4 << 30;
/// Bytes before the values.
pub const HEADER_BYTES: u64 = 48;

/// A grid as stored: sizes, channels, the file's bounding box and the values.
#[derive(Clone, Debug, PartialEq)]
pub struct VolFile {
    /// Cells along x, y, z.
    pub size: [usize; 3],
    /// 1 or 3.
    pub channels: usize,
    /// The bounding box stored in the file (used with `use_grid_bbox`).
    pub bbox_min: [f32; 3],
    pub bbox_max: [f32; 3],
    /// `size[0] * size[1] * size[2] * channels` finite values, x fastest, channels
    /// interleaved.
    pub data: Vec<f32>,
}

impl VolFile {
    /// The largest value over all voxels and channels (Mitsuba's `VolumeGrid::max`).
    pub fn max(&self) -> f32 {
        self.data.iter().copied().fold(f32::NEG_INFINITY, f32::max)
    }

    /// The smallest value over all voxels and channels.
    pub fn min(&self) -> f32 {
        self.data.iter().copied().fold(f32::INFINITY, f32::min)
    }

    /// The file's bytes (for tests and tools): the inverse of [`read_vol`].
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut b = Vec::with_capacity(HEADER_BYTES as usize + 4 * self.data.len());
        b.extend_from_slice(b"VOL");
        b.push(3);
        b.extend_from_slice(&1i32.to_le_bytes());
        for s in self.size {
            b.extend_from_slice(&(s as i32).to_le_bytes());
        }
        b.extend_from_slice(&(self.channels as i32).to_le_bytes());
        for v in self.bbox_min.iter().chain(&self.bbox_max) {
            b.extend_from_slice(&v.to_le_bytes());
        }
        for v in &self.data {
            b.extend_from_slice(&v.to_le_bytes());
        }
        b
    }
}

fn i32_at(h: &[u8], at: usize) -> i32 {
    i32::from_le_bytes([h[at], h[at + 1], h[at + 2], h[at + 3]])
}

fn f32_at(h: &[u8], at: usize) -> f32 {
    f32::from_le_bytes([h[at], h[at + 1], h[at + 2], h[at + 3]])
}

/// Why a `.vol` file cannot be read. The message is a short reason without the path
/// (the caller names the file and the parameter), e.g. "is not a Mitsuba volume: ...".
#[derive(Debug, thiserror::Error)]
pub enum VolError {
    /// The file could not be opened (missing, not a regular file, above [`MAX_VOL_BYTES`]).
    #[error(transparent)]
    Open(std::io::Error),
    /// A file shorter than the header.
    #[error("is {len} bytes, shorter than the {HEADER_BYTES}-byte header of a .vol file")]
    Short { len: u64 },
    /// The header could not be read.
    #[error("cannot read the header: {0}")]
    Header(#[source] std::io::Error),
    /// No `VOL` magic.
    #[error("is not a Mitsuba volume: it does not start with 'VOL'")]
    NotVol,
    /// A format version other than 3.
    #[error("has .vol version {version}; only version 3 is supported")]
    Version { version: u8 },
    /// An encoding other than float32.
    #[error("has encoding {encoding}; only encoding 1 (float32) is supported")]
    Encoding { encoding: i32 },
    /// A grid size that is not positive.
    #[error(
        "has grid size {} x {} x {}; every size must be positive",
        .size[0], .size[1], .size[2]
    )]
    Size { size: [i32; 3] },
    /// A channel count other than 1 or 3.
    #[error("has {channels} channels; volumes of 1 or 3 channels are supported")]
    Channels { channels: i32 },
    /// A file of `len` bytes that cannot hold the header's grid (`needed` bytes, `None`
    /// beyond 2^64).
    #[error(
        "is truncated: a {} x {} x {} grid of {channels} channel(s) needs {} bytes, the file has {len}",
        .size[0], .size[1], .size[2],
        .needed.map_or("more than 2^64".to_string(), |n| n.to_string())
    )]
    Truncated {
        size: [i32; 3],
        channels: i32,
        needed: Option<u64>,
        len: u64,
    },
    /// A grid whose values cannot be allocated.
    #[error("holds {values} values, more than can be allocated")]
    Alloc { values: usize },
    /// Reading failed at value `index` (voxel-channels count from 0).
    #[error("cannot read value {index}: {source} (truncated?)")]
    Value {
        index: usize,
        #[source]
        source: std::io::Error,
    },
    /// A NaN or infinite value at `voxel` (x, y, z), channel `channel`.
    #[error(
        "has the non-finite value {value} at voxel (x {}, y {}, z {}), channel {channel}",
        .voxel[0], .voxel[1], .voxel[2]
    )]
    NonFinite {
        value: f32,
        voxel: [usize; 3],
        channel: usize,
    },
}

/// Reads a `.vol` file. The error is a short reason without the path (the caller names
/// the file and the parameter).
pub fn read_vol(path: &Path) -> Result<VolFile, VolError> {
    let (file, len) = crate::io::open_regular(path, MAX_VOL_BYTES)
        .map_err(|e| VolError::Open(std::io::Error::other(e)))?;
    let mut reader = std::io::BufReader::new(file.take(len));
    if len < HEADER_BYTES {
        return Err(VolError::Short { len });
    }
    let mut h = [0u8; HEADER_BYTES as usize];
    reader.read_exact(&mut h).map_err(VolError::Header)?;
    if &h[0..3] != b"VOL" {
        return Err(VolError::NotVol);
    }
    if h[3] != 3 {
        return Err(VolError::Version { version: h[3] });
    }
    let encoding = i32_at(&h, 4);
    if encoding != 1 {
        return Err(VolError::Encoding { encoding });
    }
    let dims = [i32_at(&h, 8), i32_at(&h, 12), i32_at(&h, 16)];
    if dims.iter().any(|&d| d <= 0) {
        return Err(VolError::Size { size: dims });
    }
    let channels = i32_at(&h, 20);
    if channels != 1 && channels != 3 {
        return Err(VolError::Channels { channels });
    }
    let values = dims
        .iter()
        .try_fold(channels as u64, |acc, &d| acc.checked_mul(d as u64));
    let needed = values
        .and_then(|v| v.checked_mul(4))
        .and_then(|b| b.checked_add(HEADER_BYTES));
    let values = match (values, needed) {
        (Some(v), Some(n)) if n <= len => v as usize,
        _ => {
            return Err(VolError::Truncated {
                size: dims,
                channels,
                needed,
                len,
            })
        }
    };
    let bbox_min = [f32_at(&h, 24), f32_at(&h, 28), f32_at(&h, 32)];
    let bbox_max = [f32_at(&h, 36), f32_at(&h, 40), f32_at(&h, 44)];
    let mut data: Vec<f32> = Vec::new();
    data.try_reserve_exact(values)
        .map_err(|_| VolError::Alloc { values })?;
    let mut chunk = vec![0u8; 1 << 16];
    while data.len() < values {
        let n = ((values - data.len()) * 4).min(chunk.len());
        reader
            .read_exact(&mut chunk[..n])
            .map_err(|source| VolError::Value {
                index: data.len(),
                source,
            })?;
        for b in chunk[..n].chunks_exact(4) {
            let v = f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
            if !v.is_finite() {
                let i = data.len();
                let c = channels as usize;
                let (cell, channel) = (i / c, i % c);
                let (nx, ny) = (dims[0] as usize, dims[1] as usize);
                return Err(VolError::NonFinite {
                    value: v,
                    voxel: [cell % nx, (cell / nx) % ny, cell / (nx * ny)],
                    channel,
                });
            }
            data.push(v);
        }
    }
    Ok(VolFile {
        size: [dims[0] as usize, dims[1] as usize, dims[2] as usize],
        channels: channels as usize,
        bbox_min,
        bbox_max,
        data,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, name: &str, bytes: &[u8]) -> std::path::PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    }

    #[test]
    fn refuses_bad_headers_truncation_and_non_finite_values() {
        let dir = tempfile::tempdir().unwrap();
        let good = VolFile {
            size: [2, 1, 2],
            channels: 1,
            bbox_min: [0.0; 3],
            bbox_max: [1.0; 3],
            data: vec![0.0, 1.0, 2.0, 3.0],
        };
        let bytes = good.to_bytes();
        assert_eq!(read_vol(&write(dir.path(), "g.vol", &bytes)).unwrap(), good);
        let mut trailing = bytes.clone();
        trailing.extend_from_slice(&[1, 2, 3]);
        assert_eq!(
            read_vol(&write(dir.path(), "t.vol", &trailing)).unwrap(),
            good
        );
        let cases: Vec<(Vec<u8>, &str)> = vec![
            (bytes[..bytes.len() - 1].to_vec(), "truncated"),
            (bytes[..20].to_vec(), "header"),
            ([b"VOX".as_slice(), &bytes[3..]].concat(), "'VOL'"),
            ([&bytes[..3], &[2u8], &bytes[4..]].concat(), "version 2"),
            (
                [&bytes[..4], &2i32.to_le_bytes(), &bytes[8..]].concat(),
                "encoding 2",
            ),
            (
                [&bytes[..8], &0i32.to_le_bytes(), &bytes[12..]].concat(),
                "positive",
            ),
            (
                [&bytes[..8], &(-3i32).to_le_bytes(), &bytes[12..]].concat(),
                "positive",
            ),
            (
                [&bytes[..20], &6i32.to_le_bytes(), &bytes[24..]].concat(),
                "6 channels",
            ),
            (
                [
                    &bytes[..8],
                    &i32::MAX.to_le_bytes(),
                    &i32::MAX.to_le_bytes(),
                    &i32::MAX.to_le_bytes(),
                    &bytes[20..],
                ]
                .concat(),
                "truncated",
            ),
            (
                [&bytes[..48 + 8], &f32::NAN.to_le_bytes(), &bytes[48 + 12..]].concat(),
                "non-finite value NaN at voxel (x 0, y 0, z 1), channel 0",
            ),
            (
                [
                    &bytes[..48 + 4],
                    &f32::INFINITY.to_le_bytes(),
                    &bytes[48 + 8..],
                ]
                .concat(),
                "non-finite value inf at voxel (x 1, y 0, z 0)",
            ),
        ];
        for (i, (b, want)) in cases.iter().enumerate() {
            let e = read_vol(&write(dir.path(), &format!("c{i}.vol"), b)).unwrap_err();
            assert!(e.to_string().contains(want), "case {i}: {e}");
        }
        assert!(read_vol(dir.path())
            .unwrap_err()
            .to_string()
            .contains("directory"));
    }
}
