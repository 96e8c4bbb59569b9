//! Writing a bundle: every array into a temporary directory beside the target, the
//! manifest last, then one rename. An interrupted write never looks complete.

use super::manifest::{ArrayInfo, Manifest, Program, SceneRef, FORMAT, VERSION};
use super::BundleError;
use crate::render::RenderOutput;
use crate::scene::Scene;
use crate::stats::accumulators::CHANNELS;
use crate::stats::Transform;
use ndarray::{Array2, Array3, Array4};
use ndarray_npy::{write_npy, WritableElement};
use std::path::{Path, PathBuf};

/// Metadata of the render that is not in the scene.
pub struct BundleMeta {
    pub seed: u64,
    pub transform: Transform,
    pub unit_m: f64,
    pub pixel_sampling: crate::render::PixelSampling,
}

/// Refuses an existing output unless `force`; call before spending time on a render.
pub fn check_output(out: &Path, force: bool) -> Result<(), BundleError> {
    if out.exists() && !force {
        return Err(BundleError::Exists(out.to_path_buf()));
    }
    if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
        if !parent.is_dir() {
            return Err(BundleError::Io(
                out.to_path_buf(),
                format!("the directory {} does not exist", parent.display()),
            ));
        }
    }
    Ok(())
}

/// Writes `value` to `final_path` through a temporary sibling and a rename.
pub fn write_atomically(
    final_path: &Path,
    force: bool,
    write: impl FnOnce(&Path) -> Result<(), BundleError>,
) -> Result<(), BundleError> {
    stage(final_path, force, write)?.commit()
}

/// An output written completely under a temporary sibling name, not yet in place:
/// [`Staged::commit`] renames it; dropped uncommitted, it is deleted. A command with
/// several outputs stages them all before committing any, so a failure in one leaves
/// none of them behind.
pub struct Staged {
    tmp: PathBuf,
    final_path: PathBuf,
    name: String,
    parent: PathBuf,
    force: bool,
    done: bool,
}

fn remove_any(p: &Path) {
    let _ = if p.is_dir() {
        std::fs::remove_dir_all(p)
    } else {
        std::fs::remove_file(p)
    };
}

/// Writes `final_path`'s content under a temporary sibling name (see [`Staged`]).
pub fn stage(
    final_path: &Path,
    force: bool,
    write: impl FnOnce(&Path) -> Result<(), BundleError>,
) -> Result<Staged, BundleError> {
    check_output(final_path, force)?;
    let name = final_path
        .file_name()
        .ok_or_else(|| BundleError::Io(final_path.to_path_buf(), "not a file name".into()))?
        .to_string_lossy()
        .into_owned();
    let parent = final_path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
        .to_path_buf();
    let tmp = parent.join(format!(".{name}.partial-{}", std::process::id()));
    remove_any(&tmp);
    let staged = Staged {
        tmp,
        final_path: final_path.to_path_buf(),
        name,
        parent,
        force,
        done: false,
    };
    write(&staged.tmp)?;
    Ok(staged)
}

impl Staged {
    /// Puts the output in place (replacing an older one only with `force`).
    pub fn commit(mut self) -> Result<(), BundleError> {
        self.done = true;
        let final_path = &self.final_path;
        let io = |e: std::io::Error| BundleError::Io(final_path.to_path_buf(), e.to_string());
        let result = if final_path.exists() {
            if !self.force {
                Err(BundleError::Exists(final_path.clone()))
            } else {
                // --force: move the old output aside, put the new one in place, then delete.
                let old = self
                    .parent
                    .join(format!(".{}.old-{}", self.name, std::process::id()));
                std::fs::rename(final_path, &old)
                    .map_err(io)
                    .and_then(|()| {
                        match std::fs::rename(&self.tmp, final_path) {
                            Ok(()) => {
                                remove_any(&old);
                                Ok(())
                            }
                            Err(e) => {
                                // Put the old output back rather than leave nothing.
                                let _ = std::fs::rename(&old, final_path);
                                Err(io(e))
                            }
                        }
                    })
            }
        } else {
            std::fs::rename(&self.tmp, final_path).map_err(io)
        };
        if result.is_err() {
            remove_any(&self.tmp);
        }
        result
    }
}

impl Drop for Staged {
    fn drop(&mut self) {
        if !self.done {
            remove_any(&self.tmp);
        }
    }
}

/// Writes one file through a temporary sibling and a rename, replacing an older file of
/// that name (for report outputs, which their commands check up front).
pub fn replace_file(
    path: &Path,
    write: impl FnOnce(&Path) -> Result<(), String>,
) -> Result<(), String> {
    write_atomically(path, true, |tmp| {
        write(tmp).map_err(|e| BundleError::Io(path.to_path_buf(), e))
    })
    .map_err(|e| e.to_string())
}

