//! A denoised capture made safe for one reconstruction: the denoised capture `D`
//! shrunk toward the noisy one `N` by the amount that minimises the reconstruction's
//! expected error (docs/nlos.md, "Denoising a capture").
//!
//! Why. The filter trades the capture's noise for a small bias, voxel by voxel. A
//! reconstruction `R` sums many wall points and bins: independent noise averages out
//! in that sum, a bias shared by neighbouring wall points does not. So a denoised
//! capture that is better voxel by voxel can reconstruct worse once the noise is low.
//!
//! What. The capture `H_β = D + β (N - D)`, with `β` in [0, 1] chosen in the domain of
//! the reconstruction's linear field `L` (bp's volume; fbp's and pf's complex field,
//! whose magnitude is the output; fk's field before its squared magnitude; LCT's
//! before its clamp). With `e_N = N - H` and `e_D = D - H` the errors,
//!
//! ```text
//!   E ||L(H_β - H)||^2 = E ||L e_D||^2 + 2 β E<L e_D, L(e_N - e_D)> + β^2 E ||L(N - D)||^2
//!   β* = 1 - (S - C) / E ||L(N - D)||^2,   S = E ||L e_N||^2,   C = E<L e_N, L e_D>,
//! ```
//!
//! and `β = clamp(β*, 0, 1)`. The three terms are estimated from the bundle alone:
//! - `D2 = ||L(N - D)||^2`, of the capture itself;
//! - `S = E ||L ε||^2`, over draws `ε` of Gaussian noise with each voxel's variance of
//!   the mean (SPEC 5's `V`, the channels' standard deviations summed: the bound of
//!   perfectly correlated channels), independent between voxels;
//! - `C = E<L ε, L W ε>`, `W` the filter with the weights it computed on the capture
//!   held fixed (its output is a weighted average of the means, its weights depend on
//!   the tested estimates, not on the averaged means; so `W ε` is the filter run on the
//!   same estimates with `ε` as the means). Inner products come from energies:
//!   `<a, b> = (||a + b||^2 - ||a - b||^2) / 4` (fbp and pf give magnitudes only).
//!
//! `β = 0` keeps the denoised capture (noise dominates `N - D`); `β → 1` as the bias
//! dominates, so the result's error is never above the noisy capture's, up to the
//! estimates' own error: the expected error is a parabola in β with its minimum at
//! β*, equal at β = 1 and β = 2β* - 1.
//!
//! Cost: the filter runs twice (the capture, then three draws at once, one per
//! channel: its weights are shared by the channels), and the reconstruction's linear
//! field `1 + 3 × 3 = 10` times. Memory: the estimates (`3 × H W T C × 4` bytes), the
//! denoised and the payload volumes (`H W T C × 4` each), and one capture H at a time.

use super::bp::VoxelGrid;
use super::capture::Capture;
use super::reconstruct::Reconstruction;
use super::NlosError;
use crate::bundle::capture::CaptureRecord;
use crate::denoise::base_filter::Features;
use crate::denoise::estimates::{Estimates, SumsView};
use crate::denoise::filter::filter;
use crate::denoise::DenoiseParams;
use crate::stats::accumulators::CHANNELS;
use crate::stats::transform::Transform;

/// Noise draws, one per channel of a filter run.
const DRAWS: usize = CHANNELS;

/// The seed of the noise draws (fixed: the same capture gives the same β).
const DRAW_SEED: u64 = 0x5eed_5a1f_0b1e_u64;

/// The chosen blend and the estimates behind it (energies of the linear field).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Shrink {
    /// Weight of the noisy capture, in [0, 1].
    pub beta: f64,
    /// `S`, the noisy capture's expected error energy.
    pub noise: f64,
    /// `C`, the expected inner product of the noisy and the denoised errors.
    pub shared: f64,
    /// `D2`, the energy of the difference of the two captures.
    pub difference: f64,
}

