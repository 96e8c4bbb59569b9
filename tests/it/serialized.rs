//! Mitsuba `.serialized` meshes: files written by a small encoder here (versions 3, 4
//! and 5, single and double precision, several meshes with their offset dictionary)
//! load with exactly the data written; malformed files are one clear error; a scene
//! with a serialized mesh renders the same steady image as the same mesh given as PLY.

use std::io::{Cursor, Write};
use std::path::Path;

use flate2::write::ZlibEncoder;
use flate2::Compression;
use glam::{Vec2, Vec3};
use tstat::render::{render, PixelSampling, RenderSettings};
use tstat::scene::mesh::MeshData;
use tstat::scene::serialized::{read_serialized, SerializedMesh, SerializedProblem};
use tstat::scene::{Overrides, Scene};
use tstat::stats::Transform;

/// One mesh to encode.
#[derive(Clone)]
struct Mesh {
    name: &'static str,
    positions: Vec<[f64; 3]>,
    normals: Option<Vec<[f64; 3]>>,
    uvs: Option<Vec<[f64; 2]>>,
    /// Written (versions 3 and 4) and expected to be dropped.
    colors: bool,
    triangles: Vec<[u32; 3]>,
    double: bool,
}

fn quad() -> Mesh {
    Mesh {
        name: "quad",
        positions: vec![
            [-0.5, -0.5, 0.25],
            [0.5, -0.5, 0.25],
            [0.5, 0.5, 0.5],
            [-0.5, 0.5, 0.5],
        ],
        normals: Some(vec![
            [0.0, 0.0, 1.0],
            [0.0, 0.6, 0.8],
            [0.6, 0.0, 0.8],
            [0.0, -0.6, 0.8],
        ]),
        uvs: Some(vec![[0.0, 0.0], [1.0, 0.0], [1.0, 0.75], [0.125, 1.0]]),
        colors: true,
        triangles: vec![[0, 1, 2], [0, 2, 3]],
        double: false,
    }
}

fn tri(z: f64) -> Mesh {
    Mesh {
        name: "tri",
        positions: vec![[0.1, 0.2, z], [1.0, 0.0, z], [0.0, 1.0, z]],
        normals: None,
        uvs: None,
        colors: false,
        triangles: vec![[0, 1, 2]],
        double: true,
    }
}

fn zlib(body: &[u8]) -> Vec<u8> {
    let mut e = ZlibEncoder::new(Vec::new(), Compression::default());
    e.write_all(body).unwrap();
    e.finish().unwrap()
}

fn header(version: u16) -> Vec<u8> {
    [0x041Cu16.to_le_bytes(), version.to_le_bytes()].concat()
}

/// The uncompressed body of a version 3 or 4 mesh.
fn legacy_body(version: u16, m: &Mesh) -> Vec<u8> {
    let mut flags = 0u32;
    flags |= if m.normals.is_some() { 1 } else { 0 };
    flags |= if m.uvs.is_some() { 2 } else { 0 };
    flags |= if m.colors { 8 } else { 0 };
    flags |= if m.double { 0x2000 } else { 0x1000 };
    let mut b = flags.to_le_bytes().to_vec();
    if version == 4 {
        b.extend(m.name.as_bytes());
        b.push(0);
    }
    b.extend((m.positions.len() as u64).to_le_bytes());
    b.extend((m.triangles.len() as u64).to_le_bytes());
    let mut put = |v: f64| {
        if m.double {
            b.extend(v.to_le_bytes())
        } else {
            b.extend((v as f32).to_le_bytes())
        }
    };
    m.positions.iter().flatten().for_each(|&v| put(v));
    m.normals.iter().flatten().flatten().for_each(|&v| put(v));
    m.uvs.iter().flatten().flatten().for_each(|&v| put(v));
    if m.colors {
        for i in 0..3 * m.positions.len() {
            put(i as f64 * 0.01);
        }
    }
    for t in &m.triangles {
        t.iter().for_each(|i| b.extend(i.to_le_bytes()));
    }
    b
}

