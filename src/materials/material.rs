//! A surface's material: a BSDF and, where its parameters are textures, the textures
//! that set them at each hit. The integrator resolves a textured material into a plain
//! BSDF at the hit's uv ([`Material::at`]); untextured materials are used as they are
//! and never ask for uv.
//!
//! Every colour or float parameter that Mitsuba 3 reads as a texture accepts one here
//! (the [`Param`]s below; which model has which is in each model's file and in
//! docs/scenes.md). A binding names the parameter and the path to the model that owns it
//! (through `twosided`'s sides and `mask`'s nested BSDF).
//!
//! Values read from a texture are kept physical at the hit: colours are clamped to be
//! non-negative, opacity to [0, 1] (as Mitsuba clips it), roughness to [1e-4, 10] (the
//! range a constant may take; Mitsuba would produce NaNs at 0).

use super::lift::ColourKind;
use super::{Bsdf, OneSided, TemporalProfile};
use crate::spectral::curve::Curve;
use crate::textures::{TexPoint, Texture};
use glam::{Vec2, Vec3};

/// A texturable parameter.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Param {
    /// `diffuse`'s reflectance.
    Reflectance,
    /// `plastic`'s (and `roughplastic`'s) base colour.
    DiffuseReflectance,
    SpecularReflectance,
    SpecularTransmittance,
    /// A conductor's real IOR.
    Eta,
    /// A conductor's extinction coefficient.
    K,
    /// Microfacet roughness (isotropic: both axes).
    Alpha,
    /// Anisotropic microfacet roughness along the shading frame's s axis (dp/du) and
    /// t axis.
    AlphaU,
    AlphaV,
    /// `mask`'s opacity.
    Opacity,
    /// `blendbsdf`'s weight (clipped to [0, 1]).
    Weight,
    /// `pplastic`'s relative IOR `eta` (and `principledthin`'s).
    RelativeEta,
    /// `polarizer`'s, `retarder`'s and `circular`'s transmittance.
    Transmittance,
    /// `polarizer`'s and `retarder`'s axis angle in degrees (not clamped).
    Theta,
    /// `retarder`'s retardance `delta` in degrees (not clamped).
    Retardance,
    /// Temporal profile parameters of `Separable` (`ConstantTP`'s delay,
    /// `ExponentialTP`'s lambda, `EpanechnikovTP`'s mu and sigma).
    Delay,
    Lambda,
    Mu,
    Sigma,
    /// `principled`'s and `principledthin`'s parameters (`principled.rs`,
    /// `principled_thin.rs`); the thin model's IOR is [`Param::RelativeEta`].
    BaseColor,
    Roughness,
    Anisotropic,
    Metallic,
    SpecTrans,
    SpecTint,
    Sheen,
    SheenTint,
    Flatness,
    Clearcoat,
    ClearcoatGloss,
    DiffTrans,
}

impl Param {
    /// How a colour parameter becomes a spectrum (`materials::lift`); `None` for
    /// scalar parameters.
    pub fn colour_kind(self) -> Option<ColourKind> {
        match self {
            Param::Eta | Param::K => Some(ColourKind::Unbounded),
            p if p.is_scalar() => None,
            _ => Some(ColourKind::Bounded),
        }
    }

    /// Scalar parameters read the texture's one-channel value (Mitsuba's `eval_1`).
    fn is_scalar(self) -> bool {
        matches!(
            self,
            Param::Alpha
                | Param::Theta
                | Param::Retardance
                | Param::AlphaU
                | Param::AlphaV
                | Param::Opacity
                | Param::Weight
                | Param::RelativeEta
                | Param::Delay
                | Param::Lambda
                | Param::Mu
                | Param::Sigma
                | Param::Roughness
                | Param::Anisotropic
                | Param::Metallic
                | Param::SpecTrans
                | Param::SpecTint
                | Param::Sheen
                | Param::SheenTint
                | Param::Flatness
                | Param::Clearcoat
                | Param::ClearcoatGloss
                | Param::DiffTrans
        )
    }
}

