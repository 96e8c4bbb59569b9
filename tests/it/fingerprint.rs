//! `Scene::fingerprint` (the key of every scene-keyed cache) changes with everything the
//! image depends on (the scene's bytes, a volume grid, an included file, a texture, the
//! camera, a `-D` value, a film override) and with nothing else (same inputs, same key;
//! the scene's folder moved: same key), and `report convergence` reuses its cached
//! reference exactly when the key is unchanged.

use std::path::Path;
use tstat::denoise::DenoiseParams;
use tstat::render::PixelSampling;
use tstat::report::convergence::{run_convergence, ConvergenceConfig, ReferenceSource};
use tstat::scene::{Overrides, Scene};
use tstat::stats::Transform;

fn f32s(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// A Mitsuba `.vol` (version 3, float32, one channel) over the unit cube.
fn vol(n: i32, value: f32) -> Vec<u8> {
    let mut b = b"VOL\x03".to_vec();
    for v in [1, n, n, n, 1] {
        b.extend(v.to_le_bytes());
    }
    b.extend(f32s(&[-1.0, -1.0, -1.0, 1.0, 1.0, 1.0]));
    b.extend(f32s(&vec![value; (n * n * n) as usize]));
    b
}

const SCENE: &str = r#"<scene version="3.0.0">
    <default name="r" value="1"/>
    <integrator type="transient_prbvolpath"/>
    <sensor type="perspective">
        <float name="fov" value="FOV"/>
        <transform name="to_world"><lookat origin="0,0,4" target="0,0,0" up="0,1,0"/></transform>
        <film type="transient_hdr_film">
            <integer name="width" value="8"/><integer name="height" value="8"/>
            <integer name="temporal_bins" value="4"/><float name="bin_width_opl" value="1"/>
        </film>
    </sensor>
    <include filename="light.xml"/>
    <shape type="sphere">
        <float name="radius" value="$r"/>
        <bsdf type="null"/>
        <medium type="heterogeneous" name="interior">
            <volume name="sigma_t" type="gridvolume"><string name="filename" value="g.vol"/></volume>
        </medium>
    </shape>
    <shape type="rectangle">
        <transform name="to_world"><translate z="-2"/></transform>
        <bsdf type="diffuse"><texture name="reflectance" type="bitmap"><string name="filename" value="t.png"/></texture></bsdf>
    </shape>
</scene>
"#;

const LIGHT: &str = r#"<shape type="rectangle"><transform name="to_world"><translate z="3"/></transform><emitter type="area"><rgb name="radiance" value="1"/></emitter></shape>"#;

fn png(value: u8) -> Vec<u8> {
    let mut out = Vec::new();
    let img = image::RgbImage::from_pixel(2, 2, image::Rgb([value, value, value]));
    img.write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png)
        .unwrap();
    out
}

fn write_case(dir: &Path, fov: &str, grid: f32, light: &str, tex: u8) {
    std::fs::write(dir.join("scene.xml"), SCENE.replace("FOV", fov)).unwrap();
    std::fs::write(dir.join("g.vol"), vol(2, grid)).unwrap();
    std::fs::write(dir.join("light.xml"), light).unwrap();
    std::fs::write(dir.join("t.png"), png(tex)).unwrap();
}

fn key(dir: &Path, overrides: &Overrides) -> String {
    Scene::load(&dir.join("scene.xml"), overrides)
        .unwrap()
        .fingerprint()
}

