//! BSDFs: the closed set of surface scattering models, dispatched with `match`.
//!
//! Every model implements [`BsdfModel`]: `eval`, `pdf` (and both at once, `eval_pdf`),
//! `sample`, `flags` and `albedo`.
//! Conventions (as in Mitsuba 3): directions are in the local shading frame (normal +z);
//! `wo` points back along the incoming ray (towards the camera side of the path), `wi`
//! is the sampled or queried direction towards the light, both pointing away from the
//! surface. `eval` returns f * |cos(wi)|. BSDFs are one-sided: `wo.z <= 0` is black,
//! except for dielectrics (smooth and rough), `twosided`, `principled` with
//! `spec_trans` and `principledthin`.
//!
//! `twosided` holds two [`OneSided`] models, a type that has no dielectric (smooth or
//! rough) and no `twosided`: resolving the side ([`TwoSided::side`]) always ends at a
//! plain model. `mask` wraps any BSDF (Mitsuba's scenes write `mask(twosided(diffuse))`).

mod blend;
mod circular;
mod composed;
mod conductor;
pub mod conductor_presets;
mod dielectric;
mod diffuse;
mod flags;
pub mod fresnel;
pub mod lift;
mod mask;
pub mod material;
pub mod microfacet;
pub mod mueller;
mod null;
mod pane;
pub mod perturbed;
mod plastic;
mod polarizer;
mod pplastic;
mod principled;
mod principled_common;
mod principled_thin;
mod retarder;
mod rough_conductor;
mod rough_dielectric;
mod rough_plastic;
mod separable;
pub mod temporal_profile;
mod thin_dielectric;

pub use blend::Blend;
pub use circular::Circular;
pub use composed::Composed;
pub use conductor::Conductor;
pub use dielectric::Dielectric;
pub use diffuse::Diffuse;
pub use flags::BsdfFlags;
pub use mask::Mask;
pub use material::Material;
pub use microfacet::{Microfacet, MicrofacetKind};
pub use null::Null;
pub use perturbed::{HitGeometry, Perturbation, Perturbed};
pub use plastic::Plastic;
pub use polarizer::Polarizer;
pub use pplastic::PPlastic;
pub use principled::{specular_to_eta, Principled};
pub use principled_thin::PrincipledThin;
pub use retarder::Retarder;
pub use rough_conductor::RoughConductor;
pub use rough_dielectric::RoughDielectric;
pub use rough_plastic::RoughPlastic;
pub use separable::Separable;
pub use temporal_profile::TemporalProfile;
pub use thin_dielectric::ThinDielectric;

use crate::math::Rgb;
use glam::Vec3;

/// The result of sampling a BSDF.
#[derive(Clone, Copy, Debug)]
pub struct BsdfSample {
    pub wi: Vec3,
    /// f * |cos(wi)| / pdf (1 x reflectance for delta lobes).
    pub weight: Rgb,
    /// Solid-angle density; for a delta lobe the probability of having chosen it
    /// (Mitsuba's convention: a dielectric's R or 1 - R, a plastic's specular choice, 1
    /// for a mirror), which only `blendbsdf` reads (the integrator gives delta lobes
    /// MIS weight 1).
    pub pdf: f32,
    /// The one lobe that produced `wi`.
    pub lobe: BsdfFlags,
    /// Relative IOR crossed (1 unless transmitted through a dielectric interface).
    pub eta: f32,
}

/// The interface every BSDF implements (pbrt's BxDF: `f`, `Sample_f`, `PDF`, flags).
pub trait BsdfModel {
    /// The lobes seen from `wo` (`twosided` picks a side by `wo.z`). A one-sided model
    /// seen from the back keeps its lobes; `eval` and `sample` are black there.
    fn flags(&self, wo: Vec3) -> BsdfFlags;

    /// f(wo, wi) * |cos(wi)| of the non-delta lobes (deltas are zero here).
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb;

    /// Solid-angle density with which `sample` picks `wi` through a non-delta lobe.
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32;

