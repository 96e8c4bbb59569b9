//! What the path loop (`tracer.rs`: `transient_path` and `transient_prbvolpath`, with
//! next-event estimation and MIS (power heuristic), Russian roulette and Mitsuba's
//! `max_depth`) and the NLOS tracer share: a path's counts ([`PathTally`]), the one
//! place a contribution at optical path length (OPL) meets the time bins
//! ([`contribute`], SPEC 4), shadow rays between moved ends, the material of a
//! normal/bump-mapped hit, and rays that leave the scene ([`escape`]).

use super::deposits::{Deposit, PathDeposits, DEPOSIT_WIDTH};
use super::gbuffer::GSample;
use super::polarized::Polarization;
use crate::geometry::accel::offset_origin;
use crate::geometry::shadow::shadow_segment;
use crate::math::sampling::power_heuristic;
use crate::math::Rgb;
use crate::scene::Scene;
use crate::sensors::time_filter::{gaussian_shares, TimeFilter};
use crate::spectral::lift::Wavelengths;
use glam::Vec3;

/// What one path leaves behind besides its deposits.
#[derive(Default)]
pub struct PathTally {
    /// Sum of every finite contribution (in the window or not): the steady image (the
    /// film's first C channels).
    pub steady: Deposit,
    /// Contributions dropped because they were NaN or infinite.
    pub dropped_nonfinite: u64,
    /// Rays traced (closest-hit and shadow).
    pub rays: u64,
}

/// Adds a contribution `c` (rgb, or mono radiance in every lane) arriving at OPL `opl`
/// to the path's deposits.
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
    let mut d = [0.0; DEPOSIT_WIDTH];
    d[..3].copy_from_slice(&[c.x as f64, c.y as f64, c.z as f64]);
    deposit(scene, deposits, tally, opl, d);
}

/// Adds the Stokes vectors `s` (one per lane, in the sensor's frame) of a polarized
/// path `pol` (wavelengths `wl` when spectral) arriving at OPL `opl` to the path's
/// deposits, as the film's channels (`Polarization::deposit`).
#[inline(always)]
pub(super) fn contribute_stokes(
    scene: &Scene,
    deposits: &mut PathDeposits,
    tally: &mut PathTally,
    opl: f64,
    (pol, wl): (&Polarization, Option<&Wavelengths>),
    s: [glam::Vec4; 3],
) {
    if !s.iter().all(|v| v.is_finite()) {
        tally.dropped_nonfinite += 1;
        return;
    }
    if s.iter().all(|&v| v == glam::Vec4::ZERO) {
        return;
    }
    deposit(scene, deposits, tally, opl, pol.deposit(&s, wl));
}

#[inline(always)]
fn deposit(
    scene: &Scene,
    deposits: &mut PathDeposits,
    tally: &mut PathTally,
    opl: f64,
    c: Deposit,
) {
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

/// The spectrum at a spectral path's wavelengths `wl` of the colour `rgb` that emitter
/// `e` emits towards the path (`towards`: the direction from the path to the light,
/// which an environment map is looked up along): the scene's spectrum when it gave one
/// (`Scene::emitter_spectra`); an environment map's texels lifted one by one and
/// interpolated (`EnvMap::eval_uv_spectral`, as Mitsuba), times D65; else the colour
/// lifted as an illuminant (`spectral::lift`).
#[inline(never)]
pub(super) fn emitted_spectrum(
    scene: &Scene,
    e: usize,
    rgb: Rgb,
    towards: Vec3,
    wl: &Wavelengths,
) -> Rgb {
    if let Some(Some(s)) = scene.emitter_spectra.get(e) {
        return s.at(rgb, wl.lambda);
    }
    match &scene.emitters[e] {
        crate::lights::Emitter::Envmap { map, .. } => {
            map.eval_uv_spectral(map.uv(towards), wl.lambda) * wl.d65()
        }
        _ => wl.illuminant(rgb),
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
/// runs between the moved ends under the shadow-segment rule (`geometry/shadow.rs`).
/// Aiming the moved origin along the unmoved direction instead met the light's own
/// plane before the end of the ray whenever the light lay more than about 50 degrees
/// from `ng`. Length 0 when the ends coincide.
#[inline(always)]
pub fn shadow_ray(p: Vec3, ng: Vec3, ls: &crate::lights::LightSample) -> (Vec3, Vec3, f32) {
    let origin = offset_origin(p, ng, ls.wi);
    shadow_segment(origin, light_target(ls)).unwrap_or((origin, ls.wi, 0.0))
}

/// A ray from `o` along unit `d` that left the scene: the environment emitter `env`
/// seen along it, MIS-weighted against light sampling unless the last vertex was a
/// delta lobe (camera rays: weight 1, nothing when `hide_emitters`). Its segment counts
/// `eta * 2 max(R, |o - c|)` of OPL, the distance of a light sample of that emitter
/// (`lights::scene_sphere`); a camera segment under `camera_unwarp` counts nothing. A
/// camera path whose first non-delta vertex would be here sees an emitter (G-buffer).
/// A spectral path (`wl`) sees the radiance's spectrum and contributes its sRGB; a
/// polarized path (`pol`) its Stokes vectors.
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
    (wl, mono): (Option<&Wavelengths>, bool),
    pol: Option<&Polarization>,
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
    let c = match wl {
        None if mono => beta * Rgb::splat(crate::textures::luminance(radiance)) * w,
        None => beta * radiance * w,
        Some(wl) => beta * emitted_spectrum(scene, env as usize, radiance, d, wl) * w,
    };
    let opl = opl + segment;
    match (pol, wl) {
        (Some(p), _) => contribute_stokes(scene, deposits, tally, opl, (p, wl), p.unpolarized(c)),
        (None, Some(wl)) => contribute(scene, deposits, tally, opl, wl.to_srgb(c)),
        (None, None) => contribute(scene, deposits, tally, opl, c),
    }
}
