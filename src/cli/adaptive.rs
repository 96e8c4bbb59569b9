//! The flags of adaptive sampling, for `render --adaptive` and `run` (adaptive unless
//! `--no-adaptive`). The job is `job::adaptive`, the method `render::adaptive`.

use super::util::{opt_int, positive};
use crate::job::adaptive::{AdaptiveRequest, Goal};
use crate::render::adaptive::ErrorMeasure;
use anyhow::anyhow;
use clap::Args;

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

    /// The request these flags make (`sharded`: the render is a shard of a job).
    pub fn request(&self, sharded: bool) -> anyhow::Result<AdaptiveRequest> {
        Ok(AdaptiveRequest {
            measure: self.measure(),
            pilot_spp: opt_int("--pilot-spp", self.pilot_spp, 2, i64::from(u32::MAX))?,
            goal: self.goal(sharded)?,
        })
    }
}
