//! `tstat merge A.tstats B.tstats ... --out C.tstats`: one bundle from renders of the
//! same scene and settings with different seeds (e.g. from several machines, or the
//! shards of one `--shard` job), streamed in bounded memory.

use super::util::{arg, check_outputs, human_bytes, size_flag, Kind};
use crate::bundle::merge::{merge_bundles, MergeOptions};
use clap::Args;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct MergeArgs {
    /// Bundles to merge (at least two; same scene and settings, different seeds).
    /// Shards of a `--shard` job must all be given (see --partial).
    #[arg(required = true, num_args = 2..)]
    pub bundles: Vec<PathBuf>,
    /// Output bundle directory.
    #[arg(long)]
    pub out: PathBuf,
    /// Accept a job whose shards are not all given (e.g. one level of a tree of
    /// merges); repeated shards are refused all the same.
    #[arg(long)]
    pub partial: bool,
    /// Memory for the bands of rows summed at once (e.g. 512M; default 256M). The
    /// merge's memory does not grow with the number of bundles.
    #[arg(long, allow_hyphen_values = true)]
    pub max_memory: Option<String>,
    /// Replace an existing output.
    #[arg(long)]
    pub force: bool,
}

pub fn run(a: MergeArgs) -> anyhow::Result<()> {
    let inputs: Vec<_> = a.bundles.iter().map(|b| arg("bundle", b)).collect();
    check_outputs(&inputs, &[(arg("--out", &a.out), Kind::Dir)], a.force)?;
    let mut opts = MergeOptions {
        force: a.force,
        partial: a.partial,
        ..MergeOptions::default()
    };
    if let Some(s) = &a.max_memory {
        opts.memory = size_flag("--max-memory", s)?;
    }
    let m = merge_bundles(&a.bundles, &a.out, opts)?;
    let shards = match &m.shard {
        Some(s) if s.indices.len() as u64 == s.count => {
            format!(", all {} shards of job {}", s.count, s.job)
        }
        Some(s) => format!(
            ", {} of the {} shards of job {}",
            s.indices.len(),
            s.count,
            s.job
        ),
        None => String::new(),
    };
    say!(
        "merged {} bundles into {}: {} spp{shards} (band memory {})",
        a.bundles.len(),
        a.out.display(),
        m.spp,
        human_bytes(opts.memory)
    );
    Ok(())
}
