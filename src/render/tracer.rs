//! The path loop: `transient_path` (surfaces) and `transient_prbvolpath` (surfaces and
//! participating media, SPEC 7) in one loop that advances a batch of paths together.
//!
//! # The loop
//! A batch holds up to [`LANES`] camera paths (consecutive samples of one pixel), each
//! with its own sampler, deposits and counts. Every iteration advances each live path
//! by one vertex in four stages, each a pass over the live paths:
//!
//! 1. *start* (media rules only): the vertex's dimensions, Russian roulette and the
//!    `max_depth` test, before the ray (Mitsuba's `volpath` order);
//! 2. *closest hits* of every live path's ray, one after the other through the same
//!    intersection kernels (the kernels and the scene's data stay hot);
//! 3. *shade*: in a medium, a free flight and possibly a real scattering (next-event
//!    estimation with the phase function, phase sampling); at a surface, emission
//!    (MIS-weighted), the G-buffer's first vertex, next-event estimation and BSDF
//!    sampling, then Russian roulette (Mitsuba's `path` order). One block of code per
//!    step for both rule sets; the const parameter `MEDIA` selects where they differ:
//!    - Russian roulette: `path` after BSDF sampling from `depth >= rr_depth`,
//!      `volpath` at the top from `depth > rr_depth`;
//!    - `max_depth`: `path` stops before next-event estimation at the last vertex,
//!      `volpath` skips next-event estimation there and stops at the next top;
//!    - `null` surfaces and `thindielectric` transmission are no vertex under `volpath`
//!      (`volpath.rs`), shadow rays cross them with media transmittance, and the
//!      emission MIS distance runs from the last real scattering;
//!    - `camera_unwarp`: `path` counts no first segment, `volpath` starts the OPL at
//!      minus the distance to the first non-null surface (mitransient's rules);
//! 4. *shadow rays* of the surface rule's next-event estimates, one batch: a path's
//!    estimate is complete (value and arrival) when it is queued, so the occlusion
//!    test is all that is left; it is added before the path's next vertex, in the order
//!    a lone path adds it. Paths whose estimate draws a number after the test (a
//!    delaying material's `NEE_DELAY`) and paths in media (ratio tracking draws from the
//!    path's stream) test their shadow rays in stage 3 instead, so every path draws
//!    exactly the numbers, in exactly the order, of a path traced alone.
//!
//! Paths that end leave the live list (kept compact, in sample order); the batch ends
//! when the list is empty. Scenes without media run the loop with `MEDIA = false`: none
//! of the media code is compiled into it.
//!
//! # Bits
//! Each path computes exactly what it computes traced alone (`integrator::trace_ray`
//! is a batch of one): the same operations on the same numbers. Its steady-image
//! contributions are logged ([`LaneTally`]) and summed into the pixel in sample order
//! by the caller, as are its deposits, so a render is bit-identical whatever the batch
//! size or thread count.

use super::deposits::PathDeposits;
use super::gbuffer::GSample;
use super::integrator::{contribute, escape, perturbed_at, shadow_ray, LaneTally, Tally};
use super::sampler::{pick_scattering, slot, PathSampler};
use super::volpath::{
    first_surface, free_flight, medium_shadow_ray, null_event, transmittance, Flight, Spectral,
    MAX_NULL_CROSSINGS,
};
use crate::cpu::{Isa, ISA_AVX2, ISA_AVX512, ISA_BASELINE};
use crate::geometry::accel::{offset_origin, Hit};
use crate::materials::{Bsdf, BsdfModel};
use crate::math::frame::Frame;
use crate::math::sampling::power_heuristic;
use crate::math::Rgb;
use crate::scene::Scene;
use crate::textures::TexPoint;
use glam::Vec3;

/// The most paths one batch advances together.
pub const LANES: usize = 16;

/// What one path of a batch leaves behind.
#[derive(Default)]
pub struct PathRecord {
    pub deposits: PathDeposits,
    pub tally: LaneTally,
    pub g: GSample,
}

