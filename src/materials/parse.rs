//! Reading `<bsdf>` elements (and `<ref>`s to them) into [`Bsdf`] values.

use super::conductor_presets;
use super::material::{Binding, Side};
use super::{
    Bsdf, Conductor, Dielectric, Diffuse, Material, Microfacet, MicrofacetKind, Null, OneSided,
    Plastic, RoughConductor, RoughDielectric, ThinDielectric, TwoSided,
};
use crate::math::Rgb;
use crate::scene::error::SceneError;
use crate::scene::props::{Ctx, Props, Value};
use crate::scene::textures::{texture_param, NamedTextures};
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
/// documentation says copper for `roughconductor`; we follow the renderer).
fn conductor_ior(props: &mut Props, kind: &str, default: &str) -> Result<(Rgb, Rgb), SceneError> {
    let material = props.string("material")?;
    let eta = props.rgb("eta")?;
    let k = props.rgb("k")?;
    // As Mitsuba: with `eta` or `k` given (or material `none`), the missing one
    // defaults to eta 0 / k 1; a named material excludes both.
    let (eta, k) = match (eta, k, material.as_deref()) {
        (None, None, m) => conductor_preset(props, m.unwrap_or(default))?,
        (e, k, None | Some("none")) => (e.unwrap_or(Rgb::ZERO), k.unwrap_or(Rgb::ONE)),
        _ => return Err(props.err("give either 'material' or 'eta' and 'k', not both")),
    };
    if eta.min_element() < 0.0 || k.min_element() < 0.0 {
        return Err(props.err(format!("{kind} eta and k must be non-negative")));
    }
    let limit = MAX_OPTICAL_CONSTANT as f32;
    for (name, v) in [("eta", eta), ("k", k)] {
        if v.max_element() > limit {
            return Err(props.err_at(name, format!("{kind} {name} {v} exceeds {limit:e}")));
        }
    }
    Ok((eta, k))
}

