//! One control period, from wire lengths to motor torques (ARCHITECTURE "control cycle",
//! steps 2 and 4-7). Pure and allocation-free; the runtime moves the data in and out.

use crate::contact::{contact_force, ContactModel};
use crate::device::{minimum_tensions, ForceSettings, Sensed, WireDevice, WireTensions};
use crate::distribution::{Algorithm, ForceLimits};
use crate::field::ForceField;
use crate::measures::v_index;
use crate::surface::{Contact, Surface};
use crate::tension_pi::{contact_gain_share, TensionPi, TensionPiGains};
use crate::Vec3;

/// Parameters of the control step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ControlParams {
    /// Contact stiffness `K`, N/m (`f_e = K depth n`).
    pub stiffness_n_per_m: f64,
    /// Contact damping along the normal, N·s/m (0 = none). The contact force never pulls the
    /// thimble into the surface.
    pub damping_n_s_per_m: f64,
    /// Control algorithm (field rule and projection).
    pub algorithm: Algorithm,
    /// Tension limits.
    pub limits: ForceLimits,
    /// Tension loop.
    pub pi: TensionPiGains,
    /// The force field `f_c` added in contact and in free space (F1/F2; magnitude 0 for the
    /// paper's P1/P2).
    pub field: ForceField,
    /// Gravity-like free-space pull along the wires' bisector, newtons, used in free space when
    /// the algorithm has no field (`field.magnitude_n == 0`); raised where needed so every wire
    /// stays at or above `t_min` by itself. 0 = wires simply held at `t_min`.
    pub free_space_field_n: f64,
    /// The wires' elastic stretch, added to the encoders' lengths at the tensions commanded
    /// ([`WireStretch::RIGID`]: none).
    pub stretch: WireStretch,
}

/// The wires' elastic stretch. An encoder counts the wire paid out; under tension `T` the wire
/// between the pulley and the thimble is longer by `T (free + inside) / EA`, so the thimble is
/// that much further from the guide than the encoder says: pushed into a wall, deeper than the
/// wall is told, which renders the wall softer than programmed by the wires' stiffness in series
/// (`docs/haptic-bench.md`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WireStretch {
    /// Axial stiffness `EA` of the wire, newtons (infinite: a rigid wire, no correction).
    pub axial_stiffness_n: f64,
    /// Wire inside the module, from the pulley to the guide, metres (it stretches in series).
    pub inside_length_m: f64,
}

impl WireStretch {
    /// Rigid wires: the encoders' lengths are taken as they are.
    pub const RIGID: WireStretch = WireStretch {
        axial_stiffness_n: f64::INFINITY,
        inside_length_m: 0.0,
    };

    /// The length from the guide to the thimble of a wire with `free_m` paid out past the guide
    /// and carrying `tension_n`, metres. Non-finite or non-positive tensions stretch nothing.
    pub fn stretched_length_m(&self, free_m: f64, tension_n: f64) -> f64 {
        let stretches = tension_n.is_finite() && tension_n > 0.0;
        if !self.axial_stiffness_n.is_finite() || !stretches {
            return free_m;
        }
        free_m + tension_n * (free_m + self.inside_length_m).max(0.0) / self.axial_stiffness_n
    }
}

impl ControlParams {
    /// The paper's device (Table 2: 15 N per wire) with P2, no field, a 400 N/m surface, a
    /// 0.3 N tension floor and a 0.5 N free-space pull. The tension-loop gains depend on the
    /// drives and come from the configuration.
    pub fn paper_defaults(pi: TensionPiGains) -> ControlParams {
        ControlParams {
            stiffness_n_per_m: 400.0,
            damping_n_s_per_m: 0.0,
            algorithm: Algorithm::P2,
            limits: ForceLimits::default(),
            pi,
            field: ForceField::none(),
            free_space_field_n: 0.5,
            stretch: WireStretch::RIGID,
        }
    }
}

/// What the step reads each period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepInput<const N: usize> {
    /// Wire lengths from the encoders, metres.
    pub lengths_m: [f64; N],
    /// Wire length rates, m/s (positive = paying out).
    pub length_rates_m_s: [f64; N],
    /// Passive angles (azimuth, elevation), radians, on a device with angle sensors.
    pub angles_rad: [f64; 2],
    /// Rates of the passive angles, rad/s.
    pub angle_rates_rad_s: [f64; 2],
    /// Measured tensions, newtons.
    pub measured_tension_n: [f64; N],
    /// Period, seconds.
    pub dt_s: f64,
    /// False in the safe state: no force is rendered and every wire is held at `t_min`.
    pub render_forces: bool,
    /// Scale in `[0, 1]` applied to the desired force (ramps on start-up and shutdown).
    pub force_scale: f64,
}

