//! Adaptive sampling (`tstat render --adaptive`): how many samples each pixel gets.
//!
//! A pilot render of `pilot_spp` samples per pixel, with its own seed (`pilot_seed`),
//! measures per pixel `i` what one more sample is worth: the sum over its voxels of the
//! per-sample variance, `V_i = sum_{t,c} sigma^2_{itc}` (all-voxel MSE), or the same with
//! each voxel weighted by `1 / (mu^2 + EPS)` (relative MSE, [`RELMSE_EPS`]), and its cost
//! `c_i`, the rays per path. The volume's expected squared error with `n_i` samples is
//! `sum_i V_i / n_i`; at a fixed cost `sum_i c_i n_i` it is smallest for
//! `n_i ∝ sqrt(V_i / c_i)` (Lagrange). [`allocate`] gives each pixel that share of the
//! budget `N x pixels`, clamped to `[floor, cap]` (the floor guards pixels whose rare
//! light the pilot missed; the cap bounds one pixel's time), in whole multiples of a
//! granule (replicates x shards), with the total exactly the budget.
//!
//! Unbiasedness: the pilot's samples do not enter the estimate, and its seed is not the
//! render's, so each pixel's count is independent of the samples that are averaged: the
//! mean of `n_i` samples is unbiased for any rule that picks `n_i` from the pilot, and
//! the variances the bundle claims (from the `n_i` samples) stay honest. The pilot costs
//! `pilot_spp / N` of the budget on top (1/16 by default).
//!
//! Memory: the pilot keeps 2 f64 per pixel (16 bytes x H x W) besides one row's sums per
//! thread; the counts are 4 bytes per pixel. Streaming renders stay streaming.

use super::sink::{Row, RowSink};
use super::{render_into, RenderSettings};
use crate::math::rng::mix64;
use crate::scene::Scene;
use std::sync::Mutex;

/// The epsilon of the relative MSE's denominator, `(x - ref)^2 / (ref^2 + EPS)`: the
/// report's (`report::metrics::REL_EPS`; a test keeps them equal).
pub const RELMSE_EPS: f64 = 1e-2;

/// Salt of the pilot's seed.
const PILOT_SALT: u64 = 0x7069_6c6f_745f_7370;

/// Which expected error the allocation minimises.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ErrorMeasure {
    /// All-voxel mean squared error (RMSE).
    Mse,
    /// Relative MSE, `(x - ref)^2 / (ref^2 + EPS)`.
    RelMse,
}

impl ErrorMeasure {
    pub fn name(self) -> &'static str {
        match self {
            ErrorMeasure::Mse => "mse",
            ErrorMeasure::RelMse => "relmse",
        }
    }

    /// The error reported for a mean squared (or relative squared) error per voxel:
    /// its root (RMSE) for MSE, itself for relMSE.
    pub fn of(self, mean_squared: f64) -> f64 {
        match self {
            ErrorMeasure::Mse => mean_squared.sqrt(),
            ErrorMeasure::RelMse => mean_squared,
        }
    }
}

/// What the user asks of adaptive sampling.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AdaptiveOptions {
    /// The mean samples per pixel N (the budget is N x pixels).
    pub spp: u32,
    pub measure: ErrorMeasure,
    /// Samples per pixel of the pilot.
    pub pilot_spp: u32,
    /// Fewest and most samples a pixel gets.
    pub floor: u32,
    pub cap: u32,
    /// Every count is a multiple of this (replicates x shards).
    pub granule: u32,
}

impl AdaptiveOptions {
    /// The defaults for a budget of `spp` in multiples of `granule`: a pilot of
    /// max(4, N / 16) samples, a floor of N / 2 and a cap of 16 N (each rounded to the
    /// granule; the floor at least `min_floor`, and at least 2). Half the budget stays
    /// uniform: a pilot of a few samples misses rare light (caustics, glossy paths),
    /// and the Sobol' sampler's gain over independent samples shrinks with fewer
    /// samples, so pixels are never left far below N (`docs/commands.md`).
    pub fn new(spp: u32, measure: ErrorMeasure, granule: u32, min_floor: u32) -> Self {
        let g = granule.max(1);
        let round_up = |n: u32| n.div_ceil(g).saturating_mul(g);
        AdaptiveOptions {
            spp,
            measure,
            pilot_spp: (spp / 16).max(4),
            floor: round_up((spp / 2).max(min_floor).max(2)),
            cap: (spp.saturating_mul(16) / g).max(1).saturating_mul(g),
            granule: g,
        }
    }

