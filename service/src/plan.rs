//! What the service is asked to run, checked against the configuration before anything is
//! opened: the device, the hardware (the device's, or a twin), the scene, where the calibration
//! comes from, and the service's options. Every refusal is here, with the exit code `videtd`
//! ends with; the builder (`launch`) then builds what the plan says.

use std::path::{Path, PathBuf};

use tracing::{info, warn};
use videt_control::{PlanarDevice, PolarDevice, Rig3};
use videt_rt_config::Config;
use videt_runtime::setup;

use crate::service::ServiceOptions;

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

/// Why the service does not start, and the exit code it ends with.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PlanError {
    /// What a technician reads in the journal.
    pub message: String,
    /// The process exit code (2: the configuration or the command line is refused).
    pub exit_code: u8,
}

impl PlanError {
    /// A configuration or command-line refusal (exit code 2).
    fn refused(message: impl Into<String>) -> PlanError {
        PlanError {
            message: message.into(),
            exit_code: 2,
        }
    }
}

impl std::fmt::Display for PlanError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message)
    }
}

/// A checked plan: everything the builder (`launch`) needs to open the hardware or the
/// twin, build the cycle and start the threads.
#[derive(Clone)]
pub struct ServicePlan {
    /// The configuration in force (`--sim-guides` and `--stereo-calibration` applied).
    pub config: Config,
    /// The device.
    pub device: PlannedDevice,
    /// The twin to run on (`None`: the device's hardware).
    pub sim: Option<SimMode>,
    /// The scene the twin's operator touches (the wall on the device, and on the CAN twin).
    pub scene: SimScene,
    /// Where the twin's calibration comes from.
    pub twin_calibration: SimCalibration,
    /// The calibration file: loaded on the device, written by `videt init` through the socket.
    pub calibration_path: PathBuf,
    /// The motors lock to hold while running (`None`: a twin private to this process).
    pub lock_path: Option<PathBuf>,
    /// The service's options.
    pub options: ServiceOptions,
}

/// The configuration `request` names: its file, else [`DEFAULT_CONFIG`] when installed, else
/// (on a twin) the built-in defaults.
pub fn load_config(request: &ServiceRequest) -> Result<Config, PlanError> {
    let default = Path::new(DEFAULT_CONFIG);
    match &request.config {
        Some(path) => Config::load(path).map_err(|e| PlanError::refused(e.to_string())),
        None if default.exists() => {
            Config::load(default).map_err(|e| PlanError::refused(e.to_string()))
        }
        None if request.sim.is_some() => Ok(Config::default()),
        None => Err(PlanError::refused(format!(
            "no configuration: pass --config FILE or install {DEFAULT_CONFIG}"
        ))),
    }
}

