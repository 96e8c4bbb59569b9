//! The reports' text: the Markdown of `report convergence` (its tables, the
//! reconstructions' and the cross-validated captures' sections), the metric columns
//! every report's CSV shares, the per-bin table and its plot, and the charts. The
//! commands (`cli/report.rs`) run the experiments, call these to write them, and draw
//! the reconstructions' projections (`viz::mip`, a layer above).

use super::convergence::{ConvergenceConfig, ConvergenceResult, BASELINE};
use super::metrics::{Metrics, REL_EPS};
use super::plot::{line_chart, AxisScale, Series};
use super::region::{rmse_ratio, Region, RegionMetrics};
use super::speedup::Speedup;
use super::table::{num, write_text, Table};
use std::path::Path;

/// Draws a chart, noting on stderr when there is nothing to draw (all errors 0).
pub fn chart(
    path: &Path,
    title: &str,
    x: &str,
    y: &str,
    series: &[Series],
    xs: AxisScale,
    ys: AxisScale,
) -> anyhow::Result<()> {
    if !line_chart(path, title, x, y, series, xs, ys)? {
        eprintln!(
            "note: {} not written: no positive finite values to plot",
            path.display()
        );
    }
    Ok(())
}

/// Column names `{rmse,relmse,psnr_db}_{region}` for every region.
pub fn metrics_header() -> Vec<String> {
    Region::ALL
        .iter()
        .flat_map(|r| {
            ["rmse", "relmse", "psnr_db"]
                .into_iter()
                .map(move |m| format!("{m}_{}", r.name()))
        })
        .collect()
}

/// The cells of [`metrics_header`]; "-" where a region is unknown or empty.
pub fn metrics_cells(m: &RegionMetrics) -> Vec<String> {
    Region::ALL
        .iter()
        .flat_map(|&r| match m.get(r) {
            Some(m) => [num(m.rmse), num(m.relmse), num(m.psnr)],
            None => ["-".to_string(), "-".into(), "-".into()],
        })
        .collect()
}

pub fn write_per_bin(
    dir: &Path,
    stem: &str,
    per_bin: &[(String, Vec<Metrics>)],
    title: &str,
) -> anyhow::Result<()> {
    let mut header = vec!["bin".to_string()];
    for (l, _) in per_bin {
        header.extend([format!("{l}_rmse"), format!("{l}_relmse")]);
    }
    let mut t = Table {
        header,
        rows: Vec::new(),
    };
    let bins = per_bin.first().map_or(0, |p| p.1.len());
    for k in 0..bins {
        let mut row = vec![k.to_string()];
        for (_, m) in per_bin {
            row.extend([num(m[k].rmse), num(m[k].relmse)]);
        }
        t.push(row);
    }
    write_text(&dir.join(format!("{stem}.csv")), &t.csv())?;
    let series: Vec<Series> = per_bin
        .iter()
        .map(|(l, m)| Series {
            label: l.clone(),
            points: m
                .iter()
                .enumerate()
                .map(|(k, m)| (k as f64, m.rmse))
                .collect(),
        })
        .collect();
    chart(
        &dir.join(format!("{stem}.png")),
        title,
        "time bin",
        "RMSE",
        &series,
        AxisScale::Linear,
        AxisScale::Log,
    )
}

