//! The membership test m of SPEC 8 (Welch's t statistic below the critical value g).

/// One channel's test: `d^2 <= g^2 V` with `d = theta_i - theta_j`, `V = V_i + V_j`.
/// d = 0 with V = 0 passes; d != 0 with V = 0 fails. Symmetric in i and j.
/// With V = 0 the answer is exactly `d == 0` (d * d could underflow to 0 in f32).
#[inline(always)]
pub fn passes(theta_i: f32, theta_j: f32, v_i: f32, v_j: f32, g2: f32) -> bool {
    let d = theta_i - theta_j;
    let v = v_i + v_j;
    (d * d <= g2 * v) & ((v > 0.0) | (d == 0.0))
}

/// A per-voxel-pair membership test: neighbour voxel i counts for voxel j where
/// `pass` holds on every channel (estimands theta and variances V of both). The
/// published Welch test is one ([`WelchG2`]: one critical value; `pair_dof.rs`: each
/// pair's own, on estimates from replicates). A method of this kind implements it in
/// its own file and hands it to the filter in `Membership::with_pair_test` (`mod.rs`);
/// the filter (`filter.rs`) needs no change. tstat's test is not of this kind: it is
/// the filter's own patch test over neighbouring bins, with its neighbour classes.
pub trait PairTest: Sync {
    fn pass(&self, theta_i: f32, theta_j: f32, v_i: f32, v_j: f32) -> bool;
}

/// The published test with one critical value g^2 ([`passes`]).
pub struct WelchG2(pub f32);

impl PairTest for WelchG2 {
    #[inline(always)]
    fn pass(&self, theta_i: f32, theta_j: f32, v_i: f32, v_j: f32) -> bool {
        passes(theta_i, theta_j, v_i, v_j, self.0)
    }
}

/// Every neighbour passes: the base filter alone (and tstat, whose test is the
/// filter's own).
pub struct Everyone;

impl PairTest for Everyone {
    #[inline(always)]
    fn pass(&self, _: f32, _: f32, _: f32, _: f32) -> bool {
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edge_cases_and_symmetry() {
        assert!(passes(1.0, 1.0, 0.0, 0.0, 9.0));
        assert!(!passes(1.0, 1.0 + 1e-6, 0.0, 0.0, 9.0));
        // d * d underflows in f32, but d != 0 with V = 0 must still fail.
        assert!(!passes(1e-23, 2e-23, 0.0, 0.0, 4.0));
        // |d| / sqrt(V) = 2 < 3 passes; 4 > 3 fails.
        assert!(passes(2.0, 0.0, 0.5, 0.5, 9.0));
        assert!(!passes(4.0, 0.0, 0.5, 0.5, 9.0));
        for (a, b, va, vb) in [
            (0.3, 1.7, 0.1, 0.4),
            (5.0, -2.0, 1.0, 0.0),
            (0.0, 0.0, 0.0, 0.0),
        ] {
            assert_eq!(passes(a, b, va, vb, 4.0), passes(b, a, vb, va, 4.0));
        }
    }
}
