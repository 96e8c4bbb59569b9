//! `normalmap` and `bumpmap`: Mitsuba 3's `NormalMap` and `BumpMap`, a nested BSDF seen
//! in a perturbed shading frame (`src/bsdfs/normalmap.cpp`, `bumpmap.cpp`,
//! `normalmap_helpers.h`).
//!
//! | plugin | parameter | type | default | meaning |
//! |--------|-----------|------|---------|---------|
//! | normalmap | normalmap | texture (RGB) | required | tangent-space normal n = 2 rgb - 1 (read it `raw`) |
//! | bumpmap | (any name) | texture | required | a height field h(u, v); one nested `<texture>` |
//! | bumpmap | scale | float | 1 | h is multiplied by it |
//! | both | flip_invalid_normals | boolean | true | a perturbed normal facing away from `wo` is mirrored about the shading normal |
//! | both | use_shadowing_function | boolean | true | Estevez et al.'s shadowing term against the bump terminator |
//! | both | (nested) | bsdf | required | the BSDF in the perturbed frame |
//!
//! Both work in the local frame of the surface's Mitsuba shading frame (s along dp/du,
//! `Frame::from_normal_tangent`), so the integrator builds that frame for them and calls
//! [`Perturbed::resolve`] at each hit with the hit's geometry ([`HitGeometry`]); the
//! result is the perturbed frame `frame`, relative to the shading frame:
//! - normal map: n = normalize(2 rgb - 1), s = normalize(x - n n.x), t = n x s;
//! - bump map: with (h_u, h_v) = scale * grad h (the texture's `eval_1_grad`),
//!   dp/du' = dp/du + n_s (h_u - n_s . dp/du), dp/dv' likewise, n = normalize(dp/du' x
//!   dp/dv') turned to the geometric normal's side, then to local coordinates; s =
//!   normalize(dp/du - n (n . dp/du)) with dp/du in WORLD coordinates and n local,
//!   exactly as Mitsuba 3.9.1 writes it (this only turns the frame about n, which
//!   matters for an anisotropic nested BSDF alone), t = n x s.
//!
//! With `flip_invalid_normals`, where `wo.z (wo . n) <= 0` n becomes (-n.x, -n.y, n.z)
//! (before normalising, for the normal map).
//!
//! Then, with `wo'`, `wi'` the directions in the perturbed frame: eval = nested eval(wo',
//! wi') * S(wi), pdf = nested pdf(wo', wi'), both zero unless wi and wi' lie on the same
//! side (`wi.z wi'.z > 0`); sampling samples the nested BSDF in the perturbed frame and
//! multiplies its weight by S (a sample crossing sides is dropped). S(w) = 2 / (1 +
//! sqrt(1 + a^2 tan^2 theta_w)), a^2 = min(tan^2 theta_n / 8, 1), or 1 without the
//! shadowing function. No other correction (as Mitsuba: light may leak where the
//! perturbed hemisphere reaches below the surface).

use super::{Bsdf, BsdfFlags, BsdfModel, BsdfSample};
use crate::math::frame::Frame;
use crate::math::Rgb;
use crate::textures::Texture;
use glam::{Vec2, Vec3};

/// Where the perturbation comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum Perturbation {
    NormalMap(Texture),
    BumpMap { texture: Texture, scale: f32 },
}

#[derive(Clone, Debug, PartialEq)]
pub struct Perturbed {
    pub perturbation: Perturbation,
    pub flip_invalid_normals: bool,
    pub use_shadowing_function: bool,
    pub nested: Box<Bsdf>,
    /// The perturbed frame in the shading frame's coordinates (set per hit by
    /// [`Self::resolve`]; the identity until then).
    pub frame: Frame,
}

/// What a perturbation needs to know about a hit (world space unless said otherwise).
#[derive(Clone, Copy, Debug)]
pub struct HitGeometry {
    pub uv: Vec2,
    /// Mitsuba's shading frame (s from dp/du).
    pub shading: Frame,
    pub dpdu: Vec3,
    pub dpdv: Vec3,
    /// Geometric normal.
    pub ng: Vec3,
    /// The direction back along the incoming ray, in the shading frame.
    pub wo: Vec3,
}

/// The identity frame (the shading frame itself).
pub const IDENTITY: Frame = Frame {
    s: Vec3::X,
    t: Vec3::Y,
    n: Vec3::Z,
};

/// Mitsuba's `Frame::tan_theta_2`.
#[inline]
fn tan2(v: Vec3) -> f32 {
    (1.0 - v.z * v.z).max(0.0) / (v.z * v.z)
}

