//! Per-voxel, per-channel estimators of SPEC section 5.
//!
//! Given the sums `X1 = sum z`, `X2 = sum z^2`, `X3 = sum z^3` over the samples
//! that deposited something in a voxel, the number `nonzero` of such samples,
//! the sample count `n = spp` and `z0 = z(0)`, the SPEC defines
//!
//! 1. zero-fill `X_k += (n - nonzero) z0^k`;
//! 2. `mu = X1/n`, `s2 = X2/n - mu^2`, `sigma2 = s2 n/(n-1)`;
//! 3. `m3 = X3/n - 3 mu s2 - mu^3`;
//! 4. `theta = mu + m3/(6 sigma2 n)` (`mu` when `sigma2 = 0`);
//! 5. `V = sigma2/n`.
//!
//! # How it is computed
//!
//! Central moments do not change when every sample is shifted, so [`estimate`]
//! takes the moments about `c = z0` instead of about 0: with `m = nonzero`,
//! `Y1 = X1' - m c`, `Y2 = X2' - 2 c X1' + m c^2`,
//! `Y3 = X3' - 3 c X2' + 3 c^2 X1' - m c^3` (`X_k'` = the stored, unfilled sums)
//! are the sums of `(z - z0)^k` over all `n` samples, the zero samples
//! contributing exactly 0. This is algebraically identical to the zero-fill
//! formulas above (and literally the same arithmetic when `z0 = 0`, i.e.
//! identity and Yeo-Johnson), but for Box-Cox it avoids subtracting two numbers
//! of size `z0^2` when only a few of the `n` samples are non-zero, the common
//! case in transient voxels. Then `mu = z0 + Y1/n`, `s2 = Y2/n - (Y1/n)^2`, and
//! so on.
//!
//! # Rounding floors
//!
//! One-pass sums lose digits: in any summation order, a sum of `m` terms carries
//! an absolute error up to about `m u` times the sum of the terms' magnitudes
//! (`u = EPSILON/2`). For `n` identical samples the computed `X2/n - mu^2` is
//! therefore not 0 but, in practice, about `0.25 n EPSILON (X2/n)` (15 ulps at
//! 64 spp, 2e5 ulps at 10^6 spp: a fixed "few ulps" floor would miss it). The
//! estimator bounds this error from the sums themselves (see [`Floors`]) and
//! treats a biased variance `s2 <= floor2` as exactly 0, and likewise a third
//! moment `|m3| <= floor3` (it is pure rounding noise there, and would otherwise
//! put noise into the skew correction of `theta`). With `s2 = 0` also `m3 = 0`
//! (all samples equal) and `theta = mu`.
//!
//! What the floors cost is bounded: a zeroed `s2` was at most `floor2`, i.e. a
//! relative spread `sigma / rms <~ sqrt(3 m EPSILON)` (about 2e-7 at 64 spp,
//! 3e-5 at 10^6 spp, where `rms = sqrt(X2/n)`), far below Monte Carlo noise; a
//! zeroed `m3` moves `theta` by at most `floor3 / (6 sigma2 n)`.
//!
//! # NaN
//!
//! For finite inputs no output is NaN, including inconsistent or overflowing
//! sums: comparisons against the floors send NaN intermediates to 0, and a NaN
//! skew correction falls back to `theta = mu`. Outputs can be infinite only if
//! the sums themselves approach the f64 range.

/// Raw per-voxel, per-channel sums as stored in a bundle.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sums {
    /// Sum of transformed samples `z` over the samples that deposited something.
    pub x1: f64,
    /// Sum of `z^2`.
    pub x2: f64,
    /// Sum of `z^3`.
    pub x3: f64,
}

impl Sums {
    /// Accumulates one transformed sample `z` (one flushed path entry).
    #[inline]
    pub fn push(&mut self, z: f64) {
        let z2 = z * z;
        self.x1 += z;
        self.x2 += z2;
        self.x3 += z2 * z;
    }

    /// The SPEC's literal zero-fill: `X_k + (n - nonzero) z0^k`.
    ///
    /// [`estimate`] does not use this (it works about `z0`, see the module
    /// docs); it is here for callers that want the filled sums themselves.
    pub fn zero_filled(self, nonzero: u32, n: u64, z0: f64) -> Sums {
        let k = n.saturating_sub(u64::from(nonzero)) as f64;
        let z02 = z0 * z0;
        Sums {
            x1: self.x1 + k * z0,
            x2: self.x2 + k * z02,
            x3: self.x3 + k * (z02 * z0),
        }
    }
}

/// Estimates derived from the sums of n i.i.d. samples.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimate {
    /// Sample mean of the transformed values, `X1/n`.
    pub mu: f64,
    /// Unbiased variance `s2 n/(n-1)`; exactly 0 when `s2` is at rounding level.
    pub sigma2: f64,
    /// Third central moment `X3/n - 3 mu s2 - mu^3`; exactly 0 at rounding level.
    pub m3: f64,
    /// Skewness-corrected mean `mu + m3/(6 sigma2 n)`, `mu` when `sigma2 == 0`.
    pub theta: f64,
    /// Variance of the estimate, `sigma2/n`.
    pub v: f64,
}

/// Refuses sample counts that cannot give a variance. Call it before rendering
/// or denoising; [`estimate`] panics on `n < 2`.
pub fn check_spp(n: u64) -> Result<(), super::StatsError> {
    if n >= 2 {
        Ok(())
    } else {
        Err(super::StatsError::TooFewSamples(n))
    }
}

/// Worst-case bounds on the rounding error of the biased variance (`floor2`)
/// and of the third central moment (`floor3`) as computed by [`estimate`], from
/// nothing but the stored sums.
///
/// With `m = nonzero`, `c = z0` and the unknown `A1 = sum |z|`,
/// `A3 = sum |z|^3` over the deposited samples bounded by Cauchy-Schwarz as
/// `A1 <= sqrt(m X2')` and `A3 <= X2'^(3/2)`, the terms the moments about `c`
/// are built from have magnitudes at most
/// `B2 = X2' + 2|c| A1 + m c^2` and `B3 = A3 + 3|c| X2' + 3 c^2 A1 + m |c|^3`.
/// A first-order (Higham-style) error analysis of the one-pass sums (any
/// summation order) and of the formulas gives
/// `|error(s2)| <= (2.5 m + 9) EPSILON B2/n` and
/// `|error(m3)| <= (6.5 m + 33) EPSILON B3/n`; the floors round the constants up.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Floors {
    /// Values of the biased variance `s2` at or below this are rounding noise.
    pub floor2: f64,
    /// Values of `|m3|` at or below this are rounding noise.
    pub floor3: f64,
}

