//! The homing / auto-initialization state machine, [`Procedure`], run once per control period:
//! its stages, the stop detection and averaging, the speed-limited winding, the governor of the
//! paying-out wires, and the fault and limit checks that end it.

use super::failure::{Failure, Limit};
use super::params::{Plan, ProcedureParams};
use super::period::{ProcedureInput, Stage, Status};
use super::triangle::{solve_base_triangle, BaseTriangle};
use crate::WIREMAN_WIRES;

/// Per-wire stop detector and averaging window.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct StopDetector {
    /// Time the wire was first seen stopped with its tension up.
    stopped_since_s: Option<f64>,
    /// Counts summed over the measuring window (relative to `base`, so no overflow).
    sum_counts: [f64; WIREMAN_WIRES],
    samples: u32,
    done: bool,
    base: [i64; WIREMAN_WIRES],
}

/// The homing / auto-initialization state machine. See the [module documentation](super).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Procedure {
    params: ProcedureParams,
    plan: Plan,
    stage: Stage,
    stage_start_s: f64,
    started: bool,
    detectors: [StopDetector; WIREMAN_WIRES],
    speed_integral_n: [f64; WIREMAN_WIRES],
    last_time_s: f64,
    start_counts: [i64; WIREMAN_WIRES],
    first_counts: [i64; WIREMAN_WIRES],
    counts_at_stop: [[f64; WIREMAN_WIRES]; WIREMAN_WIRES],
    zero_known: [bool; WIREMAN_WIRES],
    over_tension_s: [f64; WIREMAN_WIRES],
    home_counts: [i64; WIREMAN_WIRES],
    lengths_at_stop_m: [[f64; WIREMAN_WIRES]; WIREMAN_WIRES],
    result: Option<BaseTriangle>,
    failure: Option<Failure>,
    open_loop: [bool; WIREMAN_WIRES],
}

impl Procedure {
    /// A procedure that has not started; the first [`update`](Self::update) starts it.
    pub fn new(params: ProcedureParams, plan: Plan) -> Procedure {
        Procedure {
            params,
            plan,
            stage: Stage::Settle,
            stage_start_s: 0.0,
            started: false,
            detectors: [StopDetector::default(); WIREMAN_WIRES],
            speed_integral_n: [0.0; WIREMAN_WIRES],
            last_time_s: 0.0,
            start_counts: [0; WIREMAN_WIRES],
            first_counts: [0; WIREMAN_WIRES],
            counts_at_stop: [[0.0; WIREMAN_WIRES]; WIREMAN_WIRES],
            zero_known: [false; WIREMAN_WIRES],
            over_tension_s: [0.0; WIREMAN_WIRES],
            home_counts: [0; WIREMAN_WIRES],
            lengths_at_stop_m: [[0.0; WIREMAN_WIRES]; WIREMAN_WIRES],
            result: None,
            failure: None,
            open_loop: [false; WIREMAN_WIRES],
        }
    }

    /// Which wires the last period is winding under the procedure's own speed loop (their
    /// set-point may reach the winding cap); the others hold the pay-out tension.
    pub fn winding_wires(&self) -> [bool; WIREMAN_WIRES] {
        self.open_loop
    }

    /// The current stage.
    pub fn stage(&self) -> Stage {
        self.stage
    }

    /// The plan.
    pub fn plan(&self) -> Plan {
        self.plan
    }

    /// After a successful homing or initialization: the encoder count of each homed wire at
    /// free length zero (wires not homed: 0).
    pub fn homed_zero_counts(&self) -> [i64; WIREMAN_WIRES] {
        self.home_counts
    }

    /// After a successful initialization: the base triangle.
    pub fn result(&self) -> Option<&BaseTriangle> {
        self.result.as_ref()
    }

    /// The failure that ended the procedure, if any.
    pub fn failure(&self) -> Option<Failure> {
        self.failure
    }

    /// Lengths measured at each winding's stop (valid for the windings that finished).
    pub fn lengths_at_stop_m(&self) -> &[[f64; WIREMAN_WIRES]; WIREMAN_WIRES] {
        &self.lengths_at_stop_m
    }

