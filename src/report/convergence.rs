//! The convergence experiment: render a scene at a list of spp (a fresh seed each, so
//! no two renders share samples), denoise each render with every method of
//! [`methods`], time render and denoise separately, and measure each result against a
//! reference over the three regions of [`super::region`], with the equal-error
//! speed-up of each denoised result against the noisy curve of the same region.

use super::metrics::Metrics;
use super::reconstruction::{NlosPlan, ReconstructionError, Reconstructor};
use super::region::{compare_regions, Region, RegionMetrics};
use super::speedup::{speedup_or_bound, Speedup};
use super::volume::no_light_mask;
use super::ReportError;
use crate::denoise::critical::Threshold;
use crate::denoise::gbuffers::GBuffers;
use crate::denoise::tstat::TstatParams;
use crate::denoise::{denoise_sums, estimates::SumsView, DenoiseParams, Method};
use crate::nlos::reconstruct::bp::VoxelGrid;
use crate::nlos::reconstruct::Reconstruction;
use crate::render::adaptive::{AdaptiveOptions, ErrorMeasure};
use crate::render::{render, PixelSampling, RenderOutput, RenderSettings};
use crate::scene::{Overrides, Scene};
use crate::stats::Transform;
use ndarray::{Array2, Array4};
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};

/// Where the reference volume comes from.
pub enum ReferenceSource {
    /// A given (H, W, T, C) volume (.npy or bundle).
    Volume(PathBuf),
    /// A render at this spp, cached in the output directory.
    Render { spp: u32 },
}

pub struct ConvergenceConfig {
    pub scene: PathBuf,
    /// Render overrides (their `spp` is ignored: the list below is used).
    pub overrides: Overrides,
    pub spp_list: Vec<u32>,
    pub seed: u64,
    pub transform: Transform,
    /// Sub-pixel sampling of the renders and of a rendered reference.
    pub pixel_sampling: PixelSampling,
    /// Replicates of the renders (0: none; see `RenderSettings::replicates`).
    pub replicates: u32,
    pub denoise: DenoiseParams,
    /// Each method at its own default spatial radius ([`Method::default_radius`])
    /// instead of `denoise.radius` (when the user did not choose one).
    pub method_radii: bool,
    /// The base filter was not chosen: Gaussian for scenes with media, else
    /// `denoise.base`.
    pub base_by_scene: bool,
    pub reference: ReferenceSource,
    /// NLOS scenes: the reconstructions of every capture (`super::reconstruction`).
    pub nlos: Option<NlosPlan>,
    /// NLOS scenes take the denoiser's NLOS defaults
    /// ([`DenoiseParams::adapt_to_nlos`]) unless `radius_chosen` (the spatial radius)
    /// or `depth_align_asked` (camera-depth alignment) says otherwise.
    pub radius_chosen: bool,
    pub depth_align_asked: bool,
    /// Add the adaptive pipeline's rows (`render/adaptive.rs`, minimising MSE): at each
    /// spp as the mean, `adaptive` (its noisy mean) and `adaptive tstat` (denoised with
    /// the `tstat` row's settings), timed pilot + render (+ denoise).
    pub adaptive: bool,
}

/// The adaptive pipeline's rows' names.
pub const ADAPTIVE: &str = "adaptive";
pub const ADAPTIVE_DENOISED: &str = "adaptive tstat";

/// The methods compared, in table order, each with its denoiser settings (`None`: the
/// noisy mean). `published` and `tstat` take the configured settings when the
/// configuration selects that method, else their defaults, with the configured temporal
/// radius, base filter and sigmas, and the configured spatial radius unless
/// `method_radii` asks for each method's own default.
pub fn methods(
    denoise: &DenoiseParams,
    method_radii: bool,
) -> Vec<(&'static str, Option<DenoiseParams>)> {
    // The published code's conventions (`--variance biased`, `--border zero`) are the
    // published method's alone.
    let with = |method: Method| DenoiseParams {
        method,
        radius: if method_radii {
            method.default_radius()
        } else {
            denoise.radius
        },
        variance: match method {
            Method::Published(_) => denoise.variance,
            _ => Default::default(),
        },
        border: match method {
            Method::Published(_) => denoise.border,
            _ => Default::default(),
        },
        ..*denoise
    };
    let published = match denoise.method {
        m @ Method::Published(_) => m,
        _ => Method::Published(Threshold::Auto),
    };
    let tstat = match denoise.method {
        m @ Method::Tstat(_) => m,
        _ => Method::Tstat(TstatParams::default()),
    };
    vec![
        ("noisy", None),
        ("base-only", Some(with(Method::BaseOnly))),
        ("published", Some(with(published))),
        ("tstat", Some(with(tstat))),
    ]
}

