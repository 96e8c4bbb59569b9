//! Mitsuba's `.serialized` meshes, read as Mitsuba 3's `serialized` plugin
//! (`src/shapes/serialized.cpp`) reads them.
//!
//! A file is a sequence of meshes, each an uncompressed little-endian header (`u16`
//! magic `0x041C`, `u16` version) followed by one zlib stream, and (when it holds
//! several meshes) an offset dictionary at its end: version 4 and 5 store one `u64`
//! file offset per mesh followed by a `u32` mesh count, version 3 `u32` offsets and the
//! count. `shape_index` 0 is read from the start of the file without the dictionary (as
//! Mitsuba does: single-mesh files written by Mitsuba 3 have none).
//!
//! Versions 3 and 4 (Mitsuba 0.x, most files in the wild), inside the zlib stream:
//! `u32` flags (`0x1` normals, `0x2` texture coordinates, `0x8` vertex colours, `0x2000`
//! double precision; others, such as `0x10` face normals, are ignored as Mitsuba 3
//! ignores them), the mesh name as a NUL-terminated string (version 4 only), `u64`
//! vertex and triangle counts, then per-vertex arrays: positions (3 values), normals
//! (3), texture coordinates (2), colours (3, read and dropped), in `f32` or `f64`
//! (narrowed to `f32`, as Mitsuba), and `3 F` `u32` vertex indices (Mitsuba 3 reads
//! indices only as `u32`; so does this loader, and counts above `u32::MAX` are refused).
//!
//! Version 5 (Mitsuba 3's current writer, `Mesh::write_serialized`): flags (`0x1`
//! normals, `0x2` tangents, `0x4` texture coordinates in the low bits, `0x10` face
//! normals, `0x1000` single precision, required), the name as a `u32` length and
//! bytes, `u64` counts of vertices V, faces F, surface points P and normal groups N,
//! `8 V` `f32` vertex records (position, normal or an encoded shading frame, uv),
//! `4 F` `u32` face records (three indices, a BSDF index), the vertex-to-point and
//! vertex-to-group maps (`V` `u32` each, present when P or N is non-zero), and custom
//! attributes (read and dropped). With tangents the normal is decoded from the frame;
//! without stored normals and with a point map, the computed smooth normals are
//! shared by the vertices of one surface point, as Mitsuba's are. The stored face
//! normal flag applies when the scene does not set `face_normals`.
//!
//! Texture coordinates are kept as stored (no v flip). Counts are checked against what
//! the compressed stream can possibly hold before anything is allocated (DEFLATE
//! expands at most 1032-fold), and arrays grow only as their data actually arrives, so
//! no header can make the loader allocate more than the file decompresses to.
//! Truncated or corrupt streams, indices out of range, non-finite values, an unknown
//! version or a `shape_index` beyond the dictionary are errors; so is data left in a
//! mesh's stream after its last field (its adler-32 checksum is then verified too).

use std::io::{self, BufReader, Read, Seek, SeekFrom};
use std::path::Path;

use flate2::read::ZlibDecoder;
use glam::{Vec2, Vec3};

use super::mesh::{MeshData, MeshError};

/// The file format identifier.
pub const MAGIC: u16 = 0x041C;
/// Meshes of more vertices or triangles than this are refused (indices are `u32`).
pub const MAX_COUNT: u64 = u32::MAX as u64;
/// The longest mesh or attribute name accepted (names are only informative).
const MAX_NAME_BYTES: u64 = 1 << 16;
/// Custom attributes of one version 5 mesh.
const MAX_ATTRIBUTES: u32 = 1 << 16;
/// DEFLATE's largest expansion: 258 bytes from 2 bits.
const MAX_INFLATE_RATIO: u64 = 1032;
/// Values decoded per step while reading an array (64 KiB of `f64`).
const CHUNK: usize = 8192;

