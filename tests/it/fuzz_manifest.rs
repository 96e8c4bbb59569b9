//! Fuzzing of manifests and shard records (issue 41), in the style of `tests/it/fuzz.rs`:
//! property tests that mutate the manifests of small valid NLOS capture bundles (a
//! capture, a shard of a job, a merge of two renders) -- JSON-aware mutations that put
//! NaN, infinities, 1e300, -0, long lists and control characters where numbers, lists
//! and strings were, and byte mutations of the text -- and shard records, calling the
//! library in-process. Each case must give a clean one-line error or a valid result:
//!
//! - a manifest that the reader accepts ([`parse_manifest`]) is accepted by the writer
//!   ([`manifest_json`]) and reads back as the same manifest, whose text is written
//!   again identically (the write/read symmetry); written into its bundle it opens or
//!   is refused cleanly, and a capture that opens gives finite geometry and times;
//! - shard records that validate merge into a record that validates, or are refused
//!   naming an input among those given.
//!
//! CI runs 1500 + 1500 + 3000 cases (a few seconds); a longer campaign:
//! `TSTAT_FUZZ_CASES=50000 TSTAT_FUZZ_SEED=$RANDOM cargo test --release --test fuzz_manifest`.

use crate::common::fuzz_runner;

use proptest::prelude::*;
use proptest::test_runner::TestCaseError;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use tstat::bundle::read::{check_shard_record, manifest_json, parse_manifest};
use tstat::bundle::shard::{merge_records, ShardRecord};
use tstat::bundle::Bundle;

/// This target's runner (see `common/fuzz_runner.rs`).
fn runner(default_cases: u32) -> proptest::test_runner::TestRunner {
    fuzz_runner::runner(default_cases, 20261206)
}

fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_tstat")
}

fn tstat(dir: &Path, args: &[&str]) {
    let out = std::process::Command::new(bin())
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The base bundles, rendered once: a confocal capture (c.tstats), shard 0 of 2 of a
/// job (s0.tstats), and the merge of two captures (m.tstats, with merged_seeds).
fn bundles(dir: &Path) -> Vec<PathBuf> {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/nlos_T.xml");
    let scene = scene.to_str().unwrap();
    let small = ["-D", "res=4", "-D", "bins=8", "-D", "spp=4"];
    let render = |out: &str, extra: &[&str]| {
        let mut args = vec!["render", scene];
        args.extend(small);
        args.extend(extra);
        args.extend(["--out", out]);
        tstat(dir, &args);
    };
    render("c.tstats", &["--seed", "1"]);
    render("c2.tstats", &["--seed", "2"]);
    render("s0.tstats", &["--shard", "0/2", "--seed", "3"]);
    tstat(
        dir,
        &["merge", "c.tstats", "c2.tstats", "--out", "m.tstats"],
    );
    ["c.tstats", "s0.tstats", "m.tstats"]
        .iter()
        .map(|n| dir.join(n))
        .collect()
}

/// Tokens put in place of a value, raw (not JSON values: NaN is no JSON).
const RAW: &[&str] = &[
    "NaN",
    "-NaN",
    "nan",
    "Infinity",
    "-Infinity",
    "inf",
    "1e300",
    "-1e300",
    "1e999",
    "-1e999",
    "1e15",
    "-1e15",
    "9.99e14",
    "1e-320",
    "-0",
    "-0.0",
    "0",
    "0.0",
    "-1",
    "1",
    "2",
    "18446744073709551615",
    "18446744073709551616",
    "4294967296",
    "4294967297",
    "null",
    "true",
    "\"NaN\"",
    "\"1e300\"",
    "\"\"",
    "\"a\\nb\"",
    "\"\\u0000\"",
    "\"\\u001b[31m\"",
    "\"\\u0085\"",
    "\"0123456789abcdef\"",
    "[]",
    "{}",
    "[null]",
    "[1e300,0,0]",
    "[0,0,1]",
    "[[1e300,0,0]]",
    "[NaN,0,0]",
];

/// One edit of a manifest.
#[derive(Clone, Debug)]
enum Edit {
    /// Replace the value at the k-th pointer with a raw token.
    Raw { k: usize, token: usize },
    /// Remove the k-th pointer's entry (an object key) or empty it (an array).
    Remove { k: usize },
    /// Replace the k-th pointer's array with `len` copies of its first element (or of
    /// 0), optionally with a repeat at the end: lists of up to a million entries.
    Grow { k: usize, len: usize, repeat: bool },
    /// Replace the k-th pointer's value with an increasing or decreasing list.
    Range { k: usize, len: usize, rev: bool },
    /// Byte edits of the text.
    Bytes(Vec<ByteEdit>),
}

#[derive(Clone, Debug)]
enum ByteEdit {
    Delete { at: f64, len: usize },
    Insert { at: f64, bytes: Vec<u8> },
    Flip { at: f64, bit: u8 },
}

fn edit() -> impl Strategy<Value = Edit> {
    let k = 0..100_000usize;
    let byte = prop_oneof![
        (0.0..1.0f64, 1..16usize).prop_map(|(at, len)| ByteEdit::Delete { at, len }),
        (0.0..1.0f64, prop::collection::vec(any::<u8>(), 1..6))
            .prop_map(|(at, bytes)| ByteEdit::Insert { at, bytes }),
        (0.0..1.0f64, 0..8u8).prop_map(|(at, bit)| ByteEdit::Flip { at, bit }),
    ];
    // Lists of a million entries are the corpus's (tests/it/hostile_manifest.rs) and the
    // unit tests'; here 200 000, rarely, to keep the default run short.
    let len = prop_oneof![
        8 => 0..4usize,
        8 => 0..100usize,
        1 => Just(200_000usize),
    ];
    prop_oneof![
        6 => (k.clone(), 0..RAW.len()).prop_map(|(k, token)| Edit::Raw { k, token }),
        1 => k.clone().prop_map(|k| Edit::Remove { k }),
        1 => (k.clone(), len.clone(), any::<bool>()).prop_map(|(k, len, repeat)| Edit::Grow { k, len, repeat }),
        1 => (k, len, any::<bool>()).prop_map(|(k, len, rev)| Edit::Range { k, len, rev }),
        1 => prop::collection::vec(byte, 1..4).prop_map(Edit::Bytes),
    ]
}

/// Every JSON pointer of a value (objects and arrays, recursively).
fn pointers(v: &Value, at: String, out: &mut Vec<String>) {
    match v {
        Value::Object(m) => {
            for (k, x) in m {
                let p = format!("{at}/{}", k.replace('~', "~0").replace('/', "~1"));
                out.push(p.clone());
                pointers(x, p, out);
            }
        }
        Value::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                let p = format!("{at}/{i}");
                out.push(p.clone());
                pointers(x, p, out);
            }
        }
        _ => {}
    }
}

