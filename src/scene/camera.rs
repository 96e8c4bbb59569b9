//! `perspective` sensor: a pinhole camera (Mitsuba 3's semantics).
//!
//! | parameter | type | default | meaning |
//! |-----------|------|---------|---------|
//! | fov | float | required | field of view in degrees |
//! | fov_axis | string | x | which extent fov spans: x, y, smaller, larger, diagonal |
//! | near_clip, far_clip | float | 0.01, 10000 | accepted; rays start at the pinhole (SPEC 2) |
//! | to_world | transform | identity | camera to world; the camera looks along +z, +y up |
//! | film, sampler | nested | — | `transient_hdr_film`, `independent` |
//!
//! Image row 0 is the top; column 0 is the camera's +x ("left" in Mitsuba's look-at),
//! so the image is not mirrored.

use glam::{DMat4, Vec3};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FovAxis {
    X,
    Y,
    Smaller,
    Larger,
    Diagonal,
}

impl FovAxis {
    pub fn parse(s: &str) -> Option<Self> {
        Some(match s {
            "x" => FovAxis::X,
            "y" => FovAxis::Y,
            "smaller" => FovAxis::Smaller,
            "larger" => FovAxis::Larger,
            "diagonal" => FovAxis::Diagonal,
            _ => return None,
        })
    }
}

#[derive(Clone, Debug)]
pub struct Camera {
    pub origin: Vec3,
    /// Camera axes in world space: left (+x local), up (+y), forward (+z).
    pub axes: [Vec3; 3],
    /// tan of the half field of view along x and y.
    pub tan_half: [f32; 2],
    pub width: usize,
    pub height: usize,
}

impl Camera {
    pub fn new(to_world: DMat4, fov_deg: f64, axis: FovAxis, width: usize, height: usize) -> Self {
        let (w, h) = (width as f64, height as f64);
        let t = (fov_deg.to_radians() * 0.5).tan();
        let (tx, ty) = match axis {
            FovAxis::X => (t, t * h / w),
            FovAxis::Y => (t * w / h, t),
            FovAxis::Smaller if w <= h => (t, t * h / w),
            FovAxis::Smaller => (t * w / h, t),
            FovAxis::Larger if w >= h => (t, t * h / w),
            FovAxis::Larger => (t * w / h, t),
            FovAxis::Diagonal => {
                let d = (w * w + h * h).sqrt();
                (t * w / d, t * h / d)
            }
        };
        let axis = |v: glam::DVec3| to_world.transform_vector3(v).normalize().as_vec3();
        Camera {
            origin: to_world.transform_point3(glam::DVec3::ZERO).as_vec3(),
            axes: [
                axis(glam::DVec3::X),
                axis(glam::DVec3::Y),
                axis(glam::DVec3::Z),
            ],
            tan_half: [tx as f32, ty as f32],
            width,
            height,
        }
    }

    /// Unit direction through film position (x, y) in pixels (x right, y down).
    #[inline]
    pub fn direction(&self, x: f32, y: f32) -> Vec3 {
        let sx = (1.0 - 2.0 * x / self.width as f32) * self.tan_half[0];
        let sy = (1.0 - 2.0 * y / self.height as f32) * self.tan_half[1];
        (self.axes[0] * sx + self.axes[1] * sy + self.axes[2]).normalize()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::transform::look_at;
    use glam::DVec3;

    #[test]
    fn corners_span_the_field_of_view() {
        let m = look_at(DVec3::new(0.0, 0.0, 5.0), DVec3::ZERO, DVec3::Y).unwrap();
        let cam = Camera::new(m, 90.0, FovAxis::X, 200, 100);
        let c = cam.direction(100.0, 50.0);
        assert!((c - Vec3::new(0.0, 0.0, -1.0)).length() < 1e-6);
        // Left edge of the image looks 45 degrees to world -x (camera left).
        let l = cam.direction(0.0, 50.0);
        assert!((l.x + std::f32::consts::FRAC_1_SQRT_2).abs() < 1e-6 && l.y.abs() < 1e-6);
        // Top row looks up: tan = 0.5 along y for a 2:1 image.
        let t = cam.direction(100.0, 0.0);
        assert!((t.y / -t.z - 0.5).abs() < 1e-6);
        // fov_axis smaller on a wide image spans y.
        let cam = Camera::new(m, 90.0, FovAxis::Smaller, 200, 100);
        assert!((cam.tan_half[1] - 1.0).abs() < 1e-6 && (cam.tan_half[0] - 2.0).abs() < 1e-6);
    }
}
