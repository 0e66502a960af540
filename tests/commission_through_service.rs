//! `videt commission` while `videtd --sim` runs: the service's control thread runs the rig's
//! check on its own (real-time) twin, the tool prints the same report a direct run does. A
//! configuration that reverses an encoder the twin has the right way round is found, named with
//! its fix, and keeps the service's drives off; `--write` fixes the copy, and the service started
//! with it passes the check and renders forces again afterwards.

#[path = "common/daemon.rs"]
mod daemon;

use daemon::Daemon;

use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::Duration;

fn p(path: &Path) -> &str {
    path.to_str().unwrap()
}

fn commission(config: &Path, socket: &Path, write: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_videt"))
        .args(["commission", "--json", "--only", "rig", "--config"])
        .arg(config)
        .arg("--socket")
        .arg(socket)
        .arg("--write")
        .arg(write)
        .stdin(Stdio::null())
        .output()
        .expect("videt runs")
}

fn report(out: &Output) -> serde_json::Value {
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "{e}: {}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        )
    })
}

/// `videtd --sim SIM` (`hal`: the HAL twin; `can`: behind simulated CiA 402 drives).
fn start(sim: &str, config: &Path, socket: &Path) -> Daemon {
    let daemon = Daemon::start(
        &[
            "--sim",
            sim,
            "--config",
            p(config),
            "--no-telemetry",
            "--duration",
            "120",
        ],
        socket,
    );
    daemon.wait_for(10.0, "videtd runs", |s| s.cycles > 300);
    daemon
}

#[test]
fn the_service_checks_its_own_rig_keeps_a_wrong_one_off_and_renders_again_once_fixed() {
    let dir = tempfile::tempdir().unwrap();
    let example = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/config/videt.example.toml"
    ))
    .unwrap();
    let right = "encoder_reversed = [false, false, false]";
    assert!(example.contains(right), "the example configuration changed");
    let wrong = dir.path().join("videt.toml");
    std::fs::write(
        &wrong,
        example.replace(right, "encoder_reversed = [false, false, true]"),
    )
    .unwrap();
    let fixed = dir.path().join("fixed.toml");
    let socket = dir.path().join("videtd.sock");

    // The twin is built right: the configuration's reversal of encoder 2 is the mistake.
    let daemon = start("hal", &wrong, &socket);
    let out = commission(&wrong, &socket, &fixed);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(27), "{stderr}");
    assert!(
        stderr.contains("runs the procedure on its digital twin"),
        "{stderr}"
    );
    let found = report(&out);
    let steps = found["steps"].as_array().unwrap();
    let failed: Vec<&str> = steps
        .iter()
        .filter(|s| s["result"] == "fail")
        .map(|s| s["name"].as_str().unwrap())
        .collect();
    assert_eq!(failed, ["drive2.encoder"], "{found}");
    // The HAL twin has no CANopen drives to identify.
    assert_eq!(steps[0]["name"], "drives.identity", "{found}");
    assert_eq!(steps[0]["result"], "skipped", "{found}");
    assert_eq!(
        found["fixes"],
        serde_json::json!(["drives.encoder_reversed[2] = false"])
    );
    assert_eq!(steps.len(), 18, "{found}");
    // Not as configured: the service keeps its drives off.
    let s = daemon.wait_for(5.0, "the drives stay off", |s| s.power_off);
    assert_eq!(s.safety, "drive-fault", "{s:?}");
    let cause = s.fault.clone().unwrap_or_default();
    assert!(
        cause.contains("not as configured (drive2.encoder)"),
        "{s:?}"
    );
    std::thread::sleep(Duration::from_millis(500));
    let s = daemon.status();
    // No motor pulls: the wires hang slack.
    assert!(
        s.power_off && s.tensions_n.iter().all(|t| t.abs() < 0.3),
        "{s:?}"
    );
    drop(daemon);

    // The copy with the fix, its comments kept.
    let text = std::fs::read_to_string(&fixed).unwrap();
    assert!(text.contains(right), "{text}");
    let comments = |t: &str| {
        t.lines()
            .filter(|l| l.trim_start().starts_with('#'))
            .count()
    };
    assert_eq!(comments(&text), comments(&example));

    // Started with it (behind simulated CiA 402 drives this time, whose drivers apply the
    // configuration's directions), the service passes the check and renders again: the thimble
    // back on the wires, the operator touching the wall.
    let _ = std::fs::remove_file(&socket);
    let daemon = start("can", &fixed, &socket);
    let again = dir.path().join("again.toml");
    let out = commission(&fixed, &socket, &again);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let found = report(&out);
    assert!(
        found["steps"]
            .as_array()
            .unwrap()
            .iter()
            .all(|s| s["result"] == "pass"),
        "{found}"
    );
    // Each drive answered at its node id with a CiA 402 identity.
    for wire in 0..3 {
        let name = format!("drive{wire}.identity");
        let step = found["steps"]
            .as_array()
            .unwrap()
            .iter()
            .find(|s| s["name"] == name.as_str())
            .unwrap_or_else(|| panic!("{name}: {found}"));
        assert!(
            step["measured"]
                .as_str()
                .unwrap()
                .contains(&format!("node {} answers", wire + 1)),
            "{step}"
        );
    }
    daemon.wait_for(10.0, "rendering resumes", |s| {
        s.procedure.is_none() && s.safety == "normal" && !s.power_off && s.force_n > 0.5
    });
}
