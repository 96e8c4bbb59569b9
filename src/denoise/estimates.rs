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
//! f32 holds about 1e-38..3e38, and `v` is a square: radiance of 1e20 (or 1e-20) would
//! overflow (or underflow) `v` and the t-test's squared differences, and the filter
//! would silently accept (or reject) every neighbour. So the values are stored in
//! units of a power of two ([`Scale`], fixed from the largest magnitudes of the whole
//! volume, [`Magnitudes::scan`]): `mean` divided by `2^Scale::mean`, `theta` by
//! `2^Scale::theta` and `v` by its square. Scaling by a power of two is exact in
//! floating point and the filter is homogeneous (its output is a weighted average of
//! `mean`, its weights depend on `(theta_i - theta_j)^2 / (v_i + v_j)`), so the output,
//! multiplied back by `2^Scale::mean`, is bit for bit that of unscaled arithmetic
//! wherever that does not overflow or underflow, and right where it would.
//!
//! The film's C channels (3 for RGB and spectral, 1 mono, 4 for the Stokes components
//! S0..S3 of a polarized render; `channels`) are estimated alike, each from its own
//! sums: nothing here assumes a sign (Stokes S1..S3, and spectral samples, may be
//! negative; the transform, Yeo-Johnson or the identity for signed modes, is defined
//! on the whole line).
//!
//! Memory: 3 x H x W x T x C x 4 bytes for a whole volume (177 MB for 128 x 128 x
//! 300 x 3). A slab of the image holds only its rows (see `slab.rs`): [`Estimates::rows`]
//! says which, and pixel indices stay those of the whole image.

use super::conventions::Variance;
use crate::stats::estimators::{estimate, estimate_biased, estimate_replicates, Sums};
use rayon::prelude::*;
use std::ops::Range;

pub struct Estimates {
    /// Image height H (the rows held are `rows`).
    pub height: usize,
    pub width: usize,
    pub bins: usize,
    /// C: channels per voxel (1, 3 or 4; see the module docs).
    pub channels: usize,
    /// Bin width h in OPL (scene units).
    pub bin_width: f64,
    /// Samples per pixel behind the estimates (the mean, for adaptive renders).
    pub spp: u64,
    /// Each pixel's samples (row-major over the whole image) of an adaptive render.
    pub pixel_spp: Option<std::sync::Arc<[u32]>>,
    /// Replicates B behind `v` (SPEC 5), if the bundle has them.
    pub replicates: Option<u64>,
    /// Sub-pixel positions were stratified: `v` over-estimates the variance of the
    /// mean (most at edges, where coverage noise dominates).
    pub stratified: bool,
    /// Rows per independent image (see [`SumsView::image_rows`]).
    pub image_rows: usize,
    /// The image rows held, `0..height` for a whole volume.
    pub rows: Range<usize>,
    /// The powers of two `mean`, `theta` and `v` are stored in.
    pub scale: Scale,
    /// z(0) of the transform (`theta` is stored as `theta - z(0)`).
    pub z0: f64,
    /// Which variance the estimates use (set before rows are pushed).
    pub variance: Variance,
    pub mean: Vec<f32>,
    pub theta: Vec<f32>,
    pub v: Vec<f32>,
}

/// Bounds on the largest magnitudes of a volume's estimates: `mean` is the largest
/// `|S / n|`, `theta` the largest root mean square of `z - z(0)` over a voxel's `n`
/// samples, which bounds `|theta - z(0)|` (within 1.2: the skewness correction is at
/// most `rms / (6 sqrt(n))`) and `sqrt(v)`. Bounds within a small factor suffice: any
/// power-of-two scale that neither overflows nor underflows gives the same bits.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Magnitudes {
    pub mean: f64,
    pub theta: f64,
}

impl Magnitudes {
    /// The bounds over every voxel of `s` (a few operations a value, no estimates).
    pub fn scan(s: &SumsView) -> Magnitudes {
        let c = s.z0;
        let ch = s.channels;
        let per_pixel = ch * s.bins;
        let (mean, y2) = (0..s.height * s.width)
            .into_par_iter()
            .map(|p| {
                let nf = s.samples(p) as f64;
                let (mut mean, mut y2) = (0f64, 0f64);
                for k in p * per_pixel..(p + 1) * per_pixel {
                    let mc = f64::from(s.nonzero[k / ch]) * c;
                    mean = mean.max((s.sum[k] / nf).abs());
                    // Sum of (z - c)^2 over the n samples, as in `estimate`, per sample.
                    y2 = y2.max((s.x2[k] - 2.0 * c * s.x1[k] + mc * c).abs() / nf);
                }
                (mean, y2)
            })
            .reduce(|| (0.0, 0.0), |a, b| (a.0.max(b.0), a.1.max(b.1)));
        Magnitudes {
            mean,
            theta: y2.sqrt(),
        }
    }

    /// The larger of each magnitude (of two parts of one volume).
    pub fn max(self, o: Magnitudes) -> Magnitudes {
        Magnitudes {
            mean: self.mean.max(o.mean),
            theta: self.theta.max(o.theta),
        }
    }
}

