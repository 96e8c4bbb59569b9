//! Fuzzing on the stable toolchain: property tests that mutate valid inputs (scene XML,
//! the files a scene reads -- includes, spectra, `.vol` grids, images, curves --, PLY,
//! OBJ and `.serialized` bytes, `.npy` files and manifests of a bundle) and require "a clean error
//! or a valid result, never a panic". A panic anywhere (parser, loader, renderer,
//! reader) fails the property, and proptest shrinks the mutation list to a small case.
//!
//! CI runs 1000-3000 cases per target (9500 in all, well under a minute); a developer runs more
//! with `TSTAT_FUZZ_CASES=20000 TSTAT_FUZZ_SEED=$RANDOM cargo test --release --test fuzz`
//! (docs/hostile-input.md, "Fuzzing"); CI's seed is fixed so its runs are reproducible.

use crate::common::fuzz_runner;

use proptest::prelude::*;
use proptest::test_runner::TestCaseError;
use std::path::{Path, PathBuf};
use tstat::bundle::Bundle;
use tstat::denoise::LoadedSums;
use tstat::render::{render, PixelSampling, RenderSettings};
use tstat::scene::mesh::{load_obj, load_ply};
use tstat::scene::serialized::load_serialized;
use tstat::scene::{Overrides, Scene};
use tstat::stats::Transform;

/// This target's runner (see `common/fuzz_runner.rs`).
fn runner(default_cases: u32) -> proptest::test_runner::TestRunner {
    fuzz_runner::runner(default_cases, 20261202)
}

/// Numbers and words that break parsers and the arithmetic behind them.
const NASTY: &[&str] = &[
    "0",
    "-0",
    "-1",
    "1e39",
    "-1e39",
    "1e308",
    "1e-45",
    "nan",
    "NaN",
    "inf",
    "-inf",
    "4294967296",
    "18446744073709551616",
    "99999999999999999999999",
    "-2147483649",
    "",
    "abc",
    "1,2",
    "0x10",
    "1e",
    "$x",
    "&amp;",
];

/// One edit of a byte string; positions are fractions of its length.
#[derive(Clone, Debug)]
enum Mutation {
    Delete {
        at: f64,
        len: usize,
    },
    Duplicate {
        at: f64,
        len: usize,
        to: f64,
    },
    Insert {
        at: f64,
        bytes: Vec<u8>,
    },
    Flip {
        at: f64,
        bit: u8,
    },
    /// Replace the k-th number (modulo their count) with a nasty token.
    Number {
        k: usize,
        token: usize,
    },
}

fn mutation() -> impl Strategy<Value = Mutation> {
    let at = 0.0..1.0f64;
    prop_oneof![
        (at.clone(), 1..64usize).prop_map(|(at, len)| Mutation::Delete { at, len }),
        (at.clone(), 1..64usize, 0.0..1.0f64).prop_map(|(at, len, to)| Mutation::Duplicate {
            at,
            len,
            to
        }),
        (at.clone(), prop::collection::vec(any::<u8>(), 1..8))
            .prop_map(|(at, bytes)| Mutation::Insert { at, bytes }),
        (at, 0..8u8).prop_map(|(at, bit)| Mutation::Flip { at, bit }),
        (0..10_000usize, 0..NASTY.len()).prop_map(|(k, token)| Mutation::Number { k, token }),
    ]
}

fn pos(at: f64, len: usize) -> usize {
    ((at * len as f64) as usize).min(len)
}

/// Byte ranges of the numeric literals in `b`.
fn numbers(b: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let starts = b[i].is_ascii_digit()
            || (matches!(b[i], b'-' | b'.') && b.get(i + 1).is_some_and(|c| c.is_ascii_digit()));
        if starts {
            let s = i;
            i += 1;
            while i < b.len() && (b[i].is_ascii_digit() || matches!(b[i], b'.' | b'e' | b'E')) {
                i += 1;
            }
            out.push((s, i));
        } else {
            i += 1;
        }
    }
    out
}

