//! Small y-tal HDF5 captures for the hostile-input and fuzz tests of the capture
//! reader (`tests/it/hostile_tal.rs`, `tests/it/fuzz_tal.rs`): a capture as a list of
//! datasets that a test edits (values, shapes, storage) before writing it with
//! hdf5-pure's `FileBuilder`, and byte patches for what the builder refuses to write
//! (declared shapes that do not match the data).

#![allow(dead_code)]

use hdf5_pure::FileBuilder;
use std::path::{Path, PathBuf};

pub fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/tal")
        .join(name)
}

/// The values every fixture's H holds (scripts/make_tal_fixtures.py): (16, 4, 4).
pub fn fixture_h() -> Vec<f32> {
    std::fs::read(fixture("h_values.f32"))
        .unwrap()
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect()
}

#[derive(Clone, Debug)]
pub enum Values {
    F32(Vec<f32>),
    F64(Vec<f64>),
    I32(Vec<i32>),
    Strings(Vec<String>),
}

#[derive(Clone, Debug)]
pub struct Ds {
    pub name: String,
    pub values: Values,
    pub shape: Vec<u64>,
    pub chunks: Option<Vec<u64>>,
    pub deflate: bool,
    pub shuffle: bool,
}

fn ds(name: &str, values: Values, shape: &[u64]) -> Ds {
    Ds {
        name: name.into(),
        values,
        shape: shape.to_vec(),
        chunks: None,
        deflate: false,
        shuffle: false,
    }
}

/// A confocal T_Sx_Sy capture of `bins` bins on an `n` x `n` grid of 0.1 spacing,
/// H = 0.01 (t + s) + 0.001, as y-tal lays it out.
pub fn capture(bins: usize, n: usize) -> Vec<Ds> {
    let h: Vec<f32> = (0..bins * n * n)
        .map(|k| 0.01 * ((k / (n * n)) + k % (n * n)) as f32 + 0.001)
        .collect();
    let mut grid = Vec::new();
    let mut normals = Vec::new();
    for i in 0..n {
        for j in 0..n {
            grid.extend([0.1 * i as f32, 0.1 * j as f32, 0.0]);
            normals.extend([0.0, 0.0, 1.0]);
        }
    }
    let (b, n) = (bins as u64, n as u64);
    vec![
        ds("H", Values::F32(h), &[b, n, n]),
        ds("H_format", Values::I32(vec![1]), &[]),
        ds("sensor_grid_xyz", Values::F32(grid.clone()), &[n, n, 3]),
        ds(
            "sensor_grid_normals",
            Values::F32(normals.clone()),
            &[n, n, 3],
        ),
        ds("laser_grid_xyz", Values::F32(grid), &[n, n, 3]),
        ds("laser_grid_normals", Values::F32(normals), &[n, n, 3]),
        ds("sensor_xyz", Values::F32(vec![0.0, 0.0, 1.0]), &[3]),
        ds("laser_xyz", Values::F32(vec![0.0, 0.0, 1.0]), &[3]),
        ds("delta_t", Values::F64(vec![0.05]), &[]),
        ds("t_start", Values::F64(vec![0.5]), &[]),
        ds(
            "t_accounts_first_and_last_bounces",
            Values::I32(vec![0]),
            &[],
        ),
    ]
}

pub fn get<'a>(c: &'a mut [Ds], name: &str) -> &'a mut Ds {
    c.iter_mut()
        .find(|d| d.name == name)
        .expect("a dataset of the capture")
}

/// Sets the f32 or f64 value `k` of `name`.
pub fn set(c: &mut [Ds], name: &str, k: usize, v: f64) {
    match &mut get(c, name).values {
        Values::F32(x) => x[k] = v as f32,
        Values::F64(x) => x[k] = v,
        Values::I32(x) => x[k] = v as i32,
        Values::Strings(_) => panic!("{name} holds strings"),
    }
}

pub fn remove(c: &mut Vec<Ds>, name: &str) {
    c.retain(|d| d.name != name);
}

pub fn bytes(c: &[Ds]) -> Vec<u8> {
    let mut b = FileBuilder::new();
    for d in c {
        let x = b.create_dataset(&d.name);
        match &d.values {
            Values::F32(v) => x.with_f32_data(v),
            Values::F64(v) => x.with_f64_data(v),
            Values::I32(v) => x.with_i32_data(v),
            Values::Strings(v) => {
                let v: Vec<&str> = v.iter().map(|s| s.as_str()).collect();
                x.with_vlen_strings(&v)
            }
        };
        x.with_shape(&d.shape);
        if let Some(ch) = &d.chunks {
            x.with_chunks(ch);
        }
        if d.shuffle {
            x.with_shuffle();
        }
        if d.deflate {
            x.with_deflate(6);
        }
    }
    b.finish().expect("a valid capture")
}

pub fn write(path: &Path, c: &[Ds]) {
    std::fs::write(path, bytes(c)).unwrap();
}

fn le64(v: &[u64]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

fn le32(v: &[u32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// Replaces every occurrence of `from` by `to` (same length); the count replaced.
pub fn replace(b: &mut [u8], from: &[u8], to: &[u8]) -> usize {
    assert_eq!(from.len(), to.len());
    let mut n = 0;
    let mut i = 0;
    while i + from.len() <= b.len() {
        if &b[i..i + from.len()] == from {
            b[i..i + from.len()].copy_from_slice(to);
            n += 1;
            i += from.len();
        } else {
            i += 1;
        }
    }
    n
}

/// A dataspace's dimensions (u64 LE, as every writer here stores them) patched.
pub fn patch_dims(b: &mut [u8], from: &[u64], to: &[u64]) -> usize {
    replace(b, &le64(from), &le64(to))
}

/// A chunked layout message's chunk dimensions (u32 LE, the element size last).
pub fn patch_chunk_dims(b: &mut [u8], from: &[u32], to: &[u32]) -> usize {
    replace(b, &le32(from), &le32(to))
}
