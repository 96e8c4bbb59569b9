//! `tstat export NAME.tstats --out noisy.npy [--steady steady.exr|.npy]
//! [--tal capture.hdf5 [--max-memory BYTES]]`.

use super::util::{arg, check_outputs, Kind};
use crate::bundle::write::stage;
use crate::bundle::{Bundle, BundleError, Problem};
use crate::scene::mode::RenderMode;
use anyhow::bail;
use clap::Args;
use ndarray::Array3;
use std::path::{Path, PathBuf};

#[derive(Args, Debug)]
pub struct ExportArgs {
    /// A statistics bundle directory.
    pub bundle: PathBuf,
    /// Noisy mean volume S / n, f32 (H, W, T, C) .npy.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Steady-state image, .exr or .npy (f32 (H, W, C)).
    #[arg(long)]
    pub steady: Option<PathBuf>,
    /// An NLOS capture as y-tal's HDF5 capture (`tal.io.read_capture`): H (the noisy
    /// mean summed over R, G, B, time first) with its grids, origins and times.
    #[arg(long)]
    pub tal: Option<PathBuf>,
    /// With --tal: the most of H held at once (e.g. 512Mi; default 1Gi); a larger
    /// capture is written a block of time bins at a time, reading the bundle once per
    /// block.
    #[arg(long, value_name = "BYTES")]
    pub max_memory: Option<String>,
    /// The published pipeline's arrays, as its denoiser takes them: noisy.npy,
    /// estimands.npy and estimands_variance.npy (theta and V in the bundle's transform;
    /// render with --transform yeo-johnson:0.5 for the published pipeline's), albedo.npy,
    /// normals.npy; and tstat's depth.npy, emitter.npy, pixel_spp.npy (adaptive) and
    /// meta.json, which `tstat denoise --from-arrays` reads.
    #[arg(long, value_name = "DIR")]
    pub published: Option<PathBuf>,
    /// Replace existing outputs.
    #[arg(long)]
    pub force: bool,
}

/// `--max-memory`'s default for `--tal`.
const TAL_MEMORY: u64 = 1 << 30;

fn extension(p: &Path) -> String {
    p.extension()
        .map(|e| e.to_string_lossy().to_lowercase())
        .unwrap_or_default()
}

/// Writes an (H, W, 3) image as an RGB OpenEXR (f32, lossless).
pub fn write_exr_rgb(path: &Path, img: &Array3<f32>) -> Result<(), BundleError> {
    let (h, w) = (img.shape()[0], img.shape()[1]);
    exr::prelude::write_rgb_file(path, w, h, |x, y| {
        (img[[y, x, 0]], img[[y, x, 1]], img[[y, x, 2]])
    })
    .map_err(|e| BundleError::io(path, e))
}

/// Writes an (H, W, T, C) volume as .npy: (H, W, T, 3, 4) when C = 12 (a spectral
/// Stokes volume, RGB x Stokes: the bundle's channels are RGB-major), else as it is.
pub fn write_volume_npy(
    path: &Path,
    v: ndarray::ArrayView4<f32>,
) -> Result<(), ndarray_npy::WriteNpyError> {
    let (h, w, t, c) = v.dim();
    if c == 12 {
        let v = v
            .into_shape_with_order((h, w, t, 3, 4))
            .expect("a bundle's volume is in standard layout");
        ndarray_npy::write_npy(path, &v)
    } else {
        ndarray_npy::write_npy(path, &v)
    }
}

/// The shape a `--out` or `--steady` .npy of `mode` has, from the bundle's (.., C):
/// (.., 3, 4) for spectral_polarized (RGB x Stokes), else the same.
fn stokes_shape(mode: RenderMode, shape: &[usize]) -> Vec<usize> {
    let mut s = shape.to_vec();
    if mode == RenderMode::SpectralPolarized {
        s.pop();
        s.extend([3, 4]);
    }
    s
}

/// The OpenEXR channel names of a bundle's channels: R, G, B; Y (mono); S0.Y .. S3.Y
/// (mono_polarized: Mitsuba's `stokes` integrator names its layers S0 .. S3, and a
/// mono layer's channel is Y); S0.R .. S3.B (spectral_polarized, Mitsuba's names, in
/// the bundle's RGB-major order; EXR files sort their channels by name).
pub fn exr_channel_names(mode: RenderMode) -> Vec<String> {
    match mode {
        RenderMode::MonoPolarized => mode
            .channel_names()
            .iter()
            .map(|s| format!("{s}.Y"))
            .collect(),
        _ => mode.channel_names().iter().map(|s| s.to_string()).collect(),
    }
}

/// Writes an (H, W, C) image as an OpenEXR (f32, lossless) with these channel names
/// (C of them); three channels named R, G, B go through [`write_exr_rgb`].
pub fn write_exr(path: &Path, img: &Array3<f32>, names: &[String]) -> Result<(), BundleError> {
    use exr::prelude::*;
    if names == ["R", "G", "B"] {
        return write_exr_rgb(path, img);
    }
    let (h, w, c) = img.dim();
    assert_eq!(c, names.len(), "one name per channel");
    let channels: SmallVec<[AnyChannel<FlatSamples>; 4]> = names
        .iter()
        .enumerate()
        .map(|(k, name)| {
            let plane: Vec<f32> = (0..h * w).map(|i| img[[i / w, i % w, k]]).collect();
            AnyChannel::new(name.as_str(), FlatSamples::F32(plane))
        })
        .collect();
    let layer = Layer::new(
        (w, h),
        LayerAttributes::default(),
        Encoding::FAST_LOSSLESS,
        AnyChannels::sort(channels),
    );
    Image::from_layer(layer)
        .write()
        .to_file(path)
        .map_err(|e| BundleError::io(path, e))
}

