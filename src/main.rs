//! The `tstat` command: parses flags and hands a plain configuration to the library.

use clap::Parser;

fn main() {
    let cli = tstat::cli::Cli::parse();
    if let Err(e) = tstat::cli::run(cli) {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
