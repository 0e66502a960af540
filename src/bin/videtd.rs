//! `videtd` — the VIDET service: runs the real-time control loop of the haptic interface.
//!
//! `videtd --sim` runs the real runtime and control code on the digital twin (a virtual wall and
//! a virtual operator who touches it and slides along it); `videtd --sim can` runs the same with
//! the twin's motors behind three simulated CiA 402 drives on a userspace CAN bus, through the
//! real CANopen drive driver. `--scene box` puts a bas-relief box in front of the twin (either),
//! `--scene stereo` the bas-relief of a real stereo pair (HAL twin), re-matched around the finger on a vision
//! thread while the operator sweeps across it. One status line per second; Ctrl-C or
//! SIGTERM ramps the forces out, powers the drives off and exits 0. Under systemd
//! (`Type=notify`) it reports READY=1 once the drives are enabled and pets the watchdog while the
//! control loop is healthy.
//!
//! Without `--sim` it runs on the device: the CiA 402 drives on the SocketCAN interface, the
//! strain-gauge converters and the e-stop that the configuration names, the geometry of the
//! calibration file, and the relief rebuilt from the cameras (built with `--features v4l`, a
//! stereo calibration installed) or else the check wall. `--sim --scene camera:DIR` runs the
//! same camera vision thread on the twin, with a folder of raw pairs as the camera.
//!
//! Forces are rendered only with a valid calibration (`videt init`); without one every wire is
//! held at minimum tension and the log says why. On the twin, `--sim-calibration` chooses where
//! the calibration comes from (the configured geometry, an auto-initialization at start-up, or
//! none).

use std::path::PathBuf;
use std::process::ExitCode;
use videt::WIREMAN_WIRES;

use clap::{Parser, ValueEnum};
use tracing::{error, info, warn};
use videt::can_twin::{self, CanTwin};
use videt::cycle::WireZero;
use videt::service::{run_service_with, ServiceOptions};
use videt::setup;
use videt::snapshot::FixedSurface;
use videt::twin_rt::RealTimeTwin;
use videt_rt_config::Config;

/// What the twin's operator touches.
#[derive(Debug, Clone, PartialEq, Eq)]
enum SimScene {
    /// A flat virtual wall.
    Wall,
    /// A bas-relief box built by the surface builder from known segments, rebuilt every second
    /// on a vision thread and rendered through the proxy.
    Box,
    /// The bas-relief of a real stereo pair (the compiled-in demo pair, or a pair directory),
    /// re-matched around the finger on a vision thread and rendered through the proxy.
    Stereo(Option<PathBuf>),
    /// Stereo pairs as a camera delivers them (a folder of raw left/right images played in a
    /// loop), rectified with the stereo calibration and rebuilt into a relief again and again:
    /// the device's vision thread, on the twin.
    Camera(PathBuf),
}

fn parse_scene(text: &str) -> Result<SimScene, String> {
    match text {
        "wall" => Ok(SimScene::Wall),
        "box" => Ok(SimScene::Box),
        "stereo" => Ok(SimScene::Stereo(None)),
        _ => match (text.strip_prefix("stereo:"), text.strip_prefix("camera:")) {
            (Some(""), _) => Err("stereo:DIR needs a directory".into()),
            (Some(dir), _) => Ok(SimScene::Stereo(Some(PathBuf::from(dir)))),
            (_, Some("")) => Err("camera:DIR needs a directory".into()),
            (_, Some(dir)) => Ok(SimScene::Camera(PathBuf::from(dir))),
            _ => Err(format!(
                "unknown scene {text:?}: expected wall, box, stereo, stereo:DIR or camera:DIR"
            )),
        },
    }
}

/// Which twin `--sim` runs on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum SimMode {
    /// The HAL-level physics twin (fast).
    Hal,
    /// The twin's motors behind three simulated CiA 402 drives on a userspace CAN bus, driven
    /// by the real CANopen drive driver.
    Can,
}

/// Where the twin's calibration comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum SimCalibration {
    /// The configured guides (the twin's truth), encoders homed.
    Config,
    /// Auto-initialization at start-up.
    Init,
    /// None: forces are not rendered.
    None,
}

