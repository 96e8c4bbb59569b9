//! Loading triangle meshes from disk.
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

use std::borrow::Cow;
use std::io;
use std::path::{Path, PathBuf};

use super::ply_attributes;
use crate::geometry::mesh_attributes::{MeshAttribute, MeshAttributes};
use glam::{Vec2, Vec3};
use ply_rs::parser::Parser;
use ply_rs::ply::{ElementDef, Encoding, Property, PropertyAccess, PropertyType, ScalarType};

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

/// What makes a PLY file's contents unusable ([`MeshError::Ply`] adds the path).
/// Vertex, face and entry numbers count from 0, lines from 1.
#[derive(Debug, thiserror::Error)]
pub enum PlyError {
    #[error("not a PLY file (it does not start with 'ply')")]
    NotPly,
    /// A header count or version too large for `ply-rs` (which would panic on it).
    #[error("bad header: line {line}: number {number} is too large")]
    HeaderNumber { line: usize, number: String },
    /// `ply-rs` refused the header.
    #[error("bad header: {}", one_line(&.0.to_string()))]
    Header(#[source] io::Error),
    #[error("there is no 'vertex' element")]
    NoVertexElement,
    /// A coordinate property (`x`, `y` or `z`) that is a list.
    #[error("vertex property '{name}' is a list, expected a number")]
    VertexPropertyList { name: &'static str },
    /// A missing coordinate property (`x`, `y` or `z`).
    #[error("the vertex element has no '{name}' property")]
    MissingVertexProperty { name: &'static str },
    #[error("the face element has no 'vertex_indices' (or 'vertex_index') property")]
    NoFaceList,
    /// The face list property `name` has another type.
    #[error("face property '{name}' must be a list of integers, found {found:?}")]
    FaceListType {
        name: &'static str,
        found: PropertyType,
    },
    #[error("internal error: vertex or face element was not read")]
    ElementsNotRead,
    /// A vertex's `position` or `normal` (`what`) that is not finite.
    #[error("vertex {vertex}: {what} {value:?} is not finite")]
    VertexNotFinite {
        vertex: usize,
        what: &'static str,
        value: [f64; 3],
    },
    #[error("vertex {vertex}: texture coordinates {uv:?} are not finite")]
    UvNotFinite { vertex: usize, uv: [f64; 2] },
    #[error("face {face} has {vertices} vertices, at least 3 are needed")]
    FaceTooSmall { face: usize, vertices: usize },
    #[error("face {face} refers to vertex {index}, but there are only {vertices} vertices")]
    FaceIndex {
        face: usize,
        index: i64,
        vertices: usize,
    },
    /// Two attributes of one name (Mitsuba refuses them too).
    #[error(
        "mesh attribute '{name}' is defined twice (Mitsuba: add_attribute(): attribute already exists)"
    )]
    DuplicateAttribute { name: String },
    /// An element whose declared entries cannot fit in the bytes left.
    #[error(
        "file is truncated: element '{element}' declares {count} entries but only {remaining} bytes remain"
    )]
    ElementTooLong {
        element: String,
        count: usize,
        remaining: usize,
    },
    /// An ASCII file ending after `read` of an element's `count` entries.
    #[error("file is truncated: it ends after {read} of {count} '{element}' entries")]
    EndsAfter {
        element: String,
        read: usize,
        count: usize,
    },
    #[error("line {line}: not valid text")]
    NotText { line: usize },
    /// `ply-rs` refused an ASCII entry.
    #[error("line {line} ('{element}' entry {entry}): {}", one_line(&.source.to_string()))]
    AsciiEntry {
        line: usize,
        element: String,
        entry: usize,
        source: io::Error,
    },
    /// A binary file ending inside an entry.
    #[error("file is truncated: it ends inside '{element}' entry {entry} of {count}")]
    EndsInside {
        element: String,
        entry: usize,
        count: usize,
    },
    /// `ply-rs` refused a binary entry.
    #[error("'{element}' entry {entry}: {}", one_line(&.source.to_string()))]
    BinaryEntry {
        element: String,
        entry: usize,
        source: io::Error,
    },
}

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

/// What was too large for the compressed data of a `.serialized` mesh.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum SerializedPayload {
    Mesh { vertices: u64, triangles: u64 },
    Attribute { name: String },
}

impl std::fmt::Display for SerializedPayload {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        match self {
            SerializedPayload::Mesh {
                vertices,
                triangles,
            } => write!(f, "{vertices} vertices and {triangles} triangles"),
            SerializedPayload::Attribute { name } => write!(f, "attribute '{name}'"),
        }
    }
}

