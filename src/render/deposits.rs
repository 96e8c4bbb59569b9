//! Per-path bin flushing (SPEC 4): a path collects its contributions per time bin and
//! flushes each bin once when it ends, so every path is exactly one sample of every
//! voxel it touched.

use crate::stats::accumulators::MAX_CHANNELS;

/// Entries of a deposit: the most channels a film has.
pub const DEPOSIT_WIDTH: usize = MAX_CHANNELS;

/// A deposit's channels: rgb radiance, mono radiance (entry 0), the Stokes vector
/// S0..S3, or the Stokes vectors of the sRGB channels (`polarized::Polarization::deposit`);
/// the film reads its first C, the rest are 0.
pub type Deposit = [f64; DEPOSIT_WIDTH];

/// The (bin, channels) totals of the path being traced.
#[derive(Default)]
pub struct PathDeposits {
    entries: Vec<(u32, Deposit)>,
}

impl PathDeposits {
    /// Adds a contribution to the entry of its bin, or appends a new entry.
    #[inline]
    pub fn add(&mut self, bin: u32, c: Deposit) {
        // Consecutive vertices usually land in the same or a close bin: search backwards.
        if let Some(e) = self.entries.iter_mut().rev().find(|e| e.0 == bin) {
            for (acc, v) in e.1.iter_mut().zip(c) {
                *acc += v;
            }
        } else {
            self.entries.push((bin, c));
        }
    }

    /// The path's entries, one per distinct bin; empties the list.
    #[inline]
    pub fn drain(&mut self) -> std::vec::Drain<'_, (u32, Deposit)> {
        self.entries.drain(..)
    }

    pub fn len(&self) -> usize {
        self.entries.len()
    }

    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_bin_merges_and_revisits_merge_too() {
        let w = |x: [f64; 4]| -> Deposit {
            std::array::from_fn(|c| if c < 4 { x[c] } else { c as f64 })
        };
        let mut d = PathDeposits::default();
        d.add(5, w([1.0, 0.0, 0.0, -1.0]));
        d.add(5, w([0.5, 1.0, 0.0, 0.5]));
        d.add(7, w([0.0, 0.0, 2.0, 0.0]));
        d.add(5, w([0.25, 0.0, 0.0, 0.0]));
        assert_eq!(d.len(), 2);
        let v: Vec<_> = d.drain().collect();
        let mut five = w([1.75, 1.0, 0.0, -0.5]);
        for (c, e) in five.iter_mut().enumerate().skip(4) {
            *e = 3.0 * c as f64;
        }
        assert_eq!(v, vec![(5, five), (7, w([0.0, 0.0, 2.0, 0.0]))]);
        assert!(d.is_empty());
    }
}
