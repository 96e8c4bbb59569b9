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
