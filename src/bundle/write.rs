//! Writing a bundle: every array into a temporary directory beside the target, the
//! manifest last, then one rename. An interrupted write never looks complete.
//!
//! Two writers give byte-identical files: [`write_bundle`] writes a render held in
//! memory; [`BundleWriter`] is a [`RowSink`] that writes each finished row of a running
//! render straight into its place in the preallocated `.npy` files (positioned writes;
//! Linux/Unix), so a film larger than memory streams to disk.

use super::manifest::{
    AdaptiveRecord, ArrayInfo, Manifest, Program, SceneRef, FORMAT, VERSION, VERSION_UNIFORM,
};
use super::{BundleError, RowSums};
use crate::render::gbuffer::GPixel;
use crate::render::sink::{PixelImages, Row, RowSink};
use crate::render::{RenderOutput, RenderSummary};
use crate::scene::Scene;
use crate::sensors::film::Film;
use crate::stats::Transform;
use ndarray::{Array2, Array3, Array4};
use ndarray_npy::npy::header::{Header, Layout};
use ndarray_npy::{write_npy, WritableElement};
use std::fs::File;
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, PoisonError};

// The streamed rows are written as the machine's bytes into little-endian .npy arrays.
#[cfg(not(target_endian = "little"))]
compile_error!("bundle::write::BundleWriter assumes a little-endian machine");

/// Metadata of the render that is not in the scene.
pub struct BundleMeta {
    pub seed: u64,
    pub transform: Transform,
    pub unit_m: f64,
    pub pixel_sampling: crate::render::PixelSampling,
    /// Replicates per pixel B (0: none; then no `r2.npy`).
    pub replicates: u32,
    /// The job this render is a shard of (`--shard`), if any.
    pub job: Option<JobShard>,
    /// Adaptive sampling: each pixel's samples (row-major) and the record of how they
    /// were chosen; `None` for uniform renders.
    pub adaptive: Option<(std::sync::Arc<[u32]>, AdaptiveRecord)>,
}

/// A shard's job: the shard, and the job's own seed, spp and replicates (the render's
/// are the shard's share).
#[derive(Clone, Copy, Debug)]
pub struct JobShard {
    pub shard: super::shard::Shard,
    pub seed: u64,
    pub spp: u64,
    pub replicates: u32,
}

/// Refuses an existing output unless `force`; call before spending time on a render.
pub fn check_output(out: &Path, force: bool) -> Result<(), BundleError> {
    if out.exists() && !force {
        return Err(BundleError::Exists(out.to_path_buf()));
    }
    if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
        if !parent.is_dir() {
            return Err(BundleError::NoParent(
                out.to_path_buf(),
                parent.to_path_buf(),
            ));
        }
    }
    Ok(())
}

