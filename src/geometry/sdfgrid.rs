//! Mitsuba 3's `sdfgrid` shape (`src/shapes/sdfgrid.cpp`): the zero set of a signed
//! distance function sampled on a grid of `nx x ny x nz` values (x fastest), the
//! values at the corners of `(nx - 1)(ny - 1)(nz - 1)` voxels that tile object space
//! `[0, 1]^3`, mapped to the world by an affine `to_world`.
//!
//! Grid coordinates `q = (nx - 1, ny - 1, nz - 1) * p_object` put value `(i, j, k)` at
//! the integer point `(i, j, k)`. Inside a voxel the SDF `F` is the trilinear
//! interpolation of its 8 corner values; outside `[0, n - 1]` the coordinates clamp
//! (Dr.Jit's texture with `WrapMode::Clamp`, which Mitsuba evaluates for normals).
//!
//! - **Primitives**: one per voxel whose corners are neither all > 0 nor all < 0
//!   (Mitsuba's "occupied" test), in Mitsuba's order (x fastest); each with the tight
//!   box of Hansson-Söderlund and Akenine-Möller (2023): the box of the voxel's zero
//!   corners and of the points where the SDF crosses zero along its 12 edges (the
//!   surface inside a voxel cannot reach beyond them), padded by 1e-3 of a voxel
//!   against rounding. A grid without one is an error, as in Mitsuba.
//! - **Intersection** (Hansson-Söderlund et al. 2022, as Mitsuba): the ray in the
//!   voxel's local `[0, 1]^3` (the world t kept), clipped to the voxel; along it F is
//!   the cubic `g(s) = c3 s^3 + c2 s^2 + c1 s + c0` from the entry point. The roots of
//!   g' split the segment into pieces on which g is monotone; the first piece whose
//!   ends differ in sign (or an end where g = 0) holds the first root, found by
//!   Illinois regula falsi in f64 to 1e-14 of the segment (Mitsuba: the same split,
//!   plain regula falsi in f32 to 1e-5). So a hit is the exact first zero of the
//!   trilinear SDF along the ray, not a sphere-traced approximation. The segment is
//!   widened by 1e-7 of a voxel on each side so that rounding cannot open a gap at a
//!   face shared by two voxels (each voxel's cubic extends its own trilinear, which
//!   agrees with its neighbour's on the face).
//! - **Normals**: the geometric normal is the gradient of the hit voxel's trilinear at
//!   the hit (Mitsuba's `voxel_grad`: differences across the voxel along each axis
//!   through the point), mapped by `to_world`'s normal transform. Shading normal:
//!   `analytic` = the geometric one; `smooth` (the default) = Hansson-Söderlund et al.'s:
//!   the unit gradients of the 8 voxels around the nearest grid point, each at the hit
//!   point, blended trilinearly by the hit's position between their centres (voxels
//!   with a negative index left out, the weight moved to the other side as Mitsuba
//!   does), then mapped by the normal transform. A zero gradient contributes 0 (Dr.Jit
//!   would make it NaN).
//! - **No uv** (0, 0), dp/du = dp/dv = 0 (Mitsuba leaves them zero: the shading frame
//!   is `Frame::from_normal`), **no area**: Mitsuba's `surface_area` is 0 and its
//!   position sampling returns zeros, so tstat refuses an emitter on an sdfgrid.
//! - **to_world**: any invertible affine map (Mitsuba warns on rotations because its
//!   per-voxel world boxes map only two corners; here all 8 corners are mapped, so
//!   rotated grids, as instances make them, are exact).
//!
//! Non-cubic grids: Mitsuba 3.9.1 indexes the voxel size and texel scale of axis x
//! by the tensor's first dimension (z), so its non-cubic grids mix axes; tstat spaces
//! axis x by `nx` (the documented `[0, 1]^3` mapping). Cubic grids agree.

use super::error::GeometryError;
use glam::{DMat3, DMat4, DVec3, Vec3};
use std::sync::Arc;

