//! `mesh_attribute`: a mesh's per-vertex or per-face attribute as a texture (Mitsuba
//! 3's `src/textures/mesh_attribute.cpp`).
//!
//! | parameter | type | default | meaning |
//! |-----------|------|---------|---------|
//! | name | string | — | the attribute: it must contain `vertex_` or `face_` |
//! | scale | float | 1 | multiplies the value |
//!
//! Values as Mitsuba 3.9.1's LLVM variants give them (`Mesh::eval_attribute*`): a
//! colour lookup (`eval`) of a 1-channel attribute is that value in every channel, of a
//! 3-channel one its RGB, of any other width 0; a scalar lookup (`eval_1`) is the value
//! of a 1-channel attribute and 0 for any other width. The data come from the mesh hit
//! ([`TexPoint::attributes`]); that every shape using the texture carries the attribute
//! is checked when the scene loads (Mitsuba's scalar variants throw, its LLVM variants
//! read 0). Not spatially varying in uv, no mean: it cannot serve as an emitter's
//! radiance, a spot's or projector's image, a checkerboard's colour, a normal or bump
//! map or a `pplastic` reflectance (each refused when parsed).

use super::TexPoint;
use glam::Vec3;
use std::sync::Arc;

#[derive(Clone, Debug, PartialEq)]
pub struct MeshAttributeTexture {
    pub name: Arc<str>,
    pub scale: f32,
}

impl MeshAttributeTexture {
    /// Mitsuba's `eval` (colour lookup).
    #[inline]
    pub fn eval_rgb(&self, p: &TexPoint) -> Vec3 {
        let Some(a) = p.attributes.and_then(|all| all.get(&self.name)) else {
            return Vec3::ZERO;
        };
        let ch = |c| a.channel(p.face, p.tri, p.b1, p.b2, c);
        match a.dim {
            1 => Vec3::splat(ch(0)),
            3 => Vec3::new(ch(0), ch(1), ch(2)),
            _ => return Vec3::ZERO,
        }
        .map(|v| v * self.scale)
    }

    /// Mitsuba's `eval_1` (scalar lookup).
    #[inline]
    pub fn eval_float(&self, p: &TexPoint) -> f32 {
        match p.attributes.and_then(|all| all.get(&self.name)) {
            Some(a) if a.dim == 1 => a.channel(p.face, p.tri, p.b1, p.b2, 0) * self.scale,
            _ => 0.0,
        }
    }
}
