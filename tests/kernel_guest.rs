//! The device path of `videtd` on a real Linux kernel's device interfaces: the CiA 402 drives
//! over SocketCAN (a `vcan` interface), the e-stop and vibrotactors on GPIO character devices
//! (a gpio-sim chip), the cameras on V4L2 (vivid). The drives are the twin's, served by
//! `videt sim-rig` as a process of its own on the same interface.
//!
//! These tests need root and those kernel drivers: they run in the kernel-in-the-loop guest
//! (`scripts/kernel-in-the-loop.sh`, a PREEMPT_RT kernel under QEMU) and are ignored elsewhere.
//! Each test makes its own CAN interface and GPIO chip, so they may run in any order. The guest
//! is emulated: the configuration tolerates its slow, jittery timing (see [`guest_config`]), and
//! no test here judges timing in microseconds, only in control periods.

mod guest;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use gpiosim::Simpleton;
use guest::*;
use videt_service::socket::{request, Request, StatusReport};

/// A running device: its CAN interface, GPIO chip, rig process and service.
struct Device {
    dir: tempfile::TempDir,
    can: Vcan,
    chip: Simpleton,
    config: PathBuf,
    rig: Process,
    videtd: Process,
}

impl Device {
    /// Start the rig and the service without cameras (nor colour); wait until the service
    /// renders forces.
    fn start() -> Device {
        Device::start_with(false, |dir| {
            ideal_stereo_calibration(dir);
            ["/dev/null-left".into(), "/dev/null-right".into()]
        })
    }

    /// Start the rig and the service with the cameras `cameras` returns (given the test's
    /// directory, where it may write the stereo calibration), rendering colour if `colour`.
    fn start_with(colour: bool, cameras: impl FnOnce(&Path) -> [String; 2]) -> Device {
        let dir = test_dir();
        let can = Vcan::new();
        let chip = Simpleton::new(32);
        // The e-stop is active low: released = pulled up.
        chip.pullup(ESTOP_LINE).unwrap();
        let [left, right] = cameras(dir.path());
        let config = guest_config(dir.path(), &can.0, chip.dev_path(), [&left, &right], colour);
        let rig = start_rig(&config, &can.0);
        let videtd = start_videtd(&config);
        let mut device = Device {
            dir,
            can,
            chip,
            config,
            rig,
            videtd,
        };
        device.wait_rendering(120.0);
        device
    }

    /// Wait up to `secs` for the service to render forces (normal, powered, past its first
    /// thousand periods); a service that exits first fails the test with its log.
    fn wait_rendering(&mut self, secs: f64) {
        let deadline = Instant::now() + Duration::from_secs_f64(secs);
        let mut last = None;
        loop {
            if let Some(s) = status(&self.socket()) {
                if s.safety == "normal" && !s.power_off && s.cycles > 1000 {
                    return;
                }
                last = Some(s);
            }
            if let Some(exit) = self.videtd.0.try_wait().unwrap() {
                panic!(
                    "videtd exited ({exit}) before rendering forces: {}",
                    self.log()
                );
            }
            assert!(
                Instant::now() < deadline,
                "forces rendered on the device: last status {last:?}"
            );
            std::thread::sleep(Duration::from_millis(50));
        }
    }
    fn socket(&self) -> PathBuf {
        socket_path(self.dir.path())
    }
    fn log(&self) -> String {
        std::fs::read_to_string(self.dir.path().join("videtd.log")).unwrap_or_default()
    }
    fn wait_for(
        &self,
        secs: f64,
        what: &str,
        check: impl Fn(&StatusReport) -> bool,
    ) -> StatusReport {
        wait_for(&self.socket(), secs, what, check)
    }
    /// After a drive fault that took effect at `fault_ns` (monotonic): the service reaches
    /// its power-off state, and once it is stopped the session log shows the drive fault and
    /// at most `bound` periods that still rendered forces after `fault_ns`, and its log tells
    /// the fault's `cause`.
    fn assert_drive_fault_within(&mut self, fault_ns: u64, bound: usize, what: &str, cause: &str) {
        self.wait_for(30.0, "drive fault", |s| {
            s.safety == "drive-fault" && s.power_off
        });
        self.terminate();
        let log = session_log(self.dir.path());
        let (periods, reached) = periods_to_power_off(&log, fault_ns, "drive-fault");
        assert!(reached, "the drive fault is in the session log");
        assert!(
            periods <= bound,
            "{periods} periods rendered forces after {what} (at most {bound})"
        );
        let told = self.log();
        assert!(
            told.lines()
                .any(|l| l.contains("hardware fault") && l.contains(cause)),
            "the log does not tell the cause ({cause}): {told}"
        );
    }