impl Floors {
    /// Computes the floors for one voxel/channel; arguments as for [`estimate`].
    pub fn new(sums: Sums, nonzero: u32, n: u64, z0: f64) -> Floors {
        let nf = n as f64;
        let m = f64::from(nonzero);
        let c = z0.abs();
        let c2 = c * c;
        let x2 = sums.x2.abs();
        let a1 = (m * x2).sqrt();
        let a3 = x2 * x2.sqrt();
        let b2 = x2 + 2.0 * c * a1 + m * c2;
        let b3 = a3 + 3.0 * c * x2 + 3.0 * c2 * a1 + m * c2 * c;
        Floors {
            floor2: (3.0 * m + 10.0) * f64::EPSILON * (b2 / nf),
            floor3: (7.0 * m + 33.0) * f64::EPSILON * (b3 / nf),
        }
    }
}

/// The estimators of SPEC 5 for one voxel and channel: zero-fill
/// (`X_k += (n - nonzero) z0^k`), then `mu`, `sigma2` (unbiased), `m3`,
/// `theta` and `V`.
///
/// - `sums`: the stored sums over the `nonzero` samples that deposited something;
/// - `n`: samples per pixel (spp), the same for every voxel;
/// - `z0`: the transform at 0 ([`Transform::at_zero`](super::transform::Transform::at_zero)).
///
/// Preconditions: `n >= 2` (checked: panics otherwise; refuse smaller spp
/// earlier with [`check_spp`]) and `nonzero <= n` (checked in debug builds).
///
/// Numerics (see the module docs): moments are taken about `z0`, `s2` is
/// clamped at 0 and set to exactly 0 at or below its rounding floor, `m3`
/// likewise, no division by zero, and no NaN for finite inputs. When all `n`
/// samples are equal, `sigma2`, `m3` and `v` are exactly 0 and `theta == mu`.
#[inline]
pub fn estimate(sums: Sums, nonzero: u32, n: u64, z0: f64) -> Estimate {
    assert!(
        n >= 2,
        "estimate: n = {n} samples cannot give a variance (need n >= 2)"
    );
    debug_assert!(
        u64::from(nonzero) <= n,
        "estimate: nonzero = {nonzero} exceeds n = {n}"
    );
    let nf = n as f64;
    let m = f64::from(nonzero);
    let c = z0;
    let Sums { x1, x2, x3 } = sums;

    // Sums of (z - c)^k over all n samples (the n - m zero samples give 0).
    let mc = m * c;
    let y1 = x1 - mc;
    let y2 = x2 - 2.0 * c * x1 + mc * c;
    let y3 = x3 - 3.0 * c * x2 + 3.0 * c * (c * x1) - mc * c * c;

    let a = y1 / nf; // mu - c
    let mu = c + a;
    let floors = Floors::new(sums, nonzero, n, z0);

    // Biased variance; `>` is false for NaN, so NaN goes to 0 as well.
    let s2_raw = y2 / nf - a * a;
    let s2 = if s2_raw > floors.floor2 { s2_raw } else { 0.0 };
    let sigma2 = s2 * (nf / (nf - 1.0));

    let m3 = if s2 == 0.0 {
        // All samples equal (to rounding): no skew.
        0.0
    } else {
        let r = y3 / nf - 3.0 * a * s2 - a * a * a;
        if r.abs() > floors.floor3 {
            r
        } else {
            0.0
        }
    };

    let theta = if sigma2 == 0.0 {
        mu
    } else {
        let t = mu + m3 / (6.0 * sigma2 * nf);
        // Backstop only: overflowing sums make the floors infinite, which
        // already zeroes s2 or m3 before an inf/inf or inf - inf can arise.
        if t.is_nan() {
            mu
        } else {
            t
        }
    };

    Estimate {
        mu,
        sigma2,
        m3,
        theta,
        v: sigma2 / nf,
    }
}

/// The estimators as the published method's own code computes them (its renderer's
/// `develop_stats`): the biased variance `s2` where SPEC 5 has `sigma2`, in the
/// skewness term and in V: `theta = mu + m3 / (6 s2 n)` (`mu` when `s2 == 0`) and
/// `V = s2 / n`. `sigma2` stays the unbiased variance. `--variance biased` asks for it
/// (`--method published` only); it accepts slightly fewer neighbours than SPEC 5's
/// unbiased V, which is the better estimate of the mean's variance, so it is the
/// default.
#[inline]
pub fn estimate_biased(sums: Sums, nonzero: u32, n: u64, z0: f64) -> Estimate {
    let e = estimate(sums, nonzero, n, z0);
    let nf = n as f64;
    // s2 as `estimate` had it: sigma2 = s2 n / (n - 1) undone (exactly 0 stays 0).
    let s2 = e.sigma2 * ((nf - 1.0) / nf);
    let theta = if s2 == 0.0 {
        e.mu
    } else {
        let t = e.mu + e.m3 / (6.0 * s2 * nf);
        if t.is_nan() {
            e.mu
        } else {
            t
        }
    };
    Estimate {
        theta,
        v: s2 / nf,
        ..e
    }
}

/// Replicate statistics (SPEC 5): the voxel's n samples form `b` replicates of
/// `k = n / b`, and `r2 = sum_b m_b^2` over the replicates' means of z (zero samples
/// included). Then `mu = (X1 + (n - nonzero) z0) / n` (the mean of the replicate
/// means), `V = (r2 / b - mu^2) / (b - 1)`, clamped at 0 and set to exactly 0 at or
/// below its rounding floor, with `b - 1` degrees of freedom; `theta = mu` (no
/// skewness correction: the replicate means are close to normal), `sigma2 = n V` (the
/// per-sample variance it implies) and `m3 = 0`. Valid whatever the correlation
/// between the samples of a replicate (stratified or low-discrepancy sets), as long
/// as the replicates are independent.
///
/// The floor: `r2 / b` and `mu^2` each carry a relative rounding error of at most
/// `(b + n + 4) EPSILON` (b squares and additions in r2; n additions in X1, doubled
/// by squaring), so a difference below `(2 b + 2 n + 8) EPSILON r2 / b` is noise.
/// When every replicate mean is equal, V is exactly 0.
#[inline]
pub fn estimate_replicates(x1: f64, r2: f64, nonzero: u32, n: u64, b: u64, z0: f64) -> Estimate {
    assert!(
        b >= 2 && n >= b,
        "estimate_replicates: {b} replicates of {n} samples (need 2 <= b <= n)"
    );
    let (nf, bf) = (n as f64, b as f64);
    let mu = (x1 + (nf - f64::from(nonzero)) * z0) / nf;
    let mean_sq = r2 / bf;
    let raw = mean_sq - mu * mu;
    let floor = (2.0 * bf + 2.0 * nf + 8.0) * f64::EPSILON * mean_sq;
    // `>` is false for NaN: NaN goes to 0 as well.
    let s2 = if raw > floor { raw } else { 0.0 };
    let v = s2 / (bf - 1.0);
    Estimate {
        mu,
        sigma2: v * nf,
        m3: 0.0,
        theta: mu,
        v,
    }
}

