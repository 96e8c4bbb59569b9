//! tstat's membership (the default method; SPEC 8 describes the published one):
//!
//! 1. **Classes.** Pixels that see an emitter directly (emitter G-buffer > 0) and pixels
//!    that do not are never neighbours. Emitter pixels are filtered purely spatially
//!    (no bin offsets) over a wider radius `r_e`, with the spatial sigma scaled by
//!    `r_e / r`: their signal is one bin of direct emission whose value only coverage
//!    at the light's edge changes. Two emitter pixels are neighbours only when their
//!    covered fractions agree ([`same_coverage`], with Agresti-Coull variances so that a
//!    pixel wholly inside the light is not set apart from one that missed it a few
//!    times). With stratified sub-pixel positions the default `r_e` is 0 (see
//!    [`TstatParams::emitter_radius`]).
//! 2. **Camera-depth alignment.** Voxel (p, t) is compared with (q, t + dt + k),
//!    `k = round((depth_q - depth_p) / h)` (h the bin width in OPL; k = 0 when either
//!    pixel saw nothing): the same light reaches a farther surface later, so the
//!    transient of q is that of p delayed by the extra camera distance (the transient
//!    analogue of motion compensation).
//! 3. **Patch test.** With the per-channel maximum of the Welch statistic
//!    `s(t) = max_c (theta_q - theta_p)^2 / (V_q + V_p)` (0 when d = V = 0, infinite
//!    when V = 0 and d != 0), a neighbour at one offset passes at bin t when
//!    `s(t) <= t2_max` and `(s(t-1) + s(t) + s(t+1)) / 3 <= t2_patch`; at the ends of the
//!    range where both voxels exist, the missing side repeats s(t). The patch mean
//!    rejects neighbours that pass a single voxel's test by chance but differ over
//!    their bins (the blotches of the per-voxel test at low spp). A side where both
//!    voxels are empty also repeats s(t) on images ([`patch_member`],
//!    [`TstatParams::isolated_bins_alone`]): a one-bin signal such as a small bright
//!    source's highlight is judged on its own bin, not on a mean diluted by zeros.
//!
//! As spp grows V shrinks like 1/n, so any fixed difference in expectation eventually
//! fails the test: the filter is consistent. The centre voxel always passes (s = 0).

/// Parameters of tstat's membership.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TstatParams {
    /// Per-voxel bound on s (a t^2 value).
    pub t2_max: f64,
    /// Bound on the mean of s over bins t-1..t+1.
    pub t2_patch: f64,
    /// Spatial radius for pixels that see an emitter; `None`: 4r for independent
    /// sub-pixel positions, 0 (left as rendered) for stratified ones.
    pub emitter_radius: Option<usize>,
    /// Camera-depth time alignment.
    pub depth_align: bool,
    /// Judge a bin whose sides hold nothing (both voxels empty) on s(t) alone instead of
    /// letting the empty sides' zeros dilute the patch mean ([`patch_member`]). On for
    /// images; off on NLOS captures (`adapt_to_nlos`), where at low counts nearly every
    /// occupied bin is isolated and judging it alone costs the reconstructions their
    /// gain (docs/denoiser.md).
    pub isolated_bins_alone: bool,
}

impl Default for TstatParams {
    fn default() -> Self {
        TstatParams {
            t2_max: 4.0,
            t2_patch: 2.0,
            emitter_radius: None,
            depth_align: true,
            isolated_bins_alone: true,
        }
    }
}

impl TstatParams {
    pub fn validate(&self) -> Result<(), super::DenoiseError> {
        for (flag, value) in [("--t2-max", self.t2_max), ("--t2-patch", self.t2_patch)] {
            if !(value > 0.0 && value.is_finite()) {
                return Err(super::DenoiseError::NotPositive { flag, value });
            }
        }
        if let Some(r) = self.emitter_radius {
            if r > 64 {
                return Err(super::DenoiseError::EmitterRadius(r));
            }
        }
        Ok(())
    }

    /// The emitter pixels' radius for spatial radius `r`. With stratified positions
    /// the light's pixels hold little noise (their noise is coverage, which
    /// stratification removes), while their i.i.d. variance estimate over-states it,
    /// so the test would let different coverages mix: they are left as rendered.
    pub fn emitter_radius(&self, r: usize, stratified: bool) -> usize {
        match self.emitter_radius {
            Some(re) => re,
            None if stratified => 0,
            None => 4 * r,
        }
    }
}

/// What [`statistic`] returns for a pair that holds no information (d = 0 and V = 0:
/// in practice two empty voxels). Every other value is >= 0. The per-voxel bound reads
/// it as 0 (agreement); the patch mean reads it as [`patch_member`] says, so that on
/// images empty bins beside a one-bin signal (a highlight) do not dilute the mean.
pub const UNINFORMATIVE: f32 = -1.0;

