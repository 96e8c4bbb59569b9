//! `transient_prbvolpath`: volumetric path tracing (SPEC 7) with Mitsuba 3's `volpath`
//! semantics, keeping each path's OPL as `integrator.rs` does.
//!
//! Per iteration of a path: Russian roulette (from `depth > rr_depth`, survival
//! `min(max(beta) eta^2, 0.95)`), the `max_depth` test, one closest-hit ray, then
//! - inside a medium, a free-flight distance `t` from `sigma_t` (below; by delta
//!   tracking in a heterogeneous medium, `media/heterogeneous.rs`); if `t` comes
//!   before the surface, a real scattering: `depth += 1`, next-event estimation with
//!   the phase function (unless the medium sets `sample_emitters = false`), and a new
//!   direction from the phase function (weight 1);
//! - otherwise the surface: emission (MIS-weighted against light sampling from the last
//!   real scattering vertex, unless a specular chain leads there), next-event
//!   estimation at lobes with a density (while `depth + 1 < max_depth`), and BSDF
//!   sampling. A `null` surface is an interface, not a vertex: it neither counts
//!   towards `max_depth` nor changes the MIS state; nor does the transmission of a
//!   `thindielectric`, which Mitsuba 3 flags `Null` too. Any shape with `interior` /
//!   `exterior` switches the current medium to the one the new direction enters.
//!
//! Shadow rays pass through `null` surfaces (changing medium there) and through
//! `thindielectric` ones with its null transmission `(1 - R') specular_transmittance`
//! (Mitsuba's `eval_null_transmission`), and are blocked by every other surface; their
//! transmittance is `exp(-sigma_t s)` per homogeneous medium segment, and a
//! ratio-tracking estimate of it per heterogeneous one.
//!
//! OPL: a segment of length `s` adds `eta * s`, inside media too (media have no index
//! of refraction of their own; `eta` is the product of the relative IORs crossed at
//! dielectric boundaries, as in `integrator.rs`). A null collision adds no time: the
//! OPL of a real scattering at distance `t` is `eta * t` whatever the null collisions
//! before it.
//!
//! Free-flight sampling in RGB (differs from Mitsuba's `volpath`, same expectation):
//! both pick one channel h per path, uniformly, and sample every free flight from
//! `sigma_t,h`. Mitsuba weights channel k by the ratio of its free-flight terms to
//! channel h's densities, a product over the path that is unbounded (and heavy-tailed)
//! when the channels' extinctions differ. Here the path is weighted by the balance
//! heuristic over the three channels' path densities (spectral MIS, as Mitsuba's
//! `volpathmis`): with `f_k` the product of channel k's free-flight terms
//! (`Tr_k(t) sigma_s,k` per scattering, `Tr_k(s)` per surface reached) and `p_c` the
//! product of the densities had channel c been sampled (`sigma_t,c Tr_c(t)`, `Tr_c(s)`),
//! channel k weighs `f_k / mean_c p_c` (at most `3 prod albedo_k`). Both estimators are
//! unbiased for every channel; for a grey medium they are the same. The products are
//! kept relative to `p_h` in f64. A heterogeneous medium folds in its collisions'
//! terms the same way (`(sigma_s, sigma_t)` per real, `(sigma_n, sigma_n)` per null
//! collision, the majorant's exponentials cancelling), so one path may cross media of
//! both kinds. A spatially varying albedo (`homogeneous` with an albedo volume) only
//! changes `sigma_s` at the scattering point.
//!
//! G-buffer: as `integrator.rs`, looking through `null` interfaces; a camera path whose
//! first real interaction is a medium scattering records the medium's albedo there, a zero
//! normal and `medium = true`; depth is the distance to that first interaction.

use super::deposits::PathDeposits;
use super::gbuffer::GSample;
use super::integrator::{contribute, escape, light_target, shadow_ray, PathTally};
use super::sampler::{pick_scattering, slot, PathSampler};
use crate::cpu::ISA_BASELINE;
use crate::geometry::accel::offset_origin;
use crate::geometry::shape::Shape;
use crate::materials::{Bsdf, BsdfModel};
use crate::math::frame::Frame;
use crate::math::sampling::power_heuristic;
use crate::math::Rgb;
use crate::media::{Medium, Tracked};
use crate::scene::Scene;
use crate::textures::TexPoint;
use glam::{DVec3, Vec3};

