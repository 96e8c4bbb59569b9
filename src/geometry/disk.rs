//! Analytic disk (Mitsuba 3's `disk`, `src/shapes/disk.cpp`): the unit disk
//! x^2 + y^2 <= 1 of the object-space plane z = 0, mapped by an affine `to_world`
//! (any: a non-uniform scale makes an ellipse).
//!
//! - Intersection in object space: t = -o_z / d_z for the ray mapped by the inverse
//!   transform (its direction not renormalised, so t is the world distance along the
//!   world's unit direction), a hit when x^2 + y^2 <= 1 there.
//! - Normal: `to_world`'s normal transform (inverse transpose) of +z, unit; the caller
//!   flips it for `flip_normals` (Mitsuba appends scale(1, 1, -1), which flips it and
//!   changes nothing else).
//! - uv = (r, phi / 2 pi) of the object-space point (r, phi polar, phi in [0, 2 pi)),
//!   dp/du = to_world (cos phi, sin phi, 0) (zero at the centre).
//! - Area pi |M x x M y| (an ellipse's); uniform area sampling maps the concentric
//!   disk through `to_world` (an affine map keeps a uniform density uniform).

use super::error::GeometryError;
use crate::math::sampling::concentric_disk;
use glam::{DMat4, Mat3, Vec2, Vec3};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DiskGeom {
    /// Linear part and translation of `to_world` (object to world).
    pub m: Mat3,
    pub c: Vec3,
    /// The inverse: world to object.
    pub inv: Mat3,
    /// World unit normal of the object's +z (before `flip_normals`).
    pub n: Vec3,
    pub area: f32,
}

impl DiskGeom {
    /// The disk of `to_world`, or why it cannot be one (a singular or overflowing map).
    pub fn new(to_world: &DMat4) -> Result<Self, GeometryError> {
        let lin = glam::DMat3::from_mat4(*to_world);
        let det = lin.determinant();
        let (u, v) = (lin.x_axis, lin.y_axis);
        let area = std::f64::consts::PI * u.cross(v).length();
        if !(det != 0.0 && det.is_finite() && area.is_finite() && area as f32 > 0.0) {
            return Err(GeometryError::DiskMap { area });
        }
        let n = (lin.inverse().transpose() * glam::DVec3::Z).normalize();
        Ok(DiskGeom {
            m: lin.as_mat3(),
            c: to_world.w_axis.truncate().as_vec3(),
            inv: lin.inverse().as_mat3(),
            n: n.as_vec3(),
            area: area as f32,
        })
    }

    /// The object-space point of a world point.
    #[inline]
    pub fn to_local(&self, p: Vec3) -> Vec3 {
        self.inv * (p - self.c)
    }

    /// Nearest distance t > tmin at which a ray with unit direction `d` meets the disk.
    #[inline]
    pub fn intersect(&self, o: Vec3, d: Vec3, tmin: f32) -> Option<f32> {
        let lo = self.to_local(o);
        let ld = self.inv * d;
        let t = -lo.z / ld.z;
        if !(t > tmin && t < f32::INFINITY) {
            return None;
        }
        let (x, y) = (lo.x + ld.x * t, lo.y + ld.y * t);
        (x * x + y * y <= 1.0).then_some(t)
    }

    /// `p` moved onto the disk's plane (removes the hit's rounding error).
    #[inline]
    pub fn project(&self, p: Vec3) -> Vec3 {
        p + self.n * self.n.dot(self.c - p)
    }

    /// Mitsuba's uv: (r, phi / 2 pi) of the object-space point.
    pub fn uv(&self, p: Vec3) -> Vec2 {
        let l = self.to_local(p);
        let r = (l.x * l.x + l.y * l.y).sqrt();
        let mut v = l.y.atan2(l.x) * (0.5 * std::f32::consts::FRAC_1_PI);
        if v < 0.0 {
            v += 1.0;
        }
        Vec2::new(r, v)
    }

    /// Mitsuba's dp/du: to_world (cos phi, sin phi, 0), zero at the centre.
    pub fn dpdu(&self, p: Vec3) -> Vec3 {
        let l = self.to_local(p);
        let r2 = l.x * l.x + l.y * l.y;
        let inv_r = if r2 != 0.0 { 1.0 / r2.sqrt() } else { 0.0 };
        self.m * Vec3::new(l.x * inv_r, l.y * inv_r, 0.0)
    }

