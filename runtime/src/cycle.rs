//! One control period on real or simulated hardware: read the devices, supervise, compute, write.
//!
//! Generic over the HAL capabilities; allocation-free. The math is `videt-control`'s; this module
//! only moves data between the devices and the pure functions.

use videt_control::safety::{
    SafetyInput, SafetyLimits, SafetyReason, SafetyState, SafetySupervisor,
};
use videt_control::{ControlStep, StepInput, StepOutput, Surface, WireDevice};

use crate::snapshot::SurfaceView;
use videt_hal::{
    AngleSensors, DriveSample, DriveState, EStop, MonoTime, TensionSensors, Transmission,
    WireDrives,
};

// Per-wire slots of a period's record (and of the session log): one per WireMan wire; the wires
// of a device fill the first ones, the rest stay zero. A cycle for more wires does not compile.
use crate::WIREMAN_WIRES;

/// Everything the device did in one period: the telemetry record.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CycleRecord {
    /// Period number since start.
    pub cycle: u64,
    /// Start of the period (wake-up), clock time.
    pub time: MonoTime,
    /// How late the wake-up was, nanoseconds.
    pub wake_latency_ns: u64,
    /// Time from wake-up to the end of the period's work, nanoseconds (filled in by the loop).
    pub compute_ns: u64,
    /// Wire lengths, metres.
    pub lengths_m: [f64; WIREMAN_WIRES],
    /// Tension set-points, newtons.
    pub tension_setpoint_n: [f64; WIREMAN_WIRES],
    /// Measured tensions, newtons.
    pub tension_measured_n: [f64; WIREMAN_WIRES],
    /// Motor torque commands, N·m.
    pub torque_nm: [f64; WIREMAN_WIRES],
    /// Thimble position, metres.
    pub position_m: [f64; 3],
    /// Thimble velocity, m/s.
    pub velocity_m_s: [f64; 3],
    /// Desired force, newtons.
    pub desired_force_n: [f64; 3],
    /// Force the set-points render, newtons.
    pub rendered_force_n: [f64; 3],
    /// Penetration depth, metres (0 when not in contact).
    pub contact_depth_m: f64,
    /// In contact with the surface.
    pub in_contact: bool,
    /// Safety state after this period.
    pub safety: SafetyState,
    /// Force scale of the start/stop ramp and the stale-surface fade, `[0, 1]`.
    pub force_scale: f64,
    /// Version of the surface rendered.
    pub surface_version: u64,
    /// The surface was stale (no new model for longer than allowed): forces fade out.
    pub surface_stale: bool,
    /// Wire released for replacement (`-1` when none).
    pub released_wire: i8,
    /// What the cycle read from the devices and was told this period (what a replay feeds
    /// back in).
    pub inputs: CycleInputs,
}

/// How the e-stop read in a period.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum EStopReading {
    /// Not pressed.
    #[default]
    Released,
    /// Pressed (latched).
    Pressed,
    /// The input could not be read (taken as pressed).
    Failed,
}

/// What became of the period's torque command.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TorqueWrite {
    /// Not written (drives powered off).
    #[default]
    NotWritten,
    /// Written.
    Written,
    /// The write failed.
    Failed,
}

/// An operation on the cycle from outside its period (a supervisor command, a stop, a trip),
/// recorded so that a replay applies it at the same point.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum CycleOp {
    /// No operation (an empty slot).
    #[default]
    None,
    /// [`ControlCycle::release_wire`].
    ReleaseWire(Option<u8>),
    /// [`ControlCycle::reset_faults`].
    ResetFaults,
    /// [`ControlCycle::restart`].
    Restart,
    /// [`ControlCycle::request_stop`].
    RequestStop,
    /// [`ControlCycle::trip`].
    Trip(SafetyState),
}

/// Operations on the cycle since its previous period, in order (at most
/// [`CycleOps::CAPACITY`]; more are counted as an overflow, which makes the period
/// unreplayable).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct CycleOps {
    ops: [CycleOp; CycleOps::CAPACITY],
    len: u8,
    overflowed: bool,
}

