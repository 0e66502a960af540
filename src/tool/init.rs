//! `videt init`: auto-initialization of the rig (paper section 4.3) — wind each wire in turn
//! with the empty thimble connected, measure the base triangle, write the calibration.

use std::path::Path;
use std::process::ExitCode;
use std::sync::atomic::AtomicBool;

use clap::Args;
use videt_hal::{Lifecycle, WireDrives};
use videt_rt_config::calibration::{
    backup_path, Calibration, CalibrationError, TensionCalibration,
};
use videt_rt_config::Config;

use super::device::{stop_on_signals, DeviceArgs, Exit, EXIT_CALIBRATION_WRITE, EXIT_CODES_HELP};
use super::ToolResult;
use crate::init::runner::Runner;
use crate::init::session::{self, run_settings, FlowContext, InitError, InitOutcome};
use crate::init::twin::{rest_twin, SimTechnician};

/// Arguments of `videt init`.
#[derive(Debug, Args)]
#[command(after_help = EXIT_CODES_HELP)]
pub struct InitArgs {
    /// Device, twin, files and output options.
    #[command(flatten)]
    pub device: DeviceArgs,
}

/// The exact JSON `videt init --json` prints:
/// `{"sides_m": [d01, d02, d12], "guides_m": [[x, y, z], ...], "residuals_m": [..]}`.
pub fn result_json(c: &Calibration) -> String {
    let list = |v: &[f64]| {
        let items: Vec<String> = v.iter().map(|x| json_number(*x)).collect();
        format!("[{}]", items.join(", "))
    };
    let guides: Vec<String> = c.guides_m.iter().map(|g| list(g)).collect();
    format!(
        "{{\"sides_m\": {}, \"guides_m\": [{}], \"residuals_m\": {}}}",
        list(&c.sides_m),
        guides.join(", "),
        list(&c.residuals_m)
    )
}

/// A finite number as JSON (Rust's shortest round-trip form; `-0` as `0`).
fn json_number(x: f64) -> String {
    if x == 0.0 {
        "0.0".into()
    } else if x.is_finite() {
        format!("{x:?}")
    } else {
        "null".into()
    }
}

/// A human summary of a calibration.
pub fn summary(c: &Calibration, path: &Path) -> String {
    let mm = |x: f64| x * 1e3;
    let max_res = c.residuals_m.iter().fold(0.0_f64, |a, r| a.max(r.abs()));
    let g = &c.guides_m;
    format!(
        "base triangle: d01 = {:.2} mm, d02 = {:.2} mm, d12 = {:.2} mm (largest residual {:.3} mm)\n\
         guide points (paper's frame): x0 = ({:.2}, {:.2}, 0) mm, x1 = ({:.2}, {:.2}, 0) mm, x2 = ({:.2}, {:.2}, 0) mm\n\
         workspace ({:.1} N towards the frame, condition <= {:.0}): {:.2} litres, x {:.0}..{:.0} mm, y {:.0}..{:.0} mm, z {:.0}..{:.0} mm\n\
         wires must be usable to {:.0}, {:.0}, {:.0} mm\n\
         encoder zeros: {:?} counts\n\
         calibration written to {} (previous kept as {})",
        mm(c.sides_m[0]), mm(c.sides_m[1]), mm(c.sides_m[2]), mm(max_res),
        mm(g[0][0]), mm(g[0][1]), mm(g[1][0]), mm(g[1][1]), mm(g[2][0]), mm(g[2][1]),
        c.workspace.force_n, c.workspace.max_condition, c.workspace.volume_m3 * 1e3,
        mm(c.workspace.min_m[0]), mm(c.workspace.max_m[0]), mm(c.workspace.min_m[1]),
        mm(c.workspace.max_m[1]), mm(c.workspace.min_m[2]), mm(c.workspace.max_m[2]),
        mm(c.workspace.required_length_m[0]), mm(c.workspace.required_length_m[1]),
        mm(c.workspace.required_length_m[2]),
        c.wire_zero_counts,
        path.display(),
        backup_path(path).display()
    )
}

