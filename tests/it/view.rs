//! `tstat view`: one self-contained page (no network), its data within the byte budget
//! (block-averaged beyond it, and saying so), and one clear error for bad inputs. The
//! page's behaviour in a browser is tested by scripts/view_test.py (headless Chromium).

use crate::common;

use common::page_data as data;
use std::path::Path;
use std::process::{Command, Output};

fn tstat(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_tstat"))
        .args(args)
        .output()
        .unwrap()
}

fn ok(r: &Output) -> String {
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    String::from_utf8_lossy(&r.stdout).into_owned()
}

fn fails(r: &Output, needle: &str) {
    let e = String::from_utf8_lossy(&r.stderr);
    assert!(
        !r.status.success() && e.contains(needle),
        "expected {needle:?} in: {e}"
    );
    assert!(!e.contains("panicked"), "{e}");
}

/// The JSON data block of a page.

#[test]
fn the_page_is_self_contained_and_fits_its_budget() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).display().to_string();
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cbox.xml");
    let sc = scene.to_str().unwrap();
    let film = ["--width", "16", "--bins", "20", "--spp", "4"];
    let render = |out: &str, extra: &[&str]| {
        let mut a = vec!["render", sc, "--out", out];
        a.extend_from_slice(&film);
        a.extend_from_slice(extra);
        ok(&tstat(&a));
    };
    render(&p("b.tstats"), &[]);
    render(&p("r.tstats"), &["--seed", "9"]);
    ok(&tstat(&["denoise", &p("b.tstats"), "--out", &p("d.npy")]));
    ok(&tstat(&[
        "view",
        &p("b.tstats"),
        "--denoised",
        &p("d.npy"),
        "--reference",
        &p("r.tstats"),
        "--out",
        &p("v.html"),
    ]));
    let page = std::fs::read_to_string(p("v.html")).unwrap();
    for external in ["http://", "https://", "<link", " src="] {
        assert!(
            !page.contains(external),
            "the page refers to something outside: {external}"
        );
    }
    let d = data(&page);
    assert_eq!(
        (
            d["height"].as_u64(),
            d["width"].as_u64(),
            d["bins"].as_u64()
        ),
        (Some(16), Some(16), Some(20))
    );
    assert_eq!(d["block"], 1);
    let labels: Vec<&str> = d["volumes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v["label"].as_str().unwrap())
        .collect();
    assert_eq!(
        labels,
        ["noisy", "noisy sd of the mean", "denoised", "reference"]
    );
    // The band's quantile: t_{0.975} at spp - 1 = 3 degrees of freedom is 3.182.
    assert!((d["t_quantile"].as_f64().unwrap() - 3.182).abs() < 1e-3);
    assert!(
        d["t_quantiles"].is_null(),
        "a uniform render has one quantile"
    );
    // Each volume: H W T C f16 values in base64.
    for v in d["volumes"].as_array().unwrap() {
        assert_eq!(
            v["data"].as_str().unwrap().len(),
            (16 * 16 * 20 * 3 * 2usize).div_ceil(3) * 4
        );
    }
    // A budget below the volumes' size: averaged over blocks, said on the command line
    // and (via `block`) on the page.
    let out = ok(&tstat(&[
        "view",
        &p("b.tstats"),
        "--max-bytes",
        "20K",
        "--out",
        &p("small.html"),
    ]));
    assert!(out.contains("averaged over 2 x 2 pixel blocks"), "{out}");
    let small = data(&std::fs::read_to_string(p("small.html")).unwrap());
    assert_eq!(
        (small["block"].as_u64(), small["height"].as_u64()),
        (Some(2), Some(8))
    );
    let bytes: usize = small["volumes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v["data"].as_str().unwrap().len() * 3 / 4)
        .sum();
    assert!(bytes <= 20_000, "{bytes} bytes of data for a 20K budget");
    // Box-Cox sums: no band, and the command says so.
    render(&p("bc.tstats"), &["--transform", "box-cox:0.5"]);
    let out = ok(&tstat(&["view", &p("bc.tstats"), "--out", &p("bc.html")]));
    assert!(out.contains("no confidence band"), "{out}");
    // Refusals.
    fails(
        &tstat(&["view", &p("b.tstats"), "--out", &p("v.html")]),
        "already exists",
    );
    ok(&tstat(&[
        "render",
        sc,
        "--out",
        &p("other.tstats"),
        "--width",
        "16",
        "--bins",
        "21",
        "--spp",
        "4",
    ]));
    fails(
        &tstat(&[
            "view",
            &p("b.tstats"),
            "--reference",
            &p("other.tstats"),
            "--out",
            &p("x.html"),
        ]),
        "does not match the bundle's (H, W, T, C) = (16, 16, 20, 3)",
    );
    fails(
        &tstat(&[
            "view",
            &p("b.tstats"),
            "--max-bytes",
            "12",
            "--out",
            &p("x.html"),
        ]),
        "at least 1K",
    );
    fails(
        &tstat(&[
            "view",
            &p("b.tstats"),
            "--max-bytes",
            "lots",
            "--out",
            &p("x.html"),
        ]),
        "--max-bytes",
    );
    fails(
        &tstat(&["view", &p("nope.tstats"), "--out", &p("x.html")]),
        "nope.tstats",
    );
    assert!(!Path::new(&p("x.html")).exists());
}
