//! A user's float array (a denoised volume, a reference, a reconstruction: f32 or f64
//! `.npy`) read as f32 a band of its first axis at a time, through the hardened
//! reader of [`super::npy`]: the header is checked against the file before anything is
//! allocated, non-regular files are refused before they are opened, and every value is
//! checked finite as f32 while it is read (an f64 beyond the f32 range counts as
//! infinite). The caller holds one band, never the whole array, so commands that
//! reduce a volume (`nlos mip`, `view`, `nlos reconstruct --denoised`) work in memory
//! bounded by the band, whatever the file's size.

use super::npy::{self, first_bad, show, Bad, NpyError, NpyFile};
use std::ops::Range;
use std::path::Path;

/// An open `.npy` array of f32 or f64.
pub struct FloatRows {
    file: NpyFile,
    /// f64 files: the band as read, before conversion (reused).
    wide: Vec<f64>,
}

impl FloatRows {
    /// Opens `path`: a regular file whose header declares f32 or f64 (any shape).
    pub fn open(path: &Path) -> Result<FloatRows, NpyError> {
        let file = npy::open(path)?;
        match file.header.dtype.as_str() {
            "<f4" | "<f8" => Ok(FloatRows {
                file,
                wide: Vec::new(),
            }),
            d => Err(NpyError::UnexpectedDtype {
                found: d.to_string(),
                expected: "<f4",
            }),
        }
    }

    pub fn shape(&self) -> &[usize] {
        &self.file.header.shape
    }

    /// Values per index of the first axis.
    pub fn row_len(&self) -> usize {
        self.file.row_len()
    }

    /// Bytes one row takes in memory while being read (f64 files are converted from a
    /// second buffer).
    pub fn row_bytes(&self) -> u64 {
        let per = if self.file.header.dtype == "<f8" {
            4 + 8
        } else {
            4
        };
        self.row_len() as u64 * per
    }

    /// Reads rows `rows` of the first axis into `out` (cleared first) as f32, C order;
    /// a value that is not finite as f32 ends the read with an error naming its index
    /// in the whole array on `axes`.
    pub fn read_rows(
        &mut self,
        rows: Range<usize>,
        out: &mut Vec<f32>,
        axes: &[&str],
    ) -> Result<(), NpyError> {
        if self.file.header.dtype == "<f4" {
            let check = |s: usize, b: &[f32]| -> Bad {
                first_bad(s, b, |_, v| v.is_finite(), |_, v| not_finite(v.into()))
            };
            return self.file.read_rows::<f32>(rows, out, check, axes);
        }
        let check = |s: usize, b: &[f64]| -> Bad {
            first_bad(s, b, |_, v| (v as f32).is_finite(), |_, v| not_finite(v))
        };
        self.file
            .read_rows::<f64>(rows, &mut self.wide, check, axes)?;
        out.clear();
        out.extend(self.wide.iter().map(|&v| v as f32));
        Ok(())
    }
}

fn not_finite(v: f64) -> String {
    if v.is_finite() {
        format!("is {}, beyond the f32 range", show(v))
    } else {
        format!("is {}", show(v))
    }
}

/// Bands of at most `max_bytes / row_bytes` rows (at least one) covering `0..rows`.
pub fn bands(rows: usize, row_bytes: u64, max_bytes: u64) -> impl Iterator<Item = Range<usize>> {
    let per = (max_bytes / row_bytes.max(1)).clamp(1, rows.max(1) as u64) as usize;
    (0..rows).step_by(per).map(move |r| r..(r + per).min(rows))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, name: &str, header: &str, data: &[u8]) -> std::path::PathBuf {
        let mut h = header.to_string();
        while !(10 + h.len() + 1).is_multiple_of(64) {
            h.push(' ');
        }
        h.push('\n');
        let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
        bytes.extend((h.len() as u16).to_le_bytes());
        bytes.extend(h.as_bytes());
        bytes.extend(data);
        let p = dir.join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    }

    #[test]
    fn f32_and_f64_rows_read_alike_band_by_band() {
        let dir = tempfile::tempdir().unwrap();
        let v: Vec<f64> = (0..24).map(|i| i as f64 * 0.5 - 3.0).collect();
        let f8: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
        let f4: Vec<u8> = v.iter().flat_map(|&x| (x as f32).to_le_bytes()).collect();
        let h8 = "{'descr': '<f8', 'fortran_order': False, 'shape': (4, 3, 2), }";
        let h4 = "{'descr': '<f4', 'fortran_order': False, 'shape': (4, 3, 2), }";
        for p in [
            write(dir.path(), "a.npy", h8, &f8),
            write(dir.path(), "b.npy", h4, &f4),
        ] {
            let mut a = FloatRows::open(&p).unwrap();
            assert_eq!(a.shape(), &[4, 3, 2]);
            assert_eq!(a.row_len(), 6);
            let mut all = Vec::new();
            let mut band = Vec::new();
            for r in bands(4, a.row_bytes(), 2 * a.row_bytes()) {
                a.read_rows(r, &mut band, &["x", "y", "z"]).unwrap();
                all.extend_from_slice(&band);
            }
            let want: Vec<f32> = v.iter().map(|&x| x as f32).collect();
            assert_eq!(all, want);
        }
    }

    #[test]
    fn non_finite_values_and_other_dtypes_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let mut v = [1.0f64; 6];
        v[4] = 1e300;
        let f8: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
        let h8 = "{'descr': '<f8', 'fortran_order': False, 'shape': (2, 3), }";
        let p = write(dir.path(), "a.npy", h8, &f8);
        let mut a = FloatRows::open(&p).unwrap();
        let e = a.read_rows(0..2, &mut Vec::new(), &["x", "y"]).unwrap_err();
        assert_eq!(
            e.to_string(),
            "element (x 1, y 1) is 1e300, beyond the f32 range"
        );
        let mut w = vec![0u8; 8];
        w[4..].copy_from_slice(&f32::NAN.to_le_bytes());
        let h4 = "{'descr': '<f4', 'fortran_order': False, 'shape': (2,), }";
        let p = write(dir.path(), "n.npy", h4, &w);
        let e = FloatRows::open(&p)
            .unwrap()
            .read_rows(0..2, &mut Vec::new(), &["x"])
            .unwrap_err();
        assert_eq!(e.to_string(), "element (x 1) is NaN");
        let hu = "{'descr': '<u4', 'fortran_order': False, 'shape': (2,), }";
        let p = write(dir.path(), "u.npy", hu, &[0; 8]);
        assert!(matches!(
            FloatRows::open(&p),
            Err(NpyError::UnexpectedDtype { ref found, expected: "<f4" }) if found == "<u4"
        ));
    }

    #[test]
    fn bands_cover_every_row_once() {
        for (rows, per_row, max) in [(0, 8, 100), (1, 8, 1), (10, 8, 24), (10, 8, 1 << 30)] {
            let b: Vec<_> = bands(rows, per_row, max).collect();
            let flat: Vec<usize> = b.iter().flat_map(|r| r.clone()).collect();
            assert_eq!(flat, (0..rows).collect::<Vec<_>>());
            assert!(b.iter().all(|r| !r.is_empty()));
        }
    }
}
