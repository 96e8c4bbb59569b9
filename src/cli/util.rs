//! Small helpers shared by subcommands: sizes, memory, thread pools, numeric flags,
//! output paths (checked against each other and the inputs before anything is
//! written), report directories, and printing to stdout.

pub use crate::job::system::{disk_size, human_bytes, physical_memory, with_threads};
use anyhow::{anyhow, bail, ensure};
use std::collections::HashSet;
use std::ffi::OsString;
use std::path::{Component, Path, PathBuf};

/// A size that does not parse or does not fit; shown after the flag and what the user
/// typed (see [`size_flag`]).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum SizeError {
    #[error("not a size such as 512M, 8G or 4Gi (a number, then K, M, G, T, P or E for powers of 1000, Ki, Mi, Gi, Ti, Pi or Ei for powers of 1024, and an optional B)")]
    Syntax,
    #[error("less than one byte")]
    Zero,
    #[error("more than 2^64 - 1 bytes (16Ei), the largest size")]
    Overflow,
}

/// The sizes' units: `K` = 1000, `Ki` = 1024, up to `E` and `Ei`.
const SIZE_UNITS: &str = "KMGTPE";

/// Parses a size in bytes: a decimal number (`512`, `1.5`; no sign, no exponent), then
/// an optional unit (`K`, `M`, `G`, `T`, `P`, `E`: powers of 1000; `Ki` ... `Ei`:
/// powers of 1024; any case) and an optional `B`. Exact integer arithmetic: a fraction
/// of a byte is dropped (`1.5K` = 1500, `0.3Ki` = 307), a size of 0 bytes or beyond
/// 2^64 - 1 is refused, never clamped. Use [`size_flag`] for a flag.
pub fn parse_bytes(s: &str) -> Result<u64, SizeError> {
    let t = s.trim();
    let t = t.strip_suffix(['B', 'b']).unwrap_or(t);
    let (t, binary) = match t.strip_suffix(['i', 'I']) {
        Some(head) => (head, true),
        None => (t, false),
    };
    let unit = t
        .chars()
        .next_back()
        .and_then(|c| SIZE_UNITS.find(c.to_ascii_uppercase()));
    let (num, mult) = match unit {
        Some(k) => {
            let k = k as u32 + 1;
            let mult = if binary {
                1u128 << (10 * k)
            } else {
                1000u128.pow(k)
            };
            (t[..t.len() - 1].trim_end(), mult)
        }
        None if binary => return Err(SizeError::Syntax),
        None => (t, 1),
    };
    let (int, frac) = num.split_once('.').unwrap_or((num, ""));
    let digits = |d: &str| d.bytes().all(|b| b.is_ascii_digit());
    // At most 18 decimals: their value times the largest unit (2^60) fits a u128.
    if (int.is_empty() && frac.is_empty()) || !digits(int) || !digits(frac) || frac.len() > 18 {
        return Err(SizeError::Syntax);
    }
    let whole = int
        .bytes()
        .try_fold(0u128, |a, d| {
            a.checked_mul(10)?.checked_add(u128::from(d - b'0'))
        })
        .and_then(|v| v.checked_mul(mult))
        .ok_or(SizeError::Overflow)?;
    let frac_value: u128 = frac.parse().unwrap_or(0);
    let part = frac_value * mult / 10u128.pow(frac.len() as u32);
    let bytes = whole.checked_add(part).ok_or(SizeError::Overflow)?;
    match u64::try_from(bytes) {
        Ok(0) => Err(SizeError::Zero),
        Ok(b) => Ok(b),
        Err(_) => Err(SizeError::Overflow),
    }
}

/// A size flag (`--max-memory 8G`), parsed by [`parse_bytes`]; errors name the flag and
/// echo what was typed: "--max-memory 8Q: not a size such as ...".
pub fn size_flag(flag: &str, s: &str) -> anyhow::Result<u64> {
    parse_bytes(s).map_err(|e| anyhow!("{flag} {s}: {e}"))
}

