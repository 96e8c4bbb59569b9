//! Analytic cylinder (Mitsuba 3's `cylinder`, `src/shapes/cylinder.cpp`): the open
//! tube x^2 + y^2 = 1, 0 <= z <= 1 in object space (no end caps), mapped by
//! `to_world * translate(p0) * to_frame(Frame(p1 - p0)) * scale(radius, radius, |p1 - p0|)`,
//! whose x and y axes must be orthogonal to each other and to z, of equal length
//! (Mitsuba warns otherwise and then computes a wrong area; tstat refuses).
//!
//! - Intersection in object space, the quadratic in f64 as Mitsuba's scalar variants:
//!   the nearest root t > tmin whose point has 0 <= z <= 1.
//! - Normal: outward radial (Mitsuba: cross(dp/du, dp/dv), flipped back when the map
//!   mirrors), flipped by the caller for `flip_normals`.
//! - uv = (phi / 2 pi, z), phi in [0, 2 pi); dp/du = to_world 2 pi (-y, x, 0),
//!   dp/dv = to_world (0, 0, 1).
//! - Area 2 pi r l; uniform area sampling takes phi = 2 pi u_1 and z = u_0 (Mitsuba's
//!   order).

use super::error::GeometryError;
use glam::{DMat3, DMat4, DVec3, Mat3, Vec2, Vec3};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CylinderGeom {
    /// Linear part and translation of the full object-to-world map.
    pub m: Mat3,
    pub c: Vec3,
    /// The inverse: world to object.
    pub inv: Mat3,
    /// World radius and length.
    pub radius: f32,
    pub length: f32,
}

