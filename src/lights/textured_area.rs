//! An `area` emitter whose `radiance` is a texture (`bitmap` or `checkerboard`, Mitsuba
//! 3's spatially varying radiance, `src/emitters/area.cpp`): a hit emits the texture's
//! value at the hit's uv towards the front side.
//!
//! Light samples are points uniform by area (as the untextured `area`), weighted by the
//! texture at their uv: `L(uv) cos / (pdf_A d^2)`, so that the MIS density of a hit is
//! the untextured one (`Emitter::pdf_area_hit`). Mitsuba instead draws uv from the
//! texture (`Texture::sample_position`: a bitmap's texels by value, else uniform in
//! the unit square) and maps it onto the shape (`eval_parameterization`); both are
//! unbiased estimates of the same light wherever the shape's uv covers the unit square
//! once at uniform density (rectangles, spheres, disks and uv-mapped meshes so built),
//! which is what Mitsuba's own estimate needs to be right. They differ in noise only.

use super::LightSample;
use crate::geometry::shape::{AreaSampler, Shape};
use crate::math::Rgb;
use crate::textures::Texture;
use glam::{Vec2, Vec3};

#[derive(Clone, Debug)]
pub struct TexturedArea {
    pub shape: u32,
    /// Spatially varying (`Texture::is_spatially_varying`), finite, non-negative.
    pub radiance: Texture,
    pub sampler: AreaSampler,
}

impl TexturedArea {
    /// A light sample from `x` (see the module notes).
    #[inline]
    pub fn sample(
        &self,
        shapes: &[Shape],
        x: Vec3,
        select_pdf: f32,
        u1: f32,
        u2: [f32; 2],
    ) -> Option<LightSample> {
        let shape = &shapes[self.shape as usize];
        let (s, uv) = self.sampler.sample_with_uv(shape, u1, u2);
        let (ls, _) = super::connect(s, self.sampler.total_area, x, select_pdf)?;
        Some(LightSample {
            li: self.radiance.eval_rgb(uv),
            ..ls
        })
    }

    /// The radiance emitted at a point whose uv is `uv` (front side).
    #[inline]
    pub fn emitted(&self, uv: Vec2) -> Rgb {
        self.radiance.eval_rgb(uv)
    }
}
