//! Critical values at each pair's own degrees of freedom, for estimates from replicates
//! (SPEC 5 and 8).
//!
//! With B replicates in both voxels, each V has `B - 1` degrees of freedom and Welch's
//! test takes the Welch-Satterthwaite value for the pair,
//! `nu = (V_i + V_j)^2 / (V_i^2 / (B - 1) + V_j^2 / (B - 1)) = (B - 1) / r`, where
//! `r = a^2 + (1 - a)^2` with `a = V_i / (V_i + V_j)`, so `r` lies in [1/2, 1] and `nu`
//! between `B - 1` (one variance dominates) and `2 B - 2` (equal variances).
//!
//! [`PairDof`] tabulates the critical value `g^2(nu)` (the square of Student's t
//! quantile at a two-sided level p) on a uniform grid of `r` and interpolates linearly:
//! `r` is proportional to `1 / nu`, in which `g^2` is smooth, so 512 intervals keep the
//! relative error below 1e-4 even at B = 2 (tested against the exact quantile).

use super::critical::student_t_quantile;
use super::membership::{passes, PairTest};

/// Grid intervals over r in [1/2, 1].
const INTERVALS: usize = 512;

/// The smallest two-sided level used (smaller ones give the same, effectively infinite,
/// critical values).
pub const MIN_LEVEL: f64 = 1e-30;

/// `g^2` at each pair's Welch-Satterthwaite degrees of freedom.
#[derive(Clone, Debug)]
pub struct PairDof {
    replicates: u64,
    /// `g^2` at `r_k = 1/2 + k / (2 INTERVALS)`, k = 0..=INTERVALS.
    g2: Vec<f32>,
}

/// The Welch-Satterthwaite degrees of freedom of a pair of voxels with B replicates
/// each (the obviously-correct form, for tests and for the table's nodes).
pub fn welch_satterthwaite(v_i: f64, v_j: f64, replicates: u64) -> f64 {
    let k = replicates as f64 - 1.0;
    (v_i + v_j).powi(2) / (v_i * v_i / k + v_j * v_j / k)
}

impl PairDof {
    /// The table for B = `replicates` (at least 2) and two-sided level `p`. The
    /// quantile is taken from the lower tail (`-t_{p/2}`), so tiny levels do not round
    /// `1 - p/2` to 1; levels are clamped to [`MIN_LEVEL`, 1 - 1e-9] (an extreme
    /// `t2_max` gives 0 or 1 in floating point): critical values of ~1e20 or ~0, as the
    /// limits are, and statrs' inverse stays in its working range.
    pub fn new(replicates: u64, p: f64) -> Self {
        assert!(replicates >= 2, "replicate statistics need B >= 2");
        let p = if p.is_nan() { 1.0 } else { p }.clamp(MIN_LEVEL, 1.0 - 1e-9);
        let k = replicates as f64 - 1.0;
        let g2 = (0..=INTERVALS)
            .map(|i| {
                let r = 0.5 + i as f64 / (2 * INTERVALS) as f64;
                let g = -student_t_quantile(p / 2.0, k / r);
                (g * g) as f32
            })
            .collect();
        PairDof { replicates, g2 }
    }

    pub fn replicates(&self) -> u64 {
        self.replicates
    }

    /// `g^2` for the pair (V_i, V_j). When V_i + V_j = 0 the value is that of equal
    /// variances (the test then only asks d = 0, whatever g is).
    #[inline(always)]
    pub fn g2(&self, v_i: f32, v_j: f32) -> f32 {
        // a = min / (min + max) from q = min / max, symmetric in i and j and without
        // overflow in the sum.
        let q = v_i.min(v_j) / v_i.max(v_j);
        let a = q / (1.0 + q);
        let r = a * a + (1.0 - a) * (1.0 - a);
        // NaN (V = 0) becomes 0 through `max`.
        let x = ((r - 0.5) * (2 * INTERVALS) as f32)
            .max(0.0)
            .min(INTERVALS as f32 - 1e-3);
        let k = x as usize;
        let f = x - k as f32;
        self.g2[k] + f * (self.g2[k + 1] - self.g2[k])
    }
}

