//! The mesh loaders' tests (PLY and OBJ against each other and against hostile files).

use super::obj::*;
use super::ply::*;
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