/// Writes `value` to `final_path` through a temporary sibling and a rename. `write`'s
/// error is returned as it is.
pub fn write_atomically<E: From<BundleError>>(
    final_path: &Path,
    force: bool,
    write: impl FnOnce(&Path) -> Result<(), E>,
) -> Result<(), E> {
    stage(final_path, force, write)?.commit()?;
    Ok(())
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
/// `write`'s error is returned as it is.
pub fn stage<E: From<BundleError>>(
    final_path: &Path,
    force: bool,
    write: impl FnOnce(&Path) -> Result<(), E>,
) -> Result<Staged, E> {
    check_output(final_path, force)?;
    let name = final_path
        .file_name()
        .ok_or_else(|| BundleError::NotAFileName(final_path.to_path_buf()))?
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
    /// The temporary path the output is written under.
    pub fn path(&self) -> &Path {
        &self.tmp
    }

    /// Puts the output in place (replacing an older one only with `force`).
    pub fn commit(mut self) -> Result<(), BundleError> {
        self.done = true;
        let final_path = &self.final_path;
        let io = |e: std::io::Error| BundleError::io(final_path, e);
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
/// that name (for report outputs, which their commands check up front). An error of
/// `write` becomes [`BundleError::Io`] of `path`.
pub fn replace_file<E: Into<Box<dyn std::error::Error + Send + Sync>>>(
    path: &Path,
    write: impl FnOnce(&Path) -> Result<(), E>,
) -> Result<(), BundleError> {
    write_atomically(path, true, |tmp| {
        write(tmp).map_err(|e| BundleError::io(path, e))
    })
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
    write_npy(&path, array).map_err(|e| BundleError::io(&path, e))?;
    arrays.push(ArrayInfo {
        name: name.into(),
        file,
        dtype: dtype.into(),
        shape: array.shape().to_vec(),
    });
    Ok(())
}

/// The manifest of a render of `scene`, without its array list.
fn manifest(scene: &Scene, meta: &BundleMeta, seconds: f64, dropped_nonfinite: u64) -> Manifest {
    let film = &scene.film;
    let mut m = Manifest {
        format: FORMAT.into(),
        version: if meta.adaptive.is_some() {
            VERSION
        } else {
            VERSION_UNIFORM
        },
        width: film.width,
        height: film.height,
        bins: film.time.bins,
        channels: scene
            .mode
            .channel_names()
            .iter()
            .map(|&c| c.into())
            .collect(),
        mode: scene.mode,
        spp: scene.spp as u64,
        start_opl: film.time.start_opl,
        bin_width_opl: film.time.bin_width_opl,
        unit_m: meta.unit_m,
        start_seconds: film.time.start_opl * meta.unit_m / super::manifest::C_M_PER_S,
        bin_width_seconds: film.time.bin_width_opl * meta.unit_m / super::manifest::C_M_PER_S,
        transform: meta.transform,
        time_origin: scene.camera.time_origin(),
        // The f32's shortest decimal (0.001, not 0.0010000000474974513).
        near_clip: scene
            .camera
            .near_clip
            .map(|d| d.to_string().parse().unwrap_or(f64::from(d))),
        pixel_sampling: meta.pixel_sampling.into(),
        replicates: (meta.replicates >= 2).then_some(u64::from(meta.replicates)),
        media: !scene.media.is_empty(),
        seed: meta.seed,
        merged_seeds: Vec::new(),
        scene: SceneRef {
            path: scene.file.display().to_string(),
            sha256: scene.sha256.clone(),
            identity: Some(scene.identity.clone()),
        },
        max_depth: scene.integrator.max_depth,
        time_filter_stddev_bins: scene.integrator.time_filter.stddev_bins(),
        render_seconds: seconds,
        dropped_nonfinite,
        program: Program {
            name: "tstat".into(),
            version: env!("CARGO_PKG_VERSION").into(),
        },
        arrays: Vec::new(),
        shard: None,
        nlos: super::capture::CaptureRecord::of_scene(scene),
        adaptive: meta.adaptive.as_ref().map(|(_, r)| r.clone()),
    };
    if let Some(j) = &meta.job {
        m.shard = Some(job_record(&m, j));
    }
    m
}

/// The record of shard `j` of the job whose shard renders `m`: the job's identity is a
/// hash of `m` with the job's seed, spp and replicates in place of the shard's, without
/// what may differ between its shards (the scene's path, times), and with N.
fn job_record(m: &Manifest, j: &JobShard) -> super::shard::ShardRecord {
    let mut key = m.clone();
    key.seed = j.seed;
    key.spp = j.spp;
    key.replicates = (j.replicates >= 2).then_some(u64::from(j.replicates));
    key.scene.path = String::new();
    key.render_seconds = 0.0;
    key.dropped_nonfinite = 0;
    // Shards of an adaptive job share the allocation (the job's pilot), each with
    // its share of the counts: the measure and the pilot identify the job.
    if let Some(a) = key.adaptive.as_mut() {
        a.pilot_seconds = 0.0;
        (a.min_spp, a.max_spp) = (0, 0);
        a.estimated_error = None;
    }
    let json = serde_json::to_string(&key).expect("manifest serialises");
    super::shard::ShardRecord {
        job: super::shard::job_id(&format!("{json}\nshards {}", j.shard.count)),
        count: j.shard.count,
        indices: vec![j.shard.index],
    }
}

/// Writes the per-pixel arrays (G-buffers, steady image) of an (H, W) render into `dir`.
fn write_pixel_arrays(
    dir: &Path,
    (h, w): (usize, usize),
    g: &[GPixel],
    steady: Vec<f64>,
    media: bool,
    arrays: &mut Vec<ArrayInfo>,
) -> Result<(), BundleError> {
    let channels = steady.len() / (h * w).max(1);
    let shape_err = |e: ndarray::ShapeError| BundleError::io(dir, e);
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
    if media {
        let medium: Vec<f32> = g.iter().map(|p| p.medium).collect();
        npy(
            dir,
            "medium",
            "<f4",
            &Array2::from_shape_vec((h, w), medium).map_err(shape_err)?,
            arrays,
        )?;
    }
    npy(
        dir,
        "steady",
        "<f8",
        &Array3::from_shape_vec((h, w, channels), steady).map_err(shape_err)?,
        arrays,
    )
}

/// Writes the manifest, last: a bundle directory without one is not a bundle. The
/// manifest is checked as the reader checks it ([`super::read::manifest_json`]) and
/// refused, naming `out` (the bundle being written), unless it reads back as written.
pub(crate) fn write_manifest(
    dir: &Path,
    out: &Path,
    manifest: &Manifest,
) -> Result<(), BundleError> {
    let json = super::read::manifest_json(manifest)
        .map_err(|p| BundleError::Unwritable(out.to_path_buf(), Box::new(p)))?;
    let mpath = dir.join("manifest.json");
    std::fs::write(&mpath, json).map_err(|e| BundleError::io(mpath, e))
}

/// Refuses, before any rendering work, a render of `scene` with `meta` into `out`
/// whose manifest the reader would refuse (a capture record with a position beyond
/// the bounds, a time axis that overflows, a `-D` value or scene path holding a
/// control character, ...): the manifest the render will write, with the arrays it
/// will list (its times and counts are not known yet, and never invalid), is checked
/// by the same function as the written one. `recorded` is the scene path the
/// manifest will record (`scene.file`, or where `tstat run` moves the scene).
pub fn check_render(
    out: &Path,
    scene: &Scene,
    recorded: &Path,
    meta: &BundleMeta,
) -> Result<(), BundleError> {
    let mut m = manifest(scene, meta, 0.0, 0);
    m.scene.path = recorded.display().to_string();
    check_planned(out, &m)
}

/// Refuses `m`, the manifest of a bundle about to be written to `out` without its
/// array list, unless it will read back once the bundle's arrays are listed (see
/// [`check_render`]; `merge` checks its output's manifest with it before merging).
pub(crate) fn check_planned(out: &Path, m: &Manifest) -> Result<(), BundleError> {
    let mut m = m.clone();
    m.arrays = super::read::required_arrays(&m)
        .into_iter()
        .map(|(name, dtype, shape)| ArrayInfo {
            name: name.into(),
            file: format!("{name}.npy"),
            dtype: dtype.into(),
            shape,
        })
        .collect();
    super::read::manifest_json(&m)
        .map(|_| ())
        .map_err(|p| BundleError::Unwritable(out.to_path_buf(), Box::new(p)))
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
    let (h, w, t) = (film.height, film.width, film.time.bins);
    let shape4 = (h, w, t, film.channels);
    let mut manifest = manifest(scene, meta, output.seconds, output.dropped_nonfinite);
    let shape_err = |e: ndarray::ShapeError| BundleError::io(out, e);
    let acc = output.accum;
    let written = &mut manifest;
    write_atomically(out, force, |dir| {
        std::fs::create_dir(dir).map_err(|e| BundleError::io(dir, e))?;
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
        if let Some(r2) = acc.r2 {
            npy(
                dir,
                "r2",
                "<f8",
                &Array4::from_shape_vec(shape4, r2).map_err(shape_err)?,
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
        let media = written.media;
        write_pixel_arrays(dir, (h, w), &output.gbuffer, output.steady, media, arrays)?;
        write_manifest(dir, out, written)
    })?;
    Ok(manifest)
}

/// The volume arrays of a bundle, in manifest order: name, dtype, whether it has the
/// channel axis, and its element size.
fn volume_arrays(
    transform: &Transform,
    replicates: bool,
) -> Vec<(&'static str, &'static str, bool, usize)> {
    let mut v = vec![
        ("x1", "<f8", true, 8),
        ("x2", "<f8", true, 8),
        ("x3", "<f8", true, 8),
    ];
    if !transform.is_identity() {
        v.push(("sum", "<f8", true, 8));
    }
    if replicates {
        v.push(("r2", "<f8", true, 8));
    }
    v.push(("nonzero", "<u4", false, 4));
    v
}

/// The `.npy` header of a C-order array of `shape` with element type `A`.
fn npy_header<A: WritableElement>(
    shape: &[usize],
) -> Result<Vec<u8>, ndarray_npy::npy::header::FormatHeaderError> {
    Header {
        type_descriptor: A::type_descriptor(),
        layout: Layout::Standard,
        shape: shape.to_vec(),
    }
    .to_bytes()
}

/// Bytes on disk of the bundle of a film rendered with `transform` (saturating): the
/// `.npy` files exactly, plus 64 KiB for the manifest.
pub fn bundle_bytes(film: &Film, transform: &Transform, media: bool) -> u64 {
    bundle_bytes_with(film, transform, media, false)
}

/// [`bundle_bytes`] with or without the replicates' `r2.npy`.
pub fn bundle_bytes_with(film: &Film, transform: &Transform, media: bool, replicates: bool) -> u64 {
    let (h, w, t, c) = (film.height, film.width, film.time.bins, film.channels);
    let mut files: Vec<(Vec<usize>, usize)> = volume_arrays(transform, replicates)
        .into_iter()
        .map(|(_, _, rgb, size)| {
            let shape = if rgb { vec![h, w, t, c] } else { vec![h, w, t] };
            (shape, size)
        })
        .collect();
    files.extend([
        (vec![h, w, 3], 4), // albedo
        (vec![h, w, 3], 4), // normal
        (vec![h, w], 4),    // depth
        (vec![h, w], 4),    // emitter
        (vec![h, w, c], 8), // steady
    ]);
    if media {
        files.push((vec![h, w], 4)); // medium
    }
    let total: u128 = files
        .iter()
        .map(|(shape, size)| {
            // Every dtype of a bundle ('<f8', '<f4', '<u4') has a header of this length.
            let header = npy_header::<f64>(shape).map_or(256, |b| b.len()) as u128;
            header + shape.iter().map(|&n| n as u128).product::<u128>() * *size as u128
        })
        .sum();
    u64::try_from(total + 65536).unwrap_or(u64::MAX)
}

/// One (H, W, T, C) or (H, W, T) array of a bundle being streamed: preallocated on
/// disk with its header, filled one row at a time.
struct StreamedArray {
    info: ArrayInfo,
    path: PathBuf,
    file: File,
    /// Bytes of the header: row y starts at `header + y * row_bytes`.
    header: u64,
    row_bytes: u64,
}

impl StreamedArray {
    fn create(
        dir: &Path,
        (height, width, bins, channels): (usize, usize, usize, usize),
        spec: (&str, &str, bool, usize),
    ) -> Result<Self, BundleError> {
        let (name, dtype, rgb, size) = spec;
        let mut shape = vec![height, width, bins];
        if rgb {
            shape.push(channels);
        }
        let file_name = format!("{name}.npy");
        let path = dir.join(&file_name);
        let header = if size == 8 {
            npy_header::<f64>(&shape)
        } else {
            npy_header::<u32>(&shape)
        }
        .map_err(|e| BundleError::io(&path, e))?;
        let row_bytes = (shape[1..].iter().product::<usize>() * size) as u64;
        let file = File::create_new(&path).map_err(|e| BundleError::io(&path, e))?;
        file.write_all_at(&header, 0)
            .and_then(|()| file.set_len(header.len() as u64 + height as u64 * row_bytes))
            .map_err(|e| BundleError::io(&path, e))?;
        Ok(StreamedArray {
            info: ArrayInfo {
                name: name.into(),
                file: file_name,
                dtype: dtype.into(),
                shape,
            },
            path,
            file,
            header: header.len() as u64,
            row_bytes,
        })
    }

    /// Writes the values of rows `y..y + rows` (`bytes` long: exactly those rows).
    fn put(&self, y: usize, rows: usize, bytes: &[u8]) -> Result<(), BundleError> {
        if bytes.len() as u64 != rows as u64 * self.row_bytes {
            return Err(BundleError::RowSize {
                path: self.path.clone(),
                len: bytes.len(),
                want: rows as u64 * self.row_bytes,
                rows,
                row_bytes: self.row_bytes,
            });
        }
        self.file
            .write_all_at(bytes, self.header + y as u64 * self.row_bytes)
            .map_err(|e| BundleError::io(&self.path, e))
    }
}

/// The volume arrays of a bundle written band by band by `merge`: preallocated like
/// [`BundleWriter`]'s in `dir` (a staged directory), filled from [`RowSums`].
pub struct VolumeArrays {
    arrays: Vec<StreamedArray>,
}

impl VolumeArrays {
    pub fn create(
        dir: &Path,
        dims: (usize, usize, usize, usize),
        transform: &Transform,
        replicates: bool,
    ) -> Result<Self, BundleError> {
        let arrays = volume_arrays(transform, replicates)
            .into_iter()
            .map(|spec| StreamedArray::create(dir, dims, spec))
            .collect::<Result<_, _>>()?;
        Ok(VolumeArrays { arrays })
    }

    /// Writes the band of rows `s.rows` (every array this bundle has must be filled).
    pub fn put(&self, s: &RowSums) -> Result<(), BundleError> {
        let mut volumes: Vec<&[u8]> = vec![
            bytemuck::cast_slice(&s.x1),
            bytemuck::cast_slice(&s.x2),
            bytemuck::cast_slice(&s.x3),
        ];
        for a in &self.arrays[3..] {
            match a.info.name.as_str() {
                "sum" => volumes.push(bytemuck::cast_slice(&s.sum)),
                "r2" => volumes.push(bytemuck::cast_slice(&s.r2)),
                _ => volumes.push(bytemuck::cast_slice(&s.nonzero)),
            }
        }
        self.put_bytes(s.rows.start, s.rows.len(), &volumes)
    }

    /// Writes rows `y..y + rows` of every array, given as bytes in the arrays' order
    /// (x1, x2, x3, then sum and r2 when the bundle has them, nonzero).
    fn put_bytes(&self, y: usize, rows: usize, volumes: &[&[u8]]) -> Result<(), BundleError> {
        if volumes.len() != self.arrays.len() {
            let dir = self.arrays[0].path.parent().unwrap_or(Path::new("."));
            return Err(BundleError::RowArrays(dir.to_path_buf()));
        }
        for (array, bytes) in self.arrays.iter().zip(volumes) {
            array.put(y, rows, bytes)?;
        }
        Ok(())
    }

    /// The arrays' manifest entries.
    pub fn infos(&self) -> Vec<ArrayInfo> {
        self.arrays.iter().map(|a| a.info.clone()).collect()
    }
}

/// A bundle written while its scene renders: a [`RowSink`] that puts every finished row
/// of the volume arrays at its offset in the `.npy` files, which [`BundleWriter::create`]
/// preallocates (header, then `set_len`) in the temporary directory of [`stage`].
/// [`BundleWriter::finish`] writes the per-pixel arrays and the manifest, last, and
/// renames the directory into place. Dropped unfinished (an error, a failed render), it
/// deletes the temporary directory: nothing that looks like a bundle is left behind.
///
/// Memory: the per-pixel images (G-buffers, steady), `H * W * 56` bytes; the volume
/// arrays never are in memory beyond the rows being written.
pub struct BundleWriter {
    staged: Staged,
    film: Film,
    volumes: VolumeArrays,
    images: Mutex<PixelImages>,
}

impl BundleWriter {
    /// Starts the bundle `out` of a render of `film` with `transform`; refuses an
    /// existing `out` unless `force` (which replaces it only at [`BundleWriter::finish`]).
    pub fn create(
        out: &Path,
        force: bool,
        film: &Film,
        transform: &Transform,
    ) -> Result<Self, BundleError> {
        Self::create_with(out, force, film, transform, false)
    }

    /// [`BundleWriter::create`] for a render with or without replicates (`r2.npy`).
    pub fn create_with(
        out: &Path,
        force: bool,
        film: &Film,
        transform: &Transform,
        replicates: bool,
    ) -> Result<Self, BundleError> {
        let staged = stage(out, force, |dir| {
            std::fs::create_dir(dir).map_err(|e| BundleError::io(dir, e))
        })?;
        let volumes = VolumeArrays::create(
            staged.path(),
            (film.height, film.width, film.time.bins, film.channels),
            transform,
            replicates,
        )?;
        Ok(BundleWriter {
            staged,
            film: film.clone(),
            volumes,
            images: Mutex::new(PixelImages::new(film.height, film.width, film.channels)),
        })
    }

    /// Completes the bundle of the render `summary` describes (every row must have
    /// arrived): the per-pixel arrays, the manifest, then the rename into place.
    pub fn finish(
        self,
        scene: &Scene,
        meta: &BundleMeta,
        summary: &RenderSummary,
    ) -> Result<Manifest, BundleError> {
        let dir = self.staged.path().to_path_buf();
        let images = self
            .images
            .into_inner()
            .unwrap_or_else(PoisonError::into_inner);
        if !images.complete() || scene.film != self.film {
            return Err(BundleError::Incomplete(dir));
        }
        let mut manifest = manifest(scene, meta, summary.seconds, summary.dropped_nonfinite);
        manifest.arrays = self.volumes.infos();
        drop(self.volumes);
        let hw = (self.film.height, self.film.width);
        write_pixel_arrays(
            &dir,
            hw,
            &images.gbuffer,
            images.steady,
            manifest.media,
            &mut manifest.arrays,
        )?;
        if let Some((n, _)) = &meta.adaptive {
            let counts =
                Array2::from_shape_vec(hw, n.to_vec()).map_err(|e| BundleError::io(&dir, e))?;
            npy(&dir, "pixel_spp", "<u4", &counts, &mut manifest.arrays)?;
        }
        write_manifest(&dir, &self.staged.final_path, &manifest)?;
        self.staged.commit()?;
        Ok(manifest)
    }
}

impl RowSink for BundleWriter {
    type Error = BundleError;

    fn put_row(&self, row: &Row<'_>) -> Result<(), BundleError> {
        let s = row.sums;
        let mut volumes: Vec<&[u8]> = vec![
            bytemuck::cast_slice(&s.x1),
            bytemuck::cast_slice(&s.x2),
            bytemuck::cast_slice(&s.x3),
        ];
        if let Some(sum) = &s.sum {
            volumes.push(bytemuck::cast_slice(sum));
        }
        if let Some(r2) = &s.r2 {
            volumes.push(bytemuck::cast_slice(r2));
        }
        volumes.push(bytemuck::cast_slice(&s.nonzero));
        self.volumes.put_bytes(row.y, 1, &volumes)?;
        self.images
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .put(row);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::{render_into, PixelSampling, RenderSettings};
    use crate::scene::Overrides;

    /// A positioned write that fails in the middle of a render (here: a file handle
    /// that cannot write) stops the render with an error naming the file, and the
    /// temporary bundle goes away with the writer.
    #[test]
    fn a_write_error_mid_render_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let cbox = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cbox.xml");
        let overrides = Overrides {
            width: Some(12),
            bins: Some(20),
            spp: Some(2),
            ..Overrides::default()
        };
        let scene = Scene::load(&cbox, &overrides).unwrap();
        let settings = RenderSettings {
            spp: scene.spp,
            seed: 1,
            transform: Transform::Identity,
            pixel_sampling: PixelSampling::Stratified,
            replicates: 0,
            pixel_spp: None,
        };
        let out = dir.path().join("b.tstats");
        let mut writer =
            BundleWriter::create(&out, false, &scene.film, &settings.transform).unwrap();
        let x2 = &mut writer.volumes.arrays[1];
        x2.file = File::open(&x2.path).unwrap();
        let e = render_into(&scene, &settings, &writer, &|_| {}).unwrap_err();
        assert!(e.to_string().contains("x2.npy: Bad file descriptor"), "{e}");
        assert!(writer.staged.path().join("x1.npy").is_file());
        drop(writer);
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }
}
