//! `<medium>`, `<phase>` and `<volume>` elements (Mitsuba 3's XML): a medium is declared at the top
//! level with an `id` and referenced by `<ref name="interior|exterior|medium" id=...>`,
//! or nested in a shape (`<medium name="interior" ...>`) or the sensor
//! (`<medium name="medium" ...>`, or any name there as in Mitsuba).

use super::ctx::Ctx;
use super::props::Props;
use super::SceneError;
use crate::media::vol_file::read_vol;
use crate::media::volume::{Grid, GridFilter, VolumeData};
use crate::media::{Heterogeneous, Homogeneous, Medium, Phase, Volume};
use crate::textures::bitmap::WrapMode;
use glam::DMat4;
use roxmltree::Node;
use std::collections::HashMap;
use std::sync::Arc;

/// Largest accepted extinction (1 / scene unit): beyond it free flights are shorter
/// than a ray offset in any scene tstat accepts.
const MAX_SIGMA_T: f32 = 1e7;

/// The medium plugins (the plugin table's `medium` family): both read by
/// [`parse_medium`].
pub(super) const MEDIA: &[&str] = &["homogeneous", "heterogeneous"];

/// Reads a `<medium>` element.
pub fn parse_medium(ctx: &Ctx, node: Node) -> Result<Medium, SceneError> {
    let kind = ctx.required_attr(node, "type")?;
    if !MEDIA.contains(&kind.as_str()) {
        return Err(ctx.err(
            node,
            format!("medium '{kind}' is not supported (supported: homogeneous, heterogeneous)"),
        ));
    }
    let mut p = Props::parse(ctx, node)?;
    let mut phase = None;
    let (mut sigma_t_vol, mut albedo_vol) = (None, None);
    for obj in std::mem::take(&mut p.objects) {
        match obj.tag_name().name() {
            "phase" if phase.is_some() => {
                return Err(ctx.err(obj, "only a single phase function can be specified per medium"))
            }
            "phase" => phase = Some(parse_phase(ctx, obj)?),
            "volume" => {
                let name = ctx.required_attr(obj, "name")?;
                let slot = match name.as_str() {
                    "sigma_t" => &mut sigma_t_vol,
                    "albedo" => &mut albedo_vol,
                    other => {
                        return Err(ctx.err(
                            obj,
                            format!("unexpected <volume name=\"{other}\"> (a medium takes volumes named sigma_t and albedo)"),
                        ))
                    }
                };
                if slot.is_some() || p.peek(&name).is_some() {
                    return Err(ctx.err(obj, format!("'{name}' is given twice")));
                }
                *slot = Some((obj, parse_volume(ctx, obj, &name)?));
            }
            other => {
                return Err(ctx.err(
                    obj,
                    format!("unexpected <{other}> inside <medium> (a medium takes a <phase> and <volume>s named sigma_t and albedo)"),
                ))
            }
        }
    }
    let scale = p.float_or("scale", 1.0)?;
    if !(scale >= 0.0 && scale.is_finite()) {
        return Err(p.err_at(
            "scale",
            format!("scale must be finite and >= 0, got {scale}"),
        ));
    }
    let sample_emitters = p.boolean_or("sample_emitters", true)?;
    p.ignore("has_spectral_extinction");
    let phase = phase.unwrap_or(Phase::Isotropic);
    let medium = if kind == "homogeneous" {
        let mut h = parse_homogeneous(&mut p, scale, sigma_t_vol, albedo_vol)?;
        h.phase = phase;
        h.sample_emitters = sample_emitters;
        Medium::Homogeneous(h)
    } else {
        let sigma_t = match sigma_t_vol {
            Some((_, v)) => v,
            None => {
                let st = p.rgb("sigma_t")?.unwrap_or(glam::Vec3::ONE);
                nonneg(&p, "sigma_t", st)?;
                Volume::constant(st, glam::DMat4::IDENTITY)
            }
        };
        let albedo = match albedo_vol {
            Some((_, v)) => v,
            None => {
                let al = p.rgb("albedo")?.unwrap_or(glam::Vec3::splat(0.75));
                unit_range(&p, al)?;
                Volume::constant(al, glam::DMat4::IDENTITY)
            }
        };
        let majorant = sigma_t.max * scale as f32;
        if !(majorant.is_finite() && majorant <= MAX_SIGMA_T) {
            return Err(p.err(format!(
                "the largest extinction (scale {scale} times the largest sigma_t {}) is above {MAX_SIGMA_T:e} per scene unit",
                sigma_t.max
            )));
        }
        Medium::Heterogeneous(Heterogeneous {
            sigma_t,
            albedo,
            scale: scale as f32,
            majorant,
            phase,
            sample_emitters,
        })
    };
    p.finish()?;
    Ok(medium)
}

