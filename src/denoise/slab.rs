//! Denoising a bundle larger than memory: the image is filtered in slabs, bands of
//! whole rows [y0, y1), and only what a slab needs is ever held.
//!
//! The filter reaches `halo` rows up and down ([`FilterParams::reach`]: r, or tstat's
//! emitter radius r_e when a pixel sees a light); nothing else crosses rows (depth
//! alignment and the patch test move along one neighbour's bins; spp, g^2, the time
//! weights and the G-buffers are global and small). So a slab needs the estimates of
//! rows [y0 - halo, y1 + halo) and the G-buffers of the whole image (32 bytes a pixel).
//! The estimates are a sliding window: before each slab the rows above
//! `y0 - halo` are dropped and the new rows below are made from the bundle's sums,
//! read `chunk` rows at a time ([`RowReader`], with every value check of a whole read)
//! and freed at once. Each row's sums are read twice: a first pass finds the
//! volume's largest magnitudes, which fix the power of two the f32 estimates are
//! stored in (see `estimates.rs`); the filtered slab goes to a sink (a `.npy` file
//! on disk, at the rows' offset, or a volume in memory).
//!
//! Each voxel's estimate depends only on its own sums, and the filter accumulates
//! each output voxel in the same neighbour order whatever the tiling, so the result
//! is the whole-volume denoiser's, bit for bit, for every slab height and thread count.
//!
//! Memory ([`SlabPlan::bytes`]), with `V = W x T x C` values per image row (C the
//! film's channels: 3 for RGB, 1 mono, 4 Stokes) and `S`
//! rows per slab (`held = min(S + 2 halo, H)` rows of estimates):
//!
//! | what | bytes |
//! |------|-------|
//! | G-buffers (albedo, normal, depth, emitter) | `32 H W` |
//! | estimates (mean, theta, V; f32) | `12 V held` |
//! | active bin ranges | `16 W held` |
//! | filtered slab (f32, planar) | `4 V S` |
//! | one output row in file order (f32) | `4 V` |
//! | sums of `chunk` rows (f64 X1, X2, X3 and S if stored; u32 counts) | `chunk (8 V arrays + 4 W T)` |
//! | read buffer (f64) | `8 min(chunk V, 98304)` |
//!
//! Per worker thread the filter adds a few bins of scratch and one neighbour list
//! (at most `(2 r_e + 1)^2` entries of 24 bytes), not counted.

use super::estimates::{Estimates, Magnitudes, Scale, SumsView};
use super::filter::{filter_rows, Tiling};
use super::gbuffers::GBuffers;
use super::DenoiseParams;
use crate::bundle::npy::BLOCK_ELEMS;
use crate::bundle::read::RowSums;
use crate::bundle::{Bundle, BundleError, Manifest};
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// The default memory budget of `tstat denoise` (`--max-memory`): 1 GB. Slabs cost
/// no measurable time (see docs/commands.md), so the default is small.
pub const DEFAULT_BUDGET: u64 = 1_000_000_000;

/// Target bytes of one sum array's chunk: reads of a few MB run at disk speed.
const CHUNK_BYTES: u64 = 16 << 20;

/// The sizes that fix a plan's memory.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Dims {
    pub height: usize,
    pub width: usize,
    pub bins: usize,
    /// C: channels per voxel.
    pub channels: usize,
    /// f64 sum arrays read: X1, X2, X3, and S when the transform is not the identity.
    pub sum_arrays: usize,
}

impl Dims {
    pub fn of(m: &Manifest) -> Dims {
        Dims {
            height: m.height,
            width: m.width,
            bins: m.bins,
            channels: m.channel_count(),
            sum_arrays: if m.transform.is_identity() { 3 } else { 4 },
        }
    }

    /// Values per image row of a volume: W x T x C.
    fn row_values(&self) -> u128 {
        self.width as u128 * self.bins as u128 * self.channels as u128
    }

    /// Bytes of one image row of all the sums and counts.
    fn sums_row_bytes(&self) -> u128 {
        self.row_values() * 8 * self.sum_arrays as u128 + self.width as u128 * self.bins as u128 * 4
    }
}

