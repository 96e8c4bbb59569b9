//! Denoising (SPEC 8): estimates from the bundle's sums, then the statistical
//! spatio-temporal filter (base filter x membership): tstat's membership (default,
//! `tstat.rs`) or the published per-voxel Welch test (`membership.rs`).

pub mod arrays;
pub mod base_filter;
pub mod conventions;
pub mod critical;
pub mod estimates;
pub mod filter;
pub mod gbuffers;
pub mod membership;
pub mod pair_dof;
pub mod slab;
pub mod tstat;

use crate::bundle::{Bundle, BundleError, SumArray};
use base_filter::{BaseFilter, BaseKind, Features, Sigmas};
pub use conventions::{Border, Variance};
use critical::{Threshold, Welch};
use estimates::{Estimates, SumsView};
use filter::{filter, FilterParams, Membership, Tiling};
use gbuffers::GBuffers;
use ndarray::Array4;
use pair_dof::PairDof;
use tstat::TstatParams;

/// Errors of the denoiser's parameters, named by their flags.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum DenoiseError {
    /// A parameter (`flag`) that must be a positive number.
    #[error("{flag} {value}: must be a positive number")]
    NotPositive { flag: &'static str, value: f64 },
    #[error("--emitter-radius {0}: at most 64")]
    EmitterRadius(usize),
    #[error("--gamma {0}: must be in (0, 0.5)")]
    Gamma(f64),
    #[error("--alpha {0}: must be in (0, 1)")]
    Alpha(f64),
    /// The published code's conventions asked of another method.
    #[error("{0} is the published code's convention: only with --method published")]
    PublishedOnly(&'static str),
}

/// The denoiser's method: which membership test the filter applies, with its settings.
/// `T` is the published test's threshold: as chosen ([`Threshold`], the default), or
/// resolved for a sample count ([`Welch`](critical::Welch): the form the filter takes, see
/// [`filter::Membership`] and [`Method::resolve`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Method<T = Threshold> {
    /// tstat's classes, depth alignment and patch test (the default).
    Tstat(TstatParams),
    /// The published filter's per-voxel Welch test.
    Published(T),
    /// The base filter alone (no membership test).
    BaseOnly,
}

impl<T> Method<T> {
    /// A short name for reports.
    pub fn name(&self) -> &'static str {
        match self {
            Method::Tstat(_) => "tstat",
            Method::Published(_) => "published",
            Method::BaseOnly => "base-only",
        }
    }

    /// The spatial radius r each method defaults to (measured: tstat at r = 3 matches
    /// r = 5 within 1% at half the cost; the published filter was tuned at r = 5).
    pub fn default_radius(&self) -> usize {
        match self {
            Method::Tstat(_) => 3,
            Method::Published(_) | Method::BaseOnly => 5,
        }
    }

    /// The same method with the published test's threshold mapped by `f`.
    pub fn map_threshold<U>(self, f: impl FnOnce(T) -> U) -> Method<U> {
        match self {
            Method::Tstat(t) => Method::Tstat(t),
            Method::Published(t) => Method::Published(f(t)),
            Method::BaseOnly => Method::BaseOnly,
        }
    }
}

impl Membership {
    /// Hands the method's per-voxel-pair test ([`membership::PairTest`]) to `user`
    /// (the filter, `filter.rs`), which is compiled for it: the published test with its
    /// g^2, or with each pair's own on estimates from `replicates` (when it has a
    /// level); `None` for the base filter alone and for tstat, whose test is the
    /// filter's own. A new method of the pair-test kind adds its arm here.
    pub fn with_pair_test<U: filter::PairTestUser>(
        &self,
        replicates: Option<u64>,
        user: U,
    ) -> U::Out {
        match (*self, replicates) {
            (Method::Published(Welch { alpha: Some(a), .. }), Some(b)) if b >= 2 => {
                user.with(Some(PairDof::new(b, a)))
            }
            (Method::Published(w), _) => user.with(Some(membership::WelchG2(w.g2 as f32))),
            (Method::Tstat(_) | Method::BaseOnly, _) => user.with(None::<membership::Everyone>),
        }
    }
}

