//! `videt config check FILE`: validate a configuration (ranges, the drives' units against the
//! device description it names, what the configured CAN bus can carry, whether the tension
//! loop is stable on the configured sensor) and print the drives' torque resolution, the bus
//! load, the sensor's timing and the loop's margins, and the resolved settings.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Subcommand;
use videt_rt_config::Config;

use super::ToolResult;

/// Configuration subcommands.
#[derive(Debug, Subcommand)]
pub enum ConfigCommand {
    /// Validate FILE; on success print the resolved settings (defaults filled in) as TOML.
    Check {
        /// The configuration file (e.g. /etc/videt/videt.toml).
        file: PathBuf,
    },
}

/// Run a configuration subcommand.
pub fn run(command: &ConfigCommand) -> ToolResult {
    match command {
        ConfigCommand::Check { file } => {
            let config = Config::load(file)?;
            videt_assembly::bus_budget::check(&config)?;
            videt_runtime::tension_budget::plan(&config)?;
            let resolved = toml::to_string_pretty(&config)?;
            println!(
                "# {}: valid\n# {}\n# {}\n# {}\n{resolved}",
                file.display(),
                videt_assembly::bus_budget::describe(&config),
                videt_runtime::tension_budget::describe(&config),
                config.describe_drive_units(),
            );
            Ok(ExitCode::SUCCESS)
        }
    }
}