/// Shadow rays cross at most this many `null` interfaces (then count as blocked), and a
/// path at most this many in a row: a guard against rays stuck on a surface.
const MAX_NULL_CROSSINGS: u32 = 256;

/// Traces one camera path from `o` (where its OPL starts) along unit direction `d` through a scene
/// with participating media.
///
/// The tracer runs with the baseline intersection kernels on every CPU (so its bits
/// do not depend on the instruction set either): instantiating the AVX2 / AVX-512
/// packet kernels here too gave them a second caller, and the compiler then stopped
/// inlining them into the surface tracer (`integrator.rs`), which cost scenes without
/// media 1% more instructions per path (measured with callgrind on `cbox.xml`).
#[inline(never)]
pub fn trace_volpath<S: PathSampler>(
    scene: &Scene,
    o: Vec3,
    d: Vec3,
    rng: &mut S,
    deposits: &mut PathDeposits,
    tally: &mut PathTally,
) -> GSample {
    // SAFETY: the baseline instruction set runs on every CPU.
    unsafe { trace_body::<ISA_BASELINE, S>(scene, o, d, rng, deposits, tally) }
}

/// The shadow ray of a light sample from a point `p` inside a medium (no surface to
/// leave): towards the light's point moved off its surface along its normal (as
/// `integrator::shadow_ray`), ending a relative 1e-4 short. Direction and end point.
#[inline(always)]
fn medium_shadow_ray(p: Vec3, ls: &crate::lights::LightSample) -> (Vec3, Vec3) {
    let d = light_target(ls) - p;
    let dist = d.length();
    if dist.is_nan() || dist <= 0.0 {
        return (ls.wi, p);
    }
    let dir = d / dist;
    (dir, p + dir * (dist * (1.0 - 1e-4)))
}

/// Whether the shape's material is Mitsuba's `null` (an interface, not a vertex).
#[inline(always)]
fn is_null(scene: &Scene, shape: &Shape) -> bool {
    matches!(scene.bsdfs[shape.bsdf as usize].bsdf, Bsdf::Null(_))
}

/// What a shadow ray keeps crossing the surface `h` along `d`: 1 through `null`,
/// Mitsuba's `eval_null_transmission` through a `thindielectric` (its transmission
/// is flagged `Null` in Mitsuba 3: `(1 - R') specular_transmittance`, R' the slab's
/// reflectance at the crossing), `None` for any other surface (blocked).
#[inline(always)]
fn null_transmission(
    scene: &Scene,
    shape: &Shape,
    h: &crate::geometry::accel::Hit,
    d: Vec3,
) -> Option<Rgb> {
    let material = &scene.bsdfs[shape.bsdf as usize];
    match &material.bsdf {
        Bsdf::Null(_) => Some(Rgb::ONE),
        Bsdf::ThinDielectric(t) => {
            let textured;
            let t = if material.is_plain() {
                t
            } else {
                textured = material.at_point(&TexPoint::on(shape, h.face, h.b1, h.b2, h.surface.p));
                match &textured {
                    Bsdf::ThinDielectric(t) => t,
                    _ => return None,
                }
            };
            let cos = d.dot(h.surface.ns);
            Some(t.specular_transmittance * (1.0 - t.reflectance(cos)))
        }
        _ => None,
    }
}

/// Whether a sampled event at `bsdf` is a null interaction in Mitsuba 3's sense (no
/// vertex: `max_depth`, the MIS state and the specular chain stay): `null`, and the
/// transmission of a `thindielectric`.
#[inline(always)]
fn null_event(bsdf: &Bsdf, lobe: crate::materials::BsdfFlags) -> bool {
    match bsdf {
        Bsdf::Null(_) => true,
        Bsdf::ThinDielectric(_) => lobe == crate::materials::BsdfFlags::DELTA_TRANSMISSION,
        _ => false,
    }
}

/// The spectral MIS state of a path (see the module documentation): channel `h`
/// samples the free flights; `f` and `p` are the products of every channel's
/// free-flight terms and densities, both divided by channel h's densities.
struct Spectral {
    h: usize,
    f: DVec3,
    p: DVec3,
}

impl Spectral {
    fn new(u: f32) -> Self {
        Spectral {
            h: ((u * 3.0) as usize).min(2),
            f: DVec3::ONE,
            p: DVec3::ONE,
        }
    }