/// Estevez et al.'s shadowing term (`eval_shadow_terminator`): `n` the perturbed normal
/// and `w` a direction, both in the shading frame.
#[inline]
pub fn shadow_terminator(n: Vec3, w: Vec3) -> f32 {
    let a2 = (0.125 * tan2(n)).min(1.0);
    2.0 / (1.0 + (1.0 + a2 * tan2(w)).sqrt())
}

/// `n` mirrored about the shading normal where it faces away from `wo`.
#[inline]
fn flip_invalid(n: Vec3, wo: Vec3) -> Vec3 {
    if wo.z * wo.dot(n) <= 0.0 {
        Vec3::new(-n.x, -n.y, n.z)
    } else {
        n
    }
}

/// A frame around the local normal `n` with s = normalize(d - n (n . d)); the
/// normal's own frame where that is degenerate, the identity where `n` is.
fn frame_around(n: Vec3, d: Vec3) -> Frame {
    let Some(n) = n.try_normalize() else {
        return IDENTITY;
    };
    match (d - n * n.dot(d)).try_normalize() {
        Some(s) => Frame {
            s,
            t: n.cross(s),
            n,
        },
        None => Frame::from_normal(n),
    }
}

impl Perturbed {
    /// Sets `frame` for the hit `g`.
    pub fn resolve(&mut self, g: &HitGeometry) {
        self.frame = match &self.perturbation {
            Perturbation::NormalMap(texture) => {
                let mut n = texture.eval_rgb(g.uv) * 2.0 - Vec3::ONE;
                if self.flip_invalid_normals {
                    n = flip_invalid(n, g.wo);
                }
                match n.try_normalize() {
                    Some(n) => frame_around(n, Vec3::X),
                    None => IDENTITY,
                }
            }
            Perturbation::BumpMap { texture, scale } => {
                let grad = texture.eval_1_grad(g.uv) * *scale;
                let ns = g.shading.n;
                let dpdu = g.dpdu + ns * (grad.x - ns.dot(g.dpdu));
                let dpdv = g.dpdv + ns * (grad.y - ns.dot(g.dpdv));
                match dpdu.cross(dpdv).try_normalize() {
                    Some(mut n) => {
                        if g.ng.dot(n) < 0.0 {
                            n = -n;
                        }
                        let mut n = g.shading.to_local(n);
                        if self.flip_invalid_normals {
                            n = flip_invalid(n, g.wo);
                        }
                        // Mitsuba orthogonalises the world dp/du against the local n.
                        frame_around(n, g.dpdu)
                    }
                    None => IDENTITY,
                }
            }
        };
    }

    #[inline]
    fn shadow(&self, wi: Vec3) -> f32 {
        if self.use_shadowing_function {
            shadow_terminator(self.frame.n, wi)
        } else {
            1.0
        }
    }
}