/// VIDET service: the real-time control loop of the haptic interface.
#[derive(Debug, Parser)]
#[command(name = "videtd", version, about)]
struct Args {
    /// Run on the digital twin instead of the device.
    #[arg(long, value_enum, num_args = 0..=1, default_missing_value = "hal")]
    sim: Option<SimMode>,
    /// Configuration file (default: /etc/videt/videt.toml when present; with --sim, built-in
    /// defaults otherwise).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Stop cleanly after this many seconds.
    #[arg(long, value_name = "SECS")]
    duration: Option<f64>,
    /// With --sim: the scene the virtual operator touches: `wall` (a flat virtual wall), `box`
    /// (a bas-relief box built from known segments), `stereo` (the bas-relief of the compiled-in
    /// real stereo pair, Middlebury tsukuba, re-matched around the finger as it moves) or
    /// `stereo:DIR` (the same for the pair in DIR: left.png/right.png or .ppm, and optionally a
    /// camera.toml with focal_px, baseline_m, max_disparity_px) or `camera:DIR` (the raw
    /// pairs of DIR, `*left*`/`*right*` images, as a camera delivering them in a loop at
    /// `vision.frame_rate_hz`: rectified with the stereo calibration and turned into reliefs as
    /// the device's cameras are).
    /// Without --sim the scene is the cameras' when a stereo calibration is installed, else
    /// the wall.
    #[arg(long, value_name = "SCENE", value_parser = parse_scene, default_value = "wall")]
    scene: SimScene,
    /// Stereo calibration of the cameras (overrides vision.stereo_calibration).
    #[arg(long, value_name = "FILE")]
    stereo_calibration: Option<PathBuf>,
    /// Control socket path (overrides socket.path).
    #[arg(long, value_name = "PATH")]
    socket: Option<PathBuf>,
    /// Run without the control socket.
    #[arg(long, conflicts_with = "socket")]
    no_socket: bool,
    /// Directory of the session log (overrides telemetry.directory).
    #[arg(long, value_name = "DIR")]
    telemetry_dir: Option<PathBuf>,
    /// Run without the per-period telemetry log.
    #[arg(long, conflicts_with = "telemetry_dir")]
    no_telemetry: bool,
    /// Calibration file (default: `files.calibration` of the configuration). Without a valid
    /// one no force is rendered and the log says why. With --sim, `--sim-calibration` decides
    /// instead; this file's directory still holds the strain-gauge calibration the twin's
    /// readings are corrected with.
    #[arg(long, value_name = "FILE")]
    calibration: Option<PathBuf>,
    /// With --sim, where the twin's calibration comes from: `config` (the configured guides are
    /// the twin's true geometry and its encoders start homed: a perfect calibration), `init`
    /// (auto-initialize the twin at start-up with the procedure `videt init` runs; start-up takes
    /// longer), `none` (uncalibrated: every wire at minimum tension, no force rendered).
    #[arg(long, value_enum, default_value = "config", requires = "sim")]
    sim_calibration: SimCalibration,
    /// Motors lock file (default: `files.motors_lock`; with --sim none: the twin is private to
    /// this process).
    #[arg(long, value_name = "FILE")]
    lock: Option<PathBuf>,
    /// With --sim: the twin's true guide points, metres, in the frame plane: "X,Y;X,Y;X,Y"
    /// (replaces the configured `rig.guides_m`), so `videt init` through the control socket can
    /// be rehearsed on any frame.
    #[arg(
        long,
        value_name = "X,Y;X,Y;X,Y",
        requires = "sim",
        allow_hyphen_values = true
    )]
    sim_guides: Option<String>,
}

const DEFAULT_CONFIG: &str = "/etc/videt/videt.toml";

fn load_config(args: &Args) -> Result<Config, String> {
    match &args.config {
        Some(path) => Config::load(path).map_err(|e| e.to_string()),
        None if std::path::Path::new(DEFAULT_CONFIG).exists() => {
            Config::load(std::path::Path::new(DEFAULT_CONFIG)).map_err(|e| e.to_string())
        }
        None if args.sim.is_some() => Ok(Config::default()),
        None => Err(format!(
            "no configuration: pass --config FILE or install {DEFAULT_CONFIG}"
        )),
    }
}

fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "info".into()),
        )
        .with_writer(std::io::stderr)
        .init();
    let args = Args::parse();
    let mut config = match load_config(&args) {
        Ok(c) => c,
        Err(e) => {
            error!("{e}");
            return ExitCode::from(2);
        }
    };
    info!("{}", config.describe_drive_units());
    // A rate the configured bus cannot carry is refused where a bus carries it: on the device
    // and on the CAN twin. The HAL twin has no bus; it says so and runs.
    match (videt::bus_budget::check(&config), args.sim) {
        (Ok(_), _) => info!("{}", videt::bus_budget::describe(&config)),
        (Err(e), Some(SimMode::Hal)) => {
            warn!("{e} (the HAL twin has no CAN bus: running anyway)")
        }
        (Err(e), _) => {
            error!("{e}");
            return ExitCode::from(2);
        }
    }
    // A tension sensor too slow for the configured PI gains is refused (on the twin too: its
    // sensors have the configured converter's timing) unless the degraded mode is asked for.
    match videt::tension_budget::plan(&config) {
        Ok(videt::tension_budget::TensionLoopPlan::Full(_)) => {
            info!("{}", videt::tension_budget::describe(&config))
        }
        Ok(videt::tension_budget::TensionLoopPlan::Degraded { .. }) => {
            warn!("{}", videt::tension_budget::describe(&config))
        }
        Err(e) => {
            error!("{e}");
            return ExitCode::from(2);
        }
    }
    if let Some(text) = &args.sim_guides {
        match videt::init::twin::parse_guides(text) {
            Ok(g) => config.rig.guides_m = core::array::from_fn(|i| [g[i].x, g[i].y]),
            Err(e) => {
                error!("{e}");
                return ExitCode::from(2);
            }
        }
    }
    if let Some(d) = args.duration {
        if !(d.is_finite() && d > 0.0) {
            error!("--duration must be a positive number of seconds, got {d}");
            return ExitCode::from(2);
        }
    }
    if let Some(p) = &args.stereo_calibration {
        config.vision.stereo_calibration = p.display().to_string();
    }
    let mut options = ServiceOptions::from_config(config.clone());
    options.duration_s = args.duration;
    // Where `videt init` through the control socket writes the calibration (the twin's default
    // is the one `videt init --sim` uses).
    options.calibration_path = Some(match (&args.calibration, args.sim) {
        (Some(p), _) => p.clone(),
        (None, Some(_)) => videt::init::daemon::sim_state_dir().join("calibration-sim.toml"),
        (None, None) => PathBuf::from(&config.files.calibration),
    });
    if args.no_socket {
        options.socket_path = None;
    } else if let Some(p) = &args.socket {
        options.socket_path = Some(p.clone());
    }
    if args.no_telemetry {
        options.telemetry_dir = None;
    } else if let Some(d) = &args.telemetry_dir {
        options.telemetry_dir = Some(d.clone());
    }
    let rig = match setup::rig(&config) {
        Ok(r) => r,
        Err(e) => {
            error!("rig geometry: {e}");
            return ExitCode::from(2);
        }
    };
    // One process at a time drives the motors (the `videt` tool takes the same lock). A twin is
    // private to its process, so with --sim the lock is taken only when --lock asks for it.
    let lock_path = match (&args.lock, args.sim) {
        (Some(p), _) => Some(p.clone()),
        (None, None) => Some(PathBuf::from(&config.files.motors_lock)),
        (None, Some(_)) => None,
    };
    let _motors = match lock_path
        .map(|p| videt::init::MotorsLock::acquire(&p))
        .transpose()
    {
        Ok(l) => l,
        Err(e) => {
            error!("{e}");
            return ExitCode::from(23);
        }
    };
    if config.rig.device != "wireman3" {
        return run_other_device(&config, &args, &mut options);
    }
    if args.sim == Some(SimMode::Can) && !matches!(args.scene, SimScene::Wall | SimScene::Box) {
        warn!(
            "--scene stereo and camera apply to the HAL twin only: the CAN twin touches the wall"
        );
    }
    if let (Some(SimMode::Hal), SimScene::Camera(dir)) = (args.sim, &args.scene) {
        return run_camera_relief_demo(&config, rig, &mut options, args.sim_calibration, dir);
    }
    if let (Some(SimMode::Hal), SimScene::Stereo(dir)) = (args.sim, &args.scene) {
        return run_stereo_relief_demo(
            &config,
            rig,
            &options,
            args.sim_calibration,
            dir.as_deref(),
        );
    }
    match args.sim {
        Some(sim) if args.scene == SimScene::Box => {
            run_relief_demo(&config, rig, &options, args.sim_calibration, sim)
        }
        Some(SimMode::Hal) => {
            let (scene, cycle) = wall_demo(
                &config,
                rig,
                args.sim_calibration,
                &mut options,
                "digital twin: a virtual wall, a virtual operator touching it and sliding along it",
            );
            let calibration_path = options.calibration_path.clone().unwrap_or_default();
            run_with_tension_correction(
                RealTimeTwin::new(scene.twin),
                FixedSurface(scene.wall),
                cycle,
                &options,
                &calibration_path,
                videt::service::ServiceExtras::default(),
            )
        }
        Some(SimMode::Can) => {
            let (scene, cycle) = wall_demo(
                &config,
                rig,
                args.sim_calibration,
                &mut options,
                "digital twin behind CiA 402 drives on a userspace CAN bus: a virtual wall, a virtual operator touching it and sliding along it",
            );
            let dictionary = match videt::drive_dictionary::for_config(&config) {
                Ok(d) => d,
                Err(e) => {
                    error!("simulated CAN drives: {e}");
                    return ExitCode::FAILURE;
                }
            };
            let mut hw = match CanTwin::new(
                scene.twin,
                can_twin::drive_config(&config),
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
            let extras = videt::service::ServiceExtras {
                fault_causes: Some(videt::hardware::drive_fault_causes(hw.fault_reports())),
                drives_report: Some(hw.startup_report()),
                ..Default::default()
            };
            let code = run_service_with(hw, FixedSurface(scene.wall), cycle, &options, extras);
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
        None => run_on_device(&config, &args, &mut options),
    }
}

/// The service on the device: the drives on SocketCAN, the strain-gauge converters and the
/// e-stop named by the configuration, the geometry of the calibration file. The wearer touches
/// the relief of what the cameras see when a stereo calibration is installed
/// (`vision.stereo_calibration`), else the check wall (a flat virtual wall in front of the
/// frame, as on the twin) and the log says why.
fn run_on_device(config: &Config, args: &Args, options: &mut ServiceOptions) -> ExitCode {
    if args.scene != SimScene::Wall {
        error!(
            "--scene {:?} needs --sim: on the device the surface is the cameras' or the check wall",
            args.scene
        );
        return ExitCode::from(2);
    }
    let path = options.calibration_path.clone().unwrap_or_default();
    let state = match videt::init::daemon::load(config, &path) {
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
    let mut hw = match videt::hardware::open_device(config) {
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
    let fault_causes = videt::hardware::drive_fault_causes(hw.drives_mut().fault_reports());
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
                videt::service::ServiceExtras {
                    fault_causes: Some(fault_causes),
                    drives_report: Some(drives_report),
                    ..Default::default()
                },
            )
        }
    }
}

