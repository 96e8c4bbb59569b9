//! The temporal reconstruction filter: how one contribution at OPL `t` reaches the
//! time bins (mitransient's `temporal_filter`).
//!
//! - `Box` (the default): the whole contribution goes to the bin `t` falls in.
//! - `Gaussian { stddev }` (`stddev` in bins, mitransient's `gaussian_stddev`): the
//!   contribution is split over the bins whose centres lie within Mitsuba's Gaussian
//!   reconstruction filter's radius `r = 4 stddev` of `tau = (t - t0) / h`, bin k getting
//!   the share `w_k / sum_j w_j` with Mitsuba's `w(x) = max(0, exp(-x^2 / (2 stddev^2)) -
//!   exp(-r^2 / (2 stddev^2)))` at `x = k + 1/2 - tau`. The sum runs over every bin of
//!   the support, inside the window or not, so the split preserves energy: a
//!   contribution well inside the window adds exactly `c` over its bins, and one near
//!   an edge loses what falls outside, as with the box. A filter narrower than a bin
//!   (`r <= 1/2`) is the box, as Mitsuba's image block takes its box path then.
//!
//! A path still adds one sample per voxel: its shares are summed per bin in
//! `PathDeposits` before the path's total reaches the statistics.

use crate::sensors::film::Film;

/// mitransient's documented default `gaussian_stddev`, in bins.
pub const DEFAULT_STDDEV_BINS: f64 = 2.0;

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TimeFilter {
    Box,
    Gaussian { stddev: f64 },
}

impl TimeFilter {
    /// The Gaussian of standard deviation `stddev` bins, or the box when it is
    /// narrower than a bin.
    pub fn gaussian(stddev: f64) -> TimeFilter {
        if 4.0 * stddev <= 0.5 {
            TimeFilter::Box
        } else {
            TimeFilter::Gaussian { stddev }
        }
    }

    /// The standard deviation in bins, `None` for the box.
    pub fn stddev_bins(self) -> Option<f64> {
        match self {
            TimeFilter::Box => None,
            TimeFilter::Gaussian { stddev } => Some(stddev),
        }
    }
}