impl CycleOps {
    /// Operations kept per period.
    pub const CAPACITY: usize = 8;

    /// Append an operation (counted as an overflow when full).
    pub fn push(&mut self, op: CycleOp) {
        match self.ops.get_mut(usize::from(self.len)) {
            Some(slot) => {
                *slot = op;
                self.len += 1;
            }
            None => self.overflowed = true,
        }
    }

    /// The operations, in order.
    pub fn as_slice(&self) -> &[CycleOp] {
        &self.ops[..usize::from(self.len)]
    }

    /// Whether more operations came than were kept.
    pub fn overflowed(&self) -> bool {
        self.overflowed
    }

    /// Mark as overflowed (a decoded record that said so).
    pub fn set_overflowed(&mut self) {
        self.overflowed = true;
    }
}

/// What one period of [`ControlCycle::run`] read from the devices and was told: with the
/// configuration, the calibration and the surfaces of the session, everything its outputs
/// depend on.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CycleInputs {
    /// The record comes from [`ControlCycle::run`] (`false`: a procedure's period, which a
    /// replay skips).
    pub from_cycle: bool,
    /// The loop asked for the deadline-overrun trip this period.
    pub deadline_overrun: bool,
    /// The drives were read without error.
    pub drives_read_ok: bool,
    /// The drive samples as read (whatever the read left in them on an error).
    pub drives: [DriveSample; WIREMAN_WIRES],
    /// The tensions were read without error.
    pub tensions_read_ok: bool,
    /// The tensions as read, newtons (whatever the read left in them on an error).
    pub tensions_read_n: [f64; WIREMAN_WIRES],
    /// Which wires' tension samples were new conversions (a converter slower than the control
    /// rate repeats its last one in between).
    pub tensions_fresh: [bool; WIREMAN_WIRES],
    /// The passive angle sensors were read without error (a device without them: `false`).
    pub angles_read_ok: bool,
    /// The passive angles as read (azimuth, elevation), radians; zero without angle sensors.
    pub angles_rad: [f64; 2],
    /// The e-stop reading.
    pub estop: EStopReading,
    /// The torque command's fate.
    pub torque_write: TorqueWrite,
    /// The surface came from a live source.
    pub surface_live: bool,
    /// This period is the first to render a surface version made from a camera frame: how
    /// long ago the frame was captured, nanoseconds (`SurfaceView::frame_age_ns`).
    pub surface_frame_age_ns: Option<u64>,
    /// Operations on the cycle since the previous period, applied before this one.
    pub ops: CycleOps,
}

impl CycleRecord {
    /// Names of the record's 3-vectors, in the order of [`CycleRecord::vectors`].
    pub const VECTOR_NAMES: [&'static str; 8] = [
        "lengths_m",
        "tension_setpoint_n",
        "tension_measured_n",
        "torque_nm",
        "position_m",
        "velocity_m_s",
        "desired_force_n",
        "rendered_force_n",
    ];

    /// The record's 3-vectors, in a fixed order (telemetry and CSV columns use it).
    pub fn vectors(&self) -> [&[f64; 3]; 8] {
        [
            &self.lengths_m,
            &self.tension_setpoint_n,
            &self.tension_measured_n,
            &self.torque_nm,
            &self.position_m,
            &self.velocity_m_s,
            &self.desired_force_n,
            &self.rendered_force_n,
        ]
    }

    /// The record's 3-vectors, mutably, in the order of [`CycleRecord::vectors`].
    pub fn vectors_mut(&mut self) -> [&mut [f64; 3]; 8] {
        [
            &mut self.lengths_m,
            &mut self.tension_setpoint_n,
            &mut self.tension_measured_n,
            &mut self.torque_nm,
            &mut self.position_m,
            &mut self.velocity_m_s,
            &mut self.desired_force_n,
            &mut self.rendered_force_n,
        ]
    }
}

