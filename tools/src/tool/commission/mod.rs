//! `videt commission`: the guided check of a newly assembled rig, thimble detached — the
//! computer's real-time set-up, each drive, tension sensor and the e-stop, the vibrotactors —
//! each step PASS, FAIL (with the configuration key and value that fix it, or the wiring to
//! change) or SKIPPED, and what it measured. `--write FILE` writes the configuration with the
//! fixes into FILE.

pub mod cameras;
pub mod computer;

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::AtomicBool;

use clap::{Args, ValueEnum};
use videt_config::edit::{apply_fixes, Fix};
use videt_config::Config;
use videt_service::drive_report::drive_statuses;
use videt_service::init::commission::{
    check_rig, identity_steps, CommissionTechnician, RigCheck, StepReport, Thimble, Verdict,
};
use videt_service::init::remote::ProcedureDevice;
use videt_service::init::runner::Runner;
use videt_service::init::session::{run_settings, Technician};
use videt_service::init::tension::TensionTechnician;
use videt_service::socket::ProcedureCommand;

use super::device::{DeviceArgs, Exit, DEFAULT_CONFIG, EXIT_CALIBRATION_WRITE, EXIT_MOTORS_BUSY};
use super::motors::{on_motors, MotorJob};
use super::ToolResult;

/// Exit code when the check found a mistake (each failing step names its fix).
pub const EXIT_MISTAKES: u8 = 27;

/// The parts of the check.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Part {
    /// The computer: PREEMPT_RT, the control CPU, memory-lock and priority limits, the CAN
    /// interface.
    Computer,
    /// The rig: the e-stop, each drive, encoder and tension sensor.
    Rig,
    /// The three vibrotactors, each pulsed in turn for the technician to feel.
    Vibrotactors,
    /// The cameras: frame size and rate against the stereo calibration, left and right.
    Cameras,
}

/// Arguments of `videt commission`.
#[derive(Debug, Args)]
#[command(
    after_help = "Run it on a newly assembled rig with the thimble detached and every wire \
resting against its ring. The rig part asks the technician to release and press the e-stop and to pull \
each wire out to a mark; its motors get at most the torque holding commission.test_tension_n. On any \
failure or Ctrl-C every motor is left without torque and the drives disabled. While videtd runs, its \
control thread runs the rig part on its motors (as videt init does): the technician takes the thimble \
off first and, when the rig is as configured, puts it back at the end; a rig not as configured keeps \
the service's drives off until videtd is restarted with the configuration fixed. Exit codes: 0 every \
step passed (or was skipped); 27 a step failed (each names its fix; --write FILE writes them into a \
copy of the configuration); 2 bad arguments or configuration; 3 no device backend (use --sim); \
10 e-stop pressed during a motor test; 17 drive fault; 18 tension-sensor fault; 19 a wire did not \
wind back; 20 cancelled (or no terminal to prompt, without --yes); 22 the device could not be opened \
or would not start; 23 the motors are in use (another procedure); 24 FILE could not be written; \
26 the connection to videtd broke."
)]
pub struct CommissionArgs {
    /// Device, twin, files and output options.
    #[command(flatten)]
    pub device: DeviceArgs,
    /// Write the configuration with the fixes the check found into FILE (atomically; the rest
    /// of the configuration as written, its comments kept).
    #[arg(long, value_name = "FILE")]
    pub write: Option<PathBuf>,
    /// Check only these parts (repeatable; default: all).
    #[arg(long, value_enum, value_name = "PART")]
    pub only: Vec<Part>,
    /// With --sim: a folder of raw stereo pairs (leftNN / rightNN images) played as the
    /// cameras, rectified with vision.stereo_calibration.
    #[arg(long, value_name = "DIR", requires = "sim")]
    pub sim_cameras: Option<PathBuf>,
}

/// Run `videt commission`.
pub fn run(args: &CommissionArgs) -> ToolResult {
    Ok(commission(args).unwrap_or_else(|e| e.report(args.device.json)))
}

/// The rig's check as a [`MotorJob`].
struct RigJob<'a> {
    config: &'a Config,
    /// The drives' identities once they start (on the device).
    drives: Option<videt_drivers::cia402::SharedStartupReport>,
}

impl MotorJob for RigJob<'_> {
    type Output = RigCheck;

    fn run<H, T>(
        &mut self,
        hw: &mut H,
        tech: &mut T,
        runner: &mut Runner,
        _source: &'static str,
        stop: &AtomicBool,
    ) -> Result<RigCheck, Exit>
    where
        H: ProcedureDevice,
        T: Technician<H> + TensionTechnician<H> + CommissionTechnician<H>,
    {
        Ok(check_rig(hw, tech, runner, self.config, stop, Thimble::Off))
    }

    fn drives_opened(&mut self, report: videt_drivers::cia402::SharedStartupReport) {
        self.drives = Some(report);
    }
}

