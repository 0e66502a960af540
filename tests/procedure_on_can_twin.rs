//! Whole-stack test of a service procedure through the real CANopen drive driver: the control
//! loop renders the wall through three simulated CiA 402 drives, hands the hardware over,
//! auto-initialization runs on the control thread through the same driver, and rendering
//! resumes with the measured rig and encoder zeros, the tension loops tracking their
//! set-points again. The nodes answer inline and the twin runs on its simulated clock, so the
//! test is deterministic.

mod common;
use common::Recorder;
use std::sync::atomic::{AtomicBool, Ordering};

use videt_assembly::can_twin::{drive_config, CanTwin};
use videt_config::Config;
use videt_control::safety::SafetyState;
use videt_runtime::control_loop::{
    run_control_loop, start_hardware, ControlCommand, LoopControl, LoopSettings, LoopStats,
};
use videt_runtime::cycle::WireZero;
use videt_runtime::setup;
use videt_service::init::procedure_port::{procedure_channel, saved, ProcedureKind, ProcedureSpec};
use videt_service::init::remote::run_procedure;

#[test]
fn rendering_resumes_through_cia402_drives_after_auto_initialization() {
    let config = Config::default();
    let scene = videt_assembly::twin_scene::wireman_wall_scene(&config, 7);
    let wall = scene.wall;
    let rig = setup::rig(&config).unwrap();
    let mut cycle = setup::control_cycle(&config, rig, WireZero::default(), true);
    let settings = LoopSettings {
        rate_hz: config.control.rate_hz,
        duration_ns: Some(3_000_000_000),
        max_consecutive_overruns: 10,
    };
    let mut drives = drive_config(&config);
    drives.drive_heartbeat_timeout = std::time::Duration::from_secs(5);
    let mut hw = CanTwin::stepped(scene.twin, drives, None).unwrap();
    start_hardware(&mut hw).unwrap();
    let stop = AtomicBool::new(false);

    // The client's side: an initialization with the manual steps confirmed, whose result the
    // client has saved by the time the control thread asks.
    let calibration = std::env::temp_dir().join("videt-procedure-on-can-twin.toml");
    let (port, mut handle) = procedure_channel(config.clone(), calibration, true);
    let mut session = port.begin().unwrap();
    session.submit(ProcedureSpec {
        kind: ProcedureKind::Initialize,
        yes: true,
        sim_seed: 3,
        sim_faults: Vec::new(),
        sim_new_wire_length_m: None,
    });
    session
        .control()
        .saved
        .store(saved::SAVED, Ordering::Release);

    // Render a second, then hand over.
    let (mut commands_in, mut commands) = rtrb::RingBuffer::new(4);
    let mut before = Recorder(Vec::with_capacity(4000));
    let first = LoopSettings {
        duration_ns: Some(1_000_000_000),
        ..settings
    };
    let report = run_control_loop(
        &mut hw,
        &mut videt_runtime::snapshot::FixedSurface(wall),
        &mut cycle,
        &first,
        &mut LoopControl::stop_flag(&stop),
        &mut before,
        &mut LoopStats::default(),
    );
    assert_eq!(report.final_safety, SafetyState::Normal);
    // The timed run switched the drives off: bring them up again, then hand over at once.
    start_hardware(&mut hw).unwrap();
    commands_in.push(ControlCommand::HandOver).unwrap();
    let mut handing = Recorder(Vec::with_capacity(4000));
    let report = run_control_loop(
        &mut hw,
        &mut videt_runtime::snapshot::FixedSurface(wall),
        &mut cycle,
        &settings,
        &mut LoopControl {
            stop: &stop,
            commands: Some(&mut commands),
        },
        &mut handing,
        &mut LoopStats::default(),
    );
    assert!(report.handed_over, "the loop handed the hardware over");

    let mut procedure = Recorder(Vec::with_capacity(1));
    let end = run_procedure(
        &mut hw,
        &mut handle,
        &config,
        &mut procedure,
        cycle.cycle_count(),
        cycle.wire_zero(),
        SafetyState::Normal,
    );
    let mut measured = None;
    while let Some(event) = session.next_event() {
        if let videt_service::init::procedure_port::ProcedureEvent::Finished(result) = event {
            measured = Some(result.expect("the procedure measured the rig"));
        }
    }
    assert!(measured.is_some(), "the client heard the result");
    let (recalibration, next_cycle) = (end.recalibration, end.next_cycle);
    assert_eq!(
        end.trip, None,
        "an initialization keeps the service's safety state"
    );
    let recalibration = recalibration.expect("a saved result recalibrates the service");
    // Guide points within 1 mm of the twin's (the configured frame, the paper's).
    for (measured, truth) in recalibration
        .rig
        .guides_m()
        .iter()
        .zip(&config.rig.guides_m)
    {
        let error = ((measured[0] - truth[0]).powi(2) + (measured[1] - truth[1]).powi(2)).sqrt();
        assert!(error < 1e-3, "guide {measured:?}, truth {truth:?}");
    }

    // Rendering resumes with the new calibration.
    let mut cycle = setup::control_cycle(&config, recalibration.rig, recalibration.wire_zero, true);
    cycle.set_cycle_count(next_cycle);
    let mut after = Recorder(Vec::with_capacity(4000));
    let report = run_control_loop(
        &mut hw,
        &mut videt_runtime::snapshot::FixedSurface(wall),
        &mut cycle,
        &settings,
        &mut LoopControl::stop_flag(&stop),
        &mut after,
        &mut LoopStats::default(),
    );
    assert_eq!(
        report.final_safety,
        SafetyState::Normal,
        "drive error: {:?}",
        hw.drive_error()
    );
    // The last second at full force, once the operator's push back in has settled: every
    // tension within 0.3 N of its set-point (median) and the wall felt.
    let t0 = after.0[0].time.as_secs_f64();
    let settled: Vec<_> = after
        .0
        .iter()
        .filter(|r| {
            let t = r.time.as_secs_f64() - t0;
            r.force_scale >= 1.0 && (2.0..2.9).contains(&t)
        })
        .collect();
    assert!(settled.len() > 500, "{} settled periods", settled.len());
    let mut errors: Vec<f64> = settled
        .iter()
        .flat_map(|r| (0..3).map(|i| (r.tension_measured_n[i] - r.tension_setpoint_n[i]).abs()))
        .collect();
    errors.sort_by(f64::total_cmp);
    let median = errors[errors.len() / 2];
    let worst = errors[errors.len() * 99 / 100];
    let in_contact = settled.iter().filter(|r| r.in_contact).count();
    eprintln!(
        "after the procedure: tension error median {median:.3} N, p99 {worst:.3} N, in contact {in_contact} of {} periods",
        settled.len()
    );
    assert!(
        median < 0.3 && worst < 1.5,
        "median {median} N, p99 {worst} N"
    );
    assert!(in_contact * 2 > settled.len(), "the wall is felt again");
}
