//! What the service is asked to run, checked against the configuration before anything is
//! opened: the device, the hardware (the device's, or a twin), what the control loop renders,
//! where the calibration comes from, and the service's settings. Every file the run needs is
//! loaded here and every refusal is here, with the exit code `videtd` ends with; the builder
//! (`launch`) then builds what the plan says.

use std::path::{Path, PathBuf};

use std::sync::Arc;
use std::time::Duration;

use tracing::{info, warn};
use videt_config::calibration::{CalibrationError, TensionCalibration};
use videt_config::Config;
use videt_control::{PlanarDevice, PolarDevice, Rig3};
use videt_drivers::camera::file_source::FileStereoSource;
use videt_runtime::calibration::CalibrationState;
use videt_runtime::setup;
use videt_sim::cia402_node::DriveDictionary;

use crate::camera_relief::CalibratedRig;
use crate::run::ServiceSettings;
use crate::stereo_relief::StereoPair;

/// The configuration file `videtd` reads when none is named.
pub const DEFAULT_CONFIG: &str = "/etc/videt/videt.toml";

/// Which twin `--sim` runs on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum SimMode {
    /// The HAL-level physics twin (fast).
    Hal,
    /// The twin's motors behind three simulated CiA 402 drives on a userspace CAN bus, driven
    /// by the real CANopen drive driver.
    Can,
}

/// Where the twin's calibration comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum SimCalibration {
    /// The configured guides (the twin's truth), encoders homed.
    Config,
    /// Auto-initialization at start-up.
    Init,
    /// None: forces are not rendered.
    None,
}

/// What the twin's operator touches.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SimScene {
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

/// Parse a scene as `--scene` takes it: `wall`, `box`, `stereo`, `stereo:DIR` or `camera:DIR`.
pub fn parse_scene(text: &str) -> Result<SimScene, String> {
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

/// What the command line asks of the service (`videtd --help` describes each).
#[derive(Debug, Clone, PartialEq)]
pub struct ServiceRequest {
    /// The twin to run on (`None`: the device).
    pub sim: Option<SimMode>,
    /// The configuration file (`None`: [`DEFAULT_CONFIG`] when present; with `sim`, built-in
    /// defaults otherwise).
    pub config: Option<PathBuf>,
    /// Stop cleanly after this many seconds.
    pub duration_s: Option<f64>,
    /// The scene the twin's operator touches.
    pub scene: SimScene,
    /// Stereo calibration of the cameras (overrides `vision.stereo_calibration`).
    pub stereo_calibration: Option<PathBuf>,
    /// Control socket path (overrides `socket.path`).
    pub socket: Option<PathBuf>,
    /// Run without the control socket.
    pub no_socket: bool,
    /// Directory of the session log (overrides `telemetry.directory`).
    pub telemetry_dir: Option<PathBuf>,
    /// Run without the session log.
    pub no_telemetry: bool,
    /// Calibration file (overrides `files.calibration`).
    pub calibration: Option<PathBuf>,
    /// With `sim`: where the twin's calibration comes from.
    pub sim_calibration: SimCalibration,
    /// Motors lock file (overrides `files.motors_lock`; with `sim` none unless named).
    pub lock: Option<PathBuf>,
    /// With `sim`: the twin's true guide points, `"X,Y;X,Y;X,Y"` metres.
    pub sim_guides: Option<String>,
    /// Serve the live view (`Some(None)`: on `live.address`; `Some(Some(addr))`: on that
    /// `HOST:PORT`), whatever `live.enabled` says.
    pub live: Option<Option<String>>,
}

/// The device the plan runs, built from the configuration (`rig.device`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PlannedDevice {
    /// The three-wire WireMan (its configured guides; on the device the calibration file's
    /// geometry replaces them).
    WireMan(Rig3),
    /// The planar two-wire prototype.
    Planar(PlanarDevice),
    /// The one-wire device with passive angle sensors.
    Polar(PolarDevice),
}

/// Why the service does not start (refused by the plan, or failing to launch), and the exit
/// code `videtd` ends with.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StartError {
    /// What a technician reads in the journal.
    pub message: String,
    /// The process exit code (2: the configuration or the command line is refused).
    pub exit_code: u8,
}

