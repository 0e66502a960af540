//! Plant physics: thimble point mass, elastic tension-only wires, motor + worm gear + pulley.
//!
//! Conventions (those of `videt-hal`): a positive motor torque winds the wire in; the pulley
//! angle `theta` grows when winding; the unstretched wire length from guide ring to thimble is
//! `free_length = free_length_at_zero - pulley_radius * theta`.

use videt_control::{Rig3, WireDevice};
use videt_hal::Transmission;

use crate::operator::VirtualOperator;
use crate::Vec3;

/// Physical parameters of the twin of an `N`-wire device `D`.
#[derive(Debug, Clone, PartialEq)]
pub struct PlantParams<const N: usize, D: WireDevice<N>> {
    /// The device: where its wires leave their guides, and for the planar device the plane the
    /// thimble is held in.
    pub device: D,
    /// Motor-to-wire transmission.
    pub transmission: Transmission,
    /// Axial stiffness of the wire, `EA`, newtons (Kevlar: ~3% strain at 250 N → ~8 kN).
    pub wire_ea_n: f64,
    /// Wire damping per unit of strain rate, N·s (internal friction of the yarn).
    pub wire_damping_n_s: f64,
    /// Rotor + worm inertia at the motor shaft, kg·m².
    pub motor_inertia_kg_m2: f64,
    /// Pulley inertia, kg·m².
    pub pulley_inertia_kg_m2: f64,
    /// Viscous friction at the pulley, N·m·s/rad.
    pub pulley_friction_nm_s: f64,
    /// Mass moved with the thimble (thimble + the finger's effective mass), kg.
    pub thimble_mass_kg: f64,
    /// Integration step, seconds (<= 1e-4, i.e. >= 10 kHz).
    pub step_s: f64,
}

impl PlantParams<3, Rig3> {
    /// The paper's device on a frame of the paper's size (370 mm x 300 mm).
    pub fn paper_default() -> PlantParams<3, Rig3> {
        PlantParams::for_device(Rig3::paper_frame())
    }
}

impl<const N: usize, D: WireDevice<N>> PlantParams<N, D> {
    /// The paper's actuation modules, wires and thimble on `device`.
    pub fn for_device(device: D) -> PlantParams<N, D> {
        PlantParams {
            device,
            transmission: Transmission::PAPER,
            wire_ea_n: 8000.0,
            wire_damping_n_s: 4.0,
            motor_inertia_kg_m2: 1.0e-7,
            pulley_inertia_kg_m2: 2.0e-6,
            pulley_friction_nm_s: 8.0e-4,
            thimble_mass_kg: 0.1,
            step_s: 5.0e-5,
        }
    }

    /// Inertia reflected to the pulley, kg·m².
    fn pulley_side_inertia(&self) -> f64 {
        let g = self.transmission.gear_ratio;
        self.pulley_inertia_kg_m2 + self.motor_inertia_kg_m2 * g * g
    }
}

/// The plant's state and its integrator.
#[derive(Debug, Clone, PartialEq)]
pub struct Plant<const N: usize, D: WireDevice<N>> {
    params: PlantParams<N, D>,
    /// Thimble position, metres.
    position_m: Vec3,
    /// Thimble velocity, m/s.
    velocity_m_s: Vec3,
    /// Pulley angle, rad (positive = wound in).
    pulley_angle_rad: [f64; N],
    /// Pulley speed, rad/s.
    pulley_speed_rad_s: [f64; N],
    /// Unstretched wire length at pulley angle zero, metres.
    free_length_at_zero_m: [f64; N],
    /// Wire tensions of the last step, newtons (never negative).
    tension_n: [f64; N],
    /// Whether each wire is intact (a broken wire carries no tension).
    intact: [bool; N],
    /// Last hand force on the thimble, newtons.
    hand_force_n: Vec3,
    /// Simulated time, seconds.
    time_s: f64,
    /// Wire-module details used by homing, initialization and tension calibration.
    modules: WireModules<N>,
}

