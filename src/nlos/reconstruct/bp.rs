//! Backprojection, as y-tal 0.20's `tal.reconstruct.bp` with its default camera system
//! (`CameraSystem.DIRECT_LIGHT`, no inverse-square compensation): voxel v sums, over
//! every laser point l and sensor point s, the capture at the bin of the path's length
//!
//! ```text
//!   d = [|x_laser - l|] + |l - v| + |v - s| + [|s - x_sensor|],   bin = trunc((d - t_start) / delta_t)
//! ```
//!
//! (the bracketed segments when the capture's times include the first and last
//! bounces; a confocal capture's laser point is its sensor point), when the bin lies in
//! the capture. As in y-tal, distances are single precision, and the bin index is
//! computed in double precision unless the first and last bounces are counted (then in
//! single), and truncated towards zero.
//!
//! How: each voxel's sum runs over the pairs in the same order (laser-major) in f64,
//! so the result is the same bits as the plain loop over voxels, pairs and bins (the
//! tests keep that loop as the reference), at any thread count. The pairs' time series
//! are transposed first, each contiguous and padded with a zero bin on either side
//! (`(pair, 1 + T + 1)`, the planes of the filtered backprojection interleaved so that
//! one 8-byte gather fetches both), so a bin outside the capture is clamped onto a
//! zero instead of being branched on. Voxels go in blocks (at most [`BLOCK`]); per
//! block, the distances from its voxels to every laser and sensor point are tabulated
//! once (a confocal pair's, once per pair, and once for both ends when its laser
//! point is its sensor point), then the pairs go one after the other over
//! the block's voxels: the pair's series stays in L1 (the next one's is prefetched)
//! while its bins are gathered, and the bins of 8 voxels are computed at once (AVX2,
//! which the build targets; a scalar loop otherwise). Blocks run in parallel (rayon).
//!
//! Cost: voxels x laser points x sensor points (one division and one gather per
//! voxel and pair; the gathers bound it), plus (laser + sensor points) x voxels
//! distances. Memory: f64 accumulators, NX NY NZ f64 per plane, then the output, NX
//! NY NZ f32 per plane; the transposed series, at most [`CHUNK_BYTES`] at a time (a
//! larger capture is backprojected a chunk of pairs at a time, the sums keeping their
//! order); per thread, the block's distance tables, at most [`TABLE_BYTES`] (or 64
//! voxels' worth).

use crate::nlos::capture::Capture;
use rayon::prelude::*;

/// Voxel centres: per axis `n` points spaced as `numpy.linspace(first, last, n)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VoxelGrid {
    pub first: [f64; 3],
    pub last: [f64; 3],
    pub n: [usize; 3],
}

impl VoxelGrid {
    /// Coordinate `i` of axis `a`, as numpy's linspace (then single precision, as
    /// y-tal's `astype(np.float32)`).
    pub fn coordinate(&self, a: usize, i: usize) -> f32 {
        let n = self.n[a];
        if n == 1 {
            return self.first[a] as f32;
        }
        let step = (self.last[a] - self.first[a]) / (n - 1) as f64;
        let v = if i == n - 1 {
            self.last[a]
        } else {
            self.first[a] + i as f64 * step
        };
        v as f32
    }

    pub fn voxels(&self) -> usize {
        self.n.iter().product()
    }
}

#[inline]
fn dist(a: [f32; 3], b: [f32; 3]) -> f32 {
    let d = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
}

/// The backprojection of `c` on `grid`, (NX, NY, NZ) row-major.
pub fn backproject(c: &Capture, grid: &VoxelGrid) -> Vec<f32> {
    backproject_planes(c, grid, &[&c.h]).remove(0)
}

/// y-tal's filtered backprojection (`tal.reconstruct.fbp`): the capture filtered by
/// `filter::pf_filter`, backprojected (complex), and its magnitude.
pub fn filtered_backproject(
    c: &Capture,
    grid: &VoxelGrid,
    wl_mean: f64,
    wl_sigma: f64,
) -> Vec<f32> {
    let f = crate::nlos::filter::pf_filter(c, wl_mean, wl_sigma);
    let [re, im] = <[Vec<f32>; 2]>::try_from(backproject_planes(c, grid, &[&f.re, &f.im]))
        .expect("two planes");
    re.iter().zip(&im).map(|(&a, &b)| a.hypot(b)).collect()
}