/// A file of several meshes, each a header and a zlib stream, and the dictionary.
fn file_of(version: u16, bodies: &[Vec<u8>], dictionary: bool) -> Vec<u8> {
    let mut f = Vec::new();
    let mut offsets = Vec::new();
    for body in bodies {
        offsets.push(f.len() as u64);
        f.extend(header(version));
        f.extend(zlib(body));
    }
    if dictionary {
        for o in &offsets {
            if version == 3 {
                f.extend((*o as u32).to_le_bytes());
            } else {
                f.extend(o.to_le_bytes());
            }
        }
        f.extend((offsets.len() as u32).to_le_bytes());
    }
    f
}

fn legacy_file(version: u16, meshes: &[Mesh]) -> Vec<u8> {
    let bodies: Vec<_> = meshes.iter().map(|m| legacy_body(version, m)).collect();
    file_of(version, &bodies, true)
}

/// A version 5 mesh as Mitsuba 3's `write_serialized` writes it.
struct V5 {
    layout: u32,
    face_normals: bool,
    /// Position, frame, uv lanes of each vertex.
    records: Vec<[f32; 8]>,
    faces: Vec<[u32; 4]>,
    points: Option<(u64, Vec<u32>)>,
    groups: Option<(u64, Vec<u32>)>,
    /// Name, channels, values.
    attributes: Vec<(&'static str, u32, Vec<f32>)>,
}

fn v5_body(m: &V5) -> Vec<u8> {
    let flags = 0x1000 | m.layout | if m.face_normals { 0x10 } else { 0 };
    let mut b = flags.to_le_bytes().to_vec();
    let string = |b: &mut Vec<u8>, s: &str| {
        b.extend((s.len() as u32).to_le_bytes());
        b.extend(s.as_bytes());
    };
    string(&mut b, "v5 mesh");
    b.extend((m.records.len() as u64).to_le_bytes());
    b.extend((m.faces.len() as u64).to_le_bytes());
    b.extend(m.points.as_ref().map_or(0, |p| p.0).to_le_bytes());
    b.extend(m.groups.as_ref().map_or(0, |g| g.0).to_le_bytes());
    m.records
        .iter()
        .flatten()
        .for_each(|v| b.extend(v.to_le_bytes()));
    m.faces
        .iter()
        .flatten()
        .for_each(|v| b.extend(v.to_le_bytes()));
    for (_, map) in m.points.iter().chain(&m.groups) {
        map.iter().for_each(|v| b.extend(v.to_le_bytes()));
    }
    b.extend((m.attributes.len() as u32).to_le_bytes());
    for (name, dim, values) in &m.attributes {
        string(&mut b, name);
        b.push(0);
        b.extend(dim.to_le_bytes());
        values.iter().for_each(|v| b.extend(v.to_le_bytes()));
    }
    b
}

fn read(bytes: &[u8], index: u64) -> Result<SerializedMesh, String> {
    read_serialized(&mut Cursor::new(bytes), bytes.len() as u64, index).map_err(|p| match p {
        SerializedProblem::NoFaces => "no faces".to_string(),
        SerializedProblem::Invalid(m) => m.to_string(),
    })
}

fn expect(m: &Mesh) -> MeshData {
    let v3 = |v: &[f64; 3]| Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32);
    MeshData {
        positions: m.positions.iter().map(v3).collect(),
        normals: m.normals.as_ref().map(|n| n.iter().map(v3).collect()),
        triangles: m.triangles.clone(),
        uvs: m.uvs.as_ref().map(|u| {
            u.iter()
                .map(|u| Vec2::new(u[0] as f32, u[1] as f32))
                .collect()
        }),
    }
}

#[test]
fn version_4_single_precision_loads_what_was_written() {
    let m = quad();
    let got = read(&legacy_file(4, std::slice::from_ref(&m)), 0).unwrap();
    assert_eq!(got.mesh, expect(&m));
    assert_eq!((got.name.as_str(), got.version), ("quad", 4));
    // Without a dictionary (Mitsuba 3 writes none for one mesh), mesh 0 still loads.
    let bare = file_of(4, &[legacy_body(4, &m)], false);
    assert_eq!(read(&bare, 0).unwrap().mesh, expect(&m));
    assert!(read(&bare, 1).unwrap_err().contains("dictionary"));
}

