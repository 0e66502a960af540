//! The one builder of the service: takes a checked [`ServicePlan`], holds the motors lock and
//! builds what it says on its three axes, then runs the service from one place:
//!
//! - the **hardware**: the device's ([`device`]), or the twin of any device on the HAL or
//!   behind simulated drives on a CAN bus ([`twin`]);
//! - the **feed**: a wall, the box, a stereo pair, a folder of camera pairs or the device's
//!   cameras, with the vision thread behind a relief ([`scene`]);
//! - the **calibration**: the calibration file, the configured geometry, none, or the WireMan's
//!   auto-initialization at start-up ([`calibration`]).
//!
//! [`start`] applies what every case needs (the tension correction) and runs the service. The
//! plan has loaded and checked every file already; what can still go wrong here is opening the
//! hardware, building a relief or starting a thread, returned as a [`LaunchError`] for
//! `videtd` to end with.

pub mod calibration;
pub mod device;
pub mod scene;
pub mod start;
pub mod twin;

use std::process::ExitCode;

use crate::plan::{PlannedDevice, PlannedHardware, ServicePlan};

/// Why the service could not be launched, and the exit code `videtd` ends with.
pub type LaunchError = crate::plan::StartError;

/// The exit code when another process holds the motors.
pub const EXIT_MOTORS_LOCKED: u8 = 23;

/// Run the service as `plan` says; the exit code it ended with, or why it could not start
/// (exit 23: another process holds the motors).
pub fn launch(plan: ServicePlan) -> Result<ExitCode, LaunchError> {
    let _motors = plan
        .lock_path
        .as_deref()
        .map(crate::init::MotorsLock::acquire)
        .transpose()
        .map_err(|e| LaunchError {
            message: e.to_string(),
            exit_code: EXIT_MOTORS_LOCKED,
        })?;
    let ServicePlan {
        hardware,
        feed,
        calibration,
        tension_correction,
        settings,
        ..
    } = plan;
    let starter = start::Starter {
        settings,
        tension_correction,
    };
    match hardware {
        PlannedHardware::Device(rig) => device::run(&starter, feed, &calibration, rig),
        PlannedHardware::Twin(PlannedDevice::WireMan(rig), twin) => {
            twin::run(&starter, feed, &calibration, rig, twin)
        }
        PlannedHardware::Twin(PlannedDevice::Planar(device), twin) => {
            twin::run(&starter, feed, &calibration, device, twin)
        }
        PlannedHardware::Twin(PlannedDevice::Polar(device), twin) => {
            twin::run(&starter, feed, &calibration, device, twin)
        }
    }
}
