//! Whole-stack tests: the real control loop, cycle and control step against the digital twin,
//! driven by the twin's simulated clock (faster than real time, deterministic).

use std::sync::atomic::AtomicBool;

use videt::control_loop::{
    run_control_loop, start_hardware, CycleObserver, LoopSettings, WindowStats,
};
use videt::cycle::{CycleRecord, WireZero};
use videt::setup;
use videt_control::safety::SafetyState;
use videt_rt_config::Config;
use videt_sim::{Vec3, VirtualOperator, Waypoint};

/// Keeps every record (preallocated).
struct Recorder(Vec<CycleRecord>);

impl CycleObserver for Recorder {
    fn observe(&mut self, record: &CycleRecord, _window: &WindowStats) {
        if self.0.len() < self.0.capacity() {
            self.0.push(*record);
        }
    }
}

fn run(
    config: &Config,
    operator: VirtualOperator,
    seconds: f64,
) -> (
    videt_sim::Twin,
    Vec<CycleRecord>,
    videt::control_loop::LoopReport,
) {
    let mut scene = setup::demo_scene(config, 42);
    scene.twin.set_operator(operator);
    let rig = setup::rig(config).unwrap();
    let mut cycle = setup::control_cycle(config, rig, WireZero::default(), true);
    let settings = LoopSettings {
        rate_hz: config.control.rate_hz,
        duration_ns: Some((seconds * 1e9) as u64),
        max_consecutive_overruns: 10,
    };
    let mut twin = scene.twin;
    start_hardware(&mut twin).unwrap();
    let mut recorder = Recorder(Vec::with_capacity(20_000));
    let report = run_control_loop(
        &mut twin,
        &scene.wall,
        &mut cycle,
        &settings,
        &AtomicBool::new(false),
        &mut recorder,
    );
    (twin, recorder.0, report)
}

#[test]
fn thimble_rests_on_the_wall_at_the_penetration_the_stiffness_predicts() {
    let config = Config::default();
    let scene = setup::demo_scene(&config, 42);
    let start = scene.twin.plant().position_m();
    let wall_z = scene.wall_z_m;
    // Approach the wall over 0.4 s and keep pressing 2 cm beyond it.
    let press = Vec3::new(start.x, start.y, wall_z + 0.02);
    let operator = VirtualOperator::new(
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
    );
    // Stop after 2 s; the ramp-down starts then, so look at the state just before it.
    let (_twin, records, report) = run(&config, operator, 2.0);
    assert_eq!(report.final_safety, SafetyState::Normal);
    let before_stop = records
        .iter()
        .rev()
        .find(|r| r.force_scale >= 1.0 && r.time.as_secs_f64() < 2.0)
        .unwrap();
    let k = config.control.stiffness_n_per_m;
    let penetration = before_stop.position_m[2] - wall_z;
    // The hand's push along the normal at rest equals what the wires render along it.
    let hand_push_n = 200.0 * (press.z - before_stop.position_m[2]);
    let predicted = hand_push_n / k;
    eprintln!(
        "penetration {:.3} mm, predicted {:.3} mm from a {:.3} N push",
        penetration * 1e3,
        predicted * 1e3,
        hand_push_n
    );
    assert!(
        (penetration - predicted).abs() <= 0.1 * predicted,
        "penetration {:.3} mm, predicted {:.3} mm (hand {:.3} N, K {k} N/m)",
        penetration * 1e3,
        predicted * 1e3,
        hand_push_n
    );
    // And at rest: the thimble is still.
    let speed = Vec3::from(before_stop.velocity_m_s).norm();
    assert!(speed < 0.005, "thimble still moving at {speed} m/s");
}

#[test]
fn operator_slides_along_the_wall_without_popping_through() {
    let config = Config::default();
    let scene = setup::demo_scene(&config, 7);
    let start = scene.twin.plant().position_m();
    let wall_z = scene.wall_z_m;
    let operator = VirtualOperator::touch_and_slide(start, wall_z, 0.02, 0.08, 4.0);
    let (twin, records, report) = run(&config, operator, 4.0);
    assert_eq!(report.final_safety, SafetyState::Normal);
    let in_contact: Vec<_> = records
        .iter()
        .filter(|r| r.in_contact && r.force_scale >= 1.0)
        .collect();
    assert!(
        in_contact.len() > 1000,
        "the operator touched the wall ({} periods)",
        in_contact.len()
    );
    let max_depth = in_contact
        .iter()
        .map(|r| r.contact_depth_m)
        .fold(0.0, f64::max);
    assert!(
        max_depth < 0.008,
        "never deeper than the hand can push against K: {max_depth}"
    );
    let xs: Vec<f64> = in_contact.iter().map(|r| r.position_m[0]).collect();
    let slid =
        xs.iter().cloned().fold(f64::MIN, f64::max) - xs.iter().cloned().fold(f64::MAX, f64::min);
    assert!(slid > 0.06, "slid {slid} m along the wall");
    // The true plant agrees with what the controller believed.
    let believed = Vec3::from(records.last().unwrap().position_m);
    assert!((twin.plant().position_m() - believed).norm() < 0.002);
}
