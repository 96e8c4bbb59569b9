//! Where in its pixel each primary ray starts: independently uniform (the original
//! sampler), or a per-pixel randomised low-discrepancy set over the pixel's samples.
//!
//! # The stratified set
//!
//! Sample `s` of the `n` samples of a pixel is placed at
//!
//! ```text
//! u_s = frac(s / n + r1)                 (a Cranley-Patterson rotation of s / n)
//! v_s = owen(radical_inverse_2(s))       (a nested uniform (Owen) scramble in base 2)
//! ```
//!
//! with `r1` and the scramble drawn once per pixel from a stream hashed from (seed,
//! pixel) alone, unrelated to the per-path streams `Pcg32::for_path(seed, pixel, s)`.
//! The path's own stream is still created, and its first two numbers still drawn, for
//! every sample (see `render_row`): only the sub-pixel position is replaced, so the rest
//! of every path is the same in both modes.
//!
//! Why this set:
//! - **Every sample is marginally uniform over the pixel**, so each path is, on its own,
//!   an unbiased estimate of the pixel's radiance and the sums stay unbiased for every
//!   spp (and under `merge`): `u_s` is a uniform rotation of a fixed point, and an Owen
//!   scramble maps any point to a uniform one.
//! - **`u` is stratified for every n**, not only powers of two: the n rotated points are
//!   1/n apart, so each vertical strip `[k/n, (k+1)/n)` holds exactly one. **`v` is
//!   stratified when n is a power of two**: the first n radical inverses take every
//!   value `k/n` once, and the scramble permutes those intervals (nested) and fills the
//!   rest of the digits with random bits, i.e. each point is jittered independently
//!   inside its own interval instead of the whole pattern shifting rigidly as a
//!   rotation would.
//! - We compared, on edge (half-plane), disk and smooth integrands over a unit pixel at
//!   n = 4..64, a rotated Hammersley set (rotation in both coordinates), this set, a
//!   fully Owen-scrambled Hammersley set and a jittered grid: for edges and disks all of
//!   them are within about 20% of each other (and 3-14x below independent sampling at
//!   8-64 spp); for smooth integrands the Owen-scrambled `v` is 1.7-2.7x better than a
//!   rotated one; the full Owen set needs n a power of two to stratify `u`. This set is
//!   stratified for every n and costs two hashes per sample digit, nothing next to a
//!   path.
//!
//! Positions are computed in 24-bit fixed point (the resolution of
//! [`Pcg32::next_f32`]) so that the strata are exact in `f32`: the strip test
//! `floor(u * n) == k` holds exactly for every point. Beyond 2^24 spp the strips are
//! narrower than that resolution and are no longer exact (the marginal stays uniform).
//!
//! # What this does to the statistics
//!
//! The per-voxel variance `V = sigma2 / n` (SPEC 5) assumes the n path samples of a
//! voxel are i.i.d. With a stratified set they are identically distributed (each is
//! marginally uniform) but negatively correlated, so the true variance of the mean is
//! *at most* the i.i.d. one for the integrands that matter here (edges, smooth
//! regions); `V` therefore over-estimates it. The Welch membership test then sees
//! larger variances than the truth: it rejects fewer neighbours, i.e. it is more
//! permissive (more averaging) than calibrated, never stricter. docs/commands.md gives the
//! measured effect on the final error.

use crate::math::rng::{mix64, Pcg32};
use serde::{Deserialize, Serialize};

/// How primary rays choose their sub-pixel position.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum PixelSampling {
    /// Per pixel, a randomised low-discrepancy set: one sample per 1/n strip in u (in v too
    /// when n is a power of two); each sample still uniform over the pixel.
    #[value(alias = "stratified-pixel")]
    Stratified,
    /// Each sample uniform and independent of the others (the original sampler).
    Independent,
    /// Every dimension of every path (sub-pixel position, light, BSDF, phase, delay,
    /// roulette, free flight) from a padded, scrambled Sobol' set over the pixel's
    /// samples (`render::sampler`); each sample still uniform. The default.
    #[default]
    Sobol,
}

impl PixelSampling {
    pub fn name(self) -> &'static str {
        match self {
            PixelSampling::Stratified => "stratified",
            PixelSampling::Independent => "independent",
            PixelSampling::Sobol => "sobol",
        }
    }
}

