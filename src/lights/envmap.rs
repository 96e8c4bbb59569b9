//! `envmap`: an infinitely distant environment given by a latitude-longitude image,
//! with Mitsuba 3.9.1's conventions (`src/emitters/envmap.cpp`, RGB variants).
//!
//! | parameter | type | default | meaning |
//! |-----------|------|---------|---------|
//! | filename | string | (required) | OpenEXR, Radiance HDR, PNG or JPEG (8/16-bit decoded from sRGB, as Mitsuba's bitmap conversion to linear float) |
//! | scale | float | 1 | factor on the radiance (>= 0) |
//! | to_world | transform | identity | orientation; its linear part must be a rotation (a reflection allowed) |
//! | mis_compensation | boolean | false | sample with max(luminance - mean luminance, 0), as Mitsuba (Karlik et al. 2019) |
//!
//! Mitsuba's envmap has no `filter_type`: it always interpolates bilinearly, and so does
//! this one.
//!
//! Conventions (local frame: `v = to_world^-1 d` for a world direction `d` pointing away
//! from the scene):
//! - `u = atan2(v.x, -v.z) / 2 pi` (wrapped into [0, 1)), `v = acos(v.y) / pi`: the
//!   image's first row is straight up (+y), its middle row the horizon, and u = 0 (the
//!   image's left edge) looks along -z, u = 1/4 along +x.
//! - Columns are texel-centred and periodic: column `x` sits at `u = (x + 1/2) / W`, and
//!   between the last column and the first the lookup interpolates across the seam.
//! - Rows are corner-aligned: row `y` sits at `v = y / (H - 1)`, so the first and the
//!   last rows are the poles themselves (clamped there).
//! - Images narrower than 2 or lower than 3 texels are padded by repeating the last
//!   column / row (Mitsuba's `Bitmap::pad_to(2, 3)`; this changes the lookup of a
//!   2-row image, exactly as in Mitsuba).
//!
//! Importance sampling (ours; Mitsuba warps a bilinear patch instead, only the noise
//! differs): the sphere is cut into the `W x (H - 1)` cells between the texel centres
//! (cell `(i, j)`: u from `(i + 1/2) / W` to `(i + 3/2) / W`, theta from `pi j / (H - 1)`
//! to `pi (j + 1) / (H - 1)`), the bilinear patches of the lookup. A cell is chosen
//! with probability proportional to the mean luminance of its four corner texels times
//! its solid angle `(2 pi / W) (cos theta_j - cos theta_(j+1))`, and a direction
//! uniformly in solid angle within it. The density is therefore constant on each cell,
//! `P(i, j) / Omega(i, j)`, proportional to luminance x sin(theta) in (u, theta), and
//! positive wherever the radiance can be (a bilinear patch is non-zero only if a corner
//! is). `sample` and `pdf` compute it from the direction alone, so the density of a
//! sample and the one MIS evaluates for the same direction are the same number.
//!
//! Memory: the texels (`12 W H` bytes, f32 RGB) and the sampling tables (`W (H - 1)`
//! cell densities, `(W + 1) (H - 1)` conditional and `H` marginal CDF values, all f32:
//! about `8 W H` bytes). A 2048 x 1024 map holds 42 MB.

use super::distribution::Distribution2D;
use crate::math::Rgb;
use glam::{DMat3, Mat3, Vec3};
use std::f32::consts::PI;

#[derive(Clone, Debug, PartialEq)]
pub struct EnvMap {
    width: usize,
    height: usize,
    /// Linear RGB, row-major from the image's first row (padded as Mitsuba).
    texels: Vec<Vec3>,
    scale: f32,
    to_world: Mat3,
    to_local: Mat3,
    mis_compensation: bool,
    /// Over the `width x (height - 1)` cells; `None` when the map is black.
    distr: Option<Distribution2D>,
    /// Solid-angle density on each cell: `P(i, j) / Omega(i, j)`.
    cell_pdf: Vec<f32>,
}

/// Why an image cannot be an environment map.
#[derive(Debug, PartialEq)]
pub enum EnvMapError {
    /// A texel is NaN or infinite: (x, y) in the stored image.
    NonFinite(usize, usize),
    /// The linear part of `to_world` is not a rotation or reflection.
    NotARotation,
}

