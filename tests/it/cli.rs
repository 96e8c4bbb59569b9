//! The real binary on real files: bundled scenes, determinism across thread counts,
//! and one clear error (non-zero exit, nothing written) for every kind of bad input.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn tstat(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_tstat"))
        .args(args)
        .output()
        .unwrap()
}

fn scene(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name)
        .display()
        .to_string()
}

fn s(p: &Path) -> String {
    p.display().to_string()
}

const SMALL: &[&str] = &["--width", "12", "--spp", "4", "--bins", "20"];

#[test]
fn every_bundled_scene_renders_denoises_exports_and_prints_info() {
    let dir = tempfile::tempdir().unwrap();
    // Every scene in scenes/ (the materials, delay and texture scenes included).
    let scenes_dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut names: Vec<String> = std::fs::read_dir(&scenes_dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".xml"))
        .collect();
    names.sort();
    assert!(names.len() >= 15, "{names:?}");
    for name in &names {
        let name = name.as_str();
        let out = dir.path().join(format!("{name}.tstats"));
        let mut args = vec!["render".to_string(), scene(name), "--out".into(), s(&out)];
        args.extend(SMALL.iter().map(|a| a.to_string()));
        // NLOS captures: 20 bins reach the hidden letter's echo only when wider; an
        // exhaustive one holds a 12 x 12 image per laser point of its 12 x 12 grid.
        let nlos = name.starts_with("nlos");
        let rows = if name.contains("exhaustive") {
            12 * 144
        } else {
            12
        };
        if nlos {
            args.extend(["--bin-width-opl".to_string(), "0.1".to_string()]);
        }
        let args: Vec<&str> = args.iter().map(|a| a.as_str()).collect();
        let r = tstat(&args);
        assert!(
            r.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&r.stderr)
        );
        for f in [
            "manifest.json",
            "x1.npy",
            "x2.npy",
            "x3.npy",
            "nonzero.npy",
            "albedo.npy",
            "normal.npy",
            "depth.npy",
            "emitter.npy",
            "steady.npy",
        ] {
            assert!(out.join(f).is_file(), "{name}: {f} missing");
        }
        let noisy = dir.path().join(format!("{name}.npy"));
        let exr = dir.path().join(format!("{name}.exr"));
        let r = tstat(&[
            "export",
            &s(&out),
            "--out",
            &s(&noisy),
            "--steady",
            &s(&exr),
        ]);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        let vol: ndarray::Array4<f32> = ndarray_npy::read_npy(&noisy).unwrap();
        assert_eq!(vol.shape(), &[rows, 12, 20, 3], "{name}");
        assert!(vol.iter().all(|v| v.is_finite()) && vol.iter().any(|&v| v > 0.0));
        assert!(std::fs::metadata(&exr).unwrap().len() > 0);
        let den = dir.path().join(format!("{name}.den.npy"));
        let r = tstat(&["denoise", &s(&out), "--out", &s(&den)]);
        assert!(
            r.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&r.stderr)
        );
        let d: ndarray::Array4<f32> = ndarray_npy::read_npy(&den).unwrap();
        assert_eq!(d.shape(), vol.shape());
        assert!(d.iter().all(|v| v.is_finite()));
        let r = tstat(&["info", &s(&out)]);
        assert!(r.status.success());
        let size = format!("12 x {rows} px, 20 bins");
        assert!(
            String::from_utf8_lossy(&r.stdout).contains(&size),
            "{name}: {size}"
        );
    }
}

#[test]
fn bundles_are_bit_identical_with_one_or_two_threads() {
    let dir = tempfile::tempdir().unwrap();
    let mut outs = Vec::new();
    for threads in ["1", "2"] {
        let out = dir.path().join(format!("t{threads}.tstats"));
        let r = tstat(&[
            "render",
            &scene("cbox_spheres.xml"),
            "--out",
            &s(&out),
            "--threads",
            threads,
            "--width",
            "16",
            "--spp",
            "8",
            "--bins",
            "40",
            "--seed",
            "77",
            "--transform",
            "box-cox:0.5",
        ]);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        outs.push(out);
    }
    for f in [
        "x1.npy",
        "x2.npy",
        "x3.npy",
        "sum.npy",
        "nonzero.npy",
        "albedo.npy",
        "normal.npy",
        "steady.npy",
    ] {
        let a = std::fs::read(outs[0].join(f)).unwrap();
        let b = std::fs::read(outs[1].join(f)).unwrap();
        assert!(a == b, "{f} differs between 1 and 2 threads");
    }
}

