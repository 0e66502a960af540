//! Whole-stack test through the real CANopen drive driver: the control loop drives the twin's
//! motors via three simulated CiA 402 nodes (what `videtd --sim can` runs), here with the nodes
//! answering inline and the twin on its simulated clock, so the test is deterministic and does
//! not depend on the machine's scheduling.

mod common;
use common::Recorder;
use std::sync::atomic::AtomicBool;

use videt::can_twin::{drive_config, CanTwin};
use videt::control_loop::{run_control_loop, start_hardware, LoopControl, LoopSettings, LoopStats};
use videt::cycle::WireZero;
use videt::setup;
use videt_control::safety::SafetyState;
use videt_rt_config::Config;
use videt_sim::cia402_node::DrivePower;
use videt_sim::{Vec3, VirtualOperator, Waypoint};

#[test]
fn the_wall_is_rendered_through_cia402_drives_on_the_can_bus() {
    let config = Config::default();
    let mut scene = setup::demo_scene(&config, 42);
    let start = scene.twin.plant().position_m();
    let wall_z = scene.wall_z_m;
    let press = Vec3::new(start.x, start.y, wall_z + 0.02);
    scene.twin.set_operator(VirtualOperator::new(
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
    ));
    let rig = setup::rig(&config).unwrap();
    let mut cycle = setup::control_cycle(&config, rig, WireZero::default(), true);
    let settings = LoopSettings {
        rate_hz: config.control.rate_hz,
        duration_ns: Some(2_000_000_000),
        max_consecutive_overruns: 10,
    };
    // Simulated time runs faster than the nodes' real-time heartbeats: widen the host's
    // heartbeat tolerance accordingly.
    let mut drives = drive_config(&config);
    drives.drive_heartbeat_timeout = std::time::Duration::from_secs(5);
    let mut hw = CanTwin::stepped(scene.twin, drives).unwrap();
    start_hardware(&mut hw).unwrap();
    assert!(hw
        .drive_nodes()
        .iter()
        .all(|v| v.power == DrivePower::OperationEnabled));
    let mut recorder = Recorder(Vec::with_capacity(4000));
    let stop = AtomicBool::new(false);
    let report = run_control_loop(
        &mut hw,
        &mut videt::snapshot::FixedSurface(scene.wall),
        &mut cycle,
        &settings,
        &mut LoopControl::stop_flag(&stop),
        &mut recorder,
        &mut LoopStats::default(),
    );
    let first_trip = recorder.0.iter().find(|r| r.safety != SafetyState::Normal);
    assert_eq!(
        report.final_safety,
        SafetyState::Normal,
        "drive error: {:?}, first trip at {:?}",
        hw.drive_error(),
        first_trip.map(|r| r.time)
    );
    let records = recorder.0;
    let before_stop = records
        .iter()
        .rev()
        .find(|r| r.force_scale >= 1.0 && r.time.as_secs_f64() < 2.0)
        .unwrap();
    let penetration = before_stop.position_m[2] - wall_z;
    let hand_push_n = 200.0 * (press.z - before_stop.position_m[2]);
    let predicted = hand_push_n / config.control.stiffness_n_per_m;
    eprintln!(
        "through CAN: penetration {:.3} mm, predicted {:.3} mm, {} cycles, {} overruns",
        penetration * 1e3,
        predicted * 1e3,
        report.cycles,
        report.overruns
    );
    assert!(
        (penetration - predicted).abs() <= 0.15 * predicted,
        "penetration {:.3} mm, predicted {:.3} mm",
        penetration * 1e3,
        predicted * 1e3
    );
    // The loop shut down cleanly: the drives are off.
    assert!(hw
        .drive_nodes()
        .iter()
        .all(|v| v.power != DrivePower::OperationEnabled && v.applied_torque_nm == 0.0));
}
