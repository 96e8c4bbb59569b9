//! `bitmap`: an image looked up at uv, with Mitsuba 3's conventions
//! (`src/textures/bitmap.cpp`, and Dr.Jit's `include/drjit/texture_impl.h` for the
//! lookup itself).
//!
//! | parameter | type | default | meaning |
//! |-----------|------|---------|---------|
//! | filename | string | (required) | PNG, JPEG, BMP, Radiance HDR (`.hdr`) or OpenEXR, relative to the scene file |
//! | filter_type | string | `bilinear` | `bilinear` or `nearest` |
//! | wrap_mode | string | `repeat` | `repeat`, `mirror` or `clamp`: lookups outside [0, 1] |
//! | raw | boolean | false | keep the stored values: no sRGB decoding of 8/16-bit images (normal maps, roughness) |
//! | to_uv | transform | identity | applied to uv before the lookup |
//!
//! Conventions:
//! - u runs along the image's width, v along its height, and v = 0 is the image's
//!   first stored row (the top of a PNG): Mitsuba does not flip images; its OBJ
//!   loader flips the texture coordinates instead.
//! - Texel (x, y) covers [x / W, (x + 1) / W) x [y / H, (y + 1) / H). `nearest` returns
//!   texel (floor(u W), floor(v H)); `bilinear` interpolates the four texels around
//!   (u W - 1/2, v H - 1/2), texel centres at half-integers, each corner wrapped alone.
//! - Wrapping acts on integer texel indices: `repeat` is the Euclidean remainder,
//!   `mirror` reflects every other period (…, 1, 0, 0, 1, …, W-1, W-1, W-2, …),
//!   `clamp` clips to [0, W - 1].
//! - Channels: grey (with or without alpha) is one channel, returned as a grey colour;
//!   RGB(A) is three, alpha dropped. The scalar lookup is the one channel, or the
//!   luminance of the interpolated colour.
//! - 8- and 16-bit images are sRGB-encoded and decoded to linear on load unless `raw`;
//!   HDR and EXR values are linear and kept. Interpolation runs on linear values.
//! - Mitsuba pads images smaller than 2 x 2 by repeating the last row/column; every
//!   lookup of such a padded image equals the lookup of the original, so we keep it.

