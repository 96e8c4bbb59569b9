//! Two conventions where the published method's own code (its renderer's
//! `develop_stats` and its denoiser's `StatDenoiser`) differs from SPEC 5 and SPEC 8,
//! so that `--method published` can reproduce that code when asked:
//!
//! - [`Variance`]: the code's estimates use the biased variance `s2 = X2 / n - mu^2`
//!   in the skewness term and in `V` (`stats::estimators::estimate_biased`); SPEC 5
//!   uses the unbiased `sigma2 = s2 n / (n - 1)`, the better estimate of the mean's
//!   variance (it accepts about 0.1-0.3% more neighbour pairs).
//! - [`Border`]: the code zero-pads the volume, the estimands, the variances and the
//!   guidance at the borders of space and time. A padded neighbour has radiance 0,
//!   estimand 0 (z = 0) and variance 0, and guidance 0: the guidance positions are
//!   centred on the volume, so it sits at the volume's centre with black albedo and
//!   no normal. It passes the test when the centre's estimand is within `g sqrt(V)`
//!   of 0 on every channel, and then adds its base weight to the denominator only,
//!   pulling the centre towards 0. SPEC 8 clips the neighbourhood to the volume.

/// Which variance the estimates use (see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Variance {
    /// SPEC 5: `sigma2 = s2 n / (n - 1)`, `theta = mu + m3 / (6 sigma2 n)`, `V = sigma2 / n`.
    #[default]
    Unbiased,
    /// The published code: `theta = mu + m3 / (6 s2 n)`, `V = s2 / n`.
    Biased,
}

/// What lies beyond the volume's borders (see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Border {
    /// SPEC 8: neighbourhoods end at the borders.
    #[default]
    Clip,
    /// The published code: zeros, radiance, estimand, variance and guidance alike.
    Zero,
}
