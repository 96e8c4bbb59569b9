//! Adaptive sampling as `render --adaptive` and `run` (adaptive unless `--no-adaptive`)
//! do it: the flags, the pilot and the allocation it gives, and the main pass with a
//! progress bar showing the error estimated so far. The method is `render::adaptive`.

use super::util::{opt_int, positive, with_threads};
use crate::bundle::manifest::{AdaptiveRecord, GoalRecord};
use crate::bundle::write::BundleMeta;
use crate::render::adaptive::{self, AdaptiveOptions, ErrorMeasure, ErrorTally};
use crate::render::sink::RowSink;
use crate::render::{render_into, RenderSettings, RenderSummary};
use crate::scene::Scene;
use crate::stats::accumulators::CHANNELS;
use anyhow::anyhow;
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use std::sync::Arc;

/// How adaptive sampling runs (on with `render --adaptive`; on by default in `run`).
#[derive(Args, Debug, Clone, Default)]
pub struct AdaptiveArgs {
    /// Adaptive sampling minimises mse (all-voxel squared error, RMSE; the default) or
    /// relmse ((x - ref)^2 / (ref^2 + 0.01), which weights dark voxels up).
    #[arg(long, value_parser = ["mse", "relmse"])]
    pub adaptive_measure: Option<String>,
    /// Samples per pixel of the adaptive pilot (default max(4, spp / 16)).
    #[arg(long, allow_negative_numbers = true)]
    pub pilot_spp: Option<i64>,
    /// Adaptive sampling with a time instead of an spp: the mean spp is the most the
    /// pilot predicts to fit in this time, pilot included (90s, 5m, 1.5h; --spp, if
    /// given, is the most it may choose; not with --shard).
    #[arg(long, conflicts_with = "target_error", allow_hyphen_values = true)]
    pub time_budget: Option<String>,
    /// Adaptive sampling to an error: the mean spp is the least the pilot predicts to
    /// reach this RMSE (--adaptive-measure mse) or relMSE (relmse) of the noisy volume,
    /// for independent samples (Sobol' usually does better, the denoised volume
    /// better still); --spp, if given, is the most it may choose; not with --shard.
    #[arg(long, allow_negative_numbers = true)]
    pub target_error: Option<f64>,
}

/// What a goal asks: the measure's error, or a time in seconds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Goal {
    Error(f64),
    Seconds(f64),
}

impl Goal {
    /// The manifest's name of the goal.
    fn kind(self) -> &'static str {
        match self {
            Goal::Error(_) => "target_error",
            Goal::Seconds(_) => "time_budget_seconds",
        }
    }

    fn value(self) -> f64 {
        match self {
            Goal::Error(v) | Goal::Seconds(v) => v,
        }
    }
}

impl AdaptiveArgs {
    /// Refuses every adaptive flag given while adaptive sampling is off; `off` says
    /// why it is ("without --adaptive", "with --no-adaptive").
    pub fn refuse_when_off(&self, off: &str) -> anyhow::Result<()> {
        let given = [
            (self.adaptive_measure.is_some(), "--adaptive-measure"),
            (self.pilot_spp.is_some(), "--pilot-spp"),
            (self.time_budget.is_some(), "--time-budget"),
            (self.target_error.is_some(), "--target-error"),
        ];
        match given.iter().find(|(g, _)| *g) {
            Some((_, flag)) => Err(anyhow!("{flag} is an adaptive sampling option: not {off}")),
            None => Ok(()),
        }
    }

    pub fn measure(&self) -> ErrorMeasure {
        match self.adaptive_measure.as_deref() {
            Some("relmse") => ErrorMeasure::RelMse,
            _ => ErrorMeasure::Mse,
        }
    }

    /// The goal asked, checked (`sharded`: the render is a shard of a job).
    pub fn goal(&self, sharded: bool) -> anyhow::Result<Option<Goal>> {
        let goal = match (&self.time_budget, self.target_error) {
            (Some(t), _) => Some(Goal::Seconds(super::util::duration_flag(
                "--time-budget",
                t,
            )?)),
            (None, Some(e)) => {
                positive("--target-error", e)?;
                Some(Goal::Error(e))
            }
            (None, None) => None,
        };
        anyhow::ensure!(
            goal.is_none() || !sharded,
            "--time-budget and --target-error choose the spp from the pilot's time or samples: not with --shard (give the job an --spp)"
        );
        Ok(goal)
    }

