//! The shared machinery of the sampling family: the theta x phi grid on the sphere, the
//! pdf integrated over it and the chi-square of samples against it; Fresnel and Snell
//! in f64 and the binomial test of delta lobes; the weight, furnace and reciprocity
//! measures; quadratures of the reflected and scattered energy; the basic models.

use glam::Vec3;
use statrs::distribution::{Binomial, ChiSquared, ContinuousCDF, DiscreteCDF};
use std::f64::consts::PI;
use tstat::materials::{
    Bsdf, BsdfFlags, BsdfModel, Conductor, Dielectric, Diffuse, OneSided, TwoSided,
};
use tstat::math::rng::Pcg32;
use tstat::math::sampling::cosine_hemisphere;
use tstat::math::Rgb;

// ---------------------------------------------------------------- the chi-square grid

const THETA_CELLS: usize = 16;
const PHI_CELLS: usize = 32;
const CHI2_SAMPLES: usize = 1_000_000;
/// Cells expecting fewer samples are pooled (the chi-square approximation needs ~5).
pub(crate) const MIN_EXPECTED: f64 = 5.0;

// ---------------------------------------------------------------- basic models

fn rgb(v: f32) -> Rgb {
    Rgb::splat(v)
}

pub(crate) fn diffuse(r: f32) -> Diffuse {
    Diffuse {
        reflectance: rgb(r),
    }
}

pub(crate) fn glass(eta: f32) -> Dielectric {
    Dielectric {
        eta,
        specular_reflectance: Rgb::ONE,
        specular_transmittance: Rgb::ONE,
    }
}

pub(crate) fn gold() -> Conductor {
    Conductor {
        eta: Rgb::new(0.143119, 0.374957, 1.44248),
        k: Rgb::new(3.98316, 2.38572, 1.60322),
        specular_reflectance: Rgb::ONE,
    }
}

pub(crate) fn mirror() -> Conductor {
    Conductor {
        eta: Rgb::ZERO,
        k: Rgb::ONE,
        specular_reflectance: Rgb::ONE,
    }
}

pub(crate) fn two_sided(front: OneSided, back: OneSided) -> Bsdf {
    Bsdf::TwoSided(TwoSided { front, back })
}

/// Unit direction at polar angle `theta_deg` from +z, azimuth `phi_deg`.
pub(crate) fn dir(theta_deg: f64, phi_deg: f64) -> Vec3 {
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    Vec3::new(
        (t.sin() * p.cos()) as f32,
        (t.sin() * p.sin()) as f32,
        t.cos() as f32,
    )
}

pub(crate) type Case = (String, Box<dyn BsdfModel>, Vec3);

// ---------------------------------------------------------------- pdf integrals, chi-square

fn cell_of(w: Vec3) -> usize {
    let w = w.as_dvec3().normalize();
    let theta = w.z.clamp(-1.0, 1.0).acos();
    let phi = w.y.atan2(w.x).rem_euclid(2.0 * PI);
    let t = ((theta / PI * THETA_CELLS as f64) as usize).min(THETA_CELLS - 1);
    let p = ((phi / (2.0 * PI) * PHI_CELLS as f64) as usize).min(PHI_CELLS - 1);
    t * PHI_CELLS + p
}

/// Adaptive Simpson on [a, b] to absolute tolerance `eps`.
fn simpson(f: &mut dyn FnMut(f64) -> f64, a: f64, b: f64, eps: f64) -> f64 {
    fn rec(
        f: &mut dyn FnMut(f64) -> f64,
        (a, fa): (f64, f64),
        (m, fm): (f64, f64),
        (b, fb): (f64, f64),
        whole: f64,
        eps: f64,
        depth: u32,
    ) -> f64 {
        let (lm, rm) = (0.5 * (a + m), 0.5 * (m + b));
        let (flm, frm) = (f(lm), f(rm));
        let left = (m - a) / 6.0 * (fa + 4.0 * flm + fm);
        let right = (b - m) / 6.0 * (fm + 4.0 * frm + fb);
        let delta = left + right - whole;
        if depth == 0 || delta.abs() <= 15.0 * eps {
            return left + right + delta / 15.0;
        }
        rec(f, (a, fa), (lm, flm), (m, fm), left, eps / 2.0, depth - 1)
            + rec(f, (m, fm), (rm, frm), (b, fb), right, eps / 2.0, depth - 1)
    }
    let m = 0.5 * (a + b);
    let (fa, fm, fb) = (f(a), f(m), f(b));
    let whole = (b - a) / 6.0 * (fa + 4.0 * fm + fb);
    rec(f, (a, fa), (m, fm), (b, fb), whole, eps, 12)
}

