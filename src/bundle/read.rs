//! Reading a bundle: the manifest is checked first (format, version, sizes), then each
//! array on demand, checked against the shape the manifest promises.

use super::manifest::{Manifest, FORMAT, VERSION};
use super::BundleError;
use crate::stats::accumulators::CHANNELS;
use crate::stats::estimators::check_spp;
use ndarray::{Array, Array2, Array3, Array4, Dimension};
use ndarray_npy::{read_npy, ReadableElement};
use std::path::{Path, PathBuf};

pub struct Bundle {
    pub dir: PathBuf,
    pub manifest: Manifest,
}

impl Bundle {
    pub fn open(dir: &Path) -> Result<Bundle, BundleError> {
        let mpath = dir.join("manifest.json");
        if !dir.is_dir() {
            return Err(BundleError::Invalid(
                dir.to_path_buf(),
                "not a bundle directory".into(),
            ));
        }
        let text = std::fs::read_to_string(&mpath)
            .map_err(|e| BundleError::Invalid(mpath.clone(), format!("cannot read: {e}")))?;
        let value: serde_json::Value = serde_json::from_str(&text)
            .map_err(|e| BundleError::Invalid(mpath.clone(), format!("not valid JSON: {e}")))?;
        if value.get("format").and_then(|f| f.as_str()) != Some(FORMAT) {
            return Err(BundleError::Invalid(
                mpath,
                format!("not a '{FORMAT}' manifest"),
            ));
        }
        let version = value.get("version").and_then(|v| v.as_u64());
        if version != Some(VERSION as u64) {
            return Err(BundleError::Invalid(
                mpath,
                format!("format version {version:?} is not the supported version {VERSION}"),
            ));
        }
        let manifest: Manifest = serde_json::from_value(value)
            .map_err(|e| BundleError::Invalid(mpath.clone(), format!("bad manifest: {e}")))?;
        manifest
            .transform
            .validate()
            .map_err(|e| BundleError::Invalid(mpath.clone(), format!("transform: {e}")))?;
        if manifest.width == 0 || manifest.height == 0 || manifest.bins == 0 {
            return Err(BundleError::Invalid(mpath, "empty film size".into()));
        }
        let finite_positive = |v: f64| v > 0.0 && v.is_finite();
        let axis_ok = finite_positive(manifest.bin_width_opl)
            && finite_positive(manifest.unit_m)
            && manifest.start_opl.is_finite();
        if !axis_ok {
            return Err(BundleError::Invalid(
                mpath,
                "bad time axis (bin_width_opl and unit_m must be positive, start_opl finite)"
                    .into(),
            ));
        }
        if manifest.channels.len() != CHANNELS {
            return Err(BundleError::Invalid(mpath, "expected 3 channels".into()));
        }
        check_spp(manifest.spp).map_err(|e| BundleError::Invalid(mpath.clone(), e))?;
        Ok(Bundle {
            dir: dir.to_path_buf(),
            manifest,
        })
    }

    fn read<A: ReadableElement + Clone, D: Dimension>(
        &self,
        name: &str,
        shape: &[usize],
    ) -> Result<Array<A, D>, BundleError> {
        let info = self.manifest.array(name).ok_or_else(|| {
            BundleError::Invalid(
                self.dir.join("manifest.json"),
                format!("lists no array '{name}'"),
            )
        })?;
        let path = self.dir.join(&info.file);
        if !path.is_file() {
            return Err(BundleError::Invalid(path, "missing".into()));
        }
        let a: Array<A, D> =
            read_npy(&path).map_err(|e| BundleError::Invalid(path.clone(), e.to_string()))?;
        // NumPy may write Fortran order; everything downstream reads C order.
        let a = if a.is_standard_layout() {
            a
        } else {
            a.as_standard_layout().into_owned()
        };
        if a.shape() != shape {
            return Err(BundleError::Invalid(
                path,
                format!(
                    "shape {:?} does not match the manifest's {:?}",
                    a.shape(),
                    shape
                ),
            ));
        }
        Ok(a)
    }

    fn shape4(&self) -> [usize; 4] {
        let m = &self.manifest;
        [m.height, m.width, m.bins, CHANNELS]
    }

    pub fn x1(&self) -> Result<Array4<f64>, BundleError> {
        self.read("x1", &self.shape4())
    }
    pub fn x2(&self) -> Result<Array4<f64>, BundleError> {
        self.read("x2", &self.shape4())
    }
    pub fn x3(&self) -> Result<Array4<f64>, BundleError> {
        self.read("x3", &self.shape4())
    }
    /// Raw radiance sums S (X1 itself for the identity transform).
    pub fn radiance_sum(&self) -> Result<Array4<f64>, BundleError> {
        if self.manifest.transform.is_identity() {
            self.x1()
        } else {
            self.read("sum", &self.shape4())
        }
    }
    pub fn nonzero(&self) -> Result<Array3<u32>, BundleError> {
        let m = &self.manifest;
        self.read("nonzero", &[m.height, m.width, m.bins])
    }
    pub fn albedo(&self) -> Result<Array3<f32>, BundleError> {
        let m = &self.manifest;
        self.read("albedo", &[m.height, m.width, 3])
    }
    pub fn normal(&self) -> Result<Array3<f32>, BundleError> {
        let m = &self.manifest;
        self.read("normal", &[m.height, m.width, 3])
    }
    pub fn depth(&self) -> Result<Array2<f32>, BundleError> {
        let m = &self.manifest;
        self.read("depth", &[m.height, m.width])
    }
    pub fn emitter(&self) -> Result<Array2<f32>, BundleError> {
        let m = &self.manifest;
        self.read("emitter", &[m.height, m.width])
    }
    pub fn steady(&self) -> Result<Array3<f64>, BundleError> {
        let m = &self.manifest;
        self.read("steady", &[m.height, m.width, CHANNELS])
    }

    /// The noisy mean volume S / n as f32, (H, W, T, C).
    pub fn noisy_mean(&self) -> Result<Array4<f32>, BundleError> {
        let n = self.manifest.spp as f64;
        Ok(self.radiance_sum()?.mapv(|s| (s / n) as f32))
    }
}