    /// `(eval(wo, wi), pdf(wo, wi))` in one call, for next-event estimation and MIS,
    /// which need both for the same pair. Models whose two methods share work (the
    /// half vector, D, G1, Fresnel) override it to compute it once; an override must
    /// return exactly the bits of the two calls (the same floating-point operations
    /// in the same order; `tests/it/eval_pdf.rs` checks every model).
    #[inline(always)]
    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
        (self.eval(wo, wi), self.pdf(wo, wi))
    }

    /// Samples `wi` with three uniform numbers in [0, 1): `u1` picks a lobe, `u2` the
    /// direction within it.
    fn sample(&self, wo: Vec3, u1: f32, u2: [f32; 2]) -> Option<BsdfSample>;

    /// The relative IOR crossed going from `wo` to `wi` through a non-delta lobe: 1
    /// unless `wi` is transmitted through an interface, then the IOR of `wi`'s side
    /// over that of `wo`'s (what `sample` reports as `BsdfSample::eta` for `wi`). Next-
    /// event estimation scales the segment to a light by it: a light reached through
    /// rough glass lies in the other medium. Models with a non-delta transmission
    /// lobe between different media must implement it.
    #[inline(always)]
    fn eta(&self, _wo: Vec3, _wi: Vec3) -> f32 {
        1.0
    }

    /// Directional albedo seen from `wo`, for the G-buffer: the fraction of the energy
    /// arriving along `wo` that is scattered, per channel, i.e. the expected sample
    /// weight with transmitted weights counted as energy (times `eta^2`, undoing the
    /// radiance compression across an interface). 1 for a lossless model.
    fn albedo(&self, wo: Vec3) -> Rgb;
}

/// A model that `twosided` can wrap: one-sided, never a (rough) dielectric or `twosided`.
#[derive(Clone, Debug, PartialEq)]
pub enum OneSided {
    Diffuse(Diffuse),
    Conductor(Conductor),
    RoughConductor(RoughConductor),
    Plastic(Plastic),
    RoughPlastic(RoughPlastic),
    PPlastic(PPlastic),
}

/// Mitsuba's `twosided`: the front model for `wo.z >= 0`, the back model seen with the
/// frame flipped (z -> -z) otherwise.
#[derive(Clone, Debug, PartialEq)]
pub struct TwoSided {
    pub front: OneSided,
    pub back: OneSided,
}

#[derive(Clone, Debug, PartialEq)]
pub enum Bsdf {
    Diffuse(Diffuse),
    Dielectric(Dielectric),
    Conductor(Conductor),
    RoughConductor(RoughConductor),
    RoughDielectric(RoughDielectric),
    ThinDielectric(ThinDielectric),
    Plastic(Plastic),
    RoughPlastic(RoughPlastic),
    Null(Null),
    TwoSided(TwoSided),
    Mask(Mask),
    /// Delays its re-emission (SPEC section 6).
    Separable(Separable),
    /// A mixture of two BSDFs, resolved per vertex by the integrator.
    Composed(Composed),
    /// Mitsuba's `blendbsdf`: a mixture that stays one BSDF.
    Blend(Blend),
    /// `normalmap` and `bumpmap`: a nested BSDF in a perturbed frame.
    Perturbed(Perturbed),
    PPlastic(PPlastic),
    Polarizer(Polarizer),
    /// Mitsuba's `principled` and `principledthin` (Disney's BSDF).
    Principled(Principled),
    PrincipledThin(PrincipledThin),
    /// Mitsuba's `retarder` (a wave plate) and `circular` (a circular polarizer).
    Retarder(Retarder),
    Circular(Circular),
}

impl Bsdf {
    /// [`BsdfModel::eta`] of the models that can refract and of the wrappers.
    #[inline(never)]
    fn eta_refracting(&self, wo: Vec3, wi: Vec3) -> f32 {
        match self {
            Bsdf::RoughDielectric(b) => b.eta(wo, wi),
            Bsdf::Principled(b) => b.eta(wo, wi),
            Bsdf::Mask(m) => m.nested.eta(wo, wi),
            Bsdf::Separable(s) => s.inner.eta(wo, wi),
            Bsdf::Blend(b) => b.eta(wo, wi),
            Bsdf::Perturbed(p) => p.eta(wo, wi),
            _ => 1.0,
        }
    }

    /// Whether the G-buffer looks through this surface although it has a lobe with a
    /// density (a mostly transparent `mask`); delta-only surfaces are looked through
    /// anyway.
    #[inline(always)]
    pub fn guide_looks_through(&self) -> bool {
        matches!(self, Bsdf::Mask(m) if m.mostly_transparent())
    }

