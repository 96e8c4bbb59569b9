//! Tests of the denoiser (SPEC 5 estimates as the filter sees them, SPEC 8 filter).
//!
//! - a plain, obviously-correct reference filter (every voxel, every neighbour in the
//!   window, f64 weights straight from the SPEC 8 formula) that the tiled filter must
//!   match to 1e-5 relative, bit-identically across tilings and thread counts;
//! - properties: noise-free volumes come back unchanged, steps do not leak, outliers
//!   are kept, membership is symmetric and exact at V = 0, mirrored inputs give
//!   mirrored outputs;
//! - convergence to a known truth as spp grows;
//! - the critical value for huge spp;
//! - end to end on a small Cornell box render.
//!
//! The synthetic bundles are made from actual random samples deposited like the
//! renderer does (one flushed sample per path and voxel), so the sums are consistent
//! (`nonzero <= spp`, `X2 n >= X1^2`).

// The reference filter and the generators are written as plain index loops on purpose.
#![allow(clippy::needless_range_loop)]

use std::sync::atomic::{AtomicU64, Ordering};
use tstat::bundle::manifest::{Manifest, Program, SamplingRecord, SceneRef};
use tstat::denoise::base_filter::{BaseFilter, BaseKind, Features, Sigmas};
use tstat::denoise::critical::Threshold;
use tstat::denoise::estimates::{Estimates, SumsView};
use tstat::denoise::filter::{filter, FilterParams, Membership, Tiling, Welch};
use tstat::denoise::gbuffers::GBuffers;
use tstat::denoise::membership::passes;
use tstat::denoise::pair_dof::{welch_satterthwaite, PairDof};
use tstat::denoise::slab::{self, denoise_bundle_to_npy, denoise_slabs, Dims, SlabPlan};
use tstat::denoise::{denoise_sums, Border, DenoiseParams, LoadedSums, Method, Variance};
use tstat::math::rng::Pcg32;
use tstat::stats::Transform;

const C: usize = 3;

// ---- random numbers -------------------------------------------------------------

struct Rng(Pcg32);

impl Rng {
    fn new(seed: u64) -> Rng {
        Rng(Pcg32::new(seed, 0x853c_49e6_748f_ea9b))
    }

    /// Uniform in (0, 1), 53 bits.
    fn uniform(&mut self) -> f64 {
        let a = self.0.next_u32() as u64;
        let b = self.0.next_u32() as u64;
        (((a << 21) | (b >> 11)) as f64 + 0.5) * (1.0 / (1u64 << 53) as f64)
    }

    /// Standard normal (Box-Muller).
    fn normal(&mut self) -> f64 {
        let (u1, u2) = (self.uniform(), self.uniform());
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    }

    fn below(&mut self, n: usize) -> usize {
        ((self.uniform() * n as f64) as usize).min(n - 1)
    }
}

// ---- synthetic bundles ------------------------------------------------------------

/// The sums of a synthetic render, laid out as the renderer stores them, plus
/// G-buffers.
#[derive(Clone)]
struct Bundle {
    h: usize,
    w: usize,
    t: usize,
    spp: u64,
    transform: Transform,
    /// (H, W, T, C).
    x1: Vec<f64>,
    x2: Vec<f64>,
    x3: Vec<f64>,
    sum: Vec<f64>,
    /// (H, W, T).
    nonzero: Vec<u32>,
    /// (H, W, 3).
    albedo: Vec<f32>,
    normal: Vec<f32>,
    /// (H, W).
    depth: Vec<f32>,
    emitter: Vec<f32>,
    /// Bin width h in OPL.
    bin_width: f64,
}

impl Bundle {
    fn new(h: usize, w: usize, t: usize, spp: u64, transform: Transform) -> Bundle {
        let n = h * w * t * C;
        Bundle {
            h,
            w,
            t,
            spp,
            transform,
            x1: vec![0.0; n],
            x2: vec![0.0; n],
            x3: vec![0.0; n],
            sum: vec![0.0; n],
            nonzero: vec![0; h * w * t],
            albedo: vec![0.0; h * w * 3],
            normal: vec![0.0; h * w * 3],
            depth: vec![0.0; h * w],
            emitter: vec![0.0; h * w],
            bin_width: 1.0,
        }
    }

    /// One path's total deposit in voxel (y, x, k), as one sample (like
    /// `RowAccum::add_sample`).
    fn deposit(&mut self, y: usize, x: usize, k: usize, rgb: [f64; 3]) {
        let v = (y * self.w + x) * self.t + k;
        assert!(rgb.iter().all(|&c| c >= 0.0), "radiance is non-negative");
        self.nonzero[v] += 1;
        assert!(self.nonzero[v] as u64 <= self.spp);
        for c in 0..C {
            let z = self.transform.apply(rgb[c]);
            let z2 = z * z;
            self.x1[v * C + c] += z;
            self.x2[v * C + c] += z2;
            self.x3[v * C + c] += z2 * z;
            self.sum[v * C + c] += rgb[c];
        }
    }

    fn view(&self) -> SumsView<'_> {
        SumsView {
            height: self.h,
            width: self.w,
            bins: self.t,
            channels: C,
            bin_width: self.bin_width,
            spp: self.spp,
            stratified: false,
            image_rows: self.h,
            z0: self.transform.at_zero(),
            x1: &self.x1,
            x2: &self.x2,
            x3: &self.x3,
            // With the identity `sum` is the same sequence of additions as `x1`; pass
            // X1 itself as the renderer's bundles do.
            sum: if self.transform.is_identity() {
                &self.x1
            } else {
                &self.sum
            },
            nonzero: &self.nonzero,
            replicates: None,
            pixel_spp: None,
        }
    }

    fn features(&self) -> Features<'_> {
        Features {
            albedo: &self.albedo,
            normal: &self.normal,
            depth: &self.depth,
            emitter: &self.emitter,
        }
    }

    fn estimates(&self) -> Estimates {
        Estimates::from_sums(&self.view())
    }

    fn set_features(&mut self, y: usize, x: usize, albedo: [f32; 3], normal: [f32; 3]) {
        let p = (y * self.w + x) * 3;
        self.albedo[p..p + 3].copy_from_slice(&albedo);
        self.normal[p..p + 3].copy_from_slice(&normal);
    }

    /// The same bundle with voxel (y, x, k) moved to `map(y, x, k)` (a bijection).
    /// `flip_nx` negates the normals' x components (a left-right mirror of the world).
    fn remapped(
        &self,
        map: impl Fn(usize, usize, usize) -> (usize, usize, usize),
        flip_nx: bool,
    ) -> Bundle {
        let mut b = self.clone();
        for y in 0..self.h {
            for x in 0..self.w {
                for k in 0..self.t {
                    let (y2, x2, k2) = map(y, x, k);
                    let (v, v2) = (
                        (y * self.w + x) * self.t + k,
                        (y2 * self.w + x2) * self.t + k2,
                    );
                    b.nonzero[v2] = self.nonzero[v];
                    for c in 0..C {
                        b.x1[v2 * C + c] = self.x1[v * C + c];
                        b.x2[v2 * C + c] = self.x2[v * C + c];
                        b.x3[v2 * C + c] = self.x3[v * C + c];
                        b.sum[v2 * C + c] = self.sum[v * C + c];
                    }
                }
                let (y2, x2, _) = map(y, x, 0);
                let (p, p2) = ((y * self.w + x) * 3, (y2 * self.w + x2) * 3);
                for c in 0..3 {
                    b.albedo[p2 + c] = self.albedo[p + c];
                    b.normal[p2 + c] = self.normal[p + c];
                }
                if flip_nx {
                    b.normal[p2] = -self.normal[p];
                }
            }
        }
        b
    }
}

fn unit(v: [f64; 3]) -> [f32; 3] {
    let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    v.map(|c| (c / l) as f32)
}

/// Random G-buffers: a few surfaces (palette albedo and normal, with jitter), and
/// background (zero) wherever `background(y, x)`.
fn random_features(b: &mut Bundle, rng: &mut Rng, background: impl Fn(usize, usize) -> bool) {
    let palette_a = [[0.8, 0.8, 0.8], [0.7, 0.1, 0.1], [0.15, 0.6, 0.2]];
    let palette_n = [[0.0, 0.0, 1.0], [1.0, 0.0, 0.3], [-0.2, 1.0, 0.2]];
    for y in 0..b.h {
        for x in 0..b.w {
            if background(y, x) {
                b.set_features(y, x, [0.0; 3], [0.0; 3]);
                continue;
            }
            let s = rng.below(3);
            let albedo = palette_a[s].map(|a: f64| (a + 0.08 * (rng.uniform() - 0.5)) as f32);
            let n = palette_n[s].map(|a: f64| a + 0.3 * (rng.uniform() - 0.5));
            b.set_features(y, x, albedo, unit(n));
        }
    }
}

/// A random bundle like a transient render: per pixel an arrival bin before which
/// nothing is deposited, a block of all-zero pixels (plus scattered ones), many
/// exactly-zero voxels, zero-inflated samples with per-voxel deposit probability, and
/// channels that are sometimes zero within a deposit.
fn random_bundle(
    h: usize,
    w: usize,
    t: usize,
    spp: u64,
    transform: Transform,
    seed: u64,
) -> Bundle {
    let mut rng = Rng::new(seed);
    let mut b = Bundle::new(h, w, t, spp, transform);
    let zero_pixel: Vec<bool> = (0..h * w)
        .map(|p| {
            let (y, x) = (p / w, p % w);
            (y >= h * 2 / 3 && x >= w * 2 / 3) || rng.uniform() < 0.1
        })
        .collect();
    random_features(&mut b, &mut rng, |y, x| zero_pixel[y * w + x]);
    // Some surfaces reflect nothing in some channels (exact zeros in one channel only).
    let colours = [
        [1.0, 0.8, 0.5],
        [0.3, 0.9, 0.4],
        [0.6, 0.5, 1.2],
        [0.0, 0.9, 0.4],
        [0.0, 0.0, 0.7],
    ];
    for y in 0..h {
        for x in 0..w {
            if zero_pixel[y * w + x] {
                continue;
            }
            let arrival = rng.below(t.div_ceil(3));
            let colour = colours[rng.below(colours.len())];
            for k in arrival..t {
                if rng.uniform() < 0.3 {
                    continue; // an exactly-zero voxel
                }
                // A smooth level times a random factor in [0.5, 2].
                let smooth = 1.4
                    + 0.5 * ((y as f64 * 0.7).sin() + (x as f64 * 0.5).cos())
                    + 0.3 * (k as f64 * 0.4).sin();
                let level = smooth * 2f64.powf(2.0 * rng.uniform() - 1.0);
                let q = 0.05 + 0.95 * rng.uniform(); // deposit probability
                for _ in 0..spp {
                    if rng.uniform() >= q {
                        continue;
                    }
                    let mut rgb = [0.0; 3];
                    for c in 0..C {
                        if rng.uniform() < 0.1 {
                            continue; // this channel got nothing
                        }
                        rgb[c] = level * colour[c] * (0.5 * rng.normal()).exp() / q;
                    }
                    b.deposit(y, x, k, rgb);
                }
            }
        }
    }
    b
}