impl<const N: usize> Default for StepInput<N> {
    fn default() -> Self {
        StepInput {
            lengths_m: [0.0; N],
            length_rates_m_s: [0.0; N],
            angles_rad: [0.0; 2],
            angle_rates_rad_s: [0.0; 2],
            measured_tension_n: [0.0; N],
            dt_s: 0.0,
            render_forces: false,
            force_scale: 0.0,
        }
    }
}

/// What the step produces each period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepOutput<const N: usize> {
    /// Thimble position, metres.
    pub position_m: Vec3,
    /// Thimble velocity, m/s.
    pub velocity_m_s: Vec3,
    /// Forward kinematics had to clamp (inconsistent lengths).
    pub fk_clamped: bool,
    /// Contact with the surface, if any.
    pub contact: Option<Contact>,
    /// Desired contact force `f_e` (zero in free space), newtons.
    pub desired_force_n: Vec3,
    /// Field force `f_c` added (the free-space pull when out of contact without a field), newtons.
    pub field_force_n: Vec3,
    /// What the projection aimed at, `f'_e = f_e + f_c`, newtons.
    pub target_force_n: Vec3,
    /// Performance index V (eq. 8) of the rendered force against the target.
    pub v_index: f64,
    /// Tension set-points and the force they render.
    pub distribution: WireTensions<N>,
    /// Motor torque commands, N·m (positive = winding).
    pub torque_nm: [f64; N],
}

impl<const N: usize> Default for StepOutput<N> {
    fn default() -> Self {
        StepOutput {
            position_m: Vec3::zeros(),
            velocity_m_s: Vec3::zeros(),
            fk_clamped: false,
            contact: None,
            desired_force_n: Vec3::zeros(),
            field_force_n: Vec3::zeros(),
            target_force_n: Vec3::zeros(),
            v_index: 0.0,
            distribution: WireTensions::default(),
            torque_nm: [0.0; N],
        }
    }
}

/// The control step of an `N`-wire device `D`: kinematics, contact, projection, tension loop.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ControlStep<const N: usize, D: WireDevice<N>> {
    device: D,
    params: ControlParams,
    pi: TensionPi<N>,
    /// The tension set-points of the last period: the wires' stretch this period.
    last_setpoint_n: [f64; N],
}

impl<const N: usize, D: WireDevice<N>> ControlStep<N, D> {
    /// A step for a device with the given parameters.
    pub fn new(device: D, params: ControlParams) -> ControlStep<N, D> {
        ControlStep {
            device,
            params,
            pi: TensionPi::new(params.pi),
            last_setpoint_n: [0.0; N],
        }
    }

    /// The device geometry.
    pub fn rig(&self) -> &D {
        &self.device
    }

    /// The parameters.
    pub fn params(&self) -> &ControlParams {
        &self.params
    }

    /// Forget everything the step carries from one period to the next (after the drives were
    /// off): the tension loop's integral and the last set-points (the wires' stretch).
    pub fn reset(&mut self) {
        self.pi.reset();
        self.last_setpoint_n = [0.0; N];
    }