/// Padding of a voxel's tight box, in voxels.
const BOX_PAD: f64 = 1e-3;
/// Widening of a voxel's ray segment, in voxels.
const SLAB_PAD: f64 = 1e-7;
/// Iteration cap of the root refinement (Illinois converges in about ten).
const MAX_ITER: usize = 64;

/// The grid values and their non-empty voxels (shared by the instances of one grid).
#[derive(Debug)]
pub struct SdfGrid {
    /// Values per axis (each >= 2).
    pub res: [usize; 3],
    /// `res[0] * res[1] * res[2]` finite values, x fastest then y then z.
    pub values: Vec<f32>,
    /// The non-empty voxels, `x + y (nx - 1) + z (nx - 1)(ny - 1)`, increasing.
    pub voxels: Vec<u32>,
    /// Their tight boxes in grid coordinates (padded): `[lo, hi]`.
    boxes: Vec<[DVec3; 2]>,
}

impl SdfGrid {
    /// The grid of `values` (x fastest), or why it cannot be one.
    pub fn new(res: [usize; 3], values: Vec<f32>) -> Result<Self, GeometryError> {
        if res.iter().any(|&n| n < 2) {
            return Err(GeometryError::SdfGridTooSmall { res });
        }
        let count = res[0]
            .checked_mul(res[1])
            .and_then(|c| c.checked_mul(res[2]));
        if count != Some(values.len()) {
            return Err(GeometryError::SdfGridValueCount {
                values: values.len(),
                res,
            });
        }
        let cells = (res[0] - 1) as u128 * (res[1] - 1) as u128 * (res[2] - 1) as u128;
        if cells > u32::MAX as u128 {
            return Err(GeometryError::SdfGridTooManyVoxels { voxels: cells });
        }
        if let Some(i) = values.iter().position(|v| !v.is_finite()) {
            let (x, y) = (i % res[0], (i / res[0]) % res[1]);
            let z = i / (res[0] * res[1]);
            return Err(GeometryError::SdfGridNonFinite {
                index: i,
                at: [x, y, z],
                value: values[i],
            });
        }
        let mut grid = SdfGrid {
            res,
            values,
            voxels: Vec::new(),
            boxes: Vec::new(),
        };
        let (cx, cy, cz) = (res[0] - 1, res[1] - 1, res[2] - 1);
        for z in 0..cz {
            for y in 0..cy {
                for x in 0..cx {
                    if let Some(b) = grid.tight_box([x, y, z]) {
                        grid.voxels.push((x + y * cx + z * cx * cy) as u32);
                        grid.boxes.push(b);
                    }
                }
            }
        }
        if grid.voxels.is_empty() {
            return Err(GeometryError::SdfGridEmpty);
        }
        Ok(grid)
    }

    #[inline]
    fn value(&self, x: usize, y: usize, z: usize) -> f64 {
        self.values[x + self.res[0] * (y + self.res[1] * z)] as f64
    }

    /// The 8 corner values of voxel `v`, corner `i` at offset `(i & 1, i >> 1 & 1, i >> 2)`.
    #[inline]
    fn corners(&self, v: [usize; 3]) -> [f64; 8] {
        std::array::from_fn(|i| self.value(v[0] + (i & 1), v[1] + (i >> 1 & 1), v[2] + (i >> 2)))
    }

    /// The voxel position of a voxel index.
    #[inline]
    fn voxel_pos(&self, index: u32) -> [usize; 3] {
        let (cx, cy) = (self.res[0] - 1, self.res[1] - 1);
        let i = index as usize;
        [i % cx, (i / cx) % cy, i / (cx * cy)]
    }

