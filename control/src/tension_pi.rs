//! PI control of the measured wire tension, with a static feed-forward of the set-point.

use crate::WIRES;

/// Gains and limits of the tension loop (same for every wire).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TensionPiGains {
    /// Feed-forward: motor torque per newton of tension, N·m/N (pulley radius / gear ratio).
    pub feedforward_nm_per_n: f64,
    /// Proportional gain, N·m per newton of tension error.
    pub kp_nm_per_n: f64,
    /// Integral gain, N·m per newton-second of tension error.
    pub ki_nm_per_n_s: f64,
    /// Largest motor torque magnitude commanded, N·m.
    pub torque_limit_nm: f64,
}

/// Per-wire PI tension controller with anti-windup (conditional integration at the torque limit).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TensionPi {
    gains: TensionPiGains,
    integral_nm: [f64; WIRES],
}

impl TensionPi {
    /// A controller with zero integral state.
    pub fn new(gains: TensionPiGains) -> TensionPi {
        TensionPi {
            gains,
            integral_nm: [0.0; WIRES],
        }
    }

    /// The gains.
    pub fn gains(&self) -> &TensionPiGains {
        &self.gains
    }

    /// Forget the integral state (after a fault or when the drives were off).
    pub fn reset(&mut self) {
        self.integral_nm = [0.0; WIRES];
    }

    /// One update: motor torques (N·m, positive = winding) into `torque_nm` for the set-points
    /// and measured tensions (N), over a period `dt_s` seconds. Non-finite measurements are
    /// treated as zero error (the safety layer decides what a broken sensor means).
    pub fn update(
        &mut self,
        setpoint_n: &[f64; WIRES],
        measured_n: &[f64; WIRES],
        dt_s: f64,
        torque_nm: &mut [f64; WIRES],
    ) {
        let g = &self.gains;
        for i in 0..WIRES {
            let error = if measured_n[i].is_finite() {
                setpoint_n[i] - measured_n[i]
            } else {
                0.0
            };
            let ff = g.feedforward_nm_per_n * setpoint_n[i];
            let candidate_integral = self.integral_nm[i] + g.ki_nm_per_n_s * error * dt_s;
            let unclamped = ff + g.kp_nm_per_n * error + candidate_integral;
            let saturating =
                unclamped.abs() > g.torque_limit_nm && unclamped.signum() == error.signum();
            if !saturating && candidate_integral.is_finite() {
                self.integral_nm[i] =
                    candidate_integral.clamp(-g.torque_limit_nm, g.torque_limit_nm);
            }
            let out = ff + g.kp_nm_per_n * error + self.integral_nm[i];
            torque_nm[i] = if out.is_finite() {
                out.clamp(-g.torque_limit_nm, g.torque_limit_nm)
            } else {
                0.0
            };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gains() -> TensionPiGains {
        TensionPiGains {
            feedforward_nm_per_n: 0.0008,
            kp_nm_per_n: 0.0005,
            ki_nm_per_n_s: 0.02,
            torque_limit_nm: 0.02,
        }
    }

    #[test]
    fn integral_removes_a_constant_error() {
        // Plant: measured tension = 0.8 * torque / feedforward (a 20% gain loss).
        let mut pi = TensionPi::new(gains());
        let sp = [5.0; WIRES];
        let mut measured = [0.0; WIRES];
        let mut torque = [0.0; WIRES];
        for _ in 0..5000 {
            pi.update(&sp, &measured, 1e-3, &mut torque);
            for i in 0..WIRES {
                measured[i] = 0.8 * torque[i] / gains().feedforward_nm_per_n;
            }
        }
        assert!((measured[0] - 5.0).abs() < 0.01, "{measured:?}");
    }

    #[test]
    fn output_is_limited_and_finite() {
        let mut pi = TensionPi::new(gains());
        let mut torque = [0.0; WIRES];
        pi.update(
            &[1e9, f64::NAN, -1e9],
            &[0.0, 0.0, f64::INFINITY],
            1e-3,
            &mut torque,
        );
        assert!(torque.iter().all(|t| t.is_finite() && t.abs() <= 0.02));
    }
}