    /// The pilot's seed, from the render's (the same for every shard of a job).
    pub fn pilot_seed(seed: u64) -> u64 {
        mix64(seed ^ PILOT_SALT)
    }

    pub fn validate(&self) -> Result<(), AdaptiveError> {
        let g = self.granule;
        let bad = |what: &'static str| Err(AdaptiveError::Options(what));
        if g == 0 || !self.spp.is_multiple_of(g) {
            return bad("the mean spp must be a multiple of replicates x shards");
        }
        if self.pilot_spp < 2 {
            return bad("the pilot needs at least 2 samples per pixel");
        }
        if self.floor < 2 || !self.floor.is_multiple_of(g) || !self.cap.is_multiple_of(g) {
            return bad(
                "floor and cap must be multiples of replicates x shards, the floor at least 2",
            );
        }
        if !(self.floor <= self.spp && self.spp <= self.cap) {
            return bad("the floor must be at most the mean spp, and the cap at least it");
        }
        Ok(())
    }
}

#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum AdaptiveError {
    #[error("adaptive sampling: {0}")]
    Options(&'static str),
}

/// What the pilot measured, per pixel (row-major).
#[derive(Clone, Debug, PartialEq)]
pub struct PilotMeasure {
    /// `V_i`: the summed per-sample variance of the pixel's voxels (weighted for relMSE).
    pub variance: Vec<f64>,
    /// `c_i`: rays per path.
    pub cost: Vec<f64>,
}

/// `V` of one pixel from its pilot sums: `sum_{t,c} w (x2 - x1^2 / n) / (n - 1)`, with
/// `w = 1 / (mean^2 + EPS)` for relMSE.
pub fn pixel_variance(x1: &[f64], x2: &[f64], n: u32, measure: ErrorMeasure) -> f64 {
    let nf = f64::from(n);
    x1.iter()
        .zip(x2)
        .map(|(&s1, &s2)| {
            let var = ((s2 - s1 * s1 / nf) / (nf - 1.0)).max(0.0);
            match measure {
                ErrorMeasure::Mse => var,
                ErrorMeasure::RelMse => {
                    let m = s1 / nf;
                    var / (m * m + RELMSE_EPS)
                }
            }
        })
        .sum()
}

/// Collects the pilot's rows into a [`PilotMeasure`].
struct PilotSink {
    width: usize,
    spp: u32,
    measure: ErrorMeasure,
    out: Mutex<PilotMeasure>,
}

impl RowSink for PilotSink {
    type Error = std::convert::Infallible;

    fn put_row(&self, row: &Row<'_>) -> Result<(), Self::Error> {
        let per_pixel = row.sums.bins * row.sums.channels;
        let w = self.width;
        let (v, c): (Vec<f64>, Vec<f64>) = (0..w)
            .map(|x| {
                let r = x * per_pixel..(x + 1) * per_pixel;
                (
                    pixel_variance(
                        &row.sums.x1[r.clone()],
                        &row.sums.x2[r],
                        self.spp,
                        self.measure,
                    ),
                    row.rays[x] as f64 / f64::from(self.spp),
                )
            })
            .unzip();
        let mut out = self
            .out
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        out.variance[row.y * w..(row.y + 1) * w].copy_from_slice(&v);
        out.cost[row.y * w..(row.y + 1) * w].copy_from_slice(&c);
        Ok(())
    }
}

