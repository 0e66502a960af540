//! A panic inside the control loop powers the drives off and the service exits non-zero; the
//! session log closes with the fault as the reason.

use std::process::ExitCode;

use videt_config::Config;
use videt_control::Plane;
use videt_runtime::cycle::WireZero;
use videt_runtime::setup;
use videt_runtime::snapshot::{SurfaceFeed, SurfaceView};
use videt_runtime::telemetry::EndReason;
use videt_service::run::{run_service, HardwareReports, SceneLinks, ServiceSettings, EXIT_PANIC};

/// A surface source that fails after a while.
struct FailingFeed {
    wall: Plane,
    calls: u32,
}

impl SurfaceFeed for FailingFeed {
    type Surface = Plane;
    fn current(&mut self) -> SurfaceView<'_, Plane> {
        self.calls += 1;
        assert!(self.calls < 500, "surface source failed");
        SurfaceView {
            surface: &self.wall,
            version: 0,
            live: false,
            frame_age_ns: None,
        }
    }
}

#[test]
fn a_panic_in_the_control_loop_exits_nonzero() {
    let config = Config::default();
    let scene = videt_assembly::twin_scene::wireman_wall_scene(&config, 9);
    let rig = setup::rig(&config).unwrap();
    let cycle = setup::control_cycle(&config, rig, WireZero::default(), true);
    let dir = tempfile::tempdir().unwrap();
    let mut options = ServiceSettings::from_config(config);
    options.socket_path = None;
    options.telemetry_dir = Some(dir.path().to_path_buf());
    options.status_lines = false;
    options.duration_s = Some(60.0);
    let code = run_service(
        scene.twin,
        FailingFeed {
            wall: scene.wall,
            calls: 0,
        },
        cycle,
        &options,
        SceneLinks::default(),
        HardwareReports::default(),
    );
    assert_eq!(code, ExitCode::from(EXIT_PANIC));
    let log_path = std::fs::read_dir(dir.path())
        .unwrap()
        .next()
        .unwrap()
        .unwrap()
        .path();
    let log = videt_runtime::telemetry::read_log(&log_path).unwrap();
    let end = log.end.expect("the log is closed");
    assert_eq!(
        end.reason,
        EndReason::FatalFault("the control loop panicked; drives powered off".into())
    );
    assert_eq!(end.last_cycle, log.records.last().map(|r| r.cycle));
}
