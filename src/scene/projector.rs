//! `<emitter type="projector">` (Mitsuba 3's; parameters and radiometry documented in
//! `lights/projector.rs`).

use super::ctx::Ctx;
use super::error::SceneError;
use super::limits::check_world_point;
use super::props::Props;
use super::textures::{texture_param, NamedTextures};
use crate::lights::{Emitter, Projector};
use crate::textures::Texture;
use glam::{DMat4, DVec3, Vec3};
use roxmltree::Node;

/// The projector's plugin name (the plugin table's `emitter` family).
pub const PROJECTOR: &str = "projector";

pub fn parse_projector(
    ctx: &Ctx,
    node: Node,
    named: &NamedTextures,
) -> Result<Emitter, SceneError> {
    let mut p = Props::parse(ctx, node)?;
    // An emitted colour (Mitsuba's `get_emissive_texture`): a constant follows the
    // emission rules for spectra; otherwise a nested or referenced texture.
    let irradiance = match p.peek("irradiance") {
        Some(_) => Texture::Constant(p.emission("irradiance")?.unwrap_or(Vec3::ONE)),
        None => texture_param(&mut p, "irradiance", named)?.unwrap_or(Texture::Constant(Vec3::ONE)),
    };
    super::textures::refuse_mesh_attribute(&p, "irradiance", &irradiance, "a projector's image")?;
    if !irradiance.non_negative() {
        return Err(p.err_at(
            "irradiance",
            "irradiance must be finite and non-negative everywhere",
        ));
    }
    let scale = p.float_or("scale", 1.0)?;
    if !(scale >= 0.0 && (scale as f32).is_finite()) {
        return Err(p.err_at(
            "scale",
            format!("scale must be finite and non-negative, got {scale}"),
        ));
    }
    // A point facing it at unit distance receives pi * scale * E: that must stay finite
    // in single precision, or every contribution would be dropped as non-finite.
    let peak = std::f64::consts::PI * scale * irradiance.max_value() as f64;
    if !((peak as f32).is_finite()) {
        return Err(p.err_at(
            "scale",
            format!(
                "scale {scale:e} times the largest irradiance {:e} overflows single precision",
                irradiance.max_value()
            ),
        ));
    }
    if scale as f32 == 0.0 || irradiance.is_black() {
        ctx.warn(
            node,
            "the projected irradiance is zero (in single precision): this emitter contributes nothing",
        );
    }
    let (fov, fov_axis) = super::fov::parse_fov(&mut p)?;
    let to_world = p.transform("to_world")?.unwrap_or(DMat4::IDENTITY);
    if let Some(&o) = p.objects.first() {
        return Err(ctx.err(
            o,
            "unexpected nested element in <emitter type=\"projector\"> (it takes a texture only as irradiance)",
        ));
    }
    p.finish()?;
    let position = to_world.transform_point3(DVec3::ZERO);
    check_world_point(position).map_err(|e| ctx.err(node, format!("position: {e}")))?;
    let (w, h) = irradiance.resolution();
    let (tan_half, aspect) = Projector::frustum(fov, fov_axis, w, h);
    let inv_tan_half = (1.0 / tan_half) as f32;
    if !(inv_tan_half.is_finite() && inv_tan_half > 0.0 && (aspect as f32).is_finite()) {
        return Err(ctx.err(
            node,
            format!("fov {fov:e} degrees on a {w}x{h} texture gives a frustum that is flat or unbounded in single precision"),
        ));
    }
    Ok(Emitter::Projector(Box::new(Projector {
        position: position.as_vec3(),
        to_local: to_world.inverse().as_mat4(),
        axis: to_world.transform_vector3(DVec3::Z).as_vec3(),
        inv_tan_half,
        aspect: aspect as f32,
        irradiance,
        scale: scale as f32,
    })))
}