const V3_V4_NORMALS: u32 = 0x0001;
const V3_V4_TEXCOORDS: u32 = 0x0002;
const V3_V4_COLORS: u32 = 0x0008;
const V3_V4_DOUBLE: u32 = 0x2000;

const V5_NORMALS: u32 = 0x0001;
const V5_TANGENTS: u32 = 0x0002;
const V5_TEXCOORDS: u32 = 0x0004;
const V5_FACE_NORMALS: u32 = 0x0010;
const V5_SINGLE: u32 = 0x1000;

/// One mesh of a `.serialized` file.
#[derive(Clone, Debug, PartialEq)]
pub struct SerializedMesh {
    pub mesh: MeshData,
    /// The mesh name stored in the file (empty in version 3).
    pub name: String,
    /// The format version (3, 4 or 5).
    pub version: u16,
    /// Version 5's stored face-normal flag (false for older versions).
    pub face_normals: bool,
}

/// Loads mesh `shape_index` of a `.serialized` file. Every problem is a
/// [`MeshError`] naming the file.
pub fn load_serialized(path: &Path, shape_index: u64) -> Result<SerializedMesh, MeshError> {
    let io_err = |e: String| MeshError::Io {
        path: path.to_path_buf(),
        source: io::Error::other(e),
    };
    let (mut file, len) = crate::io::open_regular(path, crate::io::MAX_MESH_BYTES)
        .map_err(|e| io_err(e.to_string()))?;
    let parsed = read_serialized(&mut file, len, shape_index).map_err(|p| match p {
        SerializedProblem::NoFaces => MeshError::NoFaces {
            path: path.to_path_buf(),
        },
        SerializedProblem::Invalid(problem) => MeshError::Serialized {
            path: path.to_path_buf(),
            problem,
        },
    })?;
    Ok(parsed)
}

/// What went wrong; the caller adds the path.
#[derive(Debug)]
pub enum SerializedProblem {
    NoFaces,
    Invalid(SerializedError),
}

impl From<SerializedError> for SerializedProblem {
    fn from(e: SerializedError) -> Self {
        SerializedProblem::Invalid(e)
    }
}

/// Reads mesh `shape_index` from `file`, `len` bytes long.
pub fn read_serialized<F: Read + Seek>(
    file: &mut F,
    len: u64,
    shape_index: u64,
) -> Result<SerializedMesh, SerializedProblem> {
    let mut header = [0u8; 4];
    read_raw(file, &mut header).map_err(|_| SerializedError::TruncatedHeader { len })?;
    let (magic, version) = header_of(header);
    if magic != MAGIC {
        return Err(SerializedError::Magic {
            found: magic,
            expected: MAGIC,
        }
        .into());
    }
    if !(3..=5).contains(&version) {
        return Err(SerializedError::Version { version }.into());
    }
    let start = if shape_index == 0 {
        4
    } else {
        let offset = dictionary_offset(file, len, version, shape_index)?;
        let mut at = [0u8; 4];
        read_raw(file, &mut at).map_err(|_| SerializedError::MeshAtEnd {
            index: shape_index,
            offset,
        })?;
        if header_of(at).0 != MAGIC {
            return Err(SerializedError::MeshHeader {
                index: shape_index,
                offset,
            }
            .into());
        }
        offset + 4
    };
    let compressed = len.saturating_sub(start);
    let mut z = Stream {
        inner: ZlibDecoder::new(BufReader::new(file.take(compressed))),
        limit: compressed.saturating_mul(MAX_INFLATE_RATIO) + 64,
        compressed,
    };
    let mut m = if version == 5 {
        read_v5(&mut z)?
    } else {
        read_legacy(&mut z, version)?
    };
    // Nothing may follow the last field; reading to the end also checks the adler-32.
    let mut probe = [0u8; 1];
    match z.inner.read(&mut probe) {
        Ok(0) => {}
        Ok(_) => return Err(SerializedError::TrailingData.into()),
        Err(e) => return Err(z.error(e).into()),
    }
    if m.mesh.triangles.is_empty() {
        return Err(SerializedProblem::NoFaces);
    }
    m.version = version;
    Ok(m)
}

