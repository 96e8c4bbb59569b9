//! Hostile bundles, `.npy` files and volumes through the real binary (issue 9): damaged
//! copies of one tiny valid render, each run through every command that reads it
//! (`info`, `denoise`, `export`, `merge`, `report compare`). Every run must end with
//! exit code 1, exactly one `error:` line on stderr (naming the file and what is wrong),
//! no panic, nothing at its output paths, within 20 s and 2 GB of address space.
//!
//! The corpus is a table: each case damages a fresh copy (or writes a volume) and
//! lists the commands to run and a phrase the error line must hold.

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const LIMIT_SECONDS: u64 = 20;
const LIMIT_BYTES: u64 = 2_000_000_000;

fn scene() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes/cbox.xml")
        .display()
        .to_string()
}

fn s(p: &Path) -> String {
    p.display().to_string()
}

struct Run {
    code: Option<i32>,
    stdout: String,
    stderr: String,
}

/// Runs the binary under an address-space limit and a time limit.
fn tstat(args: &[String], work: &Path) -> Run {
    let bin = env!("CARGO_BIN_EXE_tstat");
    let mut cmd = if Path::new("/usr/bin/prlimit").exists() || which("prlimit") {
        let mut c = Command::new("prlimit");
        c.arg(format!("--as={LIMIT_BYTES}")).arg("--").arg(bin);
        c
    } else {
        let mut c = Command::new("sh");
        c.arg("-c")
            .arg(format!(
                "ulimit -v {}; exec \"$0\" \"$@\"",
                LIMIT_BYTES / 1024
            ))
            .arg(bin);
        c
    };
    // Output to files: a pipe could fill up and stall a child we are only polling.
    let out = work.join(".stdout");
    let err = work.join(".stderr");
    let mut child = cmd
        .args(args)
        .stdin(Stdio::null())
        .stdout(std::fs::File::create(&out).unwrap())
        .stderr(std::fs::File::create(&err).unwrap())
        .spawn()
        .unwrap();
    let start = Instant::now();
    let status = loop {
        if let Some(st) = child.try_wait().unwrap() {
            break st;
        }
        if start.elapsed() > Duration::from_secs(LIMIT_SECONDS) {
            child.kill().unwrap();
            child.wait().unwrap();
            panic!("tstat {args:?} ran longer than {LIMIT_SECONDS} s");
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    let read = |p: &Path| String::from_utf8_lossy(&std::fs::read(p).unwrap()).into_owned();
    let run = Run {
        code: status.code(),
        stdout: read(&out),
        stderr: read(&err),
    };
    std::fs::remove_file(out).unwrap();
    std::fs::remove_file(err).unwrap();
    run
}

fn which(name: &str) -> bool {
    std::env::var_os("PATH")
        .is_some_and(|p| std::env::split_paths(&p).any(|d| d.join(name).is_file()))
}

/// The valid renders every case starts from.
struct Fixture {
    _dir: tempfile::TempDir,
    root: PathBuf,
    /// cbox, 8 x 8 px, 10 bins, 4 spp, seed 0, identity.
    good: PathBuf,
    /// The same with seed 1 (a merge partner).
    good2: PathBuf,
    /// Seed 0 with Box-Cox(0.5) (sums of negative transformed values are legal).
    boxcox: PathBuf,
    /// Seed 0 with 2 replicates (`r2.npy`).
    replicates: PathBuf,
    /// `good`'s noisy mean, f32 (8, 8, 10, 3).
    volume: PathBuf,
}

fn render(root: &Path, name: &str, extra: &[&str]) -> PathBuf {
    let out = root.join(name);
    let mut args: Vec<String> = [
        "render",
        &scene(),
        "--out",
        &s(&out),
        "--width",
        "8",
        "--spp",
        "4",
        "--bins",
        "10",
        "--start-opl",
        "3",
        "--bin-width-opl",
        "0.5",
    ]
    .iter()
    .map(|a| a.to_string())
    .collect();
    args.extend(extra.iter().map(|a| a.to_string()));
    let r = tstat(&args, root);
    assert_eq!(r.code, Some(0), "{}", r.stderr);
    out
}

fn fixture() -> Fixture {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().to_path_buf();
    let good = render(&root, "good.tstats", &["--seed", "0"]);
    let good2 = render(&root, "good2.tstats", &["--seed", "1"]);
    let boxcox = render(
        &root,
        "boxcox.tstats",
        &["--seed", "0", "--transform", "box-cox:0.5"],
    );
    let replicates = render(
        &root,
        "replicates.tstats",
        &["--seed", "0", "--replicates", "2"],
    );
    let volume = root.join("volume.npy");
    let r = tstat(
        &["export".into(), s(&good), "--out".into(), s(&volume)],
        &root,
    );
    assert_eq!(r.code, Some(0), "{}", r.stderr);
    Fixture {
        _dir: dir,
        root,
        replicates,
        good,
        good2,
        boxcox,
        volume,
    }
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
    }
}

fn edit_manifest(b: &Path, edit: impl FnOnce(&mut Value)) {
    let p = b.join("manifest.json");
    let mut v: Value = serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
    edit(&mut v);
    std::fs::write(p, serde_json::to_string_pretty(&v).unwrap()).unwrap();
}

fn array_entry<'a>(v: &'a mut Value, name: &str) -> &'a mut Value {
    v["arrays"]
        .as_array_mut()
        .unwrap()
        .iter_mut()
        .find(|a| a["name"] == name)
        .unwrap()
}

