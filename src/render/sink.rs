//! Where finished rows go. A render task traces one image row with all its samples, so
//! once it is done that row's sums are final: the driver ([`super::render_into`]) hands
//! each finished [`Row`] to a [`RowSink`] and reuses the row's buffers for the next one.
//!
//! Two sinks: [`MemorySink`] keeps the whole film in [`Accumulators`] (a
//! [`super::RenderOutput`], for `report convergence` and tests); the streaming bundle
//! writer (`bundle::write::BundleWriter`) writes each row straight into the bundle's
//! `.npy` files, so a render's memory depends on threads x row size, not on the height.
//! Both keep the small per-pixel images (G-buffers, steady) in a [`PixelImages`].

use super::gbuffer::GPixel;
use crate::stats::accumulators::Accumulators;
use crate::stats::Transform;
use std::sync::Mutex;

/// One finished image row.
pub struct Row<'a> {
    pub y: usize,
    /// The row's sums: an [`Accumulators`] of height 1, laid out (1, W, T, C) like the
    /// bundle's arrays, so row `y` of an (H, W, T, C) array is these values at offset
    /// `y * W * T * C`.
    pub sums: &'a Accumulators,
    /// The row's G-buffer pixels (W).
    pub gbuffer: &'a [GPixel],
    /// The row's steady-state mean radiance (W, C).
    pub steady: &'a [f64],
    /// Rays traced for each pixel of the row (W): the cost of its samples.
    pub rays: &'a [u64],
}

/// Receives every row of a render exactly once, in any order, from worker threads.
pub trait RowSink: Sync {
    type Error: Send;
    /// Takes row `row.y`; an error stops the render (rows already started finish).
    fn put_row(&self, row: &Row<'_>) -> Result<(), Self::Error>;
}

/// The per-pixel images of a render, (H, W) G-buffer pixels and (H, W, C) steady
/// radiance, filled row by row, with which rows arrived.
pub struct PixelImages {
    pub width: usize,
    pub channels: usize,
    pub gbuffer: Vec<GPixel>,
    pub steady: Vec<f64>,
    rows_done: Vec<bool>,
}

impl PixelImages {
    pub fn new(height: usize, width: usize, channels: usize) -> Self {
        PixelImages {
            width,
            channels,
            gbuffer: vec![GPixel::default(); height * width],
            steady: vec![0.0; height * width * channels],
            rows_done: vec![false; height],
        }
    }

    /// Bytes for an (H, W) film (saturating).
    pub fn bytes(height: usize, width: usize, channels: usize) -> u64 {
        let per_pixel = (std::mem::size_of::<GPixel>() + channels * 8) as u128;
        let b = height as u128 * (width as u128 * per_pixel + 1);
        u64::try_from(b).unwrap_or(u64::MAX)
    }

    pub fn put(&mut self, row: &Row<'_>) {
        assert!(!self.rows_done[row.y], "row {} arrived twice", row.y);
        self.rows_done[row.y] = true;
        let (w, c) = (self.width, self.channels);
        self.gbuffer[row.y * w..(row.y + 1) * w].copy_from_slice(row.gbuffer);
        self.steady[row.y * w * c..(row.y + 1) * w * c].copy_from_slice(row.steady);
    }

    /// Whether every row arrived.
    pub fn complete(&self) -> bool {
        self.rows_done.iter().all(|&d| d)
    }
}

/// Keeps the whole film in memory.
pub struct MemorySink {
    film: Mutex<(Accumulators, PixelImages)>,
}

impl MemorySink {
    pub fn new(
        height: usize,
        width: usize,
        bins: usize,
        channels: usize,
        transform: &Transform,
    ) -> Self {
        MemorySink {
            film: Mutex::new((
                Accumulators::new(height, width, bins, channels, transform),
                PixelImages::new(height, width, channels),
            )),
        }
    }

    /// The same sink, keeping replicate statistics (`R2`) too.
    pub fn with_r2(self) -> Self {
        let (sums, images) = self.into_parts();
        MemorySink {
            film: Mutex::new((sums.with_r2(), images)),
        }
    }

    /// The sums and the per-pixel images.
    pub fn into_parts(self) -> (Accumulators, PixelImages) {
        self.film
            .into_inner()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }
}

impl RowSink for MemorySink {
    type Error = std::convert::Infallible;

    fn put_row(&self, row: &Row<'_>) -> Result<(), Self::Error> {
        let mut film = self
            .film
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        film.0.put_row(row.y, row.sums);
        film.1.put(row);
        Ok(())
    }
}
