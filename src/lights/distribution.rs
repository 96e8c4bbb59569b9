//! A piecewise-constant distribution over the cells of an `nu x nv` grid, sampled by
//! inversion: a row `j` from the marginal CDF, then a column `i` from that row's
//! conditional CDF (pbrt's `Distribution2D`). The environment map's importance
//! sampling (`envmap.rs`) uses it.
//!
//! The probability reported for a cell is computed from the very f32 CDF values that
//! sampling inverts, `P(i, j) = (M[j+1] - M[j]) (C_j[i+1] - C_j[i])`, so the density the
//! integrator's MIS evaluates is the one the sampler realises (up to the 2^-24 spacing
//! of the random numbers). Cells of zero weight are never chosen.

/// Sampling tables: `(nv + 1)` marginal CDF values and `nv (nu + 1)` conditional ones
/// (f32).
#[derive(Clone, Debug, PartialEq)]
pub struct Distribution2D {
    nu: usize,
    nv: usize,
    marginal: Vec<f32>,
    conditional: Vec<f32>,
}

/// The normalised CDF of `w` (f64 sums, stored as f32; the last entry exactly 1), or
/// `None` when the weights sum to zero.
fn cdf(w: impl Iterator<Item = f64>, n: usize, out: &mut Vec<f32>) -> Option<()> {
    let start = out.len();
    let mut sum = 0.0f64;
    out.push(0.0);
    let mut partial = Vec::with_capacity(n);
    for v in w {
        sum += v;
        partial.push(sum);
    }
    if sum.is_nan() || sum <= 0.0 {
        out.truncate(start);
        out.extend(std::iter::repeat_n(0.0, n + 1));
        return None;
    }
    for (k, s) in partial.into_iter().enumerate() {
        out.push(if k + 1 == n { 1.0 } else { (s / sum) as f32 });
    }
    Some(())
}

/// The index `k` with `c[k] <= u < c[k + 1]` in a CDF whose last entry is 1 (so the cell
/// has positive probability), and where `u` falls within it, in [0, 1).
#[inline]
fn invert(c: &[f32], u: f32) -> (usize, f32) {
    let k = c.partition_point(|&v| v <= u).clamp(1, c.len() - 1) - 1;
    let (lo, hi) = (c[k], c[k + 1]);
    let r = if hi > lo { (u - lo) / (hi - lo) } else { 0.0 };
    (k, r.clamp(0.0, 1.0 - f32::EPSILON / 2.0))
}

impl Distribution2D {
    /// From non-negative finite weights, row-major (`weights[j * nu + i]`). `None` when
    /// they all are zero.
    pub fn new(weights: &[f64], nu: usize, nv: usize) -> Option<Self> {
        assert_eq!(weights.len(), nu * nv);
        assert!(nu > 0 && nv > 0);
        let mut conditional = Vec::with_capacity(nv * (nu + 1));
        let mut row_sums = Vec::with_capacity(nv);
        for j in 0..nv {
            let row = &weights[j * nu..(j + 1) * nu];
            row_sums.push(row.iter().sum::<f64>());
            cdf(row.iter().copied(), nu, &mut conditional);
        }
        let mut marginal = Vec::with_capacity(nv + 1);
        cdf(row_sums.into_iter(), nv, &mut marginal)?;
        Some(Distribution2D {
            nu,
            nv,
            marginal,
            conditional,
        })
    }

    /// A cell `(i, j)` with probability [`Self::prob`], and where `u` fell within it (each
    /// coordinate in [0, 1), uniform given the cell).
    #[inline]
    pub fn sample(&self, u: [f32; 2]) -> (usize, usize, [f32; 2]) {
        let (j, rv) = invert(&self.marginal, u[1]);
        let row = &self.conditional[j * (self.nu + 1)..(j + 1) * (self.nu + 1)];
        let (i, ru) = invert(row, u[0]);
        (i, j, [ru, rv])
    }

    /// The probability of cell `(i, j)`: the widths of its marginal and conditional CDF
    /// steps, the intervals of u that `sample` maps to it.
    #[inline]
    pub fn prob(&self, i: usize, j: usize) -> f32 {
        let c = &self.conditional[j * (self.nu + 1)..];
        (self.marginal[j + 1] - self.marginal[j]) * (c[i + 1] - c[i])
    }

    /// Bytes held by the tables.
    pub fn bytes(&self) -> usize {
        4 * (self.marginal.len() + self.conditional.len())
    }

    pub fn size(&self) -> (usize, usize) {
        (self.nu, self.nv)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_are_chosen_with_their_probability_and_zero_cells_never() {
        let w = [1.0, 0.0, 3.0, 0.0, 0.0, 0.0, 2.0, 2.0, 0.0];
        let d = Distribution2D::new(&w, 3, 3).unwrap();
        let total: f64 = w.iter().sum();
        for j in 0..3 {
            for i in 0..3 {
                assert!((d.prob(i, j) as f64 - w[j * 3 + i] / total).abs() < 1e-7);
            }
        }
        // Sweep u over a fine grid: the fraction landing in each cell is its probability.
        let n = 600;
        let mut counts = [0usize; 9];
        for a in 0..n {
            for b in 0..n {
                let u = [(a as f32 + 0.5) / n as f32, (b as f32 + 0.5) / n as f32];
                let (i, j, r) = d.sample(u);
                assert!(w[j * 3 + i] > 0.0, "zero cell ({i}, {j}) chosen");
                assert!((0.0..1.0).contains(&r[0]) && (0.0..1.0).contains(&r[1]));
                counts[j * 3 + i] += 1;
            }
        }
        for k in 0..9 {
            let f = counts[k] as f64 / (n * n) as f64;
            assert!((f - w[k] / total).abs() < 3.0 / n as f64, "cell {k}: {f}");
        }
        assert!(Distribution2D::new(&[0.0; 4], 2, 2).is_none());
        // The extremes of u stay inside cells of positive weight.
        for u in [[0.0, 0.0], [0.99999994, 0.99999994], [0.0, 0.99999994]] {
            let (i, j, _) = d.sample(u);
            assert!(w[j * 3 + i] > 0.0);
        }
    }
}
