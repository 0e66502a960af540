//! Runs the procedure on the HAL, one period at a time, on the injected clock: read encoders,
//! tensions and the e-stop; let the procedure choose each wire's force; write the torques that
//! make it. The same code runs on the device and on the twin (whose simulated
//! clock makes it faster than real time and deterministic).
//!
//! The loop body allocates nothing; the progress callback is called on stage changes only.

use std::sync::atomic::{AtomicBool, Ordering};
use videt_runtime::WIREMAN_WIRES;

use videt_config::calibration::TensionCalibration;
use videt_control::autoinit::{Failure, Procedure, ProcedureInput, Stage, Status};
use videt_hal::{
    Clock, DriveSample, DriveState, EStop, MonoTime, TensionSensors, Transmission, WireDrives,
};

/// The device capabilities the procedure needs.
pub trait InitHardware:
    WireDrives<WIREMAN_WIRES> + TensionSensors<WIREMAN_WIRES> + EStop + Clock
{
}
impl<T: WireDrives<WIREMAN_WIRES> + TensionSensors<WIREMAN_WIRES> + EStop + Clock> InitHardware
    for T
{
}

/// How the procedure is run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RunSettings {
    /// Loop rate, Hz.
    pub rate_hz: u32,
    /// Transmission of every wire.
    pub transmission: Transmission,
    /// Tension every wire is held at when idle or after the procedure, N.
    pub pay_out_tension_n: f64,
    /// How long the wires are held at the pay-out tension after the procedure ends, seconds.
    pub hold_after_s: f64,
    /// While holding, a wire winding faster than half this speed has its force lowered, to zero
    /// at this speed (a dangling wire let go must not whip back), m/s.
    pub governor_speed_m_s: f64,
}

/// One period's readings.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Readings {
    /// Drive samples.
    pub drives: [DriveSample; WIREMAN_WIRES],
    /// Measured tensions, N.
    pub tension_n: [f64; WIREMAN_WIRES],
    /// The procedure's view of them.
    pub input: ProcedureInput,
}

/// The loop's state: tension controller and pacing.
#[derive(Debug)]
pub struct Runner {
    settings: RunSettings,
    next: MonoTime,
    started: bool,
    torque_nm: [f64; WIREMAN_WIRES],
    readings: Readings,
    lowest_counts: [i64; WIREMAN_WIRES],
    tension_correction: Option<TensionCalibration>,
    /// What the drives or the tension sensors said when a read first failed.
    device_error: Option<String>,
}

impl Runner {
    /// A runner; the first period starts at the first call.
    pub fn new(settings: RunSettings) -> Runner {
        Runner {
            settings,
            next: MonoTime(0),
            started: false,
            torque_nm: [0.0; WIREMAN_WIRES],
            readings: Readings::default(),
            lowest_counts: [i64::MAX; WIREMAN_WIRES],
            tension_correction: None,
            device_error: None,
        }
    }

    /// Correct every tension reading with a two-point sensor calibration from now on
    /// (`videt tension-calibrate`), or stop correcting with `None`.
    pub fn set_tension_correction(&mut self, correction: Option<TensionCalibration>) {
        self.tension_correction = correction;
    }

    /// The settings.
    pub fn settings(&self) -> &RunSettings {
        &self.settings
    }

    /// The last period's readings.
    pub fn readings(&self) -> &Readings {
        &self.readings
    }

    /// The lowest count each encoder read since [`Self::reset_lowest_counts`]: how far each wire
    /// was paid out.
    pub fn lowest_counts(&self) -> [i64; WIREMAN_WIRES] {
        self.lowest_counts
    }

    /// What the drives or the tension sensors said when a read first failed.
    pub fn device_error(&self) -> Option<&str> {
        self.device_error.as_deref()
    }

    /// Restart [`Self::lowest_counts`] from the last reading.
    pub fn reset_lowest_counts(&mut self) {
        self.lowest_counts = self.readings.input.counts;
    }

    fn period_ns(&self) -> u64 {
        1_000_000_000 / u64::from(self.settings.rate_hz.max(1))
    }

    /// Wait for the next period and read the devices.
    fn read<H: InitHardware>(&mut self, hw: &mut H) {
        if !self.started {
            self.started = true;
            self.next = hw.now();
        }
        self.next = self.next.add_nanos(self.period_ns());
        hw.sleep_until(self.next);
        let now = hw.now();
        if now.nanos_since(self.next) > 10 * self.period_ns() {
            // Far behind (a paused process): keep the grid from now on.
            self.next = now;
        }
        let r = &mut self.readings;
        let mut drive_fault = match hw.read_drives(&mut r.drives) {
            Ok(()) => None,
            Err(e) => {
                keep_first_error(&mut self.device_error, &e);
                Some(None)
            }
        };
        for (i, s) in r.drives.iter().enumerate() {
            if s.state == DriveState::Fault {
                drive_fault = Some(Some(i as u8));
            }
        }
        let sensor_fault = match hw.read_tensions(&mut r.tension_n) {
            Ok(()) => false,
            Err(e) => {
                keep_first_error(&mut self.device_error, &e);
                true
            }
        };
        if let Some(c) = &self.tension_correction {
            for i in 0..WIREMAN_WIRES {
                r.tension_n[i] = c.correct(i, r.tension_n[i]);
            }
        }
        let tr = &self.settings.transmission;
        r.input = ProcedureInput {
            time_s: now.as_secs_f64(),
            counts: core::array::from_fn(|i| r.drives[i].position_counts),
            wind_speed_m_s: core::array::from_fn(|i| {
                tr.wire_speed(r.drives[i].velocity_counts_per_s)
            }),
            tension_n: r.tension_n,
            estop_pressed: hw.is_pressed().unwrap_or(true),
            drive_fault,
            sensor_fault,
        };
        for i in 0..WIREMAN_WIRES {
            self.lowest_counts[i] = self.lowest_counts[i].min(r.input.counts[i]);
        }
    }

