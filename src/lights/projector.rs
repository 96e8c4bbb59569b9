//! Mitsuba 3's `projector` (`src/emitters/projector.cpp`): a delta-position light that
//! projects an image through a perspective frustum, the reciprocal of the
//! `perspective` camera.
//!
//! | parameter | type | default | meaning |
//! |-----------|------|---------|---------|
//! | irradiance | rgb/float/spectrum or texture | 1 | E: irradiance on the virtual image plane at local z = 1 |
//! | scale | float | 1 | s, multiplies the irradiance |
//! | fov | float | — | degrees, in (0, 180), on `fov_axis` |
//! | fov_axis | string | x | x, y, smaller, larger, diagonal (of the texture's aspect) |
//! | focal_length | string | 50mm | instead of `fov` (35 mm equivalent, on the diagonal) |
//! | to_world | transform | identity | projector to world: the light sits at its origin and shines along local +z |
//!
//! The frustum is the camera's for a film of the irradiance texture's resolution
//! (W x H; 1 x 1 for constants and checkerboards, as Mitsuba's `Texture::resolution`):
//! aspect a = W / H, `fov` turned into the x field of view by Mitsuba's `parse_fov`,
//! t = tan(fov_x / 2). A point with local coordinates (x, y, z), z > 0, receives the
//! texel at
//!
//! ```text
//!   u = (1 - x / (z t)) / 2,   v = (1 - a y / (z t)) / 2
//! ```
//!
//! (`perspective_projection`), and nothing unless (u, v) lies in [0, 1]^2: u = 0 is the
//! local +x side (Mitsuba's look-at "left"), v = 0 the local +y side (up), and v = 0
//! is the image's first row, so the image lands as seen from behind the projector,
//! unmirrored, as the `perspective` camera films it. The radiance a point receives
//! from the light along the connection (its `sample_direction` weight) is
//!
//! ```text
//!   Li = E(u, v) * pi * s / (z^2 * cos),   cos = n . (x_world - p) / |x_world - p|
//! ```
//!
//! with n = `to_world` applied to the vector (0, 0, 1), not normalised, as Mitsuba
//! does. For a rigid `to_world`, z = d cos, so the intensity is
//! `I = pi s E / cos^3` and a plane facing the projector at distance d (local z = d)
//! receives the irradiance `I cos / (d / cos)^2 = pi s E(u, v) / d^2` everywhere: a
//! diffuse white plane at d = 1 shows radiance s E. The image-area normalisation
//! Mitsuba computes (`m_sensor_area`) enters only its `sample_ray` (light tracing),
//! which a path tracer never calls.

use super::LightSample;
use crate::math::Rgb;
use crate::textures::Texture;
use glam::{Mat4, Vec2, Vec3};

#[derive(Clone, Debug)]
pub struct Projector {
    /// The light's position (to_world's origin).
    pub position: Vec3,
    /// World to projector space (the inverse of to_world).
    pub to_local: Mat4,
    /// to_world applied to (0, 0, 1): Mitsuba's `ds.n`, not normalised.
    pub axis: Vec3,
    /// 1 / t, t = tan(fov_x / 2).
    pub inv_tan_half: f32,
    /// a = W / H of the irradiance texture.
    pub aspect: f32,
    pub irradiance: Texture,
    pub scale: f32,
}

impl Projector {
    /// (u, v) of the texel a point in projector space receives, when it lies in the
    /// frustum (z > 0, (u, v) in [0, 1]^2).
    #[inline]
    pub fn uv(&self, local: Vec3) -> Option<Vec2> {
        if local.z.is_nan() || local.z <= 0.0 {
            return None;
        }
        let k = self.inv_tan_half / local.z;
        let u = 0.5 - 0.5 * (local.x * k);
        let v = 0.5 - 0.5 * (self.aspect * local.y * k);
        ((0.0..=1.0).contains(&u) && (0.0..=1.0).contains(&v)).then_some(Vec2::new(u, v))
    }

    /// The connection from `x` to the light; `select_pdf` is the probability of having
    /// chosen it. None outside the frustum or where the texture is black.
    #[inline]
    pub fn sample(&self, x: Vec3, select_pdf: f32) -> Option<LightSample> {
        let local = self.to_local.transform_point3(x);
        let uv = self.uv(local)?;
        let d = self.position - x;
        let dist2 = d.length_squared();
        if dist2 <= 0.0 {
            return None;
        }
        let dist = dist2.sqrt();
        let wi = d / dist;
        let cos = -self.axis.dot(wi);
        if cos.is_nan() || cos <= 0.0 {
            return None;
        }
        let e = self.irradiance.eval_rgb(uv);
        let li = e * (std::f32::consts::PI * self.scale / (local.z * local.z * cos));
        if li == Rgb::ZERO {
            return None;
        }
        Some(LightSample {
            p: self.position,
            n: Vec3::ZERO,
            wi,
            dist,
            li,
            pdf: select_pdf,
            delta: true,
        })
    }

