//! The twin's wall scenes (the WireMan touching the check wall, the other devices touching
//! theirs), and each device's twin calibrated as the plan says for the relief scenes of
//! [`super::relief`]; on the HAL or the CAN twin.

use std::process::ExitCode;

use tracing::{error, info, warn};
use videt_assembly::can_twin::CanTwin;
use videt_assembly::twin_rt::RealTimeTwin;
use videt_assembly::twin_scene::DemoScene;
use videt_control::Rig3;
use videt_rt_config::Config;
use videt_runtime::cycle::WireZero;
use videt_runtime::setup;
use videt_runtime::snapshot::FixedSurface;
use videt_runtime::WiremanCycle;

use super::relief::SceneTwin;
use super::start::{colour_enabled, run_on_twin, run_with_tension_correction, wire_as_configured};
use crate::plan::{SimCalibration, SimMode};
use crate::service::{ServiceExtras, ServiceOptions};
use crate::service_hardware::ServiceHardware;

/// The wall demonstration on the twin of a device other than the WireMan: the twin's geometry
/// is the configured one (`--sim-calibration config`) or forces are off (`none`);
/// auto-initialization measures the WireMan's base triangle and is refused here.
pub(super) fn device_wall_demo<const N: usize, D>(
    config: &Config,
    device: D,
    sim: SimMode,
    calibration: SimCalibration,
    options: &mut ServiceOptions,
) -> ExitCode
where
    D: videt_runtime::runtime_device::RuntimeDevice<N>,
    RealTimeTwin<N, D>: ServiceHardware<N>,
    CanTwin<N, RealTimeTwin<N, D>>: ServiceHardware<N>,
{
    let name = D::KIND.name();
    let calibrated = match device_calibrated(name, calibration) {
        Ok(c) => c,
        Err(code) => return code,
    };
    let start = videt_assembly::twin_scene::demo_start(&device);
    let scene = videt_assembly::twin_scene::demo_scene_for(config, device, start, 1);
    options.what = format!(
        "digital twin of the {name} device ({N} wire{}): a virtual wall, a virtual operator \
         touching it and sliding along it",
        if N == 1 { "" } else { "s" }
    );
    tracing::info!(
        rate_hz = config.control.rate_hz,
        wall_z_m = scene.wall_z_m,
        "{}",
        options.what
    );
    if options.colour.take().is_some() || config.colour.enabled {
        info!("colour rendering off: the demonstration image is laid over the WireMan's frame");
    }
    let cycle = setup::control_cycle_for(config, device, WireZero::default(), calibrated);
    if sim == SimMode::Can {
        options.what = format!("{} (drives on a simulated CAN bus)", options.what);
    }
    run_on_twin(
        sim,
        scene.twin,
        FixedSurface(scene.wall),
        cycle,
        options,
        ServiceExtras::default(),
    )
}

/// The WireMan's twin and control cycle for a relief scene, calibrated as `calibration` says.
pub(super) fn wireman_scene_twin(
    config: &Config,
    rig: Rig3,
    calibration: SimCalibration,
) -> SceneTwin<3, Rig3> {
    let mut scene = videt_assembly::twin_scene::demo_scene(config, 1);
    let (rig, wire_zero, calibrated) = calibrate_twin(config, &mut scene, rig, calibration);
    let guides = rig.guides_m().map(|g| [g.x, g.y, g.z]);
    SceneTwin {
        twin: scene.twin,
        cycle: setup::control_cycle(config, rig, wire_zero, calibrated),
        layout: super::relief::layout_for(config, &guides),
    }
}

/// The twin and control cycle of a device other than the WireMan for a relief scene: its
/// geometry the configured one (`--sim-calibration config`) or forces off (`none`).
pub(super) fn device_scene_twin<const N: usize, D>(
    config: &Config,
    device: D,
    calibration: SimCalibration,
) -> Result<SceneTwin<N, D>, ExitCode>
where
    D: videt_runtime::runtime_device::RuntimeDevice<N>,
{
    let calibrated = device_calibrated(D::KIND.name(), calibration)?;
    let start = videt_assembly::twin_scene::demo_start(&device);
    let guides = device.logged_guides_m();
    let layout = super::relief::layout_for(config, &guides[..N]);
    let scene = videt_assembly::twin_scene::demo_scene_for(config, device, start, 1);
    Ok(SceneTwin {
        twin: scene.twin,
        cycle: setup::control_cycle_for(config, device, WireZero::default(), calibrated),
        layout,
    })
}

