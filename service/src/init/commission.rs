//! The commissioning check of an assembled rig, thimble detached (`videt commission`): the
//! e-stop's level released and pressed, each tension sensor's zero at rest, and for each drive
//! the wire it moves, the direction it winds, the sensor that answers (its sign and rough
//! scale), its encoder's direction and counts per millimetre. Each step says what it measured,
//! and a failing step the configuration fix (or the wiring to change).
//!
//! Every wire rests fully wound, its end sphere against its ring. A drive's test torque (the
//! one holding `commission.test_tension_n`) on a motor that winds pulls the sphere against the
//! ring: its wire's sensor reads that tension and the encoder hardly moves. On a motor wired the
//! other way it pays the wire out instead (slowly: a wire faster than
//! `commission.max_speed_m_s` has its torque cut) and no tension rises; the opposite torque
//! then winds it back and the tension rises. The technician pulls each wire out to a mark with
//! its motor idle: the encoder must count that length down, at the configured transmission.
//! The torques are the only ones any motor gets; every other wire has none.

use std::sync::atomic::{AtomicBool, Ordering};

use videt_control::autoinit::Failure;
use videt_rt_config::edit::{Fix, FixValue};
use videt_rt_config::{Config, LineLevel, TensionAdc};
use videt_runtime::WIREMAN_WIRES;

use super::runner::{InitHardware, Readings, Runner};

/// A step's verdict.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// As configured.
    Pass,
    /// Not as configured: the step names the fix.
    Fail,
    /// Not checked (and why).
    Skipped,
}

impl Verdict {
    /// `PASS`, `FAIL` or `SKIPPED`.
    pub fn label(self) -> &'static str {
        match self {
            Verdict::Pass => "PASS",
            Verdict::Fail => "FAIL",
            Verdict::Skipped => "SKIPPED",
        }
    }
}

/// One step of the check.
#[derive(Debug, Clone, PartialEq)]
pub struct StepReport {
    /// Stable name, e.g. `drive1.direction`.
    pub name: String,
    /// The verdict.
    pub verdict: Verdict,
    /// What was measured (or why it was skipped), as a sentence.
    pub measured: String,
    /// The configuration changes that fix a failure.
    pub fixes: Vec<Fix>,
    /// The wiring to change instead, when no configuration fixes it.
    pub wiring: Option<String>,
}

impl StepReport {
    /// A step that passed, having measured `measured`.
    pub fn pass(name: impl Into<String>, measured: impl Into<String>) -> StepReport {
        StepReport {
            name: name.into(),
            verdict: Verdict::Pass,
            measured: measured.into(),
            fixes: Vec::new(),
            wiring: None,
        }
    }
    /// A step that failed, having measured `measured`; `fixes` put it right.
    pub fn fail(
        name: impl Into<String>,
        measured: impl Into<String>,
        fixes: Vec<Fix>,
    ) -> StepReport {
        StepReport {
            verdict: Verdict::Fail,
            fixes,
            ..StepReport::pass(name, measured)
        }
    }
    /// A step not checked, and `why`.
    pub fn skipped(name: impl Into<String>, why: impl Into<String>) -> StepReport {
        StepReport {
            verdict: Verdict::Skipped,
            ..StepReport::pass(name, why)
        }
    }
    /// The same step, with the wiring to change.
    pub fn with_wiring(mut self, wiring: impl Into<String>) -> StepReport {
        self.wiring = Some(wiring.into());
        self
    }
}

/// A manual step of the check.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CommissionStep {
    /// Make sure the e-stop is released.
    ReleaseEStop,
    /// Press the e-stop and keep it pressed.
    PressEStop,
    /// Pull the wire at ring `ring` out by `length_m` (to the mark), and hold it there.
    PullOutWire {
        /// The ring (the wire as it hangs on the frame).
        ring: usize,
        /// How far, metres.
        length_m: f64,
    },
    /// Let the wire at ring `ring` go: its motor winds it back.
    LetGo {
        /// The ring.
        ring: usize,
    },
}