fn nonneg(p: &Props, name: &str, v: glam::Vec3) -> Result<(), SceneError> {
    if v.is_finite() && v.min_element() >= 0.0 {
        Ok(())
    } else {
        Err(p.err_at(
            name,
            format!("{name} must be finite and >= 0 in every channel, got {v}"),
        ))
    }
}

fn unit_range(p: &Props, al: glam::Vec3) -> Result<(), SceneError> {
    if al.is_finite() && al.min_element() >= 0.0 && al.max_element() <= 1.0 {
        Ok(())
    } else {
        Err(p.err_at(
            "albedo",
            format!("albedo must lie in [0, 1] in every channel, got {al}"),
        ))
    }
}

/// The parameters of a `homogeneous` medium (phase and `sample_emitters` are set by
/// the caller). A `constvolume` stands for its value; a grid may give the albedo only.
fn parse_homogeneous(
    p: &mut Props,
    scale: f64,
    sigma_t_vol: Option<(Node, Volume)>,
    albedo_vol: Option<(Node, Volume)>,
) -> Result<Homogeneous, SceneError> {
    let sigma_a = p.rgb("sigma_a")?;
    let sigma_s = p.rgb("sigma_s")?;
    let sigma_t = match sigma_t_vol {
        None => p.rgb("sigma_t")?,
        Some((n, v)) => Some(v.as_constant().ok_or_else(|| {
            p.ctx.err(n, "a homogeneous medium's sigma_t must be constant (a float, an rgb or a constvolume); use a heterogeneous medium for a grid")
        })?),
    };
    let (albedo, albedo_volume) = match albedo_vol {
        None => (p.rgb("albedo")?, None),
        Some((_, v)) => match v.as_constant() {
            Some(c) => (Some(c), None),
            None => (Some(v.eval(glam::Vec3::ZERO)), Some(v)),
        },
    };
    let (sigma_t, albedo) = match (sigma_a, sigma_s) {
        (None, None) => {
            let st = sigma_t.unwrap_or(glam::Vec3::ONE);
            nonneg(p, "sigma_t", st)?;
            let al = albedo.unwrap_or(glam::Vec3::splat(0.75));
            unit_range(p, al)?;
            (st * scale as f32, al)
        }
        (Some(a), Some(s)) => {
            if sigma_t.is_some() || albedo.is_some() {
                return Err(
                    p.err("give either sigma_t and albedo, or sigma_a and sigma_s, not both")
                );
            }
            nonneg(p, "sigma_a", a)?;
            nonneg(p, "sigma_s", s)?;
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
    Ok(Homogeneous {
        sigma_t,
        albedo,
        albedo_volume,
        phase: Phase::Isotropic,
        sample_emitters: true,
    })
}

/// Reads a `<volume>` element given to a medium as `role` (`sigma_t`: values >= 0;
/// `albedo`: values in [0, 1]).
pub fn parse_volume(ctx: &Ctx, node: Node, role: &str) -> Result<Volume, SceneError> {
    let kind = ctx.required_attr(node, "type")?;
    let mut p = Props::parse(ctx, node)?;
    if let Some(&o) = p.objects.first() {
        return Err(ctx.err(
            o,
            format!("unexpected nested element in <volume type=\"{kind}\"> (values are given as parameters)"),
        ));
    }
    let to_world = p.transform("to_world")?.unwrap_or(glam::DMat4::IDENTITY);
    let det = to_world.determinant();
    if !(det != 0.0 && det.is_finite() && to_world.inverse().is_finite()) {
        return Err(p.err_at("to_world", "the volume's to_world is singular"));
    }
    let read = super::table::reader(VOLUMES, &kind).ok_or_else(|| {
        ctx.err(
            node,
            format!(
                "volume '{kind}' is not supported (supported: {})",
                super::table::names(VOLUMES).join(", ")
            ),
        )
    })?;
    let volume = read(&mut p, to_world, role)?;
    if !(volume.bbox_min.is_finite() && volume.bbox_max.is_finite()) {
        return Err(p.err_at("to_world", "the volume's bounding box is not finite"));
    }
    p.finish()?;
    Ok(volume)
}

/// The values a volume in `role` may hold: (lowest, highest, as text).
fn role_range(role: &str) -> (f32, f32, &'static str) {
    let (lo_ok, hi) = if role == "albedo" {
        (0.0f32, 1.0f32)
    } else {
        (0.0, f32::INFINITY)
    };
    let range = if role == "albedo" { "[0, 1]" } else { ">= 0" };
    (lo_ok, hi, range)
}

/// The `volume` plugins and their readers (the plugin table's `volume` family,
/// [`super::plugins`]), in the order errors list them.
pub(super) const VOLUMES: &[(&str, ReadVolume)] = &[
    ("constvolume", read_constvolume),
    ("gridvolume", read_gridvolume),
];

/// Reads one `<volume>` plugin.
pub(super) type ReadVolume = fn(&mut Props<'_, '_, '_>, DMat4, &str) -> Result<Volume, SceneError>;

/// `<volume type="constvolume">`.
fn read_constvolume(p: &mut Props, to_world: DMat4, role: &str) -> Result<Volume, SceneError> {
    let (lo_ok, hi, range) = role_range(role);
    let v = p.rgb("value")?.unwrap_or(glam::Vec3::ONE);
    if !(v.is_finite() && v.min_element() >= lo_ok && v.max_element() <= hi) {
        return Err(p.err_at(
            "value",
            format!(
                "the {role} volume's value must be finite and {range} in every channel, got {v}"
            ),
        ));
    }
    Ok(Volume::constant(v, to_world))
}

/// `<volume type="gridvolume">`.
fn read_gridvolume(p: &mut Props, to_world: DMat4, role: &str) -> Result<Volume, SceneError> {
    let (lo_ok, hi, range) = role_range(role);
    let filter = match p.string("filter_type")?.as_deref() {
        None | Some("trilinear") => GridFilter::Trilinear,
        Some("nearest") => GridFilter::Nearest,
        Some(other) => {
            return Err(p.err_at(
                "filter_type",
                format!("filter_type '{other}' is not one of: trilinear, nearest"),
            ))
        }
    };
    let wrap = match p.string("wrap_mode")?.as_deref() {
        None | Some("clamp") => WrapMode::Clamp,
        Some("repeat") => WrapMode::Repeat,
        Some("mirror") => WrapMode::Mirror,
        Some(other) => {
            return Err(p.err_at(
                "wrap_mode",
                format!("wrap_mode '{other}' is not one of: clamp, repeat, mirror"),
            ))
        }
    };
    p.boolean_or("raw", false)?;
    p.boolean_or("accel", true)?;
    let use_grid_bbox = p.boolean_or("use_grid_bbox", false)?;
    let max_value = p.float("max_value")?;
    let name = p
        .string("filename")?
        .ok_or_else(|| p.err("missing parameter 'filename' (a .vol file)"))?;
    if name.trim().is_empty() {
        return Err(p.err_at("filename", "the filename is empty"));
    }
    let path = p.ctx.resolve(&name);
    p.ctx.read_mesh_file(&path);
    let file = read_vol(&path).map_err(|e| p.err_at("filename", format!("volume '{name}' {e}")))?;
    let (min, max) = (file.min(), file.max());
    if min < lo_ok || max > hi {
        return Err(p.err_at(
            "filename",
            format!(
                "volume '{name}' holds values in [{min}, {max}]; as {role} they must be {range}"
            ),
        ));
    }
    let max = match max_value {
        None => max,
        Some(m) if m.is_finite() && m as f32 >= max => m as f32,
        Some(m) => {
            return Err(p.err_at(
                "max_value",
                format!("max_value {m} is below the grid's largest value {max} (it bounds the extinction for delta tracking)"),
            ))
        }
    };
    // The local frame: the file's box onto the unit cube (`use_grid_bbox`),
    // after the world-to-volume map.
    let mut to_world = to_world;
    if use_grid_bbox {
        let lo = glam::Vec3::from_array(file.bbox_min).as_dvec3();
        let ext = glam::Vec3::from_array(file.bbox_max).as_dvec3() - lo;
        if !(ext.min_element() > 0.0 && ext.is_finite() && lo.is_finite()) {
            return Err(p.err_at(
                "use_grid_bbox",
                format!(
                    "volume '{name}' has the bounding box {:?} - {:?}, which is empty",
                    file.bbox_min, file.bbox_max
                ),
            ));
        }
        // Mitsuba: to_local = bbox_transform * to_local, bbox_transform =
        // scale(1 / extents) * translate(-min).
        to_world = to_world * glam::DMat4::from_translation(lo) * glam::DMat4::from_scale(ext);
    }
    let mut v = Volume::constant(glam::Vec3::ZERO, to_world);
    v.data = VolumeData::Grid(Arc::new(Grid {
        size: file.size,
        channels: file.channels,
        data: file.data,
        filter,
        wrap,
    }));
    v.max = max;
    Ok(v)
}

/// Reads a `<phase>` element.
pub fn parse_phase(ctx: &Ctx, node: Node) -> Result<Phase, SceneError> {
    let kind = ctx.required_attr(node, "type")?;
    let mut p = Props::parse(ctx, node)?;
    let read = super::table::reader(PHASES, &kind).ok_or_else(|| {
        ctx.err(
            node,
            format!(
                "phase function '{kind}' is not supported (supported: {})",
                super::table::names(PHASES).join(", ")
            ),
        )
    })?;
    let phase = read(&mut p)?;
    if let Some(&o) = p.objects.first() {
        return Err(ctx.err(o, "unexpected nested element in <phase>"));
    }
    p.finish()?;
    Ok(phase)
}

/// The `phase` plugins and their readers (the plugin table's `phase` family,
/// [`super::plugins`]), in the order errors list them.
pub(super) const PHASES: &[(&str, ReadPhase)] = &[("isotropic", read_isotropic), ("hg", read_hg)];

/// Reads one `<phase>` plugin.
pub(super) type ReadPhase = fn(&mut Props<'_, '_, '_>) -> Result<Phase, SceneError>;

/// `<phase type="isotropic">`.
fn read_isotropic(_p: &mut Props) -> Result<Phase, SceneError> {
    Ok(Phase::Isotropic)
}

/// `<phase type="hg">`.
fn read_hg(p: &mut Props) -> Result<Phase, SceneError> {
    let g = p.float_or("g", 0.8)?;
    if !(g > -1.0 && g < 1.0) {
        return Err(p.err_at(
            "g",
            format!("the asymmetry parameter g must lie in (-1, 1), got {g}"),
        ));
    }
    Ok(Phase::Hg { g: g as f32 })
}

/// The index of the medium an element gives: a nested `<medium>` (appended to
/// `media`) or a `<ref id=...>` to a top-level one.
pub(super) fn medium_index(
    ctx: &Ctx,
    obj: Node,
    media: &mut Vec<Medium>,
    named_media: &HashMap<String, u32>,
) -> Result<u32, SceneError> {
    if obj.has_tag_name("medium") {
        media.push(parse_medium(ctx, obj)?);
        return Ok((media.len() - 1) as u32);
    }
    let id = ctx.required_attr(obj, "id")?;
    named_media.get(&id).copied().ok_or_else(|| {
        ctx.err(
            obj,
            format!("no <medium> with id '{id}' is declared before this reference"),
        )
    })
}
