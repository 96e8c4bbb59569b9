//! The time axis (SPEC 3): `T` bins of width `h` from `t0`, in optical path length
//! (scene units). One type for every volume that has one: the film a scene renders
//! (`film.rs`), a bundle's manifest (`Manifest::time`, whose file keeps SPEC 9's flat
//! `bins`, `start_opl`, `bin_width_opl`), an NLOS capture (`nlos::capture`, whose
//! y-tal files call t0 and h `t_start` and `delta_t`) and the pictures of a volume
//! (`viz::frames`).
//!
//! A contribution with path OPL `o` lands in bin `k = floor((o - t0) / h)` when
//! `0 <= k < T` and in no bin otherwise.

/// `bins` bins of width `bin_width_opl` from `start_opl` (OPL, scene units).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TimeAxis {
    /// t0: the OPL where bin 0 starts.
    pub start_opl: f64,
    /// h: the width of a bin.
    pub bin_width_opl: f64,
    /// T: the number of bins.
    pub bins: usize,
}

impl TimeAxis {
    /// The bin of a contribution arriving at optical path length `opl`.
    #[inline]
    pub fn bin(&self, opl: f64) -> Option<u32> {
        let k = ((opl - self.start_opl) / self.bin_width_opl).floor();
        if k >= 0.0 && k < self.bins as f64 {
            Some(k as u32)
        } else {
            None
        }
    }

    /// The OPL at (fractional) bin position `k`: `t0 + k h` (the start of bin `k` for
    /// an integer `k`, its centre at `k + 1/2`).
    #[inline]
    pub fn opl(&self, k: f64) -> f64 {
        self.start_opl + k * self.bin_width_opl
    }

    /// The OPL where the last bin ends: `t0 + T h`.
    #[inline]
    pub fn end_opl(&self) -> f64 {
        self.opl(self.bins as f64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bins_are_half_open_and_the_window_ends_at_t0_plus_t_h() {
        let a = TimeAxis {
            start_opl: 1.0,
            bin_width_opl: 0.5,
            bins: 4,
        };
        assert_eq!(a.bin(0.999), None);
        assert_eq!(a.bin(1.0), Some(0));
        assert_eq!(a.bin(1.499), Some(0));
        assert_eq!(a.bin(1.5), Some(1));
        assert_eq!(a.bin(2.999), Some(3));
        assert_eq!(a.bin(3.0), None);
        assert_eq!(a.bin(f64::NAN), None);
        assert_eq!(a.opl(2.0), 2.0);
        assert_eq!(a.opl(0.5), 1.25);
        assert_eq!(a.end_opl(), 3.0);
    }
}