// ---- the reference filter -----------------------------------------------------------

struct Reference {
    /// Planar (H, W, C, T) like the fast filter.
    out: Vec<f64>,
    /// Non-centre neighbours (with a non-zero mean on either side) that passed the
    /// membership test, and all such neighbours.
    members: u64,
    pairs: u64,
}

/// SPEC 8 literally: for every voxel j, every voxel i with |dy|, |dx| <= r and
/// |dt| <= r_t inside the volume, `w_ij = p_ij m_ij` in f64 with p from the formula,
/// m from `membership::passes` on the same f32 estimates (centre always 1).
fn reference_filter(e: &Estimates, f: &Features, p: &FilterParams) -> Reference {
    let (h, w, t) = (e.height as i64, e.width as i64, e.bins as i64);
    let (r, rt) = (p.radius as i64, p.temporal_radius as i64);
    let s = p.base.sigmas;
    let jbf = match p.base.kind {
        BaseKind::Jbf => true,
        BaseKind::Gaussian => false,
    };
    // On estimates from replicates, a `--alpha` test takes g per pair at its
    // Welch-Satterthwaite degrees of freedom (the table is checked against the exact
    // quantile in `pair_dof.rs` and below).
    let pair = match (p.membership, e.replicates) {
        (Membership::Published(Welch { alpha: Some(a), .. }), Some(b)) => Some(PairDof::new(b, a)),
        _ => None,
    };
    let mut out = vec![0.0f64; e.mean.len()];
    let (mut members, mut pairs) = (0u64, 0u64);
    for yj in 0..h {
        for xj in 0..w {
            let j = (yj * w + xj) as usize;
            for tj in 0..t {
                let mut num = [0.0f64; C];
                let mut den = 0.0f64;
                for yi in yj - r..=yj + r {
                    for xi in xj - r..=xj + r {
                        for ti in tj - rt..=tj + rt {
                            if yi < 0 || yi >= h || xi < 0 || xi >= w || ti < 0 || ti >= t {
                                continue;
                            }
                            let i = (yi * w + xi) as usize;
                            let (dy, dx, dt) = (yi - yj, xi - xj, ti - tj);
                            let centre = dy == 0 && dx == 0 && dt == 0;
                            let (ti, tj) = (ti as usize, tj as usize);
                            let member = match p.membership {
                                Membership::BaseOnly => true,
                                _ if centre => true,
                                Membership::Published(Welch { g2, .. }) => (0..C).all(|c| {
                                    let (vi, vj) = (e.v[e.idx(i, c, ti)], e.v[e.idx(j, c, tj)]);
                                    passes(
                                        e.theta[e.idx(i, c, ti)],
                                        e.theta[e.idx(j, c, tj)],
                                        vi,
                                        vj,
                                        pair.as_ref().map_or(g2 as f32, |pd| pd.g2(vi, vj)),
                                    )
                                }),
                                Membership::Tstat(_) => {
                                    unreachable!("tests/it/denoise_tstat.rs has tstat's reference")
                                }
                            };
                            if !centre
                                && (0..C).any(|c| {
                                    e.mean[e.idx(i, c, ti)] != 0.0 || e.mean[e.idx(j, c, tj)] != 0.0
                                })
                            {
                                pairs += 1;
                                members += member as u64;
                            }
                            if !member {
                                continue;
                            }
                            let mut q = (dy * dy + dx * dx) as f64 / (s.xy * s.xy)
                                + (dt * dt) as f64 / (s.t * s.t);
                            if jbf {
                                for c in 0..3 {
                                    let da =
                                        f.albedo[i * 3 + c] as f64 - f.albedo[j * 3 + c] as f64;
                                    let dn =
                                        f.normal[i * 3 + c] as f64 - f.normal[j * 3 + c] as f64;
                                    q += da * da / (s.albedo * s.albedo)
                                        + dn * dn / (s.normal * s.normal);
                                }
                            }
                            let wij = (-0.5 * q).exp();
                            for c in 0..C {
                                num[c] += wij * e.mean[e.idx(i, c, ti)] as f64;
                            }
                            den += wij;
                        }
                    }
                }
                for c in 0..C {
                    // The stored means are in units of 2^scale.mean.
                    out[e.idx(j, c, tj as usize)] = num[c] / den * e.scale.unscale_mean();
                }
            }
        }
    }
    Reference {
        out,
        members,
        pairs,
    }
}

/// Below the smallest normal f32 the fast filter's f32 output cannot hold 1e-5 relative
/// precision (subnormals have fewer bits), so differences up to it are allowed.
const ABS_FLOOR: f64 = f32::MIN_POSITIVE as f64;

/// `|a - b| <= rel * max(|a|, |b|) + ABS_FLOOR` everywhere; returns the largest
/// relative difference seen.
fn assert_close(fast: &[f32], reference: &[f64], rel: f64, what: &str) -> f64 {
    assert_eq!(fast.len(), reference.len(), "{what}: lengths");
    let mut worst = 0.0f64;
    for (k, (&a, &b)) in fast.iter().zip(reference).enumerate() {
        let a = a as f64;
        assert!(
            a.is_finite() && b.is_finite(),
            "{what}: non-finite at {k}: {a} {b}"
        );
        let d = (a - b).abs();
        let m = a.abs().max(b.abs());
        assert!(
            d <= rel * m + ABS_FLOOR,
            "{what}: at planar index {k}: fast {a:e} vs reference {b:e} (rel {:e})",
            d / m
        );
        if m > 0.0 {
            worst = worst.max(d / m);
        }
    }
    worst
}

/// The published filter's membership with this g^2, or the base filter alone.
fn welch(g2: Option<f64>) -> Membership {
    g2.map_or(Membership::BaseOnly, |g2| {
        Membership::Published(Welch { g2, alpha: None })
    })
}

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
}

fn run_filter(e: &Estimates, f: &Features, p: &FilterParams, tiling: Tiling) -> Vec<f32> {
    filter(e, f, p, tiling, &|_| {}).0
}

const TILINGS: [Tiling; 5] = [
    Tiling {
        rows: 1,
        cols: 1,
        bins: 1,
    },
    Tiling {
        rows: 3,
        cols: 5,
        bins: 7,
    },
    Tiling {
        rows: 64,
        cols: 64,
        bins: 1000,
    },
    Tiling {
        rows: 4,
        cols: 16,
        bins: 64,
    },
    Tiling {
        rows: 2,
        cols: 3,
        bins: 2,
    },
];

fn bits(v: &[f32]) -> Vec<u32> {
    v.iter().map(|x| x.to_bits()).collect()
}

// ---- 1. the fast filter against the reference ------------------------------------------

#[test]
fn fast_filter_matches_reference_on_random_bundles() {
    struct Case {
        h: usize,
        w: usize,
        t: usize,
        spp: u64,
        r: usize,
        rt: usize,
        sigmas: Sigmas,
        g2: f64,
        transform: Transform,
    }
    let d = Sigmas::default();
    let odd = Sigmas {
        xy: 1.7,
        t: 0.6,
        albedo: 0.3,
        normal: 0.5,
    };
    let id = Transform::Identity;
    let cases = [
        // Non-square, moderate radius.
        Case {
            h: 13,
            w: 17,
            t: 24,
            spp: 16,
            r: 3,
            rt: 1,
            sigmas: d,
            g2: 4.0,
            transform: id,
        },
        // T = 1 (the temporal window is clipped to nothing), and T = 1 with r_t = 0.
        Case {
            h: 9,
            w: 6,
            t: 1,
            spp: 8,
            r: 2,
            rt: 1,
            sigmas: d,
            g2: 9.0,
            transform: id,
        },
        Case {
            h: 6,
            w: 9,
            t: 1,
            spp: 8,
            r: 2,
            rt: 0,
            sigmas: odd,
            g2: 4.0,
            transform: id,
        },
        // Radius larger than the image, r_t = 2.
        Case {
            h: 5,
            w: 7,
            t: 11,
            spp: 4,
            r: 9,
            rt: 2,
            sigmas: d,
            g2: 4.0,
            transform: id,
        },
        // r = 0: a purely temporal filter.
        Case {
            h: 10,
            w: 10,
            t: 16,
            spp: 32,
            r: 0,
            rt: 1,
            sigmas: d,
            g2: 4.0,
            transform: id,
        },
        // The defaults' radius, r_t = 0 and r_t = 2, the smallest spp.
        Case {
            h: 16,
            w: 12,
            t: 20,
            spp: 64,
            r: 5,
            rt: 0,
            sigmas: d,
            g2: 4.0,
            transform: id,
        },
        Case {
            h: 12,
            w: 12,
            t: 30,
            spp: 2,
            r: 5,
            rt: 2,
            sigmas: odd,
            g2: 8.2,
            transform: id,
        },
        // Box-Cox sums: theta is tested on the transformed scale, mean is radiance.
        Case {
            h: 11,
            w: 8,
            t: 12,
            spp: 24,
            r: 2,
            rt: 1,
            sigmas: d,
            g2: 4.0,
            transform: Transform::BoxCox { lambda: 0.5 },
        },
    ];
    let pools = [pool(1), pool(2)];
    let mut worst = 0.0f64;
    for (n, case) in cases.iter().enumerate() {
        let b = random_bundle(
            case.h,
            case.w,
            case.t,
            case.spp,
            case.transform,
            1000 + n as u64,
        );
        let est = b.estimates();
        let features = b.features();
        for kind in [BaseKind::Jbf, BaseKind::Gaussian] {
            for g2 in [None, Some(case.g2)] {
                let params = FilterParams {
                    radius: case.r,
                    temporal_radius: case.rt,
                    base: BaseFilter {
                        kind,
                        sigmas: case.sigmas,
                    },
                    membership: welch(g2),
                    zero_border: false,
                };
                let what = format!(
                    "case {n} ({}x{}x{}, spp {}, r {}, r_t {}), {kind:?}, g2 {g2:?}",
                    case.h, case.w, case.t, case.spp, case.r, case.rt
                );
                let reference = reference_filter(&est, &features, &params);
                // The case must exercise what it claims: membership both accepting and
                // rejecting, and a filter that changes the input.
                if g2.is_some() && reference.pairs > 0 {
                    let frac = reference.members as f64 / reference.pairs as f64;
                    assert!(
                        (0.05..0.95).contains(&frac),
                        "{what}: member fraction {frac}"
                    );
                }
                if case.r > 0 || case.t > 1 {
                    let changed = reference
                        .out
                        .iter()
                        .zip(&est.mean_in_radiance())
                        .filter(|(a, b)| (**a - **b as f64).abs() > 1e-3 * a.abs())
                        .count();
                    assert!(
                        changed * 10 > est.mean.len(),
                        "{what}: only {changed} voxels changed"
                    );
                }
                let mut first: Option<Vec<u32>> = None;
                for (threads, pool) in [1, 2].iter().zip(&pools) {
                    for tiling in TILINGS {
                        let out = pool.install(|| run_filter(&est, &features, &params, tiling));
                        let what = format!("{what}, {threads} threads, {tiling:?}");
                        worst = worst.max(assert_close(&out, &reference.out, 1e-5, &what));
                        match &first {
                            None => first = Some(bits(&out)),
                            Some(f) => assert!(
                                *f == bits(&out),
                                "{what}: not bit-identical to the first run"
                            ),
                        }
                    }
                }
            }
        }
    }
    eprintln!("largest relative difference to the reference: {worst:e}");
}