#[test]
fn several_meshes_are_found_through_the_dictionary_in_both_layouts() {
    let mut a = quad();
    a.double = true;
    let meshes = [a, tri(0.1), tri(-2.5)];
    for version in [3, 4] {
        let f = legacy_file(version, &meshes);
        for (i, m) in meshes.iter().enumerate() {
            let got = read(&f, i as u64).unwrap();
            // Double precision is narrowed to f32 (0.1 included), as Mitsuba does.
            assert_eq!(got.mesh, expect(m), "version {version}, mesh {i}");
            assert_eq!(got.name, if version == 4 { m.name } else { "" });
        }
        let e = read(&f, 3).unwrap_err();
        assert!(
            e.contains("shape_index 3 is out of range: the file holds 3 meshes"),
            "{e}"
        );
    }
}

#[test]
fn version_5_records_frames_maps_and_attributes() {
    let t = (std::f32::consts::PI / 8.0).tan();
    let rec =
        |p: [f32; 3], f: [f32; 3], uv: [f32; 2]| [p[0], p[1], p[2], f[0], f[1], f[2], uv[0], uv[1]];
    // Normals stored plainly, uv, one vertex and one face attribute.
    let plain = V5 {
        layout: 0x1 | 0x4,
        face_normals: false,
        records: vec![
            rec([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.5]),
            rec([1.0, 0.0, 0.0], [0.0, 0.6, 0.8], [1.0, 0.25]),
            rec([0.0, 1.0, 0.0], [0.6, 0.0, 0.8], [0.125, 1.0]),
        ],
        faces: vec![[0, 1, 2, 0]],
        points: None,
        groups: Some((3, vec![2, 1, 0])),
        attributes: vec![("vertex_color", 3, vec![0.5; 9]), ("face_id", 1, vec![7.0])],
    };
    let got = read(&file_of(5, &[v5_body(&plain)], false), 0).unwrap();
    assert_eq!(got.version, 5);
    assert!(!got.face_normals);
    assert_eq!(got.mesh.triangles, vec![[0, 1, 2]]);
    assert_eq!(got.mesh.positions[1], Vec3::X);
    assert_eq!(
        got.mesh.normals.as_ref().unwrap()[1],
        Vec3::new(0.0, 0.6, 0.8)
    );
    assert_eq!(got.mesh.uvs.as_ref().unwrap()[1], Vec2::new(1.0, 0.25));

    // Tangents: the frame lanes hold the rotation's modified Rodrigues parameters;
    // a quarter turn about x takes the normal from +z to -y.
    let mut framed = plain;
    framed.layout = 0x1 | 0x2 | 0x4;
    framed.face_normals = true;
    framed.records[0][3..6].copy_from_slice(&[t, 0.0, 0.0]);
    framed.records[1][3..6].copy_from_slice(&[0.0, 0.0, 0.0]);
    let got = read(&file_of(5, &[v5_body(&framed)], false), 0).unwrap();
    assert!(got.face_normals);
    let n = got.mesh.normals.unwrap();
    assert!(
        (n[0] - Vec3::new(0.0, -1.0, 0.0)).length() < 1e-6,
        "{}",
        n[0]
    );
    assert_eq!(n[1], Vec3::Z);

    // No stored normals and a point map: the smooth normals of two faces meeting at a
    // crease are shared by the duplicated vertices along it.
    let p = |x: f32, y: f32, z: f32| rec([x, y, z], [0.0; 3], [0.0; 2]);
    let crease = |points| V5 {
        layout: 0,
        face_normals: false,
        records: vec![
            p(0.0, 0.0, 0.0),
            p(1.0, 0.0, 0.0),
            p(0.0, 1.0, 0.0),
            p(1.0, 0.0, 0.0),
            p(0.0, 1.0, 0.0),
            p(1.0, 1.0, 1.0),
        ],
        faces: vec![[0, 1, 2, 0], [3, 5, 4, 0]],
        points,
        groups: None,
        attributes: vec![],
    };
    let welded = read(
        &file_of(
            5,
            &[v5_body(&crease(Some((4, vec![0, 1, 2, 1, 2, 3]))))],
            false,
        ),
        0,
    )
    .unwrap();
    let n = welded.mesh.normals.unwrap();
    assert_eq!(n[1], n[3]);
    assert_eq!(n[2], n[4]);
    assert!(n[1].z < 0.999 && n[1].z > 0.5, "{}", n[1]);
    // Without the map the loader leaves the normals to the shape (per vertex).
    let split = read(&file_of(5, &[v5_body(&crease(None))], false), 0).unwrap();
    assert!(split.mesh.normals.is_none());
}

