//! PLY meshes (ASCII, binary little- and big-endian) through `ply-rs`, with the
//! checks that keep its panics out of reach (module docs of `mesh`).

use super::{finite_vec3, read_file, MeshData, MeshError, MeshProblem};
use crate::geometry::mesh_attributes::{MeshAttribute, MeshAttributes};
use crate::scene::ply_attributes;
use glam::{Vec2, Vec3};
use ply_rs::parser::Parser;
use ply_rs::ply::{
    ElementDef, Encoding, Header, Property, PropertyAccess, PropertyType, ScalarType,
};
use std::borrow::Cow;
use std::io;
use std::path::Path;

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
        MeshProblem::NoFaces => MeshError::NoFaces {
            path: path.to_path_buf(),
        },
        MeshProblem::Invalid(problem) => MeshError::Ply {
            path: path.to_path_buf(),
            problem,
        },
    })
}

/// Names under which the face element stores its vertex list, in order of
/// preference.
const FACE_LIST_NAMES: [&str; 2] = ["vertex_indices", "vertex_index"];

fn parse_ply(bytes: &[u8]) -> Result<(MeshData, Option<MeshAttributes>), MeshProblem<PlyError>> {
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
    // The header must describe a mesh before any payload is read.
    let layout = Layout::of(&header)?;
    let (vertices, faces) = read_mesh_elements(&header, &mut data, &mut line_no)?;
    let (positions, normals, uvs) = vertex_arrays(&vertices, &layout)?;
    let names = AttributeNames::of(&layout);
    let (triangles, face_data) = triangulate(&faces, positions.len(), &names)?;
    let attributes = attributes(&vertices, &names, face_data)?;
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

/// What the header says of the mesh: its vertex and face elements, whether vertices
/// carry normals, and under which of Mitsuba's names their texture coordinates are.
struct Layout<'h> {
    vertex_def: &'h ElementDef,
    face_def: &'h ElementDef,
    has_normals: bool,
    /// The index in `UV_NAMES` of the first pair the file has both of.
    uv_rank: Option<usize>,
}

