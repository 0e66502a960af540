//! The closed loop on the twin, as the runtime runs it: every period read the drives (wire
//! lengths and rates from the encoders), the tension sensors and (one-wire device) the passive
//! angles, run the control step against the surface, write the torques, and let the simulated
//! clock advance one period. Everything the paper's figures show is recorded per period.

use videt_control::{ControlStep, StepInput, StepOutput, Surface, Vec3, WireDevice};
use videt_hal::{
    AngleSensors, Clock, DriveSample, Lifecycle, MonoTime, TensionSensors, WireDrives,
};
use videt_sim::{PlantParams, SensorModel, Twin, VirtualOperator};

use crate::params::ControlConfig;
use crate::ExperimentError;

/// Periods over which the passive angles are differenced into rates. The twin's angle sensors
/// resolve 14 bits (0.38 mrad): differenced over one 1 ms period that is a 0.38 rad/s step of
/// rate, 0.15 m/s of thimble speed at 0.4 m of wire, which the contact damping would turn into
/// force noise; over 10 periods the step is ten times smaller, for a 5 ms delay.
pub const ANGLE_RATE_WINDOW: usize = 10;

/// How the loop runs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoopSettings {
    /// Control period, seconds (1 ms: the paper's 1 kHz).
    pub period_s: f64,
    /// Simulated duration, seconds.
    pub duration_s: f64,
    /// Forces ramp from 0 to full over this time after the start, seconds.
    pub ramp_s: f64,
    /// A measured tension at or above this (or not finite) puts the loop in the safe state:
    /// from the next period on no force is rendered, every wire is held at `t_min`. Newtons.
    pub trip_tension_n: f64,
}

impl LoopSettings {
    /// The example configuration's rate, the device's 15 N with a 20 % margin as the trip, a
    /// 0.3 s start-up ramp, for `duration_s` seconds.
    pub fn for_duration(duration_s: f64) -> LoopSettings {
        let c = ControlConfig::EXAMPLE;
        LoopSettings {
            period_s: c.period_s(),
            duration_s,
            ramp_s: 0.3,
            trip_tension_n: 1.2 * c.t_max_n,
        }
    }
}

/// The stretch of `plant`'s wires, as the control corrects for it.
pub fn wire_stretch<const N: usize, D: videt_control::WireDevice<N>>(
    plant: &videt_sim::Plant<N, D>,
) -> videt_control::WireStretch {
    videt_control::WireStretch {
        axial_stiffness_n: plant.params().wire_ea_n,
        inside_length_m: plant
            .modules()
            .inside_length_m
            .first()
            .copied()
            .unwrap_or(0.0),
    }
}

/// One control period as recorded.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample<const N: usize> {
    /// Time at the start of the period, seconds.
    pub time_s: f64,
    /// Thimble position from the sensors (forward kinematics), metres: what an experiment on
    /// the real device records.
    pub position_m: Vec3,
    /// The twin's true thimble position, metres.
    pub true_position_m: Vec3,
    /// Where the operator's hand aims, metres.
    pub hand_target_m: Vec3,
    /// Thimble velocity estimated by the step, m/s.
    pub velocity_m_s: Vec3,
    /// Whether the step found contact.
    pub in_contact: bool,
    /// Penetration depth, metres (0 out of contact).
    pub depth_m: f64,
    /// Outward surface normal at the contact (zero out of contact).
    pub normal: Vec3,
    /// Desired contact force `f_e`, newtons.
    pub desired_n: Vec3,
    /// Field force `f_c` (the free-space pull out of contact without a field), newtons.
    pub field_n: Vec3,
    /// What the projection aimed at, `f'_e = f_e + f_c`, newtons.
    pub target_n: Vec3,
    /// The force of the tension set-points, `f = V t`, newtons.
    pub rendered_n: Vec3,
    /// The force of the measured tensions along the wires at the sensed position, newtons: what
    /// the wires apply, as measured.
    pub measured_n: Vec3,
    /// Index V (eq. 8) of the set-point force against the target.
    pub v_index: f64,
    /// Tension set-points, newtons.
    pub setpoint_n: [f64; N],
    /// Measured tensions, newtons.
    pub tension_n: [f64; N],
    /// This period's measured tensions tripped the safety check.
    pub safety_trip: bool,
    /// The loop was in the safe state during this period (no forces rendered).
    pub safe_state: bool,
}

/// A recorded run.
#[derive(Debug, Clone, PartialEq)]
pub struct Run<const N: usize> {
    /// One sample per period.
    pub samples: Vec<Sample<N>>,
    /// Control period, seconds.
    pub period_s: f64,
    /// Periods whose measured tensions tripped the safety check.
    pub trip_periods: usize,
    /// Periods run in the safe state.
    pub safe_state_periods: usize,
    /// When the safety check first tripped, seconds.
    pub first_trip_s: Option<f64>,
}

impl<const N: usize> Run<N> {
    /// The samples with `from_s <= time < to_s`.
    pub fn window(&self, from_s: f64, to_s: f64) -> impl Iterator<Item = &Sample<N>> + '_ {
        self.samples
            .iter()
            .filter(move |s| s.time_s >= from_s && s.time_s < to_s)
    }

    /// Largest measured tension of the run, newtons.
    pub fn max_tension_n(&self) -> f64 {
        self.samples
            .iter()
            .flat_map(|s| s.tension_n)
            .fold(0.0, f64::max)
    }
}

