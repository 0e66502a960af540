//! How the service runs: the configuration in force and what the command line chose on top of
//! it (the socket, the session log, the calibration file, the live view, a duration).

use std::path::PathBuf;

use videt_config::Config;

/// How the service runs.
#[derive(Debug, Clone)]
pub struct ServiceSettings {
    /// The validated configuration.
    pub config: Config,
    /// Stop cleanly after this many seconds.
    pub duration_s: Option<f64>,
    /// Control socket path (`None`: no socket).
    pub socket_path: Option<PathBuf>,
    /// Directory for the session log (`None`: no telemetry).
    pub telemetry_dir: Option<PathBuf>,
    /// Print one status line per second on stdout.
    pub status_lines: bool,
    /// Render the colour under the thimble on the vibrotactors (`None`: no colour thread).
    pub colour: Option<crate::colour_thread::ColourSource>,
    /// The calibration file auto-initialization through the control socket writes (`None`: the
    /// service runs no procedures).
    pub calibration_path: Option<PathBuf>,
    /// What runs (the scene, the device or the twin), for the session log.
    pub description: String,
    /// Serve the live view (`None`: off).
    pub live: Option<videt_viewers::live::LiveSettings>,
}

impl ServiceSettings {
    /// Settings from the configuration alone.
    pub fn from_config(config: Config) -> ServiceSettings {
        let config_calibration = config.files.calibration.clone();
        let live = config
            .live
            .enabled
            .then(|| videt_viewers::live::LiveSettings::from_config(&config).ok())
            .flatten();
        let socket_path = Some(PathBuf::from(&config.socket.path));
        let telemetry_dir = config
            .telemetry
            .enabled
            .then(|| PathBuf::from(&config.telemetry.directory));
        ServiceSettings {
            config,
            duration_s: None,
            socket_path,
            telemetry_dir,
            status_lines: true,
            colour: None,
            calibration_path: Some(PathBuf::from(&config_calibration)),
            description: String::new(),
            live,
        }
    }
}
