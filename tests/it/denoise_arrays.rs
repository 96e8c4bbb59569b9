//! Arrays in and out (`tstat export --published`, `tstat denoise --from-arrays`): the
//! filter on exported arrays is `tstat denoise` of the bundle bit for bit (both
//! methods, uniform and adaptive, identity and Yeo-Johnson), the published pipeline's
//! five arrays alone denoise with `--spp`, and bad arrays are one clear error.

use std::path::Path;
use std::process::{Command, Output};

fn tstat(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_tstat"))
        .current_dir(dir)
        .args(args)
        .output()
        .unwrap()
}

fn ok(dir: &Path, args: &[&str]) {
    let o = tstat(dir, args);
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

fn err(dir: &Path, args: &[&str]) -> String {
    let o = tstat(dir, args);
    assert!(!o.status.success(), "{args:?} should fail");
    let e = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(e.lines().count(), 1, "one line: {e}");
    e
}

fn scene() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes/cbox.xml")
        .display()
        .to_string()
}

fn render(dir: &Path, name: &str, extra: &[&str]) {
    let s = scene();
    let mut args = vec![
        "render",
        &s,
        "--out",
        name,
        "--spp",
        "16",
        "--width",
        "20",
        "--bins",
        "40",
        "--bin-width-opl",
        "0.15",
    ];
    args.extend_from_slice(extra);
    ok(dir, &args);
}

fn bytes(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap()
}

#[test]
fn exported_arrays_denoise_bit_for_bit_as_the_bundle() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cases: [(&str, &[&str]); 3] = [
        (
            "yj",
            &[
                "--transform",
                "yeo-johnson:0.5",
                "--pixel-sampling",
                "independent",
            ],
        ),
        ("id", &[]),
        ("ad", &["--adaptive", "--transform", "yeo-johnson:0.5"]),
    ];
    for (name, extra) in cases {
        let b = format!("{name}.tstats");
        let arr = format!("{name}_arrays");
        render(d, &b, extra);
        ok(d, &["export", &b, "--published", &arr]);
        for method in ["tstat", "published"] {
            let (x, y) = (
                format!("{name}_{method}_b.npy"),
                format!("{name}_{method}_a.npy"),
            );
            ok(d, &["denoise", &b, "--method", method, "--out", &x]);
            ok(
                d,
                &[
                    "denoise",
                    "--from-arrays",
                    &arr,
                    "--method",
                    method,
                    "--out",
                    &y,
                ],
            );
            assert!(bytes(&d.join(&x)) == bytes(&d.join(&y)), "{name} {method}");
        }
    }
    assert!(d.join("ad_arrays/pixel_spp.npy").exists());
    assert!(!d.join("yj_arrays/pixel_spp.npy").exists());
}

#[test]
fn the_published_pipelines_five_arrays_need_spp_and_differ_only_by_what_they_lack() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render(
        d,
        "b.tstats",
        &[
            "--transform",
            "yeo-johnson:0.5",
            "--pixel-sampling",
            "independent",
        ],
    );
    ok(d, &["export", "b.tstats", "--published", "arr"]);
    for extra in ["meta.json", "depth.npy", "emitter.npy"] {
        std::fs::remove_file(d.join("arr").join(extra)).unwrap();
    }
    let e = err(d, &["denoise", "--from-arrays", "arr", "--out", "x.npy"]);
    assert!(e.contains("give --spp"), "{e}");
    // The published method reads neither depth nor emitter: the same bits.
    ok(
        d,
        &[
            "denoise",
            "b.tstats",
            "--method",
            "published",
            "--out",
            "p_b.npy",
        ],
    );
    ok(
        d,
        &[
            "denoise",
            "--from-arrays",
            "arr",
            "--spp",
            "16",
            "--method",
            "published",
            "--out",
            "p_a.npy",
        ],
    );
    assert!(bytes(&d.join("p_b.npy")) == bytes(&d.join("p_a.npy")));
    // tstat's filter loses its emitter class and depth alignment: other bits.
    ok(d, &["denoise", "b.tstats", "--out", "t_b.npy"]);
    ok(
        d,
        &[
            "denoise",
            "--from-arrays",
            "arr",
            "--spp",
            "16",
            "--out",
            "t_a.npy",
        ],
    );
    assert!(bytes(&d.join("t_b.npy")) != bytes(&d.join("t_a.npy")));
}

