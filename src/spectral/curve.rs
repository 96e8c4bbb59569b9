//! A spectrum given in a scene (`<spectrum value="...">` or a `.spd` file), kept for
//! the spectral mode, which uses it as given (Mitsuba 3's `uniform` and `irregular`
//! spectra): a constant, or values at increasing wavelengths, linear in between and
//! zero outside the listed range.

/// A spectrum as the scene gives it.
#[derive(Clone, Debug, PartialEq)]
pub enum Curve {
    Uniform(f32),
    /// Wavelengths (nm, increasing, at least two) and their values.
    Irregular {
        wavelengths: Vec<f32>,
        values: Vec<f32>,
    },
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
}