impl BsdfModel for Perturbed {
    fn flags(&self, wo: Vec3) -> BsdfFlags {
        self.nested.flags(self.frame.to_local(wo))
    }

    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        let pi = self.frame.to_local(wi);
        if wi.z * pi.z <= 0.0 {
            return Rgb::ZERO;
        }
        self.nested.eval(self.frame.to_local(wo), pi) * self.shadow(wi)
    }

    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let pi = self.frame.to_local(wi);
        if wi.z * pi.z <= 0.0 {
            return 0.0;
        }
        self.nested.pdf(self.frame.to_local(wo), pi)
    }

    /// Both in the perturbed frame, the directions turned into it once.
    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
        let pi = self.frame.to_local(wi);
        if wi.z * pi.z <= 0.0 {
            return (Rgb::ZERO, 0.0);
        }
        let (e, p) = self.nested.eval_pdf(self.frame.to_local(wo), pi);
        (e * self.shadow(wi), p)
    }

    fn sample(&self, wo: Vec3, u1: f32, u2: [f32; 2]) -> Option<BsdfSample> {
        let s = self.nested.sample(self.frame.to_local(wo), u1, u2)?;
        if s.weight == Rgb::ZERO {
            return None;
        }
        let wi = self.frame.to_world(s.wi);
        if s.wi.z * wi.z <= 0.0 {
            return None;
        }
        Some(BsdfSample {
            wi,
            weight: s.weight * self.shadow(wi),
            ..s
        })
    }

    fn eta(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.nested
            .eta(self.frame.to_local(wo), self.frame.to_local(wi))
    }

    /// The nested BSDF's albedo from the perturbed `wo` (for the G-buffer; the
    /// shadowing term and the side test are left out).
    fn albedo(&self, wo: Vec3) -> Rgb {
        self.nested.albedo(self.frame.to_local(wo))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::materials::Diffuse;

    fn geometry(wo: Vec3) -> HitGeometry {
        HitGeometry {
            uv: Vec2::new(0.3, 0.6),
            shading: IDENTITY,
            dpdu: Vec3::X * 2.0,
            dpdv: Vec3::Y * 3.0,
            ng: Vec3::Z,
            wo,
        }
    }

    fn perturbed(p: Perturbation) -> Perturbed {
        Perturbed {
            perturbation: p,
            flip_invalid_normals: true,
            use_shadowing_function: true,
            nested: Box::new(Bsdf::Diffuse(Diffuse {
                reflectance: Rgb::ONE,
            })),
            frame: IDENTITY,
        }
    }

    #[test]
    fn a_flat_normal_map_and_a_flat_bump_map_change_nothing() {
        let wo = Vec3::new(0.3, -0.2, 0.9).normalize();
        for p in [
            Perturbation::NormalMap(Texture::Constant(Vec3::new(0.5, 0.5, 1.0))),
            Perturbation::BumpMap {
                texture: Texture::Constant(Vec3::splat(0.7)),
                scale: 5.0,
            },
        ] {
            let mut b = perturbed(p);
            b.resolve(&geometry(wo));
            assert!((b.frame.n - Vec3::Z).length() < 1e-6);
            assert!((b.frame.s - Vec3::X).length() < 1e-6);
            let wi = Vec3::new(-0.5, 0.1, 0.6).normalize();
            let want = wi.z / std::f32::consts::PI;
            assert!((b.eval(wo, wi).x - want).abs() < 1e-6);
        }
    }

    #[test]
    fn a_tilted_normal_turns_the_lobe_and_the_terminator_shadows() {
        // n = (0.6, 0, 0.8).
        let rgb = (Vec3::new(0.6, 0.0, 0.8) + Vec3::ONE) * 0.5;
        let mut b = perturbed(Perturbation::NormalMap(Texture::Constant(rgb)));
        let wo = Vec3::new(0.5, 0.0, 0.8).normalize();
        b.resolve(&geometry(wo));
        let n = Vec3::new(0.6, 0.0, 0.8);
        assert!((b.frame.n - n).length() < 1e-6);
        let wi = Vec3::new(0.2, 0.3, 0.9).normalize();
        let cos = wi.dot(n);
        // tan^2 theta_n = 0.36 / 0.64; S = 2 / (1 + sqrt(1 + a2 tan^2 theta_wi)).
        let a2 = 0.125 * 0.36 / 0.64;
        let t2 = (1.0 - wi.z * wi.z) / (wi.z * wi.z);
        let s = 2.0 / (1.0 + (1.0 + a2 * t2).sqrt());
        let want = cos / std::f32::consts::PI * s;
        assert!((b.eval(wo, wi).x - want).abs() < 1e-6);
        // Below the perturbed horizon but above the surface: zero.
        let wi = Vec3::new(-0.9, 0.0, 0.3).normalize();
        assert!(wi.dot(n) < 0.0 && b.eval(wo, wi) == Rgb::ZERO);
        // Seen from the side the normal leans away from, it is mirrored.
        let wo = Vec3::new(-0.9, 0.0, 0.2).normalize();
        b.resolve(&geometry(wo));
        assert!((b.frame.n - Vec3::new(-0.6, 0.0, 0.8)).length() < 1e-6);
        b.flip_invalid_normals = false;
        b.resolve(&geometry(wo));
        assert!((b.frame.n - n).length() < 1e-6);
    }

    #[test]
    fn a_bump_slope_tilts_the_normal_against_the_gradient() {
        use crate::textures::{Bitmap, FilterType, UvTransform, WrapMode};
        use std::sync::Arc;
        // A grey ramp of two texels: between their centres h rises by 1 over half of u,
        // so dh/du = 2 (Mitsuba's eval_1_grad), times the scale 0.25.
        let texture = Texture::Bitmap(Arc::new(Bitmap {
            width: 2,
            height: 1,
            channels: 1,
            data: vec![0.0, 1.0],
            filter: FilterType::Bilinear,
            wrap: WrapMode::Clamp,
            to_uv: UvTransform::IDENTITY,
        }));
        let mut b = perturbed(Perturbation::BumpMap {
            texture,
            scale: 0.25,
        });
        let mut g = geometry(Vec3::Z);
        g.uv = Vec2::new(0.5, 0.5);
        b.resolve(&g);
        // dp/du' = (2, 0, 0.5), dp/dv' = (0, 3, 0): n ~ (-1.5, 0, 6).
        let n = Vec3::new(-1.5, 0.0, 6.0).normalize();
        assert!((b.frame.n - n).length() < 1e-6, "{}", b.frame.n);
        assert!(b.frame.s.dot(n).abs() < 1e-6 && b.frame.s.x > 0.9);
    }
}
