//! `tstat view BUNDLE [--denoised D.npy] [--reference R.npy] --out view.html`: one
//! self-contained HTML page to look at the volume (see `viz::view`).

use super::util::{arg, check_outputs, human_bytes, size_flag_in, Kind};
use crate::bundle::write::replace_file;
use crate::bundle::Bundle;
use crate::report::volume::load_volume;
use crate::viz::view::{build_page, Extra, MembershipShown};
use anyhow::{anyhow, ensure};
use clap::Args;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct ViewArgs {
    /// The bundle (its noisy mean, statistics and G-buffers).
    pub bundle: PathBuf,
    /// A denoised volume of the bundle (.npy (H, W, T, 3), e.g. from `tstat denoise`).
    #[arg(long)]
    pub denoised: Option<PathBuf>,
    /// A reference volume (.npy (H, W, T, 3), or a bundle: its noisy mean).
    #[arg(long)]
    pub reference: Option<PathBuf>,
    /// Output HTML file.
    #[arg(long)]
    pub out: PathBuf,
    /// Largest size of the volumes' data in the page (e.g. 64M; default 48M): larger
    /// volumes are averaged over pixel blocks, as the page then says.
    #[arg(long, allow_hyphen_values = true)]
    pub max_bytes: Option<String>,
    /// Replace an existing output.
    #[arg(long)]
    pub force: bool,
}

pub fn run(a: ViewArgs) -> anyhow::Result<()> {
    let mut inputs = vec![arg("bundle", &a.bundle)];
    inputs.extend(a.denoised.iter().map(|p| arg("--denoised", p)));
    inputs.extend(a.reference.iter().map(|p| arg("--reference", p)));
    check_outputs(&inputs, &[(arg("--out", &a.out), Kind::File)], a.force)?;
    let budget = match &a.max_bytes {
        Some(s) => size_flag_in("--max-bytes", s, (1024, "1Ki"), (u64::MAX, "16Ei"))?,
        None => 48 << 20,
    };
    let bundle = Bundle::open(&a.bundle)?;
    let m = &bundle.manifest;
    let want = (m.height, m.width, m.bins, 3);
    let mut extras = Vec::new();
    for (label, path) in [("denoised", &a.denoised), ("reference", &a.reference)] {
        if let Some(p) = path {
            let v = load_volume(p)?.volume;
            ensure!(
                v.dim() == want,
                "--{label} {}: shape {:?} does not match the bundle's (H, W, T, C) = {want:?}",
                p.display(),
                v.shape()
            );
            extras.push(Extra {
                label: label.into(),
                volume: v,
            });
        }
    }
    let name = a.bundle.file_name().map_or_else(
        || a.bundle.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    // The default denoiser's test (tstat's method, its default radius and t2_max).
    let tp = crate::denoise::tstat::TstatParams::default();
    let method: crate::denoise::Method = crate::denoise::Method::Tstat(tp);
    let shown = MembershipShown {
        radius: method.default_radius(),
        t2_max: tp.t2_max,
        depth_align: tp.depth_align,
    };
    let (page, s) = build_page(&bundle, &name, &extras, shown, budget as usize)?;
    // check_outputs refused an existing output without --force.
    replace_file(&a.out, |tmp| {
        std::fs::write(tmp, &page).map_err(|e| e.to_string())
    })
    .map_err(|e| anyhow!("{e}"))?;
    say!(
        "wrote {} ({}){}{}",
        a.out.display(),
        human_bytes(s.bytes as u64),
        if s.block > 1 {
            format!(
                "; volumes averaged over {0} x {0} pixel blocks to fit --max-bytes",
                s.block
            )
        } else {
            String::new()
        },
        if s.band {
            ""
        } else {
            "; no confidence band (the bundle's sums are of transformed samples)"
        }
    );
    Ok(())
}