#[cfg(test)]
mod tests {
    use super::super::transform::Transform;
    use super::*;

    const EPS: f64 = f64::EPSILON;

    // ---- helpers -------------------------------------------------------------

    /// SplitMix64: a tiny deterministic generator for test data.
    struct Rng(u64);

    impl Rng {
        fn next_u64(&mut self) -> u64 {
            self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^ (z >> 31)
        }
        /// Uniform in (0, 1].
        fn uniform(&mut self) -> f64 {
            ((self.next_u64() >> 11) as f64 + 1.0) * (1.0 / (1u64 << 53) as f64)
        }
        /// Standard normal (Box-Muller).
        fn normal(&mut self) -> f64 {
            let (u, v) = (self.uniform(), self.uniform());
            (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
        }
        /// A radiance-like sample: 0 with probability `p_zero`, else heavy-tailed.
        fn radiance(&mut self, p_zero: f64) -> f64 {
            if self.uniform() < p_zero {
                0.0
            } else {
                let e = -self.uniform().ln();
                0.5 * e * e + 0.01
            }
        }
    }

    fn transforms() -> Vec<Transform> {
        vec![
            Transform::Identity,
            Transform::BoxCox { lambda: 0.5 },
            Transform::BoxCox { lambda: 0.3 },
            Transform::BoxCox { lambda: 2.0 },
            Transform::YeoJohnson { lambda: 0.5 },
            Transform::YeoJohnson { lambda: 0.0 },
            Transform::YeoJohnson { lambda: -0.7 },
        ]
    }

    /// Sums as the renderer accumulates them: one `push` per sample, in order.
    fn sums_of(z: impl IntoIterator<Item = f64>) -> Sums {
        let mut s = Sums::default();
        for v in z {
            s.push(v);
        }
        s
    }

    /// Neumaier (compensated) sum, for an accurate reference.
    fn accurate_sum(values: impl IntoIterator<Item = f64>) -> f64 {
        let (mut s, mut comp) = (0.0f64, 0.0f64);
        for v in values {
            let t = s + v;
            comp += if s.abs() >= v.abs() {
                (s - t) + v
            } else {
                (v - t) + s
            };
            s = t;
        }
        s + comp
    }

    /// The slow, obviously correct reference: two passes over the explicit
    /// transformed samples `z` (zeros included), compensated sums.
    #[derive(Debug)]
    struct Reference {
        mu: f64,
        s2: f64,
        sigma2: f64,
        m3: f64,
        theta: f64,
        v: f64,
    }

    fn reference(z: &[f64]) -> Reference {
        let n = z.len() as f64;
        let mean0 = accurate_sum(z.iter().copied()) / n;
        // Second pass refines the mean with the mean residual.
        let mu = mean0 + accurate_sum(z.iter().map(|&x| x - mean0)) / n;
        let d: Vec<f64> = z.iter().map(|&x| x - mu).collect();
        let s2 = accurate_sum(d.iter().map(|&d| d * d)) / n;
        let m3 = accurate_sum(d.iter().map(|&d| d * d * d)) / n;
        let sigma2 = s2 * n / (n - 1.0);
        let theta = if sigma2 == 0.0 {
            mu
        } else {
            mu + m3 / (6.0 * sigma2 * n)
        };
        Reference {
            mu,
            s2,
            sigma2,
            m3,
            theta,
            v: sigma2 / n,
        }
    }

    /// |a - b| <= tol * max(|a|, |b|, scale).
    fn close(a: f64, b: f64, tol: f64, scale: f64) -> bool {
        (a - b).abs() <= tol * a.abs().max(b.abs()).max(scale)
    }

    fn assert_no_nan(e: &Estimate, ctx: &str) {
        for (name, v) in [
            ("mu", e.mu),
            ("sigma2", e.sigma2),
            ("m3", e.m3),
            ("theta", e.theta),
            ("v", e.v),
        ] {
            assert!(!v.is_nan(), "{ctx}: {name} is NaN in {e:?}");
        }
        assert!(
            e.sigma2 >= 0.0 && e.v >= 0.0,
            "{ctx}: negative variance {e:?}"
        );
    }

    /// Compares every field with the reference, each relative to its natural
    /// scale (`rms` = sqrt of the second moment about z0 ... or about 0).
    fn assert_matches(e: &Estimate, r: &Reference, tol: f64, rms: f64, ctx: &str) {
        let ok = close(e.mu, r.mu, tol, rms)
            && close(e.sigma2, r.sigma2, tol, 0.0)
            && close(e.v, r.v, tol, 0.0)
            && close(e.m3, r.m3, tol, r.s2.powf(1.5))
            && close(e.theta, r.theta, tol, rms);
        assert!(ok, "{ctx}: tol {tol}\n  got {e:?}\n  ref {r:?}");
    }

    // ---- spp -------------------------------------------------------------------

    #[test]
    fn check_spp_refuses_fewer_than_two() {
        for n in [0, 1] {
            let err = check_spp(n).unwrap_err().to_string();
            assert!(err.contains(&format!("spp = {n}")), "{err}");
            assert!(
                err.contains("at least 2") && err.contains("variance"),
                "{err}"
            );
        }
        for n in [2, 3, 64, 1 << 40] {
            assert!(check_spp(n).is_ok());
        }
    }

    #[test]
    #[should_panic(expected = "need n >= 2")]
    fn estimate_panics_below_two_samples() {
        let _ = estimate(sums_of([1.0]), 1, 1, 0.0);
    }

    // ---- all samples equal ------------------------------------------------------

