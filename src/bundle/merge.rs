//! Merging bundles rendered separately (other machines, other seeds) into one: the sums
//! and counts add exactly; the G-buffers and the steady image, which are means, are
//! averaged weighted by spp (normals renormalised). Only bundles of the same scene file
//! and settings with different seeds merge: equal seeds would repeat the same paths.
//! Bundles of different pixel sampling modes merge too (every sample of either mode is
//! marginally uniform over its pixel, so the sum stays unbiased); the result records
//! the common mode, or "mixed" when they differ.

use super::manifest::Manifest;
use super::write::{npy, write_atomically};
use super::{Bundle, BundleError, SumArray};
use ndarray::{Array2, Array3, Array4, Zip};
use std::path::{Path, PathBuf};

fn same_settings(a: &Manifest, b: &Manifest) -> Result<(), String> {
    let checks: [(&str, bool); 12] = [
        ("channels", a.channels == b.channels),
        ("scene (SHA-256)", a.scene.sha256 == b.scene.sha256),
        ("width", a.width == b.width),
        ("height", a.height == b.height),
        ("bins", a.bins == b.bins),
        ("start_opl", a.start_opl == b.start_opl),
        ("bin_width_opl", a.bin_width_opl == b.bin_width_opl),
        ("transform", a.transform == b.transform),
        ("max_depth", a.max_depth == b.max_depth),
        ("unit_m", a.unit_m == b.unit_m),
        ("media", a.media == b.media),
        (
            "temporal filter",
            a.time_filter_stddev_bins == b.time_filter_stddev_bins,
        ),
    ];
    if let Some((what, _)) = checks.iter().find(|c| !c.1) {
        return Err(format!("its {what} differs from the first bundle's"));
    }
    // Replicates add up only with equal sizes (SPEC 5): R2 and B sum.
    let size = |m: &Manifest| m.replicates.map(|b| m.spp / b);
    if size(a) != size(b) {
        let show = |m: &Manifest| match size(m) {
            Some(k) => format!("replicates of {k} samples"),
            None => "no replicates".to_string(),
        };
        return Err(format!(
            "it has {} where the first bundle has {}: only bundles with replicates of equal size (or none) merge",
            show(b),
            show(a)
        ));
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
            let show = |v: Option<&String>| v.map_or("unset".to_string(), |v| format!("'{v}'"));
            return Err(format!(
                "it was rendered with -D {k} {} where the first bundle has {}",
                show(dy.get(k)),
                show(dx.get(k))
            ));
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
            return Err(format!(
                "the scene's file '{name}' (an include, mesh, image, volume or spectrum) differs from the first bundle's, or only one of them read it"
            ));
        }
    }
    Ok(())
}

fn seeds(m: &Manifest) -> Vec<u64> {
    if m.merged_seeds.is_empty() {
        vec![m.seed]
    } else {
        m.merged_seeds.clone()
    }
}