/// A small valid scene; tests break one thing at a time.
const VALID: &str = r#"<scene version="3.0.0">
    <default name="spp" value="4"/>
    <integrator type="transient_path"><integer name="max_depth" value="3"/></integrator>
    <sensor type="perspective">
        <float name="fov" value="40"/>
        <transform name="to_world"><lookat origin="0,0,4" target="0,0,0" up="0,1,0"/></transform>
        <sampler type="independent"><integer name="sample_count" value="$spp"/></sampler>
        <film type="transient_hdr_film">
            <integer name="width" value="8"/><integer name="height" value="8"/>
            <integer name="temporal_bins" value="10"/>
            <float name="start_opl" value="3"/><float name="bin_width_opl" value="0.5"/>
        </film>
    </sensor>
    <bsdf type="diffuse" id="grey"><rgb name="reflectance" value="0.5, 0.5, 0.5"/></bsdf>
    <shape type="rectangle"><ref id="grey"/></shape>
    <emitter type="point"><point name="position" x="0" y="0" z="4"/><rgb name="intensity" value="5"/></emitter>
</scene>"#;

struct Case {
    dir: tempfile::TempDir,
    scene: PathBuf,
    out: PathBuf,
}

fn case(xml: &str) -> Case {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene.xml");
    std::fs::write(&scene, xml).unwrap();
    let out = dir.path().join("out.tstats");
    Case { dir, scene, out }
}

/// Runs render on `xml` with `extra` flags; asserts a clean failure mentioning `want`.
fn assert_render_fails(xml: &str, extra: &[&str], want: &[&str]) {
    let c = case(xml);
    let mut args = vec![
        "render",
        c.scene.to_str().unwrap(),
        "--out",
        c.out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let r = tstat(&args);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "should fail: {err}");
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(
        err.trim()
            .lines()
            .filter(|l| l.starts_with("error"))
            .count(),
        1,
        "{err}"
    );
    for w in want {
        assert!(err.contains(w), "expected '{w}' in: {err}");
    }
    // Nothing written: only the scene file remains.
    let left: Vec<_> = std::fs::read_dir(c.dir.path())
        .unwrap()
        .flatten()
        .map(|e| e.file_name())
        .collect();
    assert_eq!(left.len(), 1, "left behind: {left:?}");
}

