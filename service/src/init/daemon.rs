//! What `videtd` needs from calibration: the rig and the encoder zeros from a valid calibration
//! file — or the reason there is none, in which case the safety supervisor holds every wire at
//! minimum tension (`NotCalibrated`) and no force is rendered — and, for the twin, an
//! auto-initialization at start-up.

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use videt_assembly::WiremanTwin as Twin;

use videt_control::Rig3;
use videt_hal::{Lifecycle, WireDrives};
use videt_rt_config::calibration::Calibration;
use videt_rt_config::Config;
use videt_sim::{VirtualOperator, WireModules};

use super::runner::Runner;
use super::session::{self, run_settings, FlowContext, InitError, InitOutcome};
use super::twin::{SimTechnician, TwinSetup};
use videt_runtime::cycle::WireZero;

/// The calibration state the control cycle starts with.
#[derive(Debug, Clone)]
pub struct CalibrationState {
    /// The rig to control (the calibration's when valid; else the configured one, unused for
    /// rendering).
    pub rig: Rig3,
    /// Encoder zeros.
    pub wire_zero: WireZero,
    /// Whether forces may be rendered.
    pub calibrated: bool,
    /// Why not, when not.
    pub reason: Option<String>,
    /// The calibration, when valid.
    pub calibration: Option<Calibration>,
}

/// The state from a calibration (checked against the configured transmission).
pub fn from_calibration(config: &Config, c: &Calibration) -> Result<CalibrationState, String> {
    let mpc = videt_runtime::setup::transmission(config).metres_per_count();
    if (c.metres_per_count - mpc).abs() > 1e-6 * mpc {
        return Err(format!(
            "it was measured with {} m per encoder count, the configuration gives {mpc}: run `videt init`",
            c.metres_per_count
        ));
    }
    let rig = rig_from_sides(&c.sides_m)?;
    Ok(CalibrationState {
        rig,
        wire_zero: WireZero {
            length_at_zero_m: c.length_at_zero_m(),
        },
        calibrated: true,
        reason: None,
        calibration: Some(c.clone()),
    })
}

/// Load the calibration file; when it is missing, corrupt or inconsistent, say why and fall
/// back to the configured rig with forces off.
pub fn load(config: &Config, path: &Path) -> Result<CalibrationState, InitError> {
    let not_calibrated = |reason: String| -> Result<CalibrationState, InitError> {
        let rig = videt_runtime::setup::rig(config)
            .or_else(|_| Rig3::from_sides(0.37, 0.35, 0.35))
            .map_err(|_| InitError::NoSuchWire(0))?;
        Ok(CalibrationState {
            rig,
            wire_zero: WireZero::default(),
            calibrated: false,
            reason: Some(reason),
            calibration: None,
        })
    };
    match Calibration::load(path) {
        Ok(c) => match from_calibration(config, &c) {
            Ok(s) => Ok(s),
            Err(reason) => not_calibrated(format!("{}: {reason}", path.display())),
        },
        Err(e) => not_calibrated(e.to_string()),
    }
}

/// Auto-initialize the demonstration twin at start-up: the twin is put at rest (wires detached
/// and wound, arbitrary encoder offsets), the simulated technician connects the empty thimble,
/// the procedure measures the rig; then the operator's finger goes back into the thimble at
/// `start_m` with `operator`'s script, restarted now. `stop` cancels it (a signal during
/// start-up). Runs on the twin's simulated clock, before
/// the real-time loop starts.
pub fn initialize_twin(
    config: &Config,
    twin: &mut Twin,
    operator: VirtualOperator,
    start_m: videt_sim::Vec3,
    seed: u64,
    stop: &AtomicBool,
) -> Result<InitOutcome, InitError> {
    let guides = *twin.plant().params().device.guides_m();
    let setup = TwinSetup {
        guides_m: guides,
        ..TwinSetup::from_config(config, seed)
    };
    twin.plant_mut().set_modules(WireModules::paper());
    twin.plant_mut().rest_detached();
    twin.set_operator(VirtualOperator::absent(0.2));
    twin.set_encoder_offset_counts([12_345, -67_890, 424_242]);
    let mut tech = SimTechnician::new(&setup);
    // Start-up should be quick: wind at up to 0.25 m/s (within the speed limit).
    let mut quick = config.clone();
    quick.autoinit.wind_speed_m_s = config
        .autoinit
        .wind_speed_m_s
        .max(0.25_f64.min(0.5 * config.control.max_wire_speed_m_s));
    let config = &quick;
    let mut runner = Runner::new(run_settings(config));
    let ctx = FlowContext {
        config,
        source: "twin",
        stop,
    };
    let result =
        session::start(twin).and_then(|()| session::initialize(twin, &mut tech, &mut runner, &ctx));
    let _ = twin.disable();
    let _ = twin.deactivate();
    // The wearer puts the finger in: the thimble back in front of the frame, wires taut. The
    // demonstration then runs on the basic plant it was tuned on (no inside-wire compliance,
    // no frame stop); the encoders keep counting from where the procedure homed them.
    twin.plant_mut().connect_wires_at(start_m);
    twin.plant_mut().set_modules(WireModules::default());
    let now_s = twin.plant().time_s();
    twin.set_operator(operator.starting_at(now_s));
    result
}

/// Where the twin's files live: `$XDG_STATE_HOME/videt`, else `~/.local/state/videt`.
pub fn sim_state_dir() -> PathBuf {
    if let Some(d) = std::env::var_os("XDG_STATE_HOME").filter(|d| !d.is_empty()) {
        return PathBuf::from(d).join("videt");
    }
    if let Some(h) = std::env::var_os("HOME").filter(|h| !h.is_empty()) {
        return PathBuf::from(h).join(".local/state/videt");
    }
    std::env::temp_dir().join("videt")
}

/// The control cycle's rig for measured base-triangle sides, metres.
pub fn rig_from_sides(sides_m: &[f64; 3]) -> Result<Rig3, String> {
    Rig3::from_sides(sides_m[0], sides_m[1], sides_m[2])
        .map_err(|e| format!("its sides do not make a rig: {e}"))
}
