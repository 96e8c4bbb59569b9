//! Reading `<bsdf>` elements (and `<ref>`s to them) into [`Bsdf`] values.

use super::ctx::Ctx;
use super::error::SceneError;
use super::props::{Props, Value};
use super::textures::{texture_param, NamedTextures};
use crate::materials::conductor_presets;
use crate::materials::material::{Binding, Param, SpectralParam, Step};
use crate::materials::RoughPlastic;
use crate::materials::{specular_to_eta, Principled, PrincipledThin};
use crate::materials::{
    Blend, Circular, Composed, PPlastic, Perturbation, Perturbed, Polarizer, Retarder, Separable,
    TemporalProfile,
};
use crate::materials::{
    Bsdf, Conductor, Dielectric, Diffuse, Mask, Material, Microfacet, MicrofacetKind, Null,
    OneSided, Plastic, RoughConductor, RoughDielectric, ThinDielectric, TwoSided,
};
use crate::math::Rgb;
use crate::textures::Texture;
use roxmltree::Node;
use std::collections::HashMap;

/// Mitsuba 3's named indices of refraction (`ior.h`).
pub const NAMED_IORS: &[(&str, f64)] = &[
    ("vacuum", 1.0),
    ("helium", 1.000036),
    ("hydrogen", 1.000132),
    ("air", 1.000277),
    ("carbon dioxide", 1.00045),
    ("water", 1.3330),
    ("acetone", 1.36),
    ("ethanol", 1.361),
    ("carbon tetrachloride", 1.461),
    ("glycerol", 1.4729),
    ("benzene", 1.501),
    ("silicone oil", 1.52045),
    ("bromine", 1.661),
    ("water ice", 1.31),
    ("fused quartz", 1.458),
    ("pyrex", 1.470),
    ("acrylic glass", 1.49),
    ("polypropylene", 1.49),
    ("bk7", 1.5046),
    ("sodium chloride", 1.544),
    ("amber", 1.55),
    ("pet", 1.5750),
    ("diamond", 2.419),
];

fn ior(props: &mut Props, name: &str, default: f64) -> Result<f64, SceneError> {
    if let Some(Value::Str(s)) = props.peek(name).cloned() {
        props.ignore(name);
        return NAMED_IORS
            .iter()
            .find(|(n, _)| *n == s.to_lowercase())
            .map(|(_, v)| *v)
            .ok_or_else(|| {
                let names: Vec<_> = NAMED_IORS.iter().map(|(n, _)| *n).collect();
                props.err_at(
                    name,
                    format!("unknown IOR name '{s}' (known: {})", names.join(", ")),
                )
            });
    }
    let v = props.float_or(name, default)?;
    if !(v > 0.0 && v <= MAX_OPTICAL_CONSTANT) {
        return Err(props.err_at(
            name,
            format!("{name} must be positive and at most {MAX_OPTICAL_CONSTANT:e}, got {v}"),
        ));
    }
    Ok(v)
}

/// The largest IOR, conductor eta or k accepted: Fresnel's single-precision arithmetic
/// raises them to the fourth power (real materials stay below about 10).
pub const MAX_OPTICAL_CONSTANT: f64 = 1e6;

/// Reflectances and transmittances: never negative; above 1 the material creates energy,
/// which is legal (Mitsuba renders it) but almost always a typo, so it is a warning.
fn check_reflectance(props: &Props, name: &str, c: Rgb) -> Result<Rgb, SceneError> {
    if c.min_element() < 0.0 {
        return Err(props.err_at(name, format!("{name} must be non-negative, got {c}")));
    }
    if c.max_element() > 1.0 {
        props.warn_at(
            name,
            format!("{name} {c} exceeds 1: the material reflects more energy than it receives"),
        );
    }
    Ok(c)
}

/// `int_ior / ext_ior` (`ext_ior` defaults to air), within the range Fresnel's single
/// precision handles.
fn relative_ior(props: &mut Props, int_default: f64) -> Result<f64, SceneError> {
    let int_ior = ior(props, "int_ior", int_default)?;
    let ext_ior = ior(props, "ext_ior", 1.000277)?;
    let eta = int_ior / ext_ior;
    if !(1.0 / MAX_OPTICAL_CONSTANT..=MAX_OPTICAL_CONSTANT).contains(&eta) {
        return Err(props.err(format!(
            "the relative IOR int_ior/ext_ior = {eta:e} is outside [{:e}, {MAX_OPTICAL_CONSTANT:e}]",
            1.0 / MAX_OPTICAL_CONSTANT
        )));
    }
    Ok(eta)
}

/// The RGB (eta, k) of Mitsuba's conductor `name` (`none`: a perfect mirror).
fn conductor_preset(props: &Props, name: &str) -> Result<(Rgb, Rgb), SceneError> {
    if name == "none" {
        return Ok((Rgb::ZERO, Rgb::ONE));
    }
    let (eta, k) = conductor_presets::lookup(name).ok_or_else(|| {
        props.err_at(
            "material",
            format!(
                "unknown conductor material '{name}' (known: none, {})",
                conductor_presets::names()
            ),
        )
    })?;
    Ok((Rgb::from_array(eta), Rgb::from_array(k)))
}

/// A conductor's complex IOR: `eta` and `k` together, or `material` (Mitsuba's named
/// conductors, `conductor_presets`, or `none`, a perfect mirror); `default` is the
/// material when neither is given (`none` for both in Mitsuba 3's code, although its
/// documentation says copper for `roughconductor`; we follow the renderer). `eta` and
/// `k` may be textures.
/// A conductor's `eta` or `k` given as an `<rgb>`, read for the spectral mode as
/// Mitsuba 3.9.1's spectral variants read it: a colour (not a grey, which is a flat
/// spectrum at any value) is lifted to a spectrum through the reflectance model, which
/// clamps it to [0, 1] first. The clamp is applied here, at load, with a warning; named
/// presets (`material`) are not clamped (`spectral::lift`).
fn spectral_clamp(p: &Params, name: &str, t: Texture) -> Texture {
    match t {
        Texture::Constant(v)
            if p.props.ctx.mode.is_spectral()
                && matches!(p.props.peek(name), Some(Value::Rgb(_)))
                && !(v.x == v.y && v.y == v.z)
                && v.max_element() > 1.0 =>
        {
            let c = v.clamp(Rgb::ZERO, Rgb::ONE);
            p.props.ctx.warn(
                p.props.node,
                format!("--mode {}: the colour {name} {v} is clamped to {c}, as Mitsuba's spectral variants do (give it as a <spectrum>, a grey, or use 'material')", p.props.ctx.mode.name()),
            );
            Texture::Constant(c)
        }
        t => t,
    }
}