/// [`size_flag`] within `min..=max` bytes; the bounds are shown as written in `min_text`
/// and `max_text` (e.g. "1Ki", "1Pi").
pub fn size_flag_in(
    flag: &str,
    s: &str,
    (min, min_text): (u64, &str),
    (max, max_text): (u64, &str),
) -> anyhow::Result<u64> {
    let b = size_flag(flag, s)?;
    ensure!(b >= min, "{flag} {s}: at least {min_text}");
    ensure!(b <= max, "{flag} {s}: at most {max_text}");
    Ok(b)
}

/// The spelling of a clap `ValueEnum` value on the command line (`fbp`, not `Fbp`), for
/// messages.
pub fn cli_name<T: clap::ValueEnum>(v: &T) -> String {
    v.to_possible_value()
        .map_or_else(String::new, |p| p.get_name().to_string())
}

// ---------------------------------------------------------------------------------
// Numeric flags. They are parsed as wide signed numbers with negative literals allowed,
// so that `--spp -3` reaches these checks and gets "--spp -3: must be at least 2"
// instead of clap's "unexpected argument '-3'".

/// The most worker threads `--threads` accepts (more only costs memory).
pub const MAX_THREADS: i64 = 1024;
/// The largest `--width`, `--height` and `--bins` (the memory check refuses far less;
/// this only keeps the arithmetic on them far from overflow).
pub const MAX_FILM_SIDE: i64 = 1_000_000;

/// Checks a whole-number flag against `min..=max`.
pub fn int_flag(flag: &str, v: i64, min: i64, max: i64) -> anyhow::Result<i64> {
    ensure!(v >= min, "{flag} {v}: must be at least {min}");
    ensure!(v <= max, "{flag} {v}: must be at most {max}");
    Ok(v)
}

/// [`int_flag`] for an optional flag, converted to the type the program uses.
pub fn opt_int<T: TryFrom<i64>>(
    flag: &str,
    v: Option<i64>,
    min: i64,
    max: i64,
) -> anyhow::Result<Option<T>> {
    v.map(|v| {
        let v = int_flag(flag, v, min, max)?;
        T::try_from(v).map_err(|_| anyhow!("{flag} {v}: out of range"))
    })
    .transpose()
}

/// `--threads`: 1 to [`MAX_THREADS`].
pub fn threads(v: Option<i64>) -> anyhow::Result<Option<usize>> {
    opt_int("--threads", v, 1, MAX_THREADS)
}

/// `--seed`: 0 to 2^64 - 1.
pub fn seed(v: Option<i128>) -> anyhow::Result<Option<u64>> {
    v.map(|s| {
        u64::try_from(s).map_err(|_| anyhow!("--seed {s}: must be between 0 and {}", u64::MAX))
    })
    .transpose()
}

/// A flag that must be a positive finite number.
pub fn positive(flag: &str, v: f64) -> anyhow::Result<f64> {
    ensure!(
        v > 0.0 && v.is_finite(),
        "{flag} {v}: must be a positive finite number"
    );
    Ok(v)
}

/// A flag that must be a finite number.
pub fn finite(flag: &str, v: f64) -> anyhow::Result<f64> {
    ensure!(v.is_finite(), "{flag} {v}: must be a finite number");
    Ok(v)
}

