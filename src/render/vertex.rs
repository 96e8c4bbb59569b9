//! The scattering-vertex step both path loops share (`tracer.rs`, `nlos/`): at a
//! surface hit, the shading frame, the direction back along the arriving ray in it,
//! the material with its textures resolved at the hit, and what the G-buffer records
//! of the vertex. pbrt resolves the material at a hit in one call every integrator
//! uses; this is that call.

use super::gbuffer::GSample;
use crate::geometry::accel::Hit;
use crate::geometry::shape::{Shape, SurfacePoint};
use crate::materials::lift::ColourKind;
use crate::materials::{Bsdf, BsdfModel, HitGeometry, Material};
use crate::math::frame::Frame;
use crate::scene::Scene;
use crate::spectral::lift::Wavelengths;
use crate::textures::{luminance, TexPoint};
use glam::Vec3;

/// A surface vertex: where it is and what scatters there.
pub struct SurfaceVertex<'a> {
    pub shape: &'a Shape,
    /// The hit's point and normals.
    pub sp: SurfacePoint,
    pub frame: Frame,
    /// The direction back along the arriving ray, in `frame`.
    pub wo: Vec3,
    /// The direction back along the arriving ray, in world space.
    pub wo_world: Vec3,
    /// The scene's material at the shape.
    pub material: &'a Material,
    /// The material at this hit: `material.bsdf` itself, or with its textures (and
    /// perturbed frames) resolved at the hit's uv; for a spectral path, with its
    /// colours at the path's wavelengths ([`Self::lifted`]).
    pub bsdf: &'a Bsdf,
    /// The material at this hit in RGB, which the G-buffer records (`bsdf` but for a
    /// spectral path).
    pub rgb_bsdf: &'a Bsdf,
}

impl<'a> SurfaceVertex<'a> {
    /// The vertex at `hit` of a ray along unit `d`. A textured material is resolved
    /// into `textured` (computed only then; plain materials cost nothing). Anisotropic
    /// roughness follows the surface's dp/du (Mitsuba's shading frame); every other
    /// material keeps the normal's own frame (no uv work).
    #[inline(always)]
    pub fn at(scene: &'a Scene, hit: &Hit, d: Vec3, textured: &'a mut Option<Bsdf>) -> Self {
        let shape = &scene.shapes[hit.shape as usize];
        let sp = hit.surface;
        let material = &scene.bsdfs[shape.bsdf as usize];
        let frame = if material.is_anisotropic() {
            Frame::from_normal_tangent(sp.ns, shape.dpdu(hit.face, hit.b1, hit.b2, sp.p))
        } else {
            Frame::from_normal(sp.ns)
        };
        let wo_world = -d;
        let wo = frame.to_local(wo_world);
        let bsdf: &'a Bsdf = if material.is_plain() {
            &material.bsdf
        } else if material.perturbs() {
            textured.insert(perturbed_at(material, shape, hit, &sp, &frame, wo))
        } else if material.is_textured() {
            textured.insert(material.at_point(&TexPoint::on(shape, hit.face, hit.b1, hit.b2, sp.p)))
        } else {
            &material.bsdf
        };
        SurfaceVertex {
            shape,
            sp,
            frame,
            wo,
            wo_world,
            material,
            bsdf,
            rgb_bsdf: bsdf,
        }
    }

    /// The vertex at `hit` of a spectral path: every colour of the material at the
    /// hit as its spectrum at the wavelengths `wl`: lifted from RGB
    /// (`materials::lift`, `spectral::lift`); a bilinear RGB bitmap's colour lifted
    /// texel by texel before the filter (`Material::set_texel_spectra`, as Mitsuba's
    /// bitmap); where the scene gave a spectrum, that spectrum's values
    /// (`Material::set_spectra`). Kept in `lifted`; the G-buffer still sees the RGB
    /// material.
    #[inline(always)]
    pub fn lifted(self, hit: &Hit, wl: &Wavelengths, lifted: &'a mut Option<Bsdf>) -> Self {
        let lift = |kind, c| match kind {
            ColourKind::Bounded => wl.reflectance(c),
            ColourKind::Unbounded => wl.unbounded(c),
        };
        let mut b = self.bsdf.map_colours(&lift);
        if self.material.filters_colours() {
            let p = TexPoint::on(self.shape, hit.face, hit.b1, hit.b2, self.sp.p);
            self.material.set_texel_spectra(&mut b, &p, &lift);
        }
        if !self.material.spectra.is_empty() {
            self.material.set_spectra(&mut b, wl.lambda);
        }
        let bsdf = lifted.insert(b);
        SurfaceVertex { bsdf, ..self }
    }

    /// The vertex of a mono path (`mono`, `mono_polarized`): every colour of the
    /// material at the hit as its luminance in all three lanes (Mitsuba's mono
    /// variants read an RGB value as its luminance), kept in `lifted`.
    #[inline(always)]
    pub fn mono(self, lifted: &'a mut Option<Bsdf>) -> Self {
        let bsdf = lifted.insert(self.bsdf.map_colours(&|_, c| Vec3::splat(luminance(c))));
        SurfaceVertex { bsdf, ..self }
    }

    /// The shading normal faced to the side the ray came from.
    #[inline(always)]
    pub fn faced_normal(&self) -> Vec3 {
        let ns = self.sp.ns;
        if ns.dot(self.wo_world) >= 0.0 {
            ns
        } else {
            -ns
        }
    }

    /// What the G-buffer records of a camera path's first guiding vertex: the whole
    /// material's albedo and the faced shading normal.
    #[inline(always)]
    pub fn record(&self, g: &mut GSample) {
        g.albedo = self.rgb_bsdf.albedo(self.wo);
        g.normal = self.faced_normal();
    }
}

/// The material at a hit of a `normalmap`/`bumpmap` material: textures resolved at the
/// hit's uv and every perturbed frame set from the hit's geometry (`frame` is
/// Mitsuba's dp/du shading frame, `wo` the direction back along the ray in it). Out of
/// line: only such materials come here.
#[inline(never)]
fn perturbed_at(
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