    /// Whether the model or a model inside it (twosided's sides, mask's and
    /// Separable's nested model, Composed's children) has anisotropic roughness
    /// (constant; textured roughness is known from the material's bindings).
    pub fn anisotropic(&self) -> bool {
        match self {
            Bsdf::RoughConductor(c) => c.distribution.is_anisotropic(),
            Bsdf::RoughDielectric(d) => d.distribution.is_anisotropic(),
            Bsdf::TwoSided(t) => [&t.front, &t.back].iter().any(|s| match s {
                OneSided::RoughConductor(c) => c.distribution.is_anisotropic(),
                OneSided::PPlastic(p) => p.distribution.is_anisotropic(),
                _ => false,
            }),
            Bsdf::Mask(m) => m.nested.anisotropic(),
            Bsdf::Separable(s) => s.inner.anisotropic(),
            Bsdf::Composed(c) => c.first.anisotropic() || c.second.anisotropic(),
            Bsdf::Blend(c) => c.first.anisotropic() || c.second.anisotropic(),
            Bsdf::Perturbed(p) => p.nested.anisotropic(),
            Bsdf::PPlastic(p) => p.distribution.is_anisotropic(),
            Bsdf::Principled(p) => p.anisotropic != 0.0,
            Bsdf::PrincipledThin(p) => p.anisotropic != 0.0,
            _ => false,
        }
    }

    /// Whether the model or a model inside it perturbs the shading frame (`normalmap`,
    /// `bumpmap`): then the integrator builds Mitsuba's dp/du frame and calls
    /// [`Self::resolve_frames`] at each hit.
    pub fn perturbs(&self) -> bool {
        match self {
            Bsdf::Perturbed(_) => true,
            Bsdf::Mask(m) => m.nested.perturbs(),
            Bsdf::Separable(s) => s.inner.perturbs(),
            Bsdf::Composed(c) => c.first.perturbs() || c.second.perturbs(),
            Bsdf::Blend(c) => c.first.perturbs() || c.second.perturbs(),
            _ => false,
        }
    }

    /// Sets the perturbed frame of every `normalmap`/`bumpmap` inside for the hit `g`.
    pub fn resolve_frames(&mut self, g: &HitGeometry) {
        match self {
            Bsdf::Perturbed(p) => p.resolve(g),
            Bsdf::Mask(m) => m.nested.resolve_frames(g),
            Bsdf::Separable(s) => s.inner.resolve_frames(g),
            Bsdf::Composed(c) => {
                c.first.resolve_frames(g);
                c.second.resolve_frames(g);
            }
            Bsdf::Blend(c) => {
                c.first.resolve_frames(g);
                c.second.resolve_frames(g);
            }
            _ => {}
        }
    }

    /// Whether the model or a model inside it delays its re-emission.
    pub fn delays(&self) -> bool {
        match self {
            Bsdf::Separable(_) => true,
            Bsdf::Composed(c) => c.first.delays() || c.second.delays(),
            Bsdf::Mask(m) => m.nested.delays(),
            Bsdf::Blend(c) => c.first.delays() || c.second.delays(),
            Bsdf::Perturbed(p) => p.nested.delays(),
            _ => false,
        }
    }
}

impl TryFrom<Bsdf> for OneSided {
    /// Returns the BSDF back when it cannot be wrapped.
    type Error = Bsdf;
    fn try_from(b: Bsdf) -> Result<Self, Bsdf> {
        match b {
            Bsdf::Diffuse(d) => Ok(OneSided::Diffuse(d)),
            Bsdf::Conductor(c) => Ok(OneSided::Conductor(c)),
            Bsdf::RoughConductor(c) => Ok(OneSided::RoughConductor(c)),
            Bsdf::Plastic(p) => Ok(OneSided::Plastic(p)),
            Bsdf::RoughPlastic(p) => Ok(OneSided::RoughPlastic(p)),
            Bsdf::PPlastic(p) => Ok(OneSided::PPlastic(p)),
            other @ (Bsdf::Dielectric(_)
            | Bsdf::RoughDielectric(_)
            | Bsdf::ThinDielectric(_)
            | Bsdf::Null(_)
            | Bsdf::TwoSided(_)
            | Bsdf::Mask(_)
            | Bsdf::Separable(_)
            | Bsdf::Composed(_)
            | Bsdf::Blend(_)
            | Bsdf::Perturbed(_)
            | Bsdf::Polarizer(_)
            | Bsdf::Principled(_)
            | Bsdf::PrincipledThin(_)
            | Bsdf::Retarder(_)
            | Bsdf::Circular(_)) => Err(other),
        }
    }
}

impl TwoSided {
    /// The model seen from `wo` and whether the frame is flipped for it.
    #[inline(always)]
    pub fn side(&self, wo: Vec3) -> (&OneSided, bool) {
        if wo.z >= 0.0 {
            (&self.front, false)
        } else {
            (&self.back, true)
        }
    }
}

#[inline(always)]
fn flip_z(v: Vec3) -> Vec3 {
    Vec3::new(v.x, v.y, -v.z)
}