    #[test]
    fn all_equal_samples_give_exactly_zero_variance() {
        let values = [
            0.1,
            1.0 / 3.0,
            std::f64::consts::PI,
            0.7,
            1.1e-12,
            7.3e11,
            123.456,
            1e-300,
            // exactly representable, exactly summable:
            1.0,
            0.375,
            3.0,
            1024.0,
        ];
        for t in transforms() {
            for n in [2u64, 3, 10, 64, 1000, 4096, 100_000] {
                for &x in &values {
                    let z = t.apply(x);
                    let s = sums_of((0..n).map(|_| z));
                    let e = estimate(s, n as u32, n, t.at_zero());
                    let ctx = format!("{t} n={n} x={x}");
                    assert_no_nan(&e, &ctx);
                    assert_eq!(e.sigma2, 0.0, "{ctx}: {e:?}");
                    assert_eq!(e.v, 0.0, "{ctx}: {e:?}");
                    assert_eq!(e.m3, 0.0, "{ctx}: {e:?}");
                    assert_eq!(e.theta, e.mu, "{ctx}: {e:?}");
                    // The running sum itself drifts by up to ~n ulps.
                    let scale = z.abs().max(t.at_zero().abs());
                    assert!(
                        (e.mu - z).abs() <= (n as f64 + 4.0) * EPS * scale,
                        "{ctx}: mu {} vs z {z}",
                        e.mu
                    );
                }
            }
        }
        // Exactly summable values give theta == the value itself.
        for x in [1.0, 0.375, 3.0, 1024.0] {
            let n = 4096;
            let e = estimate(sums_of((0..n).map(|_| x)), n as u32, n, 0.0);
            assert_eq!(e.theta, x);
            assert_eq!(e.mu, x);
            assert_eq!(e.v, 0.0);
        }
        // Box-Cox(0.5) at 4 is z = 2 (exact), z0 = -2.
        let t = Transform::BoxCox { lambda: 0.5 };
        let e = estimate(sums_of((0..64).map(|_| 2.0)), 64, 64, t.at_zero());
        assert_eq!((e.theta, e.v), (2.0, 0.0));
    }

    /// Why the floor scales with the sample count: the spec's "few ulps" (for
    /// instance 8 EPSILON X2/n) is exceeded by plain rounding at 64 spp.
    #[test]
    fn a_fixed_few_ulp_floor_would_not_suffice() {
        let n = 64u64;
        let s = sums_of((0..n).map(|_| 0.1));
        let nf = n as f64;
        let mu = s.x1 / nf;
        let raw = s.x2 / nf - mu * mu;
        assert!(raw.abs() > 8.0 * EPS * (s.x2 / nf), "raw s2 = {raw}");
        let floors = Floors::new(s, n as u32, n, 0.0);
        assert!(raw.abs() <= floors.floor2);
        assert_eq!(estimate(s, n as u32, n, 0.0).v, 0.0);
    }

    #[test]
    fn all_zero_voxel_is_z0_with_zero_variance() {
        for t in transforms() {
            for n in [2u64, 64, 1_000_000, 1 << 40, u64::MAX] {
                let e = estimate(Sums::default(), 0, n, t.at_zero());
                let want = Estimate {
                    mu: t.at_zero(),
                    sigma2: 0.0,
                    m3: 0.0,
                    theta: t.at_zero(),
                    v: 0.0,
                };
                assert_eq!(e, want, "{t} n={n}");
            }
        }
    }

    // ---- one non-zero sample among 10^6 ----------------------------------------

    #[test]
    fn one_nonzero_sample_among_a_million() {
        let n = 1_000_000u64;
        let nf = n as f64;
        for t in transforms() {
            for x in [3.7, 0.1, 1e-12, 1e12, 1.0, 42.0] {
                let z = t.apply(x);
                let z0 = t.at_zero();
                let e = estimate(sums_of([z]), 1, n, z0);
                let ctx = format!("{t} x={x}");
                assert_no_nan(&e, &ctx);
                // Closed forms for n - 1 copies of z0 and one z; d = z - z0.
                let d = z - z0;
                let mu = z0 + d / nf;
                let sigma2 = d * d / nf;
                let m3 = d * d * d * (nf - 1.0) * (nf - 2.0) / (nf * nf * nf);
                let theta = mu + d * (nf - 1.0) * (nf - 2.0) / (6.0 * nf * nf * nf);
                let v = sigma2 / nf;
                // Identity and Yeo-Johnson (z0 = 0) and Box-Cox samples with z >= 0
                // lose nothing: 1e-12 relative. A Box-Cox sample with z < 0 lies
                // between z0 and 0, and X2 = fl(z^2) holds (z - z0)^2 only to
                // ~EPSILON z0^2 absolute: there the error is held to the floor.
                // Likewise m3 to floor3: for x = 1e-12, m3 ~ 8e-24 is far below
                // the rounding noise of the cancelled third moment and is zeroed.
                let f = Floors::new(sums_of([z]), 1, n, z0);
                let exact = z0 == 0.0 || z >= 0.0;
                let tol = if exact {
                    1e-12
                } else if d == 0.0 {
                    // Box-Cox(2) at 1e-12 rounds to z0 itself: all samples equal.
                    0.0
                } else {
                    2.0 * f.floor2 * nf / (sigma2 * (nf - 1.0))
                };
                let m3_ok = if exact {
                    close(e.m3, m3, 3e-12, 0.0)
                } else {
                    (e.m3 - m3).abs() <= f.floor3
                };
                assert!(close(e.mu, mu, 1e-12, 0.0), "{ctx}: mu {} vs {mu}", e.mu);
                assert!(
                    close(e.sigma2, sigma2, tol, 0.0),
                    "{ctx}: {} vs {sigma2}",
                    e.sigma2
                );
                assert!(close(e.v, v, tol, 0.0), "{ctx}: v {} vs {v}", e.v);
                assert!(m3_ok, "{ctx}: m3 {} vs {m3}, {f:?}", e.m3);
                assert!(
                    close(e.theta, theta, 1e-12, 0.0),
                    "{ctx}: {} vs {theta}",
                    e.theta
                );
            }
        }
    }

    // ---- huge spp ---------------------------------------------------------------

    /// Sums of `k` equal samples `z` as the product a merge of many renders
    /// approaches (one rounding each instead of `k`).
    fn sums_of_equal(k: u32, z: f64) -> Sums {
        let kf = f64::from(k);
        Sums {
            x1: kf * z,
            x2: kf * (z * z),
            x3: kf * (z * z * z),
        }
    }

