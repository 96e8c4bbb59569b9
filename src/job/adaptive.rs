//! Adaptive sampling as a render job does it: the request, the pilot and the allocation
//! it gives (a goal turned into the mean spp), and the main pass with the error it
//! estimates as it goes. The method itself is `render::adaptive`.

use super::progress::{Cancelled, Progress, Stage};
use super::system::with_threads;
use crate::bundle::manifest::{AdaptiveRecord, GoalRecord};
use crate::bundle::write::BundleMeta;
use crate::render::adaptive::{self, AdaptiveOptions, ErrorMeasure, ErrorTally};
use crate::render::sink::{Row, RowSink};
use crate::render::{render_into, RenderSettings, RenderSummary};
use crate::scene::Scene;
use anyhow::anyhow;
use std::sync::Arc;

/// What a goal asks: the measure's error, or a time in seconds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Goal {
    Error(f64),
    Seconds(f64),
}

impl Goal {
    /// The manifest's name of the goal.
    pub fn kind(self) -> &'static str {
        match self {
            Goal::Error(_) => "target_error",
            Goal::Seconds(_) => "time_budget_seconds",
        }
    }

    pub fn value(self) -> f64 {
        match self {
            Goal::Error(v) | Goal::Seconds(v) => v,
        }
    }
}

/// Adaptive sampling as asked: `--adaptive-measure`, `--pilot-spp`, and a goal
/// (`--target-error` or `--time-budget`) or none (the spp given is the mean).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AdaptiveRequest {
    pub measure: ErrorMeasure,
    /// Samples per pixel of the pilot (default max(4, spp / 16)).
    pub pilot_spp: Option<u32>,
    pub goal: Option<Goal>,
}

impl AdaptiveRequest {
    /// The options for a job of `spp` (the whole job's, sharded or not).
    pub fn options(
        &self,
        spp: u32,
        replicates: u32,
        shards: u32,
    ) -> anyhow::Result<AdaptiveOptions> {
        let granule = replicates.max(1).saturating_mul(shards.max(1));
        // Every shard needs at least 2 samples of each pixel.
        let mut o = AdaptiveOptions::new(spp, self.measure, granule, 2 * shards.max(1));
        if let Some(p) = self.pilot_spp {
            o.pilot_spp = p;
        }
        o.validate().map_err(|e| {
            anyhow!(
                "--adaptive with --spp {spp}{}: {e} (floor {}, cap {}, multiples of {granule})",
                if granule > 1 {
                    format!(", {replicates} replicates, {shards} shards")
                } else {
                    String::new()
                },
                o.floor,
                o.cap
            )
        })?;
        Ok(o)
    }
}

/// The manifest's adaptive part before the pilot: every pixel at the mean `spp` (the
/// place-holder the manifest check before rendering sees; [`plan`] fills it in).
pub fn placeholder(o: &AdaptiveOptions, spp: u32, pixels: usize) -> (Arc<[u32]>, AdaptiveRecord) {
    let record = AdaptiveRecord {
        measure: o.measure,
        pilot_spp: u64::from(o.pilot_spp),
        pilot_seconds: 0.0,
        min_spp: u64::from(spp),
        max_spp: u64::from(spp),
        goal: None,
        estimated_error: None,
    };
    (Arc::from(vec![spp; pixels]), record)
}

/// "RMSE" or "relMSE": what the estimates of `measure` are.
pub fn error_name(measure: ErrorMeasure) -> &'static str {
    match measure {
        ErrorMeasure::Mse => "RMSE",
        ErrorMeasure::RelMse => "relMSE",
    }
}

/// What [`plan`] needs besides the render's own state.
pub struct PlanInputs<'a> {
    pub goal: Option<Goal>,
    /// The most a goal may choose (the spp given, else 2^16).
    pub most: u32,
    /// The job's seed (the pilot's comes from it, alike for every shard).
    pub job_seed: u64,
    pub shards: u32,
    pub threads: Option<usize>,
    /// When the job started (a time budget counts from there).
    pub started: std::time::Instant,
    /// Checks the memory of a render whose pixels take up to `cap` samples.
    pub check_cap: &'a dyn Fn(u32) -> anyhow::Result<()>,
}

