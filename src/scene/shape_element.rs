//! One `<shape>` element: its geometry (`shapes.rs`), BSDF, area emitter and media.

use super::bsdfs::{resolve_bsdf, Named};
use super::ctx::Ctx;
use super::emitters::{parse_area_emission, AreaEmission, AREA_KINDS};
use super::error::SceneError;
use super::media::medium_index;
use super::props::Props;
use super::shapes::parse_geometry;
use crate::geometry::shape::{Shape, ShapeGeom};
use crate::materials::{Bsdf, Diffuse, Material};
use crate::math::Rgb;
use crate::media::Medium;
use roxmltree::Node;
use std::collections::HashMap;

/// A shape, its material, its area emission and the `<sensor>` nested in it (an
/// `nlos_capture_meter`, read by the caller).
pub(super) type ParsedShape<'a, 'i> = (Shape, Material, Option<AreaEmission>, Option<Node<'a, 'i>>);

pub(super) fn parse_shape<'a, 'i>(
    ctx: &Ctx,
    node: Node<'a, 'i>,
    index: u32,
    named: &Named,
    area_emitters: &HashMap<String, AreaEmission>,
    media: &mut Vec<Medium>,
    named_media: &HashMap<String, u32>,
) -> Result<ParsedShape<'a, 'i>, SceneError> {
    let kind = ctx.required_attr(node, "type")?;
    let mut p = Props::parse(ctx, node)?;
    let geom = parse_geometry(&kind, &mut p)?;
    // Mitsuba's curves and sdfgrid read no `flip_normals` (the unknown-parameter
    // check reports it).
    let is_curve = matches!(geom, ShapeGeom::Curve(_));
    let is_sdf = matches!(geom, ShapeGeom::Sdf(_));
    let no_flip = is_curve || is_sdf;
    let flip_normals = !no_flip && p.boolean_or("flip_normals", false)?;
    let mut bsdf = None;
    let mut emission = None;
    let mut sensor = None;
    let (mut interior, mut exterior) = (None, None);
    for obj in std::mem::take(&mut p.objects) {
        let slot_name = ctx.attr(obj, "name")?;
        match obj.tag_name().name() {
            // Media: `<medium name="interior|exterior">` or `<ref name=... id=...>`.
            "medium" | "ref" if matches!(slot_name.as_deref(), Some("interior" | "exterior")) => {
                let slot = if slot_name.as_deref() == Some("interior") {
                    &mut interior
                } else {
                    &mut exterior
                };
                if slot.is_some() {
                    return Err(ctx.err(obj, format!("a shape has one {} medium", slot_name.unwrap_or_default())));
                }
                *slot = Some(medium_index(ctx, obj, media, named_media)?);
            }
            "medium" => {
                return Err(ctx.err(
                    obj,
                    "a <medium> inside <shape> needs name=\"interior\" or name=\"exterior\"",
                ))
            }
            // A reference to an area emitter declared at the top level (Mitsuba
            // resolves a shape's <ref> by the kind of object its id names).
            "ref" if area_emitters.contains_key(&ctx.required_attr(obj, "id")?) => {
                if emission.is_some() {
                    return Err(ctx.err(obj, "a shape has at most one emitter"));
                }
                emission = Some((area_emitters[&ctx.required_attr(obj, "id")?].clone(), obj));
            }
            "bsdf" | "ref" => {
                if bsdf.is_some() {
                    return Err(ctx.err(obj, "a shape has at most one BSDF"));
                }
                bsdf = Some(resolve_bsdf(ctx, obj, named)?);
            }
            "emitter" if emission.is_some() => {
                return Err(ctx.err(obj, "a shape has at most one emitter"));
            }
            "emitter" => {
                let k = ctx.required_attr(obj, "type")?;
                if !AREA_KINDS.contains(&k.as_str()) {
                    return Err(ctx.err(obj, format!("emitter '{k}' cannot be attached to a shape (use area or angulararea)")));
                }
                emission = Some((parse_area_emission(ctx, obj, &k, named.textures)?, obj));
            }
            "sensor" if sensor.is_some() => {
                return Err(ctx.err(obj, "a shape has at most one sensor"));
            }
            "sensor" => {
                let k = ctx.required_attr(obj, "type")?;
                if k != super::sensors::METER {
                    return Err(ctx.err(obj, format!("sensor '{k}' cannot be attached to a shape (only nlos_capture_meter, on a relay wall)")));
                }
                if kind != "rectangle" {
                    return Err(ctx.err(obj, format!("nlos_capture_meter is attached to a {kind}: tstat supports relay walls that are a rectangle (its grid maps the rectangle's uv square)")));
                }
                sensor = Some(obj);
            }
            other => {
                return Err(ctx.err(
                    obj,
                    format!("<{other}> inside <shape> is not supported (a shape takes a bsdf, an emitter, interior/exterior media and an nlos_capture_meter sensor)"),
                ))
            }
        }
    }
    p.finish()?;
    if is_curve {
        if let Some((_, obj)) = emission {
            return Err(ctx.err(
                obj,
                format!("a {kind} cannot be an area emitter (Mitsuba 3 defines no area or area sampling for curves)"),
            ));
        }
        if interior.is_some() || exterior.is_some() {
            return Err(ctx.err(
                node,
                format!("a {kind} cannot bound a medium (its back faces are culled: rays inside it never meet it)"),
            ));
        }
    }
    let name = ctx
        .attr(node, "id")?
        .unwrap_or_else(|| format!("shape#{index}"));
    let shape = Shape {
        name,
        geom,
        flip_normals,
        bsdf: 0,
        emitter: None,
        interior,
        exterior,
    };
    // Areas are summed from single-precision triangles, as the light sampler does.
    let area = shape.area() as f32;
    match emission {
        Some((_, obj)) if is_sdf => {
            return Err(ctx.err(
                obj,
                "an sdfgrid cannot be an emitter (Mitsuba 3's sdfgrid has no area to sample)",
            ))
        }
        None if is_sdf => {}
        Some((_, obj)) if !(area > 0.0 && area.is_finite()) => {
            return Err(ctx.err(
                obj,
                format!("the emitting shape's area is {area} (in single precision): it cannot be sampled as a light"),
            ))
        }
        None if area == 0.0 => ctx.warn(node, "the shape has zero area: it is invisible"),
        // Curves have no area (NaN): nothing to warn about.
        _ => {}
    }
    // Mitsuba's default BSDF (`shape.cpp`): diffuse 0.5, black on an emitter.
    let default_reflectance = if emission.is_some() { 0.0 } else { 0.5 };
    let bsdf = bsdf.unwrap_or(Material::plain(Bsdf::Diffuse(Diffuse {
        reflectance: Rgb::splat(default_reflectance),
    })));
    // A mesh_attribute texture reads the shape's own attribute: it must be there
    // (Mitsuba's scalar variants throw on a hit; its LLVM variants read 0).
    for want in bsdf.mesh_attribute_names() {
        if shape.attributes().and_then(|a| a.get(want)).is_none() {
            let have = shape.attributes().map_or("none".to_string(), |a| a.names());
            return Err(ctx.err(
                node,
                format!("the BSDF's mesh_attribute texture reads '{want}', which this shape does not have (its attributes: {have}; only PLY files carry attributes)"),
            ));
        }
    }
    Ok((shape, bsdf, emission.map(|(e, _)| e), sensor))
}
