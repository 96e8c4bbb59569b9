//! f-k migration of a confocal capture (Lindell, O'Toole and Wetzstein, "Wave-based
//! non-line-of-sight imaging using fast f-k migration", SIGGRAPH 2019), as y-tal 0.20's
//! `tal.reconstruct.fk.solve`, numerics included, on the capture's native grid
//! (`wave.rs`: N x N wall points, M' bins from OPL 0), then resampled onto the voxel grid.
//!
//! With τ(m, i, j) = H[m, i N + j] (bin m of point (i, j)) and `z_m = m / (M' - 1)`:
//!
//! 1. `ψ = |τ z_m|` (y-tal's `sqrt((data * grid_z)**2)`), zero-padded to (2M', 2N, 2N);
//! 2. `Ψ = fftshift(fftn ψ)`;
//! 3. Stolt resampling: on the normalised frequencies `x = k_x / N, y = k_y / N,
//!    z = k_z / M'` (`k ∈ [-N, N)`, `[-M', M')`),
//!
//!    ```text
//!      Φ(z, y, x) = [z > 0] |z| / max S · Ψ(S(z, y, x), y, x),
//!      S(z, y, x) = sqrt(s^2 (x^2 + y^2) + z^2),   s = N R / (4 M' w),
//!    ```
//!
//!    `R = M' Δt` the OPL range and `w` the wall's half-width; Ψ at S by linear
//!    interpolation along z between the frequency samples (scipy's `interpn`, linear,
//!    zero beyond the last sample), max S over the whole frequency grid;
//! 4. `|ifftn(ifftshift Φ)|^2`, cropped to (M', N, N): the native volume.
//!
//! y-tal takes `w = sensor_grid_xyz[-1, -1, 0]`, the last point's x; here
//! `w = N |du| / 2` (Lindell's "width", half the wall side the N samples cover), which
//! is what `s` needs for the depth and lateral frequencies to share a unit
//! (`s = (Δt / 2) / |du|`). On y-tal's grids (cell centres of a wall centred at the
//! origin) its value is `w - |du| / 2`.
//!
//! Memory: one padded complex volume, `2M' 2N 2N 16 = 128 M' N^2` bytes (the Stolt step
//! runs in place, one frequency column at a time), plus the native volume (`4 M' N^2`
//! bytes) and the output grid; [`memory_bytes`] gives the first two. Time: two 3-D
//! transforms, `O(M' N^2 log(M' N^2))`, and the linear Stolt pass.

use super::bp::VoxelGrid;
use super::wave::{self, fft3, linspace, Native, C64};
use crate::nlos::capture::Capture;
use crate::nlos::NlosError;
use rayon::prelude::*;
use rustfft::FftDirection;

/// Peak working memory of [`fk_migration`] on `c`, in bytes (without the capture and
/// the output grid): the padded complex volume and the native volume.
pub fn memory_bytes(c: &Capture) -> usize {
    wave::volume_bytes(c).saturating_add(wave::native_bytes(c))
}

/// The Stolt resampling (step 3) of a spectrum `f`, in place: `f` holds the
/// unshifted 3-D DFT of the (2M, 2N, 2N) padded data laid out (k_i, k_j, k_z) with
/// k_z fastest (index `(a 2N + b) 2M + k`, numpy's frequency order on each axis),
/// and `s` is the scale `N R / (4 M w)`. The result stays in unshifted order, ready for
/// the inverse transform. Every output column (a, b) depends on its input column
/// only.
pub fn stolt(f: &mut [C64], n: usize, m: usize, s: f64) {
    let (n2, m2) = (2 * n, 2 * m);
    debug_assert_eq!(f.len(), n2 * n2 * m2);
    // The z samples (numpy's arange(-M, M) / M), shifted order.
    let g: Vec<f64> = (0..m2).map(|k| (k as f64 - m as f64) / m as f64).collect();
    let last = g[m2 - 1];
    let s2 = s * s;
    // max S: at x = y = z = -1.
    let s_max = (s2 * (1.0 + 1.0) + 1.0).sqrt();
    let freq = |k: usize, len: usize| {
        // Unshifted index k of a length-2L axis -> normalised frequency (k' - L) / L,
        // k' = (k + L) mod 2L its shifted index.
        let l = len / 2;
        (((k + l) % len) as f64 - l as f64) / l as f64
    };
    f.par_chunks_mut(m2).enumerate().for_each_init(
        || vec![C64::new(0.0, 0.0); m2],
        |col_in, (ab, col)| {
            let (y, x) = (freq(ab / n2, n2), freq(ab % n2, n2));
            // The input column in shifted order: element q is frequency q - M.
            for (q, v) in col_in.iter_mut().enumerate() {
                *v = col[(q + m) % m2];
            }
            let r2 = x * x + y * y;
            // Output at shifted kz index q: z = (q - M) / M > 0 for q > M, stored at
            // unshifted index q - M; the rest is zero.
            col.fill(C64::new(0.0, 0.0));
            for q in m + 1..m2 {
                let z = g[q];
                let sq = (s2 * r2 + z * z).sqrt();
                let out = &mut col[q - m];
                if sq > last {
                    *out = C64::new(0.0, 0.0);
                    continue;
                }
                // scipy's find_interval: g[i] <= sq < g[i + 1], the last interval at the end.
                let mut i = ((sq * m as f64).floor() as usize + m).min(m2 - 2);
                while i > 0 && g[i] > sq {
                    i -= 1;
                }
                while i + 2 < m2 && g[i + 1] <= sq {
                    i += 1;
                }
                let t = (sq - g[i]) / (g[i + 1] - g[i]);
                let v = col_in[i] * (1.0 - t) + col_in[i + 1] * t;
                *out = v * (z.abs() / s_max);
            }
        },
    );
}

