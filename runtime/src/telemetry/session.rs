//! What a session log records besides the periods, so that a replay can rebuild the control
//! cycle: the configuration in force and the calibration (rig geometry, encoder zeros); and how
//! the session ended. The surfaces it records are [`super::surfaces`]'s.

use serde::{Deserialize, Serialize};
use videt_config::Config;

use crate::cycle::{ControlCycle, WireZero};
use crate::runtime_device::RuntimeDevice;
use crate::WIREMAN_WIRES;

/// The session frame: who recorded the log, what ran, and the configuration in force.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SessionInfo {
    /// Version of the `videtd` that recorded the session.
    pub videt_version: String,
    /// What ran (the scene, the device or the twin).
    pub what: String,
    /// The configuration in force, as resolved at start-up (drive units applied).
    pub config: Config,
}

impl SessionInfo {
    /// The session of this build running `config`.
    pub fn new(what: impl Into<String>, config: Config) -> SessionInfo {
        SessionInfo {
            videt_version: env!("CARGO_PKG_VERSION").to_string(),
            what: what.into(),
            config,
        }
    }

    /// TOML text.
    pub fn to_toml(&self) -> Result<String, String> {
        toml::to_string(self).map_err(|e| e.to_string())
    }

    /// Parse and validate TOML text (as recorded: drive units are not looked up again).
    pub fn from_toml(text: &str) -> Result<SessionInfo, String> {
        let session: SessionInfo = toml::from_str(text).map_err(|e| e.to_string())?;
        session.config.validate().map_err(|e| e.to_string())?;
        Ok(session)
    }
}

/// The calibration a control cycle runs with: recorded when the cycle starts and each time a
/// re-initialization through the control socket replaces it.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CalibrationInForce {
    /// Guide points, metres, one per wire of the device (the remaining slots zero).
    pub guides_m: [[f64; 3]; WIREMAN_WIRES],
    /// Wire length at encoder count zero, metres.
    pub length_at_zero_m: [f64; WIREMAN_WIRES],
    /// Forces are rendered (the rig was calibrated).
    pub calibrated: bool,
}

impl CalibrationInForce {
    /// The calibration `cycle` computes with.
    pub fn of<const N: usize, D: RuntimeDevice<N>>(
        cycle: &ControlCycle<N, D>,
    ) -> CalibrationInForce {
        CalibrationInForce {
            guides_m: cycle.rig().logged_guides_m(),
            length_at_zero_m: cycle.wire_zero().length_at_zero_m,
            calibrated: cycle.calibrated(),
        }
    }

    /// The device geometry and encoder zeros to build a cycle with.
    pub fn device<const N: usize, D: RuntimeDevice<N>>(&self) -> Result<(D, WireZero), String> {
        Ok((
            D::from_logged_guides(&self.guides_m)?,
            WireZero {
                length_at_zero_m: self.length_at_zero_m,
            },
        ))
    }
}

/// Why a session ended, as the end frame of its log records it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum EndReason {
    /// A signal asked the service to stop (SIGINT: Ctrl-C; SIGTERM: `systemctl stop`): its name.
    Signal(String),
    /// A stop request (the control socket's `stop`).
    StopRequest,
    /// The run's set duration (`--duration`) elapsed.
    DurationElapsed,
    /// A fatal fault ended the service (a panic, the hardware not starting): what it was.
    FatalFault(String),
}

impl EndReason {
    /// The reason's name: `signal`, `stop request`, `duration elapsed` or `fatal fault`.
    pub fn as_str(&self) -> &'static str {
        match self {
            EndReason::Signal(_) => "signal",
            EndReason::StopRequest => "stop request",
            EndReason::DurationElapsed => "duration elapsed",
            EndReason::FatalFault(_) => "fatal fault",
        }
    }
}

impl std::fmt::Display for EndReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            EndReason::Signal(name) => write!(f, "stopped by a signal ({name})"),
            EndReason::StopRequest => f.write_str("stopped on request (control socket)"),
            EndReason::DurationElapsed => f.write_str("its set duration elapsed"),
            EndReason::FatalFault(what) => write!(f, "a fatal fault: {what}"),
        }
    }
}

/// The end frame: the service stopped and closed the log. A log without one ended without
/// closing (power lost, the process killed, or a copy cut short).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SessionEnd {
    /// Why the session ended.
    pub reason: EndReason,
    /// The last period the control loop ran (`None`: it ran none). Later than the last record
    /// when the last periods were dropped (a full ring).
    pub last_cycle: Option<u64>,
    /// Periods written to the log.
    pub periods: u64,
    /// Periods not in the log: dropped because the ring was full, or lost because the file
    /// system refused them (a full disk).
    pub dropped: u64,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_session_round_trips_through_toml() {
        let s = SessionInfo::new("twin: a wall", Config::default());
        let text = s.to_toml().unwrap();
        assert_eq!(SessionInfo::from_toml(&text).unwrap(), s);
        assert!(SessionInfo::from_toml("what = 3").is_err());
    }
}
