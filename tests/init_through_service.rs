//! Whole-stack test of auto-initialization through the control socket: `videtd --sim` runs on a
//! twin whose frame the test chooses; `videt init` goes through the service's socket and the
//! service runs the procedure on its own (real-time) twin, writes the calibration, and renders
//! forces with it. A failure, a second request and a client that leaves change nothing.

#[path = "common/daemon.rs"]
mod daemon;
#[path = "common/init_json.rs"]
mod init_json;

use daemon::Daemon;

use std::io::{BufRead, BufReader, Write};
use std::os::unix::net::UnixStream;
use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use videt_config::calibration::{backup_path, Calibration};
use videt_config::Config;
use videt_service::socket::{request, Request};

const GUIDES: &str = "-0.05,0.02;0.33,-0.03;0.12,0.29";
const TRUE_GUIDES: [[f64; 2]; 3] = [[-0.05, 0.02], [0.33, -0.03], [0.12, 0.29]];

fn p(path: &Path) -> &str {
    path.to_str().unwrap()
}

fn videt(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_videt"))
        .args(args)
        .stdin(Stdio::null())
        .output()
        .expect("videt runs")
}

/// The sides and the guides (paper's frame) `json` reports are within 0.5 mm / 1 mm of the truth.
fn check_against_truth(json: &serde_json::Value) {
    init_json::assert_matches_truth(json, TRUE_GUIDES);
}

