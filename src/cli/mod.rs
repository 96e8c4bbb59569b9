//! Command-line interface: one file per subcommand.

mod denoise;
mod export;
mod frames;
mod info;
mod merge;
mod render;
mod report;
mod run;
pub mod util;

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
}

pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Run(a) => run::run(a),
        Command::Render(a) => render::run(a),
        Command::Denoise(a) => denoise::run(a),
        Command::Export(a) => export::run(a),
        Command::Frames(a) => frames::run(a),
        Command::Info(a) => info::run(a),
        Command::Merge(a) => merge::run(a),
        Command::Report(a) => report::run(a),
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
}
