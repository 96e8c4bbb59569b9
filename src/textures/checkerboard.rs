//! `checkerboard`: two colours alternating over each unit square of uv.
//!
//! | parameter | type | default | meaning |
//! |-----------|------|---------|---------|
//! | color0 | rgb, float or texture | 0.4 | one colour |
//! | color1 | rgb, float or texture | 0.2 | the other |
//! | to_uv | transform | identity | applied to uv first |
//!
//! Mitsuba's rule (`src/textures/checkerboard.cpp`): with `f = uv - floor(uv)`, and
//! `mx = f.x > 0.5`, `my = f.y > 0.5`, the colour lookup (`eval`) gives `color0` where
//! `mx == my` (the cells at [0, .5]^2 and (.5, 1)^2) and `color1` elsewhere. Its scalar
//! lookup (`eval_1`) has the opposite test (`color0` where `mx != my`); we follow
//! both as they are so that every value agrees with Mitsuba's. A colour that is itself a
//! texture is looked up at the original uv (the checkerboard's `to_uv` only places the
//! cells), as Mitsuba evaluates its nested textures at the surface interaction.

use super::{Texture, UvTransform};
use glam::{Vec2, Vec3};

#[derive(Clone, Debug, PartialEq)]
pub struct Checkerboard {
    pub color0: Box<Texture>,
    pub color1: Box<Texture>,
    pub to_uv: UvTransform,
}

impl Default for Checkerboard {
    fn default() -> Self {
        Checkerboard {
            color0: Box::new(Texture::Constant(Vec3::splat(0.4))),
            color1: Box::new(Texture::Constant(Vec3::splat(0.2))),
            to_uv: UvTransform::IDENTITY,
        }
    }
}

impl Checkerboard {
    /// Whether uv lies in a cell where both fractional parts are on the same side of 1/2.
    #[inline]
    fn same_half(&self, uv: Vec2) -> bool {
        let uv = self.to_uv.apply(uv);
        let f = uv - uv.floor();
        (f.x > 0.5) == (f.y > 0.5)
    }

    #[inline]
    pub fn eval_rgb(&self, uv: Vec2) -> Vec3 {
        if self.same_half(uv) {
            self.color0.eval_rgb(uv)
        } else {
            self.color1.eval_rgb(uv)
        }
    }

    /// [`Self::eval_rgb`] with `f` applied to the cell colour's texels before any
    /// filtering (`Texture::eval_mapped_at`).
    #[inline]
    pub fn eval_mapped(&self, p: &super::TexPoint, f: &impl Fn(Vec3) -> Vec3) -> Vec3 {
        if self.same_half(p.uv) {
            self.color0.eval_mapped_at(p, f)
        } else {
            self.color1.eval_mapped_at(p, f)
        }
    }

    /// The gradient of [`Self::eval_float`]: the cell's colour's (the cell edges are a
    /// set of measure zero).
    #[inline]
    pub fn eval_1_grad(&self, uv: Vec2) -> Vec2 {
        if self.same_half(uv) {
            self.color1.eval_1_grad(uv)
        } else {
            self.color0.eval_1_grad(uv)
        }
    }

    /// Mitsuba's `eval_1`: note the swapped cells (see the module documentation).
    #[inline]
    pub fn eval_float(&self, uv: Vec2) -> f32 {
        if self.same_half(uv) {
            self.color1.eval_float(uv)
        } else {
            self.color0.eval_float(uv)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_follow_mitsubas_rule() {
        let c = Checkerboard {
            color0: Box::new(Texture::Constant(Vec3::new(1.0, 0.0, 0.0))),
            color1: Box::new(Texture::Constant(Vec3::new(0.0, 0.0, 1.0))),
            to_uv: UvTransform::IDENTITY,
        };
        let red = Vec3::new(1.0, 0.0, 0.0);
        let blue = Vec3::new(0.0, 0.0, 1.0);
        assert_eq!(c.eval_rgb(Vec2::new(0.25, 0.25)), red);
        assert_eq!(c.eval_rgb(Vec2::new(0.75, 0.75)), red);
        assert_eq!(c.eval_rgb(Vec2::new(0.75, 0.25)), blue);
        assert_eq!(c.eval_rgb(Vec2::new(0.25, 0.75)), blue);
        // 0.5 itself is not above one half: it belongs to the lower cell.
        assert_eq!(c.eval_rgb(Vec2::new(0.5, 0.25)), red);
        // Periodic, including negative uv (floor, not truncation).
        assert_eq!(c.eval_rgb(Vec2::new(-0.25, 0.25)), blue);
        assert_eq!(c.eval_rgb(Vec2::new(-0.75, -0.75)), red);
        assert_eq!(c.eval_rgb(Vec2::new(3.25, 7.75)), blue);
        // The scalar lookup swaps the cells, as Mitsuba's eval_1 does.
        assert!((c.eval_float(Vec2::new(0.25, 0.25)) - 0.072169).abs() < 1e-7);
        assert!((c.eval_float(Vec2::new(0.75, 0.25)) - 0.212671).abs() < 1e-7);
    }

    #[test]
    fn defaults_and_to_uv_scaling() {
        let mut c = Checkerboard::default();
        assert_eq!(c.eval_rgb(Vec2::new(0.1, 0.1)), Vec3::splat(0.4));
        assert_eq!(c.eval_rgb(Vec2::new(0.6, 0.1)), Vec3::splat(0.2));
        c.to_uv.m = [[4.0, 0.0], [0.0, 4.0]];
        // uv 0.15 -> 0.6: the cell changes.
        assert_eq!(c.eval_rgb(Vec2::new(0.15, 0.1)), Vec3::splat(0.2));
        assert_eq!(c.eval_rgb(Vec2::new(0.3, 0.1)), Vec3::splat(0.4));
    }

    #[test]
    fn nested_colours_see_the_original_uv() {
        // color0 is itself a checkerboard of period 1 in uv; the outer one has period
        // 1/4 through to_uv. The inner lookup must use uv, not the outer to_uv(uv).
        let inner = Checkerboard {
            color0: Box::new(Texture::Constant(Vec3::X)),
            color1: Box::new(Texture::Constant(Vec3::Y)),
            to_uv: UvTransform::IDENTITY,
        };
        let mut c = Checkerboard {
            color0: Box::new(Texture::Checkerboard(inner)),
            ..Checkerboard::default()
        };
        c.to_uv.m = [[4.0, 0.0], [0.0, 4.0]];
        // uv (0.3, 0.1): outer cell 0 (4uv = (1.2, 0.4)); inner at (0.3, 0.1): X.
        assert_eq!(c.eval_rgb(Vec2::new(0.3, 0.1)), Vec3::X);
        // uv (0.8, 0.1) -> 4uv = (3.2, 0.4): outer cell 0; inner at (0.8, 0.1): Y.
        // (Looked up at 4uv, the inner board would give X.)
        assert_eq!(c.eval_rgb(Vec2::new(0.8, 0.1)), Vec3::Y);
        // Scalar lookups nest the same way (swapped cells at both levels): at
        // (0.15, 0.1) the outer cells differ (4uv = (0.6, 0.4)) -> color0, whose own
        // cells agree at (0.15, 0.1) -> its color1, Y: luminance 0.715160.
        assert!((c.eval_float(Vec2::new(0.15, 0.1)) - 0.715160).abs() < 1e-6);
        // Where the outer cells agree, color1 = 0.2 (a grey keeps its value).
        assert!((c.eval_float(Vec2::new(0.05, 0.05)) - 0.2).abs() < 1e-6);
    }
}
