//! Phasor-field reconstruction with Rayleigh-Sommerfeld propagation, as y-tal 0.20's
//! `tal.reconstruct.pf_dev.solve` with its defaults (camera system `DIRECT_LIGHT`,
//! border 'zero', no inverse-square compensation, `try_optimize_convolutions`).
//!
//! The capture's series are padded with `p = 2 ceil(6 wl_sigma / delta_t)` zeros on each
//! side (`nf = nt + 2 p` samples) and Fourier transformed; only the frequencies of the
//! virtual pulse are kept, DFT indices `k` from `floor(m - 3 s)` to `ceil(m + 3 s)` (at
//! least 0, at most `nf / 2`), `m = nf delta_t / wl_mean`, `s = nf delta_t / (6
//! wl_sigma)`, each weighted by the pulse's spectrum `w_k` (the pulse K of `filter.rs`,
//! centred by `fftshift`). At frequency `f_k` (numpy's `fftfreq`) the field at voxel v is
//!
//! ```text
//!   P_k(v) = w_k  sum_l e^{2 pi i f_k |l - v|}  sum_s e^{2 pi i f_k |v - s|}  H_k(l, s) e^{2 pi i f_k d_014(l, s)},
//!   d_014 = -t_start [+ |x_laser - l| + |s - x_sensor|]
//! ```
//!
//! (the bracketed terms when the capture's times include the first and last bounces),
//! and the reconstruction is the magnitude of the inverse DFT at the sample where the
//! padded series' time is 0: `|sum_k P_k(v) e^{2 pi i k p / nf}| / nf`. A confocal
//! capture, which y-tal's solver refuses, has one laser point per sensor point, the same
//! one: its sum is over s alone, with `e^{2 pi i f_k 2 |v - s|}`.
//!
//! The sum over sensor points is a 2-D convolution when the sensor grid is a regular
//! lattice with the voxel slice's steps (the wall in a plane z = const, its grid axes
//! along x and y, either order and sign): then it runs by FFT on the
//! `(NX + Sx - 1) x (NY + Sy - 1)` lattice of offsets (`rustfft`), one slice of constant z
//! at a time. Other volumes take the direct sum, as y-tal's fallback.
//!
//! Parallel over frequencies; each frequency's field is kept and the fields are summed
//! in frequency order, so the bits do not depend on the thread count. Memory: see
//! [`memory_bytes`].

use super::bp::VoxelGrid;
use crate::nlos::capture::Capture;
use crate::nlos::fft::Planner;
use crate::nlos::filter::{kernel, Shift};
use crate::nlos::NlosError;
use rayon::prelude::*;
use rustfft::num_complex::Complex;
use rustfft::Fft;
use std::f64::consts::TAU;
use std::sync::Arc;

type C64 = Complex<f64>;

const ZERO: C64 = C64 { re: 0.0, im: 0.0 };

/// The virtual pulse in the frequency domain.
pub struct Pulse {
    /// Padded length and the padding on each side.
    pub nf: usize,
    pub padding: usize,
    /// The DFT index of the first kept frequency (y-tal's `freq_min_idx`).
    pub first: usize,
    /// The kept frequencies (cycles per unit of OPL) and the pulse's spectrum there.
    pub freqs: Vec<f64>,
    pub weights: Vec<C64>,
}

