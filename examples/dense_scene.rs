//! Writes the dense benchmark scene (a displaced sphere of >= 1M triangles in the Cornell
//! box) into a directory, for `scripts/compare_mitransient.py` or by hand:
//!
//! ```sh
//! cargo run --release --example dense_scene -- OUT_DIR [TRIANGLES]
//! ```
//!
//! TRIANGLES (default 1000000) is a lower bound: the mesh has the smallest `20 n^2` at
//! or above it. Prints the scene XML's path.

#[path = "../benches/common/dense_scene.rs"]
mod dense_scene;

use std::path::PathBuf;
use std::process::ExitCode;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: dense_scene OUT_DIR [TRIANGLES]";
    let (dir, triangles) = match args.as_slice() {
        [dir] => (PathBuf::from(dir), Ok(1_000_000)),
        [dir, t] => (PathBuf::from(dir), t.parse::<usize>()),
        _ => {
            eprintln!("{usage}");
            return ExitCode::from(2);
        }
    };
    let triangles = match triangles {
        Ok(t) if (1..=200_000_000).contains(&t) => t,
        _ => {
            eprintln!("error: TRIANGLES must be an integer in 1..=200000000\n{usage}");
            return ExitCode::from(2);
        }
    };
    if let Err(e) = std::fs::create_dir_all(&dir) {
        eprintln!("error: cannot create {}: {e}", dir.display());
        return ExitCode::FAILURE;
    }
    match dense_scene::write_dense_scene(&dir, triangles) {
        Ok(scene) => {
            eprintln!("{} triangles", scene.triangles);
            println!("{}", scene.xml.display());
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: writing the scene into {}: {e}", dir.display());
            ExitCode::FAILURE
        }
    }
}
