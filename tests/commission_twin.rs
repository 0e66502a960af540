//! Whole-stack tests of the commissioning check on the twin: a rig built with each wiring
//! mistake, alone and two at a time, is checked; each mistake is named with its fix; the fixes
//! written into the example configuration make the check pass and `videt init` succeed. The
//! motors never get more than the check's test torque, and are left without torque when a
//! check is stopped.

use std::sync::atomic::{AtomicBool, Ordering};

use videt_assembly::as_built::WiringMistake;
use videt_assembly::WiremanTwin as Twin;
use videt_config::edit::{apply_fixes, Fix};
use videt_config::Config;
use videt_hal::{Clock, DriveSample, EStop, MonoTime, TensionSensors, WireDrives};
use videt_service::init::commission::{
    check_rig, CommissionStep, CommissionTechnician, RigCheck, Thimble, Verdict,
};
use videt_service::init::runner::Runner;
use videt_service::init::session::{self, run_settings, FlowContext};
use videt_service::init::twin::{rest_twin, SimFault, SimTechnician, TwinSetup};

const WIRES: usize = 3;

fn example() -> String {
    std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/config/videt.example.toml"
    ))
    .unwrap()
}

fn setup(config: &Config, mistakes: &[WiringMistake]) -> TwinSetup {
    let mut s = TwinSetup::from_config(config, 5);
    s.faults = mistakes.iter().map(|m| SimFault::Wiring(*m)).collect();
    s
}

/// The twin's HAL, recording the largest torque any motor was commanded.
struct Watched {
    twin: Twin,
    largest_torque_nm: f64,
}

impl videt_hal::ErrorType for Watched {
    type Error = videt_sim::TwinError;
}
impl WireDrives<WIRES> for Watched {
    fn enable(&mut self) -> Result<(), Self::Error> {
        self.twin.enable()
    }
    fn disable(&mut self) -> Result<(), Self::Error> {
        self.twin.disable()
    }
    fn read_drives(&mut self, out: &mut [DriveSample; WIRES]) -> Result<(), Self::Error> {
        self.twin.read_drives(out)
    }
    fn write_torques(&mut self, torque_nm: &[f64; WIRES]) -> Result<(), Self::Error> {
        for t in torque_nm {
            self.largest_torque_nm = self.largest_torque_nm.max(t.abs());
        }
        self.twin.write_torques(torque_nm)
    }
}
impl TensionSensors<WIRES> for Watched {
    fn read_tensions(&mut self, out_n: &mut [f64; WIRES]) -> Result<(), Self::Error> {
        self.twin.read_tensions(out_n)
    }
}
impl EStop for Watched {
    fn is_pressed(&mut self) -> Result<bool, Self::Error> {
        self.twin.is_pressed()
    }
    fn reset(&mut self) -> Result<(), Self::Error> {
        self.twin.reset()
    }
}
impl Clock for Watched {
    fn now(&self) -> MonoTime {
        self.twin.now()
    }
    fn sleep_until(&mut self, deadline: MonoTime) {
        self.twin.sleep_until(deadline)
    }
}
impl CommissionTechnician<Watched> for SimTechnician {
    fn perform_commission(
        &mut self,
        step: CommissionStep,
        hw: &mut Watched,
    ) -> Result<(), videt_control::autoinit::Failure> {
        <SimTechnician as CommissionTechnician<Twin>>::perform_commission(self, step, &mut hw.twin)
    }
}

/// Check a rig built with `mistakes` under `config`; the check, and the largest torque.
fn check(config: &Config, mistakes: &[WiringMistake], stop: &AtomicBool) -> (RigCheck, Watched) {
    check_with_gaps(config, mistakes, stop, [0.0; WIRES])
}

/// [`check`] with each wire's sphere resting `gaps_m` off its ring.
fn check_with_gaps(
    config: &Config,
    mistakes: &[WiringMistake],
    stop: &AtomicBool,
    gaps_m: [f64; WIRES],
) -> (RigCheck, Watched) {
    let s = setup(config, mistakes);
    let mut hw = Watched {
        twin: rest_twin(config, &s),
        largest_torque_nm: 0.0,
    };
    for (i, gap) in gaps_m.into_iter().enumerate() {
        hw.twin.plant_mut().set_free_length_m(i, gap);
    }
    session::start(&mut hw.twin).unwrap();
    let mut tech = SimTechnician::new(&s);
    let mut runner = Runner::new(run_settings(config));
    let found = check_rig(&mut hw, &mut tech, &mut runner, config, stop, Thimble::Off);
    (found, hw)
}