/// Renders the pilot of `scene` with the sampler and seed of `settings` (identity
/// sums, no replicates) and measures each pixel. The caller passes the pilot's seed,
/// [`AdaptiveOptions::pilot_seed`] of the job's: with the render's own seed the
/// pilot's samples would be the render's first ones, and the counts would depend on
/// the samples averaged (biased; the tests' mutation). Runs on the current rayon pool;
/// the result does not depend on the number of threads.
pub fn pilot(
    scene: &Scene,
    settings: &RenderSettings,
    o: &AdaptiveOptions,
    progress: &(dyn Fn(u64) + Sync),
) -> (PilotMeasure, super::RenderSummary) {
    let film = &scene.film;
    let pixels = film.pixels();
    let sink = PilotSink {
        width: film.width,
        spp: o.pilot_spp,
        measure: o.measure,
        out: Mutex::new(PilotMeasure {
            variance: vec![0.0; pixels],
            cost: vec![0.0; pixels],
        }),
    };
    let pilot_settings = RenderSettings {
        spp: o.pilot_spp,
        seed: settings.seed,
        transform: crate::stats::Transform::Identity,
        pixel_sampling: settings.pixel_sampling,
        replicates: 0,
        pixel_spp: None,
    };
    let summary = match render_into(scene, &pilot_settings, &sink, progress) {
        Ok(s) => s,
        Err(never) => match never {},
    };
    let measure = sink
        .out
        .into_inner()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    (measure, summary)
}

/// The weight `sqrt(V_i / c_i)` of each pixel of an image `width` pixels wide, with
/// `V_i` the mean of the pilot's measure over the pixel's 3 x 3 neighbourhood (within
/// the image): a few pilot samples estimate one pixel's variance poorly (most miss a
/// rare bright path), and neighbouring pixels share their light. 0 where the
/// neighbourhood saw no variance.
pub fn weights(m: &PilotMeasure, width: usize) -> Vec<f64> {
    let n = m.variance.len();
    let height = n / width.max(1);
    (0..n)
        .map(|p| {
            let (y, x) = (p / width, p % width);
            let (mut sum, mut count) = (0.0, 0.0);
            for yy in y.saturating_sub(1)..(y + 2).min(height) {
                for xx in x.saturating_sub(1)..(x + 2).min(width) {
                    sum += m.variance[yy * width + xx];
                    count += 1.0;
                }
            }
            let w = (sum / count / m.cost[p].max(1.0)).sqrt();
            if w.is_finite() {
                w
            } else {
                0.0
            }
        })
        .collect()
}

/// Samples per pixel: `n_i = clamp(lambda w_i, floor, cap)` with lambda such that the
/// counts sum to `spp x pixels`, rounded to multiples of the granule by largest
/// remainder (ties to the lower index), so the total is exact. Pixels of weight 0 get
/// the floor; with every weight 0 (or none finite) each pixel gets `spp`.
pub fn allocate(w: &[f64], o: &AdaptiveOptions) -> Vec<u32> {
    let n = w.len();
    let g = f64::from(o.granule);
    let (lo, hi) = (f64::from(o.floor), f64::from(o.cap));
    let total = f64::from(o.spp) * n as f64;
    let units = (u64::from(o.spp) / u64::from(o.granule)) * n as u64;
    let wmax = w.iter().cloned().fold(0.0, f64::max);
    if n == 0 || wmax <= 0.0 {
        return vec![o.spp; n];
    }
    let sum_at = |lambda: f64| -> f64 { w.iter().map(|&x| (lambda * x).clamp(lo, hi)).sum() };
    // sum_at is non-decreasing in lambda, from n lo (<= total) to at most n hi (>= total).
    let (mut a, mut b) = (0.0, hi / wmax * 2.0);
    while sum_at(b) < total && b < f64::MAX / 4.0 {
        b *= 2.0;
    }
    for _ in 0..200 {
        let m = 0.5 * (a + b);
        if sum_at(m) < total {
            a = m;
        } else {
            b = m;
        }
    }
    let mut target: Vec<f64> = w.iter().map(|&x| (b * x).clamp(lo, hi)).collect();
    // Few pixels with weight: even at their cap (the rest at the floor) the budget is
    // not spent; the rest is shared evenly, `min(t_i + mu, cap)`.
    let spent: f64 = target.iter().sum();
    if spent < total * (1.0 - 1e-12) {
        let with = |mu: f64| -> f64 { target.iter().map(|&t| (t + mu).min(hi)).sum() };
        let (mut a, mut b) = (0.0, hi);
        for _ in 0..200 {
            let m = 0.5 * (a + b);
            if with(m) < total {
                a = m;
            } else {
                b = m;
            }
        }
        for t in &mut target {
            *t = (*t + b).min(hi);
        }
    }
    let target: Vec<f64> = target.iter().map(|&t| t / g).collect();
    let mut counts: Vec<u64> = target.iter().map(|&t| t.floor() as u64).collect();
    let assigned: u64 = counts.iter().sum();
    let cap_units = (hi / g) as u64;
    if assigned < units {
        let mut order: Vec<usize> = (0..n).collect();
        // Largest remainder first; a stable sort keeps ties in index order.
        order.sort_by(|&i, &j| {
            let (ri, rj) = (target[i] - target[i].floor(), target[j] - target[j].floor());
            rj.total_cmp(&ri)
        });
        let mut left = units - assigned;
        for &i in order.iter().cycle().take(order.len() * 4) {
            if left == 0 {
                break;
            }
            if counts[i] < cap_units {
                counts[i] += 1;
                left -= 1;
            }
        }
    } else if assigned > units {
        // Rounding down never exceeds the total; kept for safety: take from the largest.
        let mut left = assigned - units;
        let floor_units = (lo / g) as u64;
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&i, &j| counts[j].cmp(&counts[i]));
        for &i in order.iter().cycle().take(order.len() * 2) {
            if left == 0 {
                break;
            }
            if counts[i] > floor_units {
                counts[i] -= 1;
                left -= 1;
            }
        }
    }
    counts
        .iter()
        .map(|&u| (u * u64::from(o.granule)) as u32)
        .collect()
}

