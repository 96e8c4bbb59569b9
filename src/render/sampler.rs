//! The random numbers of a path, one dimension at a time (SPEC 4, "Sampling and
//! replicates").
//!
//! The tracers ask for each number by what it is for: a [`Slot`] at the current vertex
//! (`get1`, `get2`), or, for loops whose length depends on the path (delta and ratio
//! tracking in heterogeneous media, nested `Composed` picks), the path's own stream
//! (`stream`). Two samplers answer:
//!
//! - [`Pcg32`] itself: every number from the path's PCG32 stream, in the order asked
//!   (the slots are ignored), i.e. the original sampler, bit for bit;
//! - [`SobolPath`]: each (vertex, slot) is its own dimension of a randomised
//!   low-discrepancy set over the samples of a replicate: a 1D slot takes the base-2
//!   van der Corput sequence, a 2D slot the first two Sobol' dimensions (a (0, 2)-
//!   sequence: stratified in every dyadic box when the replicate size is a power of
//!   two), each dimension scrambled by its own hashed nested (Owen-style) scramble and
//!   then digitally shifted by its own hashed 32-bit value. Dimensions are padded as in
//!   pbrt-v4's `PaddedSobolSampler`: each slot also permutes the sample indices by its
//!   own hashed permutation (Kensler's), so that two slots are not the same sequence
//!   scrambled twice (whose 2D projections line up: measured on cbox, that made the
//!   error 25% *worse* than independent sampling off the light); and they never wrap:
//!   the dimension index is hashed, not looked up in a table, so a path of any length
//!   gets fresh dimensions. (Mitsuba 3's `ldsampler` is measurably biased
//!   in the late bins of long paths; see the tests.)
//!
//! # Why every sample is unbiased
//! For one sample, the digital shift XORs the scrambled point with a uniform random
//! 32-bit value independent of it, so each coordinate is exactly uniform on the 2^-32
//! grid; different dimensions use unrelated hashes, so a path's numbers are i.i.d.
//! uniform (to the quality of the hash) and its estimate is that of independent
//! sampling. Only the joint distribution *across* the samples of a replicate changes
//! (they are negatively correlated: stratified), which is what lowers the variance of
//! the mean. Replicates use unrelated keys, so replicate means are i.i.d.
//!
//! # Cost
//! One 64-bit hash and about ten integer operations per number (the stream's PCG32 step
//! is three): noise next to the ray casts of a path.

use crate::materials::Bsdf;
use crate::math::rng::{mix64, Pcg32};
use crate::media::FlightNumbers;

/// What a number is for, at one vertex of a path. 2D slots take two consecutive values.
pub mod slot {
    /// Russian roulette.
    pub const RR: u32 = 0;
    /// The free-flight distance in a homogeneous medium.
    pub const FLIGHT: u32 = 1;
    /// The child of a `Composed` material (the first pick at a vertex).
    pub const PICK: u32 = 2;
    /// Which emitter next-event estimation samples.
    pub const LIGHT_SELECT: u32 = 3;
    /// The emitter sample's 1D number (e.g. the triangle of a mesh light).
    pub const LIGHT_1: u32 = 4;
    /// The emitter sample's 2D point (2D).
    pub const LIGHT_2: u32 = 5;
    /// The delay of next-event estimation at a delaying material.
    pub const NEE_DELAY: u32 = 7;
    /// The BSDF sample's 1D number (lobe choice).
    pub const BSDF_1: u32 = 8;
    /// The BSDF sample's 2D point (2D).
    pub const BSDF_2: u32 = 9;
    /// The delay of the BSDF-sampled continuation.
    pub const BSDF_DELAY: u32 = 11;
    /// The phase function's 2D point (2D).
    pub const PHASE: u32 = 12;
    /// The sub-pixel position (2D, vertex 0).
    pub const PIXEL: u32 = 14;
    /// The hero channel of spectral MIS in media (vertex 0).
    pub const CHANNEL: u32 = 16;
    /// NLOS paths: the coin flip between hidden-geometry and BSDF sampling.
    pub const NLOS_STRATEGY: u32 = 17;
}

/// Slots per vertex: every slot above is below this.
pub const SLOTS: u32 = 18;

/// The hash of `key` (a replicate's) and a vertex, from which the vertex's dimensions
/// are hashed.
#[inline(always)]
pub(super) fn vertex_key(key: u64, vertex: u64) -> u64 {
    if vertex == 0 {
        mix64(key)
    } else {
        mix64(key ^ vertex.wrapping_mul(0xd6e8_feb8_6659_fd93))
    }
}

