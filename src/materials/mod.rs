//! BSDFs: the closed set of surface scattering models, dispatched with `match`.
//!
//! Conventions (as in Mitsuba 3): directions are in the local shading frame (normal +z);
//! `wo` points back along the incoming ray (towards the camera side of the path), `wi`
//! is the sampled or queried direction towards the light. `eval` returns f * |cos(wi)|.
//! BSDFs are one-sided: `wo.z <= 0` is black, except for dielectrics and `twosided`.

mod conductor;
mod dielectric;
mod diffuse;
pub mod fresnel;
pub mod parse;

pub use conductor::Conductor;
pub use dielectric::Dielectric;
pub use diffuse::Diffuse;

use crate::math::Rgb;
use glam::Vec3;

/// The result of sampling a BSDF.
#[derive(Clone, Copy, Debug)]
pub struct BsdfSample {
    pub wi: Vec3,
    /// f * |cos(wi)| / pdf (1 x reflectance for delta lobes).
    pub weight: Rgb,
    /// Solid-angle density (meaningless for delta lobes, kept 1 there).
    pub pdf: f32,
    pub delta: bool,
    /// Relative IOR crossed (1 unless transmitted through a dielectric interface).
    pub eta: f32,
}

#[derive(Clone, Debug, PartialEq)]
pub enum Bsdf {
    Diffuse(Diffuse),
    Dielectric(Dielectric),
    Conductor(Conductor),
    /// Front and back BSDFs (Mitsuba's `twosided`): the back is seen with the frame flipped.
    TwoSided(Box<Bsdf>, Box<Bsdf>),
}

impl Bsdf {
    /// Resolves `twosided` for this `wo`: the BSDF to use and whether to flip z.
    #[inline]
    fn side(&self, wo: Vec3) -> (&Bsdf, bool) {
        match self {
            Bsdf::TwoSided(front, back) => {
                if wo.z >= 0.0 {
                    (front.side(wo).0, false)
                } else {
                    (back.side(-wo).0, true)
                }
            }
            other => (other, false),
        }
    }

    /// True when every lobe seen from `wo` is a delta (no NEE possible).
    #[inline]
    pub fn is_delta(&self, wo: Vec3) -> bool {
        match self.side(wo).0 {
            Bsdf::Diffuse(_) => false,
            Bsdf::Dielectric(_) | Bsdf::Conductor(_) => true,
            Bsdf::TwoSided(..) => unreachable!("side() resolves twosided"),
        }
    }

    /// Diffuse albedo seen from `wo` (for the G-buffer); delta BSDFs report their
    /// reflectance at normal incidence only through the chain they start.
    pub fn albedo(&self, wo: Vec3) -> Rgb {
        let (b, flip) = self.side(wo);
        let wo = if flip { flip_z(wo) } else { wo };
        match b {
            // The back of a one-sided surface renders black: its albedo is 0.
            Bsdf::Diffuse(d) if wo.z > 0.0 => d.reflectance,
            _ => Rgb::ZERO,
        }
    }

    #[inline(always)]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        let (b, flip) = self.side(wo);
        let (wo, wi) = if flip {
            (flip_z(wo), flip_z(wi))
        } else {
            (wo, wi)
        };
        match b {
            Bsdf::Diffuse(d) => d.eval(wo, wi),
            Bsdf::Dielectric(_) | Bsdf::Conductor(_) => Rgb::ZERO,
            Bsdf::TwoSided(..) => unreachable!("side() resolves twosided"),
        }
    }

    #[inline(always)]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let (b, flip) = self.side(wo);
        let (wo, wi) = if flip {
            (flip_z(wo), flip_z(wi))
        } else {
            (wo, wi)
        };
        match b {
            Bsdf::Diffuse(d) => d.pdf(wo, wi),
            Bsdf::Dielectric(_) | Bsdf::Conductor(_) => 0.0,
            Bsdf::TwoSided(..) => unreachable!("side() resolves twosided"),
        }
    }

    /// Samples `wi` with two uniform numbers in [0, 1) (`u1` picks a lobe).
    #[inline(always)]
    pub fn sample(&self, wo: Vec3, u1: f32, u2: [f32; 2]) -> Option<BsdfSample> {
        let (b, flip) = self.side(wo);
        let wo = if flip { flip_z(wo) } else { wo };
        let s = match b {
            Bsdf::Diffuse(d) => d.sample(wo, u2),
            Bsdf::Dielectric(d) => d.sample(wo, u1),
            Bsdf::Conductor(c) => c.sample(wo),
            Bsdf::TwoSided(..) => unreachable!("side() resolves twosided"),
        }?;
        Some(if flip {
            BsdfSample {
                wi: flip_z(s.wi),
                ..s
            }
        } else {
            s
        })
    }
}

#[inline]
fn flip_z(v: Vec3) -> Vec3 {
    Vec3::new(v.x, v.y, -v.z)
}
