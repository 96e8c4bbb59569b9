//! `tstat report compare | convergence | sweep`: error against a reference, speed
//! against error, and parameter sweeps, as tables (CSV, Markdown) and PNG plots.

use super::denoise::{BaseFilterArgs, FilterArgs, MethodArg};
use super::render::SceneArgs;
use super::util::{arg, float_list, int_flag, int_list, seed, split_list, Arg, ReportDir};
use crate::denoise::critical::Threshold;
use crate::denoise::tstat::TstatParams;
use crate::denoise::Method;
use crate::nlos::reconstruct::Reconstruction;
use crate::report::convergence::{
    self, run_convergence, ConvergenceConfig, ConvergenceResult, ReferenceSource, ResultRow,
};
use crate::report::metrics::{Metrics, REL_EPS};
use crate::report::plot::{AxisScale, Series};
use crate::report::reconstruction::NlosPlan;
use crate::report::region::{compare_regions, Region};

use crate::report::sweep::{run_sweep, SweepConfig};
use crate::report::table::{num, write_text, Table};
use crate::report::text::{
    chart, convergence_markdown, metrics_cells, metrics_header, ratio, write_per_bin,
};
use crate::report::volume::load_volume;
use anyhow::{anyhow, bail, ensure};
use clap::{Args, Subcommand};
use std::path::{Path, PathBuf};

#[derive(Subcommand, Debug)]
pub enum ReportCommand {
    /// Metrics of volumes (.npy or bundles) against a reference volume.
    Compare(CompareArgs),
    /// Render at a list of spp, denoise each, and measure error against time.
    Convergence(Box<ConvergenceArgs>),
    /// Error of every combination of denoiser parameters on bundles.
    Sweep(Box<SweepArgs>),
}

#[derive(Args, Debug)]
pub struct ReportArgs {
    #[command(subcommand)]
    pub command: ReportCommand,
}

#[derive(Args, Debug)]
pub struct CompareArgs {
    /// Reference volume: .npy (H, W, T, C) or a bundle (its noisy mean).
    #[arg(long)]
    pub reference: PathBuf,
    /// A volume to measure, LABEL=FILE (repeatable).
    #[arg(long = "input", value_name = "LABEL=FILE", required = true)]
    pub inputs: Vec<String>,
    /// Also write metrics.csv, metrics.md, per_bin.csv and per_bin.png here.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Replace existing result files in --out.
    #[arg(long)]
    pub force: bool,
}

#[derive(Args, Debug)]
pub struct ConvergenceArgs {
    /// Mitsuba 3 XML scene.
    pub scene: PathBuf,
    /// Leave out the adaptive pipeline's rows (`adaptive`, `adaptive tstat`: the same
    /// spp as a mean, spent where the error is; timed pilot + render).
    #[arg(long)]
    pub no_adaptive: bool,
    /// Comma-separated spp list, e.g. 16,32,64,128.
    #[arg(long, allow_hyphen_values = true)]
    pub spp: String,
    /// Output directory (tables, plots, and the cached reference).
    #[arg(long)]
    pub out: PathBuf,
    /// Reference volume (.npy or bundle) instead of rendering one.
    #[arg(long, conflicts_with = "reference_spp")]
    pub reference: Option<PathBuf>,
    /// Render the reference at this spp (default 4096), cached in --out.
    #[arg(long, allow_negative_numbers = true)]
    pub reference_spp: Option<i64>,
    /// Base seed: run k uses seed + 1 + k, the reference seed + 1000003.
    #[arg(long, default_value_t = 0, allow_negative_numbers = true)]
    pub seed: i128,
    /// Sample transform for the renders.
    #[arg(long, default_value = "identity")]
    pub transform: String,
    #[command(flatten)]
    pub scene_args: SceneArgs,
    #[command(flatten)]
    pub filter: FilterArgs,
    #[command(flatten)]
    pub nlos: NlosConvergenceArgs,
    /// Replace existing result files in --out.
    #[arg(long)]
    pub force: bool,
}