/// On estimates from B replicates, the published test with `--alpha` takes each pair's
/// critical value at its Welch-Satterthwaite degrees of freedom: the fast filter equals
/// the reference, the per-pair values change which pairs are members (against the
/// single `2 B - 2` value), and the table decides like the exact quantile on all but
/// a negligible share of pairs.
#[test]
fn published_test_takes_each_pairs_degrees_of_freedom_on_replicates() {
    let (b_reps, alpha) = (4u64, 0.05);
    let bundle = random_bundle(12, 11, 20, 16, Transform::Identity, 4242);
    let mut est = bundle.estimates();
    est.replicates = Some(b_reps);
    let features = bundle.features();
    let params = |alpha: Option<f64>| FilterParams {
        radius: 3,
        temporal_radius: 1,
        base: BaseFilter {
            kind: BaseKind::Jbf,
            sigmas: Sigmas::default(),
        },
        membership: Membership::Published(Welch {
            g2: Threshold::Alpha(0.05).g2(b_reps),
            alpha,
        }),
        zero_border: false,
    };
    let per_pair = reference_filter(&est, &features, &params(Some(alpha)));
    let fixed = reference_filter(&est, &features, &params(None));
    let frac = per_pair.members as f64 / per_pair.pairs as f64;
    assert!((0.05..0.95).contains(&frac), "member fraction {frac}");
    // nu <= 2B - 2, so the per-pair values are at least the fixed one: more members.
    assert!(
        per_pair.members as f64 > 1.02 * fixed.members as f64,
        "members: per pair {}, fixed 2B - 2 {}",
        per_pair.members,
        fixed.members
    );
    for tiling in TILINGS {
        let out = run_filter(&est, &features, &params(Some(alpha)), tiling);
        assert_close(&out, &per_pair.out, 1e-5, &format!("{tiling:?}"));
    }
    // The table against the exact quantile, on every neighbouring pair of voxels.
    let table = PairDof::new(b_reps, alpha);
    let (mut differ, mut total) = (0u64, 0u64);
    for k in 0..est.v.len() - 1 {
        let (vi, vj) = (est.v[k], est.v[k + 1]);
        let d2 = (est.theta[k] as f64 - est.theta[k + 1] as f64).powi(2);
        if vi + vj > 0.0 {
            let nu = welch_satterthwaite(vi as f64, vj as f64, b_reps);
            let exact = tstat::denoise::critical::student_t_quantile(1.0 - alpha / 2.0, nu);
            let g2 = table.g2(vi, vj) as f64;
            assert!((g2 / (exact * exact) - 1.0).abs() < 1e-4, "{vi} {vj}");
            total += 1;
            let v = (vi + vj) as f64;
            differ += ((d2 <= g2 * v) != (d2 <= exact * exact * v)) as u64;
        }
    }
    assert!(
        total > 1000 && differ * 1000 <= total,
        "{differ} of {total} decisions differ"
    );
}

/// One non-zero voxel in one channel (at the corners and inside): the voxels whose
/// window reaches it get its share, every other voxel is skipped as all-zero and must
/// be exactly 0; both must match the reference for every tiling.
#[test]
fn single_voxel_in_one_channel_matches_reference() {
    let (h, w, t, spp) = (9, 10, 12, 8);
    let mut rng = Rng::new(17);
    for (y, x, k) in [(4, 5, 6), (0, 0, 0), (8, 9, 11), (0, 9, 3)] {
        for c in 0..C {
            // 3 of 8 paths deposit 1, 2, 3 (compatible with 0 at g = 2), or all 8
            // deposit 2 (V = 0, incompatible with 0 for any g).
            for certain in [false, true] {
                let mut b = Bundle::new(h, w, t, spp, Transform::Identity);
                random_features(&mut b, &mut rng, |_, _| false);
                for s in 0..if certain { spp } else { 3 } {
                    let mut rgb = [0.0; 3];
                    rgb[c] = if certain { 2.0 } else { 1.0 + s as f64 };
                    b.deposit(y, x, k, rgb);
                }
                let est = b.estimates();
                for g2 in [None, Some(4.0)] {
                    let p = FilterParams {
                        radius: 2,
                        temporal_radius: 1,
                        base: BaseFilter {
                            kind: BaseKind::Jbf,
                            sigmas: Sigmas::default(),
                        },
                        membership: welch(g2),
                        zero_border: false,
                    };
                    let what = format!("({y},{x},{k}) c {c} certain {certain} {g2:?}");
                    let reference = reference_filter(&est, &b.features(), &p);
                    if (y, x, k) == (4, 5, 6) {
                        let nonzero = reference.out.iter().filter(|&&v| v != 0.0).count();
                        let expected = if certain && g2.is_some() {
                            1
                        } else {
                            5 * 5 * 3
                        };
                        assert_eq!(nonzero, expected, "{what}");
                    }
                    for tiling in TILINGS {
                        let out = run_filter(&est, &b.features(), &p, tiling);
                        assert_close(&out, &reference.out, 1e-5, &format!("{what} {tiling:?}"));
                    }
                }
            }
        }
    }
}

/// A volume with no voxel non-zero anywhere filters to exact zeros (no 0/0).
#[test]
fn all_zero_volume_stays_zero() {
    let b = Bundle::new(7, 9, 5, 16, Transform::Identity);
    let est = b.estimates();
    for g2 in [None, Some(4.0)] {
        let p = FilterParams {
            radius: 3,
            temporal_radius: 1,
            base: BaseFilter {
                kind: BaseKind::Jbf,
                sigmas: Sigmas::default(),
            },
            membership: welch(g2),
            zero_border: false,
        };
        let out = run_filter(&est, &b.features(), &p, Tiling::default());
        assert!(out.iter().all(|&v| v.to_bits() == 0), "{g2:?}");
    }
}

/// The estimates the filter reads agree with the sample statistics of SPEC 5 computed
/// two-pass from the explicit samples (zeros included), in the planar layout.
#[test]
fn estimates_match_two_pass_sample_statistics() {
    for transform in [
        Transform::Identity,
        Transform::BoxCox { lambda: 0.5 },
        Transform::YeoJohnson { lambda: 0.0 },
    ] {
        let (h, w, t, spp) = (4usize, 5usize, 6usize, 40u64);
        let mut rng = Rng::new(7);
        let mut b = Bundle::new(h, w, t, spp, transform);
        // samples[(voxel, c)] = every path's value, zeros included.
        let mut samples = vec![Vec::new(); h * w * t * C];
        for y in 0..h {
            for x in 0..w {
                for k in 0..t {
                    let q = [0.0, 0.05, 0.5, 1.0][(y + x + k) % 4];
                    for _ in 0..spp {
                        let v = (y * w + x) * t + k;
                        if rng.uniform() < q {
                            let rgb = [0, 1, 2].map(|c| {
                                if c == 2 && rng.uniform() < 0.3 {
                                    0.0
                                } else {
                                    (1.0 + c as f64) * (0.7 * rng.normal()).exp()
                                }
                            });
                            b.deposit(y, x, k, rgb);
                            for c in 0..C {
                                samples[v * C + c].push(rgb[c]);
                            }
                        } else {
                            for c in 0..C {
                                samples[v * C + c].push(0.0);
                            }
                        }
                    }
                }
            }
        }
        let est = b.estimates();
        let n = spp as f64;
        for y in 0..h {
            for x in 0..w {
                for k in 0..t {
                    let v = (y * w + x) * t + k;
                    for c in 0..C {
                        let raw = &samples[v * C + c];
                        let z: Vec<f64> = raw.iter().map(|&s| transform.apply(s)).collect();
                        let mean = raw.iter().sum::<f64>() / n;
                        let mu = z.iter().sum::<f64>() / n;
                        let s2 = z.iter().map(|z| (z - mu).powi(2)).sum::<f64>() / n;
                        let m3 = z.iter().map(|z| (z - mu).powi(3)).sum::<f64>() / n;
                        let sigma2 = s2 * n / (n - 1.0);
                        let (theta, vv) = if sigma2 == 0.0 {
                            (mu, 0.0)
                        } else {
                            (mu + m3 / (6.0 * sigma2 * n), sigma2 / n)
                        };
                        let i = est.idx(y * w + x, c, k);
                        let what = format!("{transform:?} voxel ({y},{x},{k}) c {c}");
                        let close = |a: f64, b: f64, scale: f64| (a - b).abs() <= 1e-6 * scale;
                        let (e_mean, e_theta, e_v) = est.unscaled(i);
                        assert!(
                            close(e_mean, mean, mean.abs()),
                            "{what}: mean {e_mean} vs {mean}"
                        );
                        // Stored relative to z(0).
                        let theta = theta - transform.at_zero();
                        assert!(
                            close(e_theta, theta, theta.abs() + vv.sqrt()),
                            "{what}: theta {e_theta} vs {theta}"
                        );
                        assert!(close(e_v, vv, vv), "{what}: v {e_v} vs {vv}");
                        if raw.iter().all(|&s| s == raw[0]) {
                            assert_eq!(est.v[i], 0.0, "{what}");
                        }
                    }
                }
            }
        }
    }
}