/// One step from a BSDF to a model inside it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Step {
    Front,
    Back,
    /// `mask`'s, `Separable`'s, `normalmap`'s or `bumpmap`'s nested BSDF.
    Nested,
    /// `Composed`'s or `blendbsdf`'s children.
    First,
    Second,
}

/// A textured parameter of the model at `path`.
#[derive(Clone, Debug, PartialEq)]
pub struct Binding {
    pub path: Vec<Step>,
    pub param: Param,
    pub texture: Texture,
}

/// A colour parameter of the model at `path` given as a spectrum (`<spectrum>`), which
/// the spectral mode uses as given at a path's wavelengths, as Mitsuba's spectral
/// variants do ([`Material::set_spectra`]). The BSDF holds the spectrum's RGB.
#[derive(Clone, Debug, PartialEq)]
pub struct SpectralParam {
    pub path: Vec<Step>,
    pub param: Param,
    pub curve: Curve,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// The BSDF with its constant parameters (textured ones hold a placeholder).
    pub bsdf: Bsdf,
    pub bindings: Vec<Binding>,
    /// Colour parameters given as spectra, for the spectral mode (empty in the other
    /// modes, which read them as their RGB in `bsdf`).
    pub spectra: Vec<SpectralParam>,
    /// Neither textured, nor composed, nor delaying: the integrator uses `bsdf` as it
    /// is, with one branch (the common case pays nothing for the others).
    plain: bool,
    /// Some model inside is anisotropic (alpha_u != alpha_v, or either textured) or
    /// perturbs the frame: the integrator builds this material's shading frames from
    /// dp/du.
    anisotropic: bool,
    /// A `normalmap` or `bumpmap` inside: each hit sets its frame.
    perturbs: bool,
    /// A colour parameter is bound to a texture that filters RGB texels
    /// (`Texture::filters_colours`): the spectral mode lifts its texels one by one
    /// ([`Self::set_texel_spectra`]).
    filters_colours: bool,
}

impl Material {
    pub fn new(bsdf: Bsdf, bindings: Vec<Binding>) -> Self {
        let perturbs = bsdf.perturbs();
        let plain = bindings.is_empty()
            && !perturbs
            && !matches!(bsdf, Bsdf::Composed(_) | Bsdf::Separable(_));
        let anisotropic = bsdf.anisotropic()
            || perturbs
            || bindings
                .iter()
                .any(|b| matches!(b.param, Param::AlphaU | Param::AlphaV | Param::Anisotropic));
        let filters_colours = bindings
            .iter()
            .any(|b| b.param.colour_kind().is_some() && b.texture.filters_colours());
        Material {
            bsdf,
            bindings,
            spectra: Vec::new(),
            plain,
            anisotropic,
            perturbs,
            filters_colours,
        }
    }

    pub fn plain(bsdf: Bsdf) -> Self {
        Self::new(bsdf, Vec::new())
    }

    /// The material with colour parameters given as spectra (see [`SpectralParam`]).
    pub fn with_spectra(mut self, spectra: Vec<SpectralParam>) -> Self {
        self.spectra = spectra;
        self
    }

    /// See the `filters_colours` field.
    #[inline(always)]
    pub fn filters_colours(&self) -> bool {
        self.filters_colours
    }

    /// Sets every colour parameter of `b` (this material at the surface point `p`)
    /// whose texture filters RGB texels (a bilinear RGB bitmap) to the filter of its
    /// texels each mapped by `lift(kind, texel)`, instead of `lift` of the filtered
    /// colour: the spectral mode lifts the four texels of a bilinear lookup and
    /// interpolates the spectra, as Mitsuba's bitmap (`interpolate_spectral`) does.
    pub fn set_texel_spectra(
        &self,
        b: &mut Bsdf,
        p: &TexPoint,
        lift: &impl Fn(ColourKind, Vec3) -> Vec3,
    ) {
        for binding in &self.bindings {
            if let Some(kind) = binding.param.colour_kind() {
                if binding.texture.filters_colours() {
                    let v = binding
                        .texture
                        .eval_mapped_at(p, &|c: Vec3| lift(kind, c.max(Vec3::ZERO)));
                    set(b, &binding.path, binding.param, v);
                }
            }
        }
    }