impl BsdfModel for TwoSided {
    #[inline(always)]
    fn flags(&self, wo: Vec3) -> BsdfFlags {
        let (b, flip) = self.side(wo);
        b.flags(if flip { flip_z(wo) } else { wo })
    }

    #[inline(always)]
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        match self.side(wo) {
            (b, false) => b.eval(wo, wi),
            (b, true) => b.eval(flip_z(wo), flip_z(wi)),
        }
    }

    #[inline(always)]
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        match self.side(wo) {
            (b, false) => b.pdf(wo, wi),
            (b, true) => b.pdf(flip_z(wo), flip_z(wi)),
        }
    }

    #[inline(always)]
    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
        match self.side(wo) {
            (b, false) => b.eval_pdf(wo, wi),
            (b, true) => b.eval_pdf(flip_z(wo), flip_z(wi)),
        }
    }

    #[inline(always)]
    fn sample(&self, wo: Vec3, u1: f32, u2: [f32; 2]) -> Option<BsdfSample> {
        match self.side(wo) {
            (b, false) => b.sample(wo, u1, u2),
            (b, true) => {
                let s = b.sample(flip_z(wo), u1, u2)?;
                Some(BsdfSample {
                    wi: flip_z(s.wi),
                    ..s
                })
            }
        }
    }

    fn albedo(&self, wo: Vec3) -> Rgb {
        let (b, flip) = self.side(wo);
        b.albedo(if flip { flip_z(wo) } else { wo })
    }
}

/// Forwards every [`BsdfModel`] method to the variant's model.
macro_rules! dispatch {
    ($self:ident, $b:ident => $call:expr, $($variant:path),+) => {
        match $self {
            $($variant($b) => $call,)+
        }
    };
}

impl BsdfModel for OneSided {
    #[inline(always)]
    fn flags(&self, wo: Vec3) -> BsdfFlags {
        dispatch!(self, b => b.flags(wo), OneSided::Diffuse, OneSided::Conductor, OneSided::RoughConductor, OneSided::Plastic, OneSided::RoughPlastic, OneSided::PPlastic)
    }
    #[inline(always)]
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        dispatch!(self, b => b.eval(wo, wi), OneSided::Diffuse, OneSided::Conductor, OneSided::RoughConductor, OneSided::Plastic, OneSided::RoughPlastic, OneSided::PPlastic)
    }
    #[inline(always)]
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        dispatch!(self, b => b.pdf(wo, wi), OneSided::Diffuse, OneSided::Conductor, OneSided::RoughConductor, OneSided::Plastic, OneSided::RoughPlastic, OneSided::PPlastic)
    }
    #[inline(always)]
    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
        dispatch!(self, b => b.eval_pdf(wo, wi), OneSided::Diffuse, OneSided::Conductor, OneSided::RoughConductor, OneSided::Plastic, OneSided::RoughPlastic, OneSided::PPlastic)
    }
    #[inline(always)]
    fn sample(&self, wo: Vec3, u1: f32, u2: [f32; 2]) -> Option<BsdfSample> {
        dispatch!(self, b => b.sample(wo, u1, u2), OneSided::Diffuse, OneSided::Conductor, OneSided::RoughConductor, OneSided::Plastic, OneSided::RoughPlastic, OneSided::PPlastic)
    }
    fn albedo(&self, wo: Vec3) -> Rgb {
        dispatch!(self, b => b.albedo(wo), OneSided::Diffuse, OneSided::Conductor, OneSided::RoughConductor, OneSided::Plastic, OneSided::RoughPlastic, OneSided::PPlastic)
    }
}