pub(crate) fn npy<A: WritableElement, D: ndarray::Dimension>(
    dir: &Path,
    name: &str,
    dtype: &str,
    array: &ndarray::Array<A, D>,
    arrays: &mut Vec<ArrayInfo>,
) -> Result<(), BundleError> {
    let file = format!("{name}.npy");
    let path: PathBuf = dir.join(&file);
    write_npy(&path, array).map_err(|e| BundleError::Io(path.clone(), e.to_string()))?;
    arrays.push(ArrayInfo {
        name: name.into(),
        file,
        dtype: dtype.into(),
        shape: array.shape().to_vec(),
    });
    Ok(())
}

/// Writes the bundle of a finished render to `out` (a directory, e.g. `NAME.tstats`).
pub fn write_bundle(
    out: &Path,
    force: bool,
    scene: &Scene,
    meta: &BundleMeta,
    output: RenderOutput,
) -> Result<Manifest, BundleError> {
    let film = &scene.film;
    let (h, w, t) = (film.height, film.width, film.bins);
    let shape4 = (h, w, t, CHANNELS);
    let mut manifest = Manifest {
        format: FORMAT.into(),
        version: VERSION,
        width: w,
        height: h,
        bins: t,
        channels: vec!["R".into(), "G".into(), "B".into()],
        spp: scene.spp as u64,
        start_opl: film.start_opl,
        bin_width_opl: film.bin_width_opl,
        unit_m: meta.unit_m,
        start_seconds: film.start_opl * meta.unit_m / super::manifest::C_M_PER_S,
        bin_width_seconds: film.bin_width_opl * meta.unit_m / super::manifest::C_M_PER_S,
        transform: meta.transform,
        pixel_sampling: meta.pixel_sampling.into(),
        seed: meta.seed,
        merged_seeds: Vec::new(),
        scene: SceneRef {
            path: scene.file.display().to_string(),
            sha256: scene.sha256.clone(),
        },
        max_depth: scene.integrator.max_depth,
        render_seconds: output.seconds,
        dropped_nonfinite: output.dropped_nonfinite,
        program: Program {
            name: "tstat".into(),
            version: env!("CARGO_PKG_VERSION").into(),
        },
        arrays: Vec::new(),
    };
    let shape_err = |e: ndarray::ShapeError| BundleError::Io(out.to_path_buf(), e.to_string());
    let acc = output.accum;
    let g = &output.gbuffer;
    let written = &mut manifest;
    write_atomically(out, force, |dir| {
        std::fs::create_dir(dir).map_err(|e| BundleError::Io(dir.to_path_buf(), e.to_string()))?;
        let arrays = &mut written.arrays;
        npy(
            dir,
            "x1",
            "<f8",
            &Array4::from_shape_vec(shape4, acc.x1).map_err(shape_err)?,
            arrays,
        )?;
        npy(
            dir,
            "x2",
            "<f8",
            &Array4::from_shape_vec(shape4, acc.x2).map_err(shape_err)?,
            arrays,
        )?;
        npy(
            dir,
            "x3",
            "<f8",
            &Array4::from_shape_vec(shape4, acc.x3).map_err(shape_err)?,
            arrays,
        )?;
        if let Some(s) = acc.sum {
            npy(
                dir,
                "sum",
                "<f8",
                &Array4::from_shape_vec(shape4, s).map_err(shape_err)?,
                arrays,
            )?;
        }
        npy(
            dir,
            "nonzero",
            "<u4",
            &Array3::from_shape_vec((h, w, t), acc.nonzero).map_err(shape_err)?,
            arrays,
        )?;
        let albedo: Vec<f32> = g.iter().flat_map(|p| p.albedo).collect();
        let normal: Vec<f32> = g.iter().flat_map(|p| p.normal).collect();
        let depth: Vec<f32> = g.iter().map(|p| p.depth).collect();
        let emitter: Vec<f32> = g.iter().map(|p| p.emitter).collect();
        npy(
            dir,
            "albedo",
            "<f4",
            &Array3::from_shape_vec((h, w, 3), albedo).map_err(shape_err)?,
            arrays,
        )?;
        npy(
            dir,
            "normal",
            "<f4",
            &Array3::from_shape_vec((h, w, 3), normal).map_err(shape_err)?,
            arrays,
        )?;
        npy(
            dir,
            "depth",
            "<f4",
            &Array2::from_shape_vec((h, w), depth).map_err(shape_err)?,
            arrays,
        )?;
        npy(
            dir,
            "emitter",
            "<f4",
            &Array2::from_shape_vec((h, w), emitter).map_err(shape_err)?,
            arrays,
        )?;
        npy(
            dir,
            "steady",
            "<f8",
            &Array3::from_shape_vec((h, w, CHANNELS), output.steady).map_err(shape_err)?,
            arrays,
        )?;
        let json = serde_json::to_string_pretty(&*written).expect("manifest serialises");
        let mpath = dir.join("manifest.json");
        std::fs::write(&mpath, json).map_err(|e| BundleError::Io(mpath, e.to_string()))
    })?;
    Ok(manifest)
}
