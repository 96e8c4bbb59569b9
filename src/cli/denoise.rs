//! `tstat denoise NAME.tstats --out denoised.npy`: the statistical spatio-temporal filter.

use super::export::{exr_channel_names, write_exr};
use super::util::{arg, check_outputs, human_bytes, size_flag, threads, with_threads, Kind};
use crate::bundle::write::{stage, Staged};
use crate::bundle::{Bundle, BundleError};
use crate::denoise::base_filter::{BaseKind, Sigmas};
use crate::denoise::critical::Threshold;
use crate::denoise::slab::{denoise_bundle_to_npy, halo, Dims, SlabPlan, DEFAULT_BUDGET};
use crate::denoise::tstat::TstatParams;
use crate::denoise::{memory_bytes, Border, DenoiseParams, Method, Variance};
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
pub enum VarianceArg {
    Unbiased,
    Biased,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum BorderArg {
    Clip,
    Zero,
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
    /// Spatial radius r in pixels (window 2r + 1) [default: 1 on NLOS captures; else 3 for tstat, 5 for published
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
    /// tstat: align neighbours' bins by camera depth also on NLOS captures (off there by
    /// default: a capture's times do not follow the depth from its sensor origin).
    #[arg(long, conflicts_with = "no_depth_align")]
    pub depth_align: bool,
    /// Published: threshold on 1 - w* (g^2 = 1/(2 gamma) - 1), in (0, 0.5). Default: 0.25 below 16 spp, 0.15 below 64, else 0.1.
    #[arg(long, conflicts_with = "alpha", allow_negative_numbers = true)]
    pub gamma: Option<f64>,
    /// Published: two-sided significance level of the Welch test, in (0, 1) (Student's t, 2n - 2 dof).
    #[arg(long, allow_negative_numbers = true)]
    pub alpha: Option<f64>,
    /// Run the base filter alone (no membership test).
    #[arg(long, conflicts_with_all = ["gamma", "alpha", "t2_max", "t2_patch", "emitter_radius", "no_depth_align", "depth_align"])]
    pub no_membership: bool,
    /// Published: the estimates' variance. unbiased (SPEC 5, the default) or biased, the
    /// published code's (X2 / n - mu^2 in the skewness term and in V; docs/denoiser.md).
    #[arg(long, value_enum, default_value = "unbiased")]
    pub variance: VarianceArg,
    /// Published: beyond the volume's borders. clip (SPEC 8, the default) or zero, the
    /// published code's zero padding of radiance, estimands, variances and guidance.
    #[arg(long, value_enum, default_value = "clip")]
    pub border: BorderArg,
    #[command(flatten)]
    pub base: BaseFilterArgs,
}

/// The base filter's options.
#[derive(Args, Debug, Clone)]
pub struct BaseFilterArgs {
    /// Base filter [default: jbf; gaussian for scenes with participating media, whose
    /// G-buffers describe the fog's first scatterings, not surfaces].
    #[arg(long, value_enum)]
    pub base: Option<BaseArg>,
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
    /// The base filter: the one asked for, else Gaussian for renders of scenes with
    /// media and the joint bilateral filter otherwise (SPEC 7, 8).
    pub fn kind(&self, media: bool) -> BaseKind {
        match (self.base, media) {
            (Some(BaseArg::Jbf), _) | (None, false) => BaseKind::Jbf,
            (Some(BaseArg::Gaussian), _) | (None, true) => BaseKind::Gaussian,
        }
    }

    /// Default parameters with this base filter.
    pub fn params(&self) -> anyhow::Result<DenoiseParams> {
        let d = Sigmas::default();
        let p = DenoiseParams {
            base: self.kind(false),
            sigmas: Sigmas {
                xy: self.sigma_xy.unwrap_or(d.xy),
                t: self.sigma_t.unwrap_or(d.t),
                albedo: self.sigma_albedo.unwrap_or(d.albedo),
                normal: self.sigma_normal.unwrap_or(d.normal),
            },
            ..Default::default()
        };
        p.validate()?;
        Ok(p)
    }
}

impl FilterArgs {
    /// The parameters' defaults that depend on the bundle: an NLOS capture's
    /// ([`DenoiseParams::adapt_to_nlos`]).
    pub fn adapt(&self, p: &mut DenoiseParams, m: &crate::bundle::Manifest) {
        if m.nlos.is_some() {
            let exhaustive = crate::denoise::slab::exhaustive(m);
            p.adapt_to_nlos(self.radius.is_some(), self.depth_align, exhaustive);
        }
    }

