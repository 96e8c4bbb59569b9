//! Variance-stabilising transforms applied to every path sample before its
//! moments are accumulated (SPEC section 5).
//!
//! - identity: `z(x) = x`;
//! - Box-Cox(lambda > 0): `z(x) = (x^lambda - 1) / lambda`, so `z(0) = -1/lambda`;
//!   radiance samples `x >= 0` only (the signed render modes refuse it);
//! - Yeo-Johnson(lambda): `z(x) = ((x + 1)^lambda - 1) / lambda` for `x >= 0` (or
//!   `ln(1 + x)` when `lambda == 0`), and `z(x) = -((1 - x)^(2 - lambda) - 1) / (2 -
//!   lambda)` for `x < 0` (or `-ln(1 - x)` when `lambda == 2`), Yeo and Johnson's
//!   (2000) both branches: `z(0) = 0`, continuous and increasing through 0, defined
//!   for every real sample (a spectral path's negative sRGB, the Stokes components
//!   S1..S3). Radiance samples take the first branch only.
//!
//! The evaluation uses `exp_m1`/`ln_1p` so that small `lambda` and `x` near the
//! point where `z` vanishes keep full relative precision.

use super::StatsError;
use std::fmt;
use std::str::FromStr;

/// The largest |lambda| accepted (see [`Transform::validate`]).
pub(crate) const MAX_LAMBDA: f64 = 10.0;
/// The smallest Box-Cox lambda accepted (see [`Transform::validate`]).
pub(crate) const BOX_COX_MIN: f64 = 1e-6;

/// The accepted textual forms, quoted in every parse error.
pub(crate) const ACCEPTED_FORMS: &str =
    "accepted forms: \"identity\", \"box-cox:LAMBDA\" (LAMBDA > 0, \
     e.g. \"box-cox:0.5\"), \"yeo-johnson:LAMBDA\" (any finite LAMBDA, e.g. \"yeo-johnson:0.5\" \
     or \"yeo-johnson:0\")";

/// The variance-stabilising transform applied to each path sample before summing.
///
/// Serialised (in the bundle manifest) as `{"kind":"identity"}`,
/// `{"kind":"box-cox","lambda":0.5}` or `{"kind":"yeo-johnson","lambda":0.0}`.
/// Deserialisation does not check `lambda`; call [`Transform::validate`] on
/// values read from files.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum Transform {
    /// `z(x) = x`.
    Identity,
    /// `z(x) = (x^lambda - 1) / lambda`, `lambda > 0`.
    BoxCox { lambda: f64 },
    /// `z(x) = ((x + 1)^lambda - 1) / lambda` (`ln(1 + x)` when `lambda == 0`).
    YeoJohnson { lambda: f64 },
}

impl Default for Transform {
    /// Identity is the default transform (SPEC 5).
    fn default() -> Self {
        Transform::Identity
    }
}

impl Transform {
    /// `z(x)` for a radiance sample `x >= 0` (SPEC 5). Hot path.
    ///
    /// Negative `x` is outside the contract (Box-Cox then gives NaN); the
    /// renderer only produces non-negative samples.
    #[inline]
    pub fn apply(&self, x: f64) -> f64 {
        match *self {
            Transform::Identity => x,
            // For x = 0: ln(0) = -inf, exp_m1(-inf) = -1, so this yields exactly
            // -1/lambda = at_zero() without a branch (lambda > 0).
            Transform::BoxCox { lambda } => (lambda * x.ln()).exp_m1() / lambda,
            Transform::YeoJohnson { lambda } if x >= 0.0 => {
                let l = x.ln_1p();
                if lambda == 0.0 {
                    l
                } else {
                    (lambda * l).exp_m1() / lambda
                }
            }
            Transform::YeoJohnson { lambda } => {
                let l = (-x).ln_1p();
                let mu = 2.0 - lambda;
                if mu == 0.0 {
                    -l
                } else {
                    -(mu * l).exp_m1() / mu
                }
            }
        }
    }

    /// `z(0)`: 0 for identity and Yeo-Johnson, `-1/lambda` for Box-Cox.
    /// This is the value zero-filled for samples that deposited nothing.
    #[inline]
    pub fn at_zero(&self) -> f64 {
        match *self {
            Transform::Identity | Transform::YeoJohnson { .. } => 0.0,
            Transform::BoxCox { lambda } => -1.0 / lambda,
        }
    }

