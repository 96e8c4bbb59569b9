//! Loading triangle meshes from disk: PLY in `ply.rs`, OBJ in `obj.rs`, the shared
//! [`MeshData`], [`MeshError`] and helpers here.
//!
//! Two formats are supported here (Mitsuba's `.serialized` meshes are read into the
//! same [`MeshData`] by [`super::serialized`]):
//!
//! * **PLY** (ASCII, binary little-endian and binary big-endian), read with the
//!   `ply-rs` crate. The `vertex` element must have scalar `x`, `y`, `z`
//!   properties (any numeric type, usually `float` or `double`); if it also has
//!   `nx`, `ny`, `nz` they become per-vertex normals. The `face` element must
//!   have an integer list property named `vertex_indices` (or `vertex_index`).
//!   Other scalar vertex and face properties become mesh attributes as Mitsuba
//!   groups them ([`load_ply_with_attributes`], `super::ply_attributes`); other
//!   elements are skipped (elements after both `vertex` and `face` are not read).
//! * **Wavefront OBJ**, read with the `tobj` crate using a single index per
//!   vertex. All objects and groups in the file are merged into one mesh.
//!   Vertices are numbered in order of first use by a face, and vertices no face
//!   uses are dropped (this is how `tobj` builds a single index). Normals are
//!   kept only if every vertex has one. Material libraries are not read; `l`
//!   (line) and `p` (point) statements are ignored.
//!
//! In both formats, polygons with more than three vertices are split into a fan
//! of triangles `(v0, v1, v2), (v0, v2, v3), ...`, keeping the vertex order
//! (and so the winding) of the file. The result is a [`MeshData`] in the file's
//! own coordinates; no transform is applied here.
//!
//! Every problem (missing file, malformed or truncated content, a face with
//! fewer than three vertices or an index out of range, a non-finite coordinate,
//! a file without faces) is returned as a [`MeshError`] whose message names the
//! file. Vertex and face numbers in messages count from 0 in file order; OBJ
//! messages also give the line. Nothing in here panics on bad input.

mod obj;
mod ply;
#[cfg(test)]
mod tests;

pub use obj::{load_obj, ObjError, ObjIndexKind};
pub use ply::{load_ply, load_ply_with_attributes, PlyError};

use super::serialized::SerializedError;
use glam::{Vec2, Vec3};
use std::io;
use std::path::{Path, PathBuf};

/// A triangle mesh as read from disk, before any to_world transform.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshData {
    pub positions: Vec<Vec3>,
    /// Per-vertex normals when the file has them (same length as positions).
    pub normals: Option<Vec<Vec3>>,
    /// Vertex indices, counter-clockwise as in the file; polygons are fan-triangulated.
    pub triangles: Vec<[u32; 3]>,
    /// Per-vertex texture coordinates as stored in the file (same length as positions),
    /// when the file has them for every vertex. The shape applies `flip_tex_coords`.
    pub uvs: Option<Vec<Vec2>>,
}

/// Why a mesh file could not be loaded. Every message names the file and fits
/// on one line.
#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    /// The file could not be opened or read.
    #[error("cannot read mesh file {}: {source}", .path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: io::Error,
    },
    /// The file was read but is not a usable PLY mesh.
    #[error("invalid PLY file {}: {problem}", .path.display())]
    Ply {
        path: PathBuf,
        #[source]
        problem: PlyError,
    },
    /// The file was read but is not a usable OBJ mesh.
    #[error("invalid OBJ file {}: {problem}", .path.display())]
    Obj {
        path: PathBuf,
        #[source]
        problem: ObjError,
    },
    /// The file was read but is not a usable Mitsuba `.serialized` mesh.
    #[error("invalid serialized mesh file {}: {problem}", .path.display())]
    Serialized {
        path: PathBuf,
        #[source]
        problem: SerializedError,
    },
    /// The file is well formed but contains no faces (e.g. a point cloud).
    #[error("mesh file {} has no faces", .path.display())]
    NoFaces { path: PathBuf },
}

/// What went wrong while decoding file contents (a [`PlyError`] or an [`ObjError`]);
/// the caller adds the path.
pub(super) enum MeshProblem<E> {
    NoFaces,
    Invalid(E),
}

impl<E> From<E> for MeshProblem<E> {
    fn from(e: E) -> Self {
        MeshProblem::Invalid(e)
    }
}

/// Reads a regular file of at most [`crate::io::MAX_MESH_BYTES`]; devices, FIFOs,
/// directories (and links to them) are refused before anything is read.
pub(super) fn read_file(path: &Path) -> Result<Vec<u8>, MeshError> {
    crate::io::read_regular(path, crate::io::MAX_MESH_BYTES).map_err(|e| MeshError::Io {
        path: path.to_path_buf(),
        source: io::Error::other(e),
    })
}

/// Converts to `f32`; `None` if any component is (or overflows to) NaN or infinity.
pub(super) fn finite_vec3(v: [f64; 3]) -> Option<Vec3> {
    let v = Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32);
    v.is_finite().then_some(v)
}

/// Smooth vertex normals for a file mesh without them, as Mitsuba computes them:
/// face normals weighted by the angle each face makes at the vertex.
pub fn vertex_normals(m: &MeshData) -> Vec<Vec3> {
    let mut acc = vec![glam::DVec3::ZERO; m.positions.len()];
    for t in &m.triangles {
        let p = t.map(|i| m.positions[i as usize].as_dvec3());
        let n = (p[1] - p[0]).cross(p[2] - p[0]);
        let Some(n) = n.try_normalize() else { continue };
        for k in 0..3 {
            let e1 = p[(k + 1) % 3] - p[k];
            let e2 = p[(k + 2) % 3] - p[k];
            if let (Some(a), Some(b)) = (e1.try_normalize(), e2.try_normalize()) {
                acc[t[k] as usize] += n * a.dot(b).clamp(-1.0, 1.0).acos();
            }
        }
    }
    acc.into_iter()
        .map(|n| n.normalize_or_zero().as_vec3())
        .collect()
}
