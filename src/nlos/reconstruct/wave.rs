//! What the wave-based confocal reconstructions share (f-k migration, `fk.rs`; the
//! light-cone transform, `lct.rs`): the capture's native grid, an in-place 3-D FFT and
//! the trilinear resampling of a native volume onto a [`VoxelGrid`].
//!
//! **The native grid.** Both algorithms need a confocal scan of an N x N regular planar
//! grid: sensor point (i, j) (`sensor_grid[i N + j]`) at `o + i du + j dv` with
//! du ⟂ dv and |du| = |dv|, and bin m of H at OPL `t0 + m Δt` with bin 0 at OPL 0
//! (O'Toole's and Lindell's codes, and y-tal's fk, assume it and ignore `t_start`).
//! A capture whose bins start later gets `p = round(t_start / Δt)` zero bins in front
//! (an earlier start drops its first `-p` bins), so that the series has
//! `M' = M + p` bins and its bin 0 lies at the residual `t0 = t_start - p Δt`,
//! `|t0| <= Δt / 2`. Their volumes are (M', N, N) arrays, depth m at the wall's point
//! (i, j):
//!
//! ```text
//!   x(m, i, j) = o + i du + j dv + n (t0 + m Δt) / 2
//! ```
//!
//! (n: the capture's wall normal, towards the hidden scene). Both use the wall's
//! half-width `w = N |du| / 2` (the half side of the N cells the points sample; y-tal's
//! fk takes `sensor_grid_xyz[-1, -1, 0]`, the last point's x, which on its grids
//! centred at the origin is `w - |du| / 2`).
//!
//! In memory a native volume is laid out (i, j, m), depth fastest: the padded
//! spectra both algorithms transform are (2N, 2N, 2M') complex arrays in the same
//! order, so every time series is contiguous.

use super::bp::VoxelGrid;
use crate::nlos::capture::Capture;
use crate::nlos::fft::Planner;
use crate::nlos::NlosError;
use rayon::prelude::*;
use rustfft::num_complex::Complex;
use rustfft::{Fft, FftDirection};
use std::sync::Arc;

pub type C64 = Complex<f64>;

/// Relative tolerance of the regular-grid checks (positions against `o + i du + j dv`,
/// |du| against |dv|, du against dv's direction).
pub const GRID_TOLERANCE: f64 = 1e-4;
/// How far from perpendicular to the grid the wall normal may be (cosine).
pub const NORMAL_TOLERANCE: f64 = 1e-3;
/// Index coordinates this close to a grid node are taken as the node, so that a voxel
/// grid that coincides with the native grid (its f32 centres a few ulps off) reads the
/// native values exactly.
pub const SNAP: f64 = 1e-3;
/// At most this many native depths (bins after padding).
pub const MAX_DEPTHS: usize = 1 << 22;

/// A confocal capture's native grid (see the module notes).
#[derive(Clone, Debug, PartialEq)]
pub struct Native {
    /// N, the sensor grid's side.
    pub n: usize,
    /// M', the native depths: the capture's bins plus `pad` minus `skip`.
    pub depths: usize,
    /// Zero bins put in front of H (`t_start > 0`).
    pub pad: usize,
    /// Bins of H dropped at its start (`t_start < 0`).
    pub skip: usize,
    /// Sensor point (0, 0) and the steps along i and j.
    pub origin: [f64; 3],
    pub du: [f64; 3],
    pub dv: [f64; 3],
    /// The wall's unit normal, towards the hidden scene.
    pub normal: [f64; 3],
    /// OPL of native bin 0, and the bin width.
    pub t0: f64,
    pub delta_t: f64,
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}
fn f64x3(p: [f32; 3]) -> [f64; 3] {
    p.map(f64::from)
}

