//! The render job, one function for `tstat render`, `tstat run`, the Python package and
//! the cluster recipes (which run `tstat render --shard`): a loaded scene and the
//! settings asked -> the shard's share, the checks (replicates, memory, disk, the
//! manifest that will be written), the adaptive plan, the render streamed into a
//! bundle written under a temporary name, and the bundle's manifest.
//!
//! Seeds (SPEC 9): `RenderJob::seed` (else the scene's sampler seed, else 0) is the
//! job's seed. An unsharded render draws its paths from it; shard I of N draws from
//! `shard_seed(job seed, I)` and records the job's seed beside it; the adaptive pilot
//! draws from `AdaptiveOptions::pilot_seed(job seed)`, alike for every shard. The
//! manifest's `seed` is the seed the bundle's paths were drawn from.

use super::adaptive::{self, AdaptiveRequest, PlanInputs, Rendered, Stopped};
use super::progress::{Cancelled, Progress};
use super::system::{check_disk, check_memory, describe_memory, human_bytes, pool_size};
use crate::bundle::shard::{shard_seed, Shard};
use crate::bundle::write::{bundle_bytes_with, check_render, BundleMeta, BundleWriter, JobShard};
use crate::render::{PixelSampling, RenderSettings, StreamingMemory};
use crate::scene::Scene;
use crate::stats::Transform;
use anyhow::Context;
use std::path::PathBuf;

/// A render job: everything but the scene.
#[derive(Clone, Debug)]
pub struct RenderJob {
    /// The bundle directory to write (refused if it exists, unless `force`).
    pub out: PathBuf,
    pub force: bool,
    /// The scene file the manifest records (default: the loaded scene's file). `tstat
    /// run` writes the bundled scene into a temporary folder first.
    pub scene_record: Option<PathBuf>,
    /// The job's seed (default: the scene's sampler seed).
    pub seed: Option<u64>,
    pub transform: Transform,
    /// Metres per scene unit (for the seconds in the manifest).
    pub unit_m: f64,
    pub pixel_sampling: PixelSampling,
    /// Replicates per pixel (SPEC 4-5; 0: none), of the whole job.
    pub replicates: u32,
    /// Worker threads (default: all cores). The bundle does not depend on it.
    pub threads: Option<usize>,
    /// The most memory the render may take (default 75% of RAM).
    pub max_memory: Option<u64>,
    /// Render this shard of the job: `scene.spp` is the job's, the shard renders its share.
    pub shard: Option<Shard>,
    /// Adaptive sampling (`scene.spp` is then the mean per pixel).
    pub adaptive: Option<AdaptiveRequest>,
    /// Whether the scene's spp was given by the caller: a goal may then choose at most
    /// that (else up to 2^16).
    pub spp_given: bool,
    /// Bytes the caller will write beside the bundle (checked with it against free disk).
    pub extra_disk: u64,
    /// When the job started (a time budget counts from there).
    pub started: std::time::Instant,
}

impl RenderJob {
    /// A job with the defaults of `tstat render`: identity transform, Sobol' sampling,
    /// no replicates, all cores, unsharded, uniform sampling.
    pub fn new(out: impl Into<PathBuf>) -> Self {
        RenderJob {
            out: out.into(),
            force: false,
            scene_record: None,
            seed: None,
            transform: Transform::Identity,
            unit_m: 1.0,
            pixel_sampling: PixelSampling::Sobol,
            replicates: 0,
            threads: None,
            max_memory: None,
            shard: None,
            adaptive: None,
            spp_given: false,
            extra_disk: 0,
            started: std::time::Instant::now(),
        }
    }
}

/// What a finished job did.
#[derive(Clone, Debug)]
pub struct RenderReport {
    pub summary: crate::render::RenderSummary,
    /// The error an adaptive render of radiance sums estimates it reached.
    pub estimated_error: Option<f64>,
    /// The bundle's size on disk as estimated before rendering.
    pub disk: u64,
}