/// A comma-separated list of whole numbers in `min..=max` ("3,5,10").
pub fn int_list(flag: &str, s: &str, min: i64, max: i64) -> anyhow::Result<Vec<i64>> {
    let v = split_list(flag, s)?
        .into_iter()
        .map(|t| match t.parse::<i64>() {
            Ok(v) => int_flag(flag, v, min, max),
            Err(_) => bail!("{flag} {s}: '{t}' is not a whole number"),
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    Ok(v)
}

/// A comma-separated list of finite numbers ("0.5,1,2").
pub fn float_list(flag: &str, s: &str) -> anyhow::Result<Vec<f64>> {
    split_list(flag, s)?
        .into_iter()
        .map(|t| match t.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => bail!("{flag} {s}: '{t}' is not a finite number"),
        })
        .collect()
}

/// The non-empty items of a comma-separated list; an empty list is an error.
pub fn split_list<'a>(flag: &str, s: &'a str) -> anyhow::Result<Vec<&'a str>> {
    let v: Vec<&str> = s
        .split(',')
        .map(str::trim)
        .filter(|t| !t.is_empty())
        .collect();
    ensure!(!v.is_empty(), "{flag}: the list is empty");
    Ok(v)
}

// ---------------------------------------------------------------------------------
// Output paths.

/// What a command writes at an output path.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// A file (a volume, an image, a table).
    File,
    /// A directory the command creates whole (a bundle, frames, a run).
    Dir,
}

/// A path argument: how the user gave it ("--out", "the scene", "--input a") and the path.
#[derive(Clone, Debug)]
pub struct Arg {
    pub name: String,
    pub path: PathBuf,
}

/// `Arg { name, path }`.
pub fn arg(name: impl Into<String>, path: impl AsRef<Path>) -> Arg {
    Arg {
        name: name.into(),
        path: path.as_ref().to_path_buf(),
    }
}

/// The path with every existing prefix resolved (symlinks, `.`, `..`), made absolute;
/// the components that do not exist yet are appended as written (`..` lexically). Two
/// spellings of the same place (`./a` and `a`, a link and its target) resolve equal.
pub fn resolve(p: &Path) -> PathBuf {
    let abs = if p.is_absolute() {
        p.to_path_buf()
    } else {
        match std::env::current_dir() {
            Ok(d) => d.join(p),
            Err(_) => p.to_path_buf(),
        }
    };
    let comps: Vec<Component> = abs.components().collect();
    for k in (1..=comps.len()).rev() {
        let prefix: PathBuf = comps[..k].iter().collect();
        if let Ok(mut out) = prefix.canonicalize() {
            for c in &comps[k..] {
                match c {
                    Component::CurDir => {}
                    Component::ParentDir => {
                        out.pop();
                    }
                    other => out.push(other),
                }
            }
            return out;
        }
    }
    abs
}

/// Refuses outputs that would replace or write into an input, or another output of the
/// same command: equal paths (through any spelling or link), an output inside an input
/// directory, an input inside an output directory (replacing it would delete the
/// input), and two outputs of which one is, or is inside, the other.
pub fn check_collisions(inputs: &[Arg], outputs: &[Arg]) -> anyhow::Result<()> {
    let ins: Vec<PathBuf> = inputs.iter().map(|a| resolve(&a.path)).collect();
    let outs: Vec<PathBuf> = outputs.iter().map(|a| resolve(&a.path)).collect();
    let show = |a: &Arg| {
        let sep = if a.name.ends_with('=') { "" } else { " " };
        format!("{}{sep}{}", a.name, a.path.display())
    };
    for (o, op) in outputs.iter().zip(&outs) {
        for (i, ip) in inputs.iter().zip(&ins) {
            if op == ip {
                bail!(
                    "{}: is the input {}; an output never replaces an input",
                    show(o),
                    show(i)
                );
            }
            if op.starts_with(ip) {
                bail!(
                    "{}: is inside the input {}; write it elsewhere",
                    show(o),
                    show(i)
                );
            }
            if ip.starts_with(op) {
                bail!(
                    "{}: contains the input {}; replacing it would delete the input",
                    show(o),
                    show(i)
                );
            }
        }
    }
    for (k, (b, bp)) in outputs.iter().zip(&outs).enumerate() {
        for (a, ap) in outputs.iter().zip(&outs).take(k) {
            if bp == ap {
                bail!("{}: is the same path as {}", show(b), show(a));
            }
            if bp.starts_with(ap) || ap.starts_with(bp) {
                let (inner, outer) = if bp.starts_with(ap) { (b, a) } else { (a, b) };
                bail!(
                    "{}: is inside {}; one output would replace the other",
                    show(inner),
                    show(outer)
                );
            }
        }
    }
    Ok(())
}

