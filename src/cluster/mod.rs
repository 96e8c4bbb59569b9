//! Recipes for running one render job's shards on an existing scheduler (SPEC 12):
//! a Slurm array job and a Kubernetes indexed Job, each followed by a merge. The
//! recipes only call `tstat render ... --shard auto/N` and `tstat merge`; the
//! scheduler does the rest. `slurm.rs` and `k8s.rs` write the text; `tstat cluster`
//! (cli/cluster.rs) checks the scene and options first.

pub mod k8s;
pub mod slurm;

use std::path::PathBuf;

/// Errors of the recipes' options: what cannot go into a Slurm or Kubernetes recipe.
/// `what` names the option or path ("--out", "the scene").
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ClusterError {
    #[error("--time {0:?}: expected a Slurm time limit such as 30, 02:00:00 or 1-00:00:00")]
    Time(String),
    #[error("--partition {0:?}: not a Slurm partition name")]
    Partition(String),
    #[error("{what} {}: not UTF-8", .path.display())]
    NotUtf8 { what: String, path: PathBuf },
    /// A character the recipes cannot carry; `directive`: the path goes into an
    /// `#SBATCH` line.
    #[error("{what} {path:?}: the character {c:?} cannot go into the recipes{}", directive_note(.directive))]
    Character {
        what: String,
        path: String,
        c: char,
        directive: bool,
    },
    #[error("{what} {} is not under the volume's mount point {mount} (--mount): the pods could not see it", .path.display())]
    NotUnderMount {
        what: String,
        path: PathBuf,
        mount: String,
    },
}

fn directive_note(directive: &bool) -> &'static str {
    if *directive {
        " (Slurm directive lines take no spaces, quotes or %)"
    } else {
        ""
    }
}

/// What both recipes need.
#[derive(Clone, Debug)]
pub struct Job {
    /// The tstat binary (absolute for Slurm; a name on the image's PATH for Kubernetes).
    pub binary: String,
    /// Absolute scene path.
    pub scene: PathBuf,
    /// Absolute output folder: shards in `DIR/shards`, logs in `DIR/logs`, the merged
    /// bundle `DIR/merged.tstats`.
    pub dir: PathBuf,
    pub shards: u64,
    /// Render options passed through (already checked by parsing them as `render`'s).
    pub render_options: Vec<String>,
    /// Also denoise the merged bundle into `DIR/denoised.npy`.
    pub denoise: bool,
    /// Resources of one task.
    pub cpus: u32,
    /// Memory of one render task and of the merge task, in MiB.
    pub render_mib: u64,
    pub merge_mib: u64,
    /// The merge's and the denoiser's `--max-memory` in MiB (the merge task's memory
    /// less the per-pixel images and a margin).
    pub band_mib: u64,
}

/// The variable the Slurm render task takes its threads from.
pub const SLURM_THREADS: &str = "${SLURM_CPUS_PER_TASK:-1}";

impl Job {
    /// `DIR/shards/shard-{shard}.tstats`: each task's output (tstat fills in the index).
    pub fn shard_pattern(&self) -> PathBuf {
        self.dir.join("shards").join("shard-{shard}.tstats")
    }

    pub fn merged(&self) -> PathBuf {
        self.dir.join("merged.tstats")
    }

    pub fn denoised(&self) -> PathBuf {
        self.dir.join("denoised.npy")
    }

    /// The render command of every task, as arguments.
    pub fn render_args(&self, threads: &str) -> Vec<String> {
        let mut v = vec![
            self.binary.clone(),
            "render".into(),
            self.scene.display().to_string(),
            "--shard".into(),
            format!("auto/{}", self.shards),
            "--out".into(),
            self.shard_pattern().display().to_string(),
            "--threads".into(),
            threads.into(),
        ];
        v.extend(self.render_options.iter().cloned());
        v
    }
}

/// The merge task's shell commands (POSIX sh): the merge of every shard (the glob left
/// to the shell), then with `denoise` the denoiser with `threads` (a number or a
/// variable the shell expands, double-quoted).
pub fn merge_commands(job: &Job, threads: &str) -> Vec<String> {
    let b = quote(&job.binary);
    let mut v = vec![format!(
        "{b} merge {}/shard-*.tstats --out {} --max-memory {}Mi",
        quote(&job.dir.join("shards").display().to_string()),
        quote(&job.merged().display().to_string()),
        job.band_mib
    )];
    if job.denoise {
        v.push(format!(
            "{b} denoise {} --out {} --threads \"{threads}\" --max-memory {}Mi",
            quote(&job.merged().display().to_string()),
            quote(&job.denoised().display().to_string()),
            job.band_mib
        ));
    }
    v
}

/// `path` with `.` and `..` resolved lexically (no file system access; the path may
/// not exist yet), so that prefix checks see where it really points.
pub fn normalize(path: &std::path::Path) -> PathBuf {
    use std::path::Component;
    let mut out = PathBuf::new();
    for c in path.components() {
        match c {
            Component::ParentDir => {
                out.pop();
            }
            Component::CurDir => {}
            other => out.push(other),
        }
    }
    out
}

/// Refuses a path the recipes cannot carry safely: control characters always, and for
/// paths in `#SBATCH` lines (`directive`) also whitespace, quotes and `%` (Slurm reads
/// directive values up to whitespace and `%` as a file name pattern).
pub fn check_path(path: &std::path::Path, what: &str, directive: bool) -> Result<(), ClusterError> {
    let s = path.to_str().ok_or_else(|| ClusterError::NotUtf8 {
        what: what.to_string(),
        path: path.to_path_buf(),
    })?;
    let bad = |c: char| c.is_control() || (directive && (c.is_whitespace() || "%\"'".contains(c)));
    match s.chars().find(|&c| bad(c)) {
        Some(c) => Err(ClusterError::Character {
            what: what.to_string(),
            path: s.to_string(),
            c,
            directive,
        }),
        None => Ok(()),
    }
}

/// One argument quoted for bash: single quotes, with `'` written as `'\''`.
pub fn quote(s: &str) -> String {
    if !s.is_empty()
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || "/._-+=:,@%".contains(c))
    {
        s.to_string()
    } else {
        format!("'{}'", s.replace('\'', r"'\''"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_are_normalized_and_checked() {
        use std::path::Path;
        assert_eq!(
            normalize(Path::new("/data/../scratch/./x")),
            Path::new("/scratch/x")
        );
        assert_eq!(normalize(Path::new("/a/b/../../..")), Path::new("/"));
        assert!(check_path(Path::new("/scratch/run 1"), "--out", true).is_err());
        assert!(check_path(Path::new("/scratch/run%j"), "--out", true).is_err());
        assert!(check_path(Path::new("/scratch/run 1"), "the scene", false).is_ok());
        assert!(check_path(Path::new("/scratch/a\nb"), "the scene", false).is_err());
    }

    #[test]
    fn quoting_survives_bash() {
        for s in [
            "plain/path.xml",
            "a b",
            "it's",
            "{shard}",
            "$HOME",
            "",
            "x\"y",
            "a\nb",
        ] {
            let out = std::process::Command::new("bash")
                .arg("-c")
                .arg(format!("printf %s {}", quote(s)))
                .output();
            let Ok(out) = out else { return }; // no bash: nothing to check against
            assert_eq!(
                String::from_utf8_lossy(&out.stdout),
                s,
                "{s:?} -> {}",
                quote(s)
            );
        }
    }
}
