//! `transient_path`: unidirectional path tracing with next-event estimation and MIS
//! (power heuristic), Russian roulette and Mitsuba's `max_depth`, keeping each path's
//! optical path length (OPL) so every contribution lands in its time bin (SPEC 4).

use super::deposits::PathDeposits;
use super::gbuffer::GSample;
use super::sampler::{pick_scattering, slot, PathSampler};
use crate::cpu::{Isa, ISA_AVX2, ISA_AVX512, ISA_BASELINE};
use crate::geometry::accel::offset_origin;
use crate::materials::{Bsdf, BsdfModel, HitGeometry};
use crate::math::frame::Frame;
use crate::math::sampling::power_heuristic;
use crate::math::Rgb;
use crate::scene::Scene;
use crate::sensors::time_filter::{gaussian_shares, TimeFilter};
use crate::textures::TexPoint;
use glam::Vec3;

/// What one path leaves behind besides its deposits.
#[derive(Default)]
pub struct PathTally {
    /// Sum of every finite contribution (in the window or not): the steady image.
    pub steady: [f64; 3],
    /// Contributions dropped because they were NaN or infinite.
    pub dropped_nonfinite: u64,
    /// Rays traced (closest-hit and shadow).
    pub rays: u64,
}

/// Adds a contribution `c` arriving at OPL `opl` to the path's deposits.
#[inline(always)]
pub(super) fn contribute(
    scene: &Scene,
    deposits: &mut PathDeposits,
    tally: &mut PathTally,
    opl: f64,
    c: Rgb,
) {
    if !c.is_finite() {
        tally.dropped_nonfinite += 1;
        return;
    }
    if c == Rgb::ZERO {
        return;
    }
    let c = [c.x as f64, c.y as f64, c.z as f64];
    for (s, v) in tally.steady.iter_mut().zip(c) {
        *s += v;
    }
    match scene.integrator.time_filter {
        TimeFilter::Box => {
            if let Some(bin) = scene.film.bin(opl) {
                deposits.add(bin, c);
            }
        }
        TimeFilter::Gaussian { stddev } => {
            gaussian_shares(&scene.film, stddev, opl, |bin, share| {
                deposits.add(bin, c.map(|v| v * share))
            })
        }
    }
}

/// The end of a shadow ray to a light sample: a point light's position, or a point on
/// an area (or distant) light moved off its surface along its normal, towards the
/// reference point.
#[inline(always)]
pub fn light_target(ls: &crate::lights::LightSample) -> Vec3 {
    if ls.delta {
        ls.p
    } else {
        offset_origin(ls.p, ls.n, -ls.wi)
    }
}

/// The shadow ray of a light sample from the surface point `p` (geometric normal
/// `ng`): both ends are moved off their surfaces, the origin along `ng` and a point on
/// an area light along its normal, each to the side the other end lies on, and the ray
/// runs between the moved ends, stopping a relative 1e-4 short. Aiming the moved
/// origin along the unmoved direction instead met the light's own plane before the
/// end of the ray whenever the light lay more than about 50 degrees from `ng`.
#[inline(always)]
pub fn shadow_ray(p: Vec3, ng: Vec3, ls: &crate::lights::LightSample) -> (Vec3, Vec3, f32) {
    let origin = offset_origin(p, ng, ls.wi);
    let d = light_target(ls) - origin;
    let dist = d.length();
    if dist.is_nan() || dist <= 0.0 {
        return (origin, ls.wi, 0.0);
    }
    (origin, d / dist, dist * (1.0 - 1e-4))
}

