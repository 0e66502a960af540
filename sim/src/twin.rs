//! The plant behind the HAL: drives, encoders, tension sensors, e-stop and a simulated clock.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use videt_control::WireDevice;
use videt_hal::{
    AngleSensors, Clock, DriveSample, DriveState, EStop, Error, ErrorKind, ErrorType, Lifecycle,
    LifecycleState, MonoTime, TensionSensors, WireDrives,
};

use crate::converter::{ConverterModel, ConverterTwin};
pub use crate::fault::TwinFault;
use crate::operator::VirtualOperator;
use crate::plant::{Plant, PlantParams};
use crate::wiring::Wiring;
use crate::Vec3;

/// A twin device error.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TwinError {
    /// What kind of failure.
    pub kind: ErrorKind,
    /// Which wire (drive or sensor), when it concerns one.
    pub wire: Option<usize>,
}

impl Error for TwinError {
    fn kind(&self) -> ErrorKind {
        self.kind
    }
}

impl core::fmt::Display for TwinError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self.wire {
            Some(w) => write!(f, "simulated device {} on wire {w}", self.kind),
            None => write!(f, "simulated device {}", self.kind),
        }
    }
}

impl std::error::Error for TwinError {}

/// How the twin's strain gauges err.
#[derive(Debug, Clone, PartialEq)]
pub struct SensorModel<const N: usize> {
    /// Offset of each sensor, newtons.
    pub offset_n: [f64; N],
    /// Relative gain error of each sensor (0.02 = reads 2% high).
    pub gain_error: [f64; N],
    /// Standard deviation of the white noise, newtons.
    pub noise_std_n: f64,
    /// Seed of the noise generator (runs are reproducible).
    pub seed: u64,
    /// The converters' timing (data rate, filter, quantization); `None`: every read returns
    /// the tension of that instant.
    pub converter: Option<ConverterModel>,
}

impl<const N: usize> Default for SensorModel<N> {
    fn default() -> Self {
        SensorModel {
            // The same per-wire errors as the three-wire default, repeated for more wires.
            offset_n: core::array::from_fn(|i| [0.02, -0.03, 0.01][i % 3]),
            gain_error: core::array::from_fn(|i| [0.01, -0.015, 0.005][i % 3]),
            noise_std_n: 0.02,
            seed: 1,
            converter: None,
        }
    }
}

impl<const N: usize> SensorModel<N> {
    /// Ideal sensors (no offset, gain error or noise).
    pub fn ideal() -> SensorModel<N> {
        SensorModel {
            offset_n: [0.0; N],
            gain_error: [0.0; N],
            noise_std_n: 0.0,
            seed: 0,
            converter: None,
        }
    }
}

/// Most faults that can be scheduled at once.
pub const FAULT_SLOTS: usize = 8;

/// How the twin's clock runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ClockMode {
    /// `sleep_until` advances the physics to the deadline at once: faster than real time and
    /// deterministic. For tests and replays.
    Simulated,
    /// Time is kept by a real clock outside the twin, which calls [`Twin::advance_to`].
    External,
}

/// The digital twin of a whole `N`-wire device `D`, implementing the HAL traits (the passive
/// angle sensors too: they read the wire's direction, eq. 7, on a device that has them).
#[derive(Debug)]
pub struct Twin<const N: usize, D: WireDevice<N>> {
    plant: Plant<N, D>,
    operator: VirtualOperator,
    sensors: SensorModel<N>,
    converters: Option<Box<[ConverterTwin; N]>>,
    rng: ChaCha8Rng,
    lifecycle: LifecycleState,
    drives_enabled: bool,
    torque_command_nm: [f64; N],
    /// One step of the drives' target torque, N·m (`None`: torque as commanded).
    torque_step_nm: Option<f64>,
    /// Largest torque the simulated motors deliver, N·m.
    motor_torque_limit_nm: f64,
    estop_held: bool,
    estop_latched: bool,
    failed_sensor: Option<usize>,
    faulted_drive: Option<usize>,
    clock_mode: ClockMode,
    steps_done: u64,
    step_ns: u64,
    /// Encoder count at free length zero (an incremental encoder starts anywhere at power-up).
    encoder_offset_counts: [i64; N],
    scheduled: [Option<(MonoTime, TwinFault)>; FAULT_SLOTS],
    inbox: std::sync::Arc<crate::fault_inbox::FaultInbox>,
    wiring: Wiring<N>,
}

