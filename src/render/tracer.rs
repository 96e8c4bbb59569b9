//! The path loop: `transient_path` (surfaces) and `transient_prbvolpath` (surfaces and
//! participating media, SPEC 7) in one loop.
//!
//! # The loop
//! Per iteration of a path (one vertex):
//!
//! 1. *start*: the vertex's dimensions (`sampler.rs`); under the media rules Russian
//!    roulette and the `max_depth` test come here, before the ray (Mitsuba's `volpath`
//!    order);
//! 2. the *closest hit* of the path's ray;
//! 3. *shade* ([`shade`]): in a medium, a free flight and possibly a real scattering
//!    (next-event estimation with the phase function, phase sampling); at a surface,
//!    emission (MIS-weighted), the G-buffer's first vertex, next-event estimation and
//!    BSDF sampling, then Russian roulette (Mitsuba's `path` order).
//!
//! One block of code per step for both rule sets; the const parameter `MEDIA` selects
//! where Mitsuba's two integrators differ:
//! - Russian roulette: `path` after BSDF sampling from `depth >= rr_depth`, `volpath`
//!   at the top from `depth > rr_depth`;
//! - `max_depth`: `path` stops before next-event estimation at the last vertex,
//!   `volpath` skips next-event estimation there and stops at the next top;
//! - `null` surfaces and `thindielectric` transmission are no vertex under `volpath`
//!   (`volpath.rs`), shadow rays cross them with the media's transmittance, and the
//!   emission MIS distance runs from the last real scattering;
//! - a front-side hit of an emitter counts as seeing it (G-buffer) under `path` when
//!   it emits, under `volpath` always;
//! - `camera_unwarp`: `path` counts no first segment, `volpath` starts the OPL at minus
//!   the distance to the first non-null surface (mitransient's rules).
//!
//! Scenes without media run the loop with `MEDIA = false`: none of the media code is
//! compiled into it, and it is, operation for operation, the surface tracer it
//! replaced (same bits, same instruction count). With media it is the volumetric
//! tracer it replaced, now with the instruction set's intersection kernels (their hits
//! are the same bits at every level).

use super::deposits::PathDeposits;
use super::gbuffer::GSample;
use super::path_common::{
    contribute, contribute_stokes, emitted_spectrum, escape, shadow_ray, PathTally,
};
use super::polarized::{self, Polarization};
use super::roulette::roulette;
use super::sampler::{pick_scattering, slot, PathSampler};
use super::vertex::SurfaceVertex;
use super::volpath::{
    first_surface, free_flight, medium_shadow_ray, null_event, transmittance, Flight, Spectral,
    MAX_NULL_CROSSINGS,
};
use crate::cpu::{Avx2, Avx512, Baseline, Detected, Level};
use crate::geometry::accel::{offset_origin, Hit};
use crate::materials::{Bsdf, BsdfModel, Separable};
use crate::math::sampling::power_heuristic;
use crate::math::Rgb;
use crate::scene::Scene;
use crate::spectral::lift::Wavelengths;
use crate::textures::luminance;
use glam::{Vec3, Vec4};

/// A path's state between vertices.
struct PathState {
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
    /// The path's wavelengths in the spectral mode (`scene::mode`): `beta` and every
    /// colour it meets are then values at them, and contributions become sRGB at
    /// [`PathState::sample`]. `None` in RGB.
    wl: Option<Wavelengths>,
    /// A mono path (`mono`, `mono_polarized`): every colour it meets is its
    /// luminance, in all three lanes of `beta`.
    mono: bool,
    /// A polarized path (`mono_polarized`, `spectral_polarized`, `polarized.rs`): the
    /// product of the normalised Mueller matrices of its vertices per lane, after the
    /// rotation into the sensor's frame; a contribution `c` (per lane, as `beta`
    /// computes it) of unpolarized light is the Stokes vector `c * column 0` per lane.
    /// `None` otherwise.
    pol: Option<Polarization>,
}