impl EnvMap {
    /// From `width x height` linear RGB texels (row-major, first row = up), the radiance
    /// `scale` and the linear part of `to_world`. Negative texel values must have been
    /// dealt with by the caller (they are clamped to 0 here).
    pub fn new(
        width: usize,
        height: usize,
        rgb: Vec<Vec3>,
        scale: f32,
        to_world: DMat3,
        mis_compensation: bool,
    ) -> Result<EnvMap, EnvMapError> {
        assert!(width > 0 && height > 0 && rgb.len() == width * height);
        if let Some(k) = rgb.iter().position(|c| !c.is_finite()) {
            return Err(EnvMapError::NonFinite(k % width, k / width));
        }
        let gram = to_world.transpose() * to_world;
        let off = (gram - DMat3::IDENTITY).to_cols_array();
        if !to_world.is_finite() || off.iter().any(|v| v.abs() > 1e-4) {
            return Err(EnvMapError::NotARotation);
        }
        // Mitsuba's Bitmap::pad_to(2, 3): repeat the last column, then the last row.
        let (w, h) = (width.max(2), height.max(3));
        let texels: Vec<Vec3> = if (w, h) == (width, height) {
            rgb.into_iter().map(|c| c.max(Vec3::ZERO)).collect()
        } else {
            (0..w * h)
                .map(|k| rgb[(k / w).min(height - 1) * width + (k % w).min(width - 1)])
                .map(|c| c.max(Vec3::ZERO))
                .collect()
        };
        // Luminance in f64 (no overflow for any finite texel).
        let lum = |c: Vec3| 0.212671 * c.x as f64 + 0.715160 * c.y as f64 + 0.072169 * c.z as f64;
        // Mitsuba's MIS compensation: subtract the mean luminance unless the map is
        // nearly constant (mean - min <= 1% of the mean).
        let mut offset = 0.0f64;
        if mis_compensation {
            let mean = texels.iter().map(|&c| lum(c)).sum::<f64>() / texels.len() as f64;
            let min = texels.iter().map(|&c| lum(c)).fold(f64::INFINITY, f64::min);
            if mean - min > 0.01 * mean {
                offset = mean;
            }
        }
        let l = |x: usize, y: usize| (lum(texels[y * w + x % w]) - offset).max(0.0);
        let (nu, nv) = (w, h - 1);
        let theta = |j: usize| std::f64::consts::PI * j as f64 / nv as f64;
        let omega: Vec<f64> = (0..nv)
            .map(|j| 2.0 * std::f64::consts::PI / nu as f64 * (theta(j).cos() - theta(j + 1).cos()))
            .collect();
        let mut weights = Vec::with_capacity(nu * nv);
        for (j, &om) in omega.iter().enumerate() {
            for i in 0..nu {
                let corners = l(i, j) + l(i + 1, j) + l(i, j + 1) + l(i + 1, j + 1);
                weights.push(0.25 * corners * om);
            }
        }
        let distr = Distribution2D::new(&weights, nu, nv);
        let cell_pdf = match &distr {
            Some(d) => (0..nu * nv)
                .map(|k| (d.prob(k % nu, k / nu) as f64 / omega[k / nu]) as f32)
                .collect(),
            None => vec![0.0; nu * nv],
        };
        let to_world_f = to_world.as_mat3();
        Ok(EnvMap {
            width: w,
            height: h,
            texels,
            scale,
            to_world: to_world_f,
            to_local: to_world.inverse().as_mat3(),
            mis_compensation,
            distr,
            cell_pdf,
        })
    }

    /// Whether the map emits nothing (all texels zero, or scale 0).
    pub fn is_black(&self) -> bool {
        self.scale == 0.0 || self.texels.iter().all(|&c| c == Vec3::ZERO)
    }