#[test]
fn the_valid_scene_renders() {
    let c = case(VALID);
    let r = tstat(&[
        "render",
        c.scene.to_str().unwrap(),
        "--out",
        c.out.to_str().unwrap(),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
}

#[test]
fn malformed_xml_names_file_and_line() {
    let xml = VALID.replace(
        "<shape type=\"rectangle\"><ref id=\"grey\"/></shape>",
        "<shape type=\"rectangle\">",
    );
    assert_render_fails(&xml, &[], &["scene.xml:", "malformed XML"]);
}

#[test]
fn unknown_plugin_names_the_element_and_line() {
    let xml = VALID.replace("type=\"diffuse\"", "type=\"plastik\"");
    assert_render_fails(&xml, &[], &["scene.xml:14:", "unknown BSDF type 'plastik'"]);
    let xml = VALID.replace("type=\"rectangle\"", "type=\"torus\"");
    assert_render_fails(&xml, &[], &["scene.xml:15:", "unknown shape type 'torus'"]);
}

#[test]
fn unknown_parameter_is_an_error() {
    let xml = VALID.replace("<rgb name=\"reflectance\"", "<rgb name=\"reflectanse\"");
    assert_render_fails(
        &xml,
        &[],
        &["scene.xml:14:", "unknown parameter 'reflectanse'"],
    );
}

#[test]
fn missing_mesh_file_is_an_error() {
    let xml = VALID.replace(
        "<shape type=\"rectangle\"><ref id=\"grey\"/></shape>",
        "<shape type=\"ply\"><string name=\"filename\" value=\"nowhere.ply\"/></shape>",
    );
    assert_render_fails(&xml, &[], &["scene.xml:15:", "nowhere.ply"]);
}

#[test]
fn bad_numbers_are_errors() {
    let xml = VALID.replace("value=\"40\"", "value=\"forty\"");
    assert_render_fails(
        &xml,
        &[],
        &["scene.xml:5:", "'forty' is not a finite number"],
    );
    let xml = VALID.replace("value=\"0.5, 0.5, 0.5\"", "value=\"0.5, 0.5\"");
    assert_render_fails(&xml, &[], &["scene.xml:14:", "one or three numbers"]);
    let xml = VALID.replace(
        "name=\"max_depth\" value=\"3\"",
        "name=\"max_depth\" value=\"3.5\"",
    );
    assert_render_fails(&xml, &[], &["scene.xml:3:", "not an integer"]);
}

#[test]
fn missing_sensor_or_film_is_an_error() {
    let start = VALID.find("<sensor").unwrap();
    let end = VALID.find("</sensor>").unwrap() + "</sensor>".len();
    let no_sensor = format!("{}{}", &VALID[..start], &VALID[end..]);
    assert_render_fails(&no_sensor, &[], &["scene.xml:1:", "no <sensor>"]);
    let start = VALID.find("<film").unwrap();
    let end = VALID.find("</film>").unwrap() + "</film>".len();
    let no_film = format!("{}{}", &VALID[..start], &VALID[end..]);
    assert_render_fails(&no_film, &[], &["scene.xml:4:", "no <film>"]);
}

#[test]
fn undefined_reference_and_default_are_errors() {
    let xml = VALID.replace("<ref id=\"grey\"/>", "<ref id=\"gray\"/>");
    assert_render_fails(&xml, &[], &["scene.xml:15:", "no BSDF with id 'gray'"]);
    let xml = VALID.replace("value=\"$spp\"", "value=\"$samples\"");
    assert_render_fails(&xml, &[], &["scene.xml:7:", "'$samples'"]);
    assert_render_fails(VALID, &["-D", "nope=3"], &["nope"]);
}

#[test]
fn bad_render_options_are_errors() {
    assert_render_fails(VALID, &["--spp", "1"], &["at least 2 samples"]);
    assert_render_fails(
        &VALID.replace("name=\"spp\" value=\"4\"", "name=\"spp\" value=\"1\""),
        &[],
        &["at least 2 samples"],
    );
    assert_render_fails(VALID, &["--bins", "0"], &["--bins"]);
    assert_render_fails(
        VALID,
        &["--bin-width-opl", "-0.1"],
        &["--bin-width-opl must be positive"],
    );
    assert_render_fails(VALID, &["--transform", "box-cox:-1"], &["--transform"]);
    assert_render_fails(VALID, &["--max-memory", "1k"], &["--max-memory"]);
    assert_render_fails(VALID, &["--threads", "0"], &["--threads"]);
}

#[test]
fn an_existing_output_is_kept_without_force_and_replaced_with_it() {
    let c = case(VALID);
    let (sc, out) = (c.scene.to_str().unwrap(), c.out.to_str().unwrap());
    std::fs::create_dir(&c.out).unwrap();
    std::fs::write(c.out.join("mine.txt"), "precious").unwrap();
    let r = tstat(&["render", sc, "--out", out]);
    assert_eq!(r.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&r.stderr).contains("already exists (use --force"));
    assert_eq!(
        std::fs::read_to_string(c.out.join("mine.txt")).unwrap(),
        "precious"
    );
    let r = tstat(&["render", sc, "--out", out, "--force"]);
    assert!(r.status.success());
    assert!(c.out.join("manifest.json").is_file() && !c.out.join("mine.txt").exists());
    let left: Vec<_> = std::fs::read_dir(c.dir.path())
        .unwrap()
        .flatten()
        .map(|e| e.file_name())
        .collect();
    assert_eq!(left.len(), 2, "temporary files left: {left:?}");
}

#[test]
fn damaged_bundles_are_refused_naming_the_file() {
    let c = case(VALID);
    let (sc, out) = (c.scene.to_str().unwrap(), c.out.to_str().unwrap());
    assert!(tstat(&["render", sc, "--out", out]).status.success());
    let npy = c.dir.path().join("noisy.npy");
    // Truncated array.
    let x1 = c.out.join("x1.npy");
    let bytes = std::fs::read(&x1).unwrap();
    std::fs::write(&x1, &bytes[..bytes.len() / 2]).unwrap();
    let r = tstat(&["export", out, "--out", npy.to_str().unwrap()]);
    assert_eq!(r.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&r.stderr).contains("x1.npy"));
    assert!(!npy.exists());
    // Other format version.
    let m = c.out.join("manifest.json");
    let text = std::fs::read_to_string(&m)
        .unwrap()
        .replace("\"version\": 1", "\"version\": 99");
    std::fs::write(&m, text).unwrap();
    let r = tstat(&["info", out]);
    assert_eq!(r.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&r.stderr).contains("manifest.json"));
}

