//! What both tracers (`integrator.rs`, `volpath.rs`) do at a scattering vertex, in one
//! place: the light sample of next-event estimation (at surfaces and in media), and at
//! a surface hit the material (`Surface`: shading frame, textures resolved, the child
//! that scatters and its delay), the G-buffer's guiding vertex, the BSDF towards a
//! light with its MIS weight and arrival time, and BSDF sampling with its delay. Each
//! draws its numbers from the same sampler slots in the same order in both tracers.

use super::gbuffer::GSample;
use super::sampler::{pick_scattering, slot, PathSampler};
use crate::geometry::accel::Hit;
use crate::geometry::shape::{Shape, SurfacePoint};
use crate::lights::LightSample;
use crate::materials::{Bsdf, BsdfModel, BsdfSample, HitGeometry, Material, Separable};
use crate::math::frame::Frame;
use crate::math::sampling::power_heuristic;
use crate::math::Rgb;
use crate::scene::Scene;
use crate::textures::TexPoint;
use glam::Vec3;

/// A light for next-event estimation from `p`: one of the scene's emitters, chosen
/// uniformly (`select_pdf` = 1 / their number), then a point on it.
#[inline(always)]
pub(super) fn sample_light<S: PathSampler>(
    scene: &Scene,
    rng: &mut S,
    p: Vec3,
    select_pdf: f32,
) -> Option<LightSample> {
    let n_emitters = scene.emitters.len();
    let u_sel = rng.get1(slot::LIGHT_SELECT);
    let u1 = rng.get1(slot::LIGHT_1);
    let u2 = rng.get2(slot::LIGHT_2);
    let idx = ((u_sel * n_emitters as f32) as usize).min(n_emitters - 1);
    scene.emitters[idx].sample(&scene.shapes, p, select_pdf, u1, u2)
}

/// The material at a surface hit, in the hit's shading frame.
pub(super) struct Surface<'a> {
    /// Mitsuba's shading frame: dp/du's for anisotropic materials, else the normal's
    /// own (same bits, no uv work).
    pub frame: Frame,
    /// The direction back along the ray, in `frame`.
    pub wo: Vec3,
    /// The material with its textures resolved, for the G-buffer (a `Composed` one as
    /// its mixture).
    pub whole: &'a Bsdf,
    /// The model that scatters: `whole`, or the `Composed` child chosen for this vertex
    /// (the first with probability w, so each child's delay stays with its own light).
    pub bsdf: &'a Bsdf,
    /// `bsdf`'s profile when it delays (`materials/composed.rs`).
    pub delaying: Option<&'a Separable>,
    /// `bsdf` has only delta lobes towards `wo`: no next-event estimation, no MIS.
    pub delta: bool,
}

impl<'a> Surface<'a> {
    /// The material of `shape` at `hit`, seen along `wo_world` (= -d). A textured or
    /// perturbed material becomes a plain BSDF at this hit, kept in `resolved`
    /// (computed only then); a `Composed` one draws its child from `rng`.
    #[inline(always)]
    pub fn at<S: PathSampler>(
        material: &'a Material,
        shape: &Shape,
        hit: &Hit,
        wo_world: Vec3,
        rng: &mut S,
        resolved: &'a mut Option<Bsdf>,
    ) -> Surface<'a> {
        let sp = &hit.surface;
        let frame = if material.is_anisotropic() {
            Frame::from_normal_tangent(sp.ns, shape.dpdu(hit.face, hit.b1, hit.b2, sp.p))
        } else {
            Frame::from_normal(sp.ns)
        };
        let wo = frame.to_local(wo_world);
        let (whole, bsdf, delaying) = if material.is_plain() {
            (&material.bsdf, &material.bsdf, None)
        } else {
            let whole: &'a Bsdf = if material.perturbs() {
                resolved.insert(perturbed_at(material, shape, hit, sp, &frame, wo))
            } else if material.is_textured() {
                resolved
                    .insert(material.at_point(&TexPoint::on(shape, hit.face, hit.b1, hit.b2, sp.p)))
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
        Surface {
            frame,
            wo,
            whole,
            bsdf,
            delaying,
            delta: !bsdf.flags(wo).has_non_delta(),
        }
    }