/// What makes a Mitsuba `.serialized` file's contents unusable (read by
/// `super::serialized`; [`MeshError::Serialized`] adds the path). Limits the file
/// broke are given with the value. Vertex and triangle numbers count from 0.
#[derive(Debug, thiserror::Error)]
pub enum SerializedError {
    #[error("truncated header ({len} bytes)")]
    TruncatedHeader { len: u64 },
    #[error("not a serialized mesh (it starts with 0x{found:04X}, not 0x{expected:04X})")]
    Magic { found: u16, expected: u16 },
    #[error("unsupported version {version} (versions 3, 4 and 5 are read)")]
    Version { version: u16 },
    /// Mesh `index` starts too close to the end for its header.
    #[error("mesh {index} starts at byte {offset}, too close to the end of the file")]
    MeshAtEnd { index: u64, offset: u64 },
    #[error(
        "mesh {index} does not start with a header at byte {offset} (a bad offset dictionary)"
    )]
    MeshHeader { index: u64, offset: u64 },
    #[error("the mesh's compressed stream holds more data than its counts describe")]
    TrailingData,
    #[error(
        "shape_index {index} needs the offset dictionary at the end of the file, which is missing or damaged"
    )]
    NoDictionary { index: u64 },
    #[error(
        "shape_index {index} is out of range: the file holds {count} mesh{}",
        if *.count == 1 { "" } else { "es" }
    )]
    IndexRange { index: u64, count: u64 },
    #[error(
        "the dictionary puts mesh {index} at byte {offset}, beyond the end of the file ({len} bytes)"
    )]
    OffsetBeyondEnd { index: u64, offset: u64, len: u64 },
    #[error("the compressed data end early (a truncated file, or counts larger than the data)")]
    Truncated,
    #[error("corrupt compressed data ({0})")]
    Corrupt(#[source] io::Error),
    /// Counts needing more bytes than the `compressed` bytes left can expand to.
    #[error(
        "{payload} need {bytes} bytes, more than the {compressed} compressed bytes left in the file can hold"
    )]
    TooLarge {
        payload: SerializedPayload,
        bytes: u128,
        compressed: u64,
    },
    /// A vertex `position` or `normal` (`what`) that is not finite.
    #[error("vertex {vertex}: {what} {value:?} is not finite")]
    VertexNotFinite {
        vertex: usize,
        what: &'static str,
        value: [f32; 3],
    },
    #[error("vertex {vertex}: texture coordinates {uv:?} are not finite")]
    UvNotFinite { vertex: usize, uv: [f32; 2] },
    /// A count of `vertices` or `triangles` (`what`) above `limit`.
    #[error("the mesh claims {count} {what}, more than {limit}")]
    Count {
        count: u64,
        what: &'static str,
        limit: u64,
    },
    #[error(
        "triangle {triangle} refers to vertex {index}, but there are only {vertices} vertices"
    )]
    TriangleIndex {
        triangle: usize,
        index: u32,
        vertices: usize,
    },
    #[error("the mesh name is longer than {limit} bytes")]
    NameTooLong { limit: u64 },
    #[error("version 5 meshes must be single precision (flag 0x1000 is not set)")]
    NotSinglePrecision,
    #[error(
        "the flags store tangents without normals and texture coordinates (Mitsuba requires both)"
    )]
    TangentsAlone,
    #[error(
        "{points} surface points and {groups} normal groups for {vertices} vertices (at most one each per vertex)"
    )]
    PointMaps {
        points: u64,
        groups: u64,
        vertices: u64,
    },
    #[error("vertex {vertex} maps to surface point {point} of {points}")]
    PointIndex {
        vertex: usize,
        point: u32,
        points: u64,
    },
    #[error("vertex {vertex} maps to normal group {group} of {groups}")]
    GroupIndex {
        vertex: usize,
        group: u32,
        groups: u64,
    },
    #[error("{count} custom attributes (at most {limit})")]
    Attributes { count: u32, limit: u32 },
    #[error("attribute '{name}' has {channels} channels (1 to 4 are allowed)")]
    AttributeChannels { name: String, channels: u32 },
    /// A length-prefixed string (`what`: the mesh or an attribute name) above `limit`.
    #[error("the {what} is {bytes} bytes long (at most {limit})")]
    StringTooLong {
        what: &'static str,
        bytes: u64,
        limit: u64,
    },
}

// ---------------------------------------------------------------------------
// PLY
// ---------------------------------------------------------------------------

/// Loads a PLY mesh (ASCII or binary, either byte order).
pub fn load_ply(path: &Path) -> Result<MeshData, MeshError> {
    load_ply_with_attributes(path).map(|(m, _)| m)
}

/// [`load_ply`], plus the mesh attributes Mitsuba makes of the file's other vertex
/// and face properties (`ply_attributes`), `None` when there are none.
pub fn load_ply_with_attributes(
    path: &Path,
) -> Result<(MeshData, Option<MeshAttributes>), MeshError> {
    let bytes = read_file(path)?;
    parse_ply(&bytes).map_err(|problem| match problem {
        Problem::NoFaces => MeshError::NoFaces {
            path: path.to_path_buf(),
        },
        Problem::Invalid(problem) => MeshError::Ply {
            path: path.to_path_buf(),
            problem,
        },
    })
}

/// What went wrong while decoding file contents (a [`PlyError`] or an [`ObjError`]);
/// the caller adds the path.
enum Problem<E> {
    NoFaces,
    Invalid(E),
}

impl<E> From<E> for Problem<E> {
    fn from(e: E) -> Self {
        Problem::Invalid(e)
    }
}

/// Names under which the face element stores its vertex list, in order of
/// preference.
const FACE_LIST_NAMES: [&str; 2] = ["vertex_indices", "vertex_index"];