/// The powers of two the f32 estimates are stored in: `mean / 2^mean`,
/// `(theta - z(0)) / 2^theta` and `v / 2^(2 theta)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Scale {
    pub mean: i32,
    pub theta: i32,
}

impl Scale {
    /// No scaling.
    pub const UNIT: Scale = Scale { mean: 0, theta: 0 };

    /// The scale that brings the largest magnitude of each kind into [1, 2), so that
    /// nothing overflows and only values 2^-126 below the largest reach f32's
    /// subnormals.
    pub fn of(m: Magnitudes) -> Scale {
        Scale {
            mean: exponent(m.mean),
            theta: exponent(m.theta),
        }
    }

    /// The factor the filtered means are multiplied by to undo the scale.
    pub fn unscale_mean(&self) -> f64 {
        pow2(self.mean)
    }
}

/// floor(log2 x) for finite x > 0 (0 otherwise), clamped to +-500 so that `v`'s
/// factor `2^(-2 theta)` is an exact f64 too.
fn exponent(x: f64) -> i32 {
    if x > 0.0 && x.is_finite() {
        (x.log2().floor() as i32).clamp(-500, 500)
    } else {
        0
    }
}

/// 2^e, exact for |e| <= 1022.
fn pow2(e: i32) -> f64 {
    2f64.powi(e)
}

/// One voxel-channel's `(S / n, theta - z(0), v)` in f64.
#[inline]
fn voxel_estimate(s: &SumsView, voxel: usize, c: usize, biased: bool) -> (f64, f64, f64) {
    let k = voxel * s.channels + c;
    let spp = s.samples(voxel / s.bins);
    if let Some((b, r2)) = s.replicates {
        let e = estimate_replicates(s.x1[k], r2[k], s.nonzero[voxel], spp, b, s.z0);
        return (s.sum[k] / spp as f64, e.theta - s.z0, e.v);
    }
    let sums = Sums {
        x1: s.x1[k],
        x2: s.x2[k],
        x3: s.x3[k],
    };
    // A voxel no sample reached (most of them at low spp) is the estimate of zero
    // sums: mean 0, theta - z0 = 0, V = 0; the same bits `estimate` gives.
    if s.nonzero[voxel] == 0
        && sums.x1 == 0.0
        && sums.x2 == 0.0
        && sums.x3 == 0.0
        && s.sum[k] == 0.0
    {
        return (0.0, 0.0, 0.0);
    }
    let e = if biased {
        estimate_biased(sums, s.nonzero[voxel], spp, s.z0)
    } else {
        estimate(sums, s.nonzero[voxel], spp, s.z0)
    };
    (s.sum[k] / spp as f64, e.theta - s.z0, e.v)
}

/// The raw sums of a bundle, (H, W, T, C) row-major, as stored on disk; or of a band
/// of its rows (then `height` is the band's).
pub struct SumsView<'a> {
    pub height: usize,
    pub width: usize,
    pub bins: usize,
    /// C: channels per voxel (the bundle's `Manifest::channel_count`).
    pub channels: usize,
    /// Bin width h in OPL (scene units).
    pub bin_width: f64,
    pub spp: u64,
    /// Sub-pixel positions were stratified (the renders' `pixel_sampling`).
    pub stratified: bool,
    /// Rows per independent image: `height` but for an exhaustive NLOS capture, whose
    /// film stacks one image per laser point (no neighbourhood crosses an image's edge).
    pub image_rows: usize,
    /// z(0) of the transform the sums were taken with.
    pub z0: f64,
    pub x1: &'a [f64],
    pub x2: &'a [f64],
    pub x3: &'a [f64],
    /// Raw radiance sums; X1 for the identity transform.
    pub sum: &'a [f64],
    pub nonzero: &'a [u32],
    /// Replicate statistics: B and R2 (SPEC 5); then V comes from the replicates.
    pub replicates: Option<(u64, &'a [f64])>,
    /// Each pixel's samples for the view's rows (adaptive renders); `None`: `spp`.
    pub pixel_spp: Option<&'a [u32]>,
}

impl SumsView<'_> {
    /// The samples of the view's pixel `p` (row-major within the view).
    #[inline]
    pub fn samples(&self, p: usize) -> u64 {
        self.pixel_spp.map_or(self.spp, |n| u64::from(n[p]))
    }
}

impl Estimates {
    /// Index of (pixel, channel, bin) in the planar layout; `pixel` is the image's
    /// row-major pixel index, which must lie in a row held.
    #[inline]
    pub fn idx(&self, pixel: usize, c: usize, t: usize) -> usize {
        ((pixel - self.rows.start * self.width) * self.channels + c) * self.bins + t
    }

    /// Entry `k` of `mean`, `theta` and `v` in the sums' own units (undoing
    /// [`Scale`]), in f64.
    pub fn unscaled(&self, k: usize) -> (f64, f64, f64) {
        let th = pow2(self.scale.theta);
        (
            f64::from(self.mean[k]) * pow2(self.scale.mean),
            f64::from(self.theta[k]) * th,
            f64::from(self.v[k]) * th * th,
        )
    }

