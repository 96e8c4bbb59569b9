//! The media rules of the path loop (`tracer.rs` with `MEDIA = true`,
//! `transient_prbvolpath`): volumetric path tracing (SPEC 7) with Mitsuba 3's `volpath`
//! semantics, keeping each path's OPL as the surface rules do; this file holds their
//! parts (spectral MIS, free flights, shadow-ray transmittance, null interfaces).
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
//! dielectric boundaries, as under the surface rules). A null collision adds no time: the
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
//! G-buffer: as under the surface rules, looking through `null` interfaces; a camera path whose
//! first real interaction is a medium scattering records the medium's albedo there, a zero
//! normal and `medium = true`; depth is the distance to that first interaction.

use super::path_common::{light_target, PathTally};
use super::sampler::PathSampler;
use crate::cpu::Level;
use crate::geometry::accel::offset_origin;
use crate::geometry::shadow::shadow_segment;
use crate::geometry::shape::Shape;
use crate::materials::Bsdf;
use crate::math::Rgb;
use crate::media::{Medium, Tracked};
use crate::scene::Scene;
use crate::textures::TexPoint;
use glam::{DVec3, Vec3};

/// Shadow rays cross at most this many `null` interfaces (then count as blocked), and a
/// path at most this many in a row: a guard against rays stuck on a surface.
pub(super) const MAX_NULL_CROSSINGS: u32 = 256;

/// The shadow ray of a light sample from a point `p` inside a medium (no surface to
/// leave): towards the light's point moved off its surface along its normal (as
/// `path_common::shadow_ray`), under the shadow-segment rule (`geometry/shadow.rs`).
/// Direction and end point.
#[inline(always)]
pub(super) fn medium_shadow_ray(p: Vec3, ls: &crate::lights::LightSample) -> (Vec3, Vec3) {
    match shadow_segment(p, light_target(ls)) {
        Some((_, dir, len)) => (dir, p + dir * len),
        None => (ls.wi, p),
    }
}

/// Whether the shape's material is Mitsuba's `null` (an interface, not a vertex).
#[inline(always)]
pub(super) fn is_null(scene: &Scene, shape: &Shape) -> bool {
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
pub(super) fn null_event(bsdf: &Bsdf, lobe: crate::materials::BsdfFlags) -> bool {
    match bsdf {
        Bsdf::Null(_) => true,
        Bsdf::ThinDielectric(_) => lobe == crate::materials::BsdfFlags::DELTA_TRANSMISSION,
        _ => false,
    }
}

/// The spectral MIS state of a path (see the module documentation): channel `h`
/// samples the free flights; `f` and `p` are the products of every channel's
/// free-flight terms and densities, both divided by channel h's densities.
pub(super) struct Spectral {
    h: usize,
    f: DVec3,
    p: DVec3,
}

impl Spectral {
    pub(super) fn new(u: f32) -> Self {
        Spectral {
            h: ((u * 3.0) as usize).min(2),
            f: DVec3::ONE,
            p: DVec3::ONE,
        }
    }

    /// The factor channel k's throughput carries: `f_k / mean_c p_c`.
    #[inline(always)]
    pub(super) fn weight(&self) -> Rgb {
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
pub(super) enum Flight {
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
pub(super) fn free_flight<S: PathSampler>(
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
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(super) fn transmittance<L: Level>(
    isa: L,
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
        let hit = scene.accel.intersect_with(isa, &scene.shapes, o, d, tmax);
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
#[inline(always)]
pub(super) fn first_surface<L: Level>(isa: L, scene: &Scene, mut o: Vec3, d: Vec3) -> f64 {
    let mut dist = 0.0f64;
    for _ in 0..MAX_NULL_CROSSINGS {
        let Some(h) = scene
            .accel
            .intersect_with(isa, &scene.shapes, o, d, f32::INFINITY)
        else {
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