    /// Mitsuba's `compute_tight_bbox` in grid coordinates, padded; `None` when the
    /// voxel is empty (all corners > 0 or all < 0).
    fn tight_box(&self, v: [usize; 3]) -> Option<[DVec3; 2]> {
        let f = self.corners(v);
        if f.iter().all(|&x| x > 0.0) || f.iter().all(|&x| x < 0.0) {
            return None;
        }
        let corner = |i: usize| DVec3::new((i & 1) as f64, (i >> 1 & 1) as f64, (i >> 2) as f64);
        let (mut lo, mut hi) = (DVec3::ONE, DVec3::ZERO);
        for (i, &fi) in f.iter().enumerate() {
            if fi == 0.0 {
                lo = lo.min(corner(i));
                hi = hi.max(corner(i));
            }
        }
        for c1 in 0..8 {
            for axis in 0..3 {
                if c1 & (1 << axis) != 0 {
                    continue;
                }
                let c2 = c1 | (1 << axis);
                if f[c1] * f[c2] <= 0.0 && f[c1] != f[c2] {
                    let p = corner(c1) + (corner(c2) - corner(c1)) * (f[c1] / (f[c1] - f[c2]));
                    lo = lo.min(p);
                    hi = hi.max(p);
                }
            }
        }
        let base = DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64);
        Some([base + lo - BOX_PAD, base + hi + BOX_PAD])
    }

    /// F at grid coordinates `q`: trilinear, coordinates clamped to the grid.
    fn eval(&self, q: DVec3) -> f64 {
        let mut i0 = [0usize; 3];
        let mut w = [0f64; 3];
        for a in 0..3 {
            let top = (self.res[a] - 1) as f64;
            let c = q[a].clamp(0.0, top);
            let i = (c.floor() as usize).min(self.res[a] - 2);
            i0[a] = i;
            w[a] = c - i as f64;
        }
        let f = self.corners(i0);
        let lerp = |a: f64, b: f64, t: f64| a * (1.0 - t) + b * t;
        let x00 = lerp(f[0], f[1], w[0]);
        let x10 = lerp(f[2], f[3], w[0]);
        let x01 = lerp(f[4], f[5], w[0]);
        let x11 = lerp(f[6], f[7], w[0]);
        lerp(lerp(x00, x10, w[1]), lerp(x01, x11, w[1]), w[2])
    }

    /// Mitsuba's `voxel_grad` in grid units: F's differences across voxel `v` along
    /// each axis, through `q` (times `n - 1` for object units).
    fn voxel_grad(&self, q: DVec3, v: [i64; 3]) -> DVec3 {
        let mut g = DVec3::ZERO;
        for a in 0..3 {
            let (mut q0, mut q1) = (q, q);
            q0[a] = v[a] as f64;
            q1[a] = v[a] as f64 + 1.0;
            g[a] = self.eval(q1) - self.eval(q0);
        }
        g
    }
}

/// An `sdfgrid` in the world.
#[derive(Clone, Debug)]
pub struct SdfGeom {
    pub grid: Arc<SdfGrid>,
    /// Object to world (affine).
    pub to_world: DMat4,
    /// World to grid coordinates: `diag(n - 1) * to_world^-1`.
    to_grid: DMat4,
    /// Object to grid scale `n - 1` per axis.
    scale: DVec3,
    /// `to_world`'s normal transform (inverse transpose of its linear part).
    normal_m: DMat3,
    /// Shading normals: Hansson-Söderlund et al.'s smooth ones, else the analytic ones.
    pub smooth: bool,
}

impl SdfGeom {
    /// The grid placed by `to_world`, or why it cannot be (a singular map).
    pub fn new(grid: Arc<SdfGrid>, to_world: DMat4, smooth: bool) -> Result<Self, GeometryError> {
        let lin = DMat3::from_mat4(to_world);
        let det = lin.determinant();
        if !(det != 0.0 && det.is_finite() && to_world.is_finite()) {
            return Err(GeometryError::SdfMap { determinant: det });
        }
        let scale = DVec3::new(
            (grid.res[0] - 1) as f64,
            (grid.res[1] - 1) as f64,
            (grid.res[2] - 1) as f64,
        );
        let to_grid = DMat4::from_scale(scale) * to_world.inverse();
        if !to_grid.is_finite() {
            return Err(GeometryError::SdfMapInverse);
        }
        Ok(SdfGeom {
            grid,
            to_world,
            to_grid,
            scale,
            normal_m: lin.inverse().transpose(),
            smooth,
        })
    }

