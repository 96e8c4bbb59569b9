//! A spectrum given in a scene (`<spectrum value="...">`, a `.spd` file or `<spectrum
//! type="blackbody">`), kept for the spectral mode, which uses it as given (Mitsuba 3's
//! `uniform`, `irregular` and `blackbody` spectra): a constant, values at increasing
//! wavelengths (linear in between, zero outside the listed range), or Planck's law.

// Mitsuba's constants and results keep their digits (f32 rounds them).
#![allow(clippy::excessive_precision)]

/// A spectrum as the scene gives it.
#[derive(Clone, Debug, PartialEq)]
pub enum Curve {
    Uniform(f32),
    /// Wavelengths (nm, increasing, at least two) and their values.
    Irregular {
        wavelengths: Vec<f32>,
        values: Vec<f32>,
    },
    /// Planck's law at `temperature` kelvin, in W m^-2 sr^-1 nm^-1 (Mitsuba's
    /// `blackbody`; [`blackbody`]), zero outside `range` (nm, inclusive).
    Blackbody {
        temperature: f32,
        range: [f32; 2],
    },
}

/// Mitsuba 3's `blackbody` constants (`src/spectra/blackbody.cpp`), in single
/// precision as there: the speed of light (m/s), Planck's and Boltzmann's constants.
const C: f32 = 2.997_924_58e8;
const H: f32 = 6.626_070_04e-34;
const K: f32 = 1.380_648_52e-23;
/// The first and second radiation constants, `2 h c^2` and `h c / k`, as Mitsuba
/// computes them (single precision, left to right).
const C0: f32 = 2.0 * H * C * C;
const C1: f32 = H * C / K;

/// Planck's law at `lambda` nm for `temperature` kelvin, per nanometre of wavelength,
/// evaluated as Mitsuba 3.9's `BlackBodySpectrum::eval_impl` (single precision, the
/// same operations in the same order): `1e-9 c0 / (l^5 (exp(c1 / (l T)) - 1))` with
/// `l = lambda 1e-9` m; zero outside `range` (nm, inclusive) and for NaN.
#[inline]
pub fn blackbody(lambda: f32, temperature: f32, range: [f32; 2]) -> f32 {
    if !(lambda >= range[0] && lambda <= range[1]) {
        return 0.0;
    }
    let l = lambda * 1e-9;
    let l2 = l * l;
    let l5 = l2 * l2 * l;
    1e-9 * C0 / (l5 * ((C1 / (l * temperature)).exp() - 1.0))
}

impl Curve {
    /// The value at `lambda` nm.
    pub fn eval(&self, lambda: f32) -> f32 {
        match self {
            Curve::Uniform(v) => *v,
            Curve::Irregular {
                wavelengths: w,
                values: v,
            } => {
                let n = w.len();
                if n < 2 || !(lambda >= w[0] && lambda <= w[n - 1]) {
                    return 0.0;
                }
                // The last listed wavelength <= lambda, kept below the last interval.
                let i = w
                    .partition_point(|&x| x <= lambda)
                    .saturating_sub(1)
                    .min(n - 2);
                let t = (lambda - w[i]) / (w[i + 1] - w[i]);
                v[i] + t * (v[i + 1] - v[i])
            }
            Curve::Blackbody { temperature, range } => blackbody(lambda, *temperature, *range),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn irregular_spectra_interpolate_and_vanish_outside() {
        let c = Curve::Irregular {
            wavelengths: vec![400.0, 500.0, 700.0],
            values: vec![1.0, 3.0, 0.0],
        };
        assert_eq!(c.eval(400.0), 1.0);
        assert_eq!(c.eval(450.0), 2.0);
        assert_eq!(c.eval(500.0), 3.0);
        assert_eq!(c.eval(600.0), 1.5);
        assert_eq!(c.eval(700.0), 0.0);
        assert_eq!(c.eval(399.9), 0.0);
        assert_eq!(c.eval(700.1), 0.0);
        assert_eq!(c.eval(f32::NAN), 0.0);
        assert_eq!(Curve::Uniform(2.5).eval(555.0), 2.5);
    }

    /// Planck's law written out in f64 with CODATA 2014's constants (those Mitsuba
    /// uses): `2 h c^2 / l^5 / (exp(h c / (l k T)) - 1)` W m^-2 sr^-1 m^-1, times 1e-9
    /// per nanometre.
    fn planck(lambda_nm: f64, t: f64) -> f64 {
        let (c, h, k) = (2.99792458e8, 6.62607004e-34, 1.38064852e-23);
        let l = lambda_nm * 1e-9;
        2.0 * h * c * c / l.powi(5) / ((h * c / (l * k * t)).exp() - 1.0) * 1e-9
    }

    #[test]
    fn blackbody_is_plancks_law_in_its_range_and_zero_outside() {
        let range = [360.0, 830.0];
        for t in [800.0, 1900.0, 2700.0, 5000.0, 6504.0, 10_000.0, 40_000.0] {
            let c = Curve::Blackbody {
                temperature: t,
                range,
            };
            for i in 0..=470 {
                let l = 360.0 + i as f32;
                let (got, want) = (f64::from(c.eval(l)), planck(f64::from(l), f64::from(t)));
                // Single precision: a few ulps through pow 5, exp and the division.
                assert!(
                    (got - want).abs() <= 2e-5 * want,
                    "T {t} K, {l} nm: {got} vs {want}"
                );
            }
            for l in [359.99, 830.01, 200.0, 1000.0, f32::NAN] {
                assert_eq!(c.eval(l), 0.0, "{l}");
            }
        }
        // A narrower range cuts the curve there.
        let c = Curve::Blackbody {
            temperature: 3000.0,
            range: [500.0, 600.0],
        };
        assert_eq!(c.eval(499.9), 0.0);
        assert_eq!(c.eval(600.1), 0.0);
        assert!(c.eval(500.0) > 0.0 && c.eval(600.0) > c.eval(500.0));
    }

    /// Mitsuba 3.9.1's `blackbody` (`scalar_spectral`, `eval` at 360, 456, 700 and 830
    /// nm; its own test checks 5000 K at 456 and 700 nm): within 2 ulps of float.
    #[test]
    fn blackbody_matches_mitsuba() {
        let mitsuba: [(f32, [f32; 4]); 3] = [
            (
                5000.0,
                [
                    6655.12060546875,
                    10997.8994140625,
                    11811.9638671875,
                    9741.78515625,
                ],
            ),
            (
                1900.0,
                [
                    0.01442571822553873,
                    0.3707160949707031,
                    14.200480461120605,
                    32.983367919921875,
                ],
            ),
            (40000.0, [11478999.0, 5030910.5, 1055002.125, 557421.8125]),
        ];
        for (t, want) in mitsuba {
            let c = Curve::Blackbody {
                temperature: t,
                range: [360.0, 830.0],
            };
            let got = [360.0, 456.0, 700.0, 830.0].map(|l| c.eval(l));
            for (g, w) in got.iter().zip(want) {
                assert!(
                    (g - w).abs() <= 2.0 * f32::EPSILON * w,
                    "{t} K: {got:?} vs {want:?}"
                );
            }
        }
    }
}
