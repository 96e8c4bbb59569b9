//! The hostile-input corpora's runner: the real binary under an address-space limit
//! and a deadline, its exit code and stderr, and a snapshot of a directory to show that
//! a failed command left nothing behind. Included by the `hostile_*` tests with
//! `#[path = "common/hostile.rs"] mod hostile;`.
#![allow(dead_code)]

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

pub const TIME_LIMIT: Duration = Duration::from_secs(20);
/// Address-space limit for every run (bytes).
pub const MEMORY_LIMIT: u64 = 2_000_000_000;

pub fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_tstat")
}

/// The binary under an address-space limit: `prlimit` if present, else `ulimit -v`.
pub fn limited(args: &[String], dir: &Path) -> Command {
    let prlimit = ["/usr/bin/prlimit", "/bin/prlimit"]
        .into_iter()
        .find(|p| Path::new(p).exists());
    let mut c = match prlimit {
        Some(p) => {
            let mut c = Command::new(p);
            c.arg(format!("--as={MEMORY_LIMIT}")).arg(bin());
            c
        }
        None => {
            let mut c = Command::new("sh");
            c.arg("-c")
                .arg(format!(
                    "ulimit -v {}; exec \"$0\" \"$@\"",
                    MEMORY_LIMIT / 1000
                ))
                .arg(bin());
            c
        }
    };
    c.args(args).current_dir(dir);
    c
}

pub struct Run {
    pub code: Option<i32>,
    pub stdout: String,
    pub stderr: String,
    pub timed_out: bool,
    pub seconds: f64,
}

/// Runs with a deadline: a run that takes longer is killed (and reported).
pub fn run(mut cmd: Command) -> Run {
    let mut child = cmd
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn tstat");
    fn reader(mut r: impl std::io::Read + Send + 'static) -> std::thread::JoinHandle<String> {
        std::thread::spawn(move || {
            let mut s = String::new();
            r.read_to_string(&mut s).ok();
            s
        })
    }
    let out = reader(child.stdout.take().unwrap());
    let err = reader(child.stderr.take().unwrap());
    let start = Instant::now();
    let mut timed_out = false;
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if start.elapsed() > TIME_LIMIT {
            timed_out = true;
            let _ = child.kill();
            break child.wait().unwrap();
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    Run {
        code: status.code(),
        stdout: out.join().unwrap(),
        stderr: err.join().unwrap(),
        timed_out,
        seconds: start.elapsed().as_secs_f64(),
    }
}

/// Every entry under `dir` (hidden ones too): file contents (FIFOs and sockets by
/// kind, never read), directories, link targets.
pub fn snapshot(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    fn walk(root: &Path, dir: &Path, out: &mut BTreeMap<PathBuf, Vec<u8>>) {
        for e in std::fs::read_dir(dir).unwrap().flatten() {
            let p = e.path();
            let rel = p.strip_prefix(root).unwrap().to_path_buf();
            let meta = std::fs::symlink_metadata(&p).unwrap();
            if meta.file_type().is_symlink() {
                let t = std::fs::read_link(&p).unwrap();
                out.insert(rel, format!("link {}", t.display()).into_bytes());
            } else if meta.is_dir() {
                out.insert(rel, b"dir".to_vec());
                walk(root, &p, out);
            } else if !meta.is_file() {
                // A FIFO or socket: reading it would block.
                out.insert(rel, b"special".to_vec());
            } else {
                out.insert(rel, std::fs::read(&p).unwrap());
            }
        }
    }
    let mut out = BTreeMap::new();
    walk(dir, dir, &mut out);
    out
}

/// What differs between two snapshots.
pub fn changed(
    before: &BTreeMap<PathBuf, Vec<u8>>,
    after: &BTreeMap<PathBuf, Vec<u8>>,
) -> Vec<PathBuf> {
    let mut out: Vec<PathBuf> = before
        .keys()
        .chain(after.keys())
        .filter(|p| before.get(*p) != after.get(*p))
        .cloned()
        .collect();
    out.dedup();
    out
}

/// Runs `args` in `dir` and lists what is wrong with the outcome for a command that
/// must fail: exit `code`, a first stderr line "error: ..." holding `want`, exactly one
/// error line (for our own errors), no panic, within the deadline, and `dir` unchanged.
pub fn check_failure(args: &[String], dir: &Path, code: i32, want: &str) -> Vec<String> {
    let before = snapshot(dir);
    let r = run(limited(args, dir));
    let after = snapshot(dir);
    let first = r.stderr.lines().next().unwrap_or_default();
    let mut problems = Vec::new();
    if r.timed_out {
        problems.push(format!("killed after {TIME_LIMIT:?}"));
    }
    if r.code != Some(code) {
        problems.push(format!("exit {:?}, expected {code}", r.code));
    }
    if !first.starts_with("error: ") || !first.contains(want) {
        problems.push(format!("first stderr line {first:?} lacks {want:?}"));
    }
    if r.stderr.contains("panicked") {
        problems.push("panicked".into());
    }
    if code == 1 && r.stderr.lines().filter(|l| l.starts_with("error")).count() != 1 {
        problems.push("more than one error line".into());
    }
    if before != after {
        problems.push(format!("changed on disk: {:?}", changed(&before, &after)));
    }
    if !problems.is_empty() {
        problems.push(format!("stderr: {}", r.stderr));
    }
    problems
}
