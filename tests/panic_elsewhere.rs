//! A panic in any thread of the service drives the control loop to the safe state (minimum
//! tension, forces ramped out, drives off) and the service exits non-zero; the session log
//! closes with the fault as the reason.

use std::process::ExitCode;
use std::time::Duration;

use videt_config::Config;
use videt_runtime::cycle::WireZero;
use videt_runtime::setup;
use videt_runtime::snapshot::FixedSurface;
use videt_service::run::{run_service, HardwareReports, SceneLinks, ServiceSettings, EXIT_PANIC};

#[test]
fn a_panic_in_another_thread_stops_the_loop_safely_with_a_nonzero_exit() {
    let dir = tempfile::tempdir().unwrap();
    let config = Config::default();
    let scene = videt_assembly::twin_scene::wireman_wall_scene(&config, 9);
    let rig = setup::rig(&config).unwrap();
    let cycle = setup::control_cycle(&config, rig, WireZero::default(), true);
    let mut options = ServiceSettings::from_config(config);
    options.socket_path = None;
    options.telemetry_dir = Some(dir.path().to_path_buf());
    options.status_lines = false;
    options.duration_s = Some(600.0);
    // The twin on its simulated clock: the service runs faster than real time.
    let panicker = std::thread::spawn(|| {
        std::thread::sleep(Duration::from_millis(300));
        panic!("a worker thread fails");
    });
    let code = run_service(
        scene.twin,
        FixedSurface(scene.wall),
        cycle,
        &options,
        SceneLinks::default(),
        HardwareReports::default(),
    );
    assert!(panicker.join().is_err());
    assert_eq!(code, ExitCode::from(EXIT_PANIC));
    let log_path = std::fs::read_dir(dir.path())
        .unwrap()
        .next()
        .unwrap()
        .unwrap()
        .path();
    let log = videt_runtime::telemetry::read_log(&log_path).unwrap();
    let last = log.records.last().unwrap();
    assert_eq!(last.safety.as_str(), "software-fault");
    assert_eq!(last.force_scale, 0.0);
    assert!(
        log.records.last().unwrap().time.as_secs_f64() < 600.0,
        "stopped long before the duration"
    );
    let end = log.end.expect("the log is closed");
    assert_eq!(
        end.reason,
        videt_runtime::telemetry::EndReason::FatalFault(
            "a thread panicked: stopped in the safe state".into()
        )
    );
    assert_eq!(end.last_cycle, Some(last.cycle));
}
