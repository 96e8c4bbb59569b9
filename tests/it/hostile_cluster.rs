//! Hostile input to `tstat cluster` (and the size parser every command shares).
//!
//! - A corpus of invocations of the real binary that must fail with exit 1 (ours) or 2
//!   (clap's), one `error:` line and nothing else on stderr or stdout (no plan line
//!   before a refusal), no panic, in bounded time and memory, and without leaving
//!   anything behind: the working directory is compared before and after every case.
//! - Round trips: for hostile output folders, search folders and binary names, the
//!   command lines `tstat cluster` prints, the `# Submit:` comment and the scripts it
//!   writes are run by a real `sh`/`bash` with `sbatch`, `kubectl` and the tstat binary
//!   replaced by stubs that record their arguments; every argument must arrive exactly
//!   as meant and no injected command may run. The Kubernetes manifests are parsed and
//!   their commands compared (the merge pod's `sh -c` script is run the same way).

use crate::common::hostile;
use hostile::{bin, limited, run, snapshot, TIME_LIMIT};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

/// The inputs and earlier outputs the cases run against: the Cornell box s.xml (and a
/// copy named like a newline), a precious file, a folder holding recipes of an earlier
/// run, one holding its merged bundle, one holding its shards, a scene inside a
/// would-be shards folder and one named like a recipe.
fn fixture() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cbox = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cbox.xml");
    std::fs::copy(&cbox, d.join("s.xml")).unwrap();
    std::fs::copy(&cbox, d.join("n\nl.xml")).unwrap();
    std::fs::write(d.join("file.txt"), "precious").unwrap();
    for (folder, file) in [
        ("existing", "render.sbatch"),
        ("existing_k8s", "merge-job.json"),
        ("prev", "merged.tstats"),
        ("prevshards/shards", "shard-03.tstats"),
        ("sh/shards", "s3.xml"),
    ] {
        std::fs::create_dir_all(d.join(folder)).unwrap();
        std::fs::write(d.join(folder).join(file), "keep").unwrap();
    }
    std::fs::create_dir_all(d.join("asrecipe")).unwrap();
    std::fs::copy(&cbox, d.join("asrecipe/render.sbatch")).unwrap();
    std::fs::copy(&cbox, d.join("sh/shards/s3.xml")).unwrap();
    std::fs::create_dir_all(d.join("isdir/merge.sbatch")).unwrap();
    dir
}

/// Usage errors (clap's): exit 2. Ours: exit 1.
#[derive(Clone, Copy, PartialEq, Debug)]
enum Exit {
    Ours,
    Usage,
}
use Exit::{Ours, Usage};

/// One hostile invocation (after `tstat cluster`), who reports it, and a piece of the
/// first stderr line.
type Case = (&'static [&'static str], Exit, &'static str);

const S: &str = "slurm";
const K: &str = "k8s";
/// What the Slurm cases share after the scheduler: the scene, shards and a small job.
macro_rules! slurm {
    ($($a:expr),* $(,)?) => { &[S, "s.xml", "--shards", "2", $($a,)*] };
}
macro_rules! k8s {
    ($($a:expr),* $(,)?) => { &[K, "s.xml", "--shards", "2", "--image", "reg/tstat:1", "--claim", "data", "--mount", "/", $($a,)*] };
}