    /// spp = 2^40 (a merge of many renders; a voxel's count is a u32, so at most
    /// 2^32 - 1 of its samples deposit): `k` deposits of `z` among `n` samples is a
    /// two-point distribution, `z` with p = k/n and `z0` otherwise.
    #[test]
    fn huge_spp_two_point_closed_forms() {
        let n = 1u64 << 40;
        let nf = n as f64;
        for t in transforms() {
            // x >= 1: z >= 0 for every transform, so no cancellation against z0
            // beyond the closed form's own (see one_nonzero_sample_among_a_million).
            for x in [1.0, 3.0, 7.5] {
                for k in [1u32, 1000, u32::MAX] {
                    let (z, z0) = (t.apply(x), t.at_zero());
                    let s = sums_of_equal(k, z);
                    let e = estimate(s, k, n, z0);
                    let ctx = format!("{t} x={x} k={k}: {e:?}");
                    assert_no_nan(&e, &ctx);
                    let (p, d) = (f64::from(k) / nf, z - z0);
                    let mu = z0 + p * d;
                    let sigma2 = d * d * p * (1.0 - p) * nf / (nf - 1.0);
                    let m3 = d * d * d * p * (1.0 - p) * (1.0 - 2.0 * p);
                    let theta = mu + m3 / (6.0 * sigma2 * nf);
                    let f = Floors::new(s, k, n, z0);
                    assert!(sigma2 > 10.0 * f.floor2, "{ctx}: {f:?}");
                    assert!(close(e.mu, mu, 1e-12, 0.0), "{ctx}: mu {mu}");
                    assert!(close(e.sigma2, sigma2, 1e-12, 0.0), "{ctx}: {sigma2}");
                    assert!(close(e.v, sigma2 / nf, 1e-12, 0.0), "{ctx}");
                    // The Cauchy-Schwarz bound on sum |z|^3 makes floor3 loose by
                    // sqrt(k): m3 is exact where it stands clear of it, else zeroed.
                    if m3.abs() > 2.0 * f.floor3 {
                        assert!(close(e.m3, m3, 1e-12, 0.0), "{ctx}: m3 {m3}");
                    } else {
                        assert!((e.m3 - m3).abs() <= f.floor3, "{ctx}: m3 {m3}, {f:?}");
                    }
                    // theta - mu = m3 / (6 sigma2 n) is ~1e-13 of mu here unless
                    // k = 1, where it is 1/6 of mu - z0: there it must be exact.
                    assert!(
                        close(e.theta - z0, theta - z0, 1e-12, 0.0),
                        "{ctx}: theta {theta}"
                    );
                }
            }
        }
    }

    /// The largest voxel where every sample deposits: n = k = 2^32 - 1 equal values.
    /// X2/n - mu^2 cancels completely and must come out exactly 0; a spread of a
    /// few per cent must survive the cancellation.
    #[test]
    fn huge_spp_cancellation() {
        let k = u32::MAX;
        let n = u64::from(k);
        for z in [0.1, std::f64::consts::PI, 1.1e-12, 7.3e11, 1e100, 1e-100] {
            let e = estimate(sums_of_equal(k, z), k, n, 0.0);
            let ctx = format!("z={z}: {e:?}");
            assert_no_nan(&e, &ctx);
            assert_eq!((e.sigma2, e.v, e.m3), (0.0, 0.0, 0.0), "{ctx}");
            assert_eq!(e.theta, e.mu, "{ctx}");
            assert!(close(e.mu, z, 4.0 * EPS, 0.0), "{ctx}");
            // Half the samples z, half z (1 + delta): s2 = (z delta / 2)^2, about
            // 400 times below X2/n for delta = 0.1; the floor is ~3e-6 X2/n.
            let delta = 0.1;
            let (a, b) = (
                sums_of_equal(k / 2, z),
                sums_of_equal(k - k / 2, z * (1.0 + delta)),
            );
            let s = Sums {
                x1: a.x1 + b.x1,
                x2: a.x2 + b.x2,
                x3: a.x3 + b.x3,
            };
            let e = estimate(s, k, n, 0.0);
            let (pa, nf) = (f64::from(k / 2) / n as f64, n as f64);
            let dz = z * delta;
            let s2 = dz * dz * pa * (1.0 - pa);
            assert!(
                close(e.sigma2, s2 * nf / (nf - 1.0), 1e-12, 0.0),
                "{ctx}: sigma2 {} vs {}",
                e.sigma2,
                s2 * nf / (nf - 1.0)
            );
        }
    }

    // ---- values near the f64 limits ------------------------------------------------

    /// Samples spread by 5% around 1e100 and 1e-100 (cubes still normal f64): as
    /// accurate as anywhere (m3 to its floor). Around 1e150 the cubes overflow:
    /// X3 = inf zeroes m3 (theta = mu) while mu and the variance stay accurate. Around 1e-160 the squares
    /// are subnormal: the variance is lost to underflow, but never NaN or
    /// negative, and mu is exact.
    #[test]
    fn values_near_the_f64_limits() {
        let mut rng = Rng(21);
        let n = 1000usize;
        for scale in [1e100, 1e-100, 1e150, 1e-160] {
            let z: Vec<f64> = (0..n)
                .map(|_| scale * (1.0 + 0.05 * rng.normal()))
                .collect();
            let s = sums_of(z.iter().copied());
            let e = estimate(s, n as u32, n as u64, 0.0);
            let r = reference(&z);
            let ctx = format!("scale {scale}: {s:?} {e:?} vs {r:?}");
            assert_no_nan(&e, &ctx);
            assert!(close(e.mu, r.mu, 1e-12, 0.0), "{ctx}");
            if scale == 1e150 {
                assert!(s.x3.is_infinite() && s.x2.is_finite(), "{ctx}");
                assert_eq!((e.m3, e.theta), (0.0, e.mu), "{ctx}");
                assert!(close(e.sigma2, r.sigma2, 1e-11, 0.0), "{ctx}");
            } else if scale == 1e-160 {
                assert!(s.x2 < f64::MIN_POSITIVE, "{ctx}");
                assert!(e.sigma2 <= 2.0 * r.sigma2 + 1e-300, "{ctx}");
            } else {
                // X2/n - mu^2 cancels by a factor ~400 (s2 good to ~1e-13); the
                // third moment cancels by ~6e4 and is held to its floor.
                let f = Floors::new(s, n as u32, n as u64, 0.0);
                assert!(close(e.sigma2, r.sigma2, 1e-12, 0.0), "{ctx}");
                assert!(close(e.v, r.v, 1e-12, 0.0), "{ctx}");
                assert!((e.m3 - r.m3).abs() <= f.floor3, "{ctx}: {f:?}");
                assert!(close(e.theta, r.theta, 1e-12, 0.0), "{ctx}");
            }
        }
    }

    // ---- wide dynamic range ----------------------------------------------------

    #[test]
    fn values_from_1e_minus_12_to_1e12() {
        let mut rng = Rng(7);
        for t in transforms() {
            // Log-uniform over 24 decades, a third of the samples zero.
            let n = 3000usize;
            let x: Vec<f64> = (0..n)
                .map(|_| {
                    if rng.uniform() < 1.0 / 3.0 {
                        0.0
                    } else {
                        10f64.powf(-12.0 + 24.0 * rng.uniform())
                    }
                })
                .collect();
            let z: Vec<f64> = x.iter().map(|&v| t.apply(v)).collect();
            let deposited: Vec<f64> = x
                .iter()
                .zip(&z)
                .filter(|(&v, _)| v != 0.0)
                .map(|(_, &z)| z)
                .collect();
            let e = estimate(
                sums_of(deposited.iter().copied()),
                deposited.len() as u32,
                n as u64,
                t.at_zero(),
            );
            let r = reference(&z);
            assert_no_nan(&e, &t.to_string());
            assert!(e.sigma2 > 0.0);
            // The largest samples dominate every moment, so nothing cancels:
            // agreement to the one-pass summation error, n EPSILON ~ 7e-13.
            let rms = r.s2.sqrt() + r.mu.abs();
            assert_matches(&e, &r, 1e-12, rms, &t.to_string());
        }
    }

