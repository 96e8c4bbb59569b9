//! `tstat render SCENE.xml --out NAME.tstats`: render and write a statistics bundle.

use super::adaptive::AdaptiveArgs;
use super::progress::Bars;
use super::util::{
    arg, check_outputs, disk_size, finite, human_bytes, opt_int, positive, seed, size_flag,
    threads, Kind, MAX_FILM_SIDE,
};
use crate::bundle::shard::{Shard, PLACEHOLDER};
use crate::job::RenderJob;
use crate::render::PixelSampling;
use crate::scene::{Overrides, Scene};
use crate::sensors::time_origin::TimeOrigin;
use crate::stats::Transform;
use anyhow::{anyhow, bail};
use clap::Args;
use std::path::{Path, PathBuf};

/// The scene's film, time axis, path depth, `<default>`s and sub-pixel sampling (the
/// spp is each command's own flag: `report convergence` takes a list).
#[derive(Args, Debug, Clone)]
pub struct SceneArgs {
    /// Image width (keeps the aspect ratio unless --height is given too).
    #[arg(long, allow_negative_numbers = true)]
    pub width: Option<i64>,
    /// Image height.
    #[arg(long, allow_negative_numbers = true)]
    pub height: Option<i64>,
    /// Number of time bins.
    #[arg(long, allow_negative_numbers = true)]
    pub bins: Option<i64>,
    /// OPL at the start of bin 0 (scene units).
    #[arg(long, allow_negative_numbers = true)]
    pub start_opl: Option<f64>,
    /// Bin width in OPL (scene units).
    #[arg(long, allow_negative_numbers = true)]
    pub bin_width_opl: Option<f64>,
    /// Longest path in segments (-1: unbounded).
    #[arg(long, allow_negative_numbers = true)]
    pub max_depth: Option<i64>,
    /// Set a scene <default>: -D name=value (repeatable).
    #[arg(short = 'D', value_name = "NAME=VALUE")]
    pub defines: Vec<String>,
    /// Add a folder to the search path for the files the scene names (meshes,
    /// textures, includes), after the scene's own folder (Mitsuba's -a; repeatable).
    #[arg(short = 'a', value_name = "DIR")]
    pub search_paths: Vec<std::path::PathBuf>,
    /// How each path draws its numbers (alias --sampler). sobol (default): every
    /// dimension of the camera and first-hit vertices (position, light, BSDF, phase,
    /// delay, free flight) from a scrambled Sobol' set; stratified (alias
    /// stratified-pixel): only the sub-pixel positions form a stratified set;
    /// independent: i.i.d. samples, exactly what the statistics assume. Under the first
    /// two the variances the denoiser estimates over-estimate the true ones
    /// (conservative) unless --replicates is given.
    #[arg(long, alias = "sampler", value_enum, default_value_t = PixelSampling::Sobol)]
    pub pixel_sampling: PixelSampling,
    /// Split each pixel's spp into B independently randomised replicates of spp / B
    /// samples and keep R2 (their squared means) per voxel: a variance of the mean that
    /// stays valid under stratified and Sobol' sampling (SPEC 4-5). B must divide spp;
    /// 0: none. Adds `r2.npy`, 24 bytes a voxel (a third more).
    #[arg(long, default_value_t = 0)]
    pub replicates: u32,
    /// Where camera paths' optical path length starts: near_clip (default; as Mitsuba
    /// and mitransient, rays start on the near-clip plane, near_clip / cos(theta) from
    /// the pinhole) or pinhole (the camera's origin; near_clip ignored). NLOS captures
    /// count from the sensor (pinhole). `tstat check` says when the two differ by more
    /// than a tenth of a bin.
    #[arg(long, value_parser = ["near_clip", "near-clip", "pinhole"])]
    pub time_origin: Option<String>,
    /// What a path carries: rgb (default: the three channels); spectral (three
    /// wavelengths per path, sampled as Mitsuba's spectral variants do; RGB in the
    /// scene lifted to smooth spectra; each path's linear sRGB recorded, so the
    /// bundle keeps three channels); mono (one channel: the luminance of every
    /// colour); mono_polarized (mono with Mueller matrices along the path: four
    /// channels, the Stokes components S0..S3 in the sensor's frame). Spectral
    /// refuses NLOS captures, media and the principled BSDFs; the mono modes NLOS
    /// captures and media. docs/spectral.md, docs/polarization.md.
    #[arg(long, value_enum, default_value_t = ModeArg::Rgb)]
    pub mode: ModeArg,
}