/// The child of a (possibly nested) `Composed` material that scatters at a vertex:
/// the first pick has its slot, nested picks (rare) take the stream. Any other
/// material is itself.
#[inline(always)]
pub fn pick_scattering<'a, S: PathSampler>(whole: &'a Bsdf, rng: &mut S) -> &'a Bsdf {
    let mut bsdf = whole;
    let mut first = true;
    while let Bsdf::Composed(c) = bsdf {
        let u = if first {
            rng.get1(slot::PICK)
        } else {
            rng.stream().next_f32()
        };
        first = false;
        bsdf = c.pick(u);
    }
    bsdf
}

/// The numbers of one path.
pub trait PathSampler {
    /// Moves on to the next vertex's dimensions (the tracers call it once per loop).
    fn next_vertex(&mut self);
    /// A number in [0, 1) for `slot` at the current vertex.
    fn get1(&mut self, slot: u32) -> f32;
    /// A point in [0, 1)^2 for `slot` at the current vertex.
    fn get2(&mut self, slot: u32) -> [f32; 2];
    /// The path's own stream, for draws whose number depends on the path.
    fn stream(&mut self) -> &mut Pcg32;
}

/// A free flight's numbers (`Medium::free_flight`): the sampler's `FLIGHT` slot and
/// the path's stream.
impl<S: PathSampler> FlightNumbers for S {
    #[inline(always)]
    fn flight_number(&mut self) -> f32 {
        self.get1(slot::FLIGHT)
    }
    #[inline(always)]
    fn flight_stream(&mut self) -> &mut Pcg32 {
        self.stream()
    }
}

/// Independent sampling: every number from the path's stream, in the order asked.
impl PathSampler for Pcg32 {
    #[inline(always)]
    fn next_vertex(&mut self) {}
    #[inline(always)]
    fn get1(&mut self, _slot: u32) -> f32 {
        self.next_f32()
    }
    #[inline(always)]
    fn get2(&mut self, _slot: u32) -> [f32; 2] {
        self.next_2d()
    }
    #[inline(always)]
    fn stream(&mut self) -> &mut Pcg32 {
        self
    }
}

/// Sample `index` of a replicate's randomised low-discrepancy set; see the module docs.
pub struct SobolPath {
    /// Hash of (seed, pixel, replicate): the randomisation of the whole set.
    key: u64,
    /// Hash of `key` and the current vertex.
    vertex_key: u64,
    index: u32,
    /// Samples in the set (`index < count`).
    count: u32,
    vertex: u64,
    /// Vertices drawn from the set; later ones take the stream.
    ld_vertices: u64,
    stream: Pcg32,
}

impl SobolPath {
    /// Sample `index` of the `count` samples of replicate `replicate` of `pixel` in a
    /// render with `seed`; `stream` is the path's own stream.
    pub fn new(
        seed: u64,
        pixel: u64,
        replicate: u32,
        index: u32,
        count: u32,
        stream: Pcg32,
    ) -> Self {
        Self::with_key(replicate_key(seed, pixel, replicate), index, count, stream)
    }

    /// As [`SobolPath::new`] with the replicate's [`replicate_key`] already computed
    /// (once per replicate, not per sample).
    #[inline]
    pub fn with_key(key: u64, index: u32, count: u32, stream: Pcg32) -> Self {
        Self::with_depth(key, index, count, stream, LD_VERTICES)
    }

    /// As [`SobolPath::with_key`] with `ld_vertices` low-discrepancy vertices (see
    /// [`LD_VERTICES`] and [`LD_VERTICES_VOLUMETRIC`]).
    #[inline]
    pub fn with_depth(key: u64, index: u32, count: u32, stream: Pcg32, ld_vertices: u64) -> Self {
        debug_assert!(index < count);
        SobolPath {
            key,
            vertex_key: vertex_key(key, 0),
            index,
            count,
            vertex: 0,
            ld_vertices,
            stream,
        }
    }

    /// The 64-bit hash of dimension `dim` (a slot and its coordinate) at this vertex.
    #[inline(always)]
    fn dim_hash(&self, dim: u32) -> u64 {
        mix64(self.vertex_key ^ u64::from(dim + 1).wrapping_mul(0x9e37_79b9_7f4a_7c15))
    }