impl CommissionStep {
    /// What a person is asked to do.
    pub fn instructions(&self) -> String {
        match *self {
            CommissionStep::ReleaseEStop => {
                "make sure the e-stop is released (not pressed); press Enter".into()
            }
            CommissionStep::PressEStop => {
                "press the e-stop and keep it pressed; press Enter".into()
            }
            CommissionStep::PullOutWire { ring, length_m } => format!(
                "pull the wire at ring {ring} out by {:.0} mm (to the mark) by its end sphere and hold it there; press Enter",
                length_m * 1e3
            ),
            CommissionStep::LetGo { ring } => format!(
                "let the wire at ring {ring} go slowly: its motor winds it back; press Enter once it rests against its ring"
            ),
        }
    }
}

/// Who performs the manual steps of the check (a person prompted at the terminal, or the
/// twin's technician). While a step is under way no motor gets torque.
pub trait CommissionTechnician<H> {
    /// Start `step`: the twin's technician does it at once; a person is told what to do.
    fn perform_commission(&mut self, step: CommissionStep, hw: &mut H) -> Result<(), Failure>;
    /// Asked every period while `step` is under way: whether it is done.
    fn commission_step_done(&mut self, _step: CommissionStep, _hw: &mut H) -> bool {
        true
    }
}

/// What the check of the rig found: its steps, and the failure that stopped it early.
#[derive(Debug, Clone, PartialEq)]
pub struct RigCheck {
    /// The steps, in the order they ran.
    pub steps: Vec<StepReport>,
    /// Why the check stopped before its end (an e-stop pressed during a test, a drive fault,
    /// a cancel), if it did.
    pub stopped: Option<Failure>,
}

/// What a drive's winding test found.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Winding {
    /// The sign of the torque that winds the drive's wire (+1 as configured, -1 reversed).
    sign: f64,
    /// The tension channel that answered.
    sensor: usize,
    /// Its change, N (negative for a cell read the other way).
    change_n: f64,
}

/// The check of the rig's drives, sensors and e-stop, on started hardware. `runner` gives the
/// readings (uncorrected: the tension calibration is not applied) and the transmission.
pub fn check_rig<H, T>(
    hw: &mut H,
    tech: &mut T,
    runner: &mut Runner,
    config: &Config,
    stop: &AtomicBool,
) -> RigCheck
where
    H: InitHardware,
    T: CommissionTechnician<H>,
{
    let mut steps = Vec::new();
    let stopped = run_checks(hw, tech, runner, config, stop, &mut steps).err();
    // Every motor idle whatever happened.
    let _ = runner.period(hw, &[0.0; WIREMAN_WIRES], None);
    if matches!(
        stopped,
        Some(Failure::EmergencyStop | Failure::DriveFault { .. })
    ) {
        let _ = hw.disable();
    }
    RigCheck { steps, stopped }
}