/// The pulse of wavelength `wl_mean` and envelope `wl_sigma` for `nt` bins of `delta_t`.
pub fn pulse(nt: usize, delta_t: f64, wl_mean: f64, wl_sigma: f64) -> Result<Pulse, NlosError> {
    let padding = 2 * (6.0 * wl_sigma / delta_t).ceil() as usize;
    let nf = nt + 2 * padding;
    let mut k = kernel(nf, delta_t, wl_mean, wl_sigma, Shift::Fft);
    Planner::new().plan_fft_forward(nf).process(&mut k);
    let (m, s) = (
        nf as f64 * delta_t / wl_mean,
        nf as f64 * delta_t / (wl_sigma * 6.0),
    );
    let first = (m - 3.0 * s).floor().max(0.0) as usize;
    let last = ((m + 3.0 * s).ceil() as usize).min(nf / 2);
    if first > last {
        return Err(NlosError::Nyquist { wl_mean, delta_t });
    }
    // numpy's fftfreq: index k is k / (nf delta_t), or k - nf above (nf - 1) / 2.
    let freq = |i: usize| {
        let k = if i <= (nf - 1) / 2 {
            i as f64
        } else {
            i as f64 - nf as f64
        };
        k / (nf as f64 * delta_t)
    };
    Ok(Pulse {
        nf,
        padding,
        first,
        freqs: (first..=last).map(freq).collect(),
        weights: k[first..=last].to_vec(),
    })
}

/// The sensor grid as a lattice aligned with the voxel slices: sensor point `s` is
/// lattice cell `cell[s]` = (a, b), at `origin + a step_x + b step_y`.
struct Lattice {
    dims: [usize; 2],
    cell: Vec<[usize; 2]>,
    origin: [f64; 3],
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn norm(a: [f64; 3]) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

fn f64x3(p: [f32; 3]) -> [f64; 3] {
    p.map(|v| v as f64)
}

/// The voxel grid's step along axis `a` (0 for a single voxel).
fn step(grid: &VoxelGrid, a: usize) -> f64 {
    if grid.n[a] < 2 {
        0.0
    } else {
        (grid.last[a] - grid.first[a]) / (grid.n[a] - 1) as f64
    }
}

/// The lattice, when the sensor grid is regular with the voxel grid's x and y steps
/// (in either order and sign) in a plane of constant z.
fn lattice(c: &Capture, grid: &VoxelGrid) -> Option<Lattice> {
    let [sx, sy] = c.sensor_dims;
    let (dx, dy) = (step(grid, 0), step(grid, 1));
    if sx < 2 || sy < 2 || sx * sy != c.sensors || dx == 0.0 || dy == 0.0 {
        return None;
    }
    let p = |i: usize, j: usize| f64x3(c.sensor_grid[i * sy + j]);
    let (p00, du, dv) = (p(0, 0), sub(p(1, 0), p(0, 0)), sub(p(0, 1), p(0, 0)));
    let tol = 1e-4 * dx.abs().min(dy.abs());
    let close = |a: [f64; 3], b: [f64; 3]| norm(sub(a, b)) <= tol;
    for i in 0..sx {
        for j in 0..sy {
            let want = [0, 1, 2].map(|k| p00[k] + i as f64 * du[k] + j as f64 * dv[k]);
            if !close(p(i, j), want) {
                return None;
            }
        }
    }
    let (ex, ey) = ([dx, 0.0, 0.0], [0.0, dy, 0.0]);
    let neg = |a: [f64; 3]| a.map(|v| -v);
    // The sign of `d` along `e`: +1 or -1 when d = +-e.
    let along = |d: [f64; 3], e: [f64; 3]| {
        if close(d, e) {
            Some(1i64)
        } else if close(d, neg(e)) {
            Some(-1)
        } else {
            None
        }
    };
    // (which lattice axis grid index i runs along, its sign, j's sign)
    let (swap, su, sv) = match (along(du, ex), along(dv, ey), along(du, ey), along(dv, ex)) {
        (Some(su), Some(sv), _, _) => (false, su, sv),
        (_, _, Some(su), Some(sv)) => (true, su, sv),
        _ => return None,
    };
    let flip = |k: usize, n: usize, sign: i64| if sign > 0 { k } else { n - 1 - k };
    let mut cell = vec![[0usize; 2]; c.sensors];
    let mut origin = p00;
    for i in 0..sx {
        for j in 0..sy {
            let (a, b) = (flip(i, sx, su), flip(j, sy, sv));
            let ab = if swap { [b, a] } else { [a, b] };
            cell[i * sy + j] = ab;
            if ab == [0, 0] {
                origin = p(i, j);
            }
        }
    }
    let dims = if swap { [sy, sx] } else { [sx, sy] };
    Some(Lattice { dims, cell, origin })
}

/// Whether the sum over sensor points runs as an FFT convolution on `grid` (its slices
/// are the wall's lattice).
pub fn convolves(c: &Capture, grid: &VoxelGrid) -> bool {
    lattice(c, grid).is_some()
}

/// Bytes the reconstruction holds at its peak: the capture's kept spectrum (`nw L S`
/// complex f64), each thread's fields of one slice (`L NX NY`, plus the FFT lattices
/// when the convolution applies), the fields of one slice at every kept frequency
/// (`nw NX NY`) and the output (`NX NY NZ` f32, twice).
pub fn memory_bytes(c: &Capture, grid: &VoxelGrid, p: &Pulse) -> usize {
    let nw = p.freqs.len();
    let slice = grid.n[0] * grid.n[1];
    let [sx, sy] = c.sensor_dims;
    let lattice = (grid.n[0] + sx) * (grid.n[1] + sy);
    let threads = rayon::current_num_threads();
    let per_thread = (c.lasers + 2) * (slice + lattice) * 16;
    nw * c.lasers * c.sensors * 16 + threads * per_thread + nw * slice * 16 + grid.voxels() * 8
}

/// How the capture's spectrum is computed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Dft {
    /// Whichever costs fewer operations: [`Dft::Direct`] when `nw T <= 4 nf log2 nf`
    /// (a complex FFT takes ~5 nf log2 nf flops at a smooth length, several times that
    /// through Bluestein's; the direct sum 4 per bin and frequency).
    Cheapest,
    /// A padded FFT of each series (length nf: a Bluestein transform when nf has large
    /// prime factors), its kept bins.
    Fft,
    /// The kept bins alone, each a sum over the series' T bins with a table of
    /// twiddles (`nw T` complex f64).
    Direct,
}

