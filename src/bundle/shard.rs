//! Shards of one render job (SPEC 12): `tstat render ... --shard I/N` renders shard I
//! of N, and `tstat merge` puts the N bundles back together, refusing a job with
//! shards missing, repeated or from another job.
//!
//! - The job's spp S and replicates B are split evenly: each shard renders S / N
//!   samples per pixel (and B / N replicates), so N must divide both.
//! - Shard I's seed is [`shard_seed`]`(seed, I)`, a hash of the job's seed and I: the N
//!   shards draw different paths, and the same job always draws the same ones.
//! - Every shard records the job's identity (`job`, a hash of everything the job
//!   renders: scene, film, settings, seed, S, B and N; not the scene's path, which may
//!   differ between nodes), N and its index. A merged bundle records the union of the
//!   indices.
//! - `--shard auto/N` takes I from the scheduler: `SLURM_ARRAY_TASK_ID` (Slurm job
//!   arrays, `--array=0-(N-1)`), else `JOB_COMPLETION_INDEX` (Kubernetes indexed Jobs).

use crate::math::rng::mix64;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

/// The scheduler variables `--shard auto/N` reads, in order.
pub const INDEX_VARIABLES: [&str; 2] = ["SLURM_ARRAY_TASK_ID", "JOB_COMPLETION_INDEX"];

/// The placeholder of `--out` replaced by the shard's index.
pub const PLACEHOLDER: &str = "{shard}";

/// Errors of `--shard` and of merging shards' records.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ShardError {
    /// `--shard SPEC` is not `I/N` or `auto/N`.
    #[error("--shard {spec:?}: expected I/N or auto/N, e.g. 3/16")]
    Spec { spec: String },
    #[error("--shard {spec}: the number of shards must be from 1 to 2^32")]
    Count { spec: String },
    /// `--shard auto/N` without a scheduler's index variable.
    #[error("--shard {spec}: neither {} is set (run it as a Slurm array task or a Kubernetes indexed Job, or give the index: --shard I/{count})", INDEX_VARIABLES.join(" nor "))]
    IndexUnset { spec: String, count: u64 },
    #[error("--shard {spec}: {var}={value:?} is not a shard index")]
    IndexVariable {
        spec: String,
        var: &'static str,
        value: String,
    },
    /// A shard index not below the number of shards; `var` names the variable it was
    /// read from, if any.
    #[error("--shard {spec}: index {index}{} is not below the number of shards {count} (indices run from 0 to {last}; a Slurm array is then --array=0-{last})", .var.map_or(String::new(), |v| format!(" ({v})")), last = .count - 1)]
    Index {
        spec: String,
        index: u64,
        var: Option<&'static str>,
        count: u64,
    },
    /// A job's spp or replicates (`what`) that the shards cannot share equally.
    #[error("{what} {total} is not a multiple of the number of shards {count}: every shard renders an equal share")]
    Share {
        what: String,
        total: u64,
        count: u64,
    },
    #[error("job {job} has bundles of {count} and of {other} shards")]
    JobCounts { job: String, count: u64, other: u64 },
    #[error("job {job}: shard {index} of {count} does not exist")]
    NoSuchShard { job: String, index: u64, count: u64 },
    #[error(
        "job {job}: shard {index} of {count} is given twice: merging would count its paths twice"
    )]
    Twice { job: String, index: u64, count: u64 },
    /// Shards of a job missing: how many, and the first 20.
    #[error("job {job}: {missing} of its {count} shards are missing: {} (render them, or merge with --partial)", show_missing(.shown, .missing))]
    Missing {
        job: String,
        count: u64,
        missing: u64,
        shown: Vec<u64>,
    },
}

fn show_missing(shown: &[u64], missing: &u64) -> String {
    let list: Vec<String> = shown.iter().map(u64::to_string).collect();
    let more = if *missing > 20 { ", ..." } else { "" };
    format!("{}{more}", list.join(", "))
}

/// Shard `index` of `count`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    pub index: u64,
    pub count: u64,
}

