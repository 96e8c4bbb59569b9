//! `tstat view`: one self-contained HTML page (no server, no network) to look at a
//! bundle's volume: the image at a time bin with a time slider and a play button,
//! exposure and log scale, noisy / denoised / reference / error side by side, and for a
//! clicked pixel its transient L(t) per channel with the confidence band
//! `mean +- t_{0.975, dof} sqrt(V)` from the statistics, the membership map of the
//! filter's per-voxel test around it, and its G-buffers.
//!
//! The page's data are the volumes as f16 (scaled by a power of two so that the
//! largest value fits) in base64 inside a JSON block; `view.html` holds the page and
//! its script. When the volumes exceed the byte budget they are averaged over k x k
//! pixel blocks (the smallest k that fits; V of a block mean is the sum of the pixels'
//! V over k^4), and the page says so.

use crate::bundle::float_rows::FloatRows;
use crate::bundle::npy::NpyError;
use crate::bundle::{Bundle, BundleError, RowSums};
use crate::denoise::critical::student_t_quantile;
use crate::stats::estimators::{estimate, estimate_replicates, Sums};
use base64::Engine;
use ndarray::{Array3, Array4};
use serde_json::json;
use std::path::PathBuf;

/// The page, with `/*DATA*/` where the JSON data go.
const PAGE: &str = include_str!("view.html");

/// The filter's per-voxel test shown around a clicked pixel.
#[derive(Clone, Copy, Debug)]
pub struct MembershipShown {
    pub radius: usize,
    pub t2_max: f64,
    pub depth_align: bool,
}

/// Where a volume beside the bundle's own noisy mean comes from: an (H, W, T, C)
/// `.npy` of f32 or f64 (shape checked by the caller), or another bundle's noisy mean.
pub enum Source {
    Npy { path: PathBuf, rows: FloatRows },
    Bundle(Box<Bundle>),
}

/// A volume beside the bundle's own noisy mean, read a row at a time.
pub struct Extra {
    pub label: String,
    pub source: Source,
}

