//! The commissioning check of an assembled rig, thimble detached (`videt commission`): the
//! e-stop's level released and pressed, each tension sensor's zero at rest, and for each drive
//! the wire it moves, the direction it winds, the sensor that answers (its sign and rough
//! scale), its encoder's direction and counts per millimetre. Each step says what it measured,
//! and a failing step the configuration fix (or the wiring to change).
//!
//! Every wire rests fully wound, its end sphere against its ring. A gentle pull (the pay-out
//! tension) on a motor that winds draws the sphere against the ring: its wire's sensor reads
//! it and the encoder hardly moves. On a motor wired the other way it pays the wire out instead
//! (slowly: a wire faster than `commission.max_speed_m_s` has its torque cut) and no tension
//! rises; the opposite pull then winds it back and the tension rises. Only with the sphere
//! against its ring does the drive get the test torque (the one holding
//! `commission.test_tension_n`), whose reading gives the sensor's sign and scale. The technician
//! pulls each wire out to a mark with its motor idle: the encoder must count that length down,
//! at the configured transmission. These torques are the only ones any motor gets; every other
//! wire has none.

mod bench;
mod identity;
mod steps;

pub use identity::identity_steps;

use std::sync::atomic::AtomicBool;

use serde::{Deserialize, Serialize};
use videt_config::edit::Fix;
use videt_config::Config;
use videt_control::autoinit::Failure;
use videt_control::safety::{SafetyReason, SafetyState};

use super::runner::{InitHardware, Runner};
use super::session::failure_exit_code;
use bench::{Bench, IDLE};

/// A step's verdict (`pass`, `fail`, `skipped` in JSON).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
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
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
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
    /// Take the thimble off the wires and lay each wire's end sphere against its ring (a check
    /// run by the service, whose wearer had it on).
    DetachThimble,
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
    /// Put the thimble back on the wires (a check run by the service, which renders again
    /// afterwards): the motors hold each wire at the pay-out tension meanwhile.
    AttachThimble,
}

impl CommissionStep {
    /// A short, stable name (the control socket's prompts).
    pub fn name(&self) -> &'static str {
        match self {
            CommissionStep::DetachThimble => "detach-thimble",
            CommissionStep::ReleaseEStop => "release-estop",
            CommissionStep::PressEStop => "press-estop",
            CommissionStep::PullOutWire { .. } => "pull-out-wire",
            CommissionStep::LetGo { .. } => "let-go",
            CommissionStep::AttachThimble => "attach-thimble",
        }
    }

    /// The ring the step is about, if one.
    pub fn ring(&self) -> Option<usize> {
        match *self {
            CommissionStep::PullOutWire { ring, .. } | CommissionStep::LetGo { ring } => Some(ring),
            _ => None,
        }
    }

    /// What a person is asked to do.
    pub fn instructions(&self) -> String {
        match *self {
            CommissionStep::DetachThimble => "take the thimble off the wires (the motors are idle) and lay each wire's end sphere against its ring; press Enter".into(),
            CommissionStep::AttachThimble => "put the thimble back on the wires (each wire is held at a light pull); press Enter once every wire is on it".into(),
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
    /// What the failing part said of it, when it said more (a drive's or a tension sensor's
    /// error).
    pub detail: Option<String>,
}

/// Whether every one of `steps` passed or was skipped.
fn as_configured(steps: &[StepReport]) -> bool {
    steps.iter().all(|s| s.verdict != Verdict::Fail)
}

impl RigCheck {
    /// Whether every step passed or was skipped.
    pub fn as_configured(&self) -> bool {
        as_configured(&self.steps)
    }

    /// Why the check stopped early, as a direct run reports it: its exit code, its name and
    /// its message (with what the failing part said, when it said more).
    pub fn stop(&self) -> Option<(u8, &'static str, String)> {
        self.stopped.map(|f| {
            let message = match &self.detail {
                Some(d) => format!("{f} ({d})"),
                None => f.to_string(),
            };
            (failure_exit_code(&f), f.name(), message)
        })
    }

    /// The safe state a service must keep after this check: power off when a step found the
    /// rig not as configured (forces would go the wrong way, or be measured wrong), with the
    /// reason of the first failing step's part; `None` when the rig is as configured.
    pub fn safe_state(&self) -> Option<SafetyState> {
        let failed = self.steps.iter().find(|s| s.verdict == Verdict::Fail)?;
        let name = failed.name.as_str();
        let wire = |prefix: &str| {
            name.strip_prefix(prefix)
                .and_then(|rest| rest.split('.').next())
                .and_then(|n| n.parse::<u8>().ok())
        };
        let reason = if name.starts_with("estop") {
            SafetyReason::EmergencyStop
        } else if name.starts_with("sensor") {
            SafetyReason::SensorFault {
                wire: wire("sensor"),
            }
        } else {
            SafetyReason::DriveFault {
                wire: wire("drive"),
            }
        };
        Some(SafetyState::PowerOff(reason))
    }
}

/// Where the thimble is when the check begins.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Thimble {
    /// Off the wires, every wire resting against its ring (a rig on the bench).
    Off,
    /// On the wires (the running service's rig): the technician takes it off first and, after
    /// a check that found the rig as configured, puts it back.
    On,
}