/// `report convergence` on an NLOS scene: reconstructions of every capture.
#[derive(Args, Debug)]
pub struct NlosConvergenceArgs {
    /// NLOS scenes: also reconstruct every capture (noisy, denoised, the reference)
    /// with these methods (comma-separated: bp, fbp, pf, fk, lct, as `nlos
    /// reconstruct`), and measure each against the reference's reconstruction.
    #[arg(long)]
    pub reconstruct: Option<String>,
    /// With --reconstruct: X0,X1,Y0,Y1,Z0,Z1, the first and last voxel centres.
    #[arg(long, allow_hyphen_values = true, requires = "reconstruct")]
    pub volume: Option<String>,
    /// With --reconstruct: NX,NY,NZ.
    #[arg(long, requires = "reconstruct")]
    pub voxels: Option<String>,
    /// fbp, pf: the virtual pulse's wavelength (OPL units).
    #[arg(long, requires = "reconstruct")]
    pub wl_mean: Option<f64>,
    /// fbp, pf: its Gaussian envelope's width (default wl_mean / sqrt(2)).
    #[arg(long, requires = "reconstruct")]
    pub wl_sigma: Option<f64>,
    /// lct: the Wiener filter's signal-to-noise ratio (default 0.8).
    #[arg(long, requires = "reconstruct")]
    pub snr: Option<f64>,
    /// The most working memory one reconstruction may take (default 8G).
    #[arg(long, requires = "reconstruct")]
    pub max_memory: Option<String>,
}

impl NlosConvergenceArgs {
    /// The reconstructions asked for, or `None`.
    fn plan(&self) -> anyhow::Result<Option<NlosPlan>> {
        use super::nlos::{memory_budget, reconstruction, voxel_grid, NlosMethod as Nlos};
        use clap::ValueEnum;
        let Some(list) = &self.reconstruct else {
            return Ok(None);
        };
        let (Some(volume), Some(voxels)) = (&self.volume, &self.voxels) else {
            bail!("--reconstruct needs --volume and --voxels (the reconstructions' grid)");
        };
        let grid = voxel_grid(volume, voxels)?;
        let mut methods: Vec<Reconstruction> = Vec::new();
        for name in split_list("--reconstruct", list)? {
            let m = Nlos::from_str(name, true).map_err(|_| {
                anyhow!("--reconstruct {list}: '{name}' is none of bp, fbp, pf, fk, lct")
            })?;
            let w = m.wavelength();
            let lct = matches!(m, Nlos::Lct);
            let r = reconstruction(
                m,
                self.wl_mean.filter(|_| w),
                self.wl_sigma.filter(|_| w),
                self.snr.filter(|_| lct),
            )?;
            ensure!(
                methods.iter().all(|x| x.name() != r.name()),
                "--reconstruct {list}: '{name}' twice"
            );
            methods.push(r);
        }
        let waves = methods
            .iter()
            .any(|r| matches!(r, Reconstruction::Fbp { .. } | Reconstruction::Pf { .. }));
        ensure!(
            waves || (self.wl_mean.is_none() && self.wl_sigma.is_none()),
            "--wl-mean and --wl-sigma belong to the methods fbp and pf"
        );
        ensure!(
            self.snr.is_none() || methods.iter().any(|r| r.name() == "lct"),
            "--snr belongs to the method lct"
        );
        Ok(Some(NlosPlan {
            methods,
            grid,
            max_memory: memory_budget(self.max_memory.as_deref())?,
        }))
    }
}