/// One channel's Welch statistic `d^2 / V` with `d = theta_i - theta_j`,
/// `V = v_i + v_j`: [`UNINFORMATIVE`] when d = 0 and V = 0, infinite when V = 0 and
/// d != 0. The maximum over channels is uninformative only when every channel is.
#[inline(always)]
pub fn statistic(theta_i: f32, theta_j: f32, v_i: f32, v_j: f32) -> f32 {
    let d = theta_i - theta_j;
    let v = v_i + v_j;
    let q = d * d / v;
    if v > 0.0 {
        q
    } else if d == 0.0 {
        UNINFORMATIVE
    } else {
        f32::INFINITY
    }
}

/// tstat's membership at bin t from the statistic at t - 1, t, t + 1: `s(t) <= t2_max`
/// and `(s(t-1) + s(t) + s(t+1)) / 3 <= t2_patch`, where an uninformative s(t) counts
/// as 0 and an uninformative side as s(t) when `alone`, else as 0. The filter passes
/// `alone` = [`TstatParams::isolated_bins_alone`] and not an emitter pixel.
///
/// Why the two: a one-bin signal beside empty bins (a highlight of a small bright
/// source) would otherwise pass at `s(t) <= 3 t2_patch`, looser than the patch bound
/// meant, and there the neighbours' bias shows (envmap_spheres at 512 spp: denoised
/// worse than noisy). Emitter pixels are guarded by the coverage test instead, their
/// direct emission is a pulse a bin or two long by construction, and judging its
/// first bin on s(t) alone cost them a fifth of their gain on the box
/// (docs/denoiser.md).
#[inline(always)]
pub fn patch_member(sp: f32, sc: f32, sn: f32, t2_max: f32, t2_patch3: f32, alone: bool) -> bool {
    let c = sc.max(0.0);
    let side = if alone { c } else { 0.0 };
    let p = if sp < 0.0 { side } else { sp };
    let n = if sn < 0.0 { side } else { sn };
    (c <= t2_max) & (p + c + n <= t2_patch3)
}

/// The bin shift k of neighbour q for pixel p: camera depths (0 = saw nothing) over
/// the bin width h, rounded to the nearest bin (halves away from zero).
#[inline]
pub fn depth_shift(depth_p: f32, depth_q: f32, h: f64) -> i64 {
    if depth_p > 0.0 && depth_q > 0.0 && h > 0.0 {
        let k = ((depth_q as f64 - depth_p as f64) / h).round();
        // Depths are finite film-scale distances; the clamp only guards absurd inputs.
        k.clamp(-(1i64 << 40) as f64, (1i64 << 40) as f64) as i64
    } else {
        0
    }
}

/// Whether two emitter pixels saw the light over the same fraction of their `n_i` and
/// `n_j` samples (their footprints cover the light alike), by the same Welch bound as
/// the voxels: `(f_i - f_j)^2 <= t2_max (f_i (1 - f_i) / n_i + f_j (1 - f_j) / n_j)`,
/// the binomial variances of the two fractions. Equal fractions pass; different ones
/// with zero variance (both 0 or 1) fail.
#[inline]
pub fn same_coverage(f_i: f32, f_j: f32, n_i: u64, n_j: u64, t2_max: f64) -> bool {
    let (f_i, f_j) = (f_i as f64, f_j as f64);
    let d = f_i - f_j;
    let v = adjusted_variance(f_i, n_i) + adjusted_variance(f_j, n_j);
    d == 0.0 || d * d <= t2_max * v
}

/// Agresti-Coull: the variance of a fraction `f` of `n` samples, from the
/// estimate with two successes and two failures added, `p = (f n + 2) / (n + 4)`,
/// `p (1 - p) / (n + 4)`. Unlike `f (1 - f) / n` it is not 0 at f = 1, where a pixel
/// fully inside the light would otherwise differ "significantly" from one that
/// missed it once in 512 samples.
#[inline]
fn adjusted_variance(f: f64, n: u64) -> f64 {
    let n = n.max(1) as f64;
    let p = (f * n + 2.0) / (n + 4.0);
    p * (1.0 - p) / (n + 4.0)
}