/// Stiffness of the frame's contact with the thimble, N/m.
const FRAME_STIFFNESS_N_PER_M: f64 = 2.0e4;
/// Damping of the frame's contact, N·s/m.
const FRAME_DAMPING_N_S_PER_M: f64 = 20.0;

/// Standard gravity, m/s².
pub const GRAVITY_M_S2: f64 = 9.806_65;

/// Wire-module details beyond the basic plant: the wire inside the module, whether each wire's
/// end is connected to the thimble, a weight hung on a detached end, and the yarn's usable length.
///
/// The defaults (no inside wire, every wire attached, no weight, unlimited yarn) reproduce the
/// basic plant exactly.
#[derive(Debug, Clone, PartialEq)]
pub struct WireModules<const N: usize> {
    /// Wire from the pulley to the guide ring (over the idle pulley), metres. It stretches in
    /// series with the free wire, and alone once the wire end is pulled against the ring.
    pub inside_length_m: [f64; N],
    /// Whether each wire's end is connected to the thimble; a detached end stops against its
    /// guide ring (end sphere larger than the ring's hole).
    pub attached: [bool; N],
    /// A weight hanging on a detached wire end, kg (tension calibration); 0 = none.
    pub hanging_mass_kg: [f64; N],
    /// Largest free length the yarn allows before its end, knotted on the pulley, stops the
    /// pulley, metres.
    pub usable_length_m: [f64; N],
    /// The frame (and the wearer's back behind it) stops the thimble at the guide plane `z = 0`:
    /// an empty thimble pulled by its wires comes to rest against it instead of swinging through.
    pub frame_stop: bool,
}

impl<const N: usize> Default for WireModules<N> {
    fn default() -> Self {
        WireModules {
            inside_length_m: [0.0; N],
            attached: [true; N],
            hanging_mass_kg: [0.0; N],
            usable_length_m: [f64::INFINITY; N],
            frame_stop: false,
        }
    }
}

impl<const N: usize> WireModules<N> {
    /// The paper's modules: 120 mm of wire inside each module, 1.5 m of usable yarn.
    pub fn paper() -> WireModules<N> {
        WireModules {
            inside_length_m: [0.12; N],
            usable_length_m: [1.5; N],
            frame_stop: true,
            ..WireModules::default()
        }
    }
}

impl<const N: usize, D: WireDevice<N>> Plant<N, D> {
    /// A plant at rest with the thimble at `position_m` (on the planar device, its projection
    /// on the plane) and every wire just taut (zero stretch), pulley angles zero.
    pub fn new(params: PlantParams<N, D>, position_m: Vec3) -> Plant<N, D> {
        let position_m = params.device.constrain(&position_m);
        let free = params.device.inverse(&position_m);
        Plant {
            params,
            position_m,
            velocity_m_s: Vec3::zeros(),
            pulley_angle_rad: [0.0; N],
            pulley_speed_rad_s: [0.0; N],
            free_length_at_zero_m: free,
            tension_n: [0.0; N],
            intact: [true; N],
            hand_force_n: Vec3::zeros(),
            time_s: 0.0,
            modules: WireModules::default(),
        }
    }

    /// The same plant with these wire-module details.
    pub fn with_modules(mut self, modules: WireModules<N>) -> Plant<N, D> {
        self.modules = modules;
        self
    }

    /// Replace the wire-module details.
    pub fn set_modules(&mut self, modules: WireModules<N>) {
        self.modules = modules;
    }

    /// The wire-module details.
    pub fn modules(&self) -> &WireModules<N> {
        &self.modules
    }

    /// Set the free (unstretched, outside the guide ring) length of wire `i`, metres, by turning
    /// its pulley; negative means the end is pulled into the ring, stretching the inside wire.
    pub fn set_free_length_m(&mut self, i: usize, free_length_m: f64) {
        let r = self.params.transmission.pulley_radius_m;
        self.pulley_angle_rad[i] = (self.free_length_at_zero_m[i] - free_length_m) / r;
        self.pulley_speed_rad_s[i] = 0.0;
    }