#[test]
fn videtd_auto_initializes_its_own_twin_for_videt_init_through_the_socket() {
    let dir = tempfile::tempdir().unwrap();
    let socket = dir.path().join("videtd.sock");
    let calibration = dir.path().join("state").join("calibration.toml");
    let direct_calibration = dir.path().join("direct").join("calibration.toml");
    // Wind quickly: the service's twin runs in real time.
    let config_path = dir.path().join("videt.toml");
    let mut config = Config::default();
    config.autoinit.wind_speed_m_s = 0.25;
    std::fs::write(&config_path, toml::to_string(&config).unwrap()).unwrap();
    let cfg = p(&config_path);

    // A previous calibration (measured by a direct run on a private twin of the same frame).
    let out = videt(&[
        "init",
        "--sim",
        "--json",
        "--config",
        cfg,
        "--sim-guides",
        GUIDES,
        "--calibration",
        p(&calibration),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let previous = std::fs::read(&calibration).unwrap();

    // The service on a twin of that frame, not calibrated: no force rendered.
    let logs = dir.path().join("logs");
    let mut daemon =
        Daemon::start_uncalibrated_twin(cfg, GUIDES, p(&calibration), 120, &socket, Some(&logs));
    daemon.wait_for(10.0, "videtd runs uncalibrated", |s| {
        s.cycles > 200 && s.safety == "not-calibrated"
    });

    // `videt init` goes through the socket: the service measures its own twin. Meanwhile a
    // second request is refused as busy.
    let started = Instant::now();
    let init = Command::new(env!("CARGO_BIN_EXE_videt"))
        .args(["init", "--json", "--config", cfg, "--socket", p(&socket)])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    daemon.wait_for(10.0, "the procedure runs", |s| {
        s.procedure.as_deref() == Some("init")
    });
    let busy = request_line(&socket, r#"{"cmd":"init"}"#);
    assert_eq!(busy["ok"], false, "{busy}");
    assert!(
        busy["error"].as_str().unwrap().starts_with("busy"),
        "{busy}"
    );
    let out = init.wait_with_output().unwrap();
    let took_s = started.elapsed().as_secs_f64();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("runs the procedure on its digital twin"),
        "{stderr}"
    );
    assert!(stderr.contains("winding wire 2"), "{stderr}");
    eprintln!("auto-initialization through the service took {took_s:.1} s");

    // The same document a direct run prints, for the calibration the service wrote; the
    // previous file kept as its backup.
    let text = String::from_utf8(out.stdout).unwrap();
    let written = Calibration::load(&calibration).unwrap();
    assert_eq!(text.trim(), videt_tools::tool::init::result_json(&written));
    let json: serde_json::Value = serde_json::from_str(text.trim()).unwrap();
    assert_eq!(json.as_object().unwrap().len(), 3, "{text}");
    check_against_truth(&json);
    assert_eq!(written.source, "twin");
    assert_eq!(std::fs::read(backup_path(&calibration)).unwrap(), previous);
    let current = std::fs::read(&calibration).unwrap();
    assert_ne!(current, previous);

    // The service renders forces with it: calibrated, no safe state, the operator feels the wall.
    daemon.wait_for(10.0, "rendering resumes", |s| {
        s.procedure.is_none() && s.safety == "normal" && !s.power_off && s.force_n > 0.5
    });

    // A failure (wire 2 not connected): the same error as a direct run; nothing lost; the
    // service keeps rendering with its calibration.
    let out = videt(&[
        "init",
        "--json",
        "--sim",
        "--sim-fault",
        "disconnected:2",
        "--config",
        cfg,
        "--socket",
        p(&socket),
    ]);
    let direct = videt(&[
        "init",
        "--json",
        "--sim",
        "--sim-fault",
        "disconnected:2",
        "--config",
        cfg,
        "--sim-guides",
        GUIDES,
        "--calibration",
        p(&direct_calibration),
    ]);
    assert_eq!(
        out.status.code(),
        Some(12),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(out.status.code(), direct.status.code());
    let failed: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let failed_direct: serde_json::Value = serde_json::from_slice(&direct.stdout).unwrap();
    assert_eq!(failed["error"], "wire-not-connected", "{failed}");
    assert_eq!(failed["error"], failed_direct["error"]);
    assert_eq!(failed["exit_code"], failed_direct["exit_code"]);
    let message = failed["message"].as_str().unwrap();
    assert!(message.contains("wire 2 never moved"), "{message}");
    assert!(
        message.ends_with(&format!(
            "the previous calibration ({}) is unchanged",
            calibration.display()
        )),
        "{message}"
    );
    assert_eq!(
        std::fs::read(&calibration).unwrap(),
        current,
        "byte for byte"
    );
    assert_eq!(std::fs::read(backup_path(&calibration)).unwrap(), previous);
    daemon.wait_for(10.0, "rendering resumes after the failure", |s| {
        s.procedure.is_none() && s.safety == "normal" && s.force_n > 0.5
    });

    // A client that leaves mid-procedure aborts it; nothing changes.
    {
        let mut stream = UnixStream::connect(&socket).unwrap();
        stream.write_all(b"{\"cmd\":\"init\"}\n").unwrap();
        stream
            .set_read_timeout(Some(Duration::from_secs(10)))
            .unwrap();
        let mut lines = BufReader::new(stream.try_clone().unwrap()).lines();
        let mut prompt_seen = false;
        while !prompt_seen {
            let line = lines.next().expect("a line").unwrap();
            let v: serde_json::Value = serde_json::from_str(&line).unwrap();
            assert_eq!(v["ok"], true, "{v}");
            prompt_seen = v["event"] == "prompt";
        }
    }
    daemon.wait_for(10.0, "the abandoned procedure ends", |s| {
        s.procedure.is_none() && s.safety == "normal" && s.force_n > 0.5
    });
    assert_eq!(std::fs::read(&calibration).unwrap(), current);

    let r = request(&socket, &Request::Stop, Duration::from_secs(2)).unwrap();
    assert!(r.ok);
    let status = daemon.wait();
    assert!(status.success(), "videtd stopped cleanly: {status:?}");

    // The session replays bit for bit across the re-initialization (the new calibration is in
    // the log), the failed and the abandoned procedures (skipped, rendering restarted).
    let log = std::fs::read_dir(&logs)
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.extension().is_some_and(|x| x == "vlog"))
        .expect("a session log");
    let out = videt(&["replay", p(&log)]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{text}");
    assert!(text.contains("identical"), "{text}");
    assert!(text.contains("procedure periods"), "{text}");
    let log = videt_runtime::telemetry::read_log(&log).unwrap();
    assert_eq!(log.calibrations.len(), 2, "at start, and the new one");
    assert!(!log.calibrations[0].calibration.calibrated);
    assert!(log.calibrations[1].calibration.calibrated);
}

/// Send one line, read one reply line.
fn request_line(socket: &Path, line: &str) -> serde_json::Value {
    let mut stream = UnixStream::connect(socket).unwrap();
    stream
        .set_read_timeout(Some(Duration::from_secs(5)))
        .unwrap();
    stream.write_all(line.as_bytes()).unwrap();
    stream.write_all(b"\n").unwrap();
    let mut reply = String::new();
    BufReader::new(stream).read_line(&mut reply).unwrap();
    serde_json::from_str(&reply).unwrap()
}