/// The check of the rig's drives, sensors and e-stop, on started hardware. `runner` gives the
/// readings (uncorrected: the tension calibration is not applied) and the transmission.
pub fn check_rig<H, T>(
    hw: &mut H,
    tech: &mut T,
    runner: &mut Runner,
    config: &Config,
    stop: &AtomicBool,
    thimble: Thimble,
) -> RigCheck
where
    H: InitHardware,
    T: CommissionTechnician<H>,
{
    let mut bench = Bench {
        hw,
        tech,
        runner,
        config,
        stop,
        steps: Vec::new(),
    };
    let stopped = run_checks(&mut bench, thimble).err();
    // Every motor idle whatever happened.
    let _ = bench.runner.period(bench.hw, &IDLE, None);
    if matches!(
        stopped,
        Some(Failure::EmergencyStop | Failure::DriveFault { .. })
    ) {
        let _ = bench.hw.disable();
    }
    let detail = match stopped {
        Some(Failure::SensorFault | Failure::DriveFault { wire: None }) => {
            bench.runner.device_error().map(str::to_string)
        }
        _ => None,
    };
    RigCheck {
        steps: bench.steps,
        stopped,
        detail,
    }
}

fn run_checks<H: InitHardware, T: CommissionTechnician<H>>(
    bench: &mut Bench<'_, H, T>,
    thimble: Thimble,
) -> Result<(), Failure> {
    if thimble == Thimble::On {
        bench.manual_step(CommissionStep::DetachThimble)?;
    }
    if !bench.estop_released()? {
        return Ok(());
    }
    let rest = bench.zeros()?;
    let (windings, found) = bench.wires(&rest)?;
    let motor_reversed = bench.directions(&windings);
    let encoder_reversed = bench.encoders(&windings)?;
    if let Some(found) = found {
        bench.wrong_wires(found, motor_reversed, encoder_reversed);
    }
    bench.estop_pressed()?;
    if thimble == Thimble::On && as_configured(&bench.steps) {
        // Every wire winds as configured: a light pull keeps them taut to the thimble.
        let hold = [bench.runner.settings().pay_out_tension_n; videt_runtime::WIREMAN_WIRES];
        bench.manual_step_holding(CommissionStep::AttachThimble, &hold)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(steps: Vec<StepReport>) -> RigCheck {
        RigCheck {
            steps,
            stopped: None,
            detail: None,
        }
    }

    #[test]
    fn a_rig_not_as_configured_is_kept_powered_off_for_its_first_failing_part() {
        let pass = StepReport::pass("estop.released", "reads released");
        let skipped = StepReport::skipped("cameras", "not here");
        assert_eq!(
            check(vec![pass.clone(), skipped.clone()]).safe_state(),
            None
        );
        assert!(check(vec![pass.clone(), skipped]).as_configured());
        for (name, reason) in [
            ("estop.pressed", SafetyReason::EmergencyStop),
            ("sensor2.zero", SafetyReason::SensorFault { wire: Some(2) }),
            (
                "sensor1.sign-and-scale",
                SafetyReason::SensorFault { wire: Some(1) },
            ),
            (
                "drive0.direction",
                SafetyReason::DriveFault { wire: Some(0) },
            ),
            ("drive2.encoder", SafetyReason::DriveFault { wire: Some(2) }),
            ("drives.wires", SafetyReason::DriveFault { wire: None }),
        ] {
            let found = check(vec![
                pass.clone(),
                StepReport::fail(name, "not as configured", Vec::new()),
                StepReport::fail("estop.pressed", "later", Vec::new()),
            ]);
            assert!(!found.as_configured());
            assert_eq!(
                found.safe_state(),
                Some(SafetyState::PowerOff(reason)),
                "{name}"
            );
        }
    }

    #[test]
    fn a_report_travels_as_json_and_comes_back_the_same() {
        let step = StepReport::fail(
            "drive1.direction",
            "a positive torque unwinds wire 1",
            vec![Fix::new(
                "drives.motor_reversed",
                Some(1),
                videt_config::edit::FixValue::Bool(true),
            )],
        )
        .with_wiring("or swap the motor's leads");
        let text = serde_json::to_string(&step).unwrap();
        assert!(text.contains(r#""verdict":"fail""#), "{text}");
        let back: StepReport = serde_json::from_str(&text).unwrap();
        assert_eq!(back, step);
    }
}
