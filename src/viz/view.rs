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

use crate::bundle::{Bundle, BundleError, RowSums};
use crate::denoise::critical::student_t_quantile;
use crate::stats::accumulators::CHANNELS;
use crate::stats::estimators::{estimate, estimate_replicates, Sums};
use base64::Engine;
use ndarray::{Array3, Array4};
use serde_json::json;

/// The page, with `/*DATA*/` where the JSON data go.
const PAGE: &str = include_str!("view.html");

/// The filter's per-voxel test shown around a clicked pixel.
#[derive(Clone, Copy, Debug)]
pub struct MembershipShown {
    pub radius: usize,
    pub t2_max: f64,
    pub depth_align: bool,
}

/// Volumes beside the bundle's own noisy mean.
pub struct Extra {
    pub label: String,
    /// f32 (H, W, T, C).
    pub volume: Array4<f32>,
}

/// What the page was built from, for the command's summary line.
pub struct PageSummary {
    pub bytes: usize,
    pub block: usize,
    pub band: bool,
}

/// The noisy mean and, for identity-transform bundles, the standard deviation of the
/// mean sqrt(V) (from the replicates when the bundle has them), both (H, W, T, C).
fn mean_and_sd(b: &Bundle) -> Result<(Array4<f32>, Option<Array4<f32>>), BundleError> {
    let m = &b.manifest;
    let (h, w, t) = (m.height, m.width, m.bins);
    let mut mean = Array4::<f32>::zeros((h, w, t, CHANNELS));
    let identity = m.transform.is_identity();
    let mut sd = identity.then(|| Array4::<f32>::zeros((h, w, t, CHANNELS)));
    let reader = b.row_reader()?;
    let mut rows = RowSums::default();
    let n = m.spp;
    let z0 = m.transform.at_zero();
    for y0 in (0..h).step_by(8) {
        let y1 = (y0 + 8).min(h);
        reader.read(y0..y1, &mut rows)?;
        let radiance = if identity { &rows.x1 } else { &rows.sum };
        for (i, &s) in radiance.iter().enumerate() {
            let flat = y0 * w * t * CHANNELS + i;
            mean.as_slice_mut().unwrap()[flat] = (s / n as f64) as f32;
            if let Some(sd) = sd.as_mut() {
                let nz = rows.nonzero[i / CHANNELS];
                let e = match m.replicates {
                    Some(bb) => estimate_replicates(rows.x1[i], rows.r2[i], nz, n, bb, z0),
                    None => estimate(
                        Sums {
                            x1: rows.x1[i],
                            x2: rows.x2[i],
                            x3: rows.x3[i],
                        },
                        nz,
                        n,
                        z0,
                    ),
                };
                sd.as_slice_mut().unwrap()[flat] = e.v.sqrt() as f32;
            }
        }
    }
    Ok((mean, sd))
}

/// Averages k x k pixel blocks (the last blocks may be smaller). With `sd`, the values
/// are standard deviations of pixel means: the block mean's is sqrt(sum sd^2) / count.
fn block_average(v: &Array4<f32>, k: usize, sd: bool) -> Array4<f32> {
    if k == 1 {
        return v.clone();
    }
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

fn block_average_pixels(v: &Array3<f32>, k: usize) -> Array3<f32> {
    let (h, w, c) = v.dim();
    let v4 = v.to_shape((h, w, 1, c)).unwrap().to_owned();
    let out = block_average(&v4, k, false);
    let (bh, bw, _, _) = out.dim();
    out.into_shape_with_order((bh, bw, c)).unwrap()
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

/// Builds the page for `bundle` with `extras` (each (H, W, T, C) like the bundle),
/// keeping the volumes' f16 data under `budget` bytes.
pub fn build_page(
    bundle: &Bundle,
    name: &str,
    extras: &[Extra],
    shown: MembershipShown,
    budget: usize,
) -> Result<(String, PageSummary), BundleError> {
    let m = &bundle.manifest;
    let (h, w, t) = (m.height, m.width, m.bins);
    let (mean, sd) = mean_and_sd(bundle)?;
    let volumes = 1 + extras.len() + usize::from(sd.is_some());
    let bytes_at = |k: usize| volumes * h.div_ceil(k) * w.div_ceil(k) * t * CHANNELS * 2;
    let mut k = 1;
    while bytes_at(k) > budget && (h.div_ceil(k) > 1 || w.div_ceil(k) > 1) {
        k += 1;
    }
    let (ph, pw) = (h.div_ceil(k), w.div_ceil(k));
    let mut vols = Vec::new();
    let mut push = |label: &str, kind: &str, v: &Array4<f32>, sd: bool| {
        let (data, scale) = encode_frames(&block_average(v, k, sd));
        vols.push(json!({"label": label, "kind": kind, "data": data, "scale": scale}));
    };
    push("noisy", "mean", &mean, false);
    if let Some(sd) = &sd {
        push("noisy sd of the mean", "sd", sd, true);
    }
    for e in extras {
        push(&e.label, "mean", &e.volume, false);
    }
    let albedo = block_average_pixels(&bundle.albedo()?, k);
    let normal = block_average_pixels(&bundle.normal()?, k);
    let flat2 = |a: ndarray::Array2<f32>| {
        let (hh, ww) = a.dim();
        block_average_pixels(&a.into_shape_with_order((hh, ww, 1)).unwrap(), k)
    };
    let depth = flat2(bundle.depth()?);
    let emitter = flat2(bundle.emitter()?);
    // The band's quantile: Student's t at the statistics' degrees of freedom.
    let dof = match m.replicates {
        Some(b) => b - 1,
        None => m.spp - 1,
    };
    let tq = student_t_quantile(0.975, dof as f64);
    let correlated = m.replicates.is_none()
        && m.pixel_sampling != crate::bundle::manifest::SamplingRecord::Independent;
    let data = json!({
        "name": name,
        "height": ph, "width": pw, "bins": t, "block": k,
        "full_height": h, "full_width": w,
        "spp": m.spp, "replicates": m.replicates, "sampling": m.pixel_sampling.name(),
        "transform": m.transform.to_string(),
        "start_opl": m.start_opl, "bin_width_opl": m.bin_width_opl,
        "start_ps": m.start_seconds * 1e12, "bin_ps": m.bin_width_seconds * 1e12,
        "t_quantile": tq, "dof": dof, "correlated": correlated,
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
        band: sd.is_some(),
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