fn pos(at: f64, len: usize) -> usize {
    ((at * len as f64) as usize).min(len)
}

/// The manifest text after `edits` (raw tokens go in through markers).
fn apply(base: &Value, edits: &[Edit]) -> String {
    let mut m = base.clone();
    let mut raws: Vec<&str> = Vec::new();
    let mut bytes: Vec<ByteEdit> = Vec::new();
    for e in edits {
        let mut paths = Vec::new();
        pointers(&m, String::new(), &mut paths);
        if paths.is_empty() {
            continue;
        }
        let at = |k: &usize| paths[k % paths.len()].clone();
        match e {
            Edit::Raw { k, token } => {
                if let Some(v) = m.pointer_mut(&at(k)) {
                    *v = json!(format!("@@RAW{}@@", raws.len()));
                    raws.push(RAW[*token]);
                }
            }
            Edit::Remove { k } => {
                let p = at(k);
                let (parent, key) = p.rsplit_once('/').unwrap();
                match m.pointer_mut(parent) {
                    Some(Value::Object(o)) => {
                        o.remove(&key.replace("~1", "/").replace("~0", "~"));
                    }
                    Some(Value::Array(a)) => a.clear(),
                    _ => {}
                }
            }
            Edit::Grow { k, len, repeat } => {
                if let Some(v) = m.pointer_mut(&at(k)) {
                    let first = match &*v {
                        Value::Array(a) => a.first().cloned().unwrap_or(json!(0)),
                        other => other.clone(),
                    };
                    // Big elements only a few times (the reader's size limit is
                    // tested elsewhere; here the checks of long lists are).
                    let len = if first.is_number() {
                        *len
                    } else {
                        (*len).min(1000)
                    };
                    let mut a = vec![first.clone(); len];
                    if *repeat {
                        a.push(first);
                    }
                    *v = Value::Array(a);
                }
            }
            Edit::Range { k, len, rev } => {
                if let Some(v) = m.pointer_mut(&at(k)) {
                    let mut a: Vec<u64> = (0..*len as u64).collect();
                    if *rev {
                        a.reverse();
                    }
                    *v = Value::from(a);
                }
            }
            Edit::Bytes(b) => bytes.extend(b.iter().cloned()),
        }
    }
    let mut text = serde_json::to_string(&m).unwrap();
    for (i, r) in raws.iter().enumerate() {
        text = text.replacen(&format!("\"@@RAW{i}@@\""), r, 1);
    }
    let mut b = text.into_bytes();
    for e in &bytes {
        let n = b.len();
        match e {
            ByteEdit::Delete { at, len } => {
                let s = pos(*at, n);
                b.drain(s..(s + len).min(n));
            }
            ByteEdit::Insert { at, bytes } => {
                let s = pos(*at, n);
                b.splice(s..s, bytes.iter().copied());
            }
            ByteEdit::Flip { at, bit } => {
                if n > 0 {
                    b[pos(*at, n - 1)] ^= 1 << bit;
                }
            }
        }
    }
    String::from_utf8_lossy(&b).into_owned()
}

