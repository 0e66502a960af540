//! `videt commission` as a technician runs it on the twin: a rig built with a reversed motor
//! and swapped cameras is checked, each mistake named with its fix in the JSON report and the
//! exit code; `--write` puts the fixes into a copy of the configuration, comments kept; with
//! that copy the check passes and `videt init` succeeds.

#[path = "common/chessboard.rs"]
mod chessboard;

use chessboard::calibrated_chessboard;
use std::path::Path;
use std::process::{Command, Output};

fn videt(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_videt"))
        .args(args)
        .output()
        .unwrap()
}

fn text(out: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

/// The example configuration with the chessboard set's calibration (written by
/// `videt calibrate-stereo` into `dir`) as the installed one.
fn configuration(dir: &Path) -> Option<(String, std::path::PathBuf)> {
    let (images, calibration) = calibrated_chessboard(dir)?;
    let example = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/config/videt.example.toml"
    ))
    .unwrap();
    let line = "stereo_calibration = \"/etc/videt/stereo.json\"";
    assert!(example.contains(line));
    let config = dir.join("videt.toml");
    std::fs::write(
        &config,
        example.replace(
            line,
            &format!(
                "stereo_calibration = {:?}",
                calibration.display().to_string()
            ),
        ),
    )
    .unwrap();
    Some((images.display().to_string(), config))
}

#[test]
fn the_check_names_each_mistake_writes_the_fixes_and_then_init_succeeds() {
    let dir = tempfile::tempdir().unwrap();
    let Some((images, config)) = configuration(dir.path()) else {
        return;
    };
    let fixed = dir.path().join("fixed.toml");
    let calibration = dir.path().join("calibration.toml");
    let config = config.to_str().unwrap();
    let mistakes = [
        "--sim-fault",
        "reversed-motor:1",
        "--sim-fault",
        "swapped-cameras",
    ];
    let check = |config: &str, extra: &[&str]| {
        let mut args = vec![
            "commission",
            "--sim",
            "--yes",
            "--json",
            "--config",
            config,
            "--sim-cameras",
            &images,
        ];
        args.extend_from_slice(&mistakes);
        args.extend_from_slice(extra);
        videt(&args)
    };
    let out = check(config, &["--write", fixed.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(27), "{}", text(&out));
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let fixes: Vec<&str> = report["fixes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f.as_str().unwrap())
        .collect();
    assert_eq!(
        fixes,
        [
            "drives.motor_reversed[1] = true",
            "vision.devices = [\"/dev/video2\", \"/dev/video0\"]"
        ],
        "{report:#}"
    );
    let failed: Vec<&str> = report["steps"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|s| s["result"] == "fail")
        .map(|s| s["name"].as_str().unwrap())
        .collect();
    assert_eq!(failed, ["drive1.direction", "cameras.order"]);
    assert_eq!(report["exit_code"], 27);
    // The copy keeps the configuration's comments; the original is untouched.
    let written = std::fs::read_to_string(&fixed).unwrap();
    assert!(written.contains("# Per wire: a positive torque unwinds the wire"));
    assert!(written.contains("motor_reversed = [false, true, false]"));
    assert!(!std::fs::read_to_string(config)
        .unwrap()
        .contains("motor_reversed = [false, true, false]"));

    let out = check(fixed.to_str().unwrap(), &[]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    let mut init = vec![
        "init",
        "--sim",
        "--yes",
        "--config",
        fixed.to_str().unwrap(),
        "--calibration",
        calibration.to_str().unwrap(),
    ];
    init.extend_from_slice(&mistakes[..2]);
    let out = videt(&init);
    assert!(out.status.success(), "{}", text(&out));
    // Without the fixes, the same rig fails to initialize.
    init[4] = config;
    let out = videt(&init);
    assert!(!out.status.success(), "{}", text(&out));
}

#[test]
fn a_wire_that_does_not_exist_is_a_usage_error_and_the_twin_skips_the_computer() {
    let out = videt(&[
        "commission",
        "--sim",
        "--yes",
        "--sim-fault",
        "reversed-motor:7",
    ]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out));
    assert!(text(&out).contains("wire \"7\" must be 0, 1 or 2"));
    // A twin built right, with the built-in configuration: every part passes or is skipped
    // (no computer, CANopen drives, fingertips or cameras on the twin).
    let out = videt(&["commission", "--sim", "--yes"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    let stdout = String::from_utf8_lossy(&out.stdout);
    for skipped in [
        "SKIPPED  computer",
        "SKIPPED  drives.identity",
        "SKIPPED  vibrotactors",
        "SKIPPED  cameras",
    ] {
        assert!(stdout.contains(skipped), "{skipped}: {stdout}");
    }
    assert!(
        stdout.contains("17 passed, 0 failed, 4 skipped"),
        "{stdout}"
    );
}