    /// Sets every colour parameter given as a spectrum in `b` (this material at a hit,
    /// its colours lifted to the wavelengths `lambda` nm) to the spectrum's values at
    /// `lambda`, as given (Mitsuba's `uniform` and `irregular` spectra; clamped to be
    /// non-negative like every colour set here, which the loader already requires).
    #[inline]
    pub fn set_spectra(&self, b: &mut Bsdf, lambda: [f32; 3]) {
        for s in &self.spectra {
            let v = Vec3::from_array(lambda.map(|l| s.curve.eval(l)));
            set(b, &s.path, s.param, v);
        }
    }

    /// See the `plain` field.
    #[inline(always)]
    pub fn is_plain(&self) -> bool {
        self.plain
    }

    /// Whether a model inside (through twosided, mask, Separable, Composed, blendbsdf,
    /// normalmap and bumpmap) has anisotropic roughness, constant or textured, or
    /// perturbs the frame (normal and bump maps live in Mitsuba's tangent frame): then
    /// the shading frame must be built from the surface's dp/du
    /// (`Frame::from_normal_tangent`); every other material keeps
    /// `Frame::from_normal`, whose orientation in the tangent plane does not matter.
    #[inline(always)]
    pub fn is_anisotropic(&self) -> bool {
        self.anisotropic
    }

    /// Whether a `normalmap` or `bumpmap` inside needs [`Bsdf::resolve_frames`] at
    /// each hit (never for plain materials).
    #[inline(always)]
    pub fn perturbs(&self) -> bool {
        self.perturbs
    }

    /// Whether the BSDF varies over the surface (then [`Self::at`] needs the hit's uv).
    #[inline(always)]
    pub fn is_textured(&self) -> bool {
        !self.bindings.is_empty()
    }

    /// The BSDF at surface coordinates `uv` (no mesh attributes).
    pub fn at(&self, uv: Vec2) -> Bsdf {
        self.at_point(&TexPoint::uv(uv))
    }

    /// The BSDF at a surface point: uv and, for `mesh_attribute` textures, the hit's
    /// triangle on a mesh with attributes (`TexPoint::on`).
    pub fn at_point(&self, p: &TexPoint) -> Bsdf {
        let mut b = self.bsdf.clone();
        for binding in &self.bindings {
            let value = if binding.param.is_scalar() {
                Vec3::splat(binding.texture.eval_float_at(p))
            } else {
                binding.texture.eval_rgb_at(p)
            };
            set(&mut b, &binding.path, binding.param, value);
        }
        b
    }

    /// The attribute names the material's `mesh_attribute` textures read (checked
    /// against each shape that uses the material when the scene loads).
    pub fn mesh_attribute_names(&self) -> Vec<&str> {
        let mut out = Vec::new();
        for b in &self.bindings {
            if let Texture::MeshAttribute(m) = &b.texture {
                out.push(&*m.name);
            }
        }
        out
    }
}

/// Sets `param` of the model at `path` inside `b` (paths and parameters come from the
/// parser, which binds only what the model has).
fn set(b: &mut Bsdf, path: &[Step], param: Param, v: Vec3) {
    match (b, path) {
        (Bsdf::TwoSided(t), [Step::Front]) => set_one_sided(&mut t.front, param, v),
        (Bsdf::TwoSided(t), [Step::Back]) => set_one_sided(&mut t.back, param, v),
        (Bsdf::Mask(m), [Step::Nested, rest @ ..]) => set(&mut m.nested, rest, param, v),
        (Bsdf::Separable(s), [Step::Nested, rest @ ..]) => set(&mut s.inner, rest, param, v),
        (Bsdf::Composed(c), [Step::First, rest @ ..]) => set(&mut c.first, rest, param, v),
        (Bsdf::Composed(c), [Step::Second, rest @ ..]) => set(&mut c.second, rest, param, v),
        (Bsdf::Blend(c), [Step::First, rest @ ..]) => set(&mut c.first, rest, param, v),
        (Bsdf::Blend(c), [Step::Second, rest @ ..]) => set(&mut c.second, rest, param, v),
        (Bsdf::Perturbed(p), [Step::Nested, rest @ ..]) => set(&mut p.nested, rest, param, v),
        (b, []) => set_model(b, param, v),
        _ => debug_assert!(false, "binding path {path:?} does not fit the BSDF"),
    }
}

