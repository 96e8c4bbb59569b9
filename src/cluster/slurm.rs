//! Slurm: `render.sbatch`, an array job of N tasks (`--array=0-(N-1)`, so
//! `SLURM_ARRAY_TASK_ID` is the shard index), and `merge.sbatch`, one task that
//! merges the shards (and may denoise). Submitted by [`submit_command`]: `sbatch
//! DIR/render.sbatch`, then `sbatch --dependency=afterok:<its job id> DIR/merge.sbatch`.
//! Every path is absolute, so both can be submitted from any folder; Slurm does not
//! create the log folder, so `tstat cluster` does.

use super::{command_line, merge_commands, quote, quote_path, ClusterError, Job, SLURM_THREADS};

/// Where `Job::render_args` puts the threads value.
const THREADS_AT: usize = 8;

/// The longest `--time` taken: a year (a shard that runs longer is no plan).
pub const MAX_TIME_SECONDS: u64 = 365 * 24 * 3600;

/// A Slurm time limit (`sbatch --time`) in seconds: `M`, `M:S`, `H:M:S`, `D-H`, `D-H:M`
/// or `D-H:M:S`, each field digits only; minutes and seconds below 60 where a larger
/// field precedes them; more than 0 (Slurm reads 0 as no limit) and at most
/// [`MAX_TIME_SECONDS`].
pub fn parse_time(t: &str) -> Result<u64, ClusterError> {
    let err = |reason| ClusterError::Time {
        value: t.to_string(),
        reason,
    };
    const FORMAT: &str = "expected a Slurm time limit: minutes, M:S, H:M:S, D-H, D-H:M or D-H:M:S (e.g. 30, 02:00:00 or 1-00:00:00)";
    let (days, rest) = match t.split_once('-') {
        Some((d, rest)) => (Some(d), rest),
        None => (None, t),
    };
    let fields: Vec<&str> = rest.split(':').collect();
    // Nine digits at most: no field can overflow, and none that long is a real limit.
    let number = |f: &str| -> Result<u64, ClusterError> {
        if f.is_empty() || f.len() > 9 || !f.bytes().all(|b| b.is_ascii_digit()) {
            return Err(err(FORMAT));
        }
        Ok(f.parse().unwrap_or(0))
    };
    let v: Vec<u64> = fields.iter().map(|f| number(f)).collect::<Result<_, _>>()?;
    // (days, hours, minutes, seconds)
    let (d, h, m, s) = match (days, v.as_slice()) {
        (None, &[m]) => (0, 0, m, 0),
        (None, &[m, s]) => (0, 0, m, s),
        (None, &[h, m, s]) => (0, h, m, s),
        (Some(d), &[h]) => (number(d)?, h, 0, 0),
        (Some(d), &[h, m]) => (number(d)?, h, m, 0),
        (Some(d), &[h, m, s]) => (number(d)?, h, m, s),
        _ => return Err(err(FORMAT)),
    };
    let minutes_bounded = days.is_some() || v.len() == 3;
    if s >= 60 || (minutes_bounded && m >= 60) || (days.is_some() && h >= 24) {
        return Err(err(
            "hours run from 0 to 23 after days, minutes and seconds from 0 to 59 after a larger unit",
        ));
    }
    let total = ((d * 24 + h) * 60 + m) * 60 + s;
    if total == 0 {
        return Err(err("give a time limit above 0 (Slurm reads 0 as no limit)"));
    }
    if total > MAX_TIME_SECONDS {
        return Err(err("at most 365 days (365-00:00:00)"));
    }
    Ok(total)
}

/// Checks `--time` ([`parse_time`]).
pub fn check_time(t: &str) -> Result<(), ClusterError> {
    parse_time(t).map(|_| ())
}

/// The commands that submit both scripts, one line of POSIX shell: the render array,
/// then the merge once every task of it succeeded (`--parsable` prints the job id, with
/// `;cluster` on a multi-cluster setup).
pub fn submit_command(job: &Job) -> String {
    format!(
        "jid=$({}) && {}\"${{jid%%;*}}\" {}",
        command_line(&[
            "sbatch",
            "--parsable",
            &job.dir.join("render.sbatch").to_string_lossy(),
        ]),
        "sbatch --dependency=afterok:",
        quote_path(&job.dir.join("merge.sbatch"))
    )
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
    // Checked to hold no whitespace, quotes, `%`, `\\` or `#` (`check_path`): Slurm
    // reads it as written.
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
        quote_path(&job.scene)
    );
    s += &format!("# Submit: {}\n", submit_command(job));
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
        quote_path(&job.scene)
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
        // The reasons parse_time gives, by their first words.
        const FORMAT: &str = "expected a Slurm time limit";
        const RANGE: &str = "hours run from 0 to 23";
        const ZERO: &str = "give a time limit above 0";
        const YEAR: &str = "at most 365 days";
        fn reason<T: std::fmt::Debug>(r: Result<T, ClusterError>, t: &str) -> &'static str {
            match r {
                Err(ClusterError::Time { value, reason }) if value == t => reason,
                other => panic!("{t:?}: {other:?}"),
            }
        }
        for t in ["", "2h", "1:", "$(rm)"] {
            let r = reason(check_time(t), t);
            assert!(r.starts_with(FORMAT), "{t}: {r}");
        }
        for (t, s) in [
            ("30", 1800),
            ("90:30", 5430),
            ("1:00:00", 3600),
            ("2-3", (2 * 24 + 3) * 3600),
            ("2-3:04", (2 * 24 + 3) * 3600 + 240),
            ("1-00:00:01", 86401),
            ("525600", MAX_TIME_SECONDS),
            ("365-00:00:00", MAX_TIME_SECONDS),
        ] {
            assert_eq!(parse_time(t), Ok(s), "{t}");
        }
        for (t, want) in [
            ("0", ZERO),
            ("00:00:00", ZERO),
            ("0-0", ZERO),
            ("525601", YEAR),
            ("366-0", YEAR),
            ("1:60", RANGE),
            ("1:60:00", RANGE),
            ("1-24", RANGE),
            ("1-1-1", FORMAT),
            ("1:2:3:4", FORMAT),
            ("1-", FORMAT),
            ("-1", FORMAT),
            (":5", FORMAT),
            ("9999999999", FORMAT),
            ("99999999999999999999", FORMAT),
            ("1 ", FORMAT),
            ("+5", FORMAT),
            ("１", FORMAT),
        ] {
            let r = reason(parse_time(t), t);
            assert!(r.starts_with(want), "{t:?}: {r}");
        }
        let e = parse_time("99999999999999999999").unwrap_err().to_string();
        assert!(
            e.starts_with("--time 99999999999999999999: expected"),
            "{e}"
        );
        assert!(check_partition("normal").is_ok());
        assert_eq!(
            check_partition("a b"),
            Err(ClusterError::Partition("a b".into()))
        );
    }
}
