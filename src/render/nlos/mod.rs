//! `transient_nlos_path`: mitransient 1.3.1's NLOS path tracer (`transientnlospath.py`,
//! after [Royo2022] "Non-line-of-sight transient rendering"), transcribed for one path
//! at a time. The scene's setup (lit points, laser, hidden geometry) is
//! `scene/nlos_setup.rs`; what a grid point's paths share is `ends.rs`, hidden-geometry
//! sampling `hidden.rs`.
//!
//! A path starts at the sensor (the capture meter's `sensor_origin`, or a camera) and
//! at each surface vertex x_d (depth d, 0 at the first hit) with a non-delta lobe:
//!
//! - **laser sampling** (`nlos_laser_sampling`): connects x_d to the lit point x_l
//!   (visible from x_d, the surface there facing x_d), with the area-to-solid-angle
//!   density `|x_l - x_d|^2 / cos_l`, then x_l to the laser:
//!   `beta f_d(x_d -> x_l) cos_l / |x_l - x_d|^2 * f_l(x_l -> laser) I / r^2`, of depth
//!   d + 2, at OPL `opl + eta |x_l - x_d|` (plus `eta r` with
//!   `account_first_and_last_bounces`). In confocal and exhaustive captures the laser
//!   is re-aimed at x_l: I is its on-axis intensity;
//! - otherwise **next-event estimation** to the laser from x_d (depth d);
//!
//! then continues by **hidden-geometry sampling** (a uniform point of the hidden
//! geometry, density converted to solid angle; `nlos_hg_sampling`, with its
//! depth limit) or BSDF sampling. With the coin flip between them
//! (`nlos_hg_sampling_do_rroulette`, each with probability 1/2) a sample
//! is weighted by the balance heuristic over both densities, `f / (pdf_hg / 2 +
//! pdf_bsdf / 2)`, the hidden-geometry density of a BSDF-sampled direction taken where
//! its ray first meets the hidden geometry. mitransient 1.3.1 divides each technique's
//! own estimate by 1/2 instead, which counts every path both can reach twice (twice the
//! energy, measured: `tests/it/nlos.rs`); tstat does not copy that. Then
//! Russian roulette from `rr_depth` on (at the vertex's depth, as mitransient).
//! Segments are timed between the vertices themselves (not from the offset origins of
//! the rays, which would shorten each by up to 1e-4 of the scene's scale). The
//! first segment (sensor to wall) counts in the OPL only with
//! `account_first_and_last_bounces`. `filter_depth` and `discard_direct_paths` act on
//! the light-sample contributions' depth. The laser, a delta light, is never hit.

pub mod ends;
pub mod hidden;

use super::deposits::PathDeposits;
use super::gbuffer::GSample;
use super::path_common::{contribute, PathTally};
use super::roulette::roulette;
use super::sampler::{slot, PathSampler};
use super::vertex::SurfaceVertex;
use crate::cpu::{Avx2, Avx512, Baseline, Detected, Level};
use crate::geometry::accel::{offset_origin, Hit};
use crate::geometry::shadow::shadow_segment;
use crate::lights::laser::{laser_light, LaserLight};
use crate::materials::BsdfModel;
use crate::math::Rgb;
use crate::scene::nlos_setup::{CaptureType, NlosSettings, NlosSetup};
use crate::scene::Scene;
use ends::PathEnds;
use glam::Vec3;

/// The probability of hidden-geometry sampling against BSDF sampling with
/// `nlos_hg_sampling_do_rroulette` (mitransient's).
const HG_SHARE: f32 = 0.5;

/// Dr.Jit's `epsilon(Float)`: mitransient's thresholds on cosines, densities and BSDF
/// values.
const EPS: f32 = f32::EPSILON / 2.0;

/// `x > t`, false for NaN (mitransient's masks drop NaN lanes).
#[inline(always)]
fn above(x: f32, t: f32) -> bool {
    x > t
}

