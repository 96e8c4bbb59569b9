//! Hostile manifests and shard records, and renders whose manifest could not be read
//! back (issue 41): a table of cases run through the real binary, each of which must
//! fail with exit 1, exactly one `error:` line (the last; only `warning:` lines may
//! precede it), no panic, within 20 s under a 2 GB address-space limit, and without
//! leaving anything behind (for renders: no bundle, no temporary directory; the whole
//! working directory is compared before and after).
//!
//! The reader and the writers share one check (`bundle::read::parse_manifest` /
//! `manifest_json`, docs/bundle.md "Bounds"): a render refuses up front what the reader
//! would refuse, and the reader refuses non-finite or absurd values (a relay wall of
//! 1e300, a bin width of 0) and answers quickly on lists of a million entries.

use crate::common::hostile;
use hostile::{bin, limited, run, snapshot, Run, TIME_LIMIT};
use serde_json::{json, Value};
use std::path::Path;
use std::process::Command;

fn s(p: &Path) -> String {
    p.to_str().unwrap().to_string()
}

/// The problems of a run that should have failed cleanly with `want` in its error.
fn failure_problems(r: &Run, want: &[&str]) -> Vec<String> {
    let mut problems = Vec::new();
    if r.timed_out {
        problems.push(format!("killed after {TIME_LIMIT:?}"));
    }
    if r.code != Some(1) {
        problems.push(format!("exit {:?}, expected 1", r.code));
    }
    if r.stderr.contains("panicked") {
        problems.push("panicked".into());
    }
    let lines: Vec<&str> = r.stderr.lines().filter(|l| !l.trim().is_empty()).collect();
    let errors: Vec<&&str> = lines.iter().filter(|l| l.starts_with("error:")).collect();
    if errors.len() != 1 || lines.last() != errors.first().copied() {
        problems.push("not exactly one error line, last".into());
    }
    if let Some(l) = lines
        .iter()
        .find(|l| !l.starts_with("error:") && !l.starts_with("warning:"))
    {
        problems.push(format!("extra stderr line {l:?}"));
    }
    if let Some(e) = errors.first() {
        // One line, of a readable length, whatever the size of the list at fault.
        if e.len() > 1000 {
            problems.push(format!("an error line of {} bytes", e.len()));
        }
        for w in want {
            if !e.contains(w) {
                problems.push(format!("no {w:?} in the error"));
            }
        }
    }
    problems
}

/// The NLOS scene of the fixture: scenes/nlos_T.xml with a string default `tag` (used
/// in a shape's id) so that any text can reach the manifest through `-D tag=...`.
fn nlos_scene() -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/nlos_T.xml");
    std::fs::read_to_string(path)
        .unwrap()
        .replace("id=\"t_bar\"", "id=\"t_bar$tag\"")
        .replace(
            "<default name=\"res\" value=\"32\"/>",
            "<default name=\"res\" value=\"32\"/>\n    <default name=\"tag\" value=\"\"/>",
        )
}

/// The error of a render refused up front.
const UNWRITABLE: &str = "refusing to write a bundle that could not be read back";
/// The rule of a coordinate beyond the bounds.
const MAG: &str = "must be finite and of magnitude below 1e15";

/// The small settings of every render here: 4 x 4 points, 8 bins, 4 spp.
const SMALL: [&str; 6] = ["-D", "res=4", "-D", "bins=8", "-D", "spp=4"];

/// Valid inputs, built once: the scene s.xml and two bundles of it, good.tstats (seed
/// 0) and good2.tstats (seed 5), a confocal capture of 4 x 4 points.
fn fixture() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("s.xml"), nlos_scene()).unwrap();
    for (name, seed) in [("good.tstats", "0"), ("good2.tstats", "5")] {
        let mut args: Vec<String> = vec!["render".into(), "s.xml".into()];
        args.extend(SMALL.iter().map(|a| a.to_string()));
        args.extend(["--seed".into(), seed.into(), "--out".into(), name.into()]);
        let out = Command::new(bin())
            .args(&args)
            .current_dir(d)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    dir
}

/// A render case: the scene file's name and text (None: s.xml), extra arguments (a
/// `-D` of res, bins or spp replaces [`SMALL`]'s), and pieces of the error.
struct RenderCase {
    name: &'static str,
    scene: Option<(&'static str, String)>,
    args: Vec<String>,
    want: &'static [&'static str],
}