    /// The options for a job of `spp` (the whole job's, sharded or not).
    pub fn options(
        &self,
        spp: u32,
        replicates: u32,
        shards: u32,
    ) -> anyhow::Result<AdaptiveOptions> {
        let granule = replicates.max(1).saturating_mul(shards.max(1));
        // Every shard needs at least 2 samples of each pixel.
        let mut o = AdaptiveOptions::new(spp, self.measure(), granule, 2 * shards.max(1));
        if let Some(p) = self.pilot_spp {
            o.pilot_spp =
                opt_int("--pilot-spp", Some(p), 2, i64::from(u32::MAX))?.unwrap_or(o.pilot_spp);
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
    /// The most a goal may choose (the --spp given, else 2^16).
    pub most: u32,
    /// The job's seed (the pilot's comes from it, alike for every shard).
    pub job_seed: u64,
    pub shards: u32,
    pub threads: Option<usize>,
    /// When the command started (a time budget counts from there).
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
) -> anyhow::Result<f64> {
    let film = &scene.film;
    let job_settings = RenderSettings {
        seed: AdaptiveOptions::pilot_seed(p.job_seed),
        ..settings.clone()
    };
    let pilot_paths = film.pixels() as u64 * u64::from(o.pilot_spp);
    let bar = ProgressBar::new(pilot_paths).with_style(
        ProgressStyle::with_template(
            "pilot {bar:34} {percent:>3}% {human_pos}/{human_len} paths, ETA {eta}",
        )
        .expect("valid template"),
    );
    let (measure, pilot) = with_threads(p.threads, || {
        adaptive::pilot(scene, &job_settings, o, &|n| bar.inc(n))
    })?;
    bar.finish_and_clear();
    let weights = adaptive::weights(&measure, film.width);
    let voxels = (film.pixels() * film.bins * CHANNELS) as f64;
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
        eprintln!(
            "adaptive: {} {} -> {} spp on average (predicted {} {predicted:.4e})",
            goal.kind().replace('_', " "),
            goal.value(),
            settings.spp,
            error_name(o.measure)
        );
    }
    let counts: Vec<u32> = adaptive::allocate(&weights, o)
        .into_iter()
        .map(|n| n / p.shards)
        .collect();
    let (lo, hi) = counts
        .iter()
        .fold((u32::MAX, 0), |(lo, hi), &n| (lo.min(n), hi.max(n)));
    eprintln!(
        "adaptive: {}-spp pilot in {:.2} s; {} to {} samples a pixel (mean {}), minimising {}",
        o.pilot_spp,
        pilot.seconds,
        lo,
        hi,
        settings.spp,
        o.measure.name()
    );
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
pub fn record_estimate(meta: &mut BundleMeta, estimated: Option<f64>) {
    if let (Some(e), Some((_, r))) = (estimated, meta.adaptive.as_mut()) {
        eprintln!(
            "adaptive: estimated {} of the noisy volume {e:.4e}",
            error_name(r.measure)
        );
        r.estimated_error = Some(e);
    }
}

/// A render's summary and, for an adaptive render of radiance sums, the error it
/// estimates it reached.
pub type Rendered = (RenderSummary, Option<f64>);

/// Renders every row into `sink` with a progress bar (none when `quiet`). With
/// `tally` (adaptive renders of radiance sums) the bar shows the error estimated from
/// the rows done so far, and the estimate of the whole volume is returned.
pub fn render_rows<S: RowSink>(
    scene: &Scene,
    settings: &RenderSettings,
    sink: &S,
    tally: Option<ErrorMeasure>,
    threads: Option<usize>,
    quiet: bool,
) -> anyhow::Result<Result<Rendered, S::Error>> {
    let film = &scene.film;
    let total = (0..film.height)
        .map(|y| settings.row_paths(y, film.width))
        .sum::<u64>();
    let bar = if quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(total)
    };
    let template = match tally {
        Some(_) => {
            "{bar:34} {percent:>3}% {human_pos}/{human_len} paths, {per_sec}, ETA {eta}, {msg}"
        }
        None => "{bar:40} {percent:>3}% {human_pos}/{human_len} paths, {per_sec}, ETA {eta}",
    };
    bar.set_style(ProgressStyle::with_template(template).expect("valid template"));
    let voxels_per_row = (film.width * film.bins * CHANNELS) as f64;
    let result = match tally {
        Some(measure) => {
            let t = ErrorTally::new(sink, settings, measure, film.height, film.width);
            let progress = |n| {
                bar.inc(n);
                if let Some(e) = t.so_far(voxels_per_row) {
                    bar.set_message(format!("{} so far {e:.3e}", error_name(measure)));
                }
            };
            with_threads(threads, || render_into(scene, settings, &t, &progress))?.map(|summary| {
                let e = t.error(voxels_per_row * film.height as f64);
                (summary, e.is_finite().then_some(e))
            })
        }
        None => with_threads(threads, || {
            render_into(scene, settings, sink, &|n| bar.inc(n))
        })?
        .map(|summary| (summary, None)),
    };
    bar.finish_and_clear();
    Ok(result)
}