impl Method {
    /// The method with the threshold `report sweep` varies set aside (t2_patch, the
    /// published threshold): the key of a sweep's curves.
    pub fn sweep_key(mut self) -> Self {
        match &mut self {
            Method::Tstat(t) => t.t2_patch = 0.0,
            Method::Published(t) => *t = Threshold::Auto,
            Method::BaseOnly => {}
        }
        self
    }

    /// Refuses settings out of range.
    pub fn validate(&self) -> Result<(), DenoiseError> {
        match self {
            Method::Tstat(t) => t.validate(),
            Method::Published(t) => t.validate(),
            Method::BaseOnly => Ok(()),
        }
    }

    /// The method as the filter applies it to estimates from `spp` samples per pixel
    /// (or `spp` replicates): the published test's g^2 (and level) for that count.
    pub fn resolve(self, spp: u64) -> Membership {
        self.map_threshold(|t| t.resolve(spp))
    }

    /// The method and its settings, for reports.
    pub fn describe(&self) -> String {
        match self {
            Method::Tstat(t) => format!(
                "tstat (t2_max = {}, t2_patch = {}, emitter radius = {}, depth alignment {}, isolated bins {})",
                t.t2_max,
                t.t2_patch,
                t.emitter_radius
                    .map_or("auto (4r; 0 on stratified renders)".to_string(), |r| r
                        .to_string()),
                if t.depth_align { "on" } else { "off" },
                if t.isolated_bins_alone {
                    "judged alone"
                } else {
                    "in the patch mean"
                }
            ),
            Method::Published(Threshold::Gamma(g)) => format!("published, gamma = {g}"),
            Method::Published(Threshold::Alpha(a)) => format!("published, alpha = {a}"),
            Method::Published(Threshold::Auto) => {
                "published, gamma = auto (0.25 below 16 spp, 0.15 below 64, else 0.1)".into()
            }
            Method::BaseOnly => "base filter alone (no membership)".into(),
        }
    }
}

/// Everything the denoiser is told.
#[derive(Clone, Copy, Debug)]
pub struct DenoiseParams {
    pub radius: usize,
    pub temporal_radius: usize,
    pub method: Method,
    pub base: BaseKind,
    pub sigmas: Sigmas,
    pub tiling: Tiling,
    /// The estimates' variance convention (`conventions.rs`; the published code's
    /// biased one only with `--method published`).
    pub variance: Variance,
    /// What lies beyond the borders (zeros only with `--method published`).
    pub border: Border,
}

impl Default for DenoiseParams {
    fn default() -> Self {
        let method = Method::Tstat(TstatParams::default());
        DenoiseParams {
            radius: method.default_radius(),
            temporal_radius: 1,
            method,
            base: BaseKind::Jbf,
            sigmas: Sigmas::default(),
            tiling: Tiling::default(),
            variance: Variance::default(),
            border: Border::default(),
        }
    }
}

impl DenoiseParams {
    pub fn validate(&self) -> Result<(), DenoiseError> {
        self.method.validate()?;
        if !matches!(self.method, Method::Published(_)) {
            if self.variance == Variance::Biased {
                return Err(DenoiseError::PublishedOnly("--variance biased"));
            }
            if self.border == Border::Zero {
                return Err(DenoiseError::PublishedOnly("--border zero"));
            }
        }
        self.sigmas.validate()
    }