/// Mitsuba's microfacet parameters: `distribution` (beckmann), `alpha` or `alpha_u` and
/// `alpha_v` (0.1), `sample_visible` (true).
fn microfacet(props: &mut Props) -> Result<Microfacet, SceneError> {
    let kind = match props.string("distribution")?.as_deref() {
        None | Some("beckmann") => MicrofacetKind::Beckmann,
        Some("ggx") => MicrofacetKind::Ggx,
        Some(other) => {
            return Err(props.err_at(
                "distribution",
                format!("unknown microfacet distribution '{other}' (beckmann or ggx)"),
            ))
        }
    };
    let alpha = props.float("alpha")?;
    let alpha_u = props.float("alpha_u")?;
    let alpha_v = props.float("alpha_v")?;
    let (alpha_u, alpha_v) = match (alpha, alpha_u, alpha_v) {
        (a, None, None) => (a.unwrap_or(0.1), a.unwrap_or(0.1)),
        (None, Some(u), Some(v)) => (u, v),
        (Some(_), _, _) => return Err(props.err("give either 'alpha' or 'alpha_u' and 'alpha_v'")),
        _ => return Err(props.err("'alpha_u' and 'alpha_v' must be given together")),
    };
    if alpha_u != alpha_v {
        // Mitsuba orients anisotropic lobes along dp/du of the surface's uv
        // parameterisation; tstat's shading frames do not carry it yet.
        return Err(props.err(
            "anisotropic roughness (alpha_u != alpha_v) is not supported: it needs the surface tangents Mitsuba derives from uv coordinates",
        ));
    }
    // Below 1e-4 the distribution is a delta that f32 cannot resolve; above 10, a
    // roughness no real surface has.
    for (name, a) in [("alpha", alpha_u), ("alpha", alpha_v)] {
        if !(1e-4..=10.0).contains(&a) {
            return Err(props.err_at(name, format!("roughness {a} is outside [1e-4, 10]")));
        }
    }
    Ok(Microfacet {
        kind,
        alpha_u: alpha_u as f32,
        alpha_v: alpha_v as f32,
        sample_visible: props.boolean_or("sample_visible", true)?,
    })
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
    let mut props = Props::parse(ctx, node)?;
    let mut bindings = Vec::new();
    let bsdf = match kind.as_str() {
        "diffuse" => {
            let reflectance = match texture_param(&mut props, "reflectance", named.textures)? {
                None => Rgb::splat(0.5),
                Some(Texture::Constant(c)) => check_reflectance(&props, "reflectance", c)?,
                Some(texture) => {
                    bindings.push(Binding {
                        side: Side::Only,
                        texture,
                    });
                    // A placeholder: `Material::at` sets it at every hit.
                    Rgb::splat(0.5)
                }
            };
            Bsdf::Diffuse(Diffuse { reflectance })
        }
        "dielectric" | "thindielectric" => {
            let eta = relative_ior(&mut props, 1.5046)?;
            let sr = props.rgb("specular_reflectance")?.unwrap_or(Rgb::ONE);
            let st = props.rgb("specular_transmittance")?.unwrap_or(Rgb::ONE);
            let (sr, st) = (
                check_reflectance(&props, "specular_reflectance", sr)?,
                check_reflectance(&props, "specular_transmittance", st)?,
            );
            if kind == "thindielectric" {
                Bsdf::ThinDielectric(ThinDielectric {
                    eta: eta as f32,
                    specular_reflectance: sr,
                    specular_transmittance: st,
                })
            } else {
                Bsdf::Dielectric(Dielectric {
                    eta: eta as f32,
                    specular_reflectance: sr,
                    specular_transmittance: st,
                })
            }
        }
        "conductor" => {
            let (eta, k) = conductor_ior(&mut props, "conductor", "none")?;
            let sr = props.rgb("specular_reflectance")?.unwrap_or(Rgb::ONE);
            Bsdf::Conductor(Conductor {
                eta,
                k,
                specular_reflectance: check_reflectance(&props, "specular_reflectance", sr)?,
            })
        }
        "null" => Bsdf::Null(Null),
        "plastic" => {
            let eta = relative_ior(&mut props, 1.49)?;
            let d = props.rgb("diffuse_reflectance")?.unwrap_or(Rgb::splat(0.5));
            let s = props.rgb("specular_reflectance")?.unwrap_or(Rgb::ONE);
            let (d, s) = (
                check_reflectance(&props, "diffuse_reflectance", d)?,
                check_reflectance(&props, "specular_reflectance", s)?,
            );
            if d.element_sum() + s.element_sum() <= 0.0 {
                return Err(props.err("plastic with zero diffuse and specular reflectance reflects nothing; use a black diffuse"));
            }
            Bsdf::Plastic(Plastic::new(
                eta as f32,
                d,
                s,
                props.boolean_or("nonlinear", false)?,
            ))
        }
        "roughconductor" => {
            let distribution = microfacet(&mut props)?;
            let (eta, k) = conductor_ior(&mut props, "roughconductor", "none")?;
            let sr = props.rgb("specular_reflectance")?.unwrap_or(Rgb::ONE);
            Bsdf::RoughConductor(RoughConductor {
                distribution,
                eta,
                k,
                specular_reflectance: check_reflectance(&props, "specular_reflectance", sr)?,
            })
        }
        "roughdielectric" => {
            let distribution = microfacet(&mut props)?;
            let eta = relative_ior(&mut props, 1.5046)?;
            // Mitsuba refuses equal IORs: without an interface the half vector of a
            // refraction (wo + eta wi) vanishes.
            if eta as f32 == 1.0 {
                return Err(props.err(
                    "roughdielectric needs int_ior and ext_ior to differ (equal IORs are no interface; use null)",
                ));
            }
            let sr = props.rgb("specular_reflectance")?.unwrap_or(Rgb::ONE);
            let st = props.rgb("specular_transmittance")?.unwrap_or(Rgb::ONE);
            Bsdf::RoughDielectric(RoughDielectric {
                distribution,
                eta: eta as f32,
                specular_reflectance: check_reflectance(&props, "specular_reflectance", sr)?,
                specular_transmittance: check_reflectance(&props, "specular_transmittance", st)?,
            })
        }
        "twosided" => {
            let children: Vec<Material> = props
                .objects
                .iter()
                .map(|&c| resolve_bsdf(ctx, c, named))
                .collect::<Result<_, _>>()?;
            let (front, back) = match children.as_slice() {
                [one] => (one.clone(), one.clone()),
                [f, b] => (f.clone(), b.clone()),
                _ => return Err(props.err("twosided needs one or two nested BSDFs")),
            };
            let one_sided = |b: Bsdf| {
                OneSided::try_from(b)
                    .map_err(|_| props.err("twosided cannot wrap a dielectric, roughdielectric, thindielectric, null or another twosided"))
            };
            for (side, child) in [(Side::Front, &front), (Side::Back, &back)] {
                bindings.extend(child.bindings.iter().map(|b| Binding {
                    side,
                    texture: b.texture.clone(),
                }));
            }
            let (front, back) = (one_sided(front.bsdf)?, one_sided(back.bsdf)?);
            props.objects.clear();
            Bsdf::TwoSided(TwoSided { front, back })
        }
        other => {
            return Err(props.err(format!(
                "unknown BSDF type '{other}' (supported: diffuse, dielectric, roughdielectric, thindielectric, conductor, roughconductor, plastic, null, twosided)"
            )))
        }
    };
    if let Some(&obj) = props.objects.first() {
        return Err(ctx.err(
            obj,
            format!(
                "unexpected nested element in <bsdf type=\"{kind}\"> (of its parameters only diffuse's reflectance takes a texture)"
            ),
        ));
    }
    props.finish()?;
    Ok(Material { bsdf, bindings })
}
