//! Hostile command lines: a table of malformed invocations of the real binary, each of
//! which must fail with exit 1 (our errors) or 2 (clap's usage errors), one clear first
//! line on stderr starting "error:", no panic, in bounded time and memory, and without
//! leaving anything behind: the whole working directory (inputs, pre-existing files,
//! hidden temporary names) is compared before and after every case.

use crate::common::hostile;

use hostile::{bin, check_failure};
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

fn ok(mut c: Command) {
    let out = c.output().unwrap();
    assert!(
        out.status.success(),
        "{:?}: {}",
        c,
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Valid inputs, built once: bundles b (seed 0) and c (seed 5) of the Cornell box at
/// 8 x 8, 4 bins, 2 spp; vol.npy (b's noisy mean); the scene s.xml, a link to it, a
/// link `here` to the directory itself, and a copy inside scenes/; a precious file, a directory named like a file, and an existing
/// report directory holding a file.
fn fixture() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cbox = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cbox.xml");
    std::fs::copy(&cbox, d.join("s.xml")).unwrap();
    std::fs::create_dir(d.join("scenes")).unwrap();
    std::fs::copy(&cbox, d.join("scenes/s2.xml")).unwrap();
    std::os::unix::fs::symlink("s.xml", d.join("link.xml")).unwrap();
    std::os::unix::fs::symlink(".", d.join("here")).unwrap();
    for (name, seed) in [("b.tstats", "0"), ("c.tstats", "5")] {
        let mut c = Command::new(bin());
        c.current_dir(d).args([
            "render", "s.xml", "--out", name, "--width", "8", "--spp", "2", "--bins", "4",
            "--seed", seed,
        ]);
        ok(c);
    }
    let mut c = Command::new(bin());
    c.current_dir(d)
        .args(["export", "b.tstats", "--out", "vol.npy"]);
    ok(c);
    std::fs::write(d.join("file.txt"), "precious").unwrap();
    std::fs::create_dir(d.join("dir.npy")).unwrap();
    std::fs::write(d.join("dir.npy/inside.txt"), "also precious").unwrap();
    std::fs::create_dir(d.join("existing")).unwrap();
    std::fs::write(d.join("existing/keep.txt"), "keep").unwrap();
    dir
}

/// Usage errors (clap's): exit 2. Ours: exit 1.
#[derive(Clone, Copy, PartialEq, Debug)]
enum Exit {
    Ours,
    Usage,
}
use Exit::{Ours, Usage};

/// One hostile invocation: the arguments (run in the fixture directory), who reports
/// it, and a piece of the first stderr line.
type Case = (&'static [&'static str], Exit, &'static str);

const R: &str = "render";

#[rustfmt::skip]
const CASES: &[Case] = &[
    // Negative and out-of-range numbers: our message naming the flag and the value.
    (&[R, "s.xml", "--out", "n.tstats", "--spp", "-3"], Ours, "--spp -3: must be at least 2"),
    (&[R, "s.xml", "--out", "n.tstats", "--spp", "0"], Ours, "--spp 0: must be at least 2"),
    (&[R, "s.xml", "--out", "n.tstats", "--spp", "99999999999"], Ours, "--spp 99999999999: must be at most"),
    (&[R, "s.xml", "--out", "n.tstats", "--width", "-1"], Ours, "--width -1: must be at least 1"),
    (&[R, "s.xml", "--out", "n.tstats", "--height", "0"], Ours, "--height 0: must be at least 1"),
    (&[R, "s.xml", "--out", "n.tstats", "--bins", "-5"], Ours, "--bins -5: must be at least 1"),
    (&[R, "s.xml", "--out", "n.tstats", "--width", "2000000"], Ours, "--width 2000000: must be at most"),
    (&[R, "s.xml", "--out", "n.tstats", "--threads", "-1"], Ours, "--threads -1: must be at least 1"),
    (&[R, "s.xml", "--out", "n.tstats", "--threads", "0"], Ours, "--threads 0: must be at least 1"),
    (&[R, "s.xml", "--out", "n.tstats", "--threads", "100000"], Ours, "--threads 100000: must be at most"),
    (&[R, "s.xml", "--out", "n.tstats", "--seed", "-1"], Ours, "--seed -1: must be between 0 and"),
    (&[R, "s.xml", "--out", "n.tstats", "--max-depth", "-5"], Ours, "--max-depth -5: must be at least -1"),
    (&[R, "s.xml", "--out", "n.tstats", "-a", "no_such_folder"], Ours, "-a no_such_folder: not a folder"),
    (&[R, "s.xml", "--out", "n.tstats", "-a", "s.xml"], Ours, "-a s.xml: not a folder"),
    (&[R, "s.xml", "--out", "n.tstats", "--unit-m", "-1"], Ours, "--unit-m -1: must be a positive"),
    (&[R, "s.xml", "--out", "n.tstats", "--unit-m", "nan"], Ours, "--unit-m NaN: must be a positive"),
    (&[R, "s.xml", "--out", "n.tstats", "--start-opl", "inf"], Ours, "--start-opl inf: must be a finite"),
    (&[R, "s.xml", "--out", "n.tstats", "--bin-width-opl", "-1"], Ours, "--bin-width-opl must be positive"),
    (&[R, "s.xml", "--out", "n.tstats", "--max-memory", "-1G"], Ours, "--max-memory"),
    // The memory check comes before any allocation (here under a 2 GB address space).
    (&[R, "s.xml", "--out", "n.tstats", "--width", "1000000", "--height", "1000000"], Ours, "the render needs"),
    // Rows stream to disk: a film that fits in memory row by row but not on the disk is
    // refused before any work.
    (&[R, "s.xml", "--out", "n.tstats", "--width", "1", "--height", "1000000", "--bins", "1000000"], Ours, "the bundle needs 76000.06 GB on disk but only"),
    (&["run", "s.xml", "--out", "r", "--width", "1", "--height", "1000000", "--bins", "1000000"], Ours, "the run's output needs"),
    (&[R, "s.xml", "--out", "n.tstats", "-D", "a"], Ours, "-D a: expected name=value"),
    (&[R, "s.xml", "--out", "n.tstats", "-D", "=b"], Ours, "-D =b: the name is empty"),
    (&[R, "s.xml", "--out", "n.tstats", "--transform", "box-cox:nan"], Ours, "--transform"),
    // clap's usage errors: exit 2, the whole complaint on the first line.
    (&[R, "s.xml", "--out", "n.tstats", "--seed", "0x10"], Usage, "invalid value '0x10' for '--seed"),
    (&[R, "s.xml", "--out", "n.tstats", "--pixel-sampling", "foo"], Usage, "[possible values: stratified, independent, sobol]"),
    (&[R], Usage, "required arguments were not provided: --out <OUT> <SCENE>"),
    (&[R, "s.xml", "--out", ""], Usage, "a value is required for '--out <OUT>'"),
    (&["rendr", "s.xml"], Usage, "unrecognized subcommand 'rendr'"),
    // Outputs that are, contain or sit inside an input, or another output.
    (&[R, "s.xml", "--out", "s.xml", "--force"], Ours, "--out s.xml: is the input scene s.xml"),
    (&[R, "s.xml", "--out", "./s.xml", "--force"], Ours, "is the input scene s.xml"),
    (&[R, "s.xml", "--out", "link.xml", "--force"], Ours, "is the input scene s.xml"),
    (&[R, "link.xml", "--out", "s.xml", "--force"], Ours, "is the input scene link.xml"),
    (&[R, "s.xml", "--out", "here/s.xml", "--force"], Ours, "is the input scene s.xml"),
    (&[R, "s.xml", "--out", "here", "--force"], Ours, "contains the input scene s.xml"),
    (&[R, concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cbox.xml"), "--out", "here", "--force"], Ours, "holds the current directory"),
    (&[R, "scenes/s2.xml", "--out", "scenes", "--force"], Ours, "contains the input scene scenes/s2.xml"),
    (&["run", "s.xml", "--out", "s.xml", "--force", "--width", "4", "--spp", "2", "--bins", "2"], Ours, "is the input scene"),
    (&["denoise", "b.tstats", "--out", "d.npy", "--exr", "d.npy"], Ours, "--exr d.npy: is the same path as --out d.npy"),
    (&["denoise", "b.tstats", "--out", "d.npy", "--exr", "./d.npy/"], Ours, "is the same path as --out d.npy"),
    (&["denoise", "b.tstats", "--out", "e/d.npy", "--exr", "e"], Ours, "is inside --exr e"),
    (&["denoise", "b.tstats", "--out", "b.tstats/x.npy"], Ours, "is inside the input bundle b.tstats"),
    // The denoiser's memory budget: a size, and at least one row and its halo.
    (&["denoise", "b.tstats", "--out", "d.npy", "--max-memory", "-1G"], Ours, "--max-memory -1G: not a size"),
    (&["denoise", "b.tstats", "--out", "d.npy", "--variance", "biased"], Ours, "--variance biased is the published code's convention: only with --method published"),
    (&["denoise", "b.tstats", "--out", "d.npy", "--border", "zero", "--no-membership"], Ours, "--border zero is the published code's convention: only with --method published"),
    (&["denoise", "b.tstats", "--out", "d.npy", "--border", "mirror"], Usage, "--border"),
    (&["denoise", "b.tstats", "--out", "d.npy", "--max-memory", "1k"], Ours, "--max-memory 1k: denoising"),
    // The denoiser's membership settings.
    (&["denoise", "b.tstats", "--out", "d.npy", "--t2-max", "-1"], Ours, "--t2-max -1: must be a positive number"),
    (&["denoise", "b.tstats", "--out", "d.npy", "--t2-patch", "nan"], Ours, "--t2-patch NaN: must be a positive number"),
    (&["denoise", "b.tstats", "--out", "d.npy", "--emitter-radius", "-2"], Ours, "--emitter-radius -2: must be >= 0"),
    (&["denoise", "b.tstats", "--out", "d.npy", "--emitter-radius", "100"], Ours, "--emitter-radius 100: at most 64"),
    (&["denoise", "b.tstats", "--out", "d.npy", "--gamma", "0.1"], Ours, "add --method published"),
    (&["denoise", "b.tstats", "--out", "d.npy", "--method", "published", "--t2-max", "4"], Ours, "belong to --method tstat"),
    (&["denoise", "b.tstats", "--out", "d.npy", "--method", "foo"], Usage, "invalid value 'foo' for '--method"),
    (&["report", "sweep", "c.tstats", "--reference", "b.tstats", "--out", "sw", "--depth-align", "maybe"], Ours, "--depth-align maybe: use on, off or on,off"),
    (&["report", "sweep", "c.tstats", "--reference", "b.tstats", "--out", "sw", "--method", "published", "--t2-patch", "2"], Ours, "belong to --method tstat"),
    (&["export", "b.tstats", "--out", "e.npy", "--steady", "e.npy"], Ours, "--steady e.npy: is the same path as --out e.npy"),
    (&["export", "b.tstats", "--out", "e.npy", "--steady", "./e.npy"], Ours, "is the same path as --out e.npy"),
    (&["merge", "b.tstats", "c.tstats", "--out", "b.tstats", "--force"], Ours, "is the input bundle b.tstats"),
    (&["merge", "b.tstats", "c.tstats", "--out", "./c.tstats/", "--force"], Ours, "is the input bundle c.tstats"),
    (&["frames", "b.tstats", "--out", "b.tstats/frames"], Ours, "is inside the input volume b.tstats"),
    (&["frames", "vol.npy", "--out", "vol.npy", "--force"], Ours, "is the input volume vol.npy"),
    (&["report", "compare", "--reference", "b.tstats", "--input", "a=c.tstats", "--out", "b.tstats"], Ours, "is inside the input --reference b.tstats"),
    (&["report", "sweep", "c.tstats", "--reference", "b.tstats", "--out", "c.tstats", "--force"], Ours, "is inside the input bundle c.tstats"),
    // Paths that name nothing, lead nowhere, or are the wrong kind of thing.
    (&[R, "s.xml", "--out", ".", "--force"], Ours, "--out .: does not name a file or directory"),
    (&[R, "s.xml", "--out", "nodir/n.tstats"], Ours, "the directory nodir does not exist"),
    (&[R, "s.xml", "--out", "file.txt/n.tstats"], Ours, "file.txt is not a directory"),
    (&[R, "s.xml", "--out", "/proc/n.tstats"], Ours, "cannot write in /proc"),
    (&[R, "s.xml", "--out", "file.txt", "--force"], Ours, "file.txt: is a file"),
    (&[R, "s.xml", "--out", "b.tstats"], Ours, "b.tstats: already exists (use --force"),
    (&["denoise", "b.tstats", "--out", "dir.npy", "--force"], Ours, "dir.npy: is a directory"),
    (&["export", "b.tstats", "--steady", "dir.npy", "--force"], Ours, "dir.npy: is a directory"),
    // Other commands' numbers.
    (&["run", "--out", "r", "--every", "0"], Ours, "--every 0: must be at least 1"),
    (&["run", "--out", "r", "--seed", "-7"], Ours, "--seed -7"),
    (&["denoise", "b.tstats", "--out", "d.npy", "--threads", "-2"], Ours, "--threads -2: must be at least 1"),
    (&["frames", "b.tstats", "--out", "f", "--every", "-1"], Ours, "--every -1: must be at least 1"),
    (&["frames", "b.tstats", "--out", "f", "--exposure", "-1"], Ours, "--exposure -1: must be a positive"),
    (&["frames", "b.tstats", "--out", "f", "--exposure", "nan"], Ours, "--exposure NaN"),
    (&["frames", "b.tstats", "--out", "f", "--exposure", "1e39"], Ours, "beyond the range of f32"),
    (&["frames", "b.tstats", "--out", "f", "--streak-row", "100"], Ours, "--streak-row 100: the image has 8 rows"),
    (&["frames", "b.tstats", "--out", "f", "--streak-row", "-1"], Ours, "--streak-row -1: must be at least 0"),
    (&["frames", "vol.npy", "--out", "f", "--start-opl", "0", "--bin-width-opl", "inf"], Ours, "--bin-width-opl inf"),
    (&["frames", "vol.npy", "--out", "f", "--unit-m", "inf"], Ours, "--unit-m inf"),
    (&["report", "sweep", "c.tstats", "--reference", "b.tstats", "--out", "sw", "--radius", "-1"], Ours, "--radius -1: must be at least 0"),
    (&["report", "sweep", "c.tstats", "--reference", "b.tstats", "--out", "sw", "--temporal-radius", "1,-2"], Ours, "--temporal-radius -2: must be at least 0"),
    (&["report", "sweep", "c.tstats", "--reference", "b.tstats", "--out", "sw", "--method", "published", "--gamma", "nan"], Ours, "--gamma nan: 'nan' is not a finite number"),
    (&["report", "convergence", "s.xml", "--out", "cv", "--spp", "2,-3"], Ours, "--spp -3: must be at least 2"),
    (&["report", "convergence", "s.xml", "--out", "cv", "--spp", "4", "--reference-spp", "-1"], Ours, "--reference-spp -1: must be at least 2"),
    (&["report", "convergence", "s.xml", "--out", "cv", "--spp", "4", "--seed", "-1"], Ours, "--seed -1"),
    (&["report", "convergence", "s.xml", "--out", "cv", "--spp", "8,12", "--replicates", "8"], Ours, "--replicates 8 does not divide spp 12"),
    (&[R, "s.xml", "--out", "n.tstats", "--spp", "8", "--replicates", "16"], Ours, "--replicates 16 does not divide spp 8"),
    (&["run", "s.xml", "--out", "r", "--spp", "8", "--replicates", "1"], Ours, "--replicates 1: a variance needs at least 2"),
    // Report commands that fail: no output directory left behind, and an existing one
    // keeps exactly what it held (the convergence cases fail after creating it).
    (&["report", "compare", "--reference", "b.tstats", "--input", "a=missing.npy", "--out", "cmp"], Ours, "missing.npy"),
    (&["report", "compare", "--reference", "b.tstats", "--input", "a=missing.npy", "--out", "existing"], Ours, "missing.npy"),
    (&["report", "compare", "--reference", "b.tstats", "--input", "a=c.tstats", "--input", "a=vol.npy"], Ours, "the label a is given twice"),
    (&["report", "compare", "--reference", "b.tstats", "--input", "=c.tstats"], Ours, "the label is empty"),
    (&["report", "compare", "--reference", "b.tstats", "--input", "a=c.tstats", "--out", "file.txt"], Ours, "exists and is not a directory"),
    (&["report", "sweep", "c.tstats", "--reference", "missing.npy", "--out", "sw"], Ours, "missing.npy"),
    (&["report", "sweep", "c.tstats", "--reference", "missing.npy", "--out", "existing"], Ours, "missing.npy"),
    (&["report", "convergence", "s.xml", "--out", "cv", "--spp", "2", "--width", "4", "--bins", "2", "--reference", "c.tstats"], Ours, "the reference has shape"),
    (&["report", "convergence", "s.xml", "--out", "existing", "--spp", "2", "--width", "4", "--bins", "2", "--reference", "c.tstats"], Ours, "the reference has shape"),
    (&["report", "convergence", "missing.xml", "--out", "cv", "--spp", "2"], Ours, "missing.xml"),
];

#[test]
fn hostile_command_lines_fail_cleanly_and_leave_nothing() {
    let fx = fixture();
    let dir = fx.path();
    let started = Instant::now();
    let mut failures = Vec::new();
    for (k, (args, exit, want)) in CASES.iter().enumerate() {
        let args: Vec<String> = args.iter().map(|a| a.to_string()).collect();
        let what = format!("case {k}: tstat {}", args.join(" "));
        let want_code = match exit {
            Ours => 1,
            Usage => 2,
        };
        let problems = check_failure(&args, dir, want_code, want);
        if !problems.is_empty() {
            failures.push(format!("{what}\n  {}", problems.join("\n  ")));
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} cases failed:\n{}",
        failures.len(),
        CASES.len(),
        failures.join("\n")
    );
    assert!(
        started.elapsed() < Duration::from_secs(60),
        "the corpus took {:?}",
        started.elapsed()
    );
}

/// A closed pipe on stdout (`tstat info B | head -0`) ends quietly; a full device is
/// one error line. Neither panics.
#[test]
fn stdout_that_cannot_be_written_is_no_panic() {
    let fx = fixture();
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    let out = Command::new(bin())
        .current_dir(fx.path())
        .args(["info", "b.tstats"])
        .stdout(writer)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(out.status.code(), Some(0), "{err}");
    if Path::new("/dev/full").exists() {
        let full = std::fs::OpenOptions::new()
            .write(true)
            .open("/dev/full")
            .unwrap();
        let out = Command::new(bin())
            .current_dir(fx.path())
            .args(["info", "b.tstats"])
            .stdout(full)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{err}");
        assert!(
            err.starts_with("error: writing to standard output:") && err.lines().count() == 1,
            "{err}"
        );
    }
}

/// The checks refuse only what is wrong: the same commands with distinct, valid
/// outputs succeed, and a report into an existing directory adds its files and keeps
/// what was there.
#[test]
fn valid_outputs_next_to_the_inputs_still_work() {
    let fx = fixture();
    let d = fx.path();
    let tstat = |args: &[&str]| {
        let mut c = Command::new(bin());
        c.current_dir(d).args(args);
        ok(c);
    };
    tstat(&["denoise", "b.tstats", "--out", "d.npy", "--exr", "d_exr"]);
    assert!(d.join("d.npy").is_file() && d.join("d_exr/bin_0000.exr").is_file());
    tstat(&["export", "b.tstats", "--out", "e.npy", "--steady", "e.exr"]);
    tstat(&["merge", "b.tstats", "./c.tstats/", "--out", "m.tstats"]);
    tstat(&[
        "report",
        "compare",
        "--reference",
        "m.tstats",
        "--input",
        "b=b.tstats",
        "--out",
        "existing",
    ]);
    assert!(d.join("existing/metrics.csv").is_file());
    assert_eq!(std::fs::read(d.join("existing/keep.txt")).unwrap(), b"keep");
    // A volume against itself has no error to plot: the summary lists only what was
    // written.
    let out = Command::new(bin())
        .current_dir(d)
        .args([
            "report",
            "compare",
            "--reference",
            "vol.npy",
            "--input",
            "same=vol.npy",
            "--out",
            "same",
        ])
        .output()
        .unwrap();
    assert!(out.status.success());
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(!d.join("same/per_bin.png").exists());
    assert!(
        stdout.contains("wrote same/{metrics.csv, metrics.md, per_bin.csv}"),
        "{stdout}"
    );
    // --force replaces an earlier output of the same kind.
    tstat(&["frames", "vol.npy", "--out", "f"]);
    tstat(&["frames", "vol.npy", "--out", "f", "--force", "--every", "2"]);
    assert_eq!(std::fs::read_dir(d.join("f/frames")).unwrap().count(), 2);
}

/// Legal but suspicious: a time window the light never reaches renders, with a warning.
#[test]
fn an_empty_time_window_is_a_warning() {
    let fx = fixture();
    let out = Command::new(bin())
        .current_dir(fx.path())
        .args([
            "render",
            "s.xml",
            "--out",
            "late.tstats",
            "--width",
            "4",
            "--spp",
            "2",
            "--bins",
            "2",
            "--start-opl",
            "1000",
        ])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("warning: nothing landed in the time window (OPL 1000 to"),
        "{err}"
    );
}

/// `run` without a scene records the bundled scene where it ends up (DIR/cbox.xml), not
/// under the temporary directory's name.
#[test]
fn run_records_the_bundled_scene_at_its_final_path() {
    let dir = tempfile::tempdir().unwrap();
    let out = Command::new(bin())
        .current_dir(dir.path())
        .args([
            "run", "--out", "r", "--width", "4", "--spp", "2", "--bins", "2",
        ])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("r/cbox.xml: 4x4 px"), "{err}");
    let manifest =
        std::fs::read_to_string(dir.path().join("r/scene.tstats/manifest.json")).unwrap();
    assert!(manifest.contains("\"path\": \"r/cbox.xml\""), "{manifest}");
    assert!(dir.path().join("r/cbox.xml").is_file());
}