/// The capture's spectrum at the pulse's frequencies, `[w][l][s]`, with the phase of
/// `d_014` applied.
fn spectrum(c: &Capture, p: &Pulse) -> Vec<C64> {
    spectrum_by(c, p, Dft::Cheapest)
}

/// [`spectrum`] computed as `how` says.
pub fn spectrum_by(c: &Capture, p: &Pulse, how: Dft) -> Vec<C64> {
    let (nt, nw, series) = (c.time.bins, p.freqs.len(), c.lasers * c.sensors);
    let direct = match how {
        Dft::Cheapest => (nw * nt) as f64 <= 4.0 * p.nf as f64 * (p.nf as f64).log2(),
        Dft::Fft => false,
        Dft::Direct => true,
    };
    // The FFT is planned only when used (a Bluestein plan is not free).
    let fft = (!direct).then(|| Planner::new().plan_fft_forward(p.nf));
    // twiddle[t nw + w] = exp(-2 pi i k n / nf) for DFT index k = first + w and padded
    // sample n = padding + t, its phase reduced modulo nf in integers.
    let twiddle: Vec<C64> = if direct {
        (0..nt)
            .flat_map(|t| {
                (0..nw).map(move |w| {
                    let kn = ((p.first + w) as u128 * (p.padding + t) as u128) % p.nf as u128;
                    C64::from_polar(1.0, -TAU * kn as f64 / p.nf as f64)
                })
            })
            .collect()
    } else {
        Vec::new()
    };
    let accounts = c.accounts_first_and_last_bounces;
    let d1 = |l: usize| match (accounts, c.laser_xyz) {
        (true, Some(x)) => norm(sub(f64x3(c.laser_grid[l]), f64x3(x))),
        _ => 0.0,
    };
    let d4 = |s: usize| match (accounts, c.sensor_xyz) {
        (true, Some(x)) => norm(sub(f64x3(c.sensor_grid[s]), f64x3(x))),
        _ => 0.0,
    };
    let block = Capture::SERIES_BLOCK;
    let per_series: Vec<Vec<C64>> = (0..series.div_ceil(block))
        .into_par_iter()
        .flat_map_iter(|b| {
            let qs = b * block..((b + 1) * block).min(series);
            let h = c.series(qs.clone());
            let mut buf = vec![ZERO; if direct { nw } else { p.nf }];
            let mut scratch = vec![ZERO; fft.as_ref().map_or(0, |f| f.get_inplace_scratch_len())];
            qs.enumerate()
                .map(|(k, q)| {
                    let (l, s) = (q / c.sensors, q % c.sensors);
                    buf.iter_mut().for_each(|z| *z = ZERO);
                    let h = &h[k * nt..(k + 1) * nt];
                    let kept = match &fft {
                        Some(fft) => {
                            for (t, &v) in h.iter().enumerate() {
                                buf[p.padding + t] = C64::new(v as f64, 0.0);
                            }
                            fft.process_with_scratch(&mut buf, &mut scratch);
                            &buf[p.first..p.first + nw]
                        }
                        None => {
                            for (&v, tw) in h.iter().zip(twiddle.chunks_exact(nw)) {
                                let v = v as f64;
                                for (z, t) in buf.iter_mut().zip(tw) {
                                    z.re += v * t.re;
                                    z.im += v * t.im;
                                }
                            }
                            &buf[..]
                        }
                    };
                    let li = if c.paired { s } else { l };
                    let d014 = -c.time.start_opl + d1(li) + d4(s);
                    kept.iter()
                        .zip(&p.freqs)
                        .map(|(&z, &f)| z * C64::from_polar(1.0, TAU * f * d014))
                        .collect::<Vec<_>>()
                })
                .collect::<Vec<_>>()
        })
        .collect();
    let mut out = vec![ZERO; nw * series];
    for (q, v) in per_series.iter().enumerate() {
        for (w, &z) in v.iter().enumerate() {
            out[w * series + q] = z;
        }
    }
    out
}