/// [`SMALL`] without the `-D`s that `args` gives, then `args`.
fn with_small(args: &[String]) -> Vec<String> {
    let given = |name: &str| {
        args.windows(2)
            .any(|w| w[0] == "-D" && w[1].starts_with(&format!("{name}=")))
    };
    let mut out = Vec::new();
    for pair in SMALL.chunks(2) {
        let name = pair[1].split('=').next().unwrap();
        if !given(name) {
            out.extend(pair.iter().map(|a| a.to_string()));
        }
    }
    out.extend(args.iter().cloned());
    out
}

fn render_cases() -> Vec<RenderCase> {
    let base = nlos_scene();
    let d = |v: &str| vec!["-D".to_string(), format!("tag={v}")];
    let flags = |f: &[&str]| f.iter().map(|a| a.to_string()).collect::<Vec<_>>();
    let control = |code: &'static str| -> &'static [&'static str] {
        match code {
            "000A" => &["refusing to write", "control character U+000A"],
            "0009" => &["refusing to write", "control character U+0009"],
            "001B" => &["refusing to write", "control character U+001B"],
            "007F" => &["refusing to write", "control character U+007F"],
            "0085" => &["refusing to write", "control character U+0085"],
            "000D" => &["refusing to write", "control character U+000D"],
            _ => unreachable!(),
        }
    };
    // The laser: placed at a translation the loader adds to its look-at.
    let laser_at = |t: &str| {
        base.replace(
            "<lookat origin=\"-2, 0, 2\" target=\"0, 0, 0\" up=\"0, 1, 0\"/>",
            &format!("<lookat origin=\"-2, 0, 2\" target=\"0, 0, 0\" up=\"0, 1, 0\"/>{t}"),
        )
    };
    let exhaustive = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/nlos_T_exhaustive.xml"),
    )
    .unwrap();
    let scan = |fov: &str| {
        exhaustive.replace(
            "<boolean name=\"account_first_and_last_bounces\" value=\"false\"/>",
            &format!("<boolean name=\"account_first_and_last_bounces\" value=\"false\"/><boolean name=\"force_equal_illumination_scanning\" value=\"false\"/><float name=\"illumination_scan_fov\" value=\"{fov}\"/>"),
        )
    };
    vec![
        RenderCase {
            name: "-D value with a newline",
            scene: None,
            args: d("a\nb"),
            want: control("000A"),
        },
        RenderCase {
            name: "-D value that is only a newline",
            scene: None,
            args: d("\n"),
            want: control("000A"),
        },
        RenderCase {
            name: "-D value with a tab",
            scene: None,
            args: d("a\tb"),
            want: control("0009"),
        },
        RenderCase {
            name: "-D value with a terminal escape",
            scene: None,
            args: d("\u{1b}[31mred"),
            want: control("001B"),
        },
        RenderCase {
            name: "-D value with DEL",
            scene: None,
            args: d("a\u{7f}"),
            want: control("007F"),
        },
        RenderCase {
            name: "-D value with a C1 control (NEL)",
            scene: None,
            args: d("a\u{85}b"),
            want: control("0085"),
        },
        RenderCase {
            name: "-D spp=4 and a newline (the integer parses, the manifest would not)",
            scene: None,
            args: flags(&["-D", "spp=4\n"]),
            want: control("000A"),
        },
        RenderCase {
            name: "scene path with a newline",
            scene: Some(("s\nx.xml", base.clone())),
            args: vec![],
            want: control("000A"),
        },
        RenderCase {
            name: "scene path with a carriage return",
            scene: Some(("s\rx.xml", base.clone())),
            args: vec![],
            want: control("000D"),
        },
        RenderCase {
            name: "scene path with a terminal escape",
            scene: Some(("s\u{1b}]0;x\u{7}.xml", base.clone())),
            args: vec![],
            want: control("001B"),
        },
        RenderCase {
            name: "scene path with a tab",
            scene: Some(("s\tx.xml", base.clone())),
            args: vec![],
            want: control("0009"),
        },
        RenderCase {
            name: "laser translated to infinity (3e38 + 3e38)",
            scene: Some((
                "inf.xml",
                laser_at("<translate z=\"3e38\"/><translate z=\"3e38\"/>"),
            )),
            args: vec![],
            want: &["beyond"],
        },
        RenderCase {
            name: "laser translated to -3e38",
            scene: Some(("neg.xml", laser_at("<translate x=\"-3e38\"/>"))),
            args: vec![],
            want: &["beyond"],
        },
        RenderCase {
            name: "laser at 1e20",
            scene: Some(("far.xml", laser_at("<translate y=\"1e20\"/>"))),
            args: vec![],
            want: &["beyond"],
        },
        RenderCase {
            name: "laser scan of 170 degrees: rays miss the wall",
            scene: Some(("scan.xml", scan("170"))),
            args: flags(&["-D", "res=2"]),
            want: &["rays meet nothing", "illumination_scan_fov"],
        },
        RenderCase {
            name: "laser scan of 100 degrees: some rays miss the wall",
            scene: Some(("scan.xml", scan("100"))),
            args: flags(&["-D", "res=4"]),
            want: &["rays meet nothing"],
        },
        RenderCase {
            name: "--unit-m 1e20",
            scene: None,
            args: flags(&["--unit-m", "1e20"]),
            want: &[UNWRITABLE, "unit_m = 1e20"],
        },
        RenderCase {
            name: "--unit-m 1e300",
            scene: None,
            args: flags(&["--unit-m", "1e300"]),
            want: &[UNWRITABLE, "unit_m"],
        },
        RenderCase {
            name: "time window ending beyond 1e15",
            scene: None,
            args: flags(&[
                "--start-opl",
                "0",
                "--bin-width-opl",
                "1e14",
                "--bins",
                "20",
            ]),
            want: &[UNWRITABLE, "the end of the last bin"],
        },
        RenderCase {
            name: "time window starting at 1e16",
            scene: None,
            args: flags(&["--start-opl", "1e16"]),
            want: &["1e16"],
        },
    ]
}

