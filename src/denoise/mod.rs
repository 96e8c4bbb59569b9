//! Denoising (SPEC 8): estimates from the bundle's sums, then the statistical
//! spatio-temporal filter (base filter x Welch-test membership).

pub mod base_filter;
pub mod critical;
pub mod estimates;
pub mod filter;
pub mod membership;

use crate::bundle::{Bundle, BundleError};
use crate::stats::accumulators::CHANNELS;
use base_filter::{BaseFilter, BaseKind, Features, Sigmas};
use critical::Threshold;
use estimates::{Estimates, SumsView};
use filter::{filter, FilterParams, Tiling};
use ndarray::Array4;

/// Everything the denoiser is told.
#[derive(Clone, Copy, Debug)]
pub struct DenoiseParams {
    pub radius: usize,
    pub temporal_radius: usize,
    /// The membership test's threshold; `None` runs the base filter alone.
    pub threshold: Option<Threshold>,
    pub base: BaseKind,
    pub sigmas: Sigmas,
    pub tiling: Tiling,
}

impl Default for DenoiseParams {
    fn default() -> Self {
        DenoiseParams {
            radius: 5,
            temporal_radius: 1,
            threshold: Some(Threshold::Auto),
            base: BaseKind::Jbf,
            sigmas: Sigmas::default(),
            tiling: Tiling::default(),
        }
    }
}

impl DenoiseParams {
    pub fn validate(&self) -> Result<(), String> {
        if let Some(t) = &self.threshold {
            t.validate()?;
        }
        self.sigmas.validate()
    }
}

pub struct Denoised {
    /// f32 (H, W, T, C).
    pub volume: Array4<f32>,
    /// Voxel-neighbour evaluations performed.
    pub evaluations: u64,
    /// Wall seconds of the whole call (reading sums and making estimates included).
    pub seconds: f64,
    /// Wall seconds of the filter alone.
    pub filter_seconds: f64,
}

/// Bytes the denoiser holds at its peak for a volume of this size: the three estimate
/// volumes and the output (f32), on top of the f64 sums while estimates are made.
pub fn memory_bytes(height: usize, width: usize, bins: usize) -> u64 {
    let b = height as u128 * width as u128 * bins as u128 * CHANNELS as u128 * 16;
    u64::try_from(b).unwrap_or(u64::MAX)
}

/// Denoises from sums and G-buffers already in memory.
pub fn denoise_sums(
    sums: &SumsView,
    albedo: &[f32],
    normal: &[f32],
    params: &DenoiseParams,
    progress: &(dyn Fn(u64) + Sync),
) -> Denoised {
    let start = std::time::Instant::now();
    let est = Estimates::from_sums(sums);
    let mut d = denoise_estimates(est, sums.spp, albedo, normal, params, progress);
    d.seconds = start.elapsed().as_secs_f64();
    d
}

/// Filters estimates already made (consumed, so their memory is freed before the
/// output is laid out).
pub fn denoise_estimates(
    est: Estimates,
    spp: u64,
    albedo: &[f32],
    normal: &[f32],
    params: &DenoiseParams,
    progress: &(dyn Fn(u64) + Sync),
) -> Denoised {
    let start = std::time::Instant::now();
    let fp = FilterParams {
        radius: params.radius,
        temporal_radius: params.temporal_radius,
        base: BaseFilter {
            kind: params.base,
            sigmas: params.sigmas,
        },
        g2: params.threshold.map(|t| t.g2(spp)),
    };
    let features = Features { albedo, normal };
    let (planar, evaluations) = filter(&est, &features, &fp, params.tiling, progress);
    let filter_seconds = start.elapsed().as_secs_f64();
    let (h, w, t) = (est.height, est.width, est.bins);
    drop(est);
    let volume = Array4::from_shape_fn((h, w, t, CHANNELS), |(y, x, k, c)| {
        planar[((y * w + x) * CHANNELS + c) * t + k]
    });
    Denoised {
        volume,
        evaluations,
        seconds: start.elapsed().as_secs_f64(),
        filter_seconds,
    }
}

/// A bundle's sums and G-buffers, read once (for several denoising runs).
pub struct LoadedSums {
    pub manifest: crate::bundle::Manifest,
    x1: ndarray::Array4<f64>,
    x2: ndarray::Array4<f64>,
    x3: ndarray::Array4<f64>,
    sum: Option<ndarray::Array4<f64>>,
    nonzero: ndarray::Array3<u32>,
    pub albedo: ndarray::Array3<f32>,
    pub normal: ndarray::Array3<f32>,
}

impl LoadedSums {
    pub fn read(bundle: &Bundle) -> Result<LoadedSums, BundleError> {
        let m = &bundle.manifest;
        let nonzero = bundle.nonzero()?;
        if let Some((v, _)) = nonzero.indexed_iter().find(|(_, &k)| k as u64 > m.spp) {
            return Err(BundleError::Invalid(
                bundle.dir.join("nonzero.npy"),
                format!("count at {v:?} exceeds spp = {}", m.spp),
            ));
        }
        Ok(LoadedSums {
            manifest: m.clone(),
            x1: bundle.x1()?,
            x2: bundle.x2()?,
            x3: bundle.x3()?,
            sum: if m.transform.is_identity() {
                None
            } else {
                Some(bundle.radiance_sum()?)
            },
            nonzero,
            albedo: bundle.albedo()?,
            normal: bundle.normal()?,
        })
    }

    pub fn view(&self) -> SumsView<'_> {
        let m = &self.manifest;
        SumsView {
            height: m.height,
            width: m.width,
            bins: m.bins,
            spp: m.spp,
            z0: m.transform.at_zero(),
            x1: std_slice(&self.x1),
            x2: std_slice(&self.x2),
            x3: std_slice(&self.x3),
            sum: std_slice(self.sum.as_ref().unwrap_or(&self.x1)),
            nonzero: std_slice(&self.nonzero),
        }
    }

    /// Keeps the manifest and G-buffers, freeing the sums.
    pub fn into_features(
        self,
    ) -> (
        crate::bundle::Manifest,
        ndarray::Array3<f32>,
        ndarray::Array3<f32>,
    ) {
        (self.manifest, self.albedo, self.normal)
    }

    pub fn denoise(&self, params: &DenoiseParams, progress: &(dyn Fn(u64) + Sync)) -> Denoised {
        denoise_sums(
            &self.view(),
            std_slice(&self.albedo),
            std_slice(&self.normal),
            params,
            progress,
        )
    }
}

/// Reads a bundle and denoises it; the f64 sums are freed once the estimates are made.
pub fn denoise_bundle(
    bundle: &Bundle,
    params: &DenoiseParams,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Denoised, BundleError> {
    let start = std::time::Instant::now();
    let sums = LoadedSums::read(bundle)?;
    let est = Estimates::from_sums(&sums.view());
    let (manifest, albedo, normal) = sums.into_features();
    let mut d = denoise_estimates(
        est,
        manifest.spp,
        std_slice(&albedo),
        std_slice(&normal),
        params,
        progress,
    );
    d.seconds = start.elapsed().as_secs_f64();
    Ok(d)
}

/// Arrays from `read_npy` are in standard (C) layout.
fn std_slice<T, D: ndarray::Dimension>(a: &ndarray::Array<T, D>) -> &[T] {
    a.as_slice().expect("read_npy gives standard layout")
}
