//! Rendering: every pixel's paths traced in parallel (rayon over image rows), each
//! path's per-bin totals flushed into the pixel's sums as one sample; a finished row's
//! sums go to a [`sink::RowSink`] (memory, or straight into a bundle on disk).
//!
//! Determinism: a path's random stream is hashed from (seed, pixel, sample index), and
//! a pixel's samples are traced and summed in order by one task, so the result is
//! bit-identical whatever the number of threads.
//!
//! Memory: each running task owns one row's scratch ([`RowScratch`]: the row's planar
//! sums, its pixel's interleaved records, its G-buffer and steady values), reused from
//! row to row; at most one per thread exists. Nothing else grows with the film's height
//! except what the sink keeps.
//!
//! Sub-pixel positions: [`PixelSampling::Stratified`] (the default) spreads a pixel's
//! samples as a randomised low-discrepancy set ([`pixel_sampling`]); `Independent` takes
//! them from the path's stream. Either way the path's stream is the same and its first
//! two numbers are drawn for the position, so everything after the primary ray uses
//! the same random numbers in both modes, and independent renders are unchanged.

pub mod adaptive;
pub mod deposits;
pub mod gbuffer;
pub mod nlos;
pub mod path_common;
pub mod pixel_sampling;
pub mod polarized;
pub mod roulette;
pub mod sampler;
pub mod sink;
pub mod sobol_table;
pub mod tracer;
pub mod vertex;
pub mod volpath;

use crate::math::rng::{mix64, Pcg32};
use crate::scene::Scene;
use crate::sensors::camera::LENS_STREAM_SALT;
use crate::sensors::film::Film;
use crate::stats::accumulators::{Accumulators, PixelSums};
use crate::stats::Transform;
use deposits::PathDeposits;
use gbuffer::{GAccum, GPixel};
use path_common::PathTally;
pub use pixel_sampling::{PixelPattern, PixelSampling};
/// `(B, spp / B)` for `replicates` B >= 2, else `(1, spp)` (see
/// [`RenderSettings::replicate_split`]).
pub fn replicate_split(spp: u32, replicates: u32) -> (u32, u32) {
    if replicates >= 2 {
        (replicates, spp / replicates)
    } else {
        (1, spp)
    }
}

/// Errors of the render settings.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum RenderError {
    #[error("--replicates 1: a variance needs at least 2 replicates (0: none)")]
    OneReplicate,
    #[error("--replicates {replicates} does not divide spp {spp}: replicates need equal sizes")]
    ReplicatesDoNotDivide { replicates: u32, spp: u32 },
}

use rayon::prelude::*;
use sampler::{replicate_key, slot, PathSampler};
use sink::{MemorySink, Row, RowSink};
use sobol_table::{SobolTable, TabledSobol};
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Mutex, PoisonError};

#[derive(Clone, Debug)]
pub struct RenderSettings {
    pub spp: u32,
    pub seed: u64,
    pub transform: Transform,
    /// How primary rays choose their sub-pixel positions.
    pub pixel_sampling: PixelSampling,
    /// Replicates B per pixel (SPEC 4-5): the spp split into B independently
    /// randomised sets of spp / B samples, with `R2 = sum_b m_b^2` accumulated per
    /// voxel; 0: none.
    pub replicates: u32,
    /// Samples of each pixel (row-major, H x W; adaptive sampling, `adaptive.rs`):
    /// pixel `p` traces samples `0..pixel_spp[p]` and its sums hold that many;
    /// `None`: every pixel takes `spp`. Each count is a multiple of the replicates.
    pub pixel_spp: Option<std::sync::Arc<[u32]>>,
}

impl RenderSettings {
    /// The replicates and their size: `(B, spp / B)`, or `(1, spp)` without replicates.
    /// [`RenderSettings::check_replicates`] makes sure B divides spp.
    pub fn replicate_split(&self) -> (u32, u32) {
        replicate_split(self.spp, self.replicates)
    }

    /// The samples of pixel `p` (row-major): its adaptive count, else `spp`.
    #[inline]
    pub fn samples(&self, p: usize) -> u32 {
        self.pixel_spp.as_ref().map_or(self.spp, |n| n[p])
    }

    /// The paths of row `y` of a film `width` pixels wide.
    pub fn row_paths(&self, y: usize, width: usize) -> u64 {
        match &self.pixel_spp {
            Some(n) => n[y * width..(y + 1) * width]
                .iter()
                .map(|&k| u64::from(k))
                .sum(),
            None => width as u64 * u64::from(self.spp),
        }
    }