/// A clean error: one line, not empty, of a readable length.
fn clean(msg: &str) -> Result<(), TestCaseError> {
    prop_assert!(
        !msg.is_empty() && !msg.contains('\n') && msg.len() < 2000,
        "not a clean one-line error: {:?}",
        msg.chars().take(3000).collect::<String>()
    );
    Ok(())
}

/// The property of one manifest text: refused cleanly, or valid, written back
/// identically, and (in its bundle) opened or refused cleanly, with finite capture
/// geometry when it opens.
fn check_text(text: &str, bundle: &Path, work: &Path) -> Result<(), TestCaseError> {
    let m = match parse_manifest(text) {
        Err(e) => return clean(&e.to_string()),
        Ok(m) => m,
    };
    // Symmetry: what the reader accepts, the writer writes, and it reads back the same.
    let json = manifest_json(&m).map_err(|e| {
        TestCaseError::fail(format!("the reader accepts what the writer refuses: {e}"))
    })?;
    let back = parse_manifest(&json)
        .map_err(|e| TestCaseError::fail(format!("the written manifest is refused: {e}")))?;
    prop_assert_eq!(&back, &m, "read back differently");
    prop_assert_eq!(
        manifest_json(&back).unwrap(),
        json,
        "written differently the second time"
    );
    // In its bundle (the arrays may no longer fit the manifest: that is refused).
    let _ = std::fs::remove_dir_all(work);
    std::fs::create_dir(work).unwrap();
    for e in std::fs::read_dir(bundle).unwrap().flatten() {
        if e.file_name() != "manifest.json" {
            std::fs::hard_link(e.path(), work.join(e.file_name())).unwrap();
        }
    }
    std::fs::write(work.join("manifest.json"), text).unwrap();
    match Bundle::open(work) {
        Err(e) => clean(&e.to_string())?,
        Ok(b) => {
            if let Some(rec) = &b.manifest.nlos {
                let [sx, sy] = rec.sensor_grid;
                for (x, y) in [(0, 0), (sx - 1, sy - 1)] {
                    let p = rec.sensor_point(x, y);
                    prop_assert!(p.iter().all(|v| v.is_finite()), "sensor point {p:?}");
                }
                match tstat::nlos::capture::Capture::from_bundle(&b) {
                    Err(e) => clean(&e.to_string())?,
                    Ok(c) => {
                        let finite = |p: &[f32; 3]| p.iter().all(|v| v.is_finite());
                        prop_assert!(c.sensor_grid.iter().all(finite), "sensor grid");
                        prop_assert!(c.laser_grid.iter().all(finite), "laser grid");
                        prop_assert!(c.h.iter().all(|v| v.is_finite()), "H");
                        let end = c.time.start_opl + c.time.bins as f64 * c.time.bin_width_opl;
                        prop_assert!(c.time.bin_width_opl > 0.0 && end.is_finite(), "time axis");
                    }
                }
            }
        }
    }
    Ok(())
}

#[test]
fn mutated_manifests_are_refused_cleanly_or_read_back_as_written() {
    let dir = tempfile::tempdir().unwrap();
    let bases = bundles(dir.path());
    let values: Vec<Value> = bases
        .iter()
        .map(|b| {
            serde_json::from_str(&std::fs::read_to_string(b.join("manifest.json")).unwrap())
                .unwrap()
        })
        .collect();
    // The bases themselves: valid, and symmetric.
    for (b, v) in bases.iter().zip(&values) {
        check_text(&v.to_string(), b, &dir.path().join("work.tstats")).unwrap();
    }
    let work = dir.path().join("work.tstats");
    runner(1500)
        .run(
            &(0..bases.len(), prop::collection::vec(edit(), 1..4)),
            |(k, edits)| {
                let text = apply(&values[k], &edits);
                check_text(&text, &bases[k], &work)
            },
        )
        .unwrap();
}

