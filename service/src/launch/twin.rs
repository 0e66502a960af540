//! The twin's scenes: the WireMan touching the check wall, a bas-relief box, the relief of a
//! real stereo pair or of a folder of camera pairs; the other devices touching the wall. Each
//! builds its surface feed and vision thread, calibrates the twin as the plan says, and runs
//! the service on the HAL or the CAN twin.

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

use super::camera::start_camera_feed;
use super::start::{colour_enabled, relief_channel, run_on_twin, run_with_tension_correction};
use crate::plan::{SimCalibration, SimMode};
use crate::service::{run_service_with, ServiceExtras, ServiceOptions};
use crate::service_hardware::ServiceHardware;

/// The twin touching the relief of a folder of raw pairs played as a camera, through the same
/// camera feed as the device.
pub(super) fn run_camera_relief_demo(
    config: &Config,
    rig: Rig3,
    options: &mut ServiceOptions,
    calibration: SimCalibration,
    dir: &std::path::Path,
) -> ExitCode {
    use crate::camera_relief::CalibratedRig;
    use crate::relief_scene::{sweep_operator, ReliefLayout, SweepPath};
    // Played like a free-running camera at the device's frame rate.
    let period = std::time::Duration::from_secs_f64(1.0 / f64::from(config.vision.frame_rate_hz));
    let camera =
        match videt_drivers::camera::file_source::FileStereoSource::from_folder(dir, period) {
            Ok(c) => c,
            Err(e) => {
                error!("camera scene: {e}");
                return ExitCode::from(2);
            }
        };
    let stereo_rig =
        match CalibratedRig::load(std::path::Path::new(&config.vision.stereo_calibration)) {
            Ok(r) => r,
            Err(e) => {
                error!("camera scene: stereo calibration {e} (--stereo-calibration FILE)");
                return ExitCode::from(2);
            }
        };
    let camera_feed = match start_camera_feed(
        config,
        camera,
        dir.display().to_string(),
        stereo_rig,
        crate::colour_thread::ColourOutputs::Recording,
    ) {
        Ok(f) => f,
        Err(e) => {
            error!("camera scene: {e}");
            return ExitCode::FAILURE;
        }
    };
    let mut scene = videt_assembly::twin_scene::demo_scene(config, 1);
    let (rig, wire_zero, calibrated) = calibrate_twin(config, &mut scene, rig, calibration);
    let layout = ReliefLayout::for_config(config);
    let start = scene.twin.plant().position_m();
    let (operator, _) = sweep_operator(&layout, &camera_feed.first, start, &SweepPath::default());
    scene.twin.set_operator(operator);
    info!("digital twin: a virtual operator sweeping across the relief of a camera's pairs");
    options.what = format!(
        "digital twin: a virtual operator sweeping across the relief of the camera pairs in {}",
        dir.display()
    );
    options.colour = camera_feed.colour;
    let cycle = setup::control_cycle(config, rig, wire_zero, calibrated);
    run_service_with(
        RealTimeTwin::new(scene.twin),
        camera_feed.feed,
        cycle,
        options,
        camera_feed.extras,
    )
}

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
    let calibrated = match calibration {
        SimCalibration::Config => true,
        SimCalibration::None => {
            warn!("forces will not be rendered (not calibrated): --sim-calibration none");
            false
        }
        // The plan refuses it already; refused here too rather than assumed.
        SimCalibration::Init => {
            error!("{}", crate::plan::init_refused(name));
            return ExitCode::from(2);
        }
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

/// The twin with the bas-relief box: built at start-up, rebuilt every second on a vision thread,
/// rendered through the proxy with blended swaps.
pub(super) fn run_relief_demo(
    config: &Config,
    rig: Rig3,
    options: &ServiceOptions,
    calibration: SimCalibration,
    sim: SimMode,
) -> ExitCode {
    use crate::relief_scene::{box_operator, box_relief, ReliefLayout};

    let layout = ReliefLayout::for_config(config);
    let (model, report) = match box_relief(&layout, 0.0) {
        Ok(m) => m,
        Err(e) => {
            error!("surface: {e}");
            return ExitCode::FAILURE;
        }
    };
    tracing::info!(
        vertices = report.vertices,
        triangles = report.triangles,
        constraints = report.constraints_kept,
        build_us = (report.timings.cleaning
            + report.timings.crossings
            + report.timings.triangulation
            + report.timings.model)
            .as_micros() as u64,
        "digital twin: a bas-relief box, a virtual operator sliding over it and off its edge"
    );
    let (mut writer, feed) = match relief_channel(config, model) {
        Ok(c) => c,
        Err(code) => return code,
    };
    let priority = videt_runtime::rt::vision_fifo_priority(&config.realtime);
    // `sim-fault vision-stall` holds the thread back (a stalled camera).
    let stall = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let stalled = std::sync::Arc::clone(&stall);
    let vision = std::thread::Builder::new()
        .name("videt-vision".into())
        .spawn(move || {
            videt_runtime::rt::enter_vision_priority(priority);
            loop {
                std::thread::sleep(std::time::Duration::from_secs(1));
                if stalled.load(std::sync::atomic::Ordering::Relaxed) {
                    continue;
                }
                match box_relief(&layout, 0.0) {
                    Ok((model, _)) => {
                        writer.publish(model);
                    }
                    Err(e) => tracing::warn!("surface rebuild failed: {e}"),
                }
            }
        });
    if let Err(e) = vision {
        error!("cannot start the vision thread: {e}");
        return ExitCode::FAILURE;
    }
    let mut scene = videt_assembly::twin_scene::demo_scene(config, 1);
    let (rig, wire_zero, calibrated) = calibrate_twin(config, &mut scene, rig, calibration);
    let start = scene.twin.plant().position_m();
    scene.twin.set_operator(box_operator(&layout, start, 6.0));
    let cycle = setup::control_cycle(config, rig, wire_zero, calibrated);
    let mut options = options.clone();
    options.what =
        "digital twin: a bas-relief box, a virtual operator sliding over it and off its edge"
            .into();
    if sim == SimMode::Can {
        options.what = format!("{} (drives on a simulated CAN bus)", options.what);
    }
    let extras = ServiceExtras {
        vision_stall: Some(stall),
        ..Default::default()
    };
    run_on_twin(sim, scene.twin, feed, cycle, &options, extras)
}

/// The twin with the bas-relief of a real stereo pair: the pipeline and the surface builder at
/// start-up, then live region updates around the finger on a vision thread, rendered through the
/// proxy with blended swaps.
pub(super) fn run_stereo_relief_demo(
    config: &Config,
    rig: Rig3,
    options: &ServiceOptions,
    calibration: SimCalibration,
    dir: Option<&std::path::Path>,
) -> ExitCode {
    use crate::relief_scene::{sweep_operator, ReliefLayout, SweepPath};
    use crate::stereo_relief::{
        spawn_live_updates, LiveSettings, LiveStats, StereoPair, StereoRelief,
    };

    let pair = match dir {
        None => StereoPair::demo(),
        Some(dir) => StereoPair::load_dir(dir).map(|(pair, nominal)| {
            if nominal {
                warn!(
                    "{}: no camera.toml: nominal camera (focal {} px, baseline {} m, disparities up to {} px)",
                    dir.display(),
                    pair.camera.focal_px,
                    pair.camera.baseline_m,
                    pair.camera.max_disparity_px
                );
            }
            pair
        }),
    };
    let pair = match pair {
        Ok(p) => p,
        Err(e) => {
            error!("stereo scene: {e}");
            return ExitCode::from(2);
        }
    };
    let name = pair.name.clone();
    let layout = ReliefLayout::for_config(config);
    let live = LiveSettings {
        checks: crate::stereo_relief::match_checks(&config.vision),
        ..LiveSettings::default()
    };
    let (relief, model, initial) = match StereoRelief::build(pair, &layout, live) {
        Ok(r) => r,
        Err(e) => {
            error!("stereo scene: {e}");
            return ExitCode::FAILURE;
        }
    };
    let rejected = initial.report.rejections.len();
    info!(
        pair = %name,
        matches = initial.matches,
        segments_3d = initial.segments_3d,
        constraints = initial.report.constraints_kept,
        rejected,
        depth_range_m = ?initial.depth_range_m,
        triangles = initial.report.triangles,
        pipeline_ms = initial.pipeline_time.as_secs_f64() * 1e3,
        build_ms = initial.build_time.as_secs_f64() * 1e3,
        "digital twin: the bas-relief of a real stereo pair, a virtual operator sweeping across it, live updates around the finger at {:.0} Hz",
        1.0 / live.update_period_s
    );
    let (writer, feed) = match relief_channel(config, model.clone()) {
        Ok(c) => c,
        Err(code) => return code,
    };
    let mut scene = videt_assembly::twin_scene::demo_scene(config, 1);
    let (rig, wire_zero, calibrated) = calibrate_twin(config, &mut scene, rig, calibration);
    let start = scene.twin.plant().position_m();
    let (operator, _) = sweep_operator(&layout, &model, start, &SweepPath::default());
    scene.twin.set_operator(operator);
    let (thimble_publisher, thimble_reader) = videt_runtime::thimble::thimble_channel();
    let stats = std::sync::Arc::new(LiveStats::default());
    let keepalive_s = (config.vision.surface_max_age_s / 4.0).max(0.05);
    if let Err(e) = spawn_live_updates(
        relief,
        model,
        writer,
        thimble_reader,
        std::sync::Arc::clone(&stats),
        keepalive_s,
        videt_runtime::rt::vision_fifo_priority(&config.realtime),
    ) {
        error!("cannot start the vision thread: {e}");
        return ExitCode::FAILURE;
    }
    let cycle = setup::control_cycle(config, rig, wire_zero, calibrated);
    let extras = ServiceExtras {
        vision_stall: None,
        thimble: Some(thimble_publisher),
        status_suffix: Some(Box::new(move || stats.status_text())),
        fault_causes: None,
        drives_report: None,
        live_image: None,
    };
    let mut options = options.clone();
    options.what = format!(
        "digital twin: a virtual operator sweeping across the bas-relief of the stereo pair {name}"
    );
    run_service_with(RealTimeTwin::new(scene.twin), feed, cycle, &options, extras)
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
    let (scene, cycle) = wall_demo(config, rig, calibration, options, what);
    match sim {
        SimMode::Hal => run_with_tension_correction(
            RealTimeTwin::new(scene.twin),
            FixedSurface(scene.wall),
            cycle,
            options,
            calibration_path,
            ServiceExtras::default(),
        ),
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