fn apply(base: &[u8], muts: &[Mutation]) -> Vec<u8> {
    let mut b = base.to_vec();
    for m in muts {
        let n = b.len();
        match m {
            Mutation::Delete { at, len } => {
                let s = pos(*at, n);
                b.drain(s..(s + len).min(n));
            }
            Mutation::Duplicate { at, len, to } => {
                let s = pos(*at, n);
                let piece = b[s..(s + len).min(n)].to_vec();
                let t = pos(*to, n);
                b.splice(t..t, piece);
            }
            Mutation::Insert { at, bytes } => {
                let s = pos(*at, n);
                b.splice(s..s, bytes.iter().copied());
            }
            Mutation::Flip { at, bit } => {
                if n > 0 {
                    let s = pos(*at, n - 1);
                    b[s] ^= 1 << bit;
                }
            }
            Mutation::Number { k, token } => {
                let nums = numbers(&b);
                if !nums.is_empty() {
                    let (s, e) = nums[k % nums.len()];
                    b.splice(s..e, NASTY[*token].bytes());
                }
            }
        }
    }
    b
}

fn mutations(max: usize) -> impl Strategy<Value = Vec<Mutation>> {
    prop::collection::vec(mutation(), 1..=max)
}

fn repo(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

/// Small film overrides: every mutated scene that loads is also rendered.
fn tiny() -> Overrides {
    Overrides {
        spp: Some(2),
        width: Some(4),
        height: Some(4),
        bins: Some(6),
        max_depth: Some(4),
        ..Default::default()
    }
}

fn render_tiny(scene: &Scene) -> Result<(), TestCaseError> {
    let out = render(
        scene,
        &RenderSettings {
            spp: 2,
            seed: 1,
            transform: Transform::Identity,
            pixel_sampling: PixelSampling::Stratified,
            replicates: 0,
            pixel_spp: None,
        },
        &|_| {},
    );
    prop_assert!(
        out.accum.x1.iter().all(|v| v.is_finite()),
        "a scene that loads renders finite sums"
    );
    Ok(())
}

#[test]
fn mutated_scenes_load_cleanly_or_fail_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    // The bundled scenes, plus a tiny one with a PLY mesh next to it.
    std::fs::write(dir.path().join("quad.ply"), ascii_ply()).unwrap();
    let mesh_scene = std::fs::read_to_string(repo("scenes/cbox.xml"))
        .unwrap()
        .replacen(
            "</scene>",
            r#"<shape type="ply"><string name="filename" value="quad.ply"/></shape></scene>"#,
            1,
        );
    let bases: Vec<Vec<u8>> = ["cbox.xml", "cbox_spheres.xml", "cbox_confocal.xml"]
        .iter()
        .map(|s| std::fs::read(repo(&format!("scenes/{s}"))).unwrap())
        .chain([mesh_scene.into_bytes()])
        .collect();
    let file = dir.path().join("s.xml");
    runner(1000)
        .run(&(0..bases.len(), mutations(4)), |(k, muts)| {
            std::fs::write(&file, apply(&bases[k], &muts)).unwrap();
            match Scene::load(&file, &tiny()) {
                Ok(scene) => render_tiny(&scene)?,
                Err(e) => {
                    let msg = e.to_string();
                    prop_assert!(!msg.is_empty() && !msg.contains('\n'), "{msg:?}");
                }
            }
            Ok(())
        })
        .unwrap();
}

/// A scene that reads one file of each kind beside it: an included XML file, a
/// spectrum (`.spd`), a grid volume (`.vol`), an environment map (PNG), a curve file
/// and a PLY mesh.
const SIDE_SCENE: &str = r#"<scene version="3.0.0">
  <integrator type="transient_prbvolpath"><integer name="max_depth" value="4"/></integrator>
  <include filename="inc.xml"/>
  <sensor type="perspective">
    <transform name="to_world"><lookat origin="0,0,4" target="0,0,0" up="0,1,0"/></transform>
    <film type="transient_hdr_film"><integer name="width" value="4"/><integer name="height" value="4"/>
      <integer name="temporal_bins" value="6"/><float name="bin_width_opl" value="1"/>
      <float name="start_opl" value="2"/></film>
  </sensor>
  <emitter type="envmap"><string name="filename" value="sky.png"/></emitter>
  <emitter type="point"><point name="position" x="0.5" y="0.5" z="2"/><rgb name="intensity" value="5"/></emitter>
  <medium type="heterogeneous" id="fog">
    <volume name="sigma_t" type="gridvolume"><string name="filename" value="grid.vol"/></volume>
  </medium>
  <shape type="cube"><bsdf type="null"/><ref name="interior" id="fog"/></shape>
  <shape type="linearcurve"><string name="filename" value="curve.txt"/></shape>
  <shape type="ply"><string name="filename" value="quad.ply"/></shape>
