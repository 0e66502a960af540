//! The twin's bas-relief scenes on every device: the box, the relief of a real stereo pair and
//! the relief of a folder of camera pairs, each with the vision thread that keeps it up to date
//! and a virtual operator who explores it, on the HAL or the CAN twin. The relief is laid out in
//! front of the device's guides; the planar device's operator sweeps along the line its plane
//! cuts through the relief.

use std::path::Path;
use std::process::ExitCode;

use tracing::{error, info, warn};
use videt_assembly::can_twin::CanTwin;
use videt_assembly::twin_rt::RealTimeTwin;
use videt_control::DeviceKind;
use videt_rt_config::Config;
use videt_runtime::cycle::ControlCycle;
use videt_runtime::runtime_device::RuntimeDevice;
use videt_sim::Twin;

use super::camera::start_camera_feed;
use super::start::{relief_channel, run_on_twin};
use crate::plan::SimMode;
use crate::relief_scene::{ReliefLayout, SweepPath};
use crate::service::{ServiceExtras, ServiceOptions};
use crate::service_hardware::ServiceHardware;

/// A device's twin and control cycle, calibrated as the plan says, and where its reliefs lie.
#[derive(Debug)]
pub struct SceneTwin<const N: usize, D: RuntimeDevice<N>> {
    /// The twin, the thimble at its start.
    pub twin: Twin<N, D>,
    /// The control cycle.
    pub cycle: ControlCycle<N, D>,
    /// The explorable area, in front of the device's guides.
    pub layout: ReliefLayout,
}

/// The explored area for a device whose guides are `guides_m`: the WireMan's layout
/// (`ReliefLayout::for_config`), centred on the mean of the device's guides.
pub fn layout_for(config: &Config, guides_m: &[[f64; 3]]) -> ReliefLayout {
    let n = guides_m.len().max(1) as f64;
    let centre = guides_m
        .iter()
        .fold([0.0, 0.0], |c, g| [c[0] + g[0] / n, c[1] + g[1] / n]);
    ReliefLayout::for_config(config).centred_at(centre)
}

impl<const N: usize, D: RuntimeDevice<N>> SceneTwin<N, D> {
    /// The twin, the cycle, the area, and how the sweeping operator explores it.
    fn into_parts(self) -> (Twin<N, D>, ControlCycle<N, D>, ReliefLayout, SweepPath) {
        let sweep = self.sweep();
        (self.twin, self.cycle, self.layout, sweep)
    }

    /// How the sweeping operator explores a relief on this device: across the area in two rows,
    /// or along its centre line on the planar device (its thimble moves in that plane).
    fn sweep(&self) -> SweepPath {
        match D::KIND {
            DeviceKind::Planar2 => SweepPath::along_centre_line(),
            _ => SweepPath::default(),
        }
    }

    /// `what` with the device named when it is not the WireMan, and the CAN bus when `sim` has
    /// one.
    fn describe(what: String, sim: SimMode) -> String {
        let mut what = match D::KIND {
            DeviceKind::Wireman3 => what,
            kind => format!("{what} (the {} device, {N} wire{})", kind.name(), plural(N)),
        };
        if sim == SimMode::Can {
            what += " (drives on a simulated CAN bus)";
        }
        what
    }
}

fn plural(n: usize) -> &'static str {
    if n == 1 {
        ""
    } else {
        "s"
    }
}

/// The twin with the bas-relief box: built at start-up, rebuilt every second on a vision
/// thread, a virtual operator pressing onto its top, sliding off its edge and back.
pub(super) fn run_box<const N: usize, D>(
    config: &Config,
    scene: SceneTwin<N, D>,
    options: &ServiceOptions,
    sim: SimMode,
) -> ExitCode
where
    D: RuntimeDevice<N>,
    RealTimeTwin<N, D>: ServiceHardware<N>,
    CanTwin<N, RealTimeTwin<N, D>>: ServiceHardware<N>,
{
    use crate::relief_scene::{box_operator, box_relief};

    let SceneTwin {
        mut twin,
        cycle,
        layout,
    } = scene;
    let (model, report) = match box_relief(&layout, 0.0) {
        Ok(m) => m,
        Err(e) => {
            error!("surface: {e}");
            return ExitCode::FAILURE;
        }
    };
    let mut options = options.clone();
    options.what = SceneTwin::<N, D>::describe(
        "digital twin: a bas-relief box, a virtual operator sliding over it and off its edge"
            .into(),
        sim,
    );
    info!(
        vertices = report.vertices,
        triangles = report.triangles,
        constraints = report.constraints_kept,
        build_us = (report.timings.cleaning
            + report.timings.crossings
            + report.timings.triangulation
            + report.timings.model)
            .as_micros() as u64,
        "{}",
        options.what
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
                    Err(e) => warn!("surface rebuild failed: {e}"),
                }
            }
        });
    if let Err(e) = vision {
        error!("cannot start the vision thread: {e}");
        return ExitCode::FAILURE;
    }
    let start = twin.plant().position_m();
    twin.set_operator(box_operator(&layout, start, 6.0));
    let extras = ServiceExtras {
        vision_stall: Some(stall),
        ..Default::default()
    };
    run_on_twin(sim, twin, feed, cycle, &options, extras)
}

