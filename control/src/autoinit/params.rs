//! What the homing / auto-initialization procedure is given: its settings
//! ([`ProcedureParams`]) and what it is to do ([`Plan`]).

use crate::WIREMAN_WIRES;

/// Settings of the procedure (from the configuration's `[autoinit]` and `[control]` sections).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProcedureParams {
    /// Metres of wire per encoder count.
    pub metres_per_count: f64,
    /// Tension of the wires that pay out, and the tension every wire is left at, N.
    pub pay_out_tension_n: f64,
    /// Largest tension set-point of a winding wire, N (it reaches it when the wire stops).
    pub wind_tension_max_n: f64,
    /// Target winding speed, m/s.
    pub wind_speed_m_s: f64,
    /// Speed loop: proportional gain, N per m/s of speed error.
    pub speed_kp_n_per_m_s: f64,
    /// Speed loop: integral gain, N per m of speed-error integral.
    pub speed_ki_n_per_m: f64,
    /// Time the set-points take to settle before winding starts, seconds.
    pub settle_s: f64,
    /// How long a wire must stay stopped with its tension up before the stop counts, seconds.
    pub stop_hold_s: f64,
    /// Averaging window of the lengths once stopped, seconds.
    pub measure_s: f64,
    /// Longest a homing or a winding may take, seconds.
    pub stage_timeout_s: f64,
    /// A winding wire shorter than this travel never moved: not connected, metres.
    pub min_travel_m: f64,
    /// Longest travel of one homing or winding before the wire counts as broken or slipping
    /// (its tension never rose), metres.
    pub max_wind_travel_m: f64,
    /// Shortest base-triangle side accepted, metres (a shorter paying-out wire is not connected).
    pub min_side_m: f64,
    /// Longest a wire may be (once its winding homed it) or pay out (before), metres.
    pub max_length_m: f64,
    /// Largest disagreement between the two measurements of one side, metres.
    pub side_tolerance_m: f64,
    /// Largest measured tension tolerated, N.
    pub max_tension_n: f64,
    /// How long a tension above `max_tension_n` is tolerated, seconds (filters spikes).
    pub over_tension_s: f64,
    /// Largest wire speed tolerated, m/s.
    pub max_speed_m_s: f64,
}

impl ProcedureParams {
    /// Tension above which a stopped winding wire counts as against its stop, N (well below
    /// the cap, so a transmission less efficient than configured still gets there).
    pub fn stop_tension_n(&self) -> f64 {
        self.pay_out_tension_n + 0.4 * (self.wind_tension_max_n - self.pay_out_tension_n)
    }
    /// Speed below which a wire counts as stopped, m/s.
    pub fn stop_speed_m_s(&self) -> f64 {
        0.05 * self.wind_speed_m_s
    }
}

/// What the procedure does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Plan {
    /// Home the selected (detached) wires, all at once; the others are held at the pay-out
    /// tension.
    Home {
        /// Which wires to home.
        wires: [bool; WIREMAN_WIRES],
    },
    /// Measure the base triangle with the wires connected to the thimble (each winding also
    /// homes its wire).
    Initialize,
}