/// Manifests that stay valid: only numbers of the capture geometry and time axis
/// change, to values in and beyond the bounds, so the symmetry is exercised on many
/// accepted manifests (most random edits are refused).
#[test]
fn valid_manifests_write_back_as_read() {
    let dir = tempfile::tempdir().unwrap();
    let bases = bundles(dir.path());
    let base: Value =
        serde_json::from_str(&std::fs::read_to_string(bases[0].join("manifest.json")).unwrap())
            .unwrap();
    let fields = [
        "/nlos/sensor_origin/0",
        "/nlos/laser_origin/1",
        "/nlos/wall_corner/2",
        "/nlos/wall_du/0",
        "/nlos/wall_dv/1",
        "/start_opl",
        "/bin_width_opl",
        "/render_seconds",
    ];
    let number = prop_oneof![
        any::<f64>(),
        -1e16..1e16f64,
        -10.0..10.0f64,
        Just(-0.0),
        Just(f64::MIN_POSITIVE),
        Just(5e-324)
    ];
    let work = dir.path().join("work.tstats");
    let accepted = std::cell::Cell::new(0u32);
    runner(1500)
        .run(
            &prop::collection::vec((0..fields.len(), number), 1..4),
            |edits| {
                let mut m = base.clone();
                for (f, v) in &edits {
                    if v.is_finite() {
                        *m.pointer_mut(fields[*f]).unwrap() = json!(v);
                    }
                }
                // The seconds restate the OPL axis (as a writer computes them).
                let c = 299_792_458.0;
                let unit = m["unit_m"].as_f64().unwrap();
                for (s, o) in [
                    ("start_seconds", "start_opl"),
                    ("bin_width_seconds", "bin_width_opl"),
                ] {
                    m[s] = json!(m[o].as_f64().unwrap() * unit / c);
                }
                let text = m.to_string();
                if parse_manifest(&text).is_ok() {
                    accepted.set(accepted.get() + 1);
                }
                check_text(&text, &bases[0], &work)
            },
        )
        .unwrap();
    let accepted = accepted.get();
    assert!(accepted > 100, "only {accepted} accepted manifests");
}

fn shard_record() -> impl Strategy<Value = ShardRecord> {
    let job = prop_oneof![
        Just("0123456789abcdef".to_string()),
        Just("fedcba9876543210".to_string()),
        Just("0123456789ABCDEF".to_string()),
        Just("xyz".to_string()),
        Just(String::new()),
    ];
    let count = prop_oneof![
        1..6u64,
        Just(0u64),
        Just(1u64 << 32),
        Just((1u64 << 32) + 1),
        Just(u64::MAX)
    ];
    let indices = prop_oneof![
        prop::collection::vec(0..8u64, 0..6),
        prop::collection::vec(any::<u64>(), 0..4),
        (0..3u64, 1..3u64, 0..20_000usize)
            .prop_map(|(s, step, n)| (0..n as u64).map(|i| s + step * i).collect()),
    ];
    (job, count, indices, any::<bool>()).prop_map(|(job, count, mut indices, sort)| {
        if sort {
            indices.sort_unstable();
            indices.dedup();
        }
        ShardRecord {
            job,
            count,
            indices,
        }
    })
}

#[test]
fn shard_records_validate_and_merge_cleanly() {
    runner(3000)
        .run(
            &(
                prop::collection::vec(prop::option::weighted(0.9, shard_record()), 1..5),
                any::<bool>(),
            ),
            |(records, partial)| {
                // Only records that a bundle could hold reach a merge (Bundle::open
                // validates them).
                let mut valid = Vec::new();
                for r in records.iter() {
                    match r {
                        Some(r) => match check_shard_record(r) {
                            Ok(()) => valid.push(Some(r)),
                            Err(e) => clean(&e.to_string())?,
                        },
                        None => valid.push(None),
                    }
                }
                match merge_records(&valid, partial) {
                    Ok(Some(merged)) => {
                        prop_assert!(
                            check_shard_record(&merged).is_ok(),
                            "the merged record is refused: {:?}",
                            check_shard_record(&merged).unwrap_err().to_string()
                        );
                        let n: usize = valid.iter().flatten().map(|r| r.indices.len()).sum();
                        prop_assert_eq!(merged.indices.len(), n);
                    }
                    Ok(None) => {}
                    Err(e) => {
                        clean(&e.to_string())?;
                        if let Some(i) = e.input {
                            prop_assert!(valid[i].is_some(), "blames a bundle without a record");
                        }
                    }
                }
                Ok(())
            },
        )
        .unwrap();
}