fn parse_ply(bytes: &[u8]) -> Result<(MeshData, Option<MeshAttributes>), Problem<PlyError>> {
    if !bytes.starts_with(b"ply") {
        return Err(PlyError::NotPly.into());
    }
    check_header_numbers(bytes)?;

    let mut data: &[u8] = bytes;
    let header = Parser::<Skip>::new()
        .read_header(&mut data)
        .map_err(PlyError::Header)?;
    // Line number of the last header line, for ASCII error messages.
    let mut line_no = bytes[..bytes.len() - data.len()]
        .iter()
        .filter(|&&b| b == b'\n')
        .count();

    // Check the header describes a mesh before reading any payload.
    let vertex_def = header
        .elements
        .get("vertex")
        .ok_or(PlyError::NoVertexElement)?;
    for name in ["x", "y", "z"] {
        match vertex_def.properties.get(name).map(|p| &p.data_type) {
            Some(PropertyType::Scalar(_)) => {}
            Some(PropertyType::List(..)) => {
                return Err(PlyError::VertexPropertyList { name }.into())
            }
            None => return Err(PlyError::MissingVertexProperty { name }.into()),
        }
    }
    let has_normals = ["nx", "ny", "nz"].iter().all(|name| {
        matches!(
            vertex_def.properties.get(*name).map(|p| &p.data_type),
            Some(PropertyType::Scalar(_))
        )
    });
    // Texture coordinates, under the first of Mitsuba's names the file has both of.
    let uv_rank = UV_NAMES.iter().position(|pair| {
        pair.iter().all(|name| {
            matches!(
                vertex_def.properties.get(*name).map(|p| &p.data_type),
                Some(PropertyType::Scalar(_))
            )
        })
    });
    let face_def = match header.elements.get("face") {
        Some(def) if def.count > 0 => def,
        _ => return Err(Problem::NoFaces),
    };
    let list_name = FACE_LIST_NAMES
        .into_iter()
        .find(|name| face_def.properties.contains_key(*name))
        .ok_or(PlyError::NoFaceList)?;
    match &face_def.properties[list_name].data_type {
        PropertyType::List(_, item) if is_integer(item) => {}
        other => {
            return Err(PlyError::FaceListType {
                name: list_name,
                found: other.clone(),
            }
            .into())
        }
    }

    // Read the elements in file order, stopping once we have what we need.
    let mut vertices: Option<Vec<PlyVertex>> = None;
    let mut faces: Option<Vec<PlyFace>> = None;
    for def in header.elements.values() {
        if vertices.is_some() && faces.is_some() {
            break;
        }
        match def.name.as_str() {
            "vertex" => {
                vertices = Some(read_entries(&mut data, header.encoding, def, &mut line_no)?)
            }
            "face" => faces = Some(read_entries(&mut data, header.encoding, def, &mut line_no)?),
            _ => {
                read_entries::<Skip>(&mut data, header.encoding, def, &mut line_no)?;
            }
        }
    }
    let (vertices, faces) = match (vertices, faces) {
        (Some(v), Some(f)) => (v, f),
        _ => return Err(PlyError::ElementsNotRead.into()),
    };

    let positions = vertices
        .iter()
        .enumerate()
        .map(|(i, v)| {
            finite_vec3(v.position).ok_or(PlyError::VertexNotFinite {
                vertex: i,
                what: "position",
                value: v.position,
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    let normals = if has_normals {
        let normals = vertices
            .iter()
            .enumerate()
            .map(|(i, v)| {
                finite_vec3(v.normal).ok_or(PlyError::VertexNotFinite {
                    vertex: i,
                    what: "normal",
                    value: v.normal,
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        Some(normals)
    } else {
        None
    };

    let uvs = match uv_rank {
        Some(rank) => Some(
            vertices
                .iter()
                .enumerate()
                .map(|(i, v)| {
                    let uv = v.uv[rank];
                    let f = Vec2::new(uv[0] as f32, uv[1] as f32);
                    f.is_finite()
                        .then_some(f)
                        .ok_or(PlyError::UvNotFinite { vertex: i, uv })
                })
                .collect::<Result<Vec<_>, _>>()?,
        ),
        None => None,
    };

    let vertex_count = positions.len();
    let mut triangles = Vec::with_capacity(faces.len());
    let mut polygon = Vec::new();
    // Mesh attributes: Mitsuba's names for the properties it does not use itself.
    let scalar_names = |def: &ElementDef| -> Vec<String> {
        def.properties
            .values()
            .filter(|p| matches!(p.data_type, PropertyType::Scalar(_)))
            .map(|p| p.name.clone())
            .collect()
    };
    let vertex_originals = scalar_names(vertex_def);
    let mut vertex_names = vertex_originals.clone();
    if let Some(rank) = uv_rank {
        for (k, to) in ["u", "v"].into_iter().enumerate() {
            if let Some(n) = vertex_names.iter_mut().find(|n| **n == UV_NAMES[rank][k]) {
                *n = to.into();
            }
        }
    }
    let vertex_groups = ply_attributes::group(
        "vertex_",
        &vertex_names,
        &["x", "y", "z", "nx", "ny", "nz", "u", "v"],
    );
    let face_names = scalar_names(face_def);
    let face_groups = ply_attributes::group("face_", &face_names, &[]);
    let mut attributes: Vec<MeshAttribute> = Vec::new();
    for d in &vertex_groups {
        let originals: Vec<&String> = d.fields.iter().map(|&f| &vertex_originals[f]).collect();
        let mut data = Vec::with_capacity(vertices.len() * d.fields.len());
        for v in &vertices {
            for n in &originals {
                data.push(extra_value(&v.extra, n));
            }
        }
        attributes.push(MeshAttribute {
            name: d.name.clone(),
            per_vertex: true,
            dim: d.fields.len(),
            data,
        });
    }
    let mut face_data: Vec<Vec<f32>> = vec![Vec::new(); face_groups.len()];
    for (f, face) in faces.iter().enumerate() {
        if face.indices.len() < 3 {
            return Err(PlyError::FaceTooSmall {
                face: f,
                vertices: face.indices.len(),
            }
            .into());
        }
        polygon.clear();
        for &index in &face.indices {
            match u32::try_from(index) {
                Ok(i) if (i as usize) < vertex_count => polygon.push(i),
                _ => {
                    return Err(PlyError::FaceIndex {
                        face: f,
                        index,
                        vertices: vertex_count,
                    }
                    .into())
                }
            }
        }
        let before = triangles.len();
        push_fan(&polygon, &mut triangles);
        for (d, data) in face_groups.iter().zip(face_data.iter_mut()) {
            for _ in before..triangles.len() {
                for &f in &d.fields {
                    data.push(extra_value(&face.extra, &face_names[f]));
                }
            }
        }
    }
    for (d, data) in face_groups.iter().zip(face_data) {
        attributes.push(MeshAttribute {
            name: d.name.clone(),
            per_vertex: false,
            dim: d.fields.len(),
            data,
        });
    }
    // Mitsuba's add_attribute refuses a name twice (e.g. r g b and color_0..2).
    for (i, a) in attributes.iter().enumerate() {
        if attributes[..i].iter().any(|b| b.name == a.name) {
            return Err(PlyError::DuplicateAttribute {
                name: a.name.clone(),
            }
            .into());
        }
    }
    let attributes = (!attributes.is_empty()).then_some(MeshAttributes { list: attributes });

    Ok((
        MeshData {
            positions,
            normals,
            triangles,
            uvs,
        },
        attributes,
    ))
}

/// The value of property `name` among an entry's extra properties (0 when absent:
/// the property exists in the header, so every entry sets it).
fn extra_value(extra: &[(String, Property)], name: &str) -> f32 {
    extra
        .iter()
        .find(|(n, _)| n == name)
        .map_or(0.0, |(_, p)| ply_attributes::value(p))
}

/// `ply-rs` 0.1 panics (an `unwrap` in its header grammar) when an element
/// count or the format version does not fit in a `u64`. Refuse such headers
/// before handing them over.
fn check_header_numbers(bytes: &[u8]) -> Result<(), PlyError> {
    for (i, line) in bytes.split(|&b| b == b'\n').enumerate() {
        let line = String::from_utf8_lossy(line);
        match line.split_whitespace().next() {
            Some("end_header") => break,
            Some("element") | Some("format") => {
                let digit_runs = line.split(|c: char| !c.is_ascii_digit());
                if let Some(run) = digit_runs
                    .filter(|r| !r.is_empty())
                    .find(|r| r.parse::<u64>().is_err())
                {
                    return Err(PlyError::HeaderNumber {
                        line: i + 1,
                        number: run.to_string(),
                    });
                }
            }
            _ => {}
        }
    }
    Ok(())
}

/// Reads all entries of one element from `data` (positioned at its start).
fn read_entries<E: PropertyAccess>(
    data: &mut &[u8],
    encoding: Encoding,
    def: &ElementDef,
    line_no: &mut usize,
) -> Result<Vec<E>, PlyError> {
    // Every entry takes at least this many bytes, so a count that cannot fit
    // in the rest of the file means truncation (or a corrupt header). Checking
    // up front also keeps a bogus huge count from looping or allocating.
    let min_bytes = match encoding {
        // Each value takes a digit and a separator (space or line end).
        // (the file's last line may lack its line end: one byte of slack below).
        Encoding::Ascii => (2 * def.properties.len()).max(1),
        _ => def
            .properties
            .values()
            .map(|p| match &p.data_type {
                PropertyType::Scalar(t) | PropertyType::List(t, _) => scalar_size(t),
            })
            .sum::<usize>()
            .max(1),
    };
    let slack = usize::from(encoding == Encoding::Ascii);
    if def
        .count
        .checked_mul(min_bytes)
        .is_none_or(|n| n > data.len() + slack)
    {
        return Err(PlyError::ElementTooLong {
            element: def.name.clone(),
            count: def.count,
            remaining: data.len(),
        });
    }

    let parser = Parser::<E>::new();
    let mut entries = Vec::with_capacity(def.count);
    for i in 0..def.count {
        let entry = match encoding {
            Encoding::Ascii => {
                let line = next_line(data).ok_or_else(|| PlyError::EndsAfter {
                    element: def.name.clone(),
                    read: i,
                    count: def.count,
                })?;
                *line_no += 1;
                let text =
                    std::str::from_utf8(line).map_err(|_| PlyError::NotText { line: *line_no })?;
                parser
                    .read_ascii_element(
                        &normalize_numbers(text.trim_end_matches(['\r', '\n'])),
                        def,
                    )
                    .map_err(|source| PlyError::AsciiEntry {
                        line: *line_no,
                        element: def.name.clone(),
                        entry: i,
                        source,
                    })?
            }
            Encoding::BinaryLittleEndian => parser
                .read_little_endian_element(data, def)
                .map_err(|e| binary_error(e, def, i))?,
            Encoding::BinaryBigEndian => parser
                .read_big_endian_element(data, def)
                .map_err(|e| binary_error(e, def, i))?,
        };
        entries.push(entry);
    }
    Ok(entries)
}

fn binary_error(e: io::Error, def: &ElementDef, i: usize) -> PlyError {
    // ply-rs wraps a failed read inside a list into an `InvalidInput` error
    // whose text carries the original error's Debug form.
    if e.kind() == io::ErrorKind::UnexpectedEof || e.to_string().contains("UnexpectedEof") {
        PlyError::EndsInside {
            element: def.name.clone(),
            entry: i,
            count: def.count,
        }
    } else {
        PlyError::BinaryEntry {
            element: def.name.clone(),
            entry: i,
            source: e,
        }
    }
}

/// The ASCII grammar of `ply-rs` only accepts numbers shaped like `-1.5e-3`.
/// Rewrite the other common spellings, `1.5E-3`, `.5` and `5.`, into that
/// shape; anything else is passed through (and rejected by `ply-rs`).
fn normalize_numbers(line: &str) -> Cow<'_, str> {
    let unusual = |t: &str| {
        let digits = t.trim_start_matches(['-', '+']);
        t.contains('E')
            || digits.starts_with('.')
            || t.ends_with('.')
            || t.contains(".e")
            || t.contains(".E")
    };
    if !line.split_whitespace().any(unusual) {
        return Cow::Borrowed(line);
    }
    let tokens: Vec<String> = line
        .split_whitespace()
        .map(|token| {
            let token = token.replace('E', "e");
            let sign_len = usize::from(token.starts_with(['-', '+']));
            let (sign, number) = token.split_at(sign_len);
            let (mantissa, exponent) = number.split_at(number.find('e').unwrap_or(number.len()));
            let mut out = sign.to_string();
            if mantissa.starts_with('.') {
                out.push('0');
            }
            out.push_str(mantissa);
            if mantissa.ends_with('.') {
                out.push('0');
            }
            out.push_str(exponent);
            out
        })
        .collect();
    Cow::Owned(tokens.join(" "))
}

/// Splits the next line (including its `\n`, if any) off the front of `data`.
fn next_line<'a>(data: &mut &'a [u8]) -> Option<&'a [u8]> {
    if data.is_empty() {
        return None;
    }
    let end = data
        .iter()
        .position(|&b| b == b'\n')
        .map_or(data.len(), |i| i + 1);
    let (line, rest) = data.split_at(end);
    *data = rest;
    Some(line)
}

fn scalar_size(t: &ScalarType) -> usize {
    match t {
        ScalarType::Char | ScalarType::UChar => 1,
        ScalarType::Short | ScalarType::UShort => 2,
        ScalarType::Int | ScalarType::UInt | ScalarType::Float => 4,
        ScalarType::Double => 8,
    }
}

fn is_integer(t: &ScalarType) -> bool {
    !matches!(t, ScalarType::Float | ScalarType::Double)
}

/// Value of a numeric scalar property, `None` for lists.
fn scalar_value(p: &Property) -> Option<f64> {
    Some(match *p {
        Property::Char(v) => v.into(),
        Property::UChar(v) => v.into(),
        Property::Short(v) => v.into(),
        Property::UShort(v) => v.into(),
        Property::Int(v) => v.into(),
        Property::UInt(v) => v.into(),
        Property::Float(v) => v.into(),
        Property::Double(v) => v,
        _ => return None,
    })
}

/// Entries of an integer list property, `None` for anything else.
fn integer_list(p: Property) -> Option<Vec<i64>> {
    fn widen<T: Into<i64>>(v: Vec<T>) -> Vec<i64> {
        v.into_iter().map(Into::into).collect()
    }
    Some(match p {
        Property::ListChar(v) => widen(v),
        Property::ListUChar(v) => widen(v),
        Property::ListShort(v) => widen(v),
        Property::ListUShort(v) => widen(v),
        Property::ListInt(v) => widen(v),
        Property::ListUInt(v) => widen(v),
        _ => return None,
    })
}

/// One PLY `vertex` entry; only the properties we use are kept.
/// The PLY vertex property pairs Mitsuba reads as texture coordinates, in its order
/// of preference (`src/shapes/ply.cpp`).
const UV_NAMES: [[&str; 2]; 3] = [["u", "v"], ["texture_u", "texture_v"], ["s", "t"]];

#[derive(Default)]
struct PlyVertex {
    position: [f64; 3],
    normal: [f64; 3],
    /// One slot per pair of [`UV_NAMES`]: the header decides which is used.
    uv: [[f64; 2]; 3],
    /// Every other scalar property, for mesh attributes (`ply_attributes`).
    extra: Vec<(String, Property)>,
}

impl PropertyAccess for PlyVertex {
    fn new() -> Self {
        Self::default()
    }

    fn set_property(&mut self, name: String, property: Property) {
        let slot = match name.as_str() {
            "x" => &mut self.position[0],
            "y" => &mut self.position[1],
            "z" => &mut self.position[2],
            "nx" => &mut self.normal[0],
            "ny" => &mut self.normal[1],
            "nz" => &mut self.normal[2],
            "u" => &mut self.uv[0][0],
            "v" => &mut self.uv[0][1],
            "texture_u" => &mut self.uv[1][0],
            "texture_v" => &mut self.uv[1][1],
            "s" => &mut self.uv[2][0],
            "t" => &mut self.uv[2][1],
            _ => {
                if ply_attributes::scalar_type(&property).is_some() {
                    self.extra.push((name, property));
                }
                return;
            }
        };
        if let Some(value) = scalar_value(&property) {
            *slot = value;
        }
    }
}

/// One PLY `face` entry: its vertex list. If a file has both list names, the
/// preferred one (`vertex_indices`) wins whatever the property order.
#[derive(Default)]
struct PlyFace {
    indices: Vec<i64>,
    from_preferred_name: bool,
    /// Every scalar property, for mesh attributes (`ply_attributes`).
    extra: Vec<(String, Property)>,
}

impl PropertyAccess for PlyFace {
    fn new() -> Self {
        Self::default()
    }

    fn set_property(&mut self, name: String, property: Property) {
        if ply_attributes::scalar_type(&property).is_some() {
            self.extra.push((name, property));
            return;
        }
        let preferred = name == FACE_LIST_NAMES[0];
        if !(preferred || (name == FACE_LIST_NAMES[1] && !self.from_preferred_name)) {
            return;
        }
        if let Some(indices) = integer_list(property) {
            self.indices = indices;
            self.from_preferred_name = preferred;
        }
    }
}

/// An entry of an element we do not use: parsed (to advance through the file)
/// and dropped.
struct Skip;

impl PropertyAccess for Skip {
    fn new() -> Self {
        Skip
    }
}

// ---------------------------------------------------------------------------
// OBJ
// ---------------------------------------------------------------------------

/// Loads a Wavefront OBJ mesh, merging all objects and groups into one mesh.
pub fn load_obj(path: &Path) -> Result<MeshData, MeshError> {
    let bytes = read_file(path)?;
    parse_obj(&bytes).map_err(|problem| match problem {
        Problem::NoFaces => MeshError::NoFaces {
            path: path.to_path_buf(),
        },
        Problem::Invalid(problem) => MeshError::Obj {
            path: path.to_path_buf(),
            problem,
        },
    })
}

fn parse_obj(bytes: &[u8]) -> Result<MeshData, Problem<ObjError>> {
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
        return Err(Problem::NoFaces);
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

// ---------------------------------------------------------------------------
// Shared helpers
// ---------------------------------------------------------------------------

/// Reads a regular file of at most [`crate::io::MAX_MESH_BYTES`]; devices, FIFOs,
/// directories (and links to them) are refused before anything is read.
fn read_file(path: &Path) -> Result<Vec<u8>, MeshError> {
    crate::io::read_regular(path, crate::io::MAX_MESH_BYTES).map_err(|e| MeshError::Io {
        path: path.to_path_buf(),
        source: io::Error::other(e),
    })
}

/// Converts to `f32`; `None` if any component is (or overflows to) NaN or infinity.
fn finite_vec3(v: [f64; 3]) -> Option<Vec3> {
    let v = Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32);
    v.is_finite().then_some(v)
}

/// Fan-triangulates a polygon given by vertex indices (at least 3).
fn push_fan(polygon: &[u32], out: &mut Vec<[u32; 3]>) {
    for pair in polygon[1..].windows(2) {
        out.push([polygon[0], pair[0], pair[1]]);
    }
}

/// Collapses line breaks and tabs (which `ply-rs` puts in its messages) so an
/// error message stays on one line.
fn one_line(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
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

#[cfg(test)]
mod tests {
    use super::*;
    use std::fs;

    /// The test mesh: a unit quad (one polygon) plus a triangle sharing an
    /// edge with it, all counter-clockwise seen from +z. Coordinates are
    /// exactly representable so every format must give identical numbers.
    const POSITIONS: [[f32; 3]; 5] = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
        [2.0, 0.5, -0.25],
    ];
    /// Distinct per-vertex normals, so a mix-up of vertices would show.
    const NORMALS: [[f32; 3]; 5] = [
        [0.0, 0.0, 1.0],
        [0.0, 1.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 0.0, -1.0],
        [0.0, -0.5, 0.75],
    ];
    const QUAD: [u32; 4] = [0, 1, 2, 3];
    const TRI: [u32; 3] = [1, 4, 2];

    fn expected(with_normals: bool) -> MeshData {
        MeshData {
            positions: POSITIONS.iter().map(|p| Vec3::from_array(*p)).collect(),
            normals: with_normals.then(|| NORMALS.iter().map(|n| Vec3::from_array(*n)).collect()),
            triangles: vec![[0, 1, 2], [0, 2, 3], [1, 4, 2]],
            uvs: None,
        }
    }

    fn ascii_ply(with_normals: bool) -> String {
        let mut s = String::from("ply\nformat ascii 1.0\ncomment written by hand\n");
        s += "element vertex 5\nproperty float x\nproperty float y\nproperty float z\n";
        if with_normals {
            s += "property float nx\nproperty float ny\nproperty float nz\n";
        }
        s += "element face 2\nproperty list uchar int vertex_indices\n";
        // An element we do not use, after the ones we do.
        s += "element material 1\nproperty uchar red\nend_header\n";
        for (p, n) in POSITIONS.iter().zip(NORMALS) {
            s += &format!("{} {} {}", p[0], p[1], p[2]);
            if with_normals {
                s += &format!(" {} {} {}", n[0], n[1], n[2]);
            }
            s += "\n";
        }
        s += "4 0 1 2 3\n3 1 4 2\n255\n";
        s
    }

    /// Binary PLY with float coordinates and `list uchar int` faces, plus an
    /// unused per-vertex property and an unused element *before* the vertices.
    fn binary_ply(with_normals: bool, big_endian: bool) -> Vec<u8> {
        let f32b = |v: f32| {
            if big_endian {
                v.to_be_bytes()
            } else {
                v.to_le_bytes()
            }
        };
        let i32b = |v: i32| {
            if big_endian {
                v.to_be_bytes()
            } else {
                v.to_le_bytes()
            }
        };
        let format = if big_endian {
            "binary_big_endian"
        } else {
            "binary_little_endian"
        };
        let mut header = format!("ply\nformat {format} 1.0\nelement camera 1\nproperty int id\n");
        header += "element vertex 5\nproperty float x\nproperty float y\nproperty float z\n";
        header += "property uchar quality\n";
        if with_normals {
            header += "property float nx\nproperty float ny\nproperty float nz\n";
        }
        header += "element face 2\nproperty list uchar int vertex_indices\nend_header\n";
        let mut bytes = header.into_bytes();
        bytes.extend(i32b(7));
        for (p, n) in POSITIONS.iter().zip(NORMALS) {
            p.iter().for_each(|&c| bytes.extend(f32b(c)));
            bytes.push(200);
            if with_normals {
                n.iter().for_each(|&c| bytes.extend(f32b(c)));
            }
        }
        bytes.push(4);
        QUAD.iter().for_each(|&i| bytes.extend(i32b(i as i32)));
        bytes.push(3);
        TRI.iter().for_each(|&i| bytes.extend(i32b(i as i32)));
        bytes
    }

    /// Binary little-endian PLY with double coordinates and `list int uint`
    /// faces named `vertex_index`.
    fn binary_ply_double() -> Vec<u8> {
        let mut bytes = b"ply\nformat binary_little_endian 1.0\nelement vertex 5\n\
            property double x\nproperty double y\nproperty double z\n\
            element face 2\nproperty list int uint vertex_index\nend_header\n"
            .to_vec();
        for p in POSITIONS {
            p.iter()
                .for_each(|&c| bytes.extend(f64::from(c).to_le_bytes()));
        }
        bytes.extend(4i32.to_le_bytes());
        QUAD.iter().for_each(|&i| bytes.extend(i.to_le_bytes()));
        bytes.extend(3i32.to_le_bytes());
        TRI.iter().for_each(|&i| bytes.extend(i.to_le_bytes()));
        bytes
    }

    fn obj(with_normals: bool) -> String {
        let mut s = String::from("# test mesh\no quad_and_triangle\n");
        for p in POSITIONS {
            s += &format!("v {} {} {}\n", p[0], p[1], p[2]);
        }
        if with_normals {
            for n in NORMALS {
                s += &format!("vn {} {} {}\n", n[0], n[1], n[2]);
            }
        }
        let corner = |i: u32| {
            if with_normals {
                format!(" {}//{}", i + 1, i + 1)
            } else {
                format!(" {}", i + 1)
            }
        };
        s += "f";
        QUAD.iter().for_each(|&i| s += &corner(i));
        s += "\nf";
        TRI.iter().for_each(|&i| s += &corner(i));
        s += "\n";
        s
    }

    fn write(dir: &tempfile::TempDir, name: &str, contents: impl AsRef<[u8]>) -> PathBuf {
        let path = dir.path().join(name);
        fs::write(&path, contents).unwrap();
        path
    }

    /// Unwraps the error and checks its message names the file and is one line.
    fn error_message(result: Result<MeshData, MeshError>, path: &Path) -> String {
        let message = result.expect_err("loading should fail").to_string();
        assert!(
            message.contains(&path.display().to_string()),
            "message does not name the file: {message}"
        );
        assert!(
            !message.contains('\n'),
            "message is not one line: {message}"
        );
        message
    }

    #[test]
    fn all_formats_agree_without_normals() {
        let dir = tempfile::tempdir().unwrap();
        let want = expected(false);
        let ascii = load_ply(&write(&dir, "a.ply", ascii_ply(false))).unwrap();
        let crlf = load_ply(&write(
            &dir,
            "crlf.ply",
            ascii_ply(false).replace('\n', "\r\n"),
        ))
        .unwrap();
        let le = load_ply(&write(&dir, "le.ply", binary_ply(false, false))).unwrap();
        let be = load_ply(&write(&dir, "be.ply", binary_ply(false, true))).unwrap();
        let double = load_ply(&write(&dir, "d.ply", binary_ply_double())).unwrap();
        let obj = load_obj(&write(&dir, "m.obj", obj(false))).unwrap();
        assert_eq!(ascii, want);
        assert_eq!(crlf, want);
        assert_eq!(le, want);
        assert_eq!(be, want);
        assert_eq!(double, want);
        assert_eq!(obj, want);
    }

    #[test]
    fn all_formats_agree_with_normals() {
        let dir = tempfile::tempdir().unwrap();
        let want = expected(true);
        assert_eq!(
            load_ply(&write(&dir, "a.ply", ascii_ply(true))).unwrap(),
            want
        );
        assert_eq!(
            load_ply(&write(&dir, "le.ply", binary_ply(true, false))).unwrap(),
            want
        );
        assert_eq!(
            load_ply(&write(&dir, "be.ply", binary_ply(true, true))).unwrap(),
            want
        );
        assert_eq!(load_obj(&write(&dir, "m.obj", obj(true))).unwrap(), want);
    }

    #[test]
    fn missing_file_is_an_error_naming_it() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("does_not_exist.ply");
        let message = error_message(load_ply(&path), &path);
        assert!(message.contains("cannot read"), "{message}");
        let path = dir.path().join("does_not_exist.obj");
        error_message(load_obj(&path), &path);
        // A directory cannot be read as a file either.
        error_message(load_ply(dir.path()), dir.path());
        error_message(load_obj(dir.path()), dir.path());
    }

    #[test]
    fn truncated_binary_ply_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        for with_normals in [false, true] {
            let full = binary_ply(with_normals, false);
            // Every proper prefix, from empty up to one byte short, must fail.
            for len in 0..full.len() {
                let path = write(&dir, "cut.ply", &full[..len]);
                error_message(load_ply(&path), &path);
            }
        }
        let full = binary_ply(false, false);
        let path = write(&dir, "cut.ply", &full[..full.len() - 1]);
        let message = error_message(load_ply(&path), &path);
        assert!(message.contains("truncated"), "{message}");
    }

    #[test]
    fn non_regular_mesh_files_are_refused_before_reading() {
        let dir = tempfile::tempdir().unwrap();
        let zero = Path::new("/dev/zero");
        let message = error_message(load_ply(zero), zero);
        assert!(message.contains("not a regular file"), "{message}");
        let message = error_message(load_obj(zero), zero);
        assert!(message.contains("not a regular file"), "{message}");
        #[cfg(unix)]
        {
            let link = dir.path().join("zero.obj");
            std::os::unix::fs::symlink("/dev/zero", &link).unwrap();
            let message = error_message(load_obj(&link), &link);
            assert!(message.contains("not a regular file"), "{message}");
        }
    }

    #[test]
    fn ascii_counts_are_checked_against_the_bytes_they_need() {
        // 100 vertices of three values need at least 600 bytes; 25 lines are there.
        let dir = tempfile::tempdir().unwrap();
        let text = "ply\nformat ascii 1.0\nelement vertex 100\nproperty float x\n\
            property float y\nproperty float z\nelement face 1\n\
            property list uchar int vertex_indices\nend_header\n"
            .to_string()
            + &"0 0 0\n".repeat(25);
        let path = write(&dir, "short.ply", text);
        let message = error_message(load_ply(&path), &path);
        assert!(
            message.contains("declares 100 entries but only 150 bytes remain"),
            "{message}"
        );
        // The shortest complete file passes the check (last line without its end).
        let text = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n\
            property float y\nproperty float z\nelement face 1\n\
            property list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2";
        let mesh = load_ply(&write(&dir, "min.ply", text)).unwrap();
        assert_eq!(mesh.triangles, vec![[0, 1, 2]]);
    }

    #[test]
    fn truncated_ascii_ply_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let full = ascii_ply(false);
        let cut = &full[..full.find("3 1 4 2").unwrap()];
        let path = write(&dir, "cut.ply", cut);
        let message = error_message(load_ply(&path), &path);
        assert!(message.contains("truncated"), "{message}");
    }

    #[test]
    fn ascii_ply_accepts_other_number_spellings() {
        let dir = tempfile::tempdir().unwrap();
        let text = ascii_ply(false)
            .replace("\n1 0 0\n", "\n1. 0 0\n")
            .replace("2 0.5 -0.25", "2E0 .5 -2.5E-1");
        assert!(text.contains("1. 0 0") && text.contains("-2.5E-1"));
        let mesh = load_ply(&write(&dir, "spell.ply", text)).unwrap();
        assert_eq!(mesh, expected(false));
        assert_eq!(normalize_numbers("1 2 3"), "1 2 3");
        assert_eq!(normalize_numbers("-.5 +1.E3 2e5"), "-0.5 +1.0e3 2e5");
    }

    #[test]
    fn out_of_range_face_index_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = write(
            &dir,
            "bad.ply",
            ascii_ply(false).replace("3 1 4 2", "3 1 5 2"),
        );
        let message = error_message(load_ply(&path), &path);
        assert!(
            message.contains("face 1") && message.contains("vertex 5"),
            "{message}"
        );

        let path = write(
            &dir,
            "neg.ply",
            ascii_ply(false).replace("3 1 4 2", "3 1 -1 2"),
        );
        let message = error_message(load_ply(&path), &path);
        assert!(message.contains("face 1"), "{message}");

        let path = write(&dir, "bad.obj", obj(false).replace("f 2 5 3", "f 2 6 3"));
        let message = error_message(load_obj(&path), &path);
        assert!(
            message.contains("face 1") && message.contains("index 6"),
            "{message}"
        );

        let path = write(&dir, "neg.obj", obj(false).replace("f 2 5 3", "f 2 -6 3"));
        error_message(load_obj(&path), &path);
    }

    #[test]
    fn bad_obj_indices_do_not_panic() {
        let dir = tempfile::tempdir().unwrap();
        let base = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n";
        for face in [
            "f 0 1 2",
            "f 1/0 2/1 3/1",
            "f 1//0 2//1 3//1",
            "f 1/-9 2/1 3/1",
            "f 1/1/1/1 2 3",
            "f /1 2 3",
            "f a b c",
            "f 99999999999999999999 1 2",
        ] {
            let path = write(&dir, "bad.obj", format!("{base}{face}\n"));
            error_message(load_obj(&path), &path);
        }
    }

    #[test]
    fn face_with_too_few_vertices_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = write(
            &dir,
            "two.ply",
            ascii_ply(false).replace("3 1 4 2", "2 1 4"),
        );
        let message = error_message(load_ply(&path), &path);
        assert!(message.contains("face 1"), "{message}");
        let path = write(&dir, "two.obj", obj(false).replace("f 2 5 3", "f 2 5"));
        error_message(load_obj(&path), &path);
    }

    #[test]
    fn ply_without_faces_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let cloud = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n\
            property float y\nproperty float z\nend_header\n0 0 0\n";
        let path = write(&dir, "cloud.ply", cloud);
        let message = error_message(load_ply(&path), &path);
        assert!(matches!(load_ply(&path), Err(MeshError::NoFaces { .. })));
        assert!(message.contains("no faces"), "{message}");

        let empty_faces = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n\
            property float y\nproperty float z\nelement face 0\n\
            property list uchar int vertex_indices\nend_header\n0 0 0\n";
        let path = write(&dir, "empty.ply", empty_faces);
        assert!(matches!(load_ply(&path), Err(MeshError::NoFaces { .. })));

        let path = write(&dir, "empty.obj", "v 0 0 0\nv 1 0 0\nl 1 2\n");
        assert!(matches!(load_obj(&path), Err(MeshError::NoFaces { .. })));
    }

    #[test]
    fn missing_coordinate_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let text = ascii_ply(false).replace("property float z\n", "");
        let path = write(&dir, "noz.ply", text);
        let message = error_message(load_ply(&path), &path);
        assert!(message.contains("'z'"), "{message}");
    }

    #[test]
    fn non_finite_coordinates_are_an_error() {
        let dir = tempfile::tempdir().unwrap();
        // ASCII: 1e39 overflows f32 to infinity.
        let path = write(
            &dir,
            "inf.ply",
            ascii_ply(false).replace("2 0.5 -0.25", "2 1e39 -0.25"),
        );
        let message = error_message(load_ply(&path), &path);
        assert!(message.contains("vertex 4"), "{message}");
        // Binary: a NaN in the first coordinate.
        let mut bytes = binary_ply_double();
        let start = bytes.len() - (5 * 3 * 8 + 2 * 4 + 4 * 4 + 3 * 4);
        bytes[start..start + 8].copy_from_slice(&f64::NAN.to_le_bytes());
        let path = write(&dir, "nan.ply", bytes);
        error_message(load_ply(&path), &path);
        // A double too large for f32.
        let mut bytes = binary_ply_double();
        bytes[start..start + 8].copy_from_slice(&1e300f64.to_le_bytes());
        let path = write(&dir, "huge.ply", bytes);
        error_message(load_ply(&path), &path);
        // OBJ.
        let path = write(
            &dir,
            "nan.obj",
            obj(false).replace("v 2 0.5 -0.25", "v 2 NaN -0.25"),
        );
        error_message(load_obj(&path), &path);
    }

    #[test]
    fn malformed_content_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let cases: Vec<(&str, Vec<u8>)> = vec![
            ("empty", Vec::new()),
            ("garbage", (0..=255u8).cycle().take(4000).collect()),
            ("not_ply", b"solid cube\nfacet normal 0 0 1\n".to_vec()),
            (
                "no_end_header",
                b"ply\nformat ascii 1.0\nelement vertex 3\n".to_vec(),
            ),
            // ply-rs itself would panic on this count.
            (
                "huge_count",
                b"ply\nformat ascii 1.0\nelement vertex 99999999999999999999999\n\
                  property float x\nend_header\n"
                    .to_vec(),
            ),
            // A count that fits but cannot be backed by the file's size.
            (
                "big_count",
                b"ply\nformat binary_little_endian 1.0\nelement vertex 4000000000000\n\
                  property float x\nproperty float y\nproperty float z\nend_header\n"
                    .to_vec(),
            ),
            (
                "bad_number",
                ascii_ply(false).replace("0.5", "0.5x").into_bytes(),
            ),
            (
                "float_indices",
                ascii_ply(false)
                    .replace("uchar int vertex", "uchar float vertex")
                    .into_bytes(),
            ),
        ];
        for (name, bytes) in cases {
            let path = write(&dir, &format!("{name}.ply"), &bytes);
            error_message(load_ply(&path), &path);
            let path = write(&dir, &format!("{name}.obj"), &bytes);
            error_message(load_obj(&path), &path);
        }
    }

    #[test]
    fn obj_objects_are_merged_with_offset_indices() {
        let dir = tempfile::tempdir().unwrap();
        let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0.5 -0.25\n\
            o quad\nf 1 2 3 4\no triangle\ng part\nf 2 5 3\n";
        let mesh = load_obj(&write(&dir, "two.obj", text)).unwrap();
        // tobj gives each object its own vertices, so shared ones are duplicated.
        assert_eq!(mesh.triangles, vec![[0, 1, 2], [0, 2, 3], [4, 5, 6]]);
        let at = |t: usize, k: usize| mesh.positions[mesh.triangles[t][k] as usize];
        assert_eq!(at(2, 0), Vec3::new(1.0, 0.0, 0.0));
        assert_eq!(at(2, 1), Vec3::new(2.0, 0.5, -0.25));
        assert_eq!(at(2, 2), Vec3::new(1.0, 1.0, 0.0));
        assert_eq!(mesh.normals, None);
    }

    #[test]
    fn obj_normals_only_if_every_vertex_has_one() {
        let dir = tempfile::tempdir().unwrap();
        let text = obj(true).replace("f 2//2 5//5 3//3", "f 2//2 5 3//3");
        let mesh = load_obj(&write(&dir, "partial.obj", text)).unwrap();
        assert_eq!(mesh.normals, None);
        assert_eq!(mesh.triangles.len(), 3);
    }

    #[test]
    fn bunny_loads() {
        let path = Path::new("/work/shared/data/meshes/bunny.ply");
        if !path.exists() {
            return;
        }
        let mesh = load_ply(path).unwrap();
        assert_eq!(mesh.positions.len(), 1839);
        assert_eq!(mesh.triangles.len(), 3674);
        assert_eq!(mesh.normals, None);
    }
}
