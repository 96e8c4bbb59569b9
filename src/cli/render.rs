//! `tstat render SCENE.xml --out NAME.tstats`: render and write a statistics bundle.

use super::util::{
    arg, check_memory, check_outputs, disk_size, human_bytes, parse_bytes, with_threads, Kind,
};
use crate::bundle::write::{write_bundle, BundleMeta};
use crate::render::{render, PixelSampling, RenderSettings};
use crate::scene::{Overrides, Scene};
use crate::stats::accumulators::Accumulators;
use crate::stats::Transform;
use anyhow::{bail, Context};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use std::path::PathBuf;

#[derive(Args, Debug, Clone)]
pub struct SceneArgs {
    /// Samples per pixel (overrides the sampler's sample_count; at least 2).
    #[arg(long)]
    pub spp: Option<u32>,
    /// Image width (keeps the aspect ratio unless --height is given too).
    #[arg(long)]
    pub width: Option<usize>,
    /// Image height.
    #[arg(long)]
    pub height: Option<usize>,
    /// Number of time bins.
    #[arg(long)]
    pub bins: Option<usize>,
    /// OPL at the start of bin 0 (scene units).
    #[arg(long, allow_negative_numbers = true)]
    pub start_opl: Option<f64>,
    /// Bin width in OPL (scene units).
    #[arg(long, allow_negative_numbers = true)]
    pub bin_width_opl: Option<f64>,
    /// Longest path in segments (-1: unbounded).
    #[arg(long, allow_negative_numbers = true)]
    pub max_depth: Option<i32>,
    /// Set a scene <default>: -D name=value (repeatable).
    #[arg(short = 'D', value_name = "NAME=VALUE")]
    pub defines: Vec<String>,
    /// Sub-pixel positions of the primary rays. Stratified lowers the error at edges; the
    /// variances the denoiser estimates then over-estimate the true ones (conservative).
    /// Independent gives i.i.d. samples, exactly what the statistics assume.
    #[arg(long, value_enum, default_value_t = PixelSampling::Stratified)]
    pub pixel_sampling: PixelSampling,
}

impl SceneArgs {
    pub fn overrides(&self) -> anyhow::Result<Overrides> {
        let mut defaults = Vec::new();
        for d in &self.defines {
            let Some((k, v)) = d.split_once('=') else {
                bail!("-D {d}: expected name=value");
            };
            anyhow::ensure!(!k.is_empty(), "-D {d}: the name is empty");
            defaults.push((k.to_string(), v.to_string()));
        }
        if let Some(s) = self.spp {
            anyhow::ensure!(
                s >= 2,
                "--spp {s}: at least 2 samples per pixel are needed to estimate a variance"
            );
        }
        if self.bins == Some(0) {
            bail!("--bins must be at least 1");
        }
        if let Some(h) = self.bin_width_opl {
            anyhow::ensure!(
                h > 0.0 && h.is_finite(),
                "--bin-width-opl must be positive, got {h}"
            );
        }
        if let Some(t0) = self.start_opl {
            anyhow::ensure!(t0.is_finite(), "--start-opl must be finite");
        }
        anyhow::ensure!(
            self.width != Some(0) && self.height != Some(0),
            "--width and --height must be positive"
        );
        Ok(Overrides {
            defaults,
            spp: self.spp,
            width: self.width,
            height: self.height,
            bins: self.bins,
            start_opl: self.start_opl,
            bin_width_opl: self.bin_width_opl,
            max_depth: self.max_depth,
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
    #[command(flatten)]
    pub scene_args: SceneArgs,
    /// Random seed (default: the sampler's seed parameter, else 0).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Worker threads (default: all cores). The bundle does not depend on it.
    #[arg(long)]
    pub threads: Option<usize>,
    /// Sample transform: identity, box-cox:LAMBDA or yeo-johnson:LAMBDA.
    #[arg(long, default_value = "identity")]
    pub transform: String,
    /// Metres per scene unit (for the seconds in the manifest).
    #[arg(long, default_value_t = 1.0)]
    pub unit_m: f64,
    /// Refuse to render when the accumulators need more than this (e.g. 8G; default 75% of RAM).
    #[arg(long)]
    pub max_memory: Option<String>,
    /// Replace an existing output.
    #[arg(long)]
    pub force: bool,
}

pub fn run(a: RenderArgs) -> anyhow::Result<()> {
    let transform: Transform = a
        .transform
        .parse()
        .map_err(|e: String| anyhow::anyhow!("--transform: {e}"))?;
    anyhow::ensure!(
        a.unit_m > 0.0 && a.unit_m.is_finite(),
        "--unit-m must be positive"
    );
    let overrides = a.scene_args.overrides()?;
    check_outputs(
        &[arg("scene", &a.scene)],
        &[(arg("--out", &a.out), Kind::Dir)],
        a.force,
    )?;
    let scene = Scene::load(&a.scene, &overrides)?;
    let film = &scene.film;

    let need = Accumulators::bytes(film.height, film.width, film.bins, &transform);
    let limit = match &a.max_memory {
        Some(s) => Some(parse_bytes(s).map_err(|e| anyhow::anyhow!("--max-memory: {e}"))?),
        None => None,
    };
    eprintln!(
        "{}: {}x{} px, {} bins, {} spp ({}), {} primitives; accumulators need {}",
        a.scene.display(),
        film.width,
        film.height,
        film.bins,
        scene.spp,
        a.scene_args.pixel_sampling,
        scene.accel.primitive_count(),
        human_bytes(need)
    );
    check_memory(need, limit)?;

    let settings = RenderSettings {
        spp: scene.spp,
        seed: a.seed.unwrap_or(scene.seed),
        transform,
        pixel_sampling: a.scene_args.pixel_sampling,
    };
    let total = film.pixels() as u64 * scene.spp as u64;
    let bar = ProgressBar::new(total).with_style(
        ProgressStyle::with_template(
            "{bar:40} {percent:>3}% {human_pos}/{human_len} paths, {per_sec}, ETA {eta}",
        )
        .expect("valid template"),
    );
    let output = with_threads(a.threads, || render(&scene, &settings, &|n| bar.inc(n)))?;
    bar.finish_and_clear();
    let (seconds, paths, rays, dropped) = (
        output.seconds,
        output.paths,
        output.rays,
        output.dropped_nonfinite,
    );
    let meta = BundleMeta {
        seed: settings.seed,
        transform,
        unit_m: a.unit_m,
        pixel_sampling: settings.pixel_sampling,
    };
    write_bundle(&a.out, a.force, &scene, &meta, output).context("writing the bundle")?;
    println!(
        "rendered {} in {:.2} s: {:.2} M paths/s, {:.2} M rays/s; bundle {} ({}){}",
        a.out.display(),
        seconds,
        paths as f64 / seconds / 1e6,
        rays as f64 / seconds / 1e6,
        human_bytes(disk_size(&a.out)),
        transform,
        if dropped > 0 {
            format!("; {dropped} non-finite contributions dropped")
        } else {
            String::new()
        }
    );
    Ok(())
}
