//! Slurm: `render.sbatch`, an array job of N tasks (`--array=0-(N-1)`, so
//! `SLURM_ARRAY_TASK_ID` is the shard index), and `merge.sbatch`, one task that
//! merges the shards (and may denoise). Submitted as
//! `sbatch DIR/render.sbatch`, then `sbatch --dependency=afterok:<job id> DIR/merge.sbatch`.
//! Every path is absolute, so both can be submitted from any folder; Slurm does not
//! create the log folder, so `tstat cluster` does.

use super::{merge_commands, quote, ClusterError, Job, SLURM_THREADS};

/// Where `Job::render_args` puts the threads value.
const THREADS_AT: usize = 8;

/// `#SBATCH` time limit, `D-HH:MM:SS` or `HH:MM:SS` or minutes.
pub fn check_time(t: &str) -> Result<(), ClusterError> {
    let ok = !t.is_empty()
        && t.chars()
            .all(|c| c.is_ascii_digit() || c == ':' || c == '-')
        && t.split(['-', ':']).all(|p| !p.is_empty());
    if ok {
        Ok(())
    } else {
        Err(ClusterError::Time(t.to_string()))
    }
}

/// A partition name as Slurm takes it.
pub fn check_partition(p: &str) -> Result<(), ClusterError> {
    if !p.is_empty()
        && p.chars()
            .all(|c| c.is_ascii_alphanumeric() || "_-.,".contains(c))
    {
        Ok(())
    } else {
        Err(ClusterError::Partition(p.to_string()))
    }
}

fn header(
    job: &Job,
    name: &str,
    log: &str,
    mib: u64,
    time: &str,
    partition: Option<&str>,
) -> String {
    let mut s = String::from("#!/bin/bash\n");
    s += &format!("#SBATCH --job-name={name}\n");
    s += &format!("#SBATCH --cpus-per-task={}\n", job.cpus);
    s += &format!("#SBATCH --mem={mib}M\n");
    s += &format!("#SBATCH --time={time}\n");
    s += &format!(
        "#SBATCH --output={}\n",
        job.dir.join("logs").join(log).display()
    );
    if let Some(p) = partition {
        s += &format!("#SBATCH --partition={p}\n");
    }
    s
}

/// `render.sbatch`.
pub fn render_script(job: &Job, time: &str, partition: Option<&str>) -> String {
    let mut s = header(
        job,
        "tstat-render",
        "render-%A_%a.log",
        job.render_mib,
        time,
        partition,
    );
    s += &format!("#SBATCH --array=0-{}\n", job.shards - 1);
    s += &format!(
        "# Written by tstat {}: shard $SLURM_ARRAY_TASK_ID of {} of {}.\n",
        env!("CARGO_PKG_VERSION"),
        job.shards,
        job.scene.display()
    );
    s += &format!(
        "# Submit: sbatch {} && sbatch --dependency=afterok:<job id> {}\n",
        job.dir.join("render.sbatch").display(),
        job.dir.join("merge.sbatch").display()
    );
    s += "set -euo pipefail\n";
    // Every argument single-quoted but the threads variable (at its own place).
    let args: Vec<String> = job
        .render_args(SLURM_THREADS)
        .iter()
        .enumerate()
        .map(|(i, a)| {
            if i == THREADS_AT {
                format!("\"{a}\"")
            } else {
                quote(a)
            }
        })
        .collect();
    s += &format!("exec {}\n", args.join(" "));
    s
}

/// `merge.sbatch`: merges every shard (tstat names any that is missing) and optionally
/// denoises.
pub fn merge_script(job: &Job, time: &str, partition: Option<&str>) -> String {
    let mut s = header(
        job,
        "tstat-merge",
        "merge-%j.log",
        job.merge_mib,
        time,
        partition,
    );
    s += &format!(
        "# Written by tstat {}: merges the {} shards of {}.\n",
        env!("CARGO_PKG_VERSION"),
        job.shards,
        job.scene.display()
    );
    s += "set -euo pipefail\n";
    for line in merge_commands(job, SLURM_THREADS) {
        s += &line;
        s.push('\n');
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn job() -> Job {
        Job {
            binary: "/opt/tstat bin/tstat".into(),
            scene: PathBuf::from("/data/it's/cbox.xml"),
            dir: PathBuf::from("/scratch/run1"),
            shards: 16,
            render_options: vec![
                "--spp".into(),
                "1024".into(),
                "-D".into(),
                "res=$x".into(),
                "--seed".into(),
                "${X:-$(id)}".into(),
            ],
            denoise: true,
            cpus: 4,
            render_mib: 2048,
            merge_mib: 1024,
            band_mib: 512,
        }
    }

    #[test]
    fn scripts_name_everything_absolutely_and_request_resources() {
        let r = render_script(&job(), "02:00:00", Some("gpu-less"));
        for line in [
            "#SBATCH --array=0-15\n",
            "#SBATCH --cpus-per-task=4\n",
            "#SBATCH --mem=2048M\n",
            "#SBATCH --time=02:00:00\n",
            "#SBATCH --partition=gpu-less\n",
            "#SBATCH --output=/scratch/run1/logs/render-%A_%a.log\n",
            "exec '/opt/tstat bin/tstat' render '/data/it'\\''s/cbox.xml' --shard auto/16 --out '/scratch/run1/shards/shard-{shard}.tstats' --threads \"${SLURM_CPUS_PER_TASK:-1}\" --spp 1024 -D 'res=$x' --seed '${X:-$(id)}'\n",
        ] {
            assert!(r.contains(line), "{line:?} not in:\n{r}");
        }
        let m = merge_script(&job(), "01:00:00", None);
        assert!(m.contains("'/opt/tstat bin/tstat' merge /scratch/run1/shards/shard-*.tstats --out /scratch/run1/merged.tstats --max-memory 512Mi\n"), "{m}");
        assert!(
            m.contains(" denoise /scratch/run1/merged.tstats --out /scratch/run1/denoised.npy"),
            "{m}"
        );
        assert!(!m.contains("--array"), "{m}");
    }

    #[test]
    fn times_and_partitions_are_checked() {
        for t in ["30", "02:00:00", "1-00:00:00"] {
            assert!(check_time(t).is_ok(), "{t}");
        }
        for t in ["", "2h", "1:", "$(rm)"] {
            assert!(check_time(t).is_err(), "{t}");
        }
        assert!(check_partition("normal").is_ok());
        assert!(check_partition("a b").is_err());
    }
}
