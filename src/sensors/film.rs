//! The film: image size and the time axis (SPEC 3; `time_axis.rs`). `scene/film.rs`
//! reads `transient_hdr_film`.
//!
//! A contribution with path OPL `o` lands in bin `k = floor((o - t0) / h)` when
//! `0 <= k < T` and in no bin otherwise (it still counts in the steady image).

use super::time_axis::TimeAxis;

#[derive(Clone, Debug, PartialEq)]
pub struct Film {
    pub width: usize,
    pub height: usize,
    pub time: TimeAxis,
    /// Channels C of every volume and image of the film: 3 (rgb, spectral: linear
    /// sRGB), 1 (mono) or 4 (mono_polarized: the Stokes components S0..S3). Set by the
    /// scene's render mode (`Scene::set_mode`); 3 when read.
    pub channels: usize,
}

impl Film {
    /// Time bin of a contribution arriving at optical path length `opl`.
    #[inline]
    pub fn bin(&self, opl: f64) -> Option<u32> {
        self.time.bin(opl)
    }

    pub fn pixels(&self) -> usize {
        self.width * self.height
    }

    /// Checks the settings after overrides were applied.
    pub fn validate(&self) -> Result<(), FilmError> {
        let (width, height, bins) = (self.width, self.height, self.time.bins);
        let (start_opl, bin_width_opl) = (self.time.start_opl, self.time.bin_width_opl);
        if width == 0 || height == 0 {
            return Err(FilmError::Empty { width, height });
        }
        if bins == 0 {
            return Err(FilmError::NoBins);
        }
        // Every later size computation (sums, G-buffers, bytes) stays within usize.
        let bytes = [height, bins, 3, 8, 4]
            .iter()
            .try_fold(width, |n, &f| n.checked_mul(f));
        if bytes.is_none() {
            return Err(FilmError::TooLarge {
                width,
                height,
                bins,
            });
        }
        if bins > u32::MAX as usize {
            return Err(FilmError::TooManyBins { bins });
        }
        check_bin_width("bin_width_opl", bin_width_opl)?;
        if !start_opl.is_finite() {
            return Err(FilmError::Start { start_opl });
        }
        // The window's end must be a number, and a bin must be wider than the f64
        // spacing of the OPLs it holds (else bins merge: k = floor((opl - t0) / h)).
        let end = start_opl + bins as f64 * bin_width_opl;
        if !end.is_finite() {
            return Err(FilmError::WindowOverflow {
                start_opl,
                bins,
                bin_width_opl,
            });
        }
        let scale = start_opl.abs().max(end.abs());
        if bin_width_opl < scale * 1e-12 {
            return Err(FilmError::BinTooNarrow {
                bin_width_opl,
                scale,
            });
        }
        Ok(())
    }
}

/// A bin width given anywhere (the scene's `bin_width_opl` or legacy `exposure`,
/// `--bin-width-opl`) that is not positive and finite; `name` is what the user wrote.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{name} must be positive, got {value}")]
pub struct BinWidthError {
    pub name: String,
    pub value: f64,
}

/// The one rule for a bin width h (SPEC 3): positive and finite. The manifest's reader
/// adds a magnitude bound of the file format (`bundle::read`), and [`Film::validate`]
/// checks h against the window's span.
pub fn check_bin_width(name: &str, h: f64) -> Result<f64, BinWidthError> {
    if h > 0.0 && h.is_finite() {
        Ok(h)
    } else {
        Err(BinWidthError {
            name: name.to_string(),
            value: h,
        })
    }
}

/// Why film settings cannot make a film ([`Film::validate`]).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum FilmError {
    /// No pixels.
    #[error("film size {width}x{height} is empty")]
    Empty { width: usize, height: usize },
    /// No time bins.
    #[error("temporal_bins must be at least 1")]
    NoBins,
    /// More values than sizes in memory (`usize`) can count.
    #[error("a film of {width}x{height} px and {bins} bins is too large to address")]
    TooLarge {
        width: usize,
        height: usize,
        bins: usize,
    },
    /// More bins than 32-bit bin indices address.
    #[error("temporal_bins {bins} is above the largest supported count {max}", max = u32::MAX)]
    TooManyBins { bins: usize },
    /// A bin width that is not positive and finite.
    #[error(transparent)]
    BinWidth(#[from] BinWidthError),
    /// A start that is not finite.
    #[error("start_opl must be finite, got {start_opl}")]
    Start { start_opl: f64 },
    /// A time window whose end overflows.
    #[error(
        "the time window ends beyond the floating-point range: start_opl {start_opl:e} + {bins} bins x {bin_width_opl:e}"
    )]
    WindowOverflow {
        start_opl: f64,
        bins: usize,
        bin_width_opl: f64,
    },
    /// Bins narrower than the double-precision spacing of the window's OPLs (`scale`,
    /// the window's largest magnitude).
    #[error(
        "bin_width_opl {bin_width_opl:e} is too narrow to resolve OPLs near {scale:e} in double precision"
    )]
    BinTooNarrow { bin_width_opl: f64, scale: f64 },
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn time_windows_beyond_double_precision_are_errors() {
        let film = |start_opl: f64, bin_width_opl: f64| Film {
            width: 2,
            height: 2,
            time: TimeAxis {
                bins: 10,
                start_opl,
                bin_width_opl,
            },
            channels: 3,
        };
        assert!(film(3.5, 0.04).validate().is_ok());
        assert!(film(-1e6, 1e-3).validate().is_ok());
        let e = film(1e308, 1e308).validate().unwrap_err();
        assert!(
            e.to_string().contains("beyond the floating-point range"),
            "{e}"
        );
        let e = film(1e10, 1e-10).validate().unwrap_err();
        assert!(e.to_string().contains("too narrow"), "{e}");
    }
}
