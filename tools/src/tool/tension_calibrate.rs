//! `videt tension-calibrate N --mass-kg M`: two-point calibration of wire N's strain gauge
//! with a known weight (on the twin, the simulated technician hangs it).

use std::process::ExitCode;
use std::sync::atomic::AtomicBool;
use std::time::{SystemTime, UNIX_EPOCH};

use clap::Args;
use videt_config::calibration::TensionCalibration;

use super::device::{DeviceArgs, Exit, EXIT_CALIBRATION_WRITE, EXIT_MOTORS_BUSY, EXIT_USAGE};
use super::motors::{on_motors, MotorJob};
use super::ToolResult;
use videt_service::init::commission::CommissionTechnician;
use videt_service::init::remote::ProcedureDevice;
use videt_service::init::runner::Runner;
use videt_service::init::session::{failure_exit_code, run_settings, Technician};
use videt_service::init::tension::{
    calibrate_tension, check_arguments, TensionCalibrationError, TensionPoint, TensionTechnician,
};

/// Exit code when the weight did not change the reading as a weight should.
const EXIT_IMPLAUSIBLE: u8 = 26;

/// Arguments of `videt tension-calibrate`.
#[derive(Debug, Args)]
#[command(
    after_help = "The result goes to tension-calibration.toml beside the calibration file (previous kept as .bak): \
a corrected tension is (reading - offset_n) * gain. On the device, stop videtd first; the tool prompts each step \
(release and unload the wire, hang the weight, take it off) and waits for Enter while the motors hold the wires; \
videtd applies the result when it starts. Exit codes: 0 done; 2 bad arguments; 3 no device backend; \
10 e-stop; 17 drive fault; 18 sensor fault; 20 cancelled (or no terminal to prompt, without --yes); \
22 the device could not be opened or started; 23 motors in use (videtd running); 24 file not written; \
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

/// The calibration of one wire's sensor as a [`MotorJob`].
struct TensionJob {
    wire: usize,
    mass_kg: f64,
}

impl MotorJob for TensionJob {
    type Output = TensionPoint;

    fn run<H, T>(
        &mut self,
        hw: &mut H,
        tech: &mut T,
        runner: &mut Runner,
        _source: &'static str,
        stop: &AtomicBool,
    ) -> Result<TensionPoint, Exit>
    where
        H: ProcedureDevice,
        T: Technician<H> + TensionTechnician<H> + CommissionTechnician<H>,
    {
        calibrate_tension(hw, tech, runner, self.wire, self.mass_kg, stop).map_err(|e| match &e {
            TensionCalibrationError::Device(f) => {
                Exit::new(failure_exit_code(f), f.name(), e.to_string())
            }
            TensionCalibrationError::Implausible { .. } => {
                Exit::new(EXIT_IMPLAUSIBLE, "implausible", e.to_string())
            }
            TensionCalibrationError::Usage(_) => Exit::new(EXIT_USAGE, "usage", e.to_string()),
        })
    }
}

fn calibrate(args: &TensionCalibrateArgs) -> Result<ExitCode, Exit> {
    let device = &args.device;
    let config = device.load_config()?;
    let path = TensionCalibration::path_beside(&device.calibration_path(&config));
    let setup = device.twin_setup(&config)?;
    check_arguments(args.wire, args.mass_kg)
        .map_err(|e| Exit::new(EXIT_USAGE, "usage", e.to_string()))?;
    if !device.sim && device.running_service(&config).is_some() {
        return Err(Exit::new(
            EXIT_MOTORS_BUSY,
            "motors-busy",
            "videtd is running and holds the motors: stop it (systemctl stop videtd), calibrate, \
             then start it again; it reads the new tension calibration when it starts",
        ));
    }
    // The readings are calibrated raw: no earlier correction applies.
    let runner = Runner::new(run_settings(&config));
    let point = on_motors(
        device,
        &config,
        &setup,
        runner,
        &mut TensionJob {
            wire: args.wire,
            mass_kg: args.mass_kg,
        },
    )?;
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
