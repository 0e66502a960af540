//! The calibration axis: the geometry forces are rendered with, and the encoder zeros, as the
//! plan says: the device's calibration file, the configured geometry (the twin's truth), none,
//! or an auto-initialization of the WireMan's twin at start-up.

use tracing::{info, warn};
use videt_config::Config;
use videt_control::{DeviceKind, PlanarDevice, PolarDevice, Rig3};
use videt_runtime::cycle::WireZero;
use videt_runtime::runtime_device::RuntimeDevice;
use videt_sim::Twin;

use crate::plan::PlannedCalibration;

/// A device whose twin may be auto-initialized at start-up (the WireMan's base triangle).
pub trait TwinInit<const N: usize>: RuntimeDevice<N> {
    /// Auto-initialize `twin` as a technician would: the measured rig and encoder zeros; `None`
    /// (the default) for a device without auto-initialization.
    fn auto_initialize(
        _config: &Config,
        _twin: &mut Twin<N, Self>,
    ) -> Option<Result<(Rig3, WireZero), String>> {
        None
    }
}

impl TwinInit<3> for Rig3 {
    fn auto_initialize(
        config: &Config,
        twin: &mut Twin<3, Rig3>,
    ) -> Option<Result<(Rig3, WireZero), String>> {
        Some(auto_initialize(config, twin))
    }
}

/// The planar device has no base triangle to measure.
impl TwinInit<2> for PlanarDevice {}

/// The one-wire device has no base triangle to measure.
impl TwinInit<1> for PolarDevice {}

/// The device forces are rendered with, its encoder zeros and whether forces are rendered at
/// all, from `calibration` (`configured`: the configuration's device; `twin`: the twin to
/// auto-initialize, on a twin).
pub fn resolve<const N: usize, D: TwinInit<N>>(
    config: &Config,
    configured: D,
    calibration: &PlannedCalibration,
    twin: Option<&mut Twin<N, D>>,
) -> (D, WireZero, bool) {
    let uncalibrated = |why: &str| {
        warn!("forces will not be rendered (not calibrated): {why}");
        (configured, WireZero::default(), false)
    };
    let measured = |rig: Rig3, wire_zero: WireZero| match D::from_base_triangle(rig) {
        Some(device) => (device, wire_zero, true),
        None => (configured, WireZero::default(), false),
    };
    match calibration {
        PlannedCalibration::File(state) => match &state.reason {
            Some(reason) => uncalibrated(reason),
            None => measured(state.rig, state.wire_zero),
        },
        PlannedCalibration::Configured => {
            if D::KIND == DeviceKind::Wireman3 {
                info!("twin calibration: the configured guides (the twin's true geometry)");
            }
            (configured, WireZero::default(), true)
        }
        PlannedCalibration::None => uncalibrated("--sim-calibration none"),
        PlannedCalibration::AutoInit => {
            let initialized = twin.and_then(|twin| D::auto_initialize(config, twin));
            match initialized {
                // (The plan refuses it for a device without one.)
                None => uncalibrated(&crate::plan::init_refused(D::KIND.name())),
                Some(Ok((rig, wire_zero))) => measured(rig, wire_zero),
                Some(Err(e)) => uncalibrated(&format!("twin auto-initialization failed: {e}")),
            }
        }
    }
}

/// Auto-initialize the WireMan's `twin` at start-up: the measured rig and encoder zeros.
fn auto_initialize(config: &Config, twin: &mut Twin<3, Rig3>) -> Result<(Rig3, WireZero), String> {
    let operator = twin.operator().clone();
    let start = twin.plant().position_m();
    // A signal during the start-up initialization cancels it (the service then starts
    // uncalibrated and stops at once: its own handlers see the same signal pending).
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        let _ = signal_hook::flag::register(signal, std::sync::Arc::clone(&stop));
    }
    let outcome = crate::init::daemon::initialize_twin(config, twin, operator, start, 1, &stop)
        .map_err(|e| e.to_string())?;
    let s = videt_runtime::calibration::from_calibration(config, &outcome.calibration)?;
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
    Ok((s.rig, s.wire_zero))
}
