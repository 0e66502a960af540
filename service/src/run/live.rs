//! The live view for Foxglove: a read-only WebSocket server fed from the control thread's status,
//! the feed's surfaces, the calibrations in force and the cameras' image.

use std::sync::Arc;

use tracing::{error, info};
use videt_config::Config;
use videt_runtime::cycle::ControlCycle;
use videt_runtime::runtime_device::RuntimeDevice;
use videt_runtime::snapshot::SurfaceFeed;
use videt_runtime::status::{status_channel, StatusPublisher};
use videt_runtime::telemetry::{self, CalibrationInForce};

/// Start the live view of `settings` on the status of a publisher it returns for the control
/// thread's observers. A view that cannot start (its port in use) is logged as an error and
/// the service runs without it: the device's rendering does not depend on being watched.
pub fn start<const N: usize, D, F>(
    settings: &videt_viewers::live::LiveSettings,
    config: &Config,
    cycle: &ControlCycle<N, D>,
    feed: &F,
    image: Option<Arc<videt_viewers::live::ImageSlot>>,
    session_log: Option<telemetry::SessionLogHealth>,
) -> (
    Option<StatusPublisher>,
    Option<rtrb::Producer<CalibrationInForce>>,
    Option<videt_viewers::live::LiveView>,
)
where
    D: RuntimeDevice<N>,
    F: SurfaceFeed,
{
    use videt_viewers::live::{LiveSources, LiveView};
    let (publisher, status) = status_channel();
    let setup =
        videt_viewers::topics::SceneSetup::new(config, Some(&CalibrationInForce::of(cycle)));
    let (calibration_tx, calibration_rx) = videt_viewers::live::calibration_channel();
    let sources = LiveSources {
        status,
        surfaces: feed.recording(),
        image,
        calibrations: Some(calibration_rx),
        config: config.clone(),
        session_log,
    };
    match LiveView::start(settings, setup, sources) {
        Ok(view) => {
            info!(
                "live view for Foxglove on ws://{}:{} ({} Hz, read-only)",
                settings.host,
                view.port(),
                settings.rate_hz
            );
            (Some(publisher), Some(calibration_tx), Some(view))
        }
        Err(e) => {
            error!("{e}; running without it");
            (None, None, None)
        }
    }
}