    /// Whether `replicates` can split `spp`: 0 (none) or at least 2, dividing spp.
    pub fn check_replicates(spp: u32, replicates: u32) -> Result<(), RenderError> {
        if replicates == 1 {
            return Err(RenderError::OneReplicate);
        }
        if replicates >= 2 && !spp.is_multiple_of(replicates) {
            return Err(RenderError::ReplicatesDoNotDivide { replicates, spp });
        }
        Ok(())
    }
}

/// The sub-pixel positions of `pixel`'s samples `0..settings.spp`, in `[0, 1)^2`, in
/// the order the renderer uses them (for tests and tools; `render` computes them the
/// same way).
pub fn pixel_positions(settings: &RenderSettings, pixel: u64) -> Vec<[f32; 2]> {
    let (reps, k) = settings.replicate_split();
    let mut table = SobolTable::default();
    let mut out = Vec::with_capacity(settings.spp as usize);
    for b in 0..reps {
        let positions = PixelPositions::new(settings, pixel, b, k);
        positions.start(&mut table, k, sampler::LD_VERTICES);
        for i in 0..k {
            let rng = Pcg32::for_path(settings.seed, pixel, (b * k + i) as u64);
            out.push(PathNumbers::new(&positions, &mut table, i, rng).1);
        }
    }
    out
}

/// One pixel's position generator.
enum PixelPositions {
    Independent,
    Stratified(PixelPattern),
    /// The replicate's [`SobolTable`] gives the position; the replicate's key.
    Sobol(u64),
}

impl PixelPositions {
    /// The positions of replicate `b` (of `k` samples) of `pixel`; without replicates
    /// `b = 0` and `k = spp`.
    fn new(settings: &RenderSettings, pixel: u64, b: u32, k: u32) -> Self {
        match settings.pixel_sampling {
            PixelSampling::Independent => PixelPositions::Independent,
            PixelSampling::Stratified => {
                // Replicates are randomised independently: each its own pattern.
                let seed = if b == 0 {
                    settings.seed
                } else {
                    mix64(settings.seed ^ mix64(u64::from(b) ^ 0x7265_706c_6963_6174))
                };
                PixelPositions::Stratified(PixelPattern::new(seed, pixel, k))
            }
            PixelSampling::Sobol => PixelPositions::Sobol(replicate_key(settings.seed, pixel, b)),
        }
    }

    /// Readies `table` for the replicate's `k` samples (Sobol' only), whose vertices
    /// `0..=ld_vertices` draw from the set.
    fn start(&self, table: &mut SobolTable, k: u32, ld_vertices: u64) {
        if let PixelPositions::Sobol(key) = self {
            table.reset(*key, k, ld_vertices);
        }
    }
}

/// A path's sampler: how its sub-pixel position and every other number are drawn.
enum PathNumbers<'a> {
    Independent(Pcg32),
    Sobol(TabledSobol<'a>),
}