fn run_checks<H, T>(
    hw: &mut H,
    tech: &mut T,
    runner: &mut Runner,
    config: &Config,
    stop: &AtomicBool,
    steps: &mut Vec<StepReport>,
) -> Result<(), Failure>
where
    H: InitHardware,
    T: CommissionTechnician<H>,
{
    let level_fix = || {
        vec![Fix::new(
            "sensors.estop_pressed_level",
            None,
            FixValue::Text(
                match config.sensors.estop_pressed_level {
                    LineLevel::Low => "high",
                    LineLevel::High => "low",
                }
                .into(),
            ),
        )]
    };
    // The e-stop released, before any motor moves.
    manual_step(hw, tech, runner, CommissionStep::ReleaseEStop, stop)?;
    let released_reads_pressed = hw.reset().is_err() || estop_reads_pressed(hw, runner)?;
    if released_reads_pressed {
        manual_step(hw, tech, runner, CommissionStep::PressEStop, stop)?;
        let pressed_reads_released = hw.reset().is_ok() && !estop_reads_pressed(hw, runner)?;
        let (measured, fixes, wiring) = if pressed_reads_released {
            (
                "the e-stop input reads pressed while the button is released, and released while it is pressed: its level is the other one",
                level_fix(),
                None,
            )
        } else {
            (
                "the e-stop input reads pressed whether the button is released or pressed",
                Vec::new(),
                Some(format!(
                    "check the e-stop's wiring to line {} of {} (sensors.estop_line, sensors.gpio_chip): a cut wire or another line",
                    config.sensors.estop_line, config.sensors.gpio_chip
                )),
            )
        };
        let mut step = StepReport::fail("estop.released", measured, fixes);
        step.wiring = wiring;
        steps.push(step);
        manual_step(hw, tech, runner, CommissionStep::ReleaseEStop, stop)?;
        for name in ["drives", "sensors", "estop.pressed"] {
            steps.push(StepReport::skipped(
                name,
                "not checked: the motors are not driven without a working e-stop (fix it and run the check again)",
            ));
        }
        return Ok(());
    }
    steps.push(StepReport::pass(
        "estop.released",
        "the e-stop input reads released",
    ));

    // Each sensor's zero at rest, every motor idle.
    let period_s = 1.0 / f64::from(runner.settings().rate_hz.max(1));
    let periods = |s: f64| ((s / period_s).round() as u32).max(1);
    let rest = drive_for(hw, runner, stop, periods(0.5), &mut |_| {
        [0.0; WIREMAN_WIRES]
    })?;
    let s = &config.sensors;
    for (j, offset) in rest.mean_tension_n.iter().enumerate() {
        let name = format!("sensor{j}.zero");
        let counts = offset / s.newtons_per_count[j];
        if offset.abs() <= 1.0 {
            steps.push(StepReport::pass(
                name,
                format!("reads {offset:+.2} N at rest ({counts:+.0} counts from sensors.zero_counts[{j}])"),
            ));
        } else {
            let zero = f64::from(s.zero_counts[j]) + counts;
            steps.push(StepReport::fail(
                name,
                format!("reads {offset:+.2} N at rest, more than 1 N"),
                vec![Fix::new(
                    "sensors.zero_counts",
                    Some(j),
                    FixValue::Integer(zero.round() as i64),
                )],
            ));
        }
    }

    // Each drive's winding test.
    let test_n = config.commission.test_tension_n;
    let max_speed = config.commission.max_speed_m_s;
    let mut windings: [Option<Winding>; WIREMAN_WIRES] = [None; WIREMAN_WIRES];
    for k in 0..WIREMAN_WIRES {
        windings[k] = winding_test(hw, runner, stop, k, test_n, max_speed, &rest, periods)?;
    }
    let tension_follows_drives = s.adc == TensionAdc::Drive;
    let mut drive_of_wire: [Option<usize>; WIREMAN_WIRES] = [None; WIREMAN_WIRES];
    for (k, w) in windings.iter().enumerate() {
        let Some(w) = w else {
            steps.push(
                StepReport::fail(
                    format!("drive{k}.wire"),
                    format!(
                        "no tension sensor answered drive {k} (node {}) under either direction of its test torque",
                        config.drives.node_ids[k]
                    ),
                    Vec::new(),
                )
                .with_wiring(format!(
                    "check that drive {k}'s motor turns a pulley whose wire ends in a sphere resting against its ring, and that the wire's load cell is connected"
                )),
            );
            continue;
        };
        if drive_of_wire[w.sensor].replace(k).is_some() {
            steps.push(
                StepReport::fail(
                    format!("drive{k}.wire"),
                    format!(
                        "drive {k} moves the wire at ring {} that another drive moves too",
                        w.sensor
                    ),
                    Vec::new(),
                )
                .with_wiring("each motor must turn its own wire's pulley"),
            );
            continue;
        }
        let moved = format!(
            "drive {k} (node {}) moves the wire at ring {}: sensor {} answered {:+.2} N",
            config.drives.node_ids[k], w.sensor, w.sensor, w.change_n
        );
        if tension_follows_drives {
            steps.push(StepReport::pass(
                format!("drive{k}.wire"),
                format!("{moved} (with sensors.adc = \"drive\" a sensor follows its drive: which wire a drive moves is not told by the sensors)"),
            ));
        } else if w.sensor == k {
            steps.push(StepReport::pass(format!("drive{k}.wire"), moved));
        } else {
            steps.push(StepReport::fail(
                format!("drive{k}.wire"),
                format!("{moved}, not the wire at ring {k} (drives.wires has the fix)"),
                Vec::new(),
            ));
        }
    }
    // Drives on the wrong wires: one fix, the ids (and each drive's directions) reordered.
    let permutation: Option<[usize; WIREMAN_WIRES]> = drive_of_wire
        .iter()
        .copied()
        .collect::<Option<Vec<usize>>>()
        .and_then(|v| v.try_into().ok());
    let wrong_wires = permutation.is_some_and(|p| p.iter().enumerate().any(|(j, k)| j != *k));

    // Direction, sensor sign and scale.
    let mut motor_reversed = config.drives.motor_reversed;
    for (k, w) in windings.iter().enumerate() {
        let Some(w) = w else {
            steps.push(StepReport::skipped(
                format!("drive{k}.direction"),
                "not checked: the drive's wire was not found",
            ));
            continue;
        };
        if w.sign > 0.0 {
            steps.push(StepReport::pass(
                format!("drive{k}.direction"),
                format!("a positive torque winds the wire at ring {}", w.sensor),
            ));
        } else {
            motor_reversed[k] = !motor_reversed[k];
            steps.push(StepReport::fail(
                format!("drive{k}.direction"),
                format!(
                    "a positive torque unwinds the wire at ring {} (the opposite torque winds it)",
                    w.sensor
                ),
                vec![Fix::new(
                    "drives.motor_reversed",
                    Some(k),
                    FixValue::Bool(motor_reversed[k]),
                )],
            ));
        }
        let j = w.sensor;
        let scale = w.change_n.abs() / test_n;
        let name = format!("sensor{j}.sign-and-scale");
        let reads = format!(
            "reads {:+.2} N while its wire is pulled at {test_n:.2} N (x{scale:.2})",
            w.change_n
        );
        let inverted = w.change_n < 0.0;
        let scale_ok = (0.5..=2.0).contains(&scale);
        let (problem, factor) = match (inverted, scale_ok) {
            (false, true) => (None, 1.0),
            (true, true) => (Some("the load cell is read the other way"), -1.0),
            (false, false) => (Some("its scale is far off"), 1.0 / scale),
            (true, false) => (
                Some("the load cell is read the other way and its scale is far off"),
                -1.0 / scale,
            ),
        };
        steps.push(match problem {
            None => StepReport::pass(
                name,
                format!("{reads}; `videt tension-calibrate` measures it exactly"),
            ),
            Some(problem) => StepReport::fail(
                name,
                format!("{reads}: {problem}"),
                vec![Fix::new(
                    "sensors.newtons_per_count",
                    Some(j),
                    FixValue::Float(factor * s.newtons_per_count[j]),
                )],
            ),
        });
    }

    // Each encoder, against a wire pulled out to the mark.
    let mut encoder_reversed = config.drives.encoder_reversed;
    let metres_per_count = runner.settings().transmission.metres_per_count();
    let pull_m = config.commission.pull_out_m;
    for (k, w) in windings.iter().enumerate() {
        let name = format!("drive{k}.encoder");
        let Some(w) = w else {
            steps.push(StepReport::skipped(
                name,
                "not checked: the drive's wire was not found",
            ));
            continue;
        };
        let ring = w.sensor;
        // The sphere held against its ring, then the motor idle while the wire is pulled.
        let hold = w.sign * runner.settings().pay_out_tension_n;
        let before = drive_for(hw, runner, stop, periods(0.3), &mut |r| {
            test_force(r, k, hold, max_speed)
        })?
        .counts
        .1[k];
        manual_step(
            hw,
            tech,
            runner,
            CommissionStep::PullOutWire {
                ring,
                length_m: pull_m,
            },
            stop,
        )?;
        let after = rest_counts(hw, runner, stop, periods(0.2))?[k];
        tech.perform_commission(CommissionStep::LetGo { ring }, hw)?;
        wind_back(hw, tech, runner, stop, k, w, test_n, max_speed, periods)?;
        let counted = (after - before) as f64;
        let expected = -pull_m / metres_per_count;
        let ratio = counted / expected;
        let per_mm = |c: f64| c.abs() / (pull_m * 1e3);
        let measured = format!(
            "{counted:+.0} counts for the {:.0} mm pulled out ({:.1} counts/mm; the transmission configured gives {:.1})",
            pull_m * 1e3,
            per_mm(counted),
            per_mm(expected)
        );
        if ratio.abs() < 0.1 {
            steps.push(
                StepReport::fail(name, format!("{measured}: the encoder did not count"), Vec::new())
                    .with_wiring(format!("check drive {k}'s encoder cable and that its encoder is on the motor turning the wire at ring {ring}")),
            );
        } else if ratio < 0.0 {
            encoder_reversed[k] = !encoder_reversed[k];
            steps.push(StepReport::fail(
                name,
                format!("{measured}: it counts up as the wire pays out"),
                vec![Fix::new(
                    "drives.encoder_reversed",
                    Some(k),
                    FixValue::Bool(encoder_reversed[k]),
                )],
            ));
        } else if (ratio - 1.0).abs() > 0.05 {
            steps.push(StepReport::fail(
                name,
                format!("{measured}: {:.1} % off", (ratio - 1.0) * 100.0),
                Vec::new(),
            ).with_wiring("check transmission.counts_per_motor_rev, transmission.gear_ratio and transmission.pulley_radius_m against the parts fitted"));
        } else {
            steps.push(StepReport::pass(name, measured));
        }
    }
    if wrong_wires && !tension_follows_drives {
        let p = permutation.expect("a permutation when the wires are wrong");
        // The drive found on wire j goes to place j, with its directions.
        let ids = p.map(|k| FixValue::Integer(i64::from(config.drives.node_ids[k])));
        let mut fixes = vec![Fix::new(
            "drives.node_ids",
            None,
            FixValue::List(ids.to_vec()),
        )];
        for (key, now, fixed) in [
            (
                "drives.motor_reversed",
                config.drives.motor_reversed,
                motor_reversed,
            ),
            (
                "drives.encoder_reversed",
                config.drives.encoder_reversed,
                encoder_reversed,
            ),
        ] {
            let placed = p.map(|k| fixed[k]);
            if placed != now {
                fixes.push(Fix::new(
                    key,
                    None,
                    FixValue::List(placed.map(FixValue::Bool).to_vec()),
                ));
            }
        }
        let rings: Vec<String> = windings
            .iter()
            .map(|w| w.map_or("?".into(), |w| w.sensor.to_string()))
            .collect();
        steps.push(StepReport::fail(
            "drives.wires",
            format!(
                "drives 0, 1, 2 move the wires at rings {}: the node ids go in the order of the wires they move (each drive's directions with it)",
                rings.join(", ")
            ),
            fixes,
        ));
    }

    // The e-stop pressed, every motor idle.
    manual_step(hw, tech, runner, CommissionStep::PressEStop, stop)?;
    let pressed = estop_reads_pressed(hw, runner)?;
    manual_step(hw, tech, runner, CommissionStep::ReleaseEStop, stop)?;
    let _ = hw.reset();
    steps.push(if pressed {
        StepReport::pass("estop.pressed", "the e-stop input reads pressed")
    } else {
        StepReport::fail(
            "estop.pressed",
            "the e-stop input reads released while the button is pressed",
            Vec::new(),
        )
        .with_wiring(format!(
            "check that the e-stop is wired to line {} of {} (sensors.estop_line, sensors.gpio_chip)",
            config.sensors.estop_line, config.sensors.gpio_chip
        ))
    });
    Ok(())
}

