//! `<emitter>` of the point family (point, spot, projector) and the area emission of
//! shapes (area, angulararea); the infinite ones are `infinite_emitters.rs`.

use super::ctx::Ctx;
use super::error::SceneError;
use super::limits::check_world_point;
use super::props::Props;
use crate::geometry::shape::AreaSampler;
use crate::lights::{AngularFalloff, Emitter, TexturedArea};
use crate::math::Rgb;
use crate::scene::textures::{texture_param, NamedTextures};
use crate::textures::Texture;
use glam::{DMat4, DVec3, Vec3};
use roxmltree::Node;

/// Emitters that live on a shape.
pub(super) const AREA_KINDS: &[&str] = &["area", "angulararea"];

/// What a shape's emitter declares: its radiance (or, for a textured `area`, its
/// texture) and, for `angulararea`, its cone.
#[derive(Clone, Debug)]
pub(super) struct AreaEmission {
    pub(super) radiance: Vec3,
    pub(super) texture: Option<Texture>,
    pub(super) falloff: Option<AngularFalloff>,
    /// The spectrum the radiance was given as, if any (`Scene::emitter_spectra`).
    pub(super) spectrum: Option<crate::spectral::curve::Curve>,
}

impl AreaEmission {
    /// The emitter of shape `shape`, whose area `sampler` draws its points.
    pub(super) fn into_emitter(self, shape: u32, sampler: AreaSampler) -> Emitter {
        match (self.falloff, self.texture) {
            (None, Some(radiance)) => Emitter::TexturedArea(Box::new(TexturedArea {
                shape,
                radiance,
                sampler,
            })),
            (None, None) => Emitter::Area {
                shape,
                radiance: self.radiance,
                sampler,
            },
            (Some(falloff), _) => Emitter::AngularArea {
                shape,
                radiance: self.radiance,
                sampler,
                falloff,
            },
        }
    }
}

/// An `<emitter>` of one of the `AREA_KINDS`.
pub(super) fn parse_area_emission(
    ctx: &Ctx,
    obj: Node,
    kind: &str,
    named: &NamedTextures,
) -> Result<AreaEmission, SceneError> {
    ctx.take_emission_spectrum();
    let mut emission = if kind == "angulararea" {
        let (radiance, falloff) = super::angular_area::parse_angular_area(ctx, obj)?;
        AreaEmission {
            radiance,
            texture: None,
            falloff: Some(falloff),
            spectrum: None,
        }
    } else {
        let (radiance, texture) = parse_area_emitter(ctx, obj, named)?;
        AreaEmission {
            radiance,
            texture,
            falloff: None,
            spectrum: None,
        }
    };
    emission.spectrum = ctx.take_emission_spectrum();
    Ok(emission)
}

/// An `<emitter type="area">`'s radiance (default 1, as Mitsuba 3's `area`): a
/// constant, or a spatially varying texture (`bitmap`, `checkerboard`; Mitsuba's
/// `get_emissive_texture`), nested or referenced.
pub(super) fn parse_area_emitter(
    ctx: &Ctx,
    obj: Node,
    named: &NamedTextures,
) -> Result<(Vec3, Option<Texture>), SceneError> {
    let mut ep = Props::parse(ctx, obj)?;
    if ep.peek("radiance").is_none() {
        if let Some(t) = texture_param(&mut ep, "radiance", named)? {
            super::textures::refuse_mesh_attribute(
                &ep,
                "radiance",
                &t,
                "an area light's radiance",
            )?;
            if !t.non_negative() {
                return Err(ep.err_at(
                    "radiance",
                    "radiance must be finite and non-negative everywhere",
                ));
            }
            if t.is_black() {
                ctx.warn(
                    obj,
                    "the radiance texture is black: this emitter contributes nothing",
                );
            }
            if let Some(&o) = ep.objects.first() {
                return Err(ctx.err(o, "unexpected nested element in <emitter>"));
            }
            ep.finish()?;
            // A constant texture (`rawconstant`) is a plain radiance.
            return Ok(match t {
                Texture::Constant(c) => (c, None),
                t => (Vec3::ZERO, Some(t)),
            });
        }
    }
    let radiance = ep.emission("radiance")?.unwrap_or(Vec3::ONE);
    if radiance.min_element() < 0.0 {
        return Err(ep.err_at("radiance", "radiance must be non-negative"));
    }
    if radiance.max_element() == 0.0 {
        ctx.warn(
            obj,
            "radiance is zero (in single precision): this emitter contributes nothing",
        );
    }
    if let Some(&o) = ep.objects.first() {
        return Err(ctx.err(o, "unexpected nested element in <emitter>"));
    }
    ep.finish()?;
    Ok((radiance, None))
}

