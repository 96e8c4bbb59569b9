//! A bundle's G-buffers, owned: what the base filter and tstat's membership read per
//! pixel (albedo, normal, depth, emitter fraction). 32 bytes per pixel.

use super::base_filter::Features;
use crate::bundle::{Bundle, BundleError};
use ndarray::{Array2, Array3};

pub struct GBuffers {
    /// (H, W, 3).
    pub albedo: Array3<f32>,
    /// (H, W, 3).
    pub normal: Array3<f32>,
    /// (H, W).
    pub depth: Array2<f32>,
    /// (H, W).
    pub emitter: Array2<f32>,
}

impl GBuffers {
    pub fn read(bundle: &Bundle) -> Result<GBuffers, BundleError> {
        Ok(GBuffers {
            albedo: bundle.albedo()?,
            normal: bundle.normal()?,
            depth: bundle.depth()?,
            emitter: bundle.emitter()?,
        })
    }

    /// From per-pixel records in row-major order.
    pub fn from_pixels(
        height: usize,
        width: usize,
        pixels: &[crate::render::gbuffer::GPixel],
    ) -> GBuffers {
        let g = |y: usize, x: usize| &pixels[y * width + x];
        GBuffers {
            albedo: Array3::from_shape_fn((height, width, 3), |(y, x, c)| g(y, x).albedo[c]),
            normal: Array3::from_shape_fn((height, width, 3), |(y, x, c)| g(y, x).normal[c]),
            depth: Array2::from_shape_fn((height, width), |(y, x)| g(y, x).depth),
            emitter: Array2::from_shape_fn((height, width), |(y, x)| g(y, x).emitter),
        }
    }

    pub fn features(&self) -> Features<'_> {
        Features {
            albedo: super::std_slice(&self.albedo),
            normal: super::std_slice(&self.normal),
            depth: super::std_slice(&self.depth),
            emitter: super::std_slice(&self.emitter),
        }
    }
}