    // ---- large offset, small spread ----------------------------------------------

    #[test]
    fn large_offset_with_small_spread() {
        let mut rng = Rng(11);
        let n = 1000usize;
        for spread in [1e4, 1e3, 1e2, 10.0, 1.0, 1e-3] {
            let z: Vec<f64> = (0..n).map(|_| 1e8 + spread * rng.normal()).collect();
            let s = sums_of(z.iter().copied());
            let e = estimate(s, n as u32, n as u64, 0.0);
            let r = reference(&z);
            let f = Floors::new(s, n as u32, n as u64, 0.0);
            let ctx = format!("spread {spread}: {e:?} vs {r:?}, floors {f:?}");
            assert_no_nan(&e, &ctx);
            // The contract: the one-pass s2 is within its documented rounding
            // bound of the two-pass value, or zeroed when below that bound.
            let s2 = e.sigma2 * (n as f64 - 1.0) / n as f64;
            assert!((s2 - r.s2).abs() <= f.floor2, "{ctx}");
            if r.s2 > 2.0 * f.floor2 {
                assert!(e.sigma2 > 0.0, "{ctx}");
            }
            // floor2 = (3n + 10) EPSILON X2/n ~ 6.7e3 here (X2/n = 1e16): the
            // resolvable spread is ~80, and a spread of 1e3 is good to ~1%.
            if spread >= 1e3 {
                assert!(close(e.sigma2, r.sigma2, 1e-2, 0.0), "{ctx}");
            }
            if spread <= 1.0 {
                assert_eq!(e.sigma2, 0.0, "{ctx}");
            }
            // The cancelled third moment is noise (~n EPSILON 1e24): it must not
            // move theta by more than a fraction of the standard error.
            assert!((e.theta - e.mu).abs() <= 0.1 * e.v.sqrt(), "{ctx}");
            assert!((e.mu - r.mu).abs() <= n as f64 * EPS * 1e8, "{ctx}");
        }
    }

    #[test]
    fn tiny_resolvable_variance_survives_the_floor() {
        // Samples 1 + k 1e-6, k = 0..9: s2 = 8.25e-12 is ~900x the floor
        // (floor2 = 40 EPSILON X2/n ~ 8.9e-15).
        let z: Vec<f64> = (0..10).map(|k| 1.0 + k as f64 * 1e-6).collect();
        let s = sums_of(z.iter().copied());
        let e = estimate(s, 10, 10, 0.0);
        let r = reference(&z);
        let f = Floors::new(s, 10, 10, 0.0);
        assert!(e.sigma2 > 0.0);
        assert!(f.floor2 < 2e-3 * r.s2, "{f:?} {r:?}");
        assert!((e.sigma2 * 0.9 - r.s2).abs() <= f.floor2, "{e:?} {r:?}");
    }

    // ---- zero-fill ---------------------------------------------------------------

    #[test]
    fn zero_fill_matches_explicit_zeros_for_every_transform() {
        let mut rng = Rng(3);
        for t in transforms() {
            for (n, p_zero) in [(997usize, 0.6), (64, 0.9), (5000, 0.3), (10, 0.5)] {
                let x: Vec<f64> = (0..n).map(|_| rng.radiance(p_zero)).collect();
                let z: Vec<f64> = x.iter().map(|&v| t.apply(v)).collect();
                let nonzero = x.iter().filter(|&&v| v != 0.0).count();
                let implicit = estimate(
                    sums_of(x.iter().zip(&z).filter(|(&v, _)| v != 0.0).map(|(_, &z)| z)),
                    nonzero as u32,
                    n as u64,
                    t.at_zero(),
                );
                let explicit =
                    estimate(sums_of(z.iter().copied()), n as u32, n as u64, t.at_zero());
                let r = reference(&z);
                let ctx = format!("{t} n={n} nonzero={nonzero}");
                assert_no_nan(&implicit, &ctx);
                assert_no_nan(&explicit, &ctx);
                let rms = (r.s2 + r.mu * r.mu).sqrt();
                let as_ref = |e: &Estimate| Reference {
                    mu: e.mu,
                    s2: e.sigma2 * (n as f64 - 1.0) / n as f64,
                    sigma2: e.sigma2,
                    m3: e.m3,
                    theta: e.theta,
                    v: e.v,
                };
                assert_matches(&implicit, &as_ref(&explicit), 1e-12, rms, &ctx);
                assert_matches(&implicit, &r, 1e-12, rms, &format!("{ctx} vs reference"));
            }
        }
    }

    #[test]
    fn agrees_with_the_spec_literal_formulas() {
        // The spec's arithmetic, verbatim: zero-fill, then raw moments.
        fn literal(s: Sums, nonzero: u32, n: u64, z0: f64) -> Estimate {
            let f = s.zero_filled(nonzero, n, z0);
            let nf = n as f64;
            let mu = f.x1 / nf;
            let s2 = (f.x2 / nf - mu * mu).max(0.0);
            let sigma2 = s2 * nf / (nf - 1.0);
            let m3 = f.x3 / nf - 3.0 * mu * s2 - mu * mu * mu;
            let theta = mu + m3 / (6.0 * sigma2 * nf);
            Estimate {
                mu,
                sigma2,
                m3,
                theta,
                v: sigma2 / nf,
            }
        }
        let mut rng = Rng(5);
        for t in transforms() {
            for _ in 0..20 {
                let n = 64u64;
                let x: Vec<f64> = (0..n).map(|_| rng.radiance(0.4)).collect();
                let dep: Vec<f64> = x
                    .iter()
                    .filter(|&&v| v != 0.0)
                    .map(|&v| t.apply(v))
                    .collect();
                let s = sums_of(dep.iter().copied());
                let a = estimate(s, dep.len() as u32, n, t.at_zero());
                let b = literal(s, dep.len() as u32, n, t.at_zero());
                let rms = (b.sigma2 + b.mu * b.mu).sqrt();
                let ok = close(a.mu, b.mu, 1e-12, rms)
                    && close(a.sigma2, b.sigma2, 1e-12, 0.0)
                    && close(a.m3, b.m3, 1e-11, b.sigma2.powf(1.5))
                    && close(a.theta, b.theta, 1e-12, rms)
                    && close(a.v, b.v, 1e-12, 0.0);
                assert!(ok, "{t}: {a:?} vs literal {b:?}");
            }
        }
        // And the literal zero-fill helper itself.
        let s = Sums {
            x1: 1.0,
            x2: 2.0,
            x3: 3.0,
        }
        .zero_filled(2, 5, -2.0);
        assert_eq!(
            s,
            Sums {
                x1: -5.0,
                x2: 14.0,
                x3: -21.0
            }
        );
    }