/// The torque a drive whose target torque comes in steps of `step_nm` (one per mille of its
/// rated torque) applies for a command of `torque_nm`: the nearest whole step, at most 32767
/// steps either way (the INTEGER16 of 0x6071). **RT-safe**.
pub fn quantize_torque(torque_nm: f64, step_nm: f64) -> f64 {
    let steps = (torque_nm / step_nm).round();
    if steps.is_nan() {
        return 0.0;
    }
    steps.clamp(f64::from(i16::MIN), f64::from(i16::MAX)) * step_nm
}

/// One converter per wire, each free-running at its own phase.
fn converters_for<const N: usize>(m: ConverterModel) -> Box<[ConverterTwin; N]> {
    Box::new(core::array::from_fn(|i| {
        ConverterTwin::new(m, m.period_s() * (0.17 + 0.31 * i as f64))
    }))
}

impl<const N: usize, D: WireDevice<N>> Twin<N, D> {
    /// A twin with the thimble at `start_m` (wires just taut), an operator, and sensor errors.
    pub fn new(
        params: PlantParams<N, D>,
        start_m: Vec3,
        operator: VirtualOperator,
        sensors: SensorModel<N>,
    ) -> Twin<N, D> {
        let step_ns = (params.step_s * 1e9).round() as u64;
        assert!(
            step_ns > 0 && step_ns <= 100_000,
            "integration step must be in (0, 100 µs]"
        );
        let rng = ChaCha8Rng::seed_from_u64(sensors.seed);
        // Free-running converters: each wire's at its own phase.
        let converters = sensors.converter.map(converters_for);
        Twin {
            plant: Plant::new(params, start_m),
            operator,
            sensors,
            converters,
            rng,
            lifecycle: LifecycleState::Unconfigured,
            drives_enabled: false,
            torque_command_nm: [0.0; N],
            torque_step_nm: None,
            motor_torque_limit_nm: 0.03,
            estop_held: false,
            estop_latched: false,
            failed_sensor: None,
            faulted_drive: None,
            clock_mode: ClockMode::Simulated,
            steps_done: 0,
            step_ns,
            encoder_offset_counts: [0; N],
            scheduled: [None; FAULT_SLOTS],
            inbox: Default::default(),
            wiring: Wiring::default(),
        }
    }

    /// Where each encoder counts from: the count read with the wire's free length at zero
    /// (default 0, i.e. the encoders start homed). Homing must find these.
    pub fn set_encoder_offset_counts(&mut self, offset_counts: [i64; N]) {
        self.encoder_offset_counts = offset_counts;
    }
    /// The encoder offsets (ground truth for tests).
    pub fn encoder_offset_counts(&self) -> [i64; N] {
        self.encoder_offset_counts
    }
    /// The e-stop button is held down now.
    pub fn estop_held(&self) -> bool {
        self.estop_held
    }

    /// Choose how the clock runs (default [`ClockMode::Simulated`]).
    pub fn set_clock_mode(&mut self, mode: ClockMode) {
        self.clock_mode = mode;
    }
    /// The plant (true state, for tests and status).
    pub fn plant(&self) -> &Plant<N, D> {
        &self.plant
    }
    /// The plant, mutably (fault injection, scenario set-up).
    pub fn plant_mut(&mut self) -> &mut Plant<N, D> {
        &mut self.plant
    }
    /// The virtual operator.
    pub fn operator(&self) -> &VirtualOperator {
        &self.operator
    }
    /// Give the strain gauges another converter timing (`None`: every read returns the tension
    /// of that instant).
    pub fn set_sensor_converter(&mut self, converter: Option<ConverterModel>) {
        self.sensors.converter = converter;
        self.converters = converter.map(converters_for);
    }

