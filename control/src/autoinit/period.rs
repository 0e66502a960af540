//! What crosses the procedure's boundary each period: what it reads ([`ProcedureInput`]),
//! where it is ([`Stage`]) and its verdict ([`Status`]).

use super::failure::Failure;
use crate::WIREMAN_WIRES;

/// What the procedure reads each period.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ProcedureInput {
    /// Time, seconds (any origin; must not go backwards).
    pub time_s: f64,
    /// Encoder counts, positive = wound in.
    pub counts: [i64; WIREMAN_WIRES],
    /// Wire speeds, m/s, positive = winding.
    pub wind_speed_m_s: [f64; WIREMAN_WIRES],
    /// Measured tensions, N.
    pub tension_n: [f64; WIREMAN_WIRES],
    /// The e-stop is (latched) pressed.
    pub estop_pressed: bool,
    /// A drive failed (`Some(None)`: which one is unknown).
    pub drive_fault: Option<Option<u8>>,
    /// A tension sensor failed.
    pub sensor_fault: bool,
}

/// Where the procedure is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    /// Every wire brought to the pay-out tension.
    Settle,
    /// Homing the selected wires.
    Homing,
    /// Winding this wire to its ring.
    Winding(u8),
    /// Finished successfully.
    Finished,
    /// Ended by a failure.
    Failed,
}

/// The procedure's verdict after a period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Status {
    /// Still running.
    Running,
    /// Finished: results are available.
    Finished,
    /// Failed: every set-point is at the pay-out (minimum) tension.
    Failed(Failure),
}