    /// The same grid mapped further by `m` (an instance's `to_world`).
    pub fn transformed(&self, m: &DMat4) -> Result<Self, GeometryError> {
        SdfGeom::new(self.grid.clone(), *m * self.to_world, self.smooth)
    }

    /// Mitsuba's box of the shape: the 8 corners of the unit cube mapped to the world.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        self.box_of(DVec3::ZERO, DVec3::ONE)
    }

    /// The world box of the object-space box `[lo, hi]` (all 8 corners mapped).
    fn box_of(&self, lo: DVec3, hi: DVec3) -> (Vec3, Vec3) {
        let (mut a, mut b) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        for i in 0..8 {
            let c = DVec3::new(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            );
            let w = self.to_world.transform_point3(c);
            a = a.min(w);
            b = b.max(w);
        }
        (a.as_vec3(), b.as_vec3())
    }

    /// The number of primitives (non-empty voxels).
    pub fn voxel_count(&self) -> usize {
        self.grid.voxels.len()
    }

    /// The world box of primitive `k` (the `k`-th non-empty voxel's tight box).
    pub fn voxel_bounds(&self, k: u32) -> (Vec3, Vec3) {
        let [lo, hi] = self.grid.boxes[k as usize];
        self.box_of(lo / self.scale, hi / self.scale)
    }

    /// Nearest distance t > tmin at which the ray (unit direction `d`) meets the
    /// trilinear SDF of primitive `k`'s voxel inside that voxel.
    #[inline(never)]
    pub fn intersect_voxel(&self, k: u32, o: Vec3, d: Vec3, tmin: f32) -> Option<f32> {
        let grid = &*self.grid;
        let v = grid.voxel_pos(grid.voxels[k as usize]);
        let base = DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64);
        let og = self.to_grid.transform_point3(o.as_dvec3()) - base;
        let dg = self.to_grid.transform_vector3(d.as_dvec3());
        let (mut t0, mut t1) = (tmin as f64, f64::INFINITY);
        for a in 0..3 {
            let (lo, hi) = (-SLAB_PAD, 1.0 + SLAB_PAD);
            if dg[a] == 0.0 {
                if !(og[a] >= lo && og[a] <= hi) {
                    return None;
                }
            } else {
                let inv = 1.0 / dg[a];
                let (ta, tb) = ((lo - og[a]) * inv, (hi - og[a]) * inv);
                t0 = t0.max(ta.min(tb));
                t1 = t1.min(ta.max(tb));
            }
        }
        if t0 > t1 {
            return None;
        }
        let c = cubic_along(&grid.corners(v), og + dg * t0, dg);
        let s = first_root(&c, t1 - t0, tmin as f64 - t0)?;
        let t = (t0 + s) as f32;
        (t > tmin && t < f32::INFINITY).then_some(t)
    }

    /// The geometric and shading normals (world, unit) at `p` on primitive `k`.
    pub fn normals(&self, k: u32, p: Vec3) -> (Vec3, Vec3) {
        let grid = &*self.grid;
        let v = grid.voxel_pos(grid.voxels[k as usize]);
        let q = self.to_grid.transform_point3(p.as_dvec3());
        let g = grid.voxel_grad(q, [v[0] as i64, v[1] as i64, v[2] as i64]) * self.scale;
        let ng = (self.normal_m * g).normalize_or_zero();
        // A flat voxel (zero gradient) has no normal: any unit vector keeps the
        // frame well defined (the hit itself is then a measure-zero event).
        let ng = if ng == DVec3::ZERO { DVec3::Z } else { ng };
        if !self.smooth {
            return (ng.as_vec3(), ng.as_vec3());
        }
        let ns = (self.normal_m * self.smooth_object_normal(q)).normalize_or_zero();
        let ns = if ns == DVec3::ZERO { ng } else { ns };
        (ng.as_vec3(), ns.as_vec3())
    }

    /// Mitsuba's `smooth_sh` (object space, not normalised) at grid coordinates `q`.
    fn smooth_object_normal(&self, q: DVec3) -> DVec3 {
        let grid = &*self.grid;
        let r = DVec3::new(
            q.x.round_ties_even(),
            q.y.round_ties_even(),
            q.z.round_ties_even(),
        );
        let v000 = [r.x as i64 - 1, r.y as i64 - 1, r.z as i64 - 1];
        let mut n = [DVec3::ZERO; 8];
        let mut valid = [false; 8];
        for (i, (ni, ok)) in n.iter_mut().zip(valid.iter_mut()).enumerate() {
            let v = [
                v000[0] + (i & 1) as i64,
                v000[1] + (i >> 1 & 1) as i64,
                v000[2] + (i >> 2) as i64,
            ];
            *ok = v.iter().all(|&c| c >= 0);
            if *ok {
                *ni = (grid.voxel_grad(q, v) * self.scale).normalize_or_zero();
            }
        }
        // The position between the voxel centres: v111 = v000 + 1 is the rounded point.
        let mut w = q - r + DVec3::splat(0.5);
        for a in 0..3 {
            let side = |bit: usize| (0..8).filter(|i| (i >> a & 1) == bit).all(|i| !valid[i]);
            if side(0) {
                w[a] = 1.0;
            }
            if side(1) {
                w[a] = 0.0;
            }
        }
        let (u, v, t) = (w.x, w.y, w.z);
        (1.0 - t) * ((1.0 - v) * ((1.0 - u) * n[0] + u * n[1]) + v * ((1.0 - u) * n[2] + u * n[3]))
            + t * ((1.0 - v) * ((1.0 - u) * n[4] + u * n[5]) + v * ((1.0 - u) * n[6] + u * n[7]))
    }
}

