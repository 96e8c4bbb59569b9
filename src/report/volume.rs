//! Loading the volumes a report compares: `.npy` arrays (f32 or f64, (H, W, T, C)) or
//! bundles (their noisy mean).

use super::ReportError;
use crate::bundle::{npy, Bundle};
use ndarray::{Array2, Array4};
use std::path::Path;

/// A volume and, when it came from a bundle, the pixels that see a light directly.
pub struct LoadedVolume {
    pub volume: Array4<f32>,
    /// Per pixel (H x W): true where no sample's first non-delta vertex was an emitter.
    pub no_light_mask: Option<Vec<bool>>,
}

pub fn no_light_mask(emitter: &Array2<f32>) -> Vec<bool> {
    emitter.iter().map(|&e| e == 0.0).collect()
}

/// Loads a volume: a bundle's noisy mean (checked as every bundle read is), or a
/// `.npy` of f32 or f64 (H, W, T, C) with C = 3 (RGB), 1 (mono), 4 (a Stokes volume:
/// S0, S1, S2, S3) or 12, or (H, W, T, 3, 4) (a spectral Stokes volume, RGB x Stokes,
/// read as 12 channels RGB-major as its bundle holds them). A `.npy` is checked before its data are
/// allocated (header against the file's size, see `bundle::npy`), must hold at least
/// one voxel, and every value must be finite (as f32: an f64 beyond the f32 range
/// counts as infinite). Errors would otherwise pass silently into the metrics: a NaN
/// reference gave an infinite PSNR, an empty one a zero RMSE.
pub fn load_volume(path: &Path) -> Result<LoadedVolume, ReportError> {
    if path.is_dir() {
        let b = Bundle::open(path)?;
        return Ok(LoadedVolume {
            volume: b.noisy_mean()?,
            no_light_mask: Some(no_light_mask(&b.emitter()?)),
        });
    }
    if !path.exists() {
        return Err(ReportError::NoSuchVolume(path.to_path_buf()));
    }
    let err = |error| ReportError::Npy {
        path: path.to_path_buf(),
        error,
    };
    let f = npy::open(path).map_err(err)?;
    let shape = f.header.shape.clone();
    let stokes_rgb = shape.len() == 5 && shape[3..] == [3, 4];
    if !(stokes_rgb || shape.len() == 4 && [1, 3, 4, 12].contains(&shape[3])) {
        return Err(ReportError::NotAVolume {
            path: path.to_path_buf(),
            shape,
        });
    }
    let channels = if stokes_rgb { 12 } else { shape[3] };
    if f.header.len == 0 {
        return Err(ReportError::EmptyVolume {
            path: path.to_path_buf(),
            shape,
        });
    }
    let axes: &[&str] = if stokes_rgb {
        &["y", "x", "t", "c", "s"]
    } else {
        &["y", "x", "t", "c"]
    };
    let why = |_: usize, v: f64| format!("is {}", npy::show(v));
    let data = match f.header.dtype.as_str() {
        "<f4" => f.read::<f32>(
            |s, b| npy::first_bad(s, b, |_, v| v.is_finite(), |i, v| why(i, v.into())),
            axes,
        ),
        "<f8" => f.read_mapped::<f64, f32>(
            |v| v as f32,
            |s, b| {
                npy::first_bad(
                    s,
                    b,
                    |_, v| (v as f32).is_finite(),
                    |i, v| {
                        if v.is_finite() {
                            format!("is {}, beyond the f32 range of a volume", npy::show(v))
                        } else {
                            why(i, v)
                        }
                    },
                )
            },
            axes,
        ),
        d => {
            return Err(ReportError::VolumeDtype {
                path: path.to_path_buf(),
                dtype: d.to_string(),
            })
        }
    }
    .map_err(err)?;
    let volume = Array4::from_shape_vec((shape[0], shape[1], shape[2], channels), data)
        .map_err(|e| err(npy::NpyError::Layout(e)))?;
    Ok(LoadedVolume {
        volume,
        no_light_mask: None,
    })
}