/// 2-D FFT in place of a row-major `nx x ny` array.
struct Fft2 {
    nx: usize,
    ny: usize,
    rows: Arc<dyn Fft<f64>>,
    cols: Arc<dyn Fft<f64>>,
}

impl Fft2 {
    fn new(planner: &mut Planner, nx: usize, ny: usize, inverse: bool) -> Fft2 {
        let plan = |p: &mut Planner, n| {
            if inverse {
                p.plan_fft_inverse(n)
            } else {
                p.plan_fft_forward(n)
            }
        };
        Fft2 {
            nx,
            ny,
            rows: plan(planner, ny),
            cols: plan(planner, nx),
        }
    }

    fn process(&self, a: &mut [C64], column: &mut Vec<C64>) {
        self.rows.process(a);
        column.resize(self.nx, ZERO);
        for j in 0..self.ny {
            for i in 0..self.nx {
                column[i] = a[i * self.ny + j];
            }
            self.cols.process(column);
            for i in 0..self.nx {
                a[i * self.ny + j] = column[i];
            }
        }
    }
}

/// One slice of constant z: its voxel centres, row-major (x, y).
fn slice_points(grid: &VoxelGrid, k: usize) -> Vec<[f64; 3]> {
    let z = grid.coordinate(2, k) as f64;
    (0..grid.n[0])
        .flat_map(|i| (0..grid.n[1]).map(move |j| (i, j)))
        .map(|(i, j)| {
            [
                grid.coordinate(0, i) as f64,
                grid.coordinate(1, j) as f64,
                z,
            ]
        })
        .collect()
}

/// How the sum over sensor points runs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Propagation {
    /// By FFT convolution when the slices are the wall's lattice, else directly.
    Fastest,
    /// Directly, voxel by voxel (the reference for the convolution).
    Direct,
}