    /// Everything that defines the map, as numbers (for cache keys): width, height,
    /// scale, `to_world` (column-major), MIS compensation, then the texels.
    pub fn key_values(&self) -> impl Iterator<Item = f32> + '_ {
        [self.width as f32, self.height as f32, self.scale]
            .into_iter()
            .chain(self.to_world.to_cols_array())
            .chain([self.mis_compensation as u8 as f32])
            .chain(self.texels.iter().flat_map(|c| c.to_array()))
    }

    /// Bytes held (texels and sampling tables).
    pub fn bytes(&self) -> usize {
        12 * self.texels.len()
            + 4 * self.cell_pdf.len()
            + self.distr.as_ref().map_or(0, |d| d.bytes())
    }

    /// Mitsuba's `direction_to_uv` of a world direction (unit) pointing away from the
    /// scene; u in [0, 1), v in [0, 1].
    #[inline]
    pub fn uv(&self, d: Vec3) -> [f32; 2] {
        let v = self.to_local * d;
        let u = v.x.atan2(-v.z) * (0.5 / PI);
        let u = u - u.floor();
        // `u - floor(u)` of a tiny negative u rounds to 1.
        let u = if u >= 1.0 { 0.0 } else { u };
        [u, v.y.clamp(-1.0, 1.0).acos() * (1.0 / PI)]
    }

    /// The radiance at (u, v): Mitsuba's bilinear lookup (periodic texel-centred columns,
    /// corner-aligned clamped rows), times `scale`.
    #[inline]
    pub fn eval_uv(&self, uv: [f32; 2]) -> Rgb {
        let ([x0, x1, y0, y1], wx, wy) = self.corners(uv);
        let w = self.width;
        let t = |x: usize, y: usize| self.texels[y * w + x];
        let top = t(x0, y0) * (1.0 - wx) + t(x1, y0) * wx;
        let bottom = t(x0, y1) * (1.0 - wx) + t(x1, y1) * wx;
        (top * (1.0 - wy) + bottom * wy) * self.scale
    }

    /// The four texels of the bilinear lookup at (u, v), `[x0, x1, y0, y1]`, and the
    /// weights `(wx, wy)` of `x1` and `y1`: periodic texel-centred columns,
    /// corner-aligned clamped rows.
    #[inline(always)]
    fn corners(&self, [u, v]: [f32; 2]) -> ([usize; 4], f32, f32) {
        let (w, h) = (self.width, self.height);
        let x = u * w as f32 - 0.5;
        let y = v.clamp(0.0, 1.0) * (h - 1) as f32;
        let (xf, yf) = (x.floor(), y.floor());
        let x0 = (xf as i64).rem_euclid(w as i64) as usize;
        let y0 = (yf as usize).min(h - 1);
        ([x0, (x0 + 1) % w, y0, (y0 + 1).min(h - 1)], x - xf, y - yf)
    }

    /// The spectrum at `lambda` (nm) of the radiance at (u, v), without the D65 factor,
    /// as Mitsuba's spectral variants compute it: each of the four texels of the
    /// bilinear lookup is the smooth spectrum of `c / (2 max c)` (`rgb2spec`) times `2
    /// max c`, and the spectra and the factors are interpolated separately (the model is
    /// not linear in the colour, so lifting the interpolated colour would differ).
    pub fn eval_uv_spectral(&self, uv: [f32; 2], lambda: [f32; 3]) -> Vec3 {
        use crate::spectral::rgb2spec::{eval, fetch};
        let ([x0, x1, y0, y1], wx, wy) = self.corners(uv);
        let w = self.width;
        // One texel: its sigmoids at the wavelengths and its factor.
        let t = |x: usize, y: usize| {
            let c = self.texels[y * w + x];
            let factor = 2.0 * c.max_element();
            let coeffs = fetch((c / factor.max(1e-8)).to_array());
            (Vec3::from_array(lambda.map(|l| eval(coeffs, l))), factor)
        };
        let ((s00, f00), (s10, f10)) = (t(x0, y0), t(x1, y0));
        let ((s01, f01), (s11, f11)) = (t(x0, y1), t(x1, y1));
        let s0 = s00 * (1.0 - wx) + s10 * wx;
        let s1 = s01 * (1.0 - wx) + s11 * wx;
        let f0 = f00 * (1.0 - wx) + f10 * wx;
        let f1 = f01 * (1.0 - wx) + f11 * wx;
        let s = s0 * (1.0 - wy) + s1 * wy;
        let f = f0 * (1.0 - wy) + f1 * wy;
        s * f * self.scale
    }

    /// The radiance arriving from world direction `d` (unit, pointing away from the scene).
    #[inline]
    pub fn eval(&self, d: Vec3) -> Rgb {
        self.eval_uv(self.uv(d))
    }

    /// The sampling cell holding (u, v).
    #[inline]
    fn cell(&self, [u, v]: [f32; 2]) -> usize {
        let (nu, nv) = (self.width, self.height - 1);
        let i = ((u * nu as f32 - 0.5).floor() as i64).rem_euclid(nu as i64) as usize;
        let j = ((v * nv as f32).floor().max(0.0) as usize).min(nv - 1);
        j * nu + i
    }

    /// Solid-angle density with which `sample` produces world direction `d`.
    #[inline]
    pub fn pdf(&self, d: Vec3) -> f32 {
        self.cell_pdf[self.cell(self.uv(d))]
    }

    /// A direction (world, unit, away from the scene) with its radiance and solid-angle
    /// density, both computed from the direction itself (`None`: a black map, or a
    /// direction that rounded into a cell of zero density).
    #[inline]
    pub fn sample(&self, u: [f32; 2]) -> Option<(Vec3, Rgb, f32)> {
        let distr = self.distr.as_ref()?;
        let (i, j, r) = distr.sample(u);
        let (nu, nv) = (self.width as f32, (self.height - 1) as f32);
        let uu = (i as f32 + 0.5 + r[0]) / nu;
        let (c0, c1) = ((PI * j as f32 / nv).cos(), (PI * (j + 1) as f32 / nv).cos());
        let cos_t = (c0 + r[1] * (c1 - c0)).clamp(-1.0, 1.0);
        let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
        let (sin_p, cos_p) = (2.0 * PI * uu).sin_cos();
        let local = Vec3::new(sin_p * sin_t, cos_t, -cos_p * sin_t);
        let d = (self.to_world * local).normalize();
        let uv = self.uv(d);
        let pdf = self.cell_pdf[self.cell(uv)];
        (pdf > 0.0).then(|| (d, self.eval_uv(uv), pdf))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn map(w: usize, h: usize, f: impl Fn(usize, usize) -> Vec3) -> EnvMap {
        let rgb: Vec<Vec3> = (0..w * h).map(|k| f(k % w, k / w)).collect();
        EnvMap::new(w, h, rgb, 1.0, DMat3::IDENTITY, false).unwrap()
    }

    #[test]
    fn texel_centres_and_poles_follow_mitsubas_convention() {
        let (w, h) = (8, 5);
        let m = map(w, h, |x, y| Vec3::new(x as f32, y as f32, 1.0));
        for y in 0..h {
            for x in 0..w {
                let uv = [(x as f32 + 0.5) / w as f32, y as f32 / (h - 1) as f32];
                let c = m.eval_uv(uv);
                assert!(
                    (c.x - x as f32).abs() < 1e-4 && (c.y - y as f32).abs() < 1e-4,
                    "{x} {y} {c}"
                );
            }
        }
        // Across the seam: u = 0 is halfway between the last column and the first.
        let c = m.eval_uv([0.0, 0.5]);
        assert!((c.x - (w - 1) as f32 / 2.0).abs() < 1e-4, "{c}");
        // Directions: up is v = 0, -z is u = 0, +x is u = 1/4, the horizon v = 1/2.
        let uv = |d: Vec3| m.uv(d);
        assert!(uv(Vec3::Y)[1].abs() < 1e-6);
        assert!((uv(-Vec3::Y)[1] - 1.0).abs() < 1e-6);
        assert!(uv(-Vec3::Z)[0].abs() < 1e-6 && (uv(-Vec3::Z)[1] - 0.5).abs() < 1e-6);
        assert!((uv(Vec3::X)[0] - 0.25).abs() < 1e-6);
        assert!((uv(Vec3::Z)[0] - 0.5).abs() < 1e-6);
        assert!((uv(-Vec3::X)[0] - 0.75).abs() < 1e-6);
    }

    /// The spectral lookup lifts texels, then interpolates: a grey map is flat at the
    /// RGB lookup's value; halfway between two colours it is the mean of their
    /// normalised spectra times the mean of their factors (Mitsuba's `envmap`), not the
    /// spectrum of their mean colour, which differs.
    #[test]
    fn spectral_lookups_interpolate_lifted_texels() {
        use crate::spectral::rgb2spec::{eval, fetch};
        let lambda = [450.0, 550.0, 650.0];
        let grey = map(4, 3, |_, _| Vec3::splat(3.0));
        let v = grey.eval_uv_spectral([0.3, 0.4], lambda);
        assert!((v - Vec3::splat(3.0)).abs().max_element() < 1e-6, "{v}");
        let (a, b) = (Vec3::new(0.8, 0.1, 0.1), Vec3::new(0.1, 0.1, 0.9));
        let two = map(8, 5, |x, _| if x < 4 { a } else { b });
        // Halfway between the centres of columns 3 and 4 (u = 3.5 / 8 and 4.5 / 8).
        let v = two.eval_uv_spectral([0.5, 0.5], lambda);
        // A colour's normalised spectrum and its factor.
        let lifted = |c: Vec3| {
            let f = 2.0 * c.max_element();
            let k = fetch((c / f).to_array());
            (Vec3::from_array(lambda.map(|l| eval(k, l))), f)
        };
        let ((sa, fa), (sb, fb)) = (lifted(a), lifted(b));
        let want = (sa + sb) * 0.5 * ((fa + fb) * 0.5);
        assert!((v - want).abs().max_element() < 1e-5, "{v} vs {want}");
        let (sm, fm) = lifted((a + b) * 0.5);
        let spectrum_of_mean = sm * fm;
        assert!(
            (v - spectrum_of_mean).abs().max_element() > 1e-2,
            "the test tells them apart"
        );
    }

    #[test]
    fn small_images_are_padded_as_mitsuba() {
        // Two rows become three (the last repeated): v = 1/2 is the second row exactly.
        let m = map(2, 2, |_, y| Vec3::splat(if y == 0 { 0.0 } else { 4.0 }));
        assert_eq!((m.width, m.height), (2, 3));
        assert!((m.eval_uv([0.3, 0.5]).x - 4.0).abs() < 1e-6);
        assert!((m.eval_uv([0.3, 0.25]).x - 2.0).abs() < 1e-6);
    }

    #[test]
    fn the_density_integrates_to_one_and_sampling_agrees_with_pdf() {
        let m = map(7, 6, |x, y| {
            Vec3::new((x * y % 5) as f32, 0.5, (x + y) as f32 * 0.1)
        });
        // Midpoint rule in (phi, cos theta): the density is constant on each cell.
        let n = 700;
        let mut sum = 0.0f64;
        for a in 0..n {
            for b in 0..n {
                let z = -1.0 + 2.0 * (a as f64 + 0.5) / n as f64;
                let phi = 2.0 * std::f64::consts::PI * (b as f64 + 0.5) / n as f64;
                let s = (1.0 - z * z).sqrt();
                let d = Vec3::new((s * phi.cos()) as f32, (s * phi.sin()) as f32, z as f32);
                sum += m.pdf(d) as f64;
            }
        }
        let integral = sum * 4.0 * std::f64::consts::PI / (n * n) as f64;
        assert!((integral - 1.0).abs() < 3e-3, "{integral}");
        let (w, h) = (7, 6);
        assert_eq!(
            m.bytes(),
            12 * w * h + 4 * w * (h - 1) + 4 * (w + 1) * (h - 1) + 4 * h
        );
        let mut rng = crate::math::rng::Pcg32::new(3, 1);
        for _ in 0..10000 {
            if let Some((d, li, pdf)) = m.sample(rng.next_2d()) {
                assert!((d.length() - 1.0).abs() < 1e-5);
                assert_eq!(pdf, m.pdf(d));
                assert_eq!(li, m.eval(d));
            }
        }
    }
}
