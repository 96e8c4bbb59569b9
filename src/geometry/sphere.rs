//! Analytic sphere intersection.

use glam::Vec3;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SphereGeom {
    pub center: Vec3,
    pub radius: f32,
}

impl SphereGeom {
    /// Nearest distance t > tmin at which a ray with unit direction `d` meets the sphere.
    /// Uses the discriminant form r^2 - |oc - (oc.d) d|^2, stable for distant origins.
    #[inline]
    pub fn intersect(&self, o: Vec3, d: Vec3, tmin: f32) -> Option<f32> {
        let oc = o - self.center;
        let b = oc.dot(d);
        let perp = oc - d * b;
        let disc = self.radius * self.radius - perp.length_squared();
        if disc < 0.0 {
            return None;
        }
        let s = disc.sqrt();
        // Two roots, computed to avoid cancellation (q has the sign of -b).
        let q = if b > 0.0 { -b - s } else { -b + s };
        let c = oc.length_squared() - self.radius * self.radius;
        let (mut t0, mut t1) = (q, if q != 0.0 { c / q } else { q });
        if t0 > t1 {
            std::mem::swap(&mut t0, &mut t1);
        }
        if t0 > tmin {
            Some(t0)
        } else if t1 > tmin {
            Some(t1)
        } else {
            None
        }
    }

    pub fn area(&self) -> f32 {
        4.0 * std::f32::consts::PI * self.radius * self.radius
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn enters_and_exits() {
        let s = SphereGeom {
            center: Vec3::new(0.0, 0.0, -5.0),
            radius: 1.0,
        };
        let t = s.intersect(Vec3::ZERO, -Vec3::Z, 0.0).unwrap();
        assert!((t - 4.0).abs() < 1e-5);
        let t = s
            .intersect(Vec3::new(0.0, 0.0, -5.0), -Vec3::Z, 0.0)
            .unwrap();
        assert!((t - 1.0).abs() < 1e-5);
        assert!(s
            .intersect(Vec3::new(0.0, 1.01, 0.0), -Vec3::Z, 0.0)
            .is_none());
        assert!(s.intersect(Vec3::ZERO, Vec3::Z, 0.0).is_none());
        // Grazing far away: still on the surface.
        let t = s
            .intersect(Vec3::new(0.0, 0.999, 1000.0), -Vec3::Z, 0.0)
            .unwrap();
        let p = Vec3::new(0.0, 0.999, 1000.0 - t);
        assert!(((p - s.center).length() - 1.0).abs() < 1e-3);
    }
}