    /// End the procedure from outside (e.g. an operator's stop), with every wire at the pay-out
    /// tension.
    pub fn abort(&mut self, failure: Failure, setpoint_n: &mut [f64; WIREMAN_WIRES]) {
        self.fail(failure, setpoint_n);
    }

    fn fail(&mut self, failure: Failure, setpoint_n: &mut [f64; WIREMAN_WIRES]) -> Status {
        if self.failure.is_none() && self.stage != Stage::Finished {
            self.failure = Some(failure);
            self.stage = Stage::Failed;
        }
        *setpoint_n = [self.params.pay_out_tension_n; WIREMAN_WIRES];
        self.open_loop = [false; WIREMAN_WIRES];
        match self.failure {
            Some(f) => Status::Failed(f),
            None => Status::Finished,
        }
    }

    /// Wire `wire`'s travel since the stage began, metres (positive = wound in).
    fn travel_m(&self, wire: usize, counts: i64) -> f64 {
        (counts - self.start_counts[wire]) as f64 * self.params.metres_per_count
    }

    fn enter(&mut self, stage: Stage, input: &ProcedureInput) {
        self.stage = stage;
        self.stage_start_s = input.time_s;
        self.start_counts = input.counts;
        self.detectors = [StopDetector::default(); WIREMAN_WIRES];
        self.speed_integral_n = [0.0; WIREMAN_WIRES];
    }

    /// Run one period: read `input`, write the tension set-points, say where the procedure is.
    /// Once finished or failed it keeps every set-point at the pay-out tension.
    pub fn update(
        &mut self,
        input: &ProcedureInput,
        setpoint_n: &mut [f64; WIREMAN_WIRES],
    ) -> Status {
        let status = self.step(input, setpoint_n);
        if status == Status::Running {
            self.govern(input, setpoint_n);
        }
        status
    }

    /// Speed governor of the tension-controlled wires: nothing holds an empty thimble, so wires
    /// at the pay-out tension could gather it (and themselves) fast. A wire winding faster than
    /// half the winding speed has its set-point lowered, to zero at the winding speed.
    fn govern(&self, input: &ProcedureInput, setpoint_n: &mut [f64; WIREMAN_WIRES]) {
        let v = self.params.wind_speed_m_s;
        for i in 0..WIREMAN_WIRES {
            if self.open_loop[i] {
                continue;
            }
            // (Only the wires holding the pay-out tension are governed.)
            let excess = (input.wind_speed_m_s[i] - 0.5 * v) / (0.5 * v);
            if excess > 0.0 {
                setpoint_n[i] *= (1.0 - excess).clamp(0.0, 1.0);
            }
        }
    }