    /// True for [`Transform::Identity`] (then the raw sum `S` is `X1`, not stored twice).
    #[inline]
    pub fn is_identity(&self) -> bool {
        matches!(self, Transform::Identity)
    }

    /// The parameter of Box-Cox / Yeo-Johnson, `None` for the identity.
    #[inline]
    pub fn lambda(&self) -> Option<f64> {
        match *self {
            Transform::Identity => None,
            Transform::BoxCox { lambda } | Transform::YeoJohnson { lambda } => Some(lambda),
        }
    }

    /// Checks the parameter: Box-Cox `lambda` in [1e-6, 10], Yeo-Johnson `lambda` in
    /// [-10, 10]. Beyond these the transformed samples' cubes overflow f64 for ordinary
    /// radiance (Box-Cox maps 0 to -1/lambda: lambda = 1e-200 put +inf into X2), and
    /// transforms in use stay within [-2, 2]. [`FromStr`] always validates; use this on
    /// values deserialised from a manifest.
    pub fn validate(&self) -> Result<(), StatsError> {
        match *self {
            Transform::Identity => Ok(()),
            Transform::BoxCox { lambda } => {
                if !lambda.is_finite() {
                    Err(StatsError::BoxCoxNotFinite(lambda))
                } else if lambda <= 0.0 {
                    Err(StatsError::BoxCoxNotPositive(lambda))
                } else if !(BOX_COX_MIN..=MAX_LAMBDA).contains(&lambda) {
                    Err(StatsError::BoxCoxRange(lambda))
                } else {
                    Ok(())
                }
            }
            Transform::YeoJohnson { lambda } => {
                if !lambda.is_finite() {
                    Err(StatsError::YeoJohnsonNotFinite(lambda))
                } else if lambda.abs() > MAX_LAMBDA {
                    Err(StatsError::YeoJohnsonRange(lambda))
                } else {
                    Ok(())
                }
            }
        }
    }
}

impl FromStr for Transform {
    type Err = StatsError;

    /// Parses `identity`, `box-cox:LAMBDA` or `yeo-johnson:LAMBDA`
    /// (surrounding whitespace is ignored).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let text = s.trim();
        let (name, param) = match text.split_once(':') {
            Some((name, param)) => (name.trim(), Some(param.trim())),
            None => (text, None),
        };
        let lambda = |kind: &'static str| -> Result<f64, StatsError> {
            match param {
                None | Some("") => Err(StatsError::NoLambda {
                    input: s.to_string(),
                    kind,
                }),
                Some(p) => p.parse::<f64>().map_err(|_| StatsError::LambdaNotANumber {
                    input: s.to_string(),
                    lambda: p.to_string(),
                }),
            }
        };
        let t = match name {
            "identity" => match param {
                None => Transform::Identity,
                Some(_) => return Err(StatsError::IdentityLambda(s.to_string())),
            },
            "box-cox" => Transform::BoxCox {
                lambda: lambda("box-cox")?,
            },
            "yeo-johnson" => Transform::YeoJohnson {
                lambda: lambda("yeo-johnson")?,
            },
            _ => return Err(StatsError::UnknownTransform(s.to_string())),
        };
        t.validate().map_err(|e| StatsError::BadLambda {
            input: s.to_string(),
            error: Box::new(e),
        })?;
        Ok(t)
    }
}

