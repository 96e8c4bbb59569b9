//! The fit behind the RGB-to-spectrum table (`rgb2spec.rs`): the forward model (a
//! coefficient vector's sRGB under D65, Simpson's 3/8 rule on 283 wavelengths), the
//! Levenberg-Marquardt optimiser, and a column's continuation along `k`, as
//! `rgb2spec_opt.cpp` does them. Pure arithmetic on `cie`'s tables and nothing else of
//! the crate, so that `build.rs` compiles this same file to compute the table the
//! binary embeds, and the tests compute columns afresh to check it.

use super::cie::{CIE1931_XYZ, CIE_SAMPLES, D65_ROWS};

/// Table resolution per axis (Mitsuba's `srgb.coeff` uses 64).
pub const RES: usize = 64;

/// Quadrature wavelengths: three per 5 nm interval of the CIE tables, plus one.
pub(crate) const FINE: usize = (CIE_SAMPLES - 1) * 3 + 1;
pub(crate) const LAMBDA_MIN: f64 = 360.0;
pub(crate) const LAMBDA_MAX: f64 = 830.0;

/// The first `k` of a column's continuation (`RES / 5` in rgb2spec).
pub(crate) const K_START: usize = RES / 5;
/// Levenberg-Marquardt iterations per node.
pub(crate) const LM_ITERATIONS: usize = 15;

/// rgb2spec's XYZ -> linear sRGB matrix (`details/cie1931.h`).
pub(crate) const XYZ_TO_SRGB: [[f64; 3]; 3] = [
    [3.240479, -1.537150, -0.498535],
    [-0.969256, 1.875991, 0.041556],
    [0.055648, -0.204043, 1.057311],
];

/// rgb2spec's linear sRGB -> XYZ matrix (`details/cie1931.h`).
pub(crate) const SRGB_TO_XYZ: [[f64; 3]; 3] = [
    [0.412453, 0.357580, 0.180423],
    [0.212671, 0.715160, 0.072169],
    [0.019334, 0.119193, 0.950227],
];

/// One table column: the coefficients of nodes `k = 0..RES` for fixed `(l, j, i)`.
pub(crate) type Column = [[f32; 3]; RES];

/// The target colour of node `(l, k, j, i)` with `x = i / (RES - 1)`, `y = j / (RES - 1)`
/// and `b = scale[k]`.
pub(crate) fn node_target(l: usize, x: f64, y: f64, b: f32) -> [f64; 3] {
    let b = f64::from(b);
    let mut rgb = [0.0; 3];
    rgb[l] = b;
    rgb[(l + 1) % 3] = x * b;
    rgb[(l + 2) % 3] = y * b;
    rgb
}

/// Coefficients on the normalised wavelength `t = (l - 360) / 470` -> on nanometres.
pub(crate) fn to_nanometres([a, b, c]: [f64; 3]) -> [f32; 3] {
    let c0 = LAMBDA_MIN;
    let c1 = 1.0 / (LAMBDA_MAX - LAMBDA_MIN);
    [
        (a * (c1 * c1)) as f32,
        (b * c1 - 2.0 * a * c0 * (c1 * c1)) as f32,
        (c - b * c0 * c1 + a * (c0 * c1) * (c0 * c1)) as f32,
    ]
}

/// The forward model: the colour of a coefficient vector, and the optimiser.
pub(crate) struct Forward {
    /// Normalised quadrature wavelengths `(l_n - 360) / 470`.
    t: [f64; FINE],
    /// `rgb_tbl[c][n]`: sRGB channel `c` of the CMFs times D65 times the quadrature
    /// weight at wavelength `n`, so that a spectrum's sRGB is `sum_n rgb_tbl[.][n] s_n`.
    rgb_tbl: [[f64; FINE]; 3],
    /// XYZ of D65 (Y = 1): the CIELab white.
    white: [f64; 3],
}

impl Forward {
    /// rgb2spec's `init_tables` for sRGB.
    pub(crate) fn new() -> Self {
        let h = (LAMBDA_MAX - LAMBDA_MIN) / (FINE - 1) as f64;
        let lambda = |n: usize| LAMBDA_MIN + n as f64 * h;
        let weight = |n: usize| {
            let w = 3.0 / 8.0 * h;
            if n == 0 || n == FINE - 1 {
                w
            } else if (n - 1) % 3 == 2 {
                w * 2.0
            } else {
                w * 3.0
            }
        };
        let cmf = |n: usize| interp(|m| CIE1931_XYZ[m].map(f64::from), lambda(n));
        let d65_raw = |n: usize| interp(|m| [f64::from(D65_ROWS[m][0])], lambda(n))[0];

        // rgb2spec's D65 has unit luminance.
        let luminance: f64 = (0..FINE).map(|n| cmf(n)[1] * d65_raw(n) * weight(n)).sum();

        let mut t = [0.0; FINE];
        let mut rgb_tbl = [[0.0; FINE]; 3];
        let mut white = [0.0; 3];
        for n in 0..FINE {
            let xyz = cmf(n);
            let d65 = d65_raw(n) / luminance;
            let w = weight(n);
            t[n] = (lambda(n) - LAMBDA_MIN) * (1.0 / (LAMBDA_MAX - LAMBDA_MIN));
            for c in 0..3 {
                rgb_tbl[c][n] = (0..3).map(|m| XYZ_TO_SRGB[c][m] * xyz[m] * d65 * w).sum();
                white[c] += xyz[c] * d65 * w;
            }
        }
        Self { t, rgb_tbl, white }
    }

