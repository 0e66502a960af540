//! Starting the service on opened hardware: the HAL twin, the CAN twin (its drives opened
//! here from the configured part's description), or any hardware with the strain-gauge
//! calibration's correction of its tension readings; and the pieces every scene shares.

use std::path::Path;
use std::process::ExitCode;

use tracing::{error, info, warn};
use videt_assembly::as_built::{configured_wiring, DriveCorrections};
use videt_assembly::can_twin::{self, CanTwin};
use videt_assembly::twin_rt::RealTimeTwin;
use videt_rt_config::Config;
use videt_runtime::cycle::ControlCycle;
use videt_runtime::runtime_device::RuntimeDevice;
use videt_runtime::snapshot::{SnapshotWriter, SurfaceFeed};
use videt_runtime::{WiremanCycle, WIREMAN_WIRES};
use videt_sim::Twin;
use videt_vision::surface::ReliefModel;

use crate::init::remote::ProcedureDevice;
use crate::plan::SimMode;
use crate::relief_feed::ReliefFeed;
use crate::service::{run_service_with, ServiceExtras, ServiceOptions};
use crate::service_hardware::ServiceHardware;

/// Wire `twin`, a rig built right, as `config` corrects it: a correction the rig does not need
/// shows as the mistake it makes on the device. The HAL twin applies the drives' directions
/// itself; behind simulated drives (`sim` CAN) the drivers apply them.
pub fn wire_as_configured<const N: usize, D: videt_control::WireDevice<N>>(
    twin: &mut Twin<N, D>,
    config: &Config,
    sim: SimMode,
) {
    let corrections = match sim {
        SimMode::Hal => DriveCorrections::InTwin,
        SimMode::Can => DriveCorrections::InDrivers,
    };
    // A wiring without permutations is always valid.
    let _ = twin.set_wiring(configured_wiring::<N>(config, corrections));
}

/// Run the service on `twin`: the HAL twin itself, or its motors behind simulated CiA 402
/// drives on a userspace CAN bus (the configured part's dictionary), as `sim` says. The CAN
/// twin's drive faults and start-up report join `extras`; its bus load is logged at the end.
pub fn run_on_twin<const N: usize, D, F>(
    sim: SimMode,
    mut twin: Twin<N, D>,
    feed: F,
    cycle: ControlCycle<N, D>,
    options: &ServiceOptions,
    extras: ServiceExtras,
) -> ExitCode
where
    D: RuntimeDevice<N>,
    F: SurfaceFeed + Send + 'static,
    RealTimeTwin<N, D>: ServiceHardware<N>,
    CanTwin<N, RealTimeTwin<N, D>>: ServiceHardware<N>,
{
    let config = &options.config;
    wire_as_configured(&mut twin, config, sim);
    if sim == SimMode::Hal {
        return run_service_with(RealTimeTwin::new(twin), feed, cycle, options, extras);
    }
    let dictionary = match videt_assembly::drive_dictionary::for_config(config) {
        Ok(d) => d,
        Err(e) => {
            error!("simulated CAN drives: {e}");
            return ExitCode::FAILURE;
        }
    };
    let mut hw = match CanTwin::new(
        twin,
        can_twin::drive_config::<N>(config),
        dictionary,
        config.drives.bitrate,
        Some(config.realtime.control_priority),
        usize::try_from(config.realtime.control_cpu).ok(),
    ) {
        Ok(hw) => hw,
        Err(e) => {
            error!("simulated CAN drives: {e}");
            return ExitCode::FAILURE;
        }
    };
    let bus = hw.bus_stats();
    let extras = ServiceExtras {
        fault_causes: Some(videt_assembly::hardware::drive_fault_causes(
            hw.fault_reports(),
        )),
        drives_report: Some(hw.startup_report()),
        ..extras
    };
    let code = run_service_with(hw, feed, cycle, options, extras);
    if let Some(s) = bus.map(|b| b.snapshot()) {
        info!(
            bitrate = s.bitrate,
            frames = s.frames,
            load_percent = format!("{:.1}", 100.0 * s.load),
            mean_wait_us = format!("{:.0}", s.mean_wait_us),
            max_wait_us = format!("{:.0}", s.max_wait_us),
            overflows = s.overflows,
            "simulated CAN bus"
        );
    }
    code
}

/// Run the service on `hw`, its tension readings corrected by the strain-gauge calibration
/// beside `calibration_path` when there is one (`videt tension-calibrate` writes it).
pub fn run_with_tension_correction<H, F>(
    hw: H,
    feed: F,
    cycle: WiremanCycle,
    options: &ServiceOptions,
    calibration_path: &Path,
    extras: ServiceExtras,
) -> ExitCode
where
    H: ServiceHardware<WIREMAN_WIRES> + ProcedureDevice,
    F: SurfaceFeed + Send + 'static,
{
    use videt_rt_config::calibration::{CalibrationError, TensionCalibration};
    let tension_path = TensionCalibration::path_beside(calibration_path);
    match TensionCalibration::load(&tension_path) {
        Ok(tc) => {
            info!(file = %tension_path.display(), "tension readings corrected");
            run_service_with(
                crate::init::corrected::CorrectedTensions::new(hw, tc),
                feed,
                cycle,
                options,
                extras,
            )
        }
        Err(e) => {
            if !matches!(e, CalibrationError::Missing { .. }) {
                warn!("tension readings not corrected: {e}");
            }
            run_service_with(hw, feed, cycle, options, extras)
        }
    }
}

/// Whether `[colour]` asks for the colour under the finger; says so when it does not.
pub fn colour_enabled(config: &Config) -> bool {
    if !config.colour.enabled {
        info!("colour rendering off (colour.enabled = false)");
    }
    config.colour.enabled
}

/// The relief channel of a scene, with the proxy, blend and stiffness of `config`; an invalid
/// setting is logged and ends the service (exit 2).
pub fn relief_channel(
    config: &Config,
    model: ReliefModel,
) -> Result<(SnapshotWriter<ReliefModel>, ReliefFeed), ExitCode> {
    crate::relief_feed::relief_channel_for(config, model).map_err(|e| {
        error!("{e}");
        ExitCode::from(2)
    })
}