/// The pdf integrated over every grid cell (solid angle: sin(theta) dtheta dphi).
pub(crate) fn cell_integrals(b: &dyn BsdfModel, wo: Vec3) -> Vec<f64> {
    pdf_cell_integrals(&|w| b.pdf(wo, w) as f64)
}

/// A solid-angle density integrated over every grid cell.
pub(crate) fn pdf_cell_integrals(pdf: &dyn Fn(Vec3) -> f64) -> Vec<f64> {
    let (dt, dp) = (PI / THETA_CELLS as f64, 2.0 * PI / PHI_CELLS as f64);
    let mut out = Vec::with_capacity(THETA_CELLS * PHI_CELLS);
    for t in 0..THETA_CELLS {
        for p in 0..PHI_CELLS {
            let (t0, p0) = (t as f64 * dt, p as f64 * dp);
            let mut outer = |theta: f64| {
                let mut inner = |phi: f64| {
                    let w = Vec3::new(
                        (theta.sin() * phi.cos()) as f32,
                        (theta.sin() * phi.sin()) as f32,
                        theta.cos() as f32,
                    );
                    pdf(w) * theta.sin()
                };
                simpson(&mut inner, p0, p0 + dp, 1e-8)
            };
            out.push(simpson(&mut outer, t0, t0 + dt, 1e-8));
        }
    }
    out
}

/// Chi-square p-value of `CHI2_SAMPLES` non-delta samples against the integrated pdf.
/// A sample in a cell whose expected count is zero gives p = 0 (pbrt's rule).
pub(crate) fn chi2_p_value(b: &dyn BsdfModel, wo: Vec3, seed: u64) -> f64 {
    let expected = cell_integrals(b, wo);
    chi2_of_samples(expected, seed, &mut |rng| {
        let (u1, u2) = (rng.next_f32(), rng.next_2d());
        b.sample(wo, u1, u2)
            .filter(|s| !s.lobe.is_delta())
            .map(|s| s.wi)
    })
}

/// Chi-square p-value of `CHI2_SAMPLES` directions drawn by `sample` (`None`: no
/// direction) against the integrated pdf per grid cell, `integrals`.
pub(crate) fn chi2_of_samples(
    integrals: Vec<f64>,
    seed: u64,
    sample: &mut dyn FnMut(&mut Pcg32) -> Option<Vec3>,
) -> f64 {
    let expected: Vec<f64> = integrals
        .into_iter()
        .map(|v| v * CHI2_SAMPLES as f64)
        .collect();
    let mut observed = vec![0u64; expected.len()];
    let mut rng = Pcg32::new(seed, 0xb5df);
    for _ in 0..CHI2_SAMPLES {
        if let Some(w) = sample(&mut rng) {
            observed[cell_of(w)] += 1;
        }
    }
    let mut order: Vec<usize> = (0..expected.len()).collect();
    order.sort_by(|&i, &j| expected[i].total_cmp(&expected[j]));
    let (mut stat, mut cells) = (0.0, 0usize);
    let (mut pool_e, mut pool_o) = (0.0, 0.0);
    for i in order {
        let (e, o) = (expected[i], observed[i] as f64);
        if e == 0.0 && o > 0.0 {
            return 0.0;
        }
        if e < MIN_EXPECTED {
            pool_e += e;
            pool_o += o;
            continue;
        }
        stat += (o - e) * (o - e) / e;
        cells += 1;
    }
    // The pooled cells; a remainder still below MIN_EXPECTED joins nothing (dropped
    // along with its observations, as pbrt does).
    if pool_e >= MIN_EXPECTED {
        stat += (pool_o - pool_e) * (pool_o - pool_e) / pool_e;
        cells += 1;
    }
    assert!(cells >= 2, "too few cells for a chi-square test");
    ChiSquared::new((cells - 1) as f64).unwrap().sf(stat)
}

