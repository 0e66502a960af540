//! Whole-stack tests of the `videt` tool on the digital twin: `init`, `wire replace`,
//! `tension-calibrate` and `status` as a technician runs them, with the exit codes, the JSON, the
//! calibration file and its backup, and the motors lock.

#[path = "common/init_json.rs"]
mod init_json;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use videt_service::init::MotorsLock;

fn videt(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_videt"))
        .args(args)
        .output()
        .expect("videt runs")
}

struct Files {
    _dir: tempfile::TempDir,
    calibration: PathBuf,
    lock: PathBuf,
}

fn files() -> Files {
    let dir = tempfile::tempdir().unwrap();
    Files {
        calibration: dir.path().join("state").join("calibration.toml"),
        lock: dir.path().join("run").join("motors.lock"),
        _dir: dir,
    }
}

fn p(path: &Path) -> &str {
    path.to_str().unwrap()
}

const GUIDES: &str = "-0.05,0.02;0.33,-0.03;0.12,0.29";
const TRUE_GUIDES: [[f64; 2]; 3] = [[-0.05, 0.02], [0.33, -0.03], [0.12, 0.29]];

fn init(f: &Files, extra: &[&str]) -> Output {
    let mut args = vec![
        "init",
        "--sim",
        "--json",
        "--sim-guides",
        GUIDES,
        "--calibration",
        p(&f.calibration),
        "--lock",
        p(&f.lock),
    ];
    args.extend_from_slice(extra);
    videt(&args)
}

#[test]
fn init_prints_the_calibration_as_json_and_writes_it() {
    let f = files();
    let out = init(&f, &[]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.starts_with("{\"sides_m\": ["), "{text}");
    let v: serde_json::Value = serde_json::from_str(text.trim()).unwrap();
    let keys: Vec<&String> = v.as_object().unwrap().keys().collect();
    assert_eq!(keys.len(), 3, "{text}");
    let residuals: Vec<f64> = serde_json::from_value(v["residuals_m"].clone()).unwrap();
    assert_eq!(residuals.len(), 6);
    init_json::assert_matches_truth(&v, TRUE_GUIDES);
    let status = videt(&[
        "status",
        "--json",
        "--calibration",
        p(&f.calibration),
        "--lock",
        p(&f.lock),
    ]);
    assert!(status.status.success());
    let s: serde_json::Value = serde_json::from_slice(&status.stdout).unwrap();
    assert_eq!(s["calibration"]["valid"], true);
    assert_eq!(s["motors"], "free");
}

#[test]
fn every_failure_leaves_the_previous_calibration_byte_for_byte() {
    let f = files();
    assert!(init(&f, &[]).status.success());
    let before = std::fs::read(&f.calibration).unwrap();
    let backup = videt_config::calibration::backup_path(&f.calibration);
    let cases: [(&[&str], i32, &str); 5] = [
        (&["--sim-fault", "disconnected:2"], 12, "wire 2 never moved"),
        (&["--sim-fault", "estop:3"], 10, "e-stop"),
        (&["--sim-fault", "break:1:8"], 13, "tension never rose"),
        (&["--sim-fault", "slip:0:4:7"], 14, "disagrees"),
        (&["--sim-fault", "sensor:2:1"], 18, "tension sensor"),
    ];
    for (extra, code, words) in cases {
        let out = init(&f, extra);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(code), "{extra:?}: {stderr}");
        assert!(stderr.contains(words), "{extra:?}: {stderr}");
        assert!(stderr.contains("previous calibration"), "{stderr}");
        let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(json["exit_code"], code);
        assert_eq!(std::fs::read(&f.calibration).unwrap(), before, "{extra:?}");
        assert!(
            !backup.exists(),
            "{extra:?}: a failure must not rotate the backup"
        );
    }
    // A degenerate frame.
    let out = videt(&[
        "init",
        "--sim",
        "--sim-guides",
        "0,0;0.2,0.004;0.4,0",
        "--calibration",
        p(&f.calibration),
        "--lock",
        p(&f.lock),
    ]);
    assert_eq!(
        out.status.code(),
        Some(16),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(std::fs::read(&f.calibration).unwrap(), before);
}

#[test]
fn a_second_process_cannot_take_the_motors() {
    let f = files();
    let held = MotorsLock::acquire(&f.lock).unwrap();
    let out = init(&f, &[]);
    assert_eq!(out.status.code(), Some(23));
    assert!(String::from_utf8_lossy(&out.stderr).contains("in use"));
    assert!(!f.calibration.exists());
    drop(held);
    assert!(init(&f, &[]).status.success());
}

#[test]
fn a_second_init_keeps_the_first_as_backup_and_a_corrupt_file_is_refused() {
    let f = files();
    assert!(init(&f, &[]).status.success());
    let first = std::fs::read(&f.calibration).unwrap();
    assert!(init(&f, &["--sim-seed", "2"]).status.success());
    let backup = videt_config::calibration::backup_path(&f.calibration);
    assert_eq!(std::fs::read(&backup).unwrap(), first);
    // Truncate: status says it is corrupt and that the rig is not calibrated.
    let text = std::fs::read(&f.calibration).unwrap();
    std::fs::write(&f.calibration, &text[..text.len() / 2]).unwrap();
    let out = videt(&[
        "status",
        "--calibration",
        p(&f.calibration),
        "--lock",
        p(&f.lock),
    ]);
    assert_eq!(out.status.code(), Some(4));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("corrupt") && stdout.contains("NOT CALIBRATED"),
        "{stdout}"
    );
}

