//! What `videtd` needs from the procedures on the twin: an auto-initialization at start-up,
//! and where the twin's files live. The calibration state a cycle starts with is the core
//! runtime's (`videt_runtime::calibration`).

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use videt_assembly::WiremanTwin as Twin;

use videt_config::Config;
use videt_hal::{Lifecycle, WireDrives};
use videt_sim::{VirtualOperator, WireModules};

use super::runner::Runner;
use super::session::{self, run_settings, FlowContext, InitError, InitOutcome};
use super::twin::{SimTechnician, TwinSetup};

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