/// A shard's share of the job's spp and replicates, checked.
pub fn shard_share(shard: &Shard, spp: u32, replicates: u32) -> anyhow::Result<(u32, u32)> {
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

/// Renders `scene` into the bundle `job.out`, reporting to `progress`. Everything is
/// checked before any rendering work; the bundle appears complete or not at all.
pub fn render(
    mut scene: Scene,
    job: &RenderJob,
    progress: &dyn Progress,
) -> anyhow::Result<RenderReport> {
    let out = &job.out;
    let job_seed = job.seed.unwrap_or(scene.seed);
    let (shard_job, replicate_count) = match &job.shard {
        None => (None, job.replicates),
        Some(s) => {
            let (spp, reps) = shard_share(s, scene.spp, job.replicates)?;
            let shard_job = JobShard {
                shard: *s,
                seed: job_seed,
                spp: u64::from(scene.spp),
                replicates: job.replicates,
            };
            scene.spp = spp;
            (Some(shard_job), reps)
        }
    };
    let film = &scene.film;
    let transform = job.transform;
    RenderSettings::check_replicates(scene.spp, replicate_count)?;
    let shards = job.shard.map_or(1, |s| s.count as u32);
    let job_spp = shard_job.map_or(scene.spp, |j| j.spp as u32);
    let adaptive = job
        .adaptive
        .map(|a| a.options(job_spp, job.replicates, shards))
        .transpose()?;
    let replicates = replicate_count >= 2;
    // The memory of a render whose pixels take up to `cap` samples each.
    let memory_for = |cap: u32| {
        StreamingMemory::new(film, &transform, pool_size(job.threads))
            .with_replicates(replicates, film)
            .with_sampler(
                job.pixel_sampling,
                cap,
                replicate_count,
                scene.integrator.volumetric,
            )
            .with_adaptive(adaptive.is_some(), film)
    };
    let memory = memory_for(adaptive.map_or(scene.spp, |o| o.cap / shards));
    check_memory(&memory, job.max_memory)?;
    let bundle_disk = bundle_bytes_with(film, &transform, !scene.media.is_empty(), replicates);
    let what = if job.extra_disk > 0 {
        "the run's output"
    } else {
        "the bundle"
    };
    check_disk(out, bundle_disk.saturating_add(job.extra_disk), what)?;
    let render_seed = match &shard_job {
        Some(j) => shard_seed(job_seed, j.shard.index),
        None => job_seed,
    };
    let meta = BundleMeta {
        seed: render_seed,
        transform,
        unit_m: job.unit_m,
        pixel_sampling: job.pixel_sampling,
        replicates: replicate_count,
        job: shard_job,
        // Checked before rendering with the counts' place-holder (the mean); the pilot
        // fills them in.
        adaptive: adaptive.map(|o| adaptive::placeholder(&o, scene.spp, film.pixels())),
    };
    let record = job
        .scene_record
        .clone()
        .unwrap_or_else(|| scene.file.clone());
    // Before any rendering work: the manifest this render will write must read back
    // (the same check as reading it).
    check_render(out, &scene, &record, &meta)?;
    if let Some(j) = &meta.job {
        progress.note(&format!(
            "shard {} of {} (indices 0-{}): {} of the job's {} spp, seed {}",
            j.shard.index,
            j.shard.count,
            j.shard.count - 1,
            scene.spp,
            j.spp,
            render_seed
        ));
    }
    progress.note(&format!(
        "{}: {}x{} px, {} bins, {} spp ({}), {} primitives; memory {}, {} {} on disk",
        record.display(),
        film.width,
        film.height,
        film.time.bins,
        scene.spp,
        job.pixel_sampling,
        scene.accel.primitive_count(),
        describe_memory(&memory),
        if job.extra_disk > 0 {
            "output"
        } else {
            "bundle"
        },
        human_bytes(bundle_disk.saturating_add(job.extra_disk))
    ));

    let mut settings = RenderSettings {
        spp: scene.spp,
        seed: render_seed,
        transform,
        pixel_sampling: job.pixel_sampling,
        replicates: replicate_count,
        pixel_spp: None,
    };
    let mut meta = meta;
    let mut adaptive = adaptive;
    if let Some(o) = adaptive.as_mut() {
        let check_cap = |cap: u32| check_memory(&memory_for(cap), job.max_memory);
        let inputs = PlanInputs {
            goal: job.adaptive.and_then(|a| a.goal),
            most: if job.spp_given { scene.spp } else { 1 << 16 },
            job_seed,
            shards,
            threads: job.threads,
            started: job.started,
            check_cap: &check_cap,
        };
        adaptive::plan(&scene, &mut settings, &mut meta, o, &inputs, progress)?;
        scene.spp = settings.spp;
    }
    // Rows go straight into the bundle's files in a temporary directory; an error (or
    // an interrupted render) leaves nothing that looks like a bundle.
    let writer = BundleWriter::create_with(out, job.force, film, &transform, replicates)
        .context("writing the bundle")?;
    // Adaptive renders of radiance sums also estimate the error they reached.
    let tally = adaptive
        .filter(|_| transform.is_identity())
        .map(|o| o.measure);
    let rendered: Rendered =
        match adaptive::render_rows(&scene, &settings, &writer, tally, job.threads, progress)? {
            Ok(r) => r,
            Err(Stopped::Cancelled) => return Err(Cancelled.into()),
            Err(Stopped::Sink(e)) => {
                return Err(anyhow::Error::new(e).context("writing the bundle"))
            }
        };
    let (summary, estimated) = rendered;
    if summary.voxel_samples == 0 {
        progress.note(&empty_window_warning(film));
    }
    adaptive::record_estimate(&mut meta, estimated, progress);
    let scene = Scene {
        file: record,
        ..scene
    };
    writer
        .finish(&scene, &meta, &summary)
        .context("writing the bundle")?;
    Ok(RenderReport {
        summary,
        estimated_error: estimated,
        disk: bundle_disk,
    })
}

/// The warning for a render where no path deposited anything in the time window: legal
/// (e.g. max_depth 0, or a window placed before or after the light arrives) but an
/// all-zero bundle.
pub fn empty_window_warning(film: &crate::sensors::film::Film) -> String {
    format!(
        "warning: nothing landed in the time window (OPL {} to {}, {} bins): the transient volume is all zero; check --start-opl, --bin-width-opl, --bins and max_depth",
        film.time.start_opl,
        film.time.start_opl + film.time.bins as f64 * film.time.bin_width_opl,
        film.time.bins
    )
}
