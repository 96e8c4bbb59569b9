//! Parameter sweeps: the error of every combination of membership settings (tstat's
//! t2 bounds and emitter radius, or the published filter's gamma), radius and
//! temporal radius on one or more bundles, over all voxels, the pixels that see a
//! light and the rest, so the defaults are chosen by measurement.

use super::region::{compare_regions, rmse_ratio, RegionMetrics};
use super::ReportError;
use crate::bundle::Bundle;
use crate::denoise::{DenoiseParams, LoadedSums, Method};
use ndarray::Array4;
use std::path::PathBuf;

#[derive(Clone, Debug)]
pub struct SweepPoint {
    pub bundle: String,
    pub transform: String,
    pub spp: u64,
    pub method: Method,
    pub radius: usize,
    pub temporal_radius: usize,
    pub seconds: f64,
    pub error: RegionMetrics,
    /// The noisy mean's errors on the same bundle, for scale.
    pub noisy: RegionMetrics,
}

pub struct SweepConfig {
    pub bundles: Vec<PathBuf>,
    pub methods: Vec<Method>,
    pub radii: Vec<usize>,
    pub temporal_radii: Vec<usize>,
    /// Everything else (base filter, sigmas) is taken from here.
    pub base: DenoiseParams,
}

fn region_metrics(x: &Array4<f32>, reference: &Array4<f32>, rest: &[bool]) -> RegionMetrics {
    compare_regions(x.view(), reference.view(), Some(rest)).0
}

pub fn run_sweep(
    cfg: &SweepConfig,
    reference: &Array4<f32>,
    log: &dyn Fn(&str),
) -> Result<Vec<SweepPoint>, ReportError> {
    let mut points = Vec::new();
    for path in &cfg.bundles {
        let bundle = Bundle::open(path)?;
        let m = &bundle.manifest;
        let shape = [m.height, m.width, m.bins, 3];
        if reference.shape() != shape {
            return Err(ReportError::SweepShape {
                path: path.clone(),
                shape,
                reference: reference.shape().to_vec(),
            });
        }
        let rest = super::volume::no_light_mask(&bundle.emitter()?);
        let sums = LoadedSums::read(&bundle)?;
        let noisy = region_metrics(&bundle.noisy_mean()?, reference, &rest);
        for &method in &cfg.methods {
            for &radius in &cfg.radii {
                for &temporal_radius in &cfg.temporal_radii {
                    let params = DenoiseParams {
                        radius,
                        temporal_radius,
                        method,
                        ..cfg.base
                    };
                    let d = sums.denoise(&params, &|_| {});
                    let error = region_metrics(&d.volume, reference, &rest);
                    let ratio = |e, n| rmse_ratio(e, n).map_or("n/a".into(), |v| format!("{v:.3}"));
                    log(&format!(
                        "{}: {}, r {radius}, r_t {temporal_radius}: RMSE {:.4e} ({} of noisy; rest {})",
                        path.display(),
                        method.describe(),
                        error.all.rmse,
                        ratio(Some(error.all), Some(noisy.all)),
                        ratio(error.rest, noisy.rest),
                    ));
                    points.push(SweepPoint {
                        bundle: path.display().to_string(),
                        transform: m.transform.to_string(),
                        spp: m.spp,
                        method,
                        radius,
                        temporal_radius,
                        seconds: d.seconds,
                        error,
                        noisy,
                    });
                }
            }
        }
    }
    Ok(points)
}