#[derive(Args, Debug)]
pub struct SweepArgs {
    /// Bundles to sweep (e.g. one per transform).
    #[arg(required = true)]
    pub bundles: Vec<PathBuf>,
    /// Reference volume (.npy or bundle).
    #[arg(long)]
    pub reference: PathBuf,
    /// Membership test to sweep.
    #[arg(long, value_enum, default_value = "tstat")]
    pub method: MethodArg,
    /// Published: comma-separated gammas [default: 0.01,0.05,0.1,0.2].
    #[arg(long, allow_hyphen_values = true)]
    pub gamma: Option<String>,
    /// tstat: comma-separated per-voxel bounds t2_max [default: 4].
    #[arg(long, allow_hyphen_values = true)]
    pub t2_max: Option<String>,
    /// tstat: comma-separated patch bounds t2_patch [default: 1,1.5,2].
    #[arg(long, allow_hyphen_values = true)]
    pub t2_patch: Option<String>,
    /// tstat: comma-separated emitter radii [default: 4r].
    #[arg(long, allow_hyphen_values = true)]
    pub emitter_radius: Option<String>,
    /// tstat: depth alignment settings to try: on, off or on,off [default: on].
    #[arg(long)]
    pub depth_align: Option<String>,
    /// Comma-separated spatial radii.
    #[arg(long, default_value = "3,5,10", allow_hyphen_values = true)]
    pub radius: String,
    /// Comma-separated temporal radii.
    #[arg(long, default_value = "0,1,2", allow_hyphen_values = true)]
    pub temporal_radius: String,
    /// Output directory for sweep.csv, sweep.md, sweep.png.
    #[arg(long)]
    pub out: PathBuf,
    #[command(flatten)]
    pub base: BaseFilterArgs,
    /// Replace existing result files in --out.
    #[arg(long)]
    pub force: bool,
}

pub fn run(a: ReportArgs) -> anyhow::Result<()> {
    match a.command {
        ReportCommand::Compare(a) => run_compare(a),
        ReportCommand::Convergence(a) => run_conv(*a),
        ReportCommand::Sweep(a) => run_sweep_cmd(*a),
    }
}

/// The largest spatial or temporal radius (as in `tstat denoise`).
const MAX_RADIUS: i64 = 64;

/// A list of radii in `0..=MAX_RADIUS`.
fn radius_list(flag: &str, s: &str) -> anyhow::Result<Vec<usize>> {
    Ok(int_list(flag, s, 0, MAX_RADIUS)?
        .into_iter()
        .map(|r| r as usize)
        .collect())
}

/// "wrote DIR/{a, b}": the result files that were written (a plot with nothing to
/// draw is not, and says so on stderr).
fn wrote(dir: &Path, files: &[&str]) -> String {
    let written: Vec<&str> = files
        .iter()
        .copied()
        .filter(|f| dir.join(f).is_file())
        .collect();
    format!("wrote {}/{{{}}}", dir.display(), written.join(", "))
}

fn run_compare(a: CompareArgs) -> anyhow::Result<()> {
    let files = ["metrics.csv", "metrics.md", "per_bin.csv", "per_bin.png"];
    let mut inputs = Vec::new();
    for spec in &a.inputs {
        let (label, file) = spec
            .split_once('=')
            .ok_or_else(|| anyhow!("--input {spec}: expected LABEL=FILE"))?;
        ensure!(!label.is_empty(), "--input {spec}: the label is empty");
        ensure!(!file.is_empty(), "--input {spec}: the file is empty");
        ensure!(
            !inputs.iter().any(|(l, _)| l == label),
            "--input {spec}: the label {label} is given twice"
        );
        inputs.push((label.to_string(), PathBuf::from(file)));
    }
    let mut args: Vec<Arg> = vec![arg("--reference", &a.reference)];
    args.extend(inputs.iter().map(|(l, f)| arg(format!("--input {l}="), f)));
    let out = match &a.out {
        Some(d) => Some(ReportDir::prepare(
            "--out",
            d,
            &files,
            |_| false,
            &args,
            a.force,
        )?),
        None => None,
    };
    let reference = load_volume(&a.reference)?;
    let mut mask = reference.no_light_mask.clone();
    let mut header = vec!["input".to_string()];
    header.extend(metrics_header());
    let mut table = Table {
        header,
        rows: Vec::new(),
    };
    let mut per_bin = Vec::new();
    let mut loaded = Vec::new();
    for (label, file) in &inputs {
        let v = load_volume(file)?;
        ensure!(
            v.volume.shape() == reference.volume.shape(),
            "{}: shape {:?} does not match the reference's {:?}",
            file.display(),
            v.volume.shape(),
            reference.volume.shape()
        );
        if mask.is_none() {
            mask = v.no_light_mask.clone();
        }
        loaded.push((label.clone(), v));
    }
    for (label, v) in &loaded {
        let (m, bins) = compare_regions(v.volume.view(), reference.volume.view(), mask.as_deref());
        let mut row = vec![label.clone()];
        row.extend(metrics_cells(&m));
        table.push(row);
        per_bin.push((label.clone(), bins));
    }
    let note = format!(
        "relmse = mean (x - ref)^2 / (ref^2 + {REL_EPS}); PSNR peak = max of the reference; light: pixels whose emitter G-buffer is > 0 (they see a light directly), rest: the others{}\n",
        if mask.is_some() {
            ""
        } else {
            " (no bundle given, so the split is unknown: not computed)"
        }
    );
    super::util::say(format_args!("{}\n{note}", table.markdown()))?;
    if let Some(mut out) = out {
        let d = out.create()?.to_path_buf();
        let d = &d;
        write_text(&d.join("metrics.csv"), &table.csv())?;
        write_text(
            &d.join("metrics.md"),
            &format!("{}\n{note}", table.markdown()),
        )?;
        write_per_bin(d, "per_bin", &per_bin, "per-bin RMSE")?;
        out.finish();
        say!("{}", wrote(d, &files));
    }
    Ok(())
}