/// The most voxels per block (a multiple of 8, the widest SIMD step): per pair, the
/// block's accumulators (8 or 16 bytes per voxel) and its two rows of distances stream
/// through L1 and L2 while the pair's series stays in L1.
pub const BLOCK: usize = 2048;

/// Bytes of transposed series held at once.
pub const CHUNK_BYTES: usize = 32 << 20;

/// Bytes of a block's distance tables at most (fewer voxels per block for captures of
/// many points).
pub const TABLE_BYTES: usize = 8 << 20;

/// The time axis and the voxel-independent segments, in the precision of the bins.
struct Bins {
    /// Single-precision bins (the first and last bounces counted).
    single: bool,
    t_start: f64,
    delta_t: f64,
    /// `T`: series hold `T + 2` entries per plane, bin b at `b + 1`.
    bins: usize,
    /// Laser to laser point, per laser-grid point; sensor point to sensor, per sensor
    /// (zeros unless `single`).
    d1: Vec<f32>,
    d4: Vec<f32>,
}

impl Bins {
    fn of(c: &Capture) -> Bins {
        let single = c.accounts_first_and_last_bounces;
        let d1 = c
            .laser_grid
            .iter()
            .map(|&p| match (single, c.laser_xyz) {
                (true, Some(x)) => dist(x, p),
                _ => 0.0,
            })
            .collect();
        let d4 = c
            .sensor_grid
            .iter()
            .map(|&p| match (single, c.sensor_xyz) {
                (true, Some(x)) => dist(p, x),
                _ => 0.0,
            })
            .collect();
        Bins {
            single,
            t_start: c.time.start_opl,
            delta_t: c.time.bin_width_opl,
            bins: c.time.bins,
            d1,
            d4,
        }
    }

    /// The bin of a path (y-tal's arithmetic): `a` is the laser side (`d1 + d2` when
    /// `single`, else `d2`), `b` the voxel to sensor point distance, `d4` the sensor
    /// segment.
    #[inline]
    fn bin(&self, a: f32, b: f32, d4: f32) -> i64 {
        if self.single {
            let d = a + b + d4;
            ((d - self.t_start as f32) / self.delta_t as f32) as i64
        } else {
            let d = a as f64 + b as f64;
            ((d - self.t_start) / self.delta_t) as i64
        }
    }

    /// The series index of a path's bin: `bin + 1`, or a padding zero's index.
    #[inline]
    fn slot(&self, a: f32, b: f32, d4: f32) -> usize {
        (self.bin(a, b, d4).clamp(-1, self.bins as i64) + 1) as usize
    }

    /// `laser`'s row of `a` for the voxels `v`: `dist(l, v)`, plus `d1` when single.
    fn laser_row(&self, out: &mut Vec<f32>, l: [f32; 3], laser: usize, v: [&[f32]; 3]) {
        let from = out.len();
        distances(out, l, v);
        if self.single {
            let d1 = self.d1[laser];
            out[from..].iter_mut().for_each(|x| *x += d1);
        }
    }
}

/// Backprojects each of `planes` (values laid out as `Capture::h`) at the same bins.
fn backproject_planes(c: &Capture, grid: &VoxelGrid, planes: &[&[f32]]) -> Vec<Vec<f32>> {
    // Blocks enough for every thread to get several, tables of at most TABLE_BYTES
    // (the sums do not depend on the block size).
    let points = if c.paired {
        2
    } else {
        c.laser_grid.len() + c.sensors
    };
    let block = (grid.voxels() / (4 * rayon::current_num_threads()))
        .next_multiple_of(8)
        .min(TABLE_BYTES / (4 * points.max(1)) / 8 * 8)
        .clamp(64, BLOCK);
    backproject_with(c, grid, planes, block, CHUNK_BYTES)
}