#[test]
fn denoise_writes_a_volume_and_refuses_bad_parameters() {
    let c = case(VALID);
    let (sc, out) = (c.scene.to_str().unwrap(), c.out.to_str().unwrap());
    assert!(tstat(&["render", sc, "--out", out]).status.success());
    let den = c.dir.path().join("den.npy");
    let exr = c.dir.path().join("bins");
    let r = tstat(&[
        "denoise",
        out,
        "--out",
        den.to_str().unwrap(),
        "--exr",
        exr.to_str().unwrap(),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(String::from_utf8_lossy(&r.stdout).contains("voxel-neighbour evaluations/s"));
    let v: ndarray::Array4<f32> = ndarray_npy::read_npy(&den).unwrap();
    assert_eq!(v.shape(), &[8, 8, 10, 3]);
    assert_eq!(std::fs::read_dir(&exr).unwrap().count(), 10);
    let fails = |extra: &[&str], want: &str| {
        let target = c.dir.path().join("bad.npy");
        let mut args = vec!["denoise", out, "--out", target.to_str().unwrap()];
        args.extend_from_slice(extra);
        let r = tstat(&args);
        let err = String::from_utf8_lossy(&r.stderr);
        // 1 for our errors, 2 for clap's usage errors.
        assert!(matches!(r.status.code(), Some(1 | 2)), "{extra:?}: {err}");
        assert!(err.contains(want), "expected '{want}' in {err}");
        assert!(!target.exists());
    };
    fails(&["--radius", "-1"], "--radius -1");
    fails(&["--temporal-radius", "-2"], "--temporal-radius -2");
    let published = |flag: &'static str, value: &'static str| {
        fails(
            &["--method", "published", flag, value],
            &format!("{flag} {value}"),
        );
    };
    published("--gamma", "0.5");
    published("--gamma", "0");
    published("--alpha", "1.5");
    fails(&["--gamma", "0.5"], "add --method published");
    fails(&["--sigma-xy", "0"], "--sigma-xy");
    fails(
        &["--gamma", "0.1", "--alpha", "0.01"],
        "cannot be used with",
    );
    // A bundle missing an array, and one with a mismatched array.
    std::fs::remove_file(c.out.join("x3.npy")).unwrap();
    fails(&[], "x3.npy");
    std::fs::copy(c.out.join("x2.npy"), c.out.join("x3.npy")).unwrap();
    std::fs::copy(c.out.join("steady.npy"), c.out.join("x2.npy")).unwrap();
    fails(&[], "x2.npy");
}

#[test]
fn fortran_order_arrays_and_missing_output_directories() {
    let c = case(VALID);
    let (sc, out) = (c.scene.to_str().unwrap(), c.out.to_str().unwrap());
    // The parent of the output must exist: refused before rendering.
    let nowhere = c.dir.path().join("no/such/dir.tstats");
    let r = tstat(&["render", sc, "--out", nowhere.to_str().unwrap()]);
    assert_eq!(r.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&r.stderr).contains("does not exist"));
    assert!(tstat(&["render", sc, "--out", out]).status.success());
    let a = c.dir.path().join("a.npy");
    assert!(tstat(&["denoise", out, "--out", a.to_str().unwrap()])
        .status
        .success());
    // NumPy may save Fortran order: same numbers, same result.
    let x1: ndarray::Array4<f64> = ndarray_npy::read_npy(c.out.join("x1.npy")).unwrap();
    let mut f = ndarray::Array4::<f64>::zeros(ndarray::ShapeBuilder::f(x1.raw_dim()));
    f.assign(&x1);
    assert!(!f.is_standard_layout());
    ndarray_npy::write_npy(c.out.join("x1.npy"), &f).unwrap();
    let b = c.dir.path().join("b.npy");
    let r = tstat(&["denoise", out, "--out", b.to_str().unwrap()]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
}

/// `--max-memory` cuts the image into slabs: the volume and the EXR bins are the same
/// bytes as with one slab, whatever the threads; a budget below one row and its halo is
/// refused before anything is written.
#[test]
fn denoise_in_slabs_writes_the_same_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let b = dir.path().join("cbox.tstats");
    let r = tstat(&[
        "render",
        &scene("cbox.xml"),
        "--width",
        "16",
        "--height",
        "40",
        "--bins",
        "30",
        "--spp",
        "4",
        "--pixel-sampling",
        "independent",
        "--out",
        &s(&b),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let run = |name: &str, extra: &[&str]| {
        let (out, exr) = (
            dir.path().join(name),
            dir.path().join(format!("{name}.bins")),
        );
        let mut args = vec!["denoise".to_string(), s(&b), "--out".into(), s(&out)];
        args.extend(["--exr".into(), s(&exr)]);
        args.extend(extra.iter().map(|a| a.to_string()));
        let args: Vec<&str> = args.iter().map(|a| a.as_str()).collect();
        let r = tstat(&args);
        let err = String::from_utf8_lossy(&r.stderr).into_owned();
        assert!(r.status.success(), "{extra:?}: {err}");
        (out, exr, err)
    };
    let (one, one_exr, err) = run("one.npy", &[]);
    assert!(
        err.contains("denoiser memory") && err.contains("1 slab of 40 rows"),
        "{err}"
    );
    let volume: ndarray::Array4<f32> = ndarray_npy::read_npy(&one).unwrap();
    for (name, extra) in [
        ("a.npy", &["--max-memory", "800k"][..]),
        ("b.npy", &["--max-memory", "600k", "--threads", "1"]),
        ("c.npy", &["--max-memory", "700k", "--threads", "3"]),
    ] {
        let (out, exr, err) = run(name, extra);
        let slabs: usize = err
            .split(" slabs of ")
            .next()
            .and_then(|l| l.rsplit('(').next())
            .and_then(|n| n.parse().ok())
            .unwrap_or_else(|| panic!("{err}"));
        assert!(slabs >= 3, "{extra:?}: {err}");
        assert_eq!(
            std::fs::read(&one).unwrap(),
            std::fs::read(&out).unwrap(),
            "{extra:?}"
        );
        for k in 0..30 {
            let f = format!("bin_{k:04}.exr");
            assert_eq!(
                std::fs::read(one_exr.join(&f)).unwrap(),
                std::fs::read(exr.join(&f)).unwrap(),
                "{extra:?} {f}"
            );
        }
    }
    // An EXR bin holds that bin of the volume.
    let k = 12;
    let img = exr::prelude::read_first_rgba_layer_from_file(
        one_exr.join(format!("bin_{k:04}.exr")),
        |size, _| vec![[0f32; 3]; size.width() * size.height()],
        |px: &mut Vec<[f32; 3]>, at, (r, g, b, _a): (f32, f32, f32, f32)| {
            px[at.y() * 16 + at.x()] = [r, g, b]
        },
    )
    .unwrap();
    let px = &img.layer_data.channel_data.pixels;
    assert!(px.iter().any(|p| p[0] > 0.0));
    for y in 0..40 {
        for x in 0..16 {
            for c in 0..3 {
                assert_eq!(px[y * 16 + x][c], volume[[y, x, k, c]], "({y}, {x}, {c})");
            }
        }
    }
    // Too small a budget: one error line naming the flag and what is needed.
    let bad = dir.path().join("bad.npy");
    let r = tstat(&["denoise", &s(&b), "--out", &s(&bad), "--max-memory", "400k"]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "{err}");
    assert!(
        err.contains("--max-memory 400k") && err.contains("needs at least"),
        "{err}"
    );
    assert!(!bad.exists());
    let r = tstat(&["denoise", &s(&b), "--out", &s(&bad), "--max-memory", "lots"]);
    assert!(String::from_utf8_lossy(&r.stderr).contains("--max-memory"));
    assert!(!bad.exists());
}

#[test]
fn merge_adds_sums_and_counts_exactly_and_refuses_mismatches() {
    let c = case(VALID);
    let sc = c.scene.to_str().unwrap();
    let p = |n: &str| c.dir.path().join(n).display().to_string();
    for (name, seed) in [("a.tstats", "1"), ("b.tstats", "2"), ("c.tstats", "1")] {
        let r = tstat(&[
            "render",
            sc,
            "--out",
            &p(name),
            "--seed",
            seed,
            "--transform",
            "yeo-johnson:0.5",
        ]);
        assert!(r.status.success());
    }
    let r = tstat(&[
        "merge",
        &p("a.tstats"),
        &p("b.tstats"),
        "--out",
        &p("m.tstats"),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let load = |d: &str, f: &str| -> ndarray::ArrayD<f64> {
        ndarray_npy::read_npy(c.dir.path().join(d).join(f)).unwrap()
    };
    for f in ["x1.npy", "x2.npy", "x3.npy", "sum.npy"] {
        assert_eq!(
            load("m.tstats", f),
            load("a.tstats", f) + load("b.tstats", f),
            "{f}"
        );
    }
    let counts = |d: &str| -> ndarray::ArrayD<u32> {
        ndarray_npy::read_npy(c.dir.path().join(d).join("nonzero.npy")).unwrap()
    };
    assert_eq!(counts("m.tstats"), counts("a.tstats") + counts("b.tstats"));
    // Means are averaged: equal spp, so the steady image is the plain average.
    let steady = (load("a.tstats", "steady.npy") + load("b.tstats", "steady.npy")) * 0.5;
    assert!((load("m.tstats", "steady.npy") - steady)
        .iter()
        .all(|d| d.abs() < 1e-12));
    let info = tstat(&["info", &p("m.tstats")]);
    assert!(String::from_utf8_lossy(&info.stdout).contains("8 spp"));
    // The merged bundle denoises like any other.
    assert!(tstat(&["denoise", &p("m.tstats"), "--out", &p("m.npy")])
        .status
        .success());
    // Same seed twice: the same paths would count twice.
    let r = tstat(&[
        "merge",
        &p("a.tstats"),
        &p("c.tstats"),
        "--out",
        &p("x.tstats"),
    ]);
    assert_eq!(r.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&r.stderr).contains("seed 1 appears twice"));
    // Different settings.
    assert!(tstat(&[
        "render",
        sc,
        "--out",
        &p("d.tstats"),
        "--seed",
        "3",
        "--bins",
        "12"
    ])
    .status
    .success());
    let r = tstat(&[
        "merge",
        &p("a.tstats"),
        &p("d.tstats"),
        "--out",
        &p("x.tstats"),
    ]);
    assert_eq!(r.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&r.stderr).contains("d.tstats"));
    assert!(!c.dir.path().join("x.tstats").exists());
}

#[test]
fn outputs_never_replace_a_mesh_the_scene_reads() {
    let dir = tempfile::tempdir().unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    std::fs::create_dir(dir.path().join("meshes")).unwrap();
    std::fs::copy(
        root.join("meshes/bunny.ply"),
        dir.path().join("meshes/bunny.ply"),
    )
    .unwrap();
    std::fs::copy(root.join("bunny.xml"), dir.path().join("bunny.xml")).unwrap();
    let scene = dir.path().join("bunny.xml");
    let before = std::fs::read(dir.path().join("meshes/bunny.ply")).unwrap();
    for cmd in ["render", "run"] {
        let r = tstat(&[
            cmd,
            scene.to_str().unwrap(),
            "--out",
            dir.path().join("meshes").to_str().unwrap(),
            "--force",
            "--width",
            "4",
            "--spp",
            "2",
            "--bins",
            "2",
        ]);
        let err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(1), "{cmd}: {err}");
        assert!(err.contains("contains the input mesh"), "{cmd}: {err}");
        assert_eq!(
            std::fs::read(dir.path().join("meshes/bunny.ply")).unwrap(),
            before
        );
        let mut left: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        left.sort();
        assert_eq!(left, ["bunny.xml", "meshes"], "{cmd}");
    }
}

/// `TSTAT_ISA` picks the tracer's instruction set; a value it does not know is a
/// warning line naming it, and the render goes on at the widest level (same bits).
#[test]
fn unknown_tstat_isa_is_a_warning_and_changes_no_bits() {
    let dir = tempfile::tempdir().unwrap();
    let render = |isa: &str, out: &str| {
        let out = s(&dir.path().join(out));
        let mut args = vec!["render".to_string(), scene("cbox.xml"), "--out".into(), out];
        args.extend(SMALL.iter().map(|a| a.to_string()));
        Command::new(env!("CARGO_BIN_EXE_tstat"))
            .args(&args)
            .env("TSTAT_ISA", isa)
            .output()
            .unwrap()
    };
    let bad = render("sse9", "a.tstats");
    let stderr = String::from_utf8_lossy(&bad.stderr);
    assert!(bad.status.success(), "{stderr}");
    assert!(
        stderr.contains("warning: TSTAT_ISA=\"sse9\" is not baseline, avx2 or avx512"),
        "{stderr}"
    );
    let base = render("baseline", "b.tstats");
    assert!(base.status.success());
    assert!(!String::from_utf8_lossy(&base.stderr).contains("TSTAT_ISA"));
    for f in ["x1.npy", "x3.npy", "nonzero.npy", "steady.npy"] {
        let a = std::fs::read(dir.path().join("a.tstats").join(f)).unwrap();
        let b = std::fs::read(dir.path().join("b.tstats").join(f)).unwrap();
        assert!(a == b, "{f} differs between instruction sets");
    }
}

#[test]
fn check_says_ok_or_lists_what_is_unsupported() {
    let r = tstat(&["check", &scene("cbox.xml"), &scene("delay_chlorophyll.xml")]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let out = String::from_utf8_lossy(&r.stdout);
    assert_eq!(out.matches(": ok").count(), 2, "{out}");
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.xml");
    let xml = std::fs::read_to_string(scene("cbox.xml")).unwrap().replace(
        "</scene>",
        "<emitter type=\"sunsky\"/><medium type=\"rayleigh_fog\"/></scene>",
    );
    std::fs::write(&bad, xml).unwrap();
    let r = tstat(&["check", &scene("cbox.xml"), &s(&bad)]);
    assert_eq!(r.status.code(), Some(1));
    let out = String::from_utf8_lossy(&r.stdout);
    assert!(
        out.contains("2 unsupported") && out.contains("sunsky") && out.contains("rayleigh_fog"),
        "{out}"
    );
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(err.trim(), "error: 1 of 2 scenes would not render");
    // A missing scene is reported, a malformed -D is one usage error.
    let r = tstat(&["check", &s(&dir.path().join("none.xml"))]);
    assert_eq!(r.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&r.stdout).contains("cannot read"));
    let r = tstat(&["check", &scene("cbox.xml"), "-D", "spp"]);
    assert_eq!(r.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&r.stderr).contains("-D spp: expected name=value"));
}

#[test]
fn a_steady_value_beyond_f32_is_refused_by_export() {
    // The mean volume had this check; the steady image did not and was written as +inf.
    let c = case(VALID);
    let (sc, out) = (c.scene.to_str().unwrap(), c.out.to_str().unwrap());
    assert!(tstat(&["render", sc, "--out", out]).status.success());
    let steady = c.out.join("steady.npy");
    let mut img: ndarray::Array3<f64> = ndarray_npy::read_npy(&steady).unwrap();
    img[[2, 3, 1]] = 1e39;
    ndarray_npy::write_npy(&steady, &img).unwrap();
    for name in ["s.exr", "s.npy"] {
        let target = c.dir.path().join(name);
        let r = tstat(&["export", out, "--steady", target.to_str().unwrap()]);
        assert_eq!(r.status.code(), Some(1));
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(
            err.contains("does not fit in f32") && err.contains("row 2, column 3"),
            "{err}"
        );
        assert!(!target.exists());
    }
}

#[test]
fn merge_refuses_bundles_of_other_d_values_or_other_scene_files() {
    // The scene file's bytes are the same; what it was rendered with is not.
    let xml = VALID
        .replace(
            r#"<default name="spp" value="4"/>"#,
            r#"<default name="spp" value="4"/><default name="refl" value="0.5"/>"#,
        )
        .replace(
            r#"<rgb name="reflectance" value="0.5, 0.5, 0.5"/>"#,
            r#"<float name="reflectance" value="$refl"/>"#,
        )
        .replace(
            r#"<shape type="rectangle"><ref id="grey"/></shape>"#,
            r#"<shape type="ply"><string name="filename" value="m.ply"/><ref id="grey"/></shape>"#,
        );
    let c = case(&xml);
    let ply = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
               property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\
               -1 -1 0\n1 -1 0\n0 1 0\n3 0 1 2\n";
    let mesh = c.dir.path().join("m.ply");
    std::fs::write(&mesh, ply).unwrap();
    let sc = c.scene.to_str().unwrap();
    let p = |n: &str| s(&c.dir.path().join(n));
    let render = |out: &str, seed: &str, refl: &str| {
        let r = tstat(&[
            "render",
            sc,
            "--out",
            &p(out),
            "--seed",
            seed,
            "-D",
            &format!("refl={refl}"),
        ]);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    };
    render("a.tstats", "1", "0.8");
    render("b.tstats", "2", "0.8");
    render("c.tstats", "3", "0.2");
    let merge =
        |x: &str, y: &str| tstat(&["merge", &p(x), &p(y), "--out", &p("m.tstats"), "--force"]);
    assert!(merge("a.tstats", "b.tstats").status.success());
    let r = merge("a.tstats", "c.tstats");
    assert_eq!(r.status.code(), Some(1));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        err.contains("-D refl '0.2' where the first bundle has '0.8'"),
        "{err}"
    );
    // The same -D, but the mesh changed between the renders.
    std::fs::write(&mesh, ply.replace("0 1 0\n3", "0 0.5 0\n3")).unwrap();
    render("d.tstats", "4", "0.8");
    let r = merge("a.tstats", "d.tstats");
    assert_eq!(r.status.code(), Some(1));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(err.contains("file 'm.ply'"), "{err}");
}