fn run_conv(a: ConvergenceArgs) -> anyhow::Result<()> {
    let nlos = a.nlos.plan()?;
    let mut files: Vec<String> = [
        "results.csv",
        "results.md",
        "error_vs_spp.png",
        "error_vs_seconds.png",
        "error_vs_seconds_light.png",
        "error_vs_seconds_rest.png",
        "error_per_bin.png",
        "error_per_bin.csv",
    ]
    .map(String::from)
    .to_vec();
    for m in nlos.iter().flat_map(|p| &p.methods) {
        for suffix in ["error_vs_seconds.png", "error_vs_spp.png", "mip.png"] {
            files.push(format!("reconstruction_{}_{suffix}", m.name()));
        }
    }
    let files: Vec<&str> = files.iter().map(String::as_str).collect();
    let spp_list = int_list("--spp", &a.spp, i64::MIN, u32::MAX as i64)?;
    if let Some(s) = spp_list.iter().find(|&&s| s < 2) {
        bail!("--spp {s}: must be at least 2 (below 2 samples per pixel no variance can be estimated)");
    }
    let spp_list: Vec<u32> = spp_list.into_iter().map(|s| s as u32).collect();
    for &spp in &spp_list {
        crate::render::RenderSettings::check_replicates(spp, a.scene_args.replicates)
            .map_err(|e| anyhow!("{e} (in --spp)"))?;
    }
    let base_seed = seed(Some(a.seed))?.unwrap_or(0);
    let transform = a.scene_args.transform(&a.transform)?;
    let overrides = a.scene_args.overrides(None)?;
    anyhow::ensure!(
        a.scene_args.replicates < 2 || a.filter.variance == super::denoise::VarianceArg::Unbiased,
        "--variance biased: the published code's convention for i.i.d. samples; with --replicates V comes from the replicates"
    );
    let cfg = ConvergenceConfig {
        scene: a.scene.clone(),
        overrides,
        spp_list,
        seed: base_seed,
        transform,
        pixel_sampling: a.scene_args.pixel_sampling,
        replicates: a.scene_args.replicates,
        denoise: a.filter.params()?,
        method_radii: a.filter.radius.is_none(),
        radius_chosen: a.filter.radius.is_some(),
        depth_align_asked: a.filter.depth_align,
        adaptive: !a.no_adaptive,
        base_by_scene: a.filter.base.base.is_none(),
        nlos,
        reference: match (&a.reference, a.reference_spp) {
            (Some(p), _) => ReferenceSource::Volume(p.clone()),
            (None, s) => {
                let spp = int_flag("--reference-spp", s.unwrap_or(4096), 2, u32::MAX as i64)?;
                ReferenceSource::Render { spp: spp as u32 }
            }
        },
    };
    let mut args = vec![arg("scene", &a.scene)];
    if let Some(r) = &a.reference {
        args.push(arg("--reference", r));
    }
    // The cached reference renders are this command's files too.
    let is_cache = |n: &str| n.starts_with("reference-") && n.ends_with(".npy");
    let mut out = ReportDir::prepare("--out", &a.out, &files, is_cache, &args, a.force)?;
    out.create()?;
    let result = run_convergence(&cfg, &a.out, &|m| eprintln!("{m}"))?;
    let md = convergence_markdown(&a.scene, &cfg, &result);
    let mut header: Vec<String> = ["spp", "method", "render_s", "denoise_s", "total_s"]
        .map(String::from)
        .to_vec();
    header.extend(metrics_header());
    header.extend(Region::ALL.map(|r| format!("speedup_{}", r.name())));
    header.extend(Region::ALL.map(|r| format!("speedup_vs_independent_{}", r.name())));
    header.push("g_evaluations_per_s".into());
    for m in &result.reconstruction_methods {
        for c in ["rel_l2", "s", "speedup"] {
            header.push(format!("{}_{c}", m.name()));
        }
    }
    let mut t = Table {
        header,
        rows: Vec::new(),
    };
    for r in &result.rows {
        let mut row = vec![
            r.spp.to_string(),
            r.method.into(),
            num(r.render_s),
            num(r.denoise_s),
            num(r.total_s),
        ];
        row.extend(metrics_cells(&r.error));
        row.extend(Region::ALL.map(|g| r.speedup(g).map_or("-".into(), |v| v.to_string())));
        row.extend(
            r.speedup_independent
                .map(|v| v.map_or("-".into(), |v| v.to_string())),
        );
        row.push(num(r.evaluations_per_s / 1e9));
        for (e, x) in r.reconstructions.iter().zip(&r.reconstruction_speedup) {
            row.push(num(e.error));
            row.push(num(e.seconds));
            row.push(x.map_or("-".into(), |v| v.to_string()));
        }
        t.push(row);
    }
    write_text(&a.out.join("results.csv"), &t.csv())?;
    write_text(&a.out.join("results.md"), &md)?;
    let curve = |m: &str, region: Region, x: fn(&ResultRow) -> f64| Series {
        label: m.to_string(),
        points: result
            .rows
            .iter()
            .filter(|r| r.method == m)
            .filter_map(|r| r.error.get(region).map(|e| (x(r), e.rmse)))
            .collect(),
    };
    let series = |region: Region, x: fn(&ResultRow) -> f64| -> Vec<Series> {
        result.methods.iter().map(|m| curve(m, region, x)).collect()
    };
    chart(
        &a.out.join("error_vs_spp.png"),
        "RMSE against samples per pixel",
        "spp",
        "RMSE",
        &series(Region::All, |r| r.spp as f64),
        AxisScale::Log,
        AxisScale::Log,
    )?;
    for region in Region::ALL {
        let stem = match region {
            Region::All => "error_vs_seconds".to_string(),
            r => format!("error_vs_seconds_{}", r.name()),
        };
        chart(
            &a.out.join(format!("{stem}.png")),
            &format!(
                "RMSE against time (render + denoise), {}",
                region.describe()
            ),
            "seconds",
            "RMSE",
            &series(region, |r| r.total_s),
            AxisScale::Log,
            AxisScale::Log,
        )?;
    }
    let per_bin: Vec<(String, Vec<Metrics>)> = result
        .per_bin
        .iter()
        .map(|(m, b)| (m.to_string(), b.clone()))
        .collect();
    let max_spp = result.rows.iter().map(|r| r.spp).max().unwrap_or(0);
    write_per_bin(
        &a.out,
        "error_per_bin",
        &per_bin,
        &format!("per-bin RMSE at {max_spp} spp"),
    )?;
    reconstruction_plots(&a.out, &result)?;
    out.finish();
    super::util::say(format_args!("{md}"))?;
    say!("{}", wrote(&a.out, &files));
    Ok(())
}

