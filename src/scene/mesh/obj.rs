//! Wavefront OBJ meshes through `tobj`, one index per vertex (module docs of `mesh`).

use super::{finite_vec3, read_file, MeshData, MeshError, MeshProblem};
use glam::Vec2;
use std::path::Path;

/// The vertex data an OBJ face index refers to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ObjIndexKind {
    Vertex,
    TextureCoordinate,
    Normal,
}

impl ObjIndexKind {
    /// The statement defining one (`v`, `vt`, `vn`), in the order of a face
    /// vertex's `v/vt/vn` parts.
    const ALL: [ObjIndexKind; 3] = [
        ObjIndexKind::Vertex,
        ObjIndexKind::TextureCoordinate,
        ObjIndexKind::Normal,
    ];

    fn statement(self) -> &'static str {
        match self {
            ObjIndexKind::Vertex => "v",
            ObjIndexKind::TextureCoordinate => "vt",
            ObjIndexKind::Normal => "vn",
        }
    }

    pub fn singular(self) -> &'static str {
        match self {
            ObjIndexKind::Vertex => "vertex",
            ObjIndexKind::TextureCoordinate => "texture coordinate",
            ObjIndexKind::Normal => "normal",
        }
    }

    pub fn plural(self) -> &'static str {
        match self {
            ObjIndexKind::Vertex => "vertices",
            ObjIndexKind::TextureCoordinate => "texture coordinates",
            ObjIndexKind::Normal => "normals",
        }
    }
}

/// What makes an OBJ file's contents unusable ([`MeshError::Obj`] adds the path).
/// Lines count from 1, faces (`f` statements) from 0.
#[derive(Debug, thiserror::Error)]
pub enum ObjError {
    #[error("not valid UTF-8 text ({0})")]
    NotUtf8(#[source] std::str::Utf8Error),
    /// `tobj` refused the file.
    #[error(transparent)]
    Tobj(tobj::LoadError),
    /// A vertex `position` or `normal` (`what`) that is not finite.
    #[error("vertex {what} {value:?} is not finite")]
    VertexNotFinite { what: &'static str, value: [f64; 3] },
    #[error("texture coordinates {uv} are not finite")]
    UvNotFinite { uv: Vec2 },
    #[error("object '{object}': index count is not a multiple of 3")]
    IndexCount { object: String },
    #[error("object '{object}': vertex index {index} is out of range")]
    IndexRange { object: String, index: u32 },
    #[error("line {line} (face {face}): face has {vertices} vertices, at least 3 are needed")]
    FaceTooSmall {
        line: usize,
        face: usize,
        vertices: usize,
    },
    #[error("line {line} (face {face}): malformed face vertex '{corner}'")]
    MalformedFaceVertex {
        line: usize,
        face: usize,
        corner: String,
    },
    /// A face index of 0 or beyond those defined (`defined` counts the whole file for
    /// positive indices, the lines before the face for negative ones).
    #[error(
        "line {line} (face {face}): {} index {index} is out of range ({defined} {} defined, indices start at 1)",
        .kind.singular(),
        .kind.plural()
    )]
    FaceIndex {
        line: usize,
        face: usize,
        kind: ObjIndexKind,
        index: i64,
        defined: usize,
    },
}

/// Loads a Wavefront OBJ mesh, merging all objects and groups into one mesh.
pub fn load_obj(path: &Path) -> Result<MeshData, MeshError> {
    let bytes = read_file(path)?;
    parse_obj(&bytes).map_err(|problem| match problem {
        MeshProblem::NoFaces => MeshError::NoFaces {
            path: path.to_path_buf(),
        },
        MeshProblem::Invalid(problem) => MeshError::Obj {
            path: path.to_path_buf(),
            problem,
        },
    })
}

