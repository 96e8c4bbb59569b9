//! The scene's bounding sphere, as Mitsuba 3's infinitely distant emitters compute it
//! in `set_scene` (`envmap.cpp`, `constant.cpp`, `directional.cpp`): the sphere
//! around the bounding box of the shapes (sensors are not in Mitsuba's scene box),
//! centre the box's centre, radius the distance to its corner, enlarged by
//! `1 + RayEpsilon` and at least `RayEpsilon` (a scene without shapes: the origin,
//! radius `RayEpsilon`).
//!
//! Time: a light sample of these emitters lies at `ds.dist = 2 max(R, |x - c|)` from
//! its reference point `x` (Mitsuba's `sample_direction`), which mitransient adds to
//! the path's OPL. tstat counts the same distance for every segment that ends on an
//! infinitely distant emitter (next-event, BSDF-sampled escape and camera ray), so the
//! transient sums to the steady image.

use crate::geometry::shape::{Shape, ShapeGeom};
use glam::Vec3;

/// Mitsuba's `math::RayEpsilon<float>`: 1500 x 2^-24.
pub const RAY_EPSILON: f32 = 1500.0 / 16_777_216.0;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneSphere {
    pub center: Vec3,
    pub radius: f32,
}

impl Default for SceneSphere {
    fn default() -> Self {
        SceneSphere {
            center: Vec3::ZERO,
            radius: RAY_EPSILON,
        }
    }
}

impl SceneSphere {
    /// Mitsuba's sphere around the shapes' bounding box (meshes: their vertices,
    /// spheres: centre +- radius).
    pub fn of_shapes(shapes: &[Shape]) -> SceneSphere {
        let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
        for shape in shapes {
            match &shape.geom {
                ShapeGeom::Mesh { positions, .. } => {
                    for &p in positions {
                        (lo, hi) = (lo.min(p), hi.max(p));
                    }
                }
                ShapeGeom::Sphere(s, _) => {
                    lo = lo.min(s.center - Vec3::splat(s.radius));
                    hi = hi.max(s.center + Vec3::splat(s.radius));
                }
                ShapeGeom::Disk(g) => {
                    let (a, b) = g.bounds();
                    (lo, hi) = (lo.min(a), hi.max(b));
                }
                ShapeGeom::Cylinder(g) => {
                    let (a, b) = g.bounds();
                    (lo, hi) = (lo.min(a), hi.max(b));
                }
                ShapeGeom::Curve(g) => {
                    let (a, b) = g.control_bounds();
                    (lo, hi) = (lo.min(a), hi.max(b));
                }
                // Mitsuba's sdfgrid box: the unit cube's 8 corners mapped to the world.
                ShapeGeom::Sdf(g) => {
                    let (a, b) = g.bounds();
                    (lo, hi) = (lo.min(a), hi.max(b));
                }
            }
        }
        if !(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z) {
            return SceneSphere::default();
        }
        let center = (lo + hi) * 0.5;
        let radius = (center - hi).length();
        SceneSphere {
            center,
            radius: (radius * (1.0 + RAY_EPSILON)).max(RAY_EPSILON),
        }
    }

    /// The distance from `x` to an infinitely distant emitter's sample point:
    /// `2 max(R, |x - c|)` (2R from anywhere inside the sphere).
    #[inline]
    pub fn distance_from(&self, x: Vec3) -> f32 {
        2.0 * self.radius.max((x - self.center).length())
    }
}
