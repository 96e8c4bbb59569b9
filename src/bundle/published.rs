//! The published pipeline's arrays as a folder of `.npy` files: what its renderer (a
//! mitransient fork) returns and its denoiser (`StatDenoiser`) takes, named as its
//! example notebook names them, each (H, W, T, 3) or (H, W, 3) f32:
//!
//! | file | what |
//! |---|---|
//! | `noisy.npy` | the linear noisy video S / n, (H, W, T, C) |
//! | `estimands.npy` | theta, the skewness-corrected mean of the transformed samples |
//! | `estimands_variance.npy` | V = sigma2 / n, the variance of theta's estimate |
//! | `albedo.npy`, `normals.npy` | the AOVs, (H, W, 3) |
//!
//! tstat adds what its own filter uses, each optional: `depth.npy` and `emitter.npy`
//! ((H, W): camera depth, the fraction of samples that saw an emitter),
//! `pixel_spp.npy` ((H, W) u32, adaptive renders), and `meta.json` (`spp`,
//! `transform`, `stratified`, `bin_width_opl`). `tstat export --published` writes all
//! of them from a bundle; `tstat denoise --from-arrays` reads them (the published
//! pipeline's five alone need `--spp`). Every file is read through the hardened reader
//! (`float_rows`, `npy`): shapes, dtypes and finiteness are checked, with the file and
//! index named.
//!
//! Memory: reading holds the three volumes whole (12 bytes a voxel-channel).

use super::float_rows::FloatRows;
use super::npy::{self, first_bad};
use super::read::Bundle;
use super::BundleError;
use crate::stats::accumulators::CHANNELS;
use crate::stats::Transform;
use ndarray::{Array2, Array3, Array4};
use std::path::{Path, PathBuf};

/// What the arrays do not say themselves (`meta.json`).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PublishedMeta {
    /// Samples per pixel behind the estimates (the mean for adaptive renders).
    pub spp: u64,
    /// The transform theta and V are in (`yeo-johnson:0.5` in the published pipeline).
    pub transform: String,
    /// Sub-pixel positions were stratified (then V over-estimates the variance).
    #[serde(default)]
    pub stratified: bool,
    /// The bin width in OPL (for tstat's camera-depth alignment, with `depth.npy`).
    #[serde(default)]
    pub bin_width_opl: Option<f64>,
}

/// The arrays, checked against each other.
pub struct PublishedArrays {
    pub noisy: Array4<f32>,
    pub estimands: Array4<f32>,
    pub variance: Array4<f32>,
    pub albedo: Array3<f32>,
    pub normals: Array3<f32>,
    pub depth: Option<Array2<f32>>,
    pub emitter: Option<Array2<f32>>,
    pub pixel_spp: Option<Vec<u32>>,
    /// `meta.json`, if the folder has one.
    pub meta: Option<PublishedMeta>,
}

#[derive(Debug, thiserror::Error)]
pub enum PublishedError {
    #[error("{}: {source}", path.display())]
    Npy {
        path: PathBuf,
        #[source]
        source: npy::NpyError,
    },
    #[error("{}: shape {found:?}, but {expected}", path.display())]
    Shape {
        path: PathBuf,
        found: Vec<usize>,
        expected: String,
    },
    #[error("{}: {why}", path.display())]
    Value { path: PathBuf, why: String },
    #[error("{}: {why}", path.display())]
    Meta { path: PathBuf, why: String },
}

fn read_float(path: &Path) -> Result<(Vec<usize>, Vec<f32>), PublishedError> {
    let err = |source| PublishedError::Npy {
        path: path.to_path_buf(),
        source,
    };
    let mut f = FloatRows::open(path).map_err(err)?;
    let shape = f.shape().to_vec();
    let axes: &[&str] = match shape.len() {
        4 => &["y", "x", "t", "c"],
        3 => &["y", "x", "c"],
        _ => &["y", "x"],
    };
    let mut data = Vec::new();
    f.read_rows(0..shape.first().copied().unwrap_or(0), &mut data, axes)
        .map_err(err)?;
    Ok((shape, data))
}

fn shaped<D: ndarray::Dimension>(
    path: &Path,
    (shape, data): (Vec<usize>, Vec<f32>),
    want: &[usize],
    what: &str,
) -> Result<ndarray::Array<f32, D>, PublishedError> {
    if shape != want {
        return Err(PublishedError::Shape {
            path: path.to_path_buf(),
            found: shape,
            expected: format!("{what} must be {want:?} (from noisy.npy)"),
        });
    }
    let a = ndarray::ArrayD::from_shape_vec(shape, data).expect("the header's shape");
    Ok(a.into_dimensionality::<D>().expect("checked rank"))
}