/// Why the page cannot be built.
#[derive(Debug, thiserror::Error)]
pub enum ViewError {
    #[error(transparent)]
    Bundle(#[from] BundleError),
    #[error("{label} {}: {error}", .path.display())]
    Volume {
        label: String,
        path: PathBuf,
        error: Box<NpyError>,
    },
}

/// What the page was built from, for the command's summary line.
pub struct PageSummary {
    pub bytes: usize,
    pub block: usize,
    pub band: bool,
}

/// The pixel block size k (k x k pixels averaged) that keeps `volumes` f16 volumes of
/// the film (h, w, t) of `c` channels within `budget` bytes: the smallest that fits,
/// or None when even one block over the whole film does not (the time axis alone is
/// too long).
pub fn block_size(
    volumes: usize,
    h: usize,
    w: usize,
    t: usize,
    c: usize,
    budget: u64,
) -> Option<usize> {
    let bytes_at = |k: usize| page_data_bytes(volumes, h, w, t, c, k);
    let mut k = 1;
    while bytes_at(k) > budget && (h.div_ceil(k) > 1 || w.div_ceil(k) > 1) {
        k += 1;
    }
    (bytes_at(k) <= budget).then_some(k)
}

/// The f16 volumes' bytes at block size `k` (`c` channels).
pub fn page_data_bytes(volumes: usize, h: usize, w: usize, t: usize, c: usize, k: usize) -> u64 {
    (volumes * h.div_ceil(k) * w.div_ceil(k) * t * c * 2) as u64
}

/// The most memory [`build_page`] takes for a film (h, w, t) of `c` channels with
/// `volumes` volumes at block size `k`, and rows of `row_bytes` read at once (the bundle's sums and the
/// extras' one image row): the block accumulators (f64) of one row of blocks, the
/// block-averaged volumes (f32), their f16 bytes, base64 and the page text (about
/// five times the f16 bytes in all), and the G-buffers (8 f32 per pixel, read whole,
/// and their block averages).
pub fn page_memory(
    volumes: usize,
    (h, w, t, c): (usize, usize, usize, usize),
    k: usize,
    row_bytes: u64,
) -> u64 {
    let data = page_data_bytes(volumes, h, w, t, c, k);
    let acc = (volumes * w.div_ceil(k) * t * c * 8) as u64;
    let gbuffers = (h * w * 8 * 4) as u64 + (h.div_ceil(k) * w.div_ceil(k) * 8 * 4) as u64;
    row_bytes + acc + 2 * data + 5 * data + gbuffers
}

/// Bytes of one image row that [`build_page`] reads from a bundle at once: the counts
/// and every sum array.
pub fn bundle_row_bytes(b: &Bundle) -> u64 {
    let m = &b.manifest;
    let voxels = (m.width * m.bins) as u64;
    let sums = 3 + u64::from(!m.transform.is_identity()) + u64::from(m.replicates.is_some());
    voxels * 4 + voxels * m.channel_count() as u64 * 8 * sums
}

/// One row of a bundle read as its noisy mean S / n and, for identity-transform
/// bundles, the standard deviation of the mean sqrt(V) (from the replicates when the
/// bundle has them), each (W, T, C).
#[derive(Default)]
struct MeanRows {
    sums: RowSums,
}

impl MeanRows {
    fn read(
        &mut self,
        b: &Bundle,
        y: usize,
        mean: &mut Vec<f32>,
        sd: Option<&mut Vec<f32>>,
    ) -> Result<(), BundleError> {
        let m = &b.manifest;
        b.row_reader()?.read(y..y + 1, &mut self.sums)?;
        let rows = &self.sums;
        let identity = m.transform.is_identity();
        let ch = m.channel_count();
        let per_pixel = m.bins * ch;
        let n = |i: usize| b.samples(y * m.width + i / per_pixel);
        let radiance = if identity { &rows.x1 } else { &rows.sum };
        mean.clear();
        mean.extend(
            radiance
                .iter()
                .enumerate()
                .map(|(i, &s)| (s / n(i) as f64) as f32),
        );
        if let Some(sd) = sd {
            let z0 = m.transform.at_zero();
            sd.clear();
            sd.extend((0..radiance.len()).map(|i| {
                let nz = rows.nonzero[i / ch];
                let e = match m.replicates {
                    Some(bb) => estimate_replicates(rows.x1[i], rows.r2[i], nz, n(i), bb, z0),
                    None => estimate(
                        Sums {
                            x1: rows.x1[i],
                            x2: rows.x2[i],
                            x3: rows.x3[i],
                        },
                        nz,
                        n(i),
                        z0,
                    ),
                };
                e.v.sqrt() as f32
            }));
        }
        Ok(())
    }
}

/// Per shown pixel (a k x k block of the film, row-major), Student's t 0.975 quantile
/// at the fewest samples `n` of the block's pixels, `n - 1` degrees of freedom (4
/// decimals, as the page shows them).
fn block_quantiles(counts: &[u32], h: usize, w: usize, k: usize) -> Vec<f64> {
    let (ph, pw) = (h.div_ceil(k), w.div_ceil(k));
    let mut fewest = vec![u32::MAX; ph * pw];
    for (p, &n) in counts.iter().enumerate() {
        let b = (p / w / k) * pw + (p % w) / k;
        fewest[b] = fewest[b].min(n);
    }
    let mut known = std::collections::HashMap::new();
    fewest
        .iter()
        .map(|&n| {
            *known.entry(n).or_insert_with(|| {
                let t = student_t_quantile(0.975, f64::from(n) - 1.0);
                (t * 1e4).round() / 1e4
            })
        })
        .collect()
}

/// Block averages of a volume (H, W, T, C) built row by row: k x k pixel blocks (the
/// last ones may be smaller). For standard deviations of pixel means (`sd`), the
/// block mean's is sqrt(sum sd^2) / count.
struct BlockRows {
    k: usize,
    w: usize,
    /// Values per pixel (T C).
    tc: usize,
    /// C.
    channels: usize,
    sd: bool,
    /// The current row of blocks: f64 sums, (W / k, T, C).
    acc: Vec<f64>,
    /// Image rows added to the current row of blocks.
    rows: usize,
    /// The finished block rows, (H / k, W / k, T, C).
    out: Vec<f32>,
}

impl BlockRows {
    /// Blocks of an image (h, w) of `t` x `c` values per pixel.
    fn new(h: usize, w: usize, (t, c): (usize, usize), k: usize, sd: bool) -> BlockRows {
        let tc = t * c;
        BlockRows {
            k,
            w,
            tc,
            channels: c,
            sd,
            acc: vec![0.0; w.div_ceil(k) * tc],
            rows: 0,
            out: Vec::with_capacity(h.div_ceil(k) * w.div_ceil(k) * tc),
        }
    }

