//! `tstat run [SCENE.xml] --out DIR`: the whole job in one command. Renders with
//! statistics (adaptive sampling unless `--no-adaptive`: `cli::adaptive`), denoises, and
//! writes the noisy and denoised volumes, side-by-side frames
//! (noisy | denoised, one exposure), an animated GIF and a streak image. Without a
//! scene it renders the bundled Cornell box.

use super::adaptive::AdaptiveArgs;
use super::denoise::FilterArgs;
use super::frames::axis_of;
use super::progress::Bars;
use super::render::SceneArgs;
use super::util::{arg, check_outputs, int_flag, seed, threads, with_threads, Kind};
use crate::bundle::write::write_atomically;
use crate::bundle::{Bundle, BundleError};
use crate::denoise::denoise_bundle;
use crate::job::{AdaptiveRequest, RenderJob};
use crate::scene::Scene;
use crate::stats::Transform;
use crate::viz::frames::{side_by_side, write_all, FramesRequest};
use crate::viz::tonemap::global_exposure;
use clap::Args;
use std::path::PathBuf;

/// The bundled Cornell box, compiled in so `tstat run` works from anywhere.
const CBOX_XML: &str = include_str!("../../scenes/cbox.xml");

#[derive(Args, Debug)]
pub struct RunArgs {
    /// Mitsuba 3 XML scene (default: the bundled Cornell box).
    pub scene: Option<PathBuf>,
    /// Output directory.
    #[arg(long)]
    pub out: PathBuf,
    /// Samples per pixel (overrides the sampler's sample_count; at least 2).
    #[arg(long, allow_negative_numbers = true)]
    pub spp: Option<i64>,
    #[command(flatten)]
    pub scene_args: SceneArgs,
    /// Uniform sampling: every pixel gets --spp samples (by default each pixel gets
    /// samples where they lower the volume's error most, --spp on average; see
    /// `tstat render --adaptive`).
    #[arg(long)]
    pub no_adaptive: bool,
    #[command(flatten)]
    pub adaptive_args: AdaptiveArgs,
    /// Random seed.
    #[arg(long, allow_negative_numbers = true)]
    pub seed: Option<i128>,
    /// Sample transform: identity, box-cox:LAMBDA or yeo-johnson:LAMBDA.
    #[arg(long, default_value = "identity")]
    pub transform: String,
    #[command(flatten)]
    pub filter: FilterArgs,
    /// Write every K-th bin as a frame.
    #[arg(long, default_value_t = 1, allow_negative_numbers = true)]
    pub every: i64,
    /// Worker threads (default: all cores).
    #[arg(long, allow_negative_numbers = true)]
    pub threads: Option<i64>,
    /// Replace an existing output directory.
    #[arg(long)]
    pub force: bool,
}

pub fn run(a: RunArgs) -> anyhow::Result<()> {
    let every = int_flag("--every", a.every, 1, i64::MAX)? as usize;
    let threads = threads(a.threads)?;
    let seed = seed(a.seed)?;
    let transform = a.scene_args.transform(&a.transform)?;
    let params = a.filter.params()?;
    let overrides = a.scene_args.overrides(a.spp)?;
    let inputs: Vec<_> = a.scene.iter().map(|p| arg("scene", p)).collect();
    check_outputs(&inputs, &[(arg("--out", &a.out), Kind::Dir)], a.force)?;
    if a.no_adaptive {
        a.adaptive_args.refuse_when_off("with --no-adaptive")?;
    }
    let adaptive = a.adaptive_args.request(false)?;
    let started = std::time::Instant::now();
    let opts = Opts {
        every,
        threads,
        seed,
        adaptive,
        started,
    };
    // Everything goes to a temporary directory that is renamed when complete. The job's
    // own error is returned as it is (not prefixed with the output directory).
    write_atomically(&a.out, a.force, |tmp| -> anyhow::Result<()> {
        let io = |e: std::io::Error| BundleError::io(tmp, e);
        std::fs::create_dir(tmp).map_err(io)?;
        let scene_path = match &a.scene {
            Some(p) => p.clone(),
            None => {
                let p = tmp.join("cbox.xml");
                std::fs::write(&p, CBOX_XML).map_err(io)?;
                p
            }
        };
        job(&a, &opts, &scene_path, tmp, transform, &params, &overrides)
    })?;
    let o = a.out.display();
    say!("done in {:.1} s. In {o}/:", started.elapsed().as_secs_f64());
    say!("  scene.tstats/     statistics bundle (tstat info {o}/scene.tstats)");
    say!("  noisy.npy         noisy mean volume, f32 (H, W, T, C)");
    say!("  denoised.npy      denoised volume, f32 (H, W, T, C)");
    say!("  frames/           PNG frames, noisy | denoised, one exposure for all bins");
    say!("  propagation.gif   the light propagating, noisy | denoised");
    say!("  streak.png        streak image (x against time) of the middle row, noisy | denoised");
    Ok(())
}

