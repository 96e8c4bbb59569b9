//! Helpers shared by the integration tests (`crate::common`), with the hostile-input
//! and fuzz runners.
#![allow(dead_code)]

pub mod fuzz_runner;
pub mod hostile;

use tstat::render::{render, PixelSampling, RenderOutput, RenderSettings};
use tstat::scene::{Overrides, Scene};
use tstat::stats::Transform;

/// OPL counted from the camera's origin (`--time-origin pinhole`), for closed forms
/// written from the pinhole; the default origin is the near-clip plane.
pub const PINHOLE: Overrides = Overrides {
    defaults: Vec::new(),
    spp: None,
    width: None,
    height: None,
    bins: None,
    start_opl: None,
    bin_width_opl: None,
    max_depth: None,
    time_origin: Some(tstat::sensors::time_origin::TimeOrigin::Pinhole),
    search_paths: Vec::new(),
    mode: tstat::scene::mode::RenderMode::Rgb,
};

/// Loads a scene written as XML text (from a temporary folder).
pub fn load(xml: &str, overrides: &Overrides) -> Scene {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("scene.xml");
    std::fs::write(&path, xml).unwrap();
    Scene::load(&path, overrides).unwrap()
}

/// The path of the bundled scene `scenes/NAME`.
pub fn bundled_path(name: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name)
}

/// Loads the bundled scene `scenes/NAME` with `overrides`.
pub fn bundled(name: &str, overrides: &Overrides) -> Scene {
    Scene::load(&bundled_path(name), overrides).unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// The error loading the bundled scene `scenes/NAME` with `overrides` gives (it must
/// give one).
pub fn bundled_error(name: &str, overrides: &Overrides) -> String {
    Scene::load(&bundled_path(name), overrides)
        .err()
        .unwrap_or_else(|| panic!("{name} loaded"))
        .to_string()
}

/// Runs the `tstat` binary with `args`.
pub fn tstat(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_tstat"))
        .args(args)
        .output()
        .unwrap()
}

/// Renders in memory with i.i.d. samples (what the statistics assume) and `seed`.
pub fn run(scene: &Scene, seed: u64) -> RenderOutput {
    run_spp(scene, scene.spp, seed)
}

/// [`run`] with `spp` samples per pixel.
/// `f` run in a pool of `threads` threads (same seed, same bits checks).
pub fn on_threads<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(f)
}

pub fn run_spp(scene: &Scene, spp: u32, seed: u64) -> RenderOutput {
    let settings = RenderSettings {
        spp,
        seed,
        transform: Transform::Identity,
        pixel_sampling: PixelSampling::Independent,
        replicates: 0,
        pixel_spp: None,
    };
    render(scene, &settings, &|_| {})
}

/// The JSON data block of a `tstat view` page.
pub fn page_data(page: &str) -> serde_json::Value {
    let start = page
        .find(r#"<script id="data" type="application/json">"#)
        .unwrap();
    let rest = &page[start..];
    let body = &rest[rest.find('>').unwrap() + 1..rest.find("</script>").unwrap()];
    assert!(!body.contains('<'), "a < inside the data block");
    serde_json::from_str(body).unwrap()
}