/// Calls `put(bin, share)` for each bin of `film` that receives a share of a
/// contribution at OPL `opl` under the Gaussian filter of `stddev` bins; the shares
/// of the whole support sum to 1.
#[inline(never)]
pub fn gaussian_shares(film: &Film, stddev: f64, opl: f64, mut put: impl FnMut(u32, f64)) {
    let tau = (opl - film.time.start_opl) / film.time.bin_width_opl;
    if !tau.is_finite() {
        return;
    }
    let radius = 4.0 * stddev;
    // Bins whose centre k + 1/2 lies within the radius of tau.
    let first = (tau - radius - 0.5).ceil();
    let last = (tau + radius - 0.5).floor();
    if last < 0.0 || first >= film.time.bins as f64 {
        return;
    }
    let alpha = -1.0 / (2.0 * stddev * stddev);
    let bias = (alpha * radius * radius).exp();
    let w = |k: f64| {
        let x = k + 0.5 - tau;
        ((alpha * x * x).exp() - bias).max(0.0)
    };
    // At most 8 stddev + 1 bins; the sum covers the whole support.
    let mut total = 0.0;
    let mut k = first;
    while k <= last {
        total += w(k);
        k += 1.0;
    }
    if total <= 0.0 {
        return;
    }
    let mut k = first.max(0.0);
    let end = last.min(film.time.bins as f64 - 1.0);
    while k <= end {
        let share = w(k) / total;
        if share > 0.0 {
            put(k as u32, share);
        }
        k += 1.0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn film(bins: usize) -> Film {
        Film {
            width: 1,
            height: 1,
            time: crate::sensors::time_axis::TimeAxis {
                bins,
                start_opl: 10.0,
                bin_width_opl: 0.5,
            },
            channels: 3,
        }
    }

    /// The shares as a plain vector over all bins, by the definition.
    fn reference(film: &Film, stddev: f64, opl: f64) -> Vec<f64> {
        let tau = (opl - film.time.start_opl) / film.time.bin_width_opl;
        let r = 4.0 * stddev;
        let g = |x: f64| {
            if x.abs() >= r {
                0.0
            } else {
                (-x * x / (2.0 * stddev * stddev)).exp() - (-r * r / (2.0 * stddev * stddev)).exp()
            }
        };
        // The support's total over a range wide enough to hold it all.
        let total: f64 = (-1000..1000).map(|k| g(k as f64 + 0.5 - tau)).sum();
        (0..film.time.bins)
            .map(|k| g(k as f64 + 0.5 - tau) / total)
            .collect()
    }

    fn shares(film: &Film, stddev: f64, opl: f64) -> Vec<f64> {
        let mut v = vec![0.0; film.time.bins];
        gaussian_shares(film, stddev, opl, |k, s| v[k as usize] += s);
        v
    }

    #[test]
    fn shares_match_the_definition_and_sum_to_one_inside_the_window() {
        let f = film(40);
        for &sd in &[0.2, 0.5, 1.0, 2.0, 3.7] {
            for &opl in &[20.0, 20.1, 20.25, 19.999, 15.3] {
                let got = shares(&f, sd, opl);
                let want = reference(&f, sd, opl);
                for (g, w) in got.iter().zip(&want) {
                    assert!(
                        (g - w).abs() < 1e-12,
                        "sd {sd} opl {opl}: {got:?} vs {want:?}"
                    );
                }
                let sum: f64 = got.iter().sum();
                let tau = (opl - f.time.start_opl) / f.time.bin_width_opl;
                let inside = tau - 4.0 * sd >= 0.0 && tau + 4.0 * sd <= f.time.bins as f64;
                if inside {
                    assert!((sum - 1.0).abs() < 1e-12, "sd {sd} opl {opl}: sum {sum}");
                } else {
                    assert!(sum < 1.0, "sd {sd} opl {opl}: sum {sum}");
                }
            }
        }
    }

    #[test]
    fn shares_are_centred_on_the_contribution() {
        // The mean bin centre of the shares is tau when the support is inside the
        // window, up to the aliasing of a Gaussian sampled at bin centres (3e-5 bins
        // at stddev 2; a filter off by a bin fails by 4 orders of magnitude).
        let f = film(60);
        let opl = 25.37;
        let tau = (opl - f.time.start_opl) / f.time.bin_width_opl;
        let v = shares(&f, 2.0, opl);
        let mean: f64 = v
            .iter()
            .enumerate()
            .map(|(k, s)| (k as f64 + 0.5) * s)
            .sum();
        assert!((mean - tau).abs() < 1e-4, "{mean} vs {tau}");
    }

    #[test]
    fn what_falls_outside_the_window_is_lost_and_the_rest_kept() {
        let f = film(10);
        // tau = 0.5: the centre of bin 0; half the support lies before the window.
        let v = shares(&f, 1.0, 10.25);
        let want = reference(&f, 1.0, 10.25);
        let sum: f64 = v.iter().sum();
        assert!(sum > 0.5 && sum < 0.75, "{sum}");
        assert!((sum - want.iter().sum::<f64>()).abs() < 1e-12);
        // Entirely outside: nothing.
        assert!(shares(&f, 1.0, 0.0).iter().all(|&s| s == 0.0));
        assert!(shares(&f, 1.0, 1e9).iter().all(|&s| s == 0.0));
        assert!(shares(&f, 1.0, f64::NAN).iter().all(|&s| s == 0.0));
    }

    #[test]
    fn a_filter_narrower_than_a_bin_is_the_box() {
        assert_eq!(TimeFilter::gaussian(0.1), TimeFilter::Box);
        assert_eq!(TimeFilter::gaussian(0.125), TimeFilter::Box);
        assert_eq!(
            TimeFilter::gaussian(0.5),
            TimeFilter::Gaussian { stddev: 0.5 }
        );
    }
}
