//! `videt` — the technician's and researcher's tool: configuration checks, calibration, wire
//! replacement, analysis and demos. `videt --help` and `videt <subcommand> --help` describe each;
//! the command line is `videt_tools::cli::Cli`.

use std::process::ExitCode;

use clap::{CommandFactory, FromArgMatches};
use videt_tools::cli::Cli;

/// What `videt --version` says it was built with.
#[cfg(feature = "v4l")]
const FEATURES: &str = "v4l; with V4L2 capture";
#[cfg(not(feature = "v4l"))]
const FEATURES: &str = "none; without V4L2 capture";

fn main() -> ExitCode {
    let matches = Cli::command()
        .version(videt_build_info::version(FEATURES))
        .get_matches();
    let cli = Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    match cli.run() {
        Ok(code) => code,
        Err(e) => {
            eprintln!("videt: {e}");
            ExitCode::FAILURE
        }
    }
}
