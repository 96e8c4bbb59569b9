//! Per-voxel sample sums, filled while rendering (SPEC 5).
//!
//! For every voxel (y, x, t) and channel c: `X1 = sum z`, `X2 = sum z^2`, `X3 = sum z^3`
//! over the paths that deposited something there (one flushed sample per path), the
//! raw radiance sum `S` when the transform is not the identity, and a u32 count of
//! those paths (`nonzero`). Paths that deposited nothing are the implicit zero samples
//! the estimators add back (zero-fill).
//!
//! Two shapes of the same sums:
//! - [`Accumulators`]: planar arrays laid out (H, W, T, C) like the bundle's `.npy`
//!   files; a whole film (kept in memory by `render::render`) or one image row (height
//!   1, the row a render task hands to its sink).
//! - [`PixelSums`]: the pixel being rendered, one interleaved record per time bin, so
//!   that one flushed sample touches one 80-byte region (104 with S) instead of four
//!   (five) separate arrays; [`PixelSums::flush_into`] de-interleaves it into its row.
//!
//! Memory: `H * W * T * C * 8` bytes per f64 array (3 arrays, 4 with S) plus
//! `H * W * T * 4` for the counts: per voxel `24 C + 4` bytes (identity), `32 C + 4`
//! with S: 76 / 100 for RGB (C = 3), 28 / 36 mono (C = 1), 100 / 132 for the four
//! Stokes components (C = 4), 292 / 388 for the Stokes components of each sRGB channel
//! (C = 12). A 128 x 128 x 300 x 3 film needs 374 MB (identity); one
//! of its rows 2.9 MB.

use super::transform::Transform;

/// The channels of an RGB (or spectral) film.
pub const CHANNELS: usize = 3;

/// The most channels a film has: the four Stokes components S0..S3 of each of the
/// three sRGB channels of a spectral polarized render. A path's deposit is always this
/// wide; only the film's first `channels` entries are read.
pub const MAX_CHANNELS: usize = 12;

/// Planar sums laid out (H, W, T, C) row-major.
pub struct Accumulators {
    pub height: usize,
    pub width: usize,
    pub bins: usize,
    /// C: 3 (RGB, spectral), 1 (mono), 4 (Stokes S0..S3) or 12 (RGB x Stokes).
    pub channels: usize,
    pub x1: Vec<f64>,
    pub x2: Vec<f64>,
    pub x3: Vec<f64>,
    /// Raw radiance sums; `None` for the identity transform (S = X1).
    pub sum: Option<Vec<f64>>,
    pub nonzero: Vec<u32>,
    /// Replicate statistics `R2 = sum_b m_b^2` (SPEC 5), when the render has
    /// replicates ([`Accumulators::with_r2`]).
    pub r2: Option<Vec<f64>>,
}

/// f64s of a replicate record: the sums of z per channel (always `MAX_CHANNELS` wide),
/// then the count.
const REP: usize = MAX_CHANNELS + 1;

/// The f64 sum arrays a transform needs: X1, X2, X3, and S unless it is the identity.
fn sum_arrays(transform: &Transform) -> usize {
    if transform.is_identity() {
        3
    } else {
        4
    }
}

impl Accumulators {
    /// Bytes needed for a film of this size with this transform (saturating, so absurd
    /// sizes compare as too large instead of wrapping).
    pub fn bytes(
        height: usize,
        width: usize,
        bins: usize,
        channels: usize,
        transform: &Transform,
    ) -> u64 {
        let arrays = sum_arrays(transform) as u128;
        let voxels = height as u128 * width as u128 * bins as u128;
        let b = voxels * channels as u128 * 8 * arrays + voxels * 4;
        u64::try_from(b).unwrap_or(u64::MAX)
    }

    pub fn new(
        height: usize,
        width: usize,
        bins: usize,
        channels: usize,
        transform: &Transform,
    ) -> Self {
        assert!((1..=MAX_CHANNELS).contains(&channels));
        let n = height * width * bins * channels;
        Accumulators {
            height,
            width,
            bins,
            channels,
            x1: vec![0.0; n],
            x2: vec![0.0; n],
            x3: vec![0.0; n],
            sum: (!transform.is_identity()).then(|| vec![0.0; n]),
            nonzero: vec![0u32; height * width * bins],
            r2: None,
        }
    }

    /// The same sums with an `R2` array (replicates).
    pub fn with_r2(mut self) -> Self {
        self.r2 = Some(vec![0.0; self.x1.len()]);
        self
    }

    /// Bytes of the `R2` array of a film of this size (saturating).
    pub fn r2_bytes(height: usize, width: usize, bins: usize, channels: usize) -> u64 {
        let b = height as u128 * width as u128 * bins as u128 * channels as u128 * 8;
        u64::try_from(b).unwrap_or(u64::MAX)
    }