fn parse_obj(bytes: &[u8]) -> Result<MeshData, MeshProblem<ObjError>> {
    let text = std::str::from_utf8(bytes).map_err(ObjError::NotUtf8)?;
    check_obj_faces(text)?;

    // The struct update covers fields that only exist with tobj's optional
    // `merging` / `reordering` features.
    #[allow(clippy::needless_update)]
    let options = tobj::LoadOptions {
        single_index: true,
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
        ..Default::default()
    };
    // Materials are not needed: answer every `mtllib` with "not found", which
    // tobj reports separately and we ignore.
    let (models, _materials) = tobj::load_obj_buf(&mut text.as_bytes(), &options, |_| {
        Err(tobj::LoadError::OpenFileFailed)
    })
    .map_err(ObjError::Tobj)?;

    let all_have_normals = models
        .iter()
        .all(|m| m.mesh.normals.len() == m.mesh.positions.len());
    let all_have_uvs = models
        .iter()
        .all(|m| 3 * m.mesh.texcoords.len() == 2 * m.mesh.positions.len());
    let mut positions = Vec::new();
    let mut normals = Vec::new();
    let mut uvs = Vec::new();
    let mut triangles = Vec::new();
    for model in &models {
        let mesh = &model.mesh;
        let offset = positions.len();
        for p in mesh.positions.chunks_exact(3) {
            let v = [to_f64(p[0]), to_f64(p[1]), to_f64(p[2])];
            positions.push(finite_vec3(v).ok_or(ObjError::VertexNotFinite {
                what: "position",
                value: v,
            })?);
        }
        if all_have_normals {
            for n in mesh.normals.chunks_exact(3) {
                let v = [to_f64(n[0]), to_f64(n[1]), to_f64(n[2])];
                normals.push(finite_vec3(v).ok_or(ObjError::VertexNotFinite {
                    what: "normal",
                    value: v,
                })?);
            }
        }
        if all_have_uvs {
            for t in mesh.texcoords.chunks_exact(2) {
                let uv = Vec2::new(t[0], t[1]);
                if !uv.is_finite() {
                    return Err(ObjError::UvNotFinite { uv }.into());
                }
                uvs.push(uv);
            }
        }
        if mesh.indices.len() % 3 != 0 {
            return Err(ObjError::IndexCount {
                object: model.name.clone(),
            }
            .into());
        }
        for tri in mesh.indices.chunks_exact(3) {
            let mut out = [0u32; 3];
            for (o, &i) in out.iter_mut().zip(tri) {
                let global = offset + i as usize;
                *o = match u32::try_from(global) {
                    Ok(g) if global < positions.len() => g,
                    _ => {
                        return Err(ObjError::IndexRange {
                            object: model.name.clone(),
                            index: i,
                        }
                        .into())
                    }
                };
            }
            triangles.push(out);
        }
    }
    if triangles.is_empty() {
        return Err(MeshProblem::NoFaces);
    }
    Ok(MeshData {
        positions,
        normals: all_have_normals.then_some(normals),
        triangles,
        uvs: all_have_uvs.then_some(uvs),
    })
}

/// Checks every `f` statement before `tobj` sees it: at least three vertices,
/// and every index non-zero and within range. Besides giving errors with line
/// numbers, this shields us from `tobj` 4, whose index arithmetic overflows
/// (a panic in debug builds) on a relative texture or normal index reaching
/// before the first one, e.g. `f 1/-5 2/1 3/1`, and which silently treats a
/// texture or normal index of 0 as absent.
fn check_obj_faces(text: &str) -> Result<(), ObjError> {
    let kind_of = |tag: &str| ObjIndexKind::ALL.iter().position(|k| k.statement() == tag);
    let mut totals = [0usize; 3];
    for line in text.lines() {
        if let Some(k) = line.split_whitespace().next().and_then(kind_of) {
            totals[k] += 1;
        }
    }

    let mut seen = [0usize; 3];
    let mut face = 0usize;
    for (n, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        let Some(tag) = words.next() else { continue };
        if let Some(k) = kind_of(tag) {
            seen[k] += 1;
            continue;
        }
        if tag != "f" {
            continue;
        }
        let corners: Vec<&str> = words.collect();
        let line = n + 1;
        if corners.len() < 3 {
            return Err(ObjError::FaceTooSmall {
                line,
                face,
                vertices: corners.len(),
            });
        }
        for corner in corners {
            let malformed = || ObjError::MalformedFaceVertex {
                line,
                face,
                corner: corner.to_string(),
            };
            let parts: Vec<&str> = corner.split('/').collect();
            if parts.len() > 3 || parts[0].is_empty() {
                return Err(malformed());
            }
            for (k, part) in parts.iter().enumerate().filter(|(_, p)| !p.is_empty()) {
                let index: i64 = part.parse().map_err(|_| malformed())?;
                // Negative indices count back from the last one defined so far.
                let ok = match index {
                    0 => false,
                    i if i < 0 => i.unsigned_abs() <= seen[k] as u64,
                    i => i as u64 <= totals[k] as u64,
                };
                if !ok {
                    return Err(ObjError::FaceIndex {
                        line,
                        face,
                        kind: ObjIndexKind::ALL[k],
                        index,
                        defined: if index < 0 { seen[k] } else { totals[k] },
                    });
                }
            }
        }
        face += 1;
    }
    Ok(())
}

/// Widens a `tobj` float (`f32`, or `f64` with its `use_f64` feature).
fn to_f64<T: Into<f64>>(v: T) -> f64 {
    v.into()
}