    /// `mean` in radiance units, as the filter outputs it.
    pub fn mean_in_radiance(&self) -> Vec<f32> {
        let u = self.scale.unscale_mean();
        self.mean
            .iter()
            .map(|&m| (f64::from(m) * u) as f32)
            .collect()
    }

    /// Values per image row in each of `mean`, `theta` and `v`.
    pub fn row_len(&self) -> usize {
        self.width * self.channels * self.bins
    }

    /// The estimates of a whole volume.
    pub fn from_sums(s: &SumsView) -> Estimates {
        Estimates::from_sums_as(s, Variance::Unbiased)
    }

    /// The estimates of a whole volume with the variance convention `variance`.
    pub fn from_sums_as(s: &SumsView, variance: Variance) -> Estimates {
        let mut e = Estimates::empty(s.height, s, Scale::of(Magnitudes::scan(s)));
        e.pixel_spp = s.pixel_spp.map(Into::into);
        e.variance = variance;
        e.push_rows(s);
        e
    }

    /// The samples of the image's pixel `p` (row-major).
    #[inline]
    pub fn samples(&self, p: usize) -> u64 {
        self.pixel_spp
            .as_ref()
            .map_or(self.spp, |n| u64::from(n[p]))
    }

    /// No rows yet of an image `height` rows high with the sizes and sampling of `s`,
    /// to be stored in `scale` (that of the whole volume's [`Magnitudes`]).
    pub fn empty(height: usize, s: &SumsView, scale: Scale) -> Estimates {
        Estimates {
            height,
            width: s.width,
            bins: s.bins,
            channels: s.channels,
            bin_width: s.bin_width,
            spp: s.spp,
            pixel_spp: None,
            replicates: s.replicates.map(|(b, _)| b),
            stratified: s.stratified,
            image_rows: s.image_rows,
            rows: 0..0,
            scale,
            z0: s.z0,
            variance: Variance::Unbiased,
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
        let t_bins = s.bins;
        let ch = s.channels;
        assert_eq!(ch, self.channels, "rows of another channel count");
        let per_pixel = ch * t_bins;
        let len = s.height * s.width * per_pixel;
        for a in [&mut self.mean, &mut self.theta, &mut self.v] {
            a.reserve(len);
        }
        let (to_mean, to_theta) = (pow2(-self.scale.mean), pow2(-self.scale.theta));
        let to_v = to_theta * to_theta;
        let biased = self.variance == Variance::Biased;
        // Written straight into the spare capacity by the workers (no serial zero-fill:
        // the first touch of the new pages is spread over the threads).
        let mean = &mut self.mean.spare_capacity_mut()[..len];
        let theta = &mut self.theta.spare_capacity_mut()[..len];
        let v = &mut self.v.spare_capacity_mut()[..len];
        mean.par_chunks_mut(per_pixel)
            .zip(theta.par_chunks_mut(per_pixel))
            .zip(v.par_chunks_mut(per_pixel))
            .enumerate()
            .for_each(|(p, ((mean, theta), v))| {
                for t in 0..t_bins {
                    let voxel = p * t_bins + t;
                    for c in 0..ch {
                        let (m, th, var) = voxel_estimate(s, voxel, c, biased);
                        let o = c * t_bins + t;
                        mean[o].write((m * to_mean) as f32);
                        theta[o].write((th * to_theta) as f32);
                        v[o].write((var * to_v) as f32);
                    }
                }
            });
        for a in [&mut self.mean, &mut self.theta, &mut self.v] {
            // SAFETY: the loop above wrote every one of the `len` slots: `per_pixel`
            // values (each (t, c) once) for each of the `len / per_pixel` pixels.
            unsafe { a.set_len(a.len() + len) };
        }
        self.rows.end += s.height;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shortcut for voxels no sample reached gives the bits `estimate` gives for
    /// zero sums, under the identity and under transforms with z(0) of either sign.
    #[test]
    fn an_empty_voxel_is_the_estimate_of_zero_sums() {
        let zeros = [0.0f64; 3];
        for z0 in [0.0, -0.0, 0.75, -1.25] {
            for n in [2u64, 3, 64, 1 << 20] {
                let view = SumsView {
                    height: 1,
                    width: 1,
                    bins: 1,
                    channels: 3,
                    bin_width: 1.0,
                    spp: n,
                    stratified: false,
                    image_rows: 1,
                    z0,
                    x1: &zeros,
                    x2: &zeros,
                    x3: &zeros,
                    sum: &zeros,
                    nonzero: &[0],
                    replicates: None,
                    pixel_spp: None,
                };
                let e = estimate(
                    Sums {
                        x1: 0.0,
                        x2: 0.0,
                        x3: 0.0,
                    },
                    0,
                    n,
                    z0,
                );
                let want = (0.0 / n as f64, e.theta - z0, e.v);
                let got = voxel_estimate(&view, 0, 0, false);
                assert_eq!(got, voxel_estimate(&view, 0, 0, true));
                assert_eq!(
                    [got.0.to_bits(), got.1.to_bits(), got.2.to_bits()],
                    [want.0.to_bits(), want.1.to_bits(), want.2.to_bits()],
                    "z0 {z0}, n {n}"
                );
            }
        }
    }
}