#[test]
fn bad_arrays_are_one_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render(d, "b.tstats", &["--transform", "yeo-johnson:0.5"]);
    ok(d, &["export", "b.tstats", "--published", "good"]);
    let copy = |name: &str| {
        let to = d.join(name);
        std::fs::create_dir(&to).unwrap();
        for e in std::fs::read_dir(d.join("good")).unwrap() {
            let e = e.unwrap();
            std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
        }
        to
    };
    let vol = |dir: &Path, file: &str| -> ndarray::Array4<f32> {
        ndarray_npy::read_npy(dir.join(file)).unwrap()
    };
    // NaN in the estimands.
    let p = copy("nan");
    let mut a = vol(&p, "estimands.npy");
    a[[3, 4, 5, 1]] = f32::NAN;
    ndarray_npy::write_npy(p.join("estimands.npy"), &a).unwrap();
    let e = err(d, &["denoise", "--from-arrays", "nan", "--out", "x.npy"]);
    assert!(
        e.contains("estimands.npy") && e.contains("NaN") && e.contains("y 3"),
        "{e}"
    );
    // A negative variance.
    let p = copy("neg");
    let mut a = vol(&p, "estimands_variance.npy");
    a[[1, 2, 3, 0]] = -1e-3;
    ndarray_npy::write_npy(p.join("estimands_variance.npy"), &a).unwrap();
    let e = err(d, &["denoise", "--from-arrays", "neg", "--out", "x.npy"]);
    assert!(
        e.contains("estimands_variance.npy") && e.contains("at least 0"),
        "{e}"
    );
    // A wrong shape.
    let p = copy("shape");
    ndarray_npy::write_npy(
        p.join("albedo.npy"),
        &ndarray::Array3::<f32>::zeros((20, 19, 3)),
    )
    .unwrap();
    let e = err(d, &["denoise", "--from-arrays", "shape", "--out", "x.npy"]);
    assert!(e.contains("albedo.npy") && e.contains("[20, 19, 3]"), "{e}");
    // Integers.
    let p = copy("ints");
    ndarray_npy::write_npy(
        p.join("normals.npy"),
        &ndarray::Array3::<i64>::zeros((20, 20, 3)),
    )
    .unwrap();
    let e = err(d, &["denoise", "--from-arrays", "ints", "--out", "x.npy"]);
    assert!(e.contains("normals.npy"), "{e}");
    // A missing array.
    let p = copy("missing");
    std::fs::remove_file(p.join("noisy.npy")).unwrap();
    let e = err(
        d,
        &["denoise", "--from-arrays", "missing", "--out", "x.npy"],
    );
    assert!(e.contains("noisy.npy"), "{e}");
    // A broken meta.json, an unknown transform, a bundle and --from-arrays at once.
    let p = copy("meta");
    std::fs::write(p.join("meta.json"), "{\"spp\": 1e400}").unwrap();
    let e = err(d, &["denoise", "--from-arrays", "meta", "--out", "x.npy"]);
    assert!(e.contains("meta.json"), "{e}");
    let e = err(
        d,
        &[
            "denoise",
            "--from-arrays",
            "good",
            "--transform",
            "log",
            "--out",
            "x.npy",
        ],
    );
    assert!(e.contains("--transform log"), "{e}");
    let e = tstat(
        d,
        &[
            "denoise",
            "b.tstats",
            "--from-arrays",
            "good",
            "--out",
            "x.npy",
        ],
    );
    assert!(!e.status.success());
    let e = err(
        d,
        &[
            "denoise",
            "--from-arrays",
            "good",
            "--variance",
            "biased",
            "--method",
            "published",
            "--out",
            "x.npy",
        ],
    );
    assert!(e.contains("--variance"), "{e}");
    // --spp and --transform belong to --from-arrays; --published never replaces a folder.
    let e = err(d, &["denoise", "b.tstats", "--spp", "8", "--out", "x.npy"]);
    assert!(e.contains("--from-arrays"), "{e}");
    let before = bytes(&d.join("good/noisy.npy"));
    let e = err(d, &["export", "b.tstats", "--published", "good"]);
    assert!(e.contains("good") && e.contains("--force"), "{e}");
    assert!(bytes(&d.join("good/noisy.npy")) == before);
    assert!(!d.join("x.npy").exists());
}
