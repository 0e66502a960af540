//! `videt init`: auto-initialization of the rig (paper section 4.3) — wind each wire in turn
//! with the empty thimble connected, measure the base triangle, write the calibration.

use std::path::Path;
use std::process::ExitCode;
use std::sync::atomic::AtomicBool;

use clap::Args;
use videt_config::calibration::{backup_path, Calibration, CalibrationError, TensionCalibration};
use videt_config::Config;

use super::device::{DeviceArgs, Exit, EXIT_CALIBRATION_WRITE, EXIT_CODES_HELP};
use super::motors::{on_motors, MotorJob};
use super::ToolResult;
use videt_service::init::commission::CommissionTechnician;
use videt_service::init::remote::ProcedureDevice;
use videt_service::init::runner::Runner;
use videt_service::init::session::{self, run_settings, FlowContext, InitOutcome, Technician};
use videt_service::init::tension::TensionTechnician;

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

/// A motor-driving flow of the rig's calibration.
#[derive(Debug, Clone, Copy)]
pub enum Flow {
    /// `videt init`.
    Initialize,
    /// `videt wire replace N`: the new yarn must be usable to `required_m`.
    ReplaceWire {
        /// The wire.
        wire: usize,
        /// Usable length the workspace needs, metres.
        required_m: f64,
    },
}

/// A flow run as a [`MotorJob`].
struct FlowJob<'a> {
    flow: Flow,
    config: &'a Config,
    /// The file the calibration goes to (named by failure messages).
    calibration_path: &'a Path,
}

impl MotorJob for FlowJob<'_> {
    type Output = InitOutcome;

    fn run<H, T>(
        &mut self,
        hw: &mut H,
        tech: &mut T,
        runner: &mut Runner,
        source: &'static str,
        stop: &AtomicBool,
    ) -> Result<InitOutcome, Exit>
    where
        H: ProcedureDevice,
        T: Technician<H> + TensionTechnician<H> + CommissionTechnician<H>,
    {
        let ctx = FlowContext {
            config: self.config,
            source,
            stop,
        };
        match self.flow {
            Flow::Initialize => session::initialize(hw, tech, runner, &ctx),
            Flow::ReplaceWire { wire, required_m } => {
                session::replace_wire(hw, tech, runner, &ctx, wire, required_m)
            }
        }
        .map_err(|e| {
            Exit::new(
                e.exit_code(),
                e.name(),
                session::failure_message(&e, self.calibration_path),
            )
        })
    }
}

/// Lock the motors, run `flow` on the twin (`--sim`, whose technician fits yarns of
/// `sim_new_wire_length_m` when given) or on the device with the technician at the terminal,
/// save the calibration on success, report. Shared by `init` and `wire replace`.
pub fn run_flow(
    device: &DeviceArgs,
    config: &Config,
    sim_new_wire_length_m: Option<f64>,
    flow: Flow,
) -> Result<ExitCode, Exit> {
    let calibration_path = device.calibration_path(config);
    // Check every argument before touching anything.
    let mut setup = device.twin_setup(config)?;
    if let Some(l) = sim_new_wire_length_m {
        setup.new_wire_length_m = l;
    }
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
    let outcome = on_motors(
        device,
        config,
        &setup,
        runner,
        &mut FlowJob {
            flow,
            config,
            calibration_path: &calibration_path,
        },
    )?;
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
    request: &videt_service::socket::ProcedureRequest,
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
                videt_service::socket::ProcedureCommand::Init,
                None,
                None,
            )?;
            return run_through_service(device, &socket, &request);
        }
        run_flow(device, &config, None, Flow::Initialize)
    });
    Ok(result.unwrap_or_else(|e| e.report(device.json)))
}