impl ServicePlan {
    /// Check `request` against `config` and say what runs. Logs what the configuration
    /// implies (drive units, bus load, the tension loop's plan) as it goes.
    pub fn new(mut config: Config, request: &ServiceRequest) -> Result<ServicePlan, PlanError> {
        info!("{}", config.describe_drive_units());
        // A rate the configured bus cannot carry is refused where a bus carries it: on the
        // device and on the CAN twin. The HAL twin has no bus; it says so and runs.
        match (videt_assembly::bus_budget::check(&config), request.sim) {
            (Ok(_), _) => info!("{}", videt_assembly::bus_budget::describe(&config)),
            (Err(e), Some(SimMode::Hal)) => {
                warn!("{e} (the HAL twin has no CAN bus: running anyway)")
            }
            (Err(e), _) => return Err(PlanError::refused(e.to_string())),
        }
        // A tension sensor too slow for the configured PI gains is refused (on the twin too:
        // its sensors have the configured converter's timing) unless the degraded mode is
        // asked for.
        use videt_runtime::tension_budget::{describe, plan, TensionLoopPlan};
        match plan(&config) {
            Ok(TensionLoopPlan::Full(_)) => info!("{}", describe(&config)),
            Ok(TensionLoopPlan::Degraded { .. }) => warn!("{}", describe(&config)),
            Err(e) => return Err(PlanError::refused(e.to_string())),
        }
        if let Some(text) = &request.sim_guides {
            let g = crate::init::twin::parse_guides(text).map_err(PlanError::refused)?;
            config.rig.guides_m = core::array::from_fn(|i| [g[i].x, g[i].y]);
        }
        if let Some(d) = request.duration_s {
            if !(d.is_finite() && d > 0.0) {
                return Err(PlanError::refused(format!(
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
                .map_err(|e| PlanError::refused(format!("--live: {e}")))?;
        }
        let mut options = ServiceOptions::from_config(config.clone());
        options.duration_s = request.duration_s;
        // Where `videt init` through the control socket writes the calibration (the twin's
        // default is the one `videt init --sim` uses).
        let calibration_path = match (&request.calibration, request.sim) {
            (Some(p), _) => p.clone(),
            (None, Some(_)) => crate::init::daemon::sim_state_dir().join("calibration-sim.toml"),
            (None, None) => PathBuf::from(&config.files.calibration),
        };
        options.calibration_path = Some(calibration_path.clone());
        if request.no_socket {
            options.socket_path = None;
        } else if let Some(p) = &request.socket {
            options.socket_path = Some(p.clone());
        }
        if request.no_telemetry {
            options.telemetry_dir = None;
        } else if let Some(d) = &request.telemetry_dir {
            options.telemetry_dir = Some(d.clone());
        }
        let device = planned_device(&config, request)?;
        // One process at a time drives the motors (the `videt` tool takes the same lock). A
        // twin is private to its process, so with --sim the lock is taken only when --lock
        // asks for it.
        let lock_path = match (&request.lock, request.sim) {
            (Some(p), _) => Some(p.clone()),
            (None, None) => Some(PathBuf::from(&config.files.motors_lock)),
            (None, Some(_)) => None,
        };
        let scene = request.scene.clone();
        if request.sim.is_none() && scene != SimScene::Wall {
            return Err(PlanError::refused(format!(
                "--scene {scene:?} needs --sim: on the device the surface is the cameras' or the \
                 check wall"
            )));
        }
        Ok(ServicePlan {
            config,
            device,
            sim: request.sim,
            scene,
            twin_calibration: request.sim_calibration,
            calibration_path,
            lock_path,
            options,
        })
    }
}

/// The configured device (`rig.device`), refused with the reason where the request asks what
/// only the WireMan has (the bas-relief scenes, the device mode, auto-initialization).
fn planned_device(config: &Config, request: &ServiceRequest) -> Result<PlannedDevice, PlanError> {
    let rig = setup::rig(config).map_err(|e| PlanError::refused(format!("rig geometry: {e}")))?;
    let name = config.rig.device.as_str();
    if name == "wireman3" {
        return Ok(PlannedDevice::WireMan(rig));
    }
    if request.sim.is_none() {
        return Err(PlanError::refused(format!(
            "rig.device = {name:?}: runs on the digital twin (--sim or --sim can); the device \
             mode drives the three-wire WireMan"
        )));
    }
    let device = match name {
        "planar2" => setup::planar_device(config)
            .map(PlannedDevice::Planar)
            .map_err(|e| PlanError::refused(format!("rig.planar_guides_x_m: {e}")))?,
        "polar1" => setup::polar_device(config)
            .map(PlannedDevice::Polar)
            .map_err(|e| PlanError::refused(format!("rig.polar_guide_m: {e}")))?,
        other => {
            return Err(PlanError::refused(format!(
                "rig.device = {other:?}: the service runs the wireman3, planar2 and polar1 devices \
                 (its session log keeps three wires); the four-wire device runs in the control \
                 benchmarks and `videt analyze`"
            )))
        }
    };
    if request.sim_calibration == SimCalibration::Init {
        return Err(PlanError::refused(init_refused(name)));
    }
    Ok(device)
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

    fn refused(config: Config, request: &ServiceRequest) -> PlanError {
        match ServicePlan::new(config, request) {
            Ok(_) => panic!("{request:?} was accepted"),
            Err(e) => e,
        }
    }

    #[test]
    fn live_turns_the_view_on_where_asked_and_refuses_an_unreadable_address() {
        let plan = ServicePlan::new(Config::default(), &twin_request()).unwrap();
        assert_eq!(plan.options.live, None, "off by default");
        let mut request = twin_request();
        request.live = Some(None);
        let plan = ServicePlan::new(Config::default(), &request).unwrap();
        let live = plan.options.live.unwrap();
        assert_eq!((live.host.as_str(), live.port), ("127.0.0.1", 8765));
        assert_eq!(live.rate_hz, 30.0);
        request.live = Some(Some("[::1]:9000".into()));
        let live = ServicePlan::new(Config::default(), &request)
            .unwrap()
            .options
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
        assert!(matches!(plan.device, PlannedDevice::WireMan(_)));
        assert_eq!(plan.config.rig.guides_m[1], [0.4, 0.0]);
        assert_eq!(plan.lock_path, None);
        assert_eq!(plan.options.socket_path, None);
        assert_eq!(plan.options.telemetry_dir, None);
        assert_eq!(plan.options.duration_s, Some(1.0));
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
            assert!(matches!(plan.device, PlannedDevice::Planar(_)));
        }
    }

    #[test]
    fn the_can_twin_keeps_every_scene_and_the_device_takes_the_lock() {
        for scene in [
            SimScene::Stereo(None),
            SimScene::Camera(PathBuf::from("pairs")),
            SimScene::Box,
        ] {
            let mut request = twin_request();
            request.sim = Some(SimMode::Can);
            request.scene = scene.clone();
            let plan = ServicePlan::new(Config::default(), &request).unwrap();
            assert_eq!(plan.scene, scene);
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
            plan.calibration_path,
            PathBuf::from(&config.files.calibration)
        );
    }
}
