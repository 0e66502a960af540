//! The service on a digital twin of any device: the twin built in front of its wall with a
//! virtual operator, calibrated as the plan says (the configured geometry, none, or the
//! WireMan's auto-initialization at start-up), wired as the configuration corrects it, its
//! scene built over the area in front of its guides, then run as the HAL twin or behind
//! simulated CiA 402 drives on a userspace CAN bus.

use std::process::ExitCode;

use tracing::{info, warn};
use videt_assembly::can_twin::{self, CanTwin};
use videt_assembly::twin_rt::RealTimeTwin;
use videt_assembly::twin_scene::{thimble_start, wall_scene};
use videt_config::Config;
use videt_control::DeviceKind;
use videt_runtime::runtime_device::RuntimeDevice;
use videt_runtime::setup;
use videt_sim::Twin;

use super::calibration::TwinInit;
use super::{start::Starter, LaunchError};
use crate::colour_thread::ColourOutputs;
use crate::init::corrected::CorrectedTensions;
use crate::plan::{PlannedCalibration, PlannedFeed, PlannedTwin, SimMode};
use crate::relief_scene::SweepPath;
use crate::run::HardwareReports;
use crate::service_hardware::ServiceHardware;

/// Run the service on `hardware`, the twin of `device` (its configured geometry), rendering
/// `feed` with the geometry `calibration` gives.
pub fn run<const N: usize, D>(
    starter: &Starter,
    feed: PlannedFeed,
    calibration: &PlannedCalibration,
    device: D,
    hardware: PlannedTwin,
) -> Result<ExitCode, LaunchError>
where
    D: TwinInit<N>,
    CorrectedTensions<RealTimeTwin<N, D>>: ServiceHardware<N>,
    CorrectedTensions<CanTwin<N, RealTimeTwin<N, D>>>: ServiceHardware<N>,
{
    let config = &starter.settings.config;
    let sim = hardware.mode();
    let wall = wall_scene(config, device, thimble_start(&device), 1);
    let mut twin = wall.twin;
    let (device, wire_zero, calibrated) =
        super::calibration::resolve(config, device, calibration, Some(&mut twin));
    let cycle = setup::control_cycle_for(config, device, wire_zero, calibrated);
    let layout = layout_in_front_of(config, &device.logged_guides_m()[..N]);
    let describe = |what: &str| describe::<N, D>(what, sim);
    let mut scene = super::scene::build(config, feed, layout, ColourOutputs::Recording, &describe)?;
    let description = match scene.description.take() {
        Some(what) => what,
        None => {
            let what = wall_description::<N, D>(sim);
            info!(
                rate_hz = config.control.rate_hz,
                wall_z_m = wall.wall_z_m,
                "{what}"
            );
            scene.colour = wall_colour::<N, D>(config, wall.wall_z_m);
            what
        }
    };
    let start_m = twin.plant().position_m();
    if let Some(operator) = scene.operator(start_m, &sweep_path::<N, D>()) {
        twin.set_operator(operator);
    }
    wire_as_configured(&mut twin, config, sim);
    let PlannedTwin::Can(dictionary) = hardware else {
        return Ok(starter.start(
            RealTimeTwin::new(twin),
            scene,
            cycle,
            description,
            HardwareReports::default(),
        ));
    };
    let mut hw = CanTwin::new(
        twin,
        can_twin::drive_config::<N>(config),
        dictionary,
        config.drives.bitrate,
        Some(config.realtime.control_priority),
        usize::try_from(config.realtime.control_cpu).ok(),
    )
    .map_err(|e| LaunchError::failed(format!("simulated CAN drives: {e}")))?;
    let bus = hw.bus_stats();
    let reports = HardwareReports::of_drives(&mut hw);
    let code = starter.start(hw, scene, cycle, description, reports);
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
    Ok(code)
}