/// Refuses a path that names no file ("", ".", "..", "/"), or a file path ending in "/".
fn check_name(o: &Arg, kind: Kind) -> anyhow::Result<()> {
    let p = &o.path;
    ensure!(!p.as_os_str().is_empty(), "{}: the path is empty", o.name);
    let last = p.components().next_back();
    ensure!(
        matches!(last, Some(Component::Normal(_))),
        "{} {}: does not name a file or directory to create",
        o.name,
        p.display()
    );
    if kind == Kind::File {
        let text = p.as_os_str().to_string_lossy();
        ensure!(
            !text.ends_with('/'),
            "{} {}: ends with '/', but a file is written here",
            o.name,
            p.display()
        );
    }
    Ok(())
}

/// The directory an output goes into (`.` for a bare name).
fn parent_of(p: &Path) -> &Path {
    match p.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// Refuses when the directory `o` goes into is missing, not a directory, or does not
/// take a file of the temporary name the output is first written under (tried by
/// creating and removing it: permissions alone do not tell, e.g. for root or /proc;
/// this also catches names too long for the file system).
fn check_writable_dir(o: &Arg, dir: &Path, name: &std::ffi::OsStr) -> anyhow::Result<()> {
    ensure!(
        dir.exists(),
        "{} {}: the directory {} does not exist",
        o.name,
        o.path.display(),
        dir.display()
    );
    ensure!(
        dir.is_dir(),
        "{} {}: {} is not a directory",
        o.name,
        o.path.display(),
        dir.display()
    );
    let mut probe_name = OsString::from(".");
    probe_name.push(name);
    probe_name.push(format!(".partial-{}", std::process::id()));
    let probe = dir.join(probe_name);
    if probe.exists() {
        return Ok(()); // left by an earlier run of this process id; the write replaces it
    }
    match std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe)
    {
        Ok(_) => {
            let _ = std::fs::remove_file(&probe);
            Ok(())
        }
        Err(e) => bail!(
            "{} {}: cannot write in {}: {e}",
            o.name,
            o.path.display(),
            dir.display()
        ),
    }
}

/// Refuses an existing output without `force`, and even with it anything but an
/// earlier output of the same kind: a file is never replaced by a directory or the
/// other way round, and no directory holding the current directory is replaced.
fn check_existing(o: &Arg, kind: Kind, force: bool) -> anyhow::Result<()> {
    let Ok(meta) = std::fs::metadata(&o.path) else {
        return Ok(());
    };
    ensure!(
        force,
        "{}: already exists (use --force to replace it)",
        o.path.display()
    );
    match kind {
        Kind::File => ensure!(
            !meta.is_dir(),
            "{} {}: is a directory; a file is written here, so it is not replaced even with --force",
            o.name,
            o.path.display()
        ),
        Kind::Dir => {
            ensure!(
                meta.is_dir(),
                "{} {}: is a file; a directory is written here, so it is not replaced even with --force",
                o.name,
                o.path.display()
            );
            if let Ok(cwd) = std::env::current_dir() {
                ensure!(
                    !resolve(&cwd).starts_with(resolve(&o.path)),
                    "{} {}: holds the current directory; not replacing it",
                    o.name,
                    o.path.display()
                );
            }
        }
    }
    Ok(())
}