/// How the encoder counts become wire lengths: `length = length_at_zero_m - counts * m/count`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WireZero {
    /// Wire length at encoder count zero, metres (0 after homing against the guide ring).
    pub length_at_zero_m: [f64; WIREMAN_WIRES],
}

impl Default for WireZero {
    fn default() -> Self {
        WireZero {
            length_at_zero_m: [0.0; WIREMAN_WIRES],
        }
    }
}

/// Settings of the cycle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CycleSettings {
    /// Transmission of every wire.
    pub transmission: Transmission,
    /// Encoder zero of every wire.
    pub wire_zero: WireZero,
    /// Period, seconds.
    pub period_s: f64,
    /// Duration of the start and stop force ramps, seconds.
    pub ramp_s: f64,
    /// The rig has a valid calibration (forces are rendered only then).
    pub calibrated: bool,
    /// A live surface older than this is stale, seconds.
    pub surface_max_age_s: f64,
    /// Time over which forces fade out on a stale surface (and back in), seconds.
    pub surface_fade_s: f64,
}

/// Where the force ramp is.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Ramp {
    Up,
    Steady,
    Down,
    Finished,
}

/// The control cycle of an `N`-wire device `D`: devices in, devices out, one period at a time.
/// One cycle for every device, monomorphized: the wire count is chosen when the service starts.
#[derive(Debug, Clone)]
pub struct ControlCycle<const N: usize, D: WireDevice<N>> {
    step: ControlStep<N, D>,
    safety: SafetySupervisor<N>,
    settings: CycleSettings,
    samples: [DriveSample; N],
    output: StepOutput<N>,
    /// The passive angles of the last [`ANGLE_RATE_PERIODS`] periods (rates by difference over
    /// them), radians, and how many are held.
    angle_history: [[f64; 2]; ANGLE_RATE_PERIODS],
    angle_history_len: usize,
    ramp: Ramp,
    /// When the shutdown ramp began (the period before its first, s) and the force scale then.
    ramp_down_from: Option<(f64, f64)>,
    force_scale: f64,
    cycle: u64,
    powered_off: bool,
    surface_version: u64,
    surface_changed_at_s: f64,
    surface_scale: f64,
    released_wire: Option<usize>,
    pending_ops: CycleOps,
}

impl<const N: usize, D: WireDevice<N>> ControlCycle<N, D> {
    /// A cycle for a control step, safety limits and settings.
    pub fn new(
        step: ControlStep<N, D>,
        limits: SafetyLimits,
        settings: CycleSettings,
    ) -> ControlCycle<N, D> {
        const {
            assert!(
                N >= 1 && N <= WIREMAN_WIRES,
                "the session log holds 1 to 3 wires"
            )
        };
        ControlCycle {
            step,
            safety: SafetySupervisor::new(limits),
            settings,
            samples: [DriveSample::default(); N],
            output: StepOutput::default(),
            angle_history: [[0.0; 2]; ANGLE_RATE_PERIODS],
            angle_history_len: 0,
            ramp: Ramp::Up,
            ramp_down_from: None,
            force_scale: 0.0,
            cycle: 0,
            powered_off: false,
            surface_version: 0,
            surface_changed_at_s: 0.0,
            surface_scale: 1.0,
            released_wire: None,
            pending_ops: CycleOps::default(),
        }
    }

    /// The device geometry the cycle computes with.
    pub fn rig(&self) -> &D {
        self.step.rig()
    }

    /// Whether the cycle renders forces at all (the rig was calibrated).
    pub fn calibrated(&self) -> bool {
        self.settings.calibrated
    }

    /// Release wire `wire` for replacement: no force rendering, that wire unpowered (it can be
    /// pulled out by hand), the others held at minimum tension. `None` resumes.
    pub fn release_wire(&mut self, wire: Option<usize>) {
        self.pending_ops
            .push(CycleOp::ReleaseWire(wire.map(|w| w.min(255) as u8)));
        self.released_wire = wire.filter(|&w| w < N);
    }