/// What a stretch of periods measured.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Stretch {
    /// Mean tension of each channel over the stretch's last quarter, N.
    mean_tension_n: [f64; WIREMAN_WIRES],
    /// Encoder counts at its start and its end.
    counts: ([i64; WIREMAN_WIRES], [i64; WIREMAN_WIRES]),
}

/// Run `periods` periods with the forces `force(readings)` (N, through the transmission; sign
/// as the HAL's: positive winds). Fails on an e-stop, a drive or sensor fault, or `stop`.
fn drive_for<H: InitHardware>(
    hw: &mut H,
    runner: &mut Runner,
    stop: &AtomicBool,
    periods: u32,
    force: &mut dyn FnMut(&Readings) -> [f64; WIREMAN_WIRES],
) -> Result<Stretch, Failure> {
    let mut f = [0.0; WIREMAN_WIRES];
    let mut sum = [0.0; WIREMAN_WIRES];
    let mut summed = 0u32;
    let mut first = None;
    let mut last = [0; WIREMAN_WIRES];
    for n in 0..periods {
        let (r, ok) = runner.period(hw, &f, None);
        check_readings(&r, ok, stop)?;
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

/// A failure the readings of a period show.
fn check_readings(r: &Readings, written: bool, stop: &AtomicBool) -> Result<(), Failure> {
    if r.input.estop_pressed {
        return Err(Failure::EmergencyStop);
    }
    if let Some(w) = r.input.drive_fault {
        return Err(Failure::DriveFault { wire: w });
    }
    if r.input.sensor_fault {
        return Err(Failure::SensorFault);
    }
    if !written {
        return Err(Failure::DriveFault { wire: None });
    }
    if stop.load(Ordering::Relaxed) {
        return Err(Failure::Cancelled);
    }
    Ok(())
}

/// The encoder counts after `periods` idle periods.
fn rest_counts<H: InitHardware>(
    hw: &mut H,
    runner: &mut Runner,
    stop: &AtomicBool,
    periods: u32,
) -> Result<[i64; WIREMAN_WIRES], Failure> {
    Ok(
        drive_for(hw, runner, stop, periods, &mut |_| [0.0; WIREMAN_WIRES])?
            .counts
            .1,
    )
}

/// Whether the e-stop reads pressed now (a period with every motor idle; the e-stop is not a
/// failure here: it is what is measured).
fn estop_reads_pressed<H: InitHardware>(hw: &mut H, runner: &mut Runner) -> Result<bool, Failure> {
    let (r, _) = runner.period(hw, &[0.0; WIREMAN_WIRES], None);
    if let Some(w) = r.input.drive_fault {
        return Err(Failure::DriveFault { wire: w });
    }
    Ok(r.input.estop_pressed)
}

/// Ask the technician for `step` and wait, every motor idle, until it is done.
fn manual_step<H: InitHardware, T: CommissionTechnician<H>>(
    hw: &mut H,
    tech: &mut T,
    runner: &mut Runner,
    step: CommissionStep,
    stop: &AtomicBool,
) -> Result<(), Failure> {
    tech.perform_commission(step, hw)?;
    loop {
        let (r, _) = runner.period(hw, &[0.0; WIREMAN_WIRES], None);
        if let Some(w) = r.input.drive_fault {
            return Err(Failure::DriveFault { wire: w });
        }
        if stop.load(Ordering::Relaxed) {
            return Err(Failure::Cancelled);
        }
        if tech.commission_step_done(step, hw) {
            return Ok(());
        }
    }
}

/// Drive `k`'s test torque one way, then (no tension rising) the other: which way winds, and
/// which sensor answers. `None` when no sensor answers either way.
#[allow(clippy::too_many_arguments)]
fn winding_test<H: InitHardware>(
    hw: &mut H,
    runner: &mut Runner,
    stop: &AtomicBool,
    k: usize,
    test_n: f64,
    max_speed: f64,
    rest: &Stretch,
    periods: impl Fn(f64) -> u32,
) -> Result<Option<Winding>, Failure> {
    // The second direction long enough to wind back what the first paid out (at the speed
    // limit) and then pull against the stop.
    for (sign, seconds) in [(1.0, 0.6), (-1.0, 2.0)] {
        let stretch = drive_for(hw, runner, stop, periods(seconds), &mut |r| {
            test_force(r, k, sign * test_n, max_speed)
        })?;
        let change: [f64; WIREMAN_WIRES] =
            core::array::from_fn(|j| stretch.mean_tension_n[j] - rest.mean_tension_n[j]);
        let j = (0..WIREMAN_WIRES)
            .max_by(|a, b| change[*a].abs().total_cmp(&change[*b].abs()))
            .unwrap_or(0);
        if change[j].abs() > 0.3 * test_n {
            // Idle again: the sphere rests against its ring.
            drive_for(hw, runner, stop, periods(0.2), &mut |_| {
                [0.0; WIREMAN_WIRES]
            })?;
            return Ok(Some(Winding {
                sign,
                sensor: j,
                change_n: change[j],
            }));
        }
    }
    Ok(None)
}

/// Drive `k`'s force `force_n` (the others none), cut while its wire moves faster than
/// `max_speed` the way the force drives it.
fn test_force(r: &Readings, k: usize, force_n: f64, max_speed: f64) -> [f64; WIREMAN_WIRES] {
    let mut f = [0.0; WIREMAN_WIRES];
    let speed = r.input.wind_speed_m_s[k];
    // The speed is the encoder's: on a reversed encoder its sign is wrong, so any fast motion
    // cuts the torque.
    if speed.abs() <= max_speed {
        f[k] = force_n;
    }
    f
}

/// After a pull-out, wind drive `k`'s wire back (its winding direction known) until its
/// sensor reads half the test tension, at most 10 s; the technician says when it rests.
#[allow(clippy::too_many_arguments)]
fn wind_back<H: InitHardware, T: CommissionTechnician<H>>(
    hw: &mut H,
    tech: &mut T,
    runner: &mut Runner,
    stop: &AtomicBool,
    k: usize,
    w: &Winding,
    test_n: f64,
    max_speed: f64,
    periods: impl Fn(f64) -> u32,
) -> Result<(), Failure> {
    let force = w.sign * test_n;
    let mut seated = false;
    let mut f = [0.0; WIREMAN_WIRES];
    for _ in 0..periods(10.0) {
        let (r, ok) = runner.period(hw, &f, None);
        check_readings(&r, ok, stop)?;
        if r.tension_n[w.sensor] * w.change_n.signum() > 0.5 * test_n {
            seated = true;
            break;
        }
        f = test_force(&r, k, force, max_speed);
    }
    drive_for(hw, runner, stop, periods(0.2), &mut |_| {
        [0.0; WIREMAN_WIRES]
    })?;
    let step = CommissionStep::LetGo { ring: w.sensor };
    while !tech.commission_step_done(step, hw) {
        let (r, ok) = runner.period(hw, &[0.0; WIREMAN_WIRES], None);
        check_readings(&r, ok, stop)?;
    }
    if !seated {
        return Err(Failure::Timeout {
            wire: k as u8,
            elapsed_s: 10.0,
        });
    }
    Ok(())
}