/// The reconstruction (magnitude), (NX, NY, NZ) row-major; see the module notes.
pub fn phasor_field(
    c: &Capture,
    grid: &VoxelGrid,
    wl_mean: f64,
    wl_sigma: f64,
) -> Result<Vec<f32>, NlosError> {
    phasor_field_by(c, grid, wl_mean, wl_sigma, Propagation::Fastest)
}

/// [`phasor_field`] with the sum over sensor points run as `how` says.
pub fn phasor_field_by(
    c: &Capture,
    grid: &VoxelGrid,
    wl_mean: f64,
    wl_sigma: f64,
    how: Propagation,
) -> Result<Vec<f32>, NlosError> {
    let p = pulse(c.time.bins, c.time.bin_width_opl, wl_mean, wl_sigma)?;
    let hw = spectrum(c, &p);
    let [nx, ny, nz] = grid.n;
    let slice = nx * ny;
    let series = c.lasers * c.sensors;
    let lat = match how {
        Propagation::Fastest => lattice(c, grid),
        Propagation::Direct => None,
    };
    let Some(lat) = lat else {
        return Ok(direct_sum(c, grid, &p, &hw));
    };
    // Confocal: the light goes to v and back, the same distance twice.
    let twice = if c.paired { 2.0 } else { 1.0 };
    let mut planner = Planner::new();
    let (rx, ry) = (nx + lat.dims[0] - 1, ny + lat.dims[1] - 1);
    let fwd = Fft2::new(&mut planner, rx, ry, false);
    let inv = Fft2::new(&mut planner, rx, ry, true);
    let (dx, dy) = (step(grid, 0), step(grid, 1));
    let laser_points: Vec<[f64; 3]> = c.laser_grid.iter().map(|&q| f64x3(q)).collect();
    let mut out = vec![0f32; grid.voxels()];
    for k in 0..nz {
        let points = slice_points(grid, k);
        // Each kept frequency's field on the slice.
        let fields: Vec<Vec<C64>> = (0..p.freqs.len())
            .into_par_iter()
            .map_init(Vec::new, |column, w| {
                let f = p.freqs[w];
                let weight = p.weights[w];
                // y-tal skips frequencies where np.isclose(weight, 0).
                if weight.norm() <= 1e-8 {
                    return vec![ZERO; slice];
                }
                let h = &hw[w * series..(w + 1) * series];
                // cam[l][v]: the sum over sensor points.
                let cam: Vec<Vec<C64>> = {
                    let (rx, ry) = (fwd.nx, fwd.ny);
                    let [lx, ly] = lat.dims;
                    // The kernel over offsets (a - i, b - j), stored at
                    // (a - i + lx - 1, b - j + ly - 1).
                    let v0 = sub(points[0], lat.origin);
                    let mut kern = vec![ZERO; rx * ry];
                    for m in 0..rx {
                        for n in 0..ry {
                            let off = [
                                v0[0] + (m as f64 - (lx - 1) as f64) * dx,
                                v0[1] + (n as f64 - (ly - 1) as f64) * dy,
                                v0[2],
                            ];
                            kern[m * ry + n] = C64::from_polar(1.0, TAU * f * twice * norm(off));
                        }
                    }
                    fwd.process(&mut kern, column);
                    (0..c.lasers)
                        .map(|l| {
                            let mut a = vec![ZERO; rx * ry];
                            for (s, &[i, j]) in lat.cell.iter().enumerate() {
                                a[i * ry + j] = h[l * c.sensors + s];
                            }
                            fwd.process(&mut a, column);
                            a.iter_mut().zip(&kern).for_each(|(x, y)| *x *= y);
                            inv.process(&mut a, column);
                            let scale = 1.0 / (rx * ry) as f64;
                            (0..slice)
                                .map(|v| a[(v / ny + lx - 1) * ry + v % ny + ly - 1] * scale)
                                .collect()
                        })
                        .collect()
                };
                // The sum over laser points (none for a confocal capture).
                let field = if c.paired {
                    cam.into_iter().next().expect("one laser row")
                } else {
                    (0..slice)
                        .map(|v| {
                            laser_points
                                .iter()
                                .zip(&cam)
                                .map(|(&lp, row)| {
                                    row[v]
                                        * C64::from_polar(1.0, TAU * f * norm(sub(points[v], lp)))
                                })
                                .sum()
                        })
                        .collect()
                };
                field
            })
            .collect();
        // The inverse DFT at sample `padding`, in frequency order.
        let factors: Vec<C64> = (0..fields.len()).map(|w| back(&p, w)).collect();
        for v in 0..slice {
            let acc: C64 = fields.iter().zip(&factors).map(|(f, b)| f[v] * b).sum();
            out[v * nz + k] = acc.norm() as f32;
        }
    }
    Ok(out)
}

