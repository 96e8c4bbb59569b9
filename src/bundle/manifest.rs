//! `manifest.json`: what a statistics bundle holds and how it was made (SPEC 9).

use crate::render::PixelSampling;
use crate::sensors::time_axis::TimeAxis;
pub use crate::sensors::time_origin::TimeOrigin;
use crate::stats::Transform;
use serde::{Deserialize, Serialize};

pub const FORMAT: &str = "tstats";
/// The newest format version: 2 for bundles of adaptive sampling (`pixel_spp.npy`), 1
/// for every other bundle (so that readers which do not know per-pixel counts refuse
/// only the bundles they would misread).
pub const VERSION: u32 = 2;
/// The version of bundles with the same samples in every pixel.
pub const VERSION_UNIFORM: u32 = 1;

/// Speed of light in vacuum, m/s (for the seconds in the metadata).
pub const C_M_PER_S: f64 = 299_792_458.0;

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct SceneRef {
    pub path: String,
    pub sha256: String,
    /// The files the scene read (by name, with their SHA-256) and the `-D` values;
    /// absent in bundles written before it was recorded.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub identity: Option<crate::scene::SceneIdentity>,
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct ArrayInfo {
    pub name: String,
    pub file: String,
    /// NumPy dtype string, e.g. "<f8".
    pub dtype: String,
    pub shape: Vec<usize>,
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Program {
    pub name: String,
    pub version: String,
}

/// How a bundle's sub-pixel positions were drawn (`pixel_sampling` in the manifest).
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum SamplingRecord {
    /// Each render's samples of a pixel form one stratified set. After `merge`, the
    /// merged bundle is a union of such sets, one per render (each unbiased; the
    /// union is not one stratified set of the total spp).
    Stratified,
    /// i.i.d. uniform positions: the statistics' assumption holds exactly.
    Independent,
    /// Every dimension of each render's paths from one scrambled Sobol' set per pixel
    /// (the samples are correlated, like `stratified`'s positions).
    Sobol,
    /// Merged from renders that used different modes.
    Mixed,
}

impl From<PixelSampling> for SamplingRecord {
    fn from(p: PixelSampling) -> Self {
        match p {
            PixelSampling::Stratified => SamplingRecord::Stratified,
            PixelSampling::Independent => SamplingRecord::Independent,
            PixelSampling::Sobol => SamplingRecord::Sobol,
        }
    }
}

impl SamplingRecord {
    /// Bundles written before the field existed were all rendered with i.i.d. positions.
    pub fn legacy() -> Self {
        SamplingRecord::Independent
    }

    /// The record of a merge of bundles recorded `self` and `other`.
    pub fn merged(self, other: SamplingRecord) -> Self {
        if self == other {
            self
        } else {
            SamplingRecord::Mixed
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            SamplingRecord::Stratified => "stratified",
            SamplingRecord::Independent => "independent",
            SamplingRecord::Sobol => "sobol",
            SamplingRecord::Mixed => "mixed",
        }
    }
}

impl std::fmt::Display for SamplingRecord {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Manifest {
    pub format: String,
    pub version: u32,
    pub width: usize,
    pub height: usize,
    pub bins: usize,
    pub channels: Vec<String>,
    /// What the paths carried (`scene::mode`): `rgb` or `spectral` (whose channels are
    /// the paths' linear sRGB). Absent in bundles written before the field: `rgb`.
    #[serde(default)]
    pub mode: crate::scene::mode::RenderMode,
    pub spp: u64,
    /// t0 and h in OPL (scene units).
    pub start_opl: f64,
    pub bin_width_opl: f64,
    /// Metres per scene unit.
    pub unit_m: f64,
    /// t0 and h in seconds: opl * unit_m / c.
    pub start_seconds: f64,
    pub bin_width_seconds: f64,
    pub transform: Transform,
    /// Where the OPL of camera paths starts (`sensors/time_origin.rs`): `near_clip`
    /// (rays start on the near-clip plane, as mitransient) or `pinhole` (the camera's
    /// origin; every NLOS capture). Bundles that predate the field: `pinhole`.
    #[serde(default = "legacy_time_origin")]
    pub time_origin: TimeOrigin,
    /// The near-clip distance (scene units) with `time_origin` `near_clip`; absent
    /// otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub near_clip: Option<f64>,
    /// Sub-pixel sampling of the primary rays; "independent" for bundles that predate
    /// the field. With "stratified" (or "mixed") samples, the variances estimated from
    /// the sums over-estimate the variance of the mean (see `render::pixel_sampling`).
    #[serde(default = "SamplingRecord::legacy")]
    pub pixel_sampling: SamplingRecord,
    /// Replicates per pixel B (SPEC 4-5): each pixel's spp in B independently
    /// randomised sets of spp / B samples, and `r2.npy` holds `R2 = sum_b m_b^2`.
    /// Absent: no replicates.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub replicates: Option<u64>,
    /// The scene has participating media (rendered by `transient_prbvolpath`): the
    /// bundle then also holds `medium.npy`, and `denoise` defaults to the Gaussian base
    /// filter. Absent (false) in bundles of surface-only scenes.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub media: bool,
    /// The seed this bundle's paths were drawn from: the job's seed for an unsharded
    /// render, `shard_seed(job seed, I)` for shard I (the job's seed is in `shard`),
    /// and for a merge the smallest of `merged_seeds` (its canonical order's first).
    /// The adaptive pilot's seed is never recorded here: it is `pilot_seed(job seed)`
    /// (`job/render.rs`).
    pub seed: u64,
    /// Seeds of every render summed into this bundle by `tstat merge` (empty otherwise).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub merged_seeds: Vec<u64>,
    /// Adaptive sampling (`render/adaptive.rs`): each pixel's sample count is in
    /// `pixel_spp.npy` ((H, W) u32) and `spp` is their mean; version 2. Absent: every
    /// pixel has `spp` samples.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub adaptive: Option<AdaptiveRecord>,
    /// An NLOS capture's geometry (`capture.rs`): its sensor grid, laser points and
    /// relay wall; absent for camera renders.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nlos: Option<super::capture::CaptureRecord>,
    /// The job and shards of a render with `--shard` (see `shard.rs`); absent otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shard: Option<super::shard::ShardRecord>,
    pub scene: SceneRef,
    pub max_depth: i32,
    /// The temporal Gaussian's standard deviation in bins (`temporal_filter`
    /// gaussian); absent for the box.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time_filter_stddev_bins: Option<f64>,
    pub render_seconds: f64,
    pub dropped_nonfinite: u64,
    pub program: Program,
    pub arrays: Vec<ArrayInfo>,
}

/// How an adaptive render chose its per-pixel counts, and what it chose.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct AdaptiveRecord {
    /// The error the allocation minimised.
    pub measure: crate::render::adaptive::ErrorMeasure,
    /// Samples per pixel of the pilot (not in the sums), and its time.
    pub pilot_spp: u64,
    pub pilot_seconds: f64,
    /// The fewest and most samples of any pixel (`pixel_spp.npy`).
    pub min_spp: u64,
    pub max_spp: u64,
    /// What decided the mean spp when the user asked for a time or an error
    /// (`--time-budget`, `--target-error`), and the error the pilot predicted.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub goal: Option<GoalRecord>,
    /// The noisy volume's error estimated from its own sums (sum of each voxel's
    /// variance of the mean; the RMSE for `mse`, the relMSE for `relmse`); absent
    /// under a transform (the sums are then not of radiance).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub estimated_error: Option<f64>,
}

/// A goal of adaptive sampling and what the pilot predicted for the spp chosen.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct GoalRecord {
    /// `time_budget_seconds` or `target_error`, as asked.
    pub kind: String,
    pub value: f64,
    pub predicted_error: f64,
}

/// Bundles written before `time_origin` was recorded counted from the camera.
fn legacy_time_origin() -> TimeOrigin {
    TimeOrigin::Pinhole
}

impl Manifest {
    /// The volume's time axis (`sensors/time_axis.rs`); the file keeps its three
    /// numbers as SPEC 9's flat fields.
    pub fn time(&self) -> TimeAxis {
        TimeAxis {
            start_opl: self.start_opl,
            bin_width_opl: self.bin_width_opl,
            bins: self.bins,
        }
    }

    /// Where OPL 0 is, for labels ("OPL from ..."): the recorded time origin of a
    /// camera render; for an NLOS capture the relay wall (the sensor and laser
    /// segments dropped) or the sensor.
    pub fn time_zero(&self) -> &'static str {
        match &self.nlos {
            Some(n) if n.account_first_and_last_bounces => "the sensor",
            Some(_) => "the relay wall",
            None => self.time_origin.describe(),
        }
    }

    /// Whether a sample may be negative: a spectral path's linear sRGB is (the sRGB
    /// matching curves are negative at some wavelengths), though each voxel's mean
    /// converges to the scene's colour.
    /// Channels C of every (H, W, T, C) and (H, W, C) array: the mode's.
    pub fn channel_count(&self) -> usize {
        self.mode.channels()
    }

    pub fn signed_samples(&self) -> bool {
        self.mode.signed()
    }

    pub fn array(&self, name: &str) -> Option<&ArrayInfo> {
        self.arrays.iter().find(|a| a.name == name)
    }
}
