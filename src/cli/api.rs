//! The command line as library calls, for the Python package (`python/`): a command run
//! in-process from its arguments, and the render job a `tstat render` command line
//! describes. The package builds the arguments from its keywords, so its checks and
//! messages are the command line's, word for word.

use super::{render, usage_error, Cli, Command};
use crate::job::RenderJob;
use crate::scene::Scene;
use clap::Parser;

/// Parses a command line (without the program's name). A usage error becomes an error
/// of its first line ("error: unexpected argument '--foo' found").
pub fn parse(argv: &[String]) -> anyhow::Result<Cli> {
    let args = std::iter::once("tstat".to_string()).chain(argv.iter().cloned());
    Cli::try_parse_from(args).map_err(|e| {
        let text = usage_error(&e);
        let first = text.lines().next().unwrap_or_default();
        anyhow::anyhow!("{}", first.trim_start_matches("error: "))
    })
}

/// Runs a command in-process, as `tstat ARGV...` would.
pub fn run_command(argv: &[String]) -> anyhow::Result<()> {
    super::run(parse(argv)?)
}

/// The scene and job of a `render SCENE --out DIR ...` command line, checked and
/// loaded as `tstat render` does before rendering.
pub fn render_job(argv: &[String]) -> anyhow::Result<(Scene, RenderJob)> {
    match parse(argv)?.command {
        Command::Render(a) => render::prepare(&a),
        _ => anyhow::bail!("not a render command line"),
    }
}