impl StartError {
    /// A configuration or command-line refusal (exit code 2).
    pub fn refused(message: impl Into<String>) -> StartError {
        StartError {
            message: message.into(),
            exit_code: 2,
        }
    }

    /// What could not be opened or started (exit code 1).
    pub fn failed(message: impl Into<String>) -> StartError {
        StartError {
            message: message.into(),
            exit_code: 1,
        }
    }
}

impl std::fmt::Display for StartError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message)
    }
}

/// The hardware the service runs on.
#[derive(Debug, Clone)]
pub enum PlannedHardware {
    /// The WireMan itself (its configured guides; the calibration file's geometry replaces
    /// them): the CiA 402 drives on SocketCAN, the strain-gauge converters and the e-stop the
    /// configuration names.
    Device(Rig3),
    /// A digital twin of the configured device.
    Twin(PlannedDevice, PlannedTwin),
}

impl PlannedHardware {
    /// Whether it is the WireMan's (the device, or its twin): the hardware the procedures and
    /// the tension correction are for.
    pub fn is_wireman(&self) -> bool {
        matches!(
            self,
            PlannedHardware::Device(_) | PlannedHardware::Twin(PlannedDevice::WireMan(_), _)
        )
    }
}

/// The twin the service runs on.
#[derive(Debug, Clone)]
pub enum PlannedTwin {
    /// The HAL twin.
    Hal,
    /// The twin's motors behind simulated CiA 402 drives on a userspace CAN bus, with the
    /// configured part's dictionary (`drives.description`), when one is configured.
    Can(Option<Arc<DriveDictionary>>),
}

impl PlannedTwin {
    /// Which twin it is.
    pub fn mode(&self) -> SimMode {
        match self {
            PlannedTwin::Hal => SimMode::Hal,
            PlannedTwin::Can(_) => SimMode::Can,
        }
    }
}

/// What the control loop renders, with every file it needs loaded.
#[derive(Debug, Clone)]
pub enum PlannedFeed {
    /// A flat virtual wall: the twin's wall scene, or the device's check wall when its cameras
    /// cannot be used (`instead_of_cameras` says why).
    Wall {
        /// Why the device's cameras are not used.
        instead_of_cameras: Option<String>,
    },
    /// The bas-relief box, rebuilt every second on a vision thread.
    Box,
    /// The bas-relief of a stereo pair, re-matched around the finger on a vision thread.
    Stereo(StereoPair),
    /// A folder of raw pairs played as a camera (`dir`), rectified with `rig`.
    CameraFolder {
        /// The folder.
        dir: PathBuf,
        /// Its pairs, played at the configured frame rate.
        source: FileStereoSource,
        /// The stereo calibration.
        rig: CalibratedRig,
    },
    /// The device's cameras (`vision.devices`), rectified with `vision.stereo_calibration`.
    Cameras(CalibratedRig),
}

/// Where the geometry forces are rendered with comes from.
#[derive(Debug, Clone)]
pub enum PlannedCalibration {
    /// The device's calibration file, loaded: its rig and encoder zeros, or why forces are off.
    File(Box<CalibrationState>),
    /// The configured geometry (the twin's truth), encoders homed.
    Configured,
    /// An auto-initialization of the WireMan's twin at start-up.
    AutoInit,
    /// None: forces are not rendered.
    None,
}

/// A checked plan: everything the builder (`launch`) needs to open the hardware or the twin,
/// build the surface feed and the cycle and start the threads, on three axes (the hardware,
/// the feed, the calibration), each chosen here once.
#[derive(Clone)]
pub struct ServicePlan {
    /// The hardware the service runs on: the device, or a twin of the configured device.
    pub hardware: PlannedHardware,
    /// What the control loop renders.
    pub feed: PlannedFeed,
    /// Where the rendering geometry comes from.
    pub calibration: PlannedCalibration,
    /// The strain-gauge calibration that corrects the WireMan's tension readings (beside the
    /// calibration file, written by `videt tension-calibrate`), when there is one.
    pub tension_correction: Option<TensionCalibration>,
    /// The motors lock to hold while running (`None`: a twin private to this process).
    pub lock_path: Option<PathBuf>,
    /// The service's settings, the configuration in force among them (`--sim-guides` and
    /// `--stereo-calibration` applied).
    pub settings: ServiceSettings,
}