fn conductor_ior(p: &mut Params, kind: &str, default: &str) -> Result<(Rgb, Rgb), SceneError> {
    let material = p.props.string("material")?;
    let eta = p.colour_param("eta", Param::Eta)?;
    let k = p.colour_param("k", Param::K)?;
    let props = &p.props;
    // As Mitsuba: with `eta` or `k` given (or material `none`), the missing one
    // defaults to eta 0 / k 1; a named material excludes both.
    let (eta, k) = match (eta, k, material.as_deref()) {
        (None, None, m) => {
            let (e, k) = conductor_preset(props, m.unwrap_or(default))?;
            (Texture::Constant(e), Texture::Constant(k))
        }
        (e, k, None | Some("none")) => (
            e.unwrap_or(Texture::Constant(Rgb::ZERO)),
            k.unwrap_or(Texture::Constant(Rgb::ONE)),
        ),
        _ => return Err(props.err("give either 'material' or 'eta' and 'k', not both")),
    };
    let (eta, k) = if material.is_none() || material.as_deref() == Some("none") {
        (spectral_clamp(p, "eta", eta), spectral_clamp(p, "k", k))
    } else {
        (eta, k)
    };
    let limit = MAX_OPTICAL_CONSTANT as f32;
    let mut constant = |name: &str, param: Param, t: Texture, placeholder: Rgb| match t {
        Texture::Constant(v) => {
            if v.min_element() < 0.0 {
                return Err(p
                    .props
                    .err_at(name, format!("{kind} {name} must be non-negative")));
            }
            if v.max_element() > limit {
                return Err(p
                    .props
                    .err_at(name, format!("{kind} {name} {v} exceeds {limit:e}")));
            }
            Ok(v)
        }
        texture => {
            p.bind(param, texture);
            Ok(placeholder)
        }
    };
    let eta = constant("eta", Param::Eta, eta, Rgb::ZERO)?;
    let k = constant("k", Param::K, k, Rgb::ONE)?;
    Ok((eta, k))
}

/// Mitsuba's microfacet parameters: `distribution` (beckmann), `alpha` (a float or a
/// texture) or `alpha_u` and `alpha_v` (floats or textures; default `alpha` 0.1),
/// `sample_visible` (true).
fn microfacet(p: &mut Params) -> Result<Microfacet, SceneError> {
    let kind = match p.props.string("distribution")?.as_deref() {
        None | Some("beckmann") => MicrofacetKind::Beckmann,
        Some("ggx") => MicrofacetKind::Ggx,
        Some(other) => {
            return Err(p.props.err_at(
                "distribution",
                format!("unknown microfacet distribution '{other}' (beckmann or ggx)"),
            ))
        }
    };
    let alpha = p.scalar("alpha", Param::Alpha, 0.1)?;
    // Anisotropic roughness: alpha_u along the shading frame's s axis, Mitsuba's
    // dp/du (`Shape::dpdu`), alpha_v along t. Either may be a texture.
    let alpha_u = p.scalar("alpha_u", Param::AlphaU, 0.1)?;
    let alpha_v = p.scalar("alpha_v", Param::AlphaV, 0.1)?;
    let names = if alpha_u.is_some() || alpha_v.is_some() {
        ["alpha_u", "alpha_v"]
    } else {
        ["alpha", "alpha"]
    };
    let props = &mut p.props;
    let (alpha_u, alpha_v) = match (alpha, alpha_u, alpha_v) {
        (a, None, None) => (a.unwrap_or(0.1), a.unwrap_or(0.1)),
        (None, Some(u), Some(v)) => (u, v),
        (Some(_), _, _) => return Err(props.err("give either 'alpha' or 'alpha_u' and 'alpha_v'")),
        _ => return Err(props.err("'alpha_u' and 'alpha_v' must be given together")),
    };
    // Below 1e-4 the distribution is a delta that f32 cannot resolve; above 10, a
    // roughness no real surface has.
    for (name, a) in [(names[0], alpha_u), (names[1], alpha_v)] {
        if !(1e-4..=10.0).contains(&a) {
            return Err(props.err_at(
                name,
                format!("roughness {} is outside [1e-4, 10]", a as f32),
            ));
        }
    }
    Ok(Microfacet {
        kind,
        alpha_u: alpha_u as f32,
        alpha_v: alpha_v as f32,
        sample_visible: props.boolean_or("sample_visible", true)?,
    })
}

/// One `<bsdf>`'s parameters and the textures bound so far.
pub(super) struct Params<'a, 'i, 'c> {
    props: Props<'a, 'i, 'c>,
    textures: &'c NamedTextures,
    bindings: Vec<Binding>,
    /// The spectral mode's colours given as spectra (`Props::given_spectrum`).
    spectra: Vec<SpectralParam>,
}

impl Params<'_, '_, '_> {
    fn bind(&mut self, param: Param, texture: Texture) {
        self.bindings.push(Binding {
            path: Vec::new(),
            param,
            texture,
        });
    }

    /// A scalar parameter that accepts a texture: a constant's value (its first
    /// channel), or for a texture, bound here, `placeholder`; `None` when absent.
    /// (Scene numbers are finite by construction: `props::scene_number`.)
    fn scalar(
        &mut self,
        name: &str,
        param: Param,
        placeholder: f64,
    ) -> Result<Option<f64>, SceneError> {
        match texture_param(&mut self.props, name, self.textures)? {
            None => Ok(None),
            Some(Texture::Constant(c)) => Ok(Some(c.x as f64)),
            Some(texture) => {
                self.bind(param, texture);
                Ok(Some(placeholder))
            }
        }
    }

    /// A colour parameter as a texture (`texture_param`); in the spectral mode, one
    /// given as a spectrum is recorded to be used as given ([`SpectralParam`]) and
    /// reads as a constant of its RGB.
    fn colour_param(&mut self, name: &str, param: Param) -> Result<Option<Texture>, SceneError> {
        if let Some((curve, rgb)) = self.props.given_spectrum(name)? {
            self.spectra.push(SpectralParam {
                path: Vec::new(),
                param,
                curve,
            });
            return Ok(Some(Texture::Constant(rgb)));
        }
        texture_param(&mut self.props, name, self.textures)
    }

    /// A reflectance-like colour that accepts a texture: a constant is checked
    /// ([`check_reflectance`]), a texture is bound and `default` stands in for it.
    fn colour(&mut self, name: &str, param: Param, default: Rgb) -> Result<Rgb, SceneError> {
        match self.colour_param(name, param)? {
            None => Ok(default),
            Some(Texture::Constant(c)) => check_reflectance(&self.props, name, c),
            Some(texture) => {
                self.bind(param, texture);
                Ok(default)
            }
        }
    }

    /// Takes a nested material's bindings, reached through `step`.
    fn adopt(&mut self, step: Step, child: &Material) {
        let under = |path: &[Step]| std::iter::once(step).chain(path.iter().copied()).collect();
        self.bindings.extend(child.bindings.iter().map(|b| Binding {
            path: under(&b.path),
            param: b.param,
            texture: b.texture.clone(),
        }));
        self.spectra
            .extend(child.spectra.iter().map(|s| SpectralParam {
                path: under(&s.path),
                param: s.param,
                curve: s.curve.clone(),
            }));
    }
}

