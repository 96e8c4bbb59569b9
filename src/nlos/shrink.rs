//! A denoised capture made safe for one reconstruction: the denoised capture `D`
//! shrunk toward the noisy one `N` by the amount that minimises the reconstruction's
//! error, chosen by cross-validation between two independent half captures
//! (docs/nlos.md, "Denoising a capture for a reconstruction").
//!
//! Why. The filter trades the capture's noise for a small bias, voxel by voxel. A
//! reconstruction sums many wall points and bins: independent noise averages out in
//! that sum, a bias shared by neighbouring wall points (whose echoes arrive at
//! different times) does not. So a denoised capture that is better voxel by voxel can
//! reconstruct worse once the noise is low.
//!
//! What. Every method is a linear field `L` of the capture followed by a pointwise
//! output map: bp's volume itself; fbp's and pf's complex field and its magnitude;
//! fk's field and its squared magnitude; LCT's field and its clamp at 0
//! ([`Reconstruction::linear_energy`]). For the blend `H_b = D + b (N - D)` the
//! field's error `||L(H_b - H)||^2` is a parabola in `b`: its expectation is least at
//! some `b*` and never above the noisy capture's (`b = 1`) for `b` in `[2 b* - 1, 1]`.
//!
//! How `b` is chosen. The truth `H` is unknown, but an independent capture of it is
//! not: with two half captures `x` and `y` (other seeds, or other shards of a job),
//! `N_y` is independent of half `x`'s `N_x` and `D_x`, so
//!
//! ```text
//!   E ||L(D_x + b (N_x - D_x)) - L N_y||^2 = E ||L(H_b,x - H)||^2 + E ||L(N_y - H)||^2,
//! ```
//!
//! half `x`'s error plus a constant. The `b` minimising the left side over the data,
//! `b_x = -<L(D_x - N_y), L(N_x - D_x)> / ||L(N_x - D_x)||^2` clamped to [0, 1], is
//! averaged over the two orders into `b_h`, a half's weight. The merged capture has
//! half a half's noise variance; with the filter's error a bias `B` that does not
//! change, `b* = B / (B + S)` (`S` the noisy capture's error energy) gives the merge
//! `b = 2 b_h / (1 + b_h)` ([`for_merge`]), the weight applied. (The filter's bias
//! falls a little with the samples too, so this errs toward the noisy capture: on the
//! letter T, 0.43 against an oracle 0.43 at 128 spp, 0.72 against 0.63 at 512.) A model of the
//! noise cannot replace the second half: a Gaussian model with each voxel's variance
//! put the noisy capture's error 1.5-2.1x too high for fbp and the filter's shared
//! error 3x too low, and chose `b = 0` where 0.3-0.6 was right
//! (`scripts/nlos_shrink_study.py`).
//!
//! Inner products come from energies, `<a, b> = (||a + b||^2 - ||a - b||^2) / 4` (fbp
//! and pf give magnitudes only). Cost: six energies (reconstructions) for `b`.

use super::capture::Capture;
use super::reconstruct::bp::VoxelGrid;
use super::reconstruct::Reconstruction;
use super::NlosError;

/// A half's `b` chosen by cross-validation between two independent half captures
/// (module docs), in [0, 1]: for each half `x` and the other `y`, the `b` minimising
/// `||L(D_x + b (N_x - D_x)) - L N_y||^2`, averaged over the two orders. `noisy` and
/// `denoised` are the halves' captures, all on one grid (only their H differ).
pub fn cross_validated_beta(
    method: &Reconstruction,
    grid: &VoxelGrid,
    noisy: [&Capture; 2],
    denoised: [&Capture; 2],
) -> Result<f64, NlosError> {
    let len = noisy[0].h.len();
    assert!(
        noisy.iter().chain(&denoised).all(|c| c.h.len() == len),
        "captures of one grid"
    );
    let mut scratch = noisy[0].clone();
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
        // u = D_x - N_y, v = N_x - D_x: the criterion is b -> ||L u + b L v||^2.
        let u = |i: usize| f64::from(dx[i]) - f64::from(ny[i]);
        let v = |i: usize| f64::from(nx[i]) - f64::from(dx[i]);
        let vv = energy(&v)?;
        let uv = (energy(&|i| u(i) + v(i))? - energy(&|i| u(i) - v(i))?) / 4.0;
        *beta = minimiser(uv, vv);
    }
    Ok((betas[0] + betas[1]) / 2.0)
}

/// The weight of the merge of two halves from a half's weight `b_h`:
/// `2 b_h / (1 + b_h)` (module docs), in [0, 1] for `b_h` in [0, 1].
pub fn for_merge(b_half: f64) -> f64 {
    2.0 * b_half / (1.0 + b_half)
}

