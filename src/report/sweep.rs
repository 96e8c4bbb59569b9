//! Parameter sweeps: the error of every combination of gamma, radius and temporal
//! radius on one or more bundles (e.g. rendered with different transforms), so the
//! defaults are chosen by measurement.

use super::metrics::{compare, Metrics};
use crate::bundle::{Bundle, BundleError};
use crate::denoise::critical::Threshold;
use crate::denoise::{DenoiseParams, LoadedSums, Method};
use ndarray::Array4;
use std::path::PathBuf;

#[derive(Clone, Debug)]
pub struct SweepPoint {
    pub bundle: String,
    pub transform: String,
    pub gamma: f64,
    pub radius: usize,
    pub temporal_radius: usize,
    pub seconds: f64,
    pub all: Metrics,
    pub no_light: Metrics,
    /// The noisy mean's metrics on the same bundle, for scale.
    pub noisy: Metrics,
}

pub struct SweepConfig {
    pub bundles: Vec<PathBuf>,
    pub gammas: Vec<f64>,
    pub radii: Vec<usize>,
    pub temporal_radii: Vec<usize>,
    /// Everything else (base filter, sigmas) is taken from here.
    pub base: DenoiseParams,
}

pub fn run_sweep(
    cfg: &SweepConfig,
    reference: &Array4<f32>,
    log: &dyn Fn(&str),
) -> Result<Vec<SweepPoint>, BundleError> {
    let mut points = Vec::new();
    for path in &cfg.bundles {
        let bundle = Bundle::open(path)?;
        let m = &bundle.manifest;
        let shape = [m.height, m.width, m.bins, 3];
        if reference.shape() != shape {
            return Err(BundleError::Invalid(
                path.clone(),
                format!(
                    "shape {:?} does not match the reference's {:?}",
                    shape,
                    reference.shape()
                ),
            ));
        }
        let mask = super::volume::no_light_mask(&bundle.emitter()?);
        let sums = LoadedSums::read(&bundle)?;
        let noisy = bundle.noisy_mean()?;
        let (noisy_m, _) = compare(noisy.view(), reference.view(), None);
        for &gamma in &cfg.gammas {
            for &radius in &cfg.radii {
                for &temporal_radius in &cfg.temporal_radii {
                    let params = DenoiseParams {
                        radius,
                        temporal_radius,
                        method: Method::Published(Threshold::Gamma(gamma)),
                        ..cfg.base
                    };
                    let d = sums.denoise(&params, &|_| {});
                    let (all, _) = compare(d.volume.view(), reference.view(), None);
                    let (no_light, _) = compare(d.volume.view(), reference.view(), Some(&mask));
                    log(&format!(
                        "{}: gamma {gamma}, r {radius}, r_t {temporal_radius}: RMSE {:.4e} ({:.3} of noisy)",
                        path.display(),
                        all.rmse,
                        all.rmse / noisy_m.rmse
                    ));
                    points.push(SweepPoint {
                        bundle: path.display().to_string(),
                        transform: m.transform.to_string(),
                        gamma,
                        radius,
                        temporal_radius,
                        seconds: d.seconds,
                        all,
                        no_light,
                        noisy: noisy_m,
                    });
                }
            }
        }
    }
    Ok(points)
}
