//! Per-voxel sample sums, filled while rendering (SPEC 5).
//!
//! For every voxel (y, x, t) and channel c: `X1 = sum z`, `X2 = sum z^2`, `X3 = sum z^3`
//! over the paths that deposited something there (one flushed sample per path), the
//! raw radiance sum `S` when the transform is not the identity, and a u32 count of
//! those paths (`nonzero`). Paths that deposited nothing are the implicit zero samples
//! the estimators add back (zero-fill).
//!
//! Memory: `H * W * T * C * 8` bytes per f64 array (3 arrays, 4 with S) plus
//! `H * W * T * 4` for the counts. A 128 x 128 x 300 x 3 film needs 354 MB (identity).

use super::transform::Transform;

pub const CHANNELS: usize = 3;

/// The volume-sized sums of one render, laid out (H, W, T, C) row-major.
pub struct Accumulators {
    pub height: usize,
    pub width: usize,
    pub bins: usize,
    pub x1: Vec<f64>,
    pub x2: Vec<f64>,
    pub x3: Vec<f64>,
    /// Raw radiance sums; `None` for the identity transform (S = X1).
    pub sum: Option<Vec<f64>>,
    pub nonzero: Vec<u32>,
}

impl Accumulators {
    /// Bytes needed for a film of this size with this transform (saturating, so absurd
    /// sizes compare as too large instead of wrapping).
    pub fn bytes(height: usize, width: usize, bins: usize, transform: &Transform) -> u64 {
        let arrays: u128 = if transform.is_identity() { 3 } else { 4 };
        let voxels = height as u128 * width as u128 * bins as u128;
        let b = voxels * CHANNELS as u128 * 8 * arrays + voxels * 4;
        u64::try_from(b).unwrap_or(u64::MAX)
    }

    pub fn new(height: usize, width: usize, bins: usize, transform: &Transform) -> Self {
        let n = height * width * bins * CHANNELS;
        Accumulators {
            height,
            width,
            bins,
            x1: vec![0.0; n],
            x2: vec![0.0; n],
            x3: vec![0.0; n],
            sum: (!transform.is_identity()).then(|| vec![0.0; n]),
            nonzero: vec![0u32; height * width * bins],
        }
    }

    /// Disjoint mutable views of each image row, for parallel rendering.
    pub fn rows_mut(&mut self) -> Vec<RowAccum<'_>> {
        let row = self.width * self.bins * CHANNELS;
        let row_counts = self.width * self.bins;
        let width = self.width;
        let bins = self.bins;
        let mut sums: Vec<Option<&mut [f64]>> = match self.sum.as_mut() {
            Some(s) => s.chunks_mut(row).map(Some).collect(),
            None => (0..self.height).map(|_| None).collect(),
        };
        self.x1
            .chunks_mut(row)
            .zip(self.x2.chunks_mut(row))
            .zip(self.x3.chunks_mut(row))
            .zip(self.nonzero.chunks_mut(row_counts))
            .zip(sums.iter_mut())
            .map(|((((x1, x2), x3), nonzero), sum)| RowAccum {
                width,
                bins,
                x1,
                x2,
                x3,
                sum: sum.take(),
                nonzero,
            })
            .collect()
    }
}

/// The sums of one image row.
pub struct RowAccum<'a> {
    pub width: usize,
    pub bins: usize,
    pub x1: &'a mut [f64],
    pub x2: &'a mut [f64],
    pub x3: &'a mut [f64],
    pub sum: Option<&'a mut [f64]>,
    pub nonzero: &'a mut [u32],
}

impl RowAccum<'_> {
    /// Adds one path's total deposit `x` (rgb radiance) in voxel (x, bin) as one sample.
    #[inline]
    pub fn add_sample(
        &mut self,
        z: impl Fn(f64) -> f64,
        px: usize,
        bin: usize,
        x: [f64; CHANNELS],
    ) {
        let v = px * self.bins + bin;
        self.nonzero[v] += 1;
        let base = v * CHANNELS;
        for (c, &xc) in x.iter().enumerate() {
            let zc = z(xc);
            let z2 = zc * zc;
            self.x1[base + c] += zc;
            self.x2[base + c] += z2;
            self.x3[base + c] += z2 * zc;
        }
        if let Some(s) = self.sum.as_deref_mut() {
            for (c, &xc) in x.iter().enumerate() {
                s[base + c] += xc;
            }
        }
    }
}