    /// The wire released for replacement, if any.
    pub fn released_wire(&self) -> Option<usize> {
        self.released_wire
    }

    /// Clear latched faults (operator action). The drives stay off after a power-off fault
    /// until the service is restarted.
    pub fn reset_faults(&mut self) {
        self.pending_ops.push(CycleOp::ResetFaults);
        if !self.powered_off {
            self.safety.reset();
        }
    }

    /// Start rendering again after a hand-over (a procedure ran on the hardware): forces ramp
    /// back in from minimum tension, the tension controllers start afresh; latched faults stay.
    pub fn restart(&mut self) {
        self.pending_ops.push(CycleOp::Restart);
        self.ramp = Ramp::Up;
        self.ramp_down_from = None;
        self.force_scale = 0.0;
        self.released_wire = None;
        self.step.reset();
    }

    /// The encoder zeros the cycle measures lengths with.
    pub fn wire_zero(&self) -> WireZero {
        self.settings.wire_zero
    }

    /// Periods counted so far (the next record's `cycle`).
    pub fn cycle_count(&self) -> u64 {
        self.cycle
    }

    /// Continue the period count from `count` (a cycle that replaces another one).
    pub fn set_cycle_count(&mut self, count: u64) {
        self.cycle = count;
    }

    /// The current safety state.
    pub fn safety_state(&self) -> SafetyState {
        self.safety.state()
    }

    /// Begin the shutdown ramp: forces fade to zero (every wire to `t_min`) over the ramp time.
    pub fn request_stop(&mut self) {
        self.pending_ops.push(CycleOp::RequestStop);
        if self.ramp != Ramp::Finished {
            self.ramp = Ramp::Down;
        }
    }

    /// Whether the shutdown ramp has finished (or the drives are already off).
    pub fn stop_finished(&self) -> bool {
        self.ramp == Ramp::Finished || (self.ramp == Ramp::Down && self.powered_off)
    }

    /// Force the safe state from outside (stale surface, overruns, an operator's stop).
    pub fn trip(&mut self, state: SafetyState) {
        self.pending_ops.push(CycleOp::Trip(state));
        self.safety.trip(state);
    }

    /// The last step output.
    pub fn output(&self) -> &StepOutput<N> {
        &self.output
    }