/// Traces one NLOS path from `o` along unit `d`; `ends` holds the surface laser
/// sampling aims at and, for a capture meter, the ray's known first hit.
#[inline]
pub fn trace_nlos<S: PathSampler>(
    scene: &Scene,
    o: Vec3,
    d: Vec3,
    ends: PathEnds,
    rng: &mut S,
    deposits: &mut PathDeposits,
    tally: &mut PathTally,
) -> GSample {
    match crate::cpu::detected() {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: the proof says this CPU runs the wrapper's instruction set.
        Detected::Avx512(isa) => unsafe {
            nlos_avx512(isa, scene, o, d, ends, rng, deposits, tally)
        },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as above.
        Detected::Avx2(isa) => unsafe { nlos_avx2(isa, scene, o, d, ends, rng, deposits, tally) },
        _ => body::<Baseline, S>(Baseline, scene, o, d, ends, rng, deposits, tally),
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512bw,avx512cd")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
#[allow(clippy::too_many_arguments)]
fn nlos_avx512<S: PathSampler>(
    isa: Avx512,
    scene: &Scene,
    o: Vec3,
    d: Vec3,
    ends: PathEnds,
    rng: &mut S,
    deposits: &mut PathDeposits,
    tally: &mut PathTally,
) -> GSample {
    body::<Avx512, S>(isa, scene, o, d, ends, rng, deposits, tally)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
#[allow(clippy::too_many_arguments)]
fn nlos_avx2<S: PathSampler>(
    isa: Avx2,
    scene: &Scene,
    o: Vec3,
    d: Vec3,
    ends: PathEnds,
    rng: &mut S,
    deposits: &mut PathDeposits,
    tally: &mut PathTally,
) -> GSample {
    body::<Avx2, S>(isa, scene, o, d, ends, rng, deposits, tally)
}

/// The path's fixed context.
struct NlosPath<'a> {
    scene: &'a Scene,
    n: &'a NlosSettings,
    setup: &'a NlosSetup,
    /// Re-aim the laser at each lit point (confocal and exhaustive laser sampling).
    focus: bool,
}

impl NlosPath<'_> {
    /// Whether something lies between `from` and `to` (the segment's last 1e-4 left
    /// out, as Mitsuba's shadow rays).
    #[inline(always)]
    fn blocked<L: Level>(&self, isa: L, from: Vec3, to: Vec3) -> bool {
        let Some((o, d, tmax)) = shadow_segment(from, to) else {
            return false;
        };
        self.scene.accel.occluded_with(isa, o, d, tmax)
    }

    /// Light-sample contribution from vertex `v` to the laser (mitransient's
    /// `emitter_nee_sample`), of depth `depth`, the path having OPL `opl` at `v`;
    /// `light` is the laser's light at `v` when it is known (a lit point), else it is
    /// found here with a shadow ray.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn laser_nee<L: Level>(
        &self,
        isa: L,
        v: &SurfaceVertex,
        light: Option<Option<LaserLight>>,
        depth: u32,
        beta: Rgb,
        opl: f64,
        eta: f32,
        deposits: &mut PathDeposits,
        tally: &mut PathTally,
    ) {
        let n = self.n;
        if n.filter_depth != -1 && i64::from(depth) != n.filter_depth {
            return;
        }
        if n.discard_direct_paths && depth <= 2 {
            return;
        }
        let scene = self.scene;
        let light = light.unwrap_or_else(|| {
            laser_light(
                &scene.emitters[0],
                self.setup.laser_origin,
                self.setup.laser_axis,
                &scene.shapes,
                v.sp.p,
                v.sp.ng,
                self.focus,
                |o, d, tmax| {
                    tally.rays += 1;
                    scene.accel.occluded_with(isa, o, d, tmax)
                },
            )
        });
        let Some(light) = light else {
            return;
        };
        let f = v.bsdf.eval(v.wo, v.frame.to_local(light.dir));
        if f == Rgb::ZERO {
            return;
        }
        let last = if n.account_first_and_last_bounces {
            eta as f64 * light.dist as f64
        } else {
            0.0
        };
        contribute(scene, deposits, tally, opl + last, beta * f * light.li);
    }

    /// Laser sampling from vertex `v` of depth `depth` through the lit surface `lit`
    /// (mitransient's `emitter_laser_targets_sample`: it tests visibility to the lit
    /// point, then finds the surface there by a second ray; the surface is known, so a
    /// shadow ray does both).
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn laser_sample<L: Level>(
        &self,
        isa: L,
        v: &SurfaceVertex,
        lit: &Hit,
        lit_light: Option<LaserLight>,
        depth: u32,
        beta: Rgb,
        opl: f64,
        eta: f32,
        deposits: &mut PathDeposits,
        tally: &mut PathTally,
    ) {
        let scene = self.scene;
        let target = lit.surface.p;
        let to_target = target - v.sp.p;
        let dist = to_target.length();
        if !above(dist, 0.0) {
            // Also a NaN target: a lit point that does not exist.
            return;
        }
        let dir = to_target / dist;
        let f = v.bsdf.eval(v.wo, v.frame.to_local(dir));
        if !above(f.max_element(), EPS) {
            return;
        }
        // Both ends moved off their surfaces, towards each other, and the ray between
        // them: a ray from the moved origin along `dir` would run beside the segment
        // and meet the lit point's own surface short of it at grazing angles.
        let end = offset_origin(target, lit.surface.ng, -dir);
        tally.rays += 1;
        if self.blocked(isa, offset_origin(v.sp.p, v.sp.ng, dir), end) {
            return;
        }
        let mut textured = None;
        let lit = SurfaceVertex::at(scene, lit, dir, &mut textured);
        let cos_l = lit.wo.z;
        if !above(cos_l, 0.0) {
            return;
        }
        let beta = beta * f * (cos_l / (dist * dist));
        (self.laser_nee(
            isa,
            &lit,
            Some(lit_light),
            depth + 2,
            beta,
            opl + eta as f64 * dist as f64,
            eta,
            deposits,
            tally,
        ));
    }
}