impl PublishedArrays {
    /// Reads the folder `dir` (see the module docs). The video's shape (H, W, T, 3)
    /// fixes every other array's; V must be at least 0.
    pub fn read(dir: &Path) -> Result<PublishedArrays, PublishedError> {
        let file = |name: &str| dir.join(name);
        let noisy_path = file("noisy.npy");
        let (shape, data) = read_float(&noisy_path)?;
        if shape.len() != 4 || shape[3] != CHANNELS || shape[..3].contains(&0) {
            return Err(PublishedError::Shape {
                path: noisy_path,
                found: shape,
                expected: "the video must be (H, W, T, 3) with H, W, T at least 1".into(),
            });
        }
        let s4 = shape.clone();
        let s3 = [shape[0], shape[1], 3];
        let s2 = [shape[0], shape[1]];
        let noisy = shaped(&noisy_path, (shape, data), &s4, "the video")?;
        let vol = |name: &str| {
            let p = file(name);
            let r = read_float(&p)?;
            shaped::<ndarray::Ix4>(&p, r, &s4, "a volume")
        };
        let estimands = vol("estimands.npy")?;
        let variance = vol("estimands_variance.npy")?;
        if let Some(i) = variance.iter().position(|&v| v < 0.0) {
            let idx = npy::unravel(i, &s4);
            return Err(PublishedError::Value {
                path: file("estimands_variance.npy"),
                why: format!(
                    "{} is {}, but a variance is at least 0",
                    npy::describe_index(&["y", "x", "t", "c"], &idx),
                    variance.as_slice().expect("standard layout")[i]
                ),
            });
        }
        let image = |name: &str| {
            let p = file(name);
            let r = read_float(&p)?;
            shaped::<ndarray::Ix3>(&p, r, &s3, "an AOV")
        };
        let optional = |name: &str| -> Result<Option<Array2<f32>>, PublishedError> {
            let p = file(name);
            if !p.exists() {
                return Ok(None);
            }
            let r = read_float(&p)?;
            shaped::<ndarray::Ix2>(&p, r, &s2, "a per-pixel image").map(Some)
        };
        let pixel_spp = {
            let p = file("pixel_spp.npy");
            if p.exists() {
                let f = npy::open(&p).map_err(|source| PublishedError::Npy {
                    path: p.clone(),
                    source,
                })?;
                f.header
                    .expect::<u32>(Some(&s2))
                    .map_err(|source| PublishedError::Npy {
                        path: p.clone(),
                        source,
                    })?;
                let check = |s: usize, b: &[u32]| {
                    first_bad(
                        s,
                        b,
                        |_, v| v >= 2,
                        |_, v| format!("is {v}, but a pixel has at least 2 samples"),
                    )
                };
                Some(
                    f.read::<u32>(check, &["y", "x"])
                        .map_err(|source| PublishedError::Npy { path: p, source })?,
                )
            } else {
                None
            }
        };
        let meta_path = file("meta.json");
        let meta = if meta_path.exists() {
            let text = crate::io::read_regular_text(&meta_path, crate::io::MAX_MANIFEST_BYTES)
                .map_err(|e| PublishedError::Meta {
                    path: meta_path.clone(),
                    why: e.to_string(),
                })?;
            Some(
                serde_json::from_str(&text).map_err(|e| PublishedError::Meta {
                    path: meta_path.clone(),
                    why: e.to_string(),
                })?,
            )
        } else {
            None
        };
        Ok(PublishedArrays {
            noisy,
            estimands,
            variance,
            albedo: image("albedo.npy")?,
            normals: image("normals.npy")?,
            depth: optional("depth.npy")?,
            emitter: optional("emitter.npy")?,
            pixel_spp,
            meta,
        })
    }
}

/// Writes the published pipeline's arrays of `bundle`, and tstat's extras, into a new
/// folder `tmp` (the caller stages it: `write::stage`; errors name `dir`, the folder's
/// final name). theta and V are in the bundle's transform (`yeo-johnson:0.5` is the
/// published pipeline's).
pub fn write_into(bundle: &Bundle, tmp: &Path, dir: &Path) -> Result<(), BundleError> {
    let m = &bundle.manifest;
    let io = |e: std::io::Error| BundleError::io(dir, e);
    std::fs::create_dir(tmp).map_err(io)?;
    save(tmp, dir, "noisy.npy", &bundle.noisy_mean()?)?;
    let e = bundle.estimates()?;
    save(tmp, dir, "estimands.npy", &e.theta)?;
    save(tmp, dir, "estimands_variance.npy", &e.variance)?;
    drop(e);
    save(tmp, dir, "albedo.npy", &bundle.albedo()?)?;
    save(tmp, dir, "normals.npy", &bundle.normal()?)?;
    save(tmp, dir, "depth.npy", &bundle.depth()?)?;
    save(tmp, dir, "emitter.npy", &bundle.emitter()?)?;
    if let Some(n) = &bundle.pixel_spp {
        let a = Array2::from_shape_vec((m.height, m.width), n.clone()).expect("checked on open");
        save(tmp, dir, "pixel_spp.npy", &a)?;
    }
    let meta = PublishedMeta {
        spp: m.spp,
        transform: m.transform.to_string(),
        // As the denoiser reads a bundle (`denoise::slab::stratified`).
        stratified: m.pixel_sampling != super::manifest::SamplingRecord::Independent
            && m.replicates.is_none(),
        bin_width_opl: Some(m.bin_width_opl),
    };
    let text = serde_json::to_string_pretty(&meta).expect("plain fields");
    std::fs::write(tmp.join("meta.json"), text + "\n").map_err(io)
}

/// Writes `a` as `tmp/name` (errors name `dir/name`).
fn save<T: ndarray_npy::WritableElement, D: ndarray::Dimension>(
    tmp: &Path,
    dir: &Path,
    name: &str,
    a: &ndarray::Array<T, D>,
) -> Result<(), BundleError> {
    ndarray_npy::write_npy(tmp.join(name), a)
        .map_err(|e| BundleError::io(dir.join(name), std::io::Error::other(e)))
}

/// The transform of `meta` (or `given`, which wins), checked.
pub fn transform_of(
    given: Option<&str>,
    meta: Option<&PublishedMeta>,
) -> Result<Transform, String> {
    let text = given
        .map(str::to_string)
        .or_else(|| meta.map(|m| m.transform.clone()))
        .unwrap_or_else(|| "yeo-johnson:0.5".to_string());
    text.parse::<Transform>()
        .map_err(|e| format!("--transform {text}: {e}"))
}