/// `denoise_sums` is the filter with the threshold's g^2, its output re-laid out as
/// (H, W, T, C); progress adds up to every pixel once.
#[test]
fn denoise_sums_is_the_filter_in_hwtc_layout() {
    let b = random_bundle(9, 11, 13, 16, Transform::Identity, 5);
    let est = b.estimates();
    for (method, g2) in [
        (Method::Published(Threshold::Gamma(0.05)), Some(9.0)),
        (
            Method::Published(Threshold::Alpha(0.005)),
            Some(Threshold::Alpha(0.005).g2(16)),
        ),
        (Method::BaseOnly, None),
    ] {
        let params = DenoiseParams {
            radius: 3,
            temporal_radius: 1,
            method,
            base: BaseKind::Jbf,
            sigmas: Sigmas::default(),
            tiling: Tiling {
                rows: 2,
                cols: 4,
                bins: 5,
            },
            variance: Variance::Unbiased,
            border: Border::Clip,
        };
        let done = AtomicU64::new(0);
        let d = denoise_sums(&b.view(), &b.features(), &params, &|k| {
            done.fetch_add(k, Ordering::Relaxed);
        });
        assert_eq!(done.load(Ordering::Relaxed), (b.h * b.w) as u64);
        let fp = FilterParams {
            radius: 3,
            temporal_radius: 1,
            base: BaseFilter {
                kind: BaseKind::Jbf,
                sigmas: Sigmas::default(),
            },
            membership: welch(g2),
            zero_border: false,
        };
        let planar = run_filter(&est, &b.features(), &fp, Tiling::default());
        assert_eq!(d.volume.shape(), &[b.h, b.w, b.t, C]);
        for ((y, x, k, c), &v) in d.volume.indexed_iter() {
            let p = planar[est.idx(y * b.w + x, c, k)];
            assert_eq!(v.to_bits(), p.to_bits(), "{method:?} ({y},{x},{k},{c})");
        }
    }
}

/// The filter averages radiance (S / n), not transformed values: with membership off,
/// Box-Cox sums of the same samples give the identity's output.
#[test]
fn filter_averages_radiance_whatever_the_transform() {
    let a = random_bundle(8, 9, 10, 16, Transform::Identity, 11);
    let b = random_bundle(8, 9, 10, 16, Transform::BoxCox { lambda: 0.5 }, 11);
    assert_eq!(a.sum, b.sum);
    let p = FilterParams {
        radius: 2,
        temporal_radius: 1,
        base: BaseFilter {
            kind: BaseKind::Jbf,
            sigmas: Sigmas::default(),
        },
        membership: Membership::BaseOnly,
        zero_border: false,
    };
    let oa = run_filter(&a.estimates(), &a.features(), &p, Tiling::default());
    let ob = run_filter(&b.estimates(), &b.features(), &p, Tiling::default());
    assert_eq!(bits(&oa), bits(&ob));
}

/// Radiance in other units: scaling every sample by 2^k (X1, X2, X3 by 2^k, 2^2k, 2^3k)
/// scales every method's output by exactly 2^k, also where f32 could not hold the
/// unscaled variances (2^±90: `v` ~ 2^±180) and the test would accept or reject
/// everything.
#[test]
fn output_scales_exactly_with_the_radiance_unit() {
    let b = random_bundle(9, 10, 12, 16, Transform::Identity, 23);
    for params in methods() {
        let base = denoise_sums(&b.view(), &b.features(), &params, &|_| {}).volume;
        assert!(base.iter().any(|&v| v > 0.0));
        for k in [-90, -45, 45, 90] {
            let f = 2f64.powi(k);
            let mut s = Bundle::new(b.h, b.w, b.t, b.spp, Transform::Identity);
            s.nonzero = b.nonzero.clone();
            s.x1 = b.x1.iter().map(|v| v * f).collect();
            s.x2 = b.x2.iter().map(|v| v * f * f).collect();
            s.x3 = b.x3.iter().map(|v| v * f * f * f).collect();
            s.sum = s.x1.clone();
            (s.albedo, s.normal) = (b.albedo.clone(), b.normal.clone());
            (s.depth, s.emitter) = (b.depth.clone(), b.emitter.clone());
            let out = denoise_sums(&s.view(), &s.features(), &params, &|_| {}).volume;
            for ((i, &v), &u) in out.indexed_iter().zip(base.iter()) {
                let want = (f64::from(u) * f) as f32;
                assert_eq!(
                    v.to_bits(),
                    want.to_bits(),
                    "{:?} 2^{k} at {i:?}: {v:e} vs {want:e}",
                    params.method
                );
            }
        }
    }
}

// ---- 2. properties ----------------------------------------------------------------------

/// A bundle where every voxel's samples all equal `value(y, x, k) * colour` (every path
/// deposits it; V = 0), or nothing (value 0).
fn noise_free(
    h: usize,
    w: usize,
    t: usize,
    spp: u64,
    value: impl Fn(usize, usize, usize) -> f64,
    colour: [f64; 3],
) -> Bundle {
    let mut b = Bundle::new(h, w, t, spp, Transform::Identity);
    for y in 0..h {
        for x in 0..w {
            for k in 0..t {
                let v = value(y, x, k);
                if v != 0.0 {
                    for _ in 0..spp {
                        b.deposit(y, x, k, colour.map(|c| c * v));
                    }
                }
            }
        }
    }
    b
}

#[test]
fn noise_free_volume_comes_back_unchanged() {
    let (h, w, t, spp) = (12, 14, 10, 16);
    // Blocks of constant value next to blocks of other values and of zeros: every
    // voxel has neighbours that agree and neighbours that do not.
    let hash = |y: usize, x: usize, k: usize| {
        let m = tstat::math::rng::mix64(((y / 3) * 1000 + (x / 4) * 10 + k / 3) as u64 + 77);
        (m % 7) as i32
    };
    let pow2 = |y, x, k| match hash(y, x, k) {
        0 => 0.0,
        e => 2f64.powi(e - 3),
    };
    let general = |y, x, k| match hash(y, x, k) {
        0 => 0.0,
        e => 0.37 * e as f64 + 0.011,
    };
    let mut rng = Rng::new(3);
    for (name, exact, b) in [
        (
            "powers of two",
            true,
            noise_free(h, w, t, spp, pow2, [1.0, 0.5, 4.0]),
        ),
        (
            "general values",
            false,
            noise_free(h, w, t, spp, general, [1.0, 0.3, 1.7]),
        ),
    ] {
        let mut b = b;
        random_features(&mut b, &mut rng, |_, _| false);
        let est = b.estimates();
        assert!(
            est.v.iter().all(|&v| v == 0.0),
            "{name}: V must be exactly 0"
        );
        assert!(est.mean.contains(&0.0) && est.mean.iter().any(|&m| m != 0.0));
        let mean = est.mean_in_radiance();
        for kind in [BaseKind::Jbf, BaseKind::Gaussian] {
            // d != 0 with V = 0 fails for any g, however large.
            for g2 in [4.0, 1e6] {
                let p = FilterParams {
                    radius: 3,
                    temporal_radius: 1,
                    base: BaseFilter {
                        kind,
                        sigmas: Sigmas::default(),
                    },
                    membership: Membership::Published(Welch { g2, alpha: None }),
                    zero_border: false,
                };
                for tiling in [TILINGS[0], TILINGS[3]] {
                    let out = run_filter(&est, &b.features(), &p, tiling);
                    if exact {
                        // sum w_i m / sum w_i with m a power of two is exact in f32.
                        assert_eq!(bits(&out), bits(&mean), "{name} {kind:?} {g2}");
                    } else {
                        // Only f32 rounding of the weighted sums (<= 363 terms).
                        assert_close(
                            &out,
                            &mean.iter().map(|&m| m as f64).collect::<Vec<_>>(),
                            2e-6,
                            name,
                        );
                    }
                }
                // Without membership the base filter blurs the same volume: the test
                // above can fail.
                let base_only = FilterParams {
                    membership: Membership::BaseOnly,
                    ..p
                };
                let out = run_filter(&est, &b.features(), &base_only, TILINGS[3]);
                let moved = out
                    .iter()
                    .zip(&mean)
                    .filter(|(a, m)| (**a - **m).abs() > 1e-3 * m.abs().max(1e-3))
                    .count();
                assert!(
                    moved * 4 > out.len(),
                    "{name}: base filter changed only {moved}"
                );
            }
        }
    }
}