    fn step(&mut self, input: &ProcedureInput, setpoint_n: &mut [f64; WIREMAN_WIRES]) -> Status {
        let p = self.params;
        self.open_loop = [false; WIREMAN_WIRES];
        match self.stage {
            Stage::Finished => {
                *setpoint_n = [p.pay_out_tension_n; WIREMAN_WIRES];
                return Status::Finished;
            }
            Stage::Failed => return self.fail(Failure::SensorFault, setpoint_n),
            _ => {}
        }
        if !self.started {
            self.started = true;
            self.last_time_s = input.time_s;
            self.first_counts = input.counts;
            self.enter(Stage::Settle, input);
        }
        let dt = (input.time_s - self.last_time_s).max(0.0);
        self.last_time_s = input.time_s;

        // Faults and limits first: any of them ends the procedure.
        if input.estop_pressed {
            return self.fail(Failure::EmergencyStop, setpoint_n);
        }
        if let Some(wire) = input.drive_fault {
            return self.fail(Failure::DriveFault { wire }, setpoint_n);
        }
        if input.sensor_fault || input.tension_n.iter().any(|t| !t.is_finite()) {
            return self.fail(Failure::SensorFault, setpoint_n);
        }
        for i in 0..WIREMAN_WIRES {
            let wire = i as u8;
            if input.tension_n[i] > p.max_tension_n {
                self.over_tension_s[i] += dt;
                if self.over_tension_s[i] >= p.over_tension_s {
                    let limit = Limit::Tension {
                        measured_n: input.tension_n[i],
                    };
                    return self.fail(Failure::LimitHit { wire, limit }, setpoint_n);
                }
            } else {
                self.over_tension_s[i] = 0.0;
            }
            if input.wind_speed_m_s[i].abs() > p.max_speed_m_s {
                let limit = Limit::Speed {
                    measured_m_s: input.wind_speed_m_s[i],
                };
                return self.fail(Failure::LimitHit { wire, limit }, setpoint_n);
            }
            // A wire's length once its winding homed it; before, how far it paid out.
            let reference = if self.zero_known[i] {
                self.counts_at_stop[i][i]
            } else {
                self.first_counts[i] as f64
            };
            let paid_out = (reference - input.counts[i] as f64) * p.metres_per_count;
            if paid_out > p.max_length_m {
                let limit = Limit::Length {
                    measured_m: paid_out,
                };
                return self.fail(Failure::LimitHit { wire, limit }, setpoint_n);
            }
        }

        let elapsed = input.time_s - self.stage_start_s;
        match self.stage {
            Stage::Settle => {
                *setpoint_n = [p.pay_out_tension_n; WIREMAN_WIRES];
                if elapsed >= p.settle_s {
                    let next = match self.plan {
                        Plan::Home { .. } => Stage::Homing,
                        Plan::Initialize => Stage::Winding(0),
                    };
                    self.enter(next, input);
                }
                Status::Running
            }
            Stage::Homing => self.homing(input, dt, elapsed, setpoint_n),
            Stage::Winding(w) => self.winding(w as usize, input, dt, elapsed, setpoint_n),
            Stage::Finished => Status::Finished,
            Stage::Failed => self.fail(Failure::SensorFault, setpoint_n),
        }
    }

    /// The speed-limited winding command of wire `i` (open-loop, see [`Self::open_loop`]): a
    /// PI loop on the winding speed whose output is a motor force between zero and the winding
    /// cap, so a stopped wire pulls with at most `wind_tension_max_n`.
    fn wind_setpoint(&mut self, i: usize, input: &ProcedureInput, dt: f64) -> f64 {
        let p = &self.params;
        self.open_loop[i] = true;
        let error = p.wind_speed_m_s - input.wind_speed_m_s[i];
        self.speed_integral_n[i] = (self.speed_integral_n[i] + p.speed_ki_n_per_m * error * dt)
            .clamp(0.0, p.wind_tension_max_n);
        (self.speed_integral_n[i] + p.speed_kp_n_per_m_s * error).clamp(0.0, p.wind_tension_max_n)
    }

    /// Feed wire `i`'s stop detector; true once the stop held and the window is averaged.
    fn detect_stop(&mut self, i: usize, input: &ProcedureInput) -> bool {
        let p = self.params;
        let stopped = input.tension_n[i] >= p.stop_tension_n()
            && input.wind_speed_m_s[i].abs() <= p.stop_speed_m_s();
        let d = &mut self.detectors[i];
        if d.done {
            return true;
        }
        match d.stopped_since_s {
            None if stopped => {
                d.stopped_since_s = Some(input.time_s);
            }
            None => {}
            Some(_) if !stopped => {
                // A stop that did not hold: start over.
                *d = StopDetector::default();
            }
            Some(since) => {
                let held = input.time_s - since;
                if held >= p.stop_hold_s {
                    if d.samples == 0 {
                        d.base = input.counts;
                    }
                    for j in 0..WIREMAN_WIRES {
                        d.sum_counts[j] += (input.counts[j] - d.base[j]) as f64;
                    }
                    d.samples += 1;
                    if held >= p.stop_hold_s + p.measure_s {
                        d.done = true;
                        return true;
                    }
                }
            }
        }
        false
    }

    /// Mean counts of wire `j` over wire `i`'s measuring window.
    fn mean_counts(&self, i: usize, j: usize) -> f64 {
        let d = &self.detectors[i];
        d.base[j] as f64 + d.sum_counts[j] / f64::from(d.samples.max(1))
    }

