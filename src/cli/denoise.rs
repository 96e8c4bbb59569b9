//! `tstat denoise NAME.tstats --out denoised.npy`: the statistical spatio-temporal filter.

use super::export::write_exr_rgb;
use super::util::{arg, check_outputs, human_bytes, threads, with_threads, Kind};
use crate::bundle::write::{stage, Staged};
use crate::bundle::{Bundle, BundleError};
use crate::denoise::base_filter::{BaseKind, Sigmas};
use crate::denoise::critical::Threshold;
use crate::denoise::tstat::TstatParams;
use crate::denoise::{denoise_bundle, memory_bytes, DenoiseParams, Method};
use anyhow::{bail, ensure};
use clap::{Args, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
use ndarray::{s, Array3, Array4};
use std::path::{Path, PathBuf};

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum BaseArg {
    /// Joint bilateral: pixel and bin offsets, albedo, normal.
    Jbf,
    /// Pixel and bin offsets only.
    Gaussian,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum MethodArg {
    /// tstat: emitter classes, camera-depth alignment, patch test (default).
    Tstat,
    /// The published filter: a per-voxel Welch test (--gamma / --alpha).
    Published,
}

/// The filter's options, shared by `denoise`, `report` and `run`.
#[derive(Args, Debug, Clone)]
pub struct FilterArgs {
    /// Membership test.
    #[arg(long, value_enum, default_value = "tstat")]
    pub method: MethodArg,
    /// Spatial radius r in pixels (window 2r + 1) [default: 3 for tstat, 5 for published
    /// and --no-membership].
    #[arg(long, allow_negative_numbers = true)]
    pub radius: Option<i64>,
    /// Temporal radius r_t in bins.
    #[arg(long, default_value_t = 1, allow_negative_numbers = true)]
    pub temporal_radius: i64,
    /// tstat: per-voxel bound on the Welch statistic max_c d^2 / V.
    #[arg(long, allow_negative_numbers = true)]
    pub t2_max: Option<f64>,
    /// tstat: bound on the statistic's mean over bins t-1..t+1.
    #[arg(long, allow_negative_numbers = true)]
    pub t2_patch: Option<f64>,
    /// tstat: spatial radius of pixels that see an emitter (default 4r on independent renders, 0 on stratified ones).
    #[arg(long, allow_negative_numbers = true)]
    pub emitter_radius: Option<i64>,
    /// tstat: do not align neighbours' bins by camera depth.
    #[arg(long)]
    pub no_depth_align: bool,
    /// Published: threshold on 1 - w* (g^2 = 1/(2 gamma) - 1), in (0, 0.5). Default: 0.25 below 16 spp, 0.15 below 64, else 0.1.
    #[arg(long, conflicts_with = "alpha", allow_negative_numbers = true)]
    pub gamma: Option<f64>,
    /// Published: two-sided significance level of the Welch test, in (0, 1) (Student's t, 2n - 2 dof).
    #[arg(long, allow_negative_numbers = true)]
    pub alpha: Option<f64>,
    /// Run the base filter alone (no membership test).
    #[arg(long, conflicts_with_all = ["gamma", "alpha", "t2_max", "t2_patch", "emitter_radius", "no_depth_align"])]
    pub no_membership: bool,
    #[command(flatten)]
    pub base: BaseFilterArgs,
}

/// The base filter's options.
#[derive(Args, Debug, Clone)]
pub struct BaseFilterArgs {
    /// Base filter.
    #[arg(long, value_enum, default_value = "jbf")]
    pub base: BaseArg,
    /// Standard deviation of pixel offsets (default sqrt(10)).
    #[arg(long, allow_negative_numbers = true)]
    pub sigma_xy: Option<f64>,
    /// Standard deviation of bin offsets (default 1).
    #[arg(long, allow_negative_numbers = true)]
    pub sigma_t: Option<f64>,
    /// Standard deviation of albedo differences per channel (default sqrt(0.02)).
    #[arg(long, allow_negative_numbers = true)]
    pub sigma_albedo: Option<f64>,
    /// Standard deviation of normal differences per component (default sqrt(0.1)).
    #[arg(long, allow_negative_numbers = true)]
    pub sigma_normal: Option<f64>,
}

impl BaseFilterArgs {
    /// Default parameters with this base filter.
    pub fn params(&self) -> anyhow::Result<DenoiseParams> {
        let d = Sigmas::default();
        let p = DenoiseParams {
            base: match self.base {
                BaseArg::Jbf => BaseKind::Jbf,
                BaseArg::Gaussian => BaseKind::Gaussian,
            },
            sigmas: Sigmas {
                xy: self.sigma_xy.unwrap_or(d.xy),
                t: self.sigma_t.unwrap_or(d.t),
                albedo: self.sigma_albedo.unwrap_or(d.albedo),
                normal: self.sigma_normal.unwrap_or(d.normal),
            },
            ..Default::default()
        };
        p.validate().map_err(|e| anyhow::anyhow!(e))?;
        Ok(p)
    }
}

impl FilterArgs {
    pub fn params(&self) -> anyhow::Result<DenoiseParams> {
        if let Some(r) = self.radius {
            ensure!(r >= 0, "--radius {r}: must be >= 0");
            ensure!(r <= 64, "--radius {r}: at most 64");
        }
        ensure!(
            self.temporal_radius >= 0,
            "--temporal-radius {}: must be >= 0",
            self.temporal_radius
        );
        ensure!(
            self.temporal_radius <= 64,
            "--temporal-radius {}: at most 64",
            self.temporal_radius
        );
        let tstat_flags = self.t2_max.is_some()
            || self.t2_patch.is_some()
            || self.emitter_radius.is_some()
            || self.no_depth_align;
        let published_flags = self.gamma.is_some() || self.alpha.is_some();
        let method = if self.no_membership {
            Method::BaseOnly
        } else {
            match self.method {
                MethodArg::Tstat => {
                    ensure!(
                        !published_flags,
                        "--gamma / --alpha set the published filter's threshold: add --method published"
                    );
                    if let Some(r) = self.emitter_radius {
                        ensure!(r >= 0, "--emitter-radius {r}: must be >= 0");
                    }
                    let d = TstatParams::default();
                    Method::Tstat(TstatParams {
                        t2_max: self.t2_max.unwrap_or(d.t2_max),
                        t2_patch: self.t2_patch.unwrap_or(d.t2_patch),
                        emitter_radius: self.emitter_radius.map(|r| r as usize),
                        depth_align: !self.no_depth_align,
                    })
                }
                MethodArg::Published => {
                    ensure!(
                        !tstat_flags,
                        "--t2-max, --t2-patch, --emitter-radius and --no-depth-align belong to --method tstat"
                    );
                    Method::Published(match (self.gamma, self.alpha) {
                        (_, Some(a)) => Threshold::Alpha(a),
                        (Some(g), None) => Threshold::Gamma(g),
                        (None, None) => Threshold::Auto,
                    })
                }
            }
        };
        let p = DenoiseParams {
            radius: self.radius.map_or(method.default_radius(), |r| r as usize),
            temporal_radius: self.temporal_radius as usize,
            method,
            ..self.base.params()?
        };
        p.validate().map_err(|e| anyhow::anyhow!(e))?;
        Ok(p)
    }
}

#[derive(Args, Debug)]
pub struct DenoiseArgs {
    /// A statistics bundle directory.
    pub bundle: PathBuf,
    /// Output volume, f32 (H, W, T, C) .npy.
    #[arg(long)]
    pub out: PathBuf,
    #[command(flatten)]
    pub filter: FilterArgs,
    /// Also write one OpenEXR per bin into this directory.
    #[arg(long)]
    pub exr: Option<PathBuf>,
    /// Worker threads (default: all cores). The output does not depend on it.
    #[arg(long, allow_negative_numbers = true)]
    pub threads: Option<i64>,
    /// Replace existing outputs.
    #[arg(long)]
    pub force: bool,
}

/// Writes every bin of an (H, W, T, C) volume as `DIR/bin_NNNN.exr` under a temporary
/// name; the caller commits it.
pub fn stage_exr_bins(
    dir: &Path,
    volume: &Array4<f32>,
    force: bool,
) -> Result<Staged, BundleError> {
    stage(dir, force, |tmp| {
        std::fs::create_dir(tmp).map_err(|e| BundleError::Io(tmp.to_path_buf(), e.to_string()))?;
        let digits = volume.shape()[2].to_string().len().max(4);
        for k in 0..volume.shape()[2] {
            let img: Array3<f32> = volume.slice(s![.., .., k, ..]).to_owned();
            write_exr_rgb(&tmp.join(format!("bin_{k:0digits$}.exr")), &img)?;
        }
        Ok(())
    })
}

pub fn run(a: DenoiseArgs) -> anyhow::Result<()> {
    let params = a.filter.params()?;
    if a.out.extension().and_then(|e| e.to_str()) != Some("npy") {
        bail!("--out {}: the volume is written as .npy", a.out.display());
    }
    let threads = threads(a.threads)?;
    let mut outputs = vec![(arg("--out", &a.out), Kind::File)];
    if let Some(d) = &a.exr {
        outputs.push((arg("--exr", d), Kind::Dir));
    }
    check_outputs(&[arg("bundle", &a.bundle)], &outputs, a.force)?;
    let bundle = Bundle::open(&a.bundle)?;
    let m = &bundle.manifest;
    eprintln!(
        "{}: {}x{} px, {} bins, {} spp; denoiser memory ~{} (plus the f64 sums while reading)",
        a.bundle.display(),
        m.width,
        m.height,
        m.bins,
        m.spp,
        human_bytes(memory_bytes(m.height, m.width, m.bins))
    );
    let bar = ProgressBar::new((m.width * m.height) as u64).with_style(
        ProgressStyle::with_template("{bar:40} {percent:>3}% pixels, ETA {eta}")
            .expect("valid template"),
    );
    let result = with_threads(threads, || {
        denoise_bundle(&bundle, &params, &|n| bar.inc(n))
    })??;
    bar.finish_and_clear();
    // Both outputs are written completely before either is put in place.
    let volume = stage(&a.out, a.force, |tmp| {
        ndarray_npy::write_npy(tmp, &result.volume)
            .map_err(|e| BundleError::Io(a.out.clone(), e.to_string()))
    })?;
    let exr = match &a.exr {
        Some(d) => Some(stage_exr_bins(d, &result.volume, a.force)?),
        None => None,
    };
    volume.commit()?;
    if let Some(e) = exr {
        e.commit()?;
    }
    say!(
        "denoised {} -> {} in {:.2} s (filter {:.2} s: {:.0} M voxel-neighbour evaluations/s){}",
        a.bundle.display(),
        a.out.display(),
        result.seconds,
        result.filter_seconds,
        result.evaluations as f64 / result.filter_seconds / 1e6,
        a.exr
            .as_ref()
            .map(|d| format!("; EXR bins in {}", d.display()))
            .unwrap_or_default()
    );
    Ok(())
}