#[test]
fn the_fingerprint_follows_everything_the_image_depends_on() {
    let d = tempfile::tempdir().unwrap();
    let dir = d.path();
    let none = Overrides::default();
    write_case(dir, "40", 1.0, LIGHT, 128);
    let base = key(dir, &none);
    assert_eq!(base.len(), 64);
    assert_eq!(key(dir, &none), base, "same inputs, same key");
    // The same files in another folder: the same key.
    let other = tempfile::tempdir().unwrap();
    write_case(other.path(), "40", 1.0, LIGHT, 128);
    assert_eq!(key(other.path(), &none), base, "moved folder");

    let mut seen = vec![base.clone()];
    let mut changed = |what: &str, k: String| {
        assert!(!seen.contains(&k), "{what}: the key did not change");
        seen.push(k);
    };
    write_case(dir, "41", 1.0, LIGHT, 128);
    changed("camera fov", key(dir, &none));
    write_case(dir, "40", 2.0, LIGHT, 128);
    changed("volume grid", key(dir, &none));
    write_case(
        dir,
        "40",
        1.0,
        &LIGHT.replace("value=\"1\"", "value=\"2\""),
        128,
    );
    changed("included file", key(dir, &none));
    write_case(dir, "40", 1.0, LIGHT, 129);
    changed("texture", key(dir, &none));
    write_case(dir, "40", 1.0, LIGHT, 128);
    assert_eq!(key(dir, &none), base, "back to the first inputs");
    let define = Overrides {
        defaults: vec![("r".into(), "0.9".into())],
        ..Overrides::default()
    };
    changed("-D r=0.9", key(dir, &define));
    let wider = Overrides {
        width: Some(9),
        ..Overrides::default()
    };
    changed("--width 9", key(dir, &wider));
    let deeper = Overrides {
        max_depth: Some(3),
        ..Overrides::default()
    };
    changed("--max-depth 3", key(dir, &deeper));
}

/// The render mode is part of the key: a spectral render has RGB's three channels
/// (the film alone does not tell them apart), and `report convergence --mode spectral`
/// must not reuse an RGB reference. Every mode has its own key.
#[test]
fn the_fingerprint_follows_the_render_mode() {
    use tstat::scene::mode::RenderMode;
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cbox.xml");
    let keys: Vec<String> = [
        RenderMode::Rgb,
        RenderMode::Spectral,
        RenderMode::Mono,
        RenderMode::MonoPolarized,
    ]
    .into_iter()
    .map(|mode| {
        let o = Overrides {
            mode,
            ..Overrides::default()
        };
        Scene::load(&path, &o).unwrap().fingerprint()
    })
    .collect();
    for i in 0..keys.len() {
        for j in 0..i {
            assert_ne!(keys[i], keys[j], "modes {i} and {j} share a key");
        }
    }
}

/// `report convergence` keys its cached reference by the fingerprint: a second run
/// reuses it; a changed `.vol` grid or camera renders a new one (then the first inputs
/// find theirs again).
#[test]
fn a_changed_volume_or_camera_invalidates_the_cached_reference() {
    let d = tempfile::tempdir().unwrap();
    let dir = d.path();
    let cache = tempfile::tempdir().unwrap();
    let cfg = ConvergenceConfig {
        scene: dir.join("scene.xml"),
        overrides: Overrides {
            width: Some(6),
            height: Some(6),
            bins: Some(4),
            ..Overrides::default()
        },
        spp_list: vec![2],
        seed: 1,
        transform: Transform::Identity,
        pixel_sampling: PixelSampling::Independent,
        replicates: 0,
        denoise: DenoiseParams::default(),
        method_radii: true,
        radius_chosen: false,
        depth_align_asked: false,
        adaptive: false,
        nlos: None,
        base_by_scene: false,
        reference: ReferenceSource::Render { spp: 4 },
    };
    let note = || {
        run_convergence(&cfg, cache.path(), &|_| {})
            .unwrap()
            .reference_note
    };
    // "N spp render, T s (cached as PATH)" when rendered, "N spp render (cached PATH)"
    // when reused.
    let rendered = |n: &str| n.contains("render, ") && n.contains("(cached as ");
    let reused = |n: &str| n.contains("render (cached ") && !n.contains("cached as ");
    let path = |n: &str| {
        n.rsplit(' ')
            .next()
            .unwrap()
            .trim_end_matches(')')
            .to_string()
    };

    write_case(dir, "40", 1.0, LIGHT, 128);
    let n = note();
    assert!(rendered(&n), "first run: {n}");
    let first = path(&n);
    let n = note();
    assert!(reused(&n), "same inputs: {n}");
    assert_eq!(path(&n), first);
    write_case(dir, "40", 2.0, LIGHT, 128);
    let n = note();
    assert!(rendered(&n), "changed .vol grid: {n}");
    write_case(dir, "41", 2.0, LIGHT, 128);
    let n = note();
    assert!(rendered(&n), "changed camera: {n}");
    write_case(dir, "40", 1.0, LIGHT, 128);
    let n = note();
    assert!(reused(&n), "the first inputs again: {n}");
    assert_eq!(path(&n), first);
}