/// The error of `bytes` (mesh `index`); panics if it loads.
fn error(bytes: &[u8], index: u64) -> String {
    match read(bytes, index) {
        Ok(_) => panic!("loaded"),
        Err(e) => e,
    }
}

#[test]
fn malformed_files_are_one_clear_error() {
    let good = legacy_file(4, &[quad(), tri(0.0)]);
    assert!(error(&good[..3], 0).contains("truncated header"));
    assert!(error(b"ply\nformat", 0).contains("not a serialized mesh"));
    let mut v6 = good.clone();
    v6[2] = 6;
    assert!(error(&v6, 0).contains("unsupported version 6"));
    // Corrupt DEFLATE data, or a flipped byte caught by the adler-32.
    let mut corrupt = good.clone();
    corrupt[4..40].iter_mut().for_each(|b| *b = !*b);
    assert!(error(&corrupt, 0).contains("corrupt compressed data"));
    let body = legacy_body(4, &quad());
    let mut stream = file_of(4, std::slice::from_ref(&body), false);
    let n = stream.len();
    stream[n - 1] ^= 1;
    let e = error(&stream, 0);
    assert!(e.contains("corrupt compressed data"), "{e}");
    // Truncated anywhere in the stream.
    let single = file_of(4, std::slice::from_ref(&body), false);
    for cut in [6, 20, single.len() - 5] {
        let e = error(&single[..cut], 0);
        assert!(
            e.contains("end early") || e.contains("more than"),
            "cut {cut}: {e}"
        );
    }
    // Counts: far beyond what the stream can hold (refused before allocating), a
    // little beyond the data, below the data, beyond u32.
    let with_counts = |v: u64, f: u64| {
        let mut b = body.clone();
        let at = 4 + "quad".len() + 1;
        b[at..at + 8].copy_from_slice(&v.to_le_bytes());
        b[at + 8..at + 16].copy_from_slice(&f.to_le_bytes());
        file_of(4, &[b], false)
    };
    let e = error(&with_counts(1 << 31, 2), 0);
    assert!(e.contains("need") && e.contains("compressed bytes"), "{e}");
    assert!(error(&with_counts(5, 2), 0).contains("end early"));
    assert!(error(&with_counts(4, 1), 0).contains("more data than its counts"));
    assert!(error(&with_counts(1 << 40, 1), 0).contains("more than 4294967295"));
    let mut empty = tri(0.0);
    empty.triangles.clear();
    assert_eq!(error(&legacy_file(4, &[empty]), 0), "no faces");
    // Indices out of range, NaN and overflowing coordinates.
    let mut m = quad();
    m.triangles[1] = [0, 2, 4];
    assert!(error(&legacy_file(4, &[m]), 0)
        .contains("triangle 1 refers to vertex 4, but there are only 4 vertices"));
    let mut m = quad();
    m.positions[2][1] = f64::NAN;
    assert!(error(&legacy_file(4, &[m]), 0).contains("vertex 2: position"));
    let mut m = tri(0.0);
    m.positions[1][0] = 1e39; // finite as f64, infinite as f32
    assert!(error(&legacy_file(3, &[m]), 0).contains("vertex 1: position"));
    let mut m = quad();
    m.uvs.as_mut().unwrap()[3][0] = f64::INFINITY;
    assert!(error(&legacy_file(4, &[m]), 0).contains("vertex 3: texture coordinates"));
    // A name without its end.
    let mut b = 0x1000u32.to_le_bytes().to_vec();
    b.extend(vec![b'a'; 70_000]);
    assert!(error(&file_of(4, &[b], false), 0).contains("longer than"));
    // Dictionaries: a count beyond the file, an offset beyond it, an offset that is
    // not a mesh header.
    let mut d = good.clone();
    let n = d.len();
    d[n - 4..].copy_from_slice(&1000u32.to_le_bytes());
    assert!(error(&d, 999).contains("dictionary"));
    let mut d = good.clone();
    d[n - 12..n - 4].copy_from_slice(&(1u64 << 40).to_le_bytes());
    assert!(error(&d, 1).contains("beyond the end of the file"));
    let mut d = good.clone();
    d[n - 12..n - 4].copy_from_slice(&7u64.to_le_bytes());
    assert!(error(&d, 1).contains("does not start with a header"));
    // Version 5 specifics.
    let v5 = |layout: u32, attrs: Vec<(&'static str, u32, Vec<f32>)>| V5 {
        layout,
        face_normals: false,
        records: vec![[0.0; 8]; 3],
        faces: vec![[0, 1, 2, 0]],
        points: None,
        groups: None,
        attributes: attrs,
    };
    let e = error(&file_of(5, &[v5_body(&v5(0x2, vec![]))], false), 0);
    assert!(e.contains("tangents without normals"), "{e}");
    let e = error(&file_of(5, &[v5_body(&v5(0x3, vec![]))], false), 0);
    assert!(e.contains("tangents without normals and texture"), "{e}");
    let e = error(
        &file_of(5, &[v5_body(&v5(0, vec![("x", 5, vec![])]))], false),
        0,
    );
    assert!(e.contains("5 channels"), "{e}");
    let e = error(
        &file_of(5, &[v5_body(&v5(0, vec![("x", 1, vec![1.0])]))], false),
        0,
    );
    assert!(e.contains("end early"), "{e}");
    let mut bad_map = v5(0, vec![]);
    bad_map.points = Some((2, vec![0, 1, 2]));
    let e = error(&file_of(5, &[v5_body(&bad_map)], false), 0);
    assert!(e.contains("vertex 2 maps to surface point 2 of 2"), "{e}");
    let mut double = v5_body(&v5(0, vec![]));
    double[..4].copy_from_slice(&0x2000u32.to_le_bytes());
    assert!(error(&file_of(5, &[double], false), 0).contains("single precision"));
}