/// Runs the pilot, turns a goal into the mean spp, allocates each pixel's samples
/// (its shard's share), and records all of it in `settings` (the mean spp a goal
/// chose included: the caller's scene takes it too) and `meta`. Returns the error the
/// pilot predicts (of the measure, for independent samples).
pub fn plan(
    scene: &Scene,
    settings: &mut RenderSettings,
    meta: &mut BundleMeta,
    o: &mut AdaptiveOptions,
    p: &PlanInputs,
    progress: &dyn Progress,
) -> anyhow::Result<f64> {
    let film = &scene.film;
    let job_settings = RenderSettings {
        seed: AdaptiveOptions::pilot_seed(p.job_seed),
        ..settings.clone()
    };
    progress.start(Stage::Pilot, film.pixels() as u64 * u64::from(o.pilot_spp));
    let (measure, pilot) = with_threads(p.threads, || {
        adaptive::pilot(scene, &job_settings, o, &|n| progress.advance(n))
    })?;
    progress.finish();
    if progress.cancelled() {
        return Err(Cancelled.into());
    }
    let weights = adaptive::weights(&measure, film.width);
    let voxels = (film.pixels() * film.time.bins * film.channels) as f64;
    if let Some(goal) = p.goal {
        let target = match goal {
            Goal::Error(e) => adaptive::Goal::Error(e),
            Goal::Seconds(s) => {
                let rays_per_second = pilot.rays as f64 / pilot.seconds.max(1e-9);
                let left = (s - p.started.elapsed().as_secs_f64()).max(0.0);
                adaptive::Goal::Rays(left * rays_per_second)
            }
        };
        let spp = adaptive::choose_spp(&measure, &weights, o, voxels, target, p.most, 2);
        *o = AdaptiveOptions {
            pilot_spp: o.pilot_spp,
            ..AdaptiveOptions::new(spp, o.measure, o.granule, 2)
        };
        settings.spp = spp;
        (p.check_cap)(o.cap)?;
    }
    let (predicted, _) = adaptive::predict(&measure, &weights, o, voxels);
    if let Some(goal) = p.goal {
        progress.note(&format!(
            "adaptive: {} {} -> {} spp on average (predicted {} {predicted:.4e})",
            goal.kind().replace('_', " "),
            goal.value(),
            settings.spp,
            error_name(o.measure)
        ));
    }
    let counts: Vec<u32> = adaptive::allocate(&weights, o)
        .into_iter()
        .map(|n| n / p.shards)
        .collect();
    let (lo, hi) = counts
        .iter()
        .fold((u32::MAX, 0), |(lo, hi), &n| (lo.min(n), hi.max(n)));
    progress.note(&format!(
        "adaptive: {}-spp pilot in {:.2} s; {} to {} samples a pixel (mean {}), minimising {}",
        o.pilot_spp,
        pilot.seconds,
        lo,
        hi,
        settings.spp,
        o.measure.name()
    ));
    let counts: Arc<[u32]> = counts.into();
    settings.pixel_spp = Some(counts.clone());
    if let Some((n, r)) = meta.adaptive.as_mut() {
        *n = counts;
        r.pilot_seconds = pilot.seconds;
        (r.min_spp, r.max_spp) = (u64::from(lo), u64::from(hi));
        r.goal = p.goal.map(|g| GoalRecord {
            kind: g.kind().into(),
            value: g.value(),
            predicted_error: predicted,
        });
    }
    Ok(predicted)
}

/// Says and records in the manifest the error an adaptive render estimates it reached.
pub fn record_estimate(meta: &mut BundleMeta, estimated: Option<f64>, progress: &dyn Progress) {
    if let (Some(e), Some((_, r))) = (estimated, meta.adaptive.as_mut()) {
        progress.note(&format!(
            "adaptive: estimated {} of the noisy volume {e:.4e}",
            error_name(r.measure)
        ));
        r.estimated_error = Some(e);
    }
}

/// A render's summary and, for an adaptive render of radiance sums, the error it
/// estimates it reached.
pub type Rendered = (RenderSummary, Option<f64>);

/// Why rows stopped going into a sink: its own error, or the job was cancelled.
pub enum Stopped<E> {
    Sink(E),
    Cancelled,
}

/// A sink that refuses further rows once `progress` asks the job to stop.
struct Stoppable<'a, S> {
    sink: &'a S,
    progress: &'a dyn Progress,
}

impl<S: RowSink> RowSink for Stoppable<'_, S> {
    type Error = Stopped<S::Error>;
    fn put_row(&self, row: &Row<'_>) -> Result<(), Self::Error> {
        if self.progress.cancelled() {
            return Err(Stopped::Cancelled);
        }
        self.sink.put_row(row).map_err(Stopped::Sink)
    }
}

/// Renders every row into `sink`, reporting to `progress`. With `tally` (adaptive
/// renders of radiance sums) the progress shows the error estimated from the rows done
/// so far, and the estimate of the whole volume is returned. Stops after the rows under
/// way when `progress` asks.
pub fn render_rows<S: RowSink>(
    scene: &Scene,
    settings: &RenderSettings,
    sink: &S,
    tally: Option<ErrorMeasure>,
    threads: Option<usize>,
    progress: &dyn Progress,
) -> anyhow::Result<Result<Rendered, Stopped<S::Error>>> {
    let film = &scene.film;
    let total = (0..film.height)
        .map(|y| settings.row_paths(y, film.width))
        .sum::<u64>();
    progress.start(Stage::Render, total);
    let sink = Stoppable { sink, progress };
    let voxels_per_row = (film.width * film.time.bins * film.channels) as f64;
    let result = match tally {
        Some(measure) => {
            let t = ErrorTally::new(&sink, settings, measure, film.height, film.width);
            let advance = |n| {
                progress.advance(n);
                if let Some(e) = t.so_far(voxels_per_row) {
                    progress.status(&format!("{} so far {e:.3e}", error_name(measure)));
                }
            };
            with_threads(threads, || render_into(scene, settings, &t, &advance))?.map(|summary| {
                let e = t.error(voxels_per_row * film.height as f64);
                (summary, e.is_finite().then_some(e))
            })
        }
        None => with_threads(threads, || {
            render_into(scene, settings, &sink, &|n| progress.advance(n))
        })?
        .map(|summary| (summary, None)),
    };
    progress.finish();
    Ok(result)
}