/// What a motor-driving flow does once the hardware is up.
pub type Flow<'a, H, T> =
    dyn FnMut(&mut H, &mut T, &mut Runner, &FlowContext<'_>) -> Result<InitOutcome, InitError> + 'a;

/// Lock the motors, run `flow` on the twin (or report that no device backend is built in),
/// save the calibration on success, report. Shared by `init` and `wire replace`.
pub fn run_flow(
    device: &DeviceArgs,
    config: &Config,
    flow: &mut Flow<'_, videt_sim::Twin, SimTechnician>,
) -> Result<ExitCode, Exit> {
    let calibration_path = device.calibration_path(config);
    // Check every argument before touching anything.
    let setup = device.twin_setup(config)?;
    let _lock = device.lock_motors(config)?;
    if !device.sim {
        return Err(device.no_backend());
    }
    let mut twin = rest_twin(config, &setup);
    let mut tech = SimTechnician::new(&setup);
    tech.echo = true;
    let mut runner = Runner::new(run_settings(config));
    // The strain gauges' own calibration, when `videt tension-calibrate` wrote one.
    let tension_path = TensionCalibration::path_beside(&calibration_path);
    match TensionCalibration::load(&tension_path) {
        Ok(tc) => {
            eprintln!(
                "videt: tension readings corrected with {}",
                tension_path.display()
            );
            runner.set_tension_correction(Some(tc));
        }
        Err(CalibrationError::Missing { .. }) => {}
        Err(e) => eprintln!("videt: tension readings not corrected: {e}"),
    }
    let stop = stop_on_signals();
    let stop: &AtomicBool = &stop;
    let ctx = FlowContext {
        config,
        source: "twin",
        stop,
    };
    let result =
        session::start(&mut twin).and_then(|()| flow(&mut twin, &mut tech, &mut runner, &ctx));
    let _ = twin.disable();
    let _ = twin.deactivate();
    let outcome = result.map_err(|e| {
        Exit::new(
            e.exit_code(),
            e.name(),
            session::failure_message(&e, &calibration_path),
        )
    })?;
    outcome.calibration.save(&calibration_path).map_err(|e| {
        Exit::new(
            EXIT_CALIBRATION_WRITE,
            "calibration-write",
            format!("the rig was measured but the calibration could not be written: {e}"),
        )
    })?;
    Ok(print_result(
        device,
        &outcome.calibration,
        &calibration_path,
    ))
}

/// Print a written calibration: the JSON document with `--json`, else the summary.
pub fn print_result(device: &DeviceArgs, calibration: &Calibration, path: &Path) -> ExitCode {
    if device.json {
        println!("{}", result_json(calibration));
    } else {
        println!("{}", summary(calibration, path));
    }
    ExitCode::SUCCESS
}

/// Run a procedure in the service answering on `socket` (its own hardware) and print the
/// result as a direct run does.
pub fn run_through_service(
    device: &DeviceArgs,
    socket: &Path,
    request: &crate::socket::ProcedureRequest,
) -> Result<ExitCode, Exit> {
    let done = super::through_service::run(socket, request)?;
    Ok(print_result(device, &done.calibration, &done.path))
}

/// Run `videt init`: in the running service when its control socket answers, else directly.
pub fn run(args: &InitArgs) -> ToolResult {
    let device = &args.device;
    let result = device.load_config().and_then(|config| {
        if let Some(socket) = device.running_service(&config) {
            let request = device.service_request(
                &config,
                crate::socket::ProcedureCommand::Init,
                None,
                None,
            )?;
            return run_through_service(device, &socket, &request);
        }
        run_flow(device, &config, &mut |hw, tech, runner, ctx| {
            session::initialize(hw, tech, runner, ctx)
        })
    });
    Ok(result.unwrap_or_else(|e| e.report(device.json)))
}