/// Why the drives' identities are not checked where there are no CANopen drives.
const NO_DRIVES: &str = "not checked: the twin's motors are not CANopen drives (videt sim-rig serves them as drives for a check over CAN)";

/// Everything the check found.
#[derive(Debug, Default)]
struct Findings {
    steps: Vec<StepReport>,
    /// What stopped the rig's check early, with its exit code.
    stopped: Option<(u8, String)>,
}

fn commission(args: &CommissionArgs) -> Result<ExitCode, Exit> {
    let device = &args.device;
    let config = device.load_config()?;
    let part = |p: Part| args.only.is_empty() || args.only.contains(&p);
    let setup = device.twin_setup(&config)?;
    let mut found = Findings::default();
    if part(Part::Computer) {
        if device.sim {
            found.steps.push(StepReport::skipped(
                "computer",
                "not checked on the twin: run the check without --sim on the rig's computer",
            ));
        } else {
            found
                .steps
                .extend(computer::check(&config, &computer::ThisComputer));
        }
    }
    // A running service holds the motors: it runs the rig's check on them.
    let service = device.running_service(&config);
    if let (true, Some(socket)) = (part(Part::Rig), &service) {
        let request = device.service_request(&config, ProcedureCommand::Commission, None, None)?;
        let checked = super::through_service::run_check(socket, &request)?;
        // The identities the service's drives gave when they started, from its status.
        let drives = videt_service::socket::request(
            socket,
            &videt_service::socket::Request::Status,
            std::time::Duration::from_secs(3),
        )
        .ok()
        .and_then(|r| r.status)
        .map(|s| s.drives)
        .unwrap_or_default();
        found
            .steps
            .extend(identity_steps(&drives, &config, NO_DRIVES));
        found.steps.extend(checked.steps);
        found.stopped = checked.stopped;
    } else if part(Part::Rig) {
        // Raw readings: a tension calibration is not applied.
        let runner = Runner::new(run_settings(&config));
        let mut job = RigJob {
            config: &config,
            drives: None,
        };
        match on_motors(device, &config, &setup, runner, &mut job) {
            Ok(check) => {
                let drives = job
                    .drives
                    .as_ref()
                    .and_then(|r| r.lock().ok().map(|r| drive_statuses(&r)))
                    .unwrap_or_default();
                found
                    .steps
                    .extend(identity_steps(&drives, &config, NO_DRIVES));
                found.stopped = check.stop().map(|(code, _, why)| (code, why));
                found.steps.extend(check.steps);
            }
            Err(e) if e.code == EXIT_MOTORS_BUSY => return Err(e),
            Err(e) => {
                found.steps.push(
                    StepReport::fail("drives.start", e.message.clone(), Vec::new()).with_wiring(
                        "the drives must answer at drives.node_ids on drives.can_interface: check their power, the bus cable and termination, and each drive's node id",
                    ),
                );
                found.stopped = Some((e.code, e.message));
            }
        }
    }
    // The service's colour and vision threads hold the vibrotactors and the cameras.
    let held = |what: &str, name: &str| {
        StepReport::skipped(
            name,
            format!("not checked: the running videtd holds the {what} (stop it to check them: systemctl stop videtd)"),
        )
    };
    let service_holds_devices = service.is_some() && !device.sim;
    if part(Part::Vibrotactors) {
        found.steps.push(if service_holds_devices {
            held("vibrotactor lines", "vibrotactors")
        } else {
            vibrotactors(device, &config)
        });
    }
    if part(Part::Cameras) && service_holds_devices {
        found.steps.push(held("cameras", "cameras"));
    } else if part(Part::Cameras) {
        found
            .steps
            .extend(cameras_part(args, &config, &setup.wiring_mistakes()));
    }
    let written = match &args.write {
        Some(path) => Some(write_fixes(device, &config, &found.steps, path)?),
        None => None,
    };
    print_findings(device.json, &found, written.as_deref());
    Ok(ExitCode::from(exit_code(&found)))
}

/// The exit code of what was found: the stop's, else 27 for a failed step, else 0.
fn exit_code(found: &Findings) -> u8 {
    match &found.stopped {
        Some((code, _)) => *code,
        None if found.steps.iter().any(|s| s.verdict == Verdict::Fail) => EXIT_MISTAKES,
        None => 0,
    }
}

/// Every fix the steps name, in their order.
fn all_fixes(steps: &[StepReport]) -> Vec<Fix> {
    steps.iter().flat_map(|s| s.fixes.iter().cloned()).collect()
}