impl<'a> PathNumbers<'a> {
    /// The sampler of sample `s` of a replicate (`table`: the replicate's, readied by
    /// [`PixelPositions::start`]), and its sub-pixel position. The independent and
    /// stratified modes always draw the position's two numbers from the path's stream,
    /// so the rest of the path sees the same stream in both.
    #[inline]
    fn new(
        positions: &PixelPositions,
        table: &'a mut SobolTable,
        s: u32,
        mut rng: Pcg32,
    ) -> (Self, [f32; 2]) {
        match positions {
            PixelPositions::Sobol(_) => {
                let mut p = TabledSobol::new(table, s, rng);
                let uv = p.get2(slot::PIXEL);
                (PathNumbers::Sobol(p), uv)
            }
            PixelPositions::Independent => {
                let uv = rng.next_2d();
                (PathNumbers::Independent(rng), uv)
            }
            PixelPositions::Stratified(pattern) => {
                rng.next_2d();
                (PathNumbers::Independent(rng), pattern.position(s))
            }
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

/// The counts and timing of a render (whatever sink took its rows).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RenderSummary {
    pub dropped_nonfinite: u64,
    pub rays: u64,
    pub paths: u64,
    /// Samples flushed into voxels: the sum of the non-zero counts (0 when nothing
    /// landed in the time window).
    pub voxel_samples: u64,
    /// Row scratches allocated (at most one per thread).
    pub row_scratches: usize,
    pub seconds: f64,
}

/// One render task's buffers for the row it is rendering, reused from row to row.
struct RowScratch {
    /// The row's sums in the bundle's planar layout (height 1).
    sums: Accumulators,
    /// The sums of the pixel being traced, interleaved per bin.
    pixel: PixelSums,
    gbuffer: Vec<GPixel>,
    steady: Vec<f64>,
    rays: Vec<u64>,
}

impl RowScratch {
    fn new(film: &Film, transform: &Transform, replicates: bool) -> Self {
        let (mut sums, mut pixel) = (
            Accumulators::new(1, film.width, film.time.bins, film.channels, transform),
            PixelSums::new(film.time.bins, film.channels, transform),
        );
        if replicates {
            (sums, pixel) = (sums.with_r2(), pixel.with_replicates());
        }
        RowScratch {
            sums,
            pixel,
            gbuffer: vec![GPixel::default(); film.width],
            steady: vec![0.0; film.width * film.channels],
            rays: vec![0; film.width],
        }
    }

    /// Bytes of one scratch (saturating).
    fn bytes(film: &Film, transform: &Transform) -> u64 {
        let c = film.channels;
        let per_pixel = (std::mem::size_of::<GPixel>() + c * 8 + 8) as u64;
        Accumulators::bytes(1, film.width, film.time.bins, c, transform)
            .saturating_add(PixelSums::bytes(film.time.bins, c, transform))
            .saturating_add((film.width as u64).saturating_mul(per_pixel))
    }
}

/// What rendering a film needs in memory besides the scene, when its rows go to a
/// streaming sink: one row scratch per thread, and the per-pixel images the sink keeps.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StreamingMemory {
    pub threads: usize,
    /// Bytes of one thread's row scratch.
    pub per_row: u64,
    /// Bytes of the (H, W) G-buffers and steady image, held once in the sink and once
    /// more while they are written out.
    pub images: u64,
}

impl StreamingMemory {
    pub fn new(film: &Film, transform: &Transform, threads: usize) -> Self {
        StreamingMemory {
            threads,
            per_row: RowScratch::bytes(film, transform),
            images: sink::PixelImages::bytes(film.height, film.width, film.channels)
                .saturating_mul(2),
        }
    }

    /// The same with replicates (`R2` in every row scratch: a row's `R2` and the
    /// pixel's replicate sums).
    pub fn with_replicates(mut self, replicates: bool, film: &Film) -> Self {
        if replicates {
            // The pixel's replicate records: 5 f64 a bin, and its R2 (C a bin).
            let extra = Accumulators::r2_bytes(1, film.width, film.time.bins, film.channels)
                .saturating_add(
                    (film.time.bins as u64).saturating_mul((5 + film.channels as u64) * 8),
                );
            self.per_row = self.per_row.saturating_add(extra);
        }
        self
    }

    /// The same with adaptive sampling's per-pixel images: the pilot's measure (16
    /// bytes a pixel) and the counts (4 bytes a pixel, held twice while written).
    pub fn with_adaptive(mut self, adaptive: bool, film: &Film) -> Self {
        if adaptive {
            self.images = self
                .images
                .saturating_add((film.pixels() as u64).saturating_mul(24));
        }
        self
    }

    /// The same with the Sobol' sampler's table in every task (`sobol_table.rs`): at
    /// most every slot of every low-discrepancy vertex for the replicate's samples.
    pub fn with_sampler(
        mut self,
        sampling: PixelSampling,
        spp: u32,
        replicates: u32,
        volumetric: bool,
    ) -> Self {
        if sampling == PixelSampling::Sobol {
            let (_, k) = replicate_split(spp, replicates);
            let ld = sampler::ld_vertices(volumetric);
            self.per_row = self.per_row.saturating_add(SobolTable::max_bytes(k, ld));
        }
        self
    }

