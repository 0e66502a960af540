//! The one builder of the service: takes a checked [`ServicePlan`], holds the motors lock,
//! opens the device's hardware or the twin the plan names, builds its surface feed (and the
//! vision and colour threads behind it) and its control cycle, and runs the service until it
//! stops. `videtd` is a command line in front of [`launch`].
//!
//! - [`device`]: the device's hardware, the cameras' relief or the check wall.
//! - [`twin`]: the twin's scenes (wall, box, stereo pair, camera folder; the other devices'
//!   wall), each on the HAL or the CAN twin.
//! - [`camera`]: the relief from a camera and the vision thread that keeps it up to date.
//! - [`start`]: running the service on opened hardware, shared by all of them.

pub mod camera;
pub mod device;
pub mod start;
pub mod twin;

use std::process::ExitCode;

use tracing::error;

use crate::plan::{PlannedDevice, ServicePlan, SimScene};

/// Run the service as `plan` says; the exit code `videtd` ends with (23: another process
/// holds the motors).
pub fn launch(mut plan: ServicePlan) -> ExitCode {
    let _motors = match plan
        .lock_path
        .as_deref()
        .map(crate::init::MotorsLock::acquire)
        .transpose()
    {
        Ok(lock) => lock,
        Err(e) => {
            error!("{e}");
            return ExitCode::from(23);
        }
    };
    let Some(sim) = plan.sim else {
        return device::run_on_device(&mut plan);
    };
    let config = &plan.config;
    let options = &mut plan.options;
    let calibration = plan.twin_calibration;
    match (plan.device, &plan.scene) {
        (PlannedDevice::Planar(device), _) => {
            twin::device_wall_demo(config, device, sim, calibration, options)
        }
        (PlannedDevice::Polar(device), _) => {
            twin::device_wall_demo(config, device, sim, calibration, options)
        }
        (PlannedDevice::WireMan(rig), SimScene::Camera(dir)) => {
            twin::run_camera_relief_demo(config, rig, options, calibration, dir)
        }
        (PlannedDevice::WireMan(rig), SimScene::Stereo(dir)) => {
            twin::run_stereo_relief_demo(config, rig, options, calibration, dir.as_deref())
        }
        (PlannedDevice::WireMan(rig), SimScene::Box) => {
            twin::run_relief_demo(config, rig, options, calibration, sim)
        }
        (PlannedDevice::WireMan(rig), SimScene::Wall) => twin::run_wall(
            config,
            rig,
            calibration,
            sim,
            options,
            &plan.calibration_path,
        ),
    }
}