/// Write the configuration with the steps' fixes into `path`; returns what was said of it.
fn write_fixes(
    device: &DeviceArgs,
    config: &Config,
    steps: &[StepReport],
    path: &Path,
) -> Result<String, Exit> {
    let source = device.config.clone().or_else(|| {
        Path::new(DEFAULT_CONFIG)
            .exists()
            .then(|| PathBuf::from(DEFAULT_CONFIG))
    });
    let failed = |message: String| Exit::new(EXIT_CALIBRATION_WRITE, "write", message);
    let text = match &source {
        Some(p) => {
            std::fs::read_to_string(p).map_err(|e| failed(format!("{}: {e}", p.display())))?
        }
        // The built-in defaults: the fixes alone make the file.
        None => String::new(),
    };
    let fixes = all_fixes(steps);
    let fixed = apply_fixes(&text, config, &fixes).map_err(failed)?;
    videt_config::calibration::write_atomically(path, fixed.as_bytes())
        .map_err(|e| failed(format!("{}: {e}", path.display())))?;
    let from = source.map_or("the built-in defaults".to_string(), |p| {
        p.display().to_string()
    });
    Ok(format!(
        "{} written: {from} with {} fix(es)",
        path.display(),
        fixes.len()
    ))
}

fn print_findings(json: bool, found: &Findings, written: Option<&str>) {
    if json {
        let steps: Vec<serde_json::Value> = found
            .steps
            .iter()
            .map(|s| {
                serde_json::json!({
                    "name": s.name,
                    "result": s.verdict.label().to_ascii_lowercase(),
                    "measured": s.measured,
                    "fixes": s.fixes.iter().map(ToString::to_string).collect::<Vec<_>>(),
                    "wiring": s.wiring,
                })
            })
            .collect();
        println!(
            "{}",
            serde_json::json!({
                "steps": steps,
                "fixes": all_fixes(&found.steps).iter().map(ToString::to_string).collect::<Vec<_>>(),
                "stopped": found.stopped.as_ref().map(|(_, m)| m),
                "written": written,
                "exit_code": exit_code(found),
            })
        );
        return;
    }
    for s in &found.steps {
        println!("{:<8} {:<28} {}", s.verdict.label(), s.name, s.measured);
        for f in &s.fixes {
            println!("{:<8} {:<28} fix: {f}", "", "");
        }
        if let Some(w) = &s.wiring {
            println!("{:<8} {:<28} wiring: {w}", "", "");
        }
    }
    let count = |v: Verdict| found.steps.iter().filter(|s| s.verdict == v).count();
    println!(
        "{} passed, {} failed, {} skipped",
        count(Verdict::Pass),
        count(Verdict::Fail),
        count(Verdict::Skipped)
    );
    if let Some((_, why)) = &found.stopped {
        println!("the check stopped early: {why}");
    }
    match written {
        Some(w) => println!("{w}"),
        None if !all_fixes(&found.steps).is_empty() => println!(
            "videt commission --write FILE writes these fixes into a copy of the configuration"
        ),
        None => {}
    }
}

/// Pulse each vibrotactor in turn for the technician to confirm (on the device, at a
/// terminal); skipped on the twin and without a terminal.
fn vibrotactors(device: &DeviceArgs, config: &Config) -> StepReport {
    let name = "vibrotactors";
    if device.sim {
        return StepReport::skipped(
            name,
            "not checked on the twin: it has no fingertips to feel them",
        );
    }
    if device.yes || !std::io::IsTerminal::is_terminal(&std::io::stdin()) {
        return StepReport::skipped(
            name,
            "not checked: a person must feel each one (run at a terminal, without --yes)",
        );
    }
    pulse_vibrotactors(config)
}

#[cfg(target_os = "linux")]
fn pulse_vibrotactors(config: &Config) -> StepReport {
    use videt_hal::Vibrotactors;
    let name = "vibrotactors";
    let s = &config.sensors;
    let mut outputs =
        match videt_drivers::gpio::linux::vibrotactors(&s.gpio_chip, s.vibrotactor_lines) {
            Ok(o) => o,
            Err(e) => {
                return StepReport::fail(
                    name,
                    format!("the vibrotactor lines could not be opened: {e}"),
                    Vec::new(),
                )
                .with_wiring("check sensors.gpio_chip and sensors.vibrotactor_lines")
            }
        };
    let half_period = std::time::Duration::from_secs_f64(0.5 / config.colour.frequency_hz);
    let mut felt = Vec::new();
    for channel in 0..videt_hal::VIBROTACTORS {
        eprintln!(
            "videt: vibrotactor {channel} (line {}) now pulses for 2 s at {} Hz",
            s.vibrotactor_lines[channel], config.colour.frequency_hz
        );
        let until = std::time::Instant::now() + std::time::Duration::from_secs(2);
        let mut on = false;
        while std::time::Instant::now() < until {
            on = !on;
            let mut out = [false; videt_hal::VIBROTACTORS];
            out[channel] = on;
            let _ = outputs.set_outputs(&out);
            std::thread::sleep(half_period);
        }
        let _ = outputs.set_outputs(&[false; videt_hal::VIBROTACTORS]);
        felt.push(super::device::confirm(&format!(
            "did the fingertip of vibrotactor {channel} vibrate (and only it)? [y/N] "
        )));
    }
    let silent: Vec<usize> = (0..felt.len()).filter(|i| !felt[*i]).collect();
    if silent.is_empty() {
        StepReport::pass(name, "each vibrotactor was felt on its own when pulsed")
    } else {
        StepReport::fail(name, format!("vibrotactors {silent:?} were not felt as their own"), Vec::new())
            .with_wiring(format!(
                "check the vibrotactors' wiring to lines {:?} of {} (sensors.vibrotactor_lines, in red, green, blue order)",
                s.vibrotactor_lines, s.gpio_chip
            ))
    }
}