    /// The sample index permuted by the slot's hash `h`.
    #[inline(always)]
    fn permuted(&self, h: u64) -> u32 {
        permute(self.index, self.count, (h >> 32) as u32)
    }

    /// Vertices past this one draw from the stream (see [`LD_VERTICES`]).
    #[inline(always)]
    fn beyond(&self) -> bool {
        self.vertex > self.ld_vertices
    }
}

/// The vertices whose numbers come from the low-discrepancy set (vertex 0 is the
/// camera: sub-pixel position, hero channel; vertex 1 the first hit); later ones take
/// the path's stream (unbiased either way: every number is uniform and independent of
/// the others). Measured on cbox at 64 spp (64x64, 150 bins of 0.08, 8 seeds, against
/// an 8192-spp independent reference, its own variance subtracted): RMSE off the light
/// 9.60e-4 with 1 low-discrepancy vertex, 9.58e-4 with 2 or 3, 9.58e-4 with all;
/// render time +5-10% with 1, +15-25% with 2-3, +50% with all (each number costs
/// about 12 ns, a stream number 1-2).
pub const LD_VERTICES: u64 = 1;

/// The same for paths under the media rules (scenes with media). Measured on
/// cbox_fog at 64 spp (64x64, 150 bins of 0.08, 3 seeds, against a 131072-spp
/// independent reference, its own variance subtracted): RMSE on the light's pixels
/// 6.37e-2 with 1 vertex, 5.05e-2 with 3, 5.08e-2 with all (Mitsuba's ldsampler
/// 4.60e-2); the rest 3.02e-3 / 2.97e-3 / 2.99e-3. There the light is seen through the
/// medium, and the free flights and phase samples after the first vertex matter.
pub const LD_VERTICES_VOLUMETRIC: u64 = 3;

/// The low-discrepancy vertices of a scene's paths: [`LD_VERTICES_VOLUMETRIC`] under
/// the media rules, else [`LD_VERTICES`].
pub fn ld_vertices(volumetric: bool) -> u64 {
    if volumetric {
        LD_VERTICES_VOLUMETRIC
    } else {
        LD_VERTICES
    }
}

/// The randomisation key of one replicate of one pixel (unrelated to the path streams
/// of [`Pcg32::for_path`] and to the pixel patterns of `pixel_sampling`).
pub fn replicate_key(seed: u64, pixel: u64, replicate: u32) -> u64 {
    let a = mix64(seed ^ 0x4528_21e6_38d0_1377 ^ mix64(pixel ^ 0xbe54_66cf_34e9_0c6c));
    mix64(a ^ mix64(u64::from(replicate) ^ 0xc0ac_29b7_c97c_50dd))
}

impl PathSampler for SobolPath {
    #[inline(always)]
    fn next_vertex(&mut self) {
        self.vertex += 1;
        if !self.beyond() {
            self.vertex_key = vertex_key(self.key, self.vertex);
        }
    }

    #[inline(always)]
    fn get1(&mut self, slot: u32) -> f32 {
        if self.beyond() {
            return self.stream.next_f32();
        }
        let h = self.dim_hash(slot);
        let i = self.permuted(h);
        to_unit(scramble_index(i, mix64(h)))
    }

    #[inline(always)]
    fn get2(&mut self, slot: u32) -> [f32; 2] {
        if self.beyond() {
            return self.stream.next_2d();
        }
        let h = self.dim_hash(slot);
        // One permutation for both coordinates: the pair keeps its (0, 2) structure.
        let i = self.permuted(h);
        let h2 = mix64(h);
        [
            to_unit(scramble_index(i, h2)),
            to_unit(randomise(sobol_1(i), mix64(h2))),
        ]
    }

    #[inline(always)]
    fn stream(&mut self) -> &mut Pcg32 {
        &mut self.stream
    }
}

/// Element `i` of a pseudo-random permutation of `0..l` keyed by `p` (Kensler,
/// "Correlated Multi-Jittered Sampling", 2013: an invertible hash on the next power of
/// two, cycle-walking until the value falls below `l`). A cheaper two-round
/// multiply-xorshift permutation left the slots partly aligned (cbox at 64 spp: 4%
/// more error off the light than with this one).
#[inline(always)]
pub fn permute(mut i: u32, l: u32, p: u32) -> u32 {
    if l <= 1 {
        return 0;
    }
    let mut w = l - 1;
    w |= w >> 1;
    w |= w >> 2;
    w |= w >> 4;
    w |= w >> 8;
    w |= w >> 16;
    loop {
        i = kensler_round(i, w, p);
        if i < l {
            break;
        }
    }
    ((u64::from(i) + u64::from(p)) % u64::from(l)) as u32
}