/// The native shape (N, M') of a capture, unchecked: for memory estimates of captures
/// that may yet be refused. M' saturates.
pub fn native_shape(c: &Capture) -> (usize, usize) {
    let n = c.sensor_dims[0].max(c.sensor_dims[1]);
    let p = if c.time.bin_width_opl > 0.0 && c.time.start_opl.is_finite() {
        (c.time.start_opl / c.time.bin_width_opl).round()
    } else {
        0.0
    };
    let m = if p >= 0.0 {
        c.time
            .bins
            .saturating_add(p.min(usize::MAX as f64) as usize)
    } else {
        c.time
            .bins
            .saturating_sub((-p).min(usize::MAX as f64) as usize)
    };
    (n, m)
}

/// Bytes of one padded complex volume (2M', 2N, 2N) of `c`, saturating.
pub fn volume_bytes(c: &Capture) -> usize {
    let (n, m) = native_shape(c);
    [2 * n, 2 * n, 2, 16]
        .iter()
        .fold(m, |acc, &f| acc.saturating_mul(f))
}

/// Bytes of the native real volume (M', N, N) f32, saturating.
pub fn native_bytes(c: &Capture) -> usize {
    let (n, m) = native_shape(c);
    m.saturating_mul(n).saturating_mul(n).saturating_mul(4)
}

impl Native {
    /// The native grid of `c`, or why fk and LCT cannot reconstruct it.
    pub fn of(c: &Capture, method: &'static str) -> Result<Native, NlosError> {
        if !c.paired {
            return Err(NlosError::NotConfocal { method });
        }
        if c.accounts_first_and_last_bounces {
            return Err(NlosError::BounceTimes { method });
        }
        let [sx, sy] = c.sensor_dims;
        if sx != sy || sx < 2 {
            return Err(NlosError::NotSquare { method, sx, sy });
        }
        let n = sx;
        if c.sensors != n * n || c.sensor_grid.len() != n * n || c.lasers != 1 {
            return Err(NlosError::GridMismatch {
                method,
                lasers: c.lasers,
                sensors: c.sensors,
                n,
                points: c.sensor_grid.len(),
            });
        }
        if c.time.bins.checked_mul(c.sensors) != Some(c.h.len()) {
            return Err(NlosError::HLength {
                method,
                values: c.h.len(),
                bins: c.time.bins,
                points: c.sensors,
            });
        }
        if c.time.bins < 2 {
            return Err(NlosError::TooFewBins {
                method,
                bins: c.time.bins,
            });
        }
        if !(c.time.bin_width_opl.is_finite()
            && c.time.bin_width_opl > 0.0
            && c.time.start_opl.is_finite())
        {
            return Err(NlosError::TimeAxis {
                method,
                t_start: c.time.start_opl,
                delta_t: c.time.bin_width_opl,
            });
        }
        if let Some(k) = c.h.iter().position(|v| !v.is_finite()) {
            return Err(NlosError::NonFiniteH {
                method,
                bin: k / c.sensors,
                point: k % c.sensors,
            });
        }
        // The grid: o + i du + j dv, du and dv from the far corners.
        let p = |i: usize, j: usize| f64x3(c.sensor_grid[i * n + j]);
        let origin = p(0, 0);
        let steps = (n - 1) as f64;
        let du = sub(p(n - 1, 0), origin).map(|v| v / steps);
        let dv = sub(p(0, n - 1), origin).map(|v| v / steps);
        let (lu, lv) = (norm(du), norm(dv));
        if !(lu.is_finite() && lu > 0.0 && lv > 0.0) {
            return Err(NlosError::NotPlanar { method, du, dv });
        }
        if (lu - lv).abs() > GRID_TOLERANCE * lu || dot(du, dv).abs() > GRID_TOLERANCE * lu * lv {
            return Err(NlosError::NotSquareCells { method, du, dv });
        }
        let far = c
            .sensor_grid
            .iter()
            .flat_map(|q| q.iter().map(|v| v.abs() as f64))
            .fold(0.0, f64::max);
        let tol = GRID_TOLERANCE * steps * lu + 4.0 * f32::EPSILON as f64 * far;
        for i in 0..n {
            for j in 0..n {
                let want = [0, 1, 2].map(|a| origin[a] + i as f64 * du[a] + j as f64 * dv[a]);
                let off = norm(sub(p(i, j), want));
                if off > tol {
                    return Err(NlosError::Irregular { method, i, j, off });
                }
            }
        }
        let nr = f64x3(c.normal);
        let ln = norm(nr);
        if !(ln.is_finite() && ln > 0.0) {
            return Err(NlosError::NormalNotDirection { method, normal: nr });
        }
        let normal = nr.map(|v| v / ln);
        if dot(normal, du).abs() > NORMAL_TOLERANCE * lu
            || dot(normal, dv).abs() > NORMAL_TOLERANCE * lv
        {
            return Err(NlosError::NormalNotPerpendicular { method, normal });
        }
        // Bin 0 at OPL 0: pad or skip whole bins.
        let p = (c.time.start_opl / c.time.bin_width_opl).round();
        if p.abs() > MAX_DEPTHS as f64 {
            return Err(NlosError::StartTooEarly { method, bins: p });
        }
        let (pad, skip) = if p >= 0.0 {
            (p as usize, 0)
        } else {
            (0, (-p) as usize)
        };
        let depths = (c.time.bins + pad).saturating_sub(skip);
        if depths < 2 {
            return Err(NlosError::TooFewDepths {
                method,
                t_start: c.time.start_opl,
                depths,
            });
        }
        if depths > MAX_DEPTHS {
            return Err(NlosError::TooManyDepths {
                method,
                depths,
                t_start: c.time.start_opl,
                pad,
            });
        }
        let t0 = c.time.start_opl - p * c.time.bin_width_opl;
        Ok(Native {
            n,
            depths,
            pad,
            skip,
            origin,
            du,
            dv,
            normal,
            t0,
            delta_t: c.time.bin_width_opl,
        })
    }