    /// Run one period: read, supervise, compute, write; fill `record`.
    pub fn run<H, S>(
        &mut self,
        hw: &mut H,
        view: SurfaceView<'_, S>,
        now: MonoTime,
        deadline_overrun: bool,
        record: &mut CycleRecord,
    ) where
        H: WireDrives<N> + TensionSensors<N> + EStop + AngleSensors,
        S: Surface + ?Sized,
    {
        let dt = self.settings.period_s;
        let mut inputs = CycleInputs {
            from_cycle: true,
            deadline_overrun,
            surface_live: view.live,
            surface_frame_age_ns: view.frame_age_ns,
            ops: core::mem::take(&mut self.pending_ops),
            ..CycleInputs::default()
        };
        let mut input = SafetyInput {
            dt_s: dt,
            deadline_overrun,
            calibrated: self.settings.calibrated,
            drives_enabled: !self.powered_off,
            setpoint_tension_n: self.output.distribution.tensions_n,
            ..SafetyInput::default()
        };
        inputs.drives_read_ok = hw.read_drives(&mut self.samples).is_ok();
        inputs.drives[..N].copy_from_slice(&self.samples);
        if !inputs.drives_read_ok {
            input.drive_fault = Some(None);
        }
        for (i, s) in self.samples.iter().enumerate() {
            if s.state == DriveState::Fault {
                input.drive_fault = Some(Some(i as u8));
            }
        }
        let mut measured = [0.0; N];
        let read = hw.read_fresh_tensions(&mut measured);
        inputs.tensions_read_ok = read.is_ok();
        inputs.tensions_fresh[..N].copy_from_slice(&read.unwrap_or([false; N]));
        inputs.tensions_read_n[..N].copy_from_slice(&measured);
        if !inputs.tensions_read_ok {
            input.sensor_fault = Some(None);
            measured = self.output.distribution.tensions_n;
        }
        input.measured_tension_n = measured;
        // The passive angles of a device that has them: a failed read is a sensor fault (the
        // thimble's position is unknown); the rates come from the previous period's angles.
        let mut angle_rates_rad_s = [0.0; 2];
        if D::KIND.has_angle_sensors() {
            let mut angles = [0.0; 2];
            inputs.angles_read_ok = hw.read_angles(&mut angles).is_ok();
            if inputs.angles_read_ok {
                inputs.angles_rad = angles;
                // The oldest held angle is `len` periods old (the history is a shift register,
                // newest last).
                let len = self.angle_history_len;
                if len > 0 {
                    let oldest = self.angle_history[ANGLE_RATE_PERIODS - len];
                    angle_rates_rad_s = angle_rates(&oldest, &angles, dt * len as f64);
                }
                self.angle_history.copy_within(1.., 0);
                self.angle_history[ANGLE_RATE_PERIODS - 1] = angles;
                self.angle_history_len = (len + 1).min(ANGLE_RATE_PERIODS);
            } else {
                input.sensor_fault = Some(None);
                inputs.angles_rad = if self.angle_history_len > 0 {
                    self.angle_history[ANGLE_RATE_PERIODS - 1]
                } else {
                    [0.0; 2]
                };
            }
        }
        let estop = hw.is_pressed();
        inputs.estop = match estop {
            Ok(false) => EStopReading::Released,
            Ok(true) => EStopReading::Pressed,
            Err(_) => EStopReading::Failed,
        };
        input.estop_pressed = estop.unwrap_or(true);

        let tr = &self.settings.transmission;
        let mpc = tr.metres_per_count();
        let mut step_in = StepInput {
            measured_tension_n: measured,
            angles_rad: inputs.angles_rad,
            angle_rates_rad_s,
            dt_s: dt,
            ..StepInput::default()
        };
        for i in 0..N {
            step_in.lengths_m[i] = self.settings.wire_zero.length_at_zero_m[i]
                - self.samples[i].position_counts as f64 * mpc;
            // Winding (positive counts/s) shortens the wire.
            step_in.length_rates_m_s[i] = -tr.wire_speed(self.samples[i].velocity_counts_per_s);
            input.wire_speed_m_s[i] = step_in.length_rates_m_s[i];
        }
        let state = self.safety.update(&input);

        // Ramp the rendered force in on start and out on stop.
        let now_s = now.as_secs_f64();
        let ramp_step = if self.settings.ramp_s > 0.0 {
            dt / self.settings.ramp_s
        } else {
            1.0
        };
        match self.ramp {
            Ramp::Up => {
                self.force_scale = (self.force_scale + ramp_step).min(1.0);
                if self.force_scale >= 1.0 {
                    self.ramp = Ramp::Steady;
                }
            }
            Ramp::Steady => {}
            Ramp::Down => {
                // By the clock, not by periods: late periods (an overloaded CPU) do not stretch
                // the stop beyond the ramp time.
                let (since_s, from) = *self
                    .ramp_down_from
                    .get_or_insert((now_s - dt, self.force_scale));
                self.force_scale = if self.settings.ramp_s > 0.0 {
                    (from - (now_s - since_s).max(0.0) / self.settings.ramp_s).max(0.0)
                } else {
                    0.0
                };
                if self.force_scale <= 0.0 {
                    self.ramp = Ramp::Finished;
                }
            }
            Ramp::Finished => self.force_scale = 0.0,
        }
        // A live surface that stopped changing is stale: fade the forces out (and back in when a
        // new model arrives).
        if view.version != self.surface_version {
            self.surface_version = view.version;
            self.surface_changed_at_s = now_s;
        }
        let stale =
            view.live && now_s - self.surface_changed_at_s > self.settings.surface_max_age_s;
        let fade_step = if self.settings.surface_fade_s > 0.0 {
            dt / self.settings.surface_fade_s
        } else {
            1.0
        };
        self.surface_scale = if stale {
            (self.surface_scale - fade_step).max(0.0)
        } else {
            (self.surface_scale + fade_step).min(1.0)
        };

        step_in.render_forces = state.renders_forces() && self.released_wire.is_none();
        step_in.force_scale = self.force_scale * self.surface_scale;
        self.step.update(&step_in, view.surface, &mut self.output);
        if let Some(w) = self.released_wire {
            self.output.torque_nm[w] = 0.0;
        }

        if state.power_off() {
            if !self.powered_off {
                // Power off is the safe state itself: a failing disable cannot make it safer.
                let _ = hw.disable();
                self.powered_off = true;
                self.step.reset();
            }
            self.output.torque_nm = [0.0; N];
        } else if hw.write_torques(&self.output.torque_nm).is_err() {
            inputs.torque_write = TorqueWrite::Failed;
            self.safety
                .trip(SafetyState::PowerOff(SafetyReason::DriveFault {
                    wire: None,
                }));
        } else {
            inputs.torque_write = TorqueWrite::Written;
        }

        let o = &self.output;
        *record = CycleRecord {
            cycle: self.cycle,
            time: now,
            wake_latency_ns: record.wake_latency_ns,
            compute_ns: record.compute_ns,
            lengths_m: slots(&step_in.lengths_m),
            tension_setpoint_n: slots(&o.distribution.tensions_n),
            tension_measured_n: slots(&measured),
            torque_nm: slots(&o.torque_nm),
            position_m: o.position_m.into(),
            velocity_m_s: o.velocity_m_s.into(),
            desired_force_n: o.desired_force_n.into(),
            rendered_force_n: o.distribution.rendered_n.into(),
            contact_depth_m: o.contact.map_or(0.0, |c| c.depth_m),
            in_contact: o.contact.is_some(),
            safety: self.safety.state(),
            force_scale: step_in.force_scale,
            surface_version: self.surface_version,
            surface_stale: stale,
            released_wire: self.released_wire.map_or(-1, |w| w as i8),
            inputs,
        };
        self.cycle += 1;
    }
}