/// The device's cameras (`vision.devices`) feeding reliefs, rectified with
/// `vision.stereo_calibration`.
fn device_camera_feed(config: &Config) -> Result<CameraFeed, String> {
    use videt::camera_relief::CalibratedRig;
    let rig = CalibratedRig::load(std::path::Path::new(&config.vision.stereo_calibration))
        .map_err(|e| format!("stereo calibration {e}"))?;
    #[cfg(feature = "v4l")]
    {
        use videt_drivers::camera::v4l_stereo::{V4lStereo, V4lStereoConfig};
        let [left, right] = &config.vision.devices;
        let camera = V4lStereo::open(&V4lStereoConfig {
            left: left.into(),
            right: right.into(),
            width: rig.size_px[0],
            height: rig.size_px[1],
            pair_tolerance: std::time::Duration::from_secs_f64(
                config.vision.pair_tolerance_ms / 1e3,
            ),
            timeout: std::time::Duration::from_secs(1),
            buffers: 4,
            frame_rate_hz: config.vision.frame_rate_hz,
            prefer_colour: config.colour.enabled,
        })
        .map_err(|e| format!("cameras (vision.devices): {e}"))?;
        let vibrotactors = videt::colour_thread::ColourOutputs::Gpio {
            chip: config.sensors.gpio_chip.clone(),
            lines: config.sensors.vibrotactor_lines,
        };
        start_camera_feed(
            config,
            camera,
            format!("cameras {left} + {right}"),
            rig,
            vibrotactors,
        )
    }
    #[cfg(not(feature = "v4l"))]
    {
        let _ = rig;
        Err(
            "this videtd is built without V4L2 capture (cargo build --release --features v4l)"
                .into(),
        )
    }
}

/// A relief feed from a camera.
struct CameraFeed {
    /// What the control loop renders.
    feed: videt::relief_feed::ReliefFeed,
    /// The camera thread's counters on the status line.
    extras: videt::service::ServiceExtras,
    /// The first relief.
    first: videt_vision::surface::ReliefModel,
    /// The colour under the finger from the camera's left frames.
    colour: Option<videt::colour_thread::ColourSource>,
}