/// The material at a hit of a `normalmap`/`bumpmap` material: textures resolved at the
/// hit's uv and every perturbed frame set from the hit's geometry (`frame` is
/// Mitsuba's dp/du shading frame, `wo` the direction back along the ray in it). Out of
/// line: only such materials come here.
#[inline(never)]
pub(super) fn perturbed_at(
    material: &crate::materials::Material,
    shape: &crate::geometry::shape::Shape,
    hit: &crate::geometry::accel::Hit,
    sp: &crate::geometry::shape::SurfacePoint,
    frame: &Frame,
    wo: Vec3,
) -> Bsdf {
    let point = TexPoint::on(shape, hit.face, hit.b1, hit.b2, sp.p);
    let uv = point.uv;
    let mut b = material.at_point(&point);
    b.resolve_frames(&HitGeometry {
        uv,
        shading: *frame,
        dpdu: shape.dpdu(hit.face, hit.b1, hit.b2, sp.p),
        dpdv: shape.dpdv(hit.face, hit.b1, sp.p),
        ng: sp.ng,
        wo,
    });
    b
}

/// A ray from `o` along unit `d` that left the scene: the environment emitter `env`
/// seen along it, MIS-weighted against light sampling unless the last vertex was a
/// delta lobe (camera rays: weight 1, nothing when `hide_emitters`). Its segment counts
/// `eta * 2 max(R, |o - c|)` of OPL, the distance of a light sample of that emitter
/// (`lights::scene_sphere`); a camera segment under `camera_unwarp` counts nothing. A
/// camera path whose first non-delta vertex would be here sees an emitter (G-buffer).
#[inline(never)]
#[allow(clippy::too_many_arguments)]
pub(super) fn escape(
    scene: &Scene,
    env: u32,
    o: Vec3,
    d: Vec3,
    depth: u32,
    opl: f64,
    eta: f32,
    beta: Rgb,
    prev_delta: bool,
    prev_pdf: f32,
    deposits: &mut PathDeposits,
    tally: &mut PathTally,
    g: &mut GSample,
    g_pending: bool,
) {
    let settings = &scene.integrator;
    if depth == 0 && settings.hide_emitters {
        return;
    }
    if g_pending {
        g.emitter = true;
    }
    let select_pdf = 1.0 / scene.emitters.len() as f32;
    let (radiance, light_pdf, dist) = scene.emitters[env as usize].escape(select_pdf, o, d);
    let w = if prev_delta {
        1.0
    } else {
        power_heuristic(prev_pdf, light_pdf)
    };
    let segment = if depth == 0 && settings.camera_unwarp {
        0.0
    } else {
        eta as f64 * dist as f64
    };
    contribute(scene, deposits, tally, opl + segment, beta * radiance * w);
}

/// Traces one camera path from the pinhole along unit direction `d`, with the tracer
/// compiled for the instruction set `cpu::current()` chose (same bits at every level).
#[inline]
pub fn trace_path<S: PathSampler>(
    scene: &Scene,
    d: Vec3,
    rng: &mut S,
    deposits: &mut PathDeposits,
    tally: &mut PathTally,
) -> GSample {
    trace_ray(scene, scene.camera.origin, d, rng, deposits, tally)
}