/// The emitter that `u_sel` in [0, 1) selects among `n` (uniformly); one emitter needs
/// no arithmetic (the general form gives 0 too).
#[inline(always)]
fn pick_emitter(u_sel: f32, n: usize) -> usize {
    if n == 1 {
        0
    } else {
        ((u_sel * n as f32) as usize).min(n - 1)
    }
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

/// Traces one camera path from `o` (where its OPL starts) along unit direction `d`,
/// with the kernels of the instruction set `cpu::current()` chose (same bits at every
/// level): the surface rules, or the media rules when the scene has media.
pub fn trace<S: PathSampler>(
    scene: &Scene,
    o: Vec3,
    d: Vec3,
    rng: &mut S,
    deposits: &mut PathDeposits,
    tally: &mut PathTally,
) -> GSample {
    if scene.integrator.volumetric {
        trace_with::<true, S>(scene, o, d, rng, deposits, tally)
    } else {
        trace_with::<false, S>(scene, o, d, rng, deposits, tally)
    }
}

/// [`trace`] under one rule set, in the wrapper of the instruction set
/// `cpu::current()` chose.
#[inline(always)]
fn trace_with<const MEDIA: bool, S: PathSampler>(
    scene: &Scene,
    o: Vec3,
    d: Vec3,
    rng: &mut S,
    deposits: &mut PathDeposits,
    tally: &mut PathTally,
) -> GSample {
    match crate::cpu::detected() {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: the proof says this CPU runs the wrapper's instruction set.
        Detected::Avx512(isa) => unsafe {
            path_avx512::<MEDIA, S>(isa, scene, o, d, rng, deposits, tally)
        },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as above.
        Detected::Avx2(isa) => unsafe {
            path_avx2::<MEDIA, S>(isa, scene, o, d, rng, deposits, tally)
        },
        _ => path_body::<Baseline, MEDIA, S>(Baseline, scene, o, d, rng, deposits, tally),
    }
}

/// Traces one perspective camera path along unit direction `d` ([`trace`]), from
/// where the camera starts it (the pinhole, or the near plane: `Camera::start`).
#[inline]
pub fn trace_path<S: PathSampler>(
    scene: &Scene,
    d: Vec3,
    rng: &mut S,
    deposits: &mut PathDeposits,
    tally: &mut PathTally,
) -> GSample {
    let o = scene.camera.start(scene.camera.origin, d);
    trace(scene, o, d, rng, deposits, tally)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512bw,avx512cd")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
fn path_avx512<const MEDIA: bool, S: PathSampler>(
    isa: Avx512,
    scene: &Scene,
    o: Vec3,
    d: Vec3,
    rng: &mut S,
    deposits: &mut PathDeposits,
    tally: &mut PathTally,
) -> GSample {
    path_body::<Avx512, MEDIA, S>(isa, scene, o, d, rng, deposits, tally)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
fn path_avx2<const MEDIA: bool, S: PathSampler>(
    isa: Avx2,
    scene: &Scene,
    o: Vec3,
    d: Vec3,
    rng: &mut S,
    deposits: &mut PathDeposits,
    tally: &mut PathTally,
) -> GSample {
    path_body::<Avx2, MEDIA, S>(isa, scene, o, d, rng, deposits, tally)
}

/// The loop (module docs), inlined into one wrapper per instruction set.
#[inline(always)]
fn path_body<L: Level, const MEDIA: bool, S: PathSampler>(
    isa: L,
    scene: &Scene,
    o: Vec3,
    d: Vec3,
    rng: &mut S,
    deposits: &mut PathDeposits,
    tally: &mut PathTally,
) -> GSample {
    let settings = &scene.integrator;
    let mut path = PathState::start::<L, MEDIA, S>(isa, scene, o, d, rng);
    // Mitsuba's `path`: max_depth = 0 renders nothing, not even directly visible
    // emitters (`volpath` stops at its first top).
    if !MEDIA && settings.max_depth == 0 {
        return path.g;
    }
    let rr_depth = settings.rr_depth;
    let max_depth = max_depth(scene);
    loop {
        // 1. Start of a vertex: its dimensions; under the media rules Russian roulette
        //    and the depth test come first.
        rng.next_vertex();
        if MEDIA {
            let u_rr = rng.get1(slot::RR);
            if path.depth > rr_depth {
                let Some(q) = roulette(path.beta.max_element(), path.eta, u_rr) else {
                    break;
                };
                path.common /= q;
                path.beta /= q;
            }
            if path.depth as u64 >= max_depth
                || path.beta == Rgb::ZERO
                || path.beta.max_element().is_nan()
            {
                break;
            }
        }
        // 2. The closest hit.
        tally.rays += 1;
        let hit = scene
            .accel
            .intersect_with(isa, &scene.shapes, path.o, path.d, f32::INFINITY);
        // 3. Shade.
        let goes_on =
            shade::<L, MEDIA, S>(isa, scene, &mut path, hit.as_ref(), rng, deposits, tally);
        if !goes_on {
            break;
        }
    }
    path.g
}

impl PathState {
    /// A camera path from `o` along unit `d` (the media rules draw the hero channel and,
    /// under `camera_unwarp`, find the first surface).
    #[inline(always)]
    fn start<L: Level, const MEDIA: bool, S: PathSampler>(
        isa: L,
        scene: &Scene,
        o: Vec3,
        d: Vec3,
        rng: &mut S,
    ) -> PathState {
        let settings = &scene.integrator;
        let (opl, spec) = if MEDIA {
            let opl = if settings.camera_unwarp {
                -(first_surface(isa, scene, o, d))
            } else {
                0.0f64
            };
            (opl, Spectral::new(rng.get1(slot::CHANNEL)))
        } else {
            (0.0, Spectral::new(0.0))
        };
        PathState {
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
            medium: if MEDIA { scene.camera_medium } else { None },
            common: Rgb::ONE,
            spec,
            camera_dist: 0.0,
            last_scatter: o,
            nulls_in_a_row: 0,
            // The spectral mode refuses media, so the media's hero channel and the
            // wavelengths never share the slot.
            wl: scene
                .mode
                .is_spectral()
                .then(|| Wavelengths::sample(rng.get1(slot::CHANNEL))),
            mono: scene.mode.is_mono(),
            pol: scene.mode.is_polarized().then(|| {
                let lanes = if scene.mode.is_mono() { 1 } else { 3 };
                Polarization::new(d, scene.camera.axes[1], lanes)
            }),
        }
    }

    /// Adds a contribution `c` at OPL `opl` through the Mueller matrix `n(lane)`
    /// (normalised, world bases) of the last step to the light: the Stokes vectors of
    /// a polarized path, else `c` itself as the film records it.
    #[inline(always)]
    fn contribute(
        &self,
        scene: &Scene,
        deposits: &mut PathDeposits,
        tally: &mut PathTally,
        opl: f64,
        c: Rgb,
        n: impl Fn(usize) -> Vec4,
    ) {
        match &self.pol {
            None => contribute(scene, deposits, tally, opl, self.sample(c)),
            Some(p) => {
                let s = p.stokes(c, n);
                contribute_stokes(scene, deposits, tally, opl, (p, self.wl.as_ref()), s)
            }
        }
    }

    /// A colour `rgb` emitted by emitter `e` towards the path (`towards`: from the
    /// path to the light) as the path sees it: itself in RGB, its spectrum at the
    /// path's wavelengths in the spectral mode.
    #[inline(always)]
    fn emitted(&self, scene: &Scene, e: usize, rgb: Rgb, towards: Vec3) -> Rgb {
        match &self.wl {
            None if self.mono => Rgb::splat(luminance(rgb)),
            None => rgb,
            Some(wl) => emitted_spectrum(scene, e, rgb, towards, wl),
        }
    }

    /// A contribution as the sample the film records: itself in RGB, its linear sRGB
    /// in the spectral mode.
    #[inline(always)]
    fn sample(&self, c: Rgb) -> Rgb {
        match &self.wl {
            None => c,
            Some(wl) => wl.to_srgb(c),
        }
    }
}

/// Step 3 of the loop: `hit` is the closest hit of the path's ray. Returns whether
/// the path goes on. In a medium the free flight may end in a real scattering first
/// ([`scatter_in_medium`]); a ray that meets nothing sees the environment; at a
/// surface the steps are [`to_surface`], the vertex (`vertex.rs`) and the lobe that
/// scatters ([`Scattering::at`]), [`emission`], the G-buffer ([`guide`]), then, unless
/// the depth ends the path, [`next_event`] and [`continue_by_bsdf`].
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn shade<L: Level, const MEDIA: bool, S: PathSampler>(
    isa: L,
    scene: &Scene,
    path: &mut PathState,
    hit: Option<&Hit>,
    rng: &mut S,
    deposits: &mut PathDeposits,
    tally: &mut PathTally,
) -> bool {
    // ---- Medium: free flight, and a real scattering before the surface. ----
    if MEDIA {
        if let Some(mi) = path.medium {
            let m = &scene.media[mi as usize];
            let s_surf = hit.map_or(f32::INFINITY, |h| h.t);
            let flight = free_flight(m, path.o, path.d, s_surf, rng, &mut path.spec);
            path.beta = path.common * path.spec.weight();
            if let Flight::Scatter { t } = flight {
                return scatter_in_medium::<L, S>(isa, scene, path, mi, t, rng, deposits, tally);
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
                path.o,
                path.d,
                path.depth,
                path.opl,
                path.eta,
                path.beta,
                path.depth == 0 || path.specular,
                path.last_pdf,
                deposits,
                tally,
                &mut path.g,
                path.g_pending,
                (path.wl.as_ref(), path.mono),
                path.pol.as_ref(),
            );
        }
        return false;
    };
    let depth = path.depth;
    to_surface::<MEDIA>(scene, path, hit);
    let (mut textured, mut lifted) = (None, None);
    let at = Scattering::at(
        scene,
        hit,
        path.d,
        &mut textured,
        &mut lifted,
        (path.wl.as_ref(), path.mono),
        rng,
    );
    if MEDIA && depth == 0 && path.g.depth.is_none() {
        if matches!(at.bsdf, Bsdf::Null(_)) {
            path.camera_dist += hit.t;
        } else {
            path.g.depth = Some(path.camera_dist + hit.t);
        }
    }
    let seen_emitter = emission::<MEDIA>(scene, path, hit, &at.v, deposits, tally);
    // Next-event estimation and MIS need a lobe with a density; the flags say so.
    let delta = !at.bsdf.flags(at.v.wo).has_non_delta();
    guide(path, &at, delta, seen_emitter);

    // Mitsuba's `path`: the next segment exists only if depth + 1 < max_depth.
    let max_depth = max_depth(scene);
    if !MEDIA && depth as u64 + 1 >= max_depth {
        return false;
    }
    // Under `volpath` the last vertex takes no light sample.
    if !delta && (!MEDIA || (depth as u64) + 1 < max_depth) {
        next_event::<L, MEDIA, S>(isa, scene, path, &at, rng, deposits, tally);
    }
    continue_by_bsdf::<MEDIA, S>(scene, path, &at, rng)
}

/// The segment to the surface hit `hit` joins the path's OPL (under `path` with
/// `camera_unwarp`, the camera's segment counts nothing); under `path` the G-buffer's
/// depth is the first hit's distance (`volpath` finds it past `null` surfaces, in
/// [`shade`]).
#[inline(always)]
fn to_surface<const MEDIA: bool>(scene: &Scene, path: &mut PathState, hit: &Hit) {
    if MEDIA {
        path.opl += path.eta as f64 * hit.t as f64;
    } else {
        let depth = path.depth;
        let segment = if depth == 0 && scene.integrator.camera_unwarp {
            0.0
        } else {
            path.eta as f64 * hit.t as f64
        };
        path.opl += segment;
        if depth == 0 {
            path.g.depth = Some(hit.t);
        }
    }
}

/// A surface vertex and the lobe that scatters there.
struct Scattering<'a> {
    /// The vertex; `v.bsdf` is the whole material (textures resolved), which the
    /// G-buffer sees.
    v: SurfaceVertex<'a>,
    /// The model that scatters: a `Composed` vertex scatters as one child, the first
    /// with probability w, so each child's delay stays with its own light.
    bsdf: &'a Bsdf,
    /// Its delay profile when it delays (`materials/composed.rs`, `separable.rs`).
    delaying: Option<&'a Separable>,
}

impl<'a> Scattering<'a> {
    /// The vertex at `hit` of the ray along `d` (`SurfaceVertex::at`, a textured
    /// material resolved into `textured`; for a spectral path with wavelengths `wl`,
    /// its colours as spectra into `lifted`), and its scattering child (a plain
    /// material draws no number).
    #[inline(always)]
    fn at<S: PathSampler>(
        scene: &'a Scene,
        hit: &Hit,
        d: Vec3,
        textured: &'a mut Option<Bsdf>,
        lifted: &'a mut Option<Bsdf>,
        (wl, mono): (Option<&Wavelengths>, bool),
        rng: &mut S,
    ) -> Self {
        let v = SurfaceVertex::at(scene, hit, d, textured);
        let v = match wl {
            None if mono => v.mono(lifted),
            None => v,
            Some(wl) => v.lifted(hit, wl, lifted),
        };
        let whole = v.bsdf;
        let (bsdf, delaying) = if v.material.is_plain() {
            (whole, None)
        } else {
            let bsdf = pick_scattering(whole, rng);
            let delaying = match bsdf {
                Bsdf::Separable(s) => Some(s),
                _ => None,
            };
            (bsdf, delaying)
        };
        Scattering { v, bsdf, delaying }
    }
}

/// Emission at the surface vertex `v` of `hit` (front side only; an angular light only
/// within its cone), MIS-weighted against light sampling from the last real vertex.
/// Returns whether the path sees an emitter there: under `path` a front-side hit
/// counts when it emits (evaluated even when hidden); under `volpath` any front-side
/// hit does.
#[inline(always)]
fn emission<const MEDIA: bool>(
    scene: &Scene,
    path: &PathState,
    hit: &Hit,
    v: &SurfaceVertex,
    deposits: &mut PathDeposits,
    tally: &mut PathTally,
) -> bool {
    let Some(ei) = v.shape.emitter else {
        return false;
    };
    let cos_l = v.wo.z;
    if cos_l <= 0.0 || cos_l.is_nan() {
        return false;
    }
    let depth = path.depth;
    let emitter = &scene.emitters[ei as usize];
    let hidden = depth == 0 && scene.integrator.hide_emitters;
    let radiance = if MEDIA && hidden {
        None
    } else {
        let (shape, sp) = (v.shape, v.sp);
        emitter.emitted(cos_l, || shape.uv(hit.face, hit.b1, hit.b2, sp.p))
    };
    let Some(radiance) = radiance else {
        return MEDIA;
    };
    if !hidden {
        let w = if depth == 0 || path.specular {
            1.0
        } else {
            let dist = if MEDIA {
                (v.sp.p - path.last_scatter).length()
            } else {
                hit.t
            };
            let select_pdf = 1.0 / scene.emitters.len() as f32;
            power_heuristic(path.last_pdf, emitter.pdf_area_hit(select_pdf, dist, cos_l))
        };
        let c = path.beta * path.emitted(scene, ei as usize, radiance, path.d) * w;
        path.contribute(scene, deposits, tally, path.opl, c, |_| Vec4::X);
    }
    true
}

/// The G-buffer records a camera path's first vertex that is not a delta lobe (nor a
/// material the guide looks through), or that sees an emitter. It sees the whole
/// material (a `Composed` one as its mixture); `delta` says whether the scattering
/// lobe is.
#[inline(always)]
fn guide(path: &mut PathState, at: &Scattering, delta: bool, seen_emitter: bool) {
    if !path.g_pending {
        return;
    }
    let whole = at.v.bsdf;
    let guide_delta = if std::ptr::eq(whole, at.bsdf) {
        delta
    } else {
        !whole.flags(at.v.wo).has_non_delta()
    };
    if (!guide_delta && !whole.guide_looks_through()) || seen_emitter {
        path.g_pending = false;
        at.v.record(&mut path.g);
        path.g.emitter = seen_emitter;
    }
}

/// Next-event estimation from the surface vertex: a light chosen uniformly, a point
/// on it, the BSDF there, MIS against BSDF sampling, and what reaches the point (under
/// the media rules through null interfaces and media, else one occlusion test).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn next_event<L: Level, const MEDIA: bool, S: PathSampler>(
    isa: L,
    scene: &Scene,
    path: &PathState,
    at: &Scattering,
    rng: &mut S,
    deposits: &mut PathDeposits,
    tally: &mut PathTally,
) {
    let (shape, sp, frame, wo, bsdf) = (at.v.shape, &at.v.sp, &at.v.frame, at.v.wo, at.bsdf);
    let n_emitters = scene.emitters.len();
    let select_pdf = 1.0 / n_emitters as f32;
    let u_sel = rng.get1(slot::LIGHT_SELECT);
    let u1 = rng.get1(slot::LIGHT_1);
    let u2 = rng.get2(slot::LIGHT_2);
    let idx = pick_emitter(u_sel, n_emitters);
    let emitter = &scene.emitters[idx];
    let Some(ls) = emitter.sample(&scene.shapes, sp.p, select_pdf, u1, u2) else {
        return;
    };
    let wi = frame.to_local(ls.wi);
    // The BSDF's density is needed only to weigh a light that has one: then value and
    // density come from one evaluation of the lobes.
    let (f, bsdf_pdf) = if ls.delta {
        (bsdf.eval(wo, wi), 0.0)
    } else {
        bsdf.eval_pdf(wo, wi)
    };
    if !(f != Rgb::ZERO && ls.pdf > 0.0) {
        return;
    }
    let (origin, dir, tmax) = shadow_ray(sp.p, sp.ng, &ls);
    let w = if ls.delta {
        1.0
    } else {
        power_heuristic(ls.pdf, bsdf_pdf)
    };
    // The segment lies in the medium on the light's side: through rough glass that is
    // the current IOR times the one crossed (the same f32 product a BSDF-sampled path
    // would carry).
    let eta_light = path.eta * bsdf.eta(wo, wi);
    let tr = if MEDIA {
        let target = origin + dir * tmax;
        let shadow_medium = if shape.is_medium_transition() {
            shape.target_medium(ls.wi, sp.ng)
        } else {
            path.medium
        };
        transmittance(
            isa,
            scene,
            origin,
            dir,
            target,
            0.0,
            shadow_medium,
            rng.stream(),
            tally,
        )
    } else {
        tally.rays += 1;
        let blocked = tmax > 0.0 && (scene.accel.occluded_with(isa, origin, dir, tmax));
        if tmax > 0.0 && !blocked {
            Rgb::ONE
        } else {
            Rgb::ZERO
        }
    };
    if tr != Rgb::ZERO {
        // A delaying material draws its delay only when the light is seen.
        let delay = at
            .delaying
            .map_or(0.0, |s| s.sample_delay(rng.get1(slot::NEE_DELAY)));
        let arrival = path.opl + delay as f64 + eta_light as f64 * ls.dist as f64;
        let c = path.beta * f * tr * path.emitted(scene, idx, ls.li, ls.wi) * (w / ls.pdf);
        path.contribute(scene, deposits, tally, arrival, c, |lane| {
            polarized::step(bsdf, frame, wo, wi, None, lane).x_axis
        });
    }
}

/// BSDF sampling: the path's next direction, throughput and OPL (a delaying material
/// adds its delay), then under `path` Russian roulette (`roulette.rs`) from
/// `rr_depth` on (`volpath` takes it at the next top). Under the media rules a `null`
/// event is no vertex, and a medium transition changes the path's medium. Returns
/// whether the path goes on.
#[inline(always)]
fn continue_by_bsdf<const MEDIA: bool, S: PathSampler>(
    scene: &Scene,
    path: &mut PathState,
    at: &Scattering,
    rng: &mut S,
) -> bool {
    let (shape, sp, frame, wo, bsdf) = (at.v.shape, &at.v.sp, &at.v.frame, at.v.wo, at.bsdf);
    let u1 = rng.get1(slot::BSDF_1);
    let u2 = rng.get2(slot::BSDF_2);
    let Some(bs) = bsdf.sample(wo, u1, u2) else {
        return false;
    };
    let wi_world = frame.to_world(bs.wi);
    if let Some(s) = at.delaying {
        path.opl += s.sample_delay(rng.get1(slot::BSDF_DELAY)) as f64;
    }
    path.eta *= bs.eta;
    if MEDIA {
        path.common *= bs.weight;
        path.beta = path.common * path.spec.weight();
        if null_event(bsdf, bs.lobe) {
            path.nulls_in_a_row += 1;
            if path.nulls_in_a_row > MAX_NULL_CROSSINGS {
                return false;
            }
        } else {
            path.depth += 1;
            path.nulls_in_a_row = 0;
            path.last_scatter = sp.p;
            path.last_pdf = bs.pdf;
            path.specular = bs.lobe.is_delta();
        }
        if shape.is_medium_transition() {
            path.medium = shape.target_medium(wi_world, sp.ng);
        }
        path.o = offset_origin(sp.p, sp.ng, wi_world);
        path.d = wi_world.normalize();
        return true;
    }
    path.beta *= bs.weight;
    if let Some(p) = path.pol.as_mut() {
        let delta = bs.lobe.is_delta().then_some(bs.lobe);
        p.scatter(bsdf, frame, wo, bs.wi, delta);
    }
    path.specular = bs.lobe.is_delta();
    path.last_pdf = bs.pdf;
    path.o = offset_origin(sp.p, sp.ng, wi_world);
    path.d = wi_world.normalize();
    path.depth += 1;

    let beta_max = path.beta.max_element();
    let u_rr = rng.get1(slot::RR);
    if path.depth >= scene.integrator.rr_depth {
        let Some(q) = roulette(beta_max, path.eta, u_rr) else {
            return false;
        };
        path.beta /= q;
    }
    !(beta_max.is_nan() || beta_max <= 0.0)
}

/// A real scattering in the medium `mi` at distance `t` along the path's ray:
/// next-event estimation with the phase function (unless the medium says not to) and
/// a new direction from it (weight 1). Returns whether the path goes on.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn scatter_in_medium<L: Level, S: PathSampler>(
    isa: L,
    scene: &Scene,
    path: &mut PathState,
    mi: u32,
    t: f32,
    rng: &mut S,
    deposits: &mut PathDeposits,
    tally: &mut PathTally,
) -> bool {
    let m = &scene.media[mi as usize];
    let n_emitters = scene.emitters.len();
    let select_pdf = 1.0 / n_emitters as f32;
    let p = path.o + path.d * t;
    path.opl += path.eta as f64 * t as f64;
    if path.depth == 0 && path.g.depth.is_none() {
        path.g.depth = Some(path.camera_dist + t);
    }
    if path.g_pending {
        path.g_pending = false;
        path.g.albedo = m.albedo_at(p);
        path.g.medium = true;
    }
    path.depth += 1;
    path.nulls_in_a_row = 0;
    path.last_scatter = p;
    if path.depth as u64 >= max_depth(scene) {
        return false;
    }
    let wi = -path.d;
    // Next-event estimation with the phase function.
    if m.sample_emitters() {
        path.specular = false;
        let u_sel = rng.get1(slot::LIGHT_SELECT);
        let u1 = rng.get1(slot::LIGHT_1);
        let u2 = rng.get2(slot::LIGHT_2);
        let idx = pick_emitter(u_sel, n_emitters);
        let emitter = &scene.emitters[idx];
        if let Some(ls) = emitter.sample(&scene.shapes, p, select_pdf, u1, u2) {
            let f = m.phase().eval(wi, ls.wi);
            if f > 0.0 && ls.pdf > 0.0 {
                let (dir, target) = medium_shadow_ray(p, &ls);
                let tr = transmittance(
                    isa,
                    scene,
                    p,
                    dir,
                    target,
                    0.0,
                    path.medium,
                    rng.stream(),
                    tally,
                );
                if tr != Rgb::ZERO {
                    let w = if ls.delta {
                        1.0
                    } else {
                        power_heuristic(ls.pdf, f)
                    };
                    let arrival = path.opl + path.eta as f64 * ls.dist as f64;
                    contribute(
                        scene,
                        deposits,
                        tally,
                        arrival,
                        path.beta * tr * ls.li * (f * w / ls.pdf),
                    );
                }
            }
        }
    } else {
        path.specular = true;
    }
    // Phase sampling (weight 1).
    let ps = m.phase().sample(wi, rng.get2(slot::PHASE));
    if ps.pdf.is_nan() || ps.pdf <= 0.0 {
        return false;
    }
    path.last_pdf = ps.pdf;
    path.o = p;
    path.d = ps.wo;
    true
}