/// The configuration `request` names: its file, else [`DEFAULT_CONFIG`] when installed, else
/// (on a twin) the built-in defaults.
pub fn load_config(request: &ServiceRequest) -> Result<Config, StartError> {
    let default = Path::new(DEFAULT_CONFIG);
    match &request.config {
        Some(path) => Config::load(path).map_err(|e| StartError::refused(e.to_string())),
        None if default.exists() => {
            Config::load(default).map_err(|e| StartError::refused(e.to_string()))
        }
        None if request.sim.is_some() => Ok(Config::default()),
        None => Err(StartError::refused(format!(
            "no configuration: pass --config FILE or install {DEFAULT_CONFIG}"
        ))),
    }
}

impl ServicePlan {
    /// Check `request` against `config` and say what runs, loading every file the run needs.
    /// Logs what the configuration implies (drive units, bus load, the tension loop's plan) as
    /// it goes.
    pub fn new(mut config: Config, request: &ServiceRequest) -> Result<ServicePlan, StartError> {
        info!("{}", config.describe_drive_units());
        // A rate the configured bus cannot carry is refused where a bus carries it: on the
        // device and on the CAN twin. The HAL twin has no bus; it says so and runs.
        match (videt_assembly::bus_budget::check(&config), request.sim) {
            (Ok(_), _) => info!("{}", videt_assembly::bus_budget::describe(&config)),
            (Err(e), Some(SimMode::Hal)) => {
                warn!("{e} (the HAL twin has no CAN bus: running anyway)")
            }
            (Err(e), _) => return Err(StartError::refused(e.to_string())),
        }
        // A tension sensor too slow for the configured PI gains is refused (on the twin too:
        // its sensors have the configured converter's timing) unless the degraded mode is
        // asked for.
        use videt_runtime::tension_budget::{describe, plan, TensionLoopPlan};
        match plan(&config) {
            Ok(TensionLoopPlan::Full(_)) => info!("{}", describe(&config)),
            Ok(TensionLoopPlan::Degraded { .. }) => warn!("{}", describe(&config)),
            Err(e) => return Err(StartError::refused(e.to_string())),
        }
        if let Some(text) = &request.sim_guides {
            let g = crate::init::twin::parse_guides(text).map_err(StartError::refused)?;
            config.rig.guides_m = core::array::from_fn(|i| [g[i].x, g[i].y]);
        }
        if let Some(d) = request.duration_s {
            if !(d.is_finite() && d > 0.0) {
                return Err(StartError::refused(format!(
                    "--duration must be a positive number of seconds, got {d}"
                )));
            }
        }
        if let Some(p) = &request.stereo_calibration {
            config.vision.stereo_calibration = p.display().to_string();
        }
        if let Some(address) = &request.live {
            config.live.enabled = true;
            if let Some(a) = address {
                config.live.address = a.clone();
            }
            config
                .live
                .host_port()
                .map_err(|e| StartError::refused(format!("--live: {e}")))?;
        }
        // The relief's proxy, blend and stiffness, checked before any relief is built.
        crate::relief_feed::check_relief_settings(&config)
            .map_err(|e| StartError::refused(e.to_string()))?;
        // Where `videt init` through the control socket writes the calibration (the twin's
        // default is the one `videt init --sim` uses).
        let calibration_path = match (&request.calibration, request.sim) {
            (Some(p), _) => p.clone(),
            (None, Some(_)) => crate::init::daemon::sim_state_dir().join("calibration-sim.toml"),
            (None, None) => PathBuf::from(&config.files.calibration),
        };
        // One process at a time drives the motors (the `videt` tool takes the same lock). A
        // twin is private to its process, so with --sim the lock is taken only when --lock
        // asks for it.
        let lock_path = match (&request.lock, request.sim) {
            (Some(p), _) => Some(p.clone()),
            (None, None) => Some(PathBuf::from(&config.files.motors_lock)),
            (None, Some(_)) => None,
        };
        if request.sim.is_none() && request.scene != SimScene::Wall {
            return Err(StartError::refused(format!(
                "--scene {:?} needs --sim: on the device the surface is the cameras' or the \
                 check wall",
                request.scene
            )));
        }
        let twin = match request.sim {
            None => None,
            Some(SimMode::Hal) => Some(PlannedTwin::Hal),
            Some(SimMode::Can) => Some(PlannedTwin::Can(
                videt_assembly::drive_dictionary::for_config(&config)
                    .map_err(|e| StartError::refused(format!("simulated CAN drives: {e}")))?,
            )),
        };
        let hardware = planned_hardware(&config, request, twin)?;
        let feed = planned_feed(&config, request)?;
        let calibration = match request.sim {
            None => PlannedCalibration::File(Box::new(
                videt_runtime::calibration::load(&config, &calibration_path)
                    .map_err(|e| StartError::refused(format!("calibration: {e}")))?,
            )),
            Some(_) => match request.sim_calibration {
                SimCalibration::Config => PlannedCalibration::Configured,
                SimCalibration::Init => PlannedCalibration::AutoInit,
                SimCalibration::None => PlannedCalibration::None,
            },
        };
        let tension_correction = hardware
            .is_wireman()
            .then(|| tension_correction(&calibration_path))
            .flatten();
        let mut settings = ServiceSettings::from_config(config);
        settings.duration_s = request.duration_s;
        settings.calibration_path = Some(calibration_path);
        if request.no_socket {
            settings.socket_path = None;
        } else if let Some(p) = &request.socket {
            settings.socket_path = Some(p.clone());
        }
        if request.no_telemetry {
            settings.telemetry_dir = None;
        } else if let Some(d) = &request.telemetry_dir {
            settings.telemetry_dir = Some(d.clone());
        }
        Ok(ServicePlan {
            hardware,
            feed,
            calibration,
            tension_correction,
            lock_path,
            settings,
        })
    }
}