    /// Model the drives' torque resolution: a CiA 402 drive takes its target torque (0x6071)
    /// in whole per mille of its rated torque (0x6076), so its motor applies the commanded
    /// torque rounded to the nearest `step_nm` (the rated torque / 1000) and saturated at
    /// ±32767 steps, as [`quantize_torque`] computes. The CAN twin's simulated drives do the
    /// same with the per mille the driver sends them. `None` (the default), or a step that is
    /// not a positive number: the torque as commanded.
    pub fn set_torque_step_nm(&mut self, step_nm: Option<f64>) {
        self.torque_step_nm = step_nm.filter(|s| s.is_finite() && *s > 0.0);
    }
    /// One step of the drives' target torque, N·m, when modelled.
    pub fn torque_step_nm(&self) -> Option<f64> {
        self.torque_step_nm
    }

    /// Replace the virtual operator's script.
    pub fn set_operator(&mut self, operator: VirtualOperator) {
        self.operator = operator;
    }
    /// Wire the twin's channels as `wiring` says (see [`Wiring`]). An invalid wiring (a wire
    /// reached twice) is refused and the wiring unchanged.
    pub fn set_wiring(&mut self, wiring: Wiring<N>) -> bool {
        if !wiring.is_valid() {
            return false;
        }
        self.wiring = wiring;
        self.set_estop_button(self.estop_held);
        true
    }
    /// How the channels reach the wires.
    pub fn wiring(&self) -> &Wiring<N> {
        &self.wiring
    }
    /// Press (`true`) or release the e-stop button. A press latches; so does a release on an
    /// input wired to the other level, which reads it as a press.
    pub fn set_estop_button(&mut self, held: bool) {
        self.estop_held = held;
        if self.estop_reads_pressed() {
            self.estop_latched = true;
        }
    }
    /// Whether the e-stop input is at its pressed level now.
    fn estop_reads_pressed(&self) -> bool {
        self.estop_held != self.wiring.estop_inverted
    }
    /// Make tension sensor `wire` fail (reads return `Disconnected`), or heal it with `None`.
    pub fn fail_tension_sensor(&mut self, wire: Option<usize>) {
        self.failed_sensor = wire;
    }
    /// Latch a fault in drive `wire` (it stops delivering torque and reports `Fault`).
    pub fn fault_drive(&mut self, wire: usize) {
        self.faulted_drive = Some(wire);
    }
    /// The torques the drives are applying, N·m.
    pub fn applied_torque_nm(&self) -> [f64; N] {
        let mut t = [0.0; N];
        if self.drives_enabled {
            for (i, ti) in t.iter_mut().enumerate() {
                if self.faulted_drive != Some(i) {
                    *ti = self.torque_command_nm[i]
                        .clamp(-self.motor_torque_limit_nm, self.motor_torque_limit_nm);
                }
            }
        }
        t
    }
    /// Whether the drives are powered.
    pub fn drives_enabled(&self) -> bool {
        self.drives_enabled
    }
    /// Simulated time.
    pub fn sim_time(&self) -> MonoTime {
        MonoTime(self.steps_done * self.step_ns)
    }

    /// Schedule `fault` to happen at simulated time `at`. Returns false when every slot is
    /// taken.
    pub fn schedule_fault(&mut self, at: MonoTime, fault: TwinFault) -> bool {
        match self.scheduled.iter_mut().find(|s| s.is_none()) {
            Some(slot) => {
                *slot = Some((at, fault));
                true
            }
            None => false,
        }
    }