/// A `.npy` file from a header dictionary and raw data.
fn npy_raw(path: &Path, major: u8, dict: &str, data: &[u8]) {
    let mut h = dict.as_bytes().to_vec();
    h.push(b'\n');
    let mut v = b"\x93NUMPY".to_vec();
    v.extend([major, 0]);
    if major == 1 {
        v.extend((h.len() as u16).to_le_bytes());
    } else {
        v.extend((h.len() as u32).to_le_bytes());
    }
    v.extend(h);
    v.extend(data);
    std::fs::write(path, v).unwrap();
}

fn header(descr: &str, shape: &str) -> String {
    format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}")
}

/// Rewrites array `file` of the bundle with one value changed.
fn poke_f64(b: &Path, file: &str, at: [usize; 4], v: f64) {
    let p = b.join(file);
    let mut a: ndarray::Array4<f64> = ndarray_npy::read_npy(&p).unwrap();
    a[at] = v;
    ndarray_npy::write_npy(&p, &a).unwrap();
}

fn poke_f32_2(b: &Path, file: &str, at: [usize; 2], v: f32) {
    let p = b.join(file);
    let mut a: ndarray::Array2<f32> = ndarray_npy::read_npy(&p).unwrap();
    a[at] = v;
    ndarray_npy::write_npy(&p, &a).unwrap();
}

fn poke_f32_3(b: &Path, file: &str, at: [usize; 3], v: f32) {
    let p = b.join(file);
    let mut a: ndarray::Array3<f32> = ndarray_npy::read_npy(&p).unwrap();
    a[at] = v;
    ndarray_npy::write_npy(&p, &a).unwrap();
}

/// The first voxel (y, x, t) where `b`'s sums are not zero.
fn lit_voxel(b: &Path) -> [usize; 3] {
    let n: ndarray::Array3<u32> = ndarray_npy::read_npy(b.join("nonzero.npy")).unwrap();
    let ((y, x, t), _) = n.indexed_iter().find(|(_, &k)| k > 0).unwrap();
    [y, x, t]
}

fn poke_counts(b: &Path, at: [usize; 3], v: u32) {
    let p = b.join("nonzero.npy");
    let mut a: ndarray::Array3<u32> = ndarray_npy::read_npy(&p).unwrap();
    a[at] = v;
    ndarray_npy::write_npy(&p, &a).unwrap();
}

/// A command a damaged input goes through.
#[derive(Clone, Copy, Debug)]
enum Cmd {
    Info,
    Denoise,
    Export,
    /// Merged with the seed-1 render.
    Merge,
    /// As the reference of `report compare` (the valid volume as input).
    CompareRef,
    /// As an input of `report compare` (the valid volume as reference).
    CompareInput,
}

const BUNDLE: &[Cmd] = &[Cmd::Info, Cmd::Denoise, Cmd::Export, Cmd::Merge];
/// Damage found only when the values are read (`info` reads only headers).
const VALUES: &[Cmd] = &[Cmd::Denoise, Cmd::Export, Cmd::Merge, Cmd::CompareRef];
const VOLUME: &[Cmd] = &[Cmd::CompareRef, Cmd::CompareInput];

struct Case {
    name: &'static str,
    /// Makes the damaged input at the given path from the fixture (for bundle
    /// cases the path is a fresh copy of the seed-0 render, made before `make`).
    make: fn(&Fixture, &Path),
    /// The input is a bundle copy (true) or a file `make` writes (false).
    bundle: bool,
    cmds: &'static [Cmd],
    /// Phrases the error line must hold (besides "error:").
    want: &'static [&'static str],
}

