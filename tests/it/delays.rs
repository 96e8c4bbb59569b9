//! Materials with scattering delays (SPEC section 6): the sampled delay densities, and
//! renders that must shift, convolve, split and keep energy exactly as the model says.
//!
//! Statistical checks form one family held to `ALPHA` (Bonferroni over `FAMILY`).

use statrs::distribution::{ChiSquared, ContinuousCDF};
use tstat::materials::TemporalProfile;
use tstat::math::rng::Pcg32;
use tstat::render::RenderOutput;
use tstat::scene::{Overrides, Scene};

use crate::common;
use common::{load, run};

const ALPHA: f64 = 0.01;
/// Delay histograms (5 profiles) + convolution bins (checked by z-scores below, 4
/// profiles x 80 bins) + the Composed split (1).
const FAMILY: usize = 5 + 4 * 80 + 1;
const LEVEL: f64 = ALPHA / FAMILY as f64;
/// |z| beyond which a normal test rejects at `LEVEL` (two-sided): 4.26 for LEVEL 3e-5.
fn z_limit() -> f64 {
    use statrs::distribution::Normal;
    Normal::new(0.0, 1.0)
        .unwrap()
        .inverse_cdf(1.0 - LEVEL / 2.0)
}

fn profiles() -> Vec<(&'static str, TemporalProfile)> {
    vec![
        (
            "exponential 2",
            TemporalProfile::Exponential { lambda: 2.0 },
        ),
        (
            "exponential 0.5",
            TemporalProfile::Exponential { lambda: 0.5 },
        ),
        (
            "epanechnikov (0.5, 0.1)",
            TemporalProfile::Epanechnikov {
                mu: 0.5,
                sigma: 0.1,
            },
        ),
        (
            "epanechnikov (0.5, 0.5)",
            TemporalProfile::Epanechnikov {
                mu: 0.5,
                sigma: 0.5,
            },
        ),
        (
            "epanechnikov (0.1, 0.1)",
            TemporalProfile::Epanechnikov {
                mu: 0.1,
                sigma: 0.1,
            },
        ),
    ]
}

/// Chi-square p-value of `n` delays drawn by `sample` against the density of `p`, on
/// 50 cells of equal probability (quantiles found by bisection on the CDF, in f64).
fn chi2_delays(p: &TemporalProfile, sample: impl Fn(f32) -> f32, n: usize, seed: u64) -> f64 {
    let cells = 50;
    let quantile = |q: f64| {
        let (mut lo, mut hi) = (0.0f64, 1e3f64);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if p.cdf(mid) < q {
                lo = mid
            } else {
                hi = mid
            }
        }
        0.5 * (lo + hi)
    };
    let edges: Vec<f64> = (1..cells)
        .map(|i| quantile(i as f64 / cells as f64))
        .collect();
    let mut observed = vec![0u64; cells];
    let mut rng = Pcg32::new(seed, 7);
    for _ in 0..n {
        let dt = sample(rng.next_f32()) as f64;
        observed[edges.partition_point(|&e| e < dt)] += 1;
    }
    let e = n as f64 / cells as f64;
    let stat: f64 = observed.iter().map(|&o| (o as f64 - e).powi(2) / e).sum();
    ChiSquared::new((cells - 1) as f64).unwrap().sf(stat)
}

#[test]
fn sampled_delays_follow_their_densities() {
    let mut ps = Vec::new();
    for (i, (name, p)) in profiles().into_iter().enumerate() {
        let pv = chi2_delays(&p, |u| p.sample(u), 100_000, i as u64);
        assert!(pv > LEVEL, "{name}: chi-square p = {pv:.2e}");
        ps.push(pv);
        // The mean, to 4 standard errors of 1e5 draws.
        let mut rng = Pcg32::new(50 + i as u64, 1);
        let n = 100_000;
        let mean = (0..n).map(|_| p.sample(rng.next_f32()) as f64).sum::<f64>() / n as f64;
        let sd = match p {
            TemporalProfile::Exponential { lambda } => 1.0 / lambda as f64,
            TemporalProfile::Epanechnikov { sigma, .. } => sigma as f64 / 5f64.sqrt(),
            TemporalProfile::Constant { .. } => 0.0,
        };
        let se = sd / (n as f64).sqrt();
        assert!((mean - p.mean()).abs() < 4.0 * se, "{name}: mean {mean}");
    }
    eprintln!("delay chi-square p-values: {ps:.3?}");
    // The harness rejects a wrong inverse CDF: Epanechnikov without the factor 2
    // (support halved), and an exponential with the rate inverted.
    let e = TemporalProfile::Epanechnikov {
        mu: 0.5,
        sigma: 0.5,
    };
    let half = |u: f32| 0.5 + 0.5 * (((2.0 * u - 1.0).asin()) / 3.0).sin();
    assert!(chi2_delays(&e, half, 100_000, 9) < LEVEL);
    let x = TemporalProfile::Exponential { lambda: 2.0 };
    assert!(chi2_delays(&x, |u| -(1.0 - u).ln() * 2.0, 100_000, 9) < LEVEL);
}