/// The membership settings a sweep tries, and for each the value plotted on x.
fn sweep_methods(a: &SweepArgs) -> anyhow::Result<(Vec<(Method, f64)>, &'static str)> {
    let mut out = Vec::new();
    let tstat_flags = a.t2_max.is_some()
        || a.t2_patch.is_some()
        || a.emitter_radius.is_some()
        || a.depth_align.is_some();
    match a.method {
        MethodArg::Published => {
            ensure!(
                !tstat_flags,
                "--t2-max, --t2-patch, --emitter-radius and --depth-align belong to --method tstat"
            );
            let gammas = a.gamma.as_deref().unwrap_or("0.01,0.05,0.1,0.2");
            for g in float_list("--gamma", gammas)? {
                let t = Threshold::Gamma(g);
                t.validate()?;
                out.push((Method::Published(t), g));
            }
            Ok((out, "gamma"))
        }
        MethodArg::Tstat => {
            ensure!(
                a.gamma.is_none(),
                "--gamma sweeps the published filter: add --method published"
            );
            let radii: Vec<Option<usize>> = match &a.emitter_radius {
                None => vec![None],
                Some(l) => int_list("--emitter-radius", l, 0, i64::MAX)?
                    .into_iter()
                    .map(|r| Some(r as usize))
                    .collect(),
            };
            let aligns: Vec<bool> =
                split_list("--depth-align", a.depth_align.as_deref().unwrap_or("on"))?
                    .into_iter()
                    .map(|v| match v {
                        "on" => Ok(true),
                        "off" => Ok(false),
                        _ => Err(anyhow!("--depth-align {v}: use on, off or on,off")),
                    })
                    .collect::<anyhow::Result<_>>()?;
            let t2_patches = float_list("--t2-patch", a.t2_patch.as_deref().unwrap_or("1,1.5,2"))?;
            for t2_max in float_list("--t2-max", a.t2_max.as_deref().unwrap_or("4"))? {
                for &t2_patch in &t2_patches {
                    for &emitter_radius in &radii {
                        for &depth_align in &aligns {
                            let t = TstatParams {
                                t2_max,
                                t2_patch,
                                emitter_radius,
                                depth_align,
                                ..TstatParams::default()
                            };
                            t.validate()?;
                            out.push((Method::Tstat(t), t2_patch));
                        }
                    }
                }
            }
            Ok((out, "t2_patch"))
        }
    }
}