fn header_of(b: [u8; 4]) -> (u16, u16) {
    (
        u16::from_le_bytes([b[0], b[1]]),
        u16::from_le_bytes([b[2], b[3]]),
    )
}

fn read_raw<F: Read>(file: &mut F, buf: &mut [u8]) -> io::Result<()> {
    file.read_exact(buf)
}

/// Seeks to mesh `index`'s header through the dictionary at the end of the file and
/// returns its offset.
fn dictionary_offset<F: Read + Seek>(
    file: &mut F,
    len: u64,
    version: u16,
    index: u64,
) -> Result<u64, SerializedProblem> {
    let no_dict = || SerializedProblem::from(SerializedError::NoDictionary { index });
    if len < 8 {
        return Err(no_dict());
    }
    let mut b4 = [0u8; 4];
    file.seek(SeekFrom::Start(len - 4)).map_err(|_| no_dict())?;
    read_raw(file, &mut b4).map_err(|_| no_dict())?;
    let count = u64::from(u32::from_le_bytes(b4));
    if index >= count {
        return Err(SerializedError::IndexRange { index, count }.into());
    }
    let width: u64 = if version >= 4 { 8 } else { 4 };
    // The offsets of meshes 0..count sit just before the count.
    let entry = (len - 4).checked_sub(width * count).ok_or_else(no_dict)? + width * index;
    file.seek(SeekFrom::Start(entry)).map_err(|_| no_dict())?;
    let offset = if width == 8 {
        let mut b8 = [0u8; 8];
        read_raw(file, &mut b8).map_err(|_| no_dict())?;
        u64::from_le_bytes(b8)
    } else {
        read_raw(file, &mut b4).map_err(|_| no_dict())?;
        u64::from(u32::from_le_bytes(b4))
    };
    if offset >= len {
        return Err(SerializedError::OffsetBeyondEnd { index, offset, len }.into());
    }
    file.seek(SeekFrom::Start(offset)).map_err(|_| no_dict())?;
    Ok(offset)
}

/// The decompressed stream of one mesh.
struct Stream<R: Read> {
    inner: ZlibDecoder<R>,
    /// The most bytes the rest of the compressed data can expand to.
    limit: u64,
    compressed: u64,
}

impl<R: Read> Stream<R> {
    fn error(&self, e: io::Error) -> SerializedError {
        if e.kind() == io::ErrorKind::UnexpectedEof {
            SerializedError::Truncated
        } else {
            SerializedError::Corrupt(e)
        }
    }

    fn bytes<const N: usize>(&mut self) -> Result<[u8; N], SerializedError> {
        let mut b = [0u8; N];
        self.inner.read_exact(&mut b).map_err(|e| self.error(e))?;
        Ok(b)
    }
    fn u8(&mut self) -> Result<u8, SerializedError> {
        Ok(self.bytes::<1>()?[0])
    }
    fn u32(&mut self) -> Result<u32, SerializedError> {
        Ok(u32::from_le_bytes(self.bytes()?))
    }
    fn u64(&mut self) -> Result<u64, SerializedError> {
        Ok(u64::from_le_bytes(self.bytes()?))
    }

    /// Refuses counts needing more bytes than the compressed data can hold.
    fn check_size(&self, payload: SerializedPayload, bytes: u128) -> Result<(), SerializedError> {
        if bytes > u128::from(self.limit) {
            return Err(SerializedError::TooLarge {
                payload,
                bytes,
                compressed: self.compressed,
            });
        }
        Ok(())
    }

