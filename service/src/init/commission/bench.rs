//! The check's hold on the rig: the hardware, the technician and the loop that runs them one
//! period at a time, and the motions every step is made of (a stretch of forces, a manual step
//! with the motors idle, a drive's winding test, a wire wound back to its ring).

use std::sync::atomic::{AtomicBool, Ordering};

use videt_config::Config;
use videt_control::autoinit::Failure;
use videt_runtime::WIREMAN_WIRES;

use super::{CommissionStep, CommissionTechnician, StepReport};
use crate::init::runner::{InitHardware, Readings, Runner};

/// The longest a wire pulled out is wound back for, seconds (the pull-out at the test's speed
/// limit takes a few).
const WIND_BACK_S: f64 = 30.0;

/// The farthest one direction of a drive's gentle probe moves its wire, metres: the slack it
/// takes up winding, the most it pays out unwinding.
const PROBE_TRAVEL_M: f64 = 0.03;

/// The longest one direction of a gentle probe lasts, seconds (a wire that hardly moves: its
/// sphere held, or its encoder silent).
const PROBE_S: f64 = 5.0;

/// How long a sensor's change must last to count as its answer, seconds.
const ANSWER_S: f64 = 0.05;

/// No force on any wire.
pub(super) const IDLE: [f64; WIREMAN_WIRES] = [0.0; WIREMAN_WIRES];

/// What a drive's winding test found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Winding {
    /// The sign of the torque that winds the drive's wire (+1 as configured, -1 reversed).
    pub sign: f64,
    /// The tension channel that answered.
    pub sensor: usize,
    /// Its change, N (negative for a cell read the other way).
    pub change_n: f64,
}

/// What one direction of a gentle probe found.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Probe {
    /// The tension channel that answered, if one did.
    answered: Option<usize>,
    /// How far the wire moved, metres.
    travelled_m: f64,
    /// The periods it lasted.
    periods: u32,
}

/// What a stretch of periods measured.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Stretch {
    /// Mean tension of each channel over the stretch's last quarter, N.
    pub mean_tension_n: [f64; WIREMAN_WIRES],
    /// Encoder counts at its start and its end.
    pub counts: ([i64; WIREMAN_WIRES], [i64; WIREMAN_WIRES]),
}

/// The rig under check: its hardware, the technician, the loop, the configuration, the stop
/// flag, and the steps reported so far.
pub(super) struct Bench<'a, H, T> {
    pub hw: &'a mut H,
    pub tech: &'a mut T,
    pub runner: &'a mut Runner,
    pub config: &'a Config,
    pub stop: &'a AtomicBool,
    pub steps: Vec<StepReport>,
}