    /// Copies `row` (the sums of one image row: height 1, same width, bins and arrays)
    /// into row `y`.
    pub fn put_row(&mut self, y: usize, row: &Accumulators) {
        assert!(
            row.height == 1
                && row.width == self.width
                && row.bins == self.bins
                && row.channels == self.channels,
            "a row of {}x{}x{}x{} does not fit a film of width {}, {} bins and {} channels",
            row.height,
            row.width,
            row.bins,
            row.channels,
            self.width,
            self.bins,
            self.channels
        );
        let n = self.width * self.bins * self.channels;
        let sums = |dst: &mut [f64], src: &[f64]| dst[y * n..(y + 1) * n].copy_from_slice(src);
        sums(&mut self.x1, &row.x1);
        sums(&mut self.x2, &row.x2);
        sums(&mut self.x3, &row.x3);
        match (self.sum.as_mut(), row.sum.as_ref()) {
            (Some(dst), Some(src)) => sums(dst, src),
            (None, None) => {}
            _ => panic!("a row with and a film without S (or the reverse)"),
        }
        let m = self.width * self.bins;
        self.nonzero[y * m..(y + 1) * m].copy_from_slice(&row.nonzero);
        match (self.r2.as_mut(), row.r2.as_ref()) {
            (Some(dst), Some(src)) => sums(dst, src),
            (None, None) => {}
            _ => panic!("a row with and a film without R2 (or the reverse)"),
        }
    }
}

/// The sums of the pixel being rendered: per time bin one record
/// `[X1 c, X2 c, X3 c, (S c,) count]` of f64 over the C channels (the count is exact:
/// at most spp < 2^32 < 2^53). A flushed sample touches only its bin's record.
pub struct PixelSums {
    bins: usize,
    channels: usize,
    /// f64s per record: 3C + 1, or 4C + 1 with S (10 or 13 for RGB).
    stride: usize,
    raw: bool,
    records: Vec<f64>,
    /// With replicates: per bin the current replicate's `[sum z c (MAX_CHANNELS), count]`,
    /// and the pixel's `R2 c` so far.
    replicate: Option<(Vec<f64>, Vec<f64>)>,
}

impl PixelSums {
    pub fn new(bins: usize, channels: usize, transform: &Transform) -> Self {
        assert!((1..=MAX_CHANNELS).contains(&channels));
        let stride = sum_arrays(transform) * channels + 1;
        PixelSums {
            bins,
            channels,
            stride,
            raw: !transform.is_identity(),
            records: vec![0.0; bins * stride],
            replicate: None,
        }
    }

    /// The same records, also accumulating replicate statistics.
    pub fn with_replicates(mut self) -> Self {
        self.replicate = Some((
            vec![0.0; self.bins * REP],
            vec![0.0; self.bins * self.channels],
        ));
        self
    }

    /// Ends a replicate of `k` samples: per bin and channel its mean of z, zero
    /// samples included (`m_b = (sum z + (k - count) z0) / k`), squared into R2.
    pub fn end_replicate(&mut self, k: u32, z0: f64) {
        let Some((current, r2)) = self.replicate.as_mut() else {
            return;
        };
        let kf = f64::from(k);
        for (cur, r) in current
            .chunks_exact_mut(REP)
            .zip(r2.chunks_exact_mut(self.channels))
        {
            let zeros = kf - cur[MAX_CHANNELS];
            for c in 0..self.channels {
                let m = (cur[c] + zeros * z0) / kf;
                r[c] += m * m;
            }
            cur.fill(0.0);
        }
    }

    /// Bytes of the records for `bins` bins (saturating).
    pub fn bytes(bins: usize, channels: usize, transform: &Transform) -> u64 {
        let stride = (sum_arrays(transform) * channels + 1) as u128;
        u64::try_from(bins as u128 * stride * 8).unwrap_or(u64::MAX)
    }

    /// Adds one path's total deposit `x` in time bin `bin` as one sample: its first
    /// `channels` values (rgb radiance, or S0..S3) are read.
    #[inline]
    pub fn add_sample(&mut self, z: impl Fn(f64) -> f64, bin: usize, x: [f64; MAX_CHANNELS]) {
        match self.channels {
            3 => self.add::<3>(z, bin, [x[0], x[1], x[2]]),
            1 => self.add::<1>(z, bin, [x[0]]),
            4 => self.add::<4>(z, bin, [x[0], x[1], x[2], x[3]]),
            _ => self.add::<MAX_CHANNELS>(z, bin, x),
        }
    }

