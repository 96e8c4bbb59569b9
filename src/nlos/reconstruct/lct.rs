//! The light-cone transform of a confocal capture (O'Toole, Lindell and Wetzstein,
//! "Confocal non-line-of-sight imaging based on the light-cone transform", Nature 2018),
//! as their reference `cnlos_reconstruction.m` with its defaults (LCT with the Wiener
//! filter, `isdiffuse = 0`, `snr = 8e-1`), on the capture's native grid (`wave.rs`: N x N
//! wall points, M' bins from OPL 0), then resampled onto the voxel grid.
//!
//! In the paper's terms, the confocal measurement τ(x', y', t) of an albedo ρ(x, y, z)
//! is, after the substitutions `v = (t / R)^2` and `u = (z / (R / 2))^2` (`R = M' Δt` the
//! OPL range), a 3-D convolution `R_t{τ} = h * R_z{ρ}` with the light cone
//! `h(x, y, v) = δ((4 w / R)^2 (x^2 + y^2) - v)` (lateral coordinates in units of 2w,
//! `w` the wall's half-width, `N |du| / 2`). The reconstruction:
//!
//! 1. `τ z_m^2` (`z_m = m / (M' - 1)`, the radiometric falloff of a retroreflective
//!    scene; the reference's default);
//! 2. resampled along time onto v: `R_t τ = A τ` with the M' x M' matrix
//!
//!    ```text
//!      A[r, c] = (1 / M') sum_{x = r M' + 1}^{(r + 1) M'} [ceil(sqrt x) = c + 1] / sqrt x
//!    ```
//!
//!    (the reference builds the M'^2 x M' matrix of the indicator over `sqrt x` and halves
//!    its rows log2 M' times by averaging pairs, for M' a power of two; the block mean
//!    above is the same matrix for any M'), zero-padded to (2M', 2N, 2N);
//! 3. convolved with the Wiener inverse of the light cone's PSF Ĥ,
//!    `F^-1[ conj(Ĥ) / (|Ĥ|^2 + 1 / snr) · F[·] ]` (F the 3-D DFT of the padded
//!    volume), and cropped to (M', N, N): the PSF is 1 on the (2M', 2N, 2N) samples
//!    where `|(4 w / R)^2 (x^2 + y^2) - v|` is least along v, divided by its count on the
//!    apex column, then by its 2-norm, and shifted circularly by N along x and y;
//! 4. resampled back along depth with `A^T` (the reference's `mtxi`), and clamped:
//!    `max(Re, 0)`.
//!
//! **One deliberate difference.** The reference's `definePsf` samples the cone at
//! `x, y = linspace(-1, 1, 2N)` and `v = linspace(0, 2, 2M')`: steps of `2 / (2N - 1)`
//! and `2 / (2M' - 1)` instead of the data's `1 / N` and `1 / M'`, and no sample at
//! x = 0, so after its shift by N the apex lies between two samples. Its volumes sit
//! off by half a sample or more along i and j and come early in depth (a point over a
//! wall sample of a 32 x 32 scan, 256 bins, peaks one sample off laterally and 5 bins
//! early; 16 x 16: 8 bins early). Here the cone is sampled on the data's own grid,
//! `x, y = (k - N) / N` (k < 2N: the apex at k = N, which the shift moves to 0) and
//! `v = k / M'`, and such a point peaks at its own sample and bin.
//!
//! Memory: two padded complex volumes (the data and the inverse PSF),
//! `2 · 2M' 2N 2N 16 = 256 M' N^2` bytes, plus the native volume (`4 M' N^2` bytes), the
//! operator (about 2M' entries) and the output grid; [`memory_bytes`] gives the first
//! three.

use super::bp::VoxelGrid;
use super::wave::{self, fft3, linspace, Native, C64};
use crate::nlos::capture::Capture;
use crate::nlos::NlosError;
use rayon::prelude::*;
use rustfft::FftDirection;

/// O'Toole's default signal-to-noise ratio of the Wiener filter (`snr = 8e-1`).
pub const DEFAULT_SNR: f64 = 0.8;

/// Peak working memory of [`lct`] on `c`, in bytes (without the capture and the
/// output grid): two padded complex volumes, the native volume and the operator.
pub fn memory_bytes(c: &Capture) -> usize {
    let (_, m) = wave::native_shape(c);
    wave::volume_bytes(c)
        .saturating_mul(2)
        .saturating_add(wave::native_bytes(c))
        .saturating_add(m.saturating_mul(2 * 24))
}

