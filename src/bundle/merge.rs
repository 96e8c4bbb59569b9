//! Merging bundles rendered separately (other machines, other seeds, the shards of one
//! job) into one: the sums and counts add exactly; the G-buffers and the steady image,
//! which are means, are averaged weighted by spp (normals renormalised). Only bundles of
//! the same scene file and settings with different seeds merge: equal seeds would
//! repeat the same paths. Shards of a job must all be there (`shard.rs`). Bundles of
//! different pixel sampling modes merge too (every sample of either mode is marginally
//! uniform over its pixel, so the sum stays unbiased); the result records the common
//! mode, or "mixed" when they differ.
//!
//! Streamed: the volume arrays are summed a band of image rows at a time, each input's
//! files opened for the band and closed after it, so memory is two bands (the sum and
//! one input's rows, sized by [`MergeOptions::memory`]) plus the per-pixel images,
//! whatever the number of inputs, and at most one input's files are open at once. The
//! inputs are summed in a canonical order (by their smallest seed), so the same set of
//! bundles merges to the same bits whatever order the command line gives them in.

use super::manifest::Manifest;
use super::shard::merge_records;
use super::write::{npy, write_atomically, VolumeArrays};
use super::{Bundle, BundleError, Problem, RowSums};
use ndarray::{Array2, Array3};
use std::path::{Path, PathBuf};

fn same_settings(a: &Manifest, b: &Manifest) -> Result<(), Problem> {
    let checks: [(&str, bool); 16] = [
        ("channels", a.channels == b.channels),
        ("mode", a.mode == b.mode),
        ("scene (SHA-256)", a.scene.sha256 == b.scene.sha256),
        ("width", a.width == b.width),
        ("height", a.height == b.height),
        ("bins", a.bins == b.bins),
        ("start_opl", a.start_opl == b.start_opl),
        ("bin_width_opl", a.bin_width_opl == b.bin_width_opl),
        ("transform", a.transform == b.transform),
        ("time_origin", a.time_origin == b.time_origin),
        ("near_clip", a.near_clip == b.near_clip),
        ("max_depth", a.max_depth == b.max_depth),
        ("unit_m", a.unit_m == b.unit_m),
        ("media", a.media == b.media),
        (
            "temporal filter",
            a.time_filter_stddev_bins == b.time_filter_stddev_bins,
        ),
        ("NLOS capture", a.nlos == b.nlos),
    ];
    if let Some((what, _)) = checks.iter().find(|c| !c.1) {
        return Err(Problem::SettingDiffers(what));
    }
    // Replicates add up only with equal sizes (SPEC 5): R2 and B sum.
    let size = |m: &Manifest| m.replicates.map(|b| m.spp / b);
    if size(a) != size(b) {
        return Err(Problem::ReplicateSizes {
            it: size(b),
            first: size(a),
        });
    }
    // What the scene read and the -D values (bundles from before this was recorded
    // compare by the scene file alone).
    if let (Some(x), Some(y)) = (&a.scene.identity, &b.scene.identity) {
        let dx: std::collections::BTreeMap<_, _> = x.defaults.iter().cloned().collect();
        let dy: std::collections::BTreeMap<_, _> = y.defaults.iter().cloned().collect();
        if let Some(k) = dx
            .keys()
            .chain(dy.keys())
            .find(|k| dx.get(*k) != dy.get(*k))
        {
            return Err(Problem::Define {
                key: k.clone(),
                it: dy.get(k).cloned(),
                first: dx.get(k).cloned(),
            });
        }
        if x.inputs != y.inputs {
            let fx: std::collections::BTreeMap<_, _> = x.inputs.iter().cloned().collect();
            let fy: std::collections::BTreeMap<_, _> = y.inputs.iter().cloned().collect();
            let name = fx
                .keys()
                .chain(fy.keys())
                .find(|k| fx.get(*k) != fy.get(*k))
                .cloned()
                .unwrap_or_default();
            return Err(Problem::SceneInput(name));
        }
    }
    Ok(())
}

