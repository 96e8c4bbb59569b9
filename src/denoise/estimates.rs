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
//! Memory: 3 x H x W x T x 3 x 4 bytes (177 MB for 128 x 128 x 300).

use crate::stats::accumulators::CHANNELS;
use crate::stats::estimators::{estimate, Sums};
use rayon::prelude::*;

pub struct Estimates {
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
    pub mean: Vec<f32>,
    pub theta: Vec<f32>,
    pub v: Vec<f32>,
}

/// The raw sums of a bundle, (H, W, T, C) row-major, as stored on disk.
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
    /// Index of (pixel, channel, bin) in the planar layout.
    #[inline]
    pub fn idx(&self, pixel: usize, c: usize, t: usize) -> usize {
        (pixel * CHANNELS + c) * self.bins + t
    }

    pub fn from_sums(s: &SumsView) -> Estimates {
        let (t_bins, n) = (s.bins, s.spp);
        let per_pixel = CHANNELS * t_bins;
        let len = s.height * s.width * per_pixel;
        let mut mean = vec![0.0f32; len];
        let mut theta = vec![0.0f32; len];
        let mut v = vec![0.0f32; len];
        mean.par_chunks_mut(per_pixel)
            .zip(theta.par_chunks_mut(per_pixel))
            .zip(v.par_chunks_mut(per_pixel))
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
        Estimates {
            height: s.height,
            width: s.width,
            bins: s.bins,
            bin_width: s.bin_width,
            spp: s.spp,
            stratified: s.stratified,
            mean,
            theta,
            v,
        }
    }
}