impl Shrink {
    /// `β = clamp(1 - (S - C) / D2, 0, 1)`; 0 (the denoised capture) when the two
    /// captures' reconstructions do not differ.
    pub fn choose(noise: f64, shared: f64, difference: f64) -> Shrink {
        let beta = if difference > 0.0 {
            (1.0 - (noise - shared) / difference).clamp(0.0, 1.0)
        } else {
            0.0
        };
        Shrink {
            beta: if beta.is_finite() { beta } else { 0.0 },
            noise,
            shared,
            difference,
        }
    }

    /// The expected error energy of the blend relative to the noisy capture's, as
    /// the estimates predict it: `E_β / S`.
    pub fn predicted_ratio(&self) -> f64 {
        if self.noise <= 0.0 {
            return 1.0;
        }
        // E_β = E_D + 2β E<e_D, e_N - e_D> + β² D2 is a parabola with its minimum at
        // β* and E_1 = S, so E_β - S = D2 ((β - β*)² - (1 - β*)²).
        let d2 = self.difference;
        let star = 1.0 - (self.noise - self.shared) / d2.max(f64::MIN_POSITIVE);
        let delta = d2 * ((self.beta - star).powi(2) - (1.0 - star).powi(2));
        ((self.noise + delta) / self.noise).max(0.0)
    }
}

/// What the shrunk denoising of a capture gives: the capture's film volume
/// (H, W, T, C), the blend, and the filter's own figures.
pub struct Shrunk {
    pub volume: ndarray::Array4<f32>,
    pub shrink: Shrink,
    /// The first filter run's voxel-neighbour evaluations and seconds.
    pub evaluations: u64,
    pub filter_seconds: f64,
}

/// The capture's geometry and time axis, to turn film volumes into captures.
pub struct CaptureFrame<'a> {
    pub record: &'a CaptureRecord,
    pub t_start: f64,
    pub delta_t: f64,
}