#[cfg(not(target_os = "linux"))]
fn pulse_vibrotactors(_config: &Config) -> StepReport {
    StepReport::skipped("vibrotactors", "no GPIO backend on this system")
}

/// The cameras' steps: the device's (`vision.devices`), or on the twin a folder of pairs.
fn cameras_part(
    args: &CommissionArgs,
    config: &Config,
    mistakes: &[videt_assembly::as_built::WiringMistake],
) -> Vec<StepReport> {
    use videt_service::camera_relief::CalibratedRig;
    // On the twin, the folder of pairs played as its cameras.
    let played = match (args.device.sim, &args.sim_cameras) {
        (true, None) => {
            return vec![StepReport::skipped(
                "cameras",
                "not checked: the twin has no cameras (--sim-cameras DIR plays a folder of pairs as them)",
            )]
        }
        (true, Some(dir)) => Some(dir),
        (false, _) => None,
    };
    let calibration = &config.vision.stereo_calibration;
    let rig = match CalibratedRig::load(Path::new(calibration)) {
        Ok(r) => r,
        Err(e) => {
            return vec![StepReport::fail(
                "cameras.calibration",
                format!("the stereo calibration cannot be used: {e}"),
                Vec::new(),
            )
            .with_wiring("calibrate the cameras (videt calibrate-stereo --out FILE) and name FILE in vision.stereo_calibration")]
        }
    };
    let period = std::time::Duration::from_secs_f64(1.0 / f64::from(config.vision.frame_rate_hz));
    if let Some(dir) = played {
        let files =
            match videt_drivers::camera::file_source::FileStereoSource::from_folder(dir, period) {
                Ok(c) => c,
                Err(e) => {
                    return vec![StepReport::fail(
                        "cameras.frames",
                        format!("{}: {e}", dir.display()),
                        Vec::new(),
                    )]
                }
            };
        let source = format!(
            "the pairs of {} as {:?}",
            dir.display(),
            config.vision.devices
        );
        return if videt_assembly::as_built::cameras_swapped(config, mistakes) {
            cameras::check(
                &mut cameras::Swapped(files),
                &rig,
                config,
                &source,
                cameras::Source::Files,
            )
        } else {
            let mut files = files;
            cameras::check(&mut files, &rig, config, &source, cameras::Source::Files)
        };
    }
    device_cameras(config, &rig, period)
}

#[cfg(feature = "v4l")]
fn device_cameras(
    config: &Config,
    rig: &videt_service::camera_relief::CalibratedRig,
    period: std::time::Duration,
) -> Vec<StepReport> {
    use videt_drivers::camera::v4l_stereo::{V4lStereo, V4lStereoConfig};
    let [left, right] = &config.vision.devices;
    let opened = V4lStereo::open(&V4lStereoConfig {
        left: left.into(),
        right: right.into(),
        width: rig.size_px[0],
        height: rig.size_px[1],
        pair_tolerance: std::time::Duration::from_secs_f64(config.vision.pair_tolerance_ms / 1e3),
        timeout: 4 * period.max(std::time::Duration::from_millis(250)),
        buffers: 4,
        frame_rate_hz: config.vision.frame_rate_hz,
        prefer_colour: false,
    });
    match opened {
        Ok(mut camera) => cameras::check(
            &mut camera,
            rig,
            config,
            &format!("{left} + {right}"),
            cameras::Source::Cameras,
        ),
        Err(e) => vec![StepReport::fail(
            "cameras.frames",
            format!("the cameras could not be opened: {e}"),
            Vec::new(),
        )
        .with_wiring("check the cameras' cables and vision.devices (left, right)")],
    }
}

#[cfg(not(feature = "v4l"))]
fn device_cameras(
    _config: &Config,
    _rig: &videt_service::camera_relief::CalibratedRig,
    _period: std::time::Duration,
) -> Vec<StepReport> {
    vec![StepReport::skipped(
        "cameras",
        "not checked: this videt is built without V4L2 capture (cargo build --release --features v4l)",
    )]
}