/// `sum_{x = a}^{b} x^{-1/2}`, `1 <= a <= b`: directly for short or early ranges,
/// else by Euler-Maclaurin to the fourth derivative (remainder below 1e-16 of the sum).
fn inv_sqrt_sum(a: u64, b: u64) -> f64 {
    if a < 256 || b - a < 256 {
        return (a..=b).map(|x| 1.0 / (x as f64).sqrt()).sum();
    }
    let (fa, fb) = (a as f64, b as f64);
    let (ra, rb) = (fa.sqrt(), fb.sqrt());
    let integral = 2.0 * (fb - fa) / (ra + rb);
    let ends = (1.0 / ra + 1.0 / rb) / 2.0;
    // f' = -x^{-3/2} / 2, f''' = -15/8 x^{-7/2}; B2/2! = 1/12, B4/4! = -1/720.
    let d1 = |x: f64| -0.5 / (x * x.sqrt());
    let d3 = |x: f64| -15.0 / 8.0 / (x * x * x * x.sqrt());
    integral + ends + (d1(fb) - d1(fa)) / 12.0 - (d3(fb) - d3(fa)) / 720.0
}

/// `ceil(sqrt x)` exactly.
fn ceil_sqrt(x: u64) -> u64 {
    let mut r = (x as f64).sqrt() as u64;
    while r * r > x {
        r -= 1;
    }
    while (r + 1) * (r + 1) <= x {
        r += 1;
    }
    if r * r == x {
        r
    } else {
        r + 1
    }
}

/// The time-to-v resampling operator A (`resamplingOperator`'s `mtx`) of `m` bins, as
/// its rows' non-zero entries (column, value), columns increasing; `mtxi = A^T`.
/// About 2m entries, built in O(m).
pub fn resampling_rows(m: usize) -> Vec<Vec<(usize, f64)>> {
    let mm = m as u64;
    (0..mm)
        .map(|r| {
            let (x0, x1) = (r * mm + 1, (r + 1) * mm);
            (ceil_sqrt(x0)..=ceil_sqrt(x1))
                .map(|cs| {
                    // x with ceil(sqrt x) = cs: ((cs - 1)^2, cs^2].
                    let lo = ((cs - 1) * (cs - 1) + 1).max(x0);
                    let hi = (cs * cs).min(x1);
                    ((cs - 1) as usize, inv_sqrt_sum(lo, hi) / m as f64)
                })
                .collect()
        })
        .collect()
}

/// The light cone's PSF, circularly shifted so that its apex is sample (0, 0, 0), into
/// `psf` laid out (2N, 2N, 2M) with the depth fastest (real values): on the samples
/// `x, y = (k - N) / N` (`k < 2N`), `v = k / M` (`k < 2M`), 1 where
/// `|(4 slope)^2 (x^2 + y^2) - v|` is least along v, divided by its count on the apex
/// column, then by its 2-norm.
fn define_psf(psf: &mut [C64], n: usize, m: usize, slope: f64) {
    let (n2, m2) = (2 * n, 2 * m);
    let xs: Vec<f64> = (0..n2).map(|k| (k as f64 - n as f64) / n as f64).collect();
    let vs: Vec<f64> = (0..m2).map(|k| k as f64 / m as f64).collect();
    let k = (4.0 * slope) * (4.0 * slope);
    // Column (a, b) here is column ((a + N) mod 2N, (b + N) mod 2N) of the centred PSF.
    psf.par_chunks_mut(m2).enumerate().for_each_init(
        || vec![0f64; m2],
        |d, (ab, col)| {
            let (a, b) = ((ab / n2 + n) % n2, (ab % n2 + n) % n2);
            let (y, x) = (xs[a], xs[b]);
            let cone = k * (x * x + y * y);
            for (dv, &v) in d.iter_mut().zip(&vs) {
                *dv = (cone - v).abs();
            }
            let least = d.iter().copied().fold(f64::INFINITY, f64::min);
            for (p, &dv) in col.iter_mut().zip(d.iter()) {
                *p = C64::new(if dv == least { 1.0 } else { 0.0 }, 0.0);
            }
        },
    );
    let apex: f64 = psf[..m2].iter().map(|v| v.re).sum();
    let count: f64 = psf.par_iter().map(|v| v.re).sum();
    let value = (1.0 / apex) / (count * (1.0 / apex) * (1.0 / apex)).sqrt();
    psf.par_iter_mut().for_each(|v| v.re *= value);
}