    /// Rest position of the device: every wire detached from the thimble and fully wound, its
    /// end just touching its guide ring (free length 0, no tension).
    pub fn rest_detached(&mut self) {
        for i in 0..N {
            self.modules.attached[i] = false;
            self.modules.hanging_mass_kg[i] = 0.0;
            self.set_free_length_m(i, 0.0);
        }
    }

    /// Detach wire `i` from the thimble (its end stays where the free length puts it).
    pub fn detach_wire(&mut self, i: usize) {
        self.modules.attached[i] = false;
    }

    /// The technician pulls every wire out to the thimble placed at `position_m` (at rest) and
    /// connects them: each wire just taut.
    pub fn connect_wires_at(&mut self, position_m: Vec3) {
        let position_m = self.params.device.constrain(&position_m);
        self.position_m = position_m;
        self.velocity_m_s = Vec3::zeros();
        let lengths = self.params.device.inverse(&position_m);
        for i in 0..N {
            self.modules.attached[i] = true;
            self.modules.hanging_mass_kg[i] = 0.0;
            self.set_free_length_m(i, lengths[i]);
        }
    }

    /// Fit a new yarn on wire `i`: intact, detached, `free_length_m` of it hanging out of the
    /// ring, `usable_length_m` in all.
    pub fn fit_new_wire(&mut self, i: usize, free_length_m: f64, usable_length_m: f64) {
        self.intact[i] = true;
        self.modules.attached[i] = false;
        self.modules.hanging_mass_kg[i] = 0.0;
        self.modules.usable_length_m[i] = usable_length_m;
        self.set_free_length_m(i, free_length_m);
    }

    /// Hang a weight of `mass_kg` on detached wire `i` (0 removes it).
    pub fn hang_weight(&mut self, i: usize, mass_kg: f64) {
        self.modules.attached[i] = false;
        self.modules.hanging_mass_kg[i] = mass_kg.max(0.0);
    }

    /// Whether wire `i` is intact.
    pub fn wire_intact(&self, i: usize) -> bool {
        self.intact[i]
    }

    /// The parameters.
    pub fn params(&self) -> &PlantParams<N, D> {
        &self.params
    }
    /// Thimble position, metres.
    pub fn position_m(&self) -> Vec3 {
        self.position_m
    }
    /// Thimble velocity, m/s.
    pub fn velocity_m_s(&self) -> Vec3 {
        self.velocity_m_s
    }
    /// True wire tensions, newtons.
    pub fn tension_n(&self) -> [f64; N] {
        self.tension_n
    }
    /// Last hand force on the thimble, newtons.
    pub fn hand_force_n(&self) -> Vec3 {
        self.hand_force_n
    }
    /// Simulated time, seconds.
    pub fn time_s(&self) -> f64 {
        self.time_s
    }
    /// Pulley angles, rad (positive = wound in).
    pub fn pulley_angle_rad(&self) -> [f64; N] {
        self.pulley_angle_rad
    }
    /// Pulley speeds, rad/s.
    pub fn pulley_speed_rad_s(&self) -> [f64; N] {
        self.pulley_speed_rad_s
    }
    /// Unstretched free length of each wire, metres.
    pub fn free_length_m(&self) -> [f64; N] {
        let r = self.params.transmission.pulley_radius_m;
        let mut l = [0.0; N];
        for i in 0..N {
            l[i] = self.free_length_at_zero_m[i] - r * self.pulley_angle_rad[i];
        }
        l
    }
    /// Cut wire `i` (it carries no tension from now on).
    pub fn break_wire(&mut self, i: usize) {
        self.intact[i] = false;
    }
    /// Place the thimble (e.g. to start a scenario), keeping the wires' free lengths.
    pub fn set_thimble(&mut self, position_m: Vec3, velocity_m_s: Vec3) {
        self.position_m = self.params.device.constrain(&position_m);
        self.velocity_m_s = self.params.device.constrain(&velocity_m_s);
    }

