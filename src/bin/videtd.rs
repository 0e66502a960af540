//! `videtd` — the VIDET service: runs the real-time control loop of the haptic interface.
//!
//! `videtd --sim` runs the real runtime and control code on the digital twin (a virtual wall and
//! a virtual operator who touches it and slides along it); `videtd --sim can` runs the same with
//! the twin's motors behind three simulated CiA 402 drives on a userspace CAN bus, through the
//! real CANopen drive driver. One status line per second; Ctrl-C or
//! SIGTERM ramps the forces out, powers the drives off and exits 0. Under systemd
//! (`Type=notify`) it reports READY=1 once the drives are enabled and pets the watchdog while the
//! control loop is healthy.
//!
//! Forces are rendered only with a valid calibration (`videt init`); without one every wire is
//! held at minimum tension and the log says why. On the twin, `--sim-calibration` chooses where
//! the calibration comes from (the configured geometry, an auto-initialization at start-up, or
//! none).

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, ValueEnum};
use tracing::{error, info, warn};
use videt::can_twin::{self, CanTwin};
use videt::cycle::WireZero;
use videt::service::{run_service, ServiceOptions};
use videt::setup;
use videt::snapshot::FixedSurface;
use videt::twin_rt::RealTimeTwin;
use videt_rt_config::Config;

/// Which twin `--sim` runs on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum SimMode {
    /// The HAL-level physics twin (fast).
    Hal,
    /// The twin's motors behind three simulated CiA 402 drives on a userspace CAN bus, driven
    /// by the real CANopen drive driver.
    Can,
}

/// Where the twin's calibration comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum SimCalibration {
    /// The configured guides (the twin's truth), encoders homed.
    Config,
    /// Auto-initialization at start-up.
    Init,
    /// None: forces are not rendered.
    None,
}

/// VIDET service: the real-time control loop of the haptic interface.
#[derive(Debug, Parser)]
#[command(name = "videtd", version, about)]
struct Args {
    /// Run on the digital twin instead of the device.
    #[arg(long, value_enum, num_args = 0..=1, default_missing_value = "hal")]
    sim: Option<SimMode>,
    /// Configuration file (default: /etc/videt/videt.toml when present; with --sim, built-in
    /// defaults otherwise).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Stop cleanly after this many seconds.
    #[arg(long, value_name = "SECS")]
    duration: Option<f64>,
    /// Control socket path (overrides socket.path).
    #[arg(long, value_name = "PATH")]
    socket: Option<PathBuf>,
    /// Run without the control socket.
    #[arg(long, conflicts_with = "socket")]
    no_socket: bool,
    /// Directory of the session log (overrides telemetry.directory).
    #[arg(long, value_name = "DIR")]
    telemetry_dir: Option<PathBuf>,
    /// Run without the per-period telemetry log.
    #[arg(long, conflicts_with = "telemetry_dir")]
    no_telemetry: bool,
    /// Calibration file (default: `files.calibration` of the configuration). Without a valid
    /// one no force is rendered and the log says why. With --sim, `--sim-calibration` decides
    /// instead; this file's directory still holds the strain-gauge calibration the twin's
    /// readings are corrected with.
    #[arg(long, value_name = "FILE")]
    calibration: Option<PathBuf>,
    /// With --sim, where the twin's calibration comes from: `config` (the configured guides are
    /// the twin's true geometry and its encoders start homed: a perfect calibration), `init`
    /// (auto-initialize the twin at start-up with the procedure `videt init` runs; start-up takes
    /// longer), `none` (uncalibrated: every wire at minimum tension, no force rendered).
    #[arg(long, value_enum, default_value = "config", requires = "sim")]
    sim_calibration: SimCalibration,
    /// Motors lock file (default: `files.motors_lock`; with --sim none: the twin is private to
    /// this process).
    #[arg(long, value_name = "FILE")]
    lock: Option<PathBuf>,
}

const DEFAULT_CONFIG: &str = "/etc/videt/videt.toml";

fn load_config(args: &Args) -> Result<Config, String> {
    match &args.config {
        Some(path) => Config::load(path).map_err(|e| e.to_string()),
        None if std::path::Path::new(DEFAULT_CONFIG).exists() => {
            Config::load(std::path::Path::new(DEFAULT_CONFIG)).map_err(|e| e.to_string())
        }
        None if args.sim.is_some() => Ok(Config::default()),
        None => Err(format!(
            "no configuration: pass --config FILE or install {DEFAULT_CONFIG}"
        )),
    }
}

fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "info".into()),
        )
        .with_writer(std::io::stderr)
        .init();
    let args = Args::parse();
    let config = match load_config(&args) {
        Ok(c) => c,
        Err(e) => {
            error!("{e}");
            return ExitCode::from(2);
        }
    };
    if let Some(d) = args.duration {
        if !(d.is_finite() && d > 0.0) {
            error!("--duration must be a positive number of seconds, got {d}");
            return ExitCode::from(2);
        }
    }
    let mut options = ServiceOptions::from_config(config.clone());
    options.duration_s = args.duration;
    if args.no_socket {
        options.socket_path = None;
    } else if let Some(p) = &args.socket {
        options.socket_path = Some(p.clone());
    }
    if args.no_telemetry {
        options.telemetry_dir = None;
    } else if let Some(d) = &args.telemetry_dir {
        options.telemetry_dir = Some(d.clone());
    }
    let rig = match setup::rig(&config) {
        Ok(r) => r,
        Err(e) => {
            error!("rig geometry: {e}");
            return ExitCode::from(2);
        }
    };
    // One process at a time drives the motors (the `videt` tool takes the same lock). A twin is
    // private to its process, so with --sim the lock is taken only when --lock asks for it.
    let lock_path = match (&args.lock, args.sim) {
        (Some(p), _) => Some(p.clone()),
        (None, None) => Some(PathBuf::from(&config.files.motors_lock)),
        (None, Some(_)) => None,
    };
    let _motors = match lock_path
        .map(|p| videt::init::MotorsLock::acquire(&p))
        .transpose()
    {
        Ok(l) => l,
        Err(e) => {
            error!("{e}");
            return ExitCode::from(23);
        }
    };
    match args.sim {
        Some(SimMode::Hal) => {
            let mut scene = setup::demo_scene(&config, 1);
            tracing::info!(
                rate_hz = config.control.rate_hz,
                wall_z_m = scene.wall_z_m,
                "digital twin: a virtual wall, a virtual operator touching it and sliding along it"
            );
            let (rig, wire_zero, calibrated) =
                calibrate_twin(&config, &mut scene, rig, args.sim_calibration);
            let cycle = setup::control_cycle(&config, rig, wire_zero, calibrated);
            // Colour under the finger: a demo image over the explored area.
            match videt::colour_thread::demo_colour(&config.rig.guides_m, scene.wall_z_m) {
                Ok(source) => options.colour = Some(source),
                Err(e) => tracing::warn!("colour rendering disabled: {e}"),
            }
            let tension_path = videt_rt_config::calibration::TensionCalibration::path_beside(
                &args.calibration.clone().unwrap_or_else(|| {
                    videt::init::daemon::sim_state_dir().join("calibration-sim.toml")
                }),
            );
            match videt_rt_config::calibration::TensionCalibration::load(&tension_path) {
                Ok(tc) => {
                    info!(file = %tension_path.display(), "tension readings corrected");
                    run_service(
                        videt::init::corrected::CorrectedTensions::new(
                            RealTimeTwin::new(scene.twin),
                            tc,
                        ),
                        FixedSurface(scene.wall),
                        cycle,
                        &options,
                    )
                }
                Err(e) => {
                    if !matches!(
                        e,
                        videt_rt_config::calibration::CalibrationError::Missing { .. }
                    ) {
                        warn!("tension readings not corrected: {e}");
                    }
                    run_service(
                        RealTimeTwin::new(scene.twin),
                        FixedSurface(scene.wall),
                        cycle,
                        &options,
                    )
                }
            }
        }
        Some(SimMode::Can) => {
            let mut scene = setup::demo_scene(&config, 1);
            tracing::info!(
                rate_hz = config.control.rate_hz,
                wall_z_m = scene.wall_z_m,
                "digital twin behind CiA 402 drives on a userspace CAN bus: a virtual wall, a virtual operator touching it and sliding along it"
            );
            let (rig, wire_zero, calibrated) =
                calibrate_twin(&config, &mut scene, rig, args.sim_calibration);
            let cycle = setup::control_cycle(&config, rig, wire_zero, calibrated);
            match videt::colour_thread::demo_colour(&config.rig.guides_m, scene.wall_z_m) {
                Ok(source) => options.colour = Some(source),
                Err(e) => tracing::warn!("colour rendering disabled: {e}"),
            }
            let hw = match CanTwin::new(
                scene.twin,
                can_twin::drive_config(&config),
                Some(config.realtime.control_priority),
            ) {
                Ok(hw) => hw,
                Err(e) => {
                    error!("simulated CAN drives: {e}");
                    return ExitCode::FAILURE;
                }
            };
            run_service(hw, FixedSurface(scene.wall), cycle, &options)
        }
        None => {
            let path = args
                .calibration
                .clone()
                .unwrap_or_else(|| PathBuf::from(&config.files.calibration));
            if let Ok(s) = videt::init::daemon::load(&config, &path) {
                if !s.calibrated {
                    warn!(
                        "forces will not be rendered (not calibrated): {}",
                        s.reason.unwrap_or_default()
                    );
                }
            }
            error!(
                "no device backend is built into this videtd: run with --sim for the digital twin"
            );
            ExitCode::from(2)
        }
    }
}

/// The twin's calibration as `--sim-calibration` chooses. Returns the rig, the encoder zeros and
/// whether forces may be rendered.
fn calibrate_twin(
    config: &Config,
    scene: &mut setup::DemoScene,
    configured: videt_control::Rig3,
    source: SimCalibration,
) -> (videt_control::Rig3, WireZero, bool) {
    match source {
        SimCalibration::Config => {
            info!("twin calibration: the configured guides (the twin's true geometry)");
            return (configured, WireZero::default(), true);
        }
        SimCalibration::None => {
            warn!("forces will not be rendered (not calibrated): --sim-calibration none");
            return (configured, WireZero::default(), false);
        }
        SimCalibration::Init => {}
    }
    let operator = scene.twin.operator().clone();
    let start = scene.twin.plant().position_m();
    // A signal during the start-up initialization cancels it (the service then starts
    // uncalibrated and stops at once: its own handlers see the same signal pending).
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        let _ = signal_hook::flag::register(signal, std::sync::Arc::clone(&stop));
    }
    match videt::init::daemon::initialize_twin(config, &mut scene.twin, operator, start, 1, &stop)
        .map_err(|e| e.to_string())
        .and_then(|o| videt::init::daemon::from_calibration(config, &o.calibration))
    {
        Ok(s) => {
            let c = s
                .calibration
                .as_ref()
                .map(|c| c.sides_m)
                .unwrap_or_default();
            info!(
                d01_mm = c[0] * 1e3,
                d02_mm = c[1] * 1e3,
                d12_mm = c[2] * 1e3,
                "twin auto-initialized at start-up"
            );
            (s.rig, s.wire_zero, true)
        }
        Err(e) => {
            warn!("forces will not be rendered (not calibrated): twin auto-initialization failed: {e}");
            (configured, WireZero::default(), false)
        }
    }
}