/// A twin of `device` with the thimble at `start_m`, the operator `operator`, the default
/// sensor errors (offset, gain error, seeded noise) and drives whose torque comes in the example
/// configuration's steps.
pub fn twin_for<const N: usize, D: WireDevice<N>>(
    device: D,
    start_m: Vec3,
    operator: VirtualOperator,
) -> Twin<N, D> {
    let mut twin = Twin::new(
        PlantParams::for_device(device),
        start_m,
        operator,
        SensorModel::<N>::default(),
    );
    twin.set_torque_step_nm(Some(ControlConfig::EXAMPLE.torque_step_nm()));
    twin
}

/// Wrap an angle difference into `(-pi, pi]`.
fn wrap_angle(a: f64) -> f64 {
    let tau = core::f64::consts::TAU;
    let w = a - tau * (a / tau).round();
    if w <= -core::f64::consts::PI {
        w + tau
    } else {
        w
    }
}

/// Run the closed loop on `twin` with `step` against `surface` for the settings' duration,
/// recording every period. The twin is configured, activated and its drives enabled first;
/// its clock must be simulated (the default).
pub fn run_closed_loop<const N: usize, D: WireDevice<N>, S: Surface + ?Sized>(
    twin: &mut Twin<N, D>,
    step: &mut ControlStep<N, D>,
    surface: &S,
    settings: &LoopSettings,
) -> Result<Run<N>, ExperimentError> {
    twin.configure()?;
    twin.activate()?;
    twin.enable()?;
    let mpc = twin.plant().params().transmission.metres_per_count();
    let device = *step.rig();
    let periods = (settings.duration_s / settings.period_s).round() as usize;
    let period_ns = (settings.period_s * 1e9).round() as u64;
    let start_ns = twin.now().as_nanos();
    let mut run = Run {
        samples: Vec::with_capacity(periods),
        period_s: settings.period_s,
        trip_periods: 0,
        safe_state_periods: 0,
        first_trip_s: None,
    };
    let mut drives = [DriveSample::default(); N];
    let mut tensions = [0.0; N];
    let mut out = StepOutput::<N>::default();
    let mut safe = false;
    let has_angles = D::KIND.has_angle_sensors();
    let mut angle_history = [[0.0f64; 2]; ANGLE_RATE_WINDOW];
    for k in 0..periods {
        let time_s = k as f64 * settings.period_s;
        twin.read_drives(&mut drives)?;
        twin.read_tensions(&mut tensions)?;
        let lengths_m: [f64; N] =
            core::array::from_fn(|i| -(drives[i].position_counts as f64) * mpc);
        // Positive drive velocity winds in: the length shrinks.
        let length_rates_m_s: [f64; N] =
            core::array::from_fn(|i| -drives[i].velocity_counts_per_s * mpc);
        let (angles_rad, angle_rates_rad_s) = if has_angles {
            let mut a = [0.0; 2];
            twin.read_angles(&mut a)?;
            if k == 0 {
                angle_history = [a; ANGLE_RATE_WINDOW];
            }
            let slot = k % ANGLE_RATE_WINDOW;
            let oldest = angle_history[slot];
            let span = k.clamp(1, ANGLE_RATE_WINDOW) as f64 * settings.period_s;
            let rates = core::array::from_fn(|j| wrap_angle(a[j] - oldest[j]) / span);
            angle_history[slot] = a;
            (a, rates)
        } else {
            ([0.0; 2], [0.0; 2])
        };
        let trip = tensions
            .iter()
            .any(|t| !t.is_finite() || *t >= settings.trip_tension_n);
        let input = StepInput {
            lengths_m,
            length_rates_m_s,
            angles_rad,
            angle_rates_rad_s,
            measured_tension_n: tensions,
            dt_s: settings.period_s,
            render_forces: !safe,
            force_scale: if settings.ramp_s > 0.0 {
                (time_s / settings.ramp_s).min(1.0)
            } else {
                1.0
            },
        };
        step.update(&input, surface, &mut out);
        twin.write_torques(&out.torque_nm)?;
        let mut measured_n = Vec3::zeros();
        for (i, t) in tensions.iter().enumerate() {
            measured_n += device.pull_direction(&out.position_m, i) * *t;
        }
        let sim_t = twin.plant().time_s();
        run.samples.push(Sample {
            time_s,
            position_m: out.position_m,
            true_position_m: twin.plant().position_m(),
            hand_target_m: twin.operator().target(sim_t).0,
            velocity_m_s: out.velocity_m_s,
            in_contact: out.contact.is_some(),
            depth_m: out.contact.map_or(0.0, |c| c.depth_m),
            normal: out.contact.map_or(Vec3::zeros(), |c| c.normal),
            desired_n: out.desired_force_n,
            field_n: out.field_force_n,
            target_n: out.target_force_n,
            rendered_n: out.distribution.rendered_n,
            measured_n,
            v_index: out.v_index,
            setpoint_n: out.distribution.tensions_n,
            tension_n: tensions,
            safety_trip: trip,
            safe_state: safe,
        });
        if safe {
            run.safe_state_periods += 1;
        }
        if trip {
            run.trip_periods += 1;
            run.first_trip_s.get_or_insert(time_s);
            safe = true;
        }
        twin.sleep_until(MonoTime(start_ns + (k as u64 + 1) * period_ns));
    }
    Ok(run)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn angle_differences_wrap() {
        let pi = core::f64::consts::PI;
        assert!((wrap_angle(2.0 * pi - 0.1) + 0.1).abs() < 1e-12);
        assert!((wrap_angle(-2.0 * pi + 0.1) - 0.1).abs() < 1e-12);
        assert!((wrap_angle(0.3) - 0.3).abs() < 1e-12);
        assert!((wrap_angle(-pi) - pi).abs() < 1e-12);
    }
}
