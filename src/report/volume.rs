//! Loading the volumes a report compares: `.npy` arrays (f32 or f64, (H, W, T, C)) or
//! bundles (their noisy mean).

use crate::bundle::{Bundle, BundleError};
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

pub fn load_volume(path: &Path) -> Result<LoadedVolume, BundleError> {
    if path.is_dir() {
        let b = Bundle::open(path)?;
        return Ok(LoadedVolume {
            volume: b.noisy_mean()?,
            no_light_mask: Some(no_light_mask(&b.emitter()?)),
        });
    }
    if !path.is_file() {
        return Err(BundleError::Io(
            path.to_path_buf(),
            "no such file or bundle".into(),
        ));
    }
    let err = |e: String| BundleError::Volume(path.to_path_buf(), e);
    let volume = match ndarray_npy::read_npy::<_, Array4<f32>>(path) {
        Ok(v) => v,
        Err(as_f32) => match ndarray_npy::read_npy::<_, Array4<f64>>(path) {
            Ok(v) => v.mapv(|x| x as f32),
            Err(as_f64) => {
                return Err(err(format!(
                    "not a 4-D f32/f64 .npy volume (H, W, T, C): as f32: {as_f32}; as f64: {as_f64}"
                )))
            }
        },
    };
    if volume.shape()[3] != 3 {
        return Err(err(format!(
            "expected 3 channels, shape is {:?}",
            volume.shape()
        )));
    }
    Ok(LoadedVolume {
        volume,
        no_light_mask: None,
    })
}