impl<H: InitHardware, T: CommissionTechnician<H>> Bench<'_, H, T> {
    /// Periods in `seconds` at the loop's rate (at least one).
    pub fn periods(&self, seconds: f64) -> u32 {
        let rate = f64::from(self.runner.settings().rate_hz.max(1));
        ((seconds * rate).round() as u32).max(1)
    }

    /// Run `periods` periods with the forces `force(readings)` (N, through the transmission;
    /// sign as the HAL's: positive winds). Fails on an e-stop, a drive or sensor fault, or the
    /// stop flag.
    pub fn drive_for(
        &mut self,
        periods: u32,
        force: &mut dyn FnMut(&Readings) -> [f64; WIREMAN_WIRES],
    ) -> Result<Stretch, Failure> {
        let mut f = IDLE;
        let mut sum = [0.0; WIREMAN_WIRES];
        let mut summed = 0u32;
        let mut first = None;
        let mut last = [0; WIREMAN_WIRES];
        for n in 0..periods {
            let r = self.period(&f)?;
            first.get_or_insert(r.input.counts);
            last = r.input.counts;
            if n >= periods - (periods / 4).max(1) {
                for (s, t) in sum.iter_mut().zip(r.tension_n) {
                    *s += t;
                }
                summed += 1;
            }
            f = force(&r);
        }
        Ok(Stretch {
            mean_tension_n: sum.map(|s| s / f64::from(summed.max(1))),
            counts: (first.unwrap_or(last), last),
        })
    }

    /// `seconds` with every motor idle.
    pub fn idle(&mut self, seconds: f64) -> Result<Stretch, Failure> {
        let periods = self.periods(seconds);
        self.drive_for(periods, &mut |_| IDLE)
    }

    /// One period with the forces `f`; its readings, or the failure they show.
    fn period(&mut self, f: &[f64; WIREMAN_WIRES]) -> Result<Readings, Failure> {
        let (r, written) = self.runner.period(self.hw, f, None);
        let input = &r.input;
        if input.estop_pressed {
            return Err(Failure::EmergencyStop);
        }
        if let Some(w) = input.drive_fault {
            return Err(Failure::DriveFault { wire: w });
        }
        if input.sensor_fault {
            return Err(Failure::SensorFault);
        }
        if !written {
            return Err(Failure::DriveFault { wire: None });
        }
        if self.stop.load(Ordering::Relaxed) {
            return Err(Failure::Cancelled);
        }
        Ok(r)
    }

    /// One period with every motor idle in which only a drive fault or the stop flag fail (the
    /// e-stop is what is measured, or what the technician is operating): its readings.
    fn idle_period(&mut self) -> Result<Readings, Failure> {
        let (r, _) = self.runner.period(self.hw, &IDLE, None);
        if let Some(w) = r.input.drive_fault {
            return Err(Failure::DriveFault { wire: w });
        }
        if self.stop.load(Ordering::Relaxed) {
            return Err(Failure::Cancelled);
        }
        Ok(r)
    }

    /// Whether the e-stop reads pressed now, after a reset (a press the input still shows
    /// stays latched).
    pub fn estop_reads_pressed(&mut self) -> Result<bool, Failure> {
        if self.hw.reset().is_err() {
            return Ok(true);
        }
        Ok(self.idle_period()?.input.estop_pressed)
    }

    /// Ask the technician for `step` and wait, every motor idle, until it is done.
    pub fn manual_step(&mut self, step: CommissionStep) -> Result<(), Failure> {
        self.tech.perform_commission(step, self.hw)?;
        loop {
            self.idle_period()?;
            if self.tech.commission_step_done(step, self.hw) {
                return Ok(());
            }
        }
    }

    /// Ask the technician for `step` and wait until it is done, the motors pulling `hold`
    /// (N, positive winds).
    pub fn manual_step_holding(
        &mut self,
        step: CommissionStep,
        hold: &[f64; WIREMAN_WIRES],
    ) -> Result<(), Failure> {
        self.tech.perform_commission(step, self.hw)?;
        loop {
            self.period(hold)?;
            if self.tech.commission_step_done(step, self.hw) {
                return Ok(());
            }
        }
    }

    /// Which way drive `k` winds, and which sensor answers (against the tensions `rest`): a
    /// gentle pull (the pay-out tension) one way until a sensor answers or the wire has moved
    /// [`PROBE_TRAVEL_M`]; then (none answering) the other way, until a sensor answers or the
    /// wire has wound back what the first paid out and [`PROBE_TRAVEL_M`] more (each way, for
    /// at most [`PROBE_S`] more than the way before took); then, the
    /// sphere against its ring, the test tension that way. A wire turning freely (paid out, or
    /// wound back) only ever gets the gentle pull, and a sphere resting a little off its ring
    /// is wound onto it however slowly the wire moves. `None` when no sensor answers either
    /// way.
    pub fn winding_test(&mut self, k: usize, rest: &Stretch) -> Result<Option<Winding>, Failure> {
        let test_n = self.config.commission.test_tension_n;
        let (mut travel_m, mut periods) = (PROBE_TRAVEL_M, self.periods(PROBE_S));
        for sign in [1.0, -1.0] {
            let probe = self.probe(k, sign, travel_m, periods, rest)?;
            let Some(j) = probe.answered else {
                travel_m = probe.travelled_m + PROBE_TRAVEL_M;
                periods = probe.periods + self.periods(PROBE_S);
                continue;
            };
            // Against the ring: the test tension, which hardly moves the wire.
            let max_speed = self.config.commission.max_speed_m_s;
            let periods = self.periods(0.4);
            let pulled =
                self.drive_for(periods, &mut |r| test_force(r, k, sign * test_n, max_speed))?;
            // Idle again: the sphere rests against its ring.
            self.idle(0.2)?;
            return Ok(Some(Winding {
                sign,
                sensor: j,
                change_n: pulled.mean_tension_n[j] - rest.mean_tension_n[j],
            }));
        }
        Ok(None)
    }

    /// Drive `k` pulling gently (the pay-out tension, `sign` as the HAL's) until a sensor
    /// answers (its change from `rest` beyond half that tension for [`ANSWER_S`]), the wire has
    /// moved `travel_m` (by its encoder, whichever way it counts), or `periods` have passed.
    fn probe(
        &mut self,
        k: usize,
        sign: f64,
        travel_m: f64,
        periods: u32,
        rest: &Stretch,
    ) -> Result<Probe, Failure> {
        let probe_n = self.runner.settings().pay_out_tension_n;
        let max_speed = self.config.commission.max_speed_m_s;
        let metres_per_count = self.runner.settings().transmission.metres_per_count().abs();
        let answer_periods = self.periods(ANSWER_S);
        let mut f = IDLE;
        let mut start = None;
        let mut travelled_m = 0.0;
        // The channel answering, and for how many periods in a row.
        let mut answering: Option<(usize, u32)> = None;
        let mut ran = 0;
        while ran < periods {
            let r = self.period(&f)?;
            ran += 1;
            let start = *start.get_or_insert(r.input.counts[k]);
            travelled_m = (r.input.counts[k] - start).unsigned_abs() as f64 * metres_per_count;
            let change: [f64; WIREMAN_WIRES] =
                core::array::from_fn(|j| r.tension_n[j] - rest.mean_tension_n[j]);
            let j = (0..WIREMAN_WIRES)
                .max_by(|a, b| change[*a].abs().total_cmp(&change[*b].abs()))
                .unwrap_or(0);
            answering = if change[j].abs() > 0.5 * probe_n {
                match answering {
                    Some((i, n)) if i == j => Some((j, n + 1)),
                    _ => Some((j, 1)),
                }
            } else {
                None
            };
            if let Some((j, n)) = answering {
                if n >= answer_periods {
                    return Ok(Probe {
                        answered: Some(j),
                        travelled_m,
                        periods: ran,
                    });
                }
            }
            if travelled_m >= travel_m {
                break;
            }
            f = test_force(&r, k, sign * probe_n, max_speed);
        }
        Ok(Probe {
            answered: None,
            travelled_m,
            periods: ran,
        })
    }

    /// Drive `k`'s encoder count with its wire's sphere held against its ring (the pay-out
    /// tension, wound the way `w` found).
    pub fn held_counts(&mut self, k: usize, w: &Winding) -> Result<i64, Failure> {
        let hold = w.sign * self.runner.settings().pay_out_tension_n;
        let max_speed = self.config.commission.max_speed_m_s;
        let periods = self.periods(0.3);
        Ok(self
            .drive_for(periods, &mut |r| test_force(r, k, hold, max_speed))?
            .counts
            .1[k])
    }

    /// After a pull-out, wind drive `k`'s wire back gently (the pay-out tension, the way `w`
    /// found) until its sensor reads half that, at most [`WIND_BACK_S`]; then wait for the
    /// technician to say it rests.
    pub fn wind_back(&mut self, k: usize, w: &Winding) -> Result<(), Failure> {
        let pull_n = self.runner.settings().pay_out_tension_n;
        let max_speed = self.config.commission.max_speed_m_s;
        let mut seated = false;
        let mut f = IDLE;
        for _ in 0..self.periods(WIND_BACK_S) {
            let r = self.period(&f)?;
            if r.tension_n[w.sensor] * w.change_n.signum() > 0.5 * pull_n {
                seated = true;
                break;
            }
            f = test_force(&r, k, w.sign * pull_n, max_speed);
        }
        self.idle(0.2)?;
        let step = CommissionStep::LetGo { ring: w.sensor };
        while !self.tech.commission_step_done(step, self.hw) {
            self.period(&IDLE)?;
        }
        if !seated {
            return Err(Failure::Timeout {
                wire: k as u8,
                elapsed_s: WIND_BACK_S,
            });
        }
        Ok(())
    }
}

/// Drive `k`'s force `force_n` (the others none), cut while its wire moves faster than
/// `max_speed`.
fn test_force(r: &Readings, k: usize, force_n: f64, max_speed: f64) -> [f64; WIREMAN_WIRES] {
    let mut f = IDLE;
    // The speed is the encoder's: on a reversed encoder its sign is wrong, so any fast motion
    // cuts the torque.
    if r.input.wind_speed_m_s[k].abs() <= max_speed {
        f[k] = force_n;
    }
    f
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_test_force_goes_to_one_drive_and_is_cut_while_its_wire_runs_fast() {
        let mut r = Readings::default();
        assert_eq!(test_force(&r, 1, -2.0, 0.05), [0.0, -2.0, 0.0]);
        r.input.wind_speed_m_s = [0.0, -0.06, 0.0];
        assert_eq!(test_force(&r, 1, -2.0, 0.05), IDLE);
        r.input.wind_speed_m_s = [1.0, 0.04, 1.0];
        assert_eq!(test_force(&r, 1, 2.0, 0.05), [0.0, 2.0, 0.0]);
    }
}