fn cases() -> Vec<Case> {
    vec![
        // ---- the bundle directory and its manifest ----
        Case {
            name: "bundle path is a file",
            make: |_, b| {
                std::fs::remove_dir_all(b).unwrap();
                std::fs::write(b, "not a bundle").unwrap();
            },
            bundle: true,
            cmds: BUNDLE,
            want: &["not a bundle directory"],
        },
        Case {
            name: "manifest is a directory",
            make: |_, b| {
                std::fs::remove_file(b.join("manifest.json")).unwrap();
                std::fs::create_dir(b.join("manifest.json")).unwrap();
            },
            bundle: true,
            cmds: BUNDLE,
            want: &["manifest.json", "directory"],
        },
        Case {
            name: "manifest is a link to /dev/zero",
            make: |_, b| {
                std::fs::remove_file(b.join("manifest.json")).unwrap();
                std::os::unix::fs::symlink("/dev/zero", b.join("manifest.json")).unwrap();
            },
            bundle: true,
            cmds: BUNDLE,
            want: &["manifest.json", "not a regular file"],
        },
        Case {
            name: "manifest is not JSON",
            make: |_, b| {
                std::fs::write(b.join("manifest.json"), "{\"format\": \"tstats\",").unwrap()
            },
            bundle: true,
            cmds: BUNDLE,
            want: &["manifest.json", "not valid JSON"],
        },
        Case {
            name: "format version mismatch",
            make: |_, b| edit_manifest(b, |v| v["version"] = 99.into()),
            bundle: true,
            cmds: BUNDLE,
            want: &["manifest.json", "version 99"],
        },
        Case {
            name: "spp below 2",
            make: |_, b| edit_manifest(b, |v| v["spp"] = 1.into()),
            bundle: true,
            cmds: BUNDLE,
            want: &["manifest.json", "spp = 1"],
        },
        Case {
            name: "zero width",
            make: |_, b| edit_manifest(b, |v| v["width"] = 0.into()),
            bundle: true,
            cmds: BUNDLE,
            want: &["manifest.json", "empty film size"],
        },
        Case {
            name: "film size overflowing the address space",
            make: |_, b| {
                edit_manifest(b, |v| {
                    v["width"] = (1u64 << 40).into();
                    v["height"] = (1u64 << 40).into();
                })
            },
            bundle: true,
            cmds: BUNDLE,
            want: &["manifest.json", "overflows"],
        },
        Case {
            // Sizes and array shapes agree with each other, not with the files: merge
            // used to allocate 2.4 TB of accumulators from this.
            name: "huge film size promised by the manifest only",
            make: |_, b| {
                edit_manifest(b, |v| {
                    v["width"] = 100_000.into();
                    v["height"] = 100_000.into();
                    for a in v["arrays"].as_array_mut().unwrap() {
                        let sh = a["shape"].as_array_mut().unwrap();
                        sh[0] = 100_000.into();
                        sh[1] = 100_000.into();
                    }
                })
            },
            bundle: true,
            cmds: BUNDLE,
            want: &[
                "x1.npy",
                "does not match the manifest's [100000, 100000, 10, 3]",
            ],
        },
        Case {
            name: "negative bin width",
            make: |_, b| edit_manifest(b, |v| v["bin_width_opl"] = (-0.5).into()),
            bundle: true,
            cmds: BUNDLE,
            want: &["manifest.json", "bin_width_opl = -5e-1: must be positive"],
        },
        Case {
            name: "Box-Cox lambda 0",
            make: |_, b| {
                edit_manifest(b, |v| {
                    v["transform"] = serde_json::json!({"kind": "box-cox", "lambda": 0.0})
                })
            },
            bundle: true,
            cmds: BUNDLE,
            want: &["manifest.json", "transform"],
        },
        Case {
            name: "spp that is not a count",
            make: |_, b| edit_manifest(b, |v| v["spp"] = (-4).into()),
            bundle: true,
            cmds: BUNDLE,
            want: &["manifest.json", "bad manifest"],
        },
        Case {
            // A JSON value keeps the last of two equal keys; the manifest must not.
            name: "key given twice",
            make: |_, b| {
                let p = b.join("manifest.json");
                let text = std::fs::read_to_string(&p).unwrap();
                let text = text.replacen("\"spp\": 4,", "\"spp\": 4, \"spp\": 64,", 1);
                std::fs::write(p, text).unwrap();
            },
            bundle: true,
            cmds: BUNDLE,
            want: &["manifest.json", "duplicate field `spp`"],
        },
        Case {
            name: "seconds that do not restate the OPL axis",
            make: |_, b| edit_manifest(b, |v| v["bin_width_seconds"] = 1.0.into()),
            bundle: true,
            cmds: BUNDLE,
            want: &["manifest.json", "bin_width_seconds = 1"],
        },
        Case {
            name: "escape sequence in the scene path",
            make: |_, b| {
                edit_manifest(b, |v| {
                    v["scene"]["path"] = "x.xml\u{1b}[2J\nfake line".into()
                })
            },
            bundle: true,
            cmds: BUNDLE,
            want: &["manifest.json", "\"scene\".\"path\"", "U+001B"],
        },
        Case {
            name: "channels other than RGB",
            make: |_, b| edit_manifest(b, |v| v["channels"] = serde_json::json!(["X", "Y", "Z"])),
            bundle: true,
            cmds: BUNDLE,
            want: &["manifest.json", "channels [\"X\", \"Y\", \"Z\"]"],
        },
        Case {
            name: "scene hash that is not a SHA-256",
            make: |_, b| edit_manifest(b, |v| v["scene"]["sha256"] = "".into()),
            bundle: true,
            cmds: BUNDLE,
            want: &["manifest.json", "not a SHA-256"],
        },
        Case {
            name: "shard index not below the shard count",
            make: |_, b| {
                edit_manifest(
                    b,
                    |v| v["shard"] = serde_json::json!({"job": "0123456789abcdef", "count": 4, "indices": [1, 4]}),
                )
            },
            bundle: true,
            cmds: BUNDLE,
            want: &["manifest.json", "increasing indices below count"],
        },
        Case {
            name: "shard job that is not a job identity",
            make: |_, b| {
                edit_manifest(b, |v| {
                    v["shard"] =
                        serde_json::json!({"job": "x\u{1b}[2J", "count": 4, "indices": [1]})
                })
            },
            bundle: true,
            cmds: BUNDLE,
            want: &["manifest.json"],
        },
        Case {
            name: "merged seeds listed twice",
            make: |_, b| edit_manifest(b, |v| v["merged_seeds"] = serde_json::json!([0, 3, 3])),
            bundle: true,
            cmds: BUNDLE,
            want: &["manifest.json", "seed 3 twice"],
        },
        Case {
            name: "replicates that do not divide spp",
            make: |_, b| edit_manifest(b, |v| v["replicates"] = serde_json::json!(3)),
            bundle: true,
            cmds: BUNDLE,
            want: &["manifest.json", "replicates = 3", "divide spp"],
        },
        Case {
            name: "replicates without r2.npy",
            make: |_, b| edit_manifest(b, |v| v["replicates"] = serde_json::json!(2)),
            bundle: true,
            cmds: BUNDLE,
            want: &["r2"],
        },
        Case {
            name: "array at an absolute path",
            make: |_, b| edit_manifest(b, |v| array_entry(v, "x1")["file"] = "/etc/passwd".into()),
            bundle: true,
            cmds: BUNDLE,
            want: &[
                "manifest.json",
                "\"/etc/passwd\"",
                "not a file name inside the bundle",
            ],
        },
        Case {
            name: "array behind ..",
            make: |_, b| {
                let outside = b.parent().unwrap().join(format!(
                    "{}-x1.npy",
                    b.file_name().unwrap().to_string_lossy()
                ));
                std::fs::copy(b.join("x1.npy"), &outside).unwrap();
                let rel = format!("../{}", outside.file_name().unwrap().to_string_lossy());
                edit_manifest(b, |v| array_entry(v, "x1")["file"] = rel.into());
            },
            bundle: true,
            cmds: BUNDLE,
            want: &["manifest.json", "not a file name inside the bundle"],
        },
        Case {
            name: "array file is a link leading out of the bundle",
            make: |f, b| {
                std::fs::remove_file(b.join("x1.npy")).unwrap();
                std::os::unix::fs::symlink(f.good.join("x1.npy"), b.join("x1.npy")).unwrap();
            },
            bundle: true,
            cmds: BUNDLE,
            want: &["x1.npy", "leads outside the bundle"],
        },
        Case {
            name: "array file is a link to /dev/zero",
            make: |_, b| {
                std::fs::remove_file(b.join("x2.npy")).unwrap();
                std::os::unix::fs::symlink("/dev/zero", b.join("x2.npy")).unwrap();
            },
            bundle: true,
            cmds: BUNDLE,
            want: &["x2.npy", "outside the bundle"],
        },
        Case {
            name: "array listed twice",
            make: |_, b| {
                edit_manifest(b, |v| {
                    let a = v["arrays"].as_array_mut().unwrap();
                    let dup = a[0].clone();
                    a.push(dup);
                })
            },
            bundle: true,
            cmds: BUNDLE,
            want: &["manifest.json", "'x1' twice"],
        },
        Case {
            name: "array not listed",
            make: |_, b| {
                edit_manifest(b, |v| {
                    v["arrays"]
                        .as_array_mut()
                        .unwrap()
                        .retain(|a| a["name"] != "x3")
                })
            },
            bundle: true,
            cmds: BUNDLE,
            want: &["manifest.json", "no array 'x3'"],
        },
        Case {
            name: "array listed with another dtype",
            make: |_, b| edit_manifest(b, |v| array_entry(v, "x1")["dtype"] = "<f4".into()),
            bundle: true,
            cmds: BUNDLE,
            want: &["manifest.json", "'x1' as \"<f4\""],
        },
        Case {
            name: "two arrays in one file",
            make: |_, b| edit_manifest(b, |v| array_entry(v, "x2")["file"] = "x1.npy".into()),
            bundle: true,
            cmds: BUNDLE,
            want: &["manifest.json", "'x1' and 'x2' are both in"],
        },
        Case {
            name: "manifest above the size limit",
            make: |_, b| {
                let p = b.join("manifest.json");
                let mut text = std::fs::read_to_string(&p).unwrap();
                text.push_str(&" ".repeat(17 << 20));
                std::fs::write(p, text).unwrap();
            },
            bundle: true,
            cmds: &[Cmd::Info],
            want: &["manifest.json", "above the limit"],
        },
        Case {
            name: "array file missing",
            make: |_, b| std::fs::remove_file(b.join("depth.npy")).unwrap(),
            bundle: true,
            cmds: BUNDLE,
            want: &["depth.npy", "missing"],
        },
        // ---- the .npy files ----
        Case {
            name: "header declares 10^12 elements in a tiny file",
            make: |_, b| {
                npy_raw(
                    &b.join("x1.npy"),
                    1,
                    &header("<f8", "(100000, 100000, 100, 1)"),
                    &[0; 64],
                )
            },
            bundle: true,
            cmds: BUNDLE,
            want: &["x1.npy", "truncated"],
        },
        Case {
            name: "array truncated to half",
            make: |_, b| {
                let p = b.join("x3.npy");
                let bytes = std::fs::read(&p).unwrap();
                std::fs::write(&p, &bytes[..bytes.len() / 2]).unwrap();
            },
            bundle: true,
            cmds: BUNDLE,
            want: &["x3.npy", "truncated"],
        },
        Case {
            name: "array with trailing bytes",
            make: |_, b| {
                let p = b.join("steady.npy");
                let mut bytes = std::fs::read(&p).unwrap();
                bytes.extend([0u8; 8]);
                std::fs::write(&p, bytes).unwrap();
            },
            bundle: true,
            cmds: BUNDLE,
            want: &["steady.npy", "8 bytes after the data"],
        },
        Case {
            name: "empty array file",
            make: |_, b| std::fs::write(b.join("nonzero.npy"), "").unwrap(),
            bundle: true,
            cmds: BUNDLE,
            want: &["nonzero.npy", "truncated"],
        },
        Case {
            name: "header length field of 4 GiB",
            make: |_, b| {
                let mut v = b"\x93NUMPY\x02\x00".to_vec();
                v.extend(u32::MAX.to_le_bytes());
                v.extend(b"{'descr': '<f8'");
                std::fs::write(b.join("x1.npy"), v).unwrap();
            },
            bundle: true,
            cmds: BUNDLE,
            want: &["x1.npy", "above the limit"],
        },
        Case {
            // ndarray-npy printed a multi-line parser diagram for this one.
            name: "garbage header",
            make: |_, b| {
                npy_raw(
                    &b.join("x1.npy"),
                    1,
                    "{'descr': '<f8', 'fortran_order': False, 'shape': (8, 8, 10, 3 ]]]} \x07\x1b[2J",
                    &[0; 15360],
                )
            },
            bundle: true,
            cmds: BUNDLE,
            want: &["x1.npy", "malformed header"],
        },
        Case {
            name: "deeply nested header",
            make: |_, b| {
                let dict = format!("{{'descr': '<f8', 'shape': {}", "(".repeat(9000));
                npy_raw(&b.join("x1.npy"), 2, &dict, &[]);
            },
            bundle: true,
            cmds: BUNDLE,
            want: &["x1.npy", "malformed header"],
        },
        Case {
            name: "not a .npy file",
            make: |_, b| std::fs::write(b.join("albedo.npy"), "PK\x03\x04 a zip archive").unwrap(),
            bundle: true,
            cmds: BUNDLE,
            want: &["albedo.npy", "not a .npy file"],
        },
        Case {
            name: "f32 data where f64 belongs",
            make: |_, b| {
                npy_raw(
                    &b.join("x2.npy"),
                    1,
                    &header("<f4", "(8, 8, 10, 3)"),
                    &[0; 8 * 8 * 10 * 3 * 4],
                )
            },
            bundle: true,
            cmds: BUNDLE,
            want: &["x2.npy", "dtype \"<f4\""],
        },
        Case {
            name: "big-endian counts",
            make: |_, b| {
                npy_raw(
                    &b.join("nonzero.npy"),
                    1,
                    &header(">u4", "(8, 8, 10)"),
                    &[0; 8 * 8 * 10 * 4],
                )
            },
            bundle: true,
            cmds: BUNDLE,
            want: &["nonzero.npy", "dtype \">u4\""],
        },
        Case {
            name: "zero-size array",
            make: |_, b| npy_raw(&b.join("x1.npy"), 1, &header("<f8", "(0, 8, 10, 3)"), &[]),
            bundle: true,
            cmds: BUNDLE,
            want: &["x1.npy", "shape [0, 8, 10, 3]"],
        },
        Case {
            name: "array file is a directory",
            make: |_, b| {
                std::fs::remove_file(b.join("emitter.npy")).unwrap();
                std::fs::create_dir(b.join("emitter.npy")).unwrap();
            },
            bundle: true,
            cmds: BUNDLE,
            want: &["emitter.npy", "directory"],
        },
        // ---- values no render can write ----
        Case {
            name: "NaN in X2",
            make: |_, b| poke_f64(b, "x2.npy", [3, 5, 7, 1], f64::NAN),
            bundle: true,
            cmds: &[Cmd::Denoise, Cmd::Merge],
            want: &["x2.npy", "voxel (y 3, x 5, t 7, c 1) is NaN"],
        },
        Case {
            name: "infinity in X1",
            make: |_, b| poke_f64(b, "x1.npy", [0, 1, 2, 0], f64::INFINITY),
            bundle: true,
            cmds: VALUES,
            want: &["x1.npy", "voxel (y 0, x 1, t 2, c 0) is +inf"],
        },
        Case {
            // Finite, but its mean is not an f32: the filter turned it into 51
            // non-finite output voxels.
            name: "radiance sum whose mean overflows f32",
            make: |_, b| {
                let [y, x, t] = lit_voxel(b);
                poke_f64(b, "x1.npy", [y, x, t, 1], 1e300)
            },
            bundle: true,
            cmds: VALUES,
            want: &[
                "x1.npy",
                "is 1e300: its mean over 4 samples is beyond the f32 range",
            ],
        },
        Case {
            name: "negative X2",
            make: |_, b| {
                let [y, x, t] = lit_voxel(b);
                poke_f64(b, "x2.npy", [y, x, t, 2], -1e-3)
            },
            bundle: true,
            cmds: &[Cmd::Denoise, Cmd::Merge],
            want: &[
                "x2.npy",
                "is -0.001, but a sum of squares cannot be negative",
            ],
        },
        Case {
            name: "negative R2",
            make: |f, b| {
                std::fs::remove_dir_all(b).unwrap();
                copy_dir(&f.replicates, b);
                let [y, x, t] = lit_voxel(b);
                poke_f64(b, "r2.npy", [y, x, t, 0], -0.5)
            },
            bundle: true,
            cmds: &[Cmd::Denoise],
            want: &["r2.npy", "is -0.5, but a sum of squares cannot be negative"],
        },
        Case {
            name: "R2 in a voxel no sample reached",
            make: |f, b| {
                std::fs::remove_dir_all(b).unwrap();
                copy_dir(&f.replicates, b);
                poke_f64(b, "r2.npy", [0, 0, 0, 1], 0.25)
            },
            bundle: true,
            cmds: &[Cmd::Denoise],
            want: &["r2.npy"],
        },
        Case {
            name: "negative X1 under the identity",
            make: |_, b| {
                let [y, x, t] = lit_voxel(b);
                poke_f64(b, "x1.npy", [y, x, t, 0], -2.5)
            },
            bundle: true,
            cmds: VALUES,
            want: &["x1.npy", "is -2.5", "never negative"],
        },
        Case {
            name: "negative raw sum under Box-Cox",
            make: |f, b| {
                std::fs::remove_dir_all(b).unwrap();
                copy_dir(&f.boxcox, b);
                let [y, x, t] = lit_voxel(b);
                poke_f64(b, "sum.npy", [y, x, t, 1], -1.0)
            },
            bundle: true,
            cmds: &[Cmd::Denoise, Cmd::Export],
            want: &["sum.npy", "radiance is never negative"],
        },
        Case {
            name: "count above spp",
            make: |_, b| poke_counts(b, [2, 2, 2], 5),
            bundle: true,
            cmds: VALUES,
            want: &[
                "nonzero.npy",
                "voxel (y 2, x 2, t 2) counts 5 samples, more than spp = 4",
            ],
        },
        Case {
            name: "sums without counts",
            make: |_, b| poke_counts(b, lit_voxel(b), 0),
            bundle: true,
            cmds: VALUES,
            want: &["x1.npy", "where nonzero.npy counts no samples"],
        },
        Case {
            name: "NaN albedo",
            make: |_, b| poke_f32_3(b, "albedo.npy", [4, 4, 1], f32::NAN),
            bundle: true,
            cmds: BUNDLE,
            want: &["albedo.npy", "pixel (y 4, x 4, c 1) is NaN"],
        },
        Case {
            name: "normal out of range",
            make: |_, b| poke_f32_3(b, "normal.npy", [1, 6, 2], 7.0),
            bundle: true,
            cmds: BUNDLE,
            want: &["normal.npy", "pixel (y 1, x 6, c 2) is 7"],
        },
        Case {
            name: "infinite depth",
            make: |_, b| poke_f32_2(b, "depth.npy", [7, 0], f32::NEG_INFINITY),
            bundle: true,
            cmds: BUNDLE,
            want: &["depth.npy", "pixel (y 7, x 0) is -inf"],
        },
        Case {
            name: "emitter fraction above 1",
            make: |_, b| poke_f32_2(b, "emitter.npy", [0, 0], 2.0),
            bundle: true,
            cmds: BUNDLE,
            want: &["emitter.npy", "pixel (y 0, x 0) is 2"],
        },
        Case {
            name: "NaN steady image",
            make: |_, b| {
                let p = b.join("steady.npy");
                let mut a: ndarray::Array3<f64> = ndarray_npy::read_npy(&p).unwrap();
                a[[5, 3, 0]] = f64::NAN;
                ndarray_npy::write_npy(&p, &a).unwrap();
            },
            bundle: true,
            cmds: BUNDLE,
            want: &["steady.npy", "pixel (y 5, x 3, c 0) is NaN"],
        },
        // ---- merging bundles that do not belong together ----
        Case {
            name: "merge with itself (same seed)",
            make: |_, _| {},
            bundle: true,
            cmds: &[Cmd::Merge],
            want: &["seed 0 appears twice"],
        },
        Case {
            // Each count fits u32 and is at most its bundle's spp; their sum does not.
            name: "merged counts overflowing u32",
            make: |f, b| {
                edit_manifest(b, |v| v["spp"] = u32::MAX.into());
                poke_counts(b, lit_voxel(&f.good2), u32::MAX);
            },
            bundle: true,
            cmds: &[Cmd::Merge],
            want: &["nonzero.npy", "exceeds the u32 range"],
        },
        Case {
            name: "merged spp overflowing u64",
            make: |_, b| edit_manifest(b, |v| v["spp"] = u64::MAX.into()),
            bundle: true,
            cmds: &[Cmd::Merge],
            want: &["merged spp would overflow"],
        },
        Case {
            name: "merge of different film sizes",
            make: |f, b| {
                std::fs::remove_dir_all(b).unwrap();
                let r = render(&f.root, "wide.tstats", &["--seed", "7", "--height", "6"]);
                std::fs::rename(r, b).unwrap();
            },
            bundle: true,
            cmds: &[Cmd::Merge],
            want: &["height differs"],
        },
        // ---- volumes for report compare ----
        Case {
            name: "volume with a NaN",
            make: |f, p| {
                let mut a: ndarray::Array4<f32> = ndarray_npy::read_npy(&f.volume).unwrap();
                a[[6, 2, 4, 1]] = f32::NAN;
                ndarray_npy::write_npy(p, &a).unwrap();
            },
            bundle: false,
            cmds: VOLUME,
            want: &["voxel (y 6, x 2, t 4, c 1) is NaN"],
        },
        Case {
            name: "f64 volume beyond the f32 range",
            make: |f, p| {
                let a: ndarray::Array4<f32> = ndarray_npy::read_npy(&f.volume).unwrap();
                let mut a = a.mapv(f64::from);
                a[[0, 0, 9, 2]] = 1e39;
                ndarray_npy::write_npy(p, &a).unwrap();
            },
            bundle: false,
            cmds: VOLUME,
            want: &["voxel (y 0, x 0, t 9, c 2) is 1e39, beyond the f32 range"],
        },
        Case {
            name: "empty volume",
            make: |_, p| npy_raw(p, 1, &header("<f4", "(0, 8, 10, 3)"), &[]),
            bundle: false,
            cmds: VOLUME,
            want: &["holds no voxels"],
        },
        Case {
            name: "volume header declaring 10^12 voxels",
            make: |_, p| npy_raw(p, 1, &header("<f4", "(100000, 100000, 100, 3)"), &[0; 256]),
            bundle: false,
            cmds: VOLUME,
            want: &["truncated"],
        },
        Case {
            name: "volume of the wrong rank",
            make: |_, p| npy_raw(p, 1, &header("<f4", "(8, 30)"), &[0; 8 * 30 * 4]),
            bundle: false,
            cmds: VOLUME,
            want: &["expected a volume (H, W, T, C)"],
        },
        Case {
            name: "volume of rank 5 that is not RGB x Stokes",
            make: |_, p| {
                npy_raw(
                    p,
                    1,
                    &header("<f4", "(4, 4, 5, 3, 3)"),
                    &[0; 4 * 4 * 5 * 9 * 4],
                )
            },
            bundle: false,
            cmds: VOLUME,
            want: &["expected a volume (H, W, T, C)", "[4, 4, 5, 3, 3]"],
        },
        Case {
            name: "volume of 5 channels",
            make: |_, p| {
                npy_raw(
                    p,
                    1,
                    &header("<f4", "(4, 4, 5, 5)"),
                    &[0; 4 * 4 * 5 * 5 * 4],
                )
            },
            bundle: false,
            cmds: VOLUME,
            want: &["expected a volume (H, W, T, C)", "[4, 4, 5, 5]"],
        },
        Case {
            name: "volume of integers",
            make: |_, p| {
                npy_raw(
                    p,
                    1,
                    &header("<i8", "(8, 8, 10, 3)"),
                    &[0; 8 * 8 * 10 * 3 * 8],
                )
            },
            bundle: false,
            cmds: VOLUME,
            want: &["dtype \"<i8\""],
        },
        Case {
            name: "volume is a link to /dev/zero",
            make: |_, p| std::os::unix::fs::symlink("/dev/zero", p).unwrap(),
            bundle: false,
            cmds: VOLUME,
            want: &["not a regular file"],
        },
    ]
}

