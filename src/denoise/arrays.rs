//! Arrays in: the filter on per-voxel estimates someone else computed (the published
//! pipeline's arrays, `bundle::published`) instead of a bundle's sums.
//!
//! The filter needs, per voxel, the radiance mean it averages, theta (tested) and V,
//! and per pixel the G-buffers; the sums X1, X2, X3 and the counts only serve to make
//! theta and V (SPEC 5: the zero-fill, the skewness correction from X3). Given theta
//! and V, nothing of the filter is lost: on arrays exported from a bundle whose
//! transform has z(0) = 0 (identity, Yeo-Johnson), the output is bit for bit `tstat
//! denoise` of the bundle (tested). What the arrays cannot give:
//! - another variance convention or transform (theta and V are fixed: `--variance`
//!   is refused), replicates, and the bundle's per-pixel counts unless
//!   `pixel_spp.npy` is given;
//! - without `emitter.npy`, tstat's emitter class (pixels that see a light are
//!   treated as the rest); without `depth.npy` (and the bin width), its camera-depth
//!   alignment. The published pipeline's arrays have neither: their cost in error is
//!   measured in docs/python.md.
//!
//! Memory: the three input volumes and the estimates made from them (24 bytes a
//! voxel-channel), then the output (4 more).

use super::base_filter::Features;
use super::estimates::{Estimates, Magnitudes, Scale};
use super::{denoise_estimates, DenoiseParams, Denoised, Variance};
use crate::bundle::published::PublishedArrays;
use crate::stats::Transform;
use ndarray::Array2;

/// What the arrays do not say, from `meta.json` or the command line.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ArraysSettings {
    pub spp: u64,
    pub transform: Transform,
    pub stratified: bool,
    /// The bin width in OPL (camera-depth alignment needs it with a depth image).
    pub bin_width_opl: Option<f64>,
}

/// Bytes [`denoise_arrays`] holds at its peak for `voxels` voxel-channels (besides the
/// G-buffers): the inputs, their estimates and the output.
pub fn memory_bytes(voxels: u64) -> u64 {
    voxels.saturating_mul(4 * 7)
}

/// The filter's estimates from the arrays (planar, scaled as `Estimates` keeps them).
pub fn estimates(a: &PublishedArrays, s: &ArraysSettings) -> Estimates {
    let (h, w, t, ch) = a.noisy.dim();
    let z0 = s.transform.at_zero();
    let slices =
        [&a.noisy, &a.estimands, &a.variance].map(|v| v.as_slice().expect("standard layout"));
    let mean_max = slices[0]
        .iter()
        .fold(0f64, |m, &v| m.max(f64::from(v).abs()));
    let theta_max = slices[1].iter().zip(slices[2]).fold(0f64, |m, (&th, &v)| {
        m.max((f64::from(th) - z0).abs()).max(f64::from(v).sqrt())
    });
    let scale = Scale::of(Magnitudes {
        mean: mean_max,
        theta: theta_max,
    });
    let to_mean = 2f64.powi(-scale.mean);
    let to_theta = 2f64.powi(-scale.theta);
    let to_v = to_theta * to_theta;
    let len = h * w * t * ch;
    let (mut mean, mut theta, mut v) = (vec![0f32; len], vec![0f32; len], vec![0f32; len]);
    // (H, W, T, C) in, planar (H, W, C, T) out.
    for p in 0..h * w {
        for k in 0..t {
            for c in 0..ch {
                let i = (p * t + k) * ch + c;
                let o = (p * ch + c) * t + k;
                mean[o] = (f64::from(slices[0][i]) * to_mean) as f32;
                theta[o] = ((f64::from(slices[1][i]) - z0) * to_theta) as f32;
                v[o] = (f64::from(slices[2][i]) * to_v) as f32;
            }
        }
    }
    Estimates {
        height: h,
        width: w,
        bins: t,
        channels: ch,
        bin_width: s.bin_width_opl.unwrap_or(0.0),
        spp: s.spp,
        pixel_spp: a.pixel_spp.as_ref().map(|n| n.as_slice().into()),
        replicates: None,
        stratified: s.stratified,
        image_rows: h,
        rows: 0..h,
        scale,
        z0,
        variance: Variance::Unbiased,
        mean,
        theta,
        v,
    }
}

/// Denoises the arrays with `params` (see the module docs for what is lost).
pub fn denoise_arrays(
    a: &PublishedArrays,
    s: &ArraysSettings,
    params: &DenoiseParams,
    progress: &(dyn Fn(u64) + Sync),
) -> Denoised {
    let start = std::time::Instant::now();
    let (h, w) = (a.noisy.dim().0, a.noisy.dim().1);
    let zeros = Array2::<f32>::zeros((h, w));
    // Without the bin width, depths cannot be turned into bin shifts: none are made.
    let depth = match (&a.depth, s.bin_width_opl) {
        (Some(d), Some(_)) => d,
        _ => &zeros,
    };
    let emitter = a.emitter.as_ref().unwrap_or(&zeros);
    let features = Features {
        albedo: a.albedo.as_slice().expect("standard layout"),
        normal: a.normals.as_slice().expect("standard layout"),
        depth: depth.as_slice().expect("standard layout"),
        emitter: emitter.as_slice().expect("standard layout"),
    };
    let est = estimates(a, s);
    let mut d = denoise_estimates(est, s.spp, &features, params, progress);
    d.seconds = start.elapsed().as_secs_f64();
    d
}