fn run_sweep_cmd(a: SweepArgs) -> anyhow::Result<()> {
    let files = ["sweep.csv", "sweep.md", "sweep.png"];
    let (methods, x_name) = sweep_methods(&a)?;
    let radii = radius_list("--radius", &a.radius)?;
    let rts = radius_list("--temporal-radius", &a.temporal_radius)?;
    let base = a.base.params()?;
    let mut args = vec![arg("--reference", &a.reference)];
    args.extend(a.bundles.iter().map(|b| arg("bundle", b)));
    let mut out = ReportDir::prepare("--out", &a.out, &files, |_| false, &args, a.force)?;
    let reference = load_volume(&a.reference)?;
    let cfg = SweepConfig {
        bundles: a.bundles.clone(),
        methods: methods.iter().map(|m| m.0).collect(),
        radii,
        temporal_radii: rts,
        base,
    };
    let pts = run_sweep(&cfg, &reference.volume, &|m| eprintln!("{m}"))?;
    let mut t = Table::new(&[
        "bundle",
        "transform",
        "spp",
        "method",
        "radius",
        "temporal_radius",
        "seconds",
        "rmse",
        "rmse/noisy",
        "rmse_light/noisy",
        "rmse_rest/noisy",
        "relmse",
    ]);
    let mut sorted = pts.clone();
    sorted.sort_by(|x, y| x.error.all.rmse.total_cmp(&y.error.all.rmse));
    for p in &sorted {
        t.push(vec![
            p.bundle.clone(),
            p.transform.clone(),
            p.spp.to_string(),
            p.method.describe(),
            p.radius.to_string(),
            p.temporal_radius.to_string(),
            format!("{:.2}", p.seconds),
            num(p.error.all.rmse),
            ratio(Some(p.error.all), Some(p.noisy.all)),
            ratio(p.error.light, p.noisy.light),
            ratio(p.error.rest, p.noisy.rest),
            num(p.error.all.relmse),
        ]);
    }
    out.create()?;
    write_text(&a.out.join("sweep.csv"), &t.csv())?;
    let md = format!(
        "# Sweep (sorted by RMSE, best first)\n\nRatios are to the noisy mean's RMSE over the same region: all voxels, pixels that see a light directly, the rest.\n\n{}",
        t.markdown()
    );
    write_text(&a.out.join("sweep.md"), &md)?;
    // One curve per bundle and setting other than the plotted one.
    let mut series: Vec<Series> = Vec::new();
    for p in &pts {
        let x = methods
            .iter()
            .find(|m| m.0 == p.method)
            .map(|m| m.1)
            .unwrap_or(0.0);
        let key = p.method.sweep_key();
        let name = Path::new(&p.bundle)
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let label = format!(
            "{}{}r={} rt={}",
            if cfg.bundles.len() > 1 {
                name
            } else {
                String::new()
            },
            match key {
                Method::Tstat(t) => format!(
                    " max={} re={} align={} ",
                    t.t2_max,
                    t.emitter_radius.map_or("auto".into(), |r| r.to_string()),
                    t.depth_align
                ),
                _ => " ".into(),
            },
            p.radius,
            p.temporal_radius
        );
        let y = p.error.all.rmse / p.noisy.all.rmse;
        match series.iter_mut().find(|s| s.label == label) {
            Some(s) => s.points.push((x, y)),
            None => series.push(Series {
                label,
                points: vec![(x, y)],
            }),
        }
    }
    chart(
        &a.out.join("sweep.png"),
        "denoised RMSE / noisy RMSE",
        x_name,
        "RMSE ratio",
        &series,
        if x_name == "gamma" {
            AxisScale::Log
        } else {
            AxisScale::Linear
        },
        AxisScale::Linear,
    )?;
    out.finish();
    super::util::say(format_args!("{md}"))?;
    say!("{}", wrote(&a.out, &files));
    Ok(())
}