    /// Make `fault` happen now. A fault on a wire the device does not have does nothing.
    pub fn inject(&mut self, fault: TwinFault) {
        let wire = match fault {
            TwinFault::BreakWire(w)
            | TwinFault::FailTensionSensor(w)
            | TwinFault::FaultDrive(w)
            | TwinFault::DetachWire(w)
            | TwinFault::SlipWire(w, _) => Some(w),
            TwinFault::PressEStop => None,
        };
        if wire.is_some_and(|w| w >= N) {
            return;
        }
        match fault {
            TwinFault::BreakWire(w) => self.plant.break_wire(w),
            TwinFault::PressEStop => self.set_estop_button(true),
            TwinFault::FailTensionSensor(w) => self.fail_tension_sensor(Some(w)),
            TwinFault::FaultDrive(w) => self.fault_drive(w),
            TwinFault::DetachWire(w) => self.plant.detach_wire(w),
            TwinFault::SlipWire(w, counts) => self.encoder_offset_counts[w] += counts,
        }
    }

    /// The inbox through which another thread posts faults to this twin while it runs.
    pub fn fault_inbox(&self) -> std::sync::Arc<crate::fault_inbox::FaultInbox> {
        std::sync::Arc::clone(&self.inbox)
    }

    fn fire_due_faults(&mut self) {
        let now = self.sim_time();
        if self.inbox.has_posts() {
            let inbox = std::sync::Arc::clone(&self.inbox);
            inbox.take(now.0, |f| match f {
                crate::fault_inbox::InboxFault::Fault(fault) => self.inject(fault),
                crate::fault_inbox::InboxFault::RestoreTensionSensor => {
                    self.fail_tension_sensor(None)
                }
                crate::fault_inbox::InboxFault::ReleaseEStop => self.set_estop_button(false),
            });
        }
        for i in 0..FAULT_SLOTS {
            if let Some((at, fault)) = self.scheduled[i] {
                if at <= now {
                    self.scheduled[i] = None;
                    self.inject(fault);
                }
            }
        }
    }

    /// Advance the physics to `t` (no-op when `t` is not later than the simulated time),
    /// firing scheduled faults on the way. Allocation-free; one plant step per integration step.
    pub fn advance_to(&mut self, t: MonoTime) {
        while self.sim_time() < t {
            self.fire_due_faults();
            let torque = self.wiring.wire_torques(&self.applied_torque_nm());
            self.plant.step(&torque, &self.operator);
            self.steps_done += 1;
        }
    }

    /// Standard normal sample (Box-Muller).
    fn gaussian(&mut self) -> f64 {
        let u1: f64 = self.rng.random::<f64>().max(1e-300);
        let u2: f64 = self.rng.random::<f64>();
        (-2.0 * u1.ln()).sqrt() * (core::f64::consts::TAU * u2).cos()
    }
}

impl<const N: usize, D: WireDevice<N>> ErrorType for Twin<N, D> {
    type Error = TwinError;
}

impl<const N: usize, D: WireDevice<N>> Lifecycle for Twin<N, D> {
    fn configure(&mut self) -> Result<(), TwinError> {
        self.lifecycle = LifecycleState::Inactive;
        Ok(())
    }
    fn activate(&mut self) -> Result<(), TwinError> {
        if self.lifecycle == LifecycleState::Unconfigured {
            return Err(TwinError {
                kind: ErrorKind::NotReady,
                wire: None,
            });
        }
        self.lifecycle = LifecycleState::Active;
        Ok(())
    }
    fn deactivate(&mut self) -> Result<(), TwinError> {
        self.drives_enabled = false;
        self.torque_command_nm = [0.0; N];
        if self.lifecycle != LifecycleState::Unconfigured {
            self.lifecycle = LifecycleState::Inactive;
        }
        Ok(())
    }
    fn lifecycle_state(&self) -> LifecycleState {
        self.lifecycle
    }
}

