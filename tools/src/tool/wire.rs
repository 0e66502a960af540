//! `videt wire replace N`: guided wire replacement — release the wire, wait while the new yarn
//! is fitted, re-home it, check its usable length against the workspace, re-initialize.

use std::process::ExitCode;

use clap::{Args, Subcommand};
use videt_config::calibration::Calibration;

use super::device::{DeviceArgs, Exit, EXIT_CODES_HELP, EXIT_USAGE};
use super::init::{run_flow, Flow};
use super::ToolResult;
use videt_service::init::session::{self, InitError};

/// Wire subcommands.
#[derive(Debug, Subcommand)]
pub enum WireCommand {
    /// Replace wire N (0, 1 or 2): release it, fit the new yarn, home it, check its length,
    /// re-run auto-initialization and write the calibration.
    Replace(ReplaceArgs),
}

/// Arguments of `videt wire replace`.
#[derive(Debug, Args)]
#[command(after_help = EXIT_CODES_HELP)]
pub struct ReplaceArgs {
    /// The wire to replace: 0, 1 or 2.
    #[arg(value_name = "N")]
    pub wire: usize,
    /// On the twin: usable length of the new yarn, metres (rehearse a yarn that is too short).
    #[arg(long, value_name = "METRES", requires = "sim")]
    pub sim_new_wire_length: Option<f64>,
    /// Device, twin, files and output options.
    #[command(flatten)]
    pub device: DeviceArgs,
}

/// Run a wire subcommand.
pub fn run(command: &WireCommand) -> ToolResult {
    match command {
        WireCommand::Replace(args) => {
            Ok(replace(args).unwrap_or_else(|e| e.report(args.device.json)))
        }
    }
}

fn replace(args: &ReplaceArgs) -> Result<ExitCode, Exit> {
    let device = &args.device;
    if args.wire > 2 {
        let e = InitError::NoSuchWire(args.wire);
        return Err(Exit::new(EXIT_USAGE, e.name(), e.to_string()));
    }
    let mut config = device.load_config()?;
    if let Some(l) = args.sim_new_wire_length {
        if !(l.is_finite() && l > 0.0 && l <= 5.0) {
            return Err(Exit::new(
                EXIT_USAGE,
                "usage",
                format!("--sim-new-wire-length {l}: must be in (0, 5] metres"),
            ));
        }
    }
    if let Some(socket) = device.running_service(&config) {
        // The service releases the wire, waits for the technician, re-homes and re-initializes
        // on its own hardware; it says how long the new yarn must be.
        let request = device.service_request(
            &config,
            videt_service::socket::ProcedureCommand::WireReplace,
            u8::try_from(args.wire).ok(),
            args.sim_new_wire_length,
        )?;
        return super::init::run_through_service(device, &socket, &request);
    }
    let current = Calibration::load(&device.calibration_path(&config)).ok();
    let required_m = session::required_wire_length_m(&config, current.as_ref());
    eprintln!(
        "videt: replacing wire {}: a new yarn must be usable to at least {:.0} mm",
        args.wire,
        required_m * 1e3
    );
    let new_length = args.sim_new_wire_length;
    if let Some(l) = new_length {
        // Winding a long new yarn back must not count as a runaway.
        config.autoinit.max_wind_travel_m = config.autoinit.max_wind_travel_m.max(l + 0.1);
    }
    run_flow(
        device,
        &config,
        new_length,
        Flow::ReplaceWire {
            wire: args.wire,
            required_m,
        },
    )
}