/// [`backproject_planes`] in blocks of `block` voxels (a multiple of 8), holding at
/// most `chunk_bytes` of transposed series (at least one pair's).
fn backproject_with(
    c: &Capture,
    grid: &VoxelGrid,
    planes: &[&[f32]],
    block: usize,
    chunk_bytes: usize,
) -> Vec<Vec<f32>> {
    assert!(block.is_multiple_of(8) && block > 0);
    let np = planes.len();
    let nv = grid.voxels();
    let (ns, pairs) = (c.sensors, c.lasers * c.sensors);
    if pairs == 0 || nv == 0 {
        return vec![vec![0.0; nv]; np];
    }
    let bins = Bins::of(c);
    let len = (c.time.bins + 2) * np;
    // The voxels' centres, row-major (NX, NY, NZ), padded to whole blocks with copies
    // of the first one (their sums are dropped).
    let blocks = nv.div_ceil(block);
    let [nx, ny, nz] = grid.n;
    let axis = |a: usize, n: usize| (0..n).map(|i| grid.coordinate(a, i)).collect::<Vec<_>>();
    let (xs, ys, zs) = (axis(0, nx), axis(1, ny), axis(2, nz));
    let mut centres = [Vec::new(), Vec::new(), Vec::new()];
    for v in 0..blocks * block {
        let v = if v < nv { v } else { 0 };
        let (i, j, k) = (v / (ny * nz), v / nz % ny, v % nz);
        for (a, x) in [xs[i], ys[j], zs[k]].into_iter().enumerate() {
            centres[a].push(x);
        }
    }
    // Voxel v's sum of plane q at v np + q.
    let mut acc = vec![0f64; blocks * block * np];
    let chunk = (chunk_bytes / (len * 4)).clamp(1, pairs);
    let mut series = vec![0f32; chunk * len];
    for p0 in (0..pairs).step_by(chunk) {
        let p1 = (p0 + chunk).min(pairs);
        let series = &mut series[..(p1 - p0) * len];
        transpose(planes, pairs, c.time.bins, p0..p1, series);
        let series = &*series;
        // The laser-grid and sensor points these pairs use.
        let (l0, l1) = (p0 / ns, (p1 - 1) / ns + 1);
        let sensors = if l1 - l0 == 1 {
            p0 % ns..(p1 - 1) % ns + 1
        } else {
            0..ns
        };
        acc.par_chunks_mut(block * np).enumerate().for_each_init(
            || (Vec::new(), Vec::new()),
            |(d2, d3), (b, acc)| {
                let at = b * block..(b + 1) * block;
                let v = [
                    &centres[0][at.clone()],
                    &centres[1][at.clone()],
                    &centres[2][at],
                ];
                // Exhaustive: the distances of every laser point (d2, plus d1 when
                // single) and sensor point (d3) to the block's voxels, `block` per
                // point, each used by many pairs. Paired: each pair's own, in turn.
                d2.clear();
                d3.clear();
                if !c.paired {
                    for l in l0..l1 {
                        bins.laser_row(d2, c.laser_grid[l], l, v);
                    }
                    for s in sensors.clone() {
                        distances(d3, c.sensor_grid[s], v);
                    }
                }
                for p in p0..p1 {
                    let (l, s) = (p / ns, p % ns);
                    let (a, b) = if c.paired {
                        d2.clear();
                        d3.clear();
                        distances(d3, c.sensor_grid[s], v);
                        if c.laser_grid[s] == c.sensor_grid[s] {
                            // The same distances (a confocal scan's laser points
                            // are its sensor points), plus d1 when single.
                            d2.extend_from_slice(d3);
                            if bins.single {
                                let d1 = bins.d1[s];
                                d2.iter_mut().for_each(|x| *x += d1);
                            }
                        } else {
                            bins.laser_row(d2, c.laser_grid[s], s, v);
                        }
                        (&d2[..], &d3[..])
                    } else {
                        (
                            &d2[(l - l0) * block..][..block],
                            &d3[(s - sensors.start) * block..][..block],
                        )
                    };
                    if p + 1 < p1 {
                        prefetch(&series[(p + 1 - p0) * len..][..len]);
                    }
                    let h = &series[(p - p0) * len..][..len];
                    pair(&bins, acc, a, b, bins.d4[s], h, np);
                }
            },
        );
    }
    (0..np)
        .map(|q| (0..nv).map(|v| acc[v * np + q] as f32).collect())
        .collect()
}

