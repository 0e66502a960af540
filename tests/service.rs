//! The service as systemd and a technician see it: the shipped unit, the notify protocol over a
//! socket the test owns, the control socket, and a clean stop.

use std::collections::HashMap;
use std::io::{BufRead, BufReader, Write};
use std::os::unix::net::{UnixDatagram, UnixStream};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use videt_config::Config;
use videt_service::socket::{request, Request};

/// `key -> values` of a unit file's `[Service]` (and other) sections, comments dropped.
fn parse_unit(text: &str) -> HashMap<String, Vec<String>> {
    let mut map: HashMap<String, Vec<String>> = HashMap::new();
    let mut section = String::new();
    for line in text.lines().map(str::trim) {
        if line.is_empty() || line.starts_with('#') || line.starts_with(';') {
            continue;
        }
        if line.starts_with('[') && line.ends_with(']') {
            section = line[1..line.len() - 1].to_string();
            continue;
        }
        let (k, v) = line
            .split_once('=')
            .unwrap_or_else(|| panic!("not a key=value line: {line}"));
        map.entry(format!("{section}.{}", k.trim()))
            .or_default()
            .push(v.trim().to_string());
    }
    map
}

fn one<'a>(unit: &'a HashMap<String, Vec<String>>, key: &str) -> &'a str {
    let v = unit.get(key).unwrap_or_else(|| panic!("{key} missing"));
    assert_eq!(v.len(), 1, "{key} set more than once");
    &v[0]
}

#[test]
fn shipped_unit_is_a_notify_service_with_realtime_limits_and_hardening() {
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("packaging/videtd.service"),
    )
    .unwrap();
    let unit = parse_unit(&text);
    let config = Config::default();
    assert_eq!(one(&unit, "Service.Type"), "notify");
    assert!(one(&unit, "Service.ExecStart")
        .starts_with("/usr/bin/videtd --config /etc/videt/videt.toml"));
    assert!(one(&unit, "Service.WatchdogSec").ends_with('s'));
    let rtprio: u8 = one(&unit, "Service.LimitRTPRIO").parse().unwrap();
    assert!(
        rtprio >= config.realtime.control_priority,
        "LimitRTPRIO must allow the control priority"
    );
    assert_eq!(one(&unit, "Service.LimitMEMLOCK"), "infinity");
    let affinity = one(&unit, "Service.CPUAffinity");
    let (lo, hi) = affinity.split_once('-').unwrap();
    let cpu = config.realtime.control_cpu;
    assert!(
        lo.parse::<i32>().unwrap() <= cpu && cpu <= hi.parse::<i32>().unwrap(),
        "control CPU inside CPUAffinity"
    );
    assert_eq!(one(&unit, "Service.KillSignal"), "SIGTERM");
    for (key, value) in [
        ("Service.NoNewPrivileges", "yes"),
        ("Service.ProtectSystem", "strict"),
        ("Service.ProtectHome", "yes"),
        ("Service.User", "videt"),
        ("Service.DevicePolicy", "closed"),
        ("Service.RuntimeDirectory", "videt"),
        ("Service.LogsDirectory", "videt"),
    ] {
        assert_eq!(one(&unit, key), value, "{key}");
    }
    let devices = &unit["Service.DeviceAllow"];
    assert!(
        devices.iter().any(|d| d.starts_with("/dev/gpiochip")),
        "GPIO allowed"
    );
    assert!(
        devices.iter().any(|d| d.contains("video4linux")),
        "cameras allowed"
    );
    for spi in &config.sensors.spi_devices {
        assert!(
            devices.iter().any(|d| d == &format!("{spi} rw")),
            "{spi} (sensors.spi_devices) allowed"
        );
    }
    assert!(
        one(&unit, "Service.RestrictAddressFamilies").contains("AF_CAN"),
        "SocketCAN allowed"
    );
    // The runtime and logs directories match the default configuration's paths.
    assert!(config.socket.path.starts_with("/run/videt/"));
    assert!(config.telemetry.directory == "/var/log/videt");
}

struct Daemon {
    child: Child,
}