    /// Stop the service with SIGTERM; it must ramp the forces out, power the drives off and
    /// exit 0.
    fn terminate(&mut self) {
        self.videtd.signal(libc::SIGTERM);
        let exit = self
            .videtd
            .wait_exit(60.0)
            .expect("videtd exits on SIGTERM");
        assert!(exit.success(), "videtd after SIGTERM: {exit}");
        let log = self.log();
        assert!(log.contains("forces ramped out, drives off"), "{log}");
    }
}

#[test]
#[ignore = "needs root, vcan, gpio-sim and vivid: runs in the kernel-in-the-loop guest (scripts/kernel-in-the-loop.sh)"]
fn videtd_renders_the_twin_over_socketcan_and_the_gpio_estop_latches_until_restart() {
    let _ = GUEST;
    let mut d = Device::start();
    // The drives answer with encoders and analog tensions: the thimble is where the twin's
    // operator holds it, and every wire is taut.
    let s = d.wait_for(30.0, "taut wires", |s| {
        s.tensions_n.iter().all(|t| *t > 0.1)
    });
    assert!(
        s.position_m[2] > 0.1 && s.position_m[2] < 0.6,
        "thimble at {:?}",
        s.position_m
    );

    // The technician's tool answers through the control socket.
    let out = Command::new(videt_bin())
        .args(["service", "status", "--json", "--socket"])
        .arg(d.socket())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let reply: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(reply["status"]["safety"], "normal", "{reply}");
    // The cameras of this configuration do not exist: the log names them and their field,
    // and the wearer touches the check wall.
    #[cfg(feature = "v4l")]
    {
        let log = d.log();
        assert!(
            log.contains("/dev/null-left") && log.contains("vision.devices"),
            "{log}"
        );
    }

    // Press the e-stop on the GPIO line: the drives are powered off.
    d.chip.pulldown(ESTOP_LINE).unwrap();
    let pressed_ns = monotonic_ns();
    d.wait_for(30.0, "e-stop", |s| s.safety == "e-stop" && s.power_off);
    // Released, it stays latched, and resetting faults does not clear a power-off fault.
    d.chip.pullup(ESTOP_LINE).unwrap();
    std::thread::sleep(Duration::from_millis(500));
    let reply = request(&d.socket(), &Request::ResetFaults, Duration::from_secs(5)).unwrap();
    let _ = reply;
    std::thread::sleep(Duration::from_millis(500));
    let s = status(&d.socket()).unwrap();
    assert_eq!(s.safety, "e-stop", "{s:?}");
    assert!(s.power_off);

    d.terminate();
    let log = session_log(d.dir.path());
    let (periods, reached) = periods_to_power_off(&log, pressed_ns, "e-stop");
    assert!(reached, "the e-stop is in the session log");
    // Debounced over 3 readings, one per period: the press is acted on in the third period
    // that reads the line low (the line is low from `pressed_ns` on).
    assert!(periods <= 3, "e-stop after {periods} periods");
    let _ = (&d.config, &d.can, &d.rig);
}

#[test]
#[ignore = "needs root, vcan, gpio-sim and vivid: runs in the kernel-in-the-loop guest (scripts/kernel-in-the-loop.sh)"]
fn the_can_interface_going_down_powers_off_within_two_periods() {
    let mut d = Device::start();
    d.can.set_up(false);
    let down_ns = monotonic_ns();
    d.assert_drive_fault_within(
        down_ns,
        2,
        "the link went down",
        "CAN interface: Network is down",
    );
    d.can.set_up(true);
}

