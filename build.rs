//! Computes the RGB-to-spectrum table of the spectral mode (`src/spectral/rgb2spec.rs`)
//! once, when the crate is built, with the same code the crate runs
//! (`src/spectral/rgb2spec_fit.rs` on `src/spectral/cie.rs`), and writes it to
//! `OUT_DIR/srgb_coeff.bin`, which the crate embeds: 3 x 64^3 nodes of 3 little-endian
//! f32 (9.4 MB), about 25 s of CPU spread over the build machine's cores. Nothing is
//! downloaded. The tests compare columns computed afresh against the embedded ones.

#[allow(dead_code)]
#[path = "src/spectral/cie.rs"]
mod cie;
#[allow(dead_code)]
#[path = "src/spectral/rgb2spec_fit.rs"]
mod rgb2spec_fit;

use rgb2spec_fit::{scale_axis, solve_column, Forward, RES};

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=src/spectral/cie.rs");
    println!("cargo:rerun-if-changed=src/spectral/rgb2spec_fit.rs");
    let out = std::path::PathBuf::from(std::env::var_os("OUT_DIR").expect("OUT_DIR"));
    let forward = Forward::new();
    let scale = scale_axis();
    let columns = 3 * RES * RES;
    let threads = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(columns);
    // Column c = (l RES + j) RES + i; each thread takes every threads-th column.
    let mut solved: Vec<Vec<(usize, [[f32; 3]; RES])>> = Vec::new();
    std::thread::scope(|s| {
        let handles: Vec<_> = (0..threads)
            .map(|t| {
                let (forward, scale) = (&forward, &scale);
                s.spawn(move || {
                    (t..columns)
                        .step_by(threads)
                        .map(|c| {
                            let (l, j, i) = (c / (RES * RES), (c / RES) % RES, c % RES);
                            (c, solve_column(forward, scale, l, j, i))
                        })
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        solved = handles
            .into_iter()
            .map(|h| h.join().expect("a table thread"))
            .collect();
    });
    let mut bytes = vec![0u8; columns * RES * 12];
    for (c, column) in solved.into_iter().flatten() {
        let (l, j, i) = (c / (RES * RES), (c / RES) % RES, c % RES);
        for (k, node) in column.iter().enumerate() {
            let at = (((l * RES + k) * RES + j) * RES + i) * 12;
            for (n, v) in node.iter().enumerate() {
                bytes[at + 4 * n..at + 4 * n + 4].copy_from_slice(&v.to_le_bytes());
            }
        }
    }
    let tmp = out.join("srgb_coeff.bin.tmp");
    std::fs::write(&tmp, &bytes).expect("writing the table");
    std::fs::rename(&tmp, out.join("srgb_coeff.bin")).expect("renaming the table");
}