/// The checked numeric options.
struct Opts {
    every: usize,
    threads: Option<usize>,
    seed: Option<u64>,
    adaptive: AdaptiveRequest,
    started: std::time::Instant,
}

fn job(
    a: &RunArgs,
    o: &Opts,
    scene_path: &std::path::Path,
    dir: &std::path::Path,
    transform: Transform,
    params: &crate::denoise::DenoiseParams,
    overrides: &crate::scene::Overrides,
) -> anyhow::Result<()> {
    let scene = Scene::load(scene_path, overrides)?;
    let params = &crate::denoise::DenoiseParams {
        base: a.filter.base.kind(!scene.media.is_empty()),
        ..*params
    };
    super::util::check_mesh_inputs(&scene, &[arg("--out", &a.out)])?;
    super::util::print_scene_warnings(&scene);
    let film = &scene.film;
    // Beside the bundle: the noisy and the denoised f32 volumes (the frames are small).
    let volume = (film.pixels() as u64)
        .saturating_mul(film.time.bins as u64)
        .saturating_mul(film.channels as u64 * 4)
        .saturating_add(4096);
    let bundle_path = dir.join("scene.tstats");
    let render_job = RenderJob {
        // The bundled scene sits in the temporary directory until that is renamed: the
        // manifest records where it will be.
        scene_record: Some(scene_record(a)),
        seed: o.seed,
        transform,
        pixel_sampling: a.scene_args.pixel_sampling,
        replicates: a.scene_args.replicates,
        threads: o.threads,
        adaptive: (!a.no_adaptive).then_some(o.adaptive),
        spp_given: a.spp.is_some(),
        extra_disk: volume.saturating_mul(2),
        started: o.started,
        ..RenderJob::new(&bundle_path)
    };
    let report = crate::job::render(scene, &render_job, &Bars::new(false))?;
    eprintln!(
        "rendered in {:.2} s ({:.2} M paths/s)",
        report.summary.seconds,
        report.summary.paths as f64 / report.summary.seconds / 1e6
    );
    let bundle = Bundle::open(&bundle_path)?;
    let noisy = bundle.noisy_mean()?;
    let mut params = *params;
    a.filter.adapt(&mut params, &bundle.manifest);
    a.filter.check_bundle(&bundle.manifest)?;
    let den = with_threads(o.threads, || denoise_bundle(&bundle, &params, &|_| {}))??;
    eprintln!("denoised in {:.2} s", den.seconds);
    super::export::write_volume_npy(&dir.join("noisy.npy"), noisy.view())?;
    super::export::write_volume_npy(&dir.join("denoised.npy"), den.volume.view())?;
    let both = side_by_side(noisy.view(), den.volume.view(), 2);
    let req = FramesRequest {
        every: o.every,
        gif: true,
        streak_row: noisy.shape()[0] / 2,
        exposure: global_exposure(den.volume.view()),
        axis: Some(axis_of(&bundle)),
        caption: format!(
            "row {}: noisy (columns 0-{}) | denoised (columns {}-{})",
            noisy.shape()[0] / 2,
            noisy.shape()[1] - 1,
            noisy.shape()[1] + 2,
            2 * noisy.shape()[1] + 1
        ),
    };
    write_all(dir, both.view(), &req)?;
    Ok(())
}

/// The scene's path as the user will find it: the given scene, or the bundled Cornell
/// box at `DIR/cbox.xml` (not the temporary directory it is first written to).
fn scene_record(a: &RunArgs) -> PathBuf {
    match &a.scene {
        Some(p) => p.clone(),
        None => a.out.join("cbox.xml"),
    }
}
