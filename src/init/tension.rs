//! Two-point calibration of one wire's strain gauge with a known weight: the reading with the
//! wire unloaded (its end hanging free, the pulley released) and with the weight hanging on it
//! (the motor balancing the weight, with damping against any motion), each averaged.

use std::sync::atomic::{AtomicBool, Ordering};

use videt_control::autoinit::Failure;
use videt_hal::WIRES;

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

/// Who performs the manual steps (a person prompted at the terminal, or the twin's technician).
pub trait TensionTechnician<H> {
    /// Perform `step` and return once it is done.
    fn perform(&mut self, step: TensionStep, hw: &mut H) -> Result<(), Failure>;
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

/// Average wire `wire`'s reading over `seconds` while applying `force` to it each period.
fn average<H: InitHardware>(
    hw: &mut H,
    runner: &mut Runner,
    wire: usize,
    seconds: f64,
    released: bool,
    force: &mut dyn FnMut(f64) -> f64,
    stop: &AtomicBool,
) -> Result<f64, Failure> {
    let periods = (seconds * f64::from(runner.settings().rate_hz)).max(1.0) as u32;
    let pay_out = runner.settings().pay_out_tension_n;
    let (mut sum, mut wind_speed) = (0.0, 0.0);
    for _ in 0..periods {
        let mut f = [pay_out; WIRES];
        f[wire] = force(wind_speed);
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
        sum += r.tension_n[wire];
    }
    Ok(sum / f64::from(periods))
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
    if wire >= WIRES {
        return Err(TensionCalibrationError::Usage(format!(
            "wire {wire} does not exist: wires are 0, 1, 2"
        )));
    }
    if !(mass_kg.is_finite() && (0.05..=1.5).contains(&mass_kg)) {
        return Err(TensionCalibrationError::Usage(format!(
            "--mass-kg {mass_kg}: must be in [0.05, 1.5] kg (a load within the wire's 15 N)"
        )));
    }
    let dev = TensionCalibrationError::Device;
    let load_n = mass_kg * GRAVITY_M_S2;
    tech.perform(TensionStep::Unload { wire }, hw)
        .map_err(dev)?;
    // Unloaded: the pulley released, the end hanging free; let it settle, then average.
    average(hw, runner, wire, 0.5, true, &mut |_| 0.0, stop).map_err(dev)?;
    let offset_n = average(hw, runner, wire, 1.0, true, &mut |_| 0.0, stop).map_err(dev)?;
    tech.perform(TensionStep::HangWeight { wire, mass_kg }, hw)
        .map_err(dev)?;
    // Loaded: the motor balances the weight's pull, damped against motion.
    let mut hold = |wind_speed_m_s: f64| (load_n - 20.0 * wind_speed_m_s).clamp(0.0, 2.0 * load_n);
    average(hw, runner, wire, 0.5, false, &mut hold, stop).map_err(dev)?;
    let loaded = average(hw, runner, wire, 1.0, false, &mut hold, stop).map_err(dev)?;
    tech.perform(TensionStep::Finish { wire }, hw)
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
