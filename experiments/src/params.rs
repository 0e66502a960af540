//! The control parameters of the experiments: the `[control]` section of the example
//! configuration (`config/videt.example.toml`), the values the twin runs with by default.

use videt_control::{Algorithm, ControlParams, ForceField, ForceLimits, TensionPiGains};
use videt_hal::Transmission;

/// The `[control]` values of the example configuration that the experiments use.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ControlConfig {
    /// Control rate, Hz (the paper's DSP ran its PI tension loops at 1 kHz).
    pub rate_hz: u32,
    /// Virtual surface stiffness `K`, N/m.
    pub stiffness_n_per_m: f64,
    /// Contact damping along the normal, N·s/m.
    pub damping_n_s_per_m: f64,
    /// Gravity-like free-space pull keeping the wires taut without a field, N.
    pub free_space_field_n: f64,
    /// Tension floor, N.
    pub t_min_n: f64,
    /// Tension ceiling (the device's 15 N), N.
    pub t_max_n: f64,
    /// Wire speed limit, m/s.
    pub max_wire_speed_m_s: f64,
    /// Proportional gain of the tension loop, N·m/N.
    pub tension_kp_nm_per_n: f64,
    /// Integral gain of the tension loop, N·m/(N·s).
    pub tension_ki_nm_per_n_s: f64,
    /// The integral learns below this wire speed only, m/s (0: at any speed).
    pub tension_integral_speed_gate_m_s: f64,
    /// Correct the encoders' lengths for the wires' stretch.
    pub stretch_compensation: bool,
    /// Winding speed of slack take-up, m/s.
    pub slack_takeup_speed_m_s: f64,
    /// Wire-speed loop gain, N·m·s/m.
    pub speed_gain_nm_s_per_m: f64,
    /// Rated torque of the drives (`[drives] rated_torque_nm`): their target torque comes in
    /// per mille of it, N·m.
    pub drive_rated_torque_nm: f64,
}

impl ControlConfig {
    /// The example configuration's values.
    pub const EXAMPLE: ControlConfig = ControlConfig {
        rate_hz: 1000,
        stiffness_n_per_m: 2000.0,
        damping_n_s_per_m: 5.0,
        free_space_field_n: 0.5,
        t_min_n: 0.3,
        t_max_n: 15.0,
        max_wire_speed_m_s: 0.8,
        tension_kp_nm_per_n: 0.0004,
        tension_ki_nm_per_n_s: 0.04,
        tension_integral_speed_gate_m_s: 0.003,
        stretch_compensation: true,
        slack_takeup_speed_m_s: 0.15,
        speed_gain_nm_s_per_m: 0.002,
        drive_rated_torque_nm: 0.05,
    };

    /// Control period, seconds.
    pub fn period_s(&self) -> f64 {
        1.0 / f64::from(self.rate_hz)
    }

    /// One step of the drives' target torque (one per mille of the rated torque), N·m.
    pub fn torque_step_nm(&self) -> f64 {
        self.drive_rated_torque_nm * 1e-3
    }

    /// The tension loop's gains on `transmission`, built as the runtime builds them
    /// (`src/setup.rs`): feed-forward from the transmission, torque limit 1.25 x the torque of
    /// `t_max`, slack below half of `t_min`, winding braked above 3/4 of the speed limit.
    pub fn tension_gains(&self, transmission: &Transmission) -> TensionPiGains {
        TensionPiGains {
            feedforward_nm_per_n: transmission.torque_for_tension(1.0),
            kp_nm_per_n: self.tension_kp_nm_per_n,
            ki_nm_per_n_s: self.tension_ki_nm_per_n_s,
            torque_limit_nm: 1.25 * transmission.torque_for_tension(self.t_max_n),
            speed_gain_nm_s_per_m: self.speed_gain_nm_s_per_m,
            slack_tension_n: 0.5 * self.t_min_n,
            takeup_speed_m_s: self.slack_takeup_speed_m_s,
            max_winding_speed_m_s: 0.75 * self.max_wire_speed_m_s,
            integral_speed_gate_m_s: if self.tension_integral_speed_gate_m_s > 0.0 {
                self.tension_integral_speed_gate_m_s
            } else {
                f64::INFINITY
            },
        }
    }

    /// Control parameters with `algorithm` and a field of `field_n` newtons (0 for the paper's
    /// P1 and P2), correcting for the wires' `stretch` when the configuration does. F1's
    /// constant field points towards the frame (`-z`).
    pub fn params(
        &self,
        transmission: &Transmission,
        stretch: videt_control::WireStretch,
        algorithm: Algorithm,
        field_n: f64,
    ) -> ControlParams {
        ControlParams {
            stiffness_n_per_m: self.stiffness_n_per_m,
            damping_n_s_per_m: self.damping_n_s_per_m,
            algorithm,
            limits: ForceLimits {
                t_min_n: self.t_min_n,
                t_max_n: self.t_max_n,
            },
            pi: self.tension_gains(transmission),
            field: ForceField::towards_frame(field_n),
            free_space_field_n: self.free_space_field_n,
            stretch: if self.stretch_compensation {
                stretch
            } else {
                videt_control::WireStretch::RIGID
            },
        }
    }
}