/// `--mode`'s values.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ModeArg {
    Rgb,
    Spectral,
    Mono,
    #[value(name = "mono_polarized", alias = "mono-polarized")]
    MonoPolarized,
    #[value(name = "spectral_polarized", alias = "spectral-polarized")]
    SpectralPolarized,
}

impl ModeArg {
    pub fn name(self) -> &'static str {
        crate::scene::mode::RenderMode::from(self).name()
    }
}

impl From<ModeArg> for crate::scene::mode::RenderMode {
    fn from(m: ModeArg) -> Self {
        match m {
            ModeArg::Rgb => Self::Rgb,
            ModeArg::Spectral => Self::Spectral,
            ModeArg::Mono => Self::Mono,
            ModeArg::MonoPolarized => Self::MonoPolarized,
            ModeArg::SpectralPolarized => Self::SpectralPolarized,
        }
    }
}

impl SceneArgs {
    /// `--transform`, checked against `--mode`: Box-Cox is undefined below zero, and a
    /// spectral path's sRGB samples may be negative.
    pub fn transform(&self, text: &str) -> anyhow::Result<Transform> {
        let t: Transform = text
            .parse()
            .map_err(|e| anyhow::anyhow!("--transform: {e}"))?;
        let mode = crate::scene::mode::RenderMode::from(self.mode);
        if mode.signed() && matches!(t, Transform::BoxCox { .. }) {
            bail!("--transform {text} with --mode {}: Box-Cox is undefined below zero, and this mode's samples can be negative (a spectral path's sRGB, the Stokes components S1..S3); use yeo-johnson (which is) or identity", self.mode.name());
        }
        Ok(t)
    }

    /// The checked overrides, with `--spp` if given.
    pub fn overrides(&self, spp: Option<i64>) -> anyhow::Result<Overrides> {
        let mut defaults = Vec::new();
        for d in &self.defines {
            let Some((k, v)) = d.split_once('=') else {
                bail!("-D {d}: expected name=value");
            };
            anyhow::ensure!(!k.trim().is_empty(), "-D {d}: the name is empty");
            defaults.push((k.to_string(), v.to_string()));
        }
        if let Some(s) = spp {
            anyhow::ensure!(
                s >= 2,
                "--spp {s}: must be at least 2 (at least 2 samples per pixel are needed to estimate a variance)"
            );
        }
        if let Some(h) = self.bin_width_opl {
            crate::sensors::film::check_bin_width("--bin-width-opl", h)?;
        }
        if let Some(t0) = self.start_opl {
            finite("--start-opl", t0)?;
        }
        Ok(Overrides {
            defaults,
            spp: opt_int("--spp", spp, 2, u32::MAX as i64)?,
            width: opt_int("--width", self.width, 1, MAX_FILM_SIDE)?,
            height: opt_int("--height", self.height, 1, MAX_FILM_SIDE)?,
            bins: opt_int("--bins", self.bins, 1, MAX_FILM_SIDE)?,
            start_opl: self.start_opl,
            bin_width_opl: self.bin_width_opl,
            max_depth: opt_int("--max-depth", self.max_depth, -1, i32::MAX as i64)?,
            time_origin: self.time_origin.as_deref().map(|o| match o {
                "pinhole" => TimeOrigin::Pinhole,
                _ => TimeOrigin::NearClip,
            }),
            search_paths: super::util::search_folders(&self.search_paths)?,
            mode: self.mode.into(),
        })
    }
}

#[derive(Args, Debug)]
pub struct RenderArgs {
    /// Mitsuba 3 XML scene.
    pub scene: PathBuf,
    /// Output bundle directory (conventionally NAME.tstats).
    #[arg(long)]
    pub out: PathBuf,
    /// Samples per pixel (overrides the sampler's sample_count; at least 2).
    #[arg(long, allow_negative_numbers = true)]
    pub spp: Option<i64>,
    #[command(flatten)]
    pub scene_args: SceneArgs,
    /// Random seed (default: the sampler's seed parameter, else 0).
    #[arg(long, allow_negative_numbers = true)]
    pub seed: Option<i128>,
    /// Worker threads (default: all cores). The bundle does not depend on it.
    #[arg(long, allow_negative_numbers = true)]
    pub threads: Option<i64>,
    /// Sample transform: identity, box-cox:LAMBDA or yeo-johnson:LAMBDA.
    #[arg(long, default_value = "identity")]
    pub transform: String,
    /// Metres per scene unit (for the seconds in the manifest).
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    pub unit_m: f64,
    /// Refuse to render when it needs more memory than this (e.g. 8G; default 75% of RAM).
    /// Rows stream to disk: the need is threads x one row's buffers, plus the G-buffers.
    #[arg(long, allow_hyphen_values = true)]
    pub max_memory: Option<String>,
    /// Render shard I of N of this job (I/N), or take I from the scheduler (auto/N:
    /// SLURM_ARRAY_TASK_ID, else JOB_COMPLETION_INDEX). The shard renders spp / N
    /// samples per pixel (and replicates / N) with its own seed derived from --seed;
    /// `{shard}` in --out becomes I (required with auto). `tstat merge` of the N
    /// bundles is the job's bundle.
    #[arg(long, value_name = "I/N")]
    pub shard: Option<String>,
    /// Adaptive sampling: --spp becomes the mean per pixel, and each pixel gets samples
    /// where they lower the volume's expected error most (n_i proportional to
    /// sqrt(V_i / cost_i), from a pilot of --pilot-spp whose samples are not in the
    /// sums; between spp / 2 and 16 spp a pixel). Adds `pixel_spp.npy` (4 bytes a pixel).
    #[arg(long)]
    pub adaptive: bool,
    #[command(flatten)]
    pub adaptive_args: AdaptiveArgs,
    /// Replace an existing output.
    #[arg(long)]
    pub force: bool,
}