/// Left half 1, right half 5, samples with 10% relative noise, 256 spp; G-buffers are
/// uniform so only membership can stop the leak.
#[test]
fn step_edge_does_not_leak() {
    let (h, w, t, spp) = (16, 16, 8, 256u64);
    let truth = |x: usize| if x < w / 2 { 1.0 } else { 5.0 };
    let colour = [1.0, 0.6, 0.3];
    let mut rng = Rng::new(21);
    let mut b = Bundle::new(h, w, t, spp, Transform::Identity);
    for y in 0..h {
        for x in 0..w {
            b.set_features(y, x, [0.5; 3], [0.0, 0.0, 1.0]);
            for k in 0..t {
                for _ in 0..spp {
                    let s = truth(x) * (1.0 + 0.1 * rng.normal());
                    b.deposit(y, x, k, colour.map(|c| c * s));
                }
            }
        }
    }
    let est = b.estimates();
    // Largest error over every voxel of the two columns at the step, in units of one
    // voxel's standard error (0.1 * value / sqrt(spp)).
    let edge_error = |out: &[f32]| {
        let mut worst = 0.0f64;
        for y in 0..h {
            for x in [w / 2 - 1, w / 2] {
                for k in 0..t {
                    for c in 0..C {
                        let v = truth(x) * colour[c];
                        let se = 0.1 * v / (spp as f64).sqrt();
                        let o = out[est.idx(y * w + x, c, k)] as f64;
                        worst = worst.max((o - v).abs() / se);
                    }
                }
            }
        }
        worst
    };
    for kind in [BaseKind::Gaussian, BaseKind::Jbf] {
        let p = FilterParams {
            radius: 5,
            temporal_radius: 1,
            base: BaseFilter {
                kind,
                sigmas: Sigmas::default(),
            },
            membership: Membership::Published(Welch {
                g2: Threshold::Gamma(0.1).g2(spp),
                alpha: None,
            }),
            zero_border: false,
        };
        let out = run_filter(&est, &b.features(), &p, Tiling::default());
        let e = edge_error(&out);
        assert!(e < 3.0, "{kind:?}: edge voxels are {e} standard errors off");
        let blurred = edge_error(&run_filter(
            &est,
            &b.features(),
            &FilterParams {
                membership: Membership::BaseOnly,
                ..p
            },
            Tiling::default(),
        ));
        assert!(
            blurred > 100.0,
            "{kind:?}: the base filter alone should leak ({blurred})"
        );
    }
}

#[test]
fn membership_is_symmetric_and_exact_at_zero_variance() {
    let mut rng = Rng::new(99);
    let mut values = vec![
        0.0f32,
        -0.0,
        1.0,
        -1.0,
        1e-3,
        3.5,
        1e6,
        -2.0,
        f32::MIN_POSITIVE,
        1e30,
    ];
    for _ in 0..200 {
        values.push((rng.normal() * 10f64.powf(6.0 * rng.uniform() - 3.0)) as f32);
    }
    let vars = [0.0f32, 1e-12, 1e-3, 0.5, 2.0, 1e8];
    for &a in &values {
        for &b in values.iter().step_by(7) {
            for &va in &vars {
                for &vb in &vars {
                    for g2 in [0.5f32, 4.0, 9.0, 8.1] {
                        assert_eq!(
                            passes(a, b, va, vb, g2),
                            passes(b, a, vb, va, g2),
                            "{a} {b} {va} {vb} {g2}"
                        );
                    }
                }
            }
        }
        // d = 0, V = 0 passes (any g); d != 0, V = 0 fails however large g is.
        for g2 in [0.0f32, 4.0, 1e30] {
            assert!(passes(a, a, 0.0, 0.0, g2), "{a} {g2}");
            let next = f32::from_bits(a.to_bits() + 1); // the next representable value
            if a.abs() >= 1e-3 && next.is_finite() {
                assert!(!passes(a, next, 0.0, 0.0, g2), "{a} vs {next}, {g2}");
                let far = a * 1.5;
                assert!(!passes(a, far, 0.0, 0.0, g2), "{a} {far} {g2}");
            }
        }
    }
    // The test is d^2 <= g^2 V: on both sides of the boundary |d| / sqrt(V) = g = 3.
    assert!(passes(0.0, 2.9, 0.5, 0.5, 9.0));
    assert!(!passes(0.0, 3.1, 0.5, 0.5, 9.0));
    assert!(passes(10.0, 10.0 - 3.0 * 0.1, 0.004, 0.006, 9.0 * 1.001));
    assert!(!passes(10.0, 10.0 - 3.0 * 0.1, 0.004, 0.006, 9.0 * 0.999));
}

/// With d != 0 but |d| below ~4e-23 the f32 product d * d underflows to 0; SPEC 8's
/// "d != 0, V = 0 fails" must hold anyway (the fast filter uses the same test).
#[test]
fn membership_tiny_nonzero_difference_with_zero_variance_fails() {
    assert!(!passes(1e-23, 2e-23, 0.0, 0.0, 4.0));
}

/// One voxel far (in standard errors) from its neighbours keeps its own value exactly,
/// and does not pull its neighbours.
#[test]
fn isolated_outlier_is_kept() {
    let (h, w, t, spp) = (15, 15, 5, 256u64);
    let (oy, ox, ok) = (7, 7, 2);
    let mut rng = Rng::new(5);
    let mut b = Bundle::new(h, w, t, spp, Transform::Identity);
    let level = |y, x, k| if (y, x, k) == (oy, ox, ok) { 3.0 } else { 1.0 };
    for y in 0..h {
        for x in 0..w {
            b.set_features(y, x, [0.5; 3], [0.0, 0.0, 1.0]);
            for k in 0..t {
                for _ in 0..spp {
                    let s = level(y, x, k) * (1.0 + 0.1 * rng.normal());
                    b.deposit(y, x, k, [s, 0.5 * s, 2.0 * s]);
                }
            }
        }
    }
    let est = b.estimates();
    let o = |c| est.idx(oy * w + ox, c, ok);
    for kind in [BaseKind::Gaussian, BaseKind::Jbf] {
        let p = FilterParams {
            radius: 5,
            temporal_radius: 1,
            base: BaseFilter {
                kind,
                sigmas: Sigmas::default(),
            },
            membership: Membership::Published(Welch {
                g2: 4.0,
                alpha: None,
            }),
            zero_border: false,
        };
        let out = run_filter(&est, &b.features(), &p, Tiling::default());
        // Every neighbour fails the test, so only the centre counts: out = mean exactly.
        for c in 0..C {
            assert_eq!(out[o(c)], est.mean_in_radiance()[o(c)], "{kind:?} c {c}");
        }
        // Its neighbours stay within 3 standard errors of 1 * colour.
        for y in oy - 2..=oy + 2 {
            for x in ox - 2..=ox + 2 {
                for k in 0..t {
                    if (y, x, k) == (oy, ox, ok) {
                        continue;
                    }
                    for (c, colour) in [1.0, 0.5, 2.0].into_iter().enumerate() {
                        let se = 0.1 * colour / (spp as f64).sqrt();
                        let v = out[est.idx(y * w + x, c, k)] as f64;
                        assert!(
                            (v - colour).abs() < 3.0 * se,
                            "{kind:?} ({y},{x},{k}) c {c}: {v}"
                        );
                    }
                }
            }
        }
        // The base filter alone blurs it away (so the check above can fail).
        let blurred = run_filter(
            &est,
            &b.features(),
            &FilterParams {
                membership: Membership::BaseOnly,
                ..p
            },
            Tiling::default(),
        );
        assert!(blurred[o(0)] < 1.2, "{kind:?}: {}", blurred[o(0)]);
    }
}

/// Filtering mirrored inputs (left-right, up-down, time reversal) gives the mirrored
/// output; only the order of the (positive) terms of the sums differs.
#[test]
fn mirrored_inputs_give_mirrored_outputs() {
    let b = random_bundle(10, 13, 14, 16, Transform::Identity, 77);
    let (h, w, t) = (b.h, b.w, b.t);
    let est = b.estimates();
    type Map = Box<dyn Fn(usize, usize, usize) -> (usize, usize, usize)>;
    let maps: [(&str, Map, bool); 3] = [
        (
            "left-right",
            Box::new(move |y, x, k| (y, w - 1 - x, k)),
            true,
        ),
        ("up-down", Box::new(move |y, x, k| (h - 1 - y, x, k)), false),
        ("time", Box::new(move |y, x, k| (y, x, t - 1 - k)), false),
    ];
    for kind in [BaseKind::Jbf, BaseKind::Gaussian] {
        let p = FilterParams {
            radius: 4,
            temporal_radius: 2,
            base: BaseFilter {
                kind,
                sigmas: Sigmas::default(),
            },
            membership: Membership::Published(Welch {
                g2: 4.0,
                alpha: None,
            }),
            zero_border: false,
        };
        let out = run_filter(&est, &b.features(), &p, TILINGS[1]);
        for (name, map, flip) in &maps {
            let m = b.remapped(map, *flip);
            let m_est = m.estimates();
            let m_out = run_filter(&m_est, &m.features(), &p, TILINGS[1]);
            // out mirrored, as f64 for assert_close.
            let mut expected = vec![0.0f64; out.len()];
            for y in 0..h {
                for x in 0..w {
                    for k in 0..t {
                        let (y2, x2, k2) = map(y, x, k);
                        for c in 0..C {
                            expected[m_est.idx(y2 * w + x2, c, k2)] =
                                out[est.idx(y * w + x, c, k)] as f64;
                        }
                    }
                }
            }
            assert_close(&m_out, &expected, 1e-5, &format!("{kind:?} {name}"));
        }
        // A symmetric input (the left half mirrored onto the right) gives a symmetric
        // output.
        let mut s = b.clone();
        for y in 0..h {
            for x in w / 2..w {
                for k in 0..t {
                    let (v, v2) = ((y * w + x) * t + k, (y * w + (w - 1 - x)) * t + k);
                    s.nonzero[v] = b.nonzero[v2];
                    for c in 0..C {
                        s.x1[v * C + c] = b.x1[v2 * C + c];
                        s.x2[v * C + c] = b.x2[v2 * C + c];
                        s.x3[v * C + c] = b.x3[v2 * C + c];
                    }
                }
                for c in 0..3 {
                    s.albedo[(y * w + x) * 3 + c] = b.albedo[(y * w + w - 1 - x) * 3 + c];
                    s.normal[(y * w + x) * 3 + c] = b.normal[(y * w + w - 1 - x) * 3 + c];
                }
            }
        }
        let s_est = s.estimates();
        let so = run_filter(&s_est, &s.features(), &p, Tiling::default());
        for y in 0..h {
            for x in 0..w {
                for k in 0..t {
                    for c in 0..C {
                        let a = so[s_est.idx(y * w + x, c, k)] as f64;
                        let m = so[s_est.idx(y * w + w - 1 - x, c, k)] as f64;
                        let d = (a - m).abs();
                        assert!(
                            d <= 1e-5 * a.abs().max(m.abs()) + ABS_FLOOR,
                            "{kind:?} ({y},{x},{k},{c}): {a} vs {m}"
                        );
                    }
                }
            }
        }
        assert!(so.iter().any(|&v| v != 0.0));
    }
}

