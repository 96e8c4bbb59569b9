//! The dense benchmark scene's generator (`benches/common/dense_scene.rs`), on a small
//! mesh: the triangle count it promises, a closed and consistently outward mesh with
//! shared vertices, and a scene that loads and renders.

#[path = "../../benches/common/dense_scene.rs"]
mod generator;

use std::collections::HashSet;
use tstat::render::{render, PixelSampling, RenderSettings};
use tstat::scene::mesh::load_ply;
use tstat::scene::{Overrides, Scene};
use tstat::stats::Transform;

#[test]
fn dense_scene_is_a_closed_outward_mesh_that_renders() {
    let dir = tempfile::tempdir().unwrap();
    // 20 n^2 >= 1000: n = 8, 1280 triangles, 10 n^2 + 2 vertices.
    let scene = generator::write_dense_scene(dir.path(), 1000).unwrap();
    assert_eq!(scene.triangles, 1280);
    let mesh = load_ply(&dir.path().join("dense_sphere.ply")).unwrap();
    assert_eq!(mesh.triangles.len(), 1280);
    assert_eq!(mesh.positions.len(), 642);

    // Closed and consistently wound: every directed edge once, its reverse present.
    let edges: HashSet<(u32, u32)> = mesh
        .triangles
        .iter()
        .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
        .collect();
    assert_eq!(edges.len(), 3 * 1280);
    assert!(edges.iter().all(|&(a, b)| edges.contains(&(b, a))));
    // Outward: positive signed volume about the centre, close to the undisplaced
    // sphere's (radius 0.48; the displacement averages out to within a few per cent).
    let c = glam::Vec3::new(0.0, -0.42, 0.05);
    let volume: f32 = mesh
        .triangles
        .iter()
        .map(|t| {
            let [a, b, d] = t.map(|i| mesh.positions[i as usize] - c);
            a.dot(b.cross(d)) / 6.0
        })
        .sum();
    let sphere = 4.0 / 3.0 * std::f32::consts::PI * 0.48f32.powi(3);
    assert!((volume / sphere - 1.0).abs() < 0.05, "{volume} vs {sphere}");

    let loaded = Scene::load(
        &scene.xml,
        &Overrides {
            width: Some(16),
            spp: Some(4),
            bins: Some(20),
            bin_width_opl: Some(0.5),
            ..Default::default()
        },
    )
    .unwrap();
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    // The room of cbox.xml (6 rectangles of 2 triangles) plus the mesh.
    assert_eq!(loaded.accel.primitive_count(), 12 + 1280);
    let settings = RenderSettings {
        spp: loaded.spp,
        seed: 1,
        transform: Transform::Identity,
        pixel_sampling: PixelSampling::default(),
        replicates: 0,
        pixel_spp: None,
    };
    let out = render(&loaded, &settings, &|_| {});
    assert!(out.steady.iter().all(|v| v.is_finite()));
    assert!(out.steady.iter().sum::<f64>() > 0.0);
}
