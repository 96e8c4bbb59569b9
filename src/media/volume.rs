//! Volumes: values over space for media (Mitsuba 3's `<volume>` plugins,
//! `src/volumes/const.cpp` and `grid.cpp`, with Dr.Jit's 3D texture lookup).
//!
//! `constvolume`:
//! | parameter | type | default | meaning |
//! |-----------|------|---------|---------|
//! | value | float, rgb or spectrum | 1 | the value everywhere (unbounded) |
//! | to_world | transform | identity | places the unit cube (its bounding box) |
//!
//! `gridvolume`:
//! | parameter | type | default | meaning |
//! |-----------|------|---------|---------|
//! | filename | string | (required) | a Mitsuba `.vol` file (`vol_file.rs`), 1 or 3 channels |
//! | filter_type | string | `trilinear` | `trilinear` or `nearest` |
//! | wrap_mode | string | `clamp` | `clamp`, `repeat` or `mirror`: lookups outside the unit cube |
//! | use_grid_bbox | boolean | false | map the file's bounding box (not the unit cube) to the grid |
//! | max_value | float | the grid's largest value | the majorant's bound; must not be below the largest value |
//! | to_world | transform | identity | places the unit cube in the scene |
//! | raw, accel | boolean | — | accepted: no effect in RGB |
//!
//! Conventions (Mitsuba's): a world point `p` is looked up at `q = to_local p` with
//! `to_local = to_world^-1` (preceded, with `use_grid_bbox`, by the map of the file's
//! box onto the unit cube). The grid's cell (x, y, z) covers `[x/nx, (x+1)/nx) x ...`
//! of the unit cube; `nearest` returns cell `floor(q * n)`, `trilinear` interpolates
//! the eight cells around `q * n - 1/2` (cell centres at half-integers), each corner's
//! index wrapped on its own, as `textures::bitmap` does in 2D. One channel is a grey.
//! The volume's bounding box (the world AABB of the transformed unit cube) bounds a
//! heterogeneous medium; `max` is Mitsuba's `Volume::max` (over every channel), which
//! times the medium's `scale` is its majorant.

use crate::math::Rgb;
use crate::textures::bitmap::WrapMode;
use glam::{DMat4, Vec3};
use std::sync::Arc;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GridFilter {
    Nearest,
    Trilinear,
}

/// Grid values and their lookup.
#[derive(Clone, Debug, PartialEq)]
pub struct Grid {
    /// Cells along x, y, z.
    pub size: [usize; 3],
    /// 1 or 3.
    pub channels: usize,
    /// `((z * ny + y) * nx + x) * channels + c`.
    pub data: Vec<f32>,
    pub filter: GridFilter,
    pub wrap: WrapMode,
}

impl Grid {
    #[inline]
    fn cell(&self, x: usize, y: usize, z: usize) -> Rgb {
        let i = ((z * self.size[1] + y) * self.size[0] + x) * self.channels;
        if self.channels == 1 {
            Rgb::splat(self.data[i])
        } else {
            Rgb::new(self.data[i], self.data[i + 1], self.data[i + 2])
        }
    }