/// The strain-gauge calibration beside `calibration_path`, when there is one; one that cannot
/// be read leaves the readings uncorrected and says why.
fn tension_correction(calibration_path: &Path) -> Option<TensionCalibration> {
    let path = TensionCalibration::path_beside(calibration_path);
    match TensionCalibration::load(&path) {
        Ok(tc) => {
            info!(file = %path.display(), "tension readings corrected");
            Some(tc)
        }
        Err(CalibrationError::Missing { .. }) => None,
        Err(e) => {
            warn!("tension readings not corrected: {e}");
            None
        }
    }
}

/// What `request` has the control loop render, its files loaded: on the twin the scene it
/// names; on the device the cameras' relief when a stereo calibration is installed (and the
/// service is built with V4L2 capture), else the check wall.
fn planned_feed(config: &Config, request: &ServiceRequest) -> Result<PlannedFeed, StartError> {
    let stereo_calibration = || CalibratedRig::load(Path::new(&config.vision.stereo_calibration));
    if request.sim.is_none() {
        let why = match stereo_calibration() {
            Err(e) => format!("stereo calibration {e}"),
            Ok(rig) if cfg!(feature = "v4l") => return Ok(PlannedFeed::Cameras(rig)),
            Ok(_) => {
                "this videtd is built without V4L2 capture (cargo build --release --features v4l)"
                    .into()
            }
        };
        return Ok(PlannedFeed::Wall {
            instead_of_cameras: Some(why),
        });
    }
    Ok(match &request.scene {
        SimScene::Wall => PlannedFeed::Wall {
            instead_of_cameras: None,
        },
        SimScene::Box => PlannedFeed::Box,
        SimScene::Stereo(None) => PlannedFeed::Stereo(
            StereoPair::demo().map_err(|e| StartError::refused(format!("stereo scene: {e}")))?,
        ),
        SimScene::Stereo(Some(dir)) => {
            let (pair, nominal) = StereoPair::load_dir(dir)
                .map_err(|e| StartError::refused(format!("stereo scene: {e}")))?;
            if nominal {
                warn!(
                    "{}: no camera.toml: nominal camera (focal {} px, baseline {} m, disparities up to {} px)",
                    dir.display(),
                    pair.camera.focal_px,
                    pair.camera.baseline_m,
                    pair.camera.max_disparity_px
                );
            }
            PlannedFeed::Stereo(pair)
        }
        SimScene::Camera(dir) => {
            // Played like a free-running camera at the device's frame rate.
            let period = Duration::from_secs_f64(1.0 / f64::from(config.vision.frame_rate_hz));
            let source = FileStereoSource::from_folder(dir, period)
                .map_err(|e| StartError::refused(format!("camera scene: {e}")))?;
            let rig = stereo_calibration().map_err(|e| {
                StartError::refused(format!(
                    "camera scene: stereo calibration {e} (--stereo-calibration FILE)"
                ))
            })?;
            PlannedFeed::CameraFolder {
                dir: dir.clone(),
                source,
                rig,
            }
        }
    })
}