impl std::fmt::Display for PixelSampling {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

const BITS: u32 = 24;
const ONE: u64 = 1 << BITS;
const SCALE: f32 = 1.0 / ONE as f32;

/// The stratified positions of one pixel's `n` samples.
#[derive(Clone, Debug)]
pub struct PixelPattern {
    n: u64,
    /// The rotation `r1 * n = shift + offset / 2^24`, in whole strips ...
    shift: u64,
    /// ... and the part within a strip, in `[n - 1, 2^24)` (see [`PixelPattern::u`]).
    offset: u64,
    /// Key of the Owen scramble of `v`.
    owen: u64,
}

impl PixelPattern {
    /// The pattern of `pixel` in a render with `seed` and `n` samples per pixel.
    pub fn new(seed: u64, pixel: u64, n: u32) -> Self {
        let n = u64::from(n.max(1));
        // A per-pixel stream with its own hashing constants: unrelated to the
        // per-path streams of `Pcg32::for_path`.
        let a = mix64(seed ^ 0x243f_6a88_85a3_08d3 ^ mix64(pixel ^ 0x1319_8a2e_0370_7344));
        let mut rng = Pcg32::new(mix64(a ^ 0xa409_3822_299f_31d0), a.rotate_left(29));
        let wide = |r: &mut Pcg32| (u64::from(r.next_u32()) << 32) | u64::from(r.next_u32());
        let shift = ((u128::from(wide(&mut rng)) * u128::from(n)) >> 64) as u64;
        // The in-strip part, uniform over the values that keep every point in its strip.
        let lo = (n - 1).min(ONE - 1);
        let offset = lo + ((u64::from(rng.next_u32() >> 8) * (ONE - lo)) >> BITS);
        let owen = wide(&mut rng);
        PixelPattern {
            n,
            shift,
            offset,
            owen,
        }
    }

    /// `u` of sample `s`, in 24-bit fixed point: `floor((k * 2^24 + offset) / n)` with
    /// `k = (s + shift) mod n`. As `n - 1 <= offset < 2^24`, the result `q` satisfies
    /// `k * 2^24 <= q * n < (k + 1) * 2^24`: it lies in strip k, exactly.
    fn u(&self, s: u64) -> u64 {
        let k = (s % self.n + self.shift) % self.n;
        ((k << BITS) + self.offset) / self.n
    }

    /// `v` of sample `s`, in 24-bit fixed point: the Owen scramble of the first 24
    /// digits of the base-2 radical inverse of `s`. Digit i (from the most significant)
    /// is flipped by a hash of the key, i and the digits above it.
    fn v(&self, s: u64) -> u64 {
        let x = u64::from((s as u32).reverse_bits() >> (32 - BITS));
        let mut out = 0;
        for i in 0..BITS {
            let bit = BITS - 1 - i;
            let prefix = x >> (bit + 1);
            let flip = mix64(self.owen ^ mix64(prefix | (u64::from(i) << 32))) >> 63;
            out |= (((x >> bit) & 1) ^ flip) << bit;
        }
        out
    }

    /// The sub-pixel position of sample `s` (of `n`), in `[0, 1)^2`.
    pub fn position(&self, s: u32) -> [f32; 2] {
        let s = u64::from(s);
        [self.u(s) as f32 * SCALE, self.v(s) as f32 * SCALE]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The 24-bit integer of a position coordinate (exact: positions are multiples of 2^-24).
    fn fixed(x: f32) -> u64 {
        let q = (x as f64 * ONE as f64) as u64;
        assert_eq!(q as f32 * SCALE, x);
        q
    }

    #[test]
    fn u_has_one_point_per_strip_and_v_one_per_dyadic_interval() {
        for n in [1u32, 2, 3, 5, 7, 16, 64, 100, 128] {
            for pixel in 0..50 {
                let p = PixelPattern::new(11, pixel, n);
                let mut us = vec![0u32; n as usize];
                let mut vs = vec![0u32; n as usize];
                for s in 0..n {
                    let [u, v] = p.position(s);
                    assert!((0.0..1.0).contains(&u) && (0.0..1.0).contains(&v));
                    us[((fixed(u) * n as u64) >> BITS) as usize] += 1;
                    vs[((fixed(v) * n as u64) >> BITS) as usize] += 1;
                }
                assert!(us.iter().all(|&c| c == 1), "n {n}: u strips {us:?}");
                if n.is_power_of_two() {
                    assert!(vs.iter().all(|&c| c == 1), "n {n}: v intervals {vs:?}");
                }
            }
        }
    }

    #[test]
    fn patterns_differ_by_pixel_and_seed_and_repeat() {
        let at = |seed, pixel| PixelPattern::new(seed, pixel, 16).position(3);
        assert_eq!(at(1, 2), at(1, 2));
        assert_ne!(at(1, 2), at(1, 3));
        assert_ne!(at(1, 2), at(2, 2));
    }

    #[test]
    fn huge_spp_stays_in_the_unit_square() {
        for n in [1 << 24, (1 << 24) + 3, u32::MAX] {
            let p = PixelPattern::new(5, 9, n);
            for s in [0, 1, n / 2, n - 1] {
                let [u, v] = p.position(s);
                assert!((0.0..1.0).contains(&u) && (0.0..1.0).contains(&v));
            }
        }
    }

    #[test]
    fn serde_names_are_lowercase() {
        assert_eq!(
            serde_json::to_string(&PixelSampling::Stratified).unwrap(),
            "\"stratified\""
        );
        let p: PixelSampling = serde_json::from_str("\"independent\"").unwrap();
        assert_eq!(p, PixelSampling::Independent);
    }
}