    /// The value at unit-cube coordinates `q`.
    #[inline]
    pub fn lookup(&self, q: Vec3) -> Rgb {
        let n = [
            self.size[0] as i64,
            self.size[1] as i64,
            self.size[2] as i64,
        ];
        let nf = Vec3::new(
            self.size[0] as f32,
            self.size[1] as f32,
            self.size[2] as f32,
        );
        // Saturating conversions: far-away points (and NaN, as 0) stay in range.
        let floor = |x: f32| x.floor() as i64;
        match self.filter {
            GridFilter::Nearest => {
                let c = q * nf;
                self.cell(
                    self.wrap.wrap(floor(c.x), n[0]),
                    self.wrap.wrap(floor(c.y), n[1]),
                    self.wrap.wrap(floor(c.z), n[2]),
                )
            }
            GridFilter::Trilinear => {
                let c = q * nf - Vec3::splat(0.5);
                let i = [floor(c.x), floor(c.y), floor(c.z)];
                let w1 = c - Vec3::new(i[0] as f32, i[1] as f32, i[2] as f32);
                let w0 = Vec3::ONE - w1;
                let idx = |a: usize| {
                    (
                        self.wrap.wrap(i[a], n[a]),
                        self.wrap.wrap(i[a].saturating_add(1), n[a]),
                    )
                };
                let (x0, x1) = idx(0);
                let (y0, y1) = idx(1);
                let (z0, z1) = idx(2);
                let along_x = |y, z| self.cell(x0, y, z) * w0.x + self.cell(x1, y, z) * w1.x;
                let v0 = along_x(y0, z0) * w0.y + along_x(y1, z0) * w1.y;
                let v1 = along_x(y0, z1) * w0.y + along_x(y1, z1) * w1.y;
                v0 * w0.z + v1 * w1.z
            }
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
pub enum VolumeData {
    Const(Rgb),
    Grid(Arc<Grid>),
}

/// A volume placed in the scene.
#[derive(Clone, Debug, PartialEq)]
pub struct Volume {
    pub data: VolumeData,
    /// World to unit-cube coordinates.
    pub to_local: DMat4,
    /// World-space AABB of the unit cube under `to_local^-1`.
    pub bbox_min: Vec3,
    pub bbox_max: Vec3,
    /// Bound on every value and channel (Mitsuba's `max()`).
    pub max: f32,
}

impl Volume {
    /// A volume of one value, placed by `to_world` (its bounding box; the value holds
    /// everywhere).
    pub fn constant(value: Rgb, to_world: DMat4) -> Volume {
        let (bbox_min, bbox_max) = unit_cube_bounds(to_world);
        Volume {
            data: VolumeData::Const(value),
            to_local: to_world.inverse(),
            bbox_min,
            bbox_max,
            max: value.max_element(),
        }
    }

    /// The constant value, if the volume is one.
    pub fn as_constant(&self) -> Option<Rgb> {
        match self.data {
            VolumeData::Const(v) => Some(v),
            VolumeData::Grid(_) => None,
        }
    }

    /// The value at world point `p`.
    #[inline]
    pub fn eval(&self, p: Vec3) -> Rgb {
        match &self.data {
            VolumeData::Const(v) => *v,
            VolumeData::Grid(g) => g.lookup(self.to_local.transform_point3(p.as_dvec3()).as_vec3()),
        }
    }

    /// The part `[t0, t1]` of the ray `o + t d` (t >= 0) inside the bounding box, if
    /// any (slab test; an axis the ray runs along bounds it only by its origin).
    #[inline]
    pub fn ray_range(&self, o: Vec3, d: Vec3) -> Option<(f32, f32)> {
        let (mut t0, mut t1) = (0.0f32, f32::INFINITY);
        for a in 0..3 {
            let (lo, hi) = (self.bbox_min[a], self.bbox_max[a]);
            if d[a] == 0.0 {
                if o[a] < lo || o[a] > hi {
                    return None;
                }
                continue;
            }
            let inv = 1.0 / d[a];
            let (mut ta, mut tb) = ((lo - o[a]) * inv, (hi - o[a]) * inv);
            if ta > tb {
                std::mem::swap(&mut ta, &mut tb);
            }
            t0 = t0.max(ta);
            t1 = t1.min(tb);
        }
        (t0 <= t1).then_some((t0, t1))
    }
}

/// The world AABB of the unit cube's eight corners under `to_world` (Mitsuba's
/// `Volume::update_bbox`).
pub fn unit_cube_bounds(to_world: DMat4) -> (Vec3, Vec3) {
    let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
    for i in 0..8 {
        let c = glam::DVec3::new((i & 1) as f64, ((i >> 1) & 1) as f64, (i >> 2) as f64);
        let w = to_world.transform_point3(c).as_vec3();
        lo = lo.min(w);
        hi = hi.max(w);
    }
    (lo, hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(size: [usize; 3], filter: GridFilter, wrap: WrapMode) -> Grid {
        let n = size[0] * size[1] * size[2];
        Grid {
            size,
            channels: 1,
            data: (0..n).map(|i| i as f32).collect(),
            filter,
            wrap,
        }
    }

    /// Trilinear lookups at cell centres return the cells, between centres the
    /// plain weighted average of the eight, and a linear function of the index stays
    /// linear (slow reference: explicit corner sums).
    #[test]
    fn trilinear_lookup_matches_a_reference() {
        let g = grid([3, 4, 5], GridFilter::Trilinear, WrapMode::Clamp);
        let value = |x: usize, y: usize, z: usize| ((z * 4 + y) * 3 + x) as f32;
        for z in 0..5 {
            for y in 0..4 {
                for x in 0..3 {
                    let q = Vec3::new(
                        (x as f32 + 0.5) / 3.0,
                        (y as f32 + 0.5) / 4.0,
                        (z as f32 + 0.5) / 5.0,
                    );
                    let v = g.lookup(q).x;
                    assert!((v - value(x, y, z)).abs() < 1e-4, "{x} {y} {z}: {v}");
                }
            }
        }
        // Inside the centres' hull the data, linear in (x, y, z), interpolate exactly.
        for k in 0..50 {
            let c = Vec3::new(
                0.5 + 2.0 * ((k as f32 * 0.37) % 1.0),
                0.5 + 3.0 * ((k as f32 * 0.61) % 1.0),
                0.5 + 4.0 * ((k as f32 * 0.13) % 1.0),
            );
            let q = c / Vec3::new(3.0, 4.0, 5.0);
            let want = (c.z - 0.5) * 12.0 + (c.y - 0.5) * 3.0 + (c.x - 0.5);
            assert!((g.lookup(q).x - want).abs() < 1e-3, "{c}");
        }
        // Clamp: outside the cube, the border cells.
        assert_eq!(g.lookup(Vec3::new(-3.0, -3.0, -3.0)).x, 0.0);
        assert_eq!(g.lookup(Vec3::new(9.0, 9.0, 9.0)).x, 59.0);
    }

    #[test]
    fn nearest_and_wrap_modes() {
        let g = grid([4, 1, 1], GridFilter::Nearest, WrapMode::Repeat);
        let at = |g: &Grid, x: f32| g.lookup(Vec3::new(x, 0.5, 0.5)).x;
        assert_eq!(at(&g, 0.3), 1.0);
        assert_eq!(at(&g, 1.3), 1.0);
        assert_eq!(at(&g, -0.1), 3.0);
        let m = grid([4, 1, 1], GridFilter::Nearest, WrapMode::Mirror);
        assert_eq!(at(&m, 1.1), 3.0);
        assert_eq!(at(&m, 1.3), 2.0);
        assert_eq!(at(&m, -0.1), 0.0);
        let c = grid([4, 1, 1], GridFilter::Nearest, WrapMode::Clamp);
        assert_eq!(at(&c, 7.0), 3.0);
        assert_eq!(at(&c, f32::NAN), 0.0);
        // Repeat with trilinear: the wrap joins the last cell to the first.
        let r = grid([4, 1, 1], GridFilter::Trilinear, WrapMode::Repeat);
        assert!((at(&r, 1.0) - 1.5).abs() < 1e-6);
    }

    #[test]
    fn bounding_box_and_ray_range() {
        let to_world = DMat4::from_translation(glam::DVec3::splat(-0.5))
            * DMat4::from_scale(glam::DVec3::splat(1.5));
        let v = Volume::constant(Rgb::ONE, to_world);
        assert_eq!(v.bbox_min, Vec3::splat(-0.5));
        assert_eq!(v.bbox_max, Vec3::splat(1.0));
        let (t0, t1) = v.ray_range(Vec3::new(0.0, 0.0, -5.0), Vec3::Z).unwrap();
        assert_eq!((t0, t1), (4.5, 6.0));
        let (t0, t1) = v.ray_range(Vec3::ZERO, Vec3::X).unwrap();
        assert_eq!((t0, t1), (0.0, 1.0));
        assert!(v.ray_range(Vec3::new(0.0, 2.0, -5.0), Vec3::Z).is_none());
        assert!(v.ray_range(Vec3::new(0.0, 0.0, 5.0), Vec3::Z).is_none());
        // Local coordinates: the box's corners map to the unit cube's.
        let q = v.to_local.transform_point3(glam::DVec3::splat(1.0));
        assert!((q - glam::DVec3::ONE).length() < 1e-12);
    }
}
