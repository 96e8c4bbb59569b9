//! `to_uv`: the 2D affine map a texture applies to uv before its lookup.

use glam::{DMat4, Vec2};

/// `uv' = [a b; c d] uv + t`.
///
/// Mitsuba reads `to_uv` as a 3x3 transform; a 4x4 `<transform>` (what the XML's
/// `translate`/`scale`/`rotate` build) is reduced by `AffineTransform::extract`
/// (`include/mitsuba/core/transform.h`): the upper-left 2x2 block and the first two
/// entries of the last column (the x/y translation). The z row and column are dropped.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UvTransform {
    /// Row-major 2x2 linear part.
    pub m: [[f32; 2]; 2],
    pub t: Vec2,
}

impl Default for UvTransform {
    fn default() -> Self {
        UvTransform::IDENTITY
    }
}

impl UvTransform {
    pub const IDENTITY: UvTransform = UvTransform {
        m: [[1.0, 0.0], [0.0, 1.0]],
        t: Vec2::ZERO,
    };

    /// From a parsed `<transform name="to_uv">` (column-major 4x4).
    pub fn from_mat4(m: &DMat4) -> Self {
        UvTransform {
            m: [
                [m.x_axis.x as f32, m.y_axis.x as f32],
                [m.x_axis.y as f32, m.y_axis.y as f32],
            ],
            t: Vec2::new(m.w_axis.x as f32, m.w_axis.y as f32),
        }
    }

    #[inline]
    pub fn apply(&self, uv: Vec2) -> Vec2 {
        if *self == UvTransform::IDENTITY {
            return uv;
        }
        Vec2::new(
            self.m[0][0] * uv.x + self.m[0][1] * uv.y + self.t.x,
            self.m[1][0] * uv.x + self.m[1][1] * uv.y + self.t.y,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    #[test]
    fn a_4x4_keeps_its_2d_part_and_xy_translation() {
        let m = DMat4::from_translation(DVec3::new(0.25, -1.0, 9.0))
            * DMat4::from_scale(DVec3::new(5.0, 2.0, 3.0));
        let t = UvTransform::from_mat4(&m);
        assert_eq!(t.apply(Vec2::new(1.0, 1.0)), Vec2::new(5.25, 1.0));
        assert_eq!(t.apply(Vec2::ZERO), Vec2::new(0.25, -1.0));
        let r = UvTransform::from_mat4(&DMat4::from_rotation_z(std::f64::consts::FRAC_PI_2));
        let p = r.apply(Vec2::new(1.0, 0.0));
        assert!((p - Vec2::new(0.0, 1.0)).length() < 1e-6, "{p}");
        assert_eq!(
            UvTransform::default().apply(Vec2::new(0.3, 0.7)),
            Vec2::new(0.3, 0.7)
        );
    }
}