    /// The sRGB of the sigmoid spectrum with normalised-wavelength coefficients `c`.
    pub(crate) fn colour(&self, [c0, c1, c2]: [f64; 3]) -> [f64; 3] {
        let mut out = [0.0; 3];
        for n in 0..FINE {
            let t = self.t[n];
            let x = (c0 * t + c1) * t + c2;
            let s = 0.5 * x / (1.0 + x * x).sqrt() + 0.5;
            for (o, tbl) in out.iter_mut().zip(&self.rgb_tbl) {
                *o += tbl[n] * s;
            }
        }
        out
    }

    /// The colour of `c` and its derivatives `d[channel][coefficient]`.
    pub(crate) fn colour_jac(&self, [c0, c1, c2]: [f64; 3]) -> ([f64; 3], [[f64; 3]; 3]) {
        let mut out = [0.0; 3];
        let mut d = [[0.0; 3]; 3];
        for n in 0..FINE {
            let t = self.t[n];
            let x = (c0 * t + c1) * t + c2;
            let q = 1.0 / (1.0 + x * x).sqrt();
            let s = 0.5 * x * q + 0.5;
            let ds = 0.5 * q * q * q;
            for c in 0..3 {
                let w = self.rgb_tbl[c][n];
                out[c] += w * s;
                let wds = w * ds;
                d[c][0] += wds * t * t;
                d[c][1] += wds * t;
                d[c][2] += wds;
            }
        }
        (out, d)
    }

    /// CIELab of linear sRGB `rgb` (rgb2spec's `cie_lab`) and its Jacobian
    /// `d lab[a] / d rgb[b]`.
    pub(crate) fn lab_jac(&self, rgb: [f64; 3]) -> ([f64; 3], [[f64; 3]; 3]) {
        let xyz: [f64; 3] =
            std::array::from_fn(|a| (0..3).map(|b| SRGB_TO_XYZ[a][b] * rgb[b]).sum());
        let delta: f64 = 6.0 / 29.0;
        let mut f = [0.0; 3];
        let mut g = [0.0; 3]; // f'(xyz / white) / white
        for k in 0..3 {
            let t = xyz[k] / self.white[k];
            if t > delta * delta * delta {
                let cr = t.cbrt();
                f[k] = cr;
                g[k] = (1.0 / 3.0) / (cr * cr * self.white[k]);
            } else {
                f[k] = t / (delta * delta * 3.0) + 4.0 / 29.0;
                g[k] = 1.0 / (delta * delta * 3.0 * self.white[k]);
            }
        }
        let lab = [
            116.0 * f[1] - 16.0,
            500.0 * (f[0] - f[1]),
            200.0 * (f[1] - f[2]),
        ];
        let dlab_dxyz = [
            [0.0, 116.0 * g[1], 0.0],
            [500.0 * g[0], -500.0 * g[1], 0.0],
            [0.0, 200.0 * g[1], -200.0 * g[2]],
        ];
        (lab, mat_mul(&dlab_dxyz, &SRGB_TO_XYZ))
    }

    pub(crate) fn lab(&self, rgb: [f64; 3]) -> [f64; 3] {
        self.lab_jac(rgb).0
    }

    /// `Lab(target) - Lab(colour(c))`.
    pub(crate) fn residual(&self, c: [f64; 3], target_lab: [f64; 3]) -> [f64; 3] {
        let lab = self.lab(self.colour(c));
        std::array::from_fn(|a| target_lab[a] - lab[a])
    }

    /// The residual and its Jacobian `d residual[a] / d c[b]`.
    pub(crate) fn residual_jac(
        &self,
        c: [f64; 3],
        target_lab: [f64; 3],
    ) -> ([f64; 3], [[f64; 3]; 3]) {
        let (rgb, d_rgb) = self.colour_jac(c);
        let (lab, d_lab) = self.lab_jac(rgb);
        let jac = mat_mul(&d_lab, &d_rgb).map(|row| row.map(|v| -v));
        (std::array::from_fn(|a| target_lab[a] - lab[a]), jac)
    }