    fn homing(
        &mut self,
        input: &ProcedureInput,
        dt: f64,
        elapsed: f64,
        setpoint_n: &mut [f64; WIREMAN_WIRES],
    ) -> Status {
        let Plan::Home { wires } = self.plan else {
            return Status::Running;
        };
        let p = self.params;
        let mut all_done = true;
        for i in 0..WIREMAN_WIRES {
            if !wires[i] {
                setpoint_n[i] = p.pay_out_tension_n;
                continue;
            }
            let travel = self.travel_m(i, input.counts[i]);
            if self.detect_stop(i, input) {
                setpoint_n[i] = p.pay_out_tension_n;
                continue;
            }
            all_done = false;
            if travel > p.max_wind_travel_m {
                let wire = i as u8;
                return self.fail(
                    Failure::TensionNeverRose {
                        wire,
                        travel_m: travel,
                    },
                    setpoint_n,
                );
            }
            if elapsed > p.stage_timeout_s {
                return self.fail(
                    Failure::Timeout {
                        wire: i as u8,
                        elapsed_s: elapsed,
                    },
                    setpoint_n,
                );
            }
            setpoint_n[i] = self.wind_setpoint(i, input, dt);
        }
        if all_done {
            for i in 0..WIREMAN_WIRES {
                if wires[i] {
                    self.home_counts[i] = libm_round(self.mean_counts(i, i));
                }
            }
            self.stage = Stage::Finished;
            *setpoint_n = [p.pay_out_tension_n; WIREMAN_WIRES];
            return Status::Finished;
        }
        Status::Running
    }

    fn winding(
        &mut self,
        w: usize,
        input: &ProcedureInput,
        dt: f64,
        elapsed: f64,
        setpoint_n: &mut [f64; WIREMAN_WIRES],
    ) -> Status {
        let p = self.params;
        *setpoint_n = [p.pay_out_tension_n; WIREMAN_WIRES];
        let wire = w as u8;
        let travel = self.travel_m(w, input.counts[w]);
        if travel > p.max_wind_travel_m {
            return self.fail(
                Failure::TensionNeverRose {
                    wire,
                    travel_m: travel,
                },
                setpoint_n,
            );
        }
        if !self.detect_stop(w, input) {
            if elapsed > p.stage_timeout_s {
                return self.fail(
                    Failure::Timeout {
                        wire,
                        elapsed_s: elapsed,
                    },
                    setpoint_n,
                );
            }
            setpoint_n[w] = self.wind_setpoint(w, input, dt);
            return Status::Running;
        }
        // Stopped with the thimble at ring `w`: wire `w` is homed, the other two give sides.
        for j in 0..WIREMAN_WIRES {
            self.counts_at_stop[w][j] = self.mean_counts(w, j);
        }
        self.zero_known[w] = true;
        let travel = (self.counts_at_stop[w][w] - self.start_counts[w] as f64) * p.metres_per_count;
        if travel < p.min_travel_m {
            return self.fail(
                Failure::NotConnected {
                    wire,
                    measured_m: travel,
                },
                setpoint_n,
            );
        }
        if w + 1 < WIREMAN_WIRES {
            self.enter(Stage::Winding(wire + 1), input);
            return Status::Running;
        }
        for i in 0..WIREMAN_WIRES {
            self.home_counts[i] = libm_round(self.counts_at_stop[i][i]);
            for j in 0..WIREMAN_WIRES {
                self.lengths_at_stop_m[i][j] =
                    (self.counts_at_stop[j][j] - self.counts_at_stop[i][j]) * p.metres_per_count;
            }
        }
        for i in 0..WIREMAN_WIRES {
            for j in 0..WIREMAN_WIRES {
                if i != j && self.lengths_at_stop_m[i][j] < p.min_side_m {
                    return self.fail(
                        Failure::NotConnected {
                            wire: j as u8,
                            measured_m: self.lengths_at_stop_m[i][j],
                        },
                        setpoint_n,
                    );
                }
            }
        }
        match solve_base_triangle(&self.lengths_at_stop_m, p.side_tolerance_m) {
            Ok(t) => {
                self.result = Some(t);
                self.stage = Stage::Finished;
                Status::Finished
            }
            Err(f) => self.fail(f, setpoint_n),
        }
    }
}