/// One round of [`permute`]'s invertible hash on `0..=w` (`w + 1` a power of two).
#[inline(always)]
pub(super) fn kensler_round(mut i: u32, w: u32, p: u32) -> u32 {
    i ^= p;
    i = i.wrapping_mul(0xe170_893d);
    i ^= p >> 16;
    i ^= (i & w) >> 4;
    i ^= p >> 8;
    i = i.wrapping_mul(0x0929_eb3f);
    i ^= p >> 23;
    i ^= (i & w) >> 1;
    i = i.wrapping_mul(1 | (p >> 27));
    i = i.wrapping_mul(0x6935_fa69);
    i ^= (i & w) >> 11;
    i = i.wrapping_mul(0x74dc_b303);
    i ^= (i & w) >> 2;
    i = i.wrapping_mul(0x9e50_1cc3);
    i ^= (i & w) >> 2;
    i = i.wrapping_mul(0xc860_a3df);
    i &= w;
    i ^= i >> 5;
    i
}

/// The first Sobol' dimension of `i`, a 32-bit binary fraction: the base-2 radical
/// inverse.
#[inline(always)]
pub fn van_der_corput(i: u32) -> u32 {
    i.reverse_bits()
}

/// The second Sobol' dimension of `i`, a 32-bit binary fraction: its generator matrix
/// is the upper-triangular Pascal matrix mod 2, i.e. direction numbers `v_0 = 2^31`,
/// `v_j = v_(j-1) xor (v_(j-1) >> 1)`.
#[inline(always)]
pub fn sobol_1(mut i: u32) -> u32 {
    let mut v = 1u32 << 31;
    let mut x = 0u32;
    while i != 0 {
        if i & 1 != 0 {
            x ^= v;
        }
        i >>= 1;
        v ^= v >> 1;
    }
    x
}

/// A nested scramble of the 32-bit fraction `x` keyed by the low half of `h`, then a
/// digital shift by its high half. The scramble (Laine and Karras's hash, as in
/// pbrt-v4's `FastOwenScrambler`) flips each digit by a function of the key and the
/// digits above it only, so it maps every dyadic interval onto one of the same size and
/// keeps the set's stratification; the shift makes each point exactly uniform.
#[inline(always)]
pub fn randomise(x: u32, h: u64) -> u32 {
    scramble_index(x.reverse_bits(), h)
}

/// `randomise(van_der_corput(i), h)`: the scramble works on the reversed digits, so
/// the radical inverse's reversal and the scramble's cancel.
#[inline(always)]
pub(super) fn scramble_index(i: u32, h: u64) -> u32 {
    let seed = h as u32;
    let mut v = i;
    v ^= v.wrapping_mul(0x3d20_adea);
    v = v.wrapping_add(seed);
    v = v.wrapping_mul((seed >> 16) | 1);
    v ^= v.wrapping_mul(0x0552_6c56);
    v ^= v.wrapping_mul(0x53a2_2864);
    v.reverse_bits() ^ (h >> 32) as u32
}