#[test]
fn renders_whose_manifest_could_not_be_read_back_are_refused_up_front() {
    let fx = fixture();
    let root = fx.path();
    let mut failures = Vec::new();
    let cases = render_cases();
    for (k, c) in cases.iter().enumerate() {
        let dir = root.join(format!("render{k:02}"));
        std::fs::create_dir(&dir).unwrap();
        let (file, text) = c.scene.clone().unwrap_or((
            "s.xml",
            std::fs::read_to_string(root.join("s.xml")).unwrap(),
        ));
        std::fs::write(dir.join(file), text).unwrap();
        let mut args: Vec<String> = vec!["render".into(), file.into()];
        args.extend(with_small(&c.args));
        args.extend(["--out".into(), "out.tstats".into()]);
        let before = snapshot(&dir);
        let r = run(limited(&args, &dir));
        let after = snapshot(&dir);
        let mut problems = failure_problems(&r, c.want);
        if dir.join("out.tstats").exists() {
            problems.push("a bundle was written".into());
        }
        if before != after {
            let changed: Vec<_> = before
                .keys()
                .chain(after.keys())
                .filter(|p| before.get(*p) != after.get(*p))
                .collect();
            problems.push(format!("left behind: {changed:?}"));
        }
        // Refused before any rendering work: no progress or render line.
        if r.stderr.contains("rendered") || r.stderr.contains("paths/s") {
            problems.push("rendered before refusing".into());
        }
        if !problems.is_empty() {
            failures.push(format!(
                "{}: {}\n    stderr: {:?}",
                c.name,
                problems.join("; "),
                r.stderr
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} cases failed:\n{}",
        failures.len(),
        cases.len(),
        failures.join("\n")
    );
}

/// The commands a manifest case runs.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Cmd {
    Info,
    /// `merge` with good2.tstats (`--partial`).
    Merge,
    /// `export --tal`.
    Tal,
    /// `nlos reconstruct --method pf`.
    Pf,
    /// `nlos reconstruct --method fbp`.
    Fbp,
}
use Cmd::{Fbp, Info, Merge, Pf, Tal};

const ALL: &[Cmd] = &[Info, Merge, Tal, Pf, Fbp];
const OPEN: &[Cmd] = &[Info, Merge];

/// The command line of `cmd` on `input`, its outputs written under `out`.
fn command(root: &Path, cmd: Cmd, input: &Path, out: &Path) -> Vec<String> {
    let i = s(input);
    let o = |name: &str| s(&out.join(name));
    let recon = |m: &str| {
        vec![
            "nlos".into(),
            "reconstruct".into(),
            i.clone(),
            "--method".into(),
            m.into(),
            "--volume".into(),
            "-1,1,-1,1,0.5,1.5".into(),
            "--voxels".into(),
            "4,4,4".into(),
            "--wl-mean".into(),
            "0.5".into(),
            "--out".into(),
            o("v.npy"),
        ]
    };
    match cmd {
        Info => vec!["info".into(), i],
        Merge => vec![
            "merge".into(),
            i,
            s(&root.join("good2.tstats")),
            "--partial".into(),
            "--out".into(),
            o("m.tstats"),
        ],
        Tal => vec!["export".into(), i, "--tal".into(), o("c.hdf5")],
        Pf => recon("pf"),
        Fbp => recon("fbp"),
    }
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir(to).unwrap();
    for e in std::fs::read_dir(from).unwrap().flatten() {
        std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
    }
}

fn read_manifest(b: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(b.join("manifest.json")).unwrap()).unwrap()
}

