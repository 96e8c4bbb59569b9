//! Recipes for running one render job's shards on an existing scheduler (SPEC 12):
//! a Slurm array job and a Kubernetes indexed Job, each followed by a merge. The
//! recipes only call `tstat render ... --shard auto/N` and `tstat merge`; the
//! scheduler does the rest. `slurm.rs` and `k8s.rs` write the text; `tstat cluster`
//! (cli/cluster.rs) checks the scene and options first.

pub mod k8s;
pub mod slurm;

use std::path::PathBuf;

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
}

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