    /// The factor channel k's throughput carries: `f_k / mean_c p_c`.
    #[inline(always)]
    fn weight(&self) -> Rgb {
        let mean = self.p.element_sum() / 3.0;
        if mean > 0.0 && mean.is_finite() {
            (self.f / mean).as_vec3()
        } else {
            Rgb::ZERO
        }
    }

    /// Folds in one event with per-channel terms `f` and densities `p`.
    #[inline(always)]
    fn update(&mut self, f: Rgb, p: Rgb) {
        let ph = p[self.h] as f64;
        if ph > 0.0 {
            self.f *= f.as_dvec3() / ph;
            self.p *= p.as_dvec3() / ph;
        } else {
            self.f = DVec3::ZERO;
        }
    }
}

/// Result of a free flight through a medium towards a surface at `s_surf`.
enum Flight {
    /// A real scattering at distance `t`.
    Scatter { t: f32 },
    /// The surface was reached.
    Surface,
}

/// Samples a free flight along unit `d` from `o` towards a surface at `s_surf`, and
/// folds its events into `spec` (`Medium::free_flight`: in a homogeneous medium a
/// distance from channel `spec.h`'s extinction, one number; in a heterogeneous one
/// delta tracking, `media/heterogeneous.rs`).
#[inline(always)]
fn free_flight<S: PathSampler>(
    m: &Medium,
    o: Vec3,
    d: Vec3,
    s_surf: f32,
    rng: &mut S,
    spec: &mut Spectral,
) -> Flight {
    let h = spec.h;
    match m.free_flight(o, d, s_surf, h, rng, |f, p| spec.update(f, p)) {
        Tracked::Real { t } => Flight::Scatter { t },
        Tracked::Through => Flight::Surface,
    }
}

/// Transmittance from `o` along unit `d` to `target` (stopping `target_eps` short),
/// starting in `medium`: through `null` interfaces (switching media there), zero at
/// any other surface.
///
/// # Safety
/// The CPU must support `ISA`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
unsafe fn transmittance<const ISA: u8>(
    scene: &Scene,
    mut o: Vec3,
    d: Vec3,
    target: Vec3,
    target_eps: f32,
    mut medium: Option<u32>,
    rng: &mut crate::math::rng::Pcg32,
    tally: &mut PathTally,
) -> Rgb {
    let mut tr = Rgb::ONE;
    for _ in 0..MAX_NULL_CROSSINGS {
        let tmax = (target - o).length() - target_eps;
        if tmax <= 0.0 {
            return tr;
        }
        tally.rays += 1;
        // SAFETY: the caller guarantees ISA.
        let hit = unsafe { scene.accel.intersect_with::<ISA>(&scene.shapes, o, d, tmax) };
        let seg = hit.as_ref().map_or(tmax, |h| h.t);
        if let Some(m) = medium {
            tr *= scene.media[m as usize].transmittance(o, d, seg, rng);
        }
        let Some(h) = hit else {
            return tr;
        };
        let shape = &scene.shapes[h.shape as usize];
        match null_transmission(scene, shape, &h, d) {
            Some(t) => tr *= t,
            None => return Rgb::ZERO,
        }
        if tr == Rgb::ZERO {
            return Rgb::ZERO;
        }
        if shape.is_medium_transition() {
            medium = shape.target_medium(d, h.surface.ng);
        }
        o = offset_origin(h.surface.p, h.surface.ng, d);
    }
    Rgb::ZERO
}

/// Distance along the camera ray to the first surface that is not `null` (0 if none):
/// mitransient's `first_surface`, for `camera_unwarp`.
///
/// # Safety
/// The CPU must support `ISA`.
#[inline(always)]
unsafe fn first_surface<const ISA: u8>(scene: &Scene, mut o: Vec3, d: Vec3) -> f64 {
    let mut dist = 0.0f64;
    for _ in 0..MAX_NULL_CROSSINGS {
        // SAFETY: the caller guarantees ISA.
        let Some(h) = (unsafe {
            scene
                .accel
                .intersect_with::<ISA>(&scene.shapes, o, d, f32::INFINITY)
        }) else {
            return 0.0;
        };
        dist += h.t as f64;
        let shape = &scene.shapes[h.shape as usize];
        // mitransient's `first_surface` passes every BSDF with a Null component
        // (`null`, `thindielectric`).
        if !is_null(scene, shape)
            && !matches!(
                scene.bsdfs[shape.bsdf as usize].bsdf,
                Bsdf::ThinDielectric(_)
            )
        {
            return dist;
        }
        o = offset_origin(h.surface.p, h.surface.ng, d);
    }
    dist
}