impl<'h> Layout<'h> {
    /// Checks that the header describes a mesh: scalar x, y, z, a non-empty face
    /// element with an integer list of indices.
    fn of(header: &'h Header) -> Result<Layout<'h>, MeshProblem<PlyError>> {
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
            _ => return Err(MeshProblem::NoFaces),
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
        Ok(Layout {
            vertex_def,
            face_def,
            has_normals,
            uv_rank,
        })
    }
}

/// Reads the elements in file order (skipping the others), stopping once the vertices
/// and faces are read.
fn read_mesh_elements(
    header: &Header,
    data: &mut &[u8],
    line_no: &mut usize,
) -> Result<(Vec<PlyVertex>, Vec<PlyFace>), MeshProblem<PlyError>> {
    let mut vertices: Option<Vec<PlyVertex>> = None;
    let mut faces: Option<Vec<PlyFace>> = None;
    for def in header.elements.values() {
        if vertices.is_some() && faces.is_some() {
            break;
        }
        match def.name.as_str() {
            "vertex" => vertices = Some(read_entries(data, header.encoding, def, line_no)?),
            "face" => faces = Some(read_entries(data, header.encoding, def, line_no)?),
            _ => {
                read_entries::<Skip>(data, header.encoding, def, line_no)?;
            }
        }
    }
    match (vertices, faces) {
        (Some(v), Some(f)) => Ok((v, f)),
        _ => Err(PlyError::ElementsNotRead.into()),
    }
}

/// Positions, normals and texture coordinates, each checked finite.
type VertexArrays = (Vec<Vec3>, Option<Vec<Vec3>>, Option<Vec<Vec2>>);

fn vertex_arrays(vertices: &[PlyVertex], layout: &Layout) -> Result<VertexArrays, PlyError> {
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
    let normals = if layout.has_normals {
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

    let uvs = match layout.uv_rank {
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
    Ok((positions, normals, uvs))
}

/// Mesh attributes: Mitsuba's names for the scalar properties it does not use itself,
/// grouped (`vertex_color` from r, g, b, ...).
struct AttributeNames {
    /// The vertex properties' names in the file.
    vertex_originals: Vec<String>,
    vertex_groups: Vec<ply_attributes::Descriptor>,
    face_names: Vec<String>,
    face_groups: Vec<ply_attributes::Descriptor>,
}

impl AttributeNames {
    fn of(layout: &Layout) -> AttributeNames {
        let scalar_names = |def: &ElementDef| -> Vec<String> {
            def.properties
                .values()
                .filter(|p| matches!(p.data_type, PropertyType::Scalar(_)))
                .map(|p| p.name.clone())
                .collect()
        };
        let vertex_originals = scalar_names(layout.vertex_def);
        let mut vertex_names = vertex_originals.clone();
        if let Some(rank) = layout.uv_rank {
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
        let face_names = scalar_names(layout.face_def);
        let face_groups = ply_attributes::group("face_", &face_names, &[]);
        AttributeNames {
            vertex_originals,
            vertex_groups,
            face_names,
            face_groups,
        }
    }
}

/// Triangles, and each face attribute group's values per triangle.
type Triangulated = (Vec<[u32; 3]>, Vec<Vec<f32>>);

/// The faces as a fan of triangles each (indices checked against `vertex_count`), and
/// each face attribute group's values repeated for every triangle of its face.
fn triangulate(
    faces: &[PlyFace],
    vertex_count: usize,
    names: &AttributeNames,
) -> Result<Triangulated, PlyError> {
    let mut triangles = Vec::with_capacity(faces.len());
    let mut polygon = Vec::new();
    let mut face_data: Vec<Vec<f32>> = vec![Vec::new(); names.face_groups.len()];
    for (f, face) in faces.iter().enumerate() {
        if face.indices.len() < 3 {
            return Err(PlyError::FaceTooSmall {
                face: f,
                vertices: face.indices.len(),
            });
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
                    })
                }
            }
        }
        let before = triangles.len();
        push_fan(&polygon, &mut triangles);
        for (d, data) in names.face_groups.iter().zip(face_data.iter_mut()) {
            for _ in before..triangles.len() {
                for &f in &d.fields {
                    data.push(extra_value(&face.extra, &names.face_names[f]));
                }
            }
        }
    }
    Ok((triangles, face_data))
}

/// The vertex attributes, then the face attributes (`face_data` from [`triangulate`]);
/// `None` when there are none. Mitsuba's add_attribute refuses a name twice (e.g. r g
/// b and color_0..2).
fn attributes(
    vertices: &[PlyVertex],
    names: &AttributeNames,
    face_data: Vec<Vec<f32>>,
) -> Result<Option<MeshAttributes>, PlyError> {
    let mut attributes: Vec<MeshAttribute> = Vec::new();
    for d in &names.vertex_groups {
        let originals: Vec<&String> = d
            .fields
            .iter()
            .map(|&f| &names.vertex_originals[f])
            .collect();
        let mut data = Vec::with_capacity(vertices.len() * d.fields.len());
        for v in vertices {
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
    for (d, data) in names.face_groups.iter().zip(face_data) {
        attributes.push(MeshAttribute {
            name: d.name.clone(),
            per_vertex: false,
            dim: d.fields.len(),
            data,
        });
    }
    for (i, a) in attributes.iter().enumerate() {
        if attributes[..i].iter().any(|b| b.name == a.name) {
            return Err(PlyError::DuplicateAttribute {
                name: a.name.clone(),
            });
        }
    }
    Ok((!attributes.is_empty()).then_some(MeshAttributes { list: attributes }))
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
pub(super) fn normalize_numbers(line: &str) -> Cow<'_, str> {
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
