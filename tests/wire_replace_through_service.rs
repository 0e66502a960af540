//! Whole-stack test of wire replacement through the control socket: `videt wire replace N`
//! while `videtd --sim` runs goes through the service, which releases the wire, has the new
//! yarn fitted by its twin's technician, re-homes it, checks its length, re-initializes and
//! renders with the new calibration; a yarn too short changes nothing.

#[path = "common/daemon.rs"]
mod daemon;

use daemon::Daemon;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use videt_config::calibration::Calibration;
use videt_config::Config;
use videt_service::socket::{request, Request};

const GUIDES: &str = "0.02,-0.01;0.40,0.03;0.17,0.31";
const TRUE_GUIDES: [[f64; 2]; 3] = [[0.02, -0.01], [0.40, 0.03], [0.17, 0.31]];

fn p(path: &Path) -> &str {
    path.to_str().unwrap()
}

#[test]
fn videt_wire_replace_runs_in_the_service_and_a_short_yarn_changes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let socket = dir.path().join("videtd.sock");
    let calibration = dir.path().join("calibration.toml");
    let config_path = dir.path().join("videt.toml");
    let mut config = Config::default();
    config.autoinit.wind_speed_m_s = 0.3;
    std::fs::write(&config_path, toml::to_string(&config).unwrap()).unwrap();
    let cfg = p(&config_path);
    let mut daemon =
        Daemon::start_uncalibrated_twin(cfg, GUIDES, p(&calibration), 90, &socket, None);
    daemon.wait_for(10.0, "videtd runs", |s| s.cycles > 200);

    // Replace wire 1 (a new yarn of 0.95 m, enough for this frame): the service does it all on
    // its twin.
    let started = Instant::now();
    let out = Command::new(env!("CARGO_BIN_EXE_videt"))
        .args(["wire", "replace", "1", "--json", "--sim"])
        .args(["--sim-new-wire-length", "0.95"])
        .args(["--config", cfg, "--socket", p(&socket)])
        .stdin(Stdio::null())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    eprintln!(
        "wire replacement through the service took {:.1} s",
        started.elapsed().as_secs_f64()
    );
    for words in [
        "replacing wire 1",
        "wire 1 homed",
        "usable length 0.950 m",
        "winding wire 2",
    ] {
        assert!(stderr.contains(words), "{words}: {stderr}");
    }
    let written = Calibration::load(&calibration).unwrap();
    let text = String::from_utf8(out.stdout).unwrap();
    assert_eq!(text.trim(), videt_tools::tool::init::result_json(&written));
    let t = TRUE_GUIDES;
    let d = |a: [f64; 2], b: [f64; 2]| ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt();
    let truth = [d(t[0], t[1]), d(t[0], t[2]), d(t[1], t[2])];
    for k in 0..3 {
        assert!(
            (written.sides_m[k] - truth[k]).abs() < 0.5e-3,
            "side {k}: {} vs {}",
            written.sides_m[k],
            truth[k]
        );
    }
    daemon.wait_for(10.0, "rendering with the new calibration", |s| {
        s.procedure.is_none() && s.safety == "normal" && s.force_n > 0.5
    });

    // A yarn too short: exit 21, the calibration byte for byte, rendering goes on.
    let before = std::fs::read(&calibration).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_videt"))
        .args([
            "wire",
            "replace",
            "2",
            "--json",
            "--sim",
            "--sim-new-wire-length",
            "0.5",
        ])
        .args(["--config", cfg, "--socket", p(&socket)])
        .stdin(Stdio::null())
        .output()
        .unwrap();
    assert_eq!(
        out.status.code(),
        Some(21),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let failed: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(failed["error"], "wire-too-short", "{failed}");
    assert_eq!(std::fs::read(&calibration).unwrap(), before);
    daemon.wait_for(10.0, "rendering resumes", |s| {
        s.procedure.is_none() && s.safety == "normal" && s.force_n > 0.5
    });

    let r = request(&socket, &Request::Stop, Duration::from_secs(2)).unwrap();
    assert!(r.ok);
    assert!(daemon.wait().success());
}