/// A `<bsdf>` element or a `<ref id>` to a named one.
/// What a BSDF may refer to: named BSDFs and named textures declared before it.
pub struct Named<'a> {
    pub bsdfs: &'a HashMap<String, Material>,
    pub textures: &'a NamedTextures,
}

pub fn resolve_bsdf(ctx: &Ctx, node: Node, named: &Named) -> Result<Material, SceneError> {
    match node.tag_name().name() {
        "ref" => {
            let id = ctx.required_attr(node, "id")?;
            named.bsdfs.get(&id).cloned().ok_or_else(|| {
                ctx.err(
                    node,
                    format!("no BSDF with id '{id}' defined before this point"),
                )
            })
        }
        "bsdf" => parse_bsdf(ctx, node, named),
        other => Err(ctx.err(node, format!("expected <bsdf> or <ref>, found <{other}>"))),
    }
}

pub fn parse_bsdf(ctx: &Ctx, node: Node, named: &Named) -> Result<Material, SceneError> {
    let kind = ctx.required_attr(node, "type")?;
    let mut p = Params {
        props: Props::parse(ctx, node)?,
        textures: named.textures,
        bindings: Vec::new(),
        spectra: Vec::new(),
    };
    let read = super::table::reader(BSDFS, &kind).ok_or_else(|| {
        p.props.err(format!(
            "unknown BSDF type '{kind}' (supported: {})",
            super::table::names(BSDFS).join(", ")
        ))
    })?;
    let bsdf = read(&mut p, ctx, named, &kind)?;
    if let Some(&obj) = p.props.objects.first() {
        return Err(ctx.err(
            obj,
            format!("unexpected nested element in <bsdf type=\"{kind}\">"),
        ));
    }
    p.props.finish()?;
    Ok(Material::new(bsdf, p.bindings).with_spectra(p.spectra))
}

/// The BSDF plugins and their readers (the plugin table's `bsdf` family,
/// [`super::plugins`]), in the order errors list them.
pub(super) const BSDFS: &[(&str, ReadBsdf)] = &[
    ("diffuse", read_diffuse),
    ("dielectric", read_dielectric),
    ("roughdielectric", read_roughdielectric),
    ("thindielectric", read_dielectric),
    ("conductor", read_conductor),
    ("roughconductor", read_roughconductor),
    ("plastic", read_plastic),
    ("roughplastic", read_roughplastic),
    ("null", read_null),
    ("twosided", read_twosided),
    ("mask", read_mask),
    ("Separable", read_separable),
    ("Composed", read_composed),
    ("blendbsdf", read_blendbsdf),
    ("normalmap", read_normalmap),
    ("bumpmap", read_normalmap),
    ("pplastic", read_pplastic),
    ("polarizer", read_polarizer),
    ("retarder", read_retarder),
    ("circular", read_circular),
    ("principled", read_principled),
    ("principledthin", read_principledthin),
];