#[rustfmt::skip]
const CASES: &[Case] = &[
    // Characters the recipes cannot carry: refused, named, before anything is created.
    (slurm!("--out=a\nb", "--", "--spp", "8"), Ours, "--out \"/"),
    (slurm!("--out=a\nb", "--", "--spp", "8"), Ours, "the character '\\n' cannot go into the recipes"),
    (slurm!("--out=a\tb", "--", "--spp", "8"), Ours, "the character '\\t'"),
    (slurm!("--out=a\u{1b}[31mb", "--", "--spp", "8"), Ours, "the character '\\u{1b}'"),
    (slurm!("--out=a\u{2028}b", "--", "--spp", "8"), Ours, "the character '\\u{2028}'"),
    (slurm!("--out=a b", "--", "--spp", "8"), Ours, "Slurm directive lines take no spaces"),
    (slurm!("--out=a'b", "--", "--spp", "8"), Ours, "the character '\\''"),
    (slurm!("--out=a\"b", "--", "--spp", "8"), Ours, "the character '\"'"),
    (slurm!("--out=run%j", "--", "--spp", "8"), Ours, "the character '%'"),
    (slurm!("--out=a\\b", "--", "--spp", "8"), Ours, "the character '\\\\'"),
    (slurm!("--out=a#b", "--", "--spp", "8"), Ours, "the character '#'"),
    (&[S, "n\nl.xml", "--shards", "2", "--out", "o", "--", "--spp", "8"], Ours, "the scene \"/"),
    (&[S, "n\nl.xml", "--shards", "2", "--out", "o", "--", "--spp", "8"], Ours, "(no control characters or line breaks)"),
    (&[S, "s\r.xml", "--shards", "2", "--out", "o", "--", "--spp", "8"], Ours, "the character '\\r'"),
    (slurm!("--out", "o", "--", "--spp", "8", "-D", "a=b\nc"), Ours, "the render option"),
    (slurm!("--out", "o", "--", "--spp", "8", "--target-error", "0.01"), Ours, "--target-error is an adaptive sampling option: not without --adaptive"),
    (slurm!("--out", "o", "--", "--spp", "8", "--adaptive", "--time-budget", "5m"), Ours, "not with --shard"),
    (slurm!("--out", "o", "--", "--spp", "8", "-a", "t\nx"), Ours, "the character '\\n'"),
    (k8s!("--out=a\nb", "--", "--spp", "8"), Ours, "the character '\\n' cannot go into the recipes"),
    (k8s!("--out", "o", "--binary", "ts tat", "--", "--spp", "8"), Ours, "--binary ts tat: empty, or holds whitespace"),
    (k8s!("--out", "o", "--binary", "t\nx", "--", "--spp", "8"), Ours, "--binary t\\nx: empty"),
    (&[K, "s.xml", "--shards", "2", "--image", "reg/t:1 ;id", "--claim", "data", "--mount", "/", "--out", "o", "--", "--spp", "8"], Ours, "--image reg/t:1 ;id: empty, or holds whitespace"),
    (&[K, "s.xml", "--shards", "2", "--image", "", "--claim", "data", "--mount", "/", "--out", "o", "--", "--spp", "8"], Ours, "--image : empty"),
    (&[K, "s.xml", "--shards", "2", "--image", "i", "--claim", "Data_1", "--mount", "/", "--out", "o", "--", "--spp", "8"], Ours, "--claim Data_1: not a Kubernetes name"),
    (&[K, "s.xml", "--shards", "2", "--image", "i", "--claim", "x-", "--mount", "/", "--out", "o", "--", "--spp", "8"], Ours, "--claim x-: not a Kubernetes name"),
    (&[K, "s.xml", "--shards", "2", "--image", "i", "--claim", "d", "--mount", "data", "--out", "o", "--", "--spp", "8"], Ours, "--mount data: an absolute path"),
    (&[K, "s.xml", "--shards", "2", "--image", "i", "--claim", "d", "--mount", "/d\na", "--out", "o", "--", "--spp", "8"], Ours, "--mount \"/d\\na\": the character"),
    (&[K, "s.xml", "--shards", "2", "--image", "i", "--claim", "d", "--mount", "/nowhere", "--out", "o", "--", "--spp", "8"], Ours, "is not under the volume's mount point /nowhere"),
    // Sizes: beyond u64, beyond the bounds, or not sizes; the message echoes the input.
    (slurm!("--out", "o", "--mem", "99999999999999999999", "--", "--spp", "8"), Ours, "--mem 99999999999999999999: more than 2^64 - 1 bytes (16Ei)"),
    (slurm!("--out", "o", "--mem", "18446744073709551616", "--", "--spp", "8"), Ours, "--mem 18446744073709551616: more than 2^64 - 1 bytes"),
    (slurm!("--out", "o", "--mem", "16Ei", "--", "--spp", "8"), Ours, "--mem 16Ei: more than 2^64 - 1 bytes"),
    (slurm!("--out", "o", "--mem", "18446744073709551615", "--", "--spp", "8"), Ours, "--mem 18446744073709551615: at most 1Pi"),
    (slurm!("--out", "o", "--mem", "2Pi", "--", "--spp", "8"), Ours, "--mem 2Pi: at most 1Pi"),
    (slurm!("--out", "o", "--mem", "1M", "--", "--spp", "8"), Ours, "--mem 1M: at least 64Mi"),
    (slurm!("--out", "o", "--mem", "4096", "--", "--spp", "8"), Ours, "--mem 4096: at least 64Mi"),
    (slurm!("--out", "o", "--mem", "-1G", "--", "--spp", "8"), Ours, "--mem -1G: not a size such as 512M"),
    (slurm!("--out", "o", "--mem", "1e9", "--", "--spp", "8"), Ours, "--mem 1e9: not a size"),
    (slurm!("--out", "o", "--mem", "4Gb ", "--merge-mem", "0", "--", "--spp", "8"), Ours, "--merge-mem 0: less than one byte"),
    (slurm!("--out", "o", "--merge-mem", "99999999999999999999Ki", "--", "--spp", "8"), Ours, "--merge-mem 99999999999999999999Ki: more than"),
    (slurm!("--out", "o", "--merge-mem", "70Mi", "--", "--spp", "8"), Ours, "--merge-mem 70Mi: the merge of a"),
    (slurm!("--out", "o", "--", "--spp", "8", "--max-memory", "99999999999999999999"), Ours, "--max-memory 99999999999999999999: more than"),
    (k8s!("--out", "o", "--mem", "1.5Ei", "--", "--spp", "8"), Ours, "--mem 1.5Ei: at most 1Pi"),
    (&["render", "s.xml", "--out", "r.tstats", "--max-memory", "18446744073709551616"], Ours, "--max-memory 18446744073709551616: more than 2^64 - 1 bytes"),
    (&["merge", "a.tstats", "b.tstats", "--out", "m.tstats", "--max-memory", "20E"], Ours, "--max-memory 20E: more than"),
    (&["view", "a.tstats", "--out", "v.html", "--max-bytes", "1K"], Ours, "--max-bytes 1K: at least 1Ki"),
    (&["view", "a.tstats", "--out", "v.html", "--max-bytes", "99999999999999999999"], Ours, "--max-bytes 99999999999999999999: more than"),
    // Counts and times.
    (slurm!("--out", "o", "--cpus", "0", "--", "--spp", "8"), Ours, "--cpus 0: must be at least 1"),
    (slurm!("--out", "o", "--cpus", "-4", "--", "--spp", "8"), Ours, "--cpus -4: must be at least 1"),
    (slurm!("--out", "o", "--cpus", "5000", "--", "--spp", "8"), Ours, "--cpus 5000: must be at most 1024"),
    (&[S, "s.xml", "--shards", "1", "--out", "o", "--", "--spp", "8"], Ours, "--shards 1: at least 2"),
    (&[S, "s.xml", "--shards", "-3", "--out", "o", "--", "--spp", "8"], Ours, "--shards -3: at least 2"),
    (&[S, "s.xml", "--shards", "4000001", "--out", "o", "--", "--spp", "8"], Ours, "--shards 4000001: must be at most 4000000"),
    (&[K, "s.xml", "--shards", "100001", "--image", "i", "--claim", "d", "--mount", "/", "--out", "o"], Ours, "--shards 100001: must be at most 100000"),
    (&[S, "s.xml", "--shards", "99999999999999999999", "--out", "o"], Usage, "invalid value '99999999999999999999' for '--shards"),
    (k8s!("--out", "o", "--parallelism", "0", "--", "--spp", "8"), Ours, "--parallelism 0: must be at least 1"),
    (k8s!("--out", "o", "--parallelism", "-2", "--", "--spp", "8"), Ours, "--parallelism -2: must be at least 1"),
    (slurm!("--out", "o", "--time", "0", "--", "--spp", "8"), Ours, "--time 0: give a time limit above 0"),
    (slurm!("--out", "o", "--time", "99999999999999999999", "--", "--spp", "8"), Ours, "--time 99999999999999999999: expected a Slurm time limit"),
    (slurm!("--out", "o", "--time", "366-00:00:00", "--", "--spp", "8"), Ours, "--time 366-00:00:00: at most 365 days"),
    (slurm!("--out", "o", "--time", "1:60", "--", "--spp", "8"), Ours, "--time 1:60: hours run from 0 to 23"),
    (slurm!("--out", "o", "--time", "-5", "--", "--spp", "8"), Ours, "--time -5: expected"),
    (slurm!("--out", "o", "--time", "$(id)", "--", "--spp", "8"), Ours, "--time $(id): expected"),
    (slurm!("--out", "o", "--partition", "a;id", "--", "--spp", "8"), Ours, "--partition \"a;id\": not a Slurm partition"),
    // The job itself.
    (slurm!("--out", "o", "--", "--spp", "7"), Ours, "the job's spp 7 is not a multiple of the number of shards 2"),
    (slurm!("--out", "o", "--", "--spp", "8", "--out", "x"), Ours, "--out among the render options"),
    (slurm!("--out", "o", "--", "--spp", "8", "--wat"), Ours, "do not parse as tstat render's"),
    (&[S, "missing.xml", "--shards", "2", "--out", "o", "--", "--spp", "8"], Ours, "missing.xml"),
    (&[S, "file.txt", "--shards", "2", "--out", "o", "--", "--spp", "8"], Ours, "file.txt"),
    // The output folder: refused before anything is created, nothing replaced.
    (slurm!("--out", "existing", "--", "--spp", "8"), Ours, "existing/render.sbatch: already exists (use --force"),
    (k8s!("--out", "existing_k8s", "--", "--spp", "8"), Ours, "existing_k8s/merge-job.json: already exists (use --force"),
    (slurm!("--out", "isdir", "--force", "--", "--spp", "8"), Ours, "isdir/merge.sbatch: is a folder"),
    (slurm!("--out", "prev", "--", "--spp", "8"), Ours, "prev/merged.tstats: left by an earlier run"),
    (slurm!("--out", "prev", "--force", "--", "--spp", "8"), Ours, "prev/merged.tstats: left by an earlier run"),
    (slurm!("--out", "prevshards", "--", "--spp", "8"), Ours, "prevshards/shards/shard-03.tstats: left by an earlier run"),
    (slurm!("--out", "file.txt", "--", "--spp", "8"), Ours, "file.txt exists and is not a folder"),
    (slurm!("--out", "s.xml", "--force", "--", "--spp", "8"), Ours, "s.xml/render.sbatch: is inside the input the scene s.xml"),
    (&[S, "asrecipe/render.sbatch", "--shards", "2", "--out", "asrecipe", "--force", "--", "--spp", "8"], Ours, "is the input the scene asrecipe/render.sbatch"),
    (&[S, "sh/shards/s3.xml", "--shards", "2", "--out", "sh", "--", "--spp", "8"], Ours, "contains the input the scene sh/shards/s3.xml"),
    // Failures while creating: what was created is removed again.
    (slurm!("--out", "file.txt/sub", "--", "--spp", "8"), Ours, "file.txt exists and is not a folder"),
    (slurm!("--out", "/proc/tstat-cluster-test/x", "--", "--spp", "8"), Ours, "creating /proc/tstat-cluster-test:"),
];

