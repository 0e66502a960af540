//! Whole-stack tests: the real control loop, cycle and control step against the digital twin,
//! driven by the twin's simulated clock (faster than real time, deterministic).

mod common;
use common::Recorder;
use std::sync::atomic::AtomicBool;

use videt_config::Config;
use videt_control::safety::SafetyState;
use videt_runtime::control_loop::{
    run_control_loop, start_hardware, LoopControl, LoopSettings, LoopStats,
};
use videt_runtime::cycle::{CycleRecord, WireZero};
use videt_runtime::setup;
use videt_sim::{Vec3, VirtualOperator, Waypoint};

fn run(
    config: &Config,
    operator: VirtualOperator,
    seconds: f64,
) -> (
    videt_assembly::WiremanTwin,
    Vec<CycleRecord>,
    videt_runtime::control_loop::LoopReport,
) {
    let mut scene = videt_assembly::twin_scene::wireman_wall_scene(config, 42);
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
    let stop = AtomicBool::new(false);
    let report = run_control_loop(
        &mut twin,
        &mut videt_runtime::snapshot::FixedSurface(scene.wall),
        &mut cycle,
        &settings,
        &mut LoopControl::stop_flag(&stop),
        &mut recorder,
        &mut LoopStats::default(),
    );
    (twin, recorder.0, report)
}

#[test]
fn thimble_rests_on_the_wall_at_the_penetration_the_stiffness_predicts() {
    let config = Config::default();
    let scene = videt_assembly::twin_scene::wireman_wall_scene(&config, 42);
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
    let scene = videt_assembly::twin_scene::wireman_wall_scene(&config, 7);
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

/// A live surface whose model is renewed once, at `renew_after` periods.
struct StallingVision {
    wall: videt_control::Plane,
    calls: u64,
    renew_after: u64,
}

impl videt_runtime::snapshot::SurfaceFeed for StallingVision {
    type Surface = videt_control::Plane;
    fn current(&mut self) -> videt_runtime::snapshot::SurfaceView<'_, videt_control::Plane> {
        self.calls += 1;
        let version = if self.calls < self.renew_after { 1 } else { 2 };
        videt_runtime::snapshot::SurfaceView {
            surface: &self.wall,
            version,
            live: true,
            frame_age_ns: None,
        }
    }
}

/// Vision stalls: the surface snapshot stops changing; after `vision.surface_max_age_s` the
/// forces fade to the free-space field over `surface_fade_s`, and come back when a new model
/// arrives.
#[test]
fn a_stale_surface_fades_to_free_space_and_recovers() {
    let mut config = Config::default();
    config.vision.surface_max_age_s = 0.5;
    config.vision.surface_fade_s = 0.2;
    let scene = videt_assembly::twin_scene::wireman_wall_scene(&config, 3);
    let start = scene.twin.plant().position_m();
    let press = Vec3::new(start.x, start.y, scene.wall_z_m + 0.02);
    let mut twin = scene.twin;
    twin.set_operator(VirtualOperator::new(
        vec![
            Waypoint {
                time_s: 0.0,
                target_m: start,
            },
            Waypoint {
                time_s: 0.3,
                target_m: press,
            },
        ],
        200.0,
        6.0,
    ));
    let rig = setup::rig(&config).unwrap();
    let mut cycle = setup::control_cycle(&config, rig, WireZero::default(), true);
    let mut vision = StallingVision {
        wall: scene.wall,
        calls: 0,
        renew_after: 1000,
    };
    start_hardware(&mut twin).unwrap();
    let stop = AtomicBool::new(false);
    let mut recorder = Recorder(Vec::with_capacity(3000));
    // No new model until 1.0 s (stale from 0.5 s), then one: stop at 1.6 s.
    let settings = LoopSettings {
        rate_hz: 1000,
        duration_ns: Some(1_600_000_000),
        max_consecutive_overruns: 10,
    };
    run_control_loop(
        &mut twin,
        &mut vision,
        &mut cycle,
        &settings,
        &mut LoopControl::stop_flag(&stop),
        &mut recorder,
        &mut LoopStats::default(),
    );
    let r = &recorder.0;
    let at = |t: f64| r.iter().find(|x| x.time.as_secs_f64() >= t).unwrap();
    assert!(!at(0.45).surface_stale && at(0.45).in_contact);
    assert!(at(0.6).surface_stale, "stale after the maximum age");
    let faded = at(0.95);
    assert_eq!(faded.force_scale, 0.0, "faded out after the fade time");
    assert!(Vec3::from(faded.desired_force_n).norm() < 1e-9);
    assert!(
        faded
            .tension_setpoint_n
            .iter()
            .all(|&t| (t - config.control.t_min_n).abs() < 1e-9),
        "free-space tensions"
    );
    let recovered = at(1.45);
    assert!(
        !recovered.surface_stale && recovered.force_scale == 1.0,
        "forces back with the new model"
    );
    assert!(recovered.in_contact && Vec3::from(recovered.rendered_force_n).norm() > 1.0);
    // Gradual both ways: per period the scale moves by at most the surface fade's share plus the
    // stop ramp's share (the two compound when the model goes stale again during the stop).
    let max_step = r
        .windows(2)
        .map(|w| (w[1].force_scale - w[0].force_scale).abs())
        .fold(0.0, f64::max);
    let bound = 1e-3 / config.vision.surface_fade_s + 1e-3 / config.control.ramp_down_s;
    assert!(max_step <= bound + 1e-9, "fade step {max_step} > {bound}");
}
