//! `transient_hdr_film` (mitransient's names): image size and the time axis.
//!
//! | parameter | type | default | meaning |
//! |-----------|------|---------|---------|
//! | width, height | integer | 768, 576 | image size in pixels |
//! | temporal_bins | integer | required | number of time bins T |
//! | start_opl | float | 0 | OPL of the start of bin 0 (t0, scene units) |
//! | bin_width_opl | float | required | bin width h in OPL (scene units) |
//! | rfilter | nested | box | only `box` (mitransient's transient block supports only it) |
//! | exhaustive_scan, laser_scan_width, laser_scan_height | boolean, integer | false, 0 | an `nlos_capture_meter`'s exhaustive laser grid (`nlos.rs`) |
//!
//! The film itself (`Film::bin`, the time axis) is [`crate::sensors::film`].

use super::ctx::Ctx;
use super::error::SceneError;
use super::props::Props;
use crate::sensors::film::{check_bin_width, Film};
use crate::sensors::time_axis::TimeAxis;
use roxmltree::Node;

/// The film plugins (the plugin table's `film` family).
pub(super) const FILMS: &[&str] = &["transient_hdr_film"];

/// The reconstruction filters a film accepts (the plugin table's `rfilter` family):
/// mitransient's transient block supports only the box.
pub(super) const RFILTERS: &[&str] = &["box"];

/// Reads a `<film>`.
pub fn parse_film(ctx: &Ctx, node: Node) -> Result<Film, SceneError> {
    Ok(parse_with_scan(ctx, node, false)?.0)
}

/// The film of an `nlos_capture_meter`: also `exhaustive_scan` (boolean, default
/// false) with `laser_scan_width` and `laser_scan_height` (the laser grid of an
/// exhaustive capture, returned when `exhaustive_scan` is true).
pub fn parse_film_for_meter(
    ctx: &Ctx,
    node: Node,
) -> Result<(Film, Option<[usize; 2]>), SceneError> {
    parse_with_scan(ctx, node, true)
}

fn parse_with_scan(
    ctx: &Ctx,
    node: Node,
    meter: bool,
) -> Result<(Film, Option<[usize; 2]>), SceneError> {
    let kind = ctx.required_attr(node, "type")?;
    if !FILMS.contains(&kind.as_str()) {
        return Err(ctx.err(
            node,
            format!("film type '{kind}' is not supported (use transient_hdr_film)"),
        ));
    }
    let mut p = Props::parse(ctx, node)?;
    let dim = |p: &mut Props, name: &str, default: Option<i64>| -> Result<usize, SceneError> {
        let v = match (p.integer(name)?, default) {
            (Some(v), _) | (None, Some(v)) => v,
            (None, None) => return Err(p.err(format!("missing parameter '{name}'"))),
        };
        if v <= 0 {
            return Err(p.err_at(name, format!("{name} must be positive, got {v}")));
        }
        Ok(v as usize)
    };
    let width = dim(&mut p, "width", Some(768))?;
    let height = dim(&mut p, "height", Some(576))?;
    let bins = dim(&mut p, "temporal_bins", None)?;
    let start_opl = p.float_or("start_opl", 0.0)?;
    let bin_width_opl = p
        .float("bin_width_opl")?
        .ok_or_else(|| p.err("missing parameter 'bin_width_opl'"))?;
    check_bin_width("bin_width_opl", bin_width_opl)
        .map_err(|e| p.err_at("bin_width_opl", e.to_string()))?;
    // mitransient film flags that do not change what is computed here.
    p.ignore("auto_detect_bins");
    let mut scan = None;
    if p.peek("exhaustive_scan").is_some() || p.peek("laser_scan_width").is_some() {
        if !meter {
            return Err(p.err_at("exhaustive_scan", "exhaustive_scan and laser_scan_width/height belong to the film of an nlos_capture_meter"));
        }
        let on = p.boolean_or("exhaustive_scan", false)?;
        let lw = p.integer("laser_scan_width")?.unwrap_or(0);
        let lh = p.integer("laser_scan_height")?.unwrap_or(0);
        if on {
            for (name, v) in [("laser_scan_width", lw), ("laser_scan_height", lh)] {
                if !(1..=1 << 16).contains(&v) {
                    return Err(p.err_at(
                        name,
                        format!("an exhaustive scan needs {name} in 1..=65536, got {v}"),
                    ));
                }
            }
            scan = Some([lw as usize, lh as usize]);
        }
    }
    for obj in std::mem::take(&mut p.objects) {
        match (obj.tag_name().name(), ctx.attr(obj, "type")?.as_deref()) {
            ("rfilter", Some(f)) if RFILTERS.contains(&f) => Props::parse(ctx, obj)?.finish()?,
            ("rfilter", other) => {
                return Err(ctx.err(obj, format!("reconstruction filter {other:?} is not supported; the transient film uses the box filter")))
            }
            (tag, _) => return Err(ctx.err(obj, format!("unexpected <{tag}> inside <film>"))),
        }
    }
    p.finish()?;
    let film = Film {
        width,
        height,
        time: TimeAxis {
            bins,
            start_opl,
            bin_width_opl,
        },
        channels: 3,
    };
    Ok((film, scan))
}
