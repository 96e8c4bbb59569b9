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
//! `.vol` (Mitsuba's `VolumeGrid::read`, little-endian): `VOL`, version byte 3, i32
//! encoding 1 (float32), i32 `nx ny nz`, i32 channels, 6 f32 (a box the sdfgrid ignores),
//! then `nx ny nz channels` f32, x fastest. Checked: magic, version, encoding, one
//! channel (Mitsuba's message), sizes (>= 2 per axis, the data present before anything
//! is allocated, bytes after it ignored as Mitsuba does), finite values, at least one
//! voxel with a zero crossing.

use super::error::SceneError;
use super::props::Props;
use crate::geometry::sdfgrid::{SdfGeom, SdfGrid};
use crate::geometry::shape::ShapeGeom;
use glam::DMat4;
use std::path::Path;
use std::sync::Arc;

/// The largest `.vol` file read (256 Mi values: 1 GiB).
pub const MAX_VOL_BYTES: u64 = 1 << 30;
/// The header's size in bytes.
const HEADER: usize = 48;

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
    let (res, values) =
        read_vol(&path).map_err(|e| props.err_at("filename", format!("'{name}': {e}")))?;
    let grid = SdfGrid::new(res, values)
        .map_err(|e| props.err_at("filename", format!("'{name}': {e}")))?;
    let geom =
        SdfGeom::new(Arc::new(grid), *to_world, smooth).map_err(|e| props.err_at("to_world", e))?;
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
    super::shapes::check_world_point(lo.as_dvec3())
        .and_then(|_| super::shapes::check_world_point(hi.as_dvec3()))
        .map_err(|e| props.err_at("to_world", e))?;
    Ok(ShapeGeom::Sdf(Box::new(geom)))
}

/// A one-channel `.vol` file: its sizes `[nx, ny, nz]` and values (x fastest).
pub fn read_vol(path: &Path) -> Result<([usize; 3], Vec<f32>), String> {
    let bytes = crate::io::read_regular(path, MAX_VOL_BYTES)?;
    parse_vol(&bytes)
}

/// [`read_vol`] on the file's bytes.
pub fn parse_vol(bytes: &[u8]) -> Result<([usize; 3], Vec<f32>), String> {
    if bytes.len() < 4 || &bytes[..3] != b"VOL" {
        return Err("not a Mitsuba volume file (it does not start with \"VOL\")".into());
    }
    if bytes[3] != 3 {
        return Err(format!(
            "volume file version {} (only version 3 is supported, as in Mitsuba 3)",
            bytes[3]
        ));
    }
    if bytes.len() < HEADER {
        return Err(format!(
            "the volume file is truncated: {} bytes, shorter than its {HEADER}-byte header",
            bytes.len()
        ));
    }
    let int = |i: usize| i32::from_le_bytes(bytes[4 + 4 * i..8 + 4 * i].try_into().unwrap());
    let encoding = int(0);
    if encoding != 1 {
        return Err(format!(
            "volume encoding {encoding} (only 1, float32, is supported, as in Mitsuba 3)"
        ));
    }
    let (nx, ny, nz, channels) = (int(1), int(2), int(3), int(4));
    if channels != 1 {
        return Err(format!("the grid has {channels} channels, expected 1"));
    }
    if nx < 2 || ny < 2 || nz < 2 {
        return Err(format!(
            "the grid is {nx} x {ny} x {nz} values: an SDF grid needs at least 2 along each axis"
        ));
    }
    let res = [nx as usize, ny as usize, nz as usize];
    let count = (res[0] as u128) * (res[1] as u128) * (res[2] as u128);
    let need = HEADER as u128 + 4 * count;
    if (bytes.len() as u128) < need {
        return Err(format!(
            "the volume file is truncated: a {nx} x {ny} x {nz} grid needs {need} bytes, the file has {}",
            bytes.len()
        ));
    }
    let values = bytes[HEADER..HEADER + 4 * count as usize]
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
        .collect();
    Ok((res, values))
}

/// A one-channel `.vol` file's bytes (for tests and tools): sizes `res`, values x
/// fastest, the header's box `[0, 1]^3`.
pub fn vol_bytes(res: [usize; 3], values: &[f32]) -> Vec<u8> {
    let mut b = b"VOL\x03".to_vec();
    for v in [1, res[0] as i32, res[1] as i32, res[2] as i32, 1] {
        b.extend(v.to_le_bytes());
    }
    for v in [0.0f32, 0.0, 0.0, 1.0, 1.0, 1.0] {
        b.extend(v.to_le_bytes());
    }
    for v in values {
        b.extend(v.to_le_bytes());
    }
    b
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vol_round_trip_and_malformed_headers() {
        let values: Vec<f32> = (0..24).map(|i| i as f32 - 10.0).collect();
        let b = vol_bytes([2, 3, 4], &values);
        assert_eq!(parse_vol(&b).unwrap(), ([2, 3, 4], values.clone()));
        // Trailing bytes are ignored, as Mitsuba reads only the values it needs.
        let mut long = b.clone();
        long.extend([0u8; 5]);
        assert!(parse_vol(&long).is_ok());
        assert!(parse_vol(&b[..b.len() - 1])
            .unwrap_err()
            .contains("truncated"));
        assert!(parse_vol(&b[..20]).unwrap_err().contains("truncated"));
        assert!(parse_vol(b"").unwrap_err().contains("VOL"));
        let mut v2 = b.clone();
        v2[3] = 2;
        assert!(parse_vol(&v2).unwrap_err().contains("version"));
        let mut enc = b.clone();
        enc[4] = 2;
        assert!(parse_vol(&enc).unwrap_err().contains("encoding"));
        let mut ch = b.clone();
        ch[20] = 3;
        assert!(parse_vol(&ch).unwrap_err().contains("3 channels"));
        let mut neg = b.clone();
        neg[8..12].copy_from_slice(&(-5i32).to_le_bytes());
        assert!(parse_vol(&neg).unwrap_err().contains("at least 2"));
        let mut huge = b;
        for i in 0..3 {
            huge[8 + 4 * i..12 + 4 * i].copy_from_slice(&i32::MAX.to_le_bytes());
        }
        assert!(parse_vol(&huge).unwrap_err().contains("truncated"));
    }
}