/// Merges `inputs` (at least two) into a new bundle at `out`; returns its manifest.
pub fn merge_bundles(inputs: &[PathBuf], out: &Path, force: bool) -> Result<Manifest, BundleError> {
    if inputs.len() < 2 {
        return Err(BundleError::Io(
            out.to_path_buf(),
            "merge needs at least two bundles".into(),
        ));
    }
    let bundles: Vec<Bundle> = inputs
        .iter()
        .map(|p| Bundle::open(p))
        .collect::<Result<_, _>>()?;
    let first = &bundles[0].manifest;
    let mut all_seeds: Vec<u64> = Vec::new();
    for b in &bundles {
        same_settings(first, &b.manifest).map_err(|e| BundleError::Invalid(b.dir.clone(), e))?;
        for s in seeds(&b.manifest) {
            if all_seeds.contains(&s) {
                return Err(BundleError::Invalid(
                    b.dir.clone(),
                    format!("seed {s} appears twice: merging would count the same paths twice"),
                ));
            }
            all_seeds.push(s);
        }
    }
    let (h, w, t) = (first.height, first.width, first.bins);
    let total_spp = bundles
        .iter()
        .try_fold(0u64, |a, b| a.checked_add(b.manifest.spp))
        .ok_or_else(|| {
            BundleError::Invalid(
                bundles[0].dir.clone(),
                "the merged spp would overflow a 64-bit count".into(),
            )
        })?;
    let mut x1 = Array4::<f64>::zeros((h, w, t, 3));
    let mut x2 = x1.clone();
    let mut x3 = x1.clone();
    let mut sum = (!first.transform.is_identity()).then(|| x1.clone());
    let mut r2 = first.replicates.map(|_| x1.clone());
    let mut nonzero = Array3::<u32>::zeros((h, w, t));
    let mut steady = Array3::<f64>::zeros((h, w, 3));
    let mut albedo = Array3::<f64>::zeros((h, w, 3));
    let mut normal = Array3::<f64>::zeros((h, w, 3));
    let mut depth = Array2::<f64>::zeros((h, w));
    let mut emitter = Array2::<f64>::zeros((h, w));
    let mut medium = first.media.then(|| Array2::<f64>::zeros((h, w)));
    for b in &bundles {
        let counts = b.nonzero()?;
        x1 += &b.sum_array(SumArray::X1, &counts)?;
        x2 += &b.sum_array(SumArray::X2, &counts)?;
        x3 += &b.sum_array(SumArray::X3, &counts)?;
        if let Some(s) = sum.as_mut() {
            *s += &b.sum_array(SumArray::Radiance, &counts)?;
        }
        if let Some(r) = r2.as_mut() {
            *r += &b.sum_array(SumArray::R2, &counts)?;
        }
        // Counts are u32 on disk: a merge of more than 2^32 - 1 samples per pixel
        // could wrap them, so refuse it where it happens.
        let mut overflow = None;
        Zip::indexed(&mut nonzero)
            .and(&counts)
            .for_each(|i, a, &k| match a.checked_add(k) {
                Some(v) => *a = v,
                None => {
                    overflow.get_or_insert(i);
                }
            });
        if let Some((y, x, k)) = overflow {
            return Err(BundleError::Invalid(
                b.dir.join("nonzero.npy"),
                format!(
                    "voxel (y {y}, x {x}, t {k}): the merged count exceeds the u32 range of nonzero.npy"
                ),
            ));
        }
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
    manifest.seed = all_seeds[0];
    manifest.pixel_sampling = bundles
        .iter()
        .map(|b| b.manifest.pixel_sampling)
        .fold(first.pixel_sampling, |a, b| a.merged(b));
    manifest.merged_seeds = all_seeds;
    manifest.render_seconds = bundles.iter().map(|b| b.manifest.render_seconds).sum();
    manifest.dropped_nonfinite = bundles.iter().map(|b| b.manifest.dropped_nonfinite).sum();
    manifest.arrays.clear();
    let f32s = |a: Array3<f64>| a.mapv(|v| v as f32);
    write_atomically(out, force, |dir| {
        std::fs::create_dir(dir).map_err(|e| BundleError::Io(dir.to_path_buf(), e.to_string()))?;
        let arrays = &mut manifest.arrays;
        npy(dir, "x1", "<f8", &x1, arrays)?;
        npy(dir, "x2", "<f8", &x2, arrays)?;
        npy(dir, "x3", "<f8", &x3, arrays)?;
        if let Some(s) = &sum {
            npy(dir, "sum", "<f8", s, arrays)?;
        }
        if let Some(r) = &r2 {
            npy(dir, "r2", "<f8", r, arrays)?;
        }
        npy(dir, "nonzero", "<u4", &nonzero, arrays)?;
        npy(dir, "albedo", "<f4", &f32s(albedo), arrays)?;
        npy(dir, "normal", "<f4", &f32s(normal), arrays)?;
        npy(dir, "depth", "<f4", &depth.mapv(|v| v as f32), arrays)?;
        npy(dir, "emitter", "<f4", &emitter.mapv(|v| v as f32), arrays)?;
        if let Some(m) = &medium {
            npy(dir, "medium", "<f4", &m.mapv(|v| v as f32), arrays)?;
        }
        npy(dir, "steady", "<f8", &steady, arrays)?;
        let json = serde_json::to_string_pretty(&manifest).expect("manifest serialises");
        let mpath = dir.join("manifest.json");
        std::fs::write(&mpath, json).map_err(|e| BundleError::Io(mpath, e.to_string()))
    })?;
    Ok(manifest)
}