impl fmt::Display for Transform {
    /// `identity`, `box-cox:0.5`, `yeo-johnson:0`; f64 `Display` is the
    /// shortest representation that parses back to the same value, so this
    /// round-trips exactly through [`FromStr`].
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Transform::Identity => write!(f, "identity"),
            Transform::BoxCox { lambda } => write!(f, "box-cox:{lambda}"),
            Transform::YeoJohnson { lambda } => write!(f, "yeo-johnson:{lambda}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const E: f64 = std::f64::consts::E;

    /// |a - b| <= tol * max(|a|, |b|), or exact equality.
    fn close(a: f64, b: f64, tol: f64) -> bool {
        a == b || (a - b).abs() <= tol * a.abs().max(b.abs())
    }

    fn bc(lambda: f64) -> Transform {
        Transform::BoxCox { lambda }
    }

    fn yj(lambda: f64) -> Transform {
        Transform::YeoJohnson { lambda }
    }

    #[test]
    fn identity_values() {
        let t = Transform::Identity;
        for x in [0.0, 1e-300, 0.1, 1.0, 3.5, 1e12] {
            assert_eq!(t.apply(x), x);
        }
        assert_eq!(t.at_zero(), 0.0);
        assert!(t.is_identity());
        assert_eq!(t.lambda(), None);
        assert_eq!(Transform::default(), Transform::Identity);
    }

    #[test]
    fn box_cox_hand_values() {
        // (4^0.5 - 1)/0.5 = 2; (0 - 1)/0.5 = -2; (1 - 1)/0.5 = 0; (9^0.5-1)/0.5 = 4.
        let t = bc(0.5);
        assert!(close(t.apply(4.0), 2.0, 1e-15), "{}", t.apply(4.0));
        assert_eq!(t.apply(0.0), -2.0);
        assert_eq!(t.apply(1.0), 0.0);
        assert!(close(t.apply(9.0), 4.0, 1e-15));
        // lambda = 1: z = x - 1; lambda = 2: z = (x^2 - 1)/2.
        assert!(close(bc(1.0).apply(5.0), 4.0, 1e-15));
        assert!(close(bc(2.0).apply(3.0), 4.0, 1e-15));
        // lambda = 0.25 at 16: (2 - 1)/0.25 = 4.
        assert!(close(bc(0.25).apply(16.0), 4.0, 1e-15));
        // Small lambda approaches ln(x) without cancellation: ln(e^2) = 2.
        let z = bc(1e-12).apply(E * E);
        assert!(close(z, 2.0, 1e-11), "{z}");
        assert!(!t.is_identity());
        assert_eq!(t.lambda(), Some(0.5));
    }

    #[test]
    fn box_cox_at_zero_and_near_zero() {
        for lambda in [0.5, 0.3, 1.0, 2.0, 1e-3] {
            let t = bc(lambda);
            assert_eq!(t.at_zero(), -1.0 / lambda);
            // apply(0) must be bit-identical to the zero-fill value.
            assert_eq!(t.apply(0.0), t.at_zero(), "lambda {lambda}");
            // Tiny and subnormal samples stay finite and just above z(0).
            for x in [1e-300, 5e-324, 1e-12] {
                let z = t.apply(x);
                assert!(
                    z.is_finite() && z >= t.at_zero(),
                    "lambda {lambda} x {x}: {z}"
                );
            }
        }
        assert_eq!(bc(0.5).at_zero(), -2.0);
    }

    #[test]
    fn yeo_johnson_hand_values() {
        // ((3+1)^0.5 - 1)/0.5 = 2.
        assert!(
            close(yj(0.5).apply(3.0), 2.0, 1e-15),
            "{}",
            yj(0.5).apply(3.0)
        );
        // lambda = 0: ln(1 + (e - 1)) = 1.
        assert!(close(yj(0.0).apply(E - 1.0), 1.0, 1e-15));
        // lambda = 2 at 1: (4 - 1)/2 = 1.5; lambda = -1 at 1: (1/2 - 1)/(-1) = 0.5.
        assert!(close(yj(2.0).apply(1.0), 1.5, 1e-15));
        assert!(close(yj(-1.0).apply(1.0), 0.5, 1e-15));
        // lambda = 1 is the identity on x >= 0.
        assert!(close(yj(1.0).apply(7.25), 7.25, 1e-15));
        // ln_1p keeps precision for tiny x: ln(1 + 1e-20) = 1e-20.
        assert!(close(yj(0.0).apply(1e-20), 1e-20, 1e-15));
        assert!(close(yj(0.5).apply(1e-20), 1e-20, 1e-15));
        // Continuity in lambda at 0.
        let x = 12.5;
        assert!(close(yj(1e-12).apply(x), yj(0.0).apply(x), 1e-11));
        assert!(close(yj(-1e-12).apply(x), yj(0.0).apply(x), 1e-11));
        assert_eq!(yj(0.0).lambda(), Some(0.0));
    }

    #[test]
    fn yeo_johnson_at_zero() {
        for lambda in [0.0, 0.5, -0.7, 2.0] {
            let t = yj(lambda);
            assert_eq!(t.at_zero(), 0.0);
            assert_eq!(t.apply(0.0), 0.0, "lambda {lambda}");
            // z >= 0 for every lambda on x >= 0.
            assert!(t.apply(0.3) > 0.0);
        }
    }

    #[test]
    fn monotone_increasing() {
        for t in [
            Transform::Identity,
            bc(0.5),
            bc(2.0),
            yj(0.0),
            yj(0.5),
            yj(-1.0),
        ] {
            let mut prev = t.apply(0.0);
            for i in 1..200 {
                let x = 1e-6 * 1.2f64.powi(i);
                let z = t.apply(x);
                assert!(z > prev, "{t}: z({x}) = {z} <= {prev}");
                prev = z;
            }
        }
    }

    #[test]
    fn parse_accepted_forms() {
        assert_eq!("identity".parse::<Transform>(), Ok(Transform::Identity));
        assert_eq!(" identity ".parse::<Transform>(), Ok(Transform::Identity));
        assert_eq!("box-cox:0.5".parse::<Transform>(), Ok(bc(0.5)));
        assert_eq!("yeo-johnson:0.5".parse::<Transform>(), Ok(yj(0.5)));
        assert_eq!("yeo-johnson:0".parse::<Transform>(), Ok(yj(0.0)));
        assert_eq!("yeo-johnson:-0.25".parse::<Transform>(), Ok(yj(-0.25)));
        assert_eq!("box-cox:1e-3".parse::<Transform>(), Ok(bc(1e-3)));
    }

    #[test]
    fn display_parse_round_trip() {
        let cases = [
            Transform::Identity,
            bc(0.5),
            bc(0.1),
            bc(1.0 / 3.0),
            bc(2.0),
            bc(1e-6),
            yj(0.0),
            yj(0.5),
            yj(-0.7),
            yj(1.0 / 3.0),
            yj(9.876),
        ];
        for t in cases {
            let s = t.to_string();
            let back: Transform = s.parse().unwrap_or_else(|e| panic!("{s}: {e}"));
            assert_eq!(back, t, "{s}");
        }
        assert_eq!(bc(0.5).to_string(), "box-cox:0.5");
        assert_eq!(yj(0.0).to_string(), "yeo-johnson:0");
        assert_eq!(Transform::Identity.to_string(), "identity");
    }

    #[test]
    fn parse_errors_name_input_and_list_forms() {
        let bad = [
            "",
            "foo",
            "boxcox:0.5",
            "Identity",
            "identity:1",
            "box-cox",
            "box-cox:",
            "box-cox:abc",
            "box-cox:0",
            "box-cox:-0.5",
            "box-cox:inf",
            "box-cox:NaN",
            "yeo-johnson",
            "yeo-johnson:",
            "yeo-johnson:x1",
            "yeo-johnson:nan",
            "yeo-johnson:-inf",
            "yeo-johnson:1e999",
        ];
        for s in bad {
            let err = s
                .parse::<Transform>()
                .expect_err(&format!("{s:?} should be rejected"))
                .to_string();
            assert!(err.contains(&format!("{s:?}")), "{s:?}: {err}");
            assert!(
                err.contains("identity")
                    && err.contains("box-cox:LAMBDA")
                    && err.contains("yeo-johnson:LAMBDA"),
                "{s:?}: {err}"
            );
        }
        let err = "box-cox:0".parse::<Transform>().unwrap_err().to_string();
        assert!(err.contains("> 0"), "{err}");
        let err = "box-cox:abc".parse::<Transform>().unwrap_err().to_string();
        assert!(
            err.contains("\"abc\"") && err.contains("not a number"),
            "{err}"
        );
        let err = "yeo-johnson:nan"
            .parse::<Transform>()
            .unwrap_err()
            .to_string();
        assert!(err.contains("finite"), "{err}");
        let err = "sqrt".parse::<Transform>().unwrap_err().to_string();
        assert!(err.contains("unknown transform"), "{err}");
    }

    #[test]
    fn validate_rejects_bad_lambdas() {
        assert!(Transform::Identity.validate().is_ok());
        assert!(bc(0.5).validate().is_ok());
        assert!(matches!(
            bc(0.0).validate(),
            Err(StatsError::BoxCoxNotPositive(l)) if l == 0.0
        ));
        assert!(matches!(
            bc(-1.0).validate(),
            Err(StatsError::BoxCoxNotPositive(l)) if l == -1.0
        ));
        assert!(matches!(
            bc(f64::NAN).validate(),
            Err(StatsError::BoxCoxNotFinite(l)) if l.is_nan()
        ));
        assert!(matches!(
            bc(f64::INFINITY).validate(),
            Err(StatsError::BoxCoxNotFinite(l)) if l == f64::INFINITY
        ));
        assert!(yj(0.0).validate().is_ok());
        assert!(yj(-3.0).validate().is_ok());
        assert!(matches!(
            yj(f64::NAN).validate(),
            Err(StatsError::YeoJohnsonNotFinite(l)) if l.is_nan()
        ));
    }

    #[test]
    fn serde_json_shape() {
        let j = |t: Transform| serde_json::to_string(&t).unwrap();
        assert_eq!(j(Transform::Identity), r#"{"kind":"identity"}"#);
        assert_eq!(j(bc(0.5)), r#"{"kind":"box-cox","lambda":0.5}"#);
        assert_eq!(j(yj(0.0)), r#"{"kind":"yeo-johnson","lambda":0.0}"#);
        let p = |s: &str| serde_json::from_str::<Transform>(s).unwrap();
        assert_eq!(p(r#"{"kind": "box-cox", "lambda": 0.5}"#), bc(0.5));
        assert_eq!(p(r#"{"kind":"identity"}"#), Transform::Identity);
        assert_eq!(p(r#"{"kind":"yeo-johnson","lambda":0}"#), yj(0.0));
        assert_eq!(p(r#"{"lambda":-0.5,"kind":"yeo-johnson"}"#), yj(-0.5));
        for t in [Transform::Identity, bc(1.0 / 3.0), yj(-0.7)] {
            assert_eq!(p(&j(t)), t);
        }
        let e = serde_json::from_str::<Transform>(r#"{"kind":"box-cox"}"#)
            .unwrap_err()
            .to_string();
        assert!(e.contains("missing field `lambda`"), "{e}");
        let e = serde_json::from_str::<Transform>(r#"{"kind":"log"}"#)
            .unwrap_err()
            .to_string();
        assert!(e.contains("unknown variant `log`"), "{e}");
    }

    #[test]
    fn lambdas_whose_moments_overflow_are_refused() {
        for bad in [
            "box-cox:1e-200",
            "box-cox:1e-7",
            "box-cox:11",
            "yeo-johnson:1e10",
            "yeo-johnson:-11",
        ] {
            let e = bad.parse::<Transform>().unwrap_err().to_string();
            assert!(e.contains("must be in"), "{bad}: {e}");
        }
        for good in [
            "box-cox:1e-6",
            "box-cox:10",
            "yeo-johnson:-10",
            "yeo-johnson:0",
        ] {
            let t: Transform = good.parse().unwrap();
            // The moments of z(0) and z(1e6) stay finite up to the cube.
            for x in [0.0, 1e6] {
                assert!(t.apply(x).powi(3).is_finite(), "{good} at {x}");
            }
        }
    }

    /// Yeo-Johnson below zero: the textbook formula written out with `powf`, the
    /// `lambda = 2` limit, continuity and increase through 0, and `lambda = 1` the
    /// identity on both sides.
    #[test]
    fn yeo_johnson_is_defined_below_zero() {
        for lambda in [-0.7, 0.0, 0.5, 1.0, 1.5, 2.0, 3.0] {
            let t = Transform::YeoJohnson { lambda };
            for x in [-40.0f64, -3.0, -1.0, -0.5, -1e-9] {
                let want = if lambda == 2.0 {
                    -(1.0 - x).ln()
                } else {
                    -((1.0 - x).powf(2.0 - lambda) - 1.0) / (2.0 - lambda)
                };
                let got = t.apply(x);
                assert!(
                    (got - want).abs() <= 1e-12 * want.abs().max(1e-300) + 1e-15,
                    "lambda {lambda} x {x}: {got} against {want}"
                );
            }
            let (below, above) = (t.apply(-1e-12), t.apply(1e-12));
            assert!(
                below < 0.0 && above > 0.0 && (above - below) < 3e-12,
                "{lambda}"
            );
            let xs = [-5.0, -2.0, -1.0, -0.1, 0.0, 0.1, 1.0, 5.0];
            assert!(
                xs.windows(2).all(|w| t.apply(w[0]) < t.apply(w[1])),
                "{lambda}"
            );
        }
        let id = Transform::YeoJohnson { lambda: 1.0 };
        for x in [-7.25, -1.0, -0.5, 0.5, 3.0] {
            assert!((id.apply(x) - x).abs() < 1e-14, "{x}");
        }
    }
}