// ------------------------------------------------------------------ renders

/// A point light at the pinhole and a plane at distance 2 facing the camera (narrow
/// field: every path arrives at OPL 4.0000-4.0012, in bin 19 of [3.025, 3.075 + 0.05 t)).
/// `BSDF` is replaced by the material under test.
const CONFOCAL_PLANE: &str = r#"<scene version="3.0.0">
  <integrator type="transient_path"><integer name="max_depth" value="MAXDEPTH"/></integrator>
  <sensor type="perspective">
    <float name="fov" value="FOV"/>
    <transform name="to_world"><lookat origin="0,0,0" target="0,0,-1" up="0,1,0"/></transform>
    <sampler type="independent"><integer name="sample_count" value="SPP"/></sampler>
    <film type="transient_hdr_film">
      <integer name="width" value="5"/><integer name="height" value="5"/>
      <integer name="temporal_bins" value="BINS"/>
      <float name="start_opl" value="3.025"/><float name="bin_width_opl" value="0.05"/>
    </film>
  </sensor>
  <emitter type="point"><point name="position" x="0" y="0" z="0"/><rgb name="intensity" value="10, 20, 30"/></emitter>
  <shape type="rectangle">
    <transform name="to_world"><scale value="5"/><translate z="-2"/></transform>
    BSDF
  </shape>
</scene>"#;

struct Plane {
    fov: f32,
    spp: u32,
    bins: usize,
    max_depth: i32,
}

const NARROW: Plane = Plane {
    fov: 2.0,
    spp: 512,
    bins: 80,
    max_depth: 2,
};

fn plane(p: &Plane, bsdf: &str) -> Scene {
    load(
        &CONFOCAL_PLANE
            .replace("MAXDEPTH", &p.max_depth.to_string())
            .replace("FOV", &p.fov.to_string())
            .replace("SPP", &p.spp.to_string())
            .replace("BINS", &p.bins.to_string())
            .replace("BSDF", bsdf),
        // The closed forms time the camera segment from the pinhole.
        &common::PINHOLE,
    )
}

const DIFFUSE: &str =
    r#"<bsdf type="diffuse"><rgb name="reflectance" value="0.5, 0.6, 0.7"/></bsdf>"#;

/// `Separable(diffuse, profile)` with the profile's parameters as XML.
fn delayed(profile: &str, params: &str) -> String {
    format!(
        r#"<bsdf type="Separable">{DIFFUSE}<TemporalProfile type="{profile}" name="tp">{params}</TemporalProfile></bsdf>"#
    )
}