    /// Records the G-buffer at the first vertex that guides it: one whose whole
    /// material has a non-delta lobe and does not look through (`null`-like), or one
    /// on an emitter. `ns` is the shading normal, turned to face `wo_world`.
    #[inline(always)]
    pub fn guide(
        &self,
        g: &mut GSample,
        g_pending: &mut bool,
        ns: Vec3,
        wo_world: Vec3,
        seen_emitter: bool,
    ) {
        let guide_delta = if std::ptr::eq(self.whole, self.bsdf) {
            self.delta
        } else {
            !self.whole.flags(self.wo).has_non_delta()
        };
        if *g_pending && ((!guide_delta && !self.whole.guide_looks_through()) || seen_emitter) {
            *g_pending = false;
            g.albedo = self.whole.albedo(self.wo);
            g.normal = if ns.dot(wo_world) >= 0.0 { ns } else { -ns };
            g.emitter = seen_emitter;
        }
    }

    /// The BSDF's value towards a light in local direction `wi`, and its density when
    /// the light has one (MIS): then both come from one evaluation of the lobes.
    #[inline(always)]
    pub fn towards_light(&self, wi: Vec3, light_delta: bool) -> (Rgb, f32) {
        if light_delta {
            (self.bsdf.eval(self.wo, wi), 0.0)
        } else {
            self.bsdf.eval_pdf(self.wo, wi)
        }
    }

    /// An unoccluded light sample's MIS weight (power heuristic against the BSDF's
    /// density `bsdf_pdf`; 1 for a delta light) and its arrival OPL from a vertex at
    /// `opl` with IOR product `eta`: a delaying model's delay, then the segment in the
    /// medium on the light's side (through rough glass the current IOR times the one
    /// crossed, the same f32 product a BSDF-sampled path would carry).
    #[inline(always)]
    pub fn light_arrival<S: PathSampler>(
        &self,
        ls: &LightSample,
        wi: Vec3,
        bsdf_pdf: f32,
        rng: &mut S,
        opl: f64,
        eta: f32,
    ) -> (f32, f64) {
        let w = if ls.delta {
            1.0
        } else {
            power_heuristic(ls.pdf, bsdf_pdf)
        };
        let delay = self
            .delaying
            .map_or(0.0, |s| s.sample_delay(rng.get1(slot::NEE_DELAY)));
        let eta_light = eta * self.bsdf.eta(self.wo, wi);
        (w, opl + delay as f64 + eta_light as f64 * ls.dist as f64)
    }

    /// Samples the path's continuation: the BSDF sample and its world direction; a
    /// delaying model adds its delay to `opl`.
    #[inline(always)]
    pub fn sample<S: PathSampler>(&self, rng: &mut S, opl: &mut f64) -> Option<(BsdfSample, Vec3)> {
        let u1 = rng.get1(slot::BSDF_1);
        let u2 = rng.get2(slot::BSDF_2);
        let bs = self.bsdf.sample(self.wo, u1, u2)?;
        let wi_world = self.frame.to_world(bs.wi);
        if let Some(s) = self.delaying {
            *opl += s.sample_delay(rng.get1(slot::BSDF_DELAY)) as f64;
        }
        Some((bs, wi_world))
    }
}

/// The material at a hit of a `normalmap`/`bumpmap` material: textures resolved at the
/// hit's uv and every perturbed frame set from the hit's geometry (`frame` is
/// Mitsuba's dp/du shading frame, `wo` the direction back along the ray in it). Out of
/// line: only such materials come here.
#[inline(never)]
pub(super) fn perturbed_at(
    material: &Material,
    shape: &Shape,
    hit: &Hit,
    sp: &SurfacePoint,
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