impl<const N: usize, D: WireDevice<N>> WireDrives<N> for Twin<N, D> {
    fn enable(&mut self) -> Result<(), TwinError> {
        if self.lifecycle != LifecycleState::Active {
            return Err(TwinError {
                kind: ErrorKind::NotReady,
                wire: None,
            });
        }
        if let Some(w) = self.faulted_drive {
            return Err(TwinError {
                kind: ErrorKind::Fault,
                wire: Some(w),
            });
        }
        self.drives_enabled = true;
        Ok(())
    }

    fn disable(&mut self) -> Result<(), TwinError> {
        self.drives_enabled = false;
        self.torque_command_nm = [0.0; N];
        Ok(())
    }

    fn read_drives(&mut self, out: &mut [DriveSample; N]) -> Result<(), TwinError> {
        let tr = self.plant.params().transmission;
        let counts_per_pulley_rad =
            tr.counts_per_motor_rev as f64 * tr.gear_ratio / core::f64::consts::TAU;
        let free = self.plant.free_length_m();
        let speed = self.plant.pulley_speed_rad_s();
        for i in 0..N {
            // Channel i reads the encoder on its wire, in its direction.
            let (wire, sign) = (self.wiring.drive_wire[i], self.wiring.encoder_sign(i));
            // Encoder zero = wire fully wound (free length 0), as after homing.
            let wound_rad = -free[wire] / tr.pulley_radius_m;
            out[i] = DriveSample {
                position_counts: (sign * wound_rad * counts_per_pulley_rad).floor() as i64
                    + self.encoder_offset_counts[i],
                velocity_counts_per_s: sign * speed[wire] * counts_per_pulley_rad,
                state: if self.faulted_drive == Some(i) {
                    DriveState::Fault
                } else if self.drives_enabled {
                    DriveState::Enabled
                } else {
                    DriveState::Disabled
                },
                error_code: if self.faulted_drive == Some(i) {
                    0x2310
                } else {
                    0
                },
            };
        }
        match self.faulted_drive {
            Some(w) => Err(TwinError {
                kind: ErrorKind::Fault,
                wire: Some(w),
            }),
            None => Ok(()),
        }
    }

    fn write_torques(&mut self, torque_nm: &[f64; N]) -> Result<(), TwinError> {
        if !self.drives_enabled {
            return Err(TwinError {
                kind: ErrorKind::NotReady,
                wire: None,
            });
        }
        self.torque_command_nm = match self.torque_step_nm {
            Some(step) => torque_nm.map(|t| quantize_torque(t, step)),
            None => *torque_nm,
        };
        Ok(())
    }
}

impl<const N: usize, D: WireDevice<N>> TensionSensors<N> for Twin<N, D> {
    fn read_tensions(&mut self, out_n: &mut [f64; N]) -> Result<(), TwinError> {
        self.read_fresh_tensions(out_n).map(|_| ())
    }

    fn read_fresh_tensions(&mut self, out_n: &mut [f64; N]) -> Result<[bool; N], TwinError> {
        if let Some(w) = self.failed_sensor {
            return Err(TwinError {
                kind: ErrorKind::Disconnected,
                wire: Some(w),
            });
        }
        let truth = self.plant.tension_n();
        for (i, out) in out_n.iter_mut().enumerate() {
            let noise = self.sensors.noise_std_n * self.gaussian();
            // Channel i reads the cell on its wire; an inverted cell, the other sign.
            let t = self.wiring.cell_sign(i) * truth[self.wiring.sensor_wire[i]];
            *out = t * (1.0 + self.sensors.gain_error[i]) + self.sensors.offset_n[i] + noise;
        }
        let Some(converters) = self.converters.as_mut() else {
            return Ok([true; N]);
        };
        let t = self.plant.time_s();
        let mut fresh = [false; N];
        for i in 0..N {
            converters[i].observe(t, out_n[i]);
            (out_n[i], fresh[i]) = converters[i].read();
        }
        Ok(fresh)
    }
}