/// The volumetric path tracer; `ISA` picks the intersection kernels.
///
/// # Safety
/// The CPU must support `ISA`.
#[inline(always)]
unsafe fn trace_body<const ISA: u8, S: PathSampler>(
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
    let max_depth = if settings.max_depth < 0 {
        u32::MAX
    } else {
        settings.max_depth as u32
    };
    let mut g = GSample::default();
    let mut g_pending = true;
    // Distance along the camera ray before the first real interaction (G-buffer depth).
    let mut camera_dist = 0.0f32;

    let mut o = o;
    let mut d = d;
    let mut medium = scene.camera_medium;
    let mut opl = if settings.camera_unwarp {
        // SAFETY: the caller guarantees ISA.
        -unsafe { first_surface::<ISA>(scene, o, d) }
    } else {
        0.0f64
    };
    // The throughput is `common * spec.weight()`: `common` holds the BSDF and phase
    // weights and Russian roulette, `spec` the free flights (spectral MIS).
    let mut spec = Spectral::new(rng.get1(slot::CHANNEL));
    let mut common = Rgb::ONE;
    let mut beta = Rgb::ONE;
    let mut eta = 1.0f32;
    let mut depth: u32 = 0;
    let mut specular_chain = !settings.hide_emitters;
    let mut last_scatter = o;
    let mut last_pdf = 1.0f32;
    let mut nulls_in_a_row = 0u32;

    loop {
        // Each vertex (null crossings included) draws its numbers from its own
        // dimensions (`sampler.rs`).
        rng.next_vertex();
        // Russian roulette (Mitsuba's volpath: after rr_depth real interactions).
        let u_rr = rng.get1(slot::RR);
        if depth > settings.rr_depth {
            let q = (beta.max_element() * eta * eta).min(0.95);
            if u_rr >= q {
                break;
            }
            common /= q;
            beta /= q;
        }
        if depth >= max_depth || beta == Rgb::ZERO || beta.max_element().is_nan() {
            break;
        }

        tally.rays += 1;
        // SAFETY: the caller guarantees ISA.
        let hit = unsafe {
            scene
                .accel
                .intersect_with::<ISA>(&scene.shapes, o, d, f32::INFINITY)
        };
        let s_surf = hit.as_ref().map_or(f32::INFINITY, |h| h.t);

        // ---- Medium: free flight, and a real scattering before the surface. ----
        if let Some(mi) = medium {
            let m = &scene.media[mi as usize];
            let flight = free_flight(m, o, d, s_surf, rng, &mut spec);
            beta = common * spec.weight();
            match flight {
                Flight::Scatter { t } => {
                    let p = o + d * t;
                    opl += eta as f64 * t as f64;
                    if depth == 0 && g.depth.is_none() {
                        g.depth = Some(camera_dist + t);
                    }
                    if g_pending {
                        g_pending = false;
                        g.albedo = m.albedo_at(p);
                        g.medium = true;
                    }
                    depth += 1;
                    nulls_in_a_row = 0;
                    last_scatter = p;
                    if depth >= max_depth {
                        break;
                    }
                    let wi = -d;
                    // Next-event estimation with the phase function.
                    if m.sample_emitters() {
                        specular_chain = false;
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
                                    transmittance::<ISA>(
                                        scene,
                                        p,
                                        dir,
                                        target,
                                        0.0,
                                        medium,
                                        rng.stream(),
                                        tally,
                                    )
                                };
                                if tr != Rgb::ZERO {
                                    let w = if ls.delta {
                                        1.0
                                    } else {
                                        power_heuristic(ls.pdf, f)
                                    };
                                    let arrival = opl + eta as f64 * ls.dist as f64;
                                    contribute(
                                        scene,
                                        deposits,
                                        tally,
                                        arrival,
                                        beta * tr * ls.li * (f * w / ls.pdf),
                                    );
                                }
                            }
                        }
                    } else {
                        specular_chain = true;
                    }
                    // Phase sampling (weight 1).
                    let ps = m.phase().sample(wi, rng.get2(slot::PHASE));
                    if ps.pdf.is_nan() || ps.pdf <= 0.0 {
                        break;
                    }
                    last_pdf = ps.pdf;
                    o = p;
                    d = ps.wo;
                    continue;
                }
                Flight::Surface => {}
            }
        }

        // ---- Surface. ----
        // A ray that meets nothing leaves the scene: it sees the environment emitter,
        // if any, at distance 2 max(R, |o - c|) as in the surface tracer (`escape`),
        // MIS-weighted against light sampling like an area light's hit.
        let Some(hit) = hit else {
            if let Some(env) = scene.environment {
                let prev_delta = depth == 0 || specular_chain;
                escape(
                    scene, env, o, d, depth, opl, eta, beta, prev_delta, last_pdf, deposits, tally,
                    &mut g, g_pending,
                );
            }
            break;
        };
        opl += eta as f64 * hit.t as f64;
        let shape = &scene.shapes[hit.shape as usize];
        let sp = hit.surface;
        let wo_world = -d;
        let material = &scene.bsdfs[shape.bsdf as usize];
        let frame = if material.is_anisotropic() {
            Frame::from_normal_tangent(sp.ns, shape.dpdu(hit.face, hit.b1, hit.b2, sp.p))
        } else {
            Frame::from_normal(sp.ns)
        };
        let wo = frame.to_local(wo_world);
        let textured;
        let (whole, bsdf, delaying) = if material.is_plain() {
            (&material.bsdf, &material.bsdf, None)
        } else {
            let whole = if material.perturbs() {
                textured = super::integrator::perturbed_at(material, shape, &hit, &sp, &frame, wo);
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
        let null = matches!(bsdf, Bsdf::Null(_));
        if depth == 0 && g.depth.is_none() {
            if null {
                camera_dist += hit.t;
            } else {
                g.depth = Some(camera_dist + hit.t);
            }
        }

        // Emission (front side only), MIS-weighted against light sampling from the last
        // real scattering vertex.
        let mut seen_emitter = false;
        if let Some(ei) = shape.emitter {
            let cos_l = wo.z;
            if cos_l > 0.0 {
                seen_emitter = true;
                if !(depth == 0 && settings.hide_emitters) {
                    let emitter = &scene.emitters[ei as usize];
                    // An angular light seen outside its cone emits nothing.
                    if let Some(radiance) =
                        emitter.emitted(cos_l, || shape.uv(hit.face, hit.b1, hit.b2, sp.p))
                    {
                        let w = if depth == 0 || specular_chain {
                            1.0
                        } else {
                            let dist = (sp.p - last_scatter).length();
                            power_heuristic(last_pdf, emitter.pdf_area_hit(select_pdf, dist, cos_l))
                        };
                        contribute(scene, deposits, tally, opl, beta * radiance * w);
                    }
                }
            }
        }

        let delta = !bsdf.flags(wo).has_non_delta();
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

        // Next-event estimation (through null interfaces and media).
        if !delta && depth + 1 < max_depth {
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
                    let target = origin + dir * tmax;
                    let shadow_medium = if shape.is_medium_transition() {
                        shape.target_medium(ls.wi, sp.ng)
                    } else {
                        medium
                    };
                    // SAFETY: the caller guarantees ISA.
                    let tr = unsafe {
                        transmittance::<ISA>(
                            scene,
                            origin,
                            dir,
                            target,
                            0.0,
                            shadow_medium,
                            rng.stream(),
                            tally,
                        )
                    };
                    if tr != Rgb::ZERO {
                        let w = if ls.delta {
                            1.0
                        } else {
                            power_heuristic(ls.pdf, bsdf_pdf)
                        };
                        let delay =
                            delaying.map_or(0.0, |s| s.sample_delay(rng.get1(slot::NEE_DELAY)));
                        let eta_light = eta * bsdf.eta(wo, wi);
                        let arrival = opl + delay as f64 + eta_light as f64 * ls.dist as f64;
                        contribute(
                            scene,
                            deposits,
                            tally,
                            arrival,
                            beta * f * tr * ls.li * (w / ls.pdf),
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
        common *= bs.weight;
        beta = common * spec.weight();
        eta *= bs.eta;
        if null_event(bsdf, bs.lobe) {
            nulls_in_a_row += 1;
            if nulls_in_a_row > MAX_NULL_CROSSINGS {
                break;
            }
        } else {
            depth += 1;
            nulls_in_a_row = 0;
            last_scatter = sp.p;
            last_pdf = bs.pdf;
            specular_chain = bs.lobe.is_delta();
        }
        if shape.is_medium_transition() {
            medium = shape.target_medium(wi_world, sp.ng);
        }
        o = offset_origin(sp.p, sp.ng, wi_world);
        d = wi_world.normalize();
    }
    g
}