/// The most shards a job may have (`--shard I/N` refuses more too).
pub const MAX_SHARDS: u64 = 1 << 32;

/// What a bundle records of the job it belongs to (`shard` in the manifest).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq, Eq)]
pub struct ShardRecord {
    /// Hex hash of the job's identity.
    pub job: String,
    /// The job's number of shards N.
    pub count: u64,
    /// The shards this bundle holds (one for a shard, the union after a merge), sorted.
    pub indices: Vec<u64>,
}

impl Shard {
    /// Parses `I/N` or `auto/N`; `env` looks up a variable (the process environment
    /// in the CLI).
    pub fn parse(spec: &str, env: impl Fn(&str) -> Option<String>) -> Result<Shard, ShardError> {
        let bad = || ShardError::Spec {
            spec: spec.to_string(),
        };
        let (i, n) = spec.split_once('/').ok_or_else(bad)?;
        let count: u64 = n.trim().parse().map_err(|_| bad())?;
        if count == 0 || count > MAX_SHARDS {
            return Err(ShardError::Count {
                spec: spec.to_string(),
            });
        }
        let (index, var) = if i.trim() == "auto" {
            let (var, value) = INDEX_VARIABLES
                .iter()
                .find_map(|v| env(v).map(|x| (*v, x)))
                .ok_or_else(|| ShardError::IndexUnset {
                    spec: spec.to_string(),
                    count,
                })?;
            let index = value
                .trim()
                .parse::<u64>()
                .map_err(|_| ShardError::IndexVariable {
                    spec: spec.to_string(),
                    var,
                    value: value.clone(),
                })?;
            (index, Some(var))
        } else {
            (i.trim().parse::<u64>().map_err(|_| bad())?, None)
        };
        if index >= count {
            return Err(ShardError::Index {
                spec: spec.to_string(),
                index,
                var,
                count,
            });
        }
        Ok(Shard { index, count })
    }

    /// The shard's share of the job's `total` (spp or replicates, named by `what`); N
    /// must divide it.
    pub fn share(&self, total: u64, what: &str) -> Result<u64, ShardError> {
        if !total.is_multiple_of(self.count) {
            return Err(ShardError::Share {
                what: what.to_string(),
                total,
                count: self.count,
            });
        }
        Ok(total / self.count)
    }

    /// `out` with [`PLACEHOLDER`] replaced by the index, zero-padded to the width of N - 1.
    pub fn out_path(&self, out: &str) -> String {
        let width = (self.count - 1).to_string().len();
        out.replace(PLACEHOLDER, &format!("{:0width$}", self.index))
    }
}

/// Shard `index`'s seed in a job of seed `seed`: different for every index of one job.
pub fn shard_seed(seed: u64, index: u64) -> u64 {
    // For a fixed seed, index -> mix64(...) is a bijection, so no two shards share a seed.
    mix64(mix64(seed) ^ index.wrapping_mul(0x9e37_79b9_7f4a_7c15))
}

/// The job's identity: a hex hash of `key` (a canonical description of what it
/// renders, see `write.rs`).
pub fn job_id(key: &str) -> String {
    let h = Sha256::digest(key.as_bytes());
    h[..8].iter().map(|b| format!("{b:02x}")).collect()
}

/// Why [`merge_records`] refuses: the error, and the input (an index into its
/// `records`) that is wrong, when one is (`None` for shards missing: the job is
/// incomplete, no input is wrong).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{error}")]
pub struct RecordsError {
    pub input: Option<usize>,
    pub error: ShardError,
}

