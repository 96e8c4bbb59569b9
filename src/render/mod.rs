//! Rendering: every pixel's paths traced in parallel (rayon over image rows), each
//! path's per-bin totals flushed into the statistics accumulators as one sample.
//!
//! Determinism: a path's random stream is hashed from (seed, pixel, sample index), and
//! a pixel's samples are traced and summed in order by one task, so the result is
//! bit-identical whatever the number of threads.
//!
//! Sub-pixel positions: [`PixelSampling::Stratified`] (the default) spreads a pixel's
//! samples as a randomised low-discrepancy set ([`pixel_sampling`]); `Independent` takes
//! them from the path's stream. Either way the path's stream is the same and its first
//! two numbers are drawn for the position, so everything after the primary ray uses
//! the same random numbers in both modes, and independent renders are unchanged.

pub mod cpu;
pub mod deposits;
pub mod gbuffer;
pub mod integrator;
pub mod pixel_sampling;

use crate::math::rng::Pcg32;
use crate::scene::Scene;
use crate::stats::accumulators::{Accumulators, RowAccum};
use crate::stats::Transform;
use deposits::PathDeposits;
use gbuffer::{GAccum, GPixel};
use integrator::{trace_path, PathTally};
pub use pixel_sampling::{PixelPattern, PixelSampling};
use rayon::prelude::*;

#[derive(Clone, Debug)]
pub struct RenderSettings {
    pub spp: u32,
    pub seed: u64,
    pub transform: Transform,
    /// How primary rays choose their sub-pixel positions.
    pub pixel_sampling: PixelSampling,
}

/// The sub-pixel positions of `pixel`'s samples `0..settings.spp`, in `[0, 1)^2`, in
/// the order the renderer uses them (for tests and tools; `render` computes them the
/// same way).
pub fn pixel_positions(settings: &RenderSettings, pixel: u64) -> Vec<[f32; 2]> {
    let pattern = PixelPositions::new(settings, pixel);
    (0..settings.spp)
        .map(|s| {
            let mut rng = Pcg32::for_path(settings.seed, pixel, s as u64);
            pattern.position(s, &mut rng)
        })
        .collect()
}

/// One pixel's position generator.
enum PixelPositions {
    Independent,
    Stratified(PixelPattern),
}

impl PixelPositions {
    fn new(settings: &RenderSettings, pixel: u64) -> Self {
        match settings.pixel_sampling {
            PixelSampling::Independent => PixelPositions::Independent,
            PixelSampling::Stratified => {
                PixelPositions::Stratified(PixelPattern::new(settings.seed, pixel, settings.spp))
            }
        }
    }

    /// The position of sample `s`. Always draws two numbers from the path's `rng`, so
    /// the rest of the path sees the same stream in both modes.
    #[inline]
    fn position(&self, s: u32, rng: &mut Pcg32) -> [f32; 2] {
        let jitter = rng.next_2d();
        match self {
            PixelPositions::Independent => jitter,
            PixelPositions::Stratified(p) => p.position(s),
        }
    }
}

/// Everything a render produces, in memory.
pub struct RenderOutput {
    pub accum: Accumulators,
    /// Per pixel, row-major (H, W).
    pub gbuffer: Vec<GPixel>,
    /// Steady-state mean radiance, (H, W, 3).
    pub steady: Vec<f64>,
    pub dropped_nonfinite: u64,
    pub rays: u64,
    pub paths: u64,
    pub seconds: f64,
}

struct RowResult {
    steady: Vec<f64>,
    gbuffer: Vec<GPixel>,
    dropped: u64,
    rays: u64,
}

fn render_row(
    scene: &Scene,
    settings: &RenderSettings,
    y: usize,
    row: &mut RowAccum,
    z: &(impl Fn(f64) -> f64 + Sync),
) -> RowResult {
    let width = scene.film.width;
    let n = settings.spp as f64;
    let mut deposits = PathDeposits::default();
    let mut result = RowResult {
        steady: vec![0.0; width * 3],
        gbuffer: Vec::with_capacity(width),
        dropped: 0,
        rays: 0,
    };
    for x in 0..width {
        let pixel = (y * width + x) as u64;
        let mut g = GAccum::default();
        let mut tally = PathTally::default();
        let positions = PixelPositions::new(settings, pixel);
        for s in 0..settings.spp {
            let mut rng = Pcg32::for_path(settings.seed, pixel, s as u64);
            let [u, v] = positions.position(s, &mut rng);
            let d = scene.camera.direction(x as f32 + u, y as f32 + v);
            g.add(&trace_path(scene, d, &mut rng, &mut deposits, &mut tally));
            for (bin, c) in deposits.drain() {
                row.add_sample(z, x, bin as usize, c);
            }
        }
        for c in 0..3 {
            result.steady[x * 3 + c] = tally.steady[c] / n;
        }
        result.gbuffer.push(g.finish());
        result.dropped += tally.dropped_nonfinite;
        result.rays += tally.rays;
    }
    result
}

/// Renders `scene` with the statistics of `settings`. `progress` is called with the
/// number of paths finished, from worker threads. Runs on the current rayon pool.
pub fn render(
    scene: &Scene,
    settings: &RenderSettings,
    progress: &(dyn Fn(u64) + Sync),
) -> RenderOutput {
    let start = std::time::Instant::now();
    let film = &scene.film;
    let mut accum = Accumulators::new(film.height, film.width, film.bins, &settings.transform);
    let per_row = film.width as u64 * settings.spp as u64;
    let rows = accum.rows_mut();
    // Monomorphised per transform: the identity costs nothing per sample.
    fn run<Z: Fn(f64) -> f64 + Sync>(
        rows: Vec<RowAccum>,
        scene: &Scene,
        settings: &RenderSettings,
        progress: &(dyn Fn(u64) + Sync),
        per_row: u64,
        z: Z,
    ) -> Vec<RowResult> {
        rows.into_par_iter()
            .enumerate()
            .map(|(y, mut row)| {
                let r = render_row(scene, settings, y, &mut row, &z);
                progress(per_row);
                r
            })
            .collect()
    }
    let t = settings.transform;
    let results = match t {
        Transform::Identity => run(rows, scene, settings, progress, per_row, |x| x),
        _ => run(rows, scene, settings, progress, per_row, move |x| {
            t.apply(x)
        }),
    };
    let mut out = RenderOutput {
        gbuffer: Vec::with_capacity(film.pixels()),
        steady: Vec::with_capacity(film.pixels() * 3),
        dropped_nonfinite: 0,
        rays: 0,
        paths: per_row * film.height as u64,
        seconds: 0.0,
        accum: Accumulators::new(0, 0, 0, &Transform::Identity),
    };
    for r in results {
        out.steady.extend_from_slice(&r.steady);
        out.gbuffer.extend_from_slice(&r.gbuffer);
        out.dropped_nonfinite += r.dropped;
        out.rays += r.rays;
    }
    out.accum = accum;
    out.seconds = start.elapsed().as_secs_f64();
    out
}