fn set_one_sided(b: &mut OneSided, param: Param, v: Vec3) {
    let mut whole = Bsdf::from(b.clone());
    set_model(&mut whole, param, v);
    if let Ok(one) = OneSided::try_from(whole) {
        *b = one;
    }
}

fn set_model(b: &mut Bsdf, param: Param, v: Vec3) {
    let colour = v.max(Vec3::ZERO);
    let alpha = v.x.clamp(1e-4, 10.0);
    match (b, param) {
        (Bsdf::Diffuse(d), Param::Reflectance) => d.reflectance = colour,
        (Bsdf::Dielectric(d), Param::SpecularReflectance) => d.specular_reflectance = colour,
        (Bsdf::Dielectric(d), Param::SpecularTransmittance) => d.specular_transmittance = colour,
        (Bsdf::ThinDielectric(d), Param::SpecularReflectance) => d.specular_reflectance = colour,
        (Bsdf::ThinDielectric(d), Param::SpecularTransmittance) => {
            d.specular_transmittance = colour
        }
        (Bsdf::Conductor(c), Param::SpecularReflectance) => c.specular_reflectance = colour,
        (Bsdf::Conductor(c), Param::Eta) => c.eta = colour,
        (Bsdf::Conductor(c), Param::K) => c.k = colour,
        (Bsdf::RoughConductor(c), Param::SpecularReflectance) => c.specular_reflectance = colour,
        (Bsdf::RoughConductor(c), Param::Eta) => c.eta = colour,
        (Bsdf::RoughConductor(c), Param::K) => c.k = colour,
        (Bsdf::RoughConductor(c), Param::Alpha) => {
            c.distribution.alpha_u = alpha;
            c.distribution.alpha_v = alpha;
        }
        (Bsdf::RoughConductor(c), Param::AlphaU) => c.distribution.alpha_u = alpha,
        (Bsdf::RoughConductor(c), Param::AlphaV) => c.distribution.alpha_v = alpha,
        (Bsdf::RoughDielectric(d), Param::SpecularReflectance) => d.specular_reflectance = colour,
        (Bsdf::RoughDielectric(d), Param::SpecularTransmittance) => {
            d.specular_transmittance = colour
        }
        (Bsdf::RoughDielectric(d), Param::Alpha) => {
            d.distribution.alpha_u = alpha;
            d.distribution.alpha_v = alpha;
        }
        (Bsdf::RoughDielectric(d), Param::AlphaU) => d.distribution.alpha_u = alpha,
        (Bsdf::RoughDielectric(d), Param::AlphaV) => d.distribution.alpha_v = alpha,
        (Bsdf::Plastic(p), Param::DiffuseReflectance) => *p = p.with_diffuse_reflectance(colour),
        (Bsdf::Plastic(p), Param::SpecularReflectance) => *p = p.with_specular_reflectance(colour),
        (Bsdf::RoughPlastic(p), Param::DiffuseReflectance) => {
            *p = p.with_diffuse_reflectance(colour)
        }
        (Bsdf::RoughPlastic(p), Param::SpecularReflectance) => {
            *p = p.with_specular_reflectance(colour)
        }
        (Bsdf::Mask(m), Param::Opacity) => m.opacity = v.x.clamp(0.0, 1.0),
        (Bsdf::Blend(b), Param::Weight) => b.weight = v.x.clamp(0.0, 1.0),
        (Bsdf::Polarizer(p), Param::Transmittance) => p.transmittance = colour,
        (Bsdf::Polarizer(p), Param::Theta) => p.theta = v.x,
        (Bsdf::Retarder(r), Param::Transmittance) => r.transmittance = colour,
        (Bsdf::Retarder(r), Param::Theta) => r.theta = v.x,
        (Bsdf::Retarder(r), Param::Retardance) => r.delta = v.x,
        (Bsdf::Circular(c), Param::Transmittance) => c.transmittance = colour,
        (Bsdf::PPlastic(p), Param::DiffuseReflectance) => p.diffuse_reflectance = colour,
        (Bsdf::PPlastic(p), Param::SpecularReflectance) => p.specular_reflectance = colour,
        // Kept away from 1 (no interface) and from 0, as a constant's range.
        (Bsdf::PPlastic(p), Param::RelativeEta) => {
            p.eta = if v.x > 0.0 && v.x.is_finite() {
                v.x.clamp(1e-6, 1e6)
            } else {
                1.0
            }
        }
        (Bsdf::PPlastic(p), Param::Alpha) => {
            p.distribution.alpha_u = alpha;
            p.distribution.alpha_v = alpha;
        }
        (Bsdf::PPlastic(p), Param::AlphaU) => p.distribution.alpha_u = alpha,
        (Bsdf::PPlastic(p), Param::AlphaV) => p.distribution.alpha_v = alpha,
        (Bsdf::Principled(p), param) => set_principled(p, param, v),
        (Bsdf::PrincipledThin(p), param) => set_principled_thin(p, param, v),
        // Profile parameters are kept in their domain when a delay is drawn
        // (`Separable::sample_delay`).
        (Bsdf::Separable(s), param) => match (&mut s.profile, param) {
            (TemporalProfile::Constant { delay }, Param::Delay) => *delay = v.x,
            (TemporalProfile::Exponential { lambda }, Param::Lambda) => *lambda = v.x,
            (TemporalProfile::Epanechnikov { mu, .. }, Param::Mu) => *mu = v.x,
            (TemporalProfile::Epanechnikov { sigma, .. }, Param::Sigma) => *sigma = v.x,
            _ => debug_assert!(false, "{param:?} is not a parameter of this profile"),
        },
        (_, param) => debug_assert!(false, "{param:?} is not a parameter of this BSDF"),
    }
}

