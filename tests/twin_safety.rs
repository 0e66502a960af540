//! Safety on the whole stack: the real loop on the twin meets the faults a device meets.
//! Each fault ends in its own safe state, within the periods stated.

mod common;
use common::Recorder;
use std::sync::atomic::AtomicBool;
use videt_assembly::WiremanTwin as Twin;

use videt_config::Config;
use videt_control::safety::{SafetyReason, SafetyState};
use videt_hal::MonoTime;
use videt_runtime::control_loop::{
    run_control_loop, start_hardware, LoopControl, LoopSettings, LoopStats,
};
use videt_runtime::cycle::{CycleRecord, WireZero};
use videt_runtime::setup;
use videt_runtime::snapshot::FixedSurface;
use videt_sim::{TwinFault, Vec3, VirtualOperator, Waypoint};

/// Run `seconds` of the demo scene with `operator`, after `prepare` has scheduled faults.
fn run(
    seconds: f64,
    operator: impl Fn(Vec3, f64) -> VirtualOperator,
    prepare: impl FnOnce(&mut Twin),
) -> (Twin, Vec<CycleRecord>) {
    let config = Config::default();
    let mut scene = videt_assembly::twin_scene::wireman_wall_scene(&config, 21);
    let start = scene.twin.plant().position_m();
    scene.twin.set_operator(operator(start, scene.wall_z_m));
    prepare(&mut scene.twin);
    let rig = setup::rig(&config).unwrap();
    let mut cycle = setup::control_cycle(&config, rig, WireZero::default(), true);
    let settings = LoopSettings {
        rate_hz: 1000,
        duration_ns: Some((seconds * 1e9) as u64),
        max_consecutive_overruns: 10,
    };
    let mut twin = scene.twin;
    start_hardware(&mut twin).unwrap();
    let mut recorder = Recorder(Vec::with_capacity((seconds * 1000.0) as usize + 2000));
    let stop = AtomicBool::new(false);
    run_control_loop(
        &mut twin,
        &mut FixedSurface(scene.wall),
        &mut cycle,
        &settings,
        &mut LoopControl::stop_flag(&stop),
        &mut recorder,
        &mut LoopStats::default(),
    );
    (twin, recorder.0)
}

fn pressing(start: Vec3, wall_z: f64) -> VirtualOperator {
    let press = Vec3::new(start.x, start.y, wall_z + 0.02);
    VirtualOperator::new(
        vec![
            Waypoint {
                time_s: 0.0,
                target_m: start,
            },
            Waypoint {
                time_s: 0.4,
                target_m: press,
            },
        ],
        200.0,
        6.0,
    )
}

fn first_unsafe(records: &[CycleRecord]) -> &CycleRecord {
    records
        .iter()
        .find(|r| r.safety != SafetyState::Normal)
        .expect("a safe state was entered")
}

#[test]
fn a_quick_retraction_makes_slack_but_no_false_wire_break_and_no_tension_spike() {
    // Press on the wall, then snap the hand back 5 cm towards the frame in one step (the
    // finger moves faster than the wires can follow), then press again.
    let (_twin, records) = run(
        4.0,
        |start, wall_z| {
            let press = Vec3::new(start.x, start.y, wall_z + 0.02);
            let back = press - Vec3::new(0.0, 0.0, 0.05);
            let wp = |t: f64, p: Vec3| Waypoint {
                time_s: t,
                target_m: p,
            };
            VirtualOperator::new(
                vec![
                    wp(0.0, start),
                    wp(0.4, press),
                    wp(1.5, press),
                    wp(1.501, back),
                    wp(2.5, back),
                    wp(2.8, press),
                ],
                200.0,
                6.0,
            )
        },
        |_| {},
    );
    assert!(
        records.iter().all(|r| r.safety == SafetyState::Normal),
        "{:?}",
        first_unsafe(&records).safety
    );
    let slack = records
        .iter()
        .filter(|r| r.tension_measured_n.iter().any(|&t| t < 0.1))
        .count();
    assert!(
        slack > 10,
        "the retraction did make slack ({slack} periods)"
    );
    let max_t = records
        .iter()
        .flat_map(|r| r.tension_measured_n)
        .fold(0.0, f64::max);
    eprintln!("slack for {slack} periods; largest measured tension {max_t:.2} N");
    assert!(max_t < 8.0, "re-tensioning spike {max_t} N");
    let back_in_contact = records
        .iter()
        .filter(|r| r.time.as_secs_f64() > 3.5)
        .all(|r| r.in_contact);
    assert!(back_in_contact, "pressing on the wall again at the end");
}

#[test]
fn a_broken_wire_is_detected_and_the_drives_power_off() {
    let (twin, records) = run(4.0, pressing, |t| {
        t.schedule_fault(MonoTime(1_500_000_000), TwinFault::BreakWire(1));
    });
    let r = first_unsafe(&records);
    assert_eq!(
        r.safety,
        SafetyState::PowerOff(SafetyReason::WireBreak { wire: 1 })
    );
    let delay = r.time.as_secs_f64() - 1.5;
    assert!(
        delay > 0.0 && delay < 1.05,
        "detected {delay:.3} s after the break"
    );
    assert!(!twin.drives_enabled());
}

#[test]
fn the_estop_powers_off_within_two_periods() {
    let (twin, records) = run(2.0, pressing, |t| {
        t.schedule_fault(MonoTime(1_000_000_000), TwinFault::PressEStop);
    });
    let r = first_unsafe(&records);
    assert_eq!(r.safety, SafetyState::PowerOff(SafetyReason::EmergencyStop));
    assert!(
        r.time.as_secs_f64() - 1.0 <= 0.002 + 1e-9,
        "at {}",
        r.time.as_secs_f64()
    );
    assert_eq!(r.torque_nm, [0.0; 3]);
    assert!(!twin.drives_enabled());
}

#[test]
fn a_failed_tension_sensor_holds_the_wires_at_minimum_tension() {
    let (_twin, records) = run(2.0, pressing, |t| {
        t.schedule_fault(MonoTime(1_000_000_000), TwinFault::FailTensionSensor(2));
    });
    let r = first_unsafe(&records);
    assert_eq!(
        r.safety,
        SafetyState::MinimumTension(SafetyReason::SensorFault { wire: None })
    );
    assert!(r.time.as_secs_f64() - 1.0 <= 0.002 + 1e-9);
    // Minimum tension, not power off: the wires stay taut, nothing is rendered.
    let later = records.iter().find(|r| r.time.as_secs_f64() > 1.5).unwrap();
    assert!(Vec3::from(later.desired_force_n).norm() < 1e-12);
    assert!(later
        .tension_setpoint_n
        .iter()
        .all(|&t| (t - Config::default().control.t_min_n).abs() < 1e-9));
    assert!(
        records.iter().all(|r| !r.safety.power_off()),
        "the drives stayed powered"
    );
}

#[test]
fn a_drive_fault_powers_off_within_two_periods() {
    let (twin, records) = run(2.0, pressing, |t| {
        t.schedule_fault(MonoTime(1_000_000_000), TwinFault::FaultDrive(0));
    });
    let r = first_unsafe(&records);
    assert!(
        matches!(
            r.safety,
            SafetyState::PowerOff(SafetyReason::DriveFault { .. })
        ),
        "{:?}",
        r.safety
    );
    assert!(r.time.as_secs_f64() - 1.0 <= 0.002 + 1e-9);
    assert!(!twin.drives_enabled());
}
