//! The `tstat` command: parses flags and hands a plain configuration to the library.
//! Errors are one line on stderr: exit 2 for usage errors (clap's, with its usage text
//! after the first line), 1 for everything else.

use clap::Parser;

fn main() {
    let cli = match tstat::cli::Cli::try_parse() {
        Ok(cli) => cli,
        // --help, --version, and the help printed when no subcommand is given.
        Err(e)
            if !e.use_stderr()
                || e.kind() == clap::error::ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand =>
        {
            e.exit()
        }
        Err(e) => {
            eprint!("{}", tstat::cli::usage_error(&e));
            std::process::exit(2);
        }
    };
    if let Err(e) = tstat::cli::run(cli) {
        eprintln!("{}", tstat::cli::error_line(&e));
        std::process::exit(1);
    }
}