    /// H at native bin `m` of point `s` (0 in the padding).
    #[inline]
    pub fn h(&self, c: &Capture, m: usize, s: usize) -> f32 {
        let b = m + self.skip;
        if b < self.pad || b - self.pad >= c.time.bins {
            0.0
        } else {
            c.h[(b - self.pad) * c.sensors + s]
        }
    }

    /// The wall's half-width w = N |du| / 2.
    pub fn half_width(&self) -> f64 {
        self.n as f64 * norm(self.du) / 2.0
    }

    /// The world point of native voxel (m, i, j).
    pub fn point(&self, m: usize, i: usize, j: usize) -> [f64; 3] {
        let depth = (self.t0 + m as f64 * self.delta_t) / 2.0;
        [0, 1, 2].map(|a| {
            self.origin[a] + i as f64 * self.du[a] + j as f64 * self.dv[a] + self.normal[a] * depth
        })
    }

    /// The voxel grid that coincides with the native grid, when du, dv and the normal
    /// point along +x, +y and +z: (N, N, M') voxels, x along i, y along j, z along m.
    pub fn voxel_grid(&self) -> Option<VoxelGrid> {
        let along = |v: [f64; 3], a: usize| {
            let l = norm(v);
            v[a] > 0.0 && (0..3).all(|b| b == a || v[b].abs() <= GRID_TOLERANCE * l)
        };
        if !(along(self.du, 0) && along(self.dv, 1) && along(self.normal, 2)) {
            return None;
        }
        let (first, last) = (
            self.point(0, 0, 0),
            self.point(self.depths - 1, self.n - 1, self.n - 1),
        );
        Some(VoxelGrid {
            first,
            last,
            n: [self.n, self.n, self.depths],
        })
    }

