//! `videtd` — the VIDET service: runs the real-time control loop of the haptic interface.
//!
//! `videtd --sim` runs the real runtime and control code on the digital twin (a virtual wall and
//! a virtual operator who touches it and slides along it); `videtd --sim can` runs the same with
//! the twin's motors behind three simulated CiA 402 drives on a userspace CAN bus, through the
//! real CANopen drive driver. `--scene box` puts a bas-relief box in front of the twin (either),
//! `--scene stereo` the bas-relief of a real stereo pair (HAL twin), re-matched around the finger on a vision
//! thread while the operator sweeps across it. One status line per second; Ctrl-C or
//! SIGTERM ramps the forces out, powers the drives off and exits 0. Under systemd
//! (`Type=notify`) it reports READY=1 once the drives are enabled and pets the watchdog while the
//! control loop is healthy.
//!
//! Without `--sim` it runs on the device: the CiA 402 drives on the SocketCAN interface, the
//! strain-gauge converters and the e-stop that the configuration names, the geometry of the
//! calibration file, and the relief rebuilt from the cameras (built with `--features v4l`, a
//! stereo calibration installed) or else the check wall. `--sim --scene camera:DIR` runs the
//! same camera vision thread on the twin, with a folder of raw pairs as the camera.
//!
//! Forces are rendered only with a valid calibration (`videt init`); without one every wire is
//! held at minimum tension and the log says why. On the twin, `--sim-calibration` chooses where
//! the calibration comes from (the configured geometry, an auto-initialization at start-up, or
//! none).

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Parser;
use tracing::error;
use videt_service::launch::launch;
use videt_service::plan::{
    load_config, parse_scene, ServicePlan, ServiceRequest, SimCalibration, SimMode, SimScene,
};

/// The version `videtd --version` prints, with the optional capabilities it was built with: the
/// guests and a technician tell a build that can capture cameras from one that cannot.
#[cfg(feature = "v4l")]
const VERSION: &str = concat!(env!("CARGO_PKG_VERSION"), " (with V4L2 capture)");
#[cfg(not(feature = "v4l"))]
const VERSION: &str = concat!(env!("CARGO_PKG_VERSION"), " (without V4L2 capture)");

/// VIDET service: the real-time control loop of the haptic interface.
#[derive(Debug, Parser)]
#[command(name = "videtd", version = VERSION, about)]
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
    /// With --sim: the scene the virtual operator touches: `wall` (a flat virtual wall), `box`
    /// (a bas-relief box built from known segments), `stereo` (the bas-relief of the compiled-in
    /// real stereo pair, Middlebury tsukuba, re-matched around the finger as it moves) or
    /// `stereo:DIR` (the same for the pair in DIR: left.png/right.png or .ppm, and optionally a
    /// camera.toml with focal_px, baseline_m, max_disparity_px) or `camera:DIR` (the raw
    /// pairs of DIR, `*left*`/`*right*` images, as a camera delivering them in a loop at
    /// `vision.frame_rate_hz`: rectified with the stereo calibration and turned into reliefs as
    /// the device's cameras are).
    /// Without --sim the scene is the cameras' when a stereo calibration is installed, else
    /// the wall.
    #[arg(long, value_name = "SCENE", value_parser = parse_scene, default_value = "wall")]
    scene: SimScene,
    /// Stereo calibration of the cameras (overrides vision.stereo_calibration).
    #[arg(long, value_name = "FILE")]
    stereo_calibration: Option<PathBuf>,
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
    /// With --sim: the twin's true guide points, metres, in the frame plane: "X,Y;X,Y;X,Y"
    /// (replaces the configured `rig.guides_m`), so `videt init` through the control socket can
    /// be rehearsed on any frame.
    #[arg(
        long,
        value_name = "X,Y;X,Y;X,Y",
        requires = "sim",
        allow_hyphen_values = true
    )]
    sim_guides: Option<String>,
    /// Serve the live view for Foxglove: the thimble, the wires, the forces, the relief, the
    /// tensions and the safety state over the Foxglove WebSocket protocol, read-only (open
    /// `ws://ADDR:PORT` in Foxglove, with docs/foxglove-layout.json). Without a value it
    /// listens on `live.address` (default 127.0.0.1:8765, loopback only).
    #[arg(long, value_name = "ADDR:PORT", num_args = 0..=1, default_missing_value = None)]
    live: Option<Option<String>>,
}

impl Args {
    /// What the command line asks of the service.
    fn request(self) -> ServiceRequest {
        ServiceRequest {
            sim: self.sim,
            config: self.config,
            duration_s: self.duration,
            scene: self.scene,
            stereo_calibration: self.stereo_calibration,
            socket: self.socket,
            no_socket: self.no_socket,
            telemetry_dir: self.telemetry_dir,
            no_telemetry: self.no_telemetry,
            calibration: self.calibration,
            sim_calibration: self.sim_calibration,
            lock: self.lock,
            sim_guides: self.sim_guides,
            live: self.live,
        }
    }
}

fn main() -> ExitCode {
    videt_service::logging::init();
    let request = Args::parse().request();
    let plan = load_config(&request).and_then(|config| ServicePlan::new(config, &request));
    match plan {
        Ok(plan) => launch(plan),
        Err(e) => {
            error!("{e}");
            ExitCode::from(e.exit_code)
        }
    }
}