    /// The defaults for NLOS captures, chosen by measurement (docs/results/nlos_denoise.md,
    /// `scripts/nlos_denoise_study.py`), where the user did not choose:
    /// - spatial radius 1 (unless `radius_chosen`): neighbouring wall points' echoes
    ///   shift by up to twice their spacing, so wider windows blur the reconstruction
    ///   (fbp error at 16 spp: r 1 0.30, r 2 0.41, r 3 0.51, docs/results/nlos_denoise.md);
    /// - radius 0 on exhaustive scans (`exhaustive`: the film stacks one sensor image per
    ///   laser point): their grids are coarse (8 x 8 points 0.29 apart on the letters T
    ///   and Z), a neighbour's echo is shifted beyond what the test can see at low
    ///   counts, and the filter alone made every reconstruction worse; without spatial
    ///   neighbours it does not (gain over noisy at 4 spp, radius 1 / 0: T bp 1.14 /
    ///   1.71, fbp 0.42 / 1.01; Z bp 1.11 / 1.75, fbp 0.69 / 1.09; T at 256 spp, radius 0:
    ///   bp 1.31, fbp 0.99; docs/nlos.md, "Denoised captures");
    /// - bins not aligned by camera depth (unless `depth_align_asked`): a capture's
    ///   times do not follow the depth from its sensor origin, and aligned, the filter
    ///   mixes echoes of different lengths (fbp error at 16 spp, r 3: 0.82 aligned, 0.51 not);
    /// - isolated bins not judged alone (`TstatParams::isolated_bins_alone`): at low
    ///   counts nearly every occupied bin of a capture is isolated, and judging them
    ///   alone cut the reconstructions' gain at 4 spp (nlos_T: bp 4.4x to 3.3x, fk 90x
    ///   to 4.8x; docs/denoiser.md).
    pub fn adapt_to_nlos(
        &mut self,
        radius_chosen: bool,
        depth_align_asked: bool,
        exhaustive: bool,
    ) {
        if !radius_chosen {
            self.radius = if exhaustive { 0 } else { 1 };
        }
        if let Method::Tstat(t) = &mut self.method {
            if !depth_align_asked {
                t.depth_align = false;
            }
            t.isolated_bins_alone = false;
        }
    }

    /// The filter's parameters for a bundle of `spp` samples per pixel (its number of
    /// replicates when it has them; the filter then takes each pair's critical value at
    /// its Welch-Satterthwaite degrees of freedom, SPEC 8, see `pair_dof.rs`).
    pub fn filter_params(&self, spp: u64) -> FilterParams {
        FilterParams {
            radius: self.radius,
            temporal_radius: self.temporal_radius,
            base: BaseFilter {
                kind: self.base,
                sigmas: self.sigmas,
            },
            membership: self.method.resolve(spp),
            zero_border: self.border == Border::Zero,
        }
    }
}

pub struct Denoised {
    /// f32 (H, W, T, C).
    pub volume: Array4<f32>,
    /// Voxel-neighbour evaluations performed.
    pub evaluations: u64,
    /// Wall seconds of the whole call (reading sums and making estimates included).
    pub seconds: f64,
    /// Wall seconds of the filter alone.
    pub filter_seconds: f64,
}

/// Bytes the denoiser holds at its peak on a bundle of these sizes cut into slabs by
/// `plan` (see [`slab::SlabPlan::bytes`]; a volume kept in memory adds `H W T C 4`).
pub fn memory_bytes(dims: slab::Dims, plan: &slab::SlabPlan) -> u64 {
    plan.bytes(dims)
}

/// Denoises from sums and G-buffers already in memory.
pub fn denoise_sums(
    sums: &SumsView,
    features: &Features,
    params: &DenoiseParams,
    progress: &(dyn Fn(u64) + Sync),
) -> Denoised {
    let start = std::time::Instant::now();
    let est = Estimates::from_sums_as(sums, params.variance);
    let mut d = denoise_estimates(est, sums.spp, features, params, progress);
    d.seconds = start.elapsed().as_secs_f64();
    d
}

/// Filters estimates already made (consumed, so their memory is freed before the
/// output is laid out).
pub fn denoise_estimates(
    est: Estimates,
    spp: u64,
    features: &Features,
    params: &DenoiseParams,
    progress: &(dyn Fn(u64) + Sync),
) -> Denoised {
    let start = std::time::Instant::now();
    let fp = params.filter_params(est.replicates.unwrap_or(spp));
    let (planar, evaluations) = filter(&est, features, &fp, params.tiling, progress);
    let filter_seconds = start.elapsed().as_secs_f64();
    let (h, w, t, ch) = (est.height, est.width, est.bins, est.channels);
    drop(est);
    let volume = Array4::from_shape_fn((h, w, t, ch), |(y, x, k, c)| {
        planar[((y * w + x) * ch + c) * t + k]
    });
    Denoised {
        volume,
        evaluations,
        seconds: start.elapsed().as_secs_f64(),
        filter_seconds,
    }
}

