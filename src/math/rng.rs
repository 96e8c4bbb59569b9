//! Random numbers: one independent PCG32 stream per (seed, pixel, sample).
//!
//! The statistical test in the denoiser assumes i.i.d. samples, so every path gets its
//! own stream derived by hashing; no stream is shared between paths, and the result of
//! a path never depends on which thread traced it.

/// SplitMix64 finaliser: a bijective 64-bit mixer with good avalanche.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// PCG32 (XSH-RR), O'Neill 2014.
#[derive(Clone, Debug)]
pub struct Pcg32 {
    state: u64,
    inc: u64,
}

const PCG_MULT: u64 = 6_364_136_223_846_793_005;

impl Pcg32 {
    pub fn new(init_state: u64, stream: u64) -> Self {
        let mut rng = Pcg32 {
            state: 0,
            inc: (stream << 1) | 1,
        };
        rng.next_u32();
        rng.state = rng.state.wrapping_add(init_state);
        rng.next_u32();
        rng
    }

    /// The stream of path `sample` of pixel `pixel` for a render with `seed`.
    pub fn for_path(seed: u64, pixel: u64, sample: u64) -> Self {
        let a = mix64(seed ^ mix64(pixel.wrapping_add(0x9e37_79b9_7f4a_7c15)));
        let b = mix64(a ^ mix64(sample.wrapping_mul(0xd6e8_feb8_6659_fd93) ^ 0x5851_f42d));
        Pcg32::new(b, mix64(a.rotate_left(17) ^ sample))
    }

    #[inline]
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(PCG_MULT).wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// Uniform in [0, 1), 24 bits of precision.
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
    }

    #[inline]
    pub fn next_2d(&mut self) -> [f32; 2] {
        [self.next_f32(), self.next_f32()]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floats_are_in_unit_interval_and_have_right_mean() {
        let mut r = Pcg32::for_path(1, 2, 3);
        let n = 200_000;
        let mut sum = 0.0f64;
        for _ in 0..n {
            let u = r.next_f32();
            assert!((0.0..1.0).contains(&u));
            sum += u as f64;
        }
        // Standard error of the mean of U(0,1) is sqrt(1/12/n) ~ 6.5e-4; 5 sigma.
        assert!((sum / n as f64 - 0.5).abs() < 5.0 * (1.0f64 / 12.0 / n as f64).sqrt());
    }

    #[test]
    fn streams_differ_by_pixel_and_sample_and_repeat_by_seed() {
        let first = |s, p, i| Pcg32::for_path(s, p, i).next_u32();
        assert_eq!(first(7, 1, 1), first(7, 1, 1));
        assert_ne!(first(7, 1, 1), first(7, 1, 2));
        assert_ne!(first(7, 1, 1), first(7, 2, 1));
        assert_ne!(first(7, 1, 1), first(8, 1, 1));
    }
}