// ---- through the scene loader and the renderer ----

const SCENE: &str = r#"<scene version="3.0.0">
  <integrator type="transient_path"><integer name="max_depth" value="3"/></integrator>
  <sensor type="perspective">
    <float name="fov" value="40"/>
    <transform name="to_world"><lookat origin="0,0,4" target="0,0,0" up="0,1,0"/></transform>
    <sampler type="independent"><integer name="sample_count" value="4"/></sampler>
    <film type="transient_hdr_film">
      <integer name="width" value="12"/><integer name="height" value="10"/>
      <integer name="temporal_bins" value="10"/>
      <float name="start_opl" value="3"/><float name="bin_width_opl" value="0.5"/>
    </film>
  </sensor>
  <emitter type="point"><point name="position" x="0" y="0.5" z="3"/><rgb name="intensity" value="5"/></emitter>
  <shape type="rectangle"><transform name="to_world"><scale value="2"/><translate z="-1"/></transform></shape>
  <shape type="KIND">
    <string name="filename" value="FILE"/>
    EXTRA
    <transform name="to_world"><rotate y="1" angle="20"/><translate x="0.1"/></transform>
    <bsdf type="diffuse"><texture type="checkerboard" name="reflectance"/></bsdf>
  </shape>
</scene>
"#;