/// A batch's working lists, reused from batch to batch.
#[derive(Default)]
pub struct BatchScratch {
    lanes: Vec<Lane>,
    /// Indices of the live paths, in sample order.
    live: Vec<u32>,
    /// The closest hit of each live path's ray (stage 2), by position in `live`.
    hits: Vec<Option<Hit>>,
    /// Queued shadow rays (stage 4).
    shadows: Vec<Shadow>,
}

/// One path's state between vertices.
struct Lane {
    o: Vec3,
    d: Vec3,
    opl: f64,
    beta: Rgb,
    /// Product of the relative IORs crossed: the current medium's IOR relative to the
    /// camera's. Scales segment lengths into OPL and enters Russian roulette as eta^2.
    eta: f32,
    /// Real scattering vertices so far.
    depth: u32,
    /// The last real vertex was a delta lobe (or there is none yet): emission met next
    /// takes MIS weight 1.
    specular: bool,
    /// The density of the direction sampled at the last real vertex.
    last_pdf: f32,
    g: GSample,
    g_pending: bool,
    alive: bool,
    // Media rules only.
    medium: Option<u32>,
    /// `beta = common * spec.weight()`: `common` holds the BSDF and phase weights and
    /// Russian roulette, `spec` the free flights (spectral MIS, `volpath.rs`).
    common: Rgb,
    spec: Spectral,
    /// Distance along the camera ray before the first real interaction (G-buffer).
    camera_dist: f32,
    last_scatter: Vec3,
    nulls_in_a_row: u32,
}

/// A next-event estimate waiting for its shadow ray.
struct Shadow {
    lane: u32,
    origin: Vec3,
    dir: Vec3,
    tmax: f32,
    arrival: f64,
    c: Rgb,
}

/// `max_depth` as a count (negative: unbounded).
#[inline(always)]
fn max_depth(scene: &Scene) -> u64 {
    let m = scene.integrator.max_depth;
    if m < 0 {
        u64::MAX
    } else {
        m as u64
    }
}