// ---------------------------------------------------------------- delta lobes

/// Fresnel reflectance and refracted direction in f64, from Snell's law directly.
pub(crate) fn reference_fresnel(wo: Vec3, eta: f64) -> (f64, Option<[f64; 3]>) {
    let wo = wo.as_dvec3();
    let (n1, n2) = if wo.z > 0.0 { (1.0, eta) } else { (eta, 1.0) };
    let ci = wo.z.abs();
    let si = (1.0 - ci * ci).max(0.0).sqrt();
    let st = n1 / n2 * si;
    if st >= 1.0 {
        return (1.0, None);
    }
    let ct = (1.0 - st * st).sqrt();
    let rs = ((n1 * ci - n2 * ct) / (n1 * ci + n2 * ct)).powi(2);
    let rp = ((n1 * ct - n2 * ci) / (n1 * ct + n2 * ci)).powi(2);
    let scale = n1 / n2;
    let t = [-scale * wo.x, -scale * wo.y, -wo.z.signum() * ct];
    (0.5 * (rs + rp), Some(t))
}

pub(crate) fn close(a: Vec3, b: [f64; 3], tol: f64) -> bool {
    (0..3).all(|i| (a[i] as f64 - b[i]).abs() <= tol)
}

/// Two-sided binomial p-value of `k` successes in `n` trials with probability `p`.
pub(crate) fn binomial_p_value(k: u64, n: u64, p: f64) -> f64 {
    if p <= 0.0 || p >= 1.0 {
        let certain = if p <= 0.0 { 0 } else { n };
        return if k == certain { 1.0 } else { 0.0 };
    }
    let d = Binomial::new(p, n).unwrap();
    let lower = d.cdf(k);
    let upper = if k == 0 { 1.0 } else { d.sf(k - 1) };
    (2.0 * lower.min(upper)).min(1.0)
}

/// Checks the delta lobes of `b` from `wo` against Fresnel (`eta`: `None` for a
/// conductor, which always reflects); returns the binomial p-value of the choice.
pub(crate) fn delta_p_value(b: &dyn BsdfModel, wo: Vec3, eta: Option<f64>, seed: u64) -> f64 {
    const N: u64 = 20_000;
    let reflected = [-wo.x as f64, -wo.y as f64, wo.z as f64];
    let (r, refracted) = match eta {
        Some(e) => reference_fresnel(wo, e),
        None => (1.0, None),
    };
    let mut rng = Pcg32::new(seed, 0xde17a);
    let mut n_reflect = 0;
    for _ in 0..N {
        let s = b
            .sample(wo, rng.next_f32(), rng.next_2d())
            .expect("a delta BSDF always scatters");
        assert!(s.lobe.is_delta(), "a delta model sampled {:?}", s.lobe);
        if s.lobe == BsdfFlags::DELTA_REFLECTION {
            assert!(
                close(s.wi, reflected, 1e-6),
                "reflection {} from {wo}",
                s.wi
            );
            n_reflect += 1;
        } else {
            assert_eq!(s.lobe, BsdfFlags::DELTA_TRANSMISSION);
            let t = refracted.expect("refraction past the critical angle");
            assert!(close(s.wi, t, 1e-5), "refraction {} from {wo}", s.wi);
            let e = eta.expect("only dielectrics refract");
            let eta_it = if wo.z > 0.0 { e } else { 1.0 / e };
            assert!(
                (s.eta as f64 - eta_it).abs() < 1e-6,
                "eta {} from {wo}",
                s.eta
            );
        }
    }
    binomial_p_value(n_reflect, N, r)
}

// ---------------------------------------------------------------- weights, pdf, furnace