impl<const N: usize, D: WireDevice<N>> AngleSensors for Twin<N, D> {
    /// The passive angles at the thimble, as an AS5048A's 14 bits resolve them. On a device
    /// without angle sensors: an `Other` error (it has none to read).
    fn read_angles(&mut self, out_rad: &mut [f64; 2]) -> Result<(), TwinError> {
        if !D::KIND.has_angle_sensors() {
            return Err(TwinError {
                kind: ErrorKind::Other,
                wire: None,
            });
        }
        let angles = self
            .plant
            .params()
            .device
            .passive_angles(&self.plant.position_m());
        for (out, a) in out_rad.iter_mut().zip(angles) {
            *out = crate::angle_sensors::quantize_angle(a, 0);
        }
        Ok(())
    }
}

impl<const N: usize, D: WireDevice<N>> EStop for Twin<N, D> {
    fn is_pressed(&mut self) -> Result<bool, TwinError> {
        Ok(self.estop_latched)
    }
    fn reset(&mut self) -> Result<(), TwinError> {
        if self.estop_reads_pressed() {
            return Err(TwinError {
                kind: ErrorKind::Fault,
                wire: None,
            });
        }
        self.estop_latched = false;
        Ok(())
    }
}

impl<const N: usize, D: WireDevice<N>> Clock for Twin<N, D> {
    fn now(&self) -> MonoTime {
        self.sim_time()
    }
    fn sleep_until(&mut self, deadline: MonoTime) {
        if self.clock_mode == ClockMode::Simulated {
            self.advance_to(deadline);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use videt_control::Rig3;

    const WIRES: usize = 3;

    fn twin() -> Twin<3, Rig3> {
        let start = Vec3::new(0.185, 0.12, 0.30);
        Twin::new(
            PlantParams::paper_default(),
            start,
            VirtualOperator::holding(start),
            SensorModel::default(),
        )
    }

    #[test]
    fn torque_is_applied_in_whole_steps_of_the_drives_resolution() {
        let mut t = twin();
        t.configure().unwrap();
        t.activate().unwrap();
        t.enable().unwrap();
        t.write_torques(&[0.01234, -0.01266, 0.0]).unwrap();
        assert_eq!(t.applied_torque_nm(), [0.01234, -0.01266, 0.0]);
        // A 1 N·m motor: steps of 1 mN·m.
        t.set_torque_step_nm(Some(0.001));
        t.write_torques(&[0.01234, -0.01266, 0.0004]).unwrap();
        let applied = t.applied_torque_nm();
        for (a, want) in applied.iter().zip([0.012, -0.013, 0.0]) {
            assert!((a - want).abs() < 1e-15, "{applied:?}");
        }
        assert_eq!(quantize_torque(1e9, 0.001), 32.767);
        assert_eq!(quantize_torque(-1e9, 0.001), -32.768);
        assert_eq!(quantize_torque(f64::NAN, 0.001), 0.0);
        t.set_torque_step_nm(Some(0.0));
        assert_eq!(t.torque_step_nm(), None, "not a step");
    }

    #[test]
    fn encoders_report_the_free_length_from_the_homed_zero() {
        let mut t = twin();
        let mut s = [DriveSample::default(); WIRES];
        t.read_drives(&mut s).unwrap();
        let mpc = t.plant().params().transmission.metres_per_count();
        for i in 0..WIRES {
            let length = -(s[i].position_counts as f64) * mpc;
            assert!(
                (length - t.plant().free_length_m()[i]).abs() <= mpc,
                "wire {i}"
            );
        }
    }

    #[test]
    fn a_miswired_twin_reads_and_moves_the_wires_its_channels_reach() {
        let mut t = twin();
        let mut truth = [DriveSample::default(); WIRES];
        t.read_drives(&mut truth).unwrap();
        assert!(t.set_wiring(Wiring {
            drive_wire: [1, 0, 2],
            encoder_reversed: [false, false, true],
            sensor_wire: [0, 2, 1],
            cell_inverted: [true, false, false],
            estop_inverted: true,
            ..Wiring::default()
        }));
        // The e-stop released reads pressed, and cannot be reset; pressed, it reads released.
        assert!(t.is_pressed().unwrap());
        assert!(t.reset().is_err());
        t.set_estop_button(true);
        t.reset().unwrap();
        assert!(!t.is_pressed().unwrap());
        let mut s = [DriveSample::default(); WIRES];
        t.read_drives(&mut s).unwrap();
        assert_eq!(s[0].position_counts, truth[1].position_counts);
        assert_eq!(s[1].position_counts, truth[0].position_counts);
        assert!((s[2].position_counts + truth[2].position_counts).abs() <= 1);
        // Channel 0's torque reaches wire 1.
        t.configure().unwrap();
        t.activate().unwrap();
        t.enable().unwrap();
        t.write_torques(&[0.01, 0.0, 0.0]).unwrap();
        assert_eq!(
            t.wiring().wire_torques(&t.applied_torque_nm()),
            [0.0, 0.01, 0.0]
        );
        let mut tension = [0.0; WIRES];
        t.advance_to(MonoTime(50_000_000));
        t.read_tensions(&mut tension).unwrap();
        let true_tension = t.plant().tension_n();
        assert!(
            true_tension[1] > 1.0 && true_tension[0] < 0.5,
            "{true_tension:?}"
        );
        assert!(tension[2] > 1.0 && tension[0] < 0.5, "{tension:?}");
        // An invalid wiring is refused.
        assert!(!t.set_wiring(Wiring {
            sensor_wire: [0, 0, 1],
            ..Wiring::default()
        }));
    }

    #[test]
    fn lifecycle_gates_commands() {
        let mut t = twin();
        assert_eq!(t.enable().unwrap_err().kind, ErrorKind::NotReady);
        t.configure().unwrap();
        t.activate().unwrap();
        t.enable().unwrap();
        t.write_torques(&[0.001; WIRES]).unwrap();
        t.deactivate().unwrap();
        assert!(!t.drives_enabled());
        assert_eq!(
            t.write_torques(&[0.001; WIRES]).unwrap_err().kind,
            ErrorKind::NotReady
        );
    }

    #[test]
    fn estop_latches_until_reset_after_release() {
        let mut t = twin();
        t.set_estop_button(true);
        t.set_estop_button(false);
        assert!(t.is_pressed().unwrap());
        t.set_estop_button(true);
        assert!(t.reset().is_err(), "cannot reset while held");
        t.set_estop_button(false);
        t.reset().unwrap();
        assert!(!t.is_pressed().unwrap());
    }

    #[test]
    fn a_fault_on_a_wire_the_device_lacks_does_nothing() {
        let start = Vec3::new(0.26, 0.0, 0.3);
        let mut t = Twin::new(
            PlantParams::for_device(videt_control::PlanarDevice::paper_prototype()),
            start,
            VirtualOperator::holding(start),
            SensorModel::<2>::ideal(),
        );
        for f in [
            TwinFault::BreakWire(2),
            TwinFault::SlipWire(3, 10),
            TwinFault::DetachWire(2),
            TwinFault::FailTensionSensor(2),
            TwinFault::FaultDrive(7),
        ] {
            t.inject(f);
        }
        assert!(t.plant().wire_intact(0) && t.plant().wire_intact(1));
        let mut tensions = [0.0; 2];
        t.read_tensions(&mut tensions).unwrap();
        let mut samples = [DriveSample::default(); 2];
        t.read_drives(&mut samples).unwrap();
        t.inject(TwinFault::BreakWire(1));
        assert!(!t.plant().wire_intact(1));
    }

    #[test]
    fn noise_is_reproducible() {
        let (mut a, mut b) = (twin(), twin());
        let (mut ta, mut tb) = ([0.0; WIRES], [0.0; WIRES]);
        for _ in 0..10 {
            a.read_tensions(&mut ta).unwrap();
            b.read_tensions(&mut tb).unwrap();
            assert_eq!(ta, tb);
        }
    }
}
