//! `<medium>` and `<phase>` elements (Mitsuba 3's XML): a medium is declared at the top
//! level with an `id` and referenced by `<ref name="interior|exterior|medium" id=...>`,
//! or nested in a shape (`<medium name="interior" ...>`) or the sensor
//! (`<medium name="medium" ...>`, or any name there as in Mitsuba).

use super::{Homogeneous, Medium, Phase};
use crate::scene::props::{Ctx, Props};
use crate::scene::SceneError;
use roxmltree::Node;

/// Largest accepted extinction (1 / scene unit): beyond it free flights are shorter
/// than a ray offset in any scene tstat accepts.
const MAX_SIGMA_T: f32 = 1e7;

/// Reads a `<medium>` element.
pub fn parse_medium(ctx: &Ctx, node: Node) -> Result<Medium, SceneError> {
    let kind = ctx.required_attr(node, "type")?;
    if kind != "homogeneous" {
        return Err(ctx.err(
            node,
            format!("medium '{kind}' is not supported (supported: homogeneous)"),
        ));
    }
    let mut p = Props::parse(ctx, node)?;
    let scale = p.float_or("scale", 1.0)?;
    if !(scale >= 0.0 && scale.is_finite()) {
        return Err(p.err_at(
            "scale",
            format!("scale must be finite and >= 0, got {scale}"),
        ));
    }
    let sigma_a = p.rgb("sigma_a")?;
    let sigma_s = p.rgb("sigma_s")?;
    let sigma_t = p.rgb("sigma_t")?;
    let albedo = p.rgb("albedo")?;
    let nonneg = |p: &Props, name: &str, v: glam::Vec3| {
        if v.is_finite() && v.min_element() >= 0.0 {
            Ok(())
        } else {
            Err(p.err_at(
                name,
                format!("{name} must be finite and >= 0 in every channel, got {v}"),
            ))
        }
    };
    let (sigma_t, albedo) = match (sigma_a, sigma_s) {
        (None, None) => {
            let st = sigma_t.unwrap_or(glam::Vec3::ONE);
            nonneg(&p, "sigma_t", st)?;
            let al = albedo.unwrap_or(glam::Vec3::splat(0.75));
            if !(al.is_finite() && al.min_element() >= 0.0 && al.max_element() <= 1.0) {
                return Err(p.err_at(
                    "albedo",
                    format!("albedo must lie in [0, 1] in every channel, got {al}"),
                ));
            }
            (st * scale as f32, al)
        }
        (Some(a), Some(s)) => {
            if sigma_t.is_some() || albedo.is_some() {
                return Err(
                    p.err("give either sigma_t and albedo, or sigma_a and sigma_s, not both")
                );
            }
            nonneg(&p, "sigma_a", a)?;
            nonneg(&p, "sigma_s", s)?;
            let st = (a + s) * scale as f32;
            let al = glam::Vec3::select(
                (a + s).cmpgt(glam::Vec3::ZERO),
                s / (a + s),
                glam::Vec3::ZERO,
            );
            (st, al)
        }
        (Some(_), None) => return Err(p.err_at("sigma_a", "sigma_a needs sigma_s")),
        (None, Some(_)) => return Err(p.err_at("sigma_s", "sigma_s needs sigma_a")),
    };
    if !(sigma_t.is_finite() && sigma_t.max_element() <= MAX_SIGMA_T) {
        return Err(p.err(format!(
            "the extinction (scale included) is {sigma_t}, above {MAX_SIGMA_T:e} per scene unit"
        )));
    }
    let sample_emitters = p.boolean_or("sample_emitters", true)?;
    p.ignore("has_spectral_extinction");
    let mut phase = None;
    for obj in std::mem::take(&mut p.objects) {
        match obj.tag_name().name() {
            "phase" if phase.is_some() => {
                return Err(ctx.err(obj, "only a single phase function can be specified per medium"))
            }
            "phase" => phase = Some(parse_phase(ctx, obj)?),
            other => {
                return Err(ctx.err(
                    obj,
                    format!("unexpected <{other}> inside <medium> (a homogeneous medium takes a <phase>; volumes are not supported)"),
                ))
            }
        }
    }
    p.finish()?;
    Ok(Homogeneous {
        sigma_t,
        albedo,
        phase: phase.unwrap_or(Phase::Isotropic),
        sample_emitters,
    })
}

/// Reads a `<phase>` element.
pub fn parse_phase(ctx: &Ctx, node: Node) -> Result<Phase, SceneError> {
    let kind = ctx.required_attr(node, "type")?;
    let mut p = Props::parse(ctx, node)?;
    let phase = match kind.as_str() {
        "isotropic" => Phase::Isotropic,
        "hg" => {
            let g = p.float_or("g", 0.8)?;
            if !(g > -1.0 && g < 1.0) {
                return Err(p.err_at(
                    "g",
                    format!("the asymmetry parameter g must lie in (-1, 1), got {g}"),
                ));
            }
            Phase::Hg { g: g as f32 }
        }
        other => {
            return Err(ctx.err(
                node,
                format!("phase function '{other}' is not supported (supported: isotropic, hg)"),
            ))
        }
    };
    if let Some(&o) = p.objects.first() {
        return Err(ctx.err(o, "unexpected nested element in <phase>"));
    }
    p.finish()?;
    Ok(phase)
}
