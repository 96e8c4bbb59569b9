//! Textures: values that vary over a surface, looked up at the hit's uv coordinates
//! (`Shape::uv`). A material parameter that accepts a texture holds a [`Texture`]; a
//! plain colour is [`Texture::Constant`], so untextured scenes pay one `match`.
//!
//! | plugin | file | what it is |
//! |--------|------|------------|
//! | `bitmap` | `bitmap.rs` (lookup), `image_file.rs` (decoding) | an image: PNG, JPEG, BMP, Radiance HDR, OpenEXR |
//! | `checkerboard` | `checkerboard.rs` | two colours in a 2 x 2 pattern per unit square of uv |
//!
//! Both take `to_uv` ([`UvTransform`]). The XML side lives in `scene::textures`.

pub mod bitmap;
pub mod checkerboard;
pub mod image_file;
pub mod uv_transform;

pub use bitmap::{Bitmap, FilterType, WrapMode};
pub use checkerboard::Checkerboard;
pub use uv_transform::UvTransform;

use glam::{Vec2, Vec3};
use std::sync::Arc;

/// A spatially varying (or constant) value over a surface.
#[derive(Clone, Debug, PartialEq)]
pub enum Texture {
    /// The same linear RGB everywhere (a plain `<rgb>` or `<float>` parameter).
    Constant(Vec3),
    /// An image; shared, since one `<texture id>` may be referenced many times.
    Bitmap(Arc<Bitmap>),
    Checkerboard(Checkerboard),
}

/// Mitsuba's luminance of linear sRGB (Rec. 709 primaries, D65): the weights of
/// `mitsuba/core/spectrum.h`'s `luminance` for RGB variants.
#[inline]
pub fn luminance(c: Vec3) -> f32 {
    c.x * 0.212671 + c.y * 0.715160 + c.z * 0.072169
}

impl Texture {
    /// The linear RGB value at `uv`.
    #[inline]
    pub fn eval_rgb(&self, uv: Vec2) -> Vec3 {
        match self {
            Texture::Constant(c) => *c,
            Texture::Bitmap(b) => b.eval_rgb(uv),
            Texture::Checkerboard(c) => c.eval_rgb(uv),
        }
    }

    /// A scalar value at `uv` (roughness, opacity, ...): a one-channel image's value,
    /// else the luminance of the colour, as Mitsuba's `eval_1`.
    #[inline]
    pub fn eval_float(&self, uv: Vec2) -> f32 {
        match self {
            Texture::Constant(c) => luminance(*c),
            Texture::Bitmap(b) => b.eval_float(uv),
            Texture::Checkerboard(c) => c.eval_float(uv),
        }
    }

    /// Mitsuba's `eval_1_grad`: the gradient of the scalar lookup [`Self::eval_float`]
    /// with respect to (u, v), for `bumpmap`. Constants have none; a bitmap's is that of
    /// its bilinear interpolation (zero for `nearest`, as Mitsuba); a checkerboard's is
    /// its cell's colour's (its cells are constant almost everywhere; Mitsuba 3.9.1
    /// implements the gradient for bitmaps only and refuses the others).
    #[inline]
    pub fn eval_1_grad(&self, uv: Vec2) -> Vec2 {
        match self {
            Texture::Constant(_) => Vec2::ZERO,
            Texture::Bitmap(b) => b.eval_1_grad(uv),
            Texture::Checkerboard(c) => c.eval_1_grad(uv),
        }
    }

    /// Mitsuba's `Texture::mean`: the average over the texture's domain of all its
    /// channels (a constant's channel mean, a bitmap's texel mean, a checkerboard's
    /// colours' average), as sampling weights use it.
    pub fn mean(&self) -> f32 {
        match self {
            Texture::Constant(c) => c.element_sum() / 3.0,
            Texture::Bitmap(b) => b.mean(),
            Texture::Checkerboard(c) => 0.5 * (c.color0.mean() + c.color1.mean()),
        }
    }

    /// The texture does not vary over the surface: callers may skip computing uv.
    pub fn is_constant(&self) -> bool {
        matches!(self, Texture::Constant(_))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constants_ignore_uv_and_reduce_to_luminance() {
        let t = Texture::Constant(Vec3::new(0.2, 0.4, 0.6));
        assert!(t.is_constant());
        assert_eq!(t.eval_rgb(Vec2::new(7.0, -3.0)), Vec3::new(0.2, 0.4, 0.6));
        let l = 0.2 * 0.212671 + 0.4 * 0.715160 + 0.6 * 0.072169;
        assert!((t.eval_float(Vec2::ZERO) - l).abs() < 1e-7);
        // The weights sum to one: a grey keeps its value.
        assert!((luminance(Vec3::splat(0.3)) - 0.3).abs() < 1e-6);
    }
}