/// Build the first relief from `camera` (rectified by `rig`), open the relief channel and
/// start the thread that keeps it up to date (`camera_relief::spawn_camera_updates`).
fn start_camera_feed<C>(
    config: &Config,
    camera: C,
    name: String,
    rig: videt::camera_relief::CalibratedRig,
    colour_outputs: videt::colour_thread::ColourOutputs,
) -> Result<CameraFeed, String>
where
    C: videt_hal::StereoCamera + Send + 'static,
{
    use std::sync::atomic::AtomicBool;
    use std::sync::Arc;
    use videt::camera_relief::{spawn_camera_updates, CameraRelief, CameraSchedule, CameraStats};
    use videt::relief_scene::ReliefLayout;
    let layout = ReliefLayout::for_config(config);
    // The colour under the finger, from the same left frames, mapped as the relief is.
    let colour = colour_enabled(config).then(|| {
        videt::colour_thread::camera_colour(&layout, rig.size_px, &config.colour, colour_outputs)
    });
    let (colour, colour_frames) = match colour {
        Some(Ok((source, writer))) => (Some(source), Some(writer)),
        Some(Err(e)) => {
            warn!("colour rendering disabled: {e}");
            (None, None)
        }
        None => (None, None),
    };
    let mut relief = CameraRelief::new(
        camera,
        name.clone(),
        rig,
        config.vision.max_disparity_px as f32,
        layout,
    )?;
    if let Some(writer) = colour_frames {
        relief = relief.with_colour(writer);
    }
    relief = relief.with_live_settings(videt::stereo_relief::LiveSettings {
        update_period_s: 1.0 / f64::from(config.vision.frame_rate_hz.max(1)),
        ..Default::default()
    });
    let (model, first) = relief.rebuild()?;
    info!(
        camera = %name,
        matches = first.matches,
        segments_3d = first.segments_3d,
        depth_range_m = ?first.depth_range_m,
        triangles = first.report.triangles,
        pipeline_ms = first.pipeline_time.as_secs_f64() * 1e3,
        build_ms = first.build_time.as_secs_f64() * 1e3,
        "relief from the cameras: updated around the finger every frame while it is over the scene (whole image every {} s), whole image every {} s while it is not",
        config.vision.full_refresh_s,
        config.vision.rebuild_period_s
    );
    let (writer, feed) = demo_relief_channel(config, model.clone())
        .map_err(|_| "invalid relief settings (see above)".to_string())?;
    let stats = Arc::new(CameraStats::default());
    let (thimble_publisher, thimble_reader) = videt::snapshot::thimble_channel();
    // The thread runs as long as the process: the service ends by exiting.
    let stop = Arc::new(AtomicBool::new(false));
    spawn_camera_updates(
        relief,
        writer,
        CameraSchedule {
            rebuild_period: std::time::Duration::from_secs_f64(config.vision.rebuild_period_s),
            full_refresh: std::time::Duration::from_secs_f64(config.vision.full_refresh_s),
        },
        Some(thimble_reader),
        Arc::clone(&stats),
        stop,
        videt::rt::vision_fifo_priority(&config.realtime),
    )
    .map_err(|e| format!("cannot start the vision thread: {e}"))?;
    let extras = videt::service::ServiceExtras {
        vision_stall: None,
        thimble: Some(thimble_publisher),
        fault_causes: None,
        drives_report: None,
        status_suffix: Some(Box::new(move || stats.status_text())),
    };
    Ok(CameraFeed {
        feed,
        extras,
        first: model,
        colour,
    })
}

/// The twin touching the relief of a folder of raw pairs played as a camera, through the same
/// camera feed as the device.
fn run_camera_relief_demo(
    config: &Config,
    rig: videt_control::Rig3,
    options: &mut ServiceOptions,
    calibration: SimCalibration,
    dir: &std::path::Path,
) -> ExitCode {
    use videt::camera_relief::CalibratedRig;
    use videt::relief_scene::{sweep_operator, ReliefLayout, SweepPath};
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
        videt::colour_thread::ColourOutputs::Recording,
    ) {
        Ok(f) => f,
        Err(e) => {
            error!("camera scene: {e}");
            return ExitCode::FAILURE;
        }
    };
    let mut scene = setup::demo_scene(config, 1);
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
    videt::service::run_service_with(
        RealTimeTwin::new(scene.twin),
        camera_feed.feed,
        cycle,
        options,
        camera_feed.extras,
    )
}

