//! The one builder of the service: takes a checked [`ServicePlan`], holds the motors lock and
//! builds what it says on its three axes, then runs the service from one place:
//!
//! - the **hardware**: the device's ([`device`]), or the twin of any device on the HAL or
//!   behind simulated drives on a CAN bus ([`twin`]);
//! - the **feed**: a wall, the box, a stereo pair, a folder of camera pairs or the device's
//!   cameras, with the vision thread behind a relief ([`scene`], [`camera`]);
//! - the **calibration**: the calibration file, the configured geometry, none, or the WireMan's
//!   auto-initialization at start-up ([`calibration`]).
//!
//! [`start`] applies what every case needs (the tension correction) and runs the service. The
//! plan has loaded and checked every file already; what can still go wrong here is opening the
//! hardware, building a relief or starting a thread, returned as a [`LaunchError`] for
//! `videtd` to end with.

pub mod calibration;
pub mod camera;
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
    match (plan.device, plan.hardware.clone()) {
        (PlannedDevice::WireMan(rig), PlannedHardware::Device) => device::run(plan, rig),
        // The plan refuses it.
        (device, PlannedHardware::Device) => Err(LaunchError::refused(format!(
            "{device:?}: the device mode drives the three-wire WireMan"
        ))),
        (PlannedDevice::WireMan(rig), PlannedHardware::Twin(twin)) => twin::run(plan, rig, twin),
        (PlannedDevice::Planar(device), PlannedHardware::Twin(twin)) => {
            twin::run(plan, device, twin)
        }
        (PlannedDevice::Polar(device), PlannedHardware::Twin(twin)) => {
            twin::run(plan, device, twin)
        }
    }
}