/// Every check on a command's outputs, made before anything is read or written: names,
/// collisions with the inputs and with each other ([`check_collisions`]), existing
/// outputs (`force`), and that each output's directory exists and is writable.
pub fn check_outputs(inputs: &[Arg], outputs: &[(Arg, Kind)], force: bool) -> anyhow::Result<()> {
    for (o, kind) in outputs {
        check_name(o, *kind)?;
    }
    let outs: Vec<Arg> = outputs.iter().map(|o| o.0.clone()).collect();
    check_collisions(inputs, &outs)?;
    for (o, kind) in outputs {
        check_existing(o, *kind, force)?;
        let name = o.path.file_name().unwrap_or_default();
        check_writable_dir(o, parent_of(&o.path), name)?;
    }
    Ok(())
}

/// A report's output directory (`--out DIR` of `report compare | convergence | sweep`):
/// checked before any work, created only when the command writes its results, and on
/// failure (when dropped before [`ReportDir::finish`]) cleaned of what this run put
/// there: the files it wrote that were not there before, and the directory itself if
/// this run created it. Files that existed before are never removed.
pub struct ReportDir {
    path: PathBuf,
    created: bool,
    before: HashSet<OsString>,
    ours: Box<dyn Fn(&str) -> bool>,
    done: bool,
}

impl ReportDir {
    /// Checks `dir` and the result `files` it will hold (plus any file for which
    /// `extra` holds, e.g. a cache) against the inputs and `force`.
    pub fn prepare(
        flag: &str,
        dir: &Path,
        files: &[&str],
        extra: fn(&str) -> bool,
        inputs: &[Arg],
        force: bool,
    ) -> anyhow::Result<ReportDir> {
        let d = arg(flag, dir);
        // Unlike a command's own output, DIR may be "." or "..": it is written into,
        // never replaced.
        ensure!(!dir.as_os_str().is_empty(), "{flag}: the path is empty");
        ensure!(
            !dir.exists() || dir.is_dir(),
            "{}: exists and is not a directory",
            dir.display()
        );
        let outs: Vec<Arg> = files.iter().map(|f| arg(flag, dir.join(f))).collect();
        check_collisions(inputs, &outs)?;
        for o in &outs {
            check_existing(o, Kind::File, force)?;
        }
        let before = match std::fs::read_dir(dir) {
            Ok(it) => it.flatten().map(|e| e.file_name()).collect(),
            Err(_) => HashSet::new(),
        };
        match dir.is_dir() {
            true => {
                for f in files {
                    check_writable_dir(&d, dir, std::ffi::OsStr::new(f))?;
                }
            }
            false => check_writable_dir(
                &d,
                parent_of(dir),
                dir.file_name().unwrap_or(dir.as_os_str()),
            )?,
        }
        let names: Vec<String> = files.iter().map(|f| f.to_string()).collect();
        Ok(ReportDir {
            path: dir.to_path_buf(),
            created: false,
            before,
            ours: Box::new(move |n| names.iter().any(|f| f == n) || extra(n)),
            done: false,
        })
    }

    /// Creates the directory if needed; returns it.
    pub fn create(&mut self) -> anyhow::Result<&Path> {
        if !self.path.is_dir() {
            std::fs::create_dir(&self.path)
                .map_err(|e| anyhow!("creating {}: {e}", self.path.display()))?;
            self.created = true;
        }
        Ok(&self.path)
    }

    /// The results are complete: keep them.
    pub fn finish(mut self) {
        self.done = true;
    }
}

impl Drop for ReportDir {
    fn drop(&mut self) {
        if self.done {
            return;
        }
        if let Ok(it) = std::fs::read_dir(&self.path) {
            for e in it.flatten() {
                let name = e.file_name();
                if !self.before.contains(&name) && (self.ours)(&name.to_string_lossy()) {
                    let _ = std::fs::remove_file(e.path());
                }
            }
        }
        if self.created {
            // Only when empty: never removes anything this run did not write.
            let _ = std::fs::remove_dir(&self.path);
        }
    }
}

// ---------------------------------------------------------------------------------
// Standard output.