/// Run a device other than the WireMan: the planar prototype or the one-wire device, on the
/// HAL twin's wall scene. The CAN twin, the bas-relief scenes, the procedures and the device
/// mode are the WireMan's: asked for, they are refused with the reason.
fn run_other_device(config: &Config, args: &Args, options: &mut ServiceOptions) -> ExitCode {
    let name = config.rig.device.as_str();
    let Some(sim) = args.sim.filter(|_| args.scene == SimScene::Wall) else {
        error!(
            "rig.device = {name:?}: runs on the digital twin's wall scene (--sim or --sim can, \
             --scene wall); the bas-relief scenes and the device mode drive the three-wire WireMan"
        );
        return ExitCode::from(2);
    };
    match name {
        "planar2" => match setup::planar_device(config) {
            Ok(device) => device_wall_demo(config, device, sim, args.sim_calibration, options),
            Err(e) => {
                error!("rig.planar_guides_x_m: {e}");
                ExitCode::from(2)
            }
        },
        "polar1" => match setup::polar_device(config) {
            Ok(device) => device_wall_demo(config, device, sim, args.sim_calibration, options),
            Err(e) => {
                error!("rig.polar_guide_m: {e}");
                ExitCode::from(2)
            }
        },
        other => {
            error!(
                "rig.device = {other:?}: the service runs the wireman3, planar2 and polar1 devices \
                 (its session log keeps three wires); the four-wire device runs in the control \
                 benchmarks and `videt analyze`"
            );
            ExitCode::from(2)
        }
    }
}

/// The wall demonstration on the twin of a device other than the WireMan: the twin's geometry
/// is the configured one (`--sim-calibration config`) or forces are off (`none`);
/// auto-initialization measures the WireMan's base triangle and is refused here.
fn device_wall_demo<const N: usize, D>(
    config: &Config,
    device: D,
    sim: SimMode,
    calibration: SimCalibration,
    options: &mut ServiceOptions,
) -> ExitCode
where
    D: videt::runtime_device::RuntimeDevice<N>,
    RealTimeTwin<N, D>: videt::runtime_device::ServiceHardware<N>,
    CanTwin<N, RealTimeTwin<N, D>>: videt::runtime_device::ServiceHardware<N>,
{
    let name = D::KIND.name();
    let calibrated = match calibration {
        SimCalibration::Config => true,
        SimCalibration::None => {
            warn!("forces will not be rendered (not calibrated): --sim-calibration none");
            false
        }
        SimCalibration::Init => {
            error!(
                "--sim-calibration init: auto-initialization measures the WireMan's base \
                 triangle; the {name} device has none (use --sim-calibration config)"
            );
            return ExitCode::from(2);
        }
    };
    let start = setup::demo_start(&device);
    let scene = setup::demo_scene_for(config, device, start, 1);
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
    let cycle = setup::control_cycle_for(
        config,
        device,
        videt::cycle::WireZero::default(),
        calibrated,
    );
    match sim {
        SimMode::Hal => run_service_with(
            RealTimeTwin::new(scene.twin),
            FixedSurface(scene.wall),
            cycle,
            options,
            videt::service::ServiceExtras::default(),
        ),
        SimMode::Can => {
            options.what = format!("{} (drives on a simulated CAN bus)", options.what);
            let dictionary = match videt::drive_dictionary::for_config(config) {
                Ok(d) => d,
                Err(e) => {
                    error!("simulated CAN drives: {e}");
                    return ExitCode::FAILURE;
                }
            };
            match CanTwin::new(
                scene.twin,
                can_twin::drive_config::<N>(config),
                dictionary,
                config.drives.bitrate,
                Some(config.realtime.control_priority),
                usize::try_from(config.realtime.control_cpu).ok(),
            ) {
                Ok(mut hw) => {
                    let extras = videt::service::ServiceExtras {
                        fault_causes: Some(videt::hardware::drive_fault_causes(hw.fault_reports())),
                        drives_report: Some(hw.startup_report()),
                        ..Default::default()
                    };
                    run_service_with(hw, FixedSurface(scene.wall), cycle, options, extras)
                }
                Err(e) => {
                    error!("simulated CAN drives: {e}");
                    ExitCode::FAILURE
                }
            }
        }
    }
}