/// A sink that passes every row on to `inner` and estimates the noisy volume's error
/// from the rows' own sums (identity sums: X1 and X2 of radiance): per voxel the
/// variance of its mean, `(X2 - X1^2 / n) / ((n - 1) n)` with the pixel's `n`,
/// weighted by `1 / (mean^2 + EPS)` for relMSE. Rows are summed in image order at the
/// end, so the estimate does not depend on the threads.
pub struct ErrorTally<'a, S> {
    pub inner: &'a S,
    settings: &'a RenderSettings,
    measure: ErrorMeasure,
    width: usize,
    /// Each row's summed error (0 until it arrives) and how many rows arrived.
    rows: Mutex<(Vec<f64>, usize)>,
}

impl<'a, S: RowSink> ErrorTally<'a, S> {
    pub fn new(
        inner: &'a S,
        settings: &'a RenderSettings,
        measure: ErrorMeasure,
        height: usize,
        width: usize,
    ) -> Self {
        ErrorTally {
            inner,
            settings,
            measure,
            width,
            rows: Mutex::new((vec![0.0; height], 0)),
        }
    }

    /// The error estimated from the rows arrived so far (`voxels_per_row`: W T C), as
    /// if the rest of the volume were like them; `None` before the first row. For a
    /// progress display: rows arrive in no fixed order.
    pub fn so_far(&self, voxels_per_row: f64) -> Option<f64> {
        let rows = self
            .rows
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        let (sums, done) = &*rows;
        (*done > 0).then(|| {
            self.measure
                .of(sums.iter().sum::<f64>() / (voxels_per_row * *done as f64))
        })
    }

    /// The estimated error of the whole volume of `voxels` (H W T C): the RMSE for
    /// MSE, the relMSE for relMSE.
    pub fn error(&self, voxels: f64) -> f64 {
        let rows = self
            .rows
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        self.measure.of(rows.0.iter().sum::<f64>() / voxels)
    }
}

impl<S: RowSink> RowSink for ErrorTally<'_, S> {
    type Error = S::Error;

    fn put_row(&self, row: &Row<'_>) -> Result<(), S::Error> {
        let per_pixel = row.sums.bins * row.sums.channels;
        let mut sum = 0.0;
        for x in 0..self.width {
            let n = f64::from(self.settings.samples(row.y * self.width + x));
            let r = x * per_pixel..(x + 1) * per_pixel;
            sum += pixel_variance(
                &row.sums.x1[r.clone()],
                &row.sums.x2[r],
                n as u32,
                self.measure,
            ) / n;
        }
        let mut rows = self
            .rows
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        rows.0[row.y] = sum;
        rows.1 += 1;
        drop(rows);
        self.inner.put_row(row)
    }
}