/// Checks that `records` (one per bundle to merge, `None` for bundles rendered without
/// `--shard`) hold no shard twice and, unless `partial`, every shard of every job.
/// Returns the merged bundle's record: the union when all come from one job. Linear
/// in the number of indices (a hash set per job), whatever their number.
pub fn merge_records(
    records: &[Option<&ShardRecord>],
    partial: bool,
) -> Result<Option<ShardRecord>, RecordsError> {
    use std::collections::{HashMap, HashSet};
    let fail = |input: usize, error: ShardError| RecordsError {
        input: Some(input),
        error,
    };
    // Per job, in order of first appearance: its record so far and the indices seen.
    let mut jobs: Vec<(ShardRecord, HashSet<u64>)> = Vec::new();
    let mut by_name: HashMap<&str, usize> = HashMap::new();
    for (input, r) in records.iter().enumerate() {
        let Some(r) = r else { continue };
        let k = *by_name.entry(r.job.as_str()).or_insert_with(|| {
            jobs.push((
                ShardRecord {
                    job: r.job.clone(),
                    count: r.count,
                    indices: Vec::new(),
                },
                HashSet::new(),
            ));
            jobs.len() - 1
        });
        let (job, seen) = &mut jobs[k];
        if job.count != r.count {
            return Err(fail(
                input,
                ShardError::JobCounts {
                    job: r.job.clone(),
                    count: job.count,
                    other: r.count,
                },
            ));
        }
        for &i in &r.indices {
            if i >= r.count {
                return Err(fail(
                    input,
                    ShardError::NoSuchShard {
                        job: r.job.clone(),
                        index: i,
                        count: r.count,
                    },
                ));
            }
            if !seen.insert(i) {
                return Err(fail(
                    input,
                    ShardError::Twice {
                        job: r.job.clone(),
                        index: i,
                        count: r.count,
                    },
                ));
            }
            job.indices.push(i);
        }
    }
    let mut jobs: Vec<ShardRecord> = jobs.into_iter().map(|(j, _)| j).collect();
    for j in &mut jobs {
        j.indices.sort_unstable();
        if !partial && j.indices.len() as u64 != j.count {
            // The indices are distinct and below count: count - len are missing. The
            // first 20 are found lazily (count may be large).
            let missing = j.count - j.indices.len() as u64;
            let shown: Vec<u64> = (0..j.count)
                .filter(|i| j.indices.binary_search(i).is_err())
                .take(20)
                .collect();
            return Err(RecordsError {
                input: None,
                error: ShardError::Missing {
                    job: j.job.clone(),
                    count: j.count,
                    missing,
                    shown,
                },
            });
        }
    }
    let all_sharded = records.iter().all(Option::is_some);
    Ok(match (jobs.len(), all_sharded) {
        (1, true) => jobs.pop(),
        _ => None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn env<'a>(vars: &'a [(&'a str, &'a str)]) -> impl Fn(&str) -> Option<String> + 'a {
        move |k| {
            vars.iter()
                .find(|(n, _)| *n == k)
                .map(|(_, v)| v.to_string())
        }
    }

    #[test]
    fn parses_explicit_and_scheduler_indices() {
        let none = env(&[]);
        assert_eq!(
            Shard::parse("3/16", &none),
            Ok(Shard {
                index: 3,
                count: 16
            })
        );
        assert_eq!(Shard::parse("0/1", &none), Ok(Shard { index: 0, count: 1 }));
        let slurm = env(&[("SLURM_ARRAY_TASK_ID", "7"), ("JOB_COMPLETION_INDEX", "2")]);
        assert_eq!(Shard::parse("auto/8", &slurm).unwrap().index, 7);
        let k8s = env(&[("JOB_COMPLETION_INDEX", "2")]);
        assert_eq!(Shard::parse("auto/8", &k8s).unwrap().index, 2);
        for (spec, vars, needle) in [
            ("16/16", &[][..], "not below"),
            ("3", &[][..], "expected I/N"),
            ("a/4", &[][..], "expected I/N"),
            ("1/0", &[][..], "from 1 to 2^32"),
            ("1/4294967297", &[][..], "from 1 to 2^32"),
            ("-1/4", &[][..], "expected I/N"),
            (
                "auto/4",
                &[][..],
                "neither SLURM_ARRAY_TASK_ID nor JOB_COMPLETION_INDEX",
            ),
            (
                "auto/4",
                &[("SLURM_ARRAY_TASK_ID", "4")][..],
                "(SLURM_ARRAY_TASK_ID)",
            ),
            (
                "auto/4",
                &[("SLURM_ARRAY_TASK_ID", "x")][..],
                "is not a shard index",
            ),
        ] {
            let e = Shard::parse(spec, env(vars)).unwrap_err().to_string();
            assert!(e.contains(needle), "{spec}: {e}");
        }
    }

    #[test]
    fn shares_seeds_and_paths() {
        let s = Shard {
            index: 5,
            count: 16,
        };
        assert_eq!(s.share(1024, "spp"), Ok(64));
        assert!(s
            .share(1000, "spp")
            .unwrap_err()
            .to_string()
            .contains("not a multiple"));
        assert_eq!(s.out_path("d/shard-{shard}.tstats"), "d/shard-05.tstats");
        assert_eq!(Shard { index: 7, count: 8 }.out_path("{shard}"), "7");
        assert_eq!(
            Shard {
                index: 3,
                count: 1000
            }
            .out_path("{shard}"),
            "003"
        );
        let seeds: std::collections::BTreeSet<u64> = (0..4096).map(|i| shard_seed(9, i)).collect();
        assert_eq!(seeds.len(), 4096);
        assert_ne!(shard_seed(9, 0), shard_seed(10, 0));
        assert_eq!(shard_seed(9, 3), shard_seed(9, 3));
    }

    #[test]
    fn records_merge_only_when_complete() {
        let rec = |job: &str, n, idx: &[u64]| ShardRecord {
            job: job.into(),
            count: n,
            indices: idx.to_vec(),
        };
        let (a0, a1, a2) = (rec("a", 3, &[0]), rec("a", 3, &[1]), rec("a", 3, &[2]));
        let all = merge_records(&[Some(&a2), Some(&a0), Some(&a1)], false).unwrap();
        assert_eq!(all, Some(rec("a", 3, &[0, 1, 2])));
        let e = merge_records(&[Some(&a0), Some(&a2)], false)
            .unwrap_err()
            .to_string();
        assert!(e.contains("1 of its 3 shards are missing: 1 "), "{e}");
        assert_eq!(
            merge_records(&[Some(&a0), Some(&a2)], true).unwrap(),
            Some(rec("a", 3, &[0, 2]))
        );
        let e = merge_records(&[Some(&a0), Some(&a0), Some(&a1), Some(&a2)], false)
            .unwrap_err()
            .to_string();
        assert!(e.contains("shard 0 of 3 is given twice"), "{e}");
        let e = merge_records(&[Some(&a0), Some(&a1), Some(&a0)], true).unwrap_err();
        assert_eq!(e.input, Some(2), "the repeating input is named");
        let e = merge_records(&[Some(&a0), Some(&a2)], false).unwrap_err();
        assert_eq!(e.input, None, "missing shards are the job's");
        let b = rec("b", 4, &[0, 1, 2, 3]);
        assert_eq!(
            merge_records(&[Some(&all.clone().unwrap()), Some(&b)], false),
            Ok(None)
        );
        assert_eq!(merge_records(&[Some(&b), None], false), Ok(None));
        let e = merge_records(&[Some(&a0), Some(&rec("a", 4, &[1]))], true)
            .unwrap_err()
            .to_string();
        assert!(e.contains("bundles of 3 and of 4 shards"), "{e}");
    }

    /// Linear in the indices: a million indices in one record (and the same million
    /// again, to be found repeated at the end) are checked in well under a second;
    /// the quadratic check this replaced took minutes.
    #[test]
    fn a_million_indices_merge_in_linear_time() {
        let n = 1_000_000u64;
        let all = ShardRecord {
            job: "0123456789abcdef".into(),
            count: 1 << 32,
            indices: (0..n).map(|i| i * 7).collect(),
        };
        let rest = ShardRecord {
            indices: vec![(n - 1) * 7],
            ..all.clone()
        };
        let merged = merge_records(&[Some(&all)], true).unwrap().unwrap();
        assert_eq!(merged.indices.len(), n as usize);
        let e = merge_records(&[Some(&all), Some(&rest)], true).unwrap_err();
        assert_eq!(e.input, Some(1));
        assert!(e.to_string().contains("given twice"), "{e}");
    }
}
