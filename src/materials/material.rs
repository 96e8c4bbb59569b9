//! A surface's material: a BSDF and, where its parameters are textures, the textures
//! that set them at each hit. The integrator resolves a textured material into a plain
//! BSDF at the hit's uv ([`Material::at`]); untextured materials are used as they are
//! and never ask for uv.
//!
//! Parameters that accept a texture today: `diffuse`'s `reflectance` (also inside
//! `twosided`).

use super::{Bsdf, OneSided};
use crate::textures::Texture;
use glam::Vec2;

/// Which diffuse model a texture sets: the material's own, or a side of `twosided`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    Only,
    Front,
    Back,
}

/// A textured `reflectance`.
#[derive(Clone, Debug, PartialEq)]
pub struct Binding {
    pub side: Side,
    pub texture: Texture,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// The BSDF with its constant parameters (textured ones hold a placeholder).
    pub bsdf: Bsdf,
    pub bindings: Vec<Binding>,
}

impl Material {
    pub fn plain(bsdf: Bsdf) -> Self {
        Material {
            bsdf,
            bindings: Vec::new(),
        }
    }

    /// Whether the BSDF varies over the surface (then [`Self::at`] needs the hit's uv).
    #[inline(always)]
    pub fn is_textured(&self) -> bool {
        !self.bindings.is_empty()
    }

    /// The BSDF at surface coordinates `uv`.
    pub fn at(&self, uv: Vec2) -> Bsdf {
        let mut b = self.bsdf.clone();
        for binding in &self.bindings {
            let value = binding.texture.eval_rgb(uv);
            match (&mut b, binding.side) {
                (Bsdf::Diffuse(d), Side::Only) => d.reflectance = value,
                (Bsdf::TwoSided(t), Side::Front) => {
                    if let OneSided::Diffuse(d) = &mut t.front {
                        d.reflectance = value;
                    }
                }
                (Bsdf::TwoSided(t), Side::Back) => {
                    if let OneSided::Diffuse(d) = &mut t.back {
                        d.reflectance = value;
                    }
                }
                // The parser only binds textures to the diffuse models above.
                _ => {}
            }
        }
        b
    }
}