/// The twin with the bas-relief of a real stereo pair: the pipeline and the surface builder at
/// start-up, then live region updates around the finger on a vision thread, rendered through the
/// proxy with blended swaps.
pub(super) fn run_stereo<const N: usize, D>(
    config: &Config,
    scene: SceneTwin<N, D>,
    options: &ServiceOptions,
    sim: SimMode,
    dir: Option<&Path>,
) -> ExitCode
where
    D: RuntimeDevice<N>,
    RealTimeTwin<N, D>: ServiceHardware<N>,
    CanTwin<N, RealTimeTwin<N, D>>: ServiceHardware<N>,
{
    use crate::relief_scene::sweep_operator;
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
    let (mut twin, cycle, layout, sweep) = scene.into_parts();
    let live = LiveSettings {
        checks: crate::stereo_relief::match_checks(&config.vision),
        patch_spacing_px: config.vision.patch_spacing_px,
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
    let start = twin.plant().position_m();
    let (operator, _) = sweep_operator(&layout, &model, start, &sweep);
    twin.set_operator(operator);
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
    let extras = ServiceExtras {
        vision_stall: None,
        thimble: Some(thimble_publisher),
        status_suffix: Some(Box::new(move || stats.status_text())),
        fault_causes: None,
        drives_report: None,
        live_image: None,
    };
    let mut options = options.clone();
    options.what = SceneTwin::<N, D>::describe(
        format!(
            "digital twin: a virtual operator sweeping across the bas-relief of the stereo pair {name}"
        ),
        sim,
    );
    run_on_twin(sim, twin, feed, cycle, &options, extras)
}

/// The twin touching the relief of a folder of raw pairs played as a camera, through the same
/// camera feed as the device.
pub(super) fn run_camera<const N: usize, D>(
    config: &Config,
    scene: SceneTwin<N, D>,
    options: &mut ServiceOptions,
    sim: SimMode,
    dir: &Path,
) -> ExitCode
where
    D: RuntimeDevice<N>,
    RealTimeTwin<N, D>: ServiceHardware<N>,
    CanTwin<N, RealTimeTwin<N, D>>: ServiceHardware<N>,
{
    use crate::camera_relief::CalibratedRig;
    use crate::relief_scene::sweep_operator;
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
    let stereo_rig = match CalibratedRig::load(Path::new(&config.vision.stereo_calibration)) {
        Ok(r) => r,
        Err(e) => {
            error!("camera scene: stereo calibration {e} (--stereo-calibration FILE)");
            return ExitCode::from(2);
        }
    };
    let (mut twin, cycle, layout, sweep) = scene.into_parts();
    let camera_feed = match start_camera_feed(
        config,
        camera,
        dir.display().to_string(),
        stereo_rig,
        layout,
        crate::colour_thread::ColourOutputs::Recording,
    ) {
        Ok(f) => f,
        Err(e) => {
            error!("camera scene: {e}");
            return ExitCode::FAILURE;
        }
    };
    let start = twin.plant().position_m();
    let (operator, _) = sweep_operator(&layout, &camera_feed.first, start, &sweep);
    twin.set_operator(operator);
    info!("digital twin: a virtual operator sweeping across the relief of a camera's pairs");
    options.what = SceneTwin::<N, D>::describe(
        format!(
            "digital twin: a virtual operator sweeping across the relief of the camera pairs in {}",
            dir.display()
        ),
        sim,
    );
    options.colour = camera_feed.colour;
    run_on_twin(
        sim,
        twin,
        camera_feed.feed,
        cycle,
        options,
        camera_feed.extras,
    )
}
