//! The cbox scene at 64x64, 16 spp, 300 bins, statistics on (identity and Box-Cox).

use criterion::{criterion_group, criterion_main, Criterion};
use std::path::Path;
use tstat::render::{render, PixelSampling, RenderSettings};
use tstat::scene::{Overrides, Scene};
use tstat::stats::Transform;

fn bench_render(c: &mut Criterion) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cbox.xml");
    let overrides = Overrides {
        width: Some(64),
        spp: Some(16),
        ..Default::default()
    };
    let scene = Scene::load(&path, &overrides).expect("cbox loads");
    let mut group = c.benchmark_group("render_cbox_64x64_16spp_300bins");
    group.sample_size(10);
    for (name, transform) in [
        ("identity", Transform::Identity),
        ("box-cox-0.5", Transform::BoxCox { lambda: 0.5 }),
    ] {
        let settings = RenderSettings {
            spp: scene.spp,
            seed: 1,
            transform,
            pixel_sampling: PixelSampling::default(),
        };
        group.bench_function(name, |b| b.iter(|| render(&scene, &settings, &|_| {})));
    }
    group.finish();
}

criterion_group!(benches, bench_render);
criterion_main!(benches);
