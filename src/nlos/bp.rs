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
//! Cost: voxels x laser points x sensor points, parallel over voxels (rayon); memory:
//! the output, NX NY NZ f32 (twice, and the complex filtered capture, for the filtered
//! backprojection).

use super::capture::Capture;
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
    let f = super::filter::pf_filter(c, wl_mean, wl_sigma);
    let [re, im] = <[Vec<f32>; 2]>::try_from(backproject_planes(c, grid, &[&f.re, &f.im]))
        .expect("two planes");
    re.iter().zip(&im).map(|(&a, &b)| a.hypot(b)).collect()
}

/// Backprojects each of `planes` (values laid out as `Capture::h`) at the same bins.
fn backproject_planes(c: &Capture, grid: &VoxelGrid, planes: &[&[f32]]) -> Vec<Vec<f32>> {
    let [nx, ny, nz] = grid.n;
    let axis = |a: usize, n: usize| (0..n).map(|i| grid.coordinate(a, i)).collect::<Vec<_>>();
    let (xs, ys, zs) = (axis(0, nx), axis(1, ny), axis(2, nz));
    let accounts = c.accounts_first_and_last_bounces;
    // The voxel-independent segments: laser to laser point, sensor point to sensor.
    let d1: Vec<f32> = (0..c.laser_grid.len())
        .map(|i| match (accounts, c.laser_xyz) {
            (true, Some(x)) => dist(x, c.laser_grid[i]),
            _ => 0.0,
        })
        .collect();
    let d4: Vec<f32> = (0..c.sensors)
        .map(|s| match (accounts, c.sensor_xyz) {
            (true, Some(x)) => dist(c.sensor_grid[s], x),
            _ => 0.0,
        })
        .collect();
    let np = planes.len();
    let mut out = vec![0f32; nx * ny * nz * np];
    out.par_chunks_mut(nz * np).enumerate().for_each_init(
        || (Vec::new(), Vec::new(), Vec::new()),
        |(d2, d3, acc), (ij, col)| {
            let (i, j) = (ij / ny, ij % ny);
            for (k, o) in col.chunks_mut(np).enumerate() {
                let v = [xs[i], ys[j], zs[k]];
                // The voxel's distances to every laser point and sensor point, once.
                d2.clear();
                d2.extend(c.laser_grid.iter().map(|&lp| dist(lp, v)));
                d3.clear();
                d3.extend(c.sensor_grid.iter().map(|&sp| dist(v, sp)));
                acc.clear();
                acc.resize(np, 0f64);
                for l in 0..c.lasers {
                    for s in 0..c.sensors {
                        let li = if c.paired { s } else { l };
                        let bin = if accounts {
                            let d = d1[li] + d2[li] + d3[s] + d4[s];
                            ((d - c.t_start as f32) / c.delta_t as f32) as i64
                        } else {
                            let d = d2[li] as f64 + d3[s] as f64;
                            ((d - c.t_start) / c.delta_t) as i64
                        };
                        if bin >= 0 && (bin as usize) < c.bins {
                            let at = (bin as usize * c.lasers + l) * c.sensors + s;
                            for (a, p) in acc.iter_mut().zip(planes) {
                                *a += p[at] as f64;
                            }
                        }
                    }
                }
                for (o, a) in o.iter_mut().zip(acc.iter()) {
                    *o = *a as f32;
                }
            }
        },
    );
    (0..np)
        .map(|q| out.iter().skip(q).step_by(np).copied().collect())
        .collect()
}
