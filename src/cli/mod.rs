//! Command-line interface: one file per subcommand.

mod denoise;
mod export;
mod info;
mod render;
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
    /// Render a scene transiently and write its statistics bundle.
    Render(render::RenderArgs),
    /// Denoise a bundle with the statistical spatio-temporal filter.
    Denoise(denoise::DenoiseArgs),
    /// Write the noisy mean volume and/or the steady image of a bundle.
    Export(export::ExportArgs),
    /// Print a bundle's manifest.
    Info(info::InfoArgs),
}

pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Render(a) => render::run(a),
        Command::Denoise(a) => denoise::run(a),
        Command::Export(a) => export::run(a),
        Command::Info(a) => info::run(a),
    }
}