</scene>"#;

/// The files [`SIDE_SCENE`] reads, valid.
fn side_files() -> Vec<(&'static str, Vec<u8>)> {
    let mut vol = b"VOL\x03".to_vec();
    for v in [1i32, 2, 2, 2, 1] {
        vol.extend(v.to_le_bytes());
    }
    for v in [
        -1f32, -1., -1., 1., 1., 1., 0.5, 1., 0.2, 2., 0., 1., 3., 0.7,
    ] {
        vol.extend(v.to_le_bytes());
    }
    let quad = b"ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n-2 -2 -2\n2 -2 -2\n2 2 -2\n-2 2 -2\n4 0 1 2 3\n";
    vec![
        (
            "inc.xml",
            br#"<scene version="3.0.0"><shape type="sphere"><float name="radius" value="0.3"/><bsdf type="diffuse"><spectrum name="reflectance" filename="r.spd"/></bsdf></shape></scene>"#.to_vec(),
        ),
        ("r.spd", b"# reflectance\n400 0.2\n550 0.6\n700 0.4\n".to_vec()),
        ("grid.vol", vol),
        ("sky.png", std::fs::read(repo("scenes/textures/wall.png")).unwrap()),
        (
            "curve.txt",
            b"0 -1 0 0.05\n0.2 0 0.1 0.05\n0 1 0 0.05\n\n-0.5 0 0 0.02\n0.5 0 0 0.02\n".to_vec(),
        ),
        ("quad.ply", quad.to_vec()),
    ]
}

/// One file a scene reads mutated at a time (the include, the spectrum, the volume,
/// the image, the curve, the mesh): a clean one-line error, or a scene that renders
/// and whose identity covers every file it read.
#[test]
fn mutated_side_files_load_cleanly_or_fail_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let scene_path = dir.path().join("scene.xml");
    std::fs::write(&scene_path, SIDE_SCENE).unwrap();
    let files = side_files();
    let write_all = |mutated: Option<(usize, &[Mutation])>| {
        for (k, (name, bytes)) in files.iter().enumerate() {
            let bytes = match mutated {
                Some((m, muts)) if m == k => apply(bytes, muts),
                _ => bytes.clone(),
            };
            std::fs::write(dir.path().join(name), bytes).unwrap();
        }
    };
    // The base is valid and its identity lists its six files (the scene file's own
    // checksum is recorded beside it).
    write_all(None);
    let scene = Scene::load(&scene_path, &tiny()).unwrap();
    let names: Vec<&str> = scene
        .identity
        .inputs
        .iter()
        .map(|(n, _)| n.as_str())
        .collect();
    let mut want: Vec<&str> = files.iter().map(|(n, _)| *n).collect();
    want.sort();
    assert_eq!(names, want);
    runner(1500)
        .run(&(0..files.len(), mutations(4)), |(k, muts)| {
            write_all(Some((k, &muts)));
            match Scene::load(&scene_path, &tiny()) {
                Ok(scene) => {
                    // A mutated include may stop reading the spectrum.
                    prop_assert!(scene.identity.inputs.len() >= files.len() - 1);
                    render_tiny(&scene)?;
                }
                Err(e) => {
                    let msg = e.to_string();
                    prop_assert!(!msg.is_empty() && !msg.contains('\n'), "{msg:?}");
                }
            }
            Ok(())
        })
        .unwrap();
}

fn ascii_ply() -> Vec<u8> {
    b"ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n".to_vec()
}