    /// Adds the next image row (W, T, C); the last row of an image closes its blocks
    /// with `last`.
    fn add(&mut self, row: &[f32], last: bool) {
        let (k, tc) = (self.k, self.tc);
        debug_assert_eq!(row.len(), self.w * tc);
        for (x, px) in row.chunks_exact(tc).enumerate() {
            let acc = &mut self.acc[(x / k) * tc..(x / k + 1) * tc];
            for (a, &v) in acc.iter_mut().zip(px) {
                let v = v as f64;
                *a += if self.sd { v * v } else { v };
            }
        }
        self.rows += 1;
        if self.rows == k || last {
            for (bx, block) in self.acc.chunks_exact_mut(tc).enumerate() {
                let cols = ((bx + 1) * k).min(self.w) - bx * k;
                let count = (self.rows * cols) as f64;
                self.out.extend(block.iter().map(|&a| {
                    if self.sd {
                        (a.sqrt() / count) as f32
                    } else {
                        (a / count) as f32
                    }
                }));
                block.fill(0.0);
            }
            self.rows = 0;
        }
    }

    fn finish(self, h: usize, t: usize) -> Array4<f32> {
        let shape = (
            h.div_ceil(self.k),
            self.w.div_ceil(self.k),
            t,
            self.channels,
        );
        Array4::from_shape_vec(shape, self.out).expect("every row of blocks closed")
    }
}

/// Averages k x k pixel blocks of a whole volume (the reference for [`BlockRows`]).
#[cfg(test)]
fn block_average(v: &Array4<f32>, k: usize, sd: bool) -> Array4<f32> {
    let (h, w, t, c) = v.dim();
    let (bh, bw) = (h.div_ceil(k), w.div_ceil(k));
    let mut out = Array4::<f32>::zeros((bh, bw, t, c));
    for by in 0..bh {
        for bx in 0..bw {
            let ys = by * k..((by + 1) * k).min(h);
            let xs = bx * k..((bx + 1) * k).min(w);
            let count = (ys.len() * xs.len()) as f64;
            for tt in 0..t {
                for cc in 0..c {
                    let mut acc = 0.0f64;
                    for y in ys.clone() {
                        for x in xs.clone() {
                            let a = v[[y, x, tt, cc]] as f64;
                            acc += if sd { a * a } else { a };
                        }
                    }
                    out[[by, bx, tt, cc]] = if sd {
                        (acc.sqrt() / count) as f32
                    } else {
                        (acc / count) as f32
                    };
                }
            }
        }
    }
    out
}

/// Averages k x k pixel blocks of an (H, W, C) image.
fn block_average_image(v: &Array3<f32>, k: usize) -> Array3<f32> {
    let (h, w, c) = v.dim();
    if k == 1 {
        return v.clone();
    }
    let mut blocks = BlockRows::new(h, w, (1, c), k, false);
    let flat = v.as_standard_layout();
    let flat = flat.as_slice().expect("standard layout");
    for (y, row) in flat.chunks_exact(w * c).enumerate() {
        blocks.add(row, y + 1 == h);
    }
    Array3::from_shape_vec((h.div_ceil(k), w.div_ceil(k), c), blocks.out).expect("blocks")
}

/// f16 base64 of `v` in (T, H, W, C) order (a frame contiguous) divided by a power of
/// two `scale` chosen so that the largest |value| is at most 32768; returns both.
fn encode_frames(v: &Array4<f32>) -> (String, f64) {
    let max = v.iter().fold(
        0.0f32,
        |a, &x| if x.is_finite() { a.max(x.abs()) } else { a },
    );
    let scale = if max > 0.0 {
        2f64.powi((max as f64 / 32768.0).log2().ceil() as i32)
    } else {
        1.0
    };
    let (h, w, t, c) = v.dim();
    let mut bytes = Vec::with_capacity(h * w * t * c * 2);
    for tt in 0..t {
        for y in 0..h {
            for x in 0..w {
                for cc in 0..c {
                    let x = (v[[y, x, tt, cc]] as f64 / scale) as f32;
                    bytes.extend(half::f16::from_f32(x).to_le_bytes());
                }
            }
        }
    }
    (
        base64::engine::general_purpose::STANDARD.encode(bytes),
        scale,
    )
}

fn encode_f32(v: impl Iterator<Item = f32>) -> String {
    let bytes: Vec<u8> = v.flat_map(f32::to_le_bytes).collect();
    base64::engine::general_purpose::STANDARD.encode(bytes)
}

/// Builds the page for `bundle` with `extras` (each (H, W, T, C) like the bundle, as
/// the caller checked) at pixel block size `k` (see [`block_size`]), reading every
/// volume a row at a time: the full-resolution volumes are never held.
pub fn build_page(
    bundle: &Bundle,
    name: &str,
    extras: &mut [Extra],
    shown: MembershipShown,
    k: usize,
) -> Result<(String, PageSummary), ViewError> {
    let m = &bundle.manifest;
    let (h, w, t, ch) = (m.height, m.width, m.bins, m.channel_count());
    let with_sd = m.transform.is_identity();
    let mut means = MeanRows::default();
    let mut blocks: Vec<BlockRows> = Vec::new();
    blocks.push(BlockRows::new(h, w, (t, ch), k, false));
    if with_sd {
        blocks.push(BlockRows::new(h, w, (t, ch), k, true));
    }
    let mut extra_means: Vec<MeanRows> = Vec::new();
    for _ in extras.iter() {
        blocks.push(BlockRows::new(h, w, (t, ch), k, false));
        extra_means.push(MeanRows::default());
    }
    let (mut mean, mut sd, mut row) = (Vec::new(), Vec::new(), Vec::new());
    for y in 0..h {
        let last = y + 1 == h;
        means.read(bundle, y, &mut mean, with_sd.then_some(&mut sd))?;
        blocks[0].add(&mean, last);
        if with_sd {
            blocks[1].add(&sd, last);
        }
        let first_extra = 1 + usize::from(with_sd);
        for (i, (e, reader)) in extras.iter_mut().zip(&mut extra_means).enumerate() {
            match &mut e.source {
                Source::Npy { path, rows } => {
                    rows.read_rows(y..y + 1, &mut row, &["y", "x", "t", "c"])
                        .map_err(|error| ViewError::Volume {
                            label: e.label.clone(),
                            path: path.clone(),
                            error: Box::new(error),
                        })?;
                }
                Source::Bundle(b) => reader.read(b, y, &mut row, None)?,
            }
            blocks[first_extra + i].add(&row, last);
        }
    }
    drop((mean, sd, row));
    let mut blocks = blocks.into_iter().map(|b| b.finish(h, t));
    let mut vols = Vec::new();
    let mut push = |label: &str, kind: &str, v: Array4<f32>| {
        let (data, scale) = encode_frames(&v);
        vols.push(json!({"label": label, "kind": kind, "data": data, "scale": scale}));
    };
    push("noisy", "mean", blocks.next().expect("the noisy mean"));
    if with_sd {
        push("noisy sd of the mean", "sd", blocks.next().expect("its sd"));
    }
    for e in extras.iter() {
        let label = e.label.trim_start_matches('-');
        push(label, "mean", blocks.next().expect("one per extra"));
    }
    let (ph, pw) = (h.div_ceil(k), w.div_ceil(k));
    let albedo = block_average_image(&bundle.albedo()?, k);
    let normal = block_average_image(&bundle.normal()?, k);
    let flat2 = |a: ndarray::Array2<f32>| {
        let (hh, ww) = a.dim();
        block_average_image(&a.into_shape_with_order((hh, ww, 1)).unwrap(), k)
    };
    let depth = flat2(bundle.depth()?);
    let emitter = flat2(bundle.emitter()?);
    // The band's quantile: Student's t at the statistics' degrees of freedom. An
    // adaptive render without replicates has a count per pixel: each shown pixel (a
    // block of k x k) gets the quantile of its fewest samples (`t_quantiles`), and
    // `dof` is the smallest.
    let dof = match m.replicates {
        Some(b) => b - 1,
        None => bundle.min_samples() - 1,
    };
    let tq = student_t_quantile(0.975, dof as f64);
    let t_quantiles = match (&bundle.pixel_spp, m.replicates) {
        (Some(counts), None) => Some(block_quantiles(counts, h, w, k)),
        _ => None,
    };
    let correlated = m.replicates.is_none()
        && m.pixel_sampling != crate::bundle::manifest::SamplingRecord::Independent;
    let data = json!({
        "name": name,
        "height": ph, "width": pw, "bins": t, "block": k,
        "channels": ch, "mode": m.mode.name(), "channel_names": m.mode.channel_names(),
        "full_height": h, "full_width": w,
        "spp": m.spp, "replicates": m.replicates, "sampling": m.pixel_sampling.name(),
        "transform": m.transform.to_string(),
        "start_opl": m.start_opl, "bin_width_opl": m.bin_width_opl,
        "time_zero": m.time_zero(),
        "start_ps": m.start_seconds * 1e12, "bin_ps": m.bin_width_seconds * 1e12,
        "t_quantile": tq, "dof": dof, "correlated": correlated,
        "t_quantiles": t_quantiles,
        "membership": {"radius": shown.radius, "t2_max": shown.t2_max, "depth_align": shown.depth_align},
        "volumes": vols,
        "albedo": encode_f32(albedo.iter().copied()),
        "normal": encode_f32(normal.iter().copied()),
        "depth": encode_f32(depth.iter().copied()),
        "emitter": encode_f32(emitter.iter().copied()),
    });
    // No `<` inside the script block (`</script>` or `<!--` would end or change it):
    // JSON may write it as \u003c in strings, and it occurs nowhere else.
    let text = serde_json::to_string(&data)
        .expect("page data serialise")
        .replace('<', "\\u003c");
    let page = PAGE.replacen("/*DATA*/", &text, 1);
    let summary = PageSummary {
        bytes: page.len(),
        block: k,
        band: with_sd,
    };
    Ok((page, summary))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn block_averages_of_means_and_of_standard_deviations() {
        let mut v = Array4::<f32>::zeros((3, 3, 1, 1));
        for (i, x) in v.iter_mut().enumerate() {
            *x = i as f32;
        }
        let m = block_average(&v, 2, false);
        assert_eq!(m.dim(), (2, 2, 1, 1));
        assert_eq!(m[[0, 0, 0, 0]], (0.0 + 1.0 + 3.0 + 4.0) / 4.0);
        assert_eq!(m[[1, 1, 0, 0]], 8.0);
        assert_eq!(m[[0, 1, 0, 0]], (2.0 + 5.0) / 2.0);
        // sd of the mean of 4 independent values of sd 2: 2 / sqrt(4) = 1.
        let s = block_average(&Array4::from_elem((2, 2, 1, 1), 2.0f32), 2, true);
        assert!((s[[0, 0, 0, 0]] - 1.0).abs() < 1e-6);
    }

    #[test]
    fn blocks_built_row_by_row_equal_the_whole_volume_average() {
        let (h, w, t) = (7, 5, 2);
        for ch in [1, 3, 4] {
            let v = Array4::from_shape_fn((h, w, t, ch), |(y, x, tt, c)| {
                ((y * 31 + x * 7 + tt * 3 + c) % 11) as f32 * 0.25 - 1.0
            });
            for k in [1, 2, 3, 5, 7, 9] {
                for sd in [false, true] {
                    let mut b = BlockRows::new(h, w, (t, ch), k, sd);
                    let flat = v.as_slice().unwrap();
                    for (y, row) in flat.chunks_exact(w * t * ch).enumerate() {
                        b.add(row, y + 1 == h);
                    }
                    let got = b.finish(h, t);
                    let want = block_average(&v, k, sd);
                    assert_eq!(got.dim(), want.dim(), "k {k}");
                    for (a, b) in got.iter().zip(want.iter()) {
                        assert!(
                            (a - b).abs() <= 1e-6 * b.abs().max(1.0),
                            "k {k} sd {sd}: {a} vs {b}"
                        );
                    }
                }
            }
        }
        // Images (H, W, C) through the same blocks.
        let img = Array3::from_shape_fn((h, w, 3), |(y, x, c)| (y * w + x + c) as f32);
        let got = block_average_image(&img, 3);
        let v4 = img.clone().into_shape_with_order((h, w, 1, 3)).unwrap();
        let want = block_average(&v4, 3, false);
        assert_eq!(got.as_slice().unwrap(), want.as_slice().unwrap());
    }

    #[test]
    fn block_size_is_the_smallest_that_fits_or_none() {
        // 2 volumes of 8 x 8 px x 4 bins x 3 channels, 2 bytes each: 3072 bytes at
        // k = 1, 768 at k = 2, 48 at k = 8.
        assert_eq!(block_size(2, 8, 8, 4, 3, 3072), Some(1));
        assert_eq!(block_size(2, 8, 8, 4, 3, 3071), Some(2));
        assert_eq!(block_size(2, 8, 8, 4, 3, 767), Some(3));
        assert_eq!(block_size(2, 8, 8, 4, 3, 48), Some(8));
        assert_eq!(block_size(2, 8, 8, 4, 3, 47), None);
        // One channel (mono): a third of the bytes; four (Stokes): a third more.
        assert_eq!(block_size(2, 8, 8, 4, 1, 1024), Some(1));
        assert_eq!(block_size(2, 8, 8, 4, 4, 3072), Some(2));
        for c in [1, 3, 4] {
            for budget in [47u64, 48, 100, 400, 767, 768, 3071, 3072, 5000] {
                if let Some(k) = block_size(2, 8, 8, 4, c, budget) {
                    assert!(page_data_bytes(2, 8, 8, 4, c, k) <= budget);
                    assert!(k == 1 || page_data_bytes(2, 8, 8, 4, c, k - 1) > budget);
                }
            }
        }
    }

    #[test]
    fn f16_frames_keep_the_values_to_half_precision() {
        let v = Array4::from_shape_fn((2, 3, 4, 3), |(y, x, t, c)| {
            (1e5 * (y + 1) as f32) * 10f32.powi(-(x as i32 + t as i32 + c as i32))
        });
        let (b64, scale) = encode_frames(&v);
        let bytes = base64::engine::general_purpose::STANDARD
            .decode(b64)
            .unwrap();
        assert!(scale >= 1.0 && v.iter().all(|&x| x as f64 / scale <= 32768.0));
        let (h, w, t, c) = v.dim();
        for tt in 0..t {
            for y in 0..h {
                for x in 0..w {
                    for cc in 0..c {
                        let i = (((tt * h + y) * w + x) * c + cc) * 2;
                        let f = half::f16::from_le_bytes([bytes[i], bytes[i + 1]]).to_f32() as f64
                            * scale;
                        let want = v[[y, x, tt, cc]] as f64;
                        assert!(
                            (f - want).abs() <= 1e-3 * want + 1e-7 * scale,
                            "{f} vs {want}"
                        );
                    }
                }
            }
        }
    }
}
