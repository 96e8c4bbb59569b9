//! The film: image size and the time axis (SPEC 3). `scene/film.rs` reads
//! `transient_hdr_film`.
//!
//! A contribution with path OPL `o` lands in bin `k = floor((o - t0) / h)` when
//! `0 <= k < T` and in no bin otherwise (it still counts in the steady image).

#[derive(Clone, Debug, PartialEq)]
pub struct Film {
    pub width: usize,
    pub height: usize,
    pub bins: usize,
    /// t0, OPL in scene units.
    pub start_opl: f64,
    /// h, OPL in scene units.
    pub bin_width_opl: f64,
}

impl Film {
    /// Time bin of a contribution arriving at optical path length `opl`.
    #[inline]
    pub fn bin(&self, opl: f64) -> Option<u32> {
        let k = ((opl - self.start_opl) / self.bin_width_opl).floor();
        if k >= 0.0 && k < self.bins as f64 {
            Some(k as u32)
        } else {
            None
        }
    }

    pub fn pixels(&self) -> usize {
        self.width * self.height
    }

    /// Checks the settings after overrides were applied.
    pub fn validate(&self) -> Result<(), String> {
        if self.width == 0 || self.height == 0 {
            return Err(format!("film size {}x{} is empty", self.width, self.height));
        }
        if self.bins == 0 {
            return Err("temporal_bins must be at least 1".into());
        }
        // Every later size computation (sums, G-buffers, bytes) stays within usize.
        let bytes = [self.height, self.bins, 3, 8, 4]
            .iter()
            .try_fold(self.width, |n, &f| n.checked_mul(f));
        if bytes.is_none() {
            return Err(format!(
                "a film of {}x{} px and {} bins is too large to address",
                self.width, self.height, self.bins
            ));
        }
        if self.bins > u32::MAX as usize {
            return Err(format!(
                "temporal_bins {} is above the largest supported count {}",
                self.bins,
                u32::MAX
            ));
        }
        if !(self.bin_width_opl > 0.0 && self.bin_width_opl.is_finite()) {
            return Err(format!(
                "bin_width_opl must be positive, got {}",
                self.bin_width_opl
            ));
        }
        if !self.start_opl.is_finite() {
            return Err(format!("start_opl must be finite, got {}", self.start_opl));
        }
        // The window's end must be a number, and a bin must be wider than the f64
        // spacing of the OPLs it holds (else bins merge: k = floor((opl - t0) / h)).
        let end = self.start_opl + self.bins as f64 * self.bin_width_opl;
        if !end.is_finite() {
            return Err(format!(
                "the time window ends beyond the floating-point range: start_opl {:e} + {} bins x {:e}",
                self.start_opl, self.bins, self.bin_width_opl
            ));
        }
        let scale = self.start_opl.abs().max(end.abs());
        if self.bin_width_opl < scale * 1e-12 {
            return Err(format!(
                "bin_width_opl {:e} is too narrow to resolve OPLs near {scale:e} in double precision",
                self.bin_width_opl
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bins_are_half_open_boxes() {
        let f = Film {
            width: 1,
            height: 1,
            bins: 10,
            start_opl: 2.0,
            bin_width_opl: 0.5,
        };
        assert_eq!(f.bin(1.999), None);
        assert_eq!(f.bin(2.0), Some(0));
        assert_eq!(f.bin(2.49), Some(0));
        assert_eq!(f.bin(2.5), Some(1));
        assert_eq!(f.bin(6.99), Some(9));
        assert_eq!(f.bin(7.0), None);
        assert_eq!(f.bin(f64::NAN), None);
    }

    #[test]
    fn time_windows_beyond_double_precision_are_errors() {
        let film = |start_opl: f64, bin_width_opl: f64| Film {
            width: 2,
            height: 2,
            bins: 10,
            start_opl,
            bin_width_opl,
        };
        assert!(film(3.5, 0.04).validate().is_ok());
        assert!(film(-1e6, 1e-3).validate().is_ok());
        let e = film(1e308, 1e308).validate().unwrap_err();
        assert!(e.contains("beyond the floating-point range"), "{e}");
        let e = film(1e10, 1e-10).validate().unwrap_err();
        assert!(e.contains("too narrow"), "{e}");
    }
}