/// A binary PLY of the same mesh (f32 positions, normals, uv).
fn ply(m: &Mesh) -> Vec<u8> {
    let mut b = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
         property float nx\nproperty float ny\nproperty float nz\nproperty float u\nproperty float v\n\
         element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        m.positions.len(),
        m.triangles.len()
    )
    .into_bytes();
    let normals = m.normals.as_ref().unwrap();
    let uvs = m.uvs.as_ref().unwrap();
    for i in 0..m.positions.len() {
        let vals = m.positions[i].iter().chain(&normals[i]).chain(&uvs[i]);
        vals.for_each(|&v| b.extend((v as f32).to_le_bytes()));
    }
    for t in &m.triangles {
        b.push(3);
        t.iter().for_each(|&i| b.extend((i as i32).to_le_bytes()));
    }
    b
}

fn load(dir: &Path, kind: &str, file: &str, extra: &str) -> Result<Scene, String> {
    let text = SCENE
        .replace("KIND", kind)
        .replace("FILE", file)
        .replace("EXTRA", extra);
    let path = dir.join(format!("{kind}-{}.xml", extra.len()));
    std::fs::write(&path, text).unwrap();
    Scene::load(&path, &Overrides::default()).map_err(|e| e.to_string())
}

fn load_error(dir: &Path, kind: &str, file: &str, extra: &str) -> String {
    match load(dir, kind, file, extra) {
        Ok(_) => panic!("{extra}: loaded"),
        Err(e) => e,
    }
}

fn steady(s: &Scene) -> Vec<f64> {
    let settings = RenderSettings {
        spp: s.spp,
        seed: 3,
        transform: Transform::Identity,
        pixel_sampling: PixelSampling::Independent,
        replicates: 0,
        pixel_spp: None,
    };
    render(s, &settings, &|_| {}).steady
}

#[test]
fn a_serialized_mesh_renders_as_the_same_ply_mesh() {
    let d = tempfile::tempdir().unwrap();
    let d = d.path();
    let m = quad();
    std::fs::write(d.join("m.ply"), ply(&m)).unwrap();
    // The quad is mesh 1, between two others.
    std::fs::write(
        d.join("m.serialized"),
        legacy_file(4, &[tri(0.0), m, tri(1.0)]),
    )
    .unwrap();
    let index = r#"<integer name="shape_index" value="1"/>"#;
    let ply_image = steady(&load(d, "ply", "m.ply", "").unwrap());
    let ser_image = steady(&load(d, "serialized", "m.serialized", index).unwrap());
    assert!(ply_image.iter().any(|&v| v > 0.0));
    assert_eq!(ply_image, ser_image);
    // face_normals and flip_normals are the shared ones.
    for extra in [
        r#"<boolean name="face_normals" value="true"/>"#,
        r#"<boolean name="flip_normals" value="true"/>"#,
    ] {
        let a = steady(&load(d, "ply", "m.ply", extra).unwrap());
        let b = steady(&load(d, "serialized", "m.serialized", &format!("{index}{extra}")).unwrap());
        assert_eq!(a, b, "{extra}");
        assert_ne!(a, ply_image, "{extra} changes nothing");
    }
    // Scene-level errors name the parameter and the file.
    let e = load_error(
        d,
        "serialized",
        "m.serialized",
        r#"<integer name="shape_index" value="-1"/>"#,
    );
    assert!(e.contains("shape_index must be non-negative"), "{e}");
    let e = load_error(
        d,
        "serialized",
        "m.serialized",
        r#"<integer name="shape_index" value="3"/>"#,
    );
    assert!(
        e.contains("m.serialized") && e.contains("out of range"),
        "{e}"
    );
    let e = load_error(
        d,
        "serialized",
        "m.serialized",
        r#"<boolean name="flip_tex_coords" value="true"/>"#,
    );
    assert!(e.contains("flip_tex_coords"), "{e}");
}