fn init_succeeds(config: &Config, mistakes: &[WiringMistake]) -> Result<(), String> {
    let s = setup(config, mistakes);
    let mut twin = rest_twin(config, &s);
    let mut tech = SimTechnician::new(&s);
    let mut runner = Runner::new(run_settings(config));
    session::start(&mut twin).map_err(|e| e.to_string())?;
    let stop = AtomicBool::new(false);
    let ctx = FlowContext {
        config,
        source: "twin",
        stop: &stop,
    };
    session::initialize(&mut twin, &mut tech, &mut runner, &ctx)
        .map(|_| ())
        .map_err(|e| e.to_string())
}

/// The configuration key each mistake's fix names.
fn fixed_by(m: WiringMistake) -> &'static str {
    match m {
        WiringMistake::ReversedMotor(_) => "drives.motor_reversed",
        WiringMistake::ReversedEncoder(_) => "drives.encoder_reversed",
        WiringMistake::SwappedNodes(..) => "drives.node_ids",
        WiringMistake::InvertedCell(_) => "sensors.newtons_per_count",
        WiringMistake::EStopLevel => "sensors.estop_pressed_level",
        WiringMistake::SwappedCameras => "vision.devices",
    }
}

/// Check, write the fixes into the example configuration, check again, until the check
/// passes (a wrong e-stop level stops the check before the motors: one more round); then
/// `videt init` on the rig as built.
fn commission_then_init(mistakes: &[WiringMistake]) {
    let mut text = example();
    let mut config: Config = toml::from_str(&text).unwrap();
    let test_torque = run_settings(&config)
        .transmission
        .torque_for_tension(config.commission.test_tension_n);
    let mut keys: Vec<String> = Vec::new();
    let rounds = if mistakes.contains(&WiringMistake::EStopLevel) {
        3
    } else {
        2
    };
    let stop = AtomicBool::new(false);
    for round in 1..=rounds {
        let (found, hw) = check(&config, mistakes, &stop);
        assert_eq!(found.stopped, None, "{mistakes:?} round {round}");
        assert!(
            hw.largest_torque_nm <= test_torque * (1.0 + 1e-9),
            "{mistakes:?}: {} N·m commanded, the test torque is {test_torque} N·m",
            hw.largest_torque_nm
        );
        let failed: Vec<_> = found
            .steps
            .iter()
            .filter(|s| s.verdict == Verdict::Fail)
            .collect();
        if failed.is_empty() {
            assert!(
                round > 1 || mistakes.is_empty(),
                "{mistakes:?}: nothing found"
            );
            for m in mistakes {
                assert!(
                    keys.iter().any(|k| k == fixed_by(*m)),
                    "{mistakes:?}: {m:?} not fixed by {} (fixes: {keys:?})",
                    fixed_by(*m)
                );
            }
            init_succeeds(&config, mistakes)
                .unwrap_or_else(|e| panic!("{mistakes:?}: videt init after the fixes: {e}"));
            return;
        }
        let fixes: Vec<Fix> = found
            .steps
            .iter()
            .flat_map(|s| s.fixes.iter().cloned())
            .collect();
        // Every failure is one the configuration fixes, or points to the step that does.
        for s in &failed {
            assert!(
                s.wiring.is_none(),
                "{mistakes:?}: {} asks for rewiring: {:?}",
                s.name,
                s.wiring
            );
        }
        assert!(!fixes.is_empty(), "{mistakes:?}: failures without a fix");
        keys.extend(fixes.iter().map(|f| f.key.clone()));
        text = apply_fixes(&text, &config, &fixes).unwrap();
        config = toml::from_str(&text).unwrap();
    }
    panic!("{mistakes:?}: the check still fails after {rounds} rounds");
}

/// One mistake of each kind, on the wires `n` picks.
fn kinds(n: usize) -> [WiringMistake; 5] {
    [
        WiringMistake::ReversedMotor(n % WIRES),
        WiringMistake::ReversedEncoder((n + 1) % WIRES),
        WiringMistake::SwappedNodes(n % WIRES, (n + 2) % WIRES),
        WiringMistake::InvertedCell((n + 2) % WIRES),
        WiringMistake::EStopLevel,
    ]
}