    /// The x field of view's half tangent t and the aspect a of a projector whose
    /// texture is `width` x `height`, from `fov` degrees on `axis`, as Mitsuba's
    /// `parse_fov` (which resolves `smaller`/`larger` by aspect > 1).
    pub fn frustum(
        fov_deg: f64,
        axis: crate::sensors::camera::FovAxis,
        width: usize,
        height: usize,
    ) -> (f64, f64) {
        use crate::sensors::camera::FovAxis;
        let a = width as f64 / height as f64;
        let t = (0.5 * fov_deg.to_radians()).tan();
        let axis = match axis {
            FovAxis::Smaller if a > 1.0 => FovAxis::Y,
            FovAxis::Smaller => FovAxis::X,
            FovAxis::Larger if a > 1.0 => FovAxis::X,
            FovAxis::Larger => FovAxis::Y,
            other => other,
        };
        let tx = match axis {
            FovAxis::Y => t * a,
            FovAxis::Diagonal => t / (1.0 + 1.0 / (a * a)).sqrt(),
            _ => t,
        };
        (tx, a)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::to_world::look_at;
    use crate::sensors::camera::FovAxis;
    use glam::DVec3;

    fn projector(irradiance: Texture, fov: f64, w: usize, h: usize) -> Projector {
        let m = look_at(DVec3::new(0.0, 0.0, 2.0), DVec3::ZERO, DVec3::Y).unwrap();
        let (t, a) = Projector::frustum(fov, FovAxis::X, w, h);
        Projector {
            position: Vec3::new(0.0, 0.0, 2.0),
            to_local: m.inverse().as_mat4(),
            axis: m.transform_vector3(DVec3::Z).as_vec3(),
            inv_tan_half: (1.0 / t) as f32,
            aspect: a as f32,
            irradiance,
            scale: 1.5,
        }
    }

    #[test]
    fn a_plane_facing_it_receives_pi_s_e_over_d_squared() {
        let p = projector(Texture::Constant(Vec3::new(1.0, 2.0, 3.0)), 60.0, 1, 1);
        // The plane z = 0 is at d = 2; irradiance = Li * cos(plane normal, wi).
        for x in [
            Vec3::ZERO,
            Vec3::new(0.5, -0.3, 0.0),
            Vec3::new(-1.1, 1.0, 0.0),
        ] {
            let ls = p.sample(x, 1.0).unwrap();
            let e = ls.li * ls.wi.z;
            let want = Vec3::new(1.0, 2.0, 3.0) * (std::f32::consts::PI * 1.5 / 4.0);
            assert!(
                (e - want).abs().max_element() < 1e-5 * want.max_element(),
                "{e} {want}"
            );
            assert!(ls.delta && (ls.dist - (x - p.position).length()).abs() < 1e-6);
        }
        // Outside the square frustum (tan 30 deg * 2 = 1.1547 at the plane), nothing;
        // behind the projector, nothing.
        assert!(p.sample(Vec3::new(1.2, 0.0, 0.0), 1.0).is_none());
        assert!(p.sample(Vec3::new(0.0, 1.2, 0.0), 1.0).is_none());
        assert!(p.sample(Vec3::new(0.0, 0.0, 3.0), 1.0).is_none());
    }

    #[test]
    fn fov_axes_follow_mitsubas_parse_fov() {
        let deg = |t: f64| 2.0 * t.atan().to_degrees();
        // 2:1 texture: x = fov; y spans the height; diagonal; smaller = y; larger = x.
        assert!((deg(Projector::frustum(40.0, FovAxis::X, 200, 100).0) - 40.0).abs() < 1e-9);
        let y = Projector::frustum(40.0, FovAxis::Y, 200, 100).0;
        assert!((y - 2.0 * 20f64.to_radians().tan()).abs() < 1e-12);
        assert_eq!(Projector::frustum(40.0, FovAxis::Smaller, 200, 100).0, y);
        assert_eq!(
            Projector::frustum(40.0, FovAxis::Larger, 200, 100).0,
            Projector::frustum(40.0, FovAxis::X, 200, 100).0
        );
        let d = Projector::frustum(40.0, FovAxis::Diagonal, 200, 100).0;
        // The diagonal half-tangent is tan 20 deg.
        assert!(((d * d + (d / 2.0) * (d / 2.0)).sqrt() - 20f64.to_radians().tan()).abs() < 1e-12);
        // 1:2 texture: smaller = x, larger = y.
        assert_eq!(
            Projector::frustum(40.0, FovAxis::Smaller, 100, 200).0,
            Projector::frustum(40.0, FovAxis::X, 100, 200).0
        );
        assert_eq!(
            Projector::frustum(40.0, FovAxis::Larger, 100, 200).0,
            Projector::frustum(40.0, FovAxis::Y, 100, 200).0
        );
    }

    #[test]
    fn corners_of_the_image_land_left_and_up() {
        // A 2 x 1 texture: the left texel (u < 1/2) lights local +x (look-at left).
        let p = projector(Texture::Constant(Vec3::ONE), 60.0, 2, 1);
        let to_local = |x: Vec3| p.to_local.transform_point3(x);
        // Looking from (0, 0, 2) to the origin with up +y, "left" is world -x... the
        // look-at's local +x is cross(up, dir) = cross(+y, -z) = -x.
        let uv = p.uv(to_local(Vec3::new(-0.5, 0.1, 0.0))).unwrap();
        assert!(uv.x < 0.5 && uv.y < 0.5, "{uv}");
        let uv = p.uv(to_local(Vec3::new(0.5, -0.1, 0.0))).unwrap();
        assert!(uv.x > 0.5 && uv.y > 0.5, "{uv}");
    }
}