fn binary_ply() -> Vec<u8> {
    let mut b = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n".to_vec();
    for v in [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
        for x in v.iter().chain(&[0.0, 0.0, 1.0]) {
            b.extend_from_slice(&x.to_le_bytes());
        }
    }
    b.push(3);
    for i in [0i32, 1, 2] {
        b.extend_from_slice(&i.to_le_bytes());
    }
    b
}

fn obj() -> Vec<u8> {
    b"# quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nvt 0 0\nf 1//1 2//1 3//1\nf 1/1/1 3/1/1 4/1/1\n".to_vec()
}

#[test]
fn mutated_meshes_load_cleanly_or_fail_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let bases = [
        ("m.ply", ascii_ply()),
        ("b.ply", binary_ply()),
        ("m.obj", obj()),
    ];
    runner(3000)
        .run(&(0..bases.len(), mutations(4)), |(k, muts)| {
            let (name, base) = &bases[k];
            let path = dir.path().join(name);
            std::fs::write(&path, apply(base, &muts)).unwrap();
            let loaded = if name.ends_with(".obj") {
                load_obj(&path)
            } else {
                load_ply(&path)
            };
            match loaded {
                Ok(m) => {
                    // A valid result: finite positions, indices in range.
                    prop_assert!(m.positions.iter().all(|p| p.is_finite()));
                    let n = m.positions.len() as u32;
                    prop_assert!(m.triangles.iter().flatten().all(|&i| i < n));
                    if let Some(normals) = &m.normals {
                        prop_assert_eq!(normals.len(), m.positions.len());
                    }
                }
                Err(e) => {
                    let msg = e.to_string();
                    prop_assert!(!msg.is_empty() && !msg.contains('\n'), "{msg:?}");
                }
            }
            Ok(())
        })
        .unwrap();
}

/// zlib-compresses `body`.
fn zlib(body: &[u8]) -> Vec<u8> {
    use std::io::Write;
    let mut e = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
    e.write_all(body).unwrap();
    e.finish().unwrap()
}

/// The decompressed body of a tiny `.serialized` mesh: a version 4 quad (f32 positions,
/// normals, uv, colours), a version 3 triangle in double precision, or a version 5
/// quad (records with normals and uv, a point map, one attribute).
fn serialized_body(version: u16) -> Vec<u8> {
    let mut b = Vec::new();
    let f32s = |b: &mut Vec<u8>, v: &[f32]| v.iter().for_each(|x| b.extend(x.to_le_bytes()));
    let u32s = |b: &mut Vec<u8>, v: &[u32]| v.iter().for_each(|x| b.extend(x.to_le_bytes()));
    let quad = [
        0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0, 0.0,
    ];
    match version {
        3 => {
            b.extend(0x2000u32.to_le_bytes());
            b.extend(3u64.to_le_bytes());
            b.extend(1u64.to_le_bytes());
            for x in [0.0f64, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] {
                b.extend(x.to_le_bytes());
            }
            u32s(&mut b, &[0, 1, 2]);
        }
        4 => {
            b.extend((0x1000u32 | 1 | 2 | 8).to_le_bytes());
            b.extend(b"quad\0");
            b.extend(4u64.to_le_bytes());
            b.extend(2u64.to_le_bytes());
            f32s(&mut b, &quad);
            f32s(&mut b, &[0.0, 0.0, 1.0].repeat(4));
            f32s(&mut b, &[0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0, 1.0]);
            f32s(&mut b, &[0.5; 12]);
            u32s(&mut b, &[0, 1, 2, 0, 2, 3]);
        }
        _ => {
            b.extend((0x1000u32 | 1 | 4).to_le_bytes());
            u32s(&mut b, &[1]);
            b.push(b'q');
            for n in [4u64, 2, 4, 0] {
                b.extend(n.to_le_bytes());
            }
            for v in quad.chunks(3) {
                f32s(&mut b, v);
                f32s(&mut b, &[0.0, 0.0, 1.0, v[0], v[1]]);
            }
            u32s(&mut b, &[0, 1, 2, 0, 0, 2, 3, 0]);
            u32s(&mut b, &[0, 1, 2, 3]);
            u32s(&mut b, &[1, 6]);
            b.extend(b"face_a");
            b.push(0);
            u32s(&mut b, &[1]);
            f32s(&mut b, &[1.0, 2.0]);
        }
    }
    b
}