/// The command line of `cmd` on `input`, and the outputs it would write.
fn command(f: &Fixture, cmd: Cmd, input: &Path, out: &Path) -> (Vec<String>, Vec<PathBuf>) {
    let i = s(input);
    match cmd {
        Cmd::Info => (vec!["info".into(), i], vec![]),
        Cmd::Denoise => {
            let o = out.join("den.npy");
            (vec!["denoise".into(), i, "--out".into(), s(&o)], vec![o])
        }
        Cmd::Export => {
            let (o, st) = (out.join("noisy.npy"), out.join("steady.npy"));
            let args = vec![
                "export".into(),
                i,
                "--out".into(),
                s(&o),
                "--steady".into(),
                s(&st),
            ];
            (args, vec![o, st])
        }
        Cmd::Merge => {
            let o = out.join("merged.tstats");
            let args = vec!["merge".into(), i, s(&f.good2), "--out".into(), s(&o)];
            (args, vec![o])
        }
        Cmd::CompareRef => (
            vec![
                "report".into(),
                "compare".into(),
                "--reference".into(),
                i,
                "--input".into(),
                format!("noisy={}", s(&f.volume)),
            ],
            vec![],
        ),
        Cmd::CompareInput => (
            vec![
                "report".into(),
                "compare".into(),
                "--reference".into(),
                s(&f.volume),
                "--input".into(),
                format!("bad={i}"),
            ],
            vec![],
        ),
    }
}