#[test]
fn a_rig_built_right_passes_and_its_configuration_needs_nothing() {
    let config: Config = toml::from_str(&example()).unwrap();
    let (found, _) = check(&config, &[], &AtomicBool::new(false));
    assert_eq!(found.stopped, None);
    assert!(
        found.steps.iter().all(|s| s.verdict == Verdict::Pass),
        "{:#?}",
        found.steps
    );
    // The check's steps: both e-stop levels, three zeros, and per drive its wire, direction,
    // sensor and encoder.
    assert_eq!(found.steps.len(), 2 + 3 + 4 * 3);
}

#[test]
fn each_mistake_alone_is_named_with_its_fix_and_after_the_fix_init_succeeds() {
    for n in 0..WIRES {
        for m in kinds(n) {
            if n > 0 && m == WiringMistake::EStopLevel {
                continue;
            }
            commission_then_init(&[m]);
        }
    }
}

#[test]
fn every_two_mistakes_together_are_found_and_fixed() {
    for (n, (a, b)) in (0..5)
        .flat_map(|i| (i + 1..5).map(move |j| (i, j)))
        .enumerate()
    {
        let k = kinds(n);
        commission_then_init(&[k[a], kinds(n + 1)[b]]);
    }
}

/// A sphere resting off its ring (a wire let go after the last check, or sagged) is wound onto
/// it whichever way its motor turns, however slowly the wires may move: every wire is found,
/// every reversed motor named.
#[test]
fn spheres_resting_off_their_rings_are_wound_onto_them() {
    let mut config: Config = toml::from_str(&example()).unwrap();
    // The slowest the check may move a wire.
    config.commission.max_speed_m_s = 0.01;
    let stop = AtomicBool::new(false);
    for gap_m in [0.002, 0.025] {
        for mistakes in [
            vec![],
            vec![WiringMistake::ReversedMotor(1)],
            vec![
                WiringMistake::ReversedMotor(0),
                WiringMistake::ReversedMotor(2),
            ],
        ] {
            let (found, _) = check_with_gaps(&config, &mistakes, &stop, [gap_m; WIRES]);
            assert_eq!(found.stopped, None, "{gap_m} m, {mistakes:?}");
            for step in &found.steps {
                let reversed = mistakes.iter().any(|m| {
                    matches!(m, WiringMistake::ReversedMotor(k) if step.name == format!("drive{k}.direction"))
                });
                let expected = if reversed {
                    Verdict::Fail
                } else {
                    Verdict::Pass
                };
                assert_eq!(step.verdict, expected, "{gap_m} m, {mistakes:?}: {step:?}");
            }
        }
    }
}

#[test]
fn a_stopped_check_leaves_every_motor_without_torque() {
    let config = Config::default();
    let stop = AtomicBool::new(false);
    // Stopped as soon as a wire is under test: the flag is read every period.
    struct StopAtPull<'a>(&'a AtomicBool);
    let s = setup(&config, &[WiringMistake::ReversedMotor(0)]);
    let mut twin = rest_twin(&config, &s);
    session::start(&mut twin).unwrap();
    let mut runner = Runner::new(run_settings(&config));
    impl CommissionTechnician<Twin> for StopAtPull<'_> {
        fn perform_commission(
            &mut self,
            step: CommissionStep,
            _hw: &mut Twin,
        ) -> Result<(), videt_control::autoinit::Failure> {
            if matches!(step, CommissionStep::PullOutWire { .. }) {
                self.0.store(true, Ordering::Relaxed);
            }
            Ok(())
        }
    }
    let found = check_rig(
        &mut twin,
        &mut StopAtPull(&stop),
        &mut runner,
        &config,
        &stop,
        Thimble::Off,
    );
    assert_eq!(
        found.stopped,
        Some(videt_control::autoinit::Failure::Cancelled)
    );
    assert_eq!(twin.applied_torque_nm(), [0.0; WIRES]);
    // The steps measured before the stop are kept.
    assert!(found.steps.iter().any(|s| s.name == "drive0.direction"));
}