use super::{luminance, UvTransform};
use glam::{Vec2, Vec3};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FilterType {
    Nearest,
    Bilinear,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WrapMode {
    Repeat,
    Mirror,
    Clamp,
}

impl WrapMode {
    /// The texel index used for integer position `i` along an axis of `n` texels.
    #[inline]
    pub fn wrap(self, i: i64, n: i64) -> usize {
        (match self {
            WrapMode::Clamp => i.clamp(0, n - 1),
            WrapMode::Repeat => i.rem_euclid(n),
            WrapMode::Mirror => {
                let m = i.rem_euclid(2 * n);
                if m < n {
                    m
                } else {
                    2 * n - 1 - m
                }
            }
        }) as usize
    }
}

/// Linear texel values, row-major from the image's first stored row.
#[derive(Clone, Debug, PartialEq)]
pub struct Bitmap {
    pub width: usize,
    pub height: usize,
    /// 1 (grey) or 3 (RGB).
    pub channels: usize,
    pub data: Vec<f32>,
    pub filter: FilterType,
    pub wrap: WrapMode,
    pub to_uv: UvTransform,
}

impl Bitmap {
    /// The texel at wrapped indices, as a colour (grey splatted).
    #[inline]
    fn texel(&self, x: usize, y: usize) -> Vec3 {
        let i = (y * self.width + x) * self.channels;
        if self.channels == 1 {
            Vec3::splat(self.data[i])
        } else {
            Vec3::new(self.data[i], self.data[i + 1], self.data[i + 2])
        }
    }

    /// Integer texel position, saturating for uv far outside any image (and 0 for NaN).
    #[inline]
    fn floor_i(x: f32) -> i64 {
        x.floor() as i64
    }

    #[inline]
    pub fn eval_rgb(&self, uv: Vec2) -> Vec3 {
        self.eval_mapped(uv, &|c| c)
    }

    /// Whether [`Self::eval_mapped`] can differ from `f` of the interpolated colour:
    /// a `bilinear` RGB image (a grey one interpolates greys, which the spectral
    /// mode's lift maps linearly; Mitsuba's `interpolate_1` does not upsample them).
    pub fn filters_colours(&self) -> bool {
        self.filter == FilterType::Bilinear && self.channels == 3
    }

    /// The lookup at `uv` with `f` applied to each texel before the filter: `f` of
    /// the nearest texel, or the bilinear interpolation of `f` of the four texels
    /// around uv, with the weights and in the order of [`Self::eval_rgb`] (which is
    /// this with `f` the identity). The spectral mode lifts each texel so, as
    /// Mitsuba's `interpolate_spectral` (`src/textures/bitmap.cpp`) upsamples the four
    /// texels before interpolating: the upsampling is not linear in the colour.
    #[inline]
    pub fn eval_mapped(&self, uv: Vec2, f: &impl Fn(Vec3) -> Vec3) -> Vec3 {
        let uv = self.to_uv.apply(uv);
        let (w, h) = (self.width as i64, self.height as i64);
        let (wf, hf) = (self.width as f32, self.height as f32);
        match self.filter {
            FilterType::Nearest => {
                let x = self.wrap.wrap(Self::floor_i(uv.x * wf), w);
                let y = self.wrap.wrap(Self::floor_i(uv.y * hf), h);
                f(self.texel(x, y))
            }
            FilterType::Bilinear => {
                let px = uv.x * wf - 0.5;
                let py = uv.y * hf - 0.5;
                let (ix, iy) = (Self::floor_i(px), Self::floor_i(py));
                let (w1x, w1y) = (px - ix as f32, py - iy as f32);
                let (w0x, w0y) = (1.0 - w1x, 1.0 - w1y);
                let (x0, x1) = (
                    self.wrap.wrap(ix, w),
                    self.wrap.wrap(ix.saturating_add(1), w),
                );
                let (y0, y1) = (
                    self.wrap.wrap(iy, h),
                    self.wrap.wrap(iy.saturating_add(1), h),
                );
                let top = f(self.texel(x0, y0)) * w0x + f(self.texel(x1, y0)) * w1x;
                let bottom = f(self.texel(x0, y1)) * w0x + f(self.texel(x1, y1)) * w1x;
                top * w0y + bottom * w1y
            }
        }
    }

    #[inline]
    pub fn eval_float(&self, uv: Vec2) -> f32 {
        let c = self.eval_rgb(uv);
        if self.channels == 1 {
            c.x
        } else {
            luminance(c)
        }
    }
}

impl Bitmap {
    /// The scalar value of texel (x, y): its one channel or its colour's luminance.
    #[inline]
    fn texel_float(&self, x: usize, y: usize) -> f32 {
        let c = self.texel(x, y);
        if self.channels == 1 {
            c.x
        } else {
            luminance(c)
        }
    }

    /// Mitsuba's `eval_1_grad` (`src/textures/bitmap.cpp`): zero for `nearest`; for
    /// `bilinear`, the derivatives of the interpolation of the four texels' scalar
    /// values with respect to the texel position, taken through `to_uv` by its
    /// transpose and then scaled by the resolution (W, H), in that order, as Mitsuba
    /// writes it (exact for a `to_uv` without rotation or shear).
    pub fn eval_1_grad(&self, uv: Vec2) -> Vec2 {
        if self.filter == FilterType::Nearest {
            return Vec2::ZERO;
        }
        let uvt = self.to_uv.apply(uv);
        let (w, h) = (self.width as i64, self.height as i64);
        let px = uvt.x * self.width as f32 - 0.5;
        let py = uvt.y * self.height as f32 - 0.5;
        let (ix, iy) = (Self::floor_i(px), Self::floor_i(py));
        let (w1x, w1y) = (px - ix as f32, py - iy as f32);
        let (w0x, w0y) = (1.0 - w1x, 1.0 - w1y);
        let (x0, x1) = (
            self.wrap.wrap(ix, w),
            self.wrap.wrap(ix.saturating_add(1), w),
        );
        let (y0, y1) = (
            self.wrap.wrap(iy, h),
            self.wrap.wrap(iy.saturating_add(1), h),
        );
        let (f00, f10) = (self.texel_float(x0, y0), self.texel_float(x1, y0));
        let (f01, f11) = (self.texel_float(x0, y1), self.texel_float(x1, y1));
        let dfx = w0y * (f10 - f00) + w1y * (f11 - f01);
        let dfy = w0x * (f01 - f00) + w1x * (f11 - f10);
        let m = &self.to_uv.m;
        Vec2::new(
            self.width as f32 * (m[0][0] * dfx + m[1][0] * dfy),
            self.height as f32 * (m[0][1] * dfx + m[1][1] * dfy),
        )
    }

    /// The mean of every stored value (all texels and channels), Mitsuba's `mean()`.
    pub fn mean(&self) -> f32 {
        if self.data.is_empty() {
            return 0.0;
        }
        (self.data.iter().map(|&v| v as f64).sum::<f64>() / self.data.len() as f64) as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Dr.Jit's wrap (`tex_wrap` in `include/drjit/texture_impl.h`), transcribed as a
    /// reference for ours.
    fn drjit_wrap(mode: WrapMode, pos: i64, res: i64) -> i64 {
        if mode == WrapMode::Clamp {
            return pos.clamp(0, res - 1);
        }
        let shifted = if pos < 0 { pos + 1 } else { pos };
        let div = shifted / res; // truncating
        let mut m = pos - div * res;
        if m < 0 {
            m += res;
        }
        if mode == WrapMode::Mirror && !(((div & 1) == 0) ^ (pos < 0)) {
            m = res - 1 - m;
        }
        m
    }

    #[test]
    fn wrap_matches_drjit() {
        for mode in [WrapMode::Repeat, WrapMode::Mirror, WrapMode::Clamp] {
            for res in 1..6 {
                for pos in -25..25 {
                    assert_eq!(
                        mode.wrap(pos, res) as i64,
                        drjit_wrap(mode, pos, res),
                        "{mode:?} pos {pos} res {res}"
                    );
                }
            }
        }
        assert_eq!(WrapMode::Mirror.wrap(-1, 4), 0);
        assert_eq!(WrapMode::Mirror.wrap(4, 4), 3);
        assert_eq!(WrapMode::Repeat.wrap(-1, 4), 3);
    }

    fn grey_2x1(filter: FilterType, wrap: WrapMode) -> Bitmap {
        Bitmap {
            width: 2,
            height: 1,
            channels: 1,
            data: vec![0.0, 1.0],
            filter,
            wrap,
            to_uv: UvTransform::IDENTITY,
        }
    }

    /// The gradient against central differences of the lookup itself, away from texel
    /// centres (where the bilinear surface has kinks), through a scaling `to_uv`.
    #[test]
    fn gradient_matches_finite_differences_of_the_lookup() {
        let mut data = Vec::new();
        for i in 0..(5 * 4) {
            let v = ((i * 37) % 11) as f32 / 11.0;
            data.extend([v, 0.5 * v, 1.0 - v]);
        }
        let b = Bitmap {
            width: 5,
            height: 4,
            channels: 3,
            data,
            filter: FilterType::Bilinear,
            wrap: WrapMode::Repeat,
            to_uv: UvTransform {
                m: [[2.0, 0.0], [0.0, 3.0]],
                t: Vec2::new(0.1, 0.2),
            },
        };
        let mut rng = crate::math::rng::Pcg32::new(3, 4);
        let h = 1e-3f32;
        for _ in 0..200 {
            let uv = Vec2::new(rng.next_f32(), rng.next_f32());
            let g = b.eval_1_grad(uv);
            let fd = |d: Vec2| {
                (b.eval_float(uv + d) as f64 - b.eval_float(uv - d) as f64) / (2.0 * h as f64)
            };
            let (gu, gv) = (fd(Vec2::new(h, 0.0)), fd(Vec2::new(0.0, h)));
            // Skip pairs that straddle a texel centre (a kink of the interpolant).
            let p = b.to_uv.apply(uv) * Vec2::new(5.0, 4.0) - Vec2::splat(0.5);
            let near = |x: f32, step: f32| (x - x.round()).abs() < step;
            if near(p.x, 2.0 * 5.0 * h) || near(p.y, 3.0 * 4.0 * h) {
                continue;
            }
            assert!(
                (g.x as f64 - gu).abs() < 1e-3 * (1.0 + gu.abs()),
                "{uv}: {g} vs ({gu}, {gv})"
            );
            assert!(
                (g.y as f64 - gv).abs() < 1e-3 * (1.0 + gv.abs()),
                "{uv}: {g} vs ({gu}, {gv})"
            );
        }
        let n = Bitmap {
            filter: FilterType::Nearest,
            ..b.clone()
        };
        assert_eq!(n.eval_1_grad(Vec2::new(0.3, 0.3)), Vec2::ZERO);
        assert!((b.mean() - b.data.iter().sum::<f32>() / 60.0).abs() < 1e-6);
    }

    #[test]
    fn texel_centres_and_interpolation() {
        let b = grey_2x1(FilterType::Bilinear, WrapMode::Clamp);
        // Centres at u = 1/4 and 3/4.
        assert_eq!(b.eval_float(Vec2::new(0.25, 0.5)), 0.0);
        assert_eq!(b.eval_float(Vec2::new(0.75, 0.5)), 1.0);
        assert!((b.eval_float(Vec2::new(0.5, 0.5)) - 0.5).abs() < 1e-6);
        assert!((b.eval_float(Vec2::new(0.375, 0.5)) - 0.25).abs() < 1e-6);
        // Clamp holds the edge texels beyond the centres.
        assert_eq!(b.eval_float(Vec2::new(0.0, 0.5)), 0.0);
        assert_eq!(b.eval_float(Vec2::new(1.5, 0.5)), 1.0);
        // Repeat interpolates across the seam: u = 0 is halfway between texel 1 and 0.
        let r = grey_2x1(FilterType::Bilinear, WrapMode::Repeat);
        assert!((r.eval_float(Vec2::new(0.0, 0.5)) - 0.5).abs() < 1e-6);
        // Nearest: texel floor(u W).
        let n = grey_2x1(FilterType::Nearest, WrapMode::Repeat);
        assert_eq!(n.eval_float(Vec2::new(0.49, 0.5)), 0.0);
        assert_eq!(n.eval_float(Vec2::new(0.5, 0.5)), 1.0);
        assert_eq!(n.eval_float(Vec2::new(-0.25, 0.5)), 1.0);
        let m = grey_2x1(FilterType::Nearest, WrapMode::Mirror);
        assert_eq!(m.eval_float(Vec2::new(-0.25, 0.5)), 0.0);
        assert_eq!(m.eval_float(Vec2::new(1.25, 0.5)), 1.0);
        assert_eq!(m.eval_float(Vec2::new(1.75, 0.5)), 0.0);
        // NaN and huge uv do not panic.
        let _ = b.eval_rgb(Vec2::new(f32::NAN, 1e30));
        let _ = r.eval_rgb(Vec2::new(-1e30, f32::INFINITY));
        let _ = m.eval_rgb(Vec2::new(f32::NEG_INFINITY, 3e38));
    }

    /// `eval_mapped` applies `f` to each of the four texels before the bilinear
    /// weights: a slow reference written out (the four texels and their weights) for
    /// a squaring `f`, which tells it from `f` of the interpolated colour; with `f` the
    /// identity it is `eval_rgb`, bit for bit; `nearest` and grey images map the one
    /// value.
    #[test]
    fn eval_mapped_maps_texels_before_the_filter() {
        let rgb = Bitmap {
            width: 2,
            height: 2,
            channels: 3,
            data: vec![
                1.0, 0.0, 0.0, /**/ 0.0, 1.0, 0.0, //
                0.0, 0.0, 1.0, /**/ 0.5, 0.5, 0.5,
            ],
            filter: FilterType::Bilinear,
            wrap: WrapMode::Clamp,
            to_uv: UvTransform::IDENTITY,
        };
        assert!(rgb.filters_colours());
        let sq = |c: Vec3| c * c;
        let texels = [
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::splat(0.5),
        ];
        for (u, v) in [
            (0.5, 0.5),
            (0.3, 0.6),
            (0.7, 0.35),
            (0.25, 0.25),
            (0.9, 0.1),
        ] {
            let uv = Vec2::new(u, v);
            // Clamp: texel centres at 1/4 and 3/4, weights clipped to the edges.
            let wx = (u * 2.0 - 0.5_f32).clamp(0.0, 1.0);
            let wy = (v * 2.0 - 0.5_f32).clamp(0.0, 1.0);
            let w = [
                (1.0 - wx) * (1.0 - wy),
                wx * (1.0 - wy),
                (1.0 - wx) * wy,
                wx * wy,
            ];
            let mapped: Vec3 = (0..4).map(|i| sq(texels[i]) * w[i]).sum();
            let filtered: Vec3 = (0..4).map(|i| texels[i] * w[i]).sum();
            let got = rgb.eval_mapped(uv, &sq);
            assert!(
                (got - mapped).abs().max_element() < 1e-6,
                "{uv}: {got} vs {mapped}"
            );
            assert_eq!(rgb.eval_mapped(uv, &|c| c), rgb.eval_rgb(uv));
            assert!((rgb.eval_rgb(uv) - filtered).abs().max_element() < 1e-6);
        }
        // Halfway between the red and the green texel: (1/2, 1/2, 0) mapped is
        // (1/2, 1/2, 0); squaring the filtered colour would give (1/4, 1/4, 0).
        let mid = rgb.eval_mapped(Vec2::new(0.5, 0.25), &sq);
        assert!(
            (mid - Vec3::new(0.5, 0.5, 0.0)).abs().max_element() < 1e-6,
            "{mid}"
        );
        let nearest = Bitmap {
            filter: FilterType::Nearest,
            ..rgb.clone()
        };
        assert!(!nearest.filters_colours());
        assert_eq!(
            nearest.eval_mapped(Vec2::new(0.6, 0.2), &sq),
            sq(Vec3::new(0.0, 1.0, 0.0))
        );
        assert!(!grey_2x1(FilterType::Bilinear, WrapMode::Clamp).filters_colours());
    }
}