    // ---- small hand-checkable cases ----------------------------------------------

    #[test]
    fn n_equals_two_closed_form() {
        // Two samples a, b: mu = (a+b)/2, sigma2 = (a-b)^2/2, m3 = 0, V = sigma2/2.
        let e = estimate(sums_of([1.0, 3.0]), 2, 2, 0.0);
        assert_eq!(
            e,
            Estimate {
                mu: 2.0,
                sigma2: 2.0,
                m3: 0.0,
                theta: 2.0,
                v: 1.0
            }
        );
        for t in transforms() {
            for (xa, xb) in [(0.1, 0.7), (0.0, 5.0), (2.5, 1e-9), (1e6, 1e6 + 1.0)] {
                let (za, zb) = (t.apply(xa), t.apply(xb));
                let dep: Vec<f64> = [(xa, za), (xb, zb)]
                    .iter()
                    .filter(|(x, _)| *x != 0.0)
                    .map(|&(_, z)| z)
                    .collect();
                let s = sums_of(dep.iter().copied());
                let e = estimate(s, dep.len() as u32, 2, t.at_zero());
                let ctx = format!("{t} ({xa}, {xb}): {e:?}");
                let mu = 0.5 * (za + zb);
                let sigma2 = 0.5 * (za - zb) * (za - zb);
                let f = Floors::new(s, dep.len() as u32, 2, t.at_zero());
                assert!(close(e.mu, mu, 1e-15, 0.0), "{ctx}");
                assert!(
                    (e.sigma2 - sigma2).abs() <= 2.0 * f.floor2 + 1e-15 * sigma2,
                    "{ctx}"
                );
                assert!(close(e.v, 0.5 * e.sigma2, 0.0, 0.0), "{ctx}");
                // Two points are never skewed: m3 = 0, theta = mu (to rounding).
                assert!(e.m3.abs() <= f.floor3, "{ctx}");
                assert!(close(e.theta, e.mu, 1e-15, 0.0), "{ctx}");
            }
        }
    }

    #[test]
    fn theta_skew_correction_by_hand() {
        // Samples 1, 2, 6: mean 3, deviations -2, -1, 3;
        // s2 = 14/3, sigma2 = 7, m3 = (-8 - 1 + 27)/3 = 6,
        // theta = 3 + 6/(6 * 7 * 3) = 3 + 1/21, V = 7/3.
        let e = estimate(sums_of([1.0, 2.0, 6.0]), 3, 3, 0.0);
        assert!(close(e.mu, 3.0, 1e-15, 0.0), "{e:?}");
        assert!(close(e.sigma2, 7.0, 1e-15, 0.0), "{e:?}");
        assert!(close(e.m3, 6.0, 1e-14, 0.0), "{e:?}");
        assert!(close(e.theta, 3.0 + 1.0 / 21.0, 1e-15, 0.0), "{e:?}");
        assert!(close(e.v, 7.0 / 3.0, 1e-15, 0.0), "{e:?}");

        // Samples 0, 0, 0, 4 with the zeros implicit: mean 1, deviations
        // -1, -1, -1, 3; s2 = 3, sigma2 = 4, m3 = 24/4 = 6,
        // theta = 1 + 6/(6 * 4 * 4) = 1.0625, V = 1.
        let e = estimate(sums_of([4.0]), 1, 4, 0.0);
        let want = Estimate {
            mu: 1.0,
            sigma2: 4.0,
            m3: 6.0,
            theta: 1.0625,
            v: 1.0,
        };
        assert_eq!(e, want);

        // The same under Box-Cox(0.5): z = -2, -2, -2, 2 (x = 0, 0, 0, 4) is the
        // previous sample shifted by -2: same spread and skew, theta shifted.
        let t = Transform::BoxCox { lambda: 0.5 };
        let e = estimate(sums_of([t.apply(4.0)]), 1, 4, t.at_zero());
        assert!(close(e.mu, -1.0, 1e-15, 0.0), "{e:?}");
        assert!(close(e.sigma2, 4.0, 1e-15, 0.0), "{e:?}");
        assert!(close(e.m3, 6.0, 1e-14, 0.0), "{e:?}");
        assert!(close(e.theta, -1.0 + 0.0625, 1e-15, 0.0), "{e:?}");
        assert!(close(e.v, 1.0, 1e-15, 0.0), "{e:?}");

        // Negative skew: 0, 4, 4, 4 -> mean 3, deviations -3, 1, 1, 1;
        // s2 = 3, sigma2 = 4, m3 = -6, theta = 3 - 1/16.
        let e = estimate(sums_of([4.0, 4.0, 4.0]), 3, 4, 0.0);
        assert!(close(e.m3, -6.0, 1e-14, 0.0), "{e:?}");
        assert!(close(e.theta, 3.0 - 0.0625, 1e-15, 0.0), "{e:?}");
    }

    // ---- robustness --------------------------------------------------------------

    #[test]
    fn never_nan_for_finite_inputs() {
        let vals = [
            0.0,
            -0.0,
            1.0,
            -1.0,
            5e-324,
            1e-300,
            -1e-300,
            1e300,
            -1e300,
            f64::MAX,
            -f64::MAX,
            f64::MIN_POSITIVE,
            3.7,
            // Near sqrt(f64::MAX): squares stay finite, cubes and products overflow.
            1e154,
            -1e154,
        ];
        let mut count = 0;
        for &x1 in &vals {
            for &x2 in &vals {
                for &x3 in &vals {
                    for &z0 in &[0.0, -2.0, -1e300, 1e300, -f64::MAX] {
                        for &(nonzero, n) in
                            &[(0u32, 2u64), (1, 2), (2, 2), (1, 1_000_000), (7, u64::MAX)]
                        {
                            let e = estimate(Sums { x1, x2, x3 }, nonzero, n, z0);
                            assert_no_nan(&e, &format!("{x1} {x2} {x3} z0 {z0} {nonzero}/{n}"));
                            count += 1;
                        }
                    }
                }
            }
        }
        assert!(count > 10_000);
    }

    #[test]
    fn variance_never_negative_on_random_voxels() {
        let mut rng = Rng(99);
        for t in transforms() {
            for _ in 0..2000 {
                let n = 2 + (rng.next_u64() % 200);
                let p = rng.uniform();
                let dep: Vec<f64> = (0..n)
                    .map(|_| rng.radiance(p))
                    .filter(|&v| v != 0.0)
                    .map(|v| t.apply(v))
                    .collect();
                let e = estimate(
                    sums_of(dep.iter().copied()),
                    dep.len() as u32,
                    n,
                    t.at_zero(),
                );
                assert_no_nan(&e, &t.to_string());
                assert_eq!(e.sigma2 == 0.0, e.v == 0.0);
            }
        }
    }