    /// Tension of wire `i` for the current state and its force on the thimble (elastic,
    /// tension-only, with damping that can only reduce a positive tension to zero, never push).
    ///
    /// The free wire (outside the ring) and the inside wire stretch in series. A wire wound
    /// past its end (free length <= 0) has its end against the guide ring: attached, it holds the
    /// thimble at the ring like a stiff spring; detached, only the inside wire carries tension.
    fn wire_tension(&self, i: usize, free_length_m: f64) -> (f64, Vec3) {
        // From the guide to the thimble.
        let (unit, length) = self.params.device.wire_from_guide(&self.position_m, i);
        let d = unit * length;
        let m = &self.modules;
        let inside = m.inside_length_m[i];
        let r = self.params.transmission.pulley_radius_m;
        let ea = self.params.wire_ea_n;
        let c = self.params.wire_damping_n_s;
        let pay_out_speed = r * self.pulley_speed_rad_s[i];
        if !self.intact[i] {
            return (0.0, Vec3::zeros());
        }
        if !m.attached[i] {
            if free_length_m > 0.0 || inside <= 0.0 {
                return (GRAVITY_M_S2 * m.hanging_mass_kg[i], Vec3::zeros());
            }
            let t = ea * (-free_length_m) / inside + c * pay_out_speed / inside;
            return (t.max(0.0), Vec3::zeros());
        }
        if free_length_m > 0.0 {
            if length <= free_length_m {
                return (0.0, Vec3::zeros());
            }
            let span = free_length_m + inside;
            let strain = (length - free_length_m) / span;
            // Strain rate: geometric lengthening plus paying out at the pulley.
            let strain_rate = (self.velocity_m_s.dot(&unit) + pay_out_speed) / span;
            let t = (ea * strain + c * strain_rate).max(0.0);
            return (t, -unit * t);
        }
        if inside <= 0.0 {
            return (0.0, Vec3::zeros());
        }
        // End against the ring: the thimble is held at the ring by the inside wire.
        let radial_speed = self.velocity_m_s.dot(&unit);
        let t = (ea * (length - free_length_m) / inside
            + c * (radial_speed + pay_out_speed) / inside)
            .max(0.0);
        let on_thimble = -d * (ea / inside) - unit * (c * radial_speed / inside);
        (t, on_thimble)
    }