    /// Run one period against `surface`, writing into `out`.
    pub fn update<S: Surface + ?Sized>(
        &mut self,
        input: &StepInput<N>,
        surface: &S,
        out: &mut StepOutput<N>,
    ) {
        // The lengths the wires have under the tensions last commanded (the drives apply them
        // this period; the measured ones come later, through the converter's filter).
        let stretch = self.params.stretch;
        let sensed = Sensed {
            lengths_m: core::array::from_fn(|i| {
                stretch.stretched_length_m(input.lengths_m[i], self.last_setpoint_n[i])
            }),
            length_rates_m_s: input.length_rates_m_s,
            angles_rad: input.angles_rad,
            angle_rates_rad_s: input.angle_rates_rad_s,
        };
        let fk = self.device.forward(&sensed);
        out.position_m = fk.position_m;
        out.fk_clamped = fk.clamped;
        out.velocity_m_s = self
            .device
            .velocity(&fk.position_m, &sensed)
            .filter(|v| v.iter().all(|c| c.is_finite()))
            .unwrap_or_else(Vec3::zeros);

        out.contact = if input.render_forces {
            surface.contact(&out.position_m)
        } else {
            None
        };
        let params = &self.params;
        // Start-up and shutdown ramps scale everything rendered above the tension floor.
        let scale = if input.force_scale.is_nan() {
            0.0
        } else {
            input.force_scale.clamp(0.0, 1.0)
        };
        out.desired_force_n = match out.contact {
            Some(c) => {
                contact_force(
                    &ContactModel {
                        stiffness_n_per_m: params.stiffness_n_per_m,
                        damping_n_s_per_m: params.damping_n_s_per_m,
                    },
                    &c,
                    &out.velocity_m_s,
                ) * scale
            }
            None => Vec3::zeros(),
        };
        let settings = ForceSettings {
            algorithm: params.algorithm,
            limits: params.limits,
            field: params.field,
            free_space_field_n: params.free_space_field_n,
        };
        let forces = if input.render_forces {
            self.device.forces(
                &out.position_m,
                &out.desired_force_n,
                out.contact.is_some(),
                scale,
                &settings,
            )
        } else {
            None
        };
        match forces {
            Some(f) => {
                out.field_force_n = f.field_force_n;
                out.target_force_n = f.target_force_n;
                out.distribution = f.tensions;
            }
            None => {
                // Safe state, or a configuration the device cannot hold: every wire at t_min.
                out.desired_force_n = Vec3::zeros();
                out.field_force_n = Vec3::zeros();
                out.target_force_n = Vec3::zeros();
                out.distribution = minimum_tensions(&self.device, &out.position_m, &params.limits);
            }
        }
        out.v_index = v_index(&out.distribution.rendered_n, &out.target_force_n);
        self.last_setpoint_n = out.distribution.tensions_n;
        let winding_speed_m_s: [f64; N] = core::array::from_fn(|i| -input.length_rates_m_s[i]);
        let kp_share = match out.contact {
            Some(c) => {
                let alignment = (0..N)
                    .map(|i| {
                        c.normal
                            .dot(&self.device.pull_direction(&out.position_m, i))
                    })
                    .fold(f64::NEG_INFINITY, f64::max);
                contact_gain_share(alignment, out.desired_force_n.norm())
            }
            None => 1.0,
        };
        self.pi.update_with_gain_share(
            &out.distribution.tensions_n,
            &input.measured_tension_n,
            &winding_speed_m_s,
            kp_share,
            input.dt_s,
            &mut out.torque_nm,
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::Rig3;
    use crate::surface::{FreeSpace, Plane};

    const WIRES: usize = 3;

    fn step(algorithm: Algorithm) -> ControlStep<3, Rig3> {
        let rig = Rig3::paper_frame();
        let mut params =
            ControlParams::paper_defaults(TensionPiGains::pi_only(0.0008, 0.0005, 0.02, 0.02));
        params.algorithm = algorithm;
        ControlStep::new(rig, params)
    }

    fn input_at(step: &ControlStep<3, Rig3>, p: Vec3) -> StepInput<3> {
        StepInput {
            lengths_m: step.rig().inverse(&p),
            dt_s: 1e-3,
            render_forces: true,
            force_scale: 1.0,
            ..StepInput::default()
        }
    }

    #[test]
    fn pressing_a_wall_renders_the_spring() {
        let mut s = step(Algorithm::P2);
        // Wall below the thimble at z = 0.3 facing the user (+z); thimble 1 cm inside.
        let wall = Plane::new(Vec3::new(0.0, 0.0, 0.3), Vec3::z()).unwrap();
        let p = Vec3::new(0.18, 0.1, 0.29);
        let mut out = StepOutput::default();
        s.update(&input_at(&s, p), &wall, &mut out);
        assert!((out.position_m - p).norm() < 1e-9);
        let c = out.contact.unwrap();
        assert!((c.depth_m - 0.01).abs() < 1e-9);
        // f_e = K depth n = 4 N along +z: outside the cone (the wires only pull towards z=0).
        assert!((out.desired_force_n - Vec3::new(0.0, 0.0, 4.0)).norm() < 1e-9);
        assert!(out.distribution.projected);
        assert!(out
            .distribution
            .tensions_n
            .iter()
            .all(|&t| (0.3..=15.0).contains(&t)));
    }

    #[test]
    fn a_wall_the_wires_can_render_is_rendered_exactly() {
        // Surface above the thimble facing the frame (-z): the wires pull towards it.
        let ceiling = Plane::new(Vec3::new(0.0, 0.0, 0.3), -Vec3::z()).unwrap();
        for alg in Algorithm::ALL {
            let mut s = step(alg);
            let mut out = StepOutput::default();
            s.update(
                &input_at(&s, Vec3::new(0.18, 0.1, 0.305)),
                &ceiling,
                &mut out,
            );
            assert!(
                (out.desired_force_n - Vec3::new(0.0, 0.0, -2.0)).norm() < 1e-9,
                "{alg:?}"
            );
            assert!(
                (out.distribution.rendered_n - out.target_force_n).norm() < 1e-9,
                "{alg:?}"
            );
            assert!((out.v_index - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn free_space_keeps_wires_taut_and_safe_state_holds_t_min() {
        let mut s = step(Algorithm::P2);
        let mut out = StepOutput::default();
        let p = Vec3::new(-0.1, 0.4, 0.2);
        s.update(&input_at(&s, p), &FreeSpace, &mut out);
        assert!(out.contact.is_none());
        assert!(
            !out.distribution.projected,
            "the free-space pull is inside F"
        );
        assert!(out.distribution.tensions_n.iter().all(|&t| t >= 0.3));
        assert!(out.field_force_n.norm() >= 0.5);
        let mut off = input_at(&s, p);
        off.render_forces = false;
        s.update(&off, &FreeSpace, &mut out);
        assert_eq!(out.distribution.tensions_n, [0.3; WIRES]);
    }

    #[test]
    fn stretch_compensation_finds_the_thimble_where_the_stretched_wires_put_it() {
        // The wires carry 2 N each, paid out 2 N's stretch short of where the thimble is.
        let stretch = WireStretch {
            axial_stiffness_n: 8000.0,
            inside_length_m: 0.12,
        };
        let mut s = step(Algorithm::P2);
        s.params.stretch = stretch;
        s.last_setpoint_n = [2.0; WIRES];
        let p = Vec3::new(0.18, 0.1, 0.3);
        let true_lengths = s.rig().inverse(&p);
        let mut input = input_at(&s, p);
        // free + 2 (free + inside) / EA = true  =>  free = (true - 2 inside / EA) / (1 + 2 / EA)
        input.lengths_m = core::array::from_fn(|i| {
            (true_lengths[i] - 2.0 * 0.12 / 8000.0) / (1.0 + 2.0 / 8000.0)
        });
        let mut rigid = step(Algorithm::P2);
        let mut out = StepOutput::default();
        rigid.update(&input, &FreeSpace, &mut out);
        let uncorrected = (out.position_m - p).norm();
        s.update(&input, &FreeSpace, &mut out);
        assert!(
            (out.position_m - p).norm() < 1e-9,
            "{:?}",
            out.position_m - p
        );
        assert!(uncorrected > 5e-5, "{uncorrected}");
        assert_eq!(stretch.stretched_length_m(0.3, f64::NAN), 0.3);
        assert_eq!(WireStretch::RIGID.stretched_length_m(0.3, 5.0), 0.3);
    }

    #[test]
    fn reset_forgets_everything_the_step_carries() {
        let mut s = step(Algorithm::P2);
        s.params.stretch = WireStretch {
            axial_stiffness_n: 8000.0,
            inside_length_m: 0.12,
        };
        let fresh = s;
        let wall = Plane::new(Vec3::new(0.0, 0.0, 0.3), Vec3::z()).unwrap();
        let mut out = StepOutput::default();
        let mut input = input_at(&s, Vec3::new(0.18, 0.1, 0.29));
        input.measured_tension_n = [1.0, 2.0, 3.0];
        for _ in 0..50 {
            s.update(&input, &wall, &mut out);
        }
        assert_ne!(s, fresh);
        s.reset();
        assert_eq!(s, fresh);
    }

    #[test]
    fn garbage_lengths_never_give_nan() {
        let mut s = step(Algorithm::Qp);
        let wall = Plane::new(Vec3::new(0.0, 0.0, 0.3), Vec3::z()).unwrap();
        let mut out = StepOutput::default();
        for lengths in [
            [f64::NAN, 0.1, 0.2],
            [0.0; 3],
            [1e300, -1.0, 0.5],
            [0.01, 0.5, 0.5],
        ] {
            let input = StepInput {
                lengths_m: lengths,
                length_rates_m_s: [f64::INFINITY, 0.0, 0.0],
                measured_tension_n: [0.0; 3],
                angles_rad: [0.0; 2],
                angle_rates_rad_s: [0.0; 2],
                dt_s: 1e-3,
                render_forces: true,
                force_scale: 1.0,
            };
            s.update(&input, &wall, &mut out);
            assert!(out.position_m.iter().all(|c| c.is_finite()));
            assert!(out.distribution.tensions_n.iter().all(|t| t.is_finite()));
            assert!(out.torque_nm.iter().all(|t| t.is_finite()));
            assert!(out.v_index.is_finite());
        }
    }
}
