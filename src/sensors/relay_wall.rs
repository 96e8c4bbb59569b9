//! The relay wall of an NLOS capture (SPEC 11): the rectangle an `nlos_capture_meter`
//! measures, its grid of points and where rays meet it. `scene/nlos_setup.rs` finds it in the
//! scene; `camera.rs` aims the meter's rays at its grid.

use crate::geometry::accel::Hit;
use crate::geometry::shape::{Shape, ShapeGeom};
use glam::Vec3;

/// The relay wall's rectangle: `p(u, v) = corner + du u + dv v` for uv in [0, 1]^2.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Wall {
    pub corner: Vec3,
    pub du: Vec3,
    pub dv: Vec3,
    /// Unit normal: the rectangle's geometric normal (local +z, or -z with flip_normals).
    pub normal: Vec3,
}

impl Wall {
    /// The wall of a `rectangle` shape (its mesh: local (-1, -1), (1, -1), (1, 1),
    /// (-1, 1) mapped by to_world).
    pub fn of_rectangle(shape: &Shape) -> Option<Wall> {
        let ShapeGeom::Mesh { positions, .. } = &shape.geom else {
            return None;
        };
        let [a, b, _, d] = <[Vec3; 4]>::try_from(positions.as_slice()).ok()?;
        let normal = shape.surface(0, 0.25, 0.25, a).ng;
        Some(Wall {
            corner: a,
            du: b - a,
            dv: d - a,
            normal,
        })
    }

    /// Where the ray (o, d) meets the rectangle: (t, u, v), t > 0, uv in [0, 1]^2.
    pub fn intersect(&self, o: Vec3, d: Vec3) -> Option<(f32, f32, f32)> {
        let n = self.du.cross(self.dv);
        let denom = n.dot(d);
        if denom == 0.0 || !denom.is_finite() {
            return None;
        }
        let t = n.dot(self.corner - o) / denom;
        if !(t > 0.0 && t.is_finite()) {
            return None;
        }
        // (u, v) of the point by the normal equations of corner + du u + dv v.
        let r = o + d * t - self.corner;
        let (a, b, c) = (
            self.du.dot(self.du),
            self.du.dot(self.dv),
            self.dv.dot(self.dv),
        );
        let det = a * c - b * b;
        let (ru, rv) = (r.dot(self.du), r.dot(self.dv));
        let u = (c * ru - b * rv) / det;
        let v = (a * rv - b * ru) / det;
        ((0.0..=1.0).contains(&u) && (0.0..=1.0).contains(&v)).then_some((t, u, v))
    }

    /// The hit at (u, v) of the rectangle `shape` (shape index `index`), at distance
    /// t and point p: the triangle and barycentrics of the rectangle's mesh (triangles
    /// (0, 1, 2) and (2, 3, 0) over the corners uv (0, 0), (1, 0), (1, 1), (0, 1)).
    pub fn hit(&self, shape: &Shape, index: u32, t: f32, u: f32, v: f32, p: Vec3) -> Hit {
        let (face, b1, b2) = if u >= v {
            (0, u - v, v)
        } else {
            (1, v - u, 1.0 - v)
        };
        Hit {
            t,
            shape: index,
            surface: shape.surface(face, b1, b2, p),
            face,
            b1,
            b2,
        }
    }

    /// The centre of grid cell (x, y) of a `w` x `h` grid.
    #[inline]
    pub fn grid_point(&self, x: usize, y: usize, w: usize, h: usize) -> Vec3 {
        let u = (x as f32 + 0.5) / w as f32;
        let v = (y as f32 + 0.5) / h as f32;
        self.corner + self.du * u + self.dv * v
    }
}