/// Mitsuba's `coordinate_system(n)` (Duff et al. 2017) in double precision: the s and
/// t axes of `Frame3f(n)`, which fix where phi = 0 lies on the cylinder.
fn coordinate_system(n: DVec3) -> (DVec3, DVec3) {
    let sign = 1.0f64.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        DVec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        DVec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

impl CylinderGeom {
    /// The full object-to-world map of Mitsuba's parameters.
    pub fn object_to_world(to_world: &DMat4, p0: DVec3, p1: DVec3, radius: f64) -> DMat4 {
        let d = p1 - p0;
        let length = d.length();
        let n = d / length;
        let (s, t) = coordinate_system(n);
        let frame = DMat4::from_cols(s.extend(0.0), t.extend(0.0), n.extend(0.0), glam::DVec4::W);
        *to_world
            * DMat4::from_translation(p0)
            * frame
            * DMat4::from_scale(DVec3::new(radius, radius, length))
    }

    /// The cylinder of the full map `m` (see [`Self::object_to_world`]), or why not.
    pub fn new(m: &DMat4) -> Result<Self, GeometryError> {
        let lin = DMat3::from_mat4(*m);
        let (x, y, z) = (lin.x_axis, lin.y_axis, lin.z_axis);
        let (r, ry, l) = (x.length(), y.length(), z.length());
        let tol = 1e-5;
        if !(r > 0.0 && ry > 0.0 && l > 0.0 && (r * l).is_finite() && (r * l) as f32 > 0.0) {
            return Err(GeometryError::CylinderSize {
                radius: r,
                length: l,
            });
        }
        if (r - ry).abs() > tol * r
            || x.dot(y).abs() > tol * r * ry
            || x.dot(z).abs() > tol * r * l
            || y.dot(z).abs() > tol * ry * l
        {
            return Err(GeometryError::CylinderShear);
        }
        Ok(CylinderGeom {
            m: lin.as_mat3(),
            c: m.w_axis.truncate().as_vec3(),
            inv: lin.inverse().as_mat3(),
            radius: r as f32,
            length: l as f32,
        })
    }

    #[inline]
    pub fn to_local(&self, p: Vec3) -> Vec3 {
        self.inv * (p - self.c)
    }

    /// Nearest distance t > tmin at which a ray with unit direction `d` meets the tube.
    #[inline]
    pub fn intersect(&self, o: Vec3, d: Vec3, tmin: f32) -> Option<f32> {
        let lo = self.to_local(o).as_dvec3();
        let ld = (self.inv * d).as_dvec3();
        let a = ld.x * ld.x + ld.y * ld.y;
        let b = 2.0 * (ld.x * lo.x + ld.y * lo.y);
        let c = lo.x * lo.x + lo.y * lo.y - 1.0;
        // Mitsuba's solve_quadratic: a = 0 (parallel to the axis) has no solution
        // unless linear, which a circle never is (b = 0 then too).
        if a == 0.0 {
            return None;
        }
        let disc = b * b - 4.0 * a * c;
        // Negative or NaN: no real root.
        if disc.is_nan() || disc < 0.0 {
            return None;
        }
        let q = -0.5 * (b + disc.sqrt().copysign(b));
        let (mut t0, mut t1) = (q / a, c / q);
        if t0 > t1 {
            std::mem::swap(&mut t0, &mut t1);
        }
        let tmin = tmin as f64;
        for t in [t0, t1] {
            let z = lo.z + ld.z * t;
            // The f32 distance must still lie beyond tmin (else it is the surface the
            // ray leaves).
            if t > tmin && (0.0..=1.0).contains(&z) && t.is_finite() && t as f32 > tmin as f32 {
                return Some(t as f32);
            }
        }
        None
    }

    /// `p` moved radially onto the tube (Mitsuba re-projects the same way), with the
    /// outward unit normal there.
    #[inline]
    pub fn project(&self, p: Vec3) -> (Vec3, Vec3) {
        let l = self.to_local(p);
        let r = (l.x * l.x + l.y * l.y).sqrt();
        let radial = if r > 0.0 {
            Vec3::new(l.x / r, l.y / r, 0.0)
        } else {
            Vec3::X
        };
        let on = Vec3::new(radial.x, radial.y, l.z);
        // The x and y axes are orthogonal to z with one length: the normal transform
        // of the radial direction is its image.
        (self.c + self.m * on, (self.m * radial).normalize())
    }

    /// Mitsuba's uv: (phi / 2 pi, z) of the object-space point.
    pub fn uv(&self, p: Vec3) -> Vec2 {
        let l = self.to_local(p);
        let mut phi = l.y.atan2(l.x);
        if phi < 0.0 {
            phi += std::f32::consts::TAU;
        }
        Vec2::new(phi * (0.5 * std::f32::consts::FRAC_1_PI), l.z)
    }

    /// Mitsuba's dp/du: to_world 2 pi (-y, x, 0) at the re-projected object point.
    pub fn dpdu(&self, p: Vec3) -> Vec3 {
        let l = self.to_local(p);
        let r = (l.x * l.x + l.y * l.y).sqrt();
        let (x, y) = if r > 0.0 {
            (l.x / r, l.y / r)
        } else {
            (1.0, 0.0)
        };
        self.m * (Vec3::new(-y, x, 0.0) * std::f32::consts::TAU)
    }

    /// Mitsuba's dp/dv: `to_world (0, 0, 1)` (v runs along the axis).
    pub fn dpdv(&self) -> Vec3 {
        self.m * Vec3::Z
    }

    pub fn area(&self) -> f32 {
        std::f32::consts::TAU * self.radius * self.length
    }

    /// A point uniformly distributed by area (Mitsuba's `sample_position`).
    #[inline]
    pub fn sample(&self, u: [f32; 2]) -> Vec3 {
        let (s, c) = (std::f32::consts::TAU * u[1]).sin_cos();
        self.c + self.m * Vec3::new(c, s, u[0])
    }

    /// A box around the tube: the boxes of its two end circles (Mitsuba's), padded.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let (x1, x2) = (self.m.x_axis, self.m.y_axis);
        let e = (x1 * x1 + x2 * x2).sqrt() * (1.0 + 1e-6) + Vec3::splat(f32::MIN_POSITIVE);
        let (p0, p1) = (self.c, self.c + self.m.z_axis);
        let pad = (p0.abs().max(p1.abs())) * 1e-6;
        ((p0 - e).min(p1 - e) - pad, (p0 + e).max(p1 + e) + pad)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cyl(to_world: DMat4, p0: DVec3, p1: DVec3, r: f64) -> CylinderGeom {
        CylinderGeom::new(&CylinderGeom::object_to_world(&to_world, p0, p1, r)).unwrap()
    }

    #[test]
    fn hits_the_tube_between_its_ends_from_outside_and_inside() {
        let g = cyl(DMat4::IDENTITY, DVec3::ZERO, DVec3::new(0.0, 0.0, 2.0), 0.5);
        assert!((g.area() - std::f32::consts::TAU * 0.5 * 2.0).abs() < 1e-5);
        // From outside along -x at z = 1: the near wall at x = 0.5.
        let t = g
            .intersect(Vec3::new(3.0, 0.0, 1.0), -Vec3::X, 0.0)
            .unwrap();
        assert!((t - 2.5).abs() < 1e-6, "{t}");
        // From the axis: the wall at distance 0.5.
        let t = g.intersect(Vec3::new(0.0, 0.0, 1.0), Vec3::Y, 0.0).unwrap();
        assert!((t - 0.5).abs() < 1e-6, "{t}");
        // Above the top end: missed; entering through the open end, the far wall.
        assert!(g
            .intersect(Vec3::new(3.0, 0.0, 2.1), -Vec3::X, 0.0)
            .is_none());
        let d = Vec3::new(-1.0, 0.0, -1.0).normalize();
        let t = g.intersect(Vec3::new(0.4, 0.0, 2.4), d, 0.0).unwrap();
        let p = Vec3::new(0.4, 0.0, 2.4) + d * t;
        assert!((p.x + 0.5).abs() < 1e-5 && p.z > 0.0 && p.z < 2.0, "{p}");
        // Along the axis: never.
        assert!(g
            .intersect(Vec3::new(0.0, 0.0, -1.0), Vec3::Z, 0.0)
            .is_none());
    }

    #[test]
    fn p0_p1_radius_and_to_world_place_the_tube() {
        let tw = DMat4::from_translation(DVec3::new(1.0, -1.0, 0.5))
            * DMat4::from_scale(DVec3::splat(2.0));
        let g = cyl(
            tw,
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 3.0, 0.0),
            0.25,
        );
        assert!((g.radius - 0.5).abs() < 1e-6 && (g.length - 6.0).abs() < 1e-5);
        // The axis runs from to_world p0 = (3, -1, 0.5) along +y.
        let (p, n) = g.project(Vec3::new(3.0, 2.0, 5.0));
        assert!((p - Vec3::new(3.0, 2.0, 1.0)).length() < 1e-5, "{p}");
        assert!((n - Vec3::Z).length() < 1e-6);
        // A mirroring to_world keeps the normal outward.
        let g = cyl(
            DMat4::from_scale(DVec3::new(-1.0, 1.0, 1.0)),
            DVec3::ZERO,
            DVec3::Z,
            1.0,
        );
        let (_, n) = g.project(Vec3::new(2.0, 0.0, 0.5));
        assert!((n - Vec3::X).length() < 1e-6, "{n}");
        // A non-uniform cross-section is refused.
        let m = CylinderGeom::object_to_world(
            &DMat4::from_scale(DVec3::new(1.0, 2.0, 1.0)),
            DVec3::ZERO,
            DVec3::Z,
            1.0,
        );
        assert!(matches!(
            CylinderGeom::new(&m),
            Err(GeometryError::CylinderShear)
        ));
    }
}