    /// Refuses what the bundle cannot give: the published code's biased variance is
    /// of i.i.d. sums, not of replicates.
    pub fn check_bundle(&self, m: &crate::bundle::Manifest) -> anyhow::Result<()> {
        ensure!(
            self.variance == VarianceArg::Unbiased || m.replicates.is_none(),
            "--variance biased: the published code's convention for i.i.d. samples; this bundle's V comes from its {} replicates",
            m.replicates.unwrap_or(0)
        );
        Ok(())
    }

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
            || self.no_depth_align
            || self.depth_align;
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
                        ..d
                    })
                }
                MethodArg::Published => {
                    ensure!(
                        !tstat_flags,
                        "--t2-max, --t2-patch, --emitter-radius and --(no-)depth-align belong to --method tstat"
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
            variance: match self.variance {
                VarianceArg::Unbiased => Variance::Unbiased,
                VarianceArg::Biased => Variance::Biased,
            },
            border: match self.border {
                BorderArg::Clip => Border::Clip,
                BorderArg::Zero => Border::Zero,
            },
            ..self.base.params()?
        };
        p.validate()?;
        Ok(p)
    }
}

#[derive(Args, Debug)]
pub struct DenoiseArgs {
    /// A statistics bundle directory.
    #[arg(
        required_unless_present = "from_arrays",
        conflicts_with = "from_arrays"
    )]
    pub bundle: Option<PathBuf>,
    /// Denoise per-voxel estimates instead of a bundle: a folder with the published
    /// pipeline's arrays (noisy.npy, estimands.npy, estimands_variance.npy, albedo.npy,
    /// normals.npy; tstat's depth.npy, emitter.npy, pixel_spp.npy and meta.json if
    /// there), as `tstat export --published` writes them (docs/python.md).
    #[arg(long, value_name = "DIR")]
    pub from_arrays: Option<PathBuf>,
    /// With --from-arrays: the samples per pixel behind the estimates (else meta.json's).
    #[arg(long, allow_negative_numbers = true)]
    pub spp: Option<i64>,
    /// With --from-arrays: the transform theta and V are in (else meta.json's, else
    /// yeo-johnson:0.5, the published pipeline's).
    #[arg(long)]
    pub transform: Option<String>,
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
    /// Memory budget (e.g. 4G): the image is denoised in slabs of rows that fit it
    /// (default 1G); refused when one row and its halo do not fit. The output does not
    /// depend on it.
    #[arg(long, allow_hyphen_values = true)]
    pub max_memory: Option<String>,
    /// Replace existing outputs.
    #[arg(long)]
    pub force: bool,
}

/// Writes every bin of the f32 (H, W, T, C) `.npy` volume at `npy` (written by
/// [`crate::denoise::slab::NpyVolumeWriter`]) as `DIR/bin_NNNN.exr` under a temporary
/// name, its C channels named `names` (`export::exr_channel_names`: R, G, B; Y;
/// S0.Y .. S3.Y); the caller commits it. Reads as many bins at a time as `budget`
/// holds.
pub fn stage_exr_bins(
    dir: &Path,
    npy: &Path,
    (h, w, t): (usize, usize, usize),
    names: &[String],
    budget: u64,
    force: bool,
) -> Result<Staged, BundleError> {
    use std::os::unix::fs::FileExt;
    let channels = names.len();
    stage(dir, force, |tmp| {
        let io = |e: std::io::Error| BundleError::io(dir, e);
        std::fs::create_dir(tmp).map_err(io)?;
        let file = std::fs::File::open(npy).map_err(io)?;
        let data_offset = file.metadata().map_err(io)?.len() - (h * w * t * channels * 4) as u64;
        let per_bin = (h * w * channels * 4) as u64;
        let step = ((budget / per_bin.max(1)) as usize).clamp(1, t);
        let digits = t.to_string().len().max(4);
        let mut run = Vec::new();
        for k0 in (0..t).step_by(step) {
            let k1 = (k0 + step).min(t);
            let n = k1 - k0;
            // (H, W, n, C): each pixel's bins k0..k1 are one run in the file.
            let mut bins = Array4::<f32>::zeros((h, w, n, channels));
            let flat = bins.as_slice_mut().expect("standard layout");
            run.resize(n * channels * 4, 0u8);
            for (p, px) in flat.chunks_exact_mut(n * channels).enumerate() {
                let at = data_offset + ((p * t + k0) * channels * 4) as u64;
                file.read_exact_at(&mut run, at).map_err(io)?;
                for (v, b) in px.iter_mut().zip(run.chunks_exact(4)) {
                    *v = f32::from_le_bytes(b.try_into().expect("4 bytes"));
                }
            }
            for k in 0..n {
                let img: Array3<f32> = bins.slice(s![.., .., k, ..]).to_owned();
                write_exr(
                    &tmp.join(format!("bin_{:0digits$}.exr", k0 + k)),
                    &img,
                    names,
                )?;
            }
        }
        Ok(())
    })
}