/// The cubic `[c0, c1, c2, c3]` of the trilinear interpolant of corner values `f`
/// (unit cube, corner `i` at `(i & 1, i >> 1 & 1, i >> 2)`) along `p + s d`.
fn cubic_along(f: &[f64; 8], p: DVec3, d: DVec3) -> [f64; 4] {
    // F = a0 + a1 x + a2 y + a3 z + a4 xy + a5 yz + a6 xz + a7 xyz.
    let a0 = f[0];
    let a1 = f[1] - f[0];
    let a2 = f[2] - f[0];
    let a3 = f[4] - f[0];
    let a4 = f[3] - f[1] - f[2] + f[0];
    let a5 = f[6] - f[2] - f[4] + f[0];
    let a6 = f[5] - f[1] - f[4] + f[0];
    let a7 = f[7] - f[3] - f[5] - f[6] + f[1] + f[2] + f[4] - f[0];
    // Products of the linear polynomials x(s) = p.x + d.x s, ...
    let mul = |(a0, a1): (f64, f64), (b0, b1): (f64, f64)| [a0 * b0, a0 * b1 + a1 * b0, a1 * b1];
    let (x, y, z) = ((p.x, d.x), (p.y, d.y), (p.z, d.z));
    let xy = mul(x, y);
    let yz = mul(y, z);
    let xz = mul(x, z);
    let xyz = [
        xy[0] * z.0,
        xy[0] * z.1 + xy[1] * z.0,
        xy[1] * z.1 + xy[2] * z.0,
        xy[2] * z.1,
    ];
    [
        a0 + a1 * x.0 + a2 * y.0 + a3 * z.0 + a4 * xy[0] + a5 * yz[0] + a6 * xz[0] + a7 * xyz[0],
        a1 * x.1 + a2 * y.1 + a3 * z.1 + a4 * xy[1] + a5 * yz[1] + a6 * xz[1] + a7 * xyz[1],
        a4 * xy[2] + a5 * yz[2] + a6 * xz[2] + a7 * xyz[2],
        a7 * xyz[3],
    ]
}