// ---- 3. convergence ----------------------------------------------------------------------

/// A moving Gaussian pulse over a dim background on the left half, zero elsewhere.
fn pulse_truth(y: usize, x: usize, k: usize, t: usize) -> f64 {
    let cx = 4.0 + 16.0 * k as f64 / t as f64;
    let cy = 12.0 + 3.0 * (k as f64 * 0.2).sin();
    let r2 = (x as f64 - cx).powi(2) + (y as f64 - cy).powi(2);
    let envelope = (-(k as f64 - 16.0).powi(2) / (2.0 * 10.0 * 10.0)).exp();
    let background = if x < 12 { 0.1 } else { 0.0 };
    2.0 * (-r2 / (2.0 * 3.0 * 3.0)).exp() * envelope + background
}

#[test]
fn output_converges_to_the_truth_as_spp_grows() {
    let (h, w, t) = (24usize, 24usize, 32usize);
    let colour = [1.0, 0.7, 0.4];
    let q = 0.4; // probability that a path deposits in a voxel
    let sigma = 0.6; // log-normal spread of a deposit
    let mut rows = Vec::new();
    for (n, spp) in [8u64, 32, 128, 512].into_iter().enumerate() {
        let mut rng = Rng::new(500 + n as u64);
        let mut b = Bundle::new(h, w, t, spp, Transform::Identity);
        let mut truth = vec![0.0f64; h * w * t * C];
        for y in 0..h {
            for x in 0..w {
                b.set_features(y, x, [0.6; 3], [0.0, 0.0, 1.0]);
                for k in 0..t {
                    let v = pulse_truth(y, x, k, t);
                    for c in 0..C {
                        truth[((y * w + x) * t + k) * C + c] = v * colour[c];
                    }
                    if v < 1e-3 {
                        continue; // nothing arrives
                    }
                    for _ in 0..spp {
                        if rng.uniform() < q {
                            let rgb = colour.map(|c| {
                                c * v / q * (sigma * rng.normal() - 0.5 * sigma * sigma).exp()
                            });
                            b.deposit(y, x, k, rgb);
                        }
                    }
                }
            }
        }
        let d = denoise_sums(&b.view(), &b.features(), &DenoiseParams::default(), &|_| {});
        let denoised = d.volume.as_slice().unwrap();
        let rmse = |a: &mut dyn Iterator<Item = f64>| {
            let (s, n) = a
                .zip(&truth)
                .fold((0.0, 0usize), |(s, n), (a, b)| (s + (a - b).powi(2), n + 1));
            (s / n as f64).sqrt()
        };
        let noisy = rmse(&mut b.x1.iter().map(|&s| s / spp as f64));
        let den = rmse(&mut denoised.iter().map(|&v| v as f64));
        eprintln!(
            "spp {spp:4}: noisy RMSE {noisy:.5}, denoised {den:.5} ({:.3} of noisy)",
            den / noisy
        );
        rows.push((spp, noisy, den));
    }
    let truth_rms = {
        let mut s = 0.0;
        let mut n = 0;
        for y in 0..h {
            for x in 0..w {
                for k in 0..t {
                    for c in colour {
                        s += (pulse_truth(y, x, k, t) * c).powi(2);
                        n += 1;
                    }
                }
            }
        }
        (s / n as f64).sqrt()
    };
    eprintln!("RMS of the truth {truth_rms:.5}");
    for w2 in rows.windows(2) {
        assert!(
            w2[1].2 < 0.6 * w2[0].2,
            "denoised RMSE must fall with spp: {w2:?}"
        );
    }
    for &(spp, noisy, den) in &rows {
        assert!(
            den < 0.95 * noisy,
            "spp {spp}: denoised {den} not below noisy {noisy}"
        );
    }
    let (first, last) = (rows[0].2, rows[rows.len() - 1].2);
    assert!(
        last < 0.2 * first,
        "RMSE at 512 spp {last} vs at 8 spp {first}"
    );
    assert!(
        last < 0.1 * truth_rms,
        "RMSE at 512 spp {last} vs RMS of the truth {truth_rms}"
    );
}

// ---- 4. the critical value for huge spp ---------------------------------------------------

#[test]
fn alpha_threshold_is_finite_and_sane_for_huge_spp() {
    // (1 - 0.005/2) quantile of the standard normal, the limit as spp grows.
    let z = 2.807_033_768_343_811;
    let t = std::time::Instant::now();
    // Student's t with 2 dof has a closed-form quantile: (2p-1) / sqrt(2 p (1-p)).
    let p: f64 = 1.0 - 0.005 / 2.0;
    let t2 = (2.0 * p - 1.0) / (2.0 * p * (1.0 - p)).sqrt();
    let g2 = Threshold::Alpha(0.005).g2(2);
    assert!(
        (g2.sqrt() - t2).abs() < 1e-9 * t2,
        "spp 2: {} vs {t2}",
        g2.sqrt()
    );
    // SPEC 8: alpha = 0.005 at 64 spp gives g = 2.86.
    assert!((Threshold::Alpha(0.005).g2(64).sqrt() - 2.86).abs() < 0.005);
    let mut spps: Vec<u64> = (1..=40).map(|k| 1u64 << k).collect();
    // Around the switch to the asymptotic expansion (2n - 2 = 1e5 degrees of freedom).
    spps.extend([49_999, 50_000, 50_001, 50_002, 50_003]);
    spps.extend([3, 5, 1000, 123_456_789, (1 << 40) - 1]);
    spps.sort();
    let mut last = f64::INFINITY;
    for &spp in &spps {
        let g2 = Threshold::Alpha(0.005).g2(spp);
        assert!(g2.is_finite() && g2 > 0.0, "spp {spp}: {g2}");
        let g = g2.sqrt();
        // Above the normal quantile, and (t - z) ~ (z^3 + z) / (4 dof) for large dof.
        let dof = 2.0 * spp as f64 - 2.0;
        assert!(g >= z, "spp {spp}: {g} < {z}");
        if dof >= 1000.0 {
            let first_order = (z * z * z + z) / (4.0 * dof);
            assert!(
                (g - z - first_order).abs() <= 0.05 * first_order + 1e-12,
                "spp {spp}: g - z = {} vs {first_order}",
                g - z
            );
        }
        // Non-increasing in spp.
        assert!(g2 <= last, "spp {spp}: g^2 {g2} above the previous {last}");
        last = g2;
    }
    assert!((Threshold::Alpha(0.005).g2(1 << 40).sqrt() - z).abs() < 1e-11);
    assert!(
        t.elapsed().as_secs_f64() < 2.0,
        "too slow: {:?}",
        t.elapsed()
    );
}

// ---- 5. end to end ---------------------------------------------------------------------------

#[test]
fn end_to_end_cbox_denoising_beats_the_noisy_render() {
    use tstat::render::{render, PixelSampling, RenderSettings};
    use tstat::scene::{Overrides, Scene};
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cbox.xml");
    let load = |spp| {
        let o = Overrides {
            width: Some(48),
            spp: Some(spp),
            bins: Some(60),
            bin_width_opl: Some(0.1),
            ..Default::default()
        };
        Scene::load(std::path::Path::new(path), &o).unwrap()
    };
    let go = |spp: u32, seed| {
        let scene = load(spp);
        let settings = RenderSettings {
            spp,
            seed,
            transform: Transform::Identity,
            pixel_sampling: PixelSampling::Independent,
            replicates: 0,
            pixel_spp: None,
        };
        render(&scene, &settings, &|_| {})
    };
    const REF_SPP: u32 = 2048;
    let start = std::time::Instant::now();
    let noisy = go(32, 1);
    let reference = go(REF_SPP, 987_654);
    let render_s = start.elapsed().as_secs_f64();
    let (h, w, t) = (noisy.accum.height, noisy.accum.width, noisy.accum.bins);
    assert_eq!((h, w, t), (48, 48, 60));
    let g = GBuffers::from_pixels(h, w, &noisy.gbuffer);
    let view = SumsView {
        height: h,
        width: w,
        bins: t,
        channels: 3,
        bin_width: 0.1,
        spp: 32,
        stratified: false, // rendered with independent positions
        image_rows: h,
        z0: 0.0,
        x1: &noisy.accum.x1,
        x2: &noisy.accum.x2,
        x3: &noisy.accum.x3,
        sum: &noisy.accum.x1,
        nonzero: &noisy.accum.nonzero,
        replicates: None,
        pixel_spp: None,
    };
    let d = denoise_sums(&view, &g.features(), &DenoiseParams::default(), &|_| {});
    let truth: Vec<f64> = reference
        .accum
        .x1
        .iter()
        .map(|s| s / REF_SPP as f64)
        .collect();
    let noisy_mean: Vec<f64> = noisy.accum.x1.iter().map(|s| s / 32.0).collect();
    let denoised: Vec<f64> = d.volume.iter().map(|&v| v as f64).collect();
    // RMSE over all voxels, and over the pixels that do not see a light directly
    // (the reference's emitter fraction is 0).
    let per_pixel = t * C;
    let rmse = |a: &[f64], only_unlit: bool| {
        let (mut s, mut n) = (0.0, 0usize);
        for (k, (x, y)) in a.iter().zip(&truth).enumerate() {
            if only_unlit && reference.gbuffer[k / per_pixel].emitter > 0.0 {
                continue;
            }
            s += (x - y).powi(2);
            n += 1;
        }
        (s / n as f64).sqrt()
    };
    let (noisy_rmse, den_rmse) = (rmse(&noisy_mean, false), rmse(&denoised, false));
    let (noisy_unlit, den_unlit) = (rmse(&noisy_mean, true), rmse(&denoised, true));
    let nonzero = truth.iter().filter(|&&v| v > 0.0).count() as f64 / truth.len() as f64;
    eprintln!(
        "cbox 48x48x60 (bins of 0.1 OPL from 3.5), 32 spp vs a {REF_SPP}-spp reference: \
         noisy RMSE {noisy_rmse:.6}, denoised RMSE {den_rmse:.6} ({:.3} of noisy); without \
         directly seen lights: noisy {noisy_unlit:.6}, denoised {den_unlit:.6} ({:.3}); \
         {:.0}% of reference voxels non-zero; renders {render_s:.1} s, denoise {:.2} s",
        den_rmse / noisy_rmse,
        den_unlit / noisy_unlit,
        100.0 * nonzero,
        d.seconds,
    );
    assert!(
        nonzero > 0.2,
        "the bins should cover the interesting part ({nonzero})"
    );
    assert!(
        den_rmse < noisy_rmse,
        "denoised {den_rmse} vs noisy {noisy_rmse}"
    );
    assert!(
        den_unlit < noisy_unlit,
        "without lights: denoised {den_unlit} vs noisy {noisy_unlit}"
    );
}

