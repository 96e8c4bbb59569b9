//! The fast statistical filter (SPEC 8):
//! `out_j = sum_i w_ij mean_i / sum_i w_ij`, `w_ij = p_ij m_ij`, over the neighbours i
//! with |dy|, |dx| <= r and |dt| <= r_t.
//!
//! Memberships m: a per-voxel-pair test ([`PairTest`], `membership.rs`: the published
//! Welch test; the filter is compiled for each, `Membership::with_pair_test`), none
//! (the base filter alone), and tstat's (see `tstat.rs`: emitter classes, camera-depth
//! alignment, which moves the neighbour's bins by a per-pair shift k, and the patch
//! test).
//!
//! Work is split into tiles: bands of image rows (run in parallel) cut into blocks of
//! pixels and ranges of bins; a tile reads its halo (r pixels, r_t + |k| bins) straight
//! from the shared read-only estimates. For each output pixel and neighbour pixel, the
//! pixel part of p (and the shift k) is computed once and reused for every bin; the
//! inner loop runs over contiguous bins (planar layout) and vectorises. Each voxel's
//! sums are accumulated in the same neighbour order whatever the tiling or thread
//! count, so the output is bit-identical across both (the patch test reads s(t +- 1)
//! from the volume, not the tile). Voxels whose whole neighbourhood is zero are
//! skipped (they are zero).

use super::base_filter::{BaseFilter, BaseKind, Features};
use super::estimates::Estimates;
use super::membership::{passes, Everyone, PairTest};
use super::pair_dof::PairDof;
use super::tstat::{
    depth_shift, patch_member, same_coverage, sees_emitter, statistic, TstatParams, UNINFORMATIVE,
};
use super::Method;
use rayon::prelude::*;
use statrs::function::erf::erfc;

pub use super::critical::Welch;

/// Which membership test m the filter applies: the denoiser's [`Method`] with the
/// published test's threshold resolved to its g^2 ([`Method::resolve`]): the base
/// filter alone (m = 1), the published per-voxel Welch test with this g^2 (see
/// [`Welch`]), or tstat's classes, depth alignment and patch test.
pub type Membership = Method<Welch>;