/// The inverse DFT's factor for kept frequency `w` at sample `padding`, with the
/// pulse's weight and the 1 / nf: `w_k e^{2 pi i k p / nf} / nf`, k = first + w.
fn back(p: &Pulse, w: usize) -> C64 {
    let idx = ((p.first + w) * p.padding) % p.nf;
    p.weights[w] * C64::from_polar(1.0, TAU * idx as f64 / p.nf as f64) / p.nf as f64
}

/// `sum_s h_s e_s` in single precision over split real and imaginary parts: the
/// reference, one term at a time.
pub fn dot_reference(hr: &[f32], hi: &[f32], er: &[f32], ei: &[f32]) -> C64 {
    let (mut re, mut im) = (0f32, 0f32);
    for s in 0..hr.len() {
        re += hr[s] * er[s] - hi[s] * ei[s];
        im += hr[s] * ei[s] + hi[s] * er[s];
    }
    C64::new(re as f64, im as f64)
}

/// [`dot_reference`], eight terms at a time where this CPU runs AVX2 + FMA (its sums
/// round differently: lanes of eight, fused multiply-adds; `dot_matches_the_reference`
/// bounds the difference).
pub fn dot(hr: &[f32], hi: &[f32], er: &[f32], ei: &[f32]) -> C64 {
    match crate::cpu::detected().avx2() {
        Some(isa) => dot_with(isa, hr, hi, er, ei),
        None => dot_with(crate::cpu::Baseline, hr, hi, er, ei),
    }
}

/// [`dot`] at the level `isa` proves.
#[inline(always)]
fn dot_with<L: crate::cpu::Level>(isa: L, hr: &[f32], hi: &[f32], er: &[f32], ei: &[f32]) -> C64 {
    #[cfg(target_arch = "x86_64")]
    if let Some(avx2) = isa.avx2() {
        return dot_avx2(avx2, hr, hi, er, ei);
    }
    dot_reference(hr, hi, er, ei)
}

/// [`dot`] with AVX2 + FMA.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn dot_avx2(_avx2: crate::cpu::Avx2, hr: &[f32], hi: &[f32], er: &[f32], ei: &[f32]) -> C64 {
    let n = hr.len();
    assert!(hi.len() == n && er.len() == n && ei.len() == n);
    let m = n / 8 * 8;
    // SAFETY: `_avx2` proves this CPU runs AVX2 and FMA (`cpu::Avx2`); the lengths are
    // as asserted.
    let (mut re, mut im) = unsafe { lanes_avx2(hr, hi, er, ei, m) };
    let tail = dot_reference(&hr[m..], &hi[m..], &er[m..], &ei[m..]);
    re += tail.re;
    im += tail.im;
    C64::new(re, im)
}

