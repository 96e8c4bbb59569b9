//! Prints what tstat reads from Mitsuba `.serialized` files: per mesh, its version,
//! name, vertex and triangle counts and which attributes it has.
//! Usage: `serialized_info FILE...` (every mesh of the file, through its dictionary);
//! meshes of at most 8 vertices also print each vertex (position, normal, uv).

use tstat::scene::serialized::load_serialized;

fn main() {
    let mut failed = false;
    for arg in std::env::args().skip(1) {
        let path = std::path::Path::new(&arg);
        let mut index = 0;
        loop {
            match load_serialized(path, index) {
                Ok(m) => {
                    println!(
                        "{arg}@{index}: version {}, '{}', {} vertices, {} triangles, normals {}, uvs {}",
                        m.version,
                        m.name,
                        m.mesh.positions.len(),
                        m.mesh.triangles.len(),
                        m.mesh.normals.is_some(),
                        m.mesh.uvs.is_some()
                    );
                    let m = m.mesh;
                    if m.positions.len() <= 8 {
                        for (i, p) in m.positions.iter().enumerate() {
                            let n = m.normals.as_ref().map(|n| n[i]);
                            let uv = m.uvs.as_ref().map(|u| u[i]);
                            println!("  vertex {i}: position {p}, normal {n:?}, uv {uv:?}");
                        }
                        println!("  triangles {:?}", m.triangles);
                    }
                }
                Err(e) => {
                    // Past the last mesh (or a file without a dictionary) after mesh 0.
                    let end = index > 0 && e.to_string().contains("shape_index");
                    if !end {
                        println!("{arg}@{index}: error: {e}");
                        failed = true;
                    }
                    break;
                }
            }
            index += 1;
        }
    }
    if failed {
        std::process::exit(1);
    }
}
