//! Textures: values that vary over a surface, looked up at the hit's uv coordinates
//! (`Shape::uv`). A material parameter that accepts a texture holds a [`Texture`]; a
//! plain colour is [`Texture::Constant`], so untextured scenes pay one `match`.
//!
//! | plugin | file | what it is |
//! |--------|------|------------|
//! | `bitmap` | `bitmap.rs` (lookup), `image_file.rs` (decoding), `jpeg.rs` (JPEG as libjpeg) | an image: PNG, JPEG, BMP, Radiance HDR, OpenEXR |
//! | `checkerboard` | `checkerboard.rs` | two colours in a 2 x 2 pattern per unit square of uv |
//! | `mesh_attribute` | `mesh_attribute.rs` | a mesh's per-vertex or per-face attribute (from its PLY file) |
//! | `rawconstant` | (a [`Texture::Constant`]) | a value used as it is, 1 or 3 channels |
//!
//! `bitmap` and `checkerboard` take `to_uv` ([`UvTransform`]). The XML side lives in
//! `scene::textures`. Material textures are looked up at a [`TexPoint`] (uv plus the
//! hit's triangle, for `mesh_attribute`; [`TexPoint::on`] a shape); every other user of a texture has uv only
//! and refuses `mesh_attribute` when the scene is parsed.

pub mod bitmap;
pub mod checkerboard;
pub mod image_file;
pub mod jpeg;
pub mod mesh_attribute;
pub mod uv_transform;

pub use bitmap::{Bitmap, FilterType, WrapMode};
pub use checkerboard::Checkerboard;
pub use image_file::ImageFileError;
pub use mesh_attribute::MeshAttributeTexture;
pub use uv_transform::UvTransform;

use crate::geometry::mesh_attributes::MeshAttributes;
use crate::geometry::shape::{Shape, ShapeGeom};
use glam::{Vec2, Vec3};
use std::sync::Arc;

/// Where a material's texture is looked up: the hit's uv and, for `mesh_attribute`,
/// the mesh's attributes (if any), the triangle (index and vertex indices) and the
/// barycentrics (b1, b2) on it. [`TexPoint::on`] builds it.
#[derive(Clone, Copy, Debug)]
pub struct TexPoint<'a> {
    pub uv: Vec2,
    pub attributes: Option<&'a MeshAttributes>,
    pub face: u32,
    pub tri: [u32; 3],
    pub b1: f32,
    pub b2: f32,
}

impl TexPoint<'_> {
    /// A point known by its uv only (no mesh attributes).
    pub fn uv(uv: Vec2) -> Self {
        TexPoint {
            uv,
            attributes: None,
            face: 0,
            tri: [0; 3],
            b1: 0.0,
            b2: 0.0,
        }
    }

    /// Where a material's textures are looked up at barycentrics (b1, b2) of triangle
    /// `face` of `shape` (or at `p` on an analytic shape): uv ([`Shape::uv`]) and, on a
    /// mesh with attributes, those with the triangle's vertices.
    #[inline]
    pub fn on(shape: &Shape, face: u32, b1: f32, b2: f32, p: Vec3) -> TexPoint<'_> {
        let uv = shape.uv(face, b1, b2, p);
        match &shape.geom {
            ShapeGeom::Mesh {
                attributes: Some(a),
                triangles,
                ..
            } => TexPoint {
                uv,
                attributes: Some(a),
                face,
                tri: triangles[face as usize],
                b1,
                b2,
            },
            _ => TexPoint::uv(uv),
        }
    }
}

/// A spatially varying (or constant) value over a surface.
#[derive(Clone, Debug, PartialEq)]
pub enum Texture {
    /// The same linear RGB everywhere (a plain `<rgb>` or `<float>` parameter).
    Constant(Vec3),
    /// An image; shared, since one `<texture id>` may be referenced many times.
    Bitmap(Arc<Bitmap>),
    Checkerboard(Checkerboard),
    /// A mesh attribute (needs a [`TexPoint`]: [`Self::eval_rgb_at`]).
    MeshAttribute(MeshAttributeTexture),
}

/// Mitsuba's luminance of linear sRGB (Rec. 709 primaries, D65): the weights of
/// `mitsuba/core/spectrum.h`'s `luminance` for RGB variants.
#[inline]
pub fn luminance(c: Vec3) -> f32 {
    c.x * 0.212671 + c.y * 0.715160 + c.z * 0.072169
}

impl Texture {
    /// The resolution Mitsuba's `Texture::resolution` reports: an image's size, else 1 x 1.
    pub fn resolution(&self) -> (usize, usize) {
        match self {
            Texture::Bitmap(b) => (b.width, b.height),
            Texture::Constant(_) | Texture::Checkerboard(_) | Texture::MeshAttribute(_) => (1, 1),
        }
    }

