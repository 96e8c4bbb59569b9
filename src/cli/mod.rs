//! Command-line interface: one file per subcommand.

/// `println!` that returns an error instead of panicking when stdout fails (see
/// [`util::say`]); use inside functions returning `anyhow::Result`.
macro_rules! say {
    ($($arg:tt)*) => {
        $crate::cli::util::say(format_args!("{}\n", format_args!($($arg)*)))?
    };
}

mod adaptive;
pub mod api;
mod check;
mod cluster;
mod denoise;
mod export;
mod frames;
mod info;
mod merge;
mod nlos;
mod progress;
mod render;
mod report;
mod run;
pub mod util;
mod view;

use clap::{Parser, Subcommand};

#[derive(Parser, Debug)]
#[command(
    name = "tstat",
    version,
    about = "Statistical transient rendering and denoising"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// The whole job: render, denoise, and write volumes, frames, a GIF and a streak image.
    Run(run::RunArgs),
    /// Render a scene transiently and write its statistics bundle.
    Render(render::RenderArgs),
    /// Denoise a bundle with the statistical spatio-temporal filter.
    Denoise(denoise::DenoiseArgs),
    /// Write the noisy mean volume and/or the steady image of a bundle.
    Export(export::ExportArgs),
    /// Error against a reference, speed against error, parameter sweeps.
    Report(report::ReportArgs),
    /// Tone-mapped PNG frames, an animated GIF and a streak image of a volume.
    Frames(frames::FramesArgs),
    /// Merge bundles of the same scene and settings rendered with different seeds.
    Merge(merge::MergeArgs),
    /// Print a bundle's manifest.
    Info(info::InfoArgs),
    /// List every unsupported feature of Mitsuba scenes (file:line), or "ok".
    Check(check::CheckArgs),
    /// Recipes that run one render's shards on Slurm or Kubernetes, then merge them.
    Cluster(cluster::ClusterArgs),
    /// One self-contained HTML page to look at a volume: time slider, side-by-side
    /// volumes, a pixel's transient with its confidence band.
    View(view::ViewArgs),
    /// NLOS captures: reconstruct the hidden scene.
    Nlos(nlos::NlosArgs),
}

pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Run(a) => run::run(a),
        Command::Render(a) => render::run(a),
        Command::Check(a) => check::run(a),
        Command::Cluster(a) => cluster::run(a),
        Command::View(a) => view::run(a),
        Command::Nlos(a) => nlos::run(a),
        Command::Denoise(a) => denoise::run(a),
        Command::Export(a) => export::run(a),
        Command::Frames(a) => frames::run(a),
        Command::Info(a) => info::run(a),
        Command::Merge(a) => merge::run(a),
        Command::Report(a) => report::run(a),
    }
}

/// One error as the user sees it: `error: ` and a single line (a message that spans
/// lines is joined with "; ").
pub fn error_line(e: &anyhow::Error) -> String {
    let text = format!("{e:#}");
    let parts: Vec<&str> = text
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect();
    format!("error: {}", parts.join("; "))
}

/// A clap usage error with its first paragraph on one line (e.g. "error: the following
/// required arguments were not provided: --out <OUT>, <SCENE>" or "error: invalid value
/// 'x' for '--pixel-sampling <PIXEL_SAMPLING>' [possible values: stratified,
/// independent]"), then clap's usage and hints as it prints them.
pub fn usage_error(e: &clap::Error) -> String {
    let text = e.render().to_string();
    let mut paragraphs = text.splitn(2, "\n\n");
    let first = paragraphs.next().unwrap_or_default();
    let mut lines = first.lines().map(str::trim).filter(|l| !l.is_empty());
    let mut head = lines
        .next()
        .unwrap_or("error: invalid arguments")
        .to_string();
    for l in lines {
        head.push(' ');
        head.push_str(l);
    }
    match paragraphs.next() {
        Some(rest) => format!("{head}\n\n{rest}"),
        None => format!("{head}\n"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn the_command_line_definition_is_consistent() {
        Cli::command().debug_assert();
    }

    #[test]
    fn usage_errors_start_with_one_clear_line() {
        let first = |args: &[&str]| {
            let e = Cli::try_parse_from(args).unwrap_err();
            usage_error(&e).lines().next().unwrap().to_string()
        };
        assert_eq!(
            first(&["tstat", "render"]),
            "error: the following required arguments were not provided: --out <OUT> <SCENE>"
        );
        assert!(first(&["tstat", "render", "s.xml", "--out", "o", "--pixel-sampling", "x"])
            .contains("'x' for '--pixel-sampling <PIXEL_SAMPLING>' [possible values: stratified, independent, sobol]"));
    }

    /// The library's typed errors expose no `source()`: `error_line` prints the chain
    /// (`{:#}`), and each message already says its cause, once, wrapped through the
    /// layers as it is.
    #[test]
    fn library_errors_say_their_cause_once() {
        use crate::bundle::{shard::ShardError, BundleError, Problem};
        let line = |e: anyhow::Error| error_line(&e);
        let io = || BundleError::io("out.npy", std::io::Error::other("disk full"));
        assert_eq!(line(io().into()), "error: out.npy: disk full");
        let unreadable = || {
            BundleError::invalid(
                "b.tstats",
                Problem::Unreadable(std::io::Error::other("gone").into()),
            )
        };
        let want = "error: b.tstats: invalid bundle: cannot read: gone";
        assert_eq!(line(unreadable().into()), want);
        assert_eq!(
            line(crate::report::ReportError::from(unreadable()).into()),
            want
        );
        assert_eq!(
            line(crate::nlos::NlosError::from(unreadable()).into()),
            want
        );
        assert_eq!(
            line(crate::viz::VizError::from(io()).into()),
            "error: out.npy: disk full"
        );
        let shard = BundleError::from(ShardError::Count { spec: "1/0".into() });
        assert_eq!(
            line(shard.into()),
            "error: --shard 1/0: the number of shards must be from 1 to 2^32"
        );
    }
}