/// Wire `twin`, a rig built right, as `config` corrects it: a correction the rig does not need
/// shows as the mistake it makes on the device. The HAL twin applies the drives' directions
/// itself; behind simulated drives (`sim` CAN) the drivers apply them.
pub fn wire_as_configured<const N: usize, D: videt_control::WireDevice<N>>(
    twin: &mut Twin<N, D>,
    config: &Config,
    sim: SimMode,
) {
    use videt_assembly::as_built::{configured_wiring, DriveCorrections};
    let corrections = match sim {
        SimMode::Hal => DriveCorrections::InTwin,
        SimMode::Can => DriveCorrections::InDrivers,
    };
    // A wiring without permutations is always valid.
    let _ = twin.set_wiring(configured_wiring::<N>(config, corrections));
}

/// The explored area for a device whose guides are `guides_m`: the configured layout
/// ([`setup::relief_layout`]), centred on the mean of the device's guides.
pub fn layout_in_front_of(config: &Config, guides_m: &[[f64; 3]]) -> videt_relief::ReliefLayout {
    let n = guides_m.len().max(1) as f64;
    let centre = guides_m
        .iter()
        .fold([0.0, 0.0], |c, g| [c[0] + g[0] / n, c[1] + g[1] / n]);
    setup::relief_layout(config).centred_at(centre)
}

/// How the sweeping operator explores a relief on a device: across the area in two rows, or
/// along its centre line on the planar device (its thimble moves in that plane).
fn sweep_path<const N: usize, D: RuntimeDevice<N>>() -> SweepPath {
    match D::KIND {
        DeviceKind::Planar2 => SweepPath::along_centre_line(),
        _ => SweepPath::default(),
    }
}

/// A relief scene's `what` with the device named when it is not the WireMan, and the CAN bus
/// when `sim` has one.
fn describe<const N: usize, D: RuntimeDevice<N>>(what: &str, sim: SimMode) -> String {
    let mut what = match D::KIND {
        DeviceKind::Wireman3 => what.to_string(),
        kind => format!("{what} (the {} device, {N} wire{})", kind.name(), plural(N)),
    };
    if sim == SimMode::Can {
        what += " (drives on a simulated CAN bus)";
    }
    what
}

/// What a device's twin touching its wall is, on the HAL or the CAN twin.
fn wall_description<const N: usize, D: RuntimeDevice<N>>(sim: SimMode) -> String {
    const WALL: &str = "a virtual wall, a virtual operator touching it and sliding along it";
    match (D::KIND, sim) {
        (DeviceKind::Wireman3, SimMode::Hal) => format!("digital twin: {WALL}"),
        (DeviceKind::Wireman3, SimMode::Can) => {
            format!("digital twin behind CiA 402 drives on a userspace CAN bus: {WALL}")
        }
        (kind, sim) => {
            let what = format!(
                "digital twin of the {} device ({N} wire{}): {WALL}",
                kind.name(),
                plural(N)
            );
            match sim {
                SimMode::Hal => what,
                SimMode::Can => format!("{what} (drives on a simulated CAN bus)"),
            }
        }
    }
}

/// The colour under the finger on a wall scene: a demonstration image laid over the WireMan's
/// frame in front of the wall at `wall_z_m`; off on the other devices.
fn wall_colour<const N: usize, D: RuntimeDevice<N>>(
    config: &Config,
    wall_z_m: f64,
) -> Option<crate::colour_thread::ColourSource> {
    if D::KIND != DeviceKind::Wireman3 {
        if config.colour.enabled {
            info!("colour rendering off: the demonstration image is laid over the WireMan's frame");
        }
        return None;
    }
    if !crate::colour_thread::colour_enabled(config) {
        return None;
    }
    crate::colour_thread::demo_colour(&config.rig.guides_m, wall_z_m, &config.colour)
        .map_err(|e| warn!("colour rendering disabled: {e}"))
        .ok()
}

fn plural(n: usize) -> &'static str {
    if n == 1 {
        ""
    } else {
        "s"
    }
}
