//! `tstat nlos reconstruct CAPTURE --method bp|fbp|pf|fk|lct [--wl-mean W [--wl-sigma S]] [--snr S]
//! --volume X0,X1,Y0,Y1,Z0,Z1 --voxels NX,NY,NZ --out VOLUME.npy`: a reconstruction of the hidden scene from an
//! NLOS capture (a tstat bundle or a y-tal HDF5 capture), as y-tal computes it.

use super::util::{arg, check_outputs, human_bytes, size_flag, Kind};
use crate::bundle::write::stage;
use crate::bundle::{Bundle, BundleError};
use crate::nlos::capture::Capture;
use crate::nlos::reconstruct::bp::VoxelGrid;
use crate::nlos::reconstruct::lct;
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
    /// The most memory the projection may take (e.g. 1G; default 8G): the volume is
    /// read a band of x slices at a time, so this bounds the band, the projection and
    /// the picture, not the volume.
    #[arg(long)]
    pub max_memory: Option<String>,
    /// The picture (.png).
    #[arg(long)]
    pub out: PathBuf,
    /// Replace an existing output.
    #[arg(long)]
    pub force: bool,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum NlosMethod {
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

impl NlosMethod {
    pub fn wavelength(self) -> bool {
        matches!(self, NlosMethod::Fbp | NlosMethod::Pf)
    }
}

#[derive(Args, Debug)]
pub struct ReconstructArgs {
    /// A capture: a tstat bundle of an NLOS scene, or a y-tal HDF5 capture (.hdf5, .h5).
    pub capture: PathBuf,
    #[arg(long, value_enum)]
    pub method: NlosMethod,
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
    #[arg(long, conflicts_with = "denoise_with")]
    pub denoised: Option<PathBuf>,
    /// Denoise and reconstruct the merge of the bundle CAPTURE and this bundle, an
    /// independent capture of the same scene (another seed, or another shard of the
    /// job): tstat's filter with its NLOS defaults, then the denoised capture shrunk
    /// toward the noisy one by the amount that minimises this reconstruction's error,
    /// chosen by cross-validation between the two (docs/nlos.md).
    #[arg(long)]
    pub denoise_with: Option<PathBuf>,
    /// lct: the Wiener filter's signal-to-noise ratio (default 0.8, O'Toole's).
    #[arg(long)]
    pub snr: Option<f64>,
    /// The most working memory the reconstruction may take (e.g. 4G; default 8G); the
    /// capture itself (T L S f32) comes on top. A y-tal file is also read within it
    /// (the file, held whole while it is parsed, and H).
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
    method: NlosMethod,
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
        (NlosMethod::Lct, Some(v)) if !(v > 0.0 && v.is_finite()) => {
            bail!("--snr {v}: the signal-to-noise ratio must be positive and finite")
        }
        (NlosMethod::Lct, _) | (_, None) => {}
        (_, Some(_)) => bail!("--snr belongs to --method lct"),
    }
    Ok(match (method, wavelengths) {
        (NlosMethod::Fbp, Some((wl_mean, wl_sigma))) => Reconstruction::Fbp { wl_mean, wl_sigma },
        (NlosMethod::Pf, Some((wl_mean, wl_sigma))) => Reconstruction::Pf { wl_mean, wl_sigma },
        (NlosMethod::Fk, _) => Reconstruction::Fk,
        (NlosMethod::Lct, _) => Reconstruction::Lct {
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

/// The capture at `path`: a bundle directory, or a y-tal HDF5 file read within
/// `budget` bytes (the file and H; `Capture::from_tal_within`).
fn load(path: &Path, budget: u64) -> anyhow::Result<Capture> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_lowercase())
        .unwrap_or_default();
    let hdf5 = ext == "hdf5" || ext == "h5";
    if path.is_dir() && !hdf5 {
        let bundle = Bundle::open(path)?;
        return Ok(Capture::from_bundle(&bundle)?);
    }
    if hdf5 {
        // Not-found, directories, FIFOs and devices are told apart there, before
        // anything is opened.
        return Ok(Capture::from_tal_within(path, budget)?);
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

/// The widest picture `nlos mip` writes, in pixels.
const MAX_PICTURE: usize = 16384;

/// Bytes of a volume read at once by `nlos mip` and `--denoised` (one band).
const BAND_BYTES: u64 = 64 << 20;

fn mip(m: MipArgs) -> anyhow::Result<()> {
    use crate::bundle::float_rows::{bands, FloatRows};
    use crate::viz::mip::{picture, Axis, Projector};
    if m.out.extension().is_none_or(|e| e != "png") {
        bail!(
            "--out {}: the projection is written as .png",
            m.out.display()
        );
    }
    let budget = memory_budget(m.max_memory.as_deref())?;
    check_outputs(
        &[arg("volume", &m.volume)],
        &[(arg("--out", &m.out), Kind::File)],
        m.force,
    )?;
    let not_volume = |e: &dyn std::fmt::Display| {
        anyhow!(
            "{}: not an (NX, NY, NZ) f32 or f64 .npy volume ({e})",
            m.volume.display()
        )
    };
    let mut volume = FloatRows::open(&m.volume).map_err(|e| not_volume(&e))?;
    let n = match *volume.shape() {
        [nx, ny, nz] if nx > 0 && ny > 0 && nz > 0 => [nx, ny, nz],
        ref s => bail!(
            "{}: shape {s:?} is not a non-empty (NX, NY, NZ) volume",
            m.volume.display()
        ),
    };
    let axis = match m.axis {
        MipAxis::X => Axis::X,
        MipAxis::Y => Axis::Y,
        MipAxis::Z => Axis::Z,
    };
    let projector = Projector::new(n, axis);
    let (width, height) = projector.size();
    let across = width.max(height);
    let scale = match m.scale {
        Some(0) => bail!("--scale 0: at least one pixel per voxel"),
        Some(k) => k,
        None => (512 / across).clamp(1, 64),
    };
    if scale.saturating_mul(across) > MAX_PICTURE {
        bail!(
            "{}: a projection of {width} x {height} cells at {scale} pixels per cell would be over {MAX_PICTURE} pixels across{}",
            m.volume.display(),
            if m.scale.is_some() { " (--scale)" } else { "" }
        );
    }
    // The projection (f32 per cell), the picture (RGB8) and one band of slices.
    let band = BAND_BYTES.min(volume.row_bytes().saturating_mul(n[0] as u64));
    let need = (width * height) as u64 * 4
        + (width * height * scale * scale) as u64 * 3
        + band.max(volume.row_bytes());
    if need > budget {
        bail!(
            "{}: projecting {n:?} along {} needs {} of memory, over --max-memory {}",
            m.volume.display(),
            super::util::cli_name(&m.axis),
            human_bytes(need),
            human_bytes(budget)
        );
    }
    let mut projector = projector;
    let mut values = Vec::new();
    for rows in bands(n[0], volume.row_bytes(), band) {
        let x0 = rows.start;
        volume
            .read_rows(rows, &mut values, &["x", "y", "z"])
            .map_err(|e| anyhow!("{}: {e}", m.volume.display()))?;
        projector.add(x0, &values);
    }
    drop(values);
    let (w, h, px) = picture(&projector.finish(), scale);
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

/// Replaces the capture's H by the denoised volume `d` of the bundle `dir`, read a
/// band of film rows at a time (checked finite, its shape against the capture's film
/// before anything is read).
fn read_denoised(capture: &mut Capture, dir: &Path, d: &Path) -> anyhow::Result<()> {
    use crate::bundle::float_rows::{bands, FloatRows};
    let name = || format!("--denoised {}", d.display());
    let bundle = Bundle::open(dir)?;
    let rec = bundle
        .manifest
        .nlos
        .as_ref()
        .ok_or_else(|| anyhow!("{}: not an NLOS capture", dir.display()))?;
    let mut v = FloatRows::open(d)
        .map_err(|e| anyhow!("{}: not an f32 (rows, Sx, T, C) .npy volume ({e})", name()))?;
    let shape = v.shape().to_vec();
    crate::nlos::denoised::check_shape(capture, rec, &shape)
        .map_err(|e| anyhow!("{}: {e}", name()))?;
    let mut band = Vec::new();
    for rows in bands(shape[0], v.row_bytes(), BAND_BYTES) {
        v.read_rows(rows.clone(), &mut band, &["y", "x", "t", "c"])
            .map_err(|e| anyhow!("{}: {e}", name()))?;
        crate::nlos::denoised::replace_rows(capture, rec, rows, &band, shape[3]);
    }
    Ok(())
}

/// Removes a directory when dropped (the merge of `--denoise-with`'s captures).
struct TempDir(PathBuf);

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Bytes `--denoise-with` holds at its peak beyond the denoiser's own (which keeps
/// within its default budget): the denoised volume of one bundle (H W T C f32) and
/// six captures (noisy and denoised of each half and of the merge, T L S f32) plus the
/// reconstructions' scratch capture.
fn denoise_with_memory(m: &crate::bundle::Manifest, h_len: usize) -> u64 {
    let film = (m.height * m.width * m.bins * m.channel_count()) as u64;
    film * 4 + 7 * h_len as u64 * 4
}

/// The merge of the captures `a` and `b` (independent captures of one scene),
/// denoised and shrunk toward its noisy capture for `method` on `grid` by
/// cross-validation between `a` and `b` (`nlos/shrink.rs`); the `b` chosen and the
/// `b` applied ([`crate::nlos::shrink::applied`]). The
/// merge is written beside `out` for the time it takes and removed after.
fn denoise_with(
    a: &Path,
    b: &Path,
    method: &Reconstruction,
    grid: &VoxelGrid,
    budget: u64,
    out: &Path,
) -> anyhow::Result<(Capture, f64, f64)> {
    use crate::bundle::merge::{merge_bundles, MergeOptions};
    use crate::denoise::{denoise_bundle, DenoiseParams};
    use crate::nlos::shrink::{applied, blend, cross_validated_beta, for_merge};
    let name = out
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let merged = TempDir(out.with_file_name(format!(".{name}.merge-{}", std::process::id())));
    let options = MergeOptions {
        partial: true,
        ..Default::default()
    };
    merge_bundles(&[a.to_path_buf(), b.to_path_buf()], &merged.0, options)
        .map_err(|e| anyhow!("--denoise-with {}: {e}", b.display()))?;
    let params_of = |m: &crate::bundle::Manifest| {
        let mut p = DenoiseParams::default();
        if m.media {
            p.base = crate::denoise::base_filter::BaseKind::Gaussian;
        }
        let exhaustive = crate::denoise::slab::exhaustive(m);
        p.adapt_to_nlos(false, false, exhaustive);
        if let Some(r) = crate::nlos::shrink::radius_for(method, exhaustive) {
            p.radius = r;
        }
        p
    };
    // The noisy and the denoised capture of each of a, b and their merge.
    let mut pairs = Vec::new();
    for dir in [a, b, merged.0.as_path()] {
        let bundle = Bundle::open(dir)?;
        let m = &bundle.manifest;
        let noisy = Capture::from_bundle(&bundle)?;
        let need = denoise_with_memory(m, noisy.h.len());
        if need > budget {
            bail!(
                "--denoise-with: the denoised volume and the six captures need {}, over --max-memory {}",
                human_bytes(need),
                human_bytes(budget)
            );
        }
        let rec = m.nlos.as_ref().expect("a capture");
        let d = denoise_bundle(&bundle, &params_of(m), &|_| {})?;
        // The denoised capture: the noisy one's grids and times, H replaced.
        let mut denoised = noisy.clone();
        let v = d.volume;
        let s = v.shape();
        let shape = [s[0], s[1], s[2], s[3]];
        let values: Vec<f32> = v.into_iter().collect();
        crate::nlos::denoised::replace_h(&mut denoised, rec, &values, shape)?;
        pairs.push((noisy, denoised));
    }
    let (merged_noisy, mut merged_denoised) = pairs.pop().expect("three captures");
    let chosen = for_merge(cross_validated_beta(
        method,
        grid,
        [&pairs[0].0, &pairs[1].0],
        [&pairs[0].1, &pairs[1].1],
    )?);
    let beta = applied(chosen);
    blend(&mut merged_denoised, &merged_noisy, beta);
    Ok((merged_denoised, chosen, beta))
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
    let mut inputs = vec![arg("capture", &r.capture)];
    inputs.extend(r.denoised.iter().map(|d| arg("--denoised", d)));
    inputs.extend(r.denoise_with.iter().map(|d| arg("--denoise-with", d)));
    check_outputs(&inputs, &[(arg("--out", &r.out), Kind::File)], r.force)?;
    if let Some(d) = &r.denoised {
        if !r.capture.is_dir() {
            bail!(
                "--denoised {}: needs the bundle it was denoised from as CAPTURE",
                d.display()
            );
        }
    }
    if let Some(b) = &r.denoise_with {
        for p in [&r.capture, b] {
            if !p.is_dir() {
                bail!(
                    "--denoise-with: {} is not a tstat bundle (a y-tal file has no sample statistics to denoise with)",
                    p.display()
                );
            }
        }
    }
    let budget = memory_budget(r.max_memory.as_deref())?;
    let mut capture = load(&r.capture, budget)?;
    if let Some(d) = &r.denoised {
        read_denoised(&mut capture, &r.capture, d)?;
    }
    check_reconstruction(&method, &capture, &grid, budget)?;
    if let Some(b) = &r.denoise_with {
        let (c, chosen, beta) = denoise_with(&r.capture, b, &method, &grid, budget, &r.out)?;
        capture = c;
        let settled = if beta == chosen {
            String::new()
        } else {
            format!(
                "; {chosen:.3} was chosen, and a blend above {} is not made",
                crate::nlos::shrink::SETTLE
            )
        };
        eprintln!(
            "reconstructing the merge of {} and {}, denoised and shrunk toward its noisy capture by b = {beta:.3} (cross-validated; 0: the denoised capture, 1: the noisy one{settled})",
            r.capture.display(),
            b.display()
        );
    }
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
        capture.time.bins
    );
    Ok(())
}