    /// Mitsuba's dp/dv at `p`: `to_world (-sin phi, cos phi, 0) 2 pi r` (v is the
    /// azimuth over 2 pi).
    pub fn dpdv(&self, p: Vec3) -> Vec3 {
        let l = self.to_local(p);
        let r = (l.x * l.x + l.y * l.y).sqrt();
        if r == 0.0 {
            return Vec3::ZERO;
        }
        self.m * (Vec3::new(-l.y / r, l.x / r, 0.0) * (std::f32::consts::TAU * r))
    }

    /// A point uniformly distributed by area.
    #[inline]
    pub fn sample(&self, u: [f32; 2]) -> Vec3 {
        let [x, y] = concentric_disk(u);
        self.c + self.m * Vec3::new(x, y, 0.0)
    }

    /// A box around the disk: centre +- sqrt(u^2 + v^2) per axis (Mitsuba's), u and v
    /// the images of the object's x and y axes, padded by a few ulps.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let (u, v) = (self.m.x_axis, self.m.y_axis);
        let e = (u * u + v * v).sqrt() * (1.0 + 1e-6) + Vec3::splat(f32::MIN_POSITIVE);
        (self.c - e, self.c + e)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    fn disk(m: DMat4) -> DiskGeom {
        DiskGeom::new(&m).unwrap()
    }

    #[test]
    fn hits_inside_the_ellipse_only_and_at_the_plane_distance() {
        // Scaled by (2, 0.5), tilted, moved: a point of the ellipse is hit at its
        // distance; just outside the rim it is missed.
        let m = DMat4::from_translation(DVec3::new(1.0, 2.0, 3.0))
            * DMat4::from_rotation_x(0.4)
            * DMat4::from_scale(DVec3::new(2.0, 0.5, 1.0));
        let g = disk(m);
        for (lx, ly, inside) in [
            (0.0, 0.0, true),
            (0.99, 0.0, true),
            (0.0, -0.99, true),
            (0.7, 0.7, true),
            (1.01, 0.0, false),
            (0.72, 0.72, false),
        ] {
            let target = m.transform_point3(DVec3::new(lx, ly, 0.0)).as_vec3();
            let o = target + Vec3::new(0.3, -0.2, 5.0);
            let d = (target - o).normalize();
            match g.intersect(o, d, 0.0) {
                Some(t) => {
                    assert!(inside, "({lx}, {ly}) hit");
                    assert!((t - (target - o).length()).abs() < 1e-5 * t, "{t}");
                }
                None => assert!(!inside, "({lx}, {ly}) missed"),
            }
        }
        // Parallel to the plane, behind the origin: no hit.
        assert!(g
            .intersect(Vec3::new(1.0, 2.0, 3.0), g.m.x_axis.normalize(), 0.0)
            .is_none());
        let o = Vec3::new(1.0, 2.0, 3.0) + g.n;
        assert!(g.intersect(o, g.n, 0.0).is_none());
        assert!(g.intersect(o, -g.n, 0.0).is_some());
    }

    #[test]
    fn area_normal_and_bounds_of_an_ellipse() {
        let m = DMat4::from_rotation_y(0.3) * DMat4::from_scale(DVec3::new(2.0, 0.5, 7.0));
        let g = disk(m);
        assert!((g.area - std::f32::consts::PI).abs() < 1e-6);
        let want = m.transform_vector3(DVec3::Z).normalize().as_vec3();
        assert!((g.n - want).length() < 1e-6);
        // A mirror keeps the normal the transformed +z (inverse transpose).
        let g = disk(DMat4::from_scale(DVec3::new(-1.0, 1.0, 1.0)));
        assert!((g.n - Vec3::Z).length() < 1e-7);
        let g = disk(DMat4::from_scale(DVec3::new(1.0, 1.0, -1.0)));
        assert!((g.n + Vec3::Z).length() < 1e-7);
        // Every sampled point lies inside the bounds.
        let g = disk(m);
        let (lo, hi) = g.bounds();
        for i in 0..1000 {
            let u = [(i as f32 * 0.618) % 1.0, (i as f32 * 0.377) % 1.0];
            let p = g.sample(u);
            assert!(p.cmpge(lo).all() && p.cmple(hi).all(), "{p}");
        }
        assert!(matches!(
            DiskGeom::new(&DMat4::from_scale(DVec3::new(1.0, 0.0, 1.0))),
            Err(GeometryError::DiskMap { area }) if area == 0.0
        ));
    }
}