/// The hardware `request` runs on: the WireMan itself, or `twin`, the twin of the configured
/// device (`rig.device`); refused with the reason where the request asks what only the WireMan
/// has (the device mode, auto-initialization).
fn planned_hardware(
    config: &Config,
    request: &ServiceRequest,
    twin: Option<PlannedTwin>,
) -> Result<PlannedHardware, StartError> {
    let rig = setup::rig(config).map_err(|e| StartError::refused(format!("rig geometry: {e}")))?;
    let name = config.rig.device.as_str();
    let Some(twin) = twin else {
        if name == "wireman3" {
            return Ok(PlannedHardware::Device(rig));
        }
        return Err(StartError::refused(format!(
            "rig.device = {name:?}: runs on the digital twin (--sim or --sim can); the device \
             mode drives the three-wire WireMan"
        )));
    };
    let device = match name {
        "wireman3" => return Ok(PlannedHardware::Twin(PlannedDevice::WireMan(rig), twin)),
        "planar2" => setup::planar_device(config)
            .map(PlannedDevice::Planar)
            .map_err(|e| StartError::refused(format!("rig.planar_guides_x_m: {e}")))?,
        "polar1" => setup::polar_device(config)
            .map(PlannedDevice::Polar)
            .map_err(|e| StartError::refused(format!("rig.polar_guide_m: {e}")))?,
        other => {
            return Err(StartError::refused(format!(
                "rig.device = {other:?}: the service runs the wireman3, planar2 and polar1 devices \
                 (its session log keeps three wires); the four-wire device runs in the control \
                 benchmarks and `videt analyze`"
            )))
        }
    };
    if request.sim_calibration == SimCalibration::Init {
        return Err(StartError::refused(init_refused(name)));
    }
    Ok(PlannedHardware::Twin(device, twin))
}

