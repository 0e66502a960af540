//! `videt` — the technician's and researcher's tool: configuration checks, calibration, wire
//! replacement, analysis and demos. `videt --help` and `videt <subcommand> --help` describe each.

use std::process::ExitCode;

use clap::{Parser, Subcommand};
use videt::tool;

/// VIDET tool: calibration, wire replacement, analysis and demos.
#[derive(Debug, Parser)]
#[command(name = "videt", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Configuration files: check one and print the resolved settings.
    #[command(subcommand)]
    Config(tool::config::ConfigCommand),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match &cli.command {
        Command::Config(c) => tool::config::run(c),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("videt: {e}");
            ExitCode::FAILURE
        }
    }
}