#[test]
#[ignore = "needs root, vcan, gpio-sim and vivid: runs in the kernel-in-the-loop guest (scripts/kernel-in-the-loop.sh)"]
fn a_killed_drive_process_powers_off_within_two_periods() {
    let mut d = Device::start();
    d.rig.kill();
    let killed_ns = monotonic_ns();
    // Silent drives are a fault once their process data has been missing for more than
    // `drives.max_missed_cycles` periods: within 2 periods with the device's 1.
    let bound = GUEST_MISSED_CYCLES as usize + 1;
    d.assert_drive_fault_within(killed_ns, bound, "the drives died", "process data missing");
}

/// A listener on `iface` that notes when the first frame with identifier `cob_id` crosses the
/// bus (monotonic ns), for timing a fault from the moment it is on the bus.
fn frame_seen(iface: &str, cob_id: u32) -> std::thread::JoinHandle<Option<u64>> {
    use embedded_can::Frame;
    use videt_drivers::can::CanPort;
    let mut port = videt_drivers::can::socketcan_port::SocketCanPort::open(iface).unwrap();
    std::thread::spawn(move || {
        let deadline = Instant::now() + Duration::from_secs(30);
        while Instant::now() < deadline {
            if let Ok(Some(f)) = port.receive_timeout(Duration::from_millis(100)) {
                let id = match f.id() {
                    embedded_can::Id::Standard(s) => u32::from(s.as_raw()),
                    embedded_can::Id::Extended(e) => e.as_raw(),
                };
                if id == cob_id {
                    return Some(monotonic_ns());
                }
            }
        }
        None
    })
}

#[test]
#[ignore = "needs root, vcan, gpio-sim and vivid: runs in the kernel-in-the-loop guest (scripts/kernel-in-the-loop.sh)"]
fn an_emcy_from_a_drive_powers_off_within_two_periods() {
    let mut d = Device::start();
    // Wire 0's drive is node 1 in the example configuration: its EMCY is COB-ID 0x81.
    let emcy = frame_seen(&d.can.0, 0x81);
    std::thread::sleep(Duration::from_millis(100));
    d.rig.signal(libc::SIGUSR1);
    let on_bus_ns = emcy.join().unwrap().expect("the drive sent its EMCY");
    d.assert_drive_fault_within(
        on_bus_ns,
        2,
        "the EMCY",
        "drive of wire 0 (node 1): emergency 0x2310",
    );
}

