//! Error metrics of a volume against a reference (SPEC 10), over the whole volume, per
//! bin, and over the pixels that do not see a light directly.
//!
//! - RMSE = sqrt(mean (x - ref)^2);
//! - relative MSE = mean (x - ref)^2 / (ref^2 + EPS), with EPS = 1e-2 (keeps dark
//!   voxels, where ref = 0, from dominating);
//! - PSNR = 10 log10(peak^2 / MSE) in dB, with peak = the reference's maximum
//!   (infinite when MSE = 0).

use ndarray::{ArrayView4, Axis};

/// The epsilon of the relative MSE denominator.
pub const REL_EPS: f64 = 1e-2;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Metrics {
    pub rmse: f64,
    pub relmse: f64,
    pub psnr: f64,
}

#[derive(Clone, Copy, Default)]
pub(super) struct Acc {
    se: f64,
    rel: f64,
    pub(super) count: u64,
}

impl Acc {
    #[inline]
    pub(super) fn add(&mut self, x: f32, r: f32) {
        let (x, r) = (x as f64, r as f64);
        let e = (x - r) * (x - r);
        self.se += e;
        self.rel += e / (r * r + REL_EPS);
        self.count += 1;
    }

    /// The accumulator of both regions together.
    pub(super) fn merged(&self, o: &Acc) -> Acc {
        Acc {
            se: self.se + o.se,
            rel: self.rel + o.rel,
            count: self.count + o.count,
        }
    }

    /// The metrics; NaN (never a plausible number) when no voxel was measured or a
    /// value was not finite. Callers refuse such volumes when loading them
    /// (`volume::load_volume`); this keeps a library caller from reading an infinite
    /// PSNR into an empty or NaN comparison. Identical volumes keep PSNR = inf.
    pub(super) fn finish(&self, peak: f64) -> Metrics {
        if self.count == 0 {
            return Metrics {
                rmse: f64::NAN,
                relmse: f64::NAN,
                psnr: f64::NAN,
            };
        }
        let n = self.count as f64;
        let mse = self.se / n;
        Metrics {
            rmse: mse.sqrt(),
            relmse: self.rel / n,
            psnr: if mse > 0.0 {
                10.0 * (peak * peak / mse).log10()
            } else if mse == 0.0 {
                f64::INFINITY
            } else {
                f64::NAN
            },
        }
    }
}

/// The PSNR peak: the reference's maximum (NaN if the reference holds a NaN, which
/// `f64::max` alone would skip).
pub(super) fn peak(reference: ArrayView4<f32>) -> f64 {
    reference.iter().fold(0.0f64, |m, &v| {
        if v.is_nan() || m.is_nan() {
            f64::NAN
        } else {
            m.max(v as f64)
        }
    })
}

/// Metrics of `x` against `reference`, both (H, W, T, C), over the voxels of the pixels
/// where `mask` (H x W, row-major) is true (all pixels when `None`). Returns the whole
/// volume's metrics and one per bin.
pub fn compare(
    x: ArrayView4<f32>,
    reference: ArrayView4<f32>,
    mask: Option<&[bool]>,
) -> (Metrics, Vec<Metrics>) {
    assert_eq!(
        x.shape(),
        reference.shape(),
        "shapes are checked by the caller"
    );
    let (h, w, t) = (x.shape()[0], x.shape()[1], x.shape()[2]);
    let peak = peak(reference);
    let mut all = Acc::default();
    let mut per_bin: Vec<Acc> = (0..t).map(|_| Acc::default()).collect();
    for y in 0..h {
        for xp in 0..w {
            if mask.is_some_and(|m| !m[y * w + xp]) {
                continue;
            }
            let xs = x.index_axis(Axis(0), y);
            let rs = reference.index_axis(Axis(0), y);
            for k in 0..t {
                for c in 0..x.shape()[3] {
                    let (a, b) = (xs[[xp, k, c]], rs[[xp, k, c]]);
                    all.add(a, b);
                    per_bin[k].add(a, b);
                }
            }
        }
    }
    (
        all.finish(peak),
        per_bin.iter().map(|a| a.finish(peak)).collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::Array4;

    #[test]
    fn hand_computed_values_with_zeros_in_the_reference() {
        // Reference [0, 2], input [1, 2]: errors 1 and 0.
        let r = Array4::from_shape_vec((1, 2, 1, 1), vec![0.0f32, 2.0]).unwrap();
        let x = Array4::from_shape_vec((1, 2, 1, 1), vec![1.0f32, 2.0]).unwrap();
        let (m, bins) = compare(x.view(), r.view(), None);
        assert!((m.rmse - 0.5f64.sqrt()).abs() < 1e-12);
        // (1 / (0 + 0.01) + 0 / (4 + 0.01)) / 2 = 50
        assert!((m.relmse - 50.0).abs() < 1e-9);
        // peak 2, MSE 0.5: 10 log10(8)
        assert!((m.psnr - 10.0 * 8f64.log10()).abs() < 1e-12);
        assert_eq!(bins.len(), 1);
        assert_eq!(bins[0], m);
        // Identical volumes: zero error, infinite PSNR.
        let (m, _) = compare(r.view(), r.view(), None);
        assert_eq!((m.rmse, m.relmse, m.psnr), (0.0, 0.0, f64::INFINITY));
    }

    #[test]
    fn empty_or_nan_comparisons_are_nan_not_infinite_psnr() {
        let empty = Array4::<f32>::zeros((0, 2, 1, 3));
        let (m, _) = compare(empty.view(), empty.view(), None);
        assert!(
            m.rmse.is_nan() && m.relmse.is_nan() && m.psnr.is_nan(),
            "{m:?}"
        );
        let mut r = Array4::<f32>::ones((1, 2, 1, 1));
        let x = r.clone();
        r[[0, 1, 0, 0]] = f32::NAN;
        let (m, bins) = compare(x.view(), r.view(), None);
        assert!(m.rmse.is_nan() && m.psnr.is_nan(), "{m:?}");
        assert!(bins[0].psnr.is_nan());
        // A NaN in the input, not the reference: NaN as well, never inf.
        let (m, _) = compare(r.view(), x.view(), None);
        assert!(m.psnr.is_nan(), "{m:?}");
    }

    #[test]
    fn per_bin_and_masked_metrics() {
        // Two pixels, two bins; the error sits in pixel 1, bin 1.
        let r = Array4::<f32>::zeros((1, 2, 2, 1));
        let mut x = Array4::<f32>::zeros((1, 2, 2, 1));
        x[[0, 1, 1, 0]] = 2.0;
        let (m, bins) = compare(x.view(), r.view(), None);
        assert!((m.rmse - 1.0).abs() < 1e-12); // sqrt(4 / 4)
        assert_eq!(bins[0].rmse, 0.0);
        assert!((bins[1].rmse - 2f64.sqrt()).abs() < 1e-12); // sqrt(4 / 2)
        let (m, _) = compare(x.view(), r.view(), Some(&[true, false]));
        assert_eq!(m.rmse, 0.0);
    }
}