/// Rewrites the manifest of `b` after `edit`, compactly (lists of a million entries
/// stay below the reader's size limit).
fn edit(b: &Path, edit: impl FnOnce(&mut Value)) {
    let mut v = read_manifest(b);
    edit(&mut v);
    std::fs::write(b.join("manifest.json"), serde_json::to_string(&v).unwrap()).unwrap();
}

/// Replaces text in the compact manifest of `b` (for what JSON values cannot express).
fn replace(b: &Path, from: &str, to: &str) {
    edit(b, |_| {});
    let p = b.join("manifest.json");
    let text = std::fs::read_to_string(&p).unwrap();
    assert!(text.contains(from), "{from:?} not in the manifest");
    std::fs::write(&p, text.replacen(from, to, 1)).unwrap();
}

/// A million distinct seeds (from 1: good2's seed is 5, so merging repeats it).
fn million_seeds() -> Value {
    Value::from((1..=1_000_000u64).collect::<Vec<_>>())
}

/// A shard record of a job of 2^32 shards holding `indices`.
fn shard(indices: impl Iterator<Item = u64>) -> Value {
    json!({"job": "0123456789abcdef", "count": 1u64 << 32, "indices": indices.collect::<Vec<_>>()})
}

/// Prepares a case: the fixture's root and the bundle to damage.
type Make = Box<dyn Fn(&Path, &Path)>;

struct ManifestCase {
    name: &'static str,
    make: Make,
    cmds: &'static [Cmd],
    want: &'static [&'static str],
}

fn case(
    name: &'static str,
    cmds: &'static [Cmd],
    want: &'static [&'static str],
    make: impl Fn(&Path) + 'static,
) -> ManifestCase {
    ManifestCase {
        name,
        make: Box::new(move |_, b| make(b)),
        cmds,
        want,
    }
}

/// A geometric field of the capture record set to `v`.
fn nlos_field(field: &'static str, i: usize, v: f64) -> impl Fn(&Path) {
    move |b| edit(b, |m| m["nlos"][field][i] = json!(v))
}