/// A file of the given bodies (each compressed after the header) and its dictionary.
fn serialized_file(version: u16, bodies: &[Vec<u8>]) -> Vec<u8> {
    let mut f = Vec::new();
    let mut offsets = Vec::new();
    for body in bodies {
        offsets.push(f.len() as u64);
        f.extend(0x041Cu16.to_le_bytes());
        f.extend(version.to_le_bytes());
        f.extend(zlib(body));
    }
    for o in offsets {
        if version == 3 {
            f.extend((o as u32).to_le_bytes());
        } else {
            f.extend(o.to_le_bytes());
        }
    }
    f.extend((bodies.len() as u32).to_le_bytes());
    f
}

/// Mutations of the file bytes (mostly caught by zlib) and of the decompressed bodies
/// (the loader's own checks), at every shape_index up to one past the last mesh.
#[test]
fn mutated_serialized_meshes_load_cleanly_or_fail_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("m.serialized");
    // The bases are valid: both meshes load.
    for version in 3..6u16 {
        let body = serialized_body(version);
        std::fs::write(&path, serialized_file(version, &[body.clone(), body])).unwrap();
        for index in 0..2 {
            let m = load_serialized(&path, index).unwrap().mesh;
            assert_eq!(m.triangles.len(), if version == 3 { 1 } else { 2 });
        }
    }
    runner(2000)
        .run(
            &(3..6u16, any::<bool>(), 0..3u64, mutations(4)),
            |(version, in_body, index, muts)| {
                let body = serialized_body(version);
                let bytes = if in_body {
                    serialized_file(version, &[body.clone(), apply(&body, &muts)])
                } else {
                    apply(&serialized_file(version, &[body.clone(), body]), &muts)
                };
                std::fs::write(&path, bytes).unwrap();
                match load_serialized(&path, index) {
                    Ok(s) => {
                        let m = s.mesh;
                        prop_assert!(m.positions.iter().all(|p| p.is_finite()));
                        let n = m.positions.len() as u32;
                        prop_assert!(m.triangles.iter().flatten().all(|&i| i < n));
                        prop_assert!(!m.triangles.is_empty());
                        for len in [
                            m.normals.as_ref().map(Vec::len),
                            m.uvs.as_ref().map(Vec::len),
                        ]
                        .into_iter()
                        .flatten()
                        {
                            prop_assert_eq!(len, m.positions.len());
                        }
                    }
                    Err(e) => {
                        let msg = e.to_string();
                        prop_assert!(!msg.is_empty() && !msg.contains('\n'), "{msg:?}");
                    }
                }
                Ok(())
            },
        )
        .unwrap();
}

/// A tiny valid bundle, rendered once by the binary.
fn tiny_bundle(dir: &Path) -> PathBuf {
    let out = dir.join("base.tstats");
    let r = std::process::Command::new(env!("CARGO_BIN_EXE_tstat"))
        .args(["render", repo("scenes/cbox.xml").to_str().unwrap(), "--out"])
        .arg(&out)
        .args(["--width", "5", "--height", "4", "--spp", "3", "--bins", "6"])
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    out
}

fn copy_dir(from: &Path, to: &Path) {
    let _ = std::fs::remove_dir_all(to);
    std::fs::create_dir(to).unwrap();
    for e in std::fs::read_dir(from).unwrap().flatten() {
        std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
    }
}

/// Opens a bundle the way `denoise` does; a bundle that opens must give finite volumes.
fn read_bundle(dir: &Path) -> Result<(), TestCaseError> {
    let loaded = Bundle::open(dir).and_then(|b| {
        let sums = LoadedSums::read(&b)?;
        let noisy = b.noisy_mean()?;
        Ok((sums, noisy))
    });
    match loaded {
        Ok((sums, noisy)) => {
            prop_assert!(noisy.iter().all(|v| v.is_finite()), "non-finite noisy mean");
            let d = sums.denoise(&Default::default(), &|_| {});
            prop_assert!(d.volume.iter().all(|v| v.is_finite()), "non-finite output");
        }
        Err(e) => {
            let msg = e.to_string();
            prop_assert!(!msg.is_empty() && !msg.contains('\n'), "{msg:?}");
        }
    }
    Ok(())
}

