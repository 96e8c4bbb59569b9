//! Temporal profiles p(dt): the density of the delay with which a delaying material
//! re-emits the light it receives (SPEC section 6). dt >= 0 in OPL units (scene units,
//! like bin widths).
//!
//! | XML type | parameters | density | inverse CDF |
//! |----------|------------|---------|-------------|
//! | `ConstantTP` | `delay` c >= 0 | delta at c | c |
//! | `ExponentialTP` | `lambda` > 0 | lambda exp(-lambda dt) | -ln(1 - u) / lambda |
//! | `EpanechnikovTP` (alias `PosEpanTP`) | `mu` >= `sigma` > 0 | 3/(4 sigma) (1 - ((dt - mu)/sigma)^2) on (mu - sigma, mu + sigma) | mu + 2 sigma sin(asin(2u - 1) / 3) |
//!
//! Every profile draws its delay from exactly one uniform number (the constant one
//! ignores it), so changing a profile's parameters never shifts the random streams of
//! the rest of the path: renders of the same scene with delays 0 and c are the same
//! paths, shifted in time.

/// A delay density.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TemporalProfile {
    Constant { delay: f32 },
    Exponential { lambda: f32 },
    Epanechnikov { mu: f32, sigma: f32 },
}

impl TemporalProfile {
    /// A delay drawn by inversion from `u` uniform in [0, 1).
    #[inline]
    pub fn sample(&self, u: f32) -> f32 {
        match *self {
            TemporalProfile::Constant { delay } => delay,
            TemporalProfile::Exponential { lambda } => -(1.0 - u).ln() / lambda,
            TemporalProfile::Epanechnikov { mu, sigma } => {
                // In f64: asin near +-1 loses precision in f32 for the outer 1e-4.
                let x = 2.0 * (((2.0 * u as f64 - 1.0).clamp(-1.0, 1.0)).asin() / 3.0).sin();
                (mu as f64 + sigma as f64 * x).max(0.0) as f32
            }
        }
    }

    /// The cumulative distribution P(delay <= dt) (for tests and binned densities).
    pub fn cdf(&self, dt: f64) -> f64 {
        match *self {
            TemporalProfile::Constant { delay } => {
                if dt >= delay as f64 {
                    1.0
                } else {
                    0.0
                }
            }
            TemporalProfile::Exponential { lambda } => {
                if dt <= 0.0 {
                    0.0
                } else {
                    1.0 - (-(lambda as f64) * dt).exp()
                }
            }
            TemporalProfile::Epanechnikov { mu, sigma } => {
                let x = ((dt - mu as f64) / sigma as f64).clamp(-1.0, 1.0);
                (2.0 + 3.0 * x - x * x * x) / 4.0
            }
        }
    }

    /// The mean delay.
    pub fn mean(&self) -> f64 {
        match *self {
            TemporalProfile::Constant { delay } => delay as f64,
            TemporalProfile::Exponential { lambda } => 1.0 / lambda as f64,
            TemporalProfile::Epanechnikov { mu, .. } => mu as f64,
        }
    }

    /// Keeps parameters read from a texture at a hit inside the model's domain: delay
    /// >= 0, lambda >= 1e-6, sigma >= 1e-6, mu >= sigma (a constant must already be).
    pub fn clamped(self) -> Self {
        match self {
            TemporalProfile::Constant { delay } => TemporalProfile::Constant {
                delay: delay.max(0.0),
            },
            TemporalProfile::Exponential { lambda } => TemporalProfile::Exponential {
                lambda: lambda.max(1e-6),
            },
            TemporalProfile::Epanechnikov { mu, sigma } => {
                let sigma = sigma.max(1e-6);
                TemporalProfile::Epanechnikov {
                    mu: mu.max(sigma),
                    sigma,
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inverse_cdfs_invert_the_cdfs() {
        let profiles = [
            TemporalProfile::Exponential { lambda: 2.0 },
            TemporalProfile::Exponential { lambda: 0.5 },
            TemporalProfile::Epanechnikov {
                mu: 0.5,
                sigma: 0.1,
            },
            TemporalProfile::Epanechnikov {
                mu: 0.5,
                sigma: 0.5,
            },
        ];
        for p in profiles {
            for i in 1..100 {
                let u = i as f32 / 100.0;
                let dt = p.sample(u);
                assert!(dt >= 0.0);
                assert!((p.cdf(dt as f64) - u as f64).abs() < 2e-5, "{p:?} u {u}");
            }
        }
        let c = TemporalProfile::Constant { delay: 1.5 };
        assert_eq!((c.sample(0.0), c.sample(0.99)), (1.5, 1.5));
        assert_eq!((c.cdf(1.4999), c.cdf(1.5)), (0.0, 1.0));
        // Support of the positive Epanechnikov: [mu - sigma, mu + sigma].
        let e = TemporalProfile::Epanechnikov {
            mu: 0.5,
            sigma: 0.5,
        };
        assert!(e.sample(0.0).abs() < 1e-6 && (e.sample(0.999_999) - 1.0).abs() < 1e-3);
    }

    #[test]
    fn clamping_keeps_textured_parameters_in_the_domain() {
        let e = TemporalProfile::Epanechnikov {
            mu: 0.1,
            sigma: 0.3,
        }
        .clamped();
        assert_eq!(
            e,
            TemporalProfile::Epanechnikov {
                mu: 0.3,
                sigma: 0.3
            }
        );
        assert_eq!(
            TemporalProfile::Constant { delay: -1.0 }.clamped(),
            TemporalProfile::Constant { delay: 0.0 }
        );
    }
}