fn manifest_cases() -> Vec<ManifestCase> {
    vec![
        // Relay walls and capture geometry: finite but absurd, or not finite.
        case(
            "wall_corner 1e300",
            ALL,
            &["nlos.wall_corner[0] = 1e300", MAG],
            nlos_field("wall_corner", 0, 1e300),
        ),
        case(
            "wall_corner -1e16",
            ALL,
            &["nlos.wall_corner[2] = -1e16", MAG],
            nlos_field("wall_corner", 2, -1e16),
        ),
        case(
            "wall_du 1e300",
            ALL,
            &["nlos.wall_du[0] = 1e300"],
            nlos_field("wall_du", 0, 1e300),
        ),
        case(
            "wall_dv 1e15",
            ALL,
            &["nlos.wall_dv[1] = 1e15"],
            nlos_field("wall_dv", 1, 1e15),
        ),
        case(
            "wall_du zero",
            ALL,
            &["|nlos.wall_du| = 0e0", "length"],
            |b| edit(b, |m| m["nlos"]["wall_du"] = json!([0.0, 0.0, 0.0])),
        ),
        case(
            "wall_normal of length 2",
            ALL,
            &["|nlos.wall_normal| = 2e0", "unit"],
            nlos_field("wall_normal", 2, 2.0),
        ),
        case(
            "wall_normal zero",
            ALL,
            &["|nlos.wall_normal|", "unit"],
            nlos_field("wall_normal", 2, 0.0),
        ),
        case(
            "wall_normal 1e300",
            ALL,
            &["nlos.wall_normal[2] = 1e300"],
            nlos_field("wall_normal", 2, 1e300),
        ),
        case(
            "sensor_origin -1e300",
            ALL,
            &["nlos.sensor_origin[1] = -1e300"],
            nlos_field("sensor_origin", 1, -1e300),
        ),
        case(
            "laser_origin 1e300",
            ALL,
            &["nlos.laser_origin[0] = 1e300"],
            nlos_field("laser_origin", 0, 1e300),
        ),
        case(
            "laser_origin 1e16",
            ALL,
            &["nlos.laser_origin[2] = 1e16"],
            nlos_field("laser_origin", 2, 1e16),
        ),
        case("laser_origin with one null", ALL, &["bad manifest"], |b| {
            edit(b, |m| m["nlos"]["laser_origin"][1] = Value::Null)
        }),
        case(
            "laser_origin as NaN (not JSON)",
            ALL,
            &["not valid JSON"],
            |b| replace(b, "\"laser_origin\":[-2.0", "\"laser_origin\":[NaN"),
        ),
        case(
            "wall_corner as Infinity (not JSON)",
            ALL,
            &["not valid JSON"],
            |b| replace(b, "\"wall_corner\":[-1.0", "\"wall_corner\":[Infinity"),
        ),
        case(
            "wall_corner 1e999 (overflows f64)",
            ALL,
            &["not valid JSON"],
            |b| replace(b, "\"wall_corner\":[-1.0", "\"wall_corner\":[1e999"),
        ),
        case(
            "laser point 1e300 (single capture)",
            ALL,
            &["nlos.laser_points[0][0] = 1e300"],
            |b| {
                edit(b, |m| {
                    m["nlos"]["capture"] = json!("single");
                    m["nlos"]["laser_points"] = json!([[1e300, 0.0, 0.0]]);
                })
            },
        ),
        case(
            "half a million laser points",
            ALL,
            &["500000 laser points for a 1x1 laser grid"],
            |b| {
                edit(b, |m| {
                    m["nlos"]["laser_points"] = Value::from(vec![[0.0, 0.0, 0.0]; 500_000])
                })
            },
        ),
        // Time axes.
        case(
            "bin width 0",
            OPEN,
            &["bin_width_opl = 0e0", "positive"],
            |b| edit(b, |m| m["bin_width_opl"] = json!(0.0)),
        ),
        case("bin width -0", OPEN, &["bin_width_opl", "positive"], |b| {
            edit(b, |m| m["bin_width_opl"] = json!(-0.0))
        }),
        case(
            "bin width negative",
            OPEN,
            &["bin_width_opl = -4e-3", "positive"],
            |b| edit(b, |m| m["bin_width_opl"] = json!(-0.004)),
        ),
        case(
            "bin width null (NaN written by an old writer)",
            OPEN,
            &["bad manifest"],
            |b| edit(b, |m| m["bin_width_opl"] = Value::Null),
        ),
        case("bin width \"NaN\"", OPEN, &["bad manifest"], |b| {
            edit(b, |m| m["bin_width_opl"] = json!("NaN"))
        }),
        case("bin width 1e300", ALL, &["bin_width_opl = 1e300"], |b| {
            edit(b, |m| m["bin_width_opl"] = json!(1e300))
        }),
        case(
            "bin width lost in start_opl",
            ALL,
            &["too small to be added to start_opl"],
            |b| {
                edit(b, |m| {
                    m["start_opl"] = json!(1e14);
                    m["bin_width_opl"] = json!(1e-10);
                })
            },
        ),
        case(
            "last bin ends beyond 1e15",
            ALL,
            &["the end of the last bin"],
            |b| edit(b, |m| m["bin_width_opl"] = json!(2e14)),
        ),
        case("start_opl 1e300", ALL, &["start_opl = 1e300"], |b| {
            edit(b, |m| m["start_opl"] = json!(1e300))
        }),
        case("start_opl -1e300", ALL, &["start_opl = -1e300"], |b| {
            edit(b, |m| m["start_opl"] = json!(-1e300))
        }),
        case("unit_m 0", OPEN, &["unit_m = 0e0"], |b| {
            edit(b, |m| m["unit_m"] = json!(0.0))
        }),
        case("unit_m -1", OPEN, &["unit_m = -1e0"], |b| {
            edit(b, |m| m["unit_m"] = json!(-1.0))
        }),
        case("unit_m 1e300", ALL, &["unit_m = 1e300"], |b| {
            edit(b, |m| m["unit_m"] = json!(1e300))
        }),
        case(
            "time filter stddev -1",
            OPEN,
            &["time_filter_stddev_bins = -1e0"],
            |b| edit(b, |m| m["time_filter_stddev_bins"] = json!(-1.0)),
        ),
        case(
            "time filter stddev 1e300",
            OPEN,
            &["time_filter_stddev_bins = 1e300"],
            |b| edit(b, |m| m["time_filter_stddev_bins"] = json!(1e300)),
        ),
        // Lists of a million entries: answered within the time limit.
        case(
            "a million merged_seeds, the last repeated",
            OPEN,
            &["merged_seeds lists seed 17 twice"],
            |b| {
                edit(b, |m| {
                    let mut v: Vec<u64> = (1..=1_000_000).collect();
                    v.push(17);
                    m["merged_seeds"] = Value::from(v);
                    m["spp"] = json!(4_000_000u64);
                })
            },
        ),
        case(
            "a million merged_seeds with spp 4",
            OPEN,
            &["merged_seeds lists 1000000 seeds, but spp = 4"],
            |b| edit(b, |m| m["merged_seeds"] = million_seeds()),
        ),
        case(
            "a million merged_seeds that repeat good2's seed",
            &[Merge],
            &["seed 5 appears twice", "good2.tstats"],
            |b| {
                edit(b, |m| {
                    m["merged_seeds"] = million_seeds();
                    m["spp"] = json!(4_000_000u64);
                })
            },
        ),
        case(
            "a million shard indices, decreasing",
            OPEN,
            &["indices 999999 then 999998 do not increase"],
            |b| edit(b, |m| m["shard"] = shard((0..1_000_000u64).rev())),
        ),
        case(
            "a million shard indices, one repeated",
            OPEN,
            &["indices 500000 then 500000 do not increase"],
            |b| {
                edit(b, |m| {
                    let mut v: Vec<u64> = (0..1_000_000).collect();
                    v.insert(500_000, 500_000);
                    m["shard"] = shard(v.into_iter());
                })
            },
        ),
        case(
            "a million shard indices beyond count",
            OPEN,
            &["index 1000 is not below count 1000"],
            |b| {
                edit(b, |m| {
                    m["shard"] = shard(0..1_000_000u64);
                    m["shard"]["count"] = json!(1000);
                })
            },
        ),
        case("shard count 2^32 + 1", OPEN, &["count 4294967297"], |b| {
            edit(b, |m| {
                m["shard"] = shard(0..3u64);
                m["shard"]["count"] = json!((1u64 << 32) + 1);
            })
        }),
        case(
            "shard job not hexadecimal",
            OPEN,
            &["is not 16 hexadecimal digits"],
            |b| {
                edit(b, |m| {
                    m["shard"] = shard(0..3u64);
                    m["shard"]["job"] = json!("x".repeat(1_000_000));
                })
            },
        ),
        case(
            "a million channels",
            OPEN,
            &["channels [\"R\", \"G\", \"B\", \"R\", ... (1000000 in all)]"],
            |b| {
                edit(b, |m| {
                    m["channels"] =
                        Value::from(["R", "G", "B"].repeat(333_334)[..1_000_000].to_vec())
                })
            },
        ),
        case(
            "100000 array entries",
            OPEN,
            &["lists 100000 arrays; a bundle has at most 64"],
            |b| {
                edit(b, |m| {
                    let extra =
                        json!({"name": "extra", "file": "extra.npy", "dtype": "<f8", "shape": [1]});
                    let a = m["arrays"].as_array_mut().unwrap();
                    let n = 100_000 - a.len();
                    a.extend(std::iter::repeat_n(extra, n));
                })
            },
        ),
        case(
            "an array of a million dimensions",
            OPEN,
            &["lists 'extra' with 1000000 dimensions"],
            |b| {
                edit(b, |m| {
                    let extra = json!({"name": "extra", "file": "extra.npy", "dtype": "<f8", "shape": vec![1; 1_000_000]});
                    m["arrays"].as_array_mut().unwrap().push(extra);
                })
            },
        ),
        case(
            "an array listed twice",
            OPEN,
            &["lists the array 'x2' twice"],
            |b| {
                edit(b, |m| {
                    let a = m["arrays"].as_array_mut().unwrap();
                    let x2 = a.iter().find(|e| e["name"] == "x2").unwrap().clone();
                    a.push(x2);
                })
            },
        ),
        case(
            "half a million -D values, one repeated",
            OPEN,
            &["scene.identity.defaults lists 'd000042' twice"],
            |b| {
                edit(b, |m| {
                    let mut v: Vec<Value> = (0..500_000)
                        .map(|i| json!([format!("d{i:06}"), "1"]))
                        .collect();
                    v.push(json!(["d000042", "2"]));
                    m["scene"]["identity"]["defaults"] = Value::from(v);
                })
            },
        ),
        case(
            "a scene input listed twice",
            OPEN,
            &["scene.identity.inputs lists 'a.ply' twice"],
            |b| {
                edit(b, |m| {
                    m["scene"]["identity"]["inputs"] = json!([["a.ply", "00"], ["a.ply", "11"]])
                })
            },
        ),
        // Strings the reader refuses (and the writer now never writes).
        case(
            "scene path with a newline",
            OPEN,
            &["control character U+000A"],
            |b| edit(b, |m| m["scene"]["path"] = json!("s\nx.xml")),
        ),
        case(
            "-D value with NUL",
            OPEN,
            &["control character U+0000"],
            |b| {
                edit(b, |m| {
                    m["scene"]["identity"]["defaults"][0][1] = json!("4\u{0}")
                })
            },
        ),
        case(
            "program version with an escape",
            OPEN,
            &["control character U+001B"],
            |b| edit(b, |m| m["program"]["version"] = json!("\u{1b}[2J")),
        ),
        // The file itself: its size is checked before it is read.
        case(
            "manifest of 17 MB",
            OPEN,
            &["above the limit of 16777216 bytes"],
            |b| {
                let p = b.join("manifest.json");
                let mut text = std::fs::read_to_string(&p).unwrap();
                text.push_str(&" ".repeat(17 << 20));
                std::fs::write(p, text).unwrap();
            },
        ),
        // Shard records that merge wrongly: the error names the input at fault.
        ManifestCase {
            name: "a million shard indices, one also in good2",
            make: Box::new(|root, b| {
                edit(b, |m| m["shard"] = shard((0..1_000_000u64).map(|i| 2 * i)));
                edit(&root.join("good2.tstats"), |m| {
                    m["shard"] = shard([1u64, 3, 1_999_998].into_iter())
                });
            }),
            cmds: &[Merge],
            want: &[
                "good2.tstats: invalid bundle",
                "shard 1999998 of 4294967296 is given twice",
            ],
        },
        ManifestCase {
            name: "shards of one job with other counts",
            make: Box::new(|root, b| {
                edit(b, |m| m["shard"] = shard(0..2u64));
                edit(&root.join("good2.tstats"), |m| {
                    m["shard"] = shard(2..3u64);
                    m["shard"]["count"] = json!(4);
                });
            }),
            cmds: &[Merge],
            want: &[
                "good2.tstats: invalid bundle",
                "bundles of 4294967296 and of 4 shards",
            ],
        },
    ]
}