    /// The total (saturating).
    pub fn bytes(&self) -> u64 {
        (self.threads as u64)
            .saturating_mul(self.per_row)
            .saturating_add(self.images)
    }
}

/// Counts of one row.
#[derive(Default)]
struct RowTally {
    dropped: u64,
    rays: u64,
    voxel_samples: u64,
}

/// Renders row `y` into `row`, compiled for the instruction set `cpu` chose (the
/// sampler, the camera and the sums, around the tracer's own dispatch; the same bits at
/// every level).
fn render_row(
    scene: &Scene,
    settings: &RenderSettings,
    y: usize,
    row: &mut RowScratch,
    z: &(impl Fn(f64) -> f64 + Sync),
) -> RowTally {
    match crate::cpu::detected().avx2() {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: the proof says this CPU runs the wrapper's instruction set.
        Some(isa) => unsafe { render_row_avx2(isa, scene, settings, y, row, z) },
        _ => render_row_body(scene, settings, y, row, z),
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
fn render_row_avx2(
    _isa: crate::cpu::Avx2,
    scene: &Scene,
    settings: &RenderSettings,
    y: usize,
    row: &mut RowScratch,
    z: &(impl Fn(f64) -> f64 + Sync),
) -> RowTally {
    render_row_body(scene, settings, y, row, z)
}

#[inline(always)]
fn render_row_body(
    scene: &Scene,
    settings: &RenderSettings,
    y: usize,
    row: &mut RowScratch,
    z: &(impl Fn(f64) -> f64 + Sync),
) -> RowTally {
    let width = scene.film.width;
    let z0 = settings.transform.at_zero();
    let mut deposits = PathDeposits::default();
    // The Sobol' sampler's columns of the replicate being traced (`sobol_table.rs`).
    let mut table = SobolTable::default();
    let mut result = RowTally::default();
    // NLOS captures: the laser point and sensor row of this film row.
    let nlos = scene.nlos.as_ref().zip(scene.integrator.nlos.as_ref());
    let (laser, sensor_row) = nlos.map_or((0, y), |(s, _)| nlos::ends::film_row(s, y));
    for x in 0..width {
        let ends = nlos.map_or_else(Default::default, |(s, n)| {
            nlos::ends::path_ends(s, n.capture, x, sensor_row, laser)
        });
        let pixel = (y * width + x) as u64;
        let mut g = GAccum::default();
        let mut tally = PathTally::default();
        let spp = settings.samples(pixel as usize);
        let (reps, k) = replicate_split(spp, settings.replicates);
        // Volumetric paths keep more low-discrepancy vertices (see `sampler.rs`).
        let ld_vertices = sampler::ld_vertices(scene.integrator.volumetric);
        for b in 0..reps {
            let positions = PixelPositions::new(settings, pixel, b, k);
            positions.start(&mut table, k, ld_vertices);
            for i in 0..k {
                let s = b * k + i;
                let rng = Pcg32::for_path(settings.seed, pixel, s as u64);
                let (mut numbers, [u, v]) = PathNumbers::new(&positions, &mut table, i, rng);
                let (o, d) = scene.camera.ray(x as f32 + u, y as f32 + v, || {
                    Pcg32::for_path(settings.seed ^ LENS_STREAM_SALT, pixel, s as u64).next_2d()
                });
                let gs = match &mut numbers {
                    PathNumbers::Sobol(p) => trace(scene, o, d, ends, p, &mut deposits, &mut tally),
                    PathNumbers::Independent(p) => {
                        trace(scene, o, d, ends, p, &mut deposits, &mut tally)
                    }
                };
                g.add(&gs);
                result.voxel_samples += deposits.len() as u64;
                for (bin, c) in deposits.drain() {
                    row.pixel.add_sample(z, bin as usize, c);
                }
            }
            row.pixel.end_replicate(k, z0);
        }
        row.pixel.flush_into(&mut row.sums, x);
        let channels = scene.film.channels;
        for c in 0..channels {
            row.steady[x * channels + c] = tally.steady[c] / f64::from(spp);
        }
        row.gbuffer[x] = g.finish();
        result.dropped += tally.dropped_nonfinite;
        result.rays += tally.rays;
        row.rays[x] = tally.rays;
    }
    result
}

/// Traces one camera path with the tracer the scene needs: the path loop of
/// `tracer.rs` (surfaces, and media when the scene has them) or the NLOS tracer.
/// `ends` are the NLOS tracer's known surfaces.
#[inline]
fn trace<S: PathSampler>(
    scene: &Scene,
    o: glam::Vec3,
    d: glam::Vec3,
    ends: nlos::ends::PathEnds,
    sampler: &mut S,
    deposits: &mut PathDeposits,
    tally: &mut PathTally,
) -> gbuffer::GSample {
    if scene.integrator.nlos.is_some() {
        nlos::trace_nlos(scene, o, d, ends, sampler, deposits, tally)
    } else {
        tracer::trace(scene, o, d, sampler, deposits, tally)
    }
}

/// Renders `scene` with the statistics of `settings`, handing every finished row to
/// `sink`. `progress` is called with the number of paths finished, from worker threads.
/// Runs on the current rayon pool. The first sink error stops the render and is returned.
pub fn render_into<S: RowSink>(
    scene: &Scene,
    settings: &RenderSettings,
    sink: &S,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<RenderSummary, S::Error> {
    let start = std::time::Instant::now();
    let film = &scene.film;
    let driver = Driver {
        scene,
        settings,
        sink,
        progress,
        counts: Default::default(),
        allocated: AtomicUsize::new(0),
        idle: Mutex::new(Vec::new()),
    };
    // Monomorphised per transform: the identity costs nothing per sample.
    let t = settings.transform;
    match t {
        Transform::Identity => driver.run(|x| x),
        _ => driver.run(move |x| t.apply(x)),
    }?;
    let [dropped, rays, voxel_samples] = driver.counts.map(AtomicU64::into_inner);
    Ok(RenderSummary {
        dropped_nonfinite: dropped,
        rays,
        paths: (0..film.height)
            .map(|y| settings.row_paths(y, film.width))
            .sum(),
        voxel_samples,
        row_scratches: driver.allocated.into_inner(),
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// The state the row tasks of one render share.
struct Driver<'a, S> {
    scene: &'a Scene,
    settings: &'a RenderSettings,
    sink: &'a S,
    progress: &'a (dyn Fn(u64) + Sync),
    /// Dropped contributions, rays, voxel samples.
    counts: [AtomicU64; 3],
    allocated: AtomicUsize,
    /// Idle row scratches: a task takes one (or makes one when none is idle) and puts it
    /// back when its row is in the sink, so at most one per thread ever exists.
    idle: Mutex<Vec<RowScratch>>,
}

impl<S: RowSink> Driver<'_, S> {
    fn run<Z: Fn(f64) -> f64 + Sync>(&self, z: Z) -> Result<(), S::Error> {
        let (h, w) = (self.scene.film.height, self.scene.film.width);
        if self.settings.pixel_spp.is_none() {
            return (0..h).into_par_iter().try_for_each(|y| self.row(y, &z));
        }
        // Adaptive counts make some rows far costlier: the costliest start first, one
        // row per task, so no thread is left with a heavy row at the end. Each row's
        // sums depend on its own samples alone: the order changes no bits.
        let mut rows: Vec<usize> = (0..h).collect();
        rows.sort_by_key(|&y| std::cmp::Reverse(self.settings.row_paths(y, w)));
        rows.into_par_iter()
            .with_max_len(1)
            .try_for_each(|y| self.row(y, &z))
    }

    fn row(&self, y: usize, z: &(impl Fn(f64) -> f64 + Sync)) -> Result<(), S::Error> {
        let taken = self
            .idle
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .pop();
        let mut row = taken.unwrap_or_else(|| {
            self.allocated.fetch_add(1, Ordering::Relaxed);
            RowScratch::new(
                &self.scene.film,
                &self.settings.transform,
                self.settings.replicates >= 2,
            )
        });
        let tally = render_row(self.scene, self.settings, y, &mut row, z);
        self.sink.put_row(&Row {
            y,
            sums: &row.sums,
            gbuffer: &row.gbuffer,
            steady: &row.steady,
            rays: &row.rays,
        })?;
        let values = [tally.dropped, tally.rays, tally.voxel_samples];
        for (count, v) in self.counts.iter().zip(values) {
            count.fetch_add(v, Ordering::Relaxed);
        }
        self.idle
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .push(row);
        (self.progress)(self.settings.row_paths(y, self.scene.film.width));
        Ok(())
    }
}

/// Renders `scene` with the statistics of `settings` into memory. `progress` is called
/// with the number of paths finished, from worker threads. Runs on the current rayon
/// pool.
pub fn render(
    scene: &Scene,
    settings: &RenderSettings,
    progress: &(dyn Fn(u64) + Sync),
) -> RenderOutput {
    let film = &scene.film;
    let mut sink = MemorySink::new(
        film.height,
        film.width,
        film.time.bins,
        film.channels,
        &settings.transform,
    );
    if settings.replicates >= 2 {
        sink = sink.with_r2();
    }
    let summary = match render_into(scene, settings, &sink, progress) {
        Ok(s) => s,
        Err(never) => match never {},
    };
    let (accum, images) = sink.into_parts();
    RenderOutput {
        accum,
        gbuffer: images.gbuffer,
        steady: images.steady,
        dropped_nonfinite: summary.dropped_nonfinite,
        rays: summary.rays,
        paths: summary.paths,
        seconds: summary.seconds,
    }
}
