//! The equal-error speed-up: how many times less time a method needs than the noisy
//! render to reach the same error. The noisy curve (seconds, error) is interpolated
//! linearly in log-log space at the method's error.

/// Seconds the noisy curve needs to reach `error`, or `None` when `error` lies outside
/// the measured range of the curve (extrapolation is not attempted).
pub fn time_to_reach(curve: &[(f64, f64)], error: f64) -> Option<f64> {
    let mut pts: Vec<(f64, f64)> = curve
        .iter()
        .copied()
        .filter(|&(s, e)| s > 0.0 && e > 0.0 && s.is_finite() && e.is_finite())
        .collect();
    if pts.is_empty() || error.is_nan() || error <= 0.0 {
        return None;
    }
    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    let le = error.ln();
    for w in pts.windows(2) {
        let ((s0, e0), (s1, e1)) = (w[0], w[1]);
        let (l0, l1) = (e0.ln(), e1.ln());
        if (l0 - le) * (l1 - le) <= 0.0 {
            if l0 == l1 {
                return Some(s0);
            }
            let f = (le - l0) / (l1 - l0);
            return Some((s0.ln() + f * (s1.ln() - s0.ln())).exp());
        }
    }
    pts.iter().find(|p| p.1 == error).map(|p| p.0)
}

/// Speed-up of a method that reached `error` in `seconds`, against the noisy curve.
pub fn equal_error_speedup(noisy: &[(f64, f64)], seconds: f64, error: f64) -> Option<f64> {
    time_to_reach(noisy, error).map(|t| t / seconds)
}

/// An equal-error speed-up, or a bound on it when the error lies outside the noisy
/// curve's measured range.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Speedup {
    Exact(f64),
    /// The error is below every noisy point: the noisy render would need more than the
    /// time of its lowest-error point (its error falls with time), so the speed-up
    /// exceeds that time over the method's.
    AtLeast(f64),
    /// The error is above every noisy point: the noisy render gets there in less than
    /// the time of its highest-error point.
    AtMost(f64),
}

impl Speedup {
    /// The number (the bound for a bound).
    pub fn value(self) -> f64 {
        match self {
            Speedup::Exact(v) | Speedup::AtLeast(v) | Speedup::AtMost(v) => v,
        }
    }
}

impl std::fmt::Display for Speedup {
    /// `2.31`, `>4.1`, `<0.4` (two decimals).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Speedup::Exact(v) => write!(f, "{v:.2}"),
            Speedup::AtLeast(v) => write!(f, ">{v:.2}"),
            Speedup::AtMost(v) => write!(f, "<{v:.2}"),
        }
    }
}

/// [`equal_error_speedup`], with a bound instead of nothing outside the measured range.
/// `None` only when the curve or the error is unusable (empty, non-positive, NaN).
pub fn speedup_or_bound(noisy: &[(f64, f64)], seconds: f64, error: f64) -> Option<Speedup> {
    if let Some(v) = equal_error_speedup(noisy, seconds, error) {
        return Some(Speedup::Exact(v));
    }
    let pts = noisy
        .iter()
        .filter(|&&(s, e)| s > 0.0 && e > 0.0 && s.is_finite() && e.is_finite());
    let lowest = pts.clone().min_by(|a, b| a.1.total_cmp(&b.1))?;
    let highest = pts.max_by(|a, b| a.1.total_cmp(&b.1))?;
    if !(error > 0.0 && seconds > 0.0) {
        None
    } else if error < lowest.1 {
        Some(Speedup::AtLeast(lowest.0 / seconds))
    } else if error > highest.1 {
        Some(Speedup::AtMost(highest.0 / seconds))
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolates_a_power_law_exactly() {
        // error = 1 / sqrt(seconds): a straight line in log-log.
        let curve: Vec<(f64, f64)> = [1.0, 4.0, 16.0, 64.0]
            .iter()
            .map(|&s: &f64| (s, 1.0 / s.sqrt()))
            .collect();
        let t = time_to_reach(&curve, 0.2).unwrap();
        assert!((t - 25.0).abs() < 1e-9, "{t}");
        // A method reaching error 0.2 in 5 s is 5x faster.
        assert!((equal_error_speedup(&curve, 5.0, 0.2).unwrap() - 5.0).abs() < 1e-9);
        // Measured points are hit exactly.
        assert!((time_to_reach(&curve, 0.25).unwrap() - 16.0).abs() < 1e-9);
    }

    #[test]
    fn bounds_outside_the_range() {
        // Noisy: error 1 at 1 s, 0.5 at 4 s.
        let curve = vec![(1.0, 1.0), (4.0, 0.5)];
        assert_eq!(
            speedup_or_bound(&curve, 2.0, 0.1),
            Some(Speedup::AtLeast(2.0))
        );
        assert_eq!(
            speedup_or_bound(&curve, 2.0, 3.0),
            Some(Speedup::AtMost(0.5))
        );
        assert_eq!(
            speedup_or_bound(&curve, 1.0, 0.5),
            Some(Speedup::Exact(4.0))
        );
        assert_eq!(speedup_or_bound(&[], 1.0, 0.5), None);
        assert_eq!(speedup_or_bound(&curve, 1.0, f64::NAN), None);
        assert_eq!(Speedup::AtLeast(4.123).to_string(), ">4.12");
        assert_eq!(Speedup::AtMost(0.5).to_string(), "<0.50");
    }

    #[test]
    fn out_of_range_is_none() {
        let curve = vec![(1.0, 1.0), (4.0, 0.5)];
        assert_eq!(time_to_reach(&curve, 0.1), None);
        assert_eq!(time_to_reach(&curve, 2.0), None);
        assert_eq!(time_to_reach(&[], 0.5), None);
        assert_eq!(equal_error_speedup(&curve, 1.0, 0.01), None);
    }
}