/// Reads one BSDF plugin's parameters from `p`; `kind` is its type as written.
pub(super) type ReadBsdf =
    fn(&mut Params<'_, '_, '_>, &Ctx<'_>, &Named<'_>, &str) -> Result<Bsdf, SceneError>;

/// `<bsdf type="diffuse">`.
fn read_diffuse(
    p: &mut Params,
    _ctx: &Ctx,
    _named: &Named,
    _kind: &str,
) -> Result<Bsdf, SceneError> {
    Ok(Bsdf::Diffuse(Diffuse {
        reflectance: p.colour("reflectance", Param::Reflectance, Rgb::splat(0.5))?,
    }))
}

/// `<bsdf type="dielectric|thindielectric">`.
fn read_dielectric(
    p: &mut Params,
    _ctx: &Ctx,
    _named: &Named,
    kind: &str,
) -> Result<Bsdf, SceneError> {
    let eta = relative_ior(&mut p.props, 1.5046)? as f32;
    let specular_reflectance =
        p.colour("specular_reflectance", Param::SpecularReflectance, Rgb::ONE)?;
    let specular_transmittance = p.colour(
        "specular_transmittance",
        Param::SpecularTransmittance,
        Rgb::ONE,
    )?;
    Ok(if kind == "thindielectric" {
        Bsdf::ThinDielectric(ThinDielectric {
            eta,
            specular_reflectance,
            specular_transmittance,
        })
    } else {
        Bsdf::Dielectric(Dielectric {
            eta,
            specular_reflectance,
            specular_transmittance,
        })
    })
}

/// `<bsdf type="conductor">`.
fn read_conductor(
    p: &mut Params,
    _ctx: &Ctx,
    _named: &Named,
    _kind: &str,
) -> Result<Bsdf, SceneError> {
    let (eta, k) = conductor_ior(p, "conductor", "none")?;
    Ok(Bsdf::Conductor(Conductor {
        eta,
        k,
        specular_reflectance: p.colour(
            "specular_reflectance",
            Param::SpecularReflectance,
            Rgb::ONE,
        )?,
    }))
}

/// `<bsdf type="null">`.
fn read_null(_p: &mut Params, _ctx: &Ctx, _named: &Named, _kind: &str) -> Result<Bsdf, SceneError> {
    Ok(Bsdf::Null(Null))
}

/// `<bsdf type="plastic">`.
fn read_plastic(
    p: &mut Params,
    _ctx: &Ctx,
    _named: &Named,
    _kind: &str,
) -> Result<Bsdf, SceneError> {
    let eta = relative_ior(&mut p.props, 1.49)?;
    let (d, s) = plastic_reflectances(p, "plastic")?;
    Ok(Bsdf::Plastic(Plastic::new(
        eta as f32,
        d,
        s,
        p.props.boolean_or("nonlinear", false)?,
    )))
}

/// A plastic's `diffuse_reflectance` and `specular_reflectance` (0.5 and 1, or
/// textures), refused when both are zero numbers.
fn plastic_reflectances(p: &mut Params, kind: &str) -> Result<(Rgb, Rgb), SceneError> {
    let d = p.colour(
        "diffuse_reflectance",
        Param::DiffuseReflectance,
        Rgb::splat(0.5),
    )?;
    let s = p.colour("specular_reflectance", Param::SpecularReflectance, Rgb::ONE)?;
    if p.bindings.is_empty() && d.element_sum() + s.element_sum() <= 0.0 {
        return Err(p.props.err(format!(
            "{kind} with zero diffuse and specular reflectance reflects nothing; use a black diffuse"
        )));
    }
    Ok((d, s))
}

/// `<bsdf type="roughplastic">`.
fn read_roughplastic(
    p: &mut Params,
    _ctx: &Ctx,
    _named: &Named,
    _kind: &str,
) -> Result<Bsdf, SceneError> {
    // Mitsuba 3's roughplastic is isotropic and reads alpha as a float (its
    // tables depend on it): no alpha_u/alpha_v, no textured alpha.
    for name in ["alpha_u", "alpha_v"] {
        if p.props.peek(name).is_some() {
            return Err(p.props.err_at(
                name,
                format!("roughplastic has no '{name}': its roughness is isotropic, give 'alpha'"),
            ));
        }
    }
    let distribution = microfacet(p)?;
    if p.bindings.iter().any(|b| b.param == Param::Alpha) {
        return Err(p.props.err_at(
            "alpha",
            "roughplastic's alpha must be a number, not a texture (as in Mitsuba: the coating's precomputed tables depend on it)",
        ));
    }
    let eta = relative_ior(&mut p.props, 1.49)?;
    if eta as f32 == 1.0 {
        return Err(p
            .props
            .err("roughplastic's int_ior and ext_ior must differ (the coating would not exist)"));
    }
    let (d, s) = plastic_reflectances(p, "roughplastic")?;
    Ok(Bsdf::RoughPlastic(RoughPlastic::new(
        distribution,
        eta as f32,
        d,
        s,
        p.props.boolean_or("nonlinear", false)?,
    )))
}

/// `<bsdf type="roughconductor">`.
fn read_roughconductor(
    p: &mut Params,
    _ctx: &Ctx,
    _named: &Named,
    _kind: &str,
) -> Result<Bsdf, SceneError> {
    let distribution = microfacet(p)?;
    let (eta, k) = conductor_ior(p, "roughconductor", "none")?;
    Ok(Bsdf::RoughConductor(RoughConductor {
        distribution,
        eta,
        k,
        specular_reflectance: p.colour(
            "specular_reflectance",
            Param::SpecularReflectance,
            Rgb::ONE,
        )?,
    }))
}

/// `<bsdf type="roughdielectric">`.
fn read_roughdielectric(
    p: &mut Params,
    _ctx: &Ctx,
    _named: &Named,
    _kind: &str,
) -> Result<Bsdf, SceneError> {
    let distribution = microfacet(p)?;
    let eta = relative_ior(&mut p.props, 1.5046)?;
    // Mitsuba refuses equal IORs: without an interface the half vector of a
    // refraction (wo + eta wi) vanishes.
    if eta as f32 == 1.0 {
        return Err(p.props.err(
            "roughdielectric needs int_ior and ext_ior to differ (equal IORs are no interface; use null)",
        ));
    }
    Ok(Bsdf::RoughDielectric(RoughDielectric {
        distribution,
        eta: eta as f32,
        specular_reflectance: p.colour(
            "specular_reflectance",
            Param::SpecularReflectance,
            Rgb::ONE,
        )?,
        specular_transmittance: p.colour(
            "specular_transmittance",
            Param::SpecularTransmittance,
            Rgb::ONE,
        )?,
    }))
}

/// `<bsdf type="twosided">`.
fn read_twosided(
    p: &mut Params,
    ctx: &Ctx,
    named: &Named,
    _kind: &str,
) -> Result<Bsdf, SceneError> {
    let children: Vec<Material> = p
        .props
        .objects
        .iter()
        .map(|&c| resolve_bsdf(ctx, c, named))
        .collect::<Result<_, _>>()?;
    let (front, back) = match children.as_slice() {
        [one] => (one.clone(), one.clone()),
        [f, b] => (f.clone(), b.clone()),
        _ => return Err(p.props.err("twosided needs one or two nested BSDFs")),
    };
    p.adopt(Step::Front, &front);
    p.adopt(Step::Back, &back);
    let one_sided = |b: Bsdf| {
        OneSided::try_from(b).map_err(|_| {
            p.props.err("twosided wraps only one-sided models (diffuse, conductor, roughconductor, plastic, roughplastic, pplastic); not a dielectric, roughdielectric, thindielectric, null, mask, Separable, Composed, blendbsdf, normalmap, bumpmap, polarizer, retarder, circular or another twosided (write mask(twosided(...)), normalmap(twosided(...)) or Separable(twosided(...)))")
        })
    };
    let (front, back) = (one_sided(front.bsdf)?, one_sided(back.bsdf)?);
    p.props.objects.clear();
    Ok(Bsdf::TwoSided(TwoSided { front, back }))
}

/// `<bsdf type="mask">`.
fn read_mask(p: &mut Params, ctx: &Ctx, named: &Named, _kind: &str) -> Result<Bsdf, SceneError> {
    // A textured opacity holds the placeholder 0.5 (set per hit).
    let o = p.scalar("opacity", Param::Opacity, 0.5)?.unwrap_or(0.5) as f32;
    if !(0.0..=1.0).contains(&o) {
        p.props.warn_at(
            "opacity",
            format!("opacity {o} is outside [0, 1]; clamped, as Mitsuba does"),
        );
    }
    let opacity = o.clamp(0.0, 1.0);
    let nested = match p.props.objects.as_slice() {
        [one] => resolve_bsdf(ctx, *one, named)?,
        _ => {
            return Err(p
                .props
                .err("mask needs exactly one nested BSDF (and its opacity)"))
        }
    };
    if nested.bsdf.delays() {
        return Err(p.props.err("mask cannot wrap a delaying BSDF (Separable or Composed): the light passing through the holes would be delayed too"));
    }
    p.adopt(Step::Nested, &nested);
    p.props.objects.clear();
    Ok(Bsdf::Mask(Mask {
        opacity,
        nested: Box::new(nested.bsdf),
    }))
}

/// `<bsdf type="Separable">`.
fn read_separable(
    p: &mut Params,
    ctx: &Ctx,
    named: &Named,
    _kind: &str,
) -> Result<Bsdf, SceneError> {
    let mut inner = None;
    let mut profile = None;
    for obj in std::mem::take(&mut p.props.objects) {
        if obj.tag_name().name() == "TemporalProfile" {
            if profile.is_some() {
                return Err(ctx.err(obj, "Separable takes one <TemporalProfile>"));
            }
            let (tp, bindings) = parse_temporal_profile(ctx, obj, named.textures)?;
            p.bindings.extend(bindings);
            profile = Some(tp);
        } else {
            if inner.is_some() {
                return Err(ctx.err(obj, "Separable takes one nested BSDF"));
            }
            inner = Some(resolve_bsdf(ctx, obj, named)?);
        }
    }
    let (Some(inner), Some(profile)) = (inner, profile) else {
        return Err(p
            .props
            .err("Separable needs a nested BSDF and a <TemporalProfile type=... name=\"tp\">"));
    };
    if inner.bsdf.delays() {
        return Err(p.props.err("Separable cannot nest another delaying BSDF (Separable or Composed); compose the profiles in a Composed instead"));
    }
    p.adopt(Step::Nested, &inner);
    Ok(Bsdf::Separable(Separable {
        inner: Box::new(inner.bsdf),
        profile,
    }))
}

/// `<bsdf type="Composed">`.
fn read_composed(
    p: &mut Params,
    ctx: &Ctx,
    named: &Named,
    _kind: &str,
) -> Result<Bsdf, SceneError> {
    let w = p.props.float_or("weight", 0.5)?;
    if !(0.0..=1.0).contains(&w) {
        return Err(p
            .props
            .err_at("weight", format!("weight must be in [0, 1], got {w}")));
    }
    let children: Vec<Material> = std::mem::take(&mut p.props.objects)
        .into_iter()
        .map(|c| resolve_bsdf(ctx, c, named))
        .collect::<Result<_, _>>()?;
    let [first, second] = <[Material; 2]>::try_from(children)
        .map_err(|_| p.props.err("Composed needs exactly two nested BSDFs"))?;
    p.adopt(Step::First, &first);
    p.adopt(Step::Second, &second);
    Ok(Bsdf::Composed(Composed {
        weight: w as f32,
        first: Box::new(first.bsdf),
        second: Box::new(second.bsdf),
    }))
}

/// `<bsdf type="blendbsdf">`.
fn read_blendbsdf(
    p: &mut Params,
    ctx: &Ctx,
    named: &Named,
    _kind: &str,
) -> Result<Bsdf, SceneError> {
    // Mitsuba requires the weight (a float or a texture) and clips it to [0, 1].
    let w = p.scalar("weight", Param::Weight, 0.5)?;
    let Some(w) = w else {
        return Err(p
            .props
            .err("blendbsdf needs 'weight' (a float or a texture: the share of the second BSDF)"));
    };
    if !(0.0..=1.0).contains(&w) {
        p.props.warn_at(
            "weight",
            format!("weight {w} is outside [0, 1]; clipped, as Mitsuba does"),
        );
    }
    let children: Vec<Material> = std::mem::take(&mut p.props.objects)
        .into_iter()
        .map(|c| resolve_bsdf(ctx, c, named))
        .collect::<Result<_, _>>()?;
    let [first, second] = <[Material; 2]>::try_from(children)
        .map_err(|_| p.props.err("blendbsdf needs exactly two nested BSDFs"))?;
    if first.bsdf.delays() || second.bsdf.delays() {
        return Err(p.props.err("blendbsdf cannot blend a delaying BSDF (Separable or Composed); use Composed, which keeps each child's delay with its light"));
    }
    if let (Some(a), Some(b)) = (rough_ior(&first.bsdf), rough_ior(&second.bsdf)) {
        if a != b {
            return Err(p.props.err("blendbsdf cannot blend two rough dielectrics of different IORs (the medium behind would be ambiguous)"));
        }
    }
    p.adopt(Step::First, &first);
    p.adopt(Step::Second, &second);
    Ok(Bsdf::Blend(Blend {
        weight: (w as f32).clamp(0.0, 1.0),
        first: Box::new(first.bsdf),
        second: Box::new(second.bsdf),
    }))
}

/// `<bsdf type="normalmap|bumpmap">`.
fn read_normalmap(
    p: &mut Params,
    ctx: &Ctx,
    named: &Named,
    kind: &str,
) -> Result<Bsdf, SceneError> {
    let flip_invalid_normals = p.props.boolean_or("flip_invalid_normals", true)?;
    let use_shadowing_function = p.props.boolean_or("use_shadowing_function", true)?;
    let perturbation = if kind == "normalmap" {
        let Some(t) = texture_param(&mut p.props, "normalmap", p.textures)? else {
            return Err(p.props.err(
                "normalmap needs a texture 'normalmap' (an RGB bitmap, read with raw = true)",
            ));
        };
        super::textures::refuse_mesh_attribute(&p.props, "normalmap", &t, "a normal map")?;
        if let Texture::Bitmap(b) = &t {
            if b.channels != 3 {
                return Err(p.props.err_at("normalmap", "normalmap's bitmap must have three channels (RGB), as Mitsuba's eval_3 requires"));
            }
        }
        Perturbation::NormalMap(t)
    } else {
        let scale = p.props.float_or("scale", 1.0)?;
        let mut texture = None;
        let mut rest = Vec::new();
        for obj in std::mem::take(&mut p.props.objects) {
            let tag = obj.tag_name().name();
            let is_texture = tag == "texture"
                || (tag == "ref"
                    && ctx
                        .attr(obj, "id")?
                        .is_some_and(|id| named.textures.contains_key(&id)));
            if !is_texture {
                rest.push(obj);
                continue;
            }
            if texture.is_some() {
                return Err(ctx.err(obj, "bumpmap takes exactly one nested texture"));
            }
            texture = Some(if tag == "ref" {
                let id = ctx.required_attr(obj, "id")?;
                named.textures[&id].clone()
            } else {
                super::textures::parse_texture(ctx, obj, named.textures)?
            });
        }
        p.props.objects = rest;
        let Some(texture) = texture else {
            return Err(p
                .props
                .err("bumpmap needs one nested <texture> (the height field)"));
        };
        super::textures::refuse_mesh_attribute(
            &p.props,
            "",
            &texture,
            "a bump map's height field",
        )?;
        Perturbation::BumpMap {
            texture,
            scale: scale as f32,
        }
    };
    let nested = match p.props.objects.as_slice() {
        [one] => resolve_bsdf(ctx, *one, named)?,
        _ => return Err(p.props.err(format!("{kind} needs exactly one nested BSDF"))),
    };
    p.props.objects.clear();
    if nested.bsdf.delays() {
        return Err(p.props.err(format!("{kind} cannot wrap a delaying BSDF (Separable or Composed); write Separable({kind}(...)) instead")));
    }
    if nested.bsdf.perturbs() {
        return Err(p
            .props
            .err(format!("{kind} cannot wrap another normalmap or bumpmap")));
    }
    p.adopt(Step::Nested, &nested);
    Ok(Bsdf::Perturbed(Perturbed {
        perturbation,
        flip_invalid_normals,
        use_shadowing_function,
        nested: Box::new(nested.bsdf),
        frame: crate::materials::perturbed::IDENTITY,
    }))
}

/// `<bsdf type="pplastic">`.
fn read_pplastic(
    p: &mut Params,
    ctx: &Ctx,
    _named: &Named,
    _kind: &str,
) -> Result<Bsdf, SceneError> {
    let distribution = microfacet(p)?;
    let eta = if p.props.peek("eta").is_some()
        || p.props
            .objects
            .iter()
            .any(|o| ctx.attr(*o, "name").ok().flatten().as_deref() == Some("eta"))
    {
        if p.props.peek("int_ior").is_some() || p.props.peek("ext_ior").is_some() {
            return Err(p
                .props
                .err("give either 'eta' or 'int_ior' and 'ext_ior', not both"));
        }
        let eta = p.scalar("eta", Param::RelativeEta, 1.49)?.unwrap_or(1.49);
        if !(eta > 0.0 && eta <= MAX_OPTICAL_CONSTANT) {
            return Err(p.props.err_at(
                "eta",
                format!("eta must be positive and at most {MAX_OPTICAL_CONSTANT:e}, got {eta}"),
            ));
        }
        eta
    } else {
        let eta = relative_ior(&mut p.props, 1.49)?;
        if eta as f32 == 1.0 {
            return Err(p
                .props
                .err("pplastic's int_ior and ext_ior must differ (as Mitsuba requires)"));
        }
        eta
    };
    // The lobe choice uses the textures' means (Mitsuba's parameters_changed).
    let mean_of = |p: &mut Params,
                   name: &str,
                   param: Param,
                   default: Rgb|
     -> Result<(Rgb, f32, bool), SceneError> {
        match p.colour_param(name, param)? {
            None => Ok((default, default.element_sum() / 3.0, false)),
            Some(Texture::Constant(c)) => {
                let c = check_reflectance(&p.props, name, c)?;
                Ok((c, c.element_sum() / 3.0, true))
            }
            Some(t) => {
                super::textures::refuse_mesh_attribute(
                    &p.props,
                    name,
                    &t,
                    "a pplastic reflectance (Mitsuba needs its mean)",
                )?;
                let mean = t.mean();
                p.bind(param, t);
                Ok((default, mean, true))
            }
        }
    };
    let (d, d_mean, _) = mean_of(
        p,
        "diffuse_reflectance",
        Param::DiffuseReflectance,
        Rgb::splat(0.5),
    )?;
    let (s, s_mean, _) = mean_of(
        p,
        "specular_reflectance",
        Param::SpecularReflectance,
        Rgb::ONE,
    )?;
    if (d_mean + s_mean).is_nan() || d_mean + s_mean <= 0.0 {
        return Err(p.props.err("pplastic with zero diffuse and specular reflectance reflects nothing; use a black diffuse"));
    }
    Ok(Bsdf::PPlastic(PPlastic {
        distribution,
        eta: eta as f32,
        diffuse_reflectance: d,
        specular_reflectance: s,
        specular_weight: s_mean / (d_mean + s_mean),
    }))
}

/// `<bsdf type="polarizer">`.
fn read_polarizer(
    p: &mut Params,
    _ctx: &Ctx,
    _named: &Named,
    _kind: &str,
) -> Result<Bsdf, SceneError> {
    // The angle and `polarizing` matter only in the polarized mode; the RGB weight is
    // 0.5 * transmittance whatever they are. A textured angle is bound per hit.
    let theta = angle(p, "theta", Param::Theta, 0.0)?;
    let polarizing = p.props.boolean_or("polarizing", true)?;
    Ok(Bsdf::Polarizer(Polarizer {
        transmittance: p.colour("transmittance", Param::Transmittance, Rgb::ONE)?,
        theta,
        polarizing,
    }))
}

/// An angle in degrees (`polarizer`'s and `retarder`'s `theta`, `retarder`'s
/// `delta`): any finite value (Mitsuba's unbounded texture), or a texture bound to
/// `param` (`default` stands in for it).
fn angle(p: &mut Params, name: &str, param: Param, default: f64) -> Result<f32, SceneError> {
    let v = p.scalar(name, param, default)?.unwrap_or(default);
    if !v.is_finite() {
        return Err(p.props.err_at(
            name,
            format!("{name} must be a finite angle in degrees, got {v}"),
        ));
    }
    Ok(v as f32)
}

/// `<bsdf type="retarder">`.
fn read_retarder(
    p: &mut Params,
    _ctx: &Ctx,
    _named: &Named,
    _kind: &str,
) -> Result<Bsdf, SceneError> {
    let theta = angle(p, "theta", Param::Theta, 0.0)?;
    let delta = angle(p, "delta", Param::Retardance, 90.0)?;
    Ok(Bsdf::Retarder(Retarder {
        transmittance: p.colour("transmittance", Param::Transmittance, Rgb::ONE)?,
        theta,
        delta,
    }))
}

/// `<bsdf type="circular">`.
fn read_circular(
    p: &mut Params,
    _ctx: &Ctx,
    _named: &Named,
    _kind: &str,
) -> Result<Bsdf, SceneError> {
    let left_handed = p.props.boolean_or("left_handed", false)?;
    Ok(Bsdf::Circular(Circular {
        transmittance: p.colour("transmittance", Param::Transmittance, Rgb::ONE)?,
        left_handed,
    }))
}

/// `<bsdf type="principled">`.
fn read_principled(
    p: &mut Params,
    _ctx: &Ctx,
    _named: &Named,
    _kind: &str,
) -> Result<Bsdf, SceneError> {
    Ok(Bsdf::Principled(principled(p)?))
}

/// `<bsdf type="principledthin">`.
fn read_principledthin(
    p: &mut Params,
    _ctx: &Ctx,
    _named: &Named,
    _kind: &str,
) -> Result<Bsdf, SceneError> {
    Ok(Bsdf::PrincipledThin(principled_thin(p)?))
}

/// The temporal profiles of `Separable` and `Composed` (the plugin table's
/// `TemporalProfile` family), in the order errors list them; `parse_temporal_profile`
/// reads each.
pub(super) const PROFILES: &[&str] =
    &["ConstantTP", "ExponentialTP", "EpanechnikovTP", "PosEpanTP"];

/// A float-or-texture weight of `principled`/`principledthin` (`default` when absent),
/// a constant checked to lie in [0, `hi`], and whether it was given other than as the
/// float 0 (Mitsuba's `get_flag`, which switches optional lobes on).
fn principled_weight(
    p: &mut Params,
    name: &str,
    param: Param,
    default: f64,
    hi: f64,
) -> Result<(f32, bool), SceneError> {
    let float_zero = matches!(p.props.peek(name), Some(Value::Float(v)) if *v == 0.0);
    match p.scalar(name, param, default)? {
        None => Ok((default as f32, false)),
        Some(v) => {
            if !(0.0..=hi).contains(&v) {
                return Err(p
                    .props
                    .err_at(name, format!("{name} must be in [0, {hi}], got {v}")));
            }
            Ok((v as f32, !float_zero))
        }
    }
}

/// A lobe sampling rate: a non-negative float, 1 by default.
fn sampling_rate(p: &mut Params, name: &str) -> Result<f32, SceneError> {
    let r = p.props.float_or(name, 1.0)?;
    if r < 0.0 {
        return Err(p
            .props
            .err_at(name, format!("{name} must be non-negative, got {r}")));
    }
    Ok(r as f32)
}

/// Mitsuba's `principled` (`principled.rs` lists the parameters).
fn principled(p: &mut Params) -> Result<Principled, SceneError> {
    let base_color = p.colour("base_color", Param::BaseColor, Rgb::splat(0.5))?;
    let (roughness, _) = principled_weight(p, "roughness", Param::Roughness, 0.5, 1.0)?;
    let (anisotropic, _) = principled_weight(p, "anisotropic", Param::Anisotropic, 0.0, 1.0)?;
    let (metallic, _) = principled_weight(p, "metallic", Param::Metallic, 0.0, 1.0)?;
    let (spec_trans, has_spec_trans) =
        principled_weight(p, "spec_trans", Param::SpecTrans, 0.0, 1.0)?;
    let (spec_tint, _) = principled_weight(p, "spec_tint", Param::SpecTint, 0.0, 1.0)?;
    let (sheen, _) = principled_weight(p, "sheen", Param::Sheen, 0.0, 1.0)?;
    let (sheen_tint, _) = principled_weight(p, "sheen_tint", Param::SheenTint, 0.0, 1.0)?;
    let (flatness, _) = principled_weight(p, "flatness", Param::Flatness, 0.0, 1.0)?;
    let (clearcoat, _) = principled_weight(p, "clearcoat", Param::Clearcoat, 0.0, 1.0)?;
    let (clearcoat_gloss, _) =
        principled_weight(p, "clearcoat_gloss", Param::ClearcoatGloss, 0.0, 1.0)?;
    let props = &mut p.props;
    // eta and specular are floats (Mitsuba reads them with get<float>) and exclusive.
    let eta = match (
        props.peek("eta").is_some(),
        props.peek("specular").is_some(),
    ) {
        (true, true) => return Err(props.err("give either 'eta' or 'specular', not both")),
        (true, false) => {
            let e = props.float_or("eta", 1.5)?;
            if !(e > 0.0 && e <= MAX_OPTICAL_CONSTANT) {
                return Err(props.err_at(
                    "eta",
                    format!("eta must be positive and at most {MAX_OPTICAL_CONSTANT:e}, got {e}"),
                ));
            }
            // An interface of eta 1 cannot transmit (Mitsuba's adjustment).
            let e = e as f32;
            if has_spec_trans && e == 1.0 {
                1.001
            } else {
                e
            }
        }
        (false, _) => {
            let s = props.float_or("specular", 0.5)?;
            let e = specular_to_eta(s as f32);
            if !(s >= 0.0 && e.is_finite() && e > 0.0 && (e as f64) <= MAX_OPTICAL_CONSTANT) {
                return Err(props.err_at(
                    "specular",
                    format!("specular must be in [0, 12.5) (it sets eta = 2 / (1 - sqrt(0.08 specular)) - 1), got {s}"),
                ));
            }
            if has_spec_trans && s == 0.0 {
                specular_to_eta(1e-3)
            } else {
                e
            }
        }
    };
    Ok(Principled {
        base_color,
        roughness,
        anisotropic,
        metallic,
        spec_trans,
        spec_tint,
        sheen,
        sheen_tint,
        flatness,
        clearcoat,
        clearcoat_gloss,
        eta,
        diffuse_rate: sampling_rate(p, "diffuse_reflectance_sampling_rate")?,
        specular_rate: sampling_rate(p, "main_specular_sampling_rate")?,
        clearcoat_rate: sampling_rate(p, "clearcoat_sampling_rate")?,
        has_spec_trans,
    })
}

/// Mitsuba's `principledthin` (`principled_thin.rs` lists the parameters).
fn principled_thin(p: &mut Params) -> Result<PrincipledThin, SceneError> {
    let base_color = p.colour("base_color", Param::BaseColor, Rgb::splat(0.5))?;
    let (roughness, _) = principled_weight(p, "roughness", Param::Roughness, 0.5, 1.0)?;
    let (anisotropic, _) = principled_weight(p, "anisotropic", Param::Anisotropic, 0.0, 1.0)?;
    let (spec_trans, has_spec_trans) =
        principled_weight(p, "spec_trans", Param::SpecTrans, 0.0, 1.0)?;
    let (diff_trans, has_diff_trans) =
        principled_weight(p, "diff_trans", Param::DiffTrans, 0.0, 2.0)?;
    let (spec_tint, _) = principled_weight(p, "spec_tint", Param::SpecTint, 0.0, 1.0)?;
    let (sheen, _) = principled_weight(p, "sheen", Param::Sheen, 0.0, 1.0)?;
    let (sheen_tint, _) = principled_weight(p, "sheen_tint", Param::SheenTint, 0.0, 1.0)?;
    let (flatness, _) = principled_weight(p, "flatness", Param::Flatness, 0.0, 1.0)?;
    let eta = p.scalar("eta", Param::RelativeEta, 1.5)?.unwrap_or(1.5);
    if !(eta > 0.0 && eta <= MAX_OPTICAL_CONSTANT) {
        return Err(p.props.err_at(
            "eta",
            format!("eta must be positive and at most {MAX_OPTICAL_CONSTANT:e}, got {eta}"),
        ));
    }
    Ok(PrincipledThin {
        base_color,
        roughness,
        anisotropic,
        spec_trans,
        diff_trans,
        eta: eta as f32,
        spec_tint,
        sheen,
        sheen_tint,
        flatness,
        spec_reflect_rate: sampling_rate(p, "specular_reflectance_sampling_rate")?,
        spec_trans_rate: sampling_rate(p, "specular_transmittance_sampling_rate")?,
        diffuse_reflect_rate: sampling_rate(p, "diffuse_reflectance_sampling_rate")?,
        diffuse_trans_rate: sampling_rate(p, "diffuse_transmittance_sampling_rate")?,
        has_spec_trans,
        has_diff_trans,
    })
}

/// The IOR of a rough dielectric inside `b` (the one non-delta lobe that crosses into
/// another medium), if any.
fn rough_ior(b: &Bsdf) -> Option<f32> {
    match b {
        Bsdf::RoughDielectric(d) => Some(d.eta),
        Bsdf::Principled(d) if d.has_spec_trans => Some(d.eta),
        Bsdf::Mask(m) => rough_ior(&m.nested),
        Bsdf::Perturbed(p) => rough_ior(&p.nested),
        Bsdf::Blend(c) => rough_ior(&c.first).or(rough_ior(&c.second)),
        _ => None,
    }
}

/// A `<TemporalProfile type=...>` (SPEC section 6) and the textures bound to its
/// parameters (paths relative to the `Separable` that holds it).
fn parse_temporal_profile(
    ctx: &Ctx,
    node: Node,
    textures: &NamedTextures,
) -> Result<(TemporalProfile, Vec<Binding>), SceneError> {
    let kind = ctx.required_attr(node, "type")?;
    let mut p = Params {
        props: Props::parse(ctx, node)?,
        textures,
        bindings: Vec::new(),
        spectra: Vec::new(),
    };
    // A float or a single-channel texture (NaN marks a textured one, set per hit).
    let scalar = |p: &mut Params, name: &str, param: Param| p.scalar(name, param, f64::NAN);
    let required = |p: &Params, v: Option<f64>, name: &str| {
        v.ok_or_else(|| p.props.err(format!("{kind} needs '{name}'")))
    };
    let profile = match kind.as_str() {
        "ConstantTP" => {
            let c = scalar(&mut p, "delay", Param::Delay)?;
            let c = required(&p, c, "delay")?;
            if c < 0.0 {
                return Err(p
                    .props
                    .err_at("delay", format!("delay must be >= 0, got {c}")));
            }
            TemporalProfile::Constant { delay: c as f32 }
        }
        "ExponentialTP" => {
            let l = scalar(&mut p, "lambda", Param::Lambda)?;
            let l = required(&p, l, "lambda")?;
            if l <= 0.0 {
                return Err(p
                    .props
                    .err_at("lambda", format!("lambda must be > 0, got {l}")));
            }
            TemporalProfile::Exponential { lambda: l as f32 }
        }
        "EpanechnikovTP" | "PosEpanTP" => {
            let mu = scalar(&mut p, "mu", Param::Mu)?;
            let sigma = scalar(&mut p, "sigma", Param::Sigma)?;
            let (mu, sigma) = (required(&p, mu, "mu")?, required(&p, sigma, "sigma")?);
            // NaN marks a textured parameter: checked per hit instead.
            if sigma <= 0.0 {
                return Err(p
                    .props
                    .err_at("sigma", format!("sigma must be > 0, got {sigma}")));
            }
            if mu < sigma {
                return Err(p.props.err_at(
                    "mu",
                    format!("mu must be >= sigma (the positive Epanechnikov profile has no negative delays), got mu {mu}, sigma {sigma}"),
                ));
            }
            TemporalProfile::Epanechnikov {
                mu: mu as f32,
                sigma: sigma as f32,
            }
        }
        other => {
            return Err(p.props.err(format!(
                "unknown temporal profile '{other}' (supported: {})",
                PROFILES.join(", ")
            )))
        }
    };
    if let Some(&obj) = p.props.objects.first() {
        return Err(ctx.err(
            obj,
            format!("unexpected nested element in <TemporalProfile type=\"{kind}\">"),
        ));
    }
    p.props.finish()?;
    // Placeholders (NaN) of textured parameters: any valid value; `Material::at` sets them.
    let profile = match profile {
        TemporalProfile::Constant { delay } => TemporalProfile::Constant {
            delay: if delay.is_nan() { 0.0 } else { delay },
        },
        TemporalProfile::Exponential { lambda } => TemporalProfile::Exponential {
            lambda: if lambda.is_nan() { 1.0 } else { lambda },
        },
        TemporalProfile::Epanechnikov { mu, sigma } => TemporalProfile::Epanechnikov {
            mu: if mu.is_nan() { 1.0 } else { mu },
            sigma: if sigma.is_nan() { 0.5 } else { sigma },
        },
    };
    Ok((profile, p.bindings))
}