/// The published test with each pair's own critical value ([`PairDof::g2`]).
impl PairTest for PairDof {
    #[inline(always)]
    fn pass(&self, theta_i: f32, theta_j: f32, v_i: f32, v_j: f32) -> bool {
        passes(theta_i, theta_j, v_i, v_j, self.g2(v_i, v_j))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn degrees_of_freedom_span_b_minus_one_to_two_b_minus_two() {
        assert!((welch_satterthwaite(1.0, 1.0, 8) - 14.0).abs() < 1e-12);
        assert!((welch_satterthwaite(1.0, 0.0, 8) - 7.0).abs() < 1e-12);
        // nu = 7 * 9 / 5 for V = (1, 2).
        assert!((welch_satterthwaite(1.0, 2.0, 8) - 12.6).abs() < 1e-12);
    }

    #[test]
    fn table_matches_the_exact_quantile() {
        for b in [2u64, 3, 4, 8, 16, 64] {
            for p in [0.005, 0.0455, 0.2] {
                let t = PairDof::new(b, p);
                for (vi, vj) in [
                    (1.0f32, 1.0f32),
                    (1.0, 0.0),
                    (0.0, 3.0),
                    (1.0, 2.0),
                    (0.3, 0.01),
                    (5e-20, 7e-20),
                    (1e30, 2e29),
                ] {
                    let nu = welch_satterthwaite(vi as f64, vj as f64, b);
                    let exact = student_t_quantile(1.0 - p / 2.0, nu).powi(2);
                    let got = t.g2(vi, vj) as f64;
                    assert!(
                        (got / exact - 1.0).abs() < 1e-4,
                        "B {b} p {p} V ({vi}, {vj}): {got} vs {exact}"
                    );
                    assert_eq!(t.g2(vi, vj), t.g2(vj, vi), "symmetric");
                }
                // V = 0: the equal-variance value, finite.
                assert_eq!(t.g2(0.0, 0.0), t.g2(1.0, 1.0));
            }
        }
    }

    #[test]
    fn extreme_levels_and_variances_stay_defined() {
        // Levels that round to 0 or 1 (t2_max of 2000 or 1e-40; alpha 1e-17).
        for (b, p) in [2u64, 4, 1 << 20]
            .into_iter()
            .flat_map(|b| [0.0, 1e-320, 1e-17, 1.0, f64::NAN].map(|p| (b, p)))
        {
            let t = PairDof::new(b, p);
            for (vi, vj) in [(1.0f32, 1.0f32), (1.0, 0.0), (3e38, 3e38)] {
                let g2 = t.g2(vi, vj);
                assert!(!g2.is_nan() && g2 >= 0.0, "p {p}: {g2}");
            }
        }
        assert!(PairDof::new(4, 1e-17).g2(1.0, 1.0) > 1e6);
        assert!(PairDof::new(4, 1.0).g2(1.0, 1.0) < 1e-6);
        // Huge variances: the same degrees of freedom as small ones.
        let t = PairDof::new(8, 0.01);
        assert_eq!(t.g2(3e38, 3e38), t.g2(1.0, 1.0));
        assert_eq!(t.g2(3e38, 1.5e38), t.g2(2.0, 1.0));
    }

    #[test]
    fn fewer_degrees_of_freedom_give_larger_critical_values() {
        let t = PairDof::new(8, 0.005);
        assert!(t.g2(1.0, 0.0) > t.g2(1.0, 0.5) && t.g2(1.0, 0.5) > t.g2(1.0, 1.0));
        // B = 8 and equal variances: nu = 14, t_{0.9975, 14} = 3.326 (tables).
        assert!((t.g2(1.0, 1.0).sqrt() - 3.326).abs() < 2e-3);
    }
}
