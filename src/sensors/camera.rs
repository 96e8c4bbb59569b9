//! Sensors: `perspective` (a pinhole), `thinlens` (a pinhole's projection through a
//! circular lens with depth of field) and `orthographic`, with Mitsuba 3's semantics
//! (`src/sensors/{perspective,thinlens,orthographic}.cpp`).
//!
//! | parameter | sensors | type | default | meaning |
//! |-----------|---------|------|---------|---------|
//! | fov | perspective, thinlens | float | — | field of view in degrees (or `focal_length`) |
//! | focal_length | perspective, thinlens | string | 50mm | 35 mm equivalent, on the diagonal |
//! | fov_axis | perspective, thinlens | string | x | which extent fov spans: x, y, smaller, larger, diagonal |
//! | aperture_radius | thinlens | float | required | lens radius in scene units (0: Mitsuba's 2^-24, with a warning) |
//! | focus_distance | thinlens | float | far_clip | distance from the lens to the plane in focus (ignored by perspective) |
//! | near_clip, far_clip | all | float | 0.01, 10000 | accepted; rays start at the camera's origin plane (below) |
//! | to_world | all | transform | identity | camera to world; the camera looks along +z, +y up; thinlens refuses scale (as Mitsuba); orthographic: its x and y scale set the view extent |
//! | film, sampler | all | nested | — | `transient_hdr_film`, `independent` |
//!
//! Image row 0 is the top; column 0 is the camera's +x ("left" in Mitsuba's look-at),
//! so the image is not mirrored.
//!
//! Where a camera ray starts, which is where its path's OPL starts (SPEC 2; Mitsuba
//! starts every camera ray on the near-clip plane instead, and mitransient counts the
//! camera segment from there unless `camera_unwarp` drops it):
//! - perspective: the pinhole;
//! - thinlens: the sampled point on the lens (the local plane z = 0), so the camera
//!   segment is the distance from the lens to the first hit;
//! - orthographic: the point of the sensor plane (local z = 0) the pixel sample maps
//!   to, local (1 - 2 x / W, (1 - 2 y / H) H / W, 0), as Mitsuba's `[-1, 1]` across the
//!   film width: every ray of a plane perpendicular to the view arrives at one OPL.
//!
//! The thin lens's aperture sample comes from its own random stream per path
//! (`Pcg32::for_path` of a salted seed), so a thinlens path draws the same other random
//! numbers as the perspective path of the same pixel and sample.

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

/// How a film position becomes a ray (the sensor plugin).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Projection {
    /// `perspective`: rays from the pinhole `Camera::origin`.
    Pinhole,
    /// `thinlens`: rays from a uniform point of the lens disk of radius
    /// `aperture_radius` towards the pinhole ray's point at depth `focus_distance`.
    ThinLens {
        aperture_radius: f32,
        focus_distance: f32,
    },
    /// `orthographic`: parallel rays along `Camera::axes[2]` from the sensor plane;
    /// `extent` holds the world images of the local x and y axes (to_world's columns,
    /// with their scale), so local (sx, sy, 0) is `origin + extent[0] sx + extent[1] sy`.
    Orthographic { extent: [Vec3; 2] },
    /// `nlos_capture_meter`: from `Camera::origin` (`sensor_origin`) towards the centre
    /// of the relay wall's grid cell of the film position (`scene/nlos.rs`); film row
    /// `r` is sensor row `r % grid_height` (exhaustive scans stack one image per laser
    /// point).
    Meter {
        wall: crate::sensors::relay_wall::Wall,
        grid_height: usize,
    },
}

/// Salt of the seed for the thin lens's aperture stream (see the module notes).
pub const LENS_STREAM_SALT: u64 = 0x6c65_6e73_5f61_7074;

#[derive(Clone, Debug)]
pub struct Camera {
    pub origin: Vec3,
    /// Camera axes in world space: left (+x local), up (+y), forward (+z).
    pub axes: [Vec3; 3],
    /// tan of the half field of view along x and y (perspective and thinlens).
    pub tan_half: [f32; 2],
    pub width: usize,
    pub height: usize,
    pub projection: Projection,
}