/// Largest relative mismatch of weight vs eval / pdf and of sample pdf vs pdf over
/// `n` samples of `b` from `wo` (non-delta samples only).
pub(crate) fn weight_mismatch(b: &dyn BsdfModel, wo: Vec3, n: usize, seed: u64) -> f32 {
    let mut rng = Pcg32::new(seed, 0x3e16);
    let mut worst = 0.0f32;
    for _ in 0..n {
        let Some(s) = b.sample(wo, rng.next_f32(), rng.next_2d()) else {
            continue;
        };
        if s.lobe.is_delta() {
            continue;
        }
        let pdf = b.pdf(wo, s.wi);
        let want = b.eval(wo, s.wi) / pdf;
        let rel = |a: f32, b: f32| (a - b).abs() / b.abs().max(1e-6);
        worst = worst.max(rel(s.pdf, pdf));
        for c in 0..3 {
            worst = worst.max(rel(s.weight[c], want[c]));
        }
    }
    worst
}

/// Tolerance on the integral of the pdf: each of the 512 cells is integrated to an
/// absolute 1e-8 (Simpson's error estimate), so quadrature contributes < 1e-5; the f32
/// pdf and direction carry relative errors ~1e-7. 1e-4 leaves room for the kink of a
/// one-sided lobe at the horizon, which lies on a cell edge, and still rejects any pdf
/// wrong by more than 0.01 %.
pub(crate) const PDF_INTEGRAL_TOL: f64 = 1e-4;

/// Mean energy weight (transmission times eta^2, undoing the radiance compression)
/// and its standard error, per channel.
pub(crate) fn furnace(b: &dyn BsdfModel, wo: Vec3, n: usize, seed: u64) -> (Rgb, Rgb) {
    let mut rng = Pcg32::new(seed, 0xf0);
    let (mut sum, mut sum2) = (glam::DVec3::ZERO, glam::DVec3::ZERO);
    for _ in 0..n {
        if let Some(s) = b.sample(wo, rng.next_f32(), rng.next_2d()) {
            let e = if s.lobe.intersects(BsdfFlags::TRANSMISSION) {
                s.weight * (s.eta * s.eta)
            } else {
                s.weight
            };
            let e = e.as_dvec3();
            sum += e;
            sum2 += e * e;
        }
    }
    let mean = sum / n as f64;
    let var = (sum2 / n as f64 - mean * mean).max(glam::DVec3::ZERO);
    (mean.as_vec3(), (var / n as f64).sqrt().as_vec3())
}

/// Five standard errors (two-sided normal p ~ 6e-7, far below `LEVEL`), plus f32
/// rounding.
pub(crate) fn within(a: Rgb, b: Rgb, se: Rgb) -> bool {
    (0..3).all(|c| (a[c] - b[c]).abs() <= 5.0 * se[c] + 1e-5)
}

// ---------------------------------------------------------------- reciprocity, energy

/// Largest relative asymmetry of f = eval / |cos wi| over same-side direction pairs.
pub(crate) fn asymmetry(b: &dyn BsdfModel, seed: u64) -> f32 {
    let mut rng = Pcg32::new(seed, 0x5e);
    let mut worst = 0.0f32;
    for _ in 0..2000 {
        let wo = tstat::math::sampling::uniform_sphere(rng.next_2d());
        let mut wi = cosine_hemisphere(rng.next_2d());
        wi.z *= wo.z.signum();
        let f = b.eval(wo, wi) / wi.z.abs();
        let g = b.eval(wi, wo) / wo.z.abs();
        for c in 0..3 {
            let scale = f[c].abs().max(g[c].abs());
            if scale > 0.0 {
                worst = worst.max((f[c] - g[c]).abs() / scale);
            }
        }
    }
    worst
}