fn constant(delay: f64) -> String {
    delayed(
        "ConstantTP",
        &format!(r#"<float name="delay" value="{delay}"/>"#),
    )
}

/// Sum over pixels of channel `c` of the per-voxel sums X1, per bin.
fn curve(out: &RenderOutput, bins: usize, c: usize) -> Vec<f64> {
    let mut v = vec![0.0; bins];
    for (i, x) in out.accum.x1.iter().enumerate() {
        if i % 3 == c {
            v[(i / 3) % bins] += x;
        }
    }
    v
}

#[test]
fn a_constant_delay_of_k_bins_shifts_every_arrival_by_exactly_k_bins() {
    let k = 3;
    let base = run(&plane(&NARROW, &constant(0.0)), 5);
    let shifted = run(&plane(&NARROW, &constant(0.05 * k as f64)), 5);
    let bins = NARROW.bins;
    let mut moved = 0;
    for voxel in 0..base.accum.nonzero.len() {
        let t = voxel % bins;
        let src = if t >= k { Some(voxel - k) } else { None };
        let want_n = src.map_or(0, |s| base.accum.nonzero[s]);
        assert_eq!(shifted.accum.nonzero[voxel], want_n, "voxel {voxel}");
        for c in 0..3 {
            let want = src.map_or(0.0, |s| base.accum.x1[s * 3 + c]);
            assert_eq!(shifted.accum.x1[voxel * 3 + c], want, "voxel {voxel}");
            let want2 = src.map_or(0.0, |s| base.accum.x2[s * 3 + c]);
            assert_eq!(shifted.accum.x2[voxel * 3 + c], want2, "voxel {voxel}");
        }
        moved += want_n as usize;
    }
    // Everything landed (bin 19 -> 22), and the steady image is the same bits.
    assert_eq!(moved, 25 * NARROW.spp as usize);
    assert_eq!(base.steady, shifted.steady);
}

#[test]
fn a_pure_delay_leaves_the_steady_image_and_gbuffers_unchanged_in_a_cornell_box() {
    // Every diffuse surface of the Cornell box delays (multi-bounce paths collect
    // several delays); the steady image and G-buffers must be the same bits as with
    // zero delays, whatever the profile (each delay takes one random number).
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cbox.xml");
    let xml = std::fs::read_to_string(path).unwrap();
    let wrap = |profile: &str| {
        let mut out = String::new();
        let mut rest = xml.as_str();
        // Wrap each top-level diffuse BSDF definition: <bsdf type="diffuse" id=..>..</bsdf>.
        while let Some(i) = rest.find(r#"<bsdf type="diffuse" id="#) {
            let end = i + rest[i..].find("</bsdf>").unwrap() + "</bsdf>".len();
            let def = &rest[i..end];
            let id_start = def.find("id=\"").unwrap() + 4;
            let id = &def[id_start..id_start + def[id_start..].find('"').unwrap()];
            let inner = def.replacen(&format!(r#" id="{id}""#), "", 1);
            out.push_str(&rest[..i]);
            out.push_str(&format!(
                r#"<bsdf type="Separable" id="{id}">{inner}{profile}</bsdf>"#
            ));
            rest = &rest[end..];
        }
        out.push_str(rest);
        out
    };
    let zero = wrap(
        r#"<TemporalProfile type="ConstantTP" name="tp"><float name="delay" value="0"/></TemporalProfile>"#,
    );
    let exp = wrap(
        r#"<TemporalProfile type="ExponentialTP" name="tp"><float name="lambda" value="2"/></TemporalProfile>"#,
    );
    assert!(
        exp.matches("Separable").count() >= 3,
        "the scene was not wrapped"
    );
    let o = Overrides {
        width: Some(24),
        spp: Some(16),
        bins: Some(300),
        ..Default::default()
    };
    let a = run(&load(&zero, &o), 8);
    let b = run(&load(&exp, &o), 8);
    assert_eq!(a.steady, b.steady);
    assert_eq!(a.gbuffer, b.gbuffer);
    // ... while the transients differ: the delays moved energy later.
    let mean_bin = |o: &RenderOutput| {
        let (mut s, mut w) = (0.0, 0.0);
        for (i, x) in o.accum.x1.iter().enumerate() {
            s += x * ((i / 3) % 300) as f64;
            w += x;
        }
        s / w
    };
    assert!(
        mean_bin(&b) > mean_bin(&a) + 2.0,
        "{} vs {}",
        mean_bin(&b),
        mean_bin(&a)
    );
}

/// The footprint-averaged probability that a path arriving at the plane's OPL lands in
/// bin t after a delay from `p`, per pixel (the undelayed transient of one pixel is one
/// arrival at 2 d / cos theta, so the delayed one is its convolution with p, binned).
fn binned_delay_density(p: &TemporalProfile, px: usize, py: usize, bins: usize) -> Vec<f64> {
    let (w, d) = (5usize, 2.0f64);
    let tan_half = (NARROW.fov as f64 / 2.0).to_radians().tan();
    let grid = 64;
    let mut out = vec![0.0; bins];
    let mut total_weight = 0.0;
    for i in 0..grid {
        for j in 0..grid {
            let x = px as f64 + (i as f64 + 0.5) / grid as f64;
            let y = py as f64 + (j as f64 + 0.5) / grid as f64;
            let sx = (1.0 - 2.0 * x / w as f64) * tan_half;
            let sy = (1.0 - 2.0 * y / w as f64) * tan_half;
            let r2 = 1.0 + sx * sx + sy * sy;
            // Radiance ~ cos^3 theta; the OPL is 2 d / cos theta.
            let weight = r2.powf(-1.5);
            let opl = 2.0 * d * r2.sqrt();
            for (t, o) in out.iter_mut().enumerate() {
                let lo = 3.025 + 0.05 * t as f64 - opl;
                *o += weight * (p.cdf(lo + 0.05) - p.cdf(lo));
            }
            total_weight += weight;
        }
    }
    out.iter().map(|v| v / total_weight).collect()
}

#[test]
fn delayed_transient_is_the_undelayed_one_convolved_with_the_binned_density() {
    let cases = [
        (
            TemporalProfile::Exponential { lambda: 2.0 },
            delayed("ExponentialTP", r#"<float name="lambda" value="2"/>"#),
        ),
        (
            TemporalProfile::Epanechnikov {
                mu: 0.5,
                sigma: 0.1,
            },
            delayed(
                "EpanechnikovTP",
                r#"<float name="mu" value="0.5"/><float name="sigma" value="0.1"/>"#,
            ),
        ),
        (
            TemporalProfile::Epanechnikov {
                mu: 0.5,
                sigma: 0.5,
            },
            delayed(
                "PosEpanTP",
                r#"<float name="mu" value="0.5"/><float name="sigma" value="0.5"/>"#,
            ),
        ),
        (
            TemporalProfile::Epanechnikov {
                mu: 0.1,
                sigma: 0.1,
            },
            delayed(
                "EpanechnikovTP",
                r#"<float name="mu" value="0.1"/><float name="sigma" value="0.1"/>"#,
            ),
        ),
    ];
    let bins = NARROW.bins;
    let spp = 4096;
    let zl = z_limit();
    let mut worst = 0.0f64;
    for (profile, xml) in cases {
        let p = Plane { spp, ..NARROW };
        let out = run(&plane(&p, &xml), 21);
        let n = spp as f64;
        // Per bin over all pixels and channel 1: the expected mean is the pixel's
        // steady value times the binned density; the variance is the sum of the
        // voxels' sample variances / n.
        let mut got = vec![0.0; bins];
        let mut want = vec![0.0; bins];
        let mut var = vec![0.0; bins];
        for py in 0..5 {
            for px in 0..5 {
                let pixel = py * 5 + px;
                let steady = out.steady[pixel * 3 + 1];
                let dens = binned_delay_density(&profile, px, py, bins);
                for t in 0..bins {
                    let v = (pixel * bins + t) * 3 + 1;
                    let mean = out.accum.x1[v] / n;
                    got[t] += mean;
                    want[t] += steady * dens[t];
                    var[t] += (out.accum.x2[v] / n - mean * mean).max(0.0) / (n - 1.0);
                }
            }
        }
        for t in 0..bins {
            // The steady value is itself an estimate; it multiplies a density <= 1 and
            // is far more precise than one bin (its relative error is ~1e-3 here), so
            // it adds 0.2 % of the expected value to the tolerance.
            let tol = zl * var[t].sqrt() + 2e-3 * want[t] + 1e-9;
            assert!(
                (got[t] - want[t]).abs() <= tol,
                "{profile:?} bin {t}: rendered {} vs convolution {} (tol {tol})",
                got[t],
                want[t]
            );
            if var[t] > 0.0 {
                worst = worst.max((got[t] - want[t]).abs() / var[t].sqrt());
            }
        }
        // The mean delay, from the rendered curve, as a summary.
        let total: f64 = got.iter().sum();
        let mean_t: f64 = got
            .iter()
            .enumerate()
            .map(|(t, v)| t as f64 * v)
            .sum::<f64>()
            / total;
        eprintln!(
            "{profile:?}: energy in window {:.4} of steady, mean bin {mean_t:.2}",
            total / (0..25).map(|p| out.steady[p * 3 + 1]).sum::<f64>()
        );
    }
    eprintln!("convolution test: largest |z| = {worst:.2} (limit {zl:.2})");
    // The check can fail: without the NEE delay, everything stays in bin 19.
    let undelayed = run(&plane(&NARROW, DIFFUSE), 21);
    let c = curve(&undelayed, bins, 1);
    assert!(c[19] > 0.0 && c.iter().enumerate().all(|(t, v)| t == 19 || *v == 0.0));
}

#[test]
fn composed_splits_energy_by_its_weight() {
    let w = 0.3;
    // Both children are the same diffuse; the second delays by 1.0 = 20 bins.
    let xml = format!(
        r#"<bsdf type="Composed"><float name="weight" value="{w}"/>{}{}</bsdf>"#,
        constant(0.0),
        constant(1.0)
    );
    let p = Plane {
        spp: 2048,
        ..NARROW
    };
    let out = run(&plane(&p, &xml), 4);
    let c = curve(&out, p.bins, 0);
    let (early, late) = (c[19], c[39]);
    assert!(c
        .iter()
        .enumerate()
        .all(|(t, v)| t == 19 || t == 39 || *v == 0.0));
    let share = early / (early + late);
    // Each path picks one child: its energy is nearly the same either way (cos^3
    // varies by 1e-3 over the field), so the share is a binomial proportion.
    let n = (25 * p.spp) as f64;
    let se = (w * (1.0 - w) / n).sqrt();
    assert!((share - w).abs() < z_limit() * se + 1e-3, "share {share}");
    // The total equals the undelayed plane's (same paths, same weights).
    let plain = run(&plane(&p, DIFFUSE), 4);
    let total: f64 = c.iter().sum();
    let plain_total: f64 = curve(&plain, p.bins, 0).iter().sum();
    assert!(
        (total / plain_total - 1.0).abs() < 1e-3,
        "{total} vs {plain_total}"
    );
}

#[test]
fn textured_regions_arrive_at_their_own_delays() {
    // A wide field over a checkerboard of delays 0 and 3 (= 60 bins): undelayed
    // arrivals span OPL 4.0-5.2 here (bins 19-43), delayed ones 7.0-8.2 (bins 79-103),
    // so bin t < 60 holds only undelayed light and bin t + 60 only delayed light.
    let p = Plane {
        fov: 60.0,
        spp: 64,
        bins: 120,
        max_depth: 2,
    };
    let checker = r#"<TemporalProfile type="ConstantTP" name="tp"><texture type="checkerboard" name="delay"><float name="color0" value="0"/><float name="color1" value="3"/><transform name="to_uv"><scale x="4" y="4"/></transform></texture></TemporalProfile>"#;
    let textured = run(
        &plane(
            &p,
            &format!(r#"<bsdf type="Separable">{DIFFUSE}{checker}</bsdf>"#),
        ),
        6,
    );
    let base = run(&plane(&p, &constant(0.0)), 6);
    let k = 60;
    let (mut pure_early, mut pure_late) = (0, 0);
    for pixel in 0..25 {
        let (mut early, mut late) = (0u32, 0u32);
        for t in 0..p.bins - k {
            let v = pixel * p.bins + t;
            let (a, b) = (textured.accum.nonzero[v], textured.accum.nonzero[v + k]);
            // Every path lands either at its undelayed bin or exactly 60 bins later.
            assert_eq!(a + b, base.accum.nonzero[v], "pixel {pixel} bin {t}");
            for c in 0..3 {
                let sum = textured.accum.x1[v * 3 + c] + textured.accum.x1[(v + k) * 3 + c];
                let want = base.accum.x1[v * 3 + c];
                assert!(
                    (sum - want).abs() <= 1e-9 * want.abs(),
                    "pixel {pixel} bin {t}"
                );
            }
            early += a;
            late += b;
        }
        pure_early += (late == 0 && early > 0) as usize;
        pure_late += (early == 0 && late > 0) as usize;
    }
    // Both regions are seen, some pixels wholly in one cell of each kind.
    assert!(pure_early > 0 && pure_late > 0, "{pure_early} {pure_late}");
}

#[test]
fn the_family_size_counts_the_tests() {
    assert_eq!(profiles().len() + 4 * NARROW.bins + 1, FAMILY);
}