impl BsdfModel for Bsdf {
    #[inline(always)]
    fn flags(&self, wo: Vec3) -> BsdfFlags {
        dispatch!(self, b => b.flags(wo),
            Bsdf::Diffuse, Bsdf::Dielectric, Bsdf::Conductor, Bsdf::RoughConductor, Bsdf::RoughDielectric, Bsdf::ThinDielectric, Bsdf::Plastic, Bsdf::RoughPlastic, Bsdf::Null, Bsdf::TwoSided, Bsdf::Mask, Bsdf::Separable, Bsdf::Composed, Bsdf::Blend, Bsdf::Perturbed, Bsdf::PPlastic, Bsdf::Polarizer, Bsdf::Principled, Bsdf::PrincipledThin, Bsdf::Retarder, Bsdf::Circular)
    }
    #[inline(always)]
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        dispatch!(self, b => b.eval(wo, wi),
            Bsdf::Diffuse, Bsdf::Dielectric, Bsdf::Conductor, Bsdf::RoughConductor, Bsdf::RoughDielectric, Bsdf::ThinDielectric, Bsdf::Plastic, Bsdf::RoughPlastic, Bsdf::Null, Bsdf::TwoSided, Bsdf::Mask, Bsdf::Separable, Bsdf::Composed, Bsdf::Blend, Bsdf::Perturbed, Bsdf::PPlastic, Bsdf::Polarizer, Bsdf::Principled, Bsdf::PrincipledThin, Bsdf::Retarder, Bsdf::Circular)
    }
    #[inline(always)]
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        dispatch!(self, b => b.pdf(wo, wi),
            Bsdf::Diffuse, Bsdf::Dielectric, Bsdf::Conductor, Bsdf::RoughConductor, Bsdf::RoughDielectric, Bsdf::ThinDielectric, Bsdf::Plastic, Bsdf::RoughPlastic, Bsdf::Null, Bsdf::TwoSided, Bsdf::Mask, Bsdf::Separable, Bsdf::Composed, Bsdf::Blend, Bsdf::Perturbed, Bsdf::PPlastic, Bsdf::Polarizer, Bsdf::Principled, Bsdf::PrincipledThin, Bsdf::Retarder, Bsdf::Circular)
    }
    #[inline(always)]
    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
        dispatch!(self, b => b.eval_pdf(wo, wi),
            Bsdf::Diffuse, Bsdf::Dielectric, Bsdf::Conductor, Bsdf::RoughConductor, Bsdf::RoughDielectric, Bsdf::ThinDielectric, Bsdf::Plastic, Bsdf::RoughPlastic, Bsdf::Null, Bsdf::TwoSided, Bsdf::Mask, Bsdf::Separable, Bsdf::Composed, Bsdf::Blend, Bsdf::Perturbed, Bsdf::PPlastic, Bsdf::Polarizer, Bsdf::Principled, Bsdf::PrincipledThin, Bsdf::Retarder, Bsdf::Circular)
    }
    #[inline(always)]
    fn sample(&self, wo: Vec3, u1: f32, u2: [f32; 2]) -> Option<BsdfSample> {
        dispatch!(self, b => b.sample(wo, u1, u2),
            Bsdf::Diffuse, Bsdf::Dielectric, Bsdf::Conductor, Bsdf::RoughConductor, Bsdf::RoughDielectric, Bsdf::ThinDielectric, Bsdf::Plastic, Bsdf::RoughPlastic, Bsdf::Null, Bsdf::TwoSided, Bsdf::Mask, Bsdf::Separable, Bsdf::Composed, Bsdf::Blend, Bsdf::Perturbed, Bsdf::PPlastic, Bsdf::Polarizer, Bsdf::Principled, Bsdf::PrincipledThin, Bsdf::Retarder, Bsdf::Circular)
    }
    /// Only rough dielectrics and `principled` with `spec_trans` refract through a
    /// non-delta lobe (also inside `mask` and `Separable`); every other model (the
    /// default, `principledthin` included) crosses no interface towards a light. A `Composed` vertex is resolved into a child before anyone asks.
    ///
    /// The common answer, 1, is inlined; the models that can refract (and those that
    /// wrap one) go through [`Bsdf::eta_refracting`], so that the recursion through
    /// wrappers does not keep this from inlining.
    #[inline(always)]
    fn eta(&self, wo: Vec3, wi: Vec3) -> f32 {
        match self {
            Bsdf::RoughDielectric(_)
            | Bsdf::Principled(_)
            | Bsdf::Mask(_)
            | Bsdf::Separable(_)
            | Bsdf::Blend(_)
            | Bsdf::Perturbed(_) => self.eta_refracting(wo, wi),
            _ => 1.0,
        }
    }
    fn albedo(&self, wo: Vec3) -> Rgb {
        dispatch!(self, b => b.albedo(wo),
            Bsdf::Diffuse, Bsdf::Dielectric, Bsdf::Conductor, Bsdf::RoughConductor, Bsdf::RoughDielectric, Bsdf::ThinDielectric, Bsdf::Plastic, Bsdf::RoughPlastic, Bsdf::Null, Bsdf::TwoSided, Bsdf::Mask, Bsdf::Separable, Bsdf::Composed, Bsdf::Blend, Bsdf::Perturbed, Bsdf::PPlastic, Bsdf::Polarizer, Bsdf::Principled, Bsdf::PrincipledThin, Bsdf::Retarder, Bsdf::Circular)
    }
}