/// The seeds of the renders summed in `m`.
fn seeds(m: &Manifest) -> &[u64] {
    if m.merged_seeds.is_empty() {
        std::slice::from_ref(&m.seed)
    } else {
        &m.merged_seeds
    }
}

/// How to merge.
#[derive(Clone, Copy, Debug)]
pub struct MergeOptions {
    /// Replace an existing output.
    pub force: bool,
    /// Allow a job's shards to be incomplete (a partial merge, e.g. one level of a
    /// tree of merges); repeated shards are refused all the same.
    pub partial: bool,
    /// Bytes for the two bands of rows in memory (at least one row is used).
    pub memory: u64,
}

impl Default for MergeOptions {
    fn default() -> Self {
        MergeOptions {
            force: false,
            partial: false,
            memory: 256 << 20,
        }
    }
}

/// Bytes one image row takes in the band buffers (the sum and one input's rows).
pub fn row_bytes(m: &Manifest) -> u64 {
    let volumes = 3 + u64::from(!m.transform.is_identity()) + u64::from(m.replicates.is_some());
    let voxels = (m.width * m.bins) as u64;
    2 * voxels * (volumes * m.channel_count() as u64 * 8 + 4)
}

/// Adds `b` into `a` (same arrays), refusing counts that would leave the u32 range.
fn add_band(a: &mut RowSums, b: &RowSums, m: &Manifest, dir: &Path) -> Result<(), BundleError> {
    let add = |x: &mut Vec<f64>, y: &Vec<f64>| {
        if x.is_empty() {
            x.clone_from(y);
        } else {
            x.iter_mut().zip(y).for_each(|(p, q)| *p += q);
        }
    };
    add(&mut a.x1, &b.x1);
    add(&mut a.x2, &b.x2);
    add(&mut a.x3, &b.x3);
    add(&mut a.sum, &b.sum);
    add(&mut a.r2, &b.r2);
    if a.nonzero.is_empty() {
        a.nonzero.clone_from(&b.nonzero);
    } else if let Some(i) =
        a.nonzero
            .iter_mut()
            .zip(&b.nonzero)
            .position(|(p, q)| match p.checked_add(*q) {
                Some(v) => {
                    *p = v;
                    false
                }
                None => true,
            })
    {
        let plane = m.width * m.bins;
        let (y, x, k) = (b.rows.start + i / plane, i % plane / m.bins, i % m.bins);
        return Err(BundleError::invalid(
            dir.join("nonzero.npy"),
            Problem::CountOverflow { y, x, t: k },
        ));
    }
    a.rows = b.rows.clone();
    Ok(())
}

