//! Whole-stack test through the real CANopen drive driver: the control loop drives the twin's
//! motors via three simulated CiA 402 nodes (what `videtd --sim can` runs), here with the nodes
//! answering inline and the twin on its simulated clock, so the test is deterministic and does
//! not depend on the machine's scheduling. The simulated drives have the configured drive's
//! rated torque, from its device description when the configuration names one.

mod common;
use common::Recorder;
use std::path::Path;
use std::sync::atomic::AtomicBool;
use videt_assembly::WiremanTwin as Twin;
use videt_runtime::WIREMAN_WIRES;

use videt_assembly::can_twin::{drive_config, CanTwin};
use videt_config::Config;
use videt_control::safety::SafetyState;
use videt_hal::{DriveSample, WireDrives};
use videt_runtime::control_loop::{
    run_control_loop, start_hardware, LoopControl, LoopSettings, LoopStats,
};
use videt_runtime::cycle::WireZero;
use videt_runtime::setup;
use videt_sim::cia402_node::DrivePower;
use videt_sim::{Vec3, VirtualOperator, Waypoint};

#[test]
fn the_wall_is_rendered_through_cia402_drives_on_the_can_bus() {
    render_the_wall(&Config::default(), 0.0);
}

/// A drive of 40 mN·m rated torque and a 2000-count encoder, as its device description says:
/// the twin's generic CiA 402 drive with its position encoder resolution (0x608F).
fn drive_eds() -> String {
    let generic = videt_sim::cia402_node::DriveDictionary::generic(40).to_eds("Example");
    format!(
        "{generic}[608F]\nObjectType=0x9\nSubNumber=3\n\n[608Fsub0]\nDataType=0x0005\n\
         AccessType=const\nDefaultValue=2\n\n[608Fsub1]\nDataType=0x0007\nAccessType=rw\n\
         DefaultValue=2000\n\n[608Fsub2]\nDataType=0x0007\nAccessType=rw\nDefaultValue=1\n"
    )
}

/// A configuration file beside a device description.
fn configured_drive(dir: &Path, description: &str, body: &str) -> Config {
    std::fs::write(dir.join("drive.eds"), description).unwrap();
    let path = dir.join("videt.toml");
    std::fs::write(
        &path,
        format!("[drives]\ndevice_description = \"drive.eds\"\n{body}"),
    )
    .unwrap();
    Config::load(&path).unwrap()
}

/// Command `torque_nm` for a few periods and return what the motors apply.
fn applied<H: WireDrives<WIREMAN_WIRES>>(
    hw: &mut H,
    torque_nm: [f64; WIREMAN_WIRES],
    twin: fn(&H) -> &Twin,
) -> [f64; WIREMAN_WIRES] {
    let mut out = [DriveSample::default(); WIREMAN_WIRES];
    for _ in 0..3 {
        hw.write_torques(&torque_nm).ok().unwrap();
        hw.read_drives(&mut out).ok().unwrap();
    }
    twin(hw).applied_torque_nm()
}

#[test]
fn the_can_twin_s_drives_have_the_rated_torque_of_the_device_description() {
    let dir = tempfile::tempdir().unwrap();
    let config = configured_drive(dir.path(), &drive_eds(), "");
    assert_eq!(config.drives.rated_torque_nm, 0.04);
    let drives = drive_config::<3>(&config);
    assert_eq!(drives.rated_torque_nm, 0.04);
    // One step of 40 µN·m: the CAN twin's drives and the HAL twin apply the same torques.
    let step = setup::twin_torque_step_nm(&config);
    assert!((step - 40e-6).abs() < 1e-15);
    let command = [0.00123, 0.00071, 0.00051];
    let expected = [0.00124, 0.00072, 0.00052];
    let mut can = can_twin(&config);
    start_hardware(&mut can).unwrap();
    let through_can = applied(&mut can, command, |h| h.twin());
    let mut hal = videt_assembly::twin_scene::wireman_wall_scene(&config, 42).twin;
    start_hardware(&mut hal).unwrap();
    let through_hal = applied(&mut hal, command, |t| t);
    for i in 0..WIREMAN_WIRES {
        assert!(
            (through_can[i] - expected[i]).abs() < 1e-12,
            "CAN twin: {through_can:?}"
        );
        assert!(
            (through_hal[i] - expected[i]).abs() < 1e-12,
            "HAL twin: {through_hal:?}"
        );
    }
    // And the stack renders the wall through them.
    render_the_wall(&config, 0.0);
}

#[test]
fn the_can_twin_renders_the_wall_with_the_epos4_of_a_real_dcf() {
    let Some(data) = videt_testdata::data_dir("canopen/eds") else {
        return;
    };
    let name = "epos4_50_15_can_ec90flat_gp52c_mile800_node1.dcf";
    let dir = tempfile::tempdir().unwrap();
    let description = std::fs::read_to_string(data.join(name)).unwrap();
    // One per mille of this 0.51 N·m motor is 0.667 N on the wire: the minimum tension is
    // raised above it.
    let config = configured_drive(
        dir.path(),
        &description,
        "[control]\nt_min_n = 0.7\n[autoinit]\npay_out_tension_n = 0.8\n",
    );
    assert_eq!(config.transmission.gear_ratio, 26.0);
    assert_eq!(config.transmission.counts_per_motor_rev, 3200);
    // The HAL twin's motors step in whole mN·m; the CAN twin's drives are the DCF's EPOS4:
    // its rated torque in µN·m.
    assert_eq!(setup::twin_rated_torque_mnm(&config), 513);
    assert_eq!(drive_config::<3>(&config).rated_torque_nm, 0.512871);
    // Each wire's tension is held to within half a step: the contact force to within 1.5 steps.
    let force_resolution_n = 1.5 * config.torque_step_tension_n();
    render_the_wall(
        &config,
        force_resolution_n / config.control.stiffness_n_per_m,
    );
}

fn can_twin(config: &Config) -> CanTwin<3, Twin> {
    // Simulated time runs faster than the nodes' real-time heartbeats: widen the host's
    // heartbeat tolerance accordingly.
    let mut drives = drive_config(config);
    drives.drive_heartbeat_timeout = std::time::Duration::from_secs(5);
    CanTwin::stepped(
        videt_assembly::twin_scene::wireman_wall_scene(config, 42).twin,
        drives,
        videt_assembly::drive_dictionary::for_config(config).unwrap(),
    )
    .unwrap()
}

/// The operator presses into the check wall through the CAN twin; the penetration is the one
/// the stiffness predicts (within 15 %, plus `resolution_m` for drives whose torque steps are
/// coarse) and the drives end powered off.
fn render_the_wall(config: &Config, resolution_m: f64) {
    let config = config.clone();
    let mut scene = videt_assembly::twin_scene::wireman_wall_scene(&config, 42);
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
    let dictionary = videt_assembly::drive_dictionary::for_config(&config).unwrap();
    let mut hw = CanTwin::stepped(scene.twin, drives, dictionary).unwrap();
    assert_eq!(hw.twin().torque_step_nm(), None, "the drives quantize");
    start_hardware(&mut hw).unwrap();
    assert!(hw
        .drive_nodes()
        .iter()
        .all(|v| v.power == DrivePower::OperationEnabled));
    let mut recorder = Recorder(Vec::with_capacity(4000));
    let stop = AtomicBool::new(false);
    let report = run_control_loop(
        &mut hw,
        &mut videt_runtime::snapshot::FixedSurface(scene.wall),
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
        (penetration - predicted).abs() <= 0.15 * predicted + resolution_m,
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