/// The spatial radius the capture is denoised with for `method` when it differs from
/// the capture's NLOS default (`DenoiseParams::adapt_to_nlos`): on exhaustive scans,
/// whose default is 0, radius 1 for every method but bp. Blended, the radius-1
/// filter's output does more for fbp and pf (4 spp, Z: 1.31x against 1.08x with
/// radius 0; T: 1.10x against 1.01x), while bp gains more from radius 0 at every count
/// (T: 1.71x against 1.49x at 4 spp; docs/nlos.md).
pub fn radius_for(method: &Reconstruction, exhaustive: bool) -> Option<usize> {
    (exhaustive && !matches!(method, Reconstruction::Bp)).then_some(1)
}

/// Blends closer to the noisy capture than this are not made: [`applied`].
pub const SETTLE: f64 = 0.96;

/// The weight applied for a cross-validated merge weight `b`: `b`, or 1 (the noisy
/// capture as it is) above [`SETTLE`]. With the filter's error a bias that does not
/// change, the blend's error energy at its best `b*` is `b*` times the noisy capture's
/// (module docs), so above 0.96 it promises less than 2% lower error, while `b` is
/// estimated from two halves and a blend is never worse only for `b` in
/// `[2 b* - 1, 1]`, a window of width `2 (1 - b*)` (0.08 at 0.96): there the estimate's
/// own error can cost more than the blend gains. Measured: exhaustive scans of the
/// letter Z at 256 spp, fbp and pf, `b` = 0.98 reconstructed 1% worse than the noisy
/// capture (docs/results/nlos_denoise_cv.md).
pub fn applied(b: f64) -> f64 {
    if b > SETTLE {
        1.0
    } else {
        b
    }
}

/// The `b` in [0, 1] minimising `||u||^2 + 2 b <u, v> + b^2 ||v||^2`, given `<u, v>`
/// and `||v||^2`: 0 (the denoised capture) when `v` vanishes.
fn minimiser(uv: f64, vv: f64) -> f64 {
    if vv > 0.0 && uv.is_finite() {
        (-uv / vv).clamp(0.0, 1.0)
    } else {
        0.0
    }
}