// ---- 6. slabs: bounded memory, the same bits ---------------------------------------------

/// Writes `b` as a bundle directory `dir` (what the renderer would have written).
fn write_bundle(
    b: &Bundle,
    dir: &std::path::Path,
    sampling: SamplingRecord,
) -> tstat::bundle::Bundle {
    use ndarray::{Array2, Array3, Array4};
    use ndarray_npy::write_npy;
    std::fs::create_dir_all(dir).unwrap();
    let (h, w, t) = (b.h, b.w, b.t);
    let mut arrays = Vec::new();
    let mut put = |name: &str, dtype: &str, shape: Vec<usize>| {
        arrays.push(tstat::bundle::manifest::ArrayInfo {
            name: name.into(),
            file: format!("{name}.npy"),
            dtype: dtype.into(),
            shape,
        });
        dir.join(format!("{name}.npy"))
    };
    let v4 = |v: &[f64]| Array4::from_shape_vec((h, w, t, C), v.to_vec()).unwrap();
    write_npy(put("x1", "<f8", vec![h, w, t, C]), &v4(&b.x1)).unwrap();
    write_npy(put("x2", "<f8", vec![h, w, t, C]), &v4(&b.x2)).unwrap();
    write_npy(put("x3", "<f8", vec![h, w, t, C]), &v4(&b.x3)).unwrap();
    if !b.transform.is_identity() {
        write_npy(put("sum", "<f8", vec![h, w, t, C]), &v4(&b.sum)).unwrap();
    }
    let nz = Array3::from_shape_vec((h, w, t), b.nonzero.clone()).unwrap();
    write_npy(put("nonzero", "<u4", vec![h, w, t]), &nz).unwrap();
    let px3 = |v: &[f32]| Array3::from_shape_vec((h, w, 3), v.to_vec()).unwrap();
    write_npy(put("albedo", "<f4", vec![h, w, 3]), &px3(&b.albedo)).unwrap();
    write_npy(put("normal", "<f4", vec![h, w, 3]), &px3(&b.normal)).unwrap();
    let px = |v: &[f32]| Array2::from_shape_vec((h, w), v.to_vec()).unwrap();
    write_npy(put("depth", "<f4", vec![h, w]), &px(&b.depth)).unwrap();
    write_npy(put("emitter", "<f4", vec![h, w]), &px(&b.emitter)).unwrap();
    let steady = Array3::from_shape_fn((h, w, C), |(y, x, c)| {
        (0..t)
            .map(|k| b.sum[((y * w + x) * t + k) * C + c])
            .sum::<f64>()
            / b.spp as f64
    });
    write_npy(put("steady", "<f8", vec![h, w, C]), &steady).unwrap();
    let c = 299_792_458.0;
    let m = Manifest {
        format: "tstats".into(),
        version: 1,
        width: w,
        height: h,
        bins: t,
        channels: vec!["R".into(), "G".into(), "B".into()],
        mode: Default::default(),
        spp: b.spp,
        start_opl: 2.0,
        bin_width_opl: b.bin_width,
        unit_m: 1.0,
        start_seconds: 2.0 / c,
        bin_width_seconds: b.bin_width / c,
        transform: b.transform,
        time_origin: tstat::bundle::manifest::TimeOrigin::Pinhole,
        near_clip: None,
        pixel_sampling: sampling,
        replicates: None,
        media: false,
        seed: 1,
        merged_seeds: Vec::new(),
        shard: None,
        nlos: None,
        adaptive: None,
        scene: SceneRef {
            path: "synthetic".into(),
            sha256: "0".repeat(64),
            identity: None,
        },
        max_depth: -1,
        time_filter_stddev_bins: None,
        render_seconds: 0.0,
        dropped_nonfinite: 0,
        program: Program {
            name: "tstat".into(),
            version: "test".into(),
        },
        arrays,
    };
    std::fs::write(
        dir.join("manifest.json"),
        serde_json::to_string(&m).unwrap(),
    )
    .unwrap();
    tstat::bundle::Bundle::open(dir).unwrap()
}

/// A random bundle with what reaches across rows in tstat: a patch of pixels that see
/// a light (fractions 1 or partial), and camera depths that shift neighbours' bins.
fn random_bundle_with_lights(
    h: usize,
    w: usize,
    t: usize,
    transform: Transform,
    seed: u64,
) -> Bundle {
    let mut b = random_bundle(h, w, t, 16, transform, seed);
    b.bin_width = 0.1;
    let mut rng = Rng::new(seed + 1000);
    for y in 0..h {
        for x in 0..w {
            let p = y * w + x;
            if b.albedo[p * 3] == 0.0 {
                continue; // sees nothing
            }
            b.depth[p] = (2.0 + 0.05 * x as f64 + 0.1 * rng.uniform()) as f32;
            if (h / 3..h / 3 + 4).contains(&y) && (2..w / 2).contains(&x) {
                b.emitter[p] = if rng.uniform() < 0.6 {
                    1.0
                } else {
                    0.25 + 0.5 * rng.uniform() as f32
                };
            }
        }
    }
    b
}

fn methods() -> Vec<DenoiseParams> {
    let d = DenoiseParams::default();
    let mut v = vec![d];
    for method in [Method::Published(Threshold::Auto), Method::BaseOnly] {
        v.push(DenoiseParams {
            radius: method.default_radius(),
            method,
            ..d
        });
    }
    v
}

fn bits32(v: &[f32]) -> Vec<u32> {
    v.iter().map(|x| x.to_bits()).collect()
}

/// Every slab height (1, r, heights that do not divide H, H and more), chunk size and
/// thread count gives the whole-volume denoiser's output bit for bit, on disk and in
/// memory, for tstat (its halo is the emitter radius 4r on independent bundles, r on
/// stratified ones), the published test and the base filter.
#[test]
fn slabs_give_the_whole_volume_output_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let (h, w, t) = (29, 13, 17);
    let cases = [
        (
            "identity-independent",
            Transform::Identity,
            SamplingRecord::Independent,
        ),
        (
            "identity-stratified",
            Transform::Identity,
            SamplingRecord::Stratified,
        ),
        (
            "boxcox-independent",
            Transform::BoxCox { lambda: 0.5 },
            SamplingRecord::Independent,
        ),
    ];
    let mut runs = 0;
    for (k, (name, transform, sampling)) in cases.into_iter().enumerate() {
        let synthetic = random_bundle_with_lights(h, w, t, transform, 40 + k as u64);
        let bundle = write_bundle(
            &synthetic,
            &dir.path().join(format!("{name}.tstats")),
            sampling,
        );
        let loaded = LoadedSums::read(&bundle).unwrap();
        for params in methods() {
            let whole = loaded.denoise(&params, &|_| {});
            let want = bits32(whole.volume.as_slice().unwrap());
            assert!(whole.volume.iter().any(|&v| v != 0.0));
            let halo = slab::halo(&bundle, &params).unwrap();
            let expected_halo = match (params.method, sampling) {
                (Method::Tstat(_), SamplingRecord::Independent) => 4 * params.radius,
                _ => params.radius,
            };
            assert_eq!(halo, expected_halo, "{name} {}", params.method.name());
            let r = params.radius;
            for rows in [1, r, 4, 7, h - 1, h, h + 5] {
                for chunk in [1, 100] {
                    for threads in [1, 3] {
                        let plan = SlabPlan { rows, halo, chunk };
                        let what =
                            format!("{name} {} {plan:?} {threads} threads", params.method.name());
                        let pool = rayon::ThreadPoolBuilder::new()
                            .num_threads(threads)
                            .build()
                            .unwrap();
                        let out = dir.path().join("out.npy");
                        let stats = pool
                            .install(|| {
                                denoise_bundle_to_npy(&bundle, &params, &plan, &out, &out, &|_| {})
                            })
                            .unwrap();
                        assert_eq!(stats.slabs, h.div_ceil(rows), "{what}");
                        assert_eq!(stats.evaluations, whole.evaluations, "{what}");
                        let got: ndarray::Array4<f32> = ndarray_npy::read_npy(&out).unwrap();
                        assert_eq!(got.shape(), whole.volume.shape());
                        assert!(bits32(got.as_slice().unwrap()) == want, "{what}");
                        runs += 1;
                    }
                }
            }
            // In memory (what `tstat run` uses), and the file's bytes are write_npy's.
            let mem = tstat::denoise::denoise_bundle(&bundle, &params, &|_| {}).unwrap();
            assert!(
                bits32(mem.volume.as_slice().unwrap()) == want,
                "{name} in memory"
            );
            let reference = dir.path().join("ref.npy");
            ndarray_npy::write_npy(&reference, &whole.volume).unwrap();
            assert_eq!(
                std::fs::read(&reference).unwrap(),
                std::fs::read(dir.path().join("out.npy")).unwrap()
            );
        }
    }
    eprintln!("{runs} slabbed runs, all bit-identical");
}

/// A plan shorter than the filter's reach is a programming error caught before any
/// output is made up from missing rows.
#[test]
#[should_panic(expected = "halo")]
fn a_plan_without_the_filters_halo_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let b = random_bundle_with_lights(12, 6, 5, Transform::Identity, 3);
    let bundle = write_bundle(&b, dir.path(), SamplingRecord::Independent);
    let plan = SlabPlan {
        rows: 4,
        halo: 2,
        chunk: 1,
    };
    let _ = denoise_slabs(
        &bundle,
        &DenoiseParams::default(),
        &plan,
        &mut |_, _| Ok(()),
        &|_| {},
    );
}