#[test]
fn hostile_manifests_and_shard_records_fail_cleanly() {
    let fx = fixture();
    let root = fx.path();
    let good2 = root.join("good2.tstats");
    let pristine2 = root.join("pristine2.tstats");
    copy_dir(&good2, &pristine2);
    let mut failures = Vec::new();
    let mut runs = 0;
    let cases = manifest_cases();
    assert!(cases.len() >= 40);
    for (k, c) in cases.iter().enumerate() {
        let dir = root.join(format!("case{k:02}"));
        std::fs::create_dir(&dir).unwrap();
        let input = dir.join("in.tstats");
        copy_dir(&root.join("good.tstats"), &input);
        // good2 as the case leaves it (some cases edit it), restored after.
        (c.make)(root, &input);
        for &cmd in c.cmds {
            let out = dir.join(format!("out-{cmd:?}"));
            std::fs::create_dir(&out).unwrap();
            let args = command(root, cmd, &input, &out);
            let before = snapshot(&dir);
            let r = run(limited(&args, &out));
            runs += 1;
            let mut problems = failure_problems(&r, c.want);
            if before != snapshot(&dir) {
                problems.push("changed on disk".into());
            }
            if !problems.is_empty() {
                failures.push(format!(
                    "{} / {cmd:?} ({:.1} s): {}\n    stderr: {:?}",
                    c.name,
                    r.seconds,
                    problems.join("; "),
                    r.stderr.chars().take(2000).collect::<String>()
                ));
            }
        }
        std::fs::remove_dir_all(&good2).unwrap();
        copy_dir(&pristine2, &good2);
    }
    assert!(
        failures.is_empty(),
        "{} of {runs} runs failed:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// Valid manifests with lists of a million entries open and merge within the time
/// limit (the quadratic checks they replace took about 50 s): 1M merged seeds, 1M
/// shard indices merged with --partial; and the captures of `transient_path` renders
/// whose laser is not positioned (laser_origin null, lit point unknown), which every
/// reader refused before, open.
#[test]
fn valid_manifests_with_a_million_entries_open_in_time() {
    let fx = fixture();
    let root = fx.path();
    let ok = |args: Vec<String>, what: &str| {
        let r = run(limited(&args, root));
        assert!(
            r.code == Some(0) && !r.timed_out,
            "{what}: exit {:?} after {:.1} s: {}",
            r.code,
            r.seconds,
            r.stderr
        );
        eprintln!("{what}: {:.2} s", r.seconds);
        r
    };
    let seeds = root.join("seeds.tstats");
    copy_dir(&root.join("good.tstats"), &seeds);
    edit(&seeds, |m| {
        let mut v: Vec<u64> = (6..1_000_005).collect();
        v.push(0);
        m["merged_seeds"] = Value::from(v);
        m["spp"] = json!(4_000_000u64);
    });
    ok(vec!["info".into(), s(&seeds)], "info, 1M merged_seeds");
    let shards = root.join("shards.tstats");
    copy_dir(&root.join("good.tstats"), &shards);
    edit(&shards, |m| {
        m["shard"] = shard((0..1_000_000u64).map(|i| 2 * i))
    });
    edit(&root.join("good2.tstats"), |m| {
        m["shard"] = shard([1u64, 3].into_iter())
    });
    ok(vec!["info".into(), s(&shards)], "info, 1M shard indices");
    ok(
        vec![
            "merge".into(),
            s(&shards),
            s(&root.join("good2.tstats")),
            "--partial".into(),
            "--out".into(),
            s(&root.join("merged.tstats")),
        ],
        "merge --partial, 1M + 2 shard indices",
    );
    let merged = read_manifest(&root.join("merged.tstats"));
    assert_eq!(
        merged["shard"]["indices"].as_array().unwrap().len(),
        1_000_002
    );
    ok(
        vec!["info".into(), s(&root.join("merged.tstats"))],
        "info of the merge",
    );

    // A transient_path capture with a point light: no laser position, no lit point.
    let scene = nlos_scene();
    let start = scene.find("<integrator").unwrap();
    let end = scene.find("</integrator>").unwrap() + "</integrator>".len();
    let tp = format!(
        "{}<integrator type=\"transient_path\"><integer name=\"max_depth\" value=\"-1\"/></integrator>{}",
        &scene[..start],
        &scene[end..]
    );
    let estart = tp.find("<emitter").unwrap();
    let eend = tp.find("</emitter>").unwrap() + "</emitter>".len();
    let point = format!(
        "{}<emitter type=\"point\"><point name=\"position\" x=\"-2\" y=\"0\" z=\"2\"/><rgb name=\"intensity\" value=\"1\"/></emitter>{}",
        &tp[..estart],
        &tp[eend..]
    );
    std::fs::write(root.join("point.xml"), point).unwrap();
    let mut args: Vec<String> = vec!["render".into(), "point.xml".into()];
    args.extend(SMALL.iter().map(|a| a.to_string()));
    args.extend(["--out".into(), "point.tstats".into()]);
    ok(args, "render, transient_path with a point light");
    let m = read_manifest(&root.join("point.tstats"));
    assert_eq!(m["nlos"]["laser_origin"], Value::Null);
    assert_eq!(m["nlos"]["laser_points"], json!([null]));
    ok(vec!["info".into(), "point.tstats".into()], "info, no laser");
    let r = run(limited(
        &[
            "export".into(),
            "point.tstats".into(),
            "--tal".into(),
            "p.hdf5".into(),
        ],
        root,
    ));
    let problems = failure_problems(&r, &["point.tstats"]);
    assert!(
        problems.is_empty(),
        "export --tal, no laser: {problems:?}: {}",
        r.stderr
    );
    assert!(!root.join("p.hdf5").exists());
}