/// With stratified renders, each spp is also rendered with independent sub-pixel
/// positions (the sampler of renderers without stratification, e.g. mitransient's
/// `independent`): its noisy mean is this row, and speed-ups are given against both.
pub const BASELINE: &str = "noisy-independent";

#[derive(Clone, Debug)]
pub struct ResultRow {
    pub spp: u32,
    pub method: &'static str,
    pub render_s: f64,
    pub denoise_s: f64,
    pub total_s: f64,
    pub error: RegionMetrics,
    /// Equal-error speed-up per region (all, light, rest) against the noisy curve of
    /// that region, or its bound where the error lies outside the curve's measured
    /// range: `None` for the noisy rows and for regions that do not exist.
    pub speedup: [Option<Speedup>; 3],
    /// The same against the [`BASELINE`] curve (stratified runs only).
    pub speedup_independent: [Option<Speedup>; 3],
    /// Voxel-neighbour evaluations per second of the filter (0 for the noisy rows).
    pub evaluations_per_s: f64,
    /// NLOS: each reconstruction's error and time (in the plan's order; empty without
    /// a plan).
    pub reconstructions: Vec<ReconstructionError>,
    /// Each reconstruction's equal-error speed-up against the noisy rows' curve of
    /// (render + reconstruction seconds, error), this row timed as render + denoise +
    /// reconstruction, the reconstruction's time the median over the rows (`None` for
    /// the noisy rows).
    pub reconstruction_speedup: Vec<Option<Speedup>>,
}

impl ResultRow {
    /// A measured row (its speed-ups are filled in later, from all rows).
    #[allow(clippy::too_many_arguments)]
    fn measured(
        spp: u32,
        method: &'static str,
        render_s: f64,
        denoise_s: f64,
        error: RegionMetrics,
        evaluations_per_s: f64,
        reconstructions: Vec<ReconstructionError>,
    ) -> ResultRow {
        ResultRow {
            reconstruction_speedup: vec![None; reconstructions.len()],
            reconstructions,
            spp,
            method,
            render_s,
            denoise_s,
            total_s: render_s + denoise_s,
            error,
            speedup: [None; 3],
            speedup_independent: [None; 3],
            evaluations_per_s,
        }
    }

    /// Speed-up over one region.
    pub fn speedup(&self, r: Region) -> Option<Speedup> {
        self.speedup[r as usize]
    }
}