/// Merges `inputs` (at least two) into a new bundle at `out`; returns its manifest.
pub fn merge_bundles(
    inputs: &[PathBuf],
    out: &Path,
    opts: MergeOptions,
) -> Result<Manifest, BundleError> {
    if inputs.len() < 2 {
        return Err(BundleError::TooFewToMerge(out.to_path_buf()));
    }
    let mut bundles: Vec<Bundle> = inputs
        .iter()
        .map(|p| Bundle::open(p))
        .collect::<Result<_, _>>()?;
    for b in &bundles {
        same_settings(&bundles[0].manifest, &b.manifest)
            .map_err(|e| BundleError::invalid(b.dir.clone(), e))?;
    }
    // Shards before seeds: a repeated shard is named as such.
    let records: Vec<_> = bundles.iter().map(|b| b.manifest.shard.as_ref()).collect();
    // An error names the input that repeats a shard or disagrees on the job's size;
    // shards missing are the job's (no input is wrong).
    let shard = merge_records(&records, opts.partial).map_err(|e| match e.input {
        Some(i) => BundleError::invalid(bundles[i].dir.clone(), Problem::Shards(e.error)),
        None => BundleError::Shard(e.error),
    })?;
    // Linear in the seeds: a hash set of those seen.
    let total_seeds: usize = bundles.iter().map(|b| seeds(&b.manifest).len()).sum();
    let mut all_seeds: Vec<u64> = Vec::with_capacity(total_seeds);
    let mut seen = std::collections::HashSet::with_capacity(total_seeds);
    for b in &bundles {
        for &s in seeds(&b.manifest) {
            if !seen.insert(s) {
                return Err(BundleError::invalid(b.dir.clone(), Problem::SeedTwice(s)));
            }
            all_seeds.push(s);
        }
    }
    drop(seen);
    // The canonical order: seeds are unique across the inputs.
    bundles.sort_by_cached_key(|b| seeds(&b.manifest).iter().min().copied());
    let first = bundles[0].manifest.clone();
    let (h, w, t) = (first.height, first.width, first.bins);
    let total_spp = bundles
        .iter()
        .try_fold(0u64, |a, b| a.checked_add(b.manifest.spp))
        .ok_or_else(|| BundleError::invalid(bundles[0].dir.clone(), Problem::SppOverflow))?;
    // Per-pixel images: small (H W), summed whole.
    let mut steady = Array3::<f64>::zeros((h, w, first.channel_count()));
    let mut albedo = Array3::<f64>::zeros((h, w, 3));
    let mut normal = Array3::<f64>::zeros((h, w, 3));
    let mut depth = Array2::<f64>::zeros((h, w));
    let mut emitter = Array2::<f64>::zeros((h, w));
    let mut medium = first.media.then(|| Array2::<f64>::zeros((h, w)));
    // Adaptive inputs: each pixel's samples add, and its images are weighted by them.
    let adaptive = bundles.iter().any(|b| b.pixel_spp.is_some());
    let pixel_spp: Option<Array2<u64>> = adaptive.then(|| {
        Array2::from_shape_fn((h, w), |(y, x)| {
            bundles.iter().map(|b| b.samples(y * w + x)).sum::<u64>()
        })
    });
    for b in &bundles {
        match &pixel_spp {
            None => {
                let wgt = b.manifest.spp as f64 / total_spp as f64;
                steady.scaled_add(wgt, &b.steady()?);
                albedo.scaled_add(wgt, &b.albedo()?.mapv(f64::from));
                normal.scaled_add(wgt, &b.normal()?.mapv(f64::from));
                depth.scaled_add(wgt, &b.depth()?.mapv(f64::from));
                emitter.scaled_add(wgt, &b.emitter()?.mapv(f64::from));
                if let (Some(m), Some(bm)) = (medium.as_mut(), b.medium()?) {
                    m.scaled_add(wgt, &bm.mapv(f64::from));
                }
            }
            Some(total) => {
                let wgt = Array2::from_shape_fn((h, w), |(y, x)| {
                    b.samples(y * w + x) as f64 / total[[y, x]] as f64
                });
                let w3 = wgt.clone().insert_axis(ndarray::Axis(2));
                steady += &(&b.steady()? * &w3);
                albedo += &(&b.albedo()?.mapv(f64::from) * &w3);
                normal += &(&b.normal()?.mapv(f64::from) * &w3);
                depth += &(&b.depth()?.mapv(f64::from) * &wgt);
                emitter += &(&b.emitter()?.mapv(f64::from) * &wgt);
                if let (Some(m), Some(bm)) = (medium.as_mut(), b.medium()?) {
                    *m += &(&bm.mapv(f64::from) * &wgt);
                }
            }
        }
    }
    for mut n in normal.rows_mut() {
        let len = n.dot(&n).sqrt();
        if len > 0.0 {
            n /= len;
        }
    }
    let mut manifest = first.clone();
    manifest.spp = total_spp;
    manifest.replicates = first
        .replicates
        .map(|_| bundles.iter().filter_map(|b| b.manifest.replicates).sum());
    all_seeds.sort_unstable();
    manifest.seed = all_seeds[0];
    manifest.pixel_sampling = bundles
        .iter()
        .map(|b| b.manifest.pixel_sampling)
        .fold(first.pixel_sampling, |a, b| a.merged(b));
    manifest.merged_seeds = all_seeds;
    manifest.shard = shard;
    // Saturating: a merged manifest must stay readable (finite, in range).
    manifest.render_seconds = bundles
        .iter()
        .map(|b| b.manifest.render_seconds)
        .sum::<f64>()
        .min(f64::MAX);
    manifest.dropped_nonfinite = bundles
        .iter()
        .fold(0u64, |a, b| a.saturating_add(b.manifest.dropped_nonfinite));
    manifest.arrays.clear();
    if let Some(total) = &pixel_spp {
        let rec = bundles
            .iter()
            .find_map(|b| b.manifest.adaptive.clone())
            .expect("an adaptive input");
        let (lo, hi) = total
            .iter()
            .fold((u64::MAX, 0), |(lo, hi), &n| (lo.min(n), hi.max(n)));
        manifest.version = super::manifest::VERSION;
        manifest.adaptive = Some(super::manifest::AdaptiveRecord {
            pilot_seconds: bundles
                .iter()
                .filter_map(|b| b.manifest.adaptive.as_ref().map(|a| a.pilot_seconds))
                .sum::<f64>()
                .min(f64::MAX),
            min_spp: lo,
            max_spp: hi,
            // The inputs' goals and error estimates are theirs, not the merge's.
            goal: None,
            estimated_error: None,
            ..rec
        });
        if hi > u64::from(u32::MAX) {
            return Err(BundleError::invalid(
                bundles[0].dir.clone(),
                Problem::SppOverflow,
            ));
        }
    }
    // What cannot be read back is refused before the merge's work (and checked
    // again, with the arrays, when written).
    super::write::check_planned(out, &manifest)?;
    let band = usize::try_from(opts.memory / row_bytes(&first).max(1))
        .unwrap_or(usize::MAX)
        .clamp(1, h.max(1));
    let f32s = |a: Array3<f64>| a.mapv(|v| v as f32);
    write_atomically(out, opts.force, |dir| {
        std::fs::create_dir(dir).map_err(|e| BundleError::io(dir, e))?;
        let volumes = VolumeArrays::create(
            dir,
            (h, w, t, first.channel_count()),
            &first.transform,
            first.replicates.is_some(),
        )?;
        let (mut acc, mut rows) = (RowSums::default(), RowSums::default());
        for y0 in (0..h).step_by(band) {
            let y1 = (y0 + band).min(h);
            for (n, b) in bundles.iter().enumerate() {
                // Opened for this band only: one input's files are open at a time.
                b.row_reader()?.read(y0..y1, &mut rows)?;
                if n == 0 {
                    std::mem::swap(&mut acc, &mut rows);
                } else {
                    add_band(&mut acc, &rows, &first, &b.dir)?;
                }
            }
            volumes.put(&acc)?;
        }
        let arrays = &mut manifest.arrays;
        arrays.extend(volumes.infos());
        drop(volumes);
        npy(dir, "albedo", "<f4", &f32s(albedo), arrays)?;
        npy(dir, "normal", "<f4", &f32s(normal), arrays)?;
        npy(dir, "depth", "<f4", &depth.mapv(|v| v as f32), arrays)?;
        npy(dir, "emitter", "<f4", &emitter.mapv(|v| v as f32), arrays)?;
        if let Some(m) = &medium {
            npy(dir, "medium", "<f4", &m.mapv(|v| v as f32), arrays)?;
        }
        npy(dir, "steady", "<f8", &steady, arrays)?;
        if let Some(total) = &pixel_spp {
            npy(dir, "pixel_spp", "<u4", &total.mapv(|n| n as u32), arrays)?;
        }
        super::write::write_manifest(dir, out, &manifest)
    })?;
    Ok(manifest)
}