    /// Levenberg-Marquardt on the CIELab residual from `coeffs` (updated in place), as
    /// rgb2spec's `LM()`; returns the final residual norm.
    pub(crate) fn optimize(&self, rgb: [f64; 3], coeffs: &mut [f64; 3]) -> f64 {
        let target = self.lab(rgb);
        let (mut r, mut jac) = self.residual_jac(*coeffs, target);
        let mut cost = norm2(r);
        let mut lambda = 1e-3;
        for _ in 0..LM_ITERATIONS {
            if cost <= 1e-12 {
                break;
            }
            // Normal equations: a = J^T J, g = J^T r.
            let a: [[f64; 3]; 3] = std::array::from_fn(|p| {
                std::array::from_fn(|q| (0..3).map(|k| jac[k][p] * jac[k][q]).sum())
            });
            let g: [f64; 3] = std::array::from_fn(|p| (0..3).map(|k| jac[k][p] * r[k]).sum());

            // Damped steps, damping harder until one lowers the cost.
            let mut accepted = false;
            for _ in 0..10 {
                let mut m = a;
                for (p, row) in m.iter_mut().enumerate() {
                    row[p] += lambda;
                }
                let Some(step) = lup_solve(m, g) else {
                    lambda *= 10.0;
                    continue;
                };
                let trial: [f64; 3] = std::array::from_fn(|p| coeffs[p] - step[p]);
                let trial_cost = norm2(self.residual(trial, target));
                if trial_cost < cost {
                    *coeffs = trial;
                    cost = trial_cost;
                    lambda = (lambda * 0.5).max(1e-12);
                    accepted = true;
                    break;
                }
                lambda *= 10.0;
                if lambda > 1e12 {
                    break;
                }
            }
            if !accepted {
                break;
            }
            (r, jac) = self.residual_jac(*coeffs, target);
        }
        cost.sqrt()
    }
}

/// Linear interpolation in a 5 nm table over [360, 830] (rgb2spec's `cie_interp`:
/// the end intervals extend beyond the range).
pub(crate) fn interp<const N: usize>(row: impl Fn(usize) -> [f64; N], lambda: f64) -> [f64; N] {
    let x = (lambda - LAMBDA_MIN) * ((CIE_SAMPLES - 1) as f64 / (LAMBDA_MAX - LAMBDA_MIN));
    let offset = (x as usize).min(CIE_SAMPLES - 2);
    let w = x - offset as f64;
    let (lo, hi) = (row(offset), row(offset + 1));
    std::array::from_fn(|c| (1.0 - w) * lo[c] + w * hi[c])
}

pub(crate) fn mat_mul(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    std::array::from_fn(|p| std::array::from_fn(|q| (0..3).map(|k| a[p][k] * b[k][q]).sum()))
}

pub(crate) fn norm2(v: [f64; 3]) -> f64 {
    v.iter().map(|x| x * x).sum()
}

/// Solves `m x = b` by LU decomposition with partial pivoting (rgb2spec's `lu.h`);
/// `None` if a pivot is below 1e-30.
pub(crate) fn lup_solve(mut m: [[f64; 3]; 3], b: [f64; 3]) -> Option<[f64; 3]> {
    let mut perm = [0, 1, 2];
    for c in 0..3 {
        let pivot = (c..3).fold(c, |p, r| if m[r][c].abs() > m[p][c].abs() { r } else { p });
        if m[pivot][c].abs() < 1e-30 {
            return None;
        }
        m.swap(c, pivot);
        perm.swap(c, pivot);
        for r in c + 1..3 {
            m[r][c] /= m[c][c];
            for k in c + 1..3 {
                m[r][k] -= m[r][c] * m[c][k];
            }
        }
    }
    let mut x = [0.0; 3];
    for r in 0..3 {
        x[r] = b[perm[r]] - (0..r).map(|k| m[r][k] * x[k]).sum::<f64>();
    }
    for r in (0..3).rev() {
        x[r] = (x[r] - (r + 1..3).map(|k| m[r][k] * x[k]).sum::<f64>()) / m[r][r];
    }
    Some(x)
}

/// The brightness axis: `scale[k] = smoothstep(smoothstep(k / (RES - 1)))`, in f32 as
/// rgb2spec computes it (so that it equals the axis of Mitsuba's file bit for bit).
pub(crate) fn scale_axis() -> [f32; RES] {
    std::array::from_fn(|k| {
        let smoothstep = |x: f32| x * x * (3.0 - 2.0 * x);
        smoothstep(smoothstep(k as f32 / (RES - 1) as f32))
    })
}

/// Solves the nodes of column `(l, j, i)` by continuation along `k`: from `K_START` up,
/// then from `K_START` down (each run starting at zero; the second solve at `K_START`
/// is kept). A pure function of its arguments.
pub(crate) fn solve_column(
    forward: &Forward,
    scale: &[f32; RES],
    l: usize,
    j: usize,
    i: usize,
) -> Column {
    let x = i as f64 / (RES - 1) as f64;
    let y = j as f64 / (RES - 1) as f64;
    let mut column = [[0.0; 3]; RES];
    let mut solve = |k: usize, coeffs: &mut [f64; 3]| {
        forward.optimize(node_target(l, x, y, scale[k]), coeffs);
        column[k] = to_nanometres(*coeffs);
    };
    let mut coeffs = [0.0; 3];
    for k in K_START..RES {
        solve(k, &mut coeffs);
    }
    let mut coeffs = [0.0; 3];
    for k in (0..=K_START).rev() {
        solve(k, &mut coeffs);
    }
    column
}