/// `D + b (N - D)`, in place of `denoised`'s H: N itself at b = 1 (bit for bit).
pub fn blend(denoised: &mut Capture, noisy: &Capture, b: f64) {
    assert_eq!(denoised.h.len(), noisy.h.len(), "captures of one grid");
    if b == 1.0 {
        denoised.h.copy_from_slice(&noisy.h);
        return;
    }
    let b = b as f32;
    for (d, &n) in denoised.h.iter_mut().zip(&noisy.h) {
        *d += b * (n - *d);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exhaustive_scans_take_radius_one_for_every_method_but_bp() {
        let fbp = Reconstruction::Fbp {
            wl_mean: 0.2,
            wl_sigma: 0.2,
        };
        assert_eq!(radius_for(&Reconstruction::Bp, true), None);
        assert_eq!(radius_for(&fbp, true), Some(1));
        assert_eq!(radius_for(&fbp, false), None);
        assert_eq!(radius_for(&Reconstruction::Bp, false), None);
    }

    #[test]
    fn blends_within_two_per_cent_of_the_noisy_capture_are_not_made() {
        assert_eq!(applied(0.0), 0.0);
        assert_eq!(applied(0.5), 0.5);
        assert_eq!(applied(SETTLE), SETTLE);
        assert_eq!(applied(0.97), 1.0);
        assert_eq!(applied(1.0), 1.0);
        // b = 1 is the noisy capture bit for bit (d + (n - d) need not round to n).
        let (mut d, n) = (capture(vec![0.7; 16], 1), capture(vec![0.123; 16], 1));
        assert_ne!(0.7f32 + (0.123f32 - 0.7f32), 0.123f32);
        blend(&mut d, &n, 1.0);
        assert_eq!(d.h, n.h);
        // The promise at the bound: the blend's error energy is b* of the noisy one's.
        assert!(1.0 / SETTLE.sqrt() > 1.02 && 1.0 / 0.97f64.sqrt() < 1.02);
    }
    use crate::math::rng::Pcg32;

    /// A confocal 4 x 4 capture at z = 0 of `bins` bins holding `h`.
    fn capture(h: Vec<f32>, bins: usize) -> Capture {
        let sensor_grid: Vec<[f32; 3]> = (0..16)
            .map(|k| [(k / 4) as f32 * 0.4 - 0.6, (k % 4) as f32 * 0.4 - 0.6, 0.0])
            .collect();
        Capture {
            time: crate::sensors::time_axis::TimeAxis {
                start_opl: 1.5,
                bin_width_opl: 0.02,
                bins,
            },
            lasers: 1,
            sensors: 16,
            sensor_dims: [4, 4],
            laser_dims: [1, 1],
            normal: [0.0, 0.0, 1.0],
            h,
            laser_grid: sensor_grid.clone(),
            sensor_grid,
            paired: true,
            laser_xyz: None,
            sensor_xyz: None,
            accounts_first_and_last_bounces: false,
        }
    }

    /// The closed form is the criterion's least point found by brute force: each
    /// order's `||L(D_x + b (N_x - D_x)) - L N_y||^2` evaluated at 2001 values of b
    /// (no inner products, no polarisation), for bp (linear) and fbp (a magnitude).
    #[test]
    fn cross_validated_beta_is_the_brute_force_least_point() {
        let bins = 80;
        let mut rng = Pcg32::new(3, 9);
        // A truth of two echoes per point, halves with independent noise, and a
        // "denoiser" that blurs the truth in time (a bias) and keeps a little noise.
        let truth: Vec<f32> = (0..bins * 16)
            .map(|i| {
                let (k, s) = ((i / 16) as f32, (i % 16) as f32);
                (-((k - 30.0 - s) / 3.0).powi(2)).exp() + 0.5 * (-((k - 55.0) / 4.0).powi(2)).exp()
            })
            .collect();
        let mut noisy = || -> Vec<f32> {
            truth
                .iter()
                .map(|&t| t + 0.3 * (rng.next_f32() - 0.5))
                .collect()
        };
        let (na, nb) = (noisy(), noisy());
        let blur = |n: &[f32]| -> Vec<f32> {
            (0..n.len())
                .map(|i| {
                    let k = i / 16;
                    let at = |k: usize| truth[k.min(bins - 1) * 16 + i % 16];
                    (at(k.saturating_sub(3)) + at(k) + at(k + 3)) / 3.0 + 0.1 * (n[i] - truth[i])
                })
                .collect()
        };
        let (da, db) = (blur(&na), blur(&nb));
        let (na, nb, da, db) = (
            capture(na, bins),
            capture(nb, bins),
            capture(da, bins),
            capture(db, bins),
        );
        let grid = VoxelGrid {
            first: [-0.6, -0.6, 0.3],
            last: [0.6, 0.6, 0.9],
            n: [5, 5, 4],
        };
        for method in [
            Reconstruction::Bp,
            Reconstruction::Fbp {
                wl_mean: 0.2,
                wl_sigma: 0.2 / std::f64::consts::SQRT_2,
            },
        ] {
            let got = cross_validated_beta(&method, &grid, [&na, &nb], [&da, &db]).unwrap();
            let mut want = 0.0;
            for (nx, dx, ny) in [(&na, &da, &nb), (&nb, &db, &na)] {
                let criterion = |b: f64| {
                    let mut c = capture(vec![0.0; nx.h.len()], bins);
                    for (i, v) in c.h.iter_mut().enumerate() {
                        let blend = dx.h[i] as f64 + b * (nx.h[i] as f64 - dx.h[i] as f64);
                        *v = (blend - ny.h[i] as f64) as f32;
                    }
                    method.linear_energy(&c, &grid).unwrap()
                };
                let best = (0..=2000)
                    .map(|k| k as f64 / 2000.0)
                    .min_by(|&a, &b| criterion(a).total_cmp(&criterion(b)))
                    .unwrap();
                want += best / 2.0;
            }
            assert!(
                (got - want).abs() < 1.5e-3,
                "{}: closed form {got}, brute force {want}",
                method.name()
            );
            assert!(
                got > 0.05 && got < 0.95,
                "{}: b {got} should be interior",
                method.name()
            );
        }
    }

    /// b* = B / (B + S): a half with noise 2S gives B / (B + 2S), the merge B / (B + S).
    #[test]
    fn the_merge_weight_is_that_of_half_the_noise() {
        for (bias, s) in [(1.0, 1.0), (0.2, 3.0), (5.0, 0.1), (0.0, 1.0)] {
            let half = bias / (bias + 2.0 * s);
            let merge = bias / (bias + s);
            assert!((for_merge(half) - merge).abs() < 1e-12, "{bias} {s}");
        }
        assert_eq!(for_merge(1.0), 1.0);
        assert_eq!(for_merge(0.0), 0.0);
    }

    #[test]
    fn minimiser_is_the_parabola_s_least_point_in_the_unit_interval() {
        // f(b) = 1 + 2b(-0.3) + b^2: least at 0.3.
        assert_eq!(minimiser(-0.3, 1.0), 0.3);
        assert_eq!(minimiser(0.5, 1.0), 0.0);
        assert_eq!(minimiser(-3.0, 1.0), 1.0);
        assert_eq!(minimiser(-1.0, 0.0), 0.0);
        assert_eq!(minimiser(f64::NAN, 1.0), 0.0);
    }
}