pub fn run(a: ExportArgs) -> anyhow::Result<()> {
    if a.out.is_none() && a.steady.is_none() && a.tal.is_none() && a.published.is_none() {
        bail!("nothing to export: give --out VOLUME.npy, --steady IMAGE.exr|.npy, --tal CAPTURE.hdf5 and/or --published DIR");
    }
    if let Some(t) = &a.tal {
        if !matches!(extension(t).as_str(), "hdf5" | "h5") {
            bail!(
                "--tal {}: y-tal's captures are .hdf5 (or .h5) files",
                t.display()
            );
        }
    }
    let tal_memory = match (&a.max_memory, &a.tal) {
        (Some(_), None) => bail!("--max-memory bounds the --tal export; give --tal"),
        (Some(s), Some(_)) => super::util::size_flag("--max-memory", s)?,
        (None, _) => TAL_MEMORY,
    };
    if let Some(out) = &a.out {
        if extension(out) != "npy" {
            bail!("--out {}: the volume is written as .npy", out.display());
        }
    }
    if let Some(s) = &a.steady {
        if !matches!(extension(s).as_str(), "npy" | "exr") {
            bail!("--steady {}: use a .exr or .npy file name", s.display());
        }
    }
    let mut outputs = Vec::new();
    if let Some(out) = &a.out {
        outputs.push((arg("--out", out), Kind::File));
    }
    if let Some(s) = &a.steady {
        outputs.push((arg("--steady", s), Kind::File));
    }
    if let Some(t) = &a.tal {
        outputs.push((arg("--tal", t), Kind::File));
    }
    if let Some(d) = &a.published {
        outputs.push((arg("--published", d), Kind::Dir));
    }
    check_outputs(&[arg("bundle", &a.bundle)], &outputs, a.force)?;
    let bundle = Bundle::open(&a.bundle)?;
    if a.published.is_some() && bundle.manifest.channel_count() != 3 {
        let m = &bundle.manifest;
        bail!(
            "--published: the published pipeline's arrays are RGB, (H, W, T, 3); {} is a --mode {} bundle ({} channel{} {}): denoise it with `tstat denoise {}` (every --method takes mono and Stokes bundles), or render with --mode rgb",
            a.bundle.display(),
            m.mode.name(),
            m.channel_count(),
            if m.channel_count() == 1 { "" } else { "s" },
            m.mode.channel_names().join(", "),
            a.bundle.display()
        );
    }
    if a.tal.is_some() && bundle.manifest.nlos.is_none() {
        bail!(
            "--tal: {} is not an NLOS capture (its scene's sensor is no nlos_capture_meter)",
            a.bundle.display()
        );
    }
    // Every output is written completely before any is put in place.
    let mut staged = Vec::new();
    if let Some(out) = &a.out {
        let mean = bundle.noisy_mean()?;
        let shape = mean.shape().to_vec();
        staged.push((
            stage(out, a.force, |tmp| {
                write_volume_npy(tmp, mean.view()).map_err(|e| BundleError::io(out, e))
            })?,
            format!(
                "wrote {} (f32 {:?})",
                out.display(),
                stokes_shape(bundle.manifest.mode, &shape)
            ),
        ));
    }
    if let Some(s) = &a.steady {
        let steady = bundle.steady()?;
        // As the mean volume: a value f32 cannot hold would be written as infinity.
        if let Some(((y, x, c), v)) = steady
            .indexed_iter()
            .find(|(_, v)| !((**v as f32).is_finite()))
        {
            return Err(BundleError::invalid(
                a.bundle.join("steady.npy"),
                Problem::SteadyBeyondF32 { value: *v, y, x, c },
            )
            .into());
        }
        let img = steady.mapv(|v| v as f32);
        staged.push((
            stage(s, a.force, |tmp| {
                if extension(s) == "exr" {
                    write_exr(tmp, &img, &exr_channel_names(bundle.manifest.mode))
                } else if bundle.manifest.mode == RenderMode::SpectralPolarized {
                    let (h, w, _) = img.dim();
                    let v = img
                        .clone()
                        .into_shape_with_order((h, w, 3, 4))
                        .expect("12 channels");
                    ndarray_npy::write_npy(tmp, &v).map_err(|e| BundleError::io(s, e))
                } else {
                    ndarray_npy::write_npy(tmp, &img).map_err(|e| BundleError::io(s, e))
                }
            })?,
            format!(
                "wrote {} (f32 {:?})",
                s.display(),
                if extension(s) == "exr" {
                    img.shape().to_vec()
                } else {
                    stokes_shape(bundle.manifest.mode, img.shape())
                }
            ),
        ));
    }
    if let Some(t) = &a.tal {
        let mut written = None;
        let file = stage(t, a.force, |tmp| -> anyhow::Result<()> {
            written = Some(crate::nlos::tal::write_capture(&bundle, tmp, tal_memory)?);
            Ok(())
        })?;
        let w = written.expect("staged");
        staged.push((
            file,
            format!(
                "wrote {} (y-tal capture, H f32 {:?}{})",
                t.display(),
                w.h_shape,
                if w.blocks > 1 {
                    format!(", in {} blocks of time bins", w.blocks)
                } else {
                    String::new()
                }
            ),
        ));
    }
    if let Some(d) = &a.published {
        staged.push((
            stage(d, a.force, |tmp| {
                crate::bundle::published::write_into(&bundle, tmp, d)
            })?,
            format!(
                "wrote {} (the published pipeline's arrays; theta and V in {})",
                d.display(),
                bundle.manifest.transform
            ),
        ));
    }
    let mut lines = Vec::new();
    for (file, line) in staged {
        file.commit()?;
        lines.push(line);
    }
    for l in lines {
        say!("{l}");
    }
    Ok(())
}