#[test]
fn hostile_cluster_commands_fail_cleanly_and_leave_nothing() {
    let fx = fixture();
    let dir = fx.path();
    let started = Instant::now();
    let mut failures = Vec::new();
    let mut cases: Vec<(Vec<String>, Exit, String)> = CASES
        .iter()
        .map(|(a, e, w)| (a.iter().map(|s| s.to_string()).collect(), *e, w.to_string()))
        .collect();
    // A failure after DIR, DIR/shards and DIR/logs are created: DIR's path so long
    // (nested 200-character names) that the folders fit within PATH_MAX (4096 bytes) but
    // the recipes' temporary names do not. The folders are removed again.
    let base = dir.display().to_string().len() + 1;
    let mut deep = String::new();
    while base + deep.len() < 4075 {
        let n = (4075 - base - deep.len()).min(200);
        if !deep.is_empty() {
            deep.push('/');
        }
        deep.push_str(&"d".repeat(n.max(2) - 1));
    }
    cases.push((
        [
            "slurm", "s.xml", "--shards", "2", "--out", &deep, "--", "--spp", "8",
        ]
        .map(String::from)
        .to_vec(),
        Ours,
        "render.sbatch: File name too long".into(),
    ));
    let total = cases.len();
    for (k, (mut args, exit, want)) in cases.into_iter().enumerate() {
        let want = want.as_str();
        if [S, K].contains(&args[0].as_str()) {
            args.insert(0, "cluster".into());
        }
        let what = format!("case {k}: tstat {args:?}");
        let before = snapshot(dir);
        let r = run(limited(&args, dir));
        let after = snapshot(dir);
        let first = r.stderr.lines().next().unwrap_or_default();
        let want_code = match exit {
            Ours => 1,
            Usage => 2,
        };
        let mut problems = Vec::new();
        if r.timed_out {
            problems.push(format!("killed after {TIME_LIMIT:?}"));
        }
        if r.code != Some(want_code) {
            problems.push(format!("exit {:?}, expected {want_code}", r.code));
        }
        if !first.starts_with("error: ") || !first.contains(want) {
            problems.push(format!("first stderr line {first:?} lacks {want:?}"));
        }
        if r.stderr.contains("panicked") {
            problems.push("panicked".into());
        }
        // Ours: the error line alone (no plan line, nothing on stdout).
        if exit == Ours && (r.stderr.lines().count() != 1 || !r.stdout.is_empty()) {
            problems.push("more than the error line".into());
        }
        if before != after {
            let changed: Vec<_> = before
                .keys()
                .chain(after.keys())
                .filter(|p| before.get(*p) != after.get(*p))
                .collect();
            problems.push(format!("changed on disk: {changed:?}"));
        }
        if !problems.is_empty() {
            failures.push(format!(
                "{what}\n  {}\n  stdout: {}\n  stderr: {}",
                problems.join("; "),
                r.stdout,
                r.stderr
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} cases failed:\n{}",
        failures.len(),
        total,
        failures.join("\n")
    );
    assert!(
        started.elapsed() < Duration::from_secs(30),
        "the corpus took {:?}",
        started.elapsed()
    );
}

// ---------------------------------------------------------------------------------
// Round trips through a real shell.

/// A stub program: records its arguments (NUL-terminated each) in a new file under
/// `$STUB_LOG` (one file per call, numbered in order), prints `4242` (a job id).
const STUB: &str = r#"#!/bin/sh
i=0
while [ -e "$STUB_LOG/$i" ]; do i=$((i+1)); done
for a in "$@"; do printf '%s\0' "$a"; done > "$STUB_LOG/$i"
echo 4242
"#;

fn write_stub(path: &Path) {
    use std::os::unix::fs::PermissionsExt;
    std::fs::write(path, STUB).unwrap();
    std::fs::set_permissions(path, std::fs::Permissions::from_mode(0o755)).unwrap();
}

/// The calls the stubs recorded since the last call, in order; clears the log.
fn calls(log: &Path) -> Vec<Vec<String>> {
    let mut out = Vec::new();
    for i in 0.. {
        let p = log.join(i.to_string());
        let Ok(bytes) = std::fs::read(&p) else { break };
        std::fs::remove_file(&p).unwrap();
        let args = bytes
            .split(|&b| b == 0)
            .map(|a| String::from_utf8(a.to_vec()).unwrap())
            .collect::<Vec<_>>();
        out.push(args[..args.len() - 1].to_vec()); // the last NUL ends the last argument
    }
    out
}

/// Where the round trips run: stubs on PATH, a log, and an empty folder as the working
/// directory of the shell (an injected `touch pwned` would land there).
struct Shell {
    stubs: PathBuf,
    log: PathBuf,
    cwd: PathBuf,
}

impl Shell {
    fn new(root: &Path) -> Shell {
        let s = Shell {
            stubs: root.join("stubs"),
            log: root.join("log"),
            cwd: root.join("cwd"),
        };
        for d in [&s.stubs, &s.log, &s.cwd] {
            std::fs::create_dir_all(d).unwrap();
        }
        for name in ["sbatch", "kubectl", "tstat"] {
            write_stub(&s.stubs.join(name));
        }
        s
    }

    /// Runs `script` with `shell` (`-c`), stubs first on PATH; checks that it
    /// succeeded and that nothing appeared in the working folder.
    fn run(&self, shell: &str, args: &[&str], env: &[(&str, &str)]) -> Vec<Vec<String>> {
        let path = format!(
            "{}:{}",
            self.stubs.display(),
            std::env::var("PATH").unwrap_or_default()
        );
        let out = Command::new(shell)
            .args(args)
            .current_dir(&self.cwd)
            .env("PATH", path)
            .env("STUB_LOG", &self.log)
            .envs(env.iter().copied())
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{shell} {args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let left: Vec<_> = std::fs::read_dir(&self.cwd).unwrap().flatten().collect();
        assert!(left.is_empty(), "{shell} {args:?} created {left:?}");
        calls(&self.log)
    }

    /// `line` checked by `sh -n`, then run by `sh -c`.
    fn line(&self, line: &str) -> Vec<Vec<String>> {
        self.run("sh", &["-n", "-c", line], &[]);
        self.run("sh", &["-c", line], &[])
    }
}

fn strings(v: &[&str]) -> Vec<String> {
    v.iter().map(|s| s.to_string()).collect()
}

/// The command lines after "submit:" / "run:" in what `tstat cluster` printed.
fn printed_commands(stdout: &str) -> Vec<&str> {
    stdout
        .lines()
        .filter_map(|l| l.strip_prefix("  "))
        .collect()
}

/// Output folder names that are legal on a Slurm `#SBATCH` line but hostile to a
/// shell; Kubernetes takes these and more (spaces, quotes, `\`, `#`, `%`).
const SLURM_NAMES: &[&str] = &[
    "d$(touch${IFS}pwned)",
    "d`touch${IFS}pwned`",
    "d;touch${IFS}pwned",
    "a&&touch${IFS}pwned||b|c",
    "-rf",
    "*",
    "~",
    "~root",
    "ünï/雪🦀",
    "{a,b}",
    "x=$(touch${IFS}pwned)",
    "[ab]?",
    "!x",
    "=ls",
    "<in>out",
];
const K8S_NAMES: &[&str] = &[
    "a b",
    "it's",
    "'$(touch pwned)'",
    "a\"b\"",
    "a\\b",
    "a#b",
    "100%",
    " lead",
];

/// `tstat cluster slurm` with hostile folder names (output, search folder, and the
/// binary's own folder): the printed submit line, the `# Submit:` comment and both
/// scripts run by real shells hand every stub exactly the intended arguments, and no
/// injected command runs.
#[test]
fn slurm_commands_round_trip_through_sh() {
    let t = tempfile::tempdir().unwrap();
    let root = t.path();
    let sh = Shell::new(root);
    // The binary in a hostile folder (its path goes into the scripts): a hard link (or a
    // copy) runs to write the recipes, then a stub takes its place to run them.
    let bindir = root.join("bin $(touch pwned) 'q'");
    std::fs::create_dir(&bindir).unwrap();
    let exe = bindir.join("tstat");
    if std::fs::hard_link(bin(), &exe).is_err() {
        std::fs::copy(bin(), &exe).unwrap();
    }
    let work = root.join("work");
    std::fs::create_dir(&work).unwrap();
    std::fs::copy(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cbox.xml"),
        work.join("s.xml"),
    )
    .unwrap();
    let textures = "tex $(touch pwned);'\"`x`";
    std::fs::create_dir(work.join(textures)).unwrap();
    let mut jobs = Vec::new();
    for name in SLURM_NAMES {
        let out = Command::new(&exe)
            .current_dir(&work)
            .args(["cluster", "slurm", "s.xml", "--shards", "2", "--denoise"])
            .arg(format!("--out={name}"))
            .args(["--", "--spp", "8", "--seed", "3", "-a", textures])
            .output()
            .unwrap();
        let stdout = String::from_utf8(out.stdout).unwrap();
        assert!(
            out.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        jobs.push((work.join(name), stdout));
    }
    // Now the stub is the binary the scripts run.
    std::fs::remove_file(&exe).unwrap();
    write_stub(&exe);
    let exe_s = exe.to_str().unwrap();
    let scene = work.join("s.xml").display().to_string();
    let tex = work.join(textures).display().to_string();
    for (dir, stdout) in &jobs {
        let d = dir.display().to_string();
        let want_submit = vec![
            strings(&["--parsable", &format!("{d}/render.sbatch")]),
            strings(&["--dependency=afterok:4242", &format!("{d}/merge.sbatch")]),
        ];
        let lines = printed_commands(stdout);
        assert_eq!(lines.len(), 1, "{stdout}");
        assert_eq!(sh.line(lines[0]), want_submit, "{d}: {}", lines[0]);
        let render = std::fs::read_to_string(dir.join("render.sbatch")).unwrap();
        let comment = render
            .lines()
            .find_map(|l| l.strip_prefix("# Submit: "))
            .unwrap();
        assert_eq!(comment, lines[0]);
        assert_eq!(sh.line(comment), want_submit);
        // The scripts themselves, as Slurm would run them (bash), with a stub tstat.
        let slurm_env = [("SLURM_ARRAY_TASK_ID", "1"), ("SLURM_CPUS_PER_TASK", "3")];
        let script = dir.join("render.sbatch");
        sh.run("bash", &["-n", script.to_str().unwrap()], &[]);
        let got = sh.run("bash", &[script.to_str().unwrap()], &slurm_env);
        let mut want = strings(&[
            "render",
            &scene,
            "--shard",
            "auto/2",
            "--out",
            &format!("{d}/shards/shard-{{shard}}.tstats"),
            "--threads",
            "3",
            "--spp",
            "8",
            "--seed",
            "3",
            "-a",
            &tex,
        ]);
        assert_eq!(got, vec![want.clone()], "{d}");
        // The merge expands the shards' glob (and only that): two shards in place.
        for i in 0..2 {
            std::fs::write(dir.join(format!("shards/shard-{i}.tstats")), "").unwrap();
        }
        let script = dir.join("merge.sbatch");
        sh.run("bash", &["-n", script.to_str().unwrap()], &[]);
        let got = sh.run("bash", &[script.to_str().unwrap()], &slurm_env);
        assert_eq!(got.len(), 2, "{got:?}");
        want = strings(&[
            "merge",
            &format!("{d}/shards/shard-0.tstats"),
            &format!("{d}/shards/shard-1.tstats"),
            "--out",
            &format!("{d}/merged.tstats"),
            "--max-memory",
        ]);
        assert_eq!(got[0][..want.len()], want[..], "{d}");
        assert_eq!(
            got[1][..6],
            strings(&[
                "denoise",
                &format!("{d}/merged.tstats"),
                "--out",
                &format!("{d}/denoised.npy"),
                "--threads",
                "3"
            ])[..],
            "{d}"
        );
        assert!(render.contains(&format!("exec {}", quote_like_sh(exe_s))));
    }
    assert!(!root.join("cwd/pwned").exists() && !work.join("pwned").exists());
}

/// The quoting the scripts use, as a shell reads it back: checked by running `printf`.
fn quote_like_sh(s: &str) -> String {
    format!("'{}'", s.replace('\'', r"'\''"))
}

/// `tstat cluster k8s` with hostile folder names and a hostile binary name: the printed
/// kubectl lines hand kubectl exactly the paths, the render Job's command is the exact
/// argument list, and the merge pod's `sh -c` script runs the stubbed binary with the
/// exact paths.
#[test]
fn k8s_commands_round_trip_through_sh() {
    let t = tempfile::tempdir().unwrap();
    let root = t.path();
    let sh = Shell::new(root);
    let binary = "ts'$(touch${IFS}pwned)";
    let textures = "tex $(touch pwned);'\"`x`";
    write_stub(&sh.stubs.join(binary));
    let work = root.join("work");
    std::fs::create_dir(&work).unwrap();
    std::fs::create_dir(work.join(textures)).unwrap();
    std::fs::copy(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cbox.xml"),
        work.join("s.xml"),
    )
    .unwrap();
    let tex = work.join(textures).display().to_string();
    let mount = root.display().to_string();
    let scene = work.join("s.xml").display().to_string();
    for name in SLURM_NAMES.iter().chain(K8S_NAMES) {
        let out = Command::new(bin())
            .current_dir(&work)
            .args(["cluster", "k8s", "s.xml", "--shards", "2", "--denoise"])
            .args([
                "--image",
                "reg/tstat:1",
                "--claim",
                "data",
                "--mount",
                &mount,
            ])
            .args(["--binary", binary, "--name", "My Job"])
            .arg(format!("--out={name}"))
            .args(["--", "--spp", "8", "-a", textures])
            .output()
            .unwrap();
        let stdout = String::from_utf8(out.stdout).unwrap();
        assert!(
            out.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let dir = work.join(name);
        let d = dir.display().to_string();
        let lines = printed_commands(&stdout);
        assert_eq!(lines.len(), 3, "{stdout}");
        let mut got = Vec::new();
        for l in &lines {
            got.extend(sh.line(l));
        }
        assert_eq!(
            got,
            vec![
                strings(&["apply", "-f", &format!("{d}/render-job.json")]),
                strings(&[
                    "wait",
                    "--for=condition=complete",
                    "--timeout=24h",
                    "job/my-job-render"
                ]),
                strings(&["apply", "-f", &format!("{d}/merge-job.json")]),
            ],
            "{d}: {stdout}"
        );
        let json = |f: &str| -> serde_json::Value {
            serde_json::from_str(&std::fs::read_to_string(dir.join(f)).unwrap()).unwrap()
        };
        let container =
            |v: &serde_json::Value| v["spec"]["template"]["spec"]["containers"][0].clone();
        let render = container(&json("render-job.json"));
        let cmd: Vec<String> = serde_json::from_value(render["command"].clone()).unwrap();
        assert_eq!(
            cmd,
            strings(&[
                binary,
                "render",
                &scene,
                "--shard",
                "auto/2",
                "--out",
                &format!("{d}/shards/shard-{{shard}}.tstats"),
                "--threads",
                "4",
                "--spp",
                "8",
                "-a",
                &tex,
            ])
        );
        let merge = container(&json("merge-job.json"));
        let cmd: Vec<String> = serde_json::from_value(merge["command"].clone()).unwrap();
        assert_eq!(cmd[..2], strings(&["sh", "-c"])[..]);
        for i in 0..2 {
            std::fs::write(dir.join(format!("shards/shard-{i}.tstats")), "").unwrap();
        }
        sh.run("sh", &["-n", "-c", &cmd[2]], &[]);
        let got = sh.run("sh", &["-c", &cmd[2]], &[]);
        assert_eq!(got.len(), 2, "{got:?}");
        assert_eq!(
            got[0][..5],
            strings(&[
                "merge",
                &format!("{d}/shards/shard-0.tstats"),
                &format!("{d}/shards/shard-1.tstats"),
                "--out",
                &format!("{d}/merged.tstats"),
            ])[..]
        );
        assert_eq!(
            got[1][..4],
            strings(&[
                "denoise",
                &format!("{d}/merged.tstats"),
                "--out",
                &format!("{d}/denoised.npy")
            ])[..]
        );
    }
    assert!(!root.join("cwd/pwned").exists() && !work.join("pwned").exists());
}
