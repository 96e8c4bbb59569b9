//! The three regions every report measures (issue: most of a noisy render's error sits
//! in the few pixels that see a light directly, so one number hides what a denoiser does
//! to the rest):
//!
//! - **all**: every voxel;
//! - **light**: the voxels of pixels that see an emitter directly (emitter G-buffer > 0,
//!   i.e. some sample's first non-delta vertex was on an emitter);
//! - **rest**: the voxels of the other pixels.
//!
//! The split comes from a bundle's emitter G-buffer (the reference's when it is a
//! bundle, else an input's); with only `.npy` volumes it is unknown and only "all" is
//! measured.

use super::metrics::{peak, Acc, Metrics};
use ndarray::ArrayView4;

/// One region's name, for table columns and labels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Region {
    All,
    Light,
    Rest,
}

impl Region {
    pub const ALL: [Region; 3] = [Region::All, Region::Light, Region::Rest];

    pub fn name(self) -> &'static str {
        match self {
            Region::All => "all",
            Region::Light => "light",
            Region::Rest => "rest",
        }
    }

    /// Words for a plot or table title.
    pub fn describe(self) -> &'static str {
        match self {
            Region::All => "all voxels",
            Region::Light => "pixels that see a light",
            Region::Rest => "pixels that do not see a light",
        }
    }
}

/// Errors over the three regions. `light` / `rest` are `None` when the split is unknown
/// or the region is empty.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RegionMetrics {
    pub all: Metrics,
    pub light: Option<Metrics>,
    pub rest: Option<Metrics>,
}

impl RegionMetrics {
    pub fn get(&self, r: Region) -> Option<Metrics> {
        match r {
            Region::All => Some(self.all),
            Region::Light => self.light,
            Region::Rest => self.rest,
        }
    }
}

/// `m.rmse / noisy.rmse`, or `None` where either region is absent or the noisy error
/// is 0 (a ratio to nothing).
pub fn rmse_ratio(m: Option<Metrics>, noisy: Option<Metrics>) -> Option<f64> {
    match (m, noisy) {
        (Some(m), Some(n)) if n.rmse > 0.0 => Some(m.rmse / n.rmse),
        _ => None,
    }
}

/// Metrics of `x` against `reference` (both (H, W, T, C)) over the three regions, in
/// one pass, and per bin over all voxels. `no_light` (H x W, row-major) is true for
/// the pixels of "rest"; the PSNR peak is the whole reference's maximum in every region.
pub fn compare_regions(
    x: ArrayView4<f32>,
    reference: ArrayView4<f32>,
    no_light: Option<&[bool]>,
) -> (RegionMetrics, Vec<Metrics>) {
    assert_eq!(
        x.shape(),
        reference.shape(),
        "shapes are checked by the caller"
    );
    let (t, c) = (x.shape()[2], x.shape()[3]);
    if let Some(m) = no_light {
        assert_eq!(m.len(), x.shape()[0] * x.shape()[1], "one flag per pixel");
    }
    let peak = peak(reference);
    let (mut light, mut rest) = (Acc::default(), Acc::default());
    let mut per_bin = vec![Acc::default(); t];
    let xs = x.as_standard_layout();
    let rs = reference.as_standard_layout();
    let (xs, rs) = (
        xs.as_slice().expect("standard layout"),
        rs.as_slice().expect("standard layout"),
    );
    for (p, (xp, rp)) in xs
        .chunks_exact(t * c)
        .zip(rs.chunks_exact(t * c))
        .enumerate()
    {
        let acc = match no_light {
            Some(m) if !m[p] => &mut light,
            _ => &mut rest,
        };
        for k in 0..t {
            for ch in 0..c {
                let (a, b) = (xp[k * c + ch], rp[k * c + ch]);
                acc.add(a, b);
                per_bin[k].add(a, b);
            }
        }
    }
    let all = light.merged(&rest);
    let region = |a: &Acc| (a.count > 0).then(|| a.finish(peak));
    (
        RegionMetrics {
            all: all.finish(peak),
            light: no_light.and_then(|_| region(&light)),
            rest: no_light.and_then(|_| region(&rest)),
        },
        per_bin.iter().map(|a| a.finish(peak)).collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::super::metrics::compare;
    use super::*;
    use ndarray::Array4;

    fn close(a: Metrics, b: Metrics) {
        for (x, y) in [(a.rmse, b.rmse), (a.relmse, b.relmse), (a.psnr, b.psnr)] {
            assert!((x - y).abs() <= 1e-12 * y.abs().max(1.0), "{a:?} vs {b:?}");
        }
    }

    #[test]
    fn one_pass_matches_the_masked_reference() {
        // A 3x4 film, 5 bins; pixels 1 and 6 see the light.
        let (h, w, t) = (3, 4, 5);
        let r = Array4::from_shape_fn((h, w, t, 3), |(y, x, k, c)| {
            ((y * 7 + x * 3 + k + c) % 5) as f32 * 0.1
        });
        let x = Array4::from_shape_fn((h, w, t, 3), |(y, x, k, c)| {
            ((y * 5 + x * 11 + k * 2 + c) % 7) as f32 * 0.1
        });
        let no_light: Vec<bool> = (0..h * w).map(|p| p != 1 && p != 6).collect();
        let light: Vec<bool> = no_light.iter().map(|&b| !b).collect();
        let (m, bins) = compare_regions(x.view(), r.view(), Some(&no_light));
        let (all, all_bins) = compare(x.view(), r.view(), None);
        close(m.all, all);
        for (a, b) in bins.iter().zip(&all_bins) {
            close(*a, *b);
        }
        close(
            m.light.unwrap(),
            compare(x.view(), r.view(), Some(&light)).0,
        );
        close(
            m.rest.unwrap(),
            compare(x.view(), r.view(), Some(&no_light)).0,
        );
        // The regions' squared errors add up to the whole's.
        let n = (h * w) as f64;
        let sum = m.light.unwrap().rmse.powi(2) * 2.0 + m.rest.unwrap().rmse.powi(2) * (n - 2.0);
        assert!((sum / n - m.all.rmse.powi(2)).abs() < 1e-12);
    }

    #[test]
    fn unknown_split_and_empty_regions_are_none() {
        let r = Array4::<f32>::zeros((2, 2, 3, 3));
        let mut x = r.clone();
        x[[1, 1, 2, 0]] = 1.0;
        let (m, _) = compare_regions(x.view(), r.view(), None);
        assert_eq!((m.light, m.rest), (None, None));
        assert!(m.all.rmse > 0.0);
        let (m, _) = compare_regions(x.view(), r.view(), Some(&[true; 4]));
        assert_eq!(m.light, None);
        assert_eq!(m.rest, Some(m.all));
        assert_eq!(m.get(Region::Rest), m.rest);
    }
}