/// A bad value in any slab ends the run with the message of a whole read: the file and
/// the voxel by its place in the whole volume, whichever slab (or halo) meets it.
#[test]
fn bad_values_in_a_slab_are_the_same_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let (h, w, t) = (23, 7, 9);
    let b = random_bundle_with_lights(h, w, t, Transform::Identity, 8);
    // A voxel with samples, in a row in the middle of the image.
    let (y, x, k) = (
        14usize,
        3usize,
        (0..t)
            .find(|&k| b.nonzero[(14 * w + 3) * t + k] > 0)
            .unwrap(),
    );
    let empty = (0..h * w * t)
        .find(|&v| b.nonzero[v] == 0 && v / (w * t) > 10)
        .unwrap();
    let (ey, ex, ek) = (empty / (w * t), empty / t % w, empty % t);
    type Poke = Box<dyn Fn(&mut Bundle)>;
    let cases: Vec<(Poke, String)> = vec![
        (
            Box::new(move |b: &mut Bundle| b.x2[((y * w + x) * t + k) * C + 1] = f64::NAN),
            format!("x2.npy: invalid bundle: voxel (y {y}, x {x}, t {k}, c 1) is NaN"),
        ),
        (
            Box::new(move |b: &mut Bundle| b.nonzero[(y * w + x) * t + k] = 17),
            format!("nonzero.npy: invalid bundle: voxel (y {y}, x {x}, t {k}) counts 17 samples, more than spp = 16"),
        ),
        (
            Box::new(move |b: &mut Bundle| b.x3[((ey * w + ex) * t + ek) * C] = 0.5),
            format!("x3.npy: invalid bundle: voxel (y {ey}, x {ex}, t {ek}, c 0) is 0.5 where nonzero.npy counts no samples (a sum without samples)"),
        ),
        (
            Box::new(move |b: &mut Bundle| b.x1[((y * w + x) * t + k) * C + 2] = -1.0),
            format!("x1.npy: invalid bundle: voxel (y {y}, x {x}, t {k}, c 2) is -1, but radiance is never negative"),
        ),
    ];
    for (n, (poke, want)) in cases.iter().enumerate() {
        let mut bad = b.clone();
        poke(&mut bad);
        let bundle = write_bundle(
            &bad,
            &dir.path().join(format!("bad{n}.tstats")),
            SamplingRecord::Independent,
        );
        let whole = LoadedSums::read(&bundle).err().unwrap().to_string();
        assert!(
            whole.ends_with(want.as_str()),
            "whole: {whole:?} vs {want:?}"
        );
        let params = DenoiseParams::default();
        let halo = slab::halo(&bundle, &params).unwrap();
        for rows in [1, 4, 14, 15, h] {
            let plan = SlabPlan {
                rows,
                halo,
                chunk: 2,
            };
            let out = dir.path().join("out.npy");
            let e = denoise_bundle_to_npy(&bundle, &params, &plan, &out, &out, &|_| {})
                .err()
                .unwrap()
                .to_string();
            assert_eq!(e, whole, "{rows} rows a slab");
        }
    }
}

/// The plan: the tallest slabs that fit the budget, one slab when all fits, and a
/// footprint that follows the documented formula.
#[test]
fn slab_plans_fit_their_budget() {
    let d = Dims {
        height: 512,
        width: 512,
        bins: 1000,
        channels: 3,
        sum_arrays: 3,
    };
    let v = 512u64 * 1000 * 3;
    let plan = SlabPlan::for_budget(d, 3, 1_000_000_000);
    assert!(plan.bytes(d) <= 1_000_000_000);
    assert!(
        SlabPlan {
            rows: plan.rows + 1,
            ..plan
        }
        .bytes(d)
            > 1_000_000_000
    );
    assert!(plan.rows > 16 && plan.rows < 64, "{plan:?}");
    assert_eq!(plan.halo, 3);
    let held = (plan.rows + 6) as u64;
    assert_eq!(
        plan.bytes(d),
        32 * 512 * 512
            + 12 * v * held
            + 16 * 512 * held
            + 4 * v * plan.rows as u64
            + 4 * v
            + plan.chunk as u64 * (8 * v * 3 + 4 * 512 * 1000)
            + 8 * (3 << 15)
    );
    let whole = SlabPlan::for_budget(d, 3, u64::MAX);
    assert_eq!((whole.rows, whole.slabs(d)), (512, 1));
    // Too small a budget still plans one row; its footprint tells the caller it does
    // not fit.
    let tiny = SlabPlan::for_budget(d, 3, 1000);
    assert_eq!(tiny.rows, 1);
    assert!(tiny.bytes(d) > 1000);
    assert_eq!(tiny.slabs(d), 512);
}

/// The same on real renders of the Cornell box (its light seen directly), stratified
/// and independent: slabbed output is the whole-volume output, bit for bit.
#[test]
fn slabs_give_the_whole_volume_output_on_real_renders() {
    let dir = tempfile::tempdir().unwrap();
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cbox.xml");
    for sampling in ["independent", "stratified"] {
        let path = dir.path().join(format!("{sampling}.tstats"));
        let r = std::process::Command::new(env!("CARGO_BIN_EXE_tstat"))
            .args([
                "render", scene, "--width", "24", "--height", "21", "--bins", "40",
            ])
            .args([
                "--bin-width-opl",
                "0.1",
                "--spp",
                "8",
                "--pixel-sampling",
                sampling,
            ])
            .arg("--out")
            .arg(&path)
            .output()
            .unwrap();
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        let bundle = tstat::bundle::Bundle::open(&path).unwrap();
        assert!(bundle.emitter().unwrap().iter().any(|&f| f > 0.0));
        let loaded = LoadedSums::read(&bundle).unwrap();
        for params in methods() {
            let whole = loaded.denoise(&params, &|_| {});
            let want = bits32(whole.volume.as_slice().unwrap());
            let halo = slab::halo(&bundle, &params).unwrap();
            for rows in [1, params.radius, 5, 21] {
                let plan = SlabPlan {
                    rows,
                    halo,
                    chunk: 2,
                };
                let out = dir.path().join("out.npy");
                denoise_bundle_to_npy(&bundle, &params, &plan, &out, &out, &|_| {}).unwrap();
                let got: ndarray::Array4<f32> = ndarray_npy::read_npy(&out).unwrap();
                assert!(
                    bits32(got.as_slice().unwrap()) == want,
                    "{sampling} {} {plan:?}",
                    params.method.name()
                );
            }
        }
    }
}

/// `--method published` with the official call's flags (docs/denoiser.md, "The
/// published code's call") reproduces the published method's own code (`StatDenoiser`,
/// run with torch on the same bundle's statistics by
/// `scripts/make_published_fixture.py`) to f32 rounding, for the example notebook's
/// call (r 10, r_t 1, alpha 0.1: a window wider than the 12 x 12 film, so the zero
/// borders weigh in everywhere) and for r 2, r_t 2, alpha 0.05. Either convention left
/// at tstat's default misses by at least 10x the tolerance: the unbiased variance in both
/// calls (2.6e-2 at r 10, 5.4e-2 at r 2), clipped borders at r 10 (3.5e-4; at r 2 the
/// padded neighbours' weight is negligible, 1.4e-5).
#[test]
fn the_published_call_reproduces_the_official_code() {
    let data =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/published_official");
    let bundle = data.join("bundle.tstats");
    let dir = tempfile::tempdir().unwrap();
    let (h, w, t) = (12.0f64, 12.0f64, 16.0f64);
    for (r, rt, alpha) in [(10u32, 1u32, "0.1"), (2, 2, "0.05")] {
        let want: ndarray::Array4<f32> =
            ndarray_npy::read_npy(data.join(format!("official_r{r}_rt{rt}_a{alpha}.npy"))).unwrap();
        let (rf, rtf) = (f64::from(r), f64::from(rt));
        // The code's guidance: positions spaced size / (r (size - 1)) apart, weighted
        // by 0.3; albedo by 50, normals by 10 (exp(-0.5 sum sigma_inv d^2)).
        let sigma_xy = rf * (w - 1.0) / (w * 0.3f64.sqrt());
        assert_eq!(h, w, "square film: x and y spaced alike");
        let sigma_t = rtf * (t - 1.0) / (t * 0.3f64.sqrt());
        let run = |extra: &[&str]| -> f64 {
            let out = dir.path().join("d.npy");
            let mut args: Vec<String> = [
                "denoise",
                bundle.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
                "--force",
                "--method",
                "published",
                "--alpha",
                alpha,
            ]
            .iter()
            .map(|s| s.to_string())
            .collect();
            args.extend([
                "--radius".into(),
                r.to_string(),
                "--temporal-radius".into(),
                rt.to_string(),
                "--sigma-xy".into(),
                format!("{sigma_xy:e}"),
                "--sigma-t".into(),
                format!("{sigma_t:e}"),
                "--sigma-albedo".into(),
                format!("{:e}", 1.0 / 50f64.sqrt()),
                "--sigma-normal".into(),
                format!("{:e}", 1.0 / 10f64.sqrt()),
            ]);
            args.extend(extra.iter().map(|s| s.to_string()));
            let o = std::process::Command::new(env!("CARGO_BIN_EXE_tstat"))
                .args(&args)
                .output()
                .unwrap();
            assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
            let got: ndarray::Array4<f32> = ndarray_npy::read_npy(&out).unwrap();
            assert_eq!(got.shape(), want.shape());
            let (mut d2, mut n2) = (0.0f64, 0.0f64);
            for (&g, &e) in got.iter().zip(want.iter()) {
                d2 += (f64::from(g) - f64::from(e)).powi(2);
                n2 += f64::from(e).powi(2);
            }
            (d2 / n2).sqrt()
        };
        let official = run(&["--variance", "biased", "--border", "zero"]);
        assert!(official < 1e-5, "r {r}: relative L2 {official:e}");
        let unbiased = run(&["--border", "zero"]);
        let clipped = run(&["--variance", "biased"]);
        assert!(
            unbiased > 1e-4,
            "r {r}: the variance matters ({unbiased:e})"
        );
        // The padded neighbours weigh in where the window passes the border by far.
        assert!(
            r < 10 || clipped > 1e-4,
            "r {r}: the borders matter ({clipped:e})"
        );
    }
}