/// stderr lines a failing command may print before its error: `denoise` reports the
/// bundle's size once the manifest and headers are checked, before the values are
/// read (a CLI line outside this test's scope).
fn informative(line: &str) -> bool {
    line.contains("denoiser memory")
}

#[test]
fn hostile_bundles_npy_files_and_volumes_fail_cleanly() {
    let start = Instant::now();
    let f = fixture();
    let mut failures = Vec::new();
    let mut runs = 0;
    let all = cases();
    assert!(all.len() >= 20);
    for (k, case) in all.iter().enumerate() {
        let dir = f.root.join(format!("case{k:02}"));
        std::fs::create_dir(&dir).unwrap();
        let input = if case.bundle {
            let b = dir.join("in.tstats");
            copy_dir(&f.good, &b);
            b
        } else {
            dir.join("in.npy")
        };
        (case.make)(&f, &input);
        for &cmd in case.cmds {
            let out = dir.join(format!("out-{cmd:?}"));
            std::fs::create_dir(&out).unwrap();
            let (mut args, outputs) = command(&f, cmd, &input, &out);
            if case.name.starts_with("merge with itself") {
                args[2] = s(&input);
            }
            let r = tstat(&args, &out);
            runs += 1;
            let lines: Vec<&str> = r.stderr.lines().filter(|l| !l.trim().is_empty()).collect();
            let errors: Vec<&&str> = lines.iter().filter(|l| l.starts_with("error:")).collect();
            let mut problems = Vec::new();
            if r.code != Some(1) {
                problems.push(format!("exit {:?} (stdout {:?})", r.code, r.stdout));
            }
            if r.stderr.contains("panicked") {
                problems.push("panicked".into());
            }
            if errors.len() != 1 || lines.last() != errors.first().copied() {
                problems.push("not exactly one error line, last".into());
            }
            if let Some(l) = lines
                .iter()
                .find(|l| !l.starts_with("error:") && !informative(l))
            {
                problems.push(format!("extra stderr line {l:?}"));
            }
            if let Some(e) = errors.first() {
                for w in case.want {
                    if !e.contains(w) {
                        problems.push(format!("no {w:?} in the error"));
                    }
                }
            }
            for o in &outputs {
                if o.exists() {
                    problems.push(format!("{} was written", o.display()));
                }
            }
            let left: Vec<_> = std::fs::read_dir(&out)
                .unwrap()
                .flatten()
                .map(|e| e.file_name())
                .collect();
            if !left.is_empty() {
                problems.push(format!("left behind in the output directory: {left:?}"));
            }
            if !problems.is_empty() {
                failures.push(format!(
                    "{} / {cmd:?}: {}\n    stderr: {:?}",
                    case.name,
                    problems.join("; "),
                    r.stderr
                ));
            }
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {runs} runs failed:\n{}",
        failures.len(),
        failures.join("\n")
    );
    eprintln!(
        "{} cases, {runs} runs in {:.1} s",
        all.len(),
        start.elapsed().as_secs_f64()
    );
}

/// Legal but unusual bundles load: unknown extra manifest fields (ignored, for
/// forward compatibility), arrays in Fortran order (NumPy may write them), an array
/// file that is a link inside the bundle, negative X1 under Box-Cox.
#[test]
fn legal_but_unusual_bundles_load() {
    let f = fixture();
    let b = f.root.join("unusual.tstats");
    copy_dir(&f.good, &b);
    edit_manifest(&b, |v| {
        v["comment"] = "annotated by hand".into();
        v["extra"] = serde_json::json!({"nested": [1, 2, 3]});
    });
    let x2: ndarray::Array4<f64> = ndarray_npy::read_npy(b.join("x2.npy")).unwrap();
    let fortran = x2.t().as_standard_layout().into_owned().reversed_axes();
    assert!(!fortran.is_standard_layout());
    ndarray_npy::write_npy(b.join("x2.npy"), &fortran).unwrap();
    std::fs::rename(b.join("x3.npy"), b.join("x3-data.npy")).unwrap();
    std::os::unix::fs::symlink("x3-data.npy", b.join("x3.npy")).unwrap();
    let den = f.root.join("unusual.npy");
    for args in [
        vec!["info".to_string(), s(&b)],
        vec!["denoise".into(), s(&b), "--out".into(), s(&den)],
    ] {
        let r = tstat(&args, &f.root);
        assert_eq!(r.code, Some(0), "{args:?}: {}", r.stderr);
    }
    let a: ndarray::Array4<f32> = ndarray_npy::read_npy(&den).unwrap();
    assert!(a.iter().all(|v| v.is_finite()));
    // Box-Cox: transformed values range down to -1/lambda, so X1 may be negative.
    let bc = f.root.join("bc.tstats");
    copy_dir(&f.boxcox, &bc);
    let [y, x, t] = lit_voxel(&bc);
    poke_f64(&bc, "x1.npy", [y, x, t, 0], -1.5);
    let r = tstat(
        &[
            "denoise".into(),
            s(&bc),
            "--out".into(),
            s(&f.root.join("bc.npy")),
        ],
        &f.root,
    );
    assert_eq!(r.code, Some(0), "{}", r.stderr);
    // Identical volumes compare with an infinite PSNR (legitimately).
    let r = tstat(
        &[
            "report".into(),
            "compare".into(),
            "--reference".into(),
            s(&f.volume),
            "--input".into(),
            format!("same={}", s(&f.volume)),
        ],
        &f.root,
    );
    assert_eq!(r.code, Some(0), "{}", r.stderr);
    assert!(r.stdout.contains("inf"), "{}", r.stdout);
}