#[inline]
fn eval_cubic(c: &[f64; 4], s: f64) -> f64 {
    ((c[3] * s + c[2]) * s + c[1]) * s + c[0]
}

/// The smallest root of cubic `c` in `[0, len]` beyond `after` (roots at or before it
/// are the ray's own start), or `None`.
fn first_root(c: &[f64; 4], len: f64, after: f64) -> Option<f64> {
    // Critical points: roots of g' = 3 c3 s^2 + 2 c2 s + c1 inside (0, len).
    let (qa, qb, qc) = (3.0 * c[3], 2.0 * c[2], c[1]);
    let mut cuts = [len; 3];
    let mut n = 0;
    let mut push = |r: f64| {
        if r > 0.0 && r < len {
            cuts[n] = r;
            n += 1;
        }
    };
    if qa != 0.0 {
        let disc = qb * qb - 4.0 * qa * qc;
        if disc >= 0.0 {
            let q = -0.5 * (qb + disc.sqrt().copysign(qb));
            push(q / qa);
            if q != 0.0 {
                push(qc / q);
            }
        }
    } else if qb != 0.0 {
        push(-qc / qb);
    }
    if n == 2 && cuts[0] > cuts[1] {
        cuts.swap(0, 1);
    }
    let (mut a, mut fa) = (0.0, eval_cubic(c, 0.0));
    for &b in cuts.iter().take(n + 1) {
        if fa == 0.0 && a > after {
            return Some(a);
        }
        let fb = eval_cubic(c, b);
        if fa * fb < 0.0 {
            let s = refine(c, a, b, fa, fb);
            if s > after {
                return Some(s);
            }
        }
        (a, fa) = (b, fb);
    }
    (fa == 0.0 && a > after).then_some(a)
}