    /// Reads `n` little-endian values of `width` bytes, converted by `f`, growing the
    /// vector only as the data arrive.
    fn array<T, const W: usize>(
        &mut self,
        n: usize,
        f: impl Fn([u8; W]) -> T,
    ) -> Result<Vec<T>, SerializedError> {
        let mut out = Vec::with_capacity(n.min(CHUNK));
        let mut buf = vec![0u8; W * CHUNK];
        while out.len() < n {
            let k = (n - out.len()).min(CHUNK);
            let chunk = &mut buf[..W * k];
            self.inner.read_exact(chunk).map_err(|e| self.error(e))?;
            out.extend(
                chunk
                    .chunks_exact(W)
                    .map(|c| f(c.try_into().expect("chunks of W bytes"))),
            );
        }
        Ok(out)
    }

    /// Reads `n` values in single or double precision as `f32`.
    fn floats(&mut self, n: usize, double: bool) -> Result<Vec<f32>, SerializedError> {
        if double {
            self.array(n, |b: [u8; 8]| f64::from_le_bytes(b) as f32)
        } else {
            self.array(n, f32::from_le_bytes)
        }
    }

    /// Reads and drops `n` bytes.
    fn skip(&mut self, n: u64) -> Result<(), SerializedError> {
        let copied =
            io::copy(&mut (&mut self.inner).take(n), &mut io::sink()).map_err(|e| self.error(e))?;
        if copied < n {
            return Err(self.error(io::ErrorKind::UnexpectedEof.into()));
        }
        Ok(())
    }
}

fn vec3s(values: &[f32], what: &'static str) -> Result<Vec<Vec3>, SerializedError> {
    values
        .chunks_exact(3)
        .enumerate()
        .map(|(i, c)| {
            let v = Vec3::from_slice(c);
            v.is_finite()
                .then_some(v)
                .ok_or(SerializedError::VertexNotFinite {
                    vertex: i,
                    what,
                    value: v.to_array(),
                })
        })
        .collect()
}

fn vec2s(values: &[f32]) -> Result<Vec<Vec2>, SerializedError> {
    values
        .chunks_exact(2)
        .enumerate()
        .map(|(i, c)| {
            let v = Vec2::from_slice(c);
            v.is_finite()
                .then_some(v)
                .ok_or(SerializedError::UvNotFinite {
                    vertex: i,
                    uv: v.to_array(),
                })
        })
        .collect()
}

fn check_counts(vertices: u64, faces: u64) -> Result<(), SerializedError> {
    for (count, what) in [(vertices, "vertices"), (faces, "triangles")] {
        if count > MAX_COUNT {
            return Err(SerializedError::Count {
                count,
                what,
                limit: MAX_COUNT,
            });
        }
    }
    Ok(())
}

fn triangles(
    indices: &[u32],
    stride: usize,
    vertices: usize,
) -> Result<Vec<[u32; 3]>, SerializedError> {
    indices
        .chunks_exact(stride)
        .enumerate()
        .map(|(f, c)| {
            let t = [c[0], c[1], c[2]];
            match t.iter().find(|&&i| i as usize >= vertices) {
                Some(&index) => Err(SerializedError::TriangleIndex {
                    triangle: f,
                    index,
                    vertices,
                }),
                None => Ok(t),
            }
        })
        .collect()
}