/// The emitters at a point (the plugin table's `emitter` family, with [`AREA_KINDS`],
/// `projector::PROJECTOR` and `infinite_emitters::KINDS`): read by
/// [`parse_point_emitter`].
pub(super) const POINT_KINDS: &[&str] = &["point", "spot"];

pub(super) fn parse_point_emitter(
    ctx: &Ctx,
    node: Node,
    named: &NamedTextures,
) -> Result<Emitter, SceneError> {
    let kind = ctx.required_attr(node, "type")?;
    if !POINT_KINDS.contains(&kind.as_str()) {
        let top_level: Vec<&str> = POINT_KINDS
            .iter()
            .copied()
            .chain([super::projector::PROJECTOR])
            .chain(super::infinite_emitters::KINDS.iter().copied())
            .collect();
        return Err(ctx.err(
            node,
            format!("emitter '{kind}' is not supported at top level (supported: {}; area lights go inside a <shape> or are attached by <ref>)", top_level.join(", ")),
        ));
    }
    let mut p = Props::parse(ctx, node)?;
    let intensity = p.emission("intensity")?.unwrap_or(Rgb::ONE);
    if intensity.min_element() < 0.0 {
        return Err(p.err_at("intensity", "intensity must be non-negative"));
    }
    if intensity.max_element() == 0.0 {
        ctx.warn(
            node,
            "intensity is zero (in single precision): this emitter contributes nothing",
        );
    }
    // A spot's projected image (Mitsuba: `texture`, which must vary over uv).
    let mut textured: Option<(Texture, glam::Mat3, f32)> = None;
    let (position, spot) = if kind == "spot" {
        // Mitsuba's spot: a to_world frame (the beam along its +z), no `position`.
        let m = p.transform("to_world")?.unwrap_or(DMat4::IDENTITY);
        let cutoff = p.float_or("cutoff_angle", 20.0)?;
        let beam = p.float_or("beam_width", cutoff * 0.75)?;
        if !(cutoff > 0.0 && cutoff <= 180.0) {
            return Err(p.err_at(
                "cutoff_angle",
                format!("cutoff_angle must be in (0, 180] degrees, got {cutoff}"),
            ));
        }
        if !(beam > 0.0 && beam <= cutoff) {
            return Err(p.err_at(
                "beam_width",
                format!("beam_width must be in (0, cutoff_angle = {cutoff}] degrees, got {beam}"),
            ));
        }
        let axis = m.transform_vector3(DVec3::Z);
        if axis.length() <= 0.0 || !axis.is_finite() {
            return Err(p.err_at("to_world", "the spot's to_world maps its axis to nothing"));
        }
        let spot = crate::lights::Spot {
            axis: axis.normalize().as_vec3(),
            cutoff: cutoff.to_radians() as f32,
            beam_width: beam.to_radians() as f32,
        };
        if let Some(t) = texture_param(&mut p, "texture", named)? {
            if !t.is_spatially_varying() {
                return Err(p.err_at(
                    "texture",
                    "a spot's 'texture' must vary over uv (a bitmap or checkerboard), as Mitsuba requires",
                ));
            }
            if !t.non_negative() {
                return Err(p.err_at(
                    "texture",
                    "the spot's texture must be finite and non-negative everywhere",
                ));
            }
            let lin = glam::DMat3::from_mat4(m);
            if !(lin.determinant().abs() > 0.0 && lin.determinant().is_finite()) {
                return Err(p.err_at("to_world", "a textured spot's to_world must be invertible"));
            }
            let to_local = lin.inverse().as_mat3();
            let uv_factor = (cutoff.to_radians() as f32).tan();
            textured = Some((t, to_local, uv_factor));
        }
        (m.transform_point3(DVec3::ZERO), Some(spot))
    } else {
        let position = match (p.point("position")?, p.transform("to_world")?) {
            (Some(_), Some(_)) => {
                return Err(p.err("give either 'position' or 'to_world', not both"))
            }
            (Some(pos), None) => DVec3::from(pos),
            (None, Some(m)) => m.transform_point3(DVec3::ZERO),
            (None, None) => DVec3::ZERO,
        };
        (position, None)
    };
    if let Some(&o) = p.objects.first() {
        return Err(ctx.err(
            o,
            "unexpected nested element in <emitter> (a spot takes a nested texture only as 'texture')",
        ));
    }
    p.finish()?;
    check_world_point(position).map_err(|e| ctx.err(node, format!("position: {e}")))?;
    if let (Some((texture, to_local, uv_factor)), Some(spot)) = (textured, spot) {
        return Ok(Emitter::TexturedSpot(Box::new(
            crate::lights::TexturedSpot {
                position: position.as_vec3(),
                intensity,
                spot,
                texture,
                to_local,
                uv_factor,
            },
        )));
    }
    Ok(Emitter::Point {
        position: position.as_vec3(),
        intensity,
        spot,
    })
}