/// The largest `u` in `lo..=hi` with `keep(u)`, for a `keep` that holds up to some
/// point and not after it (`lo` when it never holds), by bisection.
fn last_true(lo: u32, hi: u32, keep: impl Fn(u32) -> bool) -> u32 {
    if !keep(lo) {
        return lo;
    }
    if keep(hi) {
        return hi;
    }
    let (mut a, mut b) = (lo, hi);
    while b - a > 1 {
        let mid = a + (b - a) / 2;
        if keep(mid) {
            a = mid;
        } else {
            b = mid;
        }
    }
    a
}

/// What the pilot predicts for a mean of `o.spp`: the volume's expected error with
/// the counts of [`allocate`] (for independent samples: `sqrt(sum_i V_i / n_i /
/// voxels)` for MSE, the RMSE; `sum_i V_i / n_i / voxels` for relMSE, which is not a
/// square), and the rays those counts trace (`sum_i c_i n_i`). `voxels` = H W T C.
pub fn predict(m: &PilotMeasure, w: &[f64], o: &AdaptiveOptions, voxels: f64) -> (f64, f64) {
    let n = allocate(w, o);
    let (mut err, mut rays) = (0.0, 0.0);
    for ((&v, &c), &k) in m.variance.iter().zip(&m.cost).zip(&n) {
        err += v / f64::from(k);
        rays += c * f64::from(k);
    }
    (o.measure.of(err / voxels), rays)
}

/// What decides the mean spp when the user asks for a time or an error instead.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Goal {
    /// Rays the render may trace (the time left after the pilot times the pilot's
    /// rays per second).
    Rays(f64),
    /// The predicted error to reach (RMSE for MSE, relMSE for relMSE).
    Error(f64),
}

/// The smallest mean spp (a multiple of the granule, from `2 granule` to `max_spp`)
/// whose prediction meets `goal`: for `Rays`, the largest that stays within it. The
/// options' floor and cap follow the spp as [`AdaptiveOptions::new`] makes them.
pub fn choose_spp(
    m: &PilotMeasure,
    w: &[f64],
    template: &AdaptiveOptions,
    voxels: f64,
    goal: Goal,
    max_spp: u32,
    min_floor: u32,
) -> u32 {
    let g = template.granule.max(1);
    let at = |units: u32| -> (f64, f64) {
        let spp = units * g;
        let o = AdaptiveOptions {
            pilot_spp: template.pilot_spp,
            ..AdaptiveOptions::new(spp, template.measure, g, min_floor)
        };
        predict(m, w, &o, voxels)
    };
    let ok = |units: u32| -> bool {
        let (err, rays) = at(units);
        match goal {
            Goal::Rays(r) => rays <= r,
            Goal::Error(e) => err <= e,
        }
    };
    let (lo, hi) = (2u32, (max_spp / g).max(2));
    let units = match goal {
        // Rays grow with spp: the largest within the budget.
        Goal::Rays(_) => last_true(lo, hi, ok),
        // The error falls with spp: the smallest that reaches it.
        Goal::Error(_) if ok(lo) => lo,
        Goal::Error(_) => (last_true(lo, hi, |u| !ok(u)) + 1).min(hi),
    };
    units * g
}

#[cfg(test)]
mod tests {
    use super::*;

    fn opts(spp: u32, granule: u32) -> AdaptiveOptions {
        AdaptiveOptions::new(spp, ErrorMeasure::Mse, granule, 2)
    }

    /// The slow reference: the real-valued optimum clamped to [floor, cap], found by
    /// scanning lambda on a fine grid.
    fn reference_targets(w: &[f64], o: &AdaptiveOptions) -> Vec<f64> {
        let total = f64::from(o.spp) * w.len() as f64;
        let (lo, hi) = (f64::from(o.floor), f64::from(o.cap));
        let wmax = w.iter().cloned().fold(0.0, f64::max);
        let mut best = (f64::INFINITY, 0.0);
        for k in 0..=2_000_000u64 {
            let lambda = k as f64 * 1e-6 * (hi / wmax) * 2.0;
            let s: f64 = w.iter().map(|&x| (lambda * x).clamp(lo, hi)).sum();
            if (s - total).abs() < best.0 {
                best = ((s - total).abs(), lambda);
            }
        }
        w.iter().map(|&x| (best.1 * x).clamp(lo, hi)).collect()
    }

