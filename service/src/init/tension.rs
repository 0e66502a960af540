//! Two-point calibration of one wire's strain gauge with a known weight: the reading with the
//! wire unloaded (its end hanging free, the pulley released) and with the weight hanging on it
//! (the motor balancing the weight, with damping against any motion), each averaged. The
//! manual steps take the time a person takes: the motors hold the wires meanwhile, and the
//! weight is caught as soon as it pulls.

use std::sync::atomic::{AtomicBool, Ordering};
use videt_runtime::WIREMAN_WIRES;

use videt_control::autoinit::Failure;

use super::runner::{InitHardware, Runner};

/// Standard gravity, m/s².
const GRAVITY_M_S2: f64 = 9.806_65;

/// A manual step of the tension calibration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TensionStep {
    /// Pull some of the wire out and let its end hang free with nothing on it.
    Unload {
        /// The wire.
        wire: usize,
    },
    /// Hang the known weight on the wire's end.
    HangWeight {
        /// The wire.
        wire: usize,
        /// The weight, kg.
        mass_kg: f64,
    },
    /// Take the weight off and let the wire wind back to its ring.
    Finish {
        /// The wire.
        wire: usize,
    },
}

impl TensionStep {
    /// What a person is asked to do.
    pub fn instructions(&self) -> String {
        match *self {
            TensionStep::Unload { wire } => format!(
                "wire {wire} is released: pull about 30 cm of it out of ring {wire}, unhook it from the thimble and let its end hang free and still with nothing on it; press Enter"
            ),
            TensionStep::HangWeight { wire, mass_kg } => format!(
                "keep wire {wire}'s end in hand (the motor now pulls it gently), hang the {mass_kg:.3} kg weight on it and let go slowly: the motor takes its weight; when it hangs still, press Enter"
            ),
            TensionStep::Finish { wire } => format!(
                "take the weight off wire {wire} and let the motor wind the wire back slowly; press Enter"
            ),
        }
    }
}

/// Who performs the manual steps (a person prompted at the terminal, or the twin's technician).
/// While a step is under way the wires are held as it needs: the calibrated wire released during
/// [`TensionStep::Unload`], holding the weight once it pulls during [`TensionStep::HangWeight`],
/// at the pay-out tension otherwise.
pub trait TensionTechnician<H> {
    /// Start `step`: the twin's technician does it at once; a person is told what to do.
    fn perform(&mut self, step: TensionStep, hw: &mut H) -> Result<(), Failure>;
    /// Asked every period while `step`'s wires are held: whether the step is done.
    fn step_done(&mut self, _step: TensionStep, _hw: &mut H) -> bool {
        true
    }
}

/// Why the calibration failed.
#[derive(Debug, thiserror::Error)]
pub enum TensionCalibrationError {
    /// The device failed, or the run was stopped.
    #[error("{0}")]
    Device(Failure),
    /// The weight did not change the reading as a weight should.
    #[error("wire {wire}: the reading changed by {change_n:.3} N under a {load_n:.3} N weight (gain {gain:.3} outside [0.5, 2]): is the weight on wire {wire}, the sensor wired?")]
    Implausible {
        /// The wire.
        wire: usize,
        /// Reading change, N.
        change_n: f64,
        /// The weight's pull, N.
        load_n: f64,
        /// The gain it would give.
        gain: f64,
    },
    /// Bad arguments.
    #[error("{0}")]
    Usage(String),
}

/// The result: the sensor's offset and gain correction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TensionPoint {
    /// Reading unloaded, N.
    pub offset_n: f64,
    /// Known load / reading change.
    pub gain: f64,
    /// Reading with the weight, N.
    pub loaded_reading_n: f64,
}

/// Drive wire `wire` with `force(reading_n, wind_speed_m_s)` (the last period's reading and
/// winding speed; no torque at all when `released`), the other wires at the pay-out tension,
/// until `until(hw, periods)` says so; returns the mean reading over those periods. Fails on an
/// e-stop, a drive or sensor fault, or `stop`.
#[allow(clippy::too_many_arguments)]
fn hold_wire<H: InitHardware>(
    hw: &mut H,
    runner: &mut Runner,
    wire: usize,
    released: bool,
    force: &mut dyn FnMut(f64, f64) -> f64,
    stop: &AtomicBool,
    until: &mut dyn FnMut(&mut H, u32) -> bool,
) -> Result<f64, Failure> {
    let pay_out = runner.settings().pay_out_tension_n;
    let (mut sum, mut periods) = (0.0, 0u32);
    let (mut reading, mut wind_speed) = (0.0, 0.0);
    loop {
        let mut f = [pay_out; WIREMAN_WIRES];
        f[wire] = force(reading, wind_speed);
        let (r, ok) = runner.period(hw, &f, released.then_some(wire));
        if r.input.estop_pressed {
            let _ = hw.disable();
            return Err(Failure::EmergencyStop);
        }
        if let Some(w) = r.input.drive_fault {
            let _ = hw.disable();
            return Err(Failure::DriveFault { wire: w });
        }
        if r.input.sensor_fault {
            return Err(Failure::SensorFault);
        }
        if !ok {
            return Err(Failure::DriveFault { wire: None });
        }
        if stop.load(Ordering::Relaxed) {
            return Err(Failure::Cancelled);
        }
        wind_speed = r.input.wind_speed_m_s[wire];
        reading = r.tension_n[wire];
        sum += reading;
        periods += 1;
        if until(hw, periods) {
            return Ok(sum / f64::from(periods));
        }
    }
}