/// The tracer, inlined into one wrapper per instruction set.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn body<L: Level, S: PathSampler>(
    isa: L,
    scene: &Scene,
    o: Vec3,
    d: Vec3,
    ends: PathEnds,
    rng: &mut S,
    deposits: &mut PathDeposits,
    tally: &mut PathTally,
) -> GSample {
    let settings = &scene.integrator;
    let (Some(n), Some(setup)) = (settings.nlos.as_ref(), scene.nlos.as_ref()) else {
        unreachable!("the NLOS tracer runs only on scenes loaded with transient_nlos_path");
    };
    let ctx = NlosPath {
        scene,
        n,
        setup,
        focus: n.laser_sampling && n.capture != CaptureType::Single,
    };
    let mut g = GSample::default();
    let (mut o, mut d) = (o, d);
    // The last vertex (where the current ray left the surface).
    let mut prev = o;
    let mut opl = 0.0f64;
    let mut beta = Rgb::ONE;
    let mut eta = 1.0f32;
    let mut depth: u32 = 0;
    let mut next = ends.first;
    let max_depth = settings.max_depth;
    if max_depth == 0 {
        return g;
    }
    loop {
        rng.next_vertex();
        // A capture meter's first hit is known (the same ray every sample), and so is
        // the hit of a ray traced ahead for its MIS weight.
        let known = next.take();
        let hit = known.unwrap_or_else(|| {
            tally.rays += 1;
            scene
                .accel
                .intersect_with(isa, &scene.shapes, o, d, f32::INFINITY)
        });
        let Some(hit) = hit else {
            break;
        };
        // Segments are timed vertex to vertex, not from the offset ray origins (a
        // ray offset is 1e-4 of the scene's scale, a tenth of a typical NLOS bin).
        if depth == 0 {
            if n.account_first_and_last_bounces {
                opl += eta as f64 * hit.t as f64;
            }
        } else {
            opl += eta as f64 * (hit.surface.p - prev).length() as f64;
        }
        let mut textured = None;
        let v = SurfaceVertex::at(scene, &hit, d, &mut textured);
        if depth == 0 {
            g.depth = Some(hit.t);
            v.record(&mut g);
        }
        if max_depth >= 0 && depth as i64 + 1 >= max_depth as i64 {
            break;
        }
        if v.bsdf.flags(v.wo).has_non_delta() {
            if n.laser_sampling {
                if let (Some(lit), Some(light)) = (&ends.lit, ends.lit_light) {
                    ctx.laser_sample(
                        isa,
                        &v,
                        lit,
                        Some(light),
                        depth,
                        beta,
                        opl,
                        eta,
                        deposits,
                        tally,
                    );
                }
            } else {
                ctx.laser_nee(isa, &v, None, depth, beta, opl, eta, deposits, tally);
            }
        }

        // The continuation: hidden-geometry sampling, BSDF sampling, or (with the coin
        // flip) one of them, each with probability 1/2, weighted by the balance
        // heuristic over both densities (one-sample MIS; see the module notes).
        let hg = setup
            .hidden
            .as_ref()
            .filter(|_| n.hg_max_depth == -1 || (depth as i64) < n.hg_max_depth);
        let c = match hg {
            None => 0.0,
            Some(_) if n.hg_rroulette => HG_SHARE,
            Some(_) => 1.0,
        };
        let use_hg = c == 1.0 || (c > 0.0 && rng.get1(slot::NLOS_STRATEGY) < c);
        let u1 = rng.get1(slot::BSDF_1);
        let u2 = rng.get2(slot::BSDF_2);
        let (wi_world, weight, bs_eta) = if use_hg {
            let hg = hg.expect("c > 0");
            let (p, nh) = hidden::sample(hg, &scene.shapes, u1, u2);
            let to_p = p - v.sp.p;
            let dist = to_p.length();
            let dir = to_p / dist;
            let cos_i = v.sp.ng.dot(dir);
            let cos_g = nh.dot(-dir);
            if !(above(cos_i, EPS) && above(cos_g, EPS)) {
                break;
            }
            let pdf = dist * dist / (hg.total_area * cos_g);
            if !above(pdf, EPS) || !pdf.is_finite() {
                break;
            }
            let wi = v.frame.to_local(dir);
            let (f, density) = if c < 1.0 {
                let (f, bsdf_pdf) = v.bsdf.eval_pdf(v.wo, wi);
                (f, c * pdf + (1.0 - c) * bsdf_pdf)
            } else {
                (v.bsdf.eval(v.wo, wi), pdf)
            };
            (dir, f * (1.0 / density), 1.0)
        } else {
            let Some(bs) = v.bsdf.sample(v.wo, u1, u2) else {
                break;
            };
            let dir = v.frame.to_world(bs.wi).normalize();
            match hg {
                // The hidden-geometry density of this direction: where its ray first
                // meets the hidden geometry, traced now and kept for the next vertex.
                Some(hg) if c > 0.0 && !bs.lobe.is_delta() => {
                    tally.rays += 1;
                    let h = scene.accel.intersect_with(
                        isa,
                        &scene.shapes,
                        offset_origin(v.sp.p, v.sp.ng, dir),
                        dir,
                        f32::INFINITY,
                    );
                    let pdf_hg = h
                        .as_ref()
                        .map_or(0.0, |h| hidden::pdf(hg, v.sp.p, v.sp.ng, h, dir));
                    next = Some(h);
                    let density = c * pdf_hg + (1.0 - c) * bs.pdf;
                    (dir, bs.weight * (bs.pdf / density), bs.eta)
                }
                _ => (dir, bs.weight * (1.0 / (1.0 - c)), bs.eta),
            }
        };
        beta *= weight;
        eta *= bs_eta;
        o = offset_origin(v.sp.p, v.sp.ng, wi_world);
        d = wi_world;
        prev = v.sp.p;

        // Russian roulette (`roulette.rs`) at this vertex's depth, as mitransient.
        let beta_max = beta.max_element();
        if !above(beta_max, 0.0) {
            break;
        }
        let u_rr = rng.get1(slot::RR);
        if depth >= settings.rr_depth {
            let Some(q) = roulette(beta_max, eta, u_rr) else {
                break;
            };
            beta /= q;
        }
        depth += 1;
    }
    g
}