    /// Trilinear resampling of a native volume (laid out (i, j, m), `N N M'` values)
    /// onto `grid`: (NX, NY, NZ) row-major, zero outside the native grid. A voxel
    /// centre x maps to index coordinates (i, j, m) by the inverse of the native
    /// grid's affine map, `x = o + i du + j dv + n (t0 + m Δt) / 2`; coordinates within
    /// [`SNAP`] of a node are snapped to it, so a grid that coincides with the native
    /// one reads its values exactly.
    pub fn resample(&self, vol: &[f32], grid: &VoxelGrid) -> Vec<f32> {
        let (n, md) = (self.n, self.depths);
        debug_assert_eq!(vol.len(), n * n * md);
        // Columns du, dv, n Δt / 2 of the map; its inverse by cofactors.
        let h = self.delta_t / 2.0;
        let e = [self.du, self.dv, self.normal.map(|v| v * h)];
        let cross = |a: [f64; 3], b: [f64; 3]| {
            [
                a[1] * b[2] - a[2] * b[1],
                a[2] * b[0] - a[0] * b[2],
                a[0] * b[1] - a[1] * b[0],
            ]
        };
        let det = dot(e[0], cross(e[1], e[2]));
        // Rows of the inverse: (e1 x e2, e2 x e0, e0 x e1) / det.
        let inv =
            [cross(e[1], e[2]), cross(e[2], e[0]), cross(e[0], e[1])].map(|r| r.map(|v| v / det));
        let base = [0, 1, 2].map(|a| self.origin[a] + self.normal[a] * self.t0 / 2.0);
        let [nx, ny, nz] = grid.n;
        let axis = |a: usize, k: usize| (0..k).map(|i| grid.coordinate(a, i) as f64).collect();
        let (xs, ys, zs): (Vec<f64>, Vec<f64>, Vec<f64>) = (axis(0, nx), axis(1, ny), axis(2, nz));
        let snap = |f: f64| {
            let r = f.round();
            if (f - r).abs() <= SNAP {
                r
            } else {
                f
            }
        };
        // Lower node and weight of the upper one along an axis of `len` nodes.
        let locate = |f: f64, len: usize| -> Option<(usize, f64)> {
            if !(f >= 0.0 && f <= (len - 1) as f64) {
                return None;
            }
            let lo = (f.floor() as usize).min(len - 2);
            Some((lo, f - lo as f64))
        };
        let mut out = vec![0f32; nx * ny * nz];
        out.par_chunks_mut(nz.max(1))
            .enumerate()
            .for_each(|(xy, col)| {
                let (x, y) = (xy / ny, xy % ny);
                for (z, o) in col.iter_mut().enumerate() {
                    let r = sub([xs[x], ys[y], zs[z]], base);
                    let f = inv.map(|row| snap(dot(row, r)));
                    let (Some((i, a)), Some((j, b)), Some((m, g))) =
                        (locate(f[0], n), locate(f[1], n), locate(f[2], md))
                    else {
                        continue;
                    };
                    let mut acc = 0f64;
                    for (di, wi) in [(0, 1.0 - a), (1, a)] {
                        for (dj, wj) in [(0, 1.0 - b), (1, b)] {
                            for (dm, wm) in [(0, 1.0 - g), (1, g)] {
                                let w = wi * wj * wm;
                                if w != 0.0 {
                                    acc += w * vol[((i + di) * n + j + dj) * md + m + dm] as f64;
                                }
                            }
                        }
                    }
                    *o = acc as f32;
                }
            });
        out
    }
}

/// A zeroed complex buffer of `len` values, or an error when it cannot be had.
pub fn zeroed(len: usize, what: &'static str) -> Result<Vec<C64>, NlosError> {
    let mut v = Vec::new();
    v.try_reserve_exact(len)
        .map_err(|_| NlosError::Memory { what, len })?;
    v.resize(len, C64::new(0.0, 0.0));
    Ok(v)
}

/// Columns per block of the strided transforms (gathered into a contiguous buffer).
const BLOCK: usize = 16;

