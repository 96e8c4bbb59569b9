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
//! averaged over the two orders and applied to the merged capture. A model of the
//! noise cannot replace the second half: a Gaussian model with each voxel's variance
//! put the noisy capture's error 1.5-2.1x too high for fbp and the filter's shared
//! error 3x too low, and chose `b = 0` where 0.3-0.6 was right
//! (`scripts/nlos_shrink_study.py`).
//!
//! Inner products come from energies, `<a, b> = (||a + b||^2 - ||a - b||^2) / 4` (fbp
//! and pf give magnitudes only). Cost: six energies (reconstructions) for `b`.

use super::bp::VoxelGrid;
use super::capture::Capture;
use super::reconstruct::Reconstruction;
use super::NlosError;

/// `b` chosen by cross-validation between two independent half captures (module
/// docs), in [0, 1]: for each half `x` and the other `y`, the `b` minimising
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
    let mut scratch = Capture {
        h: vec![0.0; len],
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
        // u = D_x - N_y, v = N_x - D_x: the criterion is b -> ||L u + b L v||^2.
        let u = |i: usize| f64::from(dx[i]) - f64::from(ny[i]);
        let v = |i: usize| f64::from(nx[i]) - f64::from(dx[i]);
        let vv = energy(&v)?;
        let uv = (energy(&|i| u(i) + v(i))? - energy(&|i| u(i) - v(i))?) / 4.0;
        *beta = minimiser(uv, vv);
    }
    Ok((betas[0] + betas[1]) / 2.0)
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

/// `D + b (N - D)`, in place of `denoised`'s H.
pub fn blend(denoised: &mut Capture, noisy: &Capture, b: f64) {
    assert_eq!(denoised.h.len(), noisy.h.len(), "captures of one grid");
    let b = b as f32;
    for (d, &n) in denoised.h.iter_mut().zip(&noisy.h) {
        *d += b * (n - *d);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
