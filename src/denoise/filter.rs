//! The fast statistical filter (SPEC 8):
//! `out_j = sum_i w_ij mean_i / sum_i w_ij`, `w_ij = p_ij m_ij`, over the neighbours i
//! with |dy|, |dx| <= r and |dt| <= r_t.
//!
//! Work is split into tiles: bands of image rows (run in parallel) cut into blocks of
//! pixels and ranges of bins; a tile reads its halo (r pixels, r_t bins) straight from
//! the shared read-only estimates. For each output pixel and neighbour pixel, the pixel
//! part of p is computed once and reused for every bin; the inner loop runs over
//! contiguous bins (planar layout) and vectorises. Each voxel's sums are accumulated
//! in the same neighbour order whatever the tiling or thread count, so the output is
//! bit-identical across both. Voxels whose whole neighbourhood is zero are skipped
//! (they are zero).

use super::base_filter::{BaseFilter, Features};
use super::estimates::Estimates;
use super::membership::passes;
use crate::stats::accumulators::CHANNELS;
use rayon::prelude::*;

#[derive(Clone, Copy, Debug)]
pub struct FilterParams {
    pub radius: usize,
    pub temporal_radius: usize,
    pub base: BaseFilter,
    /// g^2 of the membership test; `None` runs the base filter alone.
    pub g2: Option<f64>,
}

/// Tile shape: rows per band (the parallel unit), pixels per block, bins per range.
/// Default 8 x 16 pixels x 512 bins: on 128 x 128 x 300, 64-bin ranges ran at ~0.7 G
/// evaluations/s and whole-volume ranges at ~1.5 G (the per-neighbour set-up is paid
/// once per range); 512 caps the scratch and the per-neighbour footprint for long
/// volumes.
#[derive(Clone, Copy, Debug)]
pub struct Tiling {
    pub rows: usize,
    pub cols: usize,
    pub bins: usize,
}

impl Default for Tiling {
    fn default() -> Self {
        Tiling {
            rows: 8,
            cols: 16,
            bins: 512,
        }
    }
}

/// Per pixel, the first and one-past-last bin holding any non-zero estimate.
fn active_ranges(e: &Estimates) -> Vec<(usize, usize)> {
    let t = e.bins;
    (0..e.height * e.width)
        .into_par_iter()
        .map(|p| {
            let nz = |k: usize| {
                (0..CHANNELS).any(|c| {
                    let i = e.idx(p, c, k);
                    e.mean[i] != 0.0 || e.theta[i] != 0.0 || e.v[i] != 0.0
                })
            };
            match (0..t).find(|&k| nz(k)) {
                None => (0, 0),
                Some(lo) => (lo, (lo..t).rev().find(|&k| nz(k)).unwrap() + 1),
            }
        })
        .collect()
}

/// The inner loop: one neighbour pixel at one bin offset, over `n` contiguous bins.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn accumulate<const MEMBERSHIP: bool>(
    n: usize,
    w: f32,
    g2: f32,
    theta_i: [&[f32]; 3],
    theta_j: [&[f32]; 3],
    v_i: [&[f32]; 3],
    v_j: [&[f32]; 3],
    mean_i: [&[f32]; 3],
    num: [&mut [f32]; 3],
    den: &mut [f32],
) {
    let (ti0, ti1, ti2) = (&theta_i[0][..n], &theta_i[1][..n], &theta_i[2][..n]);
    let (tj0, tj1, tj2) = (&theta_j[0][..n], &theta_j[1][..n], &theta_j[2][..n]);
    let (vi0, vi1, vi2) = (&v_i[0][..n], &v_i[1][..n], &v_i[2][..n]);
    let (vj0, vj1, vj2) = (&v_j[0][..n], &v_j[1][..n], &v_j[2][..n]);
    let (mi0, mi1, mi2) = (&mean_i[0][..n], &mean_i[1][..n], &mean_i[2][..n]);
    let [n0, n1, n2] = num;
    let (n0, n1, n2, den) = (&mut n0[..n], &mut n1[..n], &mut n2[..n], &mut den[..n]);
    for k in 0..n {
        let wk = if MEMBERSHIP {
            // membership::passes on every channel, written out so it vectorises.
            let m = passes(ti0[k], tj0[k], vi0[k], vj0[k], g2)
                & passes(ti1[k], tj1[k], vi1[k], vj1[k], g2)
                & passes(ti2[k], tj2[k], vi2[k], vj2[k], g2);
            if m {
                w
            } else {
                0.0
            }
        } else {
            w
        };
        n0[k] += wk * mi0[k];
        n1[k] += wk * mi1[k];
        n2[k] += wk * mi2[k];
        den[k] += wk;
    }
}

type Kernel = fn(
    usize,
    f32,
    f32,
    [&[f32]; 3],
    [&[f32]; 3],
    [&[f32]; 3],
    [&[f32]; 3],
    [&[f32]; 3],
    [&mut [f32]; 3],
    &mut [f32],
);

/// What every pixel's filtering shares.
struct Shared<'a> {
    e: &'a Estimates,
    features: &'a Features<'a>,
    params: &'a FilterParams,
    /// Per pixel, the bins holding anything non-zero.
    active: Vec<(usize, usize)>,
    /// The bin-offset part of p, index dt + r_t.
    pt: Vec<f64>,
    g2: f32,
    kernel: Kernel,
}

/// Per-task sums over one range of bins.
struct Scratch {
    num: [Vec<f32>; 3],
    den: Vec<f32>,
}