impl Camera {
    /// A `perspective` camera.
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
            projection: Projection::Pinhole,
        }
    }

    /// A `thinlens` camera: the perspective camera's projection seen through a lens.
    pub fn thin_lens(
        to_world: DMat4,
        fov_deg: f64,
        axis: FovAxis,
        width: usize,
        height: usize,
        aperture_radius: f32,
        focus_distance: f32,
    ) -> Self {
        Camera {
            projection: Projection::ThinLens {
                aperture_radius,
                focus_distance,
            },
            ..Camera::new(to_world, fov_deg, axis, width, height)
        }
    }

    /// An `orthographic` camera: the local square [-1, 1] across the film's width (and
    /// [-H/W, H/W] along its height) mapped by `to_world`, viewing along its +z.
    pub fn orthographic(to_world: DMat4, width: usize, height: usize) -> Self {
        let column = |v: glam::DVec3| to_world.transform_vector3(v).as_vec3();
        let mut cam = Camera::new(to_world, 90.0, FovAxis::X, width, height);
        cam.tan_half = [1.0, (height as f64 / width as f64) as f32];
        cam.projection = Projection::Orthographic {
            extent: [column(glam::DVec3::X), column(glam::DVec3::Y)],
        };
        cam
    }

    /// An `nlos_capture_meter` at `origin` measuring a `width` x `grid_height` grid of
    /// `wall`, in a film `height` rows tall.
    pub fn meter(
        origin: Vec3,
        wall: crate::sensors::relay_wall::Wall,
        width: usize,
        height: usize,
        grid_height: usize,
    ) -> Self {
        Camera {
            origin,
            axes: [Vec3::X, Vec3::Y, Vec3::Z],
            tan_half: [1.0, 1.0],
            width,
            height,
            projection: Projection::Meter { wall, grid_height },
        }
    }

    /// Unit direction of the pinhole ray through film position (x, y) in pixels (x
    /// right, y down).
    #[inline]
    pub fn direction(&self, x: f32, y: f32) -> Vec3 {
        let sx = (1.0 - 2.0 * x / self.width as f32) * self.tan_half[0];
        let sy = (1.0 - 2.0 * y / self.height as f32) * self.tan_half[1];
        (self.axes[0] * sx + self.axes[1] * sy + self.axes[2]).normalize()
    }

    /// The camera ray (origin, unit direction) through film position (x, y); `lens`
    /// gives the aperture sample, called only by the thin lens. A perspective ray is
    /// `(origin, direction(x, y))`, the same bits.
    #[inline]
    pub fn ray(&self, x: f32, y: f32, lens: impl FnOnce() -> [f32; 2]) -> (Vec3, Vec3) {
        match self.projection {
            Projection::Pinhole => (self.origin, self.direction(x, y)),
            Projection::ThinLens {
                aperture_radius,
                focus_distance,
            } => self.thin_lens_ray(x, y, aperture_radius, focus_distance, lens()),
            Projection::Orthographic { extent } => {
                let sx = 1.0 - 2.0 * x / self.width as f32;
                let sy = (1.0 - 2.0 * y / self.height as f32) * self.tan_half[1];
                (self.origin + extent[0] * sx + extent[1] * sy, self.axes[2])
            }
            Projection::Meter { wall, grid_height } => {
                // mitransient's meter: the cell's centre, whatever the sub-pixel sample.
                let px = (x.max(0.0) as usize).min(self.width - 1);
                let py = (y.max(0.0) as usize).min(self.height - 1) % grid_height;
                let p = wall.grid_point(px, py, self.width, grid_height);
                (self.origin, (p - self.origin).normalize())
            }
        }
    }

    /// Mitsuba's thin lens (`thinlens.cpp`, `sample_ray`): in camera space the film
    /// point's pinhole ray meets the focal plane z = focus_distance at
    /// `focus_distance (sx, sy, 1)`; the ray leaves the lens point
    /// `aperture_radius concentric_disk(u)` towards it.
    #[inline(never)]
    fn thin_lens_ray(&self, x: f32, y: f32, radius: f32, focus: f32, u: [f32; 2]) -> (Vec3, Vec3) {
        let sx = (1.0 - 2.0 * x / self.width as f32) * self.tan_half[0];
        let sy = (1.0 - 2.0 * y / self.height as f32) * self.tan_half[1];
        let [ax, ay] = crate::math::sampling::concentric_disk(u);
        let (ax, ay) = (ax * radius, ay * radius);
        let local = Vec3::new(sx * focus - ax, sy * focus - ay, focus).normalize();
        let to_world = |v: Vec3| self.axes[0] * v.x + self.axes[1] * v.y + self.axes[2] * v.z;
        let o = self.origin + self.axes[0] * ax + self.axes[1] * ay;
        (o, to_world(local).normalize())
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
