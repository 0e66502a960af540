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
//! none). The arguments are `videt_service::cli::Args`.
//!
//! A package of its own: the service's binary links neither the tool (its analysis and plots)
//! nor the paper's experiments.

use std::process::ExitCode;

use clap::{CommandFactory, FromArgMatches};
use tracing::error;
use videt_service::cli::Args;
use videt_service::launch::launch;
use videt_service::plan::{load_config, ServicePlan};

/// What `videtd --version` says it was built with: the guests and a technician tell a build that
/// can capture cameras from one that cannot.
#[cfg(feature = "v4l")]
const FEATURES: &str = "v4l; with V4L2 capture";
#[cfg(not(feature = "v4l"))]
const FEATURES: &str = "none; without V4L2 capture";

fn main() -> ExitCode {
    videt_service::logging::init();
    let matches = Args::command()
        .version(videt_build_info::version(FEATURES))
        .get_matches();
    let args = Args::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    let request = args.request();
    let started = load_config(&request)
        .and_then(|config| ServicePlan::new(config, &request))
        .and_then(launch);
    match started {
        Ok(code) => code,
        Err(e) => {
            error!("{e}");
            ExitCode::from(e.exit_code)
        }
    }
}