/// The native LCT volume of `c` (laid out (i, j, m), `N N M'` values) and its grid.
pub fn lct_native(c: &Capture, snr: f64) -> Result<(Native, Vec<f32>), NlosError> {
    lct_native_with(c, snr, true)
}

/// The energy of the LCT's linear field (the native volume before its clamp at 0),
/// for `nlos/shrink.rs`.
pub fn lct_linear_energy(c: &Capture, snr: f64) -> Result<f64, NlosError> {
    let (_, vol) = lct_native_with(c, snr, false)?;
    Ok(vol.iter().map(|&v| f64::from(v).powi(2)).sum())
}

/// [`lct_native`]; `clamp`: step 4's `max(Re, 0)`.
fn lct_native_with(c: &Capture, snr: f64, clamp: bool) -> Result<(Native, Vec<f32>), NlosError> {
    if !(snr.is_finite() && snr > 0.0) {
        return Err(NlosError::LctSnr(snr));
    }
    let g = Native::of(c, "lct")?;
    let (n, m) = (g.n, g.depths);
    let (n2, m2) = (2 * n, 2 * m);
    let len = n2
        .checked_mul(n2)
        .and_then(|v| v.checked_mul(m2))
        .ok_or(NlosError::PaddedOverflow { method: "lct" })?;
    let dims = [n2, n2, m2];
    let range = g.delta_t * m as f64;
    // The Wiener inverse of the PSF.
    let mut inv = wave::zeroed(len, "lct's inverse PSF")?;
    define_psf(&mut inv, n, m, g.half_width() / range);
    fft3(&mut inv, dims, FftDirection::Forward);
    inv.par_iter_mut()
        .for_each(|f| *f = f.conj() / (f.norm_sqr() + 1.0 / snr));
    // Steps 1-2: scaled, resampled onto v, padded.
    let a = resampling_rows(m);
    let z = linspace(0.0, 1.0, m);
    let mut d = wave::zeroed(len, "lct's padded volume")?;
    d.par_chunks_mut(m2).enumerate().for_each_init(
        || vec![0f64; m],
        |tau, (ab, col)| {
            let (i, j) = (ab / n2, ab % n2);
            if i >= n || j >= n {
                return;
            }
            for (k, t) in tau.iter_mut().enumerate() {
                *t = g.h(c, k, i * n + j) as f64 * (z[k] * z[k]);
            }
            for (v, row) in col[..m].iter_mut().zip(&a) {
                *v = C64::new(row.iter().map(|&(k, w)| w * tau[k]).sum(), 0.0);
            }
        },
    );
    // Step 3.
    fft3(&mut d, dims, FftDirection::Forward);
    d.par_iter_mut()
        .zip(inv.par_iter())
        .for_each(|(v, f)| *v *= f);
    drop(inv);
    fft3(&mut d, dims, FftDirection::Inverse);
    // Step 4: A^T along depth, the real part (A is real), clamped.
    let scale = 1.0 / len as f64;
    let mut vol = vec![0f32; n * n * m];
    vol.par_chunks_mut(m).enumerate().for_each_init(
        || vec![0f64; m],
        |acc, (ij, out)| {
            let (i, j) = (ij / n, ij % n);
            let col = &d[(i * n2 + j) * m2..][..m];
            acc.fill(0.0);
            for (row, v) in a.iter().zip(col) {
                let re = v.re * scale;
                for &(k, w) in row {
                    acc[k] += w * re;
                }
            }
            for (o, &v) in out.iter_mut().zip(acc.iter()) {
                *o = if clamp { v.max(0.0) } else { v } as f32;
            }
        },
    );
    Ok((g, vol))
}

/// The LCT reconstruction of the confocal capture `c` on `grid` with the Wiener
/// filter's signal-to-noise ratio `snr` ([`DEFAULT_SNR`], O'Toole's `8e-1`):
/// (NX, NY, NZ) row-major, voxel centres as [`VoxelGrid::coordinate`] (the convention
/// of `bp::backproject`), trilinear from the native volume, zero outside it. Errors
/// for captures LCT cannot take (`Native::of`) and a non-positive `snr`.
pub fn lct(c: &Capture, grid: &VoxelGrid, snr: f64) -> Result<Vec<f32>, NlosError> {
    let (g, vol) = lct_native(c, snr)?;
    Ok(g.resample(&vol, grid))
}
