//! A dense benchmark scene: a finely tessellated, radially displaced sphere inside the
//! Cornell box of `scenes/cbox.xml`, generated on demand (the mesh is tens of MB and is
//! never committed).
//!
//! The mesh is a geodesic icosphere of frequency n (each of the icosahedron's 20 faces
//! cut into n^2 triangles: `20 n^2` triangles, `10 n^2 + 2` shared vertices), projected
//! onto the sphere and displaced along the radius by a fixed sum of sines, so the same
//! triangle count always gives the same bytes. It is written as binary little-endian PLY
//! (`float x y z`, `list uchar int vertex_indices`); the scene XML is `scenes/cbox.xml`
//! with its two boxes replaced by the mesh, and reads in tstat and mitransient alike.
//!
//! Used by `benches/render.rs` and `examples/dense_scene.rs` (through `#[path]`).

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

/// Centre of the sphere (scene units; the room is [-1, 1]^3, floor at y = -1).
const CENTRE: [f64; 3] = [0.0, -0.42, 0.05];
/// Undisplaced radius.
const RADIUS: f64 = 0.48;
/// Relative amplitude of the radial displacement: radii lie in RADIUS (1 +- AMPLITUDE).
const AMPLITUDE: f64 = 0.12;

/// The written scene.
pub struct DenseScene {
    /// The scene XML (the mesh sits beside it).
    pub xml: PathBuf,
    /// Triangles in the mesh (`20 n^2`, the smallest such count >= the one asked for).
    pub triangles: usize,
}

/// Writes `dense_sphere.ply` and `dense_sphere.xml` into `dir` (which must exist), with
/// at least `min_triangles` triangles.
pub fn write_dense_scene(dir: &Path, min_triangles: usize) -> io::Result<DenseScene> {
    let n = frequency(min_triangles);
    let (vertices, faces) = geodesic_sphere(n);
    write_ply(&dir.join("dense_sphere.ply"), &vertices, &faces)?;
    let xml = dir.join("dense_sphere.xml");
    std::fs::write(&xml, scene_xml(faces.len()))?;
    Ok(DenseScene {
        xml,
        triangles: faces.len(),
    })
}

/// The smallest frequency n with `20 n^2 >= min_triangles` (at least 1).
fn frequency(min_triangles: usize) -> usize {
    let mut n = ((min_triangles as f64 / 20.0).sqrt().ceil() as usize).max(1);
    while 20 * n * n < min_triangles {
        n += 1;
    }
    n
}

/// Radial displacement factor at unit direction d: a fixed sum of three sine products,
/// in [1 - AMPLITUDE, 1 + AMPLITUDE].
fn displacement(d: [f64; 3]) -> f64 {
    let [x, y, z] = d;
    let f = 0.5 * (7.0 * x + 1.3).sin() * (9.0 * y + 0.4).sin() * (8.0 * z + 2.1).sin()
        + 0.3 * (17.0 * x - 5.0 * z).sin() * (19.0 * y + 0.7).sin()
        + 0.2 * (31.0 * y + 23.0 * z).sin() * (29.0 * x + 1.1).sin();
    1.0 + AMPLITUDE * f
}

/// The icosahedron: 12 vertices and 20 counter-clockwise (outward) faces.
fn icosahedron() -> ([[f64; 3]; 12], [[usize; 3]; 20]) {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let v = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ];
    let f = [
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    (v, f)
}

fn lerp(a: [f64; 3], b: [f64; 3], s: f64) -> [f64; 3] {
    std::array::from_fn(|k| a[k] + (b[k] - a[k]) * s)
}