#[test]
fn wire_replacement_and_tension_calibration_from_the_terminal() {
    let f = files();
    let base = [
        "--sim",
        "--sim-guides",
        GUIDES,
        "--calibration",
        p(&f.calibration),
        "--lock",
        p(&f.lock),
    ];
    let mut args = vec!["wire", "replace", "2"];
    args.extend_from_slice(&base);
    let out = videt(&args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stderr).contains("usable length"));
    assert!(f.calibration.exists());

    let mut args = vec![
        "wire",
        "replace",
        "0",
        "--sim-new-wire-length",
        "0.5",
        "--json",
    ];
    args.extend_from_slice(&base);
    let before = std::fs::read(&f.calibration).unwrap();
    let out = videt(&args);
    assert_eq!(
        out.status.code(),
        Some(21),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(std::fs::read(&f.calibration).unwrap(), before);

    let mut args = vec!["tension-calibrate", "1", "--mass-kg", "0.4", "--json"];
    args.extend_from_slice(&base);
    let out = videt(&args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let gain = v["gain"].as_f64().unwrap();
    assert!((gain - 1.0 / 0.985).abs() < 0.003, "{v}");
}

/// `videt sim-rig` with the example configuration on a CAN interface that does not exist,
/// and `args`.
fn sim_rig_on_no_interface(args: &[&str]) -> Output {
    let example = concat!(env!("CARGO_MANIFEST_DIR"), "/config/videt.example.toml");
    let mut all = vec!["sim-rig", "--config", example, "--can", "vcan-absent"];
    all.extend_from_slice(args);
    videt(&all)
}

#[test]
fn sim_rig_refuses_a_cpu_the_process_may_not_run_on() {
    let out = sim_rig_on_no_interface(&["--cpu", "4096"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    let allowed = videt_runtime::rt::cpu_list(&videt_runtime::rt::allowed_cpus());
    assert!(
        err.contains(&format!(
            "--cpu 4096: this process may run on CPUs {allowed}"
        )),
        "{err}"
    );
}

#[test]
fn sim_rig_builds_only_the_drives_and_cells_mistakes() {
    for (mistake, said) in [
        ("estop-level", "not a mistake of the drives"),
        ("swapped-cameras", "not a mistake of the drives"),
        ("break:1:2", "must be reversed-motor:N"),
        ("reversed-motor:3", "must be 0, 1 or 2"),
    ] {
        let out = sim_rig_on_no_interface(&["--at-rest", "--sim-fault", mistake]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{mistake}: {err}");
        assert!(err.contains(said), "{mistake}: {err}");
    }
    // A mistake of the drives' is taken: the interface is what is missing then.
    let out = sim_rig_on_no_interface(&["--sim-fault", "reversed-motor:1"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("vcan-absent"), "{err}");
}

#[test]
fn sim_rig_refuses_a_time_scale_outside_zero_to_one() {
    for scale in ["0", "1.5", "-0.25", "NaN"] {
        let arg = format!("--time-scale={scale}");
        let out = sim_rig_on_no_interface(&[&arg]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{scale}: {err}");
        assert!(
            err.contains("--time-scale") && err.contains("(0, 1]"),
            "{err}"
        );
    }
}

#[test]
fn every_subcommand_has_help() {
    for args in [
        &["init", "--help"][..],
        &["wire", "--help"],
        &["wire", "replace", "--help"],
        &["tension-calibrate", "--help"],
        &["status", "--help"],
    ] {
        let out = videt(args);
        assert!(out.status.success(), "{args:?}");
        assert!(!out.stdout.is_empty());
    }
    let out = videt(&["init", "--help"]);
    assert!(String::from_utf8_lossy(&out.stdout).contains("Exit codes"));
    // Bad input is an error naming what is wrong, never a panic.
    let f = files();
    let out = videt(&[
        "init",
        "--sim",
        "--sim-guides",
        "1,2;3",
        "--calibration",
        p(&f.calibration),
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("three points"));
    assert!(!f.calibration.parent().unwrap().exists(), "nothing touched");
}

#[test]
fn videtd_renders_forces_after_auto_initializing_its_twin_and_not_without_calibration() {
    for (source, expected) in [("init", "normal"), ("none", "not-calibrated")] {
        let dir = tempfile::tempdir().unwrap();
        let socket = dir.path().join("videtd.sock");
        let mut daemon = Command::new(videt_testkit::videtd_bin())
            .args([
                "--sim",
                "--sim-calibration",
                source,
                "--no-telemetry",
                "--duration",
                "60",
            ])
            .args(["--socket", p(&socket)])
            .env("RUST_LOG", "warn")
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(30);
        let status = loop {
            assert!(
                std::time::Instant::now() < deadline,
                "videtd did not answer"
            );
            std::thread::sleep(std::time::Duration::from_millis(100));
            let reply = videt_service::socket::request(
                &socket,
                &videt_service::socket::Request::Status,
                std::time::Duration::from_secs(2),
            );
            if let Ok(r) = reply {
                let s = r.status.unwrap();
                if s.cycles > 1500 {
                    break s;
                }
            }
        };
        assert_eq!(status.safety, expected, "--sim-calibration {source}");
        let _ = videt_service::socket::request(
            &socket,
            &videt_service::socket::Request::Stop,
            std::time::Duration::from_secs(2),
        );
        assert!(daemon.wait().unwrap().success());
    }
}

/// Without --sim and without a running service, the motor subcommands open the device named by
/// the configuration themselves. A missing part ends them with exit 22 and a message naming it
/// and its configuration field, before any motor moves: the calibration files stay as they
/// were, and the motors lock is free again afterwards. Bad arguments are refused before the
/// device is opened.
#[test]
fn on_the_device_the_motor_subcommands_name_a_missing_part() {
    let f = files();
    let dir = f.lock.parent().unwrap().parent().unwrap();
    let d = dir.display();
    let config = dir.join("videt.toml");
    std::fs::write(
        &config,
        format!(
            "[files]\ncalibration = \"{cal}\"\nmotors_lock = \"{lock}\"\n\
             [sensors]\ngpio_chip = \"{d}/gpiochip-absent\"\n\
             [socket]\npath = \"{d}/videt.sock\"\n",
            cal = p(&f.calibration),
            lock = p(&f.lock),
        ),
    )
    .unwrap();
    for command in [
        &["init"][..],
        &["wire", "replace", "1"],
        &["tension-calibrate", "1", "--mass-kg", "0.5"],
    ] {
        let mut args = command.to_vec();
        args.extend_from_slice(&["--config", p(&config), "--json"]);
        let out = videt(&args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(22), "{command:?}: {stderr}");
        assert!(
            stderr.contains(&format!(
                "device: GPIO {d}/gpiochip-absent line 17 (e-stop): "
            )) && stderr.contains("(sensors.gpio_chip, sensors.estop_line)"),
            "{command:?}: {stderr}"
        );
        assert!(!stderr.contains("panicked"), "{stderr}");
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(v["error"], "device", "{v}");
        assert_eq!(v["exit_code"], 22, "{v}");
        assert!(!f.calibration.exists(), "{command:?} wrote a calibration");
        drop(MotorsLock::acquire(&f.lock).expect("the lock is free again"));
    }
    let out = videt(&[
        "tension-calibrate",
        "1",
        "--mass-kg",
        "3",
        "--config",
        p(&config),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("--mass-kg 3: must be in [0.05, 1.5] kg"),
        "{stderr}"
    );
    assert!(!stderr.contains("gpiochip"), "{stderr}");
}

/// `videt angle-sensors` reads the one-wire device's encoders through the real AS5048A driver:
/// on simulated encoders the angles are eq. 7's of the thimble position, and the position comes
/// back from them and the wire length; a missing device is named with its sensor.
#[test]
fn angle_sensors_read_eq_7_of_the_thimble_and_name_a_missing_device() {
    let [x, y, z] = [0.25f64, -0.2, 0.15];
    let length = (x * x + y * y + z * z).sqrt().to_string();
    let out = videt(&[
        "angle-sensors",
        "--sim",
        "0.25,-0.2,0.15",
        "--count",
        "2",
        "--period-ms",
        "1",
        "--length",
        &length,
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout.contains("azimuth: magnetic field in range"),
        "{stdout}"
    );
    let readings: Vec<&str> = stdout.lines().filter(|l| l.starts_with("counts")).collect();
    assert_eq!(readings.len(), 2, "{stdout}");
    let number_after = |line: &str, key: &str| -> f64 {
        let rest = line.split(key).nth(1).unwrap().trim_start();
        rest.split(|c: char| c == '°' || c.is_whitespace())
            .next()
            .unwrap()
            .parse()
            .unwrap()
    };
    let alpha = y.atan2(x).to_degrees();
    let beta = z.atan2(x.hypot(y)).to_degrees();
    let count_deg = 360.0 / 16384.0;
    for line in readings {
        assert!(
            (number_after(line, "alpha") - alpha).abs() <= count_deg,
            "{line}"
        );
        assert!(
            (number_after(line, "beta") - beta).abs() <= count_deg,
            "{line}"
        );
        let position = line.split("x (").nth(1).unwrap().split(')').next().unwrap();
        let p: Vec<f64> = position
            .split(',')
            .map(|c| c.trim().parse().unwrap())
            .collect();
        for (got, want) in p.iter().zip([x, y, z]) {
            assert!((got - want).abs() < 1e-3, "{line}");
        }
    }
    let out = videt(&[
        "angle-sensors",
        "--azimuth",
        "/dev/videt-no-such-spidev",
        "--elevation",
        "/dev/videt-no-such-spidev2",
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("azimuth angle sensor: /dev/videt-no-such-spidev"),
        "{stderr}"
    );
}