/// How the image is cut into slabs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SlabPlan {
    /// Output rows per slab (the last slab may be shorter).
    pub rows: usize,
    /// Rows of estimates held above and below a slab (the filter's reach).
    pub halo: usize,
    /// Rows of sums read at once.
    pub chunk: usize,
}

impl SlabPlan {
    /// The tallest slabs whose footprint ([`SlabPlan::bytes`]) fits `budget`, and at
    /// least one row (check [`SlabPlan::bytes`] against the budget to refuse).
    pub fn for_budget(d: Dims, halo: usize, budget: u64) -> SlabPlan {
        let h = d.height.max(1);
        // Sums are read in chunks of at most CHUNK_BYTES per array and an eighth of
        // the budget in all (at least one row), and never more than a slab's rows.
        let chunk = (CHUNK_BYTES as u128 / (d.row_values() * 8).max(1))
            .min(budget as u128 / 8 / d.sums_row_bytes().max(1))
            .max(1);
        let plan = |rows: usize| SlabPlan {
            rows,
            halo,
            chunk: chunk.min(rows as u128) as usize,
        };
        let fits = |rows: usize| plan(rows).bytes(d) <= budget;
        if fits(h) {
            return plan(h);
        }
        // The footprint grows with the slab height: the largest that fits.
        let (mut lo, mut hi) = (1, h);
        while hi - lo > 1 {
            let mid = lo + (hi - lo) / 2;
            if fits(mid) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        plan(lo)
    }

    /// Bytes held at the peak (the table in the module docs), saturating.
    pub fn bytes(&self, d: Dims) -> u64 {
        let v = d.row_values();
        let held = (self.rows + 2 * self.halo).min(d.height) as u128;
        let b = 32 * d.height as u128 * d.width as u128
            + 12 * v * held
            + 16 * d.width as u128 * held
            + 4 * v * self.rows as u128
            + 4 * v
            + self.chunk as u128 * d.sums_row_bytes()
            + 8 * (self.chunk as u128 * v).min(BLOCK_ELEMS as u128);
        u64::try_from(b).unwrap_or(u64::MAX)
    }

    /// The number of slabs.
    pub fn slabs(&self, d: Dims) -> usize {
        d.height.div_ceil(self.rows.max(1))
    }
}

/// The filter's halo for a bundle: [`super::filter::FilterParams::reach`] with its
/// sampling and emitter G-buffer.
pub fn halo(bundle: &Bundle, params: &DenoiseParams) -> Result<usize, BundleError> {
    let m = &bundle.manifest;
    let emitter = bundle.emitter()?;
    Ok(params
        .filter_params(m.replicates.unwrap_or(m.spp))
        .reach(stratified(m), super::std_slice(&emitter)))
}

/// Whether the bundle's V over-estimates the variance of the mean: correlated
/// (stratified or Sobol') samples without replicates.
pub fn stratified(m: &Manifest) -> bool {
    m.pixel_sampling != crate::bundle::manifest::SamplingRecord::Independent
        && m.replicates.is_none()
}

/// Rows per independent image of a bundle: an exhaustive NLOS capture's sensor
/// images (one per laser point, stacked), else the whole film.
pub fn image_rows(m: &Manifest) -> usize {
    match &m.nlos {
        Some(n) if n.laser_grid[0] * n.laser_grid[1] > 1 => n.sensor_grid[1],
        _ => m.height,
    }
}

/// Whether the bundle is an exhaustive NLOS scan (one sensor image per laser point,
/// stacked; see [`image_rows`]).
pub fn exhaustive(m: &Manifest) -> bool {
    image_rows(m) < m.height
}

/// The sums of the rows read, as the estimates take them.
fn sums_view<'a>(m: &Manifest, s: &'a RowSums, pixel_spp: Option<&'a [u32]>) -> SumsView<'a> {
    SumsView {
        height: s.rows.len(),
        width: m.width,
        bins: m.bins,
        channels: m.channel_count(),
        bin_width: m.bin_width_opl,
        spp: m.spp,
        stratified: stratified(m),
        image_rows: image_rows(m),
        z0: m.transform.at_zero(),
        x1: &s.x1,
        x2: &s.x2,
        x3: &s.x3,
        sum: if m.transform.is_identity() {
            &s.x1
        } else {
            &s.sum
        },
        nonzero: &s.nonzero,
        replicates: m.replicates.map(|b| (b, &s.r2[..])),
        pixel_spp: pixel_spp.map(|n| &n[s.rows.start * m.width..s.rows.end * m.width]),
    }
}

/// What a slabbed run did.
#[derive(Clone, Copy, Debug)]
pub struct SlabStats {
    /// Voxel-neighbour evaluations performed.
    pub evaluations: u64,
    /// Wall seconds in all (reading and writing included).
    pub seconds: f64,
    /// Wall seconds of the filter alone.
    pub filter_seconds: f64,
    pub slabs: usize,
}

/// Receives each filtered slab: `sink(y0, planar)`, see [`denoise_slabs`].
pub type SlabSink<'a> = dyn FnMut(usize, &[f32]) -> Result<(), BundleError> + 'a;

/// Denoises `bundle` slab by slab (see the module docs) and hands each filtered slab
/// to `sink(y0, planar)`: rows `y0..y0 + planar.len() / (W T C)`, planar
/// (rows, W, C, T). Errors in the bundle's values end the run with the message of a
/// whole read (file and voxel), whichever slab finds them.
pub fn denoise_slabs(
    bundle: &Bundle,
    params: &DenoiseParams,
    plan: &SlabPlan,
    sink: &mut SlabSink,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<SlabStats, BundleError> {
    let start = std::time::Instant::now();
    let m = &bundle.manifest;
    let h = m.height;
    let rows = plan.rows.max(1);
    let gbuffers = GBuffers::read(bundle)?;
    let features = gbuffers.features();
    let fp = params.filter_params(m.replicates.unwrap_or(m.spp));
    let halo = fp.reach(stratified(m), features.emitter);
    assert!(
        plan.halo >= halo,
        "a plan with a halo of {} rows for a filter that reaches {halo}",
        plan.halo
    );
    let reader = bundle.row_reader()?;
    let counts = bundle.pixel_spp.as_deref();
    let mut sums = RowSums::default();
    // A first pass over the sums fixes the estimates' scale from the whole volume,
    // so that it does not depend on the slabs.
    let mut magnitudes = Magnitudes::default();
    for y in (0..h).step_by(plan.chunk.max(1)) {
        reader.read(y..(y + plan.chunk.max(1)).min(h), &mut sums)?;
        magnitudes = magnitudes.max(Magnitudes::scan(&sums_view(m, &sums, counts)));
    }
    let mut est = Estimates::empty(h, &sums_view(m, &sums, counts), Scale::of(magnitudes));
    est.pixel_spp = counts.map(Into::into);
    est.variance = params.variance;
    est.reserve_rows((rows + 2 * halo).min(h));
    let mut out = vec![0.0f32; rows.min(h) * est.row_len()];
    // Enough bands for every thread: the output does not depend on the tiling.
    let threads = rayon::current_num_threads().max(1);
    let tiling = Tiling {
        rows: params.tiling.rows.min(rows.div_ceil(4 * threads)).max(1),
        ..params.tiling
    };
    let (mut evaluations, mut filter_seconds, mut slabs) = (0u64, 0.0f64, 0usize);
    for y0 in (0..h).step_by(rows) {
        let y1 = (y0 + rows).min(h);
        let need = y0.saturating_sub(halo)..(y1 + halo).min(h);
        est.drop_rows_before(need.start);
        while est.rows.end < need.end {
            let next = est.rows.end..(est.rows.end + plan.chunk.max(1)).min(need.end);
            // The first pass's last chunk is still held when it is the one needed
            // (a volume read in one chunk is then read once).
            if sums.rows != next {
                reader.read(next, &mut sums)?;
            }
            est.push_rows(&sums_view(m, &sums, counts));
        }
        let slab = &mut out[..(y1 - y0) * est.row_len()];
        let f0 = std::time::Instant::now();
        evaluations += filter_rows(&est, &features, &fp, tiling, y0..y1, slab, progress);
        filter_seconds += f0.elapsed().as_secs_f64();
        sink(y0, slab)?;
        slabs += 1;
    }
    Ok(SlabStats {
        evaluations,
        seconds: start.elapsed().as_secs_f64(),
        filter_seconds,
        slabs,
    })
}

/// A denoised volume, f32 (H, W, T, C) `.npy` ((H, W, T, 3, 4) for C = 12, a
/// spectral Stokes volume, as `tstat export` writes it), written row by row at the rows'
/// offsets into a file created at its full size (the same bytes `write_npy` gives).
pub struct NpyVolumeWriter {
    file: std::fs::File,
    /// The name errors give (the final output, not the temporary file written).
    shown: PathBuf,
    data_offset: u64,
    width: usize,
    bins: usize,
    channels: usize,
    row: Vec<u8>,
}

impl NpyVolumeWriter {
    /// Creates `path` (header, then zeros: sparse where the file system allows) for a
    /// volume (height, width, bins, channels).
    pub fn create(
        path: &Path,
        shown: &Path,
        (height, width, bins, channels): (usize, usize, usize, usize),
    ) -> Result<NpyVolumeWriter, BundleError> {
        use std::io::Seek;
        let mut file = std::fs::File::create(path).map_err(|e| BundleError::io(shown, e))?;
        // A spectral Stokes volume is (H, W, T, 3, 4), RGB x Stokes: the same bytes.
        if channels == 12 {
            ndarray_npy::write_zeroed_npy::<f32, _>(&file, (height, width, bins, 3, 4))
        } else {
            ndarray_npy::write_zeroed_npy::<f32, _>(&file, (height, width, bins, channels))
        }
        .map_err(|e| BundleError::io(shown, e))?;
        let data_offset = file
            .stream_position()
            .map_err(|e| BundleError::io(shown, e))?;
        Ok(NpyVolumeWriter {
            file,
            shown: shown.to_path_buf(),
            data_offset,
            width,
            bins,
            channels,
            row: vec![0u8; width * bins * channels * 4],
        })
    }

    /// Writes rows from `y0` on, given planar (rows, W, C, T).
    pub fn write_rows(&mut self, y0: usize, planar: &[f32]) -> Result<(), BundleError> {
        use std::os::unix::fs::FileExt;
        let (w, t, ch) = (self.width, self.bins, self.channels);
        let per_pixel = ch * t;
        for (r, row) in planar.chunks_exact(w * per_pixel).enumerate() {
            self.row
                .par_chunks_mut(per_pixel * 4)
                .zip(row.par_chunks(per_pixel))
                .for_each(|(bytes, px)| {
                    for k in 0..t {
                        for c in 0..ch {
                            let o = (k * ch + c) * 4;
                            bytes[o..o + 4].copy_from_slice(&px[c * t + k].to_le_bytes());
                        }
                    }
                });
            let at = self.data_offset + ((y0 + r) * self.row.len()) as u64;
            self.file
                .write_all_at(&self.row, at)
                .map_err(|e| BundleError::io(&self.shown, e))?;
        }
        Ok(())
    }
}

/// Denoises `bundle` into the `.npy` file `path` (errors name `shown`).
pub fn denoise_bundle_to_npy(
    bundle: &Bundle,
    params: &DenoiseParams,
    plan: &SlabPlan,
    path: &Path,
    shown: &Path,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<SlabStats, BundleError> {
    let m = &bundle.manifest;
    let size = (m.height, m.width, m.bins, m.channel_count());
    let mut writer = NpyVolumeWriter::create(path, shown, size)?;
    denoise_slabs(
        bundle,
        params,
        plan,
        &mut |y0, planar| writer.write_rows(y0, planar),
        progress,
    )
}
