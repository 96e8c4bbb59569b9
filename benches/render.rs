//! Render benchmarks, statistics on, 300 bins:
//!
//! - `render_cbox_64x64_16spp_300bins`: cbox with the identity and Box-Cox transforms;
//! - `render_scenes_32x32_32spp_300bins`: one bench per scene, cbox, cbox_spheres, bunny,
//!   the dense displaced sphere (>= 1M triangles, generated into a temporary directory
//!   by `common/dense_scene.rs`), cbox_fog (the volumetric tracer) and cbox_materials
//!   (every surface model), throughput in paths;
//! - `render_isa_32x32_32spp_300bins`: cbox and bunny with the tracer forced to each
//!   instruction set the CPU has (baseline, AVX2, AVX-512).
//!
//! Scene loading and the dense scene's generation are outside the timed loop.
//! `cargo bench --bench render` takes about a minute on 2 cores. Run as a test
//! (`cargo test --benches`, criterion runs each bench once) the dense mesh has about
//! 20k triangles instead, so that is quick.

#[path = "common/dense_scene.rs"]
mod dense_scene;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use std::path::{Path, PathBuf};
use std::time::Duration;
use tstat::cpu::{self, Isa};
use tstat::render::{render, PixelSampling, RenderSettings};
use tstat::scene::{Overrides, Scene};
use tstat::stats::Transform;

fn scene_path(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name)
}

fn settings(scene: &Scene, transform: Transform) -> RenderSettings {
    RenderSettings {
        spp: scene.spp,
        seed: 1,
        transform,
        pixel_sampling: PixelSampling::default(),
        replicates: 0,
        pixel_spp: None,
    }
}

fn bench_transforms(c: &mut Criterion) {
    let overrides = Overrides {
        width: Some(64),
        spp: Some(16),
        ..Default::default()
    };
    let scene = Scene::load(&scene_path("cbox.xml"), &overrides).expect("cbox loads");
    let mut group = c.benchmark_group("render_cbox_64x64_16spp_300bins");
    group.sample_size(10);
    for (name, transform) in [
        ("identity", Transform::Identity),
        ("box-cox-0.5", Transform::BoxCox { lambda: 0.5 }),
    ] {
        let settings = settings(&scene, transform);
        group.bench_function(name, |b| b.iter(|| render(&scene, &settings, &|_| {})));
    }
    group.finish();
}

fn bench_scenes(c: &mut Criterion) {
    // `cargo bench` passes --bench; a test run (no flag) renders each bench once, so
    // it gets a small dense mesh.
    let benchmarking = std::env::args().any(|a| a == "--bench");
    let dir = tempfile::tempdir().expect("a temporary directory");
    let dense =
        dense_scene::write_dense_scene(dir.path(), if benchmarking { 1_000_000 } else { 20_000 })
            .expect("the dense scene is written");
    let scenes = [
        ("cbox".to_string(), scene_path("cbox.xml")),
        ("cbox_spheres".to_string(), scene_path("cbox_spheres.xml")),
        ("bunny".to_string(), scene_path("bunny.xml")),
        (format!("dense_{}tris", dense.triangles), dense.xml),
        ("cbox_fog".to_string(), scene_path("cbox_fog.xml")),
        (
            "cbox_materials".to_string(),
            scene_path("cbox_materials.xml"),
        ),
    ];
    // Small film, more samples: tracing dominates, not zeroing the accumulators.
    let overrides = Overrides {
        width: Some(32),
        spp: Some(32),
        ..Default::default()
    };
    let mut group = c.benchmark_group("render_scenes_32x32_32spp_300bins");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(4));
    for (name, path) in &scenes {
        let scene = Scene::load(path, &overrides).unwrap_or_else(|e| panic!("{name}: {e}"));
        let settings = settings(&scene, Transform::Identity);
        // Rays per path (closest-hit and shadow rays), the same in every run: the
        // throughput below is paths/s, times this is rays/s.
        let once = render(&scene, &settings, &|_| {});
        eprintln!(
            "{name}: {:.3} rays per path",
            once.rays as f64 / once.paths as f64
        );
        group.throughput(Throughput::Elements(
            scene.film.pixels() as u64 * scene.spp as u64,
        ));
        group.bench_function(name, |b| b.iter(|| render(&scene, &settings, &|_| {})));
    }
    group.finish();
}

/// The same render at each instruction-set level this CPU has (`cpu`): what the
/// run-time dispatch buys. Every level computes the same bits (tests/it/isa.rs).
fn bench_isa(c: &mut Criterion) {
    let overrides = Overrides {
        width: Some(32),
        spp: Some(32),
        ..Default::default()
    };
    let mut group = c.benchmark_group("render_isa_32x32_32spp_300bins");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(4));
    for name in ["cbox.xml", "bunny.xml"] {
        let scene = Scene::load(&scene_path(name), &overrides).expect("scene loads");
        let settings = settings(&scene, Transform::Identity);
        group.throughput(Throughput::Elements(
            scene.film.pixels() as u64 * scene.spp as u64,
        ));
        for isa in [Isa::Baseline, Isa::Avx2, Isa::Avx512] {
            if !isa.supported() {
                continue;
            }
            cpu::force(isa).expect("supported");
            let id = format!("{}/{}", name.trim_end_matches(".xml"), isa.name());
            group.bench_function(id, |b| b.iter(|| render(&scene, &settings, &|_| {})));
        }
    }
    cpu::force(Isa::best()).expect("supported");
    group.finish();
}

criterion_group!(benches, bench_transforms, bench_scenes, bench_isa);
criterion_main!(benches);
