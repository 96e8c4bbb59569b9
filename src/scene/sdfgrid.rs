//! `<shape type="sdfgrid">` (Mitsuba 3's `src/shapes/sdfgrid.cpp`) and the Mitsuba
//! `.vol` grid file it reads. The geometry is [`crate::geometry::sdfgrid`].
//!
//! | parameter | meaning |
//! |-----------|---------|
//! | filename | required: a Mitsuba `.vol` file of one channel (Mitsuba's `grid` tensor parameter exists only from Python/C++, not in XML; without `filename` Mitsuba throws as tstat does) |
//! | normals | `smooth` (default) or `analytic`, anything else an error (Mitsuba's message) |
//! | to_world | any invertible affine map of the grid's `[0, 1]^3` (a warning when it rotates or shears, where Mitsuba 3 warns and renders holes) |
//!
//! No `flip_normals` (Mitsuba's sdfgrid does not read it: "unreferenced property"),
//! and no emitter: its area is 0 in Mitsuba, which cannot sample it, so tstat refuses it
//! where Mitsuba would silently emit nothing.
//!
//! The `.vol` file is read by [`crate::media::vol_file::read_vol`] (shared with the
//! media's `gridvolume`: header, sizes against the file before allocating, finite
//! values); the sdfgrid then needs one channel (Mitsuba's message), at least 2 values
//! along each axis and one voxel with a zero crossing ([`SdfGrid::new`]).

use super::error::SceneError;
use super::props::Props;
use crate::geometry::sdfgrid::{SdfGeom, SdfGrid};
use crate::geometry::shape::ShapeGeom;
use crate::media::vol_file::read_vol;
use glam::DMat4;
use std::sync::Arc;

/// The `sdfgrid` shape of `props` placed by `to_world`.
pub fn parse_sdfgrid(props: &mut Props, to_world: &DMat4) -> Result<ShapeGeom, SceneError> {
    let smooth = match props.string("normals")?.as_deref() {
        None | Some("smooth") => true,
        Some("analytic") => false,
        Some(other) => {
            return Err(props.err_at(
                "normals",
                format!(
                    "invalid normals mode \"{other}\", must be one of: \"analytic\", or \"smooth\""
                ),
            ))
        }
    };
    let name = props.string("filename")?.ok_or_else(|| {
        props.err("the SDF values must be specified with the \"filename\" parameter (a .vol grid)")
    })?;
    if name.trim().is_empty() {
        return Err(props.err_at("filename", "the filename is empty"));
    }
    let path = props.ctx.resolve(&name);
    props.ctx.read_mesh_file(&path);
    let vol = read_vol(&path).map_err(|e| props.err_at("filename", format!("'{name}' {e}")))?;
    if vol.channels != 1 {
        return Err(props.err_at(
            "filename",
            format!(
                "'{name}': the grid has {} channels, expected 1",
                vol.channels
            ),
        ));
    }
    let grid = SdfGrid::new(vol.size, vol.data)
        .map_err(|e| props.err_at("filename", format!("'{name}': {e}")))?;
    let geom = SdfGeom::new(Arc::new(grid), *to_world, smooth)
        .map_err(|e| props.err_at("to_world", e.to_string()))?;
    // Mitsuba warns on rotations (its voxel boxes map only two corners, so a rotated
    // grid renders with holes there); tstat maps all eight and stays exact.
    let lin = glam::DMat3::from_mat4(*to_world);
    let scale = lin.x_axis.length() + lin.y_axis.length() + lin.z_axis.length();
    let off = [
        lin.x_axis.y,
        lin.x_axis.z,
        lin.y_axis.x,
        lin.y_axis.z,
        lin.z_axis.x,
        lin.z_axis.y,
    ];
    if off.iter().any(|v| v.abs() > 1e-6 * scale) {
        props.warn_at(
            "to_world",
            "the sdfgrid's to_world rotates or shears: tstat intersects it exactly, but Mitsuba 3 warns and renders holes (its voxel boxes assume an axis-aligned map); use shapegroup + instance to match it",
        );
    }
    let (lo, hi) = geom.bounds();
    super::limits::check_world_point(lo.as_dvec3())
        .and_then(|_| super::limits::check_world_point(hi.as_dvec3()))
        .map_err(|e| props.err_at("to_world", e.to_string()))?;
    Ok(ShapeGeom::Sdf(Box::new(geom)))
}