    #[inline(always)]
    fn add<const C: usize>(&mut self, z: impl Fn(f64) -> f64, bin: usize, x: [f64; C]) {
        let r = &mut self.records[bin * self.stride..(bin + 1) * self.stride];
        let zs = x.map(z);
        for (c, &zc) in zs.iter().enumerate() {
            let z2 = zc * zc;
            r[c] += zc;
            r[C + c] += z2;
            r[2 * C + c] += z2 * zc;
        }
        if self.raw {
            for (c, &xc) in x.iter().enumerate() {
                r[3 * C + c] += xc;
            }
        }
        r[self.stride - 1] += 1.0;
        if let Some((current, _)) = self.replicate.as_mut() {
            let cur = &mut current[bin * REP..(bin + 1) * REP];
            for (c, &zc) in zs.iter().enumerate() {
                cur[c] += zc;
            }
            cur[MAX_CHANNELS] += 1.0;
        }
    }

    /// Moves the pixel's sums into pixel `px` of `row` (height 1), overwriting what was
    /// there, and leaves the records zero for the next pixel.
    pub fn flush_into(&mut self, row: &mut Accumulators, px: usize) {
        debug_assert!(row.height == 1 && row.bins == self.bins);
        let (t, c) = (self.bins, self.channels);
        debug_assert_eq!(row.channels, c);
        let planar = px * t * c..(px + 1) * t * c;
        let out = Planar {
            x1: &mut row.x1[planar.clone()],
            x2: &mut row.x2[planar.clone()],
            x3: &mut row.x3[planar.clone()],
            sum: row.sum.as_mut().map(|s| &mut s[planar]),
            nonzero: &mut row.nonzero[px * t..(px + 1) * t],
        };
        // A record length known at compile time: the copies become plain moves.
        match (c, self.raw) {
            (3, true) => deinterleave::<3, 13>(&self.records, out),
            (3, false) => deinterleave::<3, 10>(&self.records, out),
            (1, true) => deinterleave::<1, 5>(&self.records, out),
            (1, false) => deinterleave::<1, 4>(&self.records, out),
            (4, true) => deinterleave::<4, 17>(&self.records, out),
            (4, false) => deinterleave::<4, 13>(&self.records, out),
            (_, true) => deinterleave::<12, 49>(&self.records, out),
            (_, false) => deinterleave::<12, 37>(&self.records, out),
        }
        self.records.fill(0.0);
        if let (Some((_, r2)), Some(dst)) = (self.replicate.as_mut(), row.r2.as_mut()) {
            dst[px * t * c..(px + 1) * t * c].copy_from_slice(r2);
            r2.fill(0.0);
        }
    }
}

/// One pixel's planar slices of a row, (T, C) and (T).
struct Planar<'a> {
    x1: &'a mut [f64],
    x2: &'a mut [f64],
    x3: &'a mut [f64],
    sum: Option<&'a mut [f64]>,
    nonzero: &'a mut [u32],
}