/// The first `m` (a multiple of 8) terms of [`dot_avx2`], as (re, im).
///
/// # Safety
/// The CPU runs AVX2 and FMA; every slice holds at least `m` values.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn lanes_avx2(hr: &[f32], hi: &[f32], er: &[f32], ei: &[f32], m: usize) -> (f64, f64) {
    use std::arch::x86_64::*;
    // SAFETY: every load reads 8 floats from index q <= m - 8 of slices of at least m
    // values (the caller's contract).
    unsafe {
        let (mut ar, mut ai) = (_mm256_setzero_ps(), _mm256_setzero_ps());
        for q in (0..m).step_by(8) {
            let a = _mm256_loadu_ps(hr.as_ptr().add(q));
            let b = _mm256_loadu_ps(hi.as_ptr().add(q));
            let c = _mm256_loadu_ps(er.as_ptr().add(q));
            let d = _mm256_loadu_ps(ei.as_ptr().add(q));
            ar = _mm256_fmadd_ps(a, c, _mm256_fnmadd_ps(b, d, ar));
            ai = _mm256_fmadd_ps(a, d, _mm256_fmadd_ps(b, c, ai));
        }
        let (mut r, mut i) = ([0f32; 8], [0f32; 8]);
        _mm256_storeu_ps(r.as_mut_ptr(), ar);
        _mm256_storeu_ps(i.as_mut_ptr(), ai);
        (
            r.iter().map(|&v| v as f64).sum::<f64>(),
            i.iter().map(|&v| v as f64).sum::<f64>(),
        )
    }
}

/// Phasors `e^{2 pi i f_w g d}` over the kept frequencies, advanced from one frequency
/// to the next by one multiplication (re-seeded where the frequencies are not evenly
/// spaced: numpy's fftfreq turns negative at nf / 2).
struct Phasors {
    /// The current phasor per distance, and the step.
    e: Vec<C64>,
    r: Vec<C64>,
    d: Vec<f64>,
}

impl Phasors {
    fn seed(&mut self, f: f64, df: f64) {
        self.e.clear();
        self.r.clear();
        for &d in &self.d {
            self.e.push(C64::from_polar(1.0, TAU * f * d));
            self.r.push(C64::from_polar(1.0, TAU * df * d));
        }
    }

    fn advance(&mut self) {
        self.e.iter_mut().zip(&self.r).for_each(|(e, r)| *e *= r);
    }
}

/// The reconstruction by direct sums, voxel by voxel (volumes whose slices are not
/// the wall's lattice): y-tal's `divide_volume`. The sum over sensor points runs in
/// single precision (y-tal's complex64), the rest in double.
fn direct_sum(c: &Capture, grid: &VoxelGrid, p: &Pulse, hw: &[C64]) -> Vec<f32> {
    let nw = p.freqs.len();
    let sum = DirectSum {
        c,
        grid,
        p,
        hr: hw.iter().map(|z| z.re as f32).collect(),
        hi: hw.iter().map(|z| z.im as f32).collect(),
        factors: (0..nw).map(|w| back(p, w)).collect(),
        df: if nw > 1 { p.freqs[1] - p.freqs[0] } else { 0.0 },
        twice: if c.paired { 2.0 } else { 1.0 },
    };
    let mut out = vec![0f32; grid.voxels()];
    // Voxels go in blocks that share each row of H's spectrum while it is in cache
    // (the spectrum is read once per block, not once per voxel).
    out.par_chunks_mut(DirectSum::BLOCK).enumerate().for_each(
        |(b, o)| match crate::cpu::detected().avx2() {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: the proof says this CPU runs the wrapper's instruction set.
            Some(isa) => unsafe { direct_sum_block_avx2(isa, &sum, b, o) },
            _ => direct_sum_block(crate::cpu::Baseline, &sum, b, o),
        },
    );
    out
}

/// What [`direct_sum`]'s blocks share.
struct DirectSum<'a> {
    c: &'a Capture,
    grid: &'a VoxelGrid,
    p: &'a Pulse,
    /// H's spectrum in single precision, split into real and imaginary parts.
    hr: Vec<f32>,
    hi: Vec<f32>,
    /// [`back`] per kept frequency.
    factors: Vec<C64>,
    /// The step between the first two kept frequencies.
    df: f64,
    /// 2 for confocal captures (there and back), else 1.
    twice: f64,
}