/// Whether a device other than the WireMan renders forces on the twin: with the configured
/// geometry yes, with `--sim-calibration none` no; auto-initialization measures the WireMan's
/// base triangle and is refused.
fn device_calibrated(name: &str, calibration: SimCalibration) -> Result<bool, ExitCode> {
    match calibration {
        SimCalibration::Config => Ok(true),
        SimCalibration::None => {
            warn!("forces will not be rendered (not calibrated): --sim-calibration none");
            Ok(false)
        }
        // The plan refuses it already; refused here too rather than assumed.
        SimCalibration::Init => {
            error!("{}", crate::plan::init_refused(name));
            Err(ExitCode::from(2))
        }
    }
}

/// The twin's calibration as `--sim-calibration` chooses. Returns the rig, the encoder zeros and
/// whether forces may be rendered.
fn calibrate_twin(
    config: &Config,
    scene: &mut DemoScene,
    configured: Rig3,
    source: SimCalibration,
) -> (Rig3, WireZero, bool) {
    match source {
        SimCalibration::Config => {
            info!("twin calibration: the configured guides (the twin's true geometry)");
            return (configured, WireZero::default(), true);
        }
        SimCalibration::None => {
            warn!("forces will not be rendered (not calibrated): --sim-calibration none");
            return (configured, WireZero::default(), false);
        }
        SimCalibration::Init => {}
    }
    let operator = scene.twin.operator().clone();
    let start = scene.twin.plant().position_m();
    // A signal during the start-up initialization cancels it (the service then starts
    // uncalibrated and stops at once: its own handlers see the same signal pending).
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        let _ = signal_hook::flag::register(signal, std::sync::Arc::clone(&stop));
    }
    match crate::init::daemon::initialize_twin(config, &mut scene.twin, operator, start, 1, &stop)
        .map_err(|e| e.to_string())
        .and_then(|o| videt_runtime::calibration::from_calibration(config, &o.calibration))
    {
        Ok(s) => {
            let c = s
                .calibration
                .as_ref()
                .map(|c| c.sides_m)
                .unwrap_or_default();
            info!(
                d01_mm = c[0] * 1e3,
                d02_mm = c[1] * 1e3,
                d12_mm = c[2] * 1e3,
                "twin auto-initialized at start-up"
            );
            (s.rig, s.wire_zero, true)
        }
        Err(e) => {
            warn!("forces will not be rendered (not calibrated): twin auto-initialization failed: {e}");
            (configured, WireZero::default(), false)
        }
    }
}

/// The WireMan touching the check wall: on the HAL twin with its tension readings corrected as
/// the device's are (the strain-gauge calibration beside the calibration file), or behind the
/// CAN twin's drives.
pub(super) fn run_wall(
    config: &Config,
    rig: Rig3,
    calibration: SimCalibration,
    sim: SimMode,
    options: &mut ServiceOptions,
    calibration_path: &std::path::Path,
) -> ExitCode {
    let what = match sim {
        SimMode::Hal => {
            "digital twin: a virtual wall, a virtual operator touching it and sliding along it"
        }
        SimMode::Can => {
            "digital twin behind CiA 402 drives on a userspace CAN bus: a virtual wall, a \
             virtual operator touching it and sliding along it"
        }
    };
    let (mut scene, cycle) = wall_demo(config, rig, calibration, options, what);
    match sim {
        SimMode::Hal => {
            // The other twins are wired in `run_on_twin`.
            wire_as_configured(&mut scene.twin, config, sim);
            run_with_tension_correction(
                RealTimeTwin::new(scene.twin),
                FixedSurface(scene.wall),
                cycle,
                options,
                calibration_path,
                ServiceExtras::default(),
            )
        }
        SimMode::Can => run_on_twin(
            sim,
            scene.twin,
            FixedSurface(scene.wall),
            cycle,
            options,
            ServiceExtras::default(),
        ),
    }
}

/// The twin's wall demonstration: the scene, calibrated as `calibration` says, its control cycle,
/// and the colour under the finger from a demo image over the explored area.
fn wall_demo(
    config: &Config,
    rig: Rig3,
    calibration: SimCalibration,
    options: &mut ServiceOptions,
    what: &str,
) -> (DemoScene, WiremanCycle) {
    let mut scene = videt_assembly::twin_scene::demo_scene(config, 1);
    tracing::info!(
        rate_hz = config.control.rate_hz,
        wall_z_m = scene.wall_z_m,
        "{what}"
    );
    options.what = what.to_string();
    let (rig, wire_zero, calibrated) = calibrate_twin(config, &mut scene, rig, calibration);
    let cycle = setup::control_cycle(config, rig, wire_zero, calibrated);
    if colour_enabled(config) {
        match crate::colour_thread::demo_colour(
            &config.rig.guides_m,
            scene.wall_z_m,
            &config.colour,
        ) {
            Ok(source) => options.colour = Some(source),
            Err(e) => tracing::warn!("colour rendering disabled: {e}"),
        }
    }
    (scene, cycle)
}
