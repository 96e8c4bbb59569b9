//! `<emitter type="angulararea">` (mitransient's; parameters and semantics documented
//! in `lights/angular_area.rs`), nested in a shape or declared at the top level with
//! an id, as `area`.

use super::ctx::Ctx;
use super::error::SceneError;
use super::props::Props;
use crate::lights::AngularFalloff;
use glam::Vec3;
use roxmltree::Node;

/// The radiance and cone of an `angulararea` emitter.
pub fn parse_angular_area(ctx: &Ctx, obj: Node) -> Result<(Vec3, AngularFalloff), SceneError> {
    let mut ep = Props::parse(ctx, obj)?;
    // mitransient: `props.get_emissive_texture('radiance', 1.0)`.
    let radiance = ep.emission("radiance")?.unwrap_or(Vec3::ONE);
    if radiance.min_element() < 0.0 {
        return Err(ep.err_at("radiance", "radiance must be non-negative"));
    }
    let cutoff = ep.float_or("cutoff_angle", 10.0)?;
    if !(cutoff > 0.0 && cutoff <= 180.0) {
        return Err(ep.err_at(
            "cutoff_angle",
            format!("cutoff_angle must be in (0, 180] degrees, got {cutoff}"),
        ));
    }
    let beam = ep.float_or("beam_width", cutoff)?;
    if !(beam >= 0.0 && beam <= cutoff) {
        return Err(ep.err_at(
            "beam_width",
            format!("beam_width must be in [0, cutoff_angle = {cutoff}] degrees, got {beam}"),
        ));
    }
    if radiance.max_element() == 0.0 {
        ctx.warn(
            obj,
            "radiance is zero (in single precision): this emitter contributes nothing",
        );
    }
    if let Some(&o) = ep.objects.first() {
        return Err(ctx.err(
            o,
            "unexpected nested element in <emitter type=\"angulararea\"> (a textured radiance is not supported)",
        ));
    }
    ep.finish()?;
    Ok((radiance, AngularFalloff::new(cutoff, beam)))
}
