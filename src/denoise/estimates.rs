//! The per-voxel quantities the filter needs, derived once from the sums (SPEC 5) and
//! stored planar, (H, W, C, T) in f32, so the filter's inner loop over bins reads
//! contiguous memory:
//! - `mean = S / n`, the radiance mean that is averaged;
//! - `theta`, the skewness-corrected mean of the transformed samples, that is tested,
//!   stored as `theta - z(0)`: the test uses only differences, and the shift keeps
//!   Box-Cox's large `z(0) = -1/lambda` out of the f32 values (precision, and no
//!   overflow for tiny lambda);
//! - `v = sigma^2 / n`, the variance of theta's estimate.
//!
//! Memory: 3 x H x W x T x 3 x 4 bytes for a whole volume (177 MB for 128 x 128 x
//! 300). A slab of the image holds only its rows (see `slab.rs`): [`Estimates::rows`]
//! says which, and pixel indices stay those of the whole image.

use crate::stats::accumulators::CHANNELS;
use crate::stats::estimators::{estimate, Sums};
use rayon::prelude::*;
use std::ops::Range;

pub struct Estimates {
    /// Image height H (the rows held are `rows`).
    pub height: usize,
    pub width: usize,
    pub bins: usize,
    /// Bin width h in OPL (scene units).
    pub bin_width: f64,
    /// Samples per pixel behind the estimates.
    pub spp: u64,
    /// Sub-pixel positions were stratified: `v` over-estimates the variance of the
    /// mean (most at edges, where coverage noise dominates).
    pub stratified: bool,
    /// The image rows held, `0..height` for a whole volume.
    pub rows: Range<usize>,
    pub mean: Vec<f32>,
    pub theta: Vec<f32>,
    pub v: Vec<f32>,
}

/// The raw sums of a bundle, (H, W, T, C) row-major, as stored on disk; or of a band
/// of its rows (then `height` is the band's).
pub struct SumsView<'a> {
    pub height: usize,
    pub width: usize,
    pub bins: usize,
    /// Bin width h in OPL (scene units).
    pub bin_width: f64,
    pub spp: u64,
    /// Sub-pixel positions were stratified (the renders' `pixel_sampling`).
    pub stratified: bool,
    /// z(0) of the transform the sums were taken with.
    pub z0: f64,
    pub x1: &'a [f64],
    pub x2: &'a [f64],
    pub x3: &'a [f64],
    /// Raw radiance sums; X1 for the identity transform.
    pub sum: &'a [f64],
    pub nonzero: &'a [u32],
}

impl Estimates {
    /// Index of (pixel, channel, bin) in the planar layout; `pixel` is the image's
    /// row-major pixel index, which must lie in a row held.
    #[inline]
    pub fn idx(&self, pixel: usize, c: usize, t: usize) -> usize {
        ((pixel - self.rows.start * self.width) * CHANNELS + c) * self.bins + t
    }

    /// Values per image row in each of `mean`, `theta` and `v`.
    pub fn row_len(&self) -> usize {
        self.width * CHANNELS * self.bins
    }

    /// The estimates of a whole volume.
    pub fn from_sums(s: &SumsView) -> Estimates {
        let mut e = Estimates::empty(s.height, s);
        e.push_rows(s);
        e
    }

    /// No rows yet of an image `height` rows high with the sizes and sampling of `s`.
    pub fn empty(height: usize, s: &SumsView) -> Estimates {
        Estimates {
            height,
            width: s.width,
            bins: s.bins,
            bin_width: s.bin_width,
            spp: s.spp,
            stratified: s.stratified,
            rows: 0..0,
            mean: Vec::new(),
            theta: Vec::new(),
            v: Vec::new(),
        }
    }

    /// Room for `rows` rows without reallocating (a slab and its halo).
    pub fn reserve_rows(&mut self, rows: usize) {
        let n = rows * self.row_len();
        for a in [&mut self.mean, &mut self.theta, &mut self.v] {
            a.reserve_exact(n.saturating_sub(a.len()));
        }
    }

    /// Forgets the rows above row `y`; with `y` past the rows held, forgets them all
    /// and the next rows pushed are `y` on.
    pub fn drop_rows_before(&mut self, y: usize) {
        let keep = y.clamp(self.rows.start, self.rows.end);
        let n = (keep - self.rows.start) * self.row_len();
        for a in [&mut self.mean, &mut self.theta, &mut self.v] {
            a.drain(..n);
        }
        self.rows = if y >= self.rows.end {
            y..y
        } else {
            keep..self.rows.end
        };
    }

    /// Appends the estimates of `s`, the sums of the `s.height` rows that follow the
    /// rows held. Each voxel's estimate depends on its own sums alone, so the values
    /// are those of a whole-volume [`Estimates::from_sums`], bit for bit.
    pub fn push_rows(&mut self, s: &SumsView) {
        let (t_bins, n) = (s.bins, s.spp);
        let per_pixel = CHANNELS * t_bins;
        let start = self.mean.len();
        let len = s.height * s.width * per_pixel;
        for a in [&mut self.mean, &mut self.theta, &mut self.v] {
            a.resize(start + len, 0.0);
        }
        self.mean[start..]
            .par_chunks_mut(per_pixel)
            .zip(self.theta[start..].par_chunks_mut(per_pixel))
            .zip(self.v[start..].par_chunks_mut(per_pixel))
            .enumerate()
            .for_each(|(p, ((mean, theta), v))| {
                for t in 0..t_bins {
                    let voxel = p * t_bins + t;
                    let nonzero = s.nonzero[voxel];
                    for c in 0..CHANNELS {
                        let k = voxel * CHANNELS + c;
                        let e = estimate(
                            Sums {
                                x1: s.x1[k],
                                x2: s.x2[k],
                                x3: s.x3[k],
                            },
                            nonzero,
                            n,
                            s.z0,
                        );
                        let o = c * t_bins + t;
                        mean[o] = (s.sum[k] / n as f64) as f32;
                        theta[o] = (e.theta - s.z0) as f32;
                        v[o] = e.v as f32;
                    }
                }
            });
        self.rows.end += s.height;
    }
}
