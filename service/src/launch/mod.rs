//! The one builder of the service: takes a checked [`ServicePlan`], holds the motors lock,
//! opens the device's hardware or the twin the plan names, builds its surface feed (and the
//! vision and colour threads behind it) and its control cycle, and runs the service until it
//! stops. `videtd` is a command line in front of [`launch`].
//!
//! - [`device`]: the device's hardware, the cameras' relief or the check wall.
//! - [`twin`]: the twin's wall scenes, and each device's twin calibrated for the relief scenes.
//! - [`relief`]: the twin's relief scenes (box, stereo pair, camera folder) on every device,
//!   each on the HAL or the CAN twin.
//! - [`camera`]: the relief from a camera and the vision thread that keeps it up to date.
//! - [`start`]: running the service on opened hardware, shared by all of them.

pub mod camera;
pub mod device;
pub mod relief;
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
        (PlannedDevice::WireMan(rig), SimScene::Wall) => twin::run_wall(
            config,
            rig,
            calibration,
            sim,
            options,
            &plan.calibration_path,
        ),
        (PlannedDevice::WireMan(rig), scene) => {
            let twin = twin::wireman_scene_twin(config, rig, calibration);
            run_relief_scene(config, twin, scene, sim, options)
        }
        (PlannedDevice::Planar(device), scene) => {
            run_other_device(config, device, scene, sim, calibration, options)
        }
        (PlannedDevice::Polar(device), scene) => {
            run_other_device(config, device, scene, sim, calibration, options)
        }
    }
}

/// A scene on the twin of a device other than the WireMan: its wall, or a relief.
fn run_other_device<const N: usize, D>(
    config: &videt_rt_config::Config,
    device: D,
    scene: &SimScene,
    sim: crate::plan::SimMode,
    calibration: crate::plan::SimCalibration,
    options: &mut crate::service::ServiceOptions,
) -> ExitCode
where
    D: videt_runtime::runtime_device::RuntimeDevice<N>,
    videt_assembly::twin_rt::RealTimeTwin<N, D>: crate::service_hardware::ServiceHardware<N>,
    videt_assembly::can_twin::CanTwin<N, videt_assembly::twin_rt::RealTimeTwin<N, D>>:
        crate::service_hardware::ServiceHardware<N>,
{
    if *scene == SimScene::Wall {
        return twin::device_wall_demo(config, device, sim, calibration, options);
    }
    match twin::device_scene_twin(config, device, calibration) {
        Ok(twin) => run_relief_scene(config, twin, scene, sim, options),
        Err(code) => code,
    }
}

/// A relief scene (the box, a stereo pair, a camera folder) on a device's twin.
fn run_relief_scene<const N: usize, D>(
    config: &videt_rt_config::Config,
    twin: relief::SceneTwin<N, D>,
    scene: &SimScene,
    sim: crate::plan::SimMode,
    options: &mut crate::service::ServiceOptions,
) -> ExitCode
where
    D: videt_runtime::runtime_device::RuntimeDevice<N>,
    videt_assembly::twin_rt::RealTimeTwin<N, D>: crate::service_hardware::ServiceHardware<N>,
    videt_assembly::can_twin::CanTwin<N, videt_assembly::twin_rt::RealTimeTwin<N, D>>:
        crate::service_hardware::ServiceHardware<N>,
{
    match scene {
        SimScene::Box => relief::run_box(config, twin, options, sim),
        SimScene::Stereo(dir) => relief::run_stereo(config, twin, options, sim, dir.as_deref()),
        SimScene::Camera(dir) => relief::run_camera(config, twin, options, sim, dir),
        SimScene::Wall => {
            error!("the wall scene is not a relief");
            ExitCode::from(2)
        }
    }
}