/// Per reconstruction method: its error against time (render + denoise +
/// reconstruction) and against spp, one curve per capture method, and the
/// maximum-intensity projections (along depth) of the reference's, the noisy capture's
/// and the tstat-denoised capture's reconstructions at the lowest spp, side by side.
fn reconstruction_plots(dir: &Path, r: &ConvergenceResult) -> anyhow::Result<()> {
    use crate::viz::mip::{picture, project, side_by_side, Axis};
    let Some(grid) = r.reconstruction_grid else {
        return Ok(());
    };
    for (k, m) in r.reconstruction_methods.iter().enumerate() {
        let name = m.name();
        let median = convergence::reconstruction_seconds(&r.rows, k);
        let series = |x: &dyn Fn(&ResultRow, f64) -> f64| -> Vec<Series> {
            r.methods
                .iter()
                .map(|c| Series {
                    label: c.to_string(),
                    points: r
                        .rows
                        .iter()
                        .filter(|row| row.method == *c)
                        .map(|row| (x(row, median), row.reconstructions[k].error))
                        .collect(),
                })
                .collect()
        };
        chart(
            &dir.join(format!("reconstruction_{name}_error_vs_seconds.png")),
            &format!("{name} reconstruction: error against time (render + denoise + {name}, its median {median:.2} s)"),
            "seconds",
            "relative L2 error",
            &series(&|row, s| row.total_s + s),
            AxisScale::Log,
            AxisScale::Log,
        )?;
        chart(
            &dir.join(format!("reconstruction_{name}_error_vs_spp.png")),
            &format!("{name} reconstruction: error against samples per pixel"),
            "spp",
            "relative L2 error",
            &series(&|row, _| row.spp as f64),
            AxisScale::Log,
            AxisScale::Log,
        )?;
        let n = grid.n;
        let scale = (256 / n[0].max(n[1])).clamp(1, 32);
        let panels: Vec<_> = ["reference", "noisy", "tstat"]
            .iter()
            .filter_map(|label| r.reconstruction_volumes.iter().find(|v| v.0 == *label))
            .map(|(_, v)| picture(&project(&v[k], n, Axis::Z), scale))
            .collect();
        let (w, h, px) = side_by_side(&panels, 4);
        let path = dir.join(format!("reconstruction_{name}_mip.png"));
        crate::report::plot::save_png_rgb(&path, &px, w, h)
            .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    }
    Ok(())
}