/// Versions 3 and 4.
fn read_legacy<R: Read>(
    z: &mut Stream<R>,
    version: u16,
) -> Result<SerializedMesh, SerializedProblem> {
    let flags = z.u32()?;
    let mut name = Vec::new();
    if version == 4 {
        loop {
            match z.u8()? {
                0 => break,
                c if (name.len() as u64) < MAX_NAME_BYTES => name.push(c),
                _ => {
                    return Err(SerializedError::NameTooLong {
                        limit: MAX_NAME_BYTES,
                    }
                    .into())
                }
            }
        }
    }
    let (nv, nf) = (z.u64()?, z.u64()?);
    check_counts(nv, nf)?;
    let double = flags & V3_V4_DOUBLE != 0;
    let normals = flags & V3_V4_NORMALS != 0;
    let uvs = flags & V3_V4_TEXCOORDS != 0;
    let colors = flags & V3_V4_COLORS != 0;
    let per_vertex = 3 + 3 * u128::from(normals) + 2 * u128::from(uvs) + 3 * u128::from(colors);
    let width = if double { 8 } else { 4 };
    z.check_size(
        SerializedPayload::Mesh {
            vertices: nv,
            triangles: nf,
        },
        u128::from(nv) * per_vertex * width + u128::from(nf) * 12,
    )?;
    let (v, f) = (nv as usize, nf as usize);
    let positions = vec3s(&z.floats(3 * v, double)?, "position")?;
    let normals = if normals {
        Some(vec3s(&z.floats(3 * v, double)?, "normal")?)
    } else {
        None
    };
    let uvs = if uvs {
        Some(vec2s(&z.floats(2 * v, double)?)?)
    } else {
        None
    };
    if colors {
        z.skip(nv * 3 * width as u64)?;
    }
    let indices = z.array(3 * f, u32::from_le_bytes)?;
    let triangles = triangles(&indices, 3, v)?;
    Ok(SerializedMesh {
        mesh: MeshData {
            positions,
            normals,
            triangles,
            uvs,
        },
        name: String::from_utf8_lossy(&name).into_owned(),
        version,
        face_normals: false,
    })
}

/// Mitsuba's `frame_decode`: the normal of a shading frame stored as the modified
/// Rodrigues parameters of its rotation.
fn frame_normal(p: Vec3) -> Vec3 {
    let a = 1.0 / (1.0 + p.length_squared());
    let big_a = 8.0 * a * a;
    let b = big_a - 4.0 * a;
    let x = big_a * p.x;
    let z = big_a * p.z;
    let xz = p.x * z;
    let yz = p.y * z;
    let u = 1.0 - p.y * (big_a * p.y);
    Vec3::new(b * p.y + xz, yz - b * p.x, u - p.x * x)
}