/// Denoises the capture of `sums` with `params` and shrinks it toward the noisy
/// capture for `method` on `grid` (module docs). `transform` is the bundle's.
#[allow(clippy::too_many_arguments)]
pub fn denoise_for(
    sums: &SumsView,
    features: &Features,
    params: &DenoiseParams,
    transform: Transform,
    frame: &CaptureFrame,
    method: &Reconstruction,
    grid: &VoxelGrid,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Shrunk, NlosError> {
    let start = std::time::Instant::now();
    let mut est = Estimates::from_sums_as(sums, params.variance);
    let fp = params.filter_params(est.replicates.unwrap_or(sums.spp));
    let (denoised, evaluations) = filter(&est, features, &fp, params.tiling, progress);
    let filter_seconds = start.elapsed().as_secs_f64();
    let unscale = est.scale.unscale_mean();
    let (h, w, t) = (est.height, est.width, est.bins);
    let pixels = h * w;
    let noisy = est.mean_in_radiance();
    // The filter's outputs are in radiance units (it undoes the estimates' scale).

    // Each (pixel, bin)'s standard deviation of H's mean, and three draws of noise.
    let sd = capture_sd(&est, transform);
    let mut eps = vec![0f32; noisy.len()];
    for p in 0..pixels {
        for c in 0..DRAWS {
            for k in 0..t {
                let i = (p * t + k) as u64;
                let g = gaussian(DRAW_SEED ^ ((c as u64) << 56), i);
                eps[(p * CHANNELS + c) * t + k] = (g * sd[p * t + k]) as f32;
            }
        }
    }
    // W ε: the filter with the capture's weights, the draws as the means.
    let to_scaled = 1.0 / unscale;
    let saved = std::mem::replace(
        &mut est.mean,
        eps.iter()
            .map(|&v| (f64::from(v) * to_scaled) as f32)
            .collect(),
    );
    let (w_eps, _) = filter(&est, features, &fp, params.tiling, &|_| {});
    est.mean = saved;
    drop(est);

    // Energies of the linear field.
    let energy = |f: &dyn Fn(usize, usize) -> f64| -> Result<f64, NlosError> {
        let c = capture_of(frame, h, w, t, f);
        method.linear_energy(&c, grid)
    };
    let summed = |v: &[f32], p: usize, k: usize| -> f64 {
        (0..CHANNELS)
            .map(|c| f64::from(v[(p * CHANNELS + c) * t + k]))
            .sum()
    };
    let difference = energy(&|p, k| summed(&noisy, p, k) - summed(&denoised, p, k))?;
    let (mut noise, mut shared) = (0.0, 0.0);
    for c in 0..DRAWS {
        let at = |v: &[f32], p: usize, k: usize| f64::from(v[(p * CHANNELS + c) * t + k]);
        let plus = energy(&|p, k| at(&eps, p, k) + at(&w_eps, p, k))?;
        let minus = energy(&|p, k| at(&eps, p, k) - at(&w_eps, p, k))?;
        noise += energy(&|p, k| at(&eps, p, k))?;
        shared += (plus - minus) / 4.0;
    }
    let shrink = Shrink::choose(noise / DRAWS as f64, shared / DRAWS as f64, difference);
    let b = shrink.beta as f32;
    let volume = ndarray::Array4::from_shape_fn((h, w, t, CHANNELS), |(y, x, k, c)| {
        let q = ((y * w + x) * CHANNELS + c) * t + k;
        denoised[q] + b * (noisy[q] - denoised[q])
    });
    Ok(Shrunk {
        volume,
        shrink,
        evaluations,
        filter_seconds,
    })
}

/// The standard deviation of each (pixel, bin)'s mean of H (the channels summed),
/// `(H W T)` row-major: `sum_c sqrt(V_c)`, with `V` of the radiance (for a transform,
/// the delta method: `V_z / z'(mean)^2`).
fn capture_sd(est: &Estimates, transform: Transform) -> Vec<f64> {
    let (t, pixels) = (est.bins, est.height * est.width);
    let mut sd = vec![0f64; pixels * t];
    for p in 0..pixels {
        for c in 0..CHANNELS {
            for k in 0..t {
                let (mean, _, v) = est.unscaled(est.idx(p + est.rows.start * est.width, c, k));
                let slope = transform.derivative(mean.max(0.0));
                let var = if slope.is_finite() && slope > 0.0 {
                    v / (slope * slope)
                } else {
                    0.0
                };
                sd[p * t + k] += var.max(0.0).sqrt();
            }
        }
    }
    sd
}

/// A standard normal value for draw `seed`, entry `i` (Box-Muller on two hashed
/// uniforms: the same value at any thread count).
fn gaussian(seed: u64, i: u64) -> f64 {
    use crate::math::rng::mix64;
    let a = mix64(seed ^ mix64(2 * i + 1));
    let b = mix64(a ^ 0x9e37_79b9_7f4a_7c15);
    let u1 = ((a >> 11) as f64 + 0.5) / (1u64 << 53) as f64;
    let u2 = (b >> 11) as f64 / (1u64 << 53) as f64;
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// The capture whose film (H, W, T) holds `f(pixel, bin)`.
fn capture_of(
    frame: &CaptureFrame,
    h: usize,
    w: usize,
    t: usize,
    f: &dyn Fn(usize, usize) -> f64,
) -> Capture {
    let len = t * super::tal::h_per_bin(frame.record);
    let mut c = Capture::from_record(
        frame.record,
        frame.t_start,
        frame.delta_t,
        t,
        vec![0.0; len],
    );
    let film: Vec<f32> = (0..h * w * t).map(|q| f(q / t, q % t) as f32).collect();
    super::denoised::replace_rows(&mut c, frame.record, 0..h, &film, 1);
    c
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn beta_is_the_minimiser_clamped() {
        // S = 1, C = 0.25, D2 = 3: β* = 1 - 0.75 / 3 = 0.75.
        let s = Shrink::choose(1.0, 0.25, 3.0);
        assert_eq!(s.beta, 0.75);
        // Noise alone in the difference (D2 <= S - C): the denoised capture.
        assert_eq!(Shrink::choose(1.0, 0.25, 0.5).beta, 0.0);
        assert_eq!(Shrink::choose(1.0, 0.0, 0.0).beta, 0.0);
        // C > S (a filter that adds correlated error): never beyond the noisy capture.
        assert_eq!(Shrink::choose(1.0, 2.0, 3.0).beta, 1.0);
    }

    #[test]
    fn predicted_ratio_is_one_at_the_noisy_capture() {
        let s = Shrink {
            beta: 1.0,
            noise: 2.0,
            shared: 0.5,
            difference: 4.0,
        };
        assert!((s.predicted_ratio() - 1.0).abs() < 1e-15);
        let best = Shrink::choose(2.0, 0.5, 4.0);
        assert!(best.predicted_ratio() < 1.0);
    }

    #[test]
    fn draws_are_standard_normal() {
        let n = 200_000u64;
        let (mut m1, mut m2, mut m4) = (0.0, 0.0, 0.0);
        for i in 0..n {
            let g = gaussian(7, i);
            m1 += g;
            m2 += g * g;
            m4 += g.powi(4);
        }
        let n = n as f64;
        assert!((m1 / n).abs() < 0.01, "mean {}", m1 / n);
        assert!((m2 / n - 1.0).abs() < 0.01, "variance {}", m2 / n);
        assert!((m4 / n - 3.0).abs() < 0.05, "fourth moment {}", m4 / n);
    }
}

/// `b` chosen by cross-validation between two independent half captures (docs/nlos.md,
/// `scripts/nlos_shrink_study.py`): for each half `x` and the other `y`, the `b` in
/// [0, 1] minimising `||L(D_x + b (N_x - D_x)) - L N_y||^2` (`N_y` is independent of
/// half x, so this is x's error up to a constant), averaged over the two orders.
/// `noisy` and `denoised` are the halves' captures (H as `Capture::h`, on one grid).
/// WIP (branch only): not yet wired to a command.
pub fn cross_validated_beta(
    method: &Reconstruction,
    grid: &VoxelGrid,
    noisy: [&Capture; 2],
    denoised: [&Capture; 2],
) -> Result<f64, NlosError> {
    let mut scratch = Capture {
        h: vec![0.0; noisy[0].h.len()],
        laser_grid: noisy[0].laser_grid.clone(),
        sensor_grid: noisy[0].sensor_grid.clone(),
        ..*noisy[0]
    };
    let mut energy = |f: &dyn Fn(usize) -> f64| -> Result<f64, NlosError> {
        for (i, v) in scratch.h.iter_mut().enumerate() {
            *v = f(i) as f32;
        }
        method.linear_energy(&scratch, grid)
    };
    let mut betas = [0.0; 2];
    for (x, beta) in betas.iter_mut().enumerate() {
        let y = 1 - x;
        let (nx, dx, ny) = (&noisy[x].h, &denoised[x].h, &noisy[y].h);
        // u = D_x - N_y, v = N_x - D_x: the error b -> ||L u + b L v||^2.
        let u = |i: usize| f64::from(dx[i]) - f64::from(ny[i]);
        let v = |i: usize| f64::from(nx[i]) - f64::from(dx[i]);
        let vv = energy(&v)?;
        let uv = (energy(&|i| u(i) + v(i))? - energy(&|i| u(i) - v(i))?) / 4.0;
        *beta = if vv > 0.0 {
            (-uv / vv).clamp(0.0, 1.0)
        } else {
            0.0
        };
    }
    Ok((betas[0] + betas[1]) / 2.0)
}
