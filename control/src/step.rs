//! One control period, from wire lengths to motor torques (ARCHITECTURE "control cycle",
//! steps 2 and 4-7). Pure and allocation-free; the runtime moves the data in and out.

use crate::distribution::{distribute, Algorithm, Distribution, ForceLimits};
use crate::kinematics::Rig3;
use crate::surface::{Contact, Surface};
use crate::tension_pi::{TensionPi, TensionPiGains};
use crate::{Vec3, WIRES};

/// Parameters of the control step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ControlParams {
    /// Contact stiffness `K`, N/m (`f_e = K depth n`).
    pub stiffness_n_per_m: f64,
    /// Contact damping along the normal while penetrating, N·s/m (0 = none).
    pub damping_n_s_per_m: f64,
    /// Projection algorithm.
    pub algorithm: Algorithm,
    /// Tension limits.
    pub limits: ForceLimits,
    /// Tension loop.
    pub pi: TensionPiGains,
}

/// What the step reads each period.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StepInput {
    /// Wire lengths from the encoders, metres.
    pub lengths_m: [f64; WIRES],
    /// Wire length rates, m/s (positive = paying out).
    pub length_rates_m_s: [f64; WIRES],
    /// Measured tensions, newtons.
    pub measured_tension_n: [f64; WIRES],
    /// Period, seconds.
    pub dt_s: f64,
    /// False in the safe state: no force is rendered and every wire is held at `t_min`.
    pub render_forces: bool,
    /// Scale in `[0, 1]` applied to the desired force (ramps on start-up and shutdown).
    pub force_scale: f64,
}

/// What the step produces each period.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StepOutput {
    /// Thimble position, metres.
    pub position_m: Vec3,
    /// Thimble velocity, m/s.
    pub velocity_m_s: Vec3,
    /// Forward kinematics had to clamp (inconsistent lengths).
    pub fk_clamped: bool,
    /// Contact with the surface, if any.
    pub contact: Option<Contact>,
    /// Desired force `f_e` (before projection), newtons.
    pub desired_force_n: Vec3,
    /// Tension set-points and the force they render.
    pub distribution: Distribution,
    /// Motor torque commands, N·m (positive = winding).
    pub torque_nm: [f64; WIRES],
}

/// The control step: kinematics, contact, projection, tension loop.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ControlStep {
    rig: Rig3,
    params: ControlParams,
    pi: TensionPi,
}

impl ControlStep {
    /// A step for a rig with the given parameters.
    pub fn new(rig: Rig3, params: ControlParams) -> ControlStep {
        ControlStep {
            rig,
            params,
            pi: TensionPi::new(params.pi),
        }
    }

    /// The rig geometry.
    pub fn rig(&self) -> &Rig3 {
        &self.rig
    }

    /// The parameters.
    pub fn params(&self) -> &ControlParams {
        &self.params
    }

    /// Forget the tension loop's integral (after the drives were off).
    pub fn reset(&mut self) {
        self.pi.reset();
    }

    /// Run one period against `surface`, writing into `out`.
    pub fn update<S: Surface + ?Sized>(
        &mut self,
        input: &StepInput,
        surface: &S,
        out: &mut StepOutput,
    ) {
        let fk = self.rig.forward(&input.lengths_m);
        out.position_m = fk.position_m;
        out.fk_clamped = fk.clamped;
        out.velocity_m_s = self
            .rig
            .velocity_from_rates(&fk.position_m, &input.length_rates_m_s)
            .filter(|v| v.iter().all(|c| c.is_finite()))
            .unwrap_or_else(Vec3::zeros);

        out.contact = if input.render_forces {
            surface.contact(&out.position_m)
        } else {
            None
        };
        out.desired_force_n = match out.contact {
            Some(c) => {
                let normal_speed = out.velocity_m_s.dot(&c.normal);
                // Spring along the outward normal, damping only against penetrating motion.
                let damping = if normal_speed < 0.0 {
                    -self.params.damping_n_s_per_m * normal_speed
                } else {
                    0.0
                };
                c.normal * (self.params.stiffness_n_per_m * c.depth_m + damping)
            }
            None => Vec3::zeros(),
        };
        out.desired_force_n *= input.force_scale.clamp(0.0, 1.0);
        out.distribution = distribute(
            &self.rig,
            &out.position_m,
            &out.desired_force_n,
            self.params.algorithm,
            &self.params.limits,
        );
        let winding_speed_m_s: [f64; WIRES] = core::array::from_fn(|i| -input.length_rates_m_s[i]);
        self.pi.update_with_speed(
            &out.distribution.tensions_n,
            &input.measured_tension_n,
            &winding_speed_m_s,
            input.dt_s,
            &mut out.torque_nm,
        );
    }
}