/// Version 5.
fn read_v5<R: Read>(z: &mut Stream<R>) -> Result<SerializedMesh, SerializedProblem> {
    let flags = z.u32()?;
    if flags & V5_SINGLE == 0 {
        return Err(SerializedError::NotSinglePrecision.into());
    }
    let has_normals = flags & V5_NORMALS != 0;
    let tangents = flags & V5_TANGENTS != 0;
    let has_uvs = flags & V5_TEXCOORDS != 0;
    if tangents && !(has_normals && has_uvs) {
        return Err(SerializedError::TangentsAlone.into());
    }
    let name = read_string(z, "mesh name")?;
    let (nv, nf, np, nn) = (z.u64()?, z.u64()?, z.u64()?, z.u64()?);
    check_counts(nv, nf)?;
    if np > nv || nn > nv {
        return Err(SerializedError::PointMaps {
            points: np,
            groups: nn,
            vertices: nv,
        }
        .into());
    }
    let maps = u128::from(np > 0) + u128::from(nn > 0);
    z.check_size(
        SerializedPayload::Mesh {
            vertices: nv,
            triangles: nf,
        },
        u128::from(nv) * (32 + 4 * maps) + u128::from(nf) * 16,
    )?;
    let (v, f) = (nv as usize, nf as usize);
    let records = z.floats(8 * v, false)?;
    let mut positions = Vec::with_capacity(v);
    let mut normals = Vec::with_capacity(if has_normals { v } else { 0 });
    let mut uvs = Vec::with_capacity(if has_uvs { v } else { 0 });
    for (i, r) in records.chunks_exact(8).enumerate() {
        let p = Vec3::from_slice(&r[0..3]);
        if !p.is_finite() {
            return Err(SerializedError::VertexNotFinite {
                vertex: i,
                what: "position",
                value: p.to_array(),
            }
            .into());
        }
        positions.push(p);
        if has_normals {
            let frame = Vec3::from_slice(&r[3..6]);
            let n = if tangents { frame_normal(frame) } else { frame };
            if !n.is_finite() {
                return Err(SerializedError::VertexNotFinite {
                    vertex: i,
                    what: "normal",
                    value: frame.to_array(),
                }
                .into());
            }
            normals.push(n);
        }
        if has_uvs {
            let uv = Vec2::from_slice(&r[6..8]);
            if !uv.is_finite() {
                return Err(SerializedError::UvNotFinite {
                    vertex: i,
                    uv: uv.to_array(),
                }
                .into());
            }
            uvs.push(uv);
        }
    }
    drop(records);
    let faces = z.array(4 * f, u32::from_le_bytes)?;
    let triangles = triangles(&faces, 4, v)?;
    drop(faces);
    let point_of = if np > 0 {
        let map = z.array(v, u32::from_le_bytes)?;
        if let Some((i, p)) = map.iter().enumerate().find(|(_, &p)| u64::from(p) >= np) {
            return Err(SerializedError::PointIndex {
                vertex: i,
                point: *p,
                points: np,
            }
            .into());
        }
        Some(map)
    } else {
        None
    };
    if nn > 0 {
        let map = z.array(v, u32::from_le_bytes)?;
        if let Some((i, g)) = map.iter().enumerate().find(|(_, &g)| u64::from(g) >= nn) {
            return Err(SerializedError::GroupIndex {
                vertex: i,
                group: *g,
                groups: nn,
            }
            .into());
        }
    }
    let attributes = z.u32()?;
    if attributes > MAX_ATTRIBUTES {
        return Err(SerializedError::Attributes {
            count: attributes,
            limit: MAX_ATTRIBUTES,
        }
        .into());
    }
    for _ in 0..attributes {
        let name = read_string(z, "attribute name")?;
        let _flags = z.u8()?;
        let dim = z.u32()?;
        if !(1..=4).contains(&dim) {
            return Err(SerializedError::AttributeChannels {
                name,
                channels: dim,
            }
            .into());
        }
        let rows = if name.starts_with("face_") { nf } else { nv };
        let bytes = u128::from(rows) * u128::from(dim) * 4;
        z.check_size(SerializedPayload::Attribute { name }, bytes)?;
        z.skip(bytes as u64)?;
    }
    let mut mesh = MeshData {
        positions,
        normals: has_normals.then_some(normals),
        triangles,
        uvs: has_uvs.then_some(uvs),
    };
    if let (None, Some(map)) = (&mesh.normals, &point_of) {
        mesh.normals = Some(point_normals(&mesh, map, np as usize));
    }
    Ok(SerializedMesh {
        mesh,
        name,
        version: 5,
        face_normals: flags & V5_FACE_NORMALS != 0,
    })
}

/// Smooth normals computed over surface points: vertices that share a point (a seam
/// of texture coordinates, say) get the same normal.
fn point_normals(m: &MeshData, point_of: &[u32], points: usize) -> Vec<Vec3> {
    let mut positions = vec![Vec3::ZERO; points];
    for (v, &p) in point_of.iter().enumerate() {
        positions[p as usize] = m.positions[v];
    }
    let welded = MeshData {
        positions,
        normals: None,
        triangles: m
            .triangles
            .iter()
            .map(|t| t.map(|i| point_of[i as usize]))
            .collect(),
        uvs: None,
    };
    let n = super::mesh::vertex_normals(&welded);
    point_of.iter().map(|&p| n[p as usize]).collect()
}

/// A `u32` length and that many bytes (version 5).
fn read_string<R: Read>(z: &mut Stream<R>, what: &'static str) -> Result<String, SerializedError> {
    let n = u64::from(z.u32()?);
    if n > MAX_NAME_BYTES {
        return Err(SerializedError::StringTooLong {
            what,
            bytes: n,
            limit: MAX_NAME_BYTES,
        });
    }
    let bytes = z.array(n as usize, |b: [u8; 1]| b[0])?;
    Ok(String::from_utf8_lossy(&bytes).into_owned())
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