/// Whether a pixel belongs to the emitter class.
#[inline]
pub fn sees_emitter(emitter_fraction: f32) -> bool {
    emitter_fraction > 0.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn statistic_edge_cases_and_symmetry() {
        assert_eq!(statistic(1.0, 1.0, 0.0, 0.0), UNINFORMATIVE);
        assert_eq!(statistic(0.0, 0.0, 0.0, 0.0), UNINFORMATIVE);
        assert_eq!(statistic(0.0, 0.0, 0.0, 1.0), 0.0);
        assert_eq!(statistic(1.0, 1.5, 0.0, 0.0), f32::INFINITY);
        // d * d underflows but d != 0 with V = 0 still fails every bound.
        assert_eq!(statistic(1e-23, 2e-23, 0.0, 0.0), f32::INFINITY);
        assert_eq!(statistic(3.0, 1.0, 0.5, 1.5), 2.0);
        assert_eq!(statistic(3.0, 1.0, 0.5, 1.5), statistic(1.0, 3.0, 1.5, 0.5));
    }

    #[test]
    fn empty_sides_do_not_dilute_the_patch_mean() {
        let u = UNINFORMATIVE;
        // A one-bin signal: s(t) = 1.9 beside two empty bins is judged on 1.9 alone.
        assert!(!patch_member(u, 1.9, u, 4.0, 3.0 * 1.5, true));
        assert!(patch_member(u, 1.4, u, 4.0, 3.0 * 1.5, true));
        // Informative sides count as they are; an empty centre counts as 0.
        assert!(patch_member(0.0, 1.9, 0.0, 4.0, 3.0 * 1.5, true));
        assert!(patch_member(3.0, u, 3.0, 4.0, 3.0 * 2.0, true));
        assert!(!patch_member(3.5, u, 3.5, 4.0, 3.0 * 2.0, true));
        assert!(!patch_member(0.0, 4.5, 0.0, 4.0, 3.0 * 2.0, true));
        // One empty side repeats s(t).
        assert!(!patch_member(u, 2.5, 0.5, 4.0, 3.0 * 1.8, true));
        assert!(patch_member(0.5, 2.5, 0.5, 4.0, 3.0 * 1.8, true));
        // Not alone (emitter pixels, NLOS captures): empty sides count as 0.
        assert!(patch_member(u, 1.9, u, 4.0, 3.0 * 1.5, false));
        assert!(patch_member(u, 2.5, 0.5, 4.0, 3.0 * 1.8, false));
        assert!(!patch_member(u, 4.5, u, 4.0, 3.0 * 2.0, false));
    }

    #[test]
    fn depth_shift_rounds_to_nearest_and_ignores_misses() {
        assert_eq!(depth_shift(1.0, 1.625, 0.25), 3); // exactly 2.5 -> 3 (away from zero)
        assert_eq!(depth_shift(1.625, 1.0, 0.25), -3);
        assert_eq!(depth_shift(2.0, 2.3, 0.1), 3);
        assert_eq!(depth_shift(2.0, 2.03, 0.08), 0);
        assert_eq!(depth_shift(2.0, 2.05, 0.08), 1);
        assert_eq!(depth_shift(0.0, 5.0, 0.1), 0);
        assert_eq!(depth_shift(5.0, 0.0, 0.1), 0);
    }

    #[test]
    fn coverage_test() {
        assert!(same_coverage(1.0, 1.0, 16, 16, 4.0));
        assert!(!same_coverage(1.0, 0.9375, 1_000_000, 1_000_000, 4.0));
        // Agresti-Coull: p = 18/20 and 17/20, v = 0.0045 + 0.006375: d^2 / v = 0.359.
        assert!(same_coverage(1.0, 0.9375, 16, 16, 4.0));
        assert!(same_coverage(1.0, 0.9375, 16, 16, 0.36));
        assert!(!same_coverage(1.0, 0.9375, 16, 16, 0.35));
        // A pixel wholly inside the light and one that missed it 5 times in 512: d^2 / v
        // = 2.95 (the plain binomial variance, 0 at f = 1, gave 5.2 and split them).
        assert!(same_coverage(1.0, 0.99, 512, 512, 4.0));
        assert!(!same_coverage(1.0, 0.99, 512, 512, 2.9));
        assert!(!same_coverage(1.0, 0.97, 512, 512, 4.0));
        assert!(!same_coverage(1.0, 0.999, 1_000_000, 1_000_000, 4.0));
        assert!(!same_coverage(0.5, 0.125, 16, 16, 4.0));
        assert_eq!(
            same_coverage(0.3, 0.6, 8, 8, 4.0),
            same_coverage(0.6, 0.3, 8, 8, 4.0)
        );
    }

    #[test]
    fn validation() {
        assert!(TstatParams::default().validate().is_ok());
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let p = TstatParams {
                t2_patch: bad,
                ..Default::default()
            };
            let e = p.validate();
            assert!(
                matches!(
                    e,
                    Err(crate::denoise::DenoiseError::NotPositive {
                        flag: "--t2-patch",
                        value,
                    }) if value.to_bits() == bad.to_bits()
                ),
                "{bad}: {e:?}"
            );
        }
        assert_eq!(TstatParams::default().emitter_radius(5, false), 20);
        assert_eq!(TstatParams::default().emitter_radius(5, true), 0);
        let fixed = TstatParams {
            emitter_radius: Some(7),
            ..Default::default()
        };
        assert_eq!(fixed.emitter_radius(5, true), 7);
    }
}