/// Round to the nearest integer count.
fn libm_round(x: f64) -> i64 {
    let r = nalgebra::ComplexField::floor(x + 0.5);
    r as i64
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params() -> ProcedureParams {
        ProcedureParams {
            metres_per_count: 1e-5,
            pay_out_tension_n: 0.4,
            wind_tension_max_n: 3.0,
            wind_speed_m_s: 0.1,
            speed_kp_n_per_m_s: 20.0,
            speed_ki_n_per_m: 200.0,
            settle_s: 0.1,
            stop_hold_s: 0.1,
            measure_s: 0.1,
            stage_timeout_s: 10.0,
            min_travel_m: 0.02,
            max_wind_travel_m: 1.0,
            min_side_m: 0.05,
            max_length_m: 1.5,
            side_tolerance_m: 2e-3,
            max_tension_n: 15.0,
            over_tension_s: 0.005,
            max_speed_m_s: 0.5,
        }
    }

    /// A kinematic stand-in for a detached wire: it winds at the set speed while the set-point
    /// is above the pay-out tension, until its end reaches the ring at `stop_counts`.
    #[test]
    fn homing_finds_the_stop_count() {
        let p = params();
        let mut proc = Procedure::new(
            p,
            Plan::Home {
                wires: [true, false, true],
            },
        );
        let stop = [123_456_i64, 0, -98_765];
        let mut counts = [stop[0] - 20_000, 5, stop[2] - 3_000];
        let mut sp = [0.0; 3];
        let dt = 1e-3;
        let mut t = 0.0;
        let mut status = Status::Running;
        for _ in 0..20_000 {
            let mut input = ProcedureInput {
                time_s: t,
                counts,
                ..ProcedureInput::default()
            };
            for i in 0..3 {
                let at_stop = counts[i] >= stop[i];
                input.tension_n[i] = if at_stop { sp[i] } else { 0.4 };
                input.wind_speed_m_s[i] = if !at_stop && sp[i] > 0.45 { 0.1 } else { 0.0 };
            }
            status = proc.update(&input, &mut sp);
            if status != Status::Running {
                break;
            }
            for i in 0..3 {
                if input.wind_speed_m_s[i] > 0.0 {
                    counts[i] = (counts[i] + (0.1 * dt / p.metres_per_count) as i64).min(stop[i]);
                }
            }
            t += dt;
        }
        assert_eq!(status, Status::Finished);
        let z = proc.homed_zero_counts();
        assert_eq!(z[0], stop[0]);
        assert_eq!(z[2], stop[2]);
        assert_eq!(sp, [0.4; 3]);
    }

    #[test]
    fn estop_and_limits_end_at_the_pay_out_tension() {
        let mut proc = Procedure::new(params(), Plan::Initialize);
        let mut sp = [9.0; 3];
        let input = ProcedureInput {
            estop_pressed: true,
            tension_n: [0.4; 3],
            ..ProcedureInput::default()
        };
        assert_eq!(
            proc.update(&input, &mut sp),
            Status::Failed(Failure::EmergencyStop)
        );
        assert_eq!(sp, [0.4; 3]);
        let mut proc = Procedure::new(params(), Plan::Initialize);
        let mut input = ProcedureInput {
            tension_n: [0.4; 3],
            ..ProcedureInput::default()
        };
        input.wind_speed_m_s[1] = -0.9;
        assert!(matches!(
            proc.update(&input, &mut sp),
            Status::Failed(Failure::LimitHit {
                wire: 1,
                limit: Limit::Speed { .. }
            })
        ));
        // The failure stays latched.
        let input = ProcedureInput {
            tension_n: [0.4; 3],
            time_s: 1.0,
            ..ProcedureInput::default()
        };
        assert!(matches!(
            proc.update(&input, &mut sp),
            Status::Failed(Failure::LimitHit { .. })
        ));
    }
}