/// The force that holds a weight pulling `load_n` on a wire still: its pull, less a damping
/// against the wire's motion.
fn weight_hold(load_n: f64, wind_speed_m_s: f64) -> f64 {
    (load_n - 20.0 * wind_speed_m_s).clamp(0.0, 2.0 * load_n)
}

/// Check the wire and the weight before any motor moves.
pub fn check_arguments(wire: usize, mass_kg: f64) -> Result<(), TensionCalibrationError> {
    if wire >= WIREMAN_WIRES {
        return Err(TensionCalibrationError::Usage(format!(
            "wire {wire} does not exist: wires are 0, 1, 2"
        )));
    }
    if !(mass_kg.is_finite() && (0.05..=1.5).contains(&mass_kg)) {
        return Err(TensionCalibrationError::Usage(format!(
            "--mass-kg {mass_kg}: must be in [0.05, 1.5] kg (a load within the wire's 15 N)"
        )));
    }
    Ok(())
}

/// Asks the technician for `step`, then holds `wire` by `force` (released or not) until the
/// technician says the step is done.
#[allow(clippy::too_many_arguments)]
fn perform_step<H: InitHardware, T: TensionTechnician<H>>(
    hw: &mut H,
    tech: &mut T,
    runner: &mut Runner,
    step: TensionStep,
    wire: usize,
    released: bool,
    force: &mut dyn FnMut(f64, f64) -> f64,
    stop: &AtomicBool,
) -> Result<(), Failure> {
    tech.perform(step, hw)?;
    let mut done = |hw: &mut H, _: u32| tech.step_done(step, hw);
    hold_wire(hw, runner, wire, released, force, stop, &mut done).map(|_| ())
}

/// Holds `wire` by `force` for `settle` periods, then returns its mean reading over `measure`
/// periods.
fn settled_reading<H: InitHardware>(
    hw: &mut H,
    runner: &mut Runner,
    wire: usize,
    released: bool,
    force: &mut dyn FnMut(f64, f64) -> f64,
    stop: &AtomicBool,
    (settle, measure): (u32, u32),
) -> Result<f64, Failure> {
    hold_wire(hw, runner, wire, released, force, stop, &mut |_, n| {
        n >= settle
    })?;
    hold_wire(hw, runner, wire, released, force, stop, &mut |_, n| {
        n >= measure
    })
}

/// Calibrate wire `wire`'s tension sensor with a weight of `mass_kg`. The hardware must be
/// started; the other wires are held at the pay-out tension.
pub fn calibrate_tension<H: InitHardware, T: TensionTechnician<H>>(
    hw: &mut H,
    tech: &mut T,
    runner: &mut Runner,
    wire: usize,
    mass_kg: f64,
    stop: &AtomicBool,
) -> Result<TensionPoint, TensionCalibrationError> {
    check_arguments(wire, mass_kg)?;
    let dev = TensionCalibrationError::Device;
    let load_n = mass_kg * GRAVITY_M_S2;
    let pay_out = runner.settings().pay_out_tension_n;
    let periods = |seconds: f64| (seconds * f64::from(runner.settings().rate_hz)).max(1.0) as u32;
    let (settle, measure) = (periods(0.5), periods(1.0));

    // Unloaded: the pulley released, the end hanging free; let it settle, then average.
    let mut unloaded = |_: f64, _: f64| 0.0;
    let step = TensionStep::Unload { wire };
    perform_step(hw, tech, runner, step, wire, true, &mut unloaded, stop).map_err(dev)?;
    let offset_n = settled_reading(
        hw,
        runner,
        wire,
        true,
        &mut unloaded,
        stop,
        (settle, measure),
    )
    .map_err(dev)?;

    // Loaded: while the weight is being hung the wire is held at the pay-out tension; once it
    // pulls (the reading past half its weight) the motor balances it, damped against motion.
    let mut hanging = |reading: f64, wind_speed: f64| {
        if reading - offset_n > 0.5 * load_n {
            weight_hold(load_n, wind_speed)
        } else {
            pay_out
        }
    };
    let step = TensionStep::HangWeight { wire, mass_kg };
    perform_step(hw, tech, runner, step, wire, false, &mut hanging, stop).map_err(dev)?;
    let mut hold = |_: f64, wind_speed: f64| weight_hold(load_n, wind_speed);
    let loaded = settled_reading(hw, runner, wire, false, &mut hold, stop, (settle, measure))
        .map_err(dev)?;

    // The weight off, the wire wound back at the pay-out tension.
    let step = TensionStep::Finish { wire };
    perform_step(
        hw,
        tech,
        runner,
        step,
        wire,
        false,
        &mut |_, _| pay_out,
        stop,
    )
    .map_err(dev)?;
    let change_n = loaded - offset_n;
    let gain = load_n / change_n;
    if !(gain.is_finite() && (0.5..=2.0).contains(&gain)) {
        return Err(TensionCalibrationError::Implausible {
            wire,
            change_n,
            load_n,
            gain,
        });
    }
    Ok(TensionPoint {
        offset_n,
        gain,
        loaded_reading_n: loaded,
    })
}