/// A weight read from a texture, clamped to the range a constant may take ([0, 1]; NaN
/// becomes 0), which keeps every lobe weight non-negative.
fn unit(x: f32) -> f32 {
    if x.is_nan() {
        0.0
    } else {
        x.clamp(0.0, 1.0)
    }
}

fn set_principled(p: &mut super::Principled, param: Param, v: Vec3) {
    let x = unit(v.x);
    match param {
        Param::BaseColor => p.base_color = v.max(Vec3::ZERO),
        Param::Roughness => p.roughness = x,
        Param::Anisotropic => p.anisotropic = x,
        Param::Metallic => p.metallic = x,
        Param::SpecTrans => p.spec_trans = x,
        Param::SpecTint => p.spec_tint = x,
        Param::Sheen => p.sheen = x,
        Param::SheenTint => p.sheen_tint = x,
        Param::Flatness => p.flatness = x,
        Param::Clearcoat => p.clearcoat = x,
        Param::ClearcoatGloss => p.clearcoat_gloss = x,
        _ => debug_assert!(false, "{param:?} is not a parameter of principled"),
    }
}

fn set_principled_thin(p: &mut super::PrincipledThin, param: Param, v: Vec3) {
    let x = unit(v.x);
    match param {
        Param::BaseColor => p.base_color = v.max(Vec3::ZERO),
        Param::Roughness => p.roughness = x,
        Param::Anisotropic => p.anisotropic = x,
        Param::SpecTrans => p.spec_trans = x,
        Param::SpecTint => p.spec_tint = x,
        Param::Sheen => p.sheen = x,
        Param::SheenTint => p.sheen_tint = x,
        Param::Flatness => p.flatness = x,
        // diff_trans runs over [0, 2] (Mitsuba halves it).
        Param::DiffTrans => p.diff_trans = 2.0 * unit(v.x / 2.0),
        // The sheet's IOR, kept positive as a constant's range.
        Param::RelativeEta => {
            p.eta = if v.x > 0.0 && v.x.is_finite() {
                v.x.clamp(1e-6, 1e6)
            } else {
                1.0
            }
        }
        _ => debug_assert!(false, "{param:?} is not a parameter of principledthin"),
    }
}

