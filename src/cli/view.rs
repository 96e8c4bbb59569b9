//! `tstat view BUNDLE [--denoised D.npy] [--reference R.npy] --out view.html`: one
//! self-contained HTML page to look at the volume (see `viz::view`).

use super::util::{arg, check_outputs, human_bytes, size_flag_in, Kind};
use crate::bundle::float_rows::FloatRows;
use crate::bundle::write::replace_file;
use crate::bundle::Bundle;
use crate::viz::view::{
    block_size, build_page, bundle_row_bytes, page_memory, Extra, MembershipShown, Source,
};
use anyhow::{anyhow, bail, ensure};
use clap::Args;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct ViewArgs {
    /// The bundle (its noisy mean, statistics and G-buffers).
    pub bundle: PathBuf,
    /// A denoised volume of the bundle (.npy (H, W, T, C), C the bundle's channels, e.g.
    /// from `tstat denoise`).
    #[arg(long)]
    pub denoised: Option<PathBuf>,
    /// A reference volume (.npy (H, W, T, C), or a bundle of the same mode: its noisy
    /// mean).
    #[arg(long)]
    pub reference: Option<PathBuf>,
    /// Output HTML file.
    #[arg(long)]
    pub out: PathBuf,
    /// Largest size of the volumes' data in the page (e.g. 64M; default 48M): larger
    /// volumes are averaged over pixel blocks, as the page then says.
    #[arg(long, allow_hyphen_values = true)]
    pub max_bytes: Option<String>,
    /// The most memory building the page may take (e.g. 2G; default 8G): the volumes
    /// are read a row at a time and block-averaged as they are read, so this bounds a
    /// row, the page and the G-buffers, not the volumes.
    #[arg(long)]
    pub max_memory: Option<String>,
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
    let memory = super::nlos::memory_budget(a.max_memory.as_deref())?;
    let bundle = Bundle::open(&a.bundle)?;
    let m = &bundle.manifest;
    let ch = m.channel_count();
    let want = [m.height, m.width, m.bins, ch];
    let film = (m.height, m.width, m.bins, ch);
    let mut extras = Vec::new();
    let mut row_bytes = bundle_row_bytes(&bundle);
    for (label, path) in [("--denoised", &a.denoised), ("--reference", &a.reference)] {
        let Some(p) = path else { continue };
        let source = if p.is_dir() {
            let b = Bundle::open(p)?;
            let s = [
                b.manifest.height,
                b.manifest.width,
                b.manifest.bins,
                b.manifest.channel_count(),
            ];
            ensure!(
                s == want,
                "{label} {}: shape {s:?} does not match the bundle's (H, W, T, C) = {film:?}",
                p.display()
            );
            row_bytes += bundle_row_bytes(&b);
            Source::Bundle(Box::new(b))
        } else {
            let rows = FloatRows::open(p).map_err(|e| anyhow!("{label} {}: {e}", p.display()))?;
            ensure!(
                rows.shape() == want,
                "{label} {}: shape {:?} does not match the bundle's (H, W, T, C) = {film:?}",
                p.display(),
                rows.shape()
            );
            row_bytes += rows.row_bytes();
            Source::Npy {
                path: p.clone(),
                rows,
            }
        };
        extras.push(Extra {
            label: label.into(),
            source,
        });
    }
    let volumes = 1 + extras.len() + usize::from(m.transform.is_identity());
    let Some(k) = block_size(volumes, m.height, m.width, m.bins, ch, budget) else {
        bail!(
            "--max-bytes {}: too small for {} bins of {volumes} volumes even averaged over the whole image (at least {})",
            a.max_bytes.as_deref().unwrap_or_default(),
            m.bins,
            human_bytes(crate::viz::view::page_data_bytes(volumes, 1, 1, m.bins, ch, 1))
        );
    };
    let need = page_memory(volumes, film, k, row_bytes);
    if need > memory {
        bail!(
            "{}: a page of {} x {} px blocks needs {} of memory, over --max-memory {}",
            a.bundle.display(),
            k,
            k,
            human_bytes(need),
            human_bytes(memory)
        );
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
    let (page, s) = build_page(&bundle, &name, &mut extras, shown, k)?;
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
