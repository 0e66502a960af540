//! `videt tension-calibrate N --mass-kg M`: two-point calibration of wire N's strain gauge
//! with a known weight (on the twin, the simulated technician hangs it).

use std::process::ExitCode;
use std::time::{SystemTime, UNIX_EPOCH};

use clap::Args;
use videt_hal::{Lifecycle, WireDrives};
use videt_rt_config::calibration::TensionCalibration;

use super::device::{stop_on_signals, DeviceArgs, Exit, EXIT_CALIBRATION_WRITE, EXIT_USAGE};
use super::ToolResult;
use crate::init::runner::Runner;
use crate::init::session::{self, failure_exit_code, run_settings};
use crate::init::tension::{calibrate_tension, TensionCalibrationError};
use crate::init::twin::{rest_twin, SimTechnician};

/// Arguments of `videt tension-calibrate`.
#[derive(Debug, Args)]
#[command(
    after_help = "The result goes to tension-calibration.toml beside the calibration file (previous kept as .bak): \
a corrected tension is (reading - offset_n) * gain. Exit codes: 0 done; 2 bad arguments; 3 no device backend; \
10 e-stop; 17 drive fault; 18 sensor fault; 20 cancelled; 23 motors in use; 24 file not written; \
26 the weight did not change the reading plausibly."
)]
pub struct TensionCalibrateArgs {
    /// The wire whose sensor to calibrate: 0, 1 or 2.
    #[arg(value_name = "N")]
    pub wire: usize,
    /// The known weight, kg (0.05 to 1.5).
    #[arg(long, value_name = "KG")]
    pub mass_kg: f64,
    /// Device, twin, files and output options.
    #[command(flatten)]
    pub device: DeviceArgs,
}

/// Run `videt tension-calibrate`.
pub fn run(args: &TensionCalibrateArgs) -> ToolResult {
    Ok(calibrate(args).unwrap_or_else(|e| e.report(args.device.json)))
}

fn calibrate(args: &TensionCalibrateArgs) -> Result<ExitCode, Exit> {
    let device = &args.device;
    let config = device.load_config()?;
    let path = TensionCalibration::path_beside(&device.calibration_path(&config));
    let setup = device.twin_setup(&config)?;
    let _lock = device.lock_motors(&config)?;
    if !device.sim {
        return Err(device.no_backend());
    }
    let mut twin = rest_twin(&config, &setup);
    let mut tech = SimTechnician::new(&setup);
    tech.echo = true;
    let mut runner = Runner::new(run_settings(&config));
    let stop = stop_on_signals();
    session::start(&mut twin).map_err(|e| Exit::new(e.exit_code(), e.name(), e.to_string()))?;
    let result = calibrate_tension(
        &mut twin,
        &mut tech,
        &mut runner,
        args.wire,
        args.mass_kg,
        &stop,
    );
    let _ = twin.disable();
    let _ = twin.deactivate();
    let point = result.map_err(|e| match &e {
        TensionCalibrationError::Device(f) => {
            Exit::new(failure_exit_code(f), f.name(), e.to_string())
        }
        TensionCalibrationError::Implausible { .. } => Exit::new(26, "implausible", e.to_string()),
        TensionCalibrationError::Usage(_) => Exit::new(EXIT_USAGE, "usage", e.to_string()),
    })?;
    let mut file = TensionCalibration::load(&path).unwrap_or_default();
    file.offset_n[args.wire] = point.offset_n;
    file.gain[args.wire] = point.gain;
    file.calibrated_unix_s[args.wire] = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    file.save(&path)
        .map_err(|e| Exit::new(EXIT_CALIBRATION_WRITE, "calibration-write", e.to_string()))?;
    if device.json {
        println!(
            "{}",
            serde_json::json!({"wire": args.wire, "offset_n": point.offset_n, "gain": point.gain})
        );
    } else {
        println!(
            "wire {}: offset {:+.4} N, gain {:.5} (reading {:.4} N under {:.4} N); written to {}",
            args.wire,
            point.offset_n,
            point.gain,
            point.loaded_reading_n,
            args.mass_kg * 9.806_65,
            path.display()
        );
    }
    Ok(ExitCode::SUCCESS)
}
