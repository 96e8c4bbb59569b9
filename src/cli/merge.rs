//! `tstat merge A.tstats B.tstats ... --out C.tstats`: one bundle from renders of the
//! same scene and settings with different seeds (e.g. from several machines).

use super::util::{arg, check_outputs, Kind};
use crate::bundle::merge::merge_bundles;
use clap::Args;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct MergeArgs {
    /// Bundles to merge (at least two; same scene and settings, different seeds).
    #[arg(required = true, num_args = 2..)]
    pub bundles: Vec<PathBuf>,
    /// Output bundle directory.
    #[arg(long)]
    pub out: PathBuf,
    /// Replace an existing output.
    #[arg(long)]
    pub force: bool,
}

pub fn run(a: MergeArgs) -> anyhow::Result<()> {
    let inputs: Vec<_> = a.bundles.iter().map(|b| arg("bundle", b)).collect();
    check_outputs(&inputs, &[(arg("--out", &a.out), Kind::Dir)], a.force)?;
    let m = merge_bundles(&a.bundles, &a.out, a.force)?;
    say!(
        "merged {} bundles into {}: {} spp (seeds {:?})",
        a.bundles.len(),
        a.out.display(),
        m.spp,
        m.merged_seeds
    );
    Ok(())
}