/// The native f-k volume of `c` (laid out (i, j, m), `N N M'` values) and its grid.
pub fn fk_native(c: &Capture) -> Result<(Native, Vec<f32>), NlosError> {
    fk_native_with(c, true)
}

/// The energy of f-k's linear field (the volume before its squared magnitude, on the
/// native grid), of a capture that may be signed: step 1 without its absolute value
/// (`nlos/shrink.rs`).
pub fn fk_linear_energy(c: &Capture) -> Result<f64, NlosError> {
    let (_, vol) = fk_native_with(c, false)?;
    Ok(vol.iter().map(|&v| f64::from(v)).sum())
}

/// [`fk_native`]; `abs`: step 1's absolute value (y-tal's), the identity on captures,
/// which are never negative.
fn fk_native_with(c: &Capture, abs: bool) -> Result<(Native, Vec<f32>), NlosError> {
    let g = Native::of(c, "fk")?;
    let (n, m) = (g.n, g.depths);
    let (n2, m2) = (2 * n, 2 * m);
    let len = n2
        .checked_mul(n2)
        .and_then(|v| v.checked_mul(m2))
        .ok_or(NlosError::PaddedOverflow { method: "fk" })?;
    let mut f = wave::zeroed(len, "fk's padded volume")?;
    // Step 1: ψ = |τ z_m|, in the (i < N, j < N, m < M') corner.
    let z = linspace(0.0, 1.0, m);
    f.par_chunks_mut(m2).enumerate().for_each(|(ab, col)| {
        let (i, j) = (ab / n2, ab % n2);
        if i < n && j < n {
            for (k, v) in col[..m].iter_mut().enumerate() {
                let x = g.h(c, k, i * n + j) as f64 * z[k];
                *v = C64::new(if abs { x.abs() } else { x }, 0.0);
            }
        }
    });
    // Steps 2-4.
    fft3(&mut f, [n2, n2, m2], FftDirection::Forward);
    let range = g.delta_t * m as f64;
    let s = (n as f64 * range) / (m as f64 * g.half_width() * 4.0);
    stolt(&mut f, n, m, s);
    fft3(&mut f, [n2, n2, m2], FftDirection::Inverse);
    let scale = 1.0 / len as f64;
    let mut vol = vec![0f32; n * n * m];
    vol.par_chunks_mut(m).enumerate().for_each(|(ij, out)| {
        let (i, j) = (ij / n, ij % n);
        let col = &f[(i * n2 + j) * m2..][..m];
        for (o, v) in out.iter_mut().zip(col) {
            *o = (v * scale).norm_sqr() as f32;
        }
    });
    Ok((g, vol))
}

/// The f-k migration of the confocal capture `c` on `grid`: (NX, NY, NZ) row-major,
/// voxel centres as [`VoxelGrid::coordinate`] (the convention of
/// `bp::backproject`), trilinear from the native volume, zero outside it. Errors
/// for captures fk cannot take (`Native::of`).
pub fn fk_migration(c: &Capture, grid: &VoxelGrid) -> Result<Vec<f32>, NlosError> {
    let (g, vol) = fk_native(c)?;
    Ok(g.resample(&vol, grid))
}