/// Prints to stdout. A closed pipe (`tstat info B | head -1`) ends the printing quietly;
/// any other failure (a full disk) is an error instead of a panic.
pub fn say(args: std::fmt::Arguments) -> anyhow::Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    match out.write_fmt(args).and_then(|()| out.flush()) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        Err(e) => Err(anyhow!("writing to standard output: {e}")),
    }
}

/// Refuses an output that is, holds or lies inside a mesh file the scene read (known
/// only once the scene is loaded, so checked after [`check_outputs`]).
pub fn check_mesh_inputs(scene: &crate::scene::Scene, outputs: &[Arg]) -> anyhow::Result<()> {
    let meshes: Vec<Arg> = scene.mesh_files.iter().map(|p| arg("mesh", p)).collect();
    check_collisions(&meshes, outputs)
}

/// Prints a loaded scene's warnings (legal but suspicious input), one line each.
pub fn print_scene_warnings(scene: &crate::scene::Scene) {
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
}

/// The `-a` folders, each checked to be a folder.
pub fn search_folders(dirs: &[std::path::PathBuf]) -> anyhow::Result<Vec<std::path::PathBuf>> {
    for d in dirs {
        anyhow::ensure!(d.is_dir(), "-a {}: not a folder", d.display());
    }
    Ok(dirs.to_vec())
}