pub struct ConvergenceResult {
    pub rows: Vec<ResultRow>,
    /// Method names in table order.
    pub methods: Vec<&'static str>,
    /// Per-bin metrics of each method at the highest spp.
    pub per_bin: Vec<(&'static str, Vec<Metrics>)>,
    /// How the reference was obtained (for the report).
    pub reference_note: String,
    /// The capture methods in table order with the denoiser settings each ran with.
    pub settings: Vec<(&'static str, Option<DenoiseParams>)>,
    /// NLOS: the reconstruction methods (in the rows' order).
    pub reconstruction_methods: Vec<Reconstruction>,
    /// NLOS: the reconstructions of the reference, and of each capture method at the
    /// lowest spp, per reconstruction method (for pictures).
    pub reconstruction_volumes: Vec<(&'static str, Vec<Vec<f32>>)>,
    /// NLOS: the voxel grid of the reconstructions.
    pub reconstruction_grid: Option<VoxelGrid>,
    /// NLOS with tstat among the methods: `nlos reconstruct --denoise-with`'s
    /// reconstructions at each spp of at least 4 ([`CrossValidated`]).
    pub cross_validated: Vec<CrossValidated>,
}

/// `nlos reconstruct --denoise-with` at one spp: the spp's tstat-denoised capture
/// shrunk toward its noisy capture by the weight b cross-validated between two more
/// independent captures of spp / 2 (rendered and denoised for it: `render_s`,
/// `denoise_s`); per reconstruction method, its error, time and b.
#[derive(Clone, Debug)]
pub struct CrossValidated {
    pub spp: u32,
    pub render_s: f64,
    pub denoise_s: f64,
    pub reconstructions: Vec<(ReconstructionError, f64)>,
}

/// The noisy mean S / n of a render as an (H, W, T, C) f32 volume; an error names
/// the first voxel whose mean f32 cannot hold (as a bundle's checks do).
pub fn noisy_mean(out: &RenderOutput, spp: u32) -> Result<Array4<f32>, ReportError> {
    noisy_mean_counts(out, &vec![spp; out.accum.height * out.accum.width])
}

/// [`noisy_mean`] of a render with per-pixel counts `n` (row-major).
pub fn noisy_mean_counts(out: &RenderOutput, n: &[u32]) -> Result<Array4<f32>, ReportError> {
    let a = &out.accum;
    let s = a.sum.as_ref().unwrap_or(&a.x1);
    let at = |y: usize, x: usize, t: usize, c: usize| {
        s[((y * a.width + x) * a.bins + t) * a.channels + c] / f64::from(n[y * a.width + x])
    };
    let v = Array4::from_shape_fn((a.height, a.width, a.bins, a.channels), |(y, x, t, c)| {
        at(y, x, t, c) as f32
    });
    match v.indexed_iter().find(|(_, m)| !m.is_finite()) {
        Some(((y, x, t, c), _)) => Err(ReportError::MeanBeyondF32 {
            mean: at(y, x, t, c),
            y,
            x,
            t,
            c,
        }),
        None => Ok(v),
    }
}

/// A view of a render's sums for the denoiser.
pub fn sums_view<'a>(
    out: &'a RenderOutput,
    spp: u32,
    transform: &Transform,
    bin_width: f64,
    pixel_sampling: PixelSampling,
    replicates: u32,
    image_rows: usize,
) -> SumsView<'a> {
    let a = &out.accum;
    let replicates =
        a.r2.as_deref()
            .filter(|_| replicates >= 2)
            .map(|r2| (u64::from(replicates), r2));
    SumsView {
        height: a.height,
        width: a.width,
        bins: a.bins,
        channels: a.channels,
        bin_width,
        spp: spp as u64,
        // As a bundle's manifest says (`denoise::slab::stratified`): correlated samples
        // without replicates over-state V.
        stratified: pixel_sampling != PixelSampling::Independent && replicates.is_none(),
        image_rows,
        z0: transform.at_zero(),
        x1: &a.x1,
        x2: &a.x2,
        x3: &a.x3,
        sum: a.sum.as_deref().unwrap_or(&a.x1),
        nonzero: &a.nonzero,
        replicates,
        pixel_spp: None,
    }
}

fn gbuffers(out: &RenderOutput) -> GBuffers {
    GBuffers::from_pixels(out.accum.height, out.accum.width, &out.gbuffer)
}

fn load_scene(cfg: &ConvergenceConfig, spp: u32) -> Result<Scene, ReportError> {
    let o = Overrides {
        spp: Some(spp),
        ..cfg.overrides.clone()
    };
    Scene::load(&cfg.scene, &o).map_err(ReportError::Scene)
}

/// A reference volume, its no-light mask, and how it was obtained.
type Reference = (Array4<f32>, Option<Vec<bool>>, String);

/// The reference volume and its no-light mask, rendering (and caching in `dir`) when asked.
fn reference(
    cfg: &ConvergenceConfig,
    dir: &Path,
    log: &dyn Fn(&str),
) -> Result<Reference, ReportError> {
    match &cfg.reference {
        ReferenceSource::Volume(p) => {
            let v = super::volume::load_volume(p)?;
            Ok((
                v.volume,
                v.no_light_mask,
                format!("given volume {}", p.display()),
            ))
        }
        ReferenceSource::Render { spp } => {
            let scene = load_scene(cfg, *spp)?;
            // Everything the image depends on (scene, files it read, overrides, camera,
            // program) and how the reference is rendered.
            let mut h = Sha256::new();
            h.update(
                format!(
                    "{}|{}|{}|{}",
                    scene.fingerprint(),
                    spp,
                    cfg.seed,
                    cfg.pixel_sampling
                )
                .as_bytes(),
            );
            let key = format!("{:x}", h.finalize());
            let key = &key[..16];
            let vol_path = dir.join(format!("reference-{key}.npy"));
            let em_path = dir.join(format!("reference-{key}-emitter.npy"));
            if vol_path.is_file() && em_path.is_file() {
                // Checked reads: a damaged cache is an error naming the file.
                let v = super::volume::load_volume(&vol_path)?.volume;
                let em = read_emitter(&em_path, v.shape()[0], v.shape()[1])?;
                log(&format!("reusing cached reference {}", vol_path.display()));
                return Ok((
                    v,
                    Some(no_light_mask(&em)),
                    format!("{spp} spp render (cached {})", vol_path.display()),
                ));
            }
            log(&format!("rendering the reference at {spp} spp"));
            let settings = RenderSettings {
                spp: *spp,
                seed: cfg.seed.wrapping_add(1_000_003),
                transform: Transform::Identity,
                pixel_sampling: cfg.pixel_sampling,
                replicates: 0,
                pixel_spp: None,
            };
            let out = render(&scene, &settings, &|_| {});
            let v = noisy_mean(&out, *spp)?;
            let em: Array2<f32> = gbuffers(&out).emitter;
            write_npy_atomic(&vol_path, &v)?;
            write_npy_atomic(&em_path, &em)?;
            Ok((
                v,
                Some(no_light_mask(&em)),
                format!(
                    "{spp} spp render, {:.1} s (cached as {})",
                    out.seconds,
                    vol_path.display()
                ),
            ))
        }
    }
}

/// Runs the experiment; `dir` holds the reference cache. `log` reports progress.
pub fn run_convergence(
    cfg: &ConvergenceConfig,
    dir: &Path,
    log: &dyn Fn(&str),
) -> Result<ConvergenceResult, ReportError> {
    if cfg.spp_list.is_empty() {
        return Err(ReportError::NoSpp);
    }
    if let Some(s) = cfg.spp_list.iter().find(|&&s| s < 2) {
        return Err(ReportError::TooFewSamples(*s));
    }
    let scene2 = load_scene(cfg, 2)?;
    let is_nlos = crate::bundle::capture::CaptureRecord::of_scene(&scene2).is_some();
    // Checked before the reference is rendered.
    let mut reconstructor = match &cfg.nlos {
        Some(plan) => Some(Reconstructor::new(&scene2, plan.clone())?),
        None => None,
    };
    let (reference, ref_mask, reference_note) = reference(cfg, dir, log)?;
    let mut denoise = cfg.denoise;
    if cfg.base_by_scene && !scene2.media.is_empty() {
        denoise.base = crate::denoise::base_filter::BaseKind::Gaussian;
    }
    let mut list = methods(&denoise, cfg.method_radii && !is_nlos);
    if is_nlos {
        for p in list.iter_mut().filter_map(|m| m.1.as_mut()) {
            p.adapt_to_nlos(
                cfg.radius_chosen,
                cfg.depth_align_asked,
                scene2.image_rows() < scene2.film.height,
            );
        }
    }
    // The film does not depend on the spp: one check for every render.
    let shape = [
        scene2.film.height,
        scene2.film.width,
        scene2.film.time.bins,
        scene2.film.channels,
    ];
    if reference.shape() != shape {
        return Err(ReportError::ReferenceShape {
            reference: reference.shape().to_vec(),
            renders: shape,
        });
    }
    if let Some(r) = &mut reconstructor {
        log("reconstructing the reference capture");
        r.set_reference(&reference)?;
    }
    let mut reconstruction_volumes = Vec::new();
    let mut cross_validated = Vec::new();
    if let Some(r) = &reconstructor {
        let refs = (0..r.methods().len()).map(|k| r.reference(k).to_vec());
        reconstruction_volumes.push(("reference", refs.collect()));
    }
    let min_spp = *cfg.spp_list.iter().min().expect("non-empty");
    let mut rows = Vec::new();
    let mut per_bin = Vec::new();
    let max_spp = *cfg.spp_list.iter().max().expect("non-empty");
    for (k, &spp) in cfg.spp_list.iter().enumerate() {
        let scene = load_scene(cfg, spp)?;
        if k == 0 {
            for w in &scene.warnings {
                log(&format!("warning: {w}"));
            }
        }
        let settings = RenderSettings {
            spp,
            seed: cfg.seed.wrapping_add(1 + k as u64),
            transform: cfg.transform,
            pixel_sampling: cfg.pixel_sampling,
            replicates: cfg.replicates,
            pixel_spp: None,
        };
        let out = render(&scene, &settings, &|_| {});
        let g = gbuffers(&out);
        let features = g.features();
        let mask = ref_mask
            .clone()
            .unwrap_or_else(|| features.emitter.iter().map(|&e| e == 0.0).collect());
        let view = sums_view(
            &out,
            spp,
            &cfg.transform,
            scene.film.time.bin_width_opl,
            cfg.pixel_sampling,
            cfg.replicates,
            scene.image_rows(),
        );
        let mut line = format!("spp {spp}: render {:.2} s", out.seconds);
        if cfg.pixel_sampling != PixelSampling::Independent {
            let settings = RenderSettings {
                pixel_sampling: PixelSampling::Independent,
                replicates: 0,
                pixel_spp: None,
                seed: cfg.seed.wrapping_add(500_001 + k as u64),
                ..settings
            };
            let base = render(&scene, &settings, &|_| {});
            let (error, bins) = compare_regions(
                noisy_mean(&base, spp)?.view(),
                reference.view(),
                Some(&mask),
            );
            line += &format!("; {BASELINE} {:.4e}", error.all.rmse);
            let reconstructions = match &reconstructor {
                Some(r) => r.measure(&noisy_mean(&base, spp)?)?.0,
                None => Vec::new(),
            };
            rows.push(ResultRow::measured(
                spp,
                BASELINE,
                base.seconds,
                0.0,
                error,
                0.0,
                reconstructions,
            ));
            if spp == max_spp {
                per_bin.push((BASELINE, bins));
            }
        }
        // The noisy and the tstat-denoised capture, for `--denoise-with`'s rows.
        let mut kept: (Option<Array4<f32>>, Option<Array4<f32>>) = (None, None);
        for &(method, params) in &list {
            let (vol, den_s, evals) = match params {
                None => (noisy_mean(&out, spp)?, 0.0, 0.0),
                Some(p) => {
                    let d = denoise_sums(&view, &features, &p, &|_| {});
                    let rate = d.evaluations as f64 / d.filter_seconds.max(1e-9);
                    (d.volume, d.seconds, rate)
                }
            };
            let (error, bins) = compare_regions(vol.view(), reference.view(), Some(&mask));
            line += &format!("; {method} {:.4e} ({den_s:.2} s)", error.all.rmse);
            // Halves of spp / 2 samples: at least 2, a multiple of the replicates.
            let halves_ok = spp >= 4 && (spp / 2) % cfg.replicates.max(1) == 0;
            if reconstructor.is_some() && halves_ok {
                match method {
                    "noisy" => kept.0 = Some(vol.clone()),
                    "tstat" => kept.1 = Some(vol.clone()),
                    _ => {}
                }
            }
            let reconstructions = match &reconstructor {
                Some(r) => {
                    let (errors, volumes) = r.measure(&vol)?;
                    for (m, e) in r.methods().iter().zip(&errors) {
                        line += &format!(" [{} {:.4}]", m.name(), e.error);
                    }
                    if spp == min_spp {
                        reconstruction_volumes.push((method, volumes));
                    }
                    errors
                }
                None => Vec::new(),
            };
            rows.push(ResultRow::measured(
                spp,
                method,
                out.seconds,
                den_s,
                error,
                evals,
                reconstructions,
            ));
            if spp == max_spp {
                per_bin.push((method, bins));
            }
        }
        if let (Some(r), (Some(noisy), Some(denoised))) = (&reconstructor, &kept) {
            let p = list
                .iter()
                .find(|m| m.0 == "tstat")
                .and_then(|m| m.1)
                .expect("a tstat row was kept");
            let half_scene = load_scene(cfg, spp / 2)?;
            // On an exhaustive scan at its default radius (0), fbp and pf take their
            // captures denoised at radius 1 too, as `--denoise-with` does
            // (`nlos::shrink::radius_for`).
            let exhaustive = scene.image_rows() < scene.film.height;
            let radius_one =
                (exhaustive && !cfg.radius_chosen).then_some(DenoiseParams { radius: 1, ..p });
            let (mut one_halves, mut one_merged, mut denoise_s_one) = (Vec::new(), None, 0.0);
            if let Some(p1) = &radius_one {
                let d = denoise_sums(&view, &features, p1, &|_| {});
                denoise_s_one = d.seconds;
                one_merged = Some(d.volume);
            }
            let mut halves = Vec::new();
            let (mut render_s, mut denoise_s) = (0.0, 0.0);
            for j in 0..2u64 {
                let settings = RenderSettings {
                    spp: spp / 2,
                    seed: cfg.seed.wrapping_add(900_001 + 2 * k as u64 + j),
                    pixel_spp: None,
                    ..settings.clone()
                };
                let h = render(&half_scene, &settings, &|_| {});
                render_s += h.seconds;
                let view = sums_view(
                    &h,
                    spp / 2,
                    &cfg.transform,
                    half_scene.film.time.bin_width_opl,
                    cfg.pixel_sampling,
                    cfg.replicates,
                    half_scene.image_rows(),
                );
                let hg = gbuffers(&h);
                let d = denoise_sums(&view, &hg.features(), &p, &|_| {});
                denoise_s += d.seconds;
                if let Some(p1) = &radius_one {
                    let d1 = denoise_sums(&view, &hg.features(), p1, &|_| {});
                    denoise_s += d1.seconds;
                    one_halves.push(d1.volume);
                }
                halves.push((noisy_mean(&h, spp / 2)?, d.volume));
            }
            denoise_s += denoise_s_one;
            let reconstructions = r.measure_cross_validated(
                noisy,
                denoised,
                [(&halves[0].0, &halves[0].1), (&halves[1].0, &halves[1].1)],
                one_merged
                    .as_ref()
                    .map(|d| (d, [&one_halves[0], &one_halves[1]])),
            )?;
            for (m, (e, b)) in r.methods().iter().zip(&reconstructions) {
                line += &format!(" [{} cv {:.4}, b {b:.3}]", m.name(), e.error);
            }
            cross_validated.push(CrossValidated {
                spp,
                render_s,
                denoise_s,
                reconstructions,
            });
        }
        if cfg.adaptive {
            let tstat = list.iter().find(|m| m.0 == "tstat").and_then(|m| m.1);
            let g = cfg.replicates.max(1);
            let o = AdaptiveOptions::new(spp, ErrorMeasure::Mse, g, 2);
            if o.validate().is_ok() {
                let pilot_settings = RenderSettings {
                    seed: AdaptiveOptions::pilot_seed(settings.seed),
                    ..settings.clone()
                };
                let (m, pilot) =
                    crate::render::adaptive::pilot(&scene, &pilot_settings, &o, &|_| {});
                let w = crate::render::adaptive::weights(&m, scene.film.width);
                let n: std::sync::Arc<[u32]> = crate::render::adaptive::allocate(&w, &o).into();
                let a_settings = RenderSettings {
                    pixel_spp: Some(n.clone()),
                    ..settings.clone()
                };
                let aout = render(&scene, &a_settings, &|_| {});
                let render_s = pilot.seconds + aout.seconds;
                let noisy = noisy_mean_counts(&aout, &n)?;
                let mut outputs = vec![(ADAPTIVE, noisy, 0.0, 0.0)];
                if let Some(p) = tstat {
                    let view = SumsView {
                        pixel_spp: Some(&n),
                        ..sums_view(
                            &aout,
                            spp,
                            &cfg.transform,
                            scene.film.time.bin_width_opl,
                            cfg.pixel_sampling,
                            cfg.replicates,
                            scene.image_rows(),
                        )
                    };
                    let d = denoise_sums(&view, &gbuffers(&aout).features(), &p, &|_| {});
                    let rate = d.evaluations as f64 / d.filter_seconds.max(1e-9);
                    outputs.push((ADAPTIVE_DENOISED, d.volume, d.seconds, rate));
                }
                for (method, vol, den_s, evals) in outputs {
                    let (error, bins) = compare_regions(vol.view(), reference.view(), Some(&mask));
                    line += &format!("; {method} {:.4e} ({den_s:.2} s)", error.all.rmse);
                    let reconstructions = match &reconstructor {
                        Some(r) => r.measure(&vol)?.0,
                        None => Vec::new(),
                    };
                    rows.push(ResultRow::measured(
                        spp,
                        method,
                        render_s,
                        den_s,
                        error,
                        evals,
                        reconstructions,
                    ));
                    if spp == max_spp {
                        per_bin.push((method, bins));
                    }
                }
            } else {
                line += "; adaptive: skipped (spp not a multiple of the replicates)";
            }
        }
        log(&line);
    }
    fill_speedups(&mut rows);
    fill_reconstruction_speedups(&mut rows);
    let mut methods: Vec<&'static str> = list.iter().map(|m| m.0).collect();
    if cfg.pixel_sampling != PixelSampling::Independent {
        methods.insert(1, BASELINE);
    }
    if cfg.adaptive {
        methods.push(ADAPTIVE);
        if list.iter().any(|m| m.0 == "tstat") {
            methods.push(ADAPTIVE_DENOISED);
        }
    }
    Ok(ConvergenceResult {
        rows,
        methods,
        per_bin,
        reference_note,
        settings: list,
        reconstruction_methods: cfg.nlos.as_ref().map_or(Vec::new(), |p| p.methods.clone()),
        reconstruction_volumes,
        reconstruction_grid: cfg.nlos.as_ref().map(|p| p.grid),
        cross_validated,
    })
}

/// The equal-error speed-up of every denoised row, per region, against the noisy rows'
/// (seconds, RMSE) curve over the same region, and against the independent baseline's.
fn fill_speedups(rows: &mut [ResultRow]) {
    let is_noisy = |m: &str| m == "noisy" || m == BASELINE;
    for region in Region::ALL {
        let curve = |name: &str| -> Vec<(f64, f64)> {
            rows.iter()
                .filter(|r| r.method == name)
                .filter_map(|r| r.error.get(region).map(|m| (r.total_s, m.rmse)))
                .collect()
        };
        let (noisy, baseline) = (curve("noisy"), curve(BASELINE));
        for r in rows.iter_mut().filter(|r| !is_noisy(r.method)) {
            let speedup = |c: &[(f64, f64)]| {
                r.error
                    .get(region)
                    .and_then(|m| speedup_or_bound(c, r.total_s, m.rmse))
            };
            r.speedup[region as usize] = speedup(&noisy);
            r.speedup_independent[region as usize] = speedup(&baseline);
        }
    }
}

/// The equal-error speed-up of every denoised row's reconstructions against the noisy
/// rows' curve of (render + reconstruction seconds, error), the row timed as render +
/// denoise + reconstruction. A method's reconstruction time does not depend on the
/// capture's values, so every row counts the median of its measured times (one slow
/// run would otherwise move a point of the curve).
fn fill_reconstruction_speedups(rows: &mut [ResultRow]) {
    let n = rows.first().map_or(0, |r| r.reconstructions.len());
    for k in 0..n {
        let tr = reconstruction_seconds(rows, k);
        let noisy: Vec<(f64, f64)> = rows
            .iter()
            .filter(|r| r.method == "noisy")
            .map(|r| (r.total_s + tr, r.reconstructions[k].error))
            .collect();
        for r in rows
            .iter_mut()
            .filter(|r| r.method != "noisy" && r.method != BASELINE)
        {
            let e = r.reconstructions[k].error;
            r.reconstruction_speedup[k] = speedup_or_bound(&noisy, r.total_s + tr, e);
        }
    }
}

/// The median over `rows` of reconstruction `k`'s time (0 without rows).
pub fn reconstruction_seconds(rows: &[ResultRow], k: usize) -> f64 {
    let mut times: Vec<f64> = rows.iter().map(|r| r.reconstructions[k].seconds).collect();
    times.sort_by(f64::total_cmp);
    times.get(times.len() / 2).copied().unwrap_or(0.0)
}

/// A cached (H, W) f32 emitter G-buffer: header, size and values checked (fractions in
/// [0, 1]) before use.
fn read_emitter(path: &Path, h: usize, w: usize) -> Result<Array2<f32>, ReportError> {
    use crate::bundle::npy;
    let err = |error| ReportError::Npy {
        path: path.to_path_buf(),
        error,
    };
    let f = npy::open(path).map_err(err)?;
    f.header.expect::<f32>(Some(&[h, w])).map_err(err)?;
    let data = f
        .read::<f32>(
            |s, b| {
                npy::first_bad(
                    s,
                    b,
                    |_, v| (0.0..=1.0).contains(&v),
                    |_, v| format!("is {}, not a fraction", npy::show(v.into())),
                )
            },
            &["y", "x"],
        )
        .map_err(err)?;
    Array2::from_shape_vec((h, w), data).map_err(|e| err(npy::NpyError::Layout(e)))
}

fn write_npy_atomic<A: ndarray_npy::WritableElement, D: ndarray::Dimension>(
    path: &Path,
    a: &ndarray::Array<A, D>,
) -> Result<(), ReportError> {
    crate::bundle::write::write_atomically(path, true, |tmp| {
        ndarray_npy::write_npy(tmp, a).map_err(|e| crate::bundle::BundleError::io(path, e))
    })?;
    Ok(())
}
