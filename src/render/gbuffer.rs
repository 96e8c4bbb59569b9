//! G-buffers for the joint bilateral base filter, averaged over each pixel's samples:
//! albedo and shading normal at the first non-delta vertex, depth of the first hit, and
//! the fraction of samples whose first non-delta vertex is a directly seen emitter (an
//! area light, or the environment emitter met by a ray that leaves the scene; a sample
//! that sees the environment has no depth and no normal).

use glam::Vec3;

/// What one camera sample saw.
#[derive(Clone, Copy, Debug, Default)]
pub struct GSample {
    pub albedo: Vec3,
    /// Shading normal facing the incoming ray (zero if the sample saw nothing).
    pub normal: Vec3,
    /// Distance from the pinhole to the first hit, if any.
    pub depth: Option<f32>,
    pub emitter: bool,
    /// The first real interaction was a scattering inside a medium (volumetric
    /// integrator only).
    pub medium: bool,
}

/// One pixel's sums.
#[derive(Clone, Copy, Debug, Default)]
pub struct GAccum {
    albedo: [f64; 3],
    normal: [f64; 3],
    depth: f64,
    depth_count: u32,
    emitter: u32,
    medium: u32,
    samples: u32,
}

/// Final per-pixel values, as stored in the bundle.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GPixel {
    pub albedo: [f32; 3],
    /// Unit length where any sample saw a surface, zero otherwise.
    pub normal: [f32; 3],
    /// Mean distance to the first hit over the samples that hit something (0 if none).
    pub depth: f32,
    /// Fraction of the pixel's samples whose first non-delta vertex is an emitter.
    pub emitter: f32,
    /// Fraction of the pixel's samples whose first real interaction is a scattering in
    /// a medium (0 for surface-only renders).
    pub medium: f32,
}

impl GAccum {
    pub fn add(&mut self, s: &GSample) {
        for c in 0..3 {
            self.albedo[c] += s.albedo[c] as f64;
            self.normal[c] += s.normal[c] as f64;
        }
        if let Some(d) = s.depth {
            self.depth += d as f64;
            self.depth_count += 1;
        }
        self.emitter += s.emitter as u32;
        self.medium += s.medium as u32;
        self.samples += 1;
    }

    pub fn finish(&self) -> GPixel {
        let n = self.samples.max(1) as f64;
        let len = self.normal.iter().map(|v| v * v).sum::<f64>().sqrt();
        GPixel {
            albedo: self.albedo.map(|v| (v / n) as f32),
            normal: if len > 0.0 {
                self.normal.map(|v| (v / len) as f32)
            } else {
                [0.0; 3]
            },
            depth: if self.depth_count > 0 {
                (self.depth / self.depth_count as f64) as f32
            } else {
                0.0
            },
            emitter: (self.emitter as f64 / n) as f32,
            medium: (self.medium as f64 / n) as f32,
        }
    }
}