    #[test]
    fn counts_follow_the_optimum_within_one_granule_and_sum_to_the_budget() {
        let w = [0.0, 0.1, 0.5, 1.0, 3.0, 10.0, 0.2, 0.05];
        for granule in [1, 2, 4] {
            let o = opts(64, granule);
            let n = allocate(&w, &o);
            let want = reference_targets(&w, &o);
            assert_eq!(
                n.iter().map(|&k| u64::from(k)).sum::<u64>(),
                64 * w.len() as u64
            );
            for (i, (&k, &t)) in n.iter().zip(&want).enumerate() {
                assert!(k % granule == 0 && k >= o.floor && k <= o.cap, "{i}: {k}");
                assert!(
                    (f64::from(k) - t).abs() <= f64::from(granule) + 1e-3,
                    "granule {granule} pixel {i}: {k} vs {t}"
                );
            }
            // More weight, more samples.
            assert!(n[5] >= n[4] && n[4] >= n[3] && n[3] >= n[2]);
            // Weight 0: the floor.
            assert_eq!(n[0], o.floor);
        }
    }

    #[test]
    fn flat_or_empty_weights_are_uniform_and_the_cap_holds() {
        let o = opts(16, 1);
        assert_eq!(allocate(&[0.0; 5], &o), vec![16; 5]);
        assert_eq!(allocate(&[2.0; 5], &o), vec![16; 5]);
        // One pixel with all the variance: capped at 16 N, the rest share what is left
        // (the floor N / 2 leaves room for it).
        let mut w = vec![0.0; 100];
        w[7] = 1.0;
        let n = allocate(&w, &o);
        assert_eq!(n[7], o.cap);
        assert_eq!(n.iter().map(|&k| u64::from(k)).sum::<u64>(), 1600);
        // The 99 others share 1600 - 256 evenly: 13 or 14 each.
        assert!(
            n.iter()
                .enumerate()
                .all(|(i, &k)| i == 7 || k == 13 || k == 14),
            "{n:?}"
        );
    }

    #[test]
    fn the_optimum_lowers_the_expected_error_below_uniform() {
        // sum V_i / n_i at the allocation against at uniform N, same total.
        let v = [1e-4, 1e-4, 4.0, 1e-2, 0.0, 9.0, 1e-3, 0.5];
        let o = opts(64, 1);
        let w: Vec<f64> = v.iter().map(|x: &f64| x.sqrt()).collect();
        let n = allocate(&w, &o);
        let err = |n: &[u32]| {
            v.iter()
                .zip(n)
                .map(|(&v, &k)| v / f64::from(k))
                .sum::<f64>()
        };
        // Half the budget is uniform (the floor N / 2): still 10% lower, and no
        // allocation of the same total within [floor, cap] does better (moving one
        // sample between two pixels does not lower it).
        assert!(
            err(&n) < 0.9 * err(&[64; 8]),
            "{} vs {}",
            err(&n),
            err(&[64; 8])
        );
        for i in 0..8 {
            for j in 0..8 {
                if i != j && n[i] > o.floor && n[j] < o.cap {
                    let mut m = n.clone();
                    m[i] -= 1;
                    m[j] += 1;
                    assert!(err(&m) >= err(&n) * (1.0 - 1e-3), "{i} -> {j}");
                }
            }
        }
    }