/// The root of monotone `c` in `[a, b]`, where `fa` and `fb` differ in sign: Illinois
/// regula falsi, to 1e-14 of the bracket.
fn refine(c: &[f64; 4], mut a: f64, mut b: f64, mut fa: f64, mut fb: f64) -> f64 {
    let tol = 1e-14 * (b - a).abs().max(b.abs());
    // Keep `b` the newest estimate and `a` the other end of the bracket.
    for _ in 0..MAX_ITER {
        let s = b - fb * (b - a) / (fb - fa);
        let s = if s.is_finite() && (s - a) * (s - b) <= 0.0 {
            s
        } else {
            0.5 * (a + b)
        };
        let fs = eval_cubic(c, s);
        if fs == 0.0 {
            return s;
        }
        if fs * fb < 0.0 {
            (a, fa) = (b, fb);
        } else {
            fa *= 0.5;
        }
        (b, fb) = (s, fs);
        if (b - a).abs() <= tol {
            break;
        }
    }
    b
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A grid sampling `f` at `n^3` points of [0, 1]^3.
    fn grid_of(n: usize, f: impl Fn(DVec3) -> f64) -> SdfGrid {
        let mut v = Vec::new();
        for z in 0..n {
            for y in 0..n {
                for x in 0..n {
                    let p = DVec3::new(x as f64, y as f64, z as f64) / (n - 1) as f64;
                    v.push(f(p) as f32);
                }
            }
        }
        SdfGrid::new([n; 3], v).unwrap()
    }

    #[test]
    fn cubic_is_the_trilinear_along_the_ray() {
        let f = [0.3, -0.7, 1.1, 0.2, -0.4, 0.9, -1.3, 0.5];
        let tri = |q: DVec3| {
            let l = |a: f64, b: f64, t: f64| a * (1.0 - t) + b * t;
            l(
                l(l(f[0], f[1], q.x), l(f[2], f[3], q.x), q.y),
                l(l(f[4], f[5], q.x), l(f[6], f[7], q.x), q.y),
                q.z,
            )
        };
        let (p, d) = (DVec3::new(0.1, 0.8, 0.3), DVec3::new(0.4, -0.5, 0.7));
        let c = cubic_along(&f, p, d);
        for s in [0.0, 0.3, 0.7, 1.1] {
            assert!((eval_cubic(&c, s) - tri(p + d * s)).abs() < 1e-14);
        }
    }

    #[test]
    fn first_root_takes_the_first_of_three() {
        // (s - 0.2)(s - 0.5)(s - 0.9): roots at 0.2, 0.5, 0.9.
        let c = [-0.09, 0.73, -1.6, 1.0];
        assert!((first_root(&c, 1.0, -1.0).unwrap() - 0.2).abs() < 1e-14);
        assert!((first_root(&c, 1.0, 0.3).unwrap() - 0.5).abs() < 1e-14);
        assert!(first_root(&c, 0.15, -1.0).is_none());
        // A dip below zero between two positive ends (no sign change at the ends).
        let dip = [0.01, -0.2, 1.0, 0.0]; // s^2 - 0.2 s + 0.01 - 0.0001 below
        let dip = [dip[0] - 0.0001, dip[1], dip[2], dip[3]];
        let r = first_root(&dip, 1.0, -1.0).unwrap();
        assert!((r - 0.09).abs() < 1e-12, "{r}");
    }

    #[test]
    fn empty_and_degenerate_grids_are_refused() {
        assert!(matches!(
            SdfGrid::new([2, 2, 2], vec![1.0; 8]),
            Err(GeometryError::SdfGridEmpty)
        ));
        assert!(matches!(
            SdfGrid::new([1, 2, 2], vec![1.0; 4]),
            Err(GeometryError::SdfGridTooSmall { res: [1, 2, 2] })
        ));
        assert!(matches!(
            SdfGrid::new([2, 2, 2], vec![1.0; 7]),
            Err(GeometryError::SdfGridValueCount {
                values: 7,
                res: [2, 2, 2]
            })
        ));
        let mut v = vec![1.0; 8];
        v[0] = -1.0;
        assert!(SdfGrid::new([2, 2, 2], v.clone()).is_ok());
        v[3] = f32::NAN;
        assert!(matches!(
            SdfGrid::new([2, 2, 2], v),
            Err(GeometryError::SdfGridNonFinite {
                index: 3,
                at: [1, 1, 0],
                value,
            }) if value.is_nan()
        ));
    }

    #[test]
    fn tight_boxes_hold_the_surface() {
        let g = grid_of(9, |p| (p - DVec3::splat(0.5)).length() - 0.3);
        let geom = SdfGeom::new(Arc::new(g), DMat4::IDENTITY, false).unwrap();
        // Points on the trilinear surface: bisect F along grid lines through each voxel.
        let grid = &*geom.grid;
        for (k, &vi) in grid.voxels.iter().enumerate() {
            let v = grid.voxel_pos(vi);
            let [lo, hi] = grid.boxes[k];
            let base = DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64);
            for i in 0..=8 {
                for j in 0..=8 {
                    for axis in 0..3 {
                        let mut p = base;
                        p[(axis + 1) % 3] += i as f64 / 8.0;
                        p[(axis + 2) % 3] += j as f64 / 8.0;
                        let mut q = p;
                        q[axis] += 1.0;
                        let (fa, fb) = (grid.eval(p), grid.eval(q));
                        if fa * fb > 0.0 {
                            continue;
                        }
                        let (mut a, mut b) = (p, q);
                        for _ in 0..60 {
                            let m = (a + b) * 0.5;
                            if grid.eval(m) * fa > 0.0 {
                                a = m
                            } else {
                                b = m
                            }
                        }
                        let x = (a + b) * 0.5;
                        assert!(
                            x.cmpge(lo - 1e-9).all() && x.cmple(hi + 1e-9).all(),
                            "{x} outside {lo} {hi}"
                        );
                    }
                }
            }
        }
    }
}
