//! `tstat nlos reconstruct CAPTURE --method bp|fbp|pf|fk|lct [--wl-mean W [--wl-sigma S]] [--snr S]
//! --volume X0,X1,Y0,Y1,Z0,Z1 --voxels NX,NY,NZ --out VOLUME.npy`: a reconstruction of the hidden scene from an
//! NLOS capture (a tstat bundle or a y-tal HDF5 capture), as y-tal computes it.

use super::util::{arg, check_outputs, human_bytes, size_flag, Kind};
use crate::bundle::write::stage;
use crate::bundle::{Bundle, BundleError};
use crate::nlos::bp::VoxelGrid;
use crate::nlos::capture::Capture;
use crate::nlos::lct;
use crate::nlos::reconstruct::Reconstruction;
use anyhow::{anyhow, bail};
use clap::{Args, Subcommand, ValueEnum};
use std::path::{Path, PathBuf};

#[derive(Args, Debug)]
pub struct NlosArgs {
    #[command(subcommand)]
    pub command: NlosCommand,
}

#[derive(Subcommand, Debug)]
pub enum NlosCommand {
    /// Reconstruct the hidden scene on a voxel grid (f32 (NX, NY, NZ) .npy).
    Reconstruct(ReconstructArgs),
    /// A maximum-intensity projection of a reconstruction as PNG.
    Mip(MipArgs),
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum MipAxis {
    /// Along depth: the view from the relay wall (x right, y up).
    Z,
    /// Along x: from the side (depth right, y up).
    X,
    /// Along y: from above (x right, depth up).
    Y,
}

#[derive(Args, Debug)]
pub struct MipArgs {
    /// A reconstruction: f32 or f64 (NX, NY, NZ) .npy, as `nlos reconstruct` writes.
    pub volume: PathBuf,
    /// The projection axis.
    #[arg(long, value_enum, default_value_t = MipAxis::Z)]
    pub axis: MipAxis,
    /// Pixels per voxel (default: enough for 512 pixels across, at most 64).
    #[arg(long)]
    pub scale: Option<usize>,
    /// The picture (.png).
    #[arg(long)]
    pub out: PathBuf,
    /// Replace an existing output.
    #[arg(long)]
    pub force: bool,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum Method {
    /// Backprojection (y-tal's `tal.reconstruct.bp`, camera system DIRECT_LIGHT).
    Bp,
    /// Filtered backprojection (y-tal's `tal.reconstruct.fbp`, border 'zero'): the
    /// capture filtered by a complex pulse of wavelength --wl-mean, backprojected;
    /// written as the magnitude.
    Fbp,
    /// Phasor fields with Rayleigh-Sommerfeld propagation (y-tal's
    /// `tal.reconstruct.pf_dev`, camera system DIRECT_LIGHT): the virtual pulse of
    /// wavelength --wl-mean propagated to each voxel frequency by frequency, by FFT
    /// convolution when the voxel slices are parallel to the relay wall with its grid's
    /// spacing; written as the magnitude. Confocal captures too (y-tal refuses them).
    Pf,
    /// f-k migration (y-tal's `tal.reconstruct.fk`; confocal captures of an N x N grid):
    /// the Stolt-resampled wave migration on the capture's own grid (N x N points, its
    /// bins as depths), resampled onto the voxels.
    Fk,
    /// The light-cone transform with its Wiener filter (O'Toole et al. 2018; confocal
    /// captures of an N x N grid), on the capture's own grid, resampled onto the voxels.
    Lct,
}

impl Method {
    pub fn wavelength(self) -> bool {
        matches!(self, Method::Fbp | Method::Pf)
    }
}

#[derive(Args, Debug)]
pub struct ReconstructArgs {
    /// A capture: a tstat bundle of an NLOS scene, or a y-tal HDF5 capture (.hdf5, .h5).
    pub capture: PathBuf,
    #[arg(long, value_enum)]
    pub method: Method,
    /// The volume: X0,X1,Y0,Y1,Z0,Z1, the first and last voxel centres on each axis
    /// (world coordinates, scene units; for y-tal files, its units).
    #[arg(long, allow_hyphen_values = true)]
    pub volume: String,
    /// Voxels per axis: NX,NY,NZ (centres spaced as numpy.linspace).
    #[arg(long)]
    pub voxels: String,
    /// fbp, pf: the virtual pulse's wavelength (OPL units, e.g. 8 voxel widths).
    #[arg(long)]
    pub wl_mean: Option<f64>,
    /// fbp, pf: the width of its Gaussian envelope (default wl_mean / sqrt(2), as y-tal).
    #[arg(long)]
    pub wl_sigma: Option<f64>,
    /// Reconstruct from this denoised volume of the capture (`tstat denoise`'s (rows,
    /// Sx, T, C) .npy of the bundle CAPTURE) instead of the bundle's noisy means.
    #[arg(long)]
    pub denoised: Option<PathBuf>,
    /// lct: the Wiener filter's signal-to-noise ratio (default 0.8, O'Toole's).
    #[arg(long)]
    pub snr: Option<f64>,
    /// The most working memory the reconstruction may take (e.g. 4G; default 8G); the
    /// capture itself (T L S f32) comes on top.
    #[arg(long)]
    pub max_memory: Option<String>,
    /// The reconstruction, f32 (NX, NY, NZ) .npy.
    #[arg(long)]
    pub out: PathBuf,
    /// Replace an existing output.
    #[arg(long)]
    pub force: bool,
}

/// The most voxels a reconstruction holds (1 GiB of f32).
const MAX_VOXELS: usize = 1 << 28;

fn numbers<T: std::str::FromStr>(flag: &str, s: &str, n: usize) -> anyhow::Result<Vec<T>> {
    let v: Vec<T> = s
        .split(',')
        .map(|x| x.trim().parse::<T>())
        .collect::<Result<_, _>>()
        .map_err(|_| anyhow!("{flag} {s}: expected {n} comma-separated numbers"))?;
    if v.len() != n {
        bail!(
            "{flag} {s}: expected {n} comma-separated numbers, got {}",
            v.len()
        );
    }
    Ok(v)
}

/// The voxel grid of `--volume` and `--voxels`.
pub fn voxel_grid(volume: &str, voxels: &str) -> anyhow::Result<VoxelGrid> {
    let b: Vec<f64> = numbers("--volume", volume, 6)?;
    let n: Vec<usize> = numbers("--voxels", voxels, 3)?;
    if b.iter().any(|v| !v.is_finite()) {
        bail!("--volume {volume}: the bounds must be finite");
    }
    if n.contains(&0) {
        bail!("--voxels {voxels}: every axis needs at least one voxel");
    }
    if n.iter()
        .try_fold(1usize, |a, &k| a.checked_mul(k))
        .is_none_or(|t| t > MAX_VOXELS)
    {
        bail!("--voxels {voxels}: more than {MAX_VOXELS} voxels");
    }
    for a in 0..3 {
        if n[a] == 1 && b[2 * a] != b[2 * a + 1] {
            bail!("--volume {volume}: an axis of one voxel needs its first and last centre equal");
        }
    }
    Ok(VoxelGrid {
        first: [b[0], b[2], b[4]],
        last: [b[1], b[3], b[5]],
        n: [n[0], n[1], n[2]],
    })
}

/// `--max-memory`'s default.
const DEFAULT_MAX_MEMORY: u64 = 8 << 30;

/// The reconstruction `--method` and its flags ask for (`--wl-mean` and `--wl-sigma`
/// for fbp and pf, `--snr` for lct), each flag refused where it does not belong.
pub fn reconstruction(
    method: Method,
    wl_mean: Option<f64>,
    wl_sigma: Option<f64>,
    snr: Option<f64>,
) -> anyhow::Result<Reconstruction> {
    let wavelengths = match (method.wavelength(), wl_mean, wl_sigma) {
        (false, None, None) => None,
        (false, _, _) => bail!("--wl-mean and --wl-sigma belong to --method fbp and pf"),
        (true, None, _) => bail!(
            "--method {} needs --wl-mean (the virtual pulse's wavelength)",
            super::util::cli_name(&method)
        ),
        (true, Some(m), sigma) => {
            let s = sigma.unwrap_or(m / std::f64::consts::SQRT_2);
            if !(m > 0.0 && m.is_finite() && s > 0.0 && s.is_finite()) {
                bail!("--wl-mean {m} and --wl-sigma {s} must be positive and finite");
            }
            Some((m, s))
        }
    };
    match (method, snr) {
        (Method::Lct, Some(v)) if !(v > 0.0 && v.is_finite()) => {
            bail!("--snr {v}: the signal-to-noise ratio must be positive and finite")
        }
        (Method::Lct, _) | (_, None) => {}
        (_, Some(_)) => bail!("--snr belongs to --method lct"),
    }
    Ok(match (method, wavelengths) {
        (Method::Fbp, Some((wl_mean, wl_sigma))) => Reconstruction::Fbp { wl_mean, wl_sigma },
        (Method::Pf, Some((wl_mean, wl_sigma))) => Reconstruction::Pf { wl_mean, wl_sigma },
        (Method::Fk, _) => Reconstruction::Fk,
        (Method::Lct, _) => Reconstruction::Lct {
            snr: snr.unwrap_or(lct::DEFAULT_SNR),
        },
        _ => Reconstruction::Bp,
    })
}

/// Refuses a reconstruction that cannot run on `c` (its flags named as the command
/// line spells them) or that needs more working memory than `budget`.
pub fn check_reconstruction(
    r: &Reconstruction,
    c: &Capture,
    grid: &VoxelGrid,
    budget: u64,
) -> anyhow::Result<()> {
    r.check(c)
        .map_err(|e| anyhow!("--method {}: {e}", r.name()))?;
    let need = r.working_memory(c, grid)?;
    if need > budget {
        bail!(
            "--method {} on {} x {} x {} voxels needs {} of working memory, over --max-memory {}",
            r.name(),
            grid.n[0],
            grid.n[1],
            grid.n[2],
            human_bytes(need),
            human_bytes(budget)
        );
    }
    Ok(())
}

/// `--max-memory` (default [`DEFAULT_MAX_MEMORY`]).
pub fn memory_budget(s: Option<&str>) -> anyhow::Result<u64> {
    match s {
        Some(s) => size_flag("--max-memory", s),
        None => Ok(DEFAULT_MAX_MEMORY),
    }
}

fn load(path: &Path) -> anyhow::Result<Capture> {
    if path.is_dir() {
        let bundle = Bundle::open(path)?;
        return Ok(Capture::from_bundle(&bundle)?);
    }
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_lowercase())
        .unwrap_or_default();
    if ext == "hdf5" || ext == "h5" {
        if !path.is_file() {
            bail!("{}: no such capture file", path.display());
        }
        return Ok(Capture::from_tal(path)?);
    }
    bail!(
        "{}: a capture is a tstat bundle directory or a y-tal .hdf5 / .h5 file",
        path.display()
    )
}

pub fn run(a: NlosArgs) -> anyhow::Result<()> {
    match a.command {
        NlosCommand::Reconstruct(r) => reconstruct(r),
        NlosCommand::Mip(m) => mip(m),
    }
}

fn mip(m: MipArgs) -> anyhow::Result<()> {
    use crate::viz::mip::{picture, project, Axis};
    if m.out.extension().is_none_or(|e| e != "png") {
        bail!(
            "--out {}: the projection is written as .png",
            m.out.display()
        );
    }
    check_outputs(
        &[arg("volume", &m.volume)],
        &[(arg("--out", &m.out), Kind::File)],
        m.force,
    )?;
    let read_err = |e: ndarray_npy::ReadNpyError| {
        anyhow!(
            "{}: not an (NX, NY, NZ) f32 or f64 .npy volume ({e})",
            m.volume.display()
        )
    };
    let v: ndarray::Array3<f32> = match ndarray_npy::read_npy::<_, ndarray::Array3<f32>>(&m.volume)
    {
        Ok(v) => v,
        Err(ndarray_npy::ReadNpyError::WrongDescriptor(_)) => {
            ndarray_npy::read_npy::<_, ndarray::Array3<f64>>(&m.volume)
                .map_err(read_err)?
                .mapv(|x| x as f32)
        }
        Err(e) => return Err(read_err(e)),
    };
    let shape = v.shape().to_vec();
    if shape.contains(&0) {
        bail!("{}: an empty volume {shape:?}", m.volume.display());
    }
    let n = [shape[0], shape[1], shape[2]];
    let axis = match m.axis {
        MipAxis::X => Axis::X,
        MipAxis::Y => Axis::Y,
        MipAxis::Z => Axis::Z,
    };
    let values: Vec<f32> = v.iter().copied().collect();
    let p = project(&values, n, axis);
    let scale = match m.scale {
        Some(0) => bail!("--scale 0: at least one pixel per voxel"),
        Some(k) if k.saturating_mul(p.width.max(p.height)) > 16384 => {
            bail!("--scale {k}: the picture would be over 16384 pixels across")
        }
        Some(k) => k,
        None => (512 / p.width.max(p.height)).clamp(1, 64),
    };
    let (w, h, px) = picture(&p, scale);
    crate::report::plot::save_png_rgb(&m.out, &px, w, h)
        .map_err(|e| anyhow!("{}: {e}", m.out.display()))?;
    say!(
        "wrote {} ({w} x {h} px, the maximum along {} of {:?})",
        m.out.display(),
        super::util::cli_name(&m.axis),
        n
    );
    Ok(())
}

fn reconstruct(r: ReconstructArgs) -> anyhow::Result<()> {
    let grid = voxel_grid(&r.volume, &r.voxels)?;
    let method = reconstruction(r.method, r.wl_mean, r.wl_sigma, r.snr)?;
    if r.out.extension().is_none_or(|e| e != "npy") {
        bail!(
            "--out {}: the reconstruction is written as .npy",
            r.out.display()
        );
    }
    check_outputs(
        &[arg("capture", &r.capture)],
        &[(arg("--out", &r.out), Kind::File)],
        r.force,
    )?;
    if let Some(d) = &r.denoised {
        if !d.is_file() {
            bail!("--denoised {}: no such file", d.display());
        }
    }
    let mut capture = load(&r.capture)?;
    if let Some(d) = &r.denoised {
        if !r.capture.is_dir() {
            bail!(
                "--denoised {}: needs the bundle it was denoised from as CAPTURE",
                d.display()
            );
        }
        let bundle = Bundle::open(&r.capture)?;
        let rec = bundle.manifest.nlos.as_ref().expect("loaded as a capture");
        let v: ndarray::Array4<f32> = ndarray_npy::read_npy(d).map_err(|e| {
            anyhow!(
                "--denoised {}: not an f32 (rows, Sx, T, C) .npy volume ({e})",
                d.display()
            )
        })?;
        let s = v.shape();
        let shape = [s[0], s[1], s[2], s[3]];
        let values: Vec<f32> = v.iter().copied().collect();
        crate::nlos::denoised::replace_h(&mut capture, rec, &values, shape)
            .map_err(|e| anyhow!("--denoised {}: {e}", d.display()))?;
    }
    let budget = memory_budget(r.max_memory.as_deref())?;
    check_reconstruction(&method, &capture, &grid, budget)?;
    let start = std::time::Instant::now();
    let volume = method.run(&capture, &grid)?;
    let seconds = start.elapsed().as_secs_f64();
    let shape = (grid.n[0], grid.n[1], grid.n[2]);
    let array = ndarray::Array3::from_shape_vec(shape, volume).expect("NX NY NZ voxels");
    stage(&r.out, r.force, |tmp| {
        ndarray_npy::write_npy(tmp, &array).map_err(|e| BundleError::io(&r.out, e))
    })?
    .commit()?;
    say!(
        "wrote {} (f32 {:?}, {} in {seconds:.2} s: {} laser x {} sensor points, {} bins)",
        r.out.display(),
        array.shape(),
        super::util::cli_name(&r.method),
        capture.lasers,
        capture.sensors,
        capture.bins
    );
    Ok(())
}