    #[test]
    fn push_accumulates_powers() {
        let s = sums_of([2.0, -1.0, 0.5]);
        assert_eq!(
            s,
            Sums {
                x1: 1.5,
                x2: 5.25,
                x3: 7.125
            }
        );
    }

    // ---- replicate statistics ----

    /// R2, X1 and the count of a voxel from its samples `z` (zeros as `None`) split
    /// into `b` consecutive replicates, as the renderer accumulates them.
    fn replicate_sums(z: &[Option<f64>], b: usize, z0: f64) -> (f64, f64, u32) {
        let k = z.len() / b;
        let (mut x1, mut r2, mut nonzero) = (0.0, 0.0, 0u32);
        for rep in z.chunks(k) {
            let (mut s, mut c) = (0.0, 0.0);
            for v in rep.iter().flatten() {
                s += v;
                c += 1.0;
                x1 += v;
                nonzero += 1;
            }
            let m = (s + (k as f64 - c) * z0) / k as f64;
            r2 += m * m;
        }
        (x1, r2, nonzero)
    }

    /// Against a two-pass computation: the sample variance of the replicate means
    /// (explicit zeros become z0) over B, in f64 with compensated sums.
    #[test]
    fn replicate_variance_matches_two_pass() {
        let mut rng = crate::math::rng::Pcg32::new(7, 11);
        for t in transforms() {
            let z0 = t.at_zero();
            for (n, b) in [(64usize, 8usize), (32, 2), (48, 16), (1000, 10)] {
                let z: Vec<Option<f64>> = (0..n)
                    .map(|_| {
                        let u = rng.next_f32() as f64;
                        (u > 0.4).then(|| t.apply(3.0 * u * u))
                    })
                    .collect();
                let (x1, r2, nonzero) = replicate_sums(&z, b, z0);
                let e = estimate_replicates(x1, r2, nonzero, n as u64, b as u64, z0);
                let k = n / b;
                let means: Vec<f64> = z
                    .chunks(k)
                    .map(|r| accurate_sum(r.iter().map(|v| v.unwrap_or(z0))) / k as f64)
                    .collect();
                let mu = accurate_sum(means.iter().copied()) / b as f64;
                let var =
                    accurate_sum(means.iter().map(|m| (m - mu) * (m - mu))) / (b as f64 - 1.0);
                let ctx = format!("{t:?} n {n} b {b}");
                assert!(
                    close(e.mu, mu, 1e-12, mu.abs().max(1.0)),
                    "{ctx}: mu {} vs {mu}",
                    e.mu
                );
                assert_eq!(e.theta, e.mu, "{ctx}");
                assert!(
                    close(e.v, var / b as f64, 1e-9, var / b as f64 + mu * mu * 1e-12),
                    "{ctx}: v {} vs {}",
                    e.v,
                    var / b as f64
                );
            }
        }
    }

    /// Equal replicate means (however the samples inside differ) give exactly V = 0;
    /// so do all-zero voxels under every transform.
    #[test]
    fn equal_replicate_means_give_exactly_zero_variance() {
        for t in transforms() {
            let z0 = t.at_zero();
            for (n, b) in [(64usize, 8usize), (2, 2), (1 << 16, 16)] {
                // Each replicate: the same multiset of values in another order.
                let k = n / b;
                let z: Vec<Option<f64>> = (0..n)
                    .map(|i| {
                        let j = (i % k + i / k) % k;
                        (j % 3 != 0).then(|| t.apply(0.1 + j as f64 * 0.37))
                    })
                    .collect();
                let (x1, r2, nonzero) = replicate_sums(&z, b, z0);
                let e = estimate_replicates(x1, r2, nonzero, n as u64, b as u64, z0);
                assert_eq!(e.v, 0.0, "{t:?} n {n} b {b}: v {}", e.v);
                assert_no_nan(&e, "equal");
                let empty = estimate_replicates(0.0, b as f64 * z0 * z0, 0, n as u64, b as u64, z0);
                assert_eq!((empty.v, empty.mu), (0.0, z0), "{t:?}: empty voxel");
            }
        }
    }

    #[test]
    #[should_panic(expected = "need 2 <= b <= n")]
    fn one_replicate_is_refused() {
        estimate_replicates(1.0, 1.0, 1, 4, 1, 0.0);
    }
}

#[cfg(test)]
mod published_convention_tests {
    use super::*;

    /// `estimate_biased` against the published code's formulas written out (its
    /// `develop_stats`: zero-fill, `mu = S1 / n`, `var = S2 / n - mu^2` clamped at 0,
    /// `m3 = S3 / n - 3 mu var - mu^3`, estimand `mu + m3 / (6 var n)`, variance
    /// `var / n`), on samples given one by one, zeros included, for the identity and
    /// Yeo-Johnson (z0 = 0) and Box-Cox (z0 = -2).
    #[test]
    fn the_biased_convention_is_the_published_codes() {
        let cases: [(&[f64], usize, f64); 4] = [
            (&[0.5, 2.0, 7.0], 8, 0.0),
            (&[1.0, 1.0, 1.0, 1.0], 4, 0.0),
            (&[0.3, 0.9], 64, 0.0),
            (&[0.25, 4.0, 1.0], 5, -2.0),
        ];
        for (nonzero_values, n, z0) in cases {
            let mut all = nonzero_values.to_vec();
            all.resize(n, z0);
            let nf = n as f64;
            let (s1, s2s, s3): (f64, f64, f64) = (
                all.iter().sum(),
                all.iter().map(|z| z * z).sum(),
                all.iter().map(|z| z * z * z).sum(),
            );
            let mu = s1 / nf;
            let var = (s2s / nf - mu * mu).max(0.0);
            let m3 = s3 / nf - 3.0 * mu * var - mu.powi(3);
            let want_theta = if var == 0.0 {
                mu
            } else {
                mu + m3 / (6.0 * var * nf)
            };
            let sums = Sums {
                x1: nonzero_values.iter().sum(),
                x2: nonzero_values.iter().map(|z| z * z).sum(),
                x3: nonzero_values.iter().map(|z| z * z * z).sum(),
            };
            let e = estimate_biased(sums, nonzero_values.len() as u32, n as u64, z0);
            let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * (1.0 + b.abs());
            assert!(close(e.theta, want_theta), "{e:?} {want_theta}");
            assert!(close(e.v, var / nf), "{e:?} {}", var / nf);
            // The unbiased convention differs wherever there is spread.
            let u = estimate(sums, nonzero_values.len() as u32, n as u64, z0);
            assert!(close(u.v, var / (nf - 1.0)));
            if var > 0.0 {
                assert!(e.v < u.v);
            }
        }
    }
}