/// FFT along the row index of a matrix given as its rows (all of one width): column
/// blocks are gathered, transposed, transformed and scattered back.
fn fft_columns(
    rows: &mut [&mut [C64]],
    fft: &dyn Fft<f64>,
    buf: &mut Vec<C64>,
    scratch: &mut Vec<C64>,
) {
    let len = rows.len();
    let width = rows.first().map_or(0, |r| r.len());
    scratch.resize(fft.get_inplace_scratch_len(), C64::new(0.0, 0.0));
    for c0 in (0..width).step_by(BLOCK) {
        let bw = BLOCK.min(width - c0);
        buf.resize(bw * len, C64::new(0.0, 0.0));
        for (r, row) in rows.iter().enumerate() {
            for (c, &v) in row[c0..c0 + bw].iter().enumerate() {
                buf[c * len + r] = v;
            }
        }
        fft.process_with_scratch(&mut buf[..bw * len], scratch);
        for (r, row) in rows.iter_mut().enumerate() {
            for (c, v) in row[c0..c0 + bw].iter_mut().enumerate() {
                *v = buf[c * len + r];
            }
        }
    }
}

/// The 3-D DFT of `data`, a (d0, d1, d2) row-major array, in place, unnormalised
/// (`numpy.fft.fftn`; the inverse direction is `ifftn` times `d0 d1 d2`):
///
/// ```text
///   X[k0, k1, k2] = sum_{n0, n1, n2} x[n0, n1, n2] exp(∓2πi (k0 n0 / d0 + k1 n1 / d1 + k2 n2 / d2))
/// ```
///
/// as 1-D transforms (`rustfft`) along each axis, parallel over lines (rayon); the
/// strided axes go through small transposed blocks. Extra memory: per thread a block
/// of `16 d` values and the transform's scratch.
pub fn fft3(data: &mut [C64], dims: [usize; 3], direction: FftDirection) {
    let [d0, d1, d2] = dims;
    assert_eq!(data.len(), d0 * d1 * d2, "fft3: dims do not match the data");
    if data.is_empty() {
        return;
    }
    let mut planner = Planner::new();
    let plans: [Arc<dyn Fft<f64>>; 3] = dims.map(|d| planner.plan_fft(d, direction));
    // Axis 2: contiguous lines, several per task.
    let f2 = &plans[2];
    let lines = (4096 / d2).max(1);
    data.par_chunks_mut(d2 * lines).for_each_init(
        || vec![C64::new(0.0, 0.0); f2.get_inplace_scratch_len()],
        |scratch, chunk| f2.process_with_scratch(chunk, scratch),
    );
    // Axis 1: each (d1, d2) slab on its own.
    let f1 = &*plans[1];
    data.par_chunks_mut(d1 * d2).for_each_init(
        || (Vec::new(), Vec::new()),
        |(buf, scratch), slab| {
            let mut rows: Vec<&mut [C64]> = slab.chunks_mut(d2).collect();
            fft_columns(&mut rows, f1, buf, scratch);
        },
    );
    // Axis 0: the (d0, d1 d2) matrix split into column ranges, one task each.
    let f0 = &*plans[0];
    let width = d1 * d2;
    let parts = (rayon::current_num_threads() * 8)
        .min(width.div_ceil(BLOCK))
        .max(1);
    let part = width.div_ceil(parts);
    let mut tasks: Vec<Vec<&mut [C64]>> = (0..width.div_ceil(part))
        .map(|_| Vec::with_capacity(d0))
        .collect();
    for row in data.chunks_mut(width) {
        for (t, seg) in row.chunks_mut(part).enumerate() {
            tasks[t].push(seg);
        }
    }
    tasks.into_par_iter().for_each_init(
        || (Vec::new(), Vec::new()),
        |(buf, scratch), mut rows| fft_columns(&mut rows, f0, buf, scratch),
    );
}

/// numpy's `linspace(0, stop, n)` in double precision (`i * (stop / (n - 1))`, the last
/// value `stop`).
pub fn linspace(start: f64, stop: f64, n: usize) -> Vec<f64> {
    if n == 1 {
        return vec![start];
    }
    let step = (stop - start) / (n - 1) as f64;
    (0..n)
        .map(|i| {
            if i == n - 1 {
                stop
            } else {
                i as f64 * step + start
            }
        })
        .collect()
}