#[test]
#[ignore = "needs root, vcan, gpio-sim and vivid: runs in the kernel-in-the-loop guest (scripts/kernel-in-the-loop.sh)"]
fn missing_devices_are_named_with_their_configuration_field() {
    let dir = tempfile::tempdir().unwrap();
    let chip = Simpleton::new(32);
    chip.pullup(ESTOP_LINE).unwrap();
    let can = Vcan::new();
    let cases: [(&str, &Path, &str, &str); 2] = [
        (
            "vcan-absent",
            chip.dev_path(),
            "vcan-absent",
            "drives.can_interface",
        ),
        (
            &can.0,
            Path::new("/dev/gpiochip-absent"),
            "/dev/gpiochip-absent",
            "sensors.gpio_chip",
        ),
    ];
    for (iface, gpio, device, field) in cases {
        let config = guest_config(
            dir.path(),
            iface,
            gpio,
            ["/dev/null-left", "/dev/null-right"],
            false,
        );
        let out = Command::new(videtd_bin())
            .arg("--config")
            .arg(&config)
            .output()
            .unwrap();
        let text = format!(
            "{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(!out.status.success(), "{text}");
        assert!(!text.contains("panicked"), "{text}");
        assert!(
            text.contains(device) && text.contains(field),
            "{device}/{field}: {text}"
        );
    }
}

/// `videt commission` on the device path: the rig part against `videt sim-rig` built with
/// wire 1's motor turning the other way, over SocketCAN, with the gpio-sim e-stop; the test
/// is the technician (it presses and releases the e-stop on the GPIO line, and pulls the wires
/// out through the rig's stdin). The check names the motor's fix; with the fix written the
/// check passes on the same rig.
#[test]
#[ignore = "needs root, vcan, gpio-sim and vivid: runs in the kernel-in-the-loop guest (scripts/kernel-in-the-loop.sh)"]
fn commissioning_finds_a_reversed_motor_over_socketcan_with_the_gpio_estop() {
    use std::io::{BufRead, BufReader, Write};
    use std::process::Stdio;
    let dir = test_dir();
    let can = Vcan::new();
    let chip = Simpleton::new(32);
    chip.pullup(ESTOP_LINE).unwrap();
    let config = guest_config(
        dir.path(),
        &can.0,
        chip.dev_path(),
        ["/dev/null-left", "/dev/null-right"],
        false,
    );
    // The rig's world runs in slow motion (a quarter of the wall clock), and the speeds the
    // check limits its tests by are derived from the drives' positions over the wall clock's
    // periods: the limit a quarter of the default, for the wires to move as fast as on a rig.
    let mut t: toml::Table = std::fs::read_to_string(&config).unwrap().parse().unwrap();
    t.entry("commission")
        .or_insert_with(|| toml::Value::Table(toml::Table::new()))
        .as_table_mut()
        .unwrap()
        .insert("max_speed_m_s".into(), toml::Value::Float(0.0125));
    std::fs::write(&config, toml::to_string(&t).unwrap()).unwrap();
    let mut rig = start_rig_with(
        &config,
        &can.0,
        &[
            "--at-rest",
            "--sim-fault",
            "reversed-motor:1",
            "--technician-stdin",
        ],
    );
    let mut hands = rig.0.stdin.take().expect("the rig's stdin");
    let rig_log = || std::fs::read_to_string(dir.path().join("sim-rig.log")).unwrap_or_default();
    // The rig says each pull it made: the technician's hand has acted once the log has one
    // more (the rig reads its stdin on an ordinary thread, which its real-time threads and
    // the check's may keep waiting on the emulated CPUs).
    let pulls_done = || rig_log().matches(" pulled out from ").count();
    let fixed = dir.path().join("fixed.toml");
    // The technician at work while the check runs: each prompt on stderr is done, then
    // confirmed with a line on the check's stdin.
    let mut commission = |config: &Path, extra: &[&std::ffi::OsStr]| {
        let mut check = Command::new(videt_bin())
            .args([
                "commission",
                "--only",
                "rig",
                "--json",
                "--steps-from-stdin",
                "--config",
            ])
            .arg(config)
            .args(extra)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let mut confirm = check.stdin.take().unwrap();
        let mut told = String::new();
        for line in BufReader::new(check.stderr.take().unwrap()).lines() {
            let line = line.unwrap();
            told.push_str(&line);
            told.push('\n');
            if line.contains("make sure the e-stop is released") {
                chip.pullup(ESTOP_LINE).unwrap();
            } else if line.contains("press the e-stop") {
                chip.pulldown(ESTOP_LINE).unwrap();
            } else if let Some(rest) = line.split("pull the wire at ring ").nth(1) {
                let done = pulls_done();
                writeln!(hands, "pull-out {} 0.1", &rest[..1]).unwrap();
                let deadline = Instant::now() + Duration::from_secs(60);
                while pulls_done() == done {
                    assert!(
                        Instant::now() < deadline,
                        "the rig made no pull: {}",
                        rig_log()
                    );
                    std::thread::sleep(Duration::from_millis(50));
                }
            } else if let Some(rest) = line.split("let the wire at ring ").nth(1) {
                writeln!(hands, "let-go {}", &rest[..1]).unwrap();
            } else {
                continue;
            }
            std::thread::sleep(Duration::from_millis(300));
            if writeln!(confirm, "done").is_err() {
                break;
            }
        }
        let out = check.wait_with_output().unwrap();
        let report: serde_json::Value = serde_json::from_slice(&out.stdout)
            .unwrap_or_else(|e| panic!("{e}: {}{told}", String::from_utf8_lossy(&out.stdout)));
        (out.status.code(), report, told)
    };
    let (code, report, told) = commission(&config, &["--write".as_ref(), fixed.as_os_str()]);
    assert_eq!(code, Some(27), "{report:#}\n{told}");
    let fixes: Vec<&str> = report["fixes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f.as_str().unwrap())
        .collect();
    assert_eq!(
        fixes,
        ["drives.motor_reversed[1] = true"],
        "{report:#}\n{told}"
    );
    let result = |name: &str| {
        report["steps"]
            .as_array()
            .unwrap()
            .iter()
            .find(|s| s["name"] == name)
            .map(|s| s["result"].as_str().unwrap().to_string())
    };
    for name in [
        "drive0.identity",
        "drive1.identity",
        "drive2.identity",
        "estop.released",
        "estop.pressed",
        "drive0.direction",
        "drive0.encoder",
        "drive1.encoder",
        "drive2.encoder",
    ] {
        assert_eq!(
            result(name).as_deref(),
            Some("pass"),
            "{name}: {report:#}\n{told}\n{}",
            rig_log()
        );
    }
    let (code, report, told) = commission(&fixed, &[]);
    assert_eq!(code, Some(0), "{report:#}\n{told}\n{}", rig_log());
    let _ = (&can, &rig);
}

/// The V4L2 cameras: two vivid capture devices, named by `VIDET_KIL_CAMERAS` ("LEFT,RIGHT").
#[cfg(feature = "v4l")]
mod cameras {
    use super::*;
    use gpiosim::Level;

    fn devices() -> [String; 2] {
        let list = std::env::var("VIDET_KIL_CAMERAS").unwrap_or("/dev/video0,/dev/video1".into());
        let (l, r) = list
            .split_once(',')
            .expect("VIDET_KIL_CAMERAS is LEFT,RIGHT");
        [l.to_string(), r.to_string()]
    }

    /// The pulses of the three vibrotactor lines, sampled together every 200 µs for `span`:
    /// per line, each pulse's (rising edge, high time).
    fn sample_pulses(chip: &Simpleton, span: Duration) -> Vec<Vec<(Instant, Duration)>> {
        // On a thread of its own at real-time priority (below the service's control thread and
        // the rig's drives): of ordinary priority, the vision thread's work on the same emulated
        // CPU held it off for longer than a pulse, and it saw no whole period.
        std::thread::scope(|scope| {
            scope
                .spawn(|| {
                    let _ = videt_runtime::rt::set_fifo(50);
                    sample_pulses_here(chip, span)
                })
                .join()
                .unwrap()
        })
    }

    fn sample_pulses_here(chip: &Simpleton, span: Duration) -> Vec<Vec<(Instant, Duration)>> {
        let mut pulses = vec![Vec::new(); VIBROTACTOR_LINES.len()];
        let mut rose: Vec<Option<Instant>> = vec![None; VIBROTACTOR_LINES.len()];
        let mut last = vec![Level::Low; VIBROTACTOR_LINES.len()];
        let end = Instant::now() + span;
        while Instant::now() < end {
            for (k, line) in VIBROTACTOR_LINES.iter().enumerate() {
                let level = chip.get_level(*line).unwrap();
                let now = Instant::now();
                match (last[k], level) {
                    (Level::Low, Level::High) => rose[k] = Some(now),
                    (Level::High, Level::Low) => {
                        if let Some(t) = rose[k].take() {
                            pulses[k].push((t, now - t));
                        }
                    }
                    _ => {}
                }
                last[k] = level;
            }
            std::thread::sleep(Duration::from_micros(200));
        }
        pulses
    }

    /// Whether the guest runs on an emulated CPU (QEMU's TCG; `KIL_ACCEL` from the guest's
    /// init): its timings say nothing of the product's.
    fn emulated_cpu() -> bool {
        std::env::var("KIL_ACCEL").as_deref() != Ok("kvm")
    }

    fn median(mut v: Vec<f64>) -> f64 {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    }

    #[test]
    #[ignore = "needs root, vcan, gpio-sim and vivid: runs in the kernel-in-the-loop guest (scripts/kernel-in-the-loop.sh)"]
    fn videtd_rebuilds_the_relief_from_v4l2_cameras_and_vibrates_the_colour_under_the_finger() {
        let d = Device::start_with(true, |dir| {
            ideal_stereo_calibration(dir);
            let [left, right] = devices();
            // The same test pattern in both cameras would be a scene at infinity. Both take
            // vivid's HDMI input at 640x480 (it can crop, the webcam input cannot); the right
            // one sees the pattern cropped 16 px from its left edge and scaled back to 640 px:
            // the bars' vertical edges 4 to 12 px of disparity away, a scene 2.5 to 7.5 m off.
            for camera in [&left, &right] {
                run("v4l2-ctl", &["-d", camera, "-i", "3"]);
                run(
                    "v4l2-ctl",
                    &["-d", camera, "--set-dv-bt-timings", "index=0"],
                );
                run(
                    "v4l2-ctl",
                    &[
                        "-d",
                        camera,
                        "--set-fmt-video=width=640,height=480,pixelformat=YUYV",
                    ],
                );
            }
            run(
                "v4l2-ctl",
                &[
                    "-d",
                    &right,
                    "--set-selection",
                    "target=crop,left=16,top=0,width=624,height=480",
                ],
            );
            [left, right]
        });
        // Reliefs are made from paired, rectified frames on the vision thread (`reliefs N whole
        // + M local`: whole-image runs and updates around the finger).
        let deadline = Instant::now() + Duration::from_secs(120);
        loop {
            let log = d.log();
            assert!(!log.contains("the check wall is rendered instead"), "{log}");
            let rebuilt = log
                .lines()
                .filter_map(|l| l.split(" | reliefs ").nth(1))
                .filter_map(|r| {
                    let words: Vec<&str> = r.split_whitespace().collect();
                    Some(words.first()?.parse::<u64>().ok()? + words.get(3)?.parse::<u64>().ok()?)
                })
                .max()
                .unwrap_or(0);
            if rebuilt >= 3 {
                break;
            }
            assert!(
                Instant::now() < deadline,
                "no relief rebuilt from the cameras: {log}"
            );
            std::thread::sleep(Duration::from_millis(200));
        }
        // The colour under the finger (the bar of vivid's test pattern the operator's finger
        // is over; it changes as the finger slides) plays on the vibrotactors: pulses at the
        // 75 Hz carrier, 20 % (Mid) or 50 % (High) of each period.
        // An emulated CPU wakes the pattern's thread and this sampler late at times, and a
        // period stretched past 25 ms is not counted: it is watched longer for its ten periods.
        let span = Duration::from_secs(if emulated_cpu() { 20 } else { 6 });
        let pulses = sample_pulses(&d.chip, span);
        let mut pulsing = 0;
        for (line, p) in VIBROTACTOR_LINES.iter().zip(&pulses) {
            // Each pulse's period (to the next rising edge) and its duty (its high time over
            // that period, so at most 1 whatever the sampler's wake-ups do to either edge),
            // inside runs of pulses (a gap of a silent Low level is not a period).
            let (periods, duties): (Vec<f64>, Vec<f64>) = p
                .windows(2)
                .map(|w| {
                    let period = (w[1].0 - w[0].0).as_secs_f64();
                    (period, w[0].1.as_secs_f64() / period)
                })
                .filter(|(period, _)| *period < 0.025)
                .unzip();
            if periods.len() < 10 {
                continue;
            }
            pulsing += 1;
            let hz = 1.0 / median(periods);
            let duty = median(duties);
            if emulated_cpu() {
                // Wake-ups milliseconds late (on the pattern's thread and on this sampler) move
                // each edge by a good part of the 6.7 ms half-period: an emulated CPU is only
                // asked for a pulse train near the carrier (within a factor of two) with neither
                // level stuck. The timing itself is judged on real CPUs.
                assert!(
                    (37.5..150.0).contains(&hz),
                    "line {line} pulses at {hz:.1} Hz"
                );
                assert!(
                    (0.05..0.95).contains(&duty),
                    "line {line} pulses {:.0} % of each period",
                    duty * 100.0
                );
            } else {
                assert!((hz - 75.0).abs() < 7.5, "line {line} pulses at {hz:.1} Hz");
                assert!(
                    (duty - 0.2).abs() < 0.1 || (duty - 0.5).abs() < 0.1,
                    "line {line} pulses {:.0} % of each period",
                    duty * 100.0
                );
            }
        }
        assert!(pulsing > 0, "no vibrotactor pulses: {}", d.log());
    }
}