/// A bundle's sums and G-buffers, read once (for several denoising runs).
pub struct LoadedSums {
    pub manifest: crate::bundle::Manifest,
    x1: ndarray::Array4<f64>,
    x2: ndarray::Array4<f64>,
    x3: ndarray::Array4<f64>,
    sum: Option<ndarray::Array4<f64>>,
    r2: Option<ndarray::Array4<f64>>,
    nonzero: ndarray::Array3<u32>,
    /// Each pixel's samples of an adaptive render.
    pixel_spp: Option<Vec<u32>>,
    pub gbuffers: GBuffers,
}

impl LoadedSums {
    /// Reads the sums, counts and G-buffers, each checked on load (see
    /// `bundle::read`): counts first, so that every sum is checked against them.
    pub fn read(bundle: &Bundle) -> Result<LoadedSums, BundleError> {
        let m = &bundle.manifest;
        let nonzero = bundle.nonzero()?;
        Ok(LoadedSums {
            manifest: m.clone(),
            x1: bundle.sum_array(SumArray::X1, &nonzero)?,
            x2: bundle.sum_array(SumArray::X2, &nonzero)?,
            x3: bundle.sum_array(SumArray::X3, &nonzero)?,
            sum: if m.transform.is_identity() {
                None
            } else {
                Some(bundle.sum_array(SumArray::Radiance, &nonzero)?)
            },
            r2: match m.replicates {
                Some(_) => Some(bundle.sum_array(SumArray::R2, &nonzero)?),
                None => None,
            },
            nonzero,
            pixel_spp: bundle.pixel_spp.clone(),
            gbuffers: GBuffers::read(bundle)?,
        })
    }

    pub fn view(&self) -> SumsView<'_> {
        let m = &self.manifest;
        SumsView {
            height: m.height,
            width: m.width,
            bins: m.bins,
            channels: m.channel_count(),
            bin_width: m.bin_width_opl,
            spp: m.spp,
            stratified: slab::stratified(m),
            image_rows: slab::image_rows(m),
            z0: m.transform.at_zero(),
            x1: std_slice(&self.x1),
            x2: std_slice(&self.x2),
            x3: std_slice(&self.x3),
            sum: std_slice(self.sum.as_ref().unwrap_or(&self.x1)),
            nonzero: std_slice(&self.nonzero),
            replicates: m.replicates.zip(self.r2.as_ref().map(std_slice)),
            pixel_spp: self.pixel_spp.as_deref(),
        }
    }

    pub fn denoise(&self, params: &DenoiseParams, progress: &(dyn Fn(u64) + Sync)) -> Denoised {
        denoise_sums(&self.view(), &self.gbuffers.features(), params, progress)
    }
}

/// Reads a bundle and denoises it into a volume in memory, in slabs that keep
/// everything but the volume within [`slab::DEFAULT_BUDGET`] (the sums are read a few
/// rows at a time).
pub fn denoise_bundle(
    bundle: &Bundle,
    params: &DenoiseParams,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Denoised, BundleError> {
    let m = &bundle.manifest;
    let dims = slab::Dims::of(m);
    let plan = slab::SlabPlan::for_budget(dims, slab::halo(bundle, params)?, slab::DEFAULT_BUDGET);
    let (w, t, ch) = (m.width, m.bins, m.channel_count());
    let mut volume = Array4::zeros((m.height, w, t, ch));
    let per_row = w * t * ch;
    let stats = slab::denoise_slabs(
        bundle,
        params,
        &plan,
        &mut |y0, planar| {
            let rows = planar.len() / per_row;
            let mut part = volume.slice_mut(ndarray::s![y0..y0 + rows, .., .., ..]);
            part.indexed_iter_mut().for_each(|((y, x, k, c), v)| {
                *v = planar[((y * w + x) * ch + c) * t + k];
            });
            Ok(())
        },
        progress,
    )?;
    Ok(Denoised {
        volume,
        evaluations: stats.evaluations,
        seconds: stats.seconds,
        filter_seconds: stats.filter_seconds,
    })
}

/// Arrays read from a bundle are in standard (C) layout.
pub(crate) fn std_slice<T, D: ndarray::Dimension>(a: &ndarray::Array<T, D>) -> &[T] {
    a.as_slice()
        .expect("bundle arrays are read in standard layout")
}
