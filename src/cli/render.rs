//! `tstat render SCENE.xml --out NAME.tstats`: render and write a statistics bundle.

use super::adaptive::{self, AdaptiveArgs};
use super::util::{
    arg, check_outputs, disk_size, finite, human_bytes, opt_int, physical_memory, positive, seed,
    size_flag, threads, Kind, MAX_FILM_SIDE,
};
use crate::bundle::shard::{shard_seed, Shard, PLACEHOLDER};
use crate::bundle::write::{bundle_bytes_with, check_render, BundleMeta, BundleWriter, JobShard};
use crate::render::{PixelSampling, RenderSettings, StreamingMemory};
use crate::scene::{Overrides, Scene};
use crate::sensors::time_origin::TimeOrigin;
use crate::stats::Transform;
use anyhow::{anyhow, bail, Context};
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
}

impl SceneArgs {
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
            anyhow::ensure!(
                h > 0.0 && h.is_finite(),
                "--bin-width-opl must be positive, got {h}"
            );
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

/// A shard's share of the job's spp and replicates, checked.
pub(super) fn shard_share(shard: &Shard, spp: u32, replicates: u32) -> anyhow::Result<(u32, u32)> {
    let spp_share = shard.share(u64::from(spp), "the job's spp")?;
    anyhow::ensure!(
        spp_share >= 2,
        "the job's spp {spp} over {} shards leaves {spp_share} per shard; each needs at least 2",
        shard.count
    );
    let reps = if replicates >= 2 {
        let r = shard.share(u64::from(replicates), "--replicates")?;
        anyhow::ensure!(
            r >= 2,
            "--replicates {replicates} over {} shards leaves {r} per shard; each needs at least 2",
            shard.count
        );
        r as u32
    } else {
        replicates
    };
    Ok((spp_share as u32, reps))
}

pub fn run(a: RenderArgs) -> anyhow::Result<()> {
    let transform: Transform = a
        .transform
        .parse()
        .map_err(|e| anyhow::anyhow!("--transform: {e}"))?;
    positive("--unit-m", a.unit_m)?;
    let overrides = a.scene_args.overrides(a.spp)?;
    let threads = threads(a.threads)?;
    let seed = seed(a.seed)?;
    let limit = match &a.max_memory {
        Some(s) => Some(size_flag("--max-memory", s)?),
        None => None,
    };
    let started = std::time::Instant::now();
    if !a.adaptive {
        a.adaptive_args.refuse_when_off("without --adaptive")?;
    }
    let goal = a.adaptive_args.goal(a.shard.is_some())?;
    let (shard, out) = shard_and_out(a.shard.as_deref(), &a.out)?;
    check_outputs(
        &[arg("scene", &a.scene)],
        &[(arg("--out", &out), Kind::Dir)],
        a.force,
    )?;
    let mut scene = Scene::load(&a.scene, &overrides)?;
    super::util::check_mesh_inputs(&scene, &[arg("--out", &out)])?;
    super::util::print_scene_warnings(&scene);
    let job_seed = seed.unwrap_or(scene.seed);
    let (job, replicate_count) = match &shard {
        None => (None, a.scene_args.replicates),
        Some(s) => {
            let (spp, reps) = shard_share(s, scene.spp, a.scene_args.replicates)?;
            let job = JobShard {
                shard: *s,
                seed: job_seed,
                spp: u64::from(scene.spp),
                replicates: a.scene_args.replicates,
            };
            scene.spp = spp;
            (Some(job), reps)
        }
    };
    let film = &scene.film;

    RenderSettings::check_replicates(scene.spp, replicate_count)?;
    let shards = shard.map_or(1, |s| s.count as u32);
    let job_spp = job.map_or(scene.spp, |j| j.spp as u32);
    let adaptive = a
        .adaptive
        .then(|| {
            a.adaptive_args
                .options(job_spp, a.scene_args.replicates, shards)
        })
        .transpose()?;
    let replicates = replicate_count >= 2;
    // The memory of a render whose pixels take up to `cap` samples each.
    let adaptive_on = adaptive.is_some();
    let memory_for = |cap: u32| {
        StreamingMemory::new(film, &transform, pool_size(threads))
            .with_replicates(replicates, film)
            .with_sampler(
                a.scene_args.pixel_sampling,
                cap,
                replicate_count,
                scene.integrator.volumetric,
            )
            .with_adaptive(adaptive_on, film)
    };
    let memory = memory_for(adaptive.map_or(scene.spp, |o| o.cap / shards));
    check_memory(&memory, limit)?;
    let disk = bundle_bytes_with(film, &transform, !scene.media.is_empty(), replicates);
    check_disk(&out, disk, "the bundle")?;
    let render_seed = match &job {
        Some(j) => shard_seed(job_seed, j.shard.index),
        None => job_seed,
    };
    let meta = BundleMeta {
        seed: render_seed,
        transform,
        unit_m: a.unit_m,
        pixel_sampling: a.scene_args.pixel_sampling,
        replicates: replicate_count,
        job,
        // Checked before rendering with the counts' place-holder (the mean); the pilot
        // fills them in.
        adaptive: adaptive.map(|o| adaptive::placeholder(&o, scene.spp, film.pixels())),
    };
    // Before any rendering work: the manifest this render will write must read back
    // (the same check as reading it).
    check_render(&out, &scene, &scene.file, &meta)?;
    if let Some(j) = &meta.job {
        eprintln!(
            "shard {} of {} (indices 0-{}): {} of the job's {} spp, seed {}",
            j.shard.index,
            j.shard.count,
            j.shard.count - 1,
            scene.spp,
            j.spp,
            shard_seed(j.seed, j.shard.index)
        );
    }
    eprintln!(
        "{}: {}x{} px, {} bins, {} spp ({}), {} primitives; memory {}, bundle {} on disk",
        a.scene.display(),
        film.width,
        film.height,
        film.bins,
        scene.spp,
        a.scene_args.pixel_sampling,
        scene.accel.primitive_count(),
        describe_memory(&memory),
        human_bytes(disk)
    );

    let mut settings = RenderSettings {
        spp: scene.spp,
        seed: render_seed,
        transform,
        pixel_sampling: a.scene_args.pixel_sampling,
        replicates: replicate_count,
        pixel_spp: None,
    };
    let mut meta = meta;
    let mut adaptive = adaptive;
    if let Some(o) = adaptive.as_mut() {
        let check_cap = |cap: u32| check_memory(&memory_for(cap), limit);
        let inputs = adaptive::PlanInputs {
            goal,
            most: if a.spp.is_some() { scene.spp } else { 1 << 16 },
            job_seed,
            shards,
            threads,
            started,
            check_cap: &check_cap,
        };
        adaptive::plan(&scene, &mut settings, &mut meta, o, &inputs)?;
        scene.spp = settings.spp;
    }
    // Rows go straight into the bundle's files in a temporary directory; an error (or
    // an interrupted render) leaves nothing that looks like a bundle.
    let writer = BundleWriter::create_with(&out, a.force, film, &transform, replicates)
        .context("writing the bundle")?;
    // Adaptive renders of radiance sums also estimate the error they reached.
    let tally = adaptive
        .filter(|_| transform.is_identity())
        .map(|o| o.measure);
    let (summary, estimated) =
        adaptive::render_rows(&scene, &settings, &writer, tally, threads, false)?
            .context("writing the bundle")?;
    warn_if_empty(summary.voxel_samples, film);
    adaptive::record_estimate(&mut meta, estimated);
    writer
        .finish(&scene, &meta, &summary)
        .context("writing the bundle")?;
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

/// The number of worker threads [`with_threads`] will start for `threads`: rayon's
/// default (`RAYON_NUM_THREADS`, else the available cores) when `None`. Asking rayon
/// itself would start its global pool just to count it.
pub fn pool_size(threads: Option<usize>) -> usize {
    threads.unwrap_or_else(|| {
        std::env::var("RAYON_NUM_THREADS")
            .ok()
            .and_then(|v| v.parse::<usize>().ok())
            .filter(|&n| n > 0)
            .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
    })
}

/// "1.2 GB (2 threads x 600 MB per row + 5 MB of per-pixel images)".
pub fn describe_memory(m: &StreamingMemory) -> String {
    format!(
        "{} ({} thread{} x {} per row + {} of per-pixel images)",
        human_bytes(m.bytes()),
        m.threads,
        if m.threads == 1 { "" } else { "s" },
        human_bytes(m.per_row),
        human_bytes(m.images)
    )
}

/// Refuses a render that needs more than `limit` bytes of memory (default: 75% of
/// physical RAM; a saturated need is always refused). Checked before any allocation.
pub fn check_memory(m: &StreamingMemory, limit: Option<u64>) -> anyhow::Result<()> {
    let limit = limit.unwrap_or_else(|| physical_memory().map_or(u64::MAX, |m| m / 4 * 3));
    let need = m.bytes();
    anyhow::ensure!(
        need <= limit && need != u64::MAX,
        "the render needs {} of memory but the limit is {} (--max-memory, default 75% of RAM); lower --width, --bins or --threads",
        describe_memory(m),
        human_bytes(limit)
    );
    Ok(())
}

/// Refuses an output `out` when `what` (`need` bytes) would not fit in the free space of
/// its filesystem (as an unprivileged user sees it). Where the free space cannot be
/// known (`statvfs` fails), it is not checked.
pub fn check_disk(out: &Path, need: u64, what: &str) -> anyhow::Result<()> {
    let parent = out
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    if let Ok(fs) = rustix::fs::statvfs(parent) {
        let free = fs.f_bavail.saturating_mul(fs.f_frsize);
        anyhow::ensure!(
            need <= free && need != u64::MAX,
            "--out {}: {what} needs {} on disk but only {} are free there; lower --width, --height or --bins, or write elsewhere",
            out.display(),
            human_bytes(need),
            human_bytes(free)
        );
    }
    Ok(())
}

/// Warns when no path deposited anything in the time window: legal (e.g. --max-depth 0,
/// or a window placed before or after the light arrives) but an all-zero bundle.
pub fn warn_if_empty(voxel_samples: u64, film: &crate::sensors::film::Film) {
    if voxel_samples == 0 {
        eprintln!(
            "warning: nothing landed in the time window (OPL {} to {}, {} bins): the transient volume is all zero; check --start-opl, --bin-width-opl, --bins and max_depth",
            film.start_opl,
            film.start_opl + film.bins as f64 * film.bin_width_opl,
            film.bins
        );
    }
}