pub fn run(a: DenoiseArgs) -> anyhow::Result<()> {
    let mut params = a.filter.params()?;
    let Some(bundle_path) = a.bundle.clone() else {
        return from_arrays(&a, params);
    };
    ensure!(
        a.spp.is_none() && a.transform.is_none(),
        "--spp and --transform describe --from-arrays' estimates: a bundle records its own"
    );
    if a.out.extension().and_then(|e| e.to_str()) != Some("npy") {
        bail!("--out {}: the volume is written as .npy", a.out.display());
    }
    let threads = threads(a.threads)?;
    let budget = match &a.max_memory {
        Some(s) => size_flag("--max-memory", s)?,
        None => DEFAULT_BUDGET,
    };
    let mut outputs = vec![(arg("--out", &a.out), Kind::File)];
    if let Some(d) = &a.exr {
        outputs.push((arg("--exr", d), Kind::Dir));
    }
    check_outputs(&[arg("bundle", &bundle_path)], &outputs, a.force)?;
    let bundle = Bundle::open(&bundle_path)?;
    let m = &bundle.manifest;
    params.base = a.filter.base.kind(m.media);
    a.filter.adapt(&mut params, m);
    a.filter.check_bundle(m)?;
    if m.nlos.is_some() {
        eprintln!(
            "an NLOS capture: spatial radius {}, bins {}aligned by camera depth (docs/nlos.md)",
            params.radius,
            match params.method {
                Method::Tstat(t) if t.depth_align => "",
                _ => "not ",
            }
        );
    }
    let dims = Dims::of(m);
    let halo = halo(&bundle, &params)?;
    let plan = SlabPlan::for_budget(dims, halo, budget);
    let need = memory_bytes(dims, &plan);
    ensure!(
        need <= budget,
        "--max-memory {}: denoising {}x{} px x {} bins needs at least {} (one row and its halo of {halo} rows on each side)",
        a.max_memory.clone().unwrap_or_else(|| human_bytes(budget)),
        m.width,
        m.height,
        m.bins,
        human_bytes(need)
    );
    eprintln!(
        "{}: {}x{} px, {} bins, {} spp; denoiser memory ~{} ({} of {} rows, halo {halo})",
        bundle_path.display(),
        m.width,
        m.height,
        m.bins,
        m.spp,
        human_bytes(need),
        match plan.slabs(dims) {
            1 => "1 slab".to_string(),
            n => format!("{n} slabs"),
        },
        plan.rows.min(m.height),
    );
    let bar = ProgressBar::new((m.width * m.height) as u64).with_style(
        ProgressStyle::with_template("{bar:40} {percent:>3}% pixels, ETA {eta}")
            .expect("valid template"),
    );
    // Both outputs are written completely before either is put in place.
    let (mut stats, mut exr) = (None, None);
    let volume = with_threads(threads, || {
        stage(&a.out, a.force, |tmp| -> Result<(), BundleError> {
            let progress = |n| bar.inc(n);
            stats = Some(denoise_bundle_to_npy(
                &bundle, &params, &plan, tmp, &a.out, &progress,
            )?);
            bar.finish_and_clear();
            if let Some(d) = &a.exr {
                let size = (m.height, m.width, m.bins);
                let names = exr_channel_names(m.mode);
                exr = Some(stage_exr_bins(d, tmp, size, &names, budget, a.force)?);
            }
            Ok(())
        })
    })??;
    volume.commit()?;
    if let Some(e) = exr {
        e.commit()?;
    }
    let result = stats.expect("denoised");
    say!(
        "denoised {} -> {} in {:.3} s (filter {:.3} s: {:.0} M voxel-neighbour evaluations/s){}",
        bundle_path.display(),
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

/// `--from-arrays DIR`: the filter on the published pipeline's arrays
/// (`denoise::arrays`), in memory.
fn from_arrays(a: &DenoiseArgs, mut params: DenoiseParams) -> anyhow::Result<()> {
    use crate::bundle::published::{transform_of, PublishedArrays};
    use crate::denoise::arrays::{denoise_arrays, memory_bytes, ArraysSettings};
    let dir = a
        .from_arrays
        .as_ref()
        .expect("clap: a bundle or --from-arrays");
    if a.out.extension().and_then(|e| e.to_str()) != Some("npy") {
        bail!("--out {}: the volume is written as .npy", a.out.display());
    }
    ensure!(
        a.filter.variance == VarianceArg::Unbiased,
        "--variance: the arrays' V is given, made with whatever convention made it; only a bundle's sums can be estimated again"
    );
    let threads = threads(a.threads)?;
    let budget = match &a.max_memory {
        Some(s) => size_flag("--max-memory", s)?,
        None => DEFAULT_BUDGET,
    };
    let mut outputs = vec![(arg("--out", &a.out), Kind::File)];
    if let Some(d) = &a.exr {
        outputs.push((arg("--exr", d), Kind::Dir));
    }
    check_outputs(&[arg("--from-arrays", dir)], &outputs, a.force)?;
    ensure!(
        dir.is_dir(),
        "--from-arrays {}: not a folder",
        dir.display()
    );
    let arrays = PublishedArrays::read(dir)?;
    let meta = arrays.meta.as_ref();
    let spp = match (a.spp, meta) {
        (Some(n), _) => super::util::int_flag("--spp", n, 2, i64::from(u32::MAX))? as u64,
        (None, Some(m)) => {
            ensure!(
                m.spp >= 2,
                "{}: spp {} (at least 2 samples per pixel give a variance)",
                dir.join("meta.json").display(),
                m.spp
            );
            m.spp
        }
        (None, None) => bail!(
            "--from-arrays {}: give --spp (the samples per pixel behind the estimates; the folder has no meta.json)",
            dir.display()
        ),
    };
    let transform = transform_of(a.transform.as_deref(), meta).map_err(anyhow::Error::msg)?;
    let settings = ArraysSettings {
        spp,
        transform,
        stratified: meta.is_some_and(|m| m.stratified),
        bin_width_opl: meta.and_then(|m| m.bin_width_opl),
    };
    params.base = a.filter.base.kind(false);
    let (h, w, t, ch) = arrays.noisy.dim();
    let need = memory_bytes((h * w * t * ch) as u64);
    ensure!(
        need <= budget,
        "--max-memory {}: denoising {w}x{h} px x {t} bins from arrays needs {} (the arrays are held whole)",
        a.max_memory.clone().unwrap_or_else(|| human_bytes(budget)),
        human_bytes(need)
    );
    let bar = ProgressBar::new((w * h) as u64).with_style(
        ProgressStyle::with_template("{bar:40} {percent:>3}% pixels, ETA {eta}")
            .expect("valid template"),
    );
    let den = with_threads(threads, || {
        denoise_arrays(&arrays, &settings, &params, &|n| bar.inc(n))
    })?;
    bar.finish_and_clear();
    drop(arrays);
    let mut exr = None;
    stage(&a.out, a.force, |tmp| -> Result<(), BundleError> {
        ndarray_npy::write_npy(tmp, &den.volume)
            .map_err(|e| BundleError::io(&a.out, std::io::Error::other(e)))?;
        if let Some(d) = &a.exr {
            // The published pipeline's arrays are RGB (`bundle::published`).
            let names = exr_channel_names(crate::scene::mode::RenderMode::Rgb);
            exr = Some(stage_exr_bins(d, tmp, (h, w, t), &names, budget, a.force)?);
        }
        Ok(())
    })?
    .commit()?;
    if let Some(e) = exr {
        e.commit()?;
    }
    say!(
        "denoised {} -> {} in {:.3} s ({}, {spp} spp, {})",
        dir.display(),
        a.out.display(),
        den.seconds,
        params.method.describe(),
        transform
    );
    Ok(())
}
