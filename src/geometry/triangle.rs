//! Ray-triangle intersection (Moller-Trumbore) and triangle surface sampling.

use glam::Vec3;

/// A triangle as stored for intersection: one vertex and two edges.
#[derive(Clone, Copy, Debug)]
pub struct TriangleGeom {
    pub v0: Vec3,
    pub e1: Vec3,
    pub e2: Vec3,
}

impl TriangleGeom {
    pub fn new(a: Vec3, b: Vec3, c: Vec3) -> Self {
        TriangleGeom {
            v0: a,
            e1: b - a,
            e2: c - a,
        }
    }

    /// Distance along the ray and barycentrics (b1, b2) of the hit, if any with t > tmin.
    #[inline]
    pub fn intersect(&self, o: Vec3, d: Vec3, tmin: f32) -> Option<(f32, f32, f32)> {
        let pvec = d.cross(self.e2);
        let det = self.e1.dot(pvec);
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let inv = 1.0 / det;
        let tvec = o - self.v0;
        let b1 = tvec.dot(pvec) * inv;
        if !(0.0..=1.0).contains(&b1) {
            return None;
        }
        let qvec = tvec.cross(self.e1);
        let b2 = d.dot(qvec) * inv;
        if b2 < 0.0 || b1 + b2 > 1.0 {
            return None;
        }
        let t = self.e2.dot(qvec) * inv;
        (t > tmin).then_some((t, b1, b2))
    }

    /// Unnormalised geometric normal (right-handed winding); length is twice the area.
    #[inline]
    pub fn cross(&self) -> Vec3 {
        self.e1.cross(self.e2)
    }

    pub fn area(&self) -> f32 {
        0.5 * self.cross().length()
    }

    #[inline]
    pub fn point(&self, b1: f32, b2: f32) -> Vec3 {
        self.v0 + self.e1 * b1 + self.e2 * b2
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hits_inside_misses_outside_and_behind() {
        let t = TriangleGeom::new(Vec3::ZERO, Vec3::X, Vec3::Y);
        let (dist, b1, b2) = t
            .intersect(Vec3::new(0.25, 0.25, 2.0), -Vec3::Z, 0.0)
            .unwrap();
        assert!((dist - 2.0).abs() < 1e-6 && (b1 - 0.25).abs() < 1e-6 && (b2 - 0.25).abs() < 1e-6);
        assert!(t
            .intersect(Vec3::new(0.75, 0.75, 2.0), -Vec3::Z, 0.0)
            .is_none());
        assert!(t
            .intersect(Vec3::new(0.25, 0.25, 2.0), Vec3::Z, 0.0)
            .is_none());
        assert!(t
            .intersect(Vec3::new(0.25, 0.25, 1.0), Vec3::X, 0.0)
            .is_none());
        assert!((t.area() - 0.5).abs() < 1e-7);
    }
}