/// The displaced geodesic sphere of frequency n in world units: vertices (each shared by
/// all its triangles, so smooth normals have no seams) and outward triangles.
fn geodesic_sphere(n: usize) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let (ico, faces) = icosahedron();
    // Points are placed on the flat faces, then projected: an edge point is computed once,
    // from the lower-numbered end, so both faces sharing the edge use the same vertex.
    let mut points: Vec<[f64; 3]> = ico.to_vec();
    let mut edges: Vec<([usize; 2], usize)> = Vec::new();
    let mut edge_start = |a: usize, b: usize, points: &mut Vec<[f64; 3]>| -> usize {
        let key = [a.min(b), a.max(b)];
        if let Some(&(_, first)) = edges.iter().find(|(k, _)| *k == key) {
            return first;
        }
        let first = points.len();
        for i in 1..n {
            points.push(lerp(ico[key[0]], ico[key[1]], i as f64 / n as f64));
        }
        edges.push((key, first));
        first
    };
    let mut triangles = Vec::with_capacity(20 * n * n);
    let mut grid = vec![0usize; (n + 1) * (n + 1)];
    for &[a, b, c] in &faces {
        let (ab, ac, bc) = (
            edge_start(a, b, &mut points),
            edge_start(a, c, &mut points),
            edge_start(b, c, &mut points),
        );
        // Step i along the edge from `from` to `to`, whose stored points run from the
        // lower-numbered end.
        let on_edge = |first: usize, from: usize, to: usize, i: usize| {
            if i == 0 {
                from
            } else if i == n {
                to
            } else if from < to {
                first + i - 1
            } else {
                first + n - i - 1
            }
        };
        // Grid point (i, j) = a + (b - a) i/n + (c - a) j/n, i + j <= n.
        for i in 0..=n {
            for j in 0..=n - i {
                grid[i * (n + 1) + j] = if j == 0 {
                    on_edge(ab, a, b, i)
                } else if i == 0 {
                    on_edge(ac, a, c, j)
                } else if i + j == n {
                    on_edge(bc, b, c, j)
                } else {
                    let (s, t) = (i as f64 / n as f64, j as f64 / n as f64);
                    let p = std::array::from_fn(|k| {
                        ico[a][k] + (ico[b][k] - ico[a][k]) * s + (ico[c][k] - ico[a][k]) * t
                    });
                    points.push(p);
                    points.len() - 1
                };
            }
        }
        let g = |i: usize, j: usize| grid[i * (n + 1) + j] as u32;
        for i in 0..n {
            for j in 0..n - i {
                triangles.push([g(i, j), g(i + 1, j), g(i, j + 1)]);
                if i + j + 1 < n {
                    triangles.push([g(i + 1, j), g(i + 1, j + 1), g(i, j + 1)]);
                }
            }
        }
    }
    let vertices = points
        .iter()
        .map(|p| {
            let len = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
            let d = [p[0] / len, p[1] / len, p[2] / len];
            let r = RADIUS * displacement(d);
            std::array::from_fn(|k| (CENTRE[k] + r * d[k]) as f32)
        })
        .collect();
    (vertices, triangles)
}

/// Binary little-endian PLY: `float x y z` per vertex, `list uchar int` per face.
fn write_ply(path: &Path, vertices: &[[f32; 3]], faces: &[[u32; 3]]) -> io::Result<()> {
    let mut w = BufWriter::new(File::create(path)?);
    write!(
        w,
        "ply\nformat binary_little_endian 1.0\ncomment tstat dense benchmark sphere\n\
         element vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
         element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        vertices.len(),
        faces.len()
    )?;
    for v in vertices {
        for c in v {
            w.write_all(&c.to_le_bytes())?;
        }
    }
    for f in faces {
        w.write_all(&[3u8])?;
        for &i in f {
            w.write_all(&(i as i32).to_le_bytes())?;
        }
    }
    w.flush()
}

/// `scenes/cbox.xml` with its boxes replaced by the mesh (same room, light, camera, film
/// and defaults, so the same `-D` settings apply).
fn scene_xml(triangles: usize) -> String {
    const CBOX: &str = include_str!(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cbox.xml"));
    const BOXES: &str = "    <!-- ==================== Boxes";
    let room = CBOX
        .split_once(BOXES)
        .expect("scenes/cbox.xml has its boxes section")
        .0;
    // After the XML declaration, say what this file is (cbox.xml's own comment follows).
    let (declaration, room) = room.split_once('\n').expect("cbox.xml has several lines");
    format!(
        "{declaration}\n<!-- Generated by tstat's benches/common/dense_scene.rs (examples/dense_scene.rs): \
         scenes/cbox.xml with its two boxes replaced by dense_sphere.ply. -->\n\
         {room}    <!-- ==================== Dense sphere ==================== -->\n    \
         <!-- generated by benches/common/dense_scene.rs: {triangles} triangles, centre \
         ({}, {}, {}), radius {} with a radial displacement of up to {}% -->\n    \
         <shape type=\"ply\" id=\"dense_sphere\">\n        \
         <string name=\"filename\" value=\"dense_sphere.ply\"/>\n        \
         <ref id=\"white\"/>\n    </shape>\n</scene>\n",
        CENTRE[0],
        CENTRE[1],
        CENTRE[2],
        RADIUS,
        AMPLITUDE * 100.0
    )
}