/// The top 24 bits of a 32-bit fraction as an f32 in [0, 1) (the grid of
/// [`Pcg32::next_f32`]).
#[inline(always)]
pub(super) fn to_unit(x: u32) -> f32 {
    (x >> 8) as f32 * (1.0 / 16_777_216.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The digits of the 2D point of index i, as 32-bit integers.
    fn point(i: u32) -> (u32, u32) {
        (van_der_corput(i), sobol_1(i))
    }

    #[test]
    fn the_first_two_dimensions_are_a_0_2_sequence() {
        // Every block of 2^m points (aligned) has one point in each dyadic box of area
        // 2^-m, for every shape 2^-a x 2^-(m-a).
        for m in 0..=8u32 {
            let n = 1u32 << m;
            for block in 0..4u32 {
                for a in 0..=m {
                    let mut seen = vec![0u32; n as usize];
                    for i in block * n..(block + 1) * n {
                        let (x, y) = point(i);
                        let bx = if a == 0 { 0 } else { x >> (32 - a) };
                        let by = if m - a == 0 { 0 } else { y >> (32 - (m - a)) };
                        seen[((bx << (m - a)) | by) as usize] += 1;
                    }
                    assert!(seen.iter().all(|&c| c == 1), "m {m} a {a} block {block}");
                }
            }
        }
    }

    #[test]
    fn sobol_1_matches_its_direction_numbers() {
        // In index order (not Gray-code order): v_0 = 1/2, v_1 = 3/4, v_2 = 5/8, and
        // index i is the xor of v_j over the bits j of i.
        let want = [0.0, 0.5, 0.75, 0.25, 0.625, 0.125, 0.375, 0.875];
        for (i, w) in want.iter().enumerate() {
            assert_eq!(sobol_1(i as u32) as f64 / 2f64.powi(32), *w, "i {i}");
        }
    }

    #[test]
    fn randomising_keeps_the_stratification() {
        for key in 0..50u64 {
            let h = [mix64(key), mix64(key ^ 77)];
            for m in [2u32, 4, 6] {
                let n = 1u32 << m;
                for a in 0..=m {
                    let mut seen = vec![0u32; n as usize];
                    for i in 0..n {
                        let x = randomise(van_der_corput(i), h[0]);
                        let y = randomise(sobol_1(i), h[1]);
                        let bx = if a == 0 { 0 } else { x >> (32 - a) };
                        let by = if m - a == 0 { 0 } else { y >> (32 - (m - a)) };
                        seen[((bx << (m - a)) | by) as usize] += 1;
                    }
                    assert!(seen.iter().all(|&c| c == 1), "key {key} m {m} a {a}");
                }
            }
        }
    }

    /// Each number is uniform over keys: a chi-square test on 64 cells, for a fixed
    /// index and dimension, over 64k replicates.
    #[test]
    fn each_number_is_uniform_over_replicates() {
        let cells = 64usize;
        let n = 1 << 16;
        for index in [0u32, 1, 5, 1000] {
            for slot in [slot::RR, slot::BSDF_2, slot::PIXEL] {
                let mut counts = vec![0u32; cells];
                let mut counts_y = vec![0u32; cells];
                for r in 0..n {
                    let mut s = SobolPath::new(9, 3, r, index, 1024, Pcg32::new(1, 1));
                    s.next_vertex();
                    let [x, y] = s.get2(slot);
                    assert!((0.0..1.0).contains(&x) && (0.0..1.0).contains(&y));
                    counts[(x * cells as f32) as usize] += 1;
                    counts_y[(y * cells as f32) as usize] += 1;
                }
                for c in [&counts, &counts_y] {
                    let e = n as f64 / cells as f64;
                    let chi2: f64 = c.iter().map(|&k| (k as f64 - e).powi(2) / e).sum();
                    // 63 degrees of freedom: the 0.9999 quantile is about 115.
                    assert!(chi2 < 115.0, "index {index} slot {slot}: chi2 {chi2}");
                }
            }
        }
    }

    /// Different dimensions of one sample are uncorrelated (padding): the sample
    /// correlation between two slots, and between slots at vertex 0 and 1 (the
    /// low-discrepancy vertices), over many replicates, is within 4.5 standard errors
    /// of 0.
    #[test]
    fn dimensions_are_uncorrelated() {
        let n = 1 << 15;
        let pairs: [(u32, u64, u32, u64); 3] = [
            (slot::RR, 1, slot::FLIGHT, 1),
            (slot::CHANNEL, 0, slot::BSDF_1, 1),
            (slot::LIGHT_SELECT, 1, slot::PICK, 1),
        ];
        for (sa, va, sb, vb) in pairs {
            let (mut sxy, mut sx, mut sy, mut sxx, mut syy) = (0.0f64, 0.0, 0.0, 0.0, 0.0);
            for r in 0..n {
                let mut s = SobolPath::new(4, 8, r, 3, 16, Pcg32::new(1, 1));
                let mut at = |slot: u32, vertex: u64| {
                    s.vertex = 0;
                    s.vertex_key = mix64(s.key);
                    for _ in 0..vertex {
                        s.next_vertex();
                    }
                    s.get1(slot) as f64
                };
                let x = at(sa, va);
                let y = at(sb, vb);
                sxy += x * y;
                sx += x;
                sy += y;
                sxx += x * x;
                syy += y * y;
            }
            let nf = n as f64;
            let cov = sxy / nf - sx / nf * sy / nf;
            let corr =
                cov / ((sxx / nf - (sx / nf).powi(2)) * (syy / nf - (sy / nf).powi(2))).sqrt();
            assert!(
                corr.abs() < 4.5 / nf.sqrt(),
                "{sa}@{va} vs {sb}@{vb}: {corr}"
            );
        }
    }

    #[test]
    fn scramble_index_is_randomise_of_the_radical_inverse() {
        for i in [0u32, 1, 7, 1000, u32::MAX] {
            for h in [0u64, 1, 0xdead_beef_0bad_cafe] {
                assert_eq!(scramble_index(i, h), randomise(van_der_corput(i), h));
            }
        }
    }

    #[test]
    fn every_slot_is_below_slots() {
        let all = [
            slot::RR,
            slot::FLIGHT,
            slot::PICK,
            slot::LIGHT_SELECT,
            slot::LIGHT_1,
            slot::LIGHT_2 + 1,
            slot::NEE_DELAY,
            slot::BSDF_1,
            slot::BSDF_2 + 1,
            slot::BSDF_DELAY,
            slot::PHASE + 1,
            slot::PIXEL + 1,
            slot::CHANNEL,
            slot::NLOS_STRATEGY,
        ];
        assert!(all.iter().all(|&s| s < SLOTS));
    }

    #[test]
    fn permute_is_a_permutation() {
        for l in [1u32, 2, 3, 4, 7, 8, 16, 64, 100, 1000, 1024, 1 << 16] {
            for p in [0u32, 1, 0xdead_beef, 12345] {
                let mut seen = vec![false; l as usize];
                for i in 0..l {
                    let j = permute(i, l, p) as usize;
                    assert!(!seen[j], "l {l} p {p}");
                    seen[j] = true;
                }
            }
        }
    }

    /// A pixel's samples, in two slots: each slot's 2D points stay stratified (one per
    /// quadrant of every 2x2, 4x1 ... arrangement at 16 samples) and the two slots'
    /// first coordinates do not line up (at most 12 of 16 quadrant cells of the pair
    /// (slot a x, slot b x) hit... i.e. the pair is not confined to a diagonal).
    #[test]
    fn slots_are_stratified_and_not_aligned() {
        let n = 16u32;
        for pixel in 0..20u64 {
            let pts = |slot: u32| -> Vec<[f32; 2]> {
                (0..n)
                    .map(|i| {
                        let mut s = SobolPath::new(3, pixel, 0, i, n, Pcg32::new(0, 0));
                        s.next_vertex();
                        s.get2(slot)
                    })
                    .collect()
            };
            let (a, b) = (pts(slot::BSDF_2), pts(slot::LIGHT_2));
            for p in [&a, &b] {
                let mut cells = [0; 16];
                for q in p.iter() {
                    cells[(q[0] * 4.0) as usize * 4 + (q[1] * 4.0) as usize] += 1;
                }
                assert!(cells.iter().all(|&c| c == 1), "pixel {pixel}: {cells:?}");
            }
            // Identical index orders would put (a_x, b_x) on a permutation of the
            // same strata in every slot pair; permuted, a 4x4 grid of the pair sees
            // collisions.
            let mut cells = [0; 16];
            for (p, q) in a.iter().zip(&b) {
                cells[(p[0] * 4.0) as usize * 4 + (q[0] * 4.0) as usize] += 1;
            }
            assert!(cells.contains(&0), "pixel {pixel}");
        }
    }

    #[test]
    fn independent_path_is_the_stream_in_order() {
        let mut a = Pcg32::for_path(1, 2, 3);
        let mut b = Pcg32::for_path(1, 2, 3);
        assert_eq!(PathSampler::get1(&mut a, slot::RR), b.next_f32());
        PathSampler::next_vertex(&mut a);
        assert_eq!(PathSampler::get2(&mut a, slot::BSDF_2), b.next_2d());
        assert_eq!(PathSampler::stream(&mut a).next_u32(), b.next_u32());
    }

    #[test]
    fn sobol_paths_repeat_and_differ() {
        let v = |seed, pixel, rep, index| {
            let mut s = SobolPath::new(seed, pixel, rep, index, 8, Pcg32::new(0, 0));
            s.next_vertex();
            s.get1(slot::BSDF_1)
        };
        assert_eq!(v(1, 2, 3, 4), v(1, 2, 3, 4));
        assert_ne!(v(1, 2, 3, 4), v(2, 2, 3, 4));
        assert_ne!(v(1, 2, 3, 4), v(1, 3, 3, 4));
        assert_ne!(v(1, 2, 3, 4), v(1, 2, 4, 4));
        assert_ne!(v(1, 2, 3, 4), v(1, 2, 3, 5));
    }
}