    /// The weights average V over each pixel's 3 x 3 neighbourhood within the image.
    #[test]
    fn weights_smooth_the_pilot_over_neighbours() {
        let mut m = PilotMeasure {
            variance: vec![0.0; 12],
            cost: vec![1.0; 12],
        };
        m.variance[5] = 9.0; // (1, 1) of a 4 x 3 image
        m.cost[0] = 4.0;
        let w = weights(&m, 4);
        // Corner (0, 0): 4 neighbours, cost 4: sqrt(9 / 4 / 4).
        assert!((w[0] - (9.0f64 / 4.0 / 4.0).sqrt()).abs() < 1e-12);
        // (1, 1) and (2, 2)... every pixel of its 3 x 3: 9 / 9 (interior) or 9 / 6 (edge).
        assert!((w[5] - (9.0f64 / 9.0).sqrt()).abs() < 1e-12);
        assert!((w[1] - (9.0f64 / 6.0).sqrt()).abs() < 1e-12);
        // (0, 3) is two columns away: nothing.
        assert_eq!(w[3], 0.0);
    }

    #[test]
    fn pixel_variance_is_the_unbiased_sample_variance_summed() {
        // Samples of one voxel: 1, 3, 5 (variance 4); another: 0, 0, 6 (variance 12).
        let x1 = [9.0, 6.0];
        let x2 = [35.0, 36.0];
        assert!((pixel_variance(&x1, &x2, 3, ErrorMeasure::Mse) - 16.0).abs() < 1e-12);
        let rel = 4.0 / (9.0 + RELMSE_EPS) + 12.0 / (4.0 + RELMSE_EPS);
        assert!((pixel_variance(&x1, &x2, 3, ErrorMeasure::RelMse) - rel).abs() < 1e-12);
    }

    /// The prediction against its closed form, and the spp chosen for a goal is the
    /// edge where the goal starts (or stops) being met.
    #[test]
    fn predictions_and_the_spp_chosen_for_a_goal() {
        let m = PilotMeasure {
            variance: vec![4.0, 1.0, 0.0, 9.0],
            cost: vec![2.0, 1.0, 1.0, 3.0],
        };
        let w = weights(&m, 4);
        let o = opts(8, 1);
        let n = allocate(&w, &o);
        let (err, rays) = predict(&m, &w, &o, 40.0);
        let want: f64 = m.variance.iter().zip(&n).map(|(v, &k)| v / k as f64).sum();
        assert!((err - (want / 40.0).sqrt()).abs() < 1e-12);
        let want_rays: f64 = m.cost.iter().zip(&n).map(|(c, &k)| c * k as f64).sum();
        assert!((rays - want_rays).abs() < 1e-9);
        let template = opts(8, 2);
        for target in [0.05, 0.1, 0.2] {
            let spp = choose_spp(&m, &w, &template, 40.0, Goal::Error(target), 4096, 2);
            let e = |s: u32| {
                predict(
                    &m,
                    &w,
                    &AdaptiveOptions::new(s, ErrorMeasure::Mse, 2, 2),
                    40.0,
                )
                .0
            };
            assert!(spp.is_multiple_of(2) && e(spp) <= target, "{target}: {spp}");
            assert!(
                spp == 4 || e(spp - 2) > target,
                "{target}: {spp} is not the smallest"
            );
        }
        for budget in [100.0, 1000.0, 10000.0] {
            let spp = choose_spp(&m, &w, &template, 40.0, Goal::Rays(budget), 4096, 2);
            let r = |s: u32| {
                predict(
                    &m,
                    &w,
                    &AdaptiveOptions::new(s, ErrorMeasure::Mse, 2, 2),
                    40.0,
                )
                .1
            };
            assert!(r(spp) <= budget && r(spp + 2) > budget, "{budget}: {spp}");
        }
    }

    #[test]
    fn options_are_checked() {
        assert!(opts(64, 4).validate().is_ok());
        let why = |o: &AdaptiveOptions| o.validate().unwrap_err().to_string();
        let e = why(&opts(64, 48));
        assert!(
            e.contains("the mean spp must be a multiple of replicates x shards"),
            "{e}"
        );
        let mut o = opts(64, 1);
        o.floor = 1;
        let e = why(&o);
        assert!(e.contains("the floor at least 2"), "{e}");
        o = opts(64, 1);
        o.cap = 32;
        let e = why(&o);
        assert!(e.contains("the cap at least it"), "{e}");
        o = opts(64, 1);
        o.pilot_spp = 1;
        let e = why(&o);
        assert!(
            e.contains("the pilot needs at least 2 samples per pixel"),
            "{e}"
        );
    }
}
