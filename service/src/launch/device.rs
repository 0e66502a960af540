//! The service on the device: the drives on SocketCAN, the strain-gauge converters and the
//! e-stop named by the configuration, the geometry of the calibration file. The wearer touches
//! the relief of what the cameras see when a stereo calibration is installed
//! (`vision.stereo_calibration`), else the check wall (a flat virtual wall in front of the
//! frame, as on the twin) and the log says why.

use std::process::ExitCode;

use tracing::info;
use videt_control::Rig3;
use videt_runtime::setup;

use super::{start::Starter, LaunchError};
use crate::colour_thread::ColourOutputs;
use crate::plan::{PlannedCalibration, PlannedFeed};
use crate::run::HardwareReports;

/// Open the WireMan (its configured geometry `rig`) and run the service on it, rendering `feed`
/// with the geometry `calibration` gives.
pub fn run(
    starter: &Starter,
    feed: PlannedFeed,
    calibration: &PlannedCalibration,
    rig: Rig3,
) -> Result<ExitCode, LaunchError> {
    let config = &starter.settings.config;
    let (rig, wire_zero, calibrated) = super::calibration::resolve(config, rig, calibration, None);
    let cycle = setup::control_cycle(config, rig, wire_zero, calibrated);
    let description = format!(
        "device: drives on {}, tension sensors {:?}",
        config.drives.can_interface, config.sensors.adc
    );
    let mut hw = videt_assembly::hardware::open_device(config)
        .map_err(|e| LaunchError::failed(format!("device: {e}")))?;
    info!(
        rate_hz = config.control.rate_hz,
        can = %config.drives.can_interface,
        adc = ?config.sensors.adc,
        "device opened"
    );
    let reports = HardwareReports::of_drives(&mut hw);
    // The relief lies in front of the configured frame; the colour goes to the vibrotactors.
    let outputs = ColourOutputs::Gpio {
        chip: config.sensors.gpio_chip.clone(),
        lines: config.sensors.vibrotactor_lines,
    };
    let scene = super::scene::build(
        config,
        feed,
        setup::relief_layout(config),
        outputs,
        &|what| what.to_string(),
    )?;
    Ok(starter.start(hw, scene, cycle, description, reports))
}