/// Filters pixel (yj, xj) over bins [b0, b1) into `out_j`, its (C, T) planar block;
/// returns the voxel-neighbour evaluations made.
fn filter_pixel(
    s: &Shared,
    yj: usize,
    xj: usize,
    b0: usize,
    b1: usize,
    scratch: &mut Scratch,
    out_j: &mut [f32],
) -> u64 {
    let e = s.e;
    let (h, w, t_bins) = (e.height, e.width, e.bins);
    let (r, rt) = (s.params.radius as i64, s.params.temporal_radius as i64);
    let j = yj * w + xj;
    let (ylo, yhi) = ((yj as i64 - r).max(0), (yj as i64 + r).min(h as i64 - 1));
    let (xlo, xhi) = ((xj as i64 - r).max(0), (xj as i64 + r).min(w as i64 - 1));
    let neighbours = || (ylo..=yhi).flat_map(move |yi| (xlo..=xhi).map(move |xi| (yi, xi)));
    // Bins of j whose neighbourhood holds anything non-zero; the rest stay zero.
    let (mut a, mut b) = (usize::MAX, 0usize);
    for (yi, xi) in neighbours() {
        let (lo, hi) = s.active[yi as usize * w + xi as usize];
        if hi > lo {
            a = a.min(lo.saturating_sub(rt as usize));
            b = b.max((hi + rt as usize).min(t_bins));
        }
    }
    let (a, b) = (a.max(b0), b.min(b1));
    if a >= b {
        return 0;
    }
    let n = b - a;
    let Scratch { num, den } = scratch;
    for v in num.iter_mut() {
        v[..n].fill(0.0);
    }
    den[..n].fill(0.0);
    let mut evals = 0u64;
    for (yi, xi) in neighbours() {
        let i = yi as usize * w + xi as usize;
        let ps = s
            .params
            .base
            .pair_weight(s.features, j, i, yi - yj as i64, xi - xj as i64);
        for dt in -rt..=rt {
            // Bins t of j in [a, b) whose neighbour bin t + dt exists.
            let ts = (a as i64).max(-dt) as usize;
            let te = (b as i64).min(t_bins as i64 - dt);
            if te <= ts as i64 {
                continue;
            }
            let m = te as usize - ts;
            let wt = (ps * s.pt[(dt + rt) as usize]) as f32;
            let oi: [usize; 3] = std::array::from_fn(|c| e.idx(i, c, (ts as i64 + dt) as usize));
            let oj: [usize; 3] = std::array::from_fn(|c| e.idx(j, c, ts));
            let off = ts - a;
            let [n0, n1, n2] = &mut *num;
            (s.kernel)(
                m,
                wt,
                s.g2,
                oi.map(|o| &e.theta[o..o + m]),
                oj.map(|o| &e.theta[o..o + m]),
                oi.map(|o| &e.v[o..o + m]),
                oj.map(|o| &e.v[o..o + m]),
                oi.map(|o| &e.mean[o..o + m]),
                [&mut n0[off..], &mut n1[off..], &mut n2[off..]],
                &mut den[off..],
            );
            evals += m as u64;
        }
    }
    for (c, num_c) in num.iter().enumerate() {
        let o = c * t_bins + a;
        for ((out, &sum), &d) in out_j[o..o + n].iter_mut().zip(&num_c[..n]).zip(&den[..n]) {
            *out = sum / d;
        }
    }
    evals
}

/// Filters `e`; returns the output in the planar layout (H, W, C, T) and the number of
/// voxel-neighbour evaluations. `progress` is called with pixels finished.
pub fn filter(
    e: &Estimates,
    features: &Features,
    params: &FilterParams,
    tiling: Tiling,
    progress: &(dyn Fn(u64) + Sync),
) -> (Vec<f32>, u64) {
    let (h, w, t_bins) = (e.height, e.width, e.bins);
    let per_pixel = CHANNELS * t_bins;
    let mut out = vec![0.0f32; h * w * per_pixel];
    let shared = Shared {
        e,
        features,
        params,
        active: active_ranges(e),
        pt: params.base.time_weights(params.temporal_radius),
        g2: params.g2.unwrap_or(0.0) as f32,
        kernel: if params.g2.is_some() {
            accumulate::<true>
        } else {
            accumulate::<false>
        },
    };
    let (rows, cols, bins) = (tiling.rows.max(1), tiling.cols.max(1), tiling.bins.max(1));
    let evaluations: u64 = out
        .par_chunks_mut(rows * w * per_pixel)
        .enumerate()
        .map(|(band, out_band)| {
            let (y0, y1) = (band * rows, ((band + 1) * rows).min(h));
            let mut scratch = Scratch {
                num: std::array::from_fn(|_| vec![0.0; bins]),
                den: vec![0.0; bins],
            };
            let mut evals = 0u64;
            for b0 in (0..t_bins).step_by(bins) {
                let b1 = (b0 + bins).min(t_bins);
                for x0 in (0..w).step_by(cols) {
                    for yj in y0..y1 {
                        for xj in x0..(x0 + cols).min(w) {
                            let o = ((yj - y0) * w + xj) * per_pixel;
                            evals += filter_pixel(
                                &shared,
                                yj,
                                xj,
                                b0,
                                b1,
                                &mut scratch,
                                &mut out_band[o..o + per_pixel],
                            );
                        }
                    }
                }
            }
            progress(((y1 - y0) * w) as u64);
            evals
        })
        .sum();
    (out, evaluations)
}