/// Asks for `h` in L1 (the next pair's series while this pair's are gathered).
#[inline]
fn prefetch(h: &[f32]) {
    #[cfg(target_arch = "x86_64")]
    for k in (0..h.len()).step_by(16) {
        // SAFETY: a prefetch of an address inside `h` (SSE, part of x86_64) has no
        // effect but on the caches.
        unsafe {
            use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
            _mm_prefetch::<_MM_HINT_T0>(h.as_ptr().add(k) as *const i8);
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = h;
}

/// Appends the distances from point `p` to the voxels `v` (x, y, z columns): `dist(p,
/// v)`, which is also `dist(v, p)` to the bit (`a - b` is exactly `-(b - a)`, and the
/// squares agree).
fn distances(out: &mut Vec<f32>, p: [f32; 3], v: [&[f32]; 3]) {
    out.extend(v[0].iter().zip(v[1]).zip(v[2]).map(|((&x, &y), &z)| {
        let d = [x - p[0], y - p[1], z - p[2]];
        (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
    }));
}

/// Series `range` of `planes` ((T, pairs) each) into `out`: per pair `1 + T + 1`
/// entries per plane, the planes interleaved (entry b of plane q at `b np + q`), zero
/// at either end.
fn transpose(
    planes: &[&[f32]],
    pairs: usize,
    t: usize,
    range: std::ops::Range<usize>,
    out: &mut [f32],
) {
    let np = planes.len();
    let len = (t + 2) * np;
    // Pairs per task: a task reads rows of this many values, and writes as many
    // series at once.
    const PAIRS: usize = 64;
    out.par_chunks_mut(PAIRS * len)
        .enumerate()
        .for_each(|(k, out)| {
            let q0 = range.start + k * PAIRS;
            let n = out.len() / len;
            for (q, plane) in planes.iter().enumerate() {
                for e in 0..n {
                    out[e * len + q] = 0.0;
                    out[e * len + (t + 1) * np + q] = 0.0;
                }
                for b in 0..t {
                    let row = &plane[b * pairs + q0..][..n];
                    for (e, &x) in row.iter().enumerate() {
                        out[e * len + (b + 1) * np + q] = x;
                    }
                }
            }
        });
}

/// Adds pair `h`'s values at the voxels' bins to `acc` (voxel v's plane q at `v np +
/// q`, f64): `a` the laser side and `b` the sensor side of each voxel's path (as many
/// as `acc` has voxels), `d4` the sensor segment.
#[inline]
fn pair(bins: &Bins, acc: &mut [f64], a: &[f32], b: &[f32], d4: f32, h: &[f32], np: usize) {
    #[cfg(target_arch = "x86_64")]
    if let (Some(avx2), true) = (
        crate::cpu::detected().avx2(),
        np <= 2 && bins.bins < (i32::MAX - 2) as usize,
    ) {
        simd::pair(avx2, bins, acc, a, b, d4, h, np);
        return;
    }
    pair_scalar(bins, acc, a, b, d4, h, np);
}

/// [`pair`] one voxel at a time.
fn pair_scalar(bins: &Bins, acc: &mut [f64], a: &[f32], b: &[f32], d4: f32, h: &[f32], np: usize) {
    for (v, (&a, &b)) in a.iter().zip(b).enumerate() {
        let i = bins.slot(a, b, d4) * np;
        for q in 0..np {
            acc[v * np + q] += h[i + q] as f64;
        }
    }
}

#[cfg(target_arch = "x86_64")]
mod simd {
    use super::Bins;
    use crate::cpu::Avx2;
    use std::arch::x86_64::*;

    /// [`super::pair`], 8 voxels at a time; `np` is 1 or 2.
    #[allow(clippy::too_many_arguments)]
    pub fn pair(
        _avx2: Avx2,
        bins: &Bins,
        acc: &mut [f64],
        a: &[f32],
        b: &[f32],
        d4: f32,
        h: &[f32],
        np: usize,
    ) {
        let n = a.len();
        assert!(n.is_multiple_of(8) && b.len() == n && acc.len() == n * np && (np == 1 || np == 2));
        assert!(h.len() == (bins.bins + 2) * np && bins.bins < (i32::MAX - 2) as usize);
        // SAFETY: `_avx2` proves this CPU runs AVX2; the lengths are as asserted.
        unsafe { pair_avx2(bins, acc, a, b, d4, h, np) }
    }

    /// [`pair`]'s kernel.
    ///
    /// # Safety
    /// The CPU runs AVX2, and the slices' lengths are as [`pair`] asserts (the gathers
    /// read only indices clamped into `h`).
    #[target_feature(enable = "avx2")]
    unsafe fn pair_avx2(
        bins: &Bins,
        acc: &mut [f64],
        a: &[f32],
        b: &[f32],
        d4: f32,
        h: &[f32],
        np: usize,
    ) {
        // SAFETY: the caller runs AVX2 and passes slices of the asserted lengths; every load and
        // store stays within them (8 voxels from v < n, n a multiple of 8), and the gathers
        // read `h` only at clamped slots.
        unsafe {
            let n = a.len();
            let (a, b, h, acc) = (a.as_ptr(), b.as_ptr(), h.as_ptr(), acc.as_mut_ptr());
            // Slot = clamp(bin, -1, T) + 1: a bin past either end reads a padding zero
            // (a conversion out of i32's range gives i32::MIN, clamped to -1).
            let (lo, hi) = (_mm256_set1_epi32(-1), _mm256_set1_epi32(bins.bins as i32));
            let slot = |i: __m256i| {
                _mm256_add_epi32(
                    _mm256_min_epi32(_mm256_max_epi32(i, lo), hi),
                    _mm256_set1_epi32(1),
                )
            };
            if bins.single {
                let t0 = _mm256_set1_ps(bins.t_start as f32);
                let dt = _mm256_set1_ps(bins.delta_t as f32);
                let d4 = _mm256_set1_ps(d4);
                for v in (0..n).step_by(8) {
                    let ab = _mm256_add_ps(_mm256_loadu_ps(a.add(v)), _mm256_loadu_ps(b.add(v)));
                    let q = _mm256_div_ps(_mm256_sub_ps(_mm256_add_ps(ab, d4), t0), dt);
                    add(np, h, slot(_mm256_cvttps_epi32(q)), acc.add(v * np));
                }
            } else {
                let (t0, dt) = (_mm256_set1_pd(bins.t_start), _mm256_set1_pd(bins.delta_t));
                for v in (0..n).step_by(8) {
                    let bin = |v: usize| {
                        let x = _mm256_cvtps_pd(_mm_loadu_ps(a.add(v)));
                        let y = _mm256_cvtps_pd(_mm_loadu_ps(b.add(v)));
                        _mm256_cvttpd_epi32(_mm256_div_pd(
                            _mm256_sub_pd(_mm256_add_pd(x, y), t0),
                            dt,
                        ))
                    };
                    let i = _mm256_set_m128i(bin(v + 4), bin(v));
                    add(np, h, slot(i), acc.add(v * np));
                }
            }
        }
    }

    /// Gathers the entries at the 8 slots `i` of `h` and adds them to the 8 voxels'
    /// sums at `acc` (`np` planes interleaved).
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn add(np: usize, h: *const f32, i: __m256i, acc: *mut f64) {
        // SAFETY: the caller runs AVX2, `i` holds slots within `h`, and `acc` has the 8 voxels'
        // `np` sums each.
        unsafe {
            let upd = |p: *mut f64, x: __m128| {
                _mm256_storeu_pd(p, _mm256_add_pd(_mm256_loadu_pd(p), _mm256_cvtps_pd(x)))
            };
            if np == 1 {
                let x = _mm256_i32gather_ps::<4>(h, i);
                upd(acc, _mm256_castps256_ps128(x));
                upd(acc.add(4), _mm256_extractf128_ps::<1>(x));
            } else {
                // A slot's (re, im) as one 8-byte element: 4 voxels' (re, im) per gather,
                // in the accumulators' order.
                for (k, i) in [_mm256_castsi256_si128(i), _mm256_extracti128_si256::<1>(i)]
                    .into_iter()
                    .enumerate()
                {
                    let x = _mm256_castpd_ps(_mm256_i32gather_pd::<8>(h as *const f64, i));
                    upd(acc.add(8 * k), _mm256_castps256_ps128(x));
                    upd(acc.add(8 * k + 4), _mm256_extractf128_ps::<1>(x));
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::rng::Pcg32;
    use crate::sensors::time_axis::TimeAxis;

    /// The backprojection as plainly as it can be written: per voxel, per laser and
    /// sensor point, the bin in y-tal's precision, the sum in f64.
    fn reference(c: &Capture, grid: &VoxelGrid, planes: &[&[f32]]) -> Vec<Vec<f32>> {
        let [nx, ny, nz] = grid.n;
        let accounts = c.accounts_first_and_last_bounces;
        let mut out = vec![vec![0f32; nx * ny * nz]; planes.len()];
        for i in 0..nx {
            for j in 0..ny {
                for k in 0..nz {
                    let v = [
                        grid.coordinate(0, i),
                        grid.coordinate(1, j),
                        grid.coordinate(2, k),
                    ];
                    let mut acc = vec![0f64; planes.len()];
                    for l in 0..c.lasers {
                        for s in 0..c.sensors {
                            let li = if c.paired { s } else { l };
                            let (lp, sp) = (c.laser_grid[li], c.sensor_grid[s]);
                            let bin = if accounts {
                                let d1 = dist(c.laser_xyz.unwrap(), lp);
                                let d4 = dist(sp, c.sensor_xyz.unwrap());
                                let d = d1 + dist(lp, v) + dist(v, sp) + d4;
                                ((d - c.time.start_opl as f32) / c.time.bin_width_opl as f32) as i64
                            } else {
                                let d = dist(lp, v) as f64 + dist(v, sp) as f64;
                                ((d - c.time.start_opl) / c.time.bin_width_opl) as i64
                            };
                            if bin >= 0 && (bin as usize) < c.time.bins {
                                let at = (bin as usize * c.lasers + l) * c.sensors + s;
                                for (a, p) in acc.iter_mut().zip(planes) {
                                    *a += p[at] as f64;
                                }
                            }
                        }
                    }
                    for (o, a) in out.iter_mut().zip(&acc) {
                        o[(i * ny + j) * nz + k] = *a as f32;
                    }
                }
            }
        }
        out
    }

    /// A random capture: `lasers` laser points (paired: one per sensor point, on it or
    /// near it), 4 x 5 sensor points on a wall at z = 0, random values, a time
    /// axis that leaves some paths before its start and some after its end.
    fn random_capture(rng: &mut Pcg32, lasers: usize, paired: bool, accounts: bool) -> Capture {
        let mut point = |z: f32| [rng.next_f32() * 2.0 - 1.0, rng.next_f32() * 2.0 - 1.0, z];
        let sensor_grid: Vec<[f32; 3]> = (0..20).map(|_| point(0.0)).collect();
        let laser_grid: Vec<[f32; 3]> = if paired {
            sensor_grid
                .iter()
                .enumerate()
                .map(|(s, p)| match s % 2 {
                    0 => *p,
                    _ => [p[0] + 0.01, p[1] - 0.02, 0.0],
                })
                .collect()
        } else {
            (0..lasers).map(|_| point(0.0)).collect()
        };
        let (laser_xyz, sensor_xyz) = (point(1.5), point(1.2));
        let nl = if paired { 1 } else { lasers };
        let bins = 97;
        let h = (0..bins * nl * 20).map(|_| rng.next_f32() - 0.25).collect();
        // Paths of length ~1 to ~4.5 (plus ~3.5 for the first and last bounces).
        let (t_start, delta_t) = if accounts {
            (5.0, 0.031)
        } else {
            (1.5, 0.0213)
        };
        Capture {
            time: TimeAxis {
                start_opl: t_start,
                bin_width_opl: delta_t,
                bins,
            },
            lasers: nl,
            sensors: 20,
            sensor_dims: [4, 5],
            laser_dims: [nl, 1],
            normal: [0.0, 0.0, 1.0],
            h,
            laser_grid,
            sensor_grid,
            paired,
            laser_xyz: Some(laser_xyz),
            sensor_xyz: Some(sensor_xyz),
            accounts_first_and_last_bounces: accounts,
        }
    }

    fn bits(v: &[Vec<f32>]) -> Vec<Vec<u32>> {
        v.iter()
            .map(|p| p.iter().map(|x| x.to_bits()).collect())
            .collect()
    }

    /// The blocked, transposed, vectorised backprojection is the plain loop's, to the
    /// bit: confocal and exhaustive, bins in double and in single precision, one and
    /// two planes, volumes of less than one block and of several (with a partial last
    /// one), the series whole or in chunks (down to one pair), at 1 and 3 threads.
    #[test]
    fn backprojection_is_the_plain_loop_to_the_bit() {
        let mut rng = Pcg32::new(3, 5);
        let grids = [
            VoxelGrid {
                first: [-0.8, -0.7, 0.3],
                last: [0.9, 0.6, 1.4],
                n: [5, 4, 6],
            },
            VoxelGrid {
                first: [-1.0, -1.0, 0.2],
                last: [1.0, 1.0, 1.6],
                n: [9, 11, 13],
            },
        ];
        let pool = |n| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .unwrap()
        };
        let (one, three) = (pool(1), pool(3));
        for (lasers, paired) in [(1, true), (6, false)] {
            for accounts in [false, true] {
                let c = random_capture(&mut rng, lasers, paired, accounts);
                let im: Vec<f32> = c.h.iter().map(|x| 1.0 - 2.0 * x).collect();
                for grid in &grids {
                    // The public entry points (blocks as many threads need).
                    let want = bits(&reference(&c, grid, &[&c.h]));
                    assert!(bits(&[backproject(&c, grid)]) == want);
                    let f = crate::nlos::filter::pf_filter(&c, 0.1, 0.07);
                    let [fre, fim] =
                        <[Vec<f32>; 2]>::try_from(reference(&c, grid, &[&f.re, &f.im])).unwrap();
                    let want: Vec<f32> = fre.iter().zip(&fim).map(|(&a, &b)| a.hypot(b)).collect();
                    assert!(bits(&[filtered_backproject(&c, grid, 0.1, 0.07)]) == bits(&[want]));
                    for planes in [vec![&c.h[..]], vec![&c.h[..], &im[..]]] {
                        let want = bits(&reference(&c, grid, &planes));
                        assert!(want[0].iter().any(|&x| f32::from_bits(x) != 0.0));
                        let pair_bytes = (c.time.bins + 2) * planes.len() * 4;
                        for (chunk, block) in [
                            (CHUNK_BYTES, BLOCK),
                            (pair_bytes, 64),
                            (7 * pair_bytes, 208),
                        ] {
                            for pool in [&one, &three] {
                                let got = pool
                                    .install(|| backproject_with(&c, grid, &planes, block, chunk));
                                assert!(
                                    bits(&got) == want,
                                    "paired {paired}, accounts {accounts}, grid {:?}, {} planes, chunk {chunk}, block {block}",
                                    grid.n,
                                    planes.len()
                                );
                            }
                        }
                    }
                }
            }
        }
    }

    /// The vectorised pair is the scalar one, to the bit, for bins before, at and past
    /// both ends of the capture (and far beyond i32's range), in both precisions.
    #[test]
    fn vectorised_pair_is_the_scalar_pair() {
        let mut rng = Pcg32::new(9, 2);
        let n = 64;
        for single in [false, true] {
            let bins = Bins {
                single,
                t_start: 1.0,
                delta_t: 0.01,
                bins: 50,
                d1: Vec::new(),
                d4: Vec::new(),
            };
            // Path lengths from 0.9 to 1.6 (bins -10 to 60), some exactly at a bin's
            // start, a few enormous.
            let mut a: Vec<f32> = (0..n).map(|_| 0.4 + 0.35 * rng.next_f32()).collect();
            let mut b: Vec<f32> = (0..n).map(|_| 0.5 + 0.35 * rng.next_f32()).collect();
            for (k, v) in [
                (3, 0.5),
                (4, 0.49),
                (5, 0.995),
                (6, 1.0),
                (7, 1.499),
                (8, 1.5),
            ] {
                a[k] = 0.5;
                b[k] = v;
            }
            a[9] = 1e30;
            a[10] = -1e30;
            a[11] = 3e7;
            for np in [1, 2] {
                let h: Vec<f32> = (0..(bins.bins + 2) * np)
                    .map(|i| {
                        if i < np || i >= (bins.bins + 1) * np {
                            0.0
                        } else {
                            rng.next_f32()
                        }
                    })
                    .collect();
                let start: Vec<f64> = (0..n * np).map(|_| rng.next_f32() as f64).collect();
                let (mut fast, mut slow) = (start.clone(), start);
                for d4 in [0.0, 0.25] {
                    pair(&bins, &mut fast, &a, &b, d4, &h, np);
                    pair_scalar(&bins, &mut slow, &a, &b, d4, &h, np);
                }
                let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&fast), bits(&slow), "single {single}, np {np}");
            }
        }
    }
}
