//! The service on the device: the drives on SocketCAN, the strain-gauge converters and the
//! e-stop named by the configuration, the geometry of the calibration file. The wearer touches
//! the relief of what the cameras see when a stereo calibration is installed
//! (`vision.stereo_calibration`), else the check wall (a flat virtual wall in front of the
//! frame, as on the twin) and the log says why.

use std::process::ExitCode;

use tracing::{error, info, warn};
use videt_runtime::setup;
use videt_runtime::snapshot::FixedSurface;

use super::camera::device_camera_feed;
use super::start::run_with_tension_correction;
use crate::plan::ServicePlan;
use crate::service::ServiceExtras;

/// Open the device and run the service on it.
pub fn run_on_device(plan: &mut ServicePlan) -> ExitCode {
    let config = &plan.config;
    let options = &mut plan.options;
    let path = plan.calibration_path.clone();
    let state = match videt_runtime::calibration::load(config, &path) {
        Ok(s) => s,
        Err(e) => {
            error!("calibration: {e}");
            return ExitCode::from(2);
        }
    };
    if let Some(reason) = &state.reason {
        warn!("forces will not be rendered (not calibrated): {reason}");
    }
    let cycle = setup::control_cycle(config, state.rig, state.wire_zero, state.calibrated);
    options.colour = None;
    options.what = format!(
        "device: drives on {}, tension sensors {:?}",
        config.drives.can_interface, config.sensors.adc
    );
    let mut hw = match videt_assembly::hardware::open_device(config) {
        Ok(hw) => hw,
        Err(e) => {
            error!("device: {e}");
            return ExitCode::FAILURE;
        }
    };
    info!(
        rate_hz = config.control.rate_hz,
        can = %config.drives.can_interface,
        adc = ?config.sensors.adc,
        "device opened"
    );
    let fault_causes =
        videt_assembly::hardware::drive_fault_causes(hw.drives_mut().fault_reports());
    let drives_report = hw.drives_mut().startup_report();
    match device_camera_feed(config) {
        Ok(mut camera) => {
            options.colour = camera.colour;
            camera.extras.fault_causes = Some(fault_causes);
            camera.extras.drives_report = Some(drives_report);
            run_with_tension_correction(hw, camera.feed, cycle, options, &path, camera.extras)
        }
        Err(why) => {
            warn!(
                wall_z_m = setup::CHECK_WALL_Z_M,
                "the check wall is rendered instead of the scene: {why}"
            );
            run_with_tension_correction(
                hw,
                FixedSurface(setup::check_wall()),
                cycle,
                options,
                &path,
                ServiceExtras {
                    fault_causes: Some(fault_causes),
                    drives_report: Some(drives_report),
                    ..Default::default()
                },
            )
        }
    }
}