pub fn convergence_markdown(
    scene: &Path,
    cfg: &ConvergenceConfig,
    r: &ConvergenceResult,
) -> String {
    let base = r
        .settings
        .iter()
        .find_map(|s| s.1)
        .map_or(cfg.denoise.base, |p| p.base);
    let mut md = format!(
        "# Convergence: {}\n\nReference: {}. Denoisers: r_t = {}, base {:?}; {}. Transform: {}. Pixel sampling: {}. Every spp is a separate render with its own seed.\n\n",
        scene.display(),
        r.reference_note,
        cfg.denoise.temporal_radius,
        base,
        r.settings
            .iter()
            .filter_map(|(name, p)| {
                p.map(|p| format!("{name}: r = {}, {}", p.radius, p.method.describe()))
            })
            .collect::<Vec<_>>()
            .join("; "),
        cfg.transform,
        cfg.pixel_sampling
    );
    md += "Regions: all voxels; light = pixels that see a light directly (emitter G-buffer > 0); rest = the other pixels.\n\n";
    let mut t = Table::new(&[
        "spp",
        "method",
        "render s",
        "denoise s",
        "total s",
        "RMSE all",
        "RMSE light",
        "RMSE rest",
        "PSNR dB",
        "G eval/s",
    ]);
    let rmse = |m: Option<Metrics>| m.map_or("-".into(), |m| num(m.rmse));
    for row in &r.rows {
        t.push(vec![
            row.spp.to_string(),
            row.method.into(),
            format!("{:.2}", row.render_s),
            format!("{:.2}", row.denoise_s),
            format!("{:.2}", row.total_s),
            num(row.error.all.rmse),
            rmse(row.error.light),
            rmse(row.error.rest),
            format!("{:.2}", row.error.all.psnr),
            if row.evaluations_per_s == 0.0 {
                "-".into()
            } else {
                format!("{:.2}", row.evaluations_per_s / 1e9)
            },
        ]);
    }
    md += &t.markdown();
    md += "\n## Against the noisy render\n\nRMSE / noisy RMSE at the same spp (same render), and the equal-error speed-up: how many times less time (render + denoise) the result needs than the noisy render to reach the same RMSE over the same region (noisy curve interpolated in log-log; outside its measured range, a bound: `>Ax` when the result beats the noisy render's best point, A = that point's time over the result's, `<Ax` when it is worse than its first point).";
    let baseline = r.methods.contains(&BASELINE);
    let mut header = vec![
        "spp",
        "method",
        "ratio all",
        "ratio light",
        "ratio rest",
        "speed-up all",
        "speed-up light",
        "speed-up rest",
    ];
    if baseline {
        md += " The last three columns: the speed-up against the noisy render with independent sub-pixel positions (`noisy-independent`, separate seeds), i.e. stratified sampling and denoising together against a renderer without either.";
        header.extend([
            "vs independent all",
            "vs independent light",
            "vs independent rest",
        ]);
    }
    md += "\n\n";
    let mut s = Table::new(&header);
    let x_fmt = |v: Option<Speedup>| v.map_or("-".into(), |v| format!("{v}x"));
    for row in r
        .rows
        .iter()
        .filter(|x| x.method != "noisy" && x.method != BASELINE)
    {
        let noisy = r
            .rows
            .iter()
            .find(|x| x.method == "noisy" && x.spp == row.spp)
            .expect("every spp has a noisy row");
        let ratio = |g: Region| {
            rmse_ratio(row.error.get(g), noisy.error.get(g))
                .map_or("-".into(), |v| format!("{v:.3}"))
        };
        let mut cells = vec![row.spp.to_string(), row.method.into()];
        cells.extend(Region::ALL.map(ratio));
        cells.extend(Region::ALL.map(|g| x_fmt(row.speedup(g))));
        if baseline {
            cells.extend(row.speedup_independent.map(x_fmt));
        }
        s.push(cells);
    }
    md += &s.markdown();
    md += &format!(
        "\nrelMSE = mean (x - ref)^2 / (ref^2 + {REL_EPS}); PSNR peak = max of the reference.\n"
    );
    md += &reconstruction_markdown(r);
    md
}