/// Replicates through the command line: `--replicates` must divide spp; a bundle with
/// replicates holds `r2.npy` and says so in `info`; bundles with replicates of equal
/// size merge by adding R2 and B (and denoise), other sizes (or none) are refused.
#[test]
fn replicates_render_merge_and_refuse_mismatches() {
    let c = case(VALID);
    let sc = c.scene.to_str().unwrap();
    let p = |n: &str| c.dir.path().join(n).display().to_string();
    let render = |name: &str, seed: &str, spp: &str, reps: &str| {
        tstat(&[
            "render",
            sc,
            "--out",
            &p(name),
            "--seed",
            seed,
            "--spp",
            spp,
            "--sampler",
            "sobol",
            "--replicates",
            reps,
        ])
    };
    for reps in ["3", "1"] {
        let r = render("bad.tstats", "1", "8", reps);
        assert!(!r.status.success());
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(err.contains(&format!("--replicates {reps}")), "{err}");
        assert!(!c.dir.path().join("bad.tstats").exists());
    }
    for (name, seed, spp, reps) in [
        ("a.tstats", "1", "8", "4"),
        ("b.tstats", "2", "16", "8"),
        ("c.tstats", "3", "8", "2"),
        ("d.tstats", "4", "8", "0"),
    ] {
        let r = render(name, seed, spp, reps);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    }
    let info = String::from_utf8_lossy(&tstat(&["info", &p("a.tstats")]).stdout).to_string();
    assert!(info.contains("replicates  4 of 2 samples"), "{info}");
    assert!(c.dir.path().join("a.tstats/r2.npy").exists());
    assert!(!c.dir.path().join("d.tstats/r2.npy").exists());
    let r = tstat(&[
        "merge",
        &p("a.tstats"),
        &p("b.tstats"),
        "--out",
        &p("m.tstats"),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let m: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(c.dir.path().join("m.tstats/manifest.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(
        (m["spp"].as_u64(), m["replicates"].as_u64()),
        (Some(24), Some(12))
    );
    let load = |d: &str| -> ndarray::ArrayD<f64> {
        ndarray_npy::read_npy(c.dir.path().join(d).join("r2.npy")).unwrap()
    };
    assert_eq!(load("m.tstats"), load("a.tstats") + load("b.tstats"));
    let r = tstat(&["denoise", &p("m.tstats"), "--out", &p("m.npy")]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    // Extreme thresholds on replicate estimates (per-pair critical values at levels
    // that round to 0 or 1) denoise to finite volumes, never a panic.
    for extra in [
        &["--t2-max", "2000"][..],
        &["--t2-max", "1e-40"],
        &["--method", "published", "--alpha", "1e-17"],
        &["--method", "published", "--alpha", "0.999999999999"],
    ] {
        let mut args = vec![
            "denoise",
            &p("m.tstats") as &str,
            "--out",
            &p("x.npy") as &str,
            "--force",
        ]
        .into_iter()
        .map(String::from)
        .collect::<Vec<_>>();
        args.extend(extra.iter().map(|s| s.to_string()));
        let r = tstat(&args.iter().map(String::as_str).collect::<Vec<_>>());
        assert!(
            r.status.success(),
            "{extra:?}: {}",
            String::from_utf8_lossy(&r.stderr)
        );
        let v: ndarray::ArrayD<f32> = ndarray_npy::read_npy(c.dir.path().join("x.npy")).unwrap();
        assert!(v.iter().all(|x| x.is_finite()), "{extra:?}");
    }
    for other in ["c.tstats", "d.tstats"] {
        let r = tstat(&["merge", &p("a.tstats"), &p(other), "--out", &p("x.tstats")]);
        assert!(!r.status.success());
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(
            err.contains("only bundles with replicates of equal size"),
            "{err}"
        );
    }
}

/// The time origin through the binary: `check` notes a near_clip of more than a tenth
/// of a bin, the manifest and `info` record the origin, bundles of the two origins do
/// not merge, and an NLOS capture refuses `--time-origin near_clip`.
#[test]
fn the_time_origin_is_noted_recorded_and_kept_apart() {
    let far = VALID.replace(
        r#"<float name="fov" value="40"/>"#,
        r#"<float name="fov" value="40"/><float name="near_clip" value="0.2"/>"#,
    );
    let c = case(&far);
    let sc = c.scene.to_str().unwrap();
    let p = |n: &str| c.dir.path().join(n).display().to_string();
    let out = String::from_utf8_lossy(&tstat(&["check", sc]).stdout).to_string();
    // 0.2 / 0.5 = 0.4 bins at the centre; the corner's 1 / cos: 0.2 sqrt(1 + 2 tan^2 20).
    let corner = 0.2 * (1.0 + 2.0 * 20f64.to_radians().tan().powi(2)).sqrt();
    assert!(
        out.contains(&format!("note: time origin: OPL counts from the near-clip plane (as mitransient), so arrivals are 0.2000..{corner:.4} OPL (0.40..{:.2} bins) earlier", corner / 0.5)),
        "{out}"
    );
    // A near_clip of a twentieth of a bin is no note: the default scene (0.01).
    let c2 = case(VALID);
    let out =
        String::from_utf8_lossy(&tstat(&["check", c2.scene.to_str().unwrap()]).stdout).to_string();
    assert!(out.contains(": ok") && !out.contains("note"), "{out}");
    for (name, seed, origin) in [("n.tstats", "1", None), ("p.tstats", "2", Some("pinhole"))] {
        let out = p(name);
        let mut args = vec!["render", sc, "--out", &out, "--seed", seed];
        if let Some(o) = origin {
            args.extend(["--time-origin", o]);
        }
        let r = tstat(&args);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    }
    let manifest = |n: &str| -> serde_json::Value {
        serde_json::from_str(
            &std::fs::read_to_string(c.dir.path().join(n).join("manifest.json")).unwrap(),
        )
        .unwrap()
    };
    let (n, ph) = (manifest("n.tstats"), manifest("p.tstats"));
    assert_eq!(n["time_origin"], "near_clip");
    // The f32's shortest decimal.
    assert_eq!(n["near_clip"].as_f64(), Some(0.2));
    assert_eq!(ph["time_origin"], "pinhole");
    assert!(ph.get("near_clip").is_none());
    let info = String::from_utf8_lossy(&tstat(&["info", &p("n.tstats")]).stdout).to_string();
    assert!(
        info.contains("time origin near_clip: OPL counts from the near-clip plane"),
        "{info}"
    );
    let r = tstat(&[
        "merge",
        &p("n.tstats"),
        &p("p.tstats"),
        "--out",
        &p("m.tstats"),
    ]);
    assert_eq!(r.status.code(), Some(1));
    assert!(
        String::from_utf8_lossy(&r.stderr).contains("time_origin"),
        "{}",
        String::from_utf8_lossy(&r.stderr)
    );
    assert!(!c.dir.path().join("m.tstats").exists());
    // The meter has no near plane.
    let r = tstat(&[
        "render",
        &scene("nlos_T.xml"),
        "--out",
        &p("nlos.tstats"),
        "--spp",
        "2",
        "--time-origin",
        "near_clip",
    ]);
    assert_eq!(r.status.code(), Some(1));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        err.contains("the meter has no near plane") && err.lines().count() == 1,
        "{err}"
    );
    assert!(!c.dir.path().join("nlos.tstats").exists());
}