/// Run the service on `hw`, its tension readings corrected by the strain-gauge calibration
/// beside `calibration_path` when there is one (`videt tension-calibrate` writes it).
fn run_with_tension_correction<H, F>(
    hw: H,
    feed: F,
    cycle: videt::WiremanCycle,
    options: &ServiceOptions,
    calibration_path: &std::path::Path,
    extras: videt::service::ServiceExtras,
) -> ExitCode
where
    H: videt::runtime_device::ServiceHardware<WIREMAN_WIRES> + videt::init::remote::ProcedureDevice,
    F: videt::snapshot::SurfaceFeed + Send + 'static,
{
    use videt_rt_config::calibration::{CalibrationError, TensionCalibration};
    let tension_path = TensionCalibration::path_beside(calibration_path);
    match TensionCalibration::load(&tension_path) {
        Ok(tc) => {
            info!(file = %tension_path.display(), "tension readings corrected");
            run_service_with(
                videt::init::corrected::CorrectedTensions::new(hw, tc),
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

/// The twin with the bas-relief box: built at start-up, rebuilt every second on a vision thread,
/// rendered through the proxy with blended swaps.
fn run_relief_demo(
    config: &Config,
    rig: videt_control::Rig3,
    options: &ServiceOptions,
    calibration: SimCalibration,
    sim: SimMode,
) -> ExitCode {
    use videt::relief_scene::{box_operator, box_relief, ReliefLayout};

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
    let (mut writer, feed) = match demo_relief_channel(config, model) {
        Ok(c) => c,
        Err(code) => return code,
    };
    let priority = videt::rt::vision_fifo_priority(&config.realtime);
    // `sim-fault vision-stall` holds the thread back (a stalled camera).
    let stall = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let stalled = std::sync::Arc::clone(&stall);
    let vision = std::thread::Builder::new()
        .name("videt-vision".into())
        .spawn(move || {
            videt::rt::enter_vision_priority(priority);
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
    let mut scene = setup::demo_scene(config, 1);
    let (rig, wire_zero, calibrated) = calibrate_twin(config, &mut scene, rig, calibration);
    let start = scene.twin.plant().position_m();
    scene.twin.set_operator(box_operator(&layout, start, 6.0));
    let cycle = setup::control_cycle(config, rig, wire_zero, calibrated);
    let mut options = options.clone();
    options.what =
        "digital twin: a bas-relief box, a virtual operator sliding over it and off its edge"
            .into();
    let extras = || videt::service::ServiceExtras {
        vision_stall: Some(stall.clone()),
        ..Default::default()
    };
    match sim {
        SimMode::Hal => run_service_with(
            RealTimeTwin::new(scene.twin),
            feed,
            cycle,
            &options,
            extras(),
        ),
        SimMode::Can => {
            options.what = format!("{} (drives on a simulated CAN bus)", options.what);
            let dictionary = match videt::drive_dictionary::for_config(config) {
                Ok(d) => d,
                Err(e) => {
                    error!("simulated CAN drives: {e}");
                    return ExitCode::FAILURE;
                }
            };
            match CanTwin::new(
                scene.twin,
                can_twin::drive_config(config),
                dictionary,
                config.drives.bitrate,
                Some(config.realtime.control_priority),
                usize::try_from(config.realtime.control_cpu).ok(),
            ) {
                Ok(mut hw) => {
                    let extras = videt::service::ServiceExtras {
                        fault_causes: Some(videt::hardware::drive_fault_causes(hw.fault_reports())),
                        drives_report: Some(hw.startup_report()),
                        ..extras()
                    };
                    run_service_with(hw, feed, cycle, &options, extras)
                }
                Err(e) => {
                    error!("simulated CAN drives: {e}");
                    ExitCode::FAILURE
                }
            }
        }
    }
}

/// The twin with the bas-relief of a real stereo pair: the pipeline and the surface builder at
/// start-up, then live region updates around the finger on a vision thread, rendered through the
/// proxy with blended swaps.
fn run_stereo_relief_demo(
    config: &Config,
    rig: videt_control::Rig3,
    options: &ServiceOptions,
    calibration: SimCalibration,
    dir: Option<&std::path::Path>,
) -> ExitCode {
    use videt::relief_scene::{sweep_operator, ReliefLayout, SweepPath};
    use videt::stereo_relief::{
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
    let live = LiveSettings::default();
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
    let (writer, feed) = match demo_relief_channel(config, model.clone()) {
        Ok(c) => c,
        Err(code) => return code,
    };
    let mut scene = setup::demo_scene(config, 1);
    let (rig, wire_zero, calibrated) = calibrate_twin(config, &mut scene, rig, calibration);
    let start = scene.twin.plant().position_m();
    let (operator, _) = sweep_operator(&layout, &model, start, &SweepPath::default());
    scene.twin.set_operator(operator);
    let (thimble_publisher, thimble_reader) = videt::snapshot::thimble_channel();
    let stats = std::sync::Arc::new(LiveStats::default());
    let keepalive_s = (config.vision.surface_max_age_s / 4.0).max(0.05);
    if let Err(e) = spawn_live_updates(
        relief,
        model,
        writer,
        thimble_reader,
        std::sync::Arc::clone(&stats),
        keepalive_s,
        videt::rt::vision_fifo_priority(&config.realtime),
    ) {
        error!("cannot start the vision thread: {e}");
        return ExitCode::FAILURE;
    }
    let cycle = setup::control_cycle(config, rig, wire_zero, calibrated);
    let extras = videt::service::ServiceExtras {
        vision_stall: None,
        thimble: Some(thimble_publisher),
        status_suffix: Some(Box::new(move || stats.status_text())),
        fault_causes: None,
        drives_report: None,
    };
    let mut options = options.clone();
    options.what = format!(
        "digital twin: a virtual operator sweeping across the bas-relief of the stereo pair {name}"
    );
    videt::service::run_service_with(RealTimeTwin::new(scene.twin), feed, cycle, &options, extras)
}

/// The twin's calibration as `--sim-calibration` chooses. Returns the rig, the encoder zeros and
/// whether forces may be rendered.
fn calibrate_twin(
    config: &Config,
    scene: &mut setup::DemoScene,
    configured: videt_control::Rig3,
    source: SimCalibration,
) -> (videt_control::Rig3, WireZero, bool) {
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
    match videt::init::daemon::initialize_twin(config, &mut scene.twin, operator, start, 1, &stop)
        .map_err(|e| e.to_string())
        .and_then(|o| videt::init::daemon::from_calibration(config, &o.calibration))
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

/// The twin's wall demonstration: the scene, calibrated as `calibration` says, its control cycle,
/// and the colour under the finger from a demo image over the explored area.
fn wall_demo(
    config: &Config,
    rig: videt_control::Rig3,
    calibration: SimCalibration,
    options: &mut ServiceOptions,
    what: &str,
) -> (setup::DemoScene, videt::WiremanCycle) {
    let mut scene = setup::demo_scene(config, 1);
    tracing::info!(
        rate_hz = config.control.rate_hz,
        wall_z_m = scene.wall_z_m,
        "{what}"
    );
    options.what = what.to_string();
    let (rig, wire_zero, calibrated) = calibrate_twin(config, &mut scene, rig, calibration);
    let cycle = setup::control_cycle(config, rig, wire_zero, calibrated);
    if colour_enabled(config) {
        match videt::colour_thread::demo_colour(
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

/// Whether `[colour]` asks for the colour under the finger; says so when it does not.
fn colour_enabled(config: &Config) -> bool {
    if !config.colour.enabled {
        info!("colour rendering off (colour.enabled = false)");
    }
    config.colour.enabled
}

/// The relief channel of the twin's demonstrations, with the proxy, blend and stiffness of
/// `config`; an invalid setting is logged and ends the service (exit 2).
fn demo_relief_channel(
    config: &Config,
    model: videt_vision::surface::ReliefModel,
) -> Result<
    (
        videt::snapshot::SnapshotWriter<videt_vision::surface::ReliefModel>,
        videt::relief_feed::ReliefFeed,
    ),
    ExitCode,
> {
    videt::relief_feed::relief_channel_for(config, model).map_err(|e| {
        error!("{e}");
        ExitCode::from(2)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scenes_parse_with_clear_errors() {
        assert_eq!(parse_scene("wall").unwrap(), SimScene::Wall);
        assert_eq!(parse_scene("box").unwrap(), SimScene::Box);
        assert_eq!(parse_scene("stereo").unwrap(), SimScene::Stereo(None));
        assert_eq!(
            parse_scene("stereo:pairs/teddy").unwrap(),
            SimScene::Stereo(Some(PathBuf::from("pairs/teddy")))
        );
        assert!(parse_scene("stereo:").unwrap_err().contains("directory"));
        let e = parse_scene("cube").unwrap_err();
        assert!(e.contains("cube") && e.contains("stereo:DIR"), "{e}");
    }
}