/// The reconstructions' section of the convergence report (empty without them).
pub fn reconstruction_markdown(r: &ConvergenceResult) -> String {
    let Some(g) = r.reconstruction_grid else {
        return String::new();
    };
    let methods = &r.reconstruction_methods;
    let mut md = format!(
        "\n## Reconstructions\n\nEvery capture above (and the reference) reconstructed with {} on {} x {} x {} voxels from ({}, {}, {}) to ({}, {}, {}). Error: relative L2, ||V - V_ref|| / ||V_ref||, against the reconstruction of the reference capture. Time: the reconstruction's alone (s); the speed-up compares render + denoise + reconstruction with the noisy curve's render + reconstruction at the same error (the reconstruction's time taken as its median over all rows: it does not depend on the capture's values) (interpolated in log-log; `>Ax` / `<Ax` bounds outside its range). Gain at equal spp: the noisy capture's error at the same spp (the same render) over this one's.\n\n",
        methods.iter().map(|m| m.describe()).collect::<Vec<_>>().join("; "),
        g.n[0], g.n[1], g.n[2], g.first[0], g.first[1], g.first[2], g.last[0], g.last[1], g.last[2]
    );
    let mut header = vec!["spp".to_string(), "capture".to_string()];
    for m in methods {
        let n = m.name();
        header.extend([
            format!("{n} error"),
            format!("{n} s"),
            format!("{n} gain, equal spp"),
            format!("{n} speed-up"),
        ]);
    }
    let header: Vec<&str> = header.iter().map(String::as_str).collect();
    let mut t = Table::new(&header);
    for row in &r.rows {
        let noisy = r
            .rows
            .iter()
            .find(|x| x.method == "noisy" && x.spp == row.spp)
            .expect("every spp has a noisy row");
        let mut cells = vec![row.spp.to_string(), row.method.to_string()];
        for (k, e) in row.reconstructions.iter().enumerate() {
            let denoised = row.method != "noisy" && row.method != BASELINE;
            cells.push(format!("{:.4}", e.error));
            cells.push(format!("{:.2}", e.seconds));
            cells.push(if denoised {
                format!("{:.2}", noisy.reconstructions[k].error / e.error)
            } else {
                String::new()
            });
            cells.push(match row.reconstruction_speedup[k] {
                Some(v) => format!("{v}x"),
                None if denoised => "-".into(),
                None => String::new(),
            });
        }
        t.push(cells);
    }
    md += &t.markdown();
    md += &cross_validated_markdown(r);
    let min_spp = r.rows.iter().map(|x| x.spp).min().unwrap_or(0);
    md += &format!(
        "\nPictures: `reconstruction_{{method}}_mip.png`, the maximum along depth of the reconstruction of, left to right, the reference, the noisy capture and the tstat-denoised capture at {min_spp} spp (each scaled by its own maximum); plots `reconstruction_{{method}}_error_vs_seconds.png` and `_error_vs_spp.png`.\n"
    );
    md
}

/// `nlos reconstruct --denoise-with`'s rows of the reconstructions' section.
pub fn cross_validated_markdown(r: &ConvergenceResult) -> String {
    if r.cross_validated.is_empty() {
        return String::new();
    }
    let methods = &r.reconstruction_methods;
    let mut md = "\n### Denoised for the reconstruction (`nlos reconstruct --denoise-with`)\n\nEach spp's tstat-denoised capture shrunk toward its noisy capture by the weight b (0: the denoised capture, 1: the noisy one) cross-validated, per method, between two more independent captures of spp / 2, rendered and denoised for it (docs/nlos.md). Gain: the noisy capture's error at the same spp over this one's; never below 1 but for the estimate's own error.\n\n".to_string();
    let mut header = vec![
        "spp".to_string(),
        "halves: render s".into(),
        "halves: denoise s".into(),
    ];
    for m in methods {
        let n = m.name();
        header.extend([format!("{n} error"), format!("{n} gain"), format!("{n} b")]);
    }
    let header: Vec<&str> = header.iter().map(String::as_str).collect();
    let mut t = Table::new(&header);
    for cv in &r.cross_validated {
        let noisy = r
            .rows
            .iter()
            .find(|x| x.method == "noisy" && x.spp == cv.spp)
            .expect("every spp has a noisy row");
        let mut cells = vec![
            cv.spp.to_string(),
            format!("{:.2}", cv.render_s),
            format!("{:.2}", cv.denoise_s),
        ];
        for (k, (e, b)) in cv.reconstructions.iter().enumerate() {
            cells.push(format!("{:.4}", e.error));
            cells.push(format!("{:.2}", noisy.reconstructions[k].error / e.error));
            cells.push(format!("{b:.3}"));
        }
        t.push(cells);
    }
    md += &t.markdown();
    md
}

pub fn ratio(m: Option<Metrics>, noisy: Option<Metrics>) -> String {
    rmse_ratio(m, noisy).map_or("n/a".into(), |v| format!("{v:.3}"))
}