/// Periods over which the passive angles are differenced into rates: a 14-bit encoder's count
/// (0.38 mrad) over one 1 ms period is 0.4 rad/s, about 0.15 m/s at the end of a 0.4 m wire,
/// noise the contact damping would render; over ten periods it is a tenth of that, for 5 ms of
/// delay.
pub const ANGLE_RATE_PERIODS: usize = 10;

/// `N` per-wire values in the record's slots (the rest zero).
fn slots<const N: usize>(values: &[f64; N]) -> [f64; WIREMAN_WIRES] {
    let mut out = [0.0; WIREMAN_WIRES];
    out[..N].copy_from_slice(values);
    out
}

/// Rates of two angles between periods `dt_s` apart, the shorter way round (an angle wraps at
/// ±π).
fn angle_rates(last: &[f64; 2], now: &[f64; 2], dt_s: f64) -> [f64; 2] {
    core::array::from_fn(|i| {
        let d = (now[i] - last[i] + core::f64::consts::PI).rem_euclid(core::f64::consts::TAU)
            - core::f64::consts::PI;
        if dt_s > 0.0 && d.is_finite() {
            d / dt_s
        } else {
            0.0
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn angle_rates_take_the_short_way_round() {
        let r = angle_rates(&[3.1, 0.0], &[-3.1, 0.01], 0.01);
        assert!(
            (r[0] - (core::f64::consts::TAU - 6.2) / 0.01).abs() < 1e-9,
            "{r:?}"
        );
        assert!((r[1] - 1.0).abs() < 1e-9);
        assert_eq!(angle_rates(&[0.0; 2], &[f64::NAN, 0.0], 0.01)[0], 0.0);
        assert_eq!(angle_rates(&[0.0; 2], &[1.0, 1.0], 0.0), [0.0; 2]);
    }
}
