//! The `videtd` command line: its arguments and what they ask of the service. The binary parses
//! them; the manual pages and shell completions are generated from the same definitions
//! (`videt-tools`' `manual`), so they cannot drift from `videtd --help`.

use std::path::PathBuf;

use clap::Parser;

use crate::plan::{parse_scene, ServiceRequest, SimCalibration, SimMode, SimScene};

/// VIDET service: the real-time control loop of the haptic interface.
#[derive(Debug, Parser)]
#[command(name = "videtd", version, about)]
pub struct Args {
    /// Run on the digital twin instead of the device.
    #[arg(long, value_enum, num_args = 0..=1, default_missing_value = "hal")]
    pub sim: Option<SimMode>,
    /// Configuration file (default: /etc/videt/videt.toml when present; with --sim, built-in
    /// defaults otherwise).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Stop cleanly after this many seconds.
    #[arg(long, value_name = "SECS")]
    pub duration: Option<f64>,
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
    pub scene: SimScene,
    /// Stereo calibration of the cameras (overrides vision.stereo_calibration).
    #[arg(long, value_name = "FILE")]
    pub stereo_calibration: Option<PathBuf>,
    /// Control socket path (overrides socket.path).
    #[arg(long, value_name = "PATH")]
    pub socket: Option<PathBuf>,
    /// Run without the control socket.
    #[arg(long, conflicts_with = "socket")]
    pub no_socket: bool,
    /// Directory of the session log (overrides telemetry.directory).
    #[arg(long, value_name = "DIR")]
    pub telemetry_dir: Option<PathBuf>,
    /// Run without the per-period telemetry log.
    #[arg(long, conflicts_with = "telemetry_dir")]
    pub no_telemetry: bool,
    /// Calibration file (default: `files.calibration` of the configuration). Without a valid
    /// one no force is rendered and the log says why. With --sim, `--sim-calibration` decides
    /// instead; this file's directory still holds the strain-gauge calibration the twin's
    /// readings are corrected with.
    #[arg(long, value_name = "FILE")]
    pub calibration: Option<PathBuf>,
    /// With --sim, where the twin's calibration comes from: `config` (the configured guides are
    /// the twin's true geometry and its encoders start homed: a perfect calibration), `init`
    /// (auto-initialize the twin at start-up with the procedure `videt init` runs; start-up takes
    /// longer), `none` (uncalibrated: every wire at minimum tension, no force rendered).
    #[arg(long, value_enum, default_value = "config", requires = "sim")]
    pub sim_calibration: SimCalibration,
    /// Motors lock file (default: `files.motors_lock`; with --sim none: the twin is private to
    /// this process).
    #[arg(long, value_name = "FILE")]
    pub lock: Option<PathBuf>,
    /// With --sim: the twin's true guide points, metres, in the frame plane: "X,Y;X,Y;X,Y"
    /// (replaces the configured `rig.guides_m`), so `videt init` through the control socket can
    /// be rehearsed on any frame.
    #[arg(
        long,
        value_name = "X,Y;X,Y;X,Y",
        requires = "sim",
        allow_hyphen_values = true
    )]
    pub sim_guides: Option<String>,
    /// Serve the live view for Foxglove: the thimble, the wires, the forces, the relief, the
    /// tensions and the safety state over the Foxglove WebSocket protocol, read-only (open
    /// `ws://ADDR:PORT` in Foxglove, with docs/foxglove-layout.json). Without a value it
    /// listens on `live.address` (default 127.0.0.1:8765, loopback only).
    #[arg(long, value_name = "ADDR:PORT", num_args = 0..=1, default_missing_value = None)]
    pub live: Option<Option<String>>,
}

impl Args {
    /// What the command line asks of the service.
    pub fn request(self) -> ServiceRequest {
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