impl From<OneSided> for Bsdf {
    fn from(b: OneSided) -> Self {
        match b {
            OneSided::Diffuse(d) => Bsdf::Diffuse(d),
            OneSided::Conductor(c) => Bsdf::Conductor(c),
            OneSided::RoughConductor(c) => Bsdf::RoughConductor(c),
            OneSided::Plastic(p) => Bsdf::Plastic(p),
            OneSided::RoughPlastic(p) => Bsdf::RoughPlastic(p),
            OneSided::PPlastic(p) => Bsdf::PPlastic(p),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::materials::{Diffuse, Mask, Plastic, TwoSided};
    use crate::math::Rgb;
    use crate::textures::Checkerboard;

    fn checker(a: Vec3, b: Vec3) -> Texture {
        Texture::Checkerboard(Checkerboard {
            color0: Box::new(Texture::Constant(a)),
            color1: Box::new(Texture::Constant(b)),
            ..Checkerboard::default()
        })
    }

    #[test]
    fn bindings_reach_through_mask_and_twosided() {
        let diffuse = OneSided::Diffuse(Diffuse {
            reflectance: Rgb::splat(0.5),
        });
        let m = Material::new(
            Bsdf::Mask(Mask {
                opacity: 0.5,
                nested: Box::new(Bsdf::TwoSided(TwoSided {
                    front: diffuse.clone(),
                    back: diffuse,
                })),
            }),
            vec![
                Binding {
                    path: vec![Step::Nested, Step::Back],
                    param: Param::Reflectance,
                    texture: checker(Vec3::X, Vec3::Y),
                },
                Binding {
                    path: vec![],
                    param: Param::Opacity,
                    // Scalar lookups of a checkerboard swap its cells (Mitsuba's
                    // eval_1): at (0.25, 0.25) this is color1's luminance 0.0 -> 0.
                    texture: checker(Vec3::splat(1.0), Vec3::splat(-3.0)),
                },
            ],
        );
        let Bsdf::Mask(at) = m.at(Vec2::new(0.25, 0.25)) else {
            panic!()
        };
        // Opacity: luminance(-3) clamped to 0.
        assert_eq!(at.opacity, 0.0);
        let Bsdf::TwoSided(t) = *at.nested else {
            panic!()
        };
        assert_eq!(
            t.back,
            OneSided::Diffuse(Diffuse {
                reflectance: Vec3::X
            })
        );
        // The front side keeps its constant.
        assert_eq!(
            t.front,
            OneSided::Diffuse(Diffuse {
                reflectance: Rgb::splat(0.5)
            })
        );
    }

    #[test]
    fn blend_weights_are_clipped_and_bindings_reach_inside_normal_maps() {
        use crate::materials::{Blend, Perturbation, Perturbed};
        let d = |r: f32| {
            Bsdf::Diffuse(Diffuse {
                reflectance: Rgb::splat(r),
            })
        };
        let m = Material::new(
            Bsdf::Blend(Blend {
                weight: 0.5,
                first: Box::new(d(0.1)),
                second: Box::new(Bsdf::Perturbed(Perturbed {
                    perturbation: Perturbation::NormalMap(Texture::Constant(Vec3::Z)),
                    flip_invalid_normals: true,
                    use_shadowing_function: true,
                    nested: Box::new(d(0.2)),
                    frame: crate::materials::perturbed::IDENTITY,
                })),
            }),
            vec![
                Binding {
                    path: vec![],
                    param: Param::Weight,
                    // eval_1 at (0.25, 0.25): color1's luminance, 3 -> clipped to 1.
                    texture: checker(Vec3::splat(-1.0), Vec3::splat(3.0)),
                },
                Binding {
                    path: vec![Step::Second, Step::Nested],
                    param: Param::Reflectance,
                    texture: checker(Vec3::X, Vec3::Y),
                },
            ],
        );
        assert!(m.perturbs() && m.is_anisotropic() && !m.is_plain());
        let Bsdf::Blend(b) = m.at(Vec2::new(0.25, 0.25)) else {
            panic!()
        };
        assert_eq!(b.weight, 1.0);
        let Bsdf::Perturbed(p) = *b.second else {
            panic!()
        };
        assert_eq!(
            *p.nested,
            Bsdf::Diffuse(Diffuse {
                reflectance: Vec3::X
            })
        );
        let Bsdf::Blend(b) = m.at(Vec2::new(0.75, 0.25)) else {
            panic!()
        };
        assert_eq!(b.weight, 0.0);
    }

    #[test]
    fn textured_plastic_equals_the_plastic_built_with_that_colour() {
        let base = Plastic::new(1.49, Rgb::splat(0.5), Rgb::ONE, true);
        let m = Material::new(
            Bsdf::Plastic(base),
            vec![Binding {
                path: vec![],
                param: Param::DiffuseReflectance,
                texture: checker(Vec3::new(0.8, 0.2, 0.1), Vec3::ZERO),
            }],
        );
        assert_eq!(
            m.at(Vec2::new(0.1, 0.1)),
            Bsdf::Plastic(Plastic::new(1.49, Rgb::new(0.8, 0.2, 0.1), Rgb::ONE, true))
        );
    }

    /// The spectral mode's per-texel lift (`set_texel_spectra`), with the spectral
    /// mode's own reflectance lift: halfway between a red and a green texel of a
    /// bilinear bitmap, a diffuse reflectance is the mean of the two texels' spectra
    /// (Mitsuba's `interpolate_spectral`), which differs from the spectrum of the
    /// interpolated colour (1/2, 1/2, 0) by more than 0.05 at some wavelength; a
    /// constant and a nearest-filtered binding are left as lifted.
    #[test]
    fn texels_are_lifted_before_the_bilinear_filter() {
        use crate::spectral::lift::Wavelengths;
        use crate::textures::bitmap::{Bitmap, FilterType, WrapMode};
        use crate::textures::UvTransform;
        use std::sync::Arc;
        let image = |filter| {
            Texture::Bitmap(Arc::new(Bitmap {
                width: 2,
                height: 1,
                channels: 3,
                data: vec![1.0, 0.0, 0.0, 0.0, 1.0, 0.0],
                filter,
                wrap: WrapMode::Clamp,
                to_uv: UvTransform::IDENTITY,
            }))
        };
        let diffuse = Bsdf::Diffuse(Diffuse {
            reflectance: Vec3::splat(0.5),
        });
        let m = Material::new(
            diffuse.clone(),
            vec![Binding {
                path: vec![],
                param: Param::Reflectance,
                texture: image(FilterType::Bilinear),
            }],
        );
        assert!(m.filters_colours());
        let p = TexPoint::uv(Vec2::new(0.5, 0.5));
        let mut worst = 0.0f32;
        for u in [0.05, 0.2, 0.35, 0.5, 0.65, 0.8, 0.95] {
            let wl = Wavelengths::sample(u);
            let lift = |kind: ColourKind, c: Vec3| match kind {
                ColourKind::Bounded => wl.reflectance(c),
                ColourKind::Unbounded => wl.unbounded(c),
            };
            let mut b = m.at_point(&p).map_colours(&lift);
            let filtered_then_lifted = match &b {
                Bsdf::Diffuse(d) => d.reflectance,
                _ => unreachable!(),
            };
            m.set_texel_spectra(&mut b, &p, &lift);
            let Bsdf::Diffuse(d) = b else { unreachable!() };
            let want = (wl.reflectance(Vec3::X) + wl.reflectance(Vec3::Y)) * 0.5;
            assert!((d.reflectance - want).abs().max_element() < 1e-6, "{wl:?}");
            assert_eq!(
                filtered_then_lifted,
                wl.reflectance(Vec3::new(0.5, 0.5, 0.0))
            );
            worst = worst.max((d.reflectance - filtered_then_lifted).abs().max_element());
        }
        assert!(worst > 0.05, "the two lifts agree within {worst}: no test");
        // Nothing to do for nearest lookups and constants.
        for t in [image(FilterType::Nearest), Texture::Constant(Vec3::X)] {
            let m = Material::new(
                diffuse.clone(),
                vec![Binding {
                    path: vec![],
                    param: Param::Reflectance,
                    texture: t,
                }],
            );
            assert!(!m.filters_colours());
        }
    }
}