/// A duration flag: seconds, or a number with `s`, `m` or `h` ("90", "90s", "5m",
/// "1.5h"); positive and at most a year.
pub fn duration_flag(flag: &str, text: &str) -> anyhow::Result<f64> {
    let t = text.trim();
    let (num, unit) = match t.char_indices().last() {
        Some((i, c)) if c.is_ascii_alphabetic() => (&t[..i], c),
        _ => (t, 's'),
    };
    let scale = match unit {
        's' => 1.0,
        'm' => 60.0,
        'h' => 3600.0,
        _ => anyhow::bail!("{flag} {text:?}: a duration is a number of seconds, or one with s, m or h (90s, 5m, 1.5h)"),
    };
    let v: f64 = num
        .parse()
        .map_err(|_| anyhow::anyhow!("{flag} {text:?}: a duration is a number of seconds, or one with s, m or h (90s, 5m, 1.5h)"))?;
    let secs = v * scale;
    anyhow::ensure!(
        secs > 0.0 && secs <= 3.2e7,
        "{flag} {text:?}: must be positive and at most a year"
    );
    Ok(secs)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse() {
        assert_eq!(parse_bytes("512M"), Ok(512_000_000));
        assert_eq!(parse_bytes("8g"), Ok(8_000_000_000));
        assert_eq!(parse_bytes("1.5GB"), Ok(1_500_000_000));
        assert_eq!(parse_bytes("1000"), Ok(1000));
        assert_eq!(parse_bytes("512Mi"), Ok(512 << 20));
        assert_eq!(parse_bytes("4GiB"), Ok(4 << 30));
        assert_eq!(parse_bytes("2ki"), Ok(2048));
        assert_eq!(parse_bytes(" 3 K "), Ok(3000));
        assert_eq!(parse_bytes("7b"), Ok(7));
        assert_eq!(parse_bytes("4i"), Err(SizeError::Syntax));
        assert_eq!(parse_bytes("-1G"), Err(SizeError::Syntax));
        assert_eq!(parse_bytes("lots"), Err(SizeError::Syntax));
    }

    #[test]
    fn every_unit_is_exact() {
        let units = ["K", "M", "G", "T", "P", "E"];
        for (k, u) in units.iter().enumerate() {
            let k = k as u32 + 1;
            let dec = 1000u64.pow(k);
            let bin = 1u64 << (10 * k);
            for spelled in [
                u.to_string(),
                u.to_lowercase(),
                format!("{u}B"),
                format!("{u}b"),
            ] {
                assert_eq!(parse_bytes(&format!("1{spelled}")), Ok(dec), "1{spelled}");
            }
            for spelled in [
                format!("{u}i"),
                format!("{u}iB"),
                format!("{}I", u.to_lowercase()),
            ] {
                assert_eq!(parse_bytes(&format!("1{spelled}")), Ok(bin), "1{spelled}");
            }
            assert_eq!(parse_bytes(&format!("1.5{u}")), Ok(dec + dec / 2));
            assert_eq!(parse_bytes(&format!("0.5{u}i")), Ok(bin / 2));
            assert_eq!(parse_bytes(&format!(".25{u}i")), Ok(bin / 4));
        }
        // A fraction of a byte is dropped, never rounded up.
        assert_eq!(parse_bytes("0.3Ki"), Ok(307));
        assert_eq!(parse_bytes("1.9"), Ok(1));
        assert_eq!(
            parse_bytes("1.000000000000000001E"),
            Ok(1_000_000_000_000_000_001)
        );
        // Exact where f64 is not: 2^53 + 1.
        assert_eq!(parse_bytes("9007199254740993"), Ok(9_007_199_254_740_993));
    }

    #[test]
    fn sizes_beyond_u64_are_refused_not_clamped() {
        assert_eq!(parse_bytes("18446744073709551615"), Ok(u64::MAX));
        assert_eq!(parse_bytes("18446744073709551615B"), Ok(u64::MAX));
        for s in [
            "18446744073709551616",
            "99999999999999999999",
            "16Ei",
            "18.446744073709551616E",
            "18446744073709551616.0",
            "20E",
            "1000000000000000000000000000000000000000000000K",
            "99999999999999999999999999999999999999999",
        ] {
            assert_eq!(parse_bytes(s), Err(SizeError::Overflow), "{s}");
        }
        assert_eq!(
            parse_bytes("15.999999999999999999Ei"),
            Ok(18_446_744_073_709_551_614)
        );
        assert_eq!(parse_bytes("18.446744073709551615E"), Ok(u64::MAX));
        for s in ["0", "0K", "0.0001", "0.0000000001K"] {
            assert_eq!(parse_bytes(s), Err(SizeError::Zero), "{s}");
        }
        for s in [
            "",
            ".",
            "K",
            "Ki",
            "B",
            "iB",
            "1e9",
            "1..5K",
            "1.5.K",
            "+1K",
            "-0",
            "1 2K",
            "1KK",
            "1Bi",
            "1XiB",
            "nan",
            "inf",
            "0x10",
            "1.0000000000000000001K",
            "１K",
            "1K\u{0}",
        ] {
            assert_eq!(parse_bytes(s), Err(SizeError::Syntax), "{s:?}");
        }
        let e = size_flag("--mem", "99999999999999999999").unwrap_err();
        assert_eq!(
            e.to_string(),
            "--mem 99999999999999999999: more than 2^64 - 1 bytes (16Ei), the largest size"
        );
        let e = size_flag_in("--max-bytes", "1K", (1024, "1Ki"), (u64::MAX, "16Ei")).unwrap_err();
        assert_eq!(e.to_string(), "--max-bytes 1K: at least 1Ki");
        assert_eq!(
            size_flag_in("--max-bytes", "1Ki", (1024, "1Ki"), (u64::MAX, "16Ei")).unwrap(),
            1024
        );
        let e = size_flag_in("--mem", "2Pi", (1, "1"), (1 << 50, "1Pi")).unwrap_err();
        assert_eq!(e.to_string(), "--mem 2Pi: at most 1Pi");
    }

    #[test]
    fn value_enums_are_named_as_typed() {
        assert_eq!(cli_name(&crate::render::PixelSampling::Sobol), "sobol");
        use crate::cli::nlos::{reconstruction, NlosMethod};
        for (m, name) in [(NlosMethod::Fbp, "fbp"), (NlosMethod::Pf, "pf")] {
            let e = reconstruction(m, None, None, None)
                .err()
                .unwrap()
                .to_string();
            assert!(
                e.starts_with(&format!("--method {name} needs --wl-mean")),
                "{e}"
            );
        }
    }
}