#[derive(Clone, Copy, Debug)]
pub struct FilterParams {
    pub radius: usize,
    pub temporal_radius: usize,
    pub base: BaseFilter,
    pub membership: Membership,
    /// Zeros beyond the borders (`conventions::Border::Zero`; published only).
    pub zero_border: bool,
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

impl FilterParams {
    /// How many image rows away a neighbour can lie (the halo a band of output rows
    /// needs): r, or under tstat r_e when some pixel sees an emitter. Nothing else
    /// reaches across rows: depth alignment and the patch test move along the bins of
    /// one neighbour pixel, and everything global (spp, g^2, the time weights, the
    /// emitter pixels' sigma) is a scalar.
    pub fn reach(&self, stratified: bool, emitter: &[f32]) -> usize {
        match &self.membership {
            Membership::Tstat(tp) if emitter.iter().any(|&f| sees_emitter(f)) => {
                self.radius.max(tp.emitter_radius(self.radius, stratified))
            }
            _ => self.radius,
        }
    }
}

/// Per pixel held, the first and one-past-last bin holding any non-zero estimate.
fn active_ranges(e: &Estimates) -> Vec<(usize, usize)> {
    let t = e.bins;
    let first = e.rows.start * e.width;
    (first..e.rows.end * e.width)
        .into_par_iter()
        .map(|p| {
            let nz = |k: usize| {
                (0..e.channels).any(|c| {
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

/// The filter's inner loops for films of N channels ([`Kernels`]), one monomorphic
/// copy per channel count a film can have (1, 3, 4).
pub struct Ch;

/// The inner loops over `n` contiguous bins, for N channels. Each is written out per
/// channel by `kernels!` (the slices of each channel bound to their own locals, so the
/// loop over bins vectorises as the hand-written three-channel loops did): per channel
/// the floating-point operations, and their order, are those of the three-channel
/// filter before C varied, and RGB output is the same bit for bit.
///
/// - `accumulate`: one neighbour pixel at one bin offset; it counts with weight `w`
///   where the pair test passes on every channel (the test of a Stokes film asks S0,
///   S1, S2 and S3 alike, so that differently polarized light is not mixed;
///   docs/denoiser.md), or everywhere without a test (`MEMBERSHIP` false).
/// - `statistics`: tstat's statistic, `out[k] = max_c s_c` (`s_0.max(s_1).max(s_2)`
///   for RGB).
/// - `accumulate_patch`: tstat's inner loop: `s` holds the statistic at bins t - 1 ..
///   t + n (n + 2 values, the ends already repeated where the volume ends); a neighbour
///   voxel counts with weight `w` where [`patch_member`]: `s(t) <= t2_max` and
///   `s(t-1) + s(t) + s(t+1) <= 3 t2_patch`, uninformative values read as that
///   function says.
pub trait Kernels<const N: usize> {
    #[allow(clippy::too_many_arguments)]
    fn accumulate<const MEMBERSHIP: bool, T: PairTest>(
        n: usize,
        w: f32,
        test: &T,
        theta_i: [&[f32]; N],
        theta_j: [&[f32]; N],
        v_i: [&[f32]; N],
        v_j: [&[f32]; N],
        mean_i: [&[f32]; N],
        num: [&mut [f32]; N],
        den: &mut [f32],
    );

    fn statistics(
        n: usize,
        theta_i: [&[f32]; N],
        theta_j: [&[f32]; N],
        v_i: [&[f32]; N],
        v_j: [&[f32]; N],
        out: &mut [f32],
    );

    #[allow(clippy::too_many_arguments)]
    fn accumulate_patch(
        n: usize,
        w: f32,
        t2_max: f32,
        t2_patch3: f32,
        alone: bool,
        s: &[f32],
        mean_i: [&[f32]; N],
        num: [&mut [f32]; N],
        den: &mut [f32],
    );
}

/// [`Kernels`] for N channels: `kernels!(N: (c, theta_i, theta_j, v_i, v_j, mean, num)
/// ...)` with, per channel c, the names of its locals.
macro_rules! kernels {
    ($n:literal: $(($c:literal, $ti:ident, $tj:ident, $vi:ident, $vj:ident, $mi:ident, $nm:ident)),+) => {
        impl Kernels<$n> for Ch {
            #[inline(always)]
            fn accumulate<const MEMBERSHIP: bool, T: PairTest>(
                n: usize,
                w: f32,
                test: &T,
                theta_i: [&[f32]; $n],
                theta_j: [&[f32]; $n],
                v_i: [&[f32]; $n],
                v_j: [&[f32]; $n],
                mean_i: [&[f32]; $n],
                num: [&mut [f32]; $n],
                den: &mut [f32],
            ) {
                $(
                    let ($ti, $tj) = (&theta_i[$c][..n], &theta_j[$c][..n]);
                    let ($vi, $vj) = (&v_i[$c][..n], &v_j[$c][..n]);
                    let $mi = &mean_i[$c][..n];
                )+
                let [$($nm),+] = num;
                $( let $nm = &mut $nm[..n]; )+
                let den = &mut den[..n];
                for k in 0..n {
                    let wk = if MEMBERSHIP {
                        // The test on every channel (`&`, not `&&`, so it vectorises).
                        let m = true $( & test.pass($ti[k], $tj[k], $vi[k], $vj[k]) )+;
                        if m {
                            w
                        } else {
                            0.0
                        }
                    } else {
                        w
                    };
                    $( $nm[k] += wk * $mi[k]; )+
                    den[k] += wk;
                }
            }

            #[inline(always)]
            fn statistics(
                n: usize,
                theta_i: [&[f32]; $n],
                theta_j: [&[f32]; $n],
                v_i: [&[f32]; $n],
                v_j: [&[f32]; $n],
                out: &mut [f32],
            ) {
                $(
                    let ($ti, $tj) = (&theta_i[$c][..n], &theta_j[$c][..n]);
                    let ($vi, $vj) = (&v_i[$c][..n], &v_j[$c][..n]);
                )+
                let out = &mut out[..n];
                for k in 0..n {
                    let s = [$( statistic($ti[k], $tj[k], $vi[k], $vj[k]) ),+];
                    let mut m = s[0];
                    for &x in &s[1..] {
                        m = m.max(x);
                    }
                    out[k] = m;
                }
            }

            #[inline(always)]
            fn accumulate_patch(
                n: usize,
                w: f32,
                t2_max: f32,
                t2_patch3: f32,
                alone: bool,
                s: &[f32],
                mean_i: [&[f32]; $n],
                num: [&mut [f32]; $n],
                den: &mut [f32],
            ) {
                let (sp, sc, sn) = (&s[..n], &s[1..n + 1], &s[2..n + 2]);
                $( let $mi = &mean_i[$c][..n]; )+
                let [$($nm),+] = num;
                $( let $nm = &mut $nm[..n]; )+
                let den = &mut den[..n];
                for k in 0..n {
                    let pass = patch_member(sp[k], sc[k], sn[k], t2_max, t2_patch3, alone);
                    let wk = if pass { w } else { 0.0 };
                    $( $nm[k] += wk * $mi[k]; )+
                    den[k] += wk;
                }
            }
        }
    };
}

kernels!(1: (0, ti0, tj0, vi0, vj0, mi0, n0));
kernels!(3:
    (0, ti0, tj0, vi0, vj0, mi0, n0),
    (1, ti1, tj1, vi1, vj1, mi1, n1),
    (2, ti2, tj2, vi2, vj2, mi2, n2)
);
kernels!(4:
    (0, ti0, tj0, vi0, vj0, mi0, n0),
    (1, ti1, tj1, vi1, vj1, mi1, n1),
    (2, ti2, tj2, vi2, vj2, mi2, n2),
    (3, ti3, tj3, vi3, vj3, mi3, n3)
);
kernels!(12:
    (0, ti0, tj0, vi0, vj0, mi0, n0),
    (1, ti1, tj1, vi1, vj1, mi1, n1),
    (2, ti2, tj2, vi2, vj2, mi2, n2),
    (3, ti3, tj3, vi3, vj3, mi3, n3),
    (4, ti4, tj4, vi4, vj4, mi4, n4),
    (5, ti5, tj5, vi5, vj5, mi5, n5),
    (6, ti6, tj6, vi6, vj6, mi6, n6),
    (7, ti7, tj7, vi7, vj7, mi7, n7),
    (8, ti8, tj8, vi8, vj8, mi8, n8),
    (9, ti9, tj9, vi9, vj9, mi9, n9),
    (10, ti10, tj10, vi10, vj10, mi10, n10),
    (11, ti11, tj11, vi11, vj11, mi11, n11)
);

/// What the filter does with a method's pair test ([`PairTest`], `membership.rs`): the
/// method hands its test, or `None`, to [`PairTestUser::with`]
/// (`Membership::with_pair_test`, `mod.rs`), and the filter is compiled for it.
pub trait PairTestUser {
    type Out;
    fn with<T: PairTest>(self, test: Option<T>) -> Self::Out;
}

/// [`statistics`] for estimates from replicates: each channel's `s_c` is put on the
/// scale of infinite degrees of freedom, `s_c t2_max / g^2(nu)` with `g^2(nu)` the
/// pair's critical value at the tail level of `t2_max` (so `s_c <= g^2(nu)` exactly when
/// the scaled value is `<= t2_max`; the patch mean uses the same scaled values).
#[allow(clippy::too_many_arguments)]
fn statistics_pair<const N: usize>(
    n: usize,
    pair: &PairDof,
    t2_max: f32,
    theta_i: [&[f32]; N],
    theta_j: [&[f32]; N],
    v_i: [&[f32]; N],
    v_j: [&[f32]; N],
    out: &mut [f32],
) {
    for (k, o) in out[..n].iter_mut().enumerate() {
        *o = (0..N)
            .map(|c| {
                let (vi, vj) = (v_i[c][k], v_j[c][k]);
                let raw = statistic(theta_i[c][k], theta_j[c][k], vi, vj);
                let s = raw * (t2_max / pair.g2(vi, vj));
                if raw < 0.0 {
                    raw // uninformative stays so at any scale
                } else if s.is_nan() {
                    // inf * 0 (V = 0 with d != 0 at an infinite critical value) fails.
                    f32::INFINITY
                } else {
                    s
                }
            })
            .fold(UNINFORMATIVE, f32::max);
    }
}

/// What every pixel's filtering shares.
struct Shared<'a, T> {
    e: &'a Estimates,
    features: &'a Features<'a>,
    params: &'a FilterParams,
    /// tstat's parameters, when that is the membership.
    tstat: Option<TstatParams>,
    /// The base filter of emitter pixels under tstat (spatial sigma scaled by r_e / r).
    base_emitter: BaseFilter,
    /// Per pixel held (from the first pixel of `e.rows`), the bins holding anything
    /// non-zero.
    active: Vec<(usize, usize)>,
    /// The bin-offset part of p, index dt + r_t.
    pt: Vec<f64>,
    /// The method's pair test ([`PairTest`]); `None`: every neighbour passes (the base
    /// filter alone), or tstat's own test.
    test: Option<T>,
    /// tstat on estimates from replicates: per-pair critical values at the tail level
    /// of t2_max.
    pair: Option<PairDof>,
}

/// One neighbour pixel of an output pixel.
#[derive(Clone, Copy)]
struct Neighbour {
    /// Pixel index.
    i: usize,
    /// The pixel-pair part of p.
    weight: f64,
    /// Bin shift k: bin t of the output pixel meets bin t + dt + k of the neighbour.
    shift: i64,
}

/// Per-task scratch (N channels).
struct Scratch<const N: usize> {
    num: [Vec<f32>; N],
    den: Vec<f32>,
    /// tstat's statistic over a range of bins plus one on each side.
    stat: Vec<f32>,
    neighbours: Vec<Neighbour>,
}

impl<T> Shared<'_, T> {
    /// The neighbours of pixel (yj, xj) in accumulation order, and its temporal radius.
    fn neighbours(&self, yj: usize, xj: usize, out: &mut Vec<Neighbour>) -> i64 {
        let (h, w) = (self.e.height as i64, self.e.width as i64);
        let f = self.features;
        let j = yj * w as usize + xj;
        let (mut r, mut rt) = (
            self.params.radius as i64,
            self.params.temporal_radius as i64,
        );
        let mut base = &self.params.base;
        let class_j = sees_emitter(f.emitter[j]);
        if let Some(tp) = &self.tstat {
            if class_j {
                r = tp.emitter_radius(self.params.radius, self.e.stratified) as i64;
                rt = 0;
                base = &self.base_emitter;
            }
        }
        out.clear();
        // Neighbours stay within pixel j's image (an exhaustive NLOS capture's film
        // stacks one image per laser point).
        let ir = self.e.image_rows.max(1) as i64;
        let top = yj as i64 / ir * ir;
        let bottom = (top + ir - 1).min(h - 1);
        for yi in (yj as i64 - r).max(top)..=(yj as i64 + r).min(bottom) {
            for xi in (xj as i64 - r).max(0)..=(xj as i64 + r).min(w - 1) {
                let i = (yi * w + xi) as usize;
                let mut shift = 0;
                if let Some(tp) = &self.tstat {
                    if sees_emitter(f.emitter[i]) != class_j {
                        continue;
                    }
                    if class_j
                        && !same_coverage(
                            f.emitter[i],
                            f.emitter[j],
                            self.e.samples(i),
                            self.e.samples(j),
                            tp.t2_max,
                        )
                    {
                        continue;
                    }
                    if tp.depth_align {
                        shift = depth_shift(f.depth[j], f.depth[i], self.e.bin_width);
                    }
                }
                out.push(Neighbour {
                    i,
                    weight: base.pair_weight(f, j, i, yi - yj as i64, xi - xj as i64),
                    shift,
                });
            }
        }
        rt
    }
}

/// Filters pixel (yj, xj) over bins [b0, b1) into `out_j`, its (C, T) planar block;
/// returns the voxel-neighbour evaluations made.
#[inline(always)]
fn filter_pixel<T: PairTest, const N: usize>(
    s: &Shared<T>,
    yj: usize,
    xj: usize,
    b0: usize,
    b1: usize,
    scratch: &mut Scratch<N>,
    out_j: &mut [f32],
) -> u64
where
    Ch: Kernels<N>,
{
    let e = s.e;
    let t_bins = e.bins as i64;
    let j = yj * e.width + xj;
    let Scratch {
        num,
        den,
        stat,
        neighbours,
    } = scratch;
    let rt = s.neighbours(yj, xj, neighbours);
    // Emitter pixels are guarded by the coverage test; their pulse's first bin is not
    // judged alone (`patch_member`).
    let alone =
        s.tstat.is_some_and(|tp| tp.isolated_bins_alone) && !sees_emitter(s.features.emitter[j]);
    // Bins of j whose neighbourhood holds anything non-zero; the rest stay zero.
    let (mut a, mut b) = (i64::MAX, i64::MIN);
    for nb in neighbours.iter() {
        let (lo, hi) = s.active[nb.i - e.rows.start * e.width];
        if hi > lo {
            a = a.min(lo as i64 - rt - nb.shift);
            b = b.max(hi as i64 + rt - nb.shift);
        }
    }
    let (a, b) = (a.max(b0 as i64).max(0), b.min(b1 as i64).min(t_bins));
    if a >= b {
        return 0;
    }
    let n = (b - a) as usize;
    for v in num.iter_mut() {
        v[..n].fill(0.0);
    }
    den[..n].fill(0.0);
    let mut evals = 0u64;
    for nb in neighbours.iter() {
        let i = nb.i;
        for dt in -rt..=rt {
            let o = dt + nb.shift;
            // Bins t of j in [a, b) whose neighbour bin t + o exists.
            let ts = a.max(-o);
            let te = b.min(t_bins - o);
            if te <= ts {
                continue;
            }
            let m = (te - ts) as usize;
            let wt = (nb.weight * s.pt[(dt + s.params.temporal_radius as i64) as usize]) as f32;
            let oi: [usize; N] = std::array::from_fn(|c| e.idx(i, c, (ts + o) as usize));
            let oj: [usize; N] = std::array::from_fn(|c| e.idx(j, c, ts as usize));
            let off = (ts - a) as usize;
            let acc = num.each_mut().map(|v| &mut v[off..]);
            match (&s.tstat, &s.test) {
                (None, Some(test)) => <Ch as Kernels<N>>::accumulate::<true, T>(
                    m,
                    wt,
                    test,
                    oi.map(|q| &e.theta[q..q + m]),
                    oj.map(|q| &e.theta[q..q + m]),
                    oi.map(|q| &e.v[q..q + m]),
                    oj.map(|q| &e.v[q..q + m]),
                    oi.map(|q| &e.mean[q..q + m]),
                    acc,
                    &mut den[off..],
                ),
                (None, None) => <Ch as Kernels<N>>::accumulate::<false, Everyone>(
                    m,
                    wt,
                    &Everyone,
                    oi.map(|q| &e.theta[q..q + m]),
                    oj.map(|q| &e.theta[q..q + m]),
                    oi.map(|q| &e.v[q..q + m]),
                    oj.map(|q| &e.v[q..q + m]),
                    oi.map(|q| &e.mean[q..q + m]),
                    acc,
                    &mut den[off..],
                ),
                (Some(tp), _) => {
                    // s over [lo, hi): one more bin on each side where both voxels exist.
                    let lo = if ts > (-o).max(0) { ts - 1 } else { ts };
                    let hi = if te < t_bins.min(t_bins - o) {
                        te + 1
                    } else {
                        te
                    };
                    let len = (hi - lo) as usize;
                    let first = if lo < ts { 0 } else { 1 };
                    let si: [usize; N] = std::array::from_fn(|c| e.idx(i, c, (lo + o) as usize));
                    let sj: [usize; N] = std::array::from_fn(|c| e.idx(j, c, lo as usize));
                    let (ti, tj) = (
                        si.map(|q| &e.theta[q..q + len]),
                        sj.map(|q| &e.theta[q..q + len]),
                    );
                    let (vi, vj) = (si.map(|q| &e.v[q..q + len]), sj.map(|q| &e.v[q..q + len]));
                    let out = &mut stat[first..first + len];
                    match &s.pair {
                        None => <Ch as Kernels<N>>::statistics(len, ti, tj, vi, vj, out),
                        Some(pd) => statistics_pair(len, pd, tp.t2_max as f32, ti, tj, vi, vj, out),
                    }
                    if first == 1 {
                        stat[0] = stat[1];
                    }
                    if hi == te {
                        stat[m + 1] = stat[m];
                    }
                    <Ch as Kernels<N>>::accumulate_patch(
                        m,
                        wt,
                        tp.t2_max as f32,
                        (3.0 * tp.t2_patch) as f32,
                        alone,
                        &stat[..m + 2],
                        oi.map(|q| &e.mean[q..q + m]),
                        acc,
                        &mut den[off..],
                    );
                }
            }
            evals += m as u64;
        }
    }
    if s.params.zero_border {
        zero_border(s, yj, xj, rt, a, &mut den[..n]);
    }
    // The means were stored in units of 2^scale.mean (see `estimates.rs`).
    let unscale = e.scale.unscale_mean();
    for (c, num_c) in num.iter().enumerate() {
        let q = c * e.bins + a as usize;
        for ((out, &sum), &d) in out_j[q..q + n].iter_mut().zip(&num_c[..n]).zip(&den[..n]) {
            *out = (f64::from(sum / d) * unscale) as f32;
        }
    }
    evals
}

/// The published code's zero padding (`conventions::Border::Zero`) for output pixel
/// (yj, xj) over bins `a..a + den.len()`: each of the window's voxels beyond the volume
/// (space or time) has radiance 0, estimand z = 0, variance 0 and guidance 0, so it
/// adds nothing to the numerator and, when the centre passes the test against it on
/// every channel, the base weight between the centre and a voxel at the volume's
/// centre with black albedo and no normal to the denominator.
fn zero_border<T>(s: &Shared<T>, yj: usize, xj: usize, rt: i64, a: i64, den: &mut [f32]) {
    let e = s.e;
    let (r, t_bins) = (s.params.radius as i64, e.bins as i64);
    let inside = |c: i64, len: i64| (c - r).max(0).min(len)..(c + r + 1).min(len);
    let ys = inside(yj as i64, e.height as i64);
    let xs = inside(xj as i64, e.width as i64);
    let in_image = ys.end.saturating_sub(ys.start) * xs.end.saturating_sub(xs.start);
    let window = (2 * r + 1) * (2 * r + 1) * (2 * rt + 1);
    let g2 = match s.params.membership {
        Membership::Published(w) => w.g2 as f32,
        _ => unreachable!("zero borders are the published method's (validated)"),
    };
    // The padded voxel's guidance and estimand.
    let sig = &s.params.base.sigmas;
    let (cy, cx) = ((e.height as f64 - 1.0) / 2.0, (e.width as f64 - 1.0) / 2.0);
    let (dy, dx) = (yj as f64 - cy, xj as f64 - cx);
    let j = yj * e.width + xj;
    let mut pixel = (dx * dx + dy * dy) / (sig.xy * sig.xy);
    if s.params.base.kind == BaseKind::Jbf {
        let f = s.features;
        let sq = |v: &[f32]| (0..3).map(|c| f64::from(v[j * 3 + c]).powi(2)).sum::<f64>();
        pixel +=
            sq(f.albedo) / (sig.albedo * sig.albedo) + sq(f.normal) / (sig.normal * sig.normal);
    }
    let theta_pad = (-e.z0 * 2f64.powi(-e.scale.theta)) as f32;
    let ct = (t_bins as f64 - 1.0) / 2.0;
    for (k, d) in den.iter_mut().enumerate() {
        let t = a + k as i64;
        let in_time = (t + rt + 1).min(t_bins) - (t - rt).max(0);
        let padded = window - in_image * in_time;
        if padded <= 0 {
            continue;
        }
        let pass = (0..e.channels).all(|c| {
            let q = e.idx(j, c, t as usize);
            passes(e.theta[q], theta_pad, e.v[q], 0.0, g2)
        });
        if pass {
            let dt = t as f64 - ct;
            let w = (-0.5 * (pixel + dt * dt / (sig.t * sig.t))).exp();
            *d += padded as f32 * w as f32;
        }
    }
}

/// Filters `e`, which must hold the whole image; returns the output in the planar
/// layout (H, W, C, T) and the number of voxel-neighbour evaluations. `progress` is
/// called with pixels finished.
pub fn filter(
    e: &Estimates,
    features: &Features,
    params: &FilterParams,
    tiling: Tiling,
    progress: &(dyn Fn(u64) + Sync),
) -> (Vec<f32>, u64) {
    let mut out = vec![0.0f32; e.height * e.row_len()];
    let evaluations = filter_rows(e, features, params, tiling, 0..e.height, &mut out, progress);
    (out, evaluations)
}

/// Filters the image rows `rows` into `out`, planar (rows, W, C, T); returns the
/// voxel-neighbour evaluations. `e` must hold those rows and the
/// [`FilterParams::reach`] rows on either side (as far as the image goes); each
/// voxel's output is the one [`filter`] gives on the whole image, bit for bit.
pub fn filter_rows(
    e: &Estimates,
    features: &Features,
    params: &FilterParams,
    tiling: Tiling,
    rows: std::ops::Range<usize>,
    out: &mut [f32],
    progress: &(dyn Fn(u64) + Sync),
) -> u64 {
    let (h, w, t_bins) = (e.height, e.width, e.bins);
    let per_pixel = e.channels * t_bins;
    let reach = params.reach(e.stratified, features.emitter);
    assert!(
        e.rows.start <= rows.start.saturating_sub(reach)
            && (rows.end + reach).min(h) <= e.rows.end
            && rows.start <= rows.end,
        "rows {rows:?} with a halo of {reach} need estimates of more than rows {:?}",
        e.rows
    );
    assert_eq!(out.len(), rows.len() * w * per_pixel);
    out.fill(0.0);
    let tstat = match params.membership {
        Membership::Tstat(tp) => Some(tp),
        _ => None,
    };
    let mut base_emitter = params.base;
    if let Some(tp) = &tstat {
        base_emitter.sigmas.xy *= tp.emitter_radius(params.radius, e.stratified).max(1) as f64
            / params.radius.max(1) as f64;
    }
    params.membership.with_pair_test(
        e.replicates,
        Rows {
            e,
            features,
            params,
            tstat,
            base_emitter,
            pair: match (params.membership, e.replicates) {
                (Membership::Tstat(tp), Some(b)) if b >= 2 => {
                    Some(PairDof::new(b, erfc((tp.t2_max / 2.0).sqrt())))
                }
                _ => None,
            },
            tiling,
            rows,
            out,
            progress,
        },
    )
}

/// [`filter_rows`] once the method's pair test is known ([`PairTestUser`]).
struct Rows<'a, 'p> {
    e: &'a Estimates,
    features: &'a Features<'a>,
    params: &'a FilterParams,
    tstat: Option<TstatParams>,
    base_emitter: BaseFilter,
    pair: Option<PairDof>,
    tiling: Tiling,
    rows: std::ops::Range<usize>,
    out: &'a mut [f32],
    progress: &'p (dyn Fn(u64) + Sync),
}

impl PairTestUser for Rows<'_, '_> {
    type Out = u64;

    fn with<T: PairTest>(self, test: Option<T>) -> u64 {
        let Rows {
            e,
            features,
            params,
            tstat,
            base_emitter,
            pair,
            tiling,
            rows,
            out,
            progress,
        } = self;
        let w = e.width;
        let per_pixel = e.channels * e.bins;
        let shared = Shared {
            e,
            features,
            params,
            tstat,
            base_emitter,
            active: active_ranges(e),
            pt: params.base.time_weights(params.temporal_radius),
            test,
            pair,
        };
        let (band_rows, cols, bins) = (tiling.rows.max(1), tiling.cols.max(1), tiling.bins.max(1));
        let band = Band {
            rows: rows.clone(),
            band_rows,
            cols,
            bins,
        };
        out.par_chunks_mut(band_rows * w * per_pixel)
            .enumerate()
            .map(|(k, out_band)| {
                // The kernels are compiled for each channel count (see `accumulate`).
                let evals = match e.channels {
                    1 => filter_band_isa::<T, 1>(&shared, &band, k, out_band),
                    3 => filter_band_isa::<T, 3>(&shared, &band, k, out_band),
                    4 => filter_band_isa::<T, 4>(&shared, &band, k, out_band),
                    12 => filter_band_isa::<T, 12>(&shared, &band, k, out_band),
                    c => {
                        unreachable!("{c} channels: films have 1, 3, 4 or 12 (checked on reading)")
                    }
                };
                let y0 = rows.start + k * band_rows;
                progress(((rows.end.min(y0 + band_rows) - y0) * w) as u64);
                evals
            })
            .sum()
    }
}

/// How [`filter_rows`] cuts its rows: bands of `band_rows` rows (one task each), each
/// filtered in blocks of `cols` columns by `bins` bins.
struct Band {
    rows: std::ops::Range<usize>,
    band_rows: usize,
    cols: usize,
    bins: usize,
}

/// [`filter_band`] on the widest instruction set this CPU runs.
#[inline(always)]
fn filter_band_isa<T: PairTest, const N: usize>(
    s: &Shared<T>,
    band: &Band,
    k: usize,
    out_band: &mut [f32],
) -> u64
where
    Ch: Kernels<N>,
{
    match crate::cpu::detected().avx2() {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: the proof says this CPU runs the wrapper's instruction set.
        Some(isa) => unsafe { filter_band_avx2::<T, N>(isa, s, band, k, out_band) },
        _ => filter_band::<T, N>(s, band, k, out_band),
    }
}

/// Filters band `k` of a film of `N` channels into `out_band`; returns the
/// voxel-neighbour evaluations.
#[inline(always)]
fn filter_band<T: PairTest, const N: usize>(
    s: &Shared<T>,
    band: &Band,
    k: usize,
    out_band: &mut [f32],
) -> u64
where
    Ch: Kernels<N>,
{
    let (w, t_bins) = (s.e.width, s.e.bins);
    debug_assert_eq!(s.e.channels, N);
    let per_pixel = N * t_bins;
    let (cols, bins) = (band.cols, band.bins);
    let y0 = band.rows.start + k * band.band_rows;
    let y1 = (y0 + band.band_rows).min(band.rows.end);
    let mut scratch = Scratch::<N> {
        num: std::array::from_fn(|_| vec![0.0; bins]),
        den: vec![0.0; bins],
        stat: vec![0.0; bins + 2],
        neighbours: Vec::new(),
    };
    let mut evals = 0u64;
    for b0 in (0..t_bins).step_by(bins) {
        let b1 = (b0 + bins).min(t_bins);
        for x0 in (0..w).step_by(cols) {
            for yj in y0..y1 {
                for xj in x0..(x0 + cols).min(w) {
                    let o = ((yj - y0) * w + xj) * per_pixel;
                    evals += filter_pixel(
                        s,
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
    evals
}

/// [`filter_band`] compiled for AVX2 + FMA (the same bits: Rust neither fuses nor
/// reorders float operations; `tests/it/isa.rs`).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
fn filter_band_avx2<T: PairTest, const N: usize>(
    _isa: crate::cpu::Avx2,
    s: &Shared<T>,
    band: &Band,
    k: usize,
    out_band: &mut [f32],
) -> u64
where
    Ch: Kernels<N>,
{
    filter_band::<T, N>(s, band, k, out_band)
}
