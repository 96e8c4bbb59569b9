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
//! | near_clip | all | float | 0.01 | where camera rays and their OPL start (below; `time_origin.rs`) |
//! | far_clip | all | float | 10000 | checked (greater than near_clip); rays are not cut there |
//! | to_world | all | transform | identity | camera to world; the camera looks along +z, +y up; thinlens refuses scale (as Mitsuba); orthographic: its x and y scale set the view extent |
//! | film, sampler | all | nested | — | `transient_hdr_film`, `independent` |
//!
//! Image row 0 is the top; column 0 is the camera's +x ("left" in Mitsuba's look-at),
//! so the image is not mirrored.
//!
//! Where a camera ray starts, which is where its path's OPL starts (SPEC 2), with the
//! time origin `Pinhole`:
//! - perspective: the pinhole;
//! - thinlens: the sampled point on the lens (the local plane z = 0), so the camera
//!   segment is the distance from the lens to the first hit;
//! - orthographic: the point of the sensor plane (local z = 0) the pixel sample maps
//!   to, local (1 - 2 x / W, (1 - 2 y / H) H / W, 0), as Mitsuba's `[-1, 1]` across the
//!   film width: every ray of a plane perpendicular to the view arrives at one OPL.
//!
//! With `NearClip` (the default, Mitsuba's `sample_ray`), the same ray starts on the
//! near-clip plane, local z = near_clip: `near_clip / d_z` along it (d_z the local
//! direction's z) for perspective and thinlens, and the local offset (0, 0, near_clip)
//! through `to_world` for orthographic. The direction is the same bits either way.
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
    /// `depth` is the world image of the local z axis (to_world's third column, with
    /// its scale): the near plane is `near_clip` of it away.
    Orthographic { extent: [Vec3; 2], depth: Vec3 },
    /// `nlos_capture_meter`: from `Camera::origin` (`sensor_origin`) towards the centre
    /// of the relay wall's grid cell of the film position (`scene/nlos_setup.rs`); film row
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
    /// The near-clip distance where rays start (time origin `NearClip`); `None`: at
    /// the camera's origin (`Pinhole`, and the meter).
    pub near_clip: Option<f32>,
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
            near_clip: None,
        }
    }

    /// The camera with its rays starting `near_clip` away on the near plane (time
    /// origin `NearClip`), or at its origin (`Pinhole`). The meter has no near plane:
    /// it is returned as it is.
    pub fn with_time_origin(self, origin: super::time_origin::TimeOrigin, near_clip: f32) -> Self {
        let near_clip = match (origin, self.projection) {
            (_, Projection::Meter { .. }) | (super::time_origin::TimeOrigin::Pinhole, _) => None,
            (super::time_origin::TimeOrigin::NearClip, _) => Some(near_clip),
        };
        Camera { near_clip, ..self }
    }

    /// The shortest and longest distance from the camera's origin to where a ray
    /// starts with the time origin `NearClip` (`near_clip / cos(theta)`, at the film's
    /// centre and corner; `near_clip` |to_world z| for orthographic), by which its
    /// arrivals are earlier than from the `Pinhole` origin; `None` when rays start at
    /// the origin.
    pub fn near_offsets(&self) -> Option<[f64; 2]> {
        let near = self.near_clip? as f64;
        Some(match self.projection {
            Projection::Orthographic { depth, .. } => [near * depth.length() as f64; 2],
            _ => {
                let [tx, ty] = self.tan_half.map(|t| t as f64);
                [near, near * (1.0 + tx * tx + ty * ty).sqrt()]
            }
        })
    }

    /// The time origin the rays use.
    pub fn time_origin(&self) -> super::time_origin::TimeOrigin {
        match self.near_clip {
            Some(_) => super::time_origin::TimeOrigin::NearClip,
            None => super::time_origin::TimeOrigin::Pinhole,
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
            depth: column(glam::DVec3::Z),
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
            near_clip: None,
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
    /// gives the aperture sample, called only by the thin lens. A perspective ray from
    /// the pinhole is `(origin, direction(x, y))`, the same bits.
    #[inline]
    pub fn ray(&self, x: f32, y: f32, lens: impl FnOnce() -> [f32; 2]) -> (Vec3, Vec3) {
        let (o, d) = match self.projection {
            Projection::Pinhole => (self.origin, self.direction(x, y)),
            Projection::ThinLens {
                aperture_radius,
                focus_distance,
            } => self.thin_lens_ray(x, y, aperture_radius, focus_distance, lens()),
            Projection::Orthographic { extent, depth } => {
                let sx = 1.0 - 2.0 * x / self.width as f32;
                let sy = (1.0 - 2.0 * y / self.height as f32) * self.tan_half[1];
                let o = self.origin + extent[0] * sx + extent[1] * sy;
                return match self.near_clip {
                    Some(near) => (o + depth * near, self.axes[2]),
                    None => (o, self.axes[2]),
                };
            }
            Projection::Meter { wall, grid_height } => {
                // mitransient's meter: the cell's centre, whatever the sub-pixel sample.
                let px = (x.max(0.0) as usize).min(self.width - 1);
                let py = (y.max(0.0) as usize).min(self.height - 1) % grid_height;
                let p = wall.grid_point(px, py, self.width, grid_height);
                return (self.origin, (p - self.origin).normalize());
            }
        };
        (self.start(o, d), d)
    }

    /// Where a perspective or thin-lens ray from `o` (the pinhole or lens point) along
    /// unit `d` starts: `o` itself, or on the near plane `near_clip / d_z` along it.
    #[inline]
    pub fn start(&self, o: Vec3, d: Vec3) -> Vec3 {
        match self.near_clip {
            // d_z = cos(theta) in camera space: the axes are orthonormal (perspective
            // and thinlens refuse scale, as Mitsuba).
            Some(near) => o + d * (near / d.dot(self.axes[2])),
            None => o,
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
    use crate::scene::to_world::look_at;
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

    /// With the near-clip origin every ray starts on the plane local z = near_clip,
    /// `near_clip / cos(theta)` along the pinhole ray, in the same direction (bits).
    #[test]
    fn near_clip_rays_start_on_the_near_plane() {
        use super::super::time_origin::TimeOrigin;
        let m = look_at(DVec3::new(1.0, 2.0, 5.0), DVec3::ZERO, DVec3::Y).unwrap();
        let pinhole = Camera::new(m, 70.0, FovAxis::X, 40, 30);
        let near = pinhole.clone().with_time_origin(TimeOrigin::NearClip, 0.75);
        assert_eq!(near.time_origin(), TimeOrigin::NearClip);
        for (x, y) in [(20.0, 15.0), (0.0, 0.0), (40.0, 30.0), (3.5, 27.25)] {
            let (o0, d0) = pinhole.ray(x, y, || unreachable!());
            let (o, d) = near.ray(x, y, || unreachable!());
            assert_eq!(o0, pinhole.origin);
            assert_eq!(d, d0);
            assert!(((o - o0).dot(pinhole.axes[2]) - 0.75).abs() < 1e-6);
            let cos = d.dot(pinhole.axes[2]);
            assert!(((o - o0).length() - 0.75 / cos).abs() < 1e-6);
            assert!(((o - o0).normalize() - d).length() < 1e-6);
        }
        let [lo, hi] = near.near_offsets().unwrap();
        assert_eq!(lo, 0.75);
        let (_, corner) = pinhole.ray(0.0, 0.0, || unreachable!());
        assert!((hi - 0.75 / corner.dot(pinhole.axes[2]) as f64).abs() < 1e-6);
        assert_eq!(pinhole.near_offsets(), None);
        // Pinhole is the camera as constructed (the same bits).
        let back = near.with_time_origin(TimeOrigin::Pinhole, 0.75);
        assert_eq!(back.near_clip, None);
        assert_eq!(
            back.ray(3.5, 27.25, || unreachable!()),
            pinhole.ray(3.5, 27.25, || unreachable!())
        );
    }

    /// The thin lens: from the lens point to the near plane along the ray; the
    /// orthographic camera: near_clip along its (scaled) z axis.
    #[test]
    fn thin_lens_and_orthographic_near_planes() {
        use super::super::time_origin::TimeOrigin;
        let m = look_at(DVec3::new(0.0, 0.0, 4.0), DVec3::ZERO, DVec3::Y).unwrap();
        let lens = Camera::thin_lens(m, 40.0, FovAxis::X, 16, 16, 0.2, 4.0);
        let near = lens.clone().with_time_origin(TimeOrigin::NearClip, 0.5);
        for u in [[0.1, 0.9], [0.5, 0.5], [0.97, 0.03]] {
            let (o0, d0) = lens.ray(2.0, 13.0, || u);
            let (o, d) = near.ray(2.0, 13.0, || u);
            assert_eq!(d, d0);
            // The lens point is on the plane z = 0; the ray starts on z = 0.5.
            assert!((o0 - lens.origin).dot(lens.axes[2]).abs() < 1e-6);
            assert!(((o - lens.origin).dot(lens.axes[2]) - 0.5).abs() < 1e-6);
            assert!(((o - o0).normalize() - d).length() < 1e-5);
        }
        let scaled = m * DMat4::from_scale(DVec3::new(2.0, 2.0, 3.0));
        let ortho = Camera::orthographic(scaled, 8, 8);
        let near = ortho.clone().with_time_origin(TimeOrigin::NearClip, 0.5);
        let (o0, d0) = ortho.ray(1.0, 6.0, || unreachable!());
        let (o, d) = near.ray(1.0, 6.0, || unreachable!());
        assert_eq!(d, d0);
        // local (0, 0, 0.5) through to_world: 1.5 along the view.
        assert!(((o - o0) - d * 1.5).length() < 1e-6);
        assert_eq!(near.near_offsets(), Some([1.5, 1.5]));
    }

    /// A meter has no near plane: it keeps its rays whatever the origin asked.
    #[test]
    fn the_meter_ignores_the_near_plane() {
        use super::super::time_origin::TimeOrigin;
        let wall = crate::sensors::relay_wall::Wall {
            corner: Vec3::new(-1.0, -1.0, 0.0),
            du: Vec3::new(2.0, 0.0, 0.0),
            dv: Vec3::new(0.0, 2.0, 0.0),
            normal: Vec3::Z,
        };
        let meter = Camera::meter(Vec3::new(0.0, 0.0, 2.0), wall, 4, 4, 4)
            .with_time_origin(TimeOrigin::NearClip, 0.5);
        assert_eq!(meter.near_clip, None);
        assert_eq!(
            meter.ray(1.5, 2.5, || unreachable!()).0,
            Vec3::new(0.0, 0.0, 2.0)
        );
    }
}