/// Largest relative violation of the reciprocity of refraction in radiance transport,
/// f(wo, wi) / n(wo)^2 = f(wi, wo) / n(wi)^2 (Veach 1997, 5.2; n the IOR on a
/// direction's side: 1 above, `eta` below), over direction pairs on opposite sides,
/// and the number of values compared. Pairs whose microfacet (Walter's generalized
/// half vector, here in f64) meets a direction within 6 deg of grazing are skipped:
/// there one side's Fresnel transmittance is that of the other near the critical
/// angle, 1 - eta^2 sin^2 in f32 cancels, and both evaluations lose about a per cent.
pub(crate) fn refraction_asymmetry(b: &dyn BsdfModel, eta: f32, seed: u64) -> (f32, usize) {
    let n = |w: Vec3| if w.z > 0.0 { 1.0 } else { eta as f64 };
    let mut rng = Pcg32::new(seed, 0x7e);
    let (mut worst, mut compared) = (0.0f32, 0);
    for _ in 0..4000 {
        let wo = tstat::math::sampling::uniform_sphere(rng.next_2d());
        let mut wi = cosine_hemisphere(rng.next_2d());
        wi.z *= -wo.z.signum();
        let h = (wo.as_dvec3() * n(wo) + wi.as_dvec3() * n(wi)).normalize();
        if h.dot(wo.as_dvec3()).abs().min(h.dot(wi.as_dvec3()).abs()) < 0.1 {
            continue;
        }
        let f = b.eval(wo, wi) / (wi.z.abs() * (n(wo) * n(wo)) as f32);
        let g = b.eval(wi, wo) / (wo.z.abs() * (n(wi) * n(wi)) as f32);
        for c in 0..3 {
            let scale = f[c].abs().max(g[c].abs());
            // Far in a lobe's tail D is a few ulps above f32's smallest normal.
            if scale > 1e-20 {
                worst = worst.max((f[c] - g[c]).abs() / scale);
                compared += 1;
            }
        }
    }
    (worst, compared)
}

/// The reflected energy from `wo` by quadrature of `eval` over the upper hemisphere
/// (midpoint rule in f64 on a 600 x 1200 (theta, phi) grid: cells of 0.15 deg resolve
/// lobes of roughness >= 0.1), independent of the sampler.
pub(crate) fn reflected_energy(b: &dyn BsdfModel, wo: Vec3) -> glam::DVec3 {
    let (nt, np) = (600usize, 1200usize);
    let (dt, dp) = (0.5 * PI / nt as f64, 2.0 * PI / np as f64);
    let mut sum = glam::DVec3::ZERO;
    for i in 0..nt {
        let t = (i as f64 + 0.5) * dt;
        let w = t.sin() * dt * dp;
        for j in 0..np {
            let p = (j as f64 + 0.5) * dp;
            let wi = Vec3::new(
                (t.sin() * p.cos()) as f32,
                (t.sin() * p.sin()) as f32,
                t.cos() as f32,
            );
            sum += b.eval(wo, wi).as_dvec3() * w;
        }
    }
    sum
}

/// The energy leaving a rough glass from `wo` by quadrature of `eval` over the whole
/// sphere (midpoint rule in f64 on a 1200 x 1200 (theta, phi) grid, cells of 0.15 deg;
/// a transmission lobe is narrower than the reflection one by about (eta - 1) / eta, a
/// few degrees at roughness 0.1), transmitted values times `eta_it^2` (energy, not
/// radiance), independent of the sampler.
pub(crate) fn scattered_energy(b: &dyn BsdfModel, eta: f32, wo: Vec3) -> glam::DVec3 {
    let eta_it = if wo.z > 0.0 { eta } else { 1.0 / eta } as f64;
    let (nt, np) = (1200usize, 1200usize);
    let (dt, dp) = (PI / nt as f64, 2.0 * PI / np as f64);
    let mut sum = glam::DVec3::ZERO;
    for i in 0..nt {
        let t = (i as f64 + 0.5) * dt;
        let mut w = t.sin() * dt * dp;
        if (t.cos() > 0.0) != (wo.z > 0.0) {
            w *= eta_it * eta_it;
        }
        for j in 0..np {
            let p = (j as f64 + 0.5) * dp;
            let wi = Vec3::new(
                (t.sin() * p.cos()) as f32,
                (t.sin() * p.sin()) as f32,
                t.cos() as f32,
            );
            sum += b.eval(wo, wi).as_dvec3() * w;
        }
    }
    sum
}