impl DirectSum<'_> {
    /// Voxels per block.
    const BLOCK: usize = 32;

    /// Whether kept frequency `w` is one step `df` after `w - 1`.
    fn even(&self, w: usize) -> bool {
        let f = &self.p.freqs;
        (f[w] - f[w - 1] - self.df).abs() <= 1e-9 * self.df.abs()
    }
}

/// [`direct_sum_block`] compiled for AVX2 + FMA (the same bits but for [`dot`]'s,
/// which are [`dot`]'s at this level wherever it runs).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
fn direct_sum_block_avx2(isa: crate::cpu::Avx2, sum: &DirectSum, b: usize, o: &mut [f32]) {
    direct_sum_block(isa, sum, b, o)
}

/// Block `b` of [`direct_sum`]'s voxels, into `o`.
#[inline(always)]
fn direct_sum_block<L: crate::cpu::Level>(isa: L, sum: &DirectSum, b: usize, o: &mut [f32]) {
    let DirectSum {
        c,
        grid,
        p,
        hr,
        hi,
        factors,
        df,
        twice,
    } = sum;
    let (nl, ns) = (c.lasers, c.sensors);
    let [_, ny, nz] = grid.n;
    let empty = || Phasors {
        e: Vec::new(),
        r: Vec::new(),
        d: Vec::new(),
    };
    let mut cams: Vec<Phasors> = (0..o.len()).map(|_| empty()).collect();
    let mut projs: Vec<Phasors> = (0..o.len()).map(|_| empty()).collect();
    for (q, (cam, proj)) in cams.iter_mut().zip(projs.iter_mut()).enumerate() {
        let idx = b * DirectSum::BLOCK + q;
        let (i, j, k) = (idx / (ny * nz), idx / nz % ny, idx % nz);
        let v = [0, 1, 2].map(|a| grid.coordinate(a, [i, j, k][a]) as f64);
        cam.d = c
            .sensor_grid
            .iter()
            .map(|&s| twice * norm(sub(v, f64x3(s))))
            .collect();
        if !c.paired {
            proj.d = c
                .laser_grid
                .iter()
                .map(|&l| norm(sub(v, f64x3(l))))
                .collect();
        }
    }
    let mut er = vec![0f32; o.len() * ns];
    let mut ei = vec![0f32; o.len() * ns];
    let mut field = vec![ZERO; o.len()];
    let mut acc = vec![ZERO; o.len()];
    for (w, factor) in factors.iter().enumerate() {
        for (cam, proj) in cams.iter_mut().zip(projs.iter_mut()) {
            if w == 0 || !sum.even(w) {
                cam.seed(p.freqs[w], *df);
                proj.seed(p.freqs[w], *df);
            } else {
                cam.advance();
                proj.advance();
            }
        }
        if p.weights[w].norm() <= 1e-8 {
            continue;
        }
        for (q, cam) in cams.iter().enumerate() {
            for (s, z) in cam.e.iter().enumerate() {
                er[q * ns + s] = z.re as f32;
                ei[q * ns + s] = z.im as f32;
            }
        }
        field.iter_mut().for_each(|f| *f = ZERO);
        let h = w * nl * ns;
        for l in 0..nl {
            let (hrl, hil) = (
                &hr[h + l * ns..h + (l + 1) * ns],
                &hi[h + l * ns..h + (l + 1) * ns],
            );
            for (q, f) in field.iter_mut().enumerate() {
                let e = q * ns..(q + 1) * ns;
                let s = dot_with(isa, hrl, hil, &er[e.clone()], &ei[e]);
                *f += if c.paired { s } else { s * projs[q].e[l] };
            }
        }
        for (a, f) in acc.iter_mut().zip(&field) {
            *a += f * factor;
        }
    }
    for (o, a) in o.iter_mut().zip(&acc) {
        *o = a.norm() as f32;
    }
}