/// Why `--sim-calibration init` is refused on a device other than the WireMan (`name`).
pub(crate) fn init_refused(name: &str) -> String {
    format!(
        "--sim-calibration init: auto-initialization measures the WireMan's base triangle; \
         the {name} device has none (use --sim-calibration config)"
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn twin_request() -> ServiceRequest {
        ServiceRequest {
            sim: Some(SimMode::Hal),
            config: None,
            duration_s: Some(1.0),
            scene: SimScene::Wall,
            stereo_calibration: None,
            socket: None,
            no_socket: true,
            telemetry_dir: None,
            no_telemetry: true,
            calibration: None,
            sim_calibration: SimCalibration::Config,
            lock: None,
            sim_guides: None,
            live: None,
        }
    }

    fn refused(config: Config, request: &ServiceRequest) -> StartError {
        match ServicePlan::new(config, request) {
            Ok(_) => panic!("{request:?} was accepted"),
            Err(e) => e,
        }
    }

    #[test]
    fn live_turns_the_view_on_where_asked_and_refuses_an_unreadable_address() {
        let plan = ServicePlan::new(Config::default(), &twin_request()).unwrap();
        assert_eq!(plan.settings.live, None, "off by default");
        let mut request = twin_request();
        request.live = Some(None);
        let plan = ServicePlan::new(Config::default(), &request).unwrap();
        let live = plan.settings.live.unwrap();
        assert_eq!((live.host.as_str(), live.port), ("127.0.0.1", 8765));
        assert_eq!(live.rate_hz, 30.0);
        request.live = Some(Some("[::1]:9000".into()));
        let live = ServicePlan::new(Config::default(), &request)
            .unwrap()
            .settings
            .live
            .unwrap();
        assert_eq!((live.host.as_str(), live.port), ("::1", 9000));
        request.live = Some(Some("8765".into()));
        let e = refused(Config::default(), &request);
        assert!(
            e.to_string().contains("--live") && e.to_string().contains("HOST:PORT"),
            "{e}"
        );
    }

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

    #[test]
    fn a_twin_plan_takes_the_request_and_no_lock() {
        let mut request = twin_request();
        request.sim_guides = Some("0,0;0.4,0;0.2,0.3".into());
        let plan = ServicePlan::new(Config::default(), &request).unwrap();
        assert!(matches!(
            plan.hardware,
            PlannedHardware::Twin(PlannedDevice::WireMan(_), PlannedTwin::Hal)
        ));
        assert_eq!(plan.settings.config.rig.guides_m[1], [0.4, 0.0]);
        assert_eq!(plan.lock_path, None);
        assert_eq!(plan.settings.socket_path, None);
        assert_eq!(plan.settings.telemetry_dir, None);
        assert_eq!(plan.settings.duration_s, Some(1.0));
    }

    #[test]
    fn refusals_name_what_to_change_and_exit_2() {
        let mut request = twin_request();
        request.duration_s = Some(-1.0);
        let e = refused(Config::default(), &request);
        assert_eq!(e.exit_code, 2);
        assert!(e.message.contains("--duration"), "{e}");

        let mut request = twin_request();
        request.sim = None;
        request.scene = SimScene::Box;
        let e = refused(Config::default(), &request);
        assert!(e.message.contains("needs --sim"), "{e}");

        let mut config = Config::default();
        config.rig.device = "planar2".into();
        let mut request = twin_request();
        request.sim_calibration = SimCalibration::Init;
        let e = refused(config.clone(), &request);
        assert!(e.message.contains("base triangle"), "{e}");
        request.sim_calibration = SimCalibration::Config;
        request.sim = None;
        let e = refused(config.clone(), &request);
        assert!(e.message.contains("runs on the digital twin"), "{e}");
        request.sim = Some(SimMode::Hal);
        for scene in [SimScene::Wall, SimScene::Box, SimScene::Stereo(None)] {
            request.scene = scene;
            let plan = ServicePlan::new(config.clone(), &request).unwrap();
            assert!(matches!(
                plan.hardware,
                PlannedHardware::Twin(PlannedDevice::Planar(_), _)
            ));
        }
    }

    #[test]
    fn the_can_twin_keeps_every_scene_and_the_device_takes_the_lock() {
        for scene in [SimScene::Stereo(None), SimScene::Box] {
            let mut request = twin_request();
            request.sim = Some(SimMode::Can);
            request.scene = scene.clone();
            let plan = ServicePlan::new(Config::default(), &request).unwrap();
            assert!(matches!(
                plan.hardware,
                PlannedHardware::Twin(PlannedDevice::WireMan(_), PlannedTwin::Can(None))
            ));
            assert!(
                matches!(
                    (&scene, &plan.feed),
                    (SimScene::Stereo(None), PlannedFeed::Stereo(_))
                        | (SimScene::Box, PlannedFeed::Box)
                ),
                "{scene:?}: {:?}",
                plan.feed
            );
        }

        let mut request = twin_request();
        request.sim = None;
        let config = Config::default();
        let plan = ServicePlan::new(config.clone(), &request).unwrap();
        assert_eq!(
            plan.lock_path,
            Some(PathBuf::from(&config.files.motors_lock))
        );
        assert_eq!(
            plan.settings.calibration_path,
            Some(PathBuf::from(&config.files.calibration))
        );
        // Without an installed calibration: the check wall, and why; forces off, and why.
        assert!(
            matches!(&plan.feed, PlannedFeed::Wall { instead_of_cameras: Some(why) } if why.contains("stereo calibration")),
            "{:?}",
            plan.feed
        );
        assert!(
            matches!(&plan.calibration, PlannedCalibration::File(state) if !state.calibrated && state.reason.is_some()),
            "{:?}",
            plan.calibration
        );
    }

    #[test]
    fn the_files_a_scene_needs_are_loaded_while_planning_and_refused_with_exit_2() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("no-such-folder");
        let mut request = twin_request();
        request.scene = SimScene::Camera(missing.clone());
        let e = refused(Config::default(), &request);
        assert_eq!(e.exit_code, 2);
        assert!(e.message.starts_with("camera scene"), "{e}");
        request.scene = SimScene::Stereo(Some(missing));
        let e = refused(Config::default(), &request);
        assert_eq!(e.exit_code, 2);
        assert!(e.message.starts_with("stereo scene"), "{e}");
        // An invalid relief setting is refused before any relief is built.
        let mut config = Config::default();
        config.control.stiffness_n_per_m = f64::NAN;
        let e = refused(config, &twin_request());
        assert_eq!(e.exit_code, 2);
    }
}
