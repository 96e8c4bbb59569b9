//! Orthonormal frames: local shading coordinates with the normal along +z.

use glam::Vec3;

/// An orthonormal basis (s, t, n); `to_local(v).z` is the cosine with n.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    pub s: Vec3,
    pub t: Vec3,
    pub n: Vec3,
}

impl Frame {
    /// Duff et al. 2017, "Building an Orthonormal Basis, Revisited".
    pub fn from_normal(n: Vec3) -> Self {
        let sign = 1.0f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let s = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let t = Vec3::new(b, sign + n.y * n.y * a, -n.y);
        Frame { s, t, n }
    }

    /// Mitsuba 3's shading frame from a surface's dp/du (`SurfaceInteraction::
    /// initialize_sh_frame`): `s` is `dpdu` made orthogonal to `n` (Gram-Schmidt) and
    /// normalised, `t = n x s`. Where `dpdu` gives no direction (zero, as at a sphere's
    /// poles, not finite, or within about 1e-5 rad of `n`), the frame of
    /// [`Self::from_normal`], as Mitsuba falls back to `coordinate_system(n)` for a
    /// zero dp/du. Used only for anisotropic materials, whose lobes follow `s`
    /// (alpha_u) and `t` (alpha_v).
    pub fn from_normal_tangent(n: Vec3, dpdu: Vec3) -> Self {
        let Some(d) = dpdu.try_normalize() else {
            return Self::from_normal(n);
        };
        let s = d - n * n.dot(d);
        if s.length_squared() > 1e-10 {
            let s = s.normalize();
            Frame {
                s,
                t: n.cross(s),
                n,
            }
        } else {
            Self::from_normal(n)
        }
    }

    #[inline]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.s), v.dot(self.t), v.dot(self.n))
    }

    #[inline]
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        self.s * v.x + self.t * v.y + self.n * v.z
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_are_orthonormal_and_round_trip() {
        for n in [
            Vec3::Z,
            -Vec3::Z,
            Vec3::X,
            Vec3::new(0.3, -0.4, 0.5).normalize(),
            Vec3::new(-1e-7, 0.0, -1.0).normalize(),
        ] {
            let f = Frame::from_normal(n);
            assert!((f.s.length() - 1.0).abs() < 1e-5);
            assert!((f.t.length() - 1.0).abs() < 1e-5);
            assert!(f.s.dot(f.t).abs() < 1e-5 && f.s.dot(n).abs() < 1e-5);
            let v = Vec3::new(0.2, 0.7, -0.1);
            assert!((f.to_world(f.to_local(v)) - v).length() < 1e-5);
            assert!((f.to_local(n).z - 1.0).abs() < 1e-5);
        }
    }

    #[test]
    fn tangent_frames_follow_dpdu_and_fall_back_to_the_normal_frame() {
        let n = Vec3::new(0.3, -0.4, 0.5).normalize();
        let dpdu = Vec3::new(2.0, 1.0, -0.5);
        let f = Frame::from_normal_tangent(n, dpdu);
        assert!((f.s.length() - 1.0).abs() < 1e-6 && (f.t.length() - 1.0).abs() < 1e-6);
        assert!(f.s.dot(n).abs() < 1e-6 && f.t.dot(n).abs() < 1e-6 && f.s.dot(f.t).abs() < 1e-6);
        // s is dp/du's direction within the tangent plane; (s, t, n) right-handed.
        assert!(f.s.dot(dpdu) > 0.0 && f.s.cross(dpdu).dot(n).abs() < 1e-5);
        assert!((f.s.cross(f.t) - n).length() < 1e-6);
        // The frame of from_normal is right-handed too: the same convention.
        let g = Frame::from_normal(n);
        assert!((g.s.cross(g.t) - n).length() < 1e-6);
        let nearly_n = n + Frame::from_normal(n).t * 1e-7;
        for degenerate in [Vec3::ZERO, n * 3.0, nearly_n, Vec3::NAN, Vec3::INFINITY] {
            let f = Frame::from_normal_tangent(n, degenerate);
            assert_eq!((f.s, f.t, f.n), (g.s, g.t, g.n));
        }
    }
}