    /// Whether every value the texture can return is finite and non-negative (a mesh
    /// attribute: unknown until a mesh is bound, false; emitters refuse them first).
    pub fn non_negative(&self) -> bool {
        match self {
            Texture::Constant(c) => c.is_finite() && c.min_element() >= 0.0,
            Texture::Bitmap(b) => b.data.iter().all(|v| v.is_finite() && *v >= 0.0),
            Texture::Checkerboard(c) => c.color0.non_negative() && c.color1.non_negative(),
            Texture::MeshAttribute(_) => false,
        }
    }

    /// The largest value the texture takes (0 for mesh attributes, which emitters
    /// refuse).
    pub fn max_value(&self) -> f32 {
        match self {
            Texture::Constant(c) => c.max_element(),
            Texture::Bitmap(b) => b.data.iter().fold(0.0f32, |m, v| m.max(*v)),
            Texture::Checkerboard(c) => c.color0.max_value().max(c.color1.max_value()),
            Texture::MeshAttribute(_) => 0.0,
        }
    }

    /// Whether the texture is black everywhere (mesh attributes: unknown, false).
    pub fn is_black(&self) -> bool {
        match self {
            Texture::Constant(c) => c.max_element() == 0.0,
            Texture::Bitmap(b) => b.data.iter().all(|v| *v == 0.0),
            Texture::Checkerboard(c) => c.color0.is_black() && c.color1.is_black(),
            Texture::MeshAttribute(_) => false,
        }
    }

    /// The linear RGB value at `uv`.
    #[inline]
    pub fn eval_rgb(&self, uv: Vec2) -> Vec3 {
        match self {
            Texture::Constant(c) => *c,
            Texture::Bitmap(b) => b.eval_rgb(uv),
            Texture::Checkerboard(c) => c.eval_rgb(uv),
            // Parsing keeps mesh attributes out of every uv-only lookup; a point
            // without attributes reads 0, as Mitsuba's LLVM variants.
            Texture::MeshAttribute(_) => Vec3::ZERO,
        }
    }

    /// The linear RGB value at a surface point (material textures).
    #[inline]
    pub fn eval_rgb_at(&self, p: &TexPoint) -> Vec3 {
        match self {
            Texture::MeshAttribute(m) => m.eval_rgb(p),
            _ => self.eval_rgb(p.uv),
        }
    }

    /// Whether [`Self::eval_mapped_at`] can differ from `f` of [`Self::eval_rgb_at`]: a
    /// bilinear RGB bitmap, alone or as a checkerboard's colour.
    pub fn filters_colours(&self) -> bool {
        match self {
            Texture::Bitmap(b) => b.filters_colours(),
            Texture::Checkerboard(c) => c.color0.filters_colours() || c.color1.filters_colours(),
            Texture::Constant(_) | Texture::MeshAttribute(_) => false,
        }
    }

    /// The colour at a surface point with `f` applied to each texel before the
    /// texture filters them (`Bitmap::eval_mapped`); for what does not filter
    /// texels (constants, nearest lookups, grey images, mesh attributes), `f` of
    /// [`Self::eval_rgb_at`]. The spectral mode lifts a bitmap's texels so.
    #[inline]
    pub fn eval_mapped_at(&self, p: &TexPoint, f: &impl Fn(Vec3) -> Vec3) -> Vec3 {
        match self {
            Texture::Bitmap(b) if b.filters_colours() => b.eval_mapped(p.uv, f),
            Texture::Checkerboard(c) => c.eval_mapped(p, f),
            _ => f(self.eval_rgb_at(p)),
        }
    }

    /// The scalar value at a surface point (material textures).
    #[inline]
    pub fn eval_float_at(&self, p: &TexPoint) -> f32 {
        match self {
            Texture::MeshAttribute(m) => m.eval_float(p),
            _ => self.eval_float(p.uv),
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
            Texture::MeshAttribute(_) => 0.0,
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
            Texture::MeshAttribute(_) => Vec2::ZERO,
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
            // Mitsuba has none (NotImplementedError); parsing refuses such uses.
            Texture::MeshAttribute(_) => 0.0,
        }
    }

    /// Whether this is a `mesh_attribute` texture, or a checkerboard with one inside.
    pub fn uses_mesh_attributes(&self) -> bool {
        match self {
            Texture::MeshAttribute(_) => true,
            Texture::Checkerboard(c) => {
                c.color0.uses_mesh_attributes() || c.color1.uses_mesh_attributes()
            }
            _ => false,
        }
    }

    /// Whether the value varies over a surface's uv (Mitsuba's `is_spatially_varying`:
    /// bitmaps and checkerboards).
    pub fn is_spatially_varying(&self) -> bool {
        matches!(self, Texture::Bitmap(_) | Texture::Checkerboard(_))
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