    /// Advance by one integration step under motor torques (N·m, positive = winding) and the
    /// operator's hand (semi-implicit Euler).
    pub fn step(&mut self, motor_torque_nm: &[f64; N], operator: &VirtualOperator) {
        let h = self.params.step_s;
        let tr = self.params.transmission;
        let free = self.free_length_m();
        let mut wire_force = Vec3::zeros();
        for (i, free_i) in free.iter().enumerate() {
            let (t, force) = self.wire_tension(i, *free_i);
            self.tension_n[i] = t;
            wire_force += force;
        }
        self.hand_force_n = operator.force_n(self.time_s, &self.position_m, &self.velocity_m_s);
        if self.modules.frame_stop && self.position_m.z < 0.0 {
            // A stiff, damped contact that only pushes.
            let push = -FRAME_STIFFNESS_N_PER_M * self.position_m.z
                - FRAME_DAMPING_N_S_PER_M * self.velocity_m_s.z;
            wire_force.z += push.max(0.0);
        }
        let accel = (wire_force + self.hand_force_n) / self.params.thimble_mass_kg;
        // The planar device's linkage takes the out-of-plane part (a projection: linear).
        let accel = self.params.device.constrain(&accel);
        self.velocity_m_s += accel * h;
        self.position_m += self.velocity_m_s * h;

        let base_inertia = self.params.pulley_side_inertia();
        let r = tr.pulley_radius_m;
        for i in 0..N {
            let hanging = if !self.modules.attached[i] && free[i] > 0.0 && self.intact[i] {
                self.modules.hanging_mass_kg[i] * r * r
            } else {
                0.0
            };
            let inertia = base_inertia + hanging;
            let drive = motor_torque_nm[i] * tr.gear_ratio * tr.efficiency;
            let load = self.tension_n[i] * r;
            let friction = self.params.pulley_friction_nm_s * self.pulley_speed_rad_s[i];
            let alpha = (drive - load - friction) / inertia;
            self.pulley_speed_rad_s[i] += alpha * h;
            self.pulley_angle_rad[i] += self.pulley_speed_rad_s[i] * h;
            // The yarn's end is knotted on the pulley: it cannot pay out past its usable length.
            let usable = self.modules.usable_length_m[i];
            if usable.is_finite() {
                let min_angle = (self.free_length_at_zero_m[i] - usable) / r;
                if self.pulley_angle_rad[i] < min_angle {
                    self.pulley_angle_rad[i] = min_angle;
                    self.pulley_speed_rad_s[i] = self.pulley_speed_rad_s[i].max(0.0);
                }
            }
        }
        self.time_s += h;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const WIRES: usize = 3;
    use proptest::prelude::*;

    fn centre() -> Vec3 {
        Vec3::new(0.185, 0.12, 0.30)
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 64, rng_seed: proptest::test_runner::RngSeed::Fixed(11), ..ProptestConfig::default() })]
        /// Whatever the motors and the hand do, a wire never pushes: every tension is >= 0 and
        /// the wire force on the thimble always points into the guides' side.
        #[test]
        fn a_wire_never_pushes(torques in proptest::array::uniform3(-0.02f64..0.02),
                               tx in -0.2f64..0.6, ty in -0.2f64..0.5, tz in 0.05f64..0.7) {
            let mut plant = Plant::new(PlantParams::paper_default(), centre());
            let op = VirtualOperator::new(vec![crate::Waypoint { time_s: 0.0, target_m: Vec3::new(tx, ty, tz) }], 300.0, 5.0);
            for _ in 0..4000 {
                // Tensions of a step are computed from the state before it.
                let free = plant.free_length_m();
                let slack: [bool; WIRES] = core::array::from_fn(|i| {
                    plant.params().device.inverse(&plant.position_m())[i] <= free[i]
                });
                plant.step(&torques, &op);
                for (i, t) in plant.tension_n().iter().enumerate() {
                    prop_assert!(*t >= 0.0);
                    if slack[i] {
                        prop_assert_eq!(*t, 0.0, "a slack wire carries no tension");
                    }
                }
            }
        }
    }

    /// With the tensions balancing the hand's force, a thimble held still stays still.
    #[test]
    fn balanced_tensions_hold_the_thimble_still() {
        let params = PlantParams::paper_default();
        let p0 = centre();
        let mut plant = Plant::new(params.clone(), p0);
        // Pre-stretch: wind each wire by the stretch that gives 2 N, and hold with the static
        // torque; the hand pushes away from the frame with exactly the wires' resultant.
        let tensions = [2.0; WIRES];
        let r = params.transmission.pulley_radius_m;
        let mut resultant = Vec3::zeros();
        for i in 0..WIRES {
            let g = params.device.guides_m()[i];
            let l = (p0 - g).norm();
            let free = l / (1.0 + tensions[i] / params.wire_ea_n);
            plant.free_length_at_zero_m[i] = free;
            resultant -= (p0 - g) / l * tensions[i];
            let _ = r;
        }
        let torques: [f64; WIRES] =
            core::array::from_fn(|i| params.transmission.torque_for_tension(tensions[i]));
        // A hand whose spring force at p0 is exactly -resultant.
        let op = VirtualOperator::new(
            vec![crate::Waypoint {
                time_s: 0.0,
                target_m: p0 - resultant / 200.0,
            }],
            200.0,
            6.0,
        );
        for _ in 0..40_000 {
            plant.step(&torques, &op);
        }
        assert!(
            (plant.position_m() - p0).norm() < 1e-6,
            "moved {:?}",
            plant.position_m() - p0
        );
        for t in plant.tension_n() {
            assert!((t - 2.0).abs() < 1e-3, "{t}");
        }
    }
}