/// Traces one camera path from `o` (where its OPL starts) along unit direction `d`:
/// the ray `Camera::ray` gives, for every sensor.
#[inline]
pub fn trace_ray<S: PathSampler>(
    scene: &Scene,
    o: Vec3,
    d: Vec3,
    rng: &mut S,
    deposits: &mut PathDeposits,
    tally: &mut PathTally,
) -> GSample {
    match crate::cpu::current() {
        // SAFETY: `cpu::current` returns a level only when the CPU supports it.
        #[cfg(target_arch = "x86_64")]
        Isa::Avx512 => unsafe { trace_path_avx512(scene, o, d, rng, deposits, tally) },
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 => unsafe { trace_path_avx2(scene, o, d, rng, deposits, tally) },
        _ => trace_path_baseline(scene, o, d, rng, deposits, tally),
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512bw,avx512cd")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
fn trace_path_avx512<S: PathSampler>(
    scene: &Scene,
    o: Vec3,
    d: Vec3,
    rng: &mut S,
    deposits: &mut PathDeposits,
    tally: &mut PathTally,
) -> GSample {
    // SAFETY: this wrapper is compiled for (and only called on CPUs with) ISA_AVX512.
    unsafe { trace_path_body::<ISA_AVX512, S>(scene, o, d, rng, deposits, tally) }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
fn trace_path_avx2<S: PathSampler>(
    scene: &Scene,
    o: Vec3,
    d: Vec3,
    rng: &mut S,
    deposits: &mut PathDeposits,
    tally: &mut PathTally,
) -> GSample {
    // SAFETY: this wrapper is compiled for (and only called on CPUs with) ISA_AVX2.
    unsafe { trace_path_body::<ISA_AVX2, S>(scene, o, d, rng, deposits, tally) }
}

fn trace_path_baseline<S: PathSampler>(
    scene: &Scene,
    o: Vec3,
    d: Vec3,
    rng: &mut S,
    deposits: &mut PathDeposits,
    tally: &mut PathTally,
) -> GSample {
    // SAFETY: this wrapper is compiled for (and only called on CPUs with) ISA_BASELINE.
    unsafe { trace_path_body::<ISA_BASELINE, S>(scene, o, d, rng, deposits, tally) }
}

/// The path tracer itself, inlined into one wrapper per instruction set; `ISA` picks
/// the intersection kernels.
///
/// # Safety
/// The CPU must support `ISA`.
#[inline(always)]
unsafe fn trace_path_body<const ISA: u8, S: PathSampler>(
    scene: &Scene,
    o: Vec3,
    d: Vec3,
    rng: &mut S,
    deposits: &mut PathDeposits,
    tally: &mut PathTally,
) -> GSample {
    let settings = &scene.integrator;
    let n_emitters = scene.emitters.len();
    let select_pdf = 1.0 / n_emitters as f32;
    let mut g = GSample::default();
    let mut g_pending = true;

    let mut o = o;
    let mut d = d;
    let mut opl = 0.0f64;
    let mut beta = Rgb::ONE;
    // Product of the relative IORs crossed: the current medium's IOR relative to the
    // camera's. Scales segment lengths into OPL and enters Russian roulette as eta^2.
    let mut eta = 1.0f32;
    let mut prev_delta = true;
    let mut prev_pdf = 1.0f32;
    let mut depth: u32 = 0;
    let max_depth = settings.max_depth;
    if max_depth == 0 {
        // Mitsuba: max_depth = 0 renders nothing, not even directly visible emitters.
        return g;
    }

    loop {
        // Each vertex draws its numbers from its own dimensions (`sampler.rs`).
        rng.next_vertex();
        tally.rays += 1;
        // SAFETY: the caller guarantees ISA.
        let hit = unsafe {
            scene
                .accel
                .intersect_with::<ISA>(&scene.shapes, o, d, f32::INFINITY)
        };
        let Some(hit) = hit else {
            // Only scenes with an environment emitter take this branch.
            if let Some(env) = scene.environment {
                escape(
                    scene, env, o, d, depth, opl, eta, beta, prev_delta, prev_pdf, deposits, tally,
                    &mut g, g_pending,
                );
            }
            break;
        };
        let segment = if depth == 0 && settings.camera_unwarp {
            0.0
        } else {
            eta as f64 * hit.t as f64
        };
        opl += segment;
        if depth == 0 {
            g.depth = Some(hit.t);
        }
        let shape = &scene.shapes[hit.shape as usize];
        let sp = hit.surface;
        let wo_world = -d;
        let material = &scene.bsdfs[shape.bsdf as usize];
        // Anisotropic roughness follows the surface's dp/du (Mitsuba's shading frame);
        // every other material keeps the normal's own frame (same bits, no uv work).
        let frame = if material.is_anisotropic() {
            Frame::from_normal_tangent(sp.ns, shape.dpdu(hit.face, hit.b1, hit.b2, sp.p))
        } else {
            Frame::from_normal(sp.ns)
        };
        let wo = frame.to_local(wo_world);
        // A textured material becomes a plain BSDF at this hit's uv (computed only then).
        // The material at this hit: `whole` (textures resolved) for the G-buffer,
        // `bsdf` the model that scatters (a `Composed` vertex scatters as one child,
        // the first with probability w, so each child's delay stays with its own
        // light), `delaying` its profile when it delays (`materials/composed.rs`).
        let textured;
        let (whole, bsdf, delaying) = if material.is_plain() {
            (&material.bsdf, &material.bsdf, None)
        } else {
            let whole = if material.perturbs() {
                textured = perturbed_at(material, shape, &hit, &sp, &frame, wo);
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

        // Emission (front side only; an angular light only within its cone),
        // MIS-weighted against light sampling.
        let mut seen_emitter = false;
        if let Some(ei) = shape.emitter {
            let cos_l = wo.z;
            let emitter = &scene.emitters[ei as usize];
            let radiance = if cos_l > 0.0 {
                emitter.emitted(cos_l, || shape.uv(hit.face, hit.b1, hit.b2, sp.p))
            } else {
                None
            };
            if let Some(radiance) = radiance {
                seen_emitter = true;
                if !(depth == 0 && settings.hide_emitters) {
                    let w = if prev_delta {
                        1.0
                    } else {
                        power_heuristic(prev_pdf, emitter.pdf_area_hit(select_pdf, hit.t, cos_l))
                    };
                    contribute(scene, deposits, tally, opl, beta * radiance * w);
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
        if g_pending && ((!guide_delta && !whole.guide_looks_through()) || seen_emitter) {
            g_pending = false;
            g.albedo = whole.albedo(wo);
            g.normal = if sp.ns.dot(wo_world) >= 0.0 {
                sp.ns
            } else {
                -sp.ns
            };
            g.emitter = seen_emitter;
        }

        // Mitsuba: the next segment exists only if depth + 1 < max_depth.
        if max_depth >= 0 && depth as i64 + 1 >= max_depth as i64 {
            break;
        }

        // Next-event estimation.
        if !delta {
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
                    tally.rays += 1;
                    // SAFETY: the caller guarantees ISA.
                    let blocked = tmax > 0.0
                        && unsafe { scene.accel.occluded_with::<ISA>(origin, dir, tmax) };
                    if tmax > 0.0 && !blocked {
                        let w = if ls.delta {
                            1.0
                        } else {
                            power_heuristic(ls.pdf, bsdf_pdf)
                        };
                        let delay =
                            delaying.map_or(0.0, |s| s.sample_delay(rng.get1(slot::NEE_DELAY)));
                        // The segment lies in the medium on the light's side: through
                        // rough glass that is the current IOR times the one crossed
                        // (the same f32 product a BSDF-sampled path would carry).
                        let eta_light = eta * bsdf.eta(wo, wi);
                        let arrival = opl + delay as f64 + eta_light as f64 * ls.dist as f64;
                        contribute(
                            scene,
                            deposits,
                            tally,
                            arrival,
                            beta * f * ls.li * (w / ls.pdf),
                        );
                    }
                }
            }
        }

        // BSDF sampling.
        let u1 = rng.get1(slot::BSDF_1);
        let u2 = rng.get2(slot::BSDF_2);
        let Some(bs) = bsdf.sample(wo, u1, u2) else {
            break;
        };
        let wi_world = frame.to_world(bs.wi);
        if let Some(s) = delaying {
            opl += s.sample_delay(rng.get1(slot::BSDF_DELAY)) as f64;
        }
        beta *= bs.weight;
        eta *= bs.eta;
        prev_delta = bs.lobe.is_delta();
        prev_pdf = bs.pdf;
        o = offset_origin(sp.p, sp.ng, wi_world);
        d = wi_world.normalize();
        depth += 1;

        // Russian roulette (Mitsuba: from rr_depth on, survival min(max(beta) eta^2, 0.95)).
        let beta_max = beta.max_element();
        let u_rr = rng.get1(slot::RR);
        if depth >= settings.rr_depth {
            let q = (beta_max * eta * eta).min(0.95);
            if u_rr >= q {
                break;
            }
            beta /= q;
        }
        if beta_max.is_nan() || beta_max <= 0.0 {
            break;
        }
    }
    g
}
