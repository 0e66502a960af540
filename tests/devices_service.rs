//! Every device of the paper as configuration of one service: `videtd --sim` (and `--sim can`,
//! through the real CiA 402 driver) runs the planar prototype and the one-wire device from
//! `rig.device`, answers the control socket with their
//! wires, records their session, and `videt replay` reproduces it bit for bit; what makes no
//! sense for a device is refused with the field named.

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use videt_config::Config;
use videt_service::socket::{request, Request};

struct Daemon(Child);

impl Drop for Daemon {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn config_for(dir: &Path, device: &str) -> std::path::PathBuf {
    let mut config = Config::default();
    config.rig.device = device.into();
    let path = dir.join(format!("{device}.toml"));
    std::fs::write(&path, toml::to_string(&config).unwrap()).unwrap();
    path
}

fn spawn(config: &Path, extra: &[&str]) -> Daemon {
    Daemon(
        Command::new(videt_testkit::videtd_bin())
            .arg("--config")
            .arg(config)
            .args(extra)
            .env("RUST_LOG", "warn")
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap(),
    )
}

fn wait_exit(d: &mut Daemon, within: Duration) -> std::process::ExitStatus {
    let deadline = Instant::now() + within;
    loop {
        if let Some(status) = d.0.try_wait().unwrap() {
            return status;
        }
        assert!(Instant::now() < deadline, "videtd did not exit in time");
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn stderr_of(d: &mut Daemon) -> String {
    let mut text = String::new();
    if let Some(mut e) = d.0.stderr.take() {
        let _ = std::io::Read::read_to_string(&mut e, &mut text);
    }
    text
}

#[test]
fn the_planar_and_one_wire_devices_run_on_both_twins_from_their_configuration() {
    for (device, wires, sim) in [
        ("planar2", 2usize, "hal"),
        ("polar1", 1, "hal"),
        ("planar2", 2, "can"),
        ("polar1", 1, "can"),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let config = config_for(dir.path(), device);
        let socket = dir.path().join("ctl.sock");
        let logs = dir.path().join("logs");
        let mut daemon = spawn(
            &config,
            &[
                "--sim",
                sim,
                "--duration",
                "4",
                "--socket",
                socket.to_str().unwrap(),
                "--telemetry-dir",
                logs.to_str().unwrap(),
            ],
        );
        // The control socket reports the device and one tension per wire.
        let deadline = Instant::now() + Duration::from_secs(20);
        let status = loop {
            if let Ok(r) = request(&socket, &Request::Status, Duration::from_secs(2)) {
                if let Some(s) = r.status.filter(|s| s.time_s > 1.5) {
                    break s;
                }
            }
            assert!(Instant::now() < deadline, "{device}: no status");
            std::thread::sleep(Duration::from_millis(100));
        };
        assert_eq!(status.device, device);
        assert_eq!(status.tensions_n.len(), wires, "{device}: {status:?}");
        assert!(
            status.tensions_n.iter().all(|t| *t > 0.1),
            "{device}: every wire taut: {status:?}"
        );
        if device == "planar2" {
            assert_eq!(
                status.position_m[1], 0.0,
                "the planar thimble stays in its plane"
            );
        }
        // A wire the device does not have is refused, not indexed.
        let r = request(
            &socket,
            &Request::Release { wire: wires as u8 },
            Duration::from_secs(2),
        )
        .unwrap();
        assert!(!r.ok, "{device}: {r:?}");
        assert!(
            r.error
                .as_deref()
                .unwrap_or("")
                .contains("the device's wires are 0"),
            "{device}: {r:?}"
        );
        // Auto-initialization measures the WireMan's base triangle: not offered here.
        let mut stream = std::os::unix::net::UnixStream::connect(&socket).unwrap();
        std::io::Write::write_all(&mut stream, b"{\"cmd\":\"init\",\"yes\":true}\n").unwrap();
        let mut line = String::new();
        std::io::BufRead::read_line(&mut std::io::BufReader::new(&stream), &mut line).unwrap();
        assert!(
            line.contains("\"ok\":false") && line.contains("WireMan"),
            "{device}: {line}"
        );
        let exit = wait_exit(&mut daemon, Duration::from_secs(30));
        assert!(
            exit.success(),
            "{device}: {exit:?}: {}",
            stderr_of(&mut daemon)
        );

        // The session: the wall touched, no safe state, the unused wire slots empty.
        let path = std::fs::read_dir(&logs)
            .unwrap()
            .next()
            .unwrap()
            .unwrap()
            .path();
        let log = videt_runtime::telemetry::read_log(&path).unwrap();
        let session = log.session.as_ref().unwrap().as_ref().unwrap();
        assert_eq!(session.config.rig.device, device);
        assert!(log.records.len() > 3000, "{device}: {}", log.records.len());
        let unsafe_state = log.records.iter().find(|r| r.safety.reason().is_some());
        assert!(unsafe_state.is_none(), "{device}: {unsafe_state:?}");
        let contact = log.records.iter().filter(|r| r.in_contact).count();
        assert!(
            contact > log.records.len() / 4,
            "{device}: in contact {contact} of {} periods",
            log.records.len()
        );
        // In contact the wall is felt: the rendered force pushes the thimble out of the wall
        // (towards the guides, -z), about K x depth.
        let pressing: Vec<_> = log
            .records
            .iter()
            .filter(|r| r.in_contact && r.force_scale >= 1.0 && r.contact_depth_m > 0.001)
            .collect();
        assert!(!pressing.is_empty(), "{device}: never pressed the wall");
        for r in &pressing {
            assert!(r.rendered_force_n[2] < -0.5, "{device}: {r:?}");
        }
        for r in &log.records {
            assert!(r.lengths_m[wires..].iter().all(|l| *l == 0.0));
            assert!(r.tension_setpoint_n[..wires].iter().all(|t| *t >= 0.29));
        }
        if device == "polar1" {
            assert!(
                log.records.iter().all(|r| r.inputs.angles_read_ok),
                "the one-wire device's angles are read every period"
            );
        }

        // The same cycle replays the session bit for bit.
        let replay = Command::new(env!("CARGO_BIN_EXE_videt"))
            .arg("replay")
            .arg(&path)
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&replay.stdout);
        assert!(replay.status.success(), "{device}: {text}");
        assert!(text.contains("identical"), "{device}: {text}");
    }
}

#[test]
fn what_a_device_cannot_do_is_refused_with_the_reason() {
    let dir = tempfile::tempdir().unwrap();
    for (device, extra, needle) in [
        ("polar1", vec![], "runs on the digital twin"),
        ("planar2", vec![], "runs on the digital twin"),
        (
            "planar2",
            vec!["--sim", "--sim-calibration", "init"],
            "base triangle",
        ),
        ("spidar4", vec!["--sim"], "three wires"),
    ] {
        let config = config_for(dir.path(), device);
        let mut args = extra.clone();
        args.extend(["--no-socket", "--no-telemetry", "--duration", "1"]);
        let mut daemon = spawn(&config, &args);
        let exit = wait_exit(&mut daemon, Duration::from_secs(20));
        let err = stderr_of(&mut daemon);
        assert_eq!(exit.code(), Some(2), "{device} {extra:?}: {err}");
        assert!(err.contains(needle), "{device} {extra:?}: {err}");
    }
    let mut config = Config::default();
    config.rig.device = "wireman".into();
    let e = config.validate().unwrap_err().to_string();
    assert!(e.contains("rig.device") && e.contains("polar1"), "{e}");
}

/// The paper's experiments run with the example configuration's control settings; the test
/// that would catch the two drifting apart.
#[test]
fn the_experiments_run_with_the_example_configuration() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("config/videt.example.toml");
    let config = Config::load(&path).unwrap();
    let c = &config.control;
    let e = videt_experiments::ControlConfig::EXAMPLE;
    assert_eq!(e.rate_hz, c.rate_hz);
    assert_eq!(e.stiffness_n_per_m, c.stiffness_n_per_m);
    assert_eq!(e.damping_n_s_per_m, c.damping_n_s_per_m);
    assert_eq!(e.free_space_field_n, c.free_space_field_n);
    assert_eq!(e.t_min_n, c.t_min_n);
    assert_eq!(e.t_max_n, c.t_max_n);
    assert_eq!(e.max_wire_speed_m_s, c.max_wire_speed_m_s);
    assert_eq!(e.tension_kp_nm_per_n, c.tension_kp_nm_per_n);
    assert_eq!(e.tension_ki_nm_per_n_s, c.tension_ki_nm_per_n_s);
    assert_eq!(e.slack_takeup_speed_m_s, c.slack_takeup_speed_m_s);
    assert_eq!(e.speed_gain_nm_s_per_m, c.speed_gain_nm_s_per_m);
    assert_eq!(e.drive_rated_torque_nm, config.drives.rated_torque_nm);
}

/// `videt experiments` writes the three figures and the summary.
#[test]
fn videt_experiments_writes_the_papers_figures() {
    let dir = tempfile::tempdir().unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_videt"))
        .args(["experiments", "--out"])
        .arg(dir.path())
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{text}");
    assert!(
        text.contains("sides followed (>= 80 % touched): 7 of 7"),
        "{text}"
    );
    for name in [
        "fig18_planar_p1_profile.png",
        "fig22_planar_region_c_field.png",
        "fig23_one_wire_contour.png",
        "summary.txt",
    ] {
        let len = std::fs::metadata(dir.path().join(name)).unwrap().len();
        assert!(len > 1000, "{name}: {len} bytes");
    }
}