/// Copies records of `N` f64s (`[X1 c, X2 c, X3 c, (S c,) count]` over `C` channels)
/// into `out`.
fn deinterleave<const C: usize, const N: usize>(records: &[f64], out: Planar<'_>) {
    let (records, _) = records.as_chunks::<N>();
    let planar = out
        .x1
        .as_chunks_mut::<C>()
        .0
        .iter_mut()
        .zip(out.x2.as_chunks_mut::<C>().0)
        .zip(out.x3.as_chunks_mut::<C>().0)
        .zip(out.nonzero.iter_mut());
    for (r, (((x1, x2), x3), nonzero)) in records.iter().zip(planar) {
        x1.copy_from_slice(&r[0..C]);
        x2.copy_from_slice(&r[C..2 * C]);
        x3.copy_from_slice(&r[2 * C..3 * C]);
        *nonzero = r[N - 1] as u32;
    }
    if let Some(sum) = out.sum {
        for (r, s) in records.iter().zip(sum.as_chunks_mut::<C>().0) {
            s.copy_from_slice(&r[3 * C..4 * C]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The plain planar form: what the interleaved records must reproduce bit for bit.
    fn planar_add(a: &mut Accumulators, z: impl Fn(f64) -> f64, px: usize, bin: usize, x: &[f64]) {
        let v = px * a.bins + bin;
        let ch = a.channels;
        a.nonzero[v] += 1;
        for (c, &xc) in x.iter().enumerate() {
            let zc = z(xc);
            a.x1[v * ch + c] += zc;
            a.x2[v * ch + c] += zc * zc;
            a.x3[v * ch + c] += zc * zc * zc;
            if let Some(s) = a.sum.as_mut() {
                s[v * ch + c] += xc;
            }
        }
    }

    /// Every channel count a film has (1, 3, 4, 12), signed values included.
    #[test]
    fn interleaved_records_give_the_planar_sums_bit_for_bit() {
        for ch in [1, 3, 4, MAX_CHANNELS] {
            for t in [Transform::Identity, Transform::YeoJohnson { lambda: 0.5 }] {
                let (w, bins) = (3, 5);
                let mut want = Accumulators::new(1, w, bins, ch, &t);
                let mut row = Accumulators::new(1, w, bins, ch, &t);
                // Garbage in the row: flushing overwrites every value.
                row.x2.fill(7.0);
                row.nonzero.fill(9);
                let mut p = PixelSums::new(bins, ch, &t);
                let z = |x: f64| t.apply(x);
                for px in 0..w {
                    for s in 0..40u32 {
                        let bin = (s as usize * 7 + px) % bins;
                        if bin == 3 {
                            continue; // an empty bin stays zero
                        }
                        let x: [f64; MAX_CHANNELS] = std::array::from_fn(|c| {
                            let v = 0.1 * s as f64 + 1.0 / (1.0 + (s + c as u32) as f64);
                            if c >= ch {
                                999.0 // beyond the film's channels: never read
                            } else if c % 4 == 2 {
                                -v / (1.0 + v) // S1..S3 and sRGB samples can be negative
                            } else {
                                v
                            }
                        });
                        p.add_sample(z, bin, x);
                        planar_add(&mut want, z, px, bin, &x[..ch]);
                    }
                    p.flush_into(&mut row, px);
                }
                assert!(row.x1 == want.x1 && row.x2 == want.x2 && row.x3 == want.x3);
                assert!(row.sum == want.sum && row.nonzero == want.nonzero);
                assert!(p.records.iter().all(|&v| v == 0.0));
            }
        }
    }

    #[test]
    fn rows_land_at_their_offset() {
        let t = Transform::BoxCox { lambda: 0.5 };
        let mut film = Accumulators::new(3, 2, 4, 3, &t);
        let mut row = Accumulators::new(1, 2, 4, 3, &t);
        row.x3.fill(3.0);
        row.sum.as_mut().unwrap().fill(4.0);
        row.nonzero.fill(5);
        film.put_row(1, &row);
        let n = 2 * 4 * 3;
        assert!(film.x3[..n].iter().all(|&v| v == 0.0));
        assert!(film.x3[n..2 * n].iter().all(|&v| v == 3.0));
        assert!(film.x3[2 * n..].iter().all(|&v| v == 0.0));
        assert!(film.sum.as_ref().unwrap()[n..2 * n]
            .iter()
            .all(|&v| v == 4.0));
        assert_eq!(
            film.nonzero,
            [0, 0, 0, 0, 0, 0, 0, 0, 5, 5, 5, 5, 5, 5, 5, 5, 0, 0, 0, 0, 0, 0, 0, 0]
        );
    }

    fn pad(x: [f64; 3]) -> [f64; MAX_CHANNELS] {
        std::array::from_fn(|c| if c < 3 { x[c] } else { 0.0 })
    }

    /// R2 from the interleaved records: per replicate the mean of z over its k samples
    /// (zeros as z(0)), squared and summed, against a plain computation.
    #[test]
    fn replicate_r2_is_the_sum_of_squared_replicate_means() {
        for t in [Transform::Identity, Transform::BoxCox { lambda: 0.5 }] {
            let (w, bins, reps, k) = (2usize, 4usize, 3u32, 5u32);
            let z0 = t.at_zero();
            let mut row = Accumulators::new(1, w, bins, 3, &t).with_r2();
            let mut p = PixelSums::new(bins, 3, &t).with_replicates();
            let z = |x: f64| t.apply(x);
            let mut want = vec![0.0; w * bins * 3];
            for px in 0..w {
                for b in 0..reps {
                    let mut sums = vec![0.0; bins * 3];
                    let mut counts = vec![0u32; bins];
                    for s in 0..k {
                        let bin = ((b * 7 + s * 3) as usize + px) % bins;
                        if bin == 2 {
                            continue;
                        }
                        let x = [0.3 * s as f64, 1.0 + b as f64, (s % 2) as f64];
                        p.add_sample(z, bin, pad(x));
                        counts[bin] += 1;
                        for c in 0..3 {
                            sums[bin * 3 + c] += z(x[c]);
                        }
                    }
                    p.end_replicate(k, z0);
                    for bin in 0..bins {
                        for c in 0..3 {
                            let m = (sums[bin * 3 + c] + f64::from(k - counts[bin]) * z0)
                                / f64::from(k);
                            want[(px * bins + bin) * 3 + c] += m * m;
                        }
                    }
                }
                p.flush_into(&mut row, px);
            }
            assert_eq!(row.r2.as_ref().unwrap(), &want, "{t:?}");
        }
    }
}
