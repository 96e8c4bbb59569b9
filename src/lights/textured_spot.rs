//! A `spot` light with a `texture` (Mitsuba 3's `src/emitters/spot.cpp`): the image is
//! projected through the cone. Towards unit direction `d` (from the light) the
//! intensity is `I * T(uv) * falloff(d)`, with `l = to_world^-1 d` in the light's frame
//! and `uv = (0.5 + 0.5 l.x / (l.z tan(cutoff)), 0.5 + 0.5 l.y / (l.z tan(cutoff)))`
//! (`direction_to_uv`): the unit square spans the cone's tangent-plane square, so
//! the image's border circle touches the cutoff. The falloff is the untextured spot's
//! (`Spot::falloff`); a direction with falloff 0 reads no texel.

use super::{LightSample, Spot};
use crate::math::Rgb;
use crate::textures::Texture;
use glam::{Mat3, Vec2, Vec3};

#[derive(Clone, Debug)]
pub struct TexturedSpot {
    pub position: Vec3,
    pub intensity: Rgb,
    pub spot: Spot,
    /// Spatially varying (`Texture::is_spatially_varying`), as Mitsuba requires.
    pub texture: Texture,
    /// The inverse of to_world's linear part.
    pub to_local: Mat3,
    /// `tan(cutoff)`.
    pub uv_factor: f32,
}

impl TexturedSpot {
    /// Mitsuba's `direction_to_uv` of direction `d` (from the light, world space).
    #[inline]
    pub fn uv(&self, d: Vec3) -> Vec2 {
        let l = self.to_local * d;
        Vec2::new(
            0.5 + 0.5 * l.x / (l.z * self.uv_factor),
            0.5 + 0.5 * l.y / (l.z * self.uv_factor),
        )
    }

    /// The light's connection to `x` (a delta light: `pdf` is the choice probability).
    #[inline]
    pub fn sample(&self, x: Vec3, select_pdf: f32) -> Option<LightSample> {
        let d = self.position - x;
        let dist2 = d.length_squared();
        if dist2 <= 0.0 {
            return None;
        }
        let dist = dist2.sqrt();
        let wi = d / dist;
        let falloff = self.spot.falloff(-wi);
        if falloff <= 0.0 {
            return None;
        }
        let t = self.texture.eval_rgb(self.uv(-wi));
        Some(LightSample {
            p: self.position,
            n: Vec3::ZERO,
            wi,
            dist,
            li: self.intensity * t * (falloff / dist2),
            pdf: select_pdf,
            delta: true,
        })
    }
}