#[test]
fn mutated_npy_files_are_read_cleanly_or_refused() {
    let dir = tempfile::tempdir().unwrap();
    let base = tiny_bundle(dir.path());
    let arrays: Vec<String> = std::fs::read_dir(&base)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".npy"))
        .collect();
    let work = dir.path().join("case.tstats");
    // Mutations aimed at the header (the first ~128 bytes) and anywhere in the data.
    let header_bias = prop_oneof![
        mutations(3).prop_map(|m| m
            .into_iter()
            .map(|m| match m {
                Mutation::Delete { at, len } => Mutation::Delete { at: at * 0.05, len },
                Mutation::Flip { at, bit } => Mutation::Flip { at: at * 0.05, bit },
                Mutation::Insert { at, bytes } => Mutation::Insert {
                    at: at * 0.05,
                    bytes
                },
                other => other,
            })
            .collect::<Vec<_>>()),
        mutations(3),
    ];
    runner(1000)
        .run(&(0..arrays.len(), header_bias), |(k, muts)| {
            copy_dir(&base, &work);
            let path = work.join(&arrays[k]);
            let bytes = std::fs::read(&path).unwrap();
            std::fs::write(&path, apply(&bytes, &muts)).unwrap();
            read_bundle(&work)
        })
        .unwrap();
}

/// Every JSON pointer of a value (objects and arrays, recursively).
fn pointers(v: &serde_json::Value, at: String, out: &mut Vec<String>) {
    match v {
        serde_json::Value::Object(m) => {
            for (k, x) in m {
                let p = format!("{at}/{}", k.replace('~', "~0").replace('/', "~1"));
                out.push(p.clone());
                pointers(x, p, out);
            }
        }
        serde_json::Value::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                let p = format!("{at}/{i}");
                out.push(p.clone());
                pointers(x, p, out);
            }
        }
        _ => {}
    }
}

#[test]
fn mutated_manifests_are_read_cleanly_or_refused() {
    use serde_json::{json, Value};
    let dir = tempfile::tempdir().unwrap();
    let base = tiny_bundle(dir.path());
    let manifest: Value =
        serde_json::from_str(&std::fs::read_to_string(base.join("manifest.json")).unwrap())
            .unwrap();
    let mut paths = Vec::new();
    pointers(&manifest, String::new(), &mut paths);
    let values = [
        json!(null),
        json!(0),
        json!(-1),
        json!(1e300),
        json!(-1e300),
        json!(u64::MAX),
        json!(0.5),
        json!(""),
        json!("../../etc/passwd"),
        json!("/dev/zero"),
        json!("x3.npy"),
        json!([]),
        json!({}),
        json!(true),
        json!(4_000_000_000u64),
    ];
    let work = dir.path().join("case.tstats");
    runner(1000)
        .run(
            &prop::collection::vec((0..paths.len(), 0..values.len() + 1), 1..4),
            |edits| {
                copy_dir(&base, &work);
                let mut m = manifest.clone();
                for (p, v) in edits {
                    let (parent, key) = paths[p].rsplit_once('/').unwrap();
                    match (m.pointer_mut(parent), values.get(v)) {
                        (Some(Value::Object(o)), None) => {
                            o.remove(key);
                        }
                        (Some(Value::Object(o)), Some(v)) => {
                            o.insert(key.replace("~1", "/").replace("~0", "~"), v.clone());
                        }
                        (Some(Value::Array(a)), Some(v)) => {
                            if let Ok(i) = key.parse::<usize>() {
                                if i < a.len() {
                                    a[i] = v.clone();
                                }
                            }
                        }
                        _ => {}
                    }
                }
                std::fs::write(work.join("manifest.json"), m.to_string()).unwrap();
                read_bundle(&work)
            },
        )
        .unwrap();
}