impl Drop for Daemon {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn spawn_videtd(dir: &Path, extra: &[&str], notify: Option<&Path>) -> Daemon {
    let mut cmd = Command::new(videt_testkit::videtd_bin());
    cmd.arg("--sim")
        .arg("--telemetry-dir")
        .arg(dir.join("logs"))
        .args(extra)
        .env("RUST_LOG", "warn")
        .stdout(Stdio::null())
        .stderr(Stdio::null());
    if let Some(n) = notify {
        cmd.env("NOTIFY_SOCKET", n).env("WATCHDOG_USEC", "200000");
    }
    Daemon {
        child: cmd.spawn().unwrap(),
    }
}

fn wait_exit(d: &mut Daemon, within: Duration) -> std::process::ExitStatus {
    let deadline = Instant::now() + within;
    loop {
        if let Some(status) = d.child.try_wait().unwrap() {
            return status;
        }
        assert!(Instant::now() < deadline, "videtd did not exit in time");
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn only_log(dir: &Path) -> std::path::PathBuf {
    let entries: Vec<_> = std::fs::read_dir(dir.join("logs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(entries.len(), 1, "{entries:?}");
    entries[0].clone()
}

#[test]
fn videtd_speaks_the_notify_protocol_and_answers_the_control_socket() {
    let dir = tempfile::tempdir().unwrap();
    let notify_path = dir.path().join("notify.sock");
    let notify = UnixDatagram::bind(&notify_path).unwrap();
    notify
        .set_read_timeout(Some(Duration::from_secs(30)))
        .unwrap();
    let socket = dir.path().join("ctl.sock");
    let mut daemon = spawn_videtd(
        dir.path(),
        &["--socket", socket.to_str().unwrap()],
        Some(&notify_path),
    );

    let mut messages: Vec<String> = Vec::new();
    let mut buf = [0u8; 4096];
    let recv = |messages: &mut Vec<String>, buf: &mut [u8]| {
        let n = notify.recv(buf).expect("notify message");
        messages.push(String::from_utf8_lossy(&buf[..n]).into_owned());
    };
    while !messages.iter().any(|m| m.contains("READY=1")) {
        recv(&mut messages, &mut buf);
    }
    // Three more watchdog pets arrive within 3 s.
    let three_watchdogs_within_3_s = |messages: &mut Vec<String>, buf: &mut [u8]| {
        let pets = |m: &Vec<String>| m.iter().filter(|m| m.contains("WATCHDOG=1")).count();
        let before = pets(messages);
        let t0 = Instant::now();
        while pets(messages) < before + 3 {
            recv(messages, buf);
        }
        assert!(t0.elapsed() < Duration::from_secs(3));
    };
    // The watchdog is petted while the loop is healthy (WATCHDOG_USEC = 200 ms: every ~100 ms).
    three_watchdogs_within_3_s(&mut messages, &mut buf);

    let status = request(&socket, &Request::Status, Duration::from_secs(3)).unwrap();
    let first = status.status.unwrap();
    assert!(status.ok && first.safety == "normal");

    // Malformed and oversized requests get an error reply and do not disturb the loop.
    let mut s = UnixStream::connect(&socket).unwrap();
    s.write_all(b"{\"cmd\": 12}\n").unwrap();
    let mut line = String::new();
    let mut reader = BufReader::new(s.try_clone().unwrap());
    reader.read_line(&mut line).unwrap();
    assert!(
        line.contains("\"ok\":false") && line.contains("malformed"),
        "{line}"
    );
    let mut big = UnixStream::connect(&socket).unwrap();
    let _ = big.write_all(&vec![b'a'; 64 * 1024]);
    let mut line = String::new();
    BufReader::new(big).read_line(&mut line).unwrap();
    assert!(line.contains("too large"), "{line}");
    std::thread::sleep(Duration::from_millis(300));
    let later = request(&socket, &Request::Status, Duration::from_secs(3))
        .unwrap()
        .status
        .unwrap();
    assert!(
        later.cycles > first.cycles + 100,
        "the loop kept running: {} -> {}",
        first.cycles,
        later.cycles
    );
    assert_eq!(later.safety, "normal");

    // Releasing a wire stops force rendering; resume restores it.
    assert!(
        request(
            &socket,
            &Request::Release { wire: 1 },
            Duration::from_secs(3)
        )
        .unwrap()
        .ok
    );
    std::thread::sleep(Duration::from_millis(100));
    let released = request(&socket, &Request::Status, Duration::from_secs(3))
        .unwrap()
        .status
        .unwrap();
    assert_eq!(released.released_wire, Some(1));
    assert!(
        request(&socket, &Request::Resume, Duration::from_secs(3))
            .unwrap()
            .ok
    );

    // A latched e-stop is a safe state the loop holds, not a hang: the watchdog keeps being
    // petted, so that systemd does not restart the service (which would clear the latch).
    assert!(
        request(
            &socket,
            &Request::SimFault {
                fault: "estop".into()
            },
            Duration::from_secs(3)
        )
        .unwrap()
        .ok
    );
    let t0 = Instant::now();
    loop {
        let s = request(&socket, &Request::Status, Duration::from_secs(3))
            .unwrap()
            .status
            .unwrap();
        if s.safety == "e-stop" {
            break;
        }
        assert!(t0.elapsed() < Duration::from_secs(3), "no e-stop: {s:?}");
        std::thread::sleep(Duration::from_millis(20));
    }
    three_watchdogs_within_3_s(&mut messages, &mut buf);

    // Stop through the socket: ramps out, exits 0, says STOPPING=1.
    assert!(
        request(&socket, &Request::Stop, Duration::from_secs(3))
            .unwrap()
            .ok
    );
    let status = wait_exit(&mut daemon, Duration::from_secs(10));
    assert!(status.success(), "{status:?}");
    notify
        .set_read_timeout(Some(Duration::from_secs(2)))
        .unwrap();
    while !messages.iter().any(|m| m.contains("STOPPING=1")) {
        recv(&mut messages, &mut buf);
    }
    assert!(!socket.exists(), "the socket file is removed on exit");
    let log = videt_runtime::telemetry::read_log(&only_log(dir.path())).unwrap();
    assert!(log.records.len() > 500);
    assert!(
        log.records.windows(2).all(|w| w[1].cycle == w[0].cycle + 1),
        "no record dropped"
    );
    // Closed, on the request, at the last period.
    let end = log.end.as_ref().expect("the log is closed");
    assert_eq!(end.reason, videt_runtime::telemetry::EndReason::StopRequest);
    assert_eq!(end.last_cycle, Some(log.records.last().unwrap().cycle));
    assert_eq!((end.periods, end.dropped), (log.records.len() as u64, 0));
}

#[test]
fn sigterm_ramps_the_forces_out_and_exits_zero() {
    let dir = tempfile::tempdir().unwrap();
    let mut daemon = spawn_videtd(dir.path(), &["--no-socket"], None);
    // Long enough for the operator to reach the wall (the demo presses after ~1 s).
    std::thread::sleep(Duration::from_millis(2500));
    // SAFETY: plain kill(2) on our own child.
    assert_eq!(
        unsafe { libc::kill(daemon.child.id() as i32, libc::SIGTERM) },
        0
    );
    let status = wait_exit(&mut daemon, Duration::from_secs(10));
    assert!(status.success(), "{status:?}");
    let log = videt_runtime::telemetry::read_log(&only_log(dir.path())).unwrap();
    let last = log.records.last().unwrap();
    assert_eq!(last.force_scale, 0.0, "forces ramped out before exit");
    assert_eq!(
        log.end_note(),
        format!(
            "session closed at cycle {}: stopped by a signal (SIGTERM)",
            last.cycle
        )
    );
    let ramp: Vec<f64> = log
        .records
        .iter()
        .rev()
        .take(300)
        .map(|r| r.force_scale)
        .collect();
    assert!(
        ramp.windows(2).all(|w| w[0] <= w[1] + 1e-12),
        "the scale falls monotonically to zero"
    );
    assert!(
        ramp.iter().any(|&s| s > 0.2 && s < 0.8),
        "a ramp, not a step"
    );
    assert!(last
        .tension_setpoint_n
        .iter()
        .all(|&t| (t - Config::default().control.t_min_n).abs() < 1e-9));
}

/// Both twins run the demonstration in real time without entering a safe state: the operator
/// reaches the wall and the log shows contact and normal operation throughout.
#[test]
fn the_demonstration_runs_cleanly_on_both_twins() {
    for sim in ["hal", "can"] {
        let dir = tempfile::tempdir().unwrap();
        let mut daemon = Daemon {
            child: Command::new(videt_testkit::videtd_bin())
                .args([
                    "--sim",
                    sim,
                    "--duration",
                    "3",
                    "--no-socket",
                    "--telemetry-dir",
                ])
                .arg(dir.path().join("logs"))
                .env("RUST_LOG", "warn")
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .spawn()
                .unwrap(),
        };
        let status = wait_exit(&mut daemon, Duration::from_secs(20));
        assert!(status.success(), "--sim {sim}: {status:?}");
        let log = videt_runtime::telemetry::read_log(&only_log(dir.path())).unwrap();
        assert_eq!(
            log.end.as_ref().map(|e| &e.reason),
            Some(&videt_runtime::telemetry::EndReason::DurationElapsed),
            "--sim {sim}"
        );
        let unsafe_state = log.records.iter().find(|r| r.safety.reason().is_some());
        assert!(
            unsafe_state.is_none(),
            "--sim {sim}: {:?}",
            unsafe_state.map(|r| (r.time, r.safety))
        );
        let contact = log.records.iter().filter(|r| r.in_contact).count();
        assert!(
            contact > 500,
            "--sim {sim}: in contact for {contact} periods only"
        );
        // The session's figures: every one drawn, and each more than a blank canvas.
        let plots = dir.path().join("plots");
        let out = Command::new(env!("CARGO_BIN_EXE_videt"))
            .arg("log")
            .arg(only_log(dir.path()))
            .arg("--plot")
            .arg(&plots)
            .arg("--view-figure")
            .arg(plots.join("still.png"))
            .output()
            .unwrap();
        assert!(out.status.success(), "{out:?}");
        let still = image::open(plots.join("still.png")).unwrap().to_rgb8();
        assert_eq!(still.dimensions(), (1600, 900), "--sim {sim}");
        // At a moment asked for: the period at or after it.
        let out = Command::new(env!("CARGO_BIN_EXE_videt"))
            .arg("log")
            .arg(only_log(dir.path()))
            .arg("--view-figure")
            .arg(plots.join("at.png"))
            .args(["--at", "0.5"])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            out.status.success() && err.contains("(the session at 0.50"),
            "--sim {sim}: {err}"
        );
        for name in [
            "path.png",
            "tensions.png",
            "forces.png",
            "timing.png",
            "still.png",
            "at.png",
        ] {
            let img = image::open(plots.join(name)).unwrap().to_rgb8();
            let background = *img.get_pixel(0, 0);
            let drawn = img.pixels().filter(|p| **p != background).count();
            assert!(
                drawn > img.pixels().len() / 50,
                "--sim {sim}: {name} has {drawn} drawn pixels"
            );
        }
        // The session replays through the same control cycle, bit for bit.
        let out = Command::new(env!("CARGO_BIN_EXE_videt"))
            .arg("replay")
            .arg(only_log(dir.path()))
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(out.status.success(), "--sim {sim}: {out:?}");
        assert!(text.contains("identical"), "--sim {sim}: {text}");
    }
}

/// A drive's fault puts the service in its safe state, and the log says which drive and why, as
/// the drive set latched it: what a technician reads when the forces went away.
#[test]
fn a_drive_fault_is_logged_with_its_cause() {
    let dir = tempfile::tempdir().unwrap();
    let socket = dir.path().join("ctl.sock");
    let stderr = dir.path().join("videtd.log");
    let mut daemon = Daemon {
        child: Command::new(videt_testkit::videtd_bin())
            .args(["--sim", "can", "--duration", "20", "--socket"])
            .arg(&socket)
            .arg("--telemetry-dir")
            .arg(dir.path().join("logs"))
            .env("RUST_LOG", "warn")
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(&stderr).unwrap())
            .spawn()
            .unwrap(),
    };
    let status = |within: Duration| {
        let deadline = Instant::now() + within;
        loop {
            if let Ok(r) = request(&socket, &Request::Status, Duration::from_secs(2)) {
                if let Some(s) = r.status.filter(|s| s.cycles > 500) {
                    return s;
                }
            }
            assert!(Instant::now() < deadline, "no status from videtd");
            std::thread::sleep(Duration::from_millis(50));
        }
    };
    let before = status(Duration::from_secs(15));
    assert_eq!(
        before.safety,
        "normal",
        "{:?}: {}",
        before.fault,
        std::fs::read_to_string(&stderr).unwrap_or_default()
    );
    let injected = request(
        &socket,
        &Request::SimFault {
            // Wire 2's drive: CAN node 3.
            fault: "emcy:2:8611".into(),
        },
        Duration::from_secs(2),
    )
    .unwrap();
    assert!(injected.ok, "{injected:?}");
    let deadline = Instant::now() + Duration::from_secs(5);
    while status(Duration::from_secs(5)).safety != "drive-fault" {
        assert!(Instant::now() < deadline, "no drive fault");
        std::thread::sleep(Duration::from_millis(20));
    }
    // The supervisor tells the cause within its next few ticks, in the log and in the status.
    std::thread::sleep(Duration::from_millis(200));
    let fault = status(Duration::from_secs(5)).fault.unwrap_or_default();
    assert!(
        fault.contains("drive of wire 2 (node 3): emergency 0x8611"),
        "{fault}"
    );
    assert!(
        request(&socket, &Request::Stop, Duration::from_secs(2))
            .unwrap()
            .ok
    );
    wait_exit(&mut daemon, Duration::from_secs(10));
    let log = std::fs::read_to_string(&stderr).unwrap();
    let told: Vec<&str> = log
        .lines()
        .filter(|l| l.contains("hardware fault"))
        .collect();
    assert_eq!(told.len(), 1, "{log}");
    assert!(
        told[0].contains("drive of wire 2 (node 3): emergency 0x8611 (following error)"),
        "{}",
        told[0]
    );
}

/// Without --sim the service opens the device named by the configuration. A part that is not
/// there ends the start with an error naming it and the configuration field to look at; no
/// panic, and nothing else is opened after it (the e-stop is opened first).
#[test]
fn on_the_device_a_missing_part_is_named_with_its_configuration_field() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().display();
    let config = dir.path().join("videt.toml");
    std::fs::write(
        &config,
        format!(
            "[files]\ncalibration = \"{d}/calibration.toml\"\nmotors_lock = \"{d}/motors.lock\"\n\
             [sensors]\ngpio_chip = \"{d}/gpiochip-absent\"\n\
             [socket]\npath = \"{d}/videt.sock\"\n[telemetry]\ndirectory = \"{d}/logs\"\n"
        ),
    )
    .unwrap();
    let out = Command::new(videt_testkit::videtd_bin())
        .arg("--config")
        .arg(&config)
        .args(["--duration", "1"])
        .env("RUST_LOG", "info")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains(&format!(
            "device: GPIO {d}/gpiochip-absent line 17 (e-stop): "
        )) && stderr.contains("(sensors.gpio_chip, sensors.estop_line)"),
        "{stderr}"
    );
    assert!(
        stderr.contains("forces will not be rendered (not calibrated)"),
        "{stderr}"
    );
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(!stderr.contains("CAN interface"), "{stderr}");

    let out = Command::new(videt_testkit::videtd_bin())
        .arg("--config")
        .arg(&config)
        .args(["--scene", "box"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("needs --sim"), "{stderr}");
}

/// The scheduling policy and real-time priority of the thread of `pid` named `name`, read from
/// `/proc` (policy 1 is SCHED_FIFO).
fn thread_policy(pid: u32, name: &str) -> Option<(u32, u32)> {
    for task in std::fs::read_dir(format!("/proc/{pid}/task")).ok()? {
        let task = task.ok()?.path();
        let comm = std::fs::read_to_string(task.join("comm")).unwrap_or_default();
        if comm.trim_end() != name {
            continue;
        }
        let stat = std::fs::read_to_string(task.join("stat")).ok()?;
        // Fields after the command's closing parenthesis start at field 3 (the state);
        // rt_priority is field 40 and policy field 41.
        let fields: Vec<&str> = stat.rsplit_once(')')?.1.split_whitespace().collect();
        return Some((fields[41 - 3].parse().ok()?, fields[40 - 3].parse().ok()?));
    }
    None
}

/// The vision threads of the twin's relief scenes run at `realtime.vision_priority`, as the
/// camera's does (or say why not, where the process may not use SCHED_FIFO).
#[test]
fn the_twin_scenes_vision_threads_take_the_configured_priority() {
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("videt.toml");
    std::fs::write(&config, "[realtime]\nvision_priority = 7\n").unwrap();
    for scene in ["box", "stereo"] {
        let mut daemon = Daemon {
            child: Command::new(videt_testkit::videtd_bin())
                .arg("--config")
                .arg(&config)
                .args(["--sim", "--scene", scene, "--duration", "20"])
                .args(["--no-socket", "--no-telemetry"])
                .stdout(Stdio::null())
                .stderr(Stdio::piped())
                .spawn()
                .unwrap(),
        };
        let pid = daemon.child.id();
        let deadline = Instant::now() + Duration::from_secs(15);
        let mut seen = None;
        while Instant::now() < deadline {
            seen = thread_policy(pid, "videt-vision");
            if seen == Some((1, 7)) {
                break;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        let _ = daemon.child.kill();
        let mut stderr = String::new();
        std::io::Read::read_to_string(daemon.child.stderr.as_mut().unwrap(), &mut stderr).unwrap();
        if seen != Some((1, 7)) {
            assert!(
                seen.is_some() && stderr.contains("the vision thread stays SCHED_OTHER"),
                "--scene {scene}: vision thread {seen:?}, {stderr}"
            );
        }
    }
}

/// A control rate the configured CAN bus cannot carry is refused before anything starts, by
/// the service (on the device and on the CAN twin) and by `videt config check`, with the
/// fields and the numbers named; the HAL twin, which has no bus, warns and runs.
#[test]
fn a_rate_the_bus_cannot_carry_is_refused_with_the_fields_named() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().display();
    let config = dir.path().join("videt.toml");
    std::fs::write(
        &config,
        format!(
            "[control]\nrate_hz = 4000\n\
             [files]\ncalibration = \"{d}/calibration.toml\"\nmotors_lock = \"{d}/motors.lock\"\n\
             [socket]\npath = \"{d}/videt.sock\"\n[telemetry]\ndirectory = \"{d}/logs\"\n"
        ),
    )
    .unwrap();
    let named = |text: &str| {
        text.contains("control.rate_hz = 4000")
            && text.contains("drives.bitrate = 1000000")
            && text.contains("drives.max_bus_load = 0.8")
    };
    for mode in [&["--sim", "can"][..], &[][..]] {
        let out = Command::new(videt_testkit::videtd_bin())
            .arg("--config")
            .arg(&config)
            .args(mode)
            .args(["--duration", "1", "--no-socket", "--no-telemetry"])
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{mode:?}: {stderr}");
        assert!(named(&stderr), "{mode:?}: {stderr}");
        assert!(!stderr.contains("control loop running"), "{stderr}");
    }
    let out = Command::new(env!("CARGO_BIN_EXE_videt"))
        .args(["config", "check"])
        .arg(&config)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(named(&stderr), "{stderr}");
    // The default rate passes, and the check prints the load it computed.
    std::fs::write(&config, "[control]\nrate_hz = 1000\n").unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_videt"))
        .args(["config", "check"])
        .arg(&config)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}");
    assert!(
        stdout.contains("CAN bus at 1000000 bit/s, 1000 Hz") && stdout.contains("worst case"),
        "{stdout}"
    );
}

/// A tension sensor too slow for the configured PI gains is refused by the service (on the
/// twin too: its strain gauges have the configured converter's timing); with the degraded
/// mode asked for, the service runs the lower gains and says so.
#[test]
fn a_tension_sensor_too_slow_for_the_gains_is_refused_or_runs_degraded_and_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().display();
    let config = dir.path().join("videt.toml");
    let write = |degraded: bool| {
        std::fs::write(
            &config,
            format!(
                "[control]\nallow_degraded_tension_loop = {degraded}\n\
                 [sensors]\nadc = \"hx711\"\nsample_rate_sps = 80\nstale_after_ms = 100\n\
                 hx711_clock_lines = [5, 6, 13]\nhx711_data_lines = [16, 20, 21]\n\
                 [files]\ncalibration = \"{d}/calibration.toml\"\nmotors_lock = \"{d}/motors.lock\"\n\
                 [socket]\npath = \"{d}/videt.sock\"\n[telemetry]\ndirectory = \"{d}/logs\"\n"
            ),
        )
        .unwrap();
    };
    let run = || {
        Command::new(videt_testkit::videtd_bin())
            .arg("--config")
            .arg(&config)
            .args([
                "--sim",
                "--duration",
                "1.5",
                "--no-socket",
                "--no-telemetry",
            ])
            .env("RUST_LOG", "info")
            .output()
            .unwrap()
    };
    write(false);
    let out = run();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("control.tension_ki_nm_per_n_s = 0.04")
            && stderr.contains("HX711 at 80 samples/s")
            && stderr.contains("control.allow_degraded_tension_loop = true"),
        "{stderr}"
    );
    write(true);
    let out = run();
    let stderr = String::from_utf8_lossy(&out.stderr);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("PI tension loop DEGRADED to 0."),
        "the start-up log says it: {stderr}"
    );
    assert!(
        stdout.contains("tension loop degraded (PI gains x0.")
            || stderr.contains("tension loop degraded (PI gains x0."),
        "the status line says it: {stdout}{stderr}"
    );
}