/// The shard of `--shard` and the output path with `{shard}` filled in.
fn shard_and_out(spec: Option<&str>, out: &Path) -> anyhow::Result<(Option<Shard>, PathBuf)> {
    let Some(spec) = spec else {
        return Ok((None, out.to_path_buf()));
    };
    let shard = Shard::parse(spec, |k| std::env::var(k).ok())?;
    let text = out.to_str().ok_or_else(|| {
        anyhow!(
            "--out {}: with --shard the path must be UTF-8",
            out.display()
        )
    })?;
    anyhow::ensure!(
        text.contains(PLACEHOLDER) || !spec.trim_start().starts_with("auto"),
        "--out {text}: with --shard auto/N every task needs its own output; put {PLACEHOLDER} in the path (it becomes the shard's index)"
    );
    Ok((Some(shard), PathBuf::from(shard.out_path(text))))
}

/// The checked flags, the output checked against the inputs, and the scene loaded:
/// the job `tstat render` (and the Python package's `render`) runs.
pub fn prepare(a: &RenderArgs) -> anyhow::Result<(Scene, RenderJob)> {
    let started = std::time::Instant::now();
    let transform = a.scene_args.transform(&a.transform)?;
    positive("--unit-m", a.unit_m)?;
    let overrides = a.scene_args.overrides(a.spp)?;
    let threads = threads(a.threads)?;
    let seed = seed(a.seed)?;
    let max_memory = match &a.max_memory {
        Some(s) => Some(size_flag("--max-memory", s)?),
        None => None,
    };
    if !a.adaptive {
        a.adaptive_args.refuse_when_off("without --adaptive")?;
    }
    let adaptive = a.adaptive_args.request(a.shard.is_some())?;
    let (shard, out) = shard_and_out(a.shard.as_deref(), &a.out)?;
    check_outputs(
        &[arg("scene", &a.scene)],
        &[(arg("--out", &out), Kind::Dir)],
        a.force,
    )?;
    let scene = Scene::load(&a.scene, &overrides)?;
    super::util::check_mesh_inputs(&scene, &[arg("--out", &out)])?;
    super::util::print_scene_warnings(&scene);
    let job = RenderJob {
        force: a.force,
        seed,
        transform,
        unit_m: a.unit_m,
        pixel_sampling: a.scene_args.pixel_sampling,
        replicates: a.scene_args.replicates,
        threads,
        max_memory,
        shard,
        adaptive: a.adaptive.then_some(adaptive),
        spp_given: a.spp.is_some(),
        started,
        ..RenderJob::new(&out)
    };
    Ok((scene, job))
}

pub fn run(a: RenderArgs) -> anyhow::Result<()> {
    let (scene, job) = prepare(&a)?;
    let transform = job.transform;
    let out = job.out.clone();
    let report = crate::job::render(scene, &job, &Bars::new(false))?;
    let summary = &report.summary;
    let seconds = summary.seconds;
    say!(
        "rendered {} in {:.2} s: {:.2} M paths/s, {:.2} M rays/s ({} paths, {} rays); bundle {} ({}){}",
        out.display(),
        seconds,
        summary.paths as f64 / seconds / 1e6,
        summary.rays as f64 / seconds / 1e6,
        summary.paths,
        summary.rays,
        human_bytes(disk_size(&out)),
        transform,
        if summary.dropped_nonfinite > 0 {
            format!(
                "; {} non-finite contributions dropped",
                summary.dropped_nonfinite
            )
        } else {
            String::new()
        }
    );
    Ok(())
}