/// Traces the camera rays `rays` (origin, unit direction) together, path `i` with
/// `samplers[i]` into `out[i]` (emptied first), with the kernels of the instruction set
/// `cpu::current()` chose (same bits at every level).
pub fn trace_batch<S: PathSampler>(
    scene: &Scene,
    rays: &[(Vec3, Vec3)],
    samplers: &mut [S],
    out: &mut [PathRecord],
    scratch: &mut BatchScratch,
) {
    assert!(rays.len() == samplers.len() && rays.len() == out.len());
    let media = scene.integrator.volumetric;
    match (crate::cpu::current(), media) {
        // SAFETY: `cpu::current` returns a level only when the CPU supports it.
        #[cfg(target_arch = "x86_64")]
        (Isa::Avx512, false) => unsafe { batch_avx512::<false, S>(scene, rays, samplers, out, scratch) },
        #[cfg(target_arch = "x86_64")]
        (Isa::Avx512, true) => unsafe { batch_avx512::<true, S>(scene, rays, samplers, out, scratch) },
        #[cfg(target_arch = "x86_64")]
        (Isa::Avx2, false) => unsafe { batch_avx2::<false, S>(scene, rays, samplers, out, scratch) },
        #[cfg(target_arch = "x86_64")]
        (Isa::Avx2, true) => unsafe { batch_avx2::<true, S>(scene, rays, samplers, out, scratch) },
        // SAFETY: the baseline runs on every CPU.
        (_, false) => unsafe {
            batch_body::<ISA_BASELINE, false, S>(scene, rays, samplers, out, scratch)
        },
        (_, true) => unsafe {
            batch_body::<ISA_BASELINE, true, S>(scene, rays, samplers, out, scratch)
        },
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512bw,avx512cd")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
fn batch_avx512<const MEDIA: bool, S: PathSampler>(
    scene: &Scene,
    rays: &[(Vec3, Vec3)],
    samplers: &mut [S],
    out: &mut [PathRecord],
    scratch: &mut BatchScratch,
) {
    // SAFETY: this wrapper is compiled for (and only called on CPUs with) ISA_AVX512.
    unsafe { batch_body::<ISA_AVX512, MEDIA, S>(scene, rays, samplers, out, scratch) }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
fn batch_avx2<const MEDIA: bool, S: PathSampler>(
    scene: &Scene,
    rays: &[(Vec3, Vec3)],
    samplers: &mut [S],
    out: &mut [PathRecord],
    scratch: &mut BatchScratch,
) {
    // SAFETY: this wrapper is compiled for (and only called on CPUs with) ISA_AVX2.
    unsafe { batch_body::<ISA_AVX2, MEDIA, S>(scene, rays, samplers, out, scratch) }
}

/// The loop (module docs), inlined into one wrapper per instruction set.
///
/// # Safety
/// The CPU must support `ISA`.
#[inline(always)]
unsafe fn batch_body<const ISA: u8, const MEDIA: bool, S: PathSampler>(
    scene: &Scene,
    rays: &[(Vec3, Vec3)],
    samplers: &mut [S],
    out: &mut [PathRecord],
    scratch: &mut BatchScratch,
) {
    let BatchScratch {
        lanes,
        live,
        hits,
        shadows,
    } = scratch;
    lanes.clear();
    live.clear();
    let settings = &scene.integrator;
    for (i, (&(o, d), rng)) in rays.iter().zip(samplers.iter_mut()).enumerate() {
        out[i].g = GSample::default();
        // SAFETY: the caller guarantees ISA.
        let lane = unsafe { Lane::start::<ISA, MEDIA, S>(scene, o, d, rng) };
        // Mitsuba's `path`: max_depth = 0 renders nothing, not even directly visible
        // emitters (`volpath` stops at its first top).
        if MEDIA || settings.max_depth != 0 {
            live.push(i as u32);
        }
        lanes.push(lane);
    }
    let rr_depth = settings.rr_depth;
    let max_depth = max_depth(scene);

    while !live.is_empty() {
        // 1. Start of a vertex: its dimensions; under the media rules Russian roulette
        //    and the depth test come first.
        for &i in live.iter() {
            let (lane, rng) = (&mut lanes[i as usize], &mut samplers[i as usize]);
            rng.next_vertex();
            if MEDIA {
                let u_rr = rng.get1(slot::RR);
                if lane.depth > rr_depth {
                    let q = (lane.beta.max_element() * lane.eta * lane.eta).min(0.95);
                    if u_rr >= q {
                        lane.alive = false;
                        continue;
                    }
                    lane.common /= q;
                    lane.beta /= q;
                }
                if lane.depth as u64 >= max_depth
                    || lane.beta == Rgb::ZERO
                    || lane.beta.max_element().is_nan()
                {
                    lane.alive = false;
                }
            }
        }
        if MEDIA {
            live.retain(|&i| lanes[i as usize].alive);
        }

        // 2. Closest hits.
        hits.clear();
        for &i in live.iter() {
            let lane = &lanes[i as usize];
            out[i as usize].tally.rays(1);
            // SAFETY: the caller guarantees ISA.
            hits.push(unsafe {
                scene
                    .accel
                    .intersect_with::<ISA>(&scene.shapes, lane.o, lane.d, f32::INFINITY)
            });
        }

        // 3. Shade.
        shadows.clear();
        for (&i, hit) in live.iter().zip(hits.iter()) {
            let k = i as usize;
            // SAFETY: the caller guarantees ISA.
            let alive = unsafe {
                shade::<ISA, MEDIA, S>(
                    scene,
                    &mut lanes[k],
                    hit.as_ref(),
                    &mut samplers[k],
                    &mut out[k],
                    shadows,
                    i,
                )
            };
            lanes[k].alive = alive;
        }

        // 4. Shadow rays.
        for q in shadows.iter() {
            // SAFETY: the caller guarantees ISA.
            let open = q.tmax > 0.0
                && !unsafe { scene.accel.occluded_with::<ISA>(q.origin, q.dir, q.tmax) };
            if open {
                let rec = &mut out[q.lane as usize];
                contribute(scene, &mut rec.deposits, &mut rec.tally, q.arrival, q.c);
            }
        }
        live.retain(|&i| lanes[i as usize].alive);
    }
    for (rec, lane) in out.iter_mut().zip(lanes.iter()) {
        rec.g = lane.g;
    }
}

impl Lane {
    /// A camera path from `o` along unit `d` (the media rules draw the hero channel and,
    /// under `camera_unwarp`, find the first surface).
    ///
    /// # Safety
    /// The CPU must support `ISA`.
    #[inline(always)]
    unsafe fn start<const ISA: u8, const MEDIA: bool, S: PathSampler>(
        scene: &Scene,
        o: Vec3,
        d: Vec3,
        rng: &mut S,
    ) -> Lane {
        let settings = &scene.integrator;
        let (opl, spec) = if MEDIA {
            let opl = if settings.camera_unwarp {
                // SAFETY: the caller guarantees ISA.
                -unsafe { first_surface::<ISA>(scene, o, d) }
            } else {
                0.0f64
            };
            (opl, Spectral::new(rng.get1(slot::CHANNEL)))
        } else {
            (0.0, Spectral::new(0.0))
        };
        Lane {
            o,
            d,
            opl,
            beta: Rgb::ONE,
            eta: 1.0,
            depth: 0,
            // `volpath` with `hide_emitters` weighs even the camera's emitters by MIS
            // (its `depth == 0` test still shows none).
            specular: !MEDIA || !settings.hide_emitters,
            last_pdf: 1.0,
            g: GSample::default(),
            g_pending: true,
            alive: true,
            medium: if MEDIA { scene.camera_medium } else { None },
            common: Rgb::ONE,
            spec,
            camera_dist: 0.0,
            last_scatter: o,
            nulls_in_a_row: 0,
        }
    }
}

/// Stage 3 for one path: `hit` is the closest hit of its ray. Returns whether the path
/// goes on; a queued shadow ray is added even when it does not.
///
/// # Safety
/// The CPU must support `ISA`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
unsafe fn shade<const ISA: u8, const MEDIA: bool, S: PathSampler>(
    scene: &Scene,
    lane: &mut Lane,
    hit: Option<&Hit>,
    rng: &mut S,
    rec: &mut PathRecord,
    shadows: &mut Vec<Shadow>,
    index: u32,
) -> bool {
    let settings = &scene.integrator;
    let n_emitters = scene.emitters.len();
    let select_pdf = 1.0 / n_emitters as f32;
    let max_depth = max_depth(scene);

    // ---- Medium: free flight, and a real scattering before the surface. ----
    if MEDIA {
        if let Some(mi) = lane.medium {
            let m = &scene.media[mi as usize];
            let s_surf = hit.map_or(f32::INFINITY, |h| h.t);
            let flight = free_flight(m, lane.o, lane.d, s_surf, rng, &mut lane.spec);
            lane.beta = lane.common * lane.spec.weight();
            if let Flight::Scatter { t } = flight {
                // SAFETY: the caller guarantees ISA.
                return unsafe { scatter_in_medium::<ISA, S>(scene, lane, mi, t, rng, rec) };
            }
        }
    }

    // ---- Surface. ----
    // A ray that meets nothing leaves the scene: it sees the environment emitter, if
    // any (only scenes with one take this branch).
    let Some(hit) = hit else {
        if let Some(env) = scene.environment {
            escape(
                scene,
                env,
                lane.o,
                lane.d,
                lane.depth,
                lane.opl,
                lane.eta,
                lane.beta,
                lane.depth == 0 || lane.specular,
                lane.last_pdf,
                &mut rec.deposits,
                &mut rec.tally,
                &mut lane.g,
                lane.g_pending,
            );
        }
        return false;
    };
    let depth = lane.depth;
    if MEDIA {
        lane.opl += lane.eta as f64 * hit.t as f64;
    } else {
        let segment = if depth == 0 && settings.camera_unwarp {
            0.0
        } else {
            lane.eta as f64 * hit.t as f64
        };
        lane.opl += segment;
        if depth == 0 {
            lane.g.depth = Some(hit.t);
        }
    }
    let shape = &scene.shapes[hit.shape as usize];
    let sp = hit.surface;
    let wo_world = -lane.d;
    let material = &scene.bsdfs[shape.bsdf as usize];
    // Anisotropic roughness follows the surface's dp/du (Mitsuba's shading frame);
    // every other material keeps the normal's own frame (no uv work).
    let frame = if material.is_anisotropic() {
        Frame::from_normal_tangent(sp.ns, shape.dpdu(hit.face, hit.b1, hit.b2, sp.p))
    } else {
        Frame::from_normal(sp.ns)
    };
    let wo = frame.to_local(wo_world);
    // The material at this hit: `whole` (textures resolved) for the G-buffer, `bsdf`
    // the model that scatters (a `Composed` vertex scatters as one child, the first
    // with probability w, so each child's delay stays with its own light), `delaying`
    // its profile when it delays (`materials/composed.rs`). A textured material
    // becomes a plain BSDF at this hit's uv (computed only then).
    let textured;
    let (whole, bsdf, delaying) = if material.is_plain() {
        (&material.bsdf, &material.bsdf, None)
    } else {
        let whole = if material.perturbs() {
            textured = perturbed_at(material, shape, hit, &sp, &frame, wo);
            &textured
        } else if material.is_textured() {
            textured = material.at_point(&TexPoint::on(shape, hit.face, hit.b1, hit.b2, sp.p));
            &textured
        } else {
            &material.bsdf
        };
        let bsdf = pick_scattering(whole, rng);
        let delaying = match bsdf {
            Bsdf::Separable(s) => Some(s),
            _ => None,
        };
        (whole, bsdf, delaying)
    };
    if MEDIA && depth == 0 && lane.g.depth.is_none() {
        if matches!(bsdf, Bsdf::Null(_)) {
            lane.camera_dist += hit.t;
        } else {
            lane.g.depth = Some(lane.camera_dist + hit.t);
        }
    }

    // Emission (front side only; an angular light only within its cone), MIS-weighted
    // against light sampling from the last real vertex. Under `path` a front-side hit
    // counts as seeing the emitter when it emits (evaluated even when hidden); under
    // `volpath` any front-side hit does.
    let mut seen_emitter = false;
    if let Some(ei) = shape.emitter {
        let cos_l = wo.z;
        let emitter = &scene.emitters[ei as usize];
        let hidden = depth == 0 && settings.hide_emitters;
        if cos_l > 0.0 {
            seen_emitter = MEDIA;
            let radiance = if MEDIA && hidden {
                None
            } else {
                emitter.emitted(cos_l, || shape.uv(hit.face, hit.b1, hit.b2, sp.p))
            };
            if let Some(radiance) = radiance {
                seen_emitter = true;
                if !hidden {
                    let w = if depth == 0 || lane.specular {
                        1.0
                    } else {
                        let dist = if MEDIA {
                            (sp.p - lane.last_scatter).length()
                        } else {
                            hit.t
                        };
                        power_heuristic(
                            lane.last_pdf,
                            emitter.pdf_area_hit(select_pdf, dist, cos_l),
                        )
                    };
                    contribute(
                        scene,
                        &mut rec.deposits,
                        &mut rec.tally,
                        lane.opl,
                        lane.beta * radiance * w,
                    );
                }
            }
        }
    }

    // Next-event estimation and MIS need a lobe with a density; the flags say so.
    let delta = !bsdf.flags(wo).has_non_delta();
    // The G-buffer sees the whole material (a Composed one as its mixture).
    let guide_delta = if std::ptr::eq(whole, bsdf) {
        delta
    } else {
        !whole.flags(wo).has_non_delta()
    };
    if lane.g_pending && ((!guide_delta && !whole.guide_looks_through()) || seen_emitter) {
        lane.g_pending = false;
        lane.g.albedo = whole.albedo(wo);
        lane.g.normal = if sp.ns.dot(wo_world) >= 0.0 {
            sp.ns
        } else {
            -sp.ns
        };
        lane.g.emitter = seen_emitter;
    }

    // Mitsuba's `path`: the next segment exists only if depth + 1 < max_depth.
    if !MEDIA && depth as u64 + 1 >= max_depth {
        return false;
    }

    // Next-event estimation (under the media rules through null interfaces and media).
    if !delta && (!MEDIA || (depth as u64) + 1 < max_depth) {
        let u_sel = rng.get1(slot::LIGHT_SELECT);
        let u1 = rng.get1(slot::LIGHT_1);
        let u2 = rng.get2(slot::LIGHT_2);
        let idx = ((u_sel * n_emitters as f32) as usize).min(n_emitters - 1);
        let emitter = &scene.emitters[idx];
        if let Some(ls) = emitter.sample(&scene.shapes, sp.p, select_pdf, u1, u2) {
            let wi = frame.to_local(ls.wi);
            // The BSDF's density is needed only to weigh a light that has one: then
            // value and density come from one evaluation of the lobes.
            let (f, bsdf_pdf) = if ls.delta {
                (bsdf.eval(wo, wi), 0.0)
            } else {
                bsdf.eval_pdf(wo, wi)
            };
            if f != Rgb::ZERO && ls.pdf > 0.0 {
                let (origin, dir, tmax) = shadow_ray(sp.p, sp.ng, &ls);
                let w = if ls.delta {
                    1.0
                } else {
                    power_heuristic(ls.pdf, bsdf_pdf)
                };
                // The segment lies in the medium on the light's side: through rough
                // glass that is the current IOR times the one crossed (the same f32
                // product a BSDF-sampled path would carry).
                let eta_light = lane.eta * bsdf.eta(wo, wi);
                if MEDIA {
                    let target = origin + dir * tmax;
                    let shadow_medium = if shape.is_medium_transition() {
                        shape.target_medium(ls.wi, sp.ng)
                    } else {
                        lane.medium
                    };
                    // SAFETY: the caller guarantees ISA.
                    let tr = unsafe {
                        transmittance::<ISA, _>(
                            scene,
                            origin,
                            dir,
                            target,
                            0.0,
                            shadow_medium,
                            rng.stream(),
                            &mut rec.tally,
                        )
                    };
                    if tr != Rgb::ZERO {
                        let delay =
                            delaying.map_or(0.0, |s| s.sample_delay(rng.get1(slot::NEE_DELAY)));
                        let arrival =
                            lane.opl + delay as f64 + eta_light as f64 * ls.dist as f64;
                        contribute(
                            scene,
                            &mut rec.deposits,
                            &mut rec.tally,
                            arrival,
                            lane.beta * f * tr * ls.li * (w / ls.pdf),
                        );
                    }
                } else {
                    rec.tally.rays(1);
                    let c = lane.beta * f * ls.li * (w / ls.pdf);
                    if let Some(s) = delaying {
                        // The delay is drawn only when the light is seen: test now.
                        // SAFETY: the caller guarantees ISA.
                        let open = tmax > 0.0
                            && !unsafe { scene.accel.occluded_with::<ISA>(origin, dir, tmax) };
                        if open {
                            let delay = s.sample_delay(rng.get1(slot::NEE_DELAY));
                            let arrival =
                                lane.opl + delay as f64 + eta_light as f64 * ls.dist as f64;
                            contribute(scene, &mut rec.deposits, &mut rec.tally, arrival, c);
                        }
                    } else {
                        let delay = 0.0f32;
                        shadows.push(Shadow {
                            lane: index,
                            origin,
                            dir,
                            tmax,
                            arrival: lane.opl + delay as f64 + eta_light as f64 * ls.dist as f64,
                            c,
                        });
                    }
                }
            }
        }
    }

    // BSDF sampling.
    let u1 = rng.get1(slot::BSDF_1);
    let u2 = rng.get2(slot::BSDF_2);
    let Some(bs) = bsdf.sample(wo, u1, u2) else {
        return false;
    };
    let wi_world = frame.to_world(bs.wi);
    if let Some(s) = delaying {
        lane.opl += s.sample_delay(rng.get1(slot::BSDF_DELAY)) as f64;
    }
    lane.eta *= bs.eta;
    if MEDIA {
        lane.common *= bs.weight;
        lane.beta = lane.common * lane.spec.weight();
        if null_event(bsdf, bs.lobe) {
            lane.nulls_in_a_row += 1;
            if lane.nulls_in_a_row > MAX_NULL_CROSSINGS {
                return false;
            }
        } else {
            lane.depth += 1;
            lane.nulls_in_a_row = 0;
            lane.last_scatter = sp.p;
            lane.last_pdf = bs.pdf;
            lane.specular = bs.lobe.is_delta();
        }
        if shape.is_medium_transition() {
            lane.medium = shape.target_medium(wi_world, sp.ng);
        }
        lane.o = offset_origin(sp.p, sp.ng, wi_world);
        lane.d = wi_world.normalize();
        return true;
    }
    lane.beta *= bs.weight;
    lane.specular = bs.lobe.is_delta();
    lane.last_pdf = bs.pdf;
    lane.o = offset_origin(sp.p, sp.ng, wi_world);
    lane.d = wi_world.normalize();
    lane.depth += 1;

    // Russian roulette (Mitsuba: from rr_depth on, survival min(max(beta) eta^2, 0.95)).
    let beta_max = lane.beta.max_element();
    let u_rr = rng.get1(slot::RR);
    if lane.depth >= settings.rr_depth {
        let q = (beta_max * lane.eta * lane.eta).min(0.95);
        if u_rr >= q {
            return false;
        }
        lane.beta /= q;
    }
    !(beta_max.is_nan() || beta_max <= 0.0)
}

/// A real scattering in the medium `mi` at distance `t` along the path's ray:
/// next-event estimation with the phase function (unless the medium says not to) and
/// a new direction from it (weight 1). Returns whether the path goes on.
///
/// # Safety
/// The CPU must support `ISA`.
#[inline(always)]
unsafe fn scatter_in_medium<const ISA: u8, S: PathSampler>(
    scene: &Scene,
    lane: &mut Lane,
    mi: u32,
    t: f32,
    rng: &mut S,
    rec: &mut PathRecord,
) -> bool {
    let m = &scene.media[mi as usize];
    let n_emitters = scene.emitters.len();
    let select_pdf = 1.0 / n_emitters as f32;
    let p = lane.o + lane.d * t;
    lane.opl += lane.eta as f64 * t as f64;
    if lane.depth == 0 && lane.g.depth.is_none() {
        lane.g.depth = Some(lane.camera_dist + t);
    }
    if lane.g_pending {
        lane.g_pending = false;
        lane.g.albedo = m.albedo_at(p);
        lane.g.medium = true;
    }
    lane.depth += 1;
    lane.nulls_in_a_row = 0;
    lane.last_scatter = p;
    if lane.depth as u64 >= max_depth(scene) {
        return false;
    }
    let wi = -lane.d;
    // Next-event estimation with the phase function.
    if m.sample_emitters() {
        lane.specular = false;
        let u_sel = rng.get1(slot::LIGHT_SELECT);
        let u1 = rng.get1(slot::LIGHT_1);
        let u2 = rng.get2(slot::LIGHT_2);
        let idx = ((u_sel * n_emitters as f32) as usize).min(n_emitters - 1);
        let emitter = &scene.emitters[idx];
        if let Some(ls) = emitter.sample(&scene.shapes, p, select_pdf, u1, u2) {
            let f = m.phase().eval(wi, ls.wi);
            if f > 0.0 && ls.pdf > 0.0 {
                let (dir, target) = medium_shadow_ray(p, &ls);
                // SAFETY: the caller guarantees ISA.
                let tr = unsafe {
                    transmittance::<ISA, _>(
                        scene,
                        p,
                        dir,
                        target,
                        0.0,
                        lane.medium,
                        rng.stream(),
                        &mut rec.tally,
                    )
                };
                if tr != Rgb::ZERO {
                    let w = if ls.delta {
                        1.0
                    } else {
                        power_heuristic(ls.pdf, f)
                    };
                    let arrival = lane.opl + lane.eta as f64 * ls.dist as f64;
                    contribute(
                        scene,
                        &mut rec.deposits,
                        &mut rec.tally,
                        arrival,
                        lane.beta * tr * ls.li * (f * w / ls.pdf),
                    );
                }
            }
        }
    } else {
        lane.specular = true;
    }
    // Phase sampling (weight 1).
    let ps = m.phase().sample(wi, rng.get2(slot::PHASE));
    if ps.pdf.is_nan() || ps.pdf <= 0.0 {
        return false;
    }
    lane.last_pdf = ps.pdf;
    lane.o = p;
    lane.d = ps.wo;
    true
}