    /// Apply `setpoint_n` as motor forces on the wires (torque through the transmission; a
    /// `released` wire gets no torque) and write.
    fn write<H: InitHardware>(
        &mut self,
        hw: &mut H,
        setpoint_n: &[f64; WIREMAN_WIRES],
        released: Option<usize>,
    ) -> bool {
        let tr = self.settings.transmission;
        for i in 0..WIREMAN_WIRES {
            self.torque_nm[i] = tr.torque_for_tension(setpoint_n[i]);
        }
        if let Some(w) = released.filter(|w| *w < WIREMAN_WIRES) {
            self.torque_nm[w] = 0.0;
        }
        hw.write_torques(&self.torque_nm).is_ok()
    }

    /// One period with these motor forces (a `released` wire gets no torque); returns the
    /// readings it started with. False in the second field when the drives refused the torques.
    pub fn period<H: InitHardware>(
        &mut self,
        hw: &mut H,
        force_n: &[f64; WIREMAN_WIRES],
        released: Option<usize>,
    ) -> (Readings, bool) {
        self.read(hw);
        let ok = self.write(hw, force_n, released);
        (self.readings, ok)
    }

    /// Run `procedure` to its end, then hold every wire at the pay-out tension for
    /// `hold_after_s` (drives off instead after an e-stop or a drive fault). `stop` cancels it.
    /// `progress` is told each new stage.
    pub fn run<H: InitHardware>(
        &mut self,
        hw: &mut H,
        procedure: &mut Procedure,
        stop: &AtomicBool,
        progress: &mut dyn FnMut(Stage, &Readings),
    ) -> Status {
        let mut setpoint = [self.settings.pay_out_tension_n; WIREMAN_WIRES];
        let mut stage = None;
        let status = loop {
            self.read(hw);
            let mut status = procedure.update(&self.readings.input, &mut setpoint);
            if status == Status::Running && stop.load(Ordering::Relaxed) {
                procedure.abort(Failure::Cancelled, &mut setpoint);
                status = Status::Failed(Failure::Cancelled);
            }
            if stage != Some(procedure.stage()) {
                stage = Some(procedure.stage());
                progress(procedure.stage(), &self.readings);
            }
            let written = self.write(hw, &setpoint, None);
            if !written && status == Status::Running {
                procedure.abort(Failure::DriveFault { wire: None }, &mut setpoint);
                break Status::Failed(Failure::DriveFault { wire: None });
            }
            if status != Status::Running {
                break status;
            }
        };
        let power_off = matches!(
            status,
            Status::Failed(Failure::EmergencyStop | Failure::DriveFault { .. })
        );
        if power_off {
            let _ = hw.disable();
        } else {
            let periods = (self.settings.hold_after_s * f64::from(self.settings.rate_hz)) as u64;
            for _ in 0..periods {
                self.read(hw);
                let hold = self.governed_hold();
                if self.readings.input.estop_pressed {
                    let _ = hw.disable();
                    break;
                }
                self.write(hw, &hold, None);
            }
        }
        status
    }

    /// The pay-out force on every wire, lowered on a wire winding faster than half the governor
    /// speed (to zero at the governor speed).
    fn governed_hold(&self) -> [f64; WIREMAN_WIRES] {
        let v = self.settings.governor_speed_m_s.max(1e-3);
        let mut hold = [self.settings.pay_out_tension_n; WIREMAN_WIRES];
        for (i, f) in hold.iter_mut().enumerate() {
            let excess = (self.readings.input.wind_speed_m_s[i] - 0.5 * v) / (0.5 * v);
            if excess > 0.0 {
                *f *= (1.0 - excess).clamp(0.0, 1.0);
            }
        }
        hold
    }

    /// Hold every wire at the pay-out tension (wire `released`: no torque, free to pull) until
    /// `done` says so; returns early with the failure on an e-stop, a drive or sensor fault, or
    /// `stop`. Calls `watch` every period with the readings (e.g. to track a wire's length).
    pub fn hold_until<H: InitHardware>(
        &mut self,
        hw: &mut H,
        released: Option<usize>,
        stop: &AtomicBool,
        done: &mut dyn FnMut() -> bool,
        watch: &mut dyn FnMut(&Readings),
    ) -> Result<(), Failure> {
        loop {
            self.read(hw);
            let hold = self.governed_hold();
            let input = &self.readings.input;
            if input.estop_pressed {
                let _ = hw.disable();
                return Err(Failure::EmergencyStop);
            }
            if let Some(wire) = input.drive_fault {
                let _ = hw.disable();
                return Err(Failure::DriveFault { wire });
            }
            if input.sensor_fault {
                return Err(Failure::SensorFault);
            }
            if stop.load(Ordering::Relaxed) {
                return Err(Failure::Cancelled);
            }
            watch(&self.readings);
            if !self.write(hw, &hold, released) {
                return Err(Failure::DriveFault { wire: None });
            }
            if done() {
                return Ok(());
            }
        }
    }
}

/// Keep what a failed read said in `kept`, for the report: the first failure only, so that a
/// device that keeps failing while the wires are held is not formatted every period.
fn keep_first_error(kept: &mut Option<String>, e: &impl core::fmt::Display) {
    if kept.is_none() {
        *kept = Some(e.to_string());
    }
}
