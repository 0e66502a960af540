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

use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::{Duration, Instant};

use gpiosim::Simpleton;
use videt::socket::{request, Request, StatusReport};
use videt::telemetry::read_log;
use videt_control::safety::SafetyState;

const GUEST: &str =
    "needs root, vcan, gpio-sim and vivid: runs in the kernel-in-the-loop guest (scripts/kernel-in-the-loop.sh)";

/// The configuration's GPIO lines.
const ESTOP_LINE: u32 = 17;
const VIBROTACTOR_LINES: [u32; 3] = [22, 23, 24];

/// Periods a drive's process data may be missing in the guest (`drives.max_missed_cycles`;
/// 1 on the device; 100 is the most the configuration allows): the emulated CPU answers late
/// at times, for tens of ms while the vision thread runs, and on a loaded host for longer.
const GUEST_MISSED_CYCLES: u32 = 100;

/// Silence after which a drive's heartbeat is lost in the guest (`drives.heartbeat_timeout_ms`;
/// 50 on the device): the emulated CPU that produces the heartbeats stalls for tens of ms. Well
/// beyond [`GUEST_MISSED_CYCLES`] periods even at a third of the rate, so that silent drives
/// are told by their missing process data, as on the device.
const GUEST_HEARTBEAT_TIMEOUT_MS: u32 = 2000;

/// Part of the period the service waits for the drives' answers to SYNC in the guest
/// (`drives.pdo_wait_fraction`; 0.6 on the device, 0.95 the most it allows): the drive process
/// shares the control thread's emulated CPU and answers in the time the control thread waits,
/// which under emulation is often more than 0.6 ms.
const GUEST_PDO_WAIT_FRACTION: f64 = 0.95;

/// Time a drive's power state machine is given in the guest (`drives.power_timeout_ms`; 500
/// on the device): each step of it is a frame the emulated drive process answers, late at times.
const GUEST_POWER_TIMEOUT_MS: u32 = 5000;

/// Age at which a strain-gauge sample is stale in the guest (`sensors.stale_after_ms`; 20 on
/// the device).
const GUEST_STALE_AFTER_MS: u32 = 200;

/// Monotonic clock, ns: the same clock as the session log's period starts.
fn monotonic_ns() -> u64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}

/// The binary `name`: from `VIDET_BIN_DIR` when set (the suite runs optimized binaries built
/// with the cameras' feature), else the one cargo built for this test.
fn bin(name: &str, built: &str) -> PathBuf {
    match std::env::var_os("VIDET_BIN_DIR") {
        Some(dir) => Path::new(&dir).join(name),
        None => PathBuf::from(built),
    }
}

fn videt_bin() -> PathBuf {
    bin("videt", env!("CARGO_BIN_EXE_videt"))
}

fn videtd_bin() -> PathBuf {
    bin("videtd", env!("CARGO_BIN_EXE_videtd"))
}

fn run(cmd: &str, args: &[&str]) {
    let out = Command::new(cmd).args(args).output().unwrap();
    assert!(
        out.status.success(),
        "{cmd} {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// A vcan interface of this test's own, removed when dropped.
struct Vcan(String);

impl Vcan {
    fn new() -> Vcan {
        static NEXT: AtomicU32 = AtomicU32::new(0);
        let name = format!(
            "vt{}x{}",
            std::process::id() % 10000,
            NEXT.fetch_add(1, Ordering::Relaxed)
        );
        run("ip", &["link", "add", "dev", &name, "type", "vcan"]);
        run("ip", &["link", "set", "up", &name]);
        Vcan(name)
    }
    fn set_up(&self, up: bool) {
        run(
            "ip",
            &["link", "set", if up { "up" } else { "down" }, &self.0],
        );
    }
}

impl Drop for Vcan {
    fn drop(&mut self) {
        let _ = Command::new("ip").args(["link", "del", &self.0]).status();
    }
}

/// A child process killed when dropped.
struct Process(Child);

impl Process {
    fn kill(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
    /// Wait up to `secs` for the process to exit.
    fn wait_exit(&mut self, secs: f64) -> Option<ExitStatus> {
        let deadline = Instant::now() + Duration::from_secs_f64(secs);
        while Instant::now() < deadline {
            if let Some(s) = self.0.try_wait().unwrap() {
                return Some(s);
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        None
    }
    fn signal(&self, signal: i32) {
        // SAFETY: sending a signal to our own child.
        unsafe { libc::kill(self.0.id() as i32, signal) };
    }
}

impl Drop for Process {
    fn drop(&mut self) {
        self.kill();
    }
}

/// The configuration of the guest's device: the example configuration with the test's CAN
/// interface, GPIO chip and files, tension read through the drives' analog inputs (no SPI in a
/// PC guest), and the emulator's allowances: the deadline-overrun policy counts overruns up to
/// the most the configuration allows before it trips, the drives tolerate the emulator's late
/// answers as the twin's CAN bus does, and the cameras are whatever `cameras` names. Colour
/// rendering is on only when `colour` is: its 1.5 kHz vibration thread is a good part of what
/// an emulated CPU can do, and only the camera test judges it.
fn guest_config(dir: &Path, can: &str, chip: &Path, cameras: [&str; 2], colour: bool) -> PathBuf {
    let example = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("config/videt.example.toml"),
    )
    .unwrap();
    let mut t: toml::Table = example.parse().unwrap();
    let set = |t: &mut toml::Table, section: &str, key: &str, v: toml::Value| {
        t.get_mut(section)
            .and_then(|s| s.as_table_mut())
            .unwrap_or_else(|| panic!("[{section}] in the example"))
            .insert(key.into(), v);
    };
    let s = |x: &str| toml::Value::String(x.into());
    let p = |x: &Path| toml::Value::String(x.display().to_string());
    set(&mut t, "drives", "can_interface", s(can));
    set(&mut t, "sensors", "adc", s("drive"));
    set(&mut t, "sensors", "gpio_chip", p(chip));
    set(
        &mut t,
        "sensors",
        "estop_line",
        toml::Value::Integer(ESTOP_LINE.into()),
    );
    set(
        &mut t,
        "sensors",
        "vibrotactor_lines",
        toml::Value::Array(
            VIBROTACTOR_LINES
                .iter()
                .map(|l| toml::Value::Integer((*l).into()))
                .collect(),
        ),
    );
    // The analog inputs: 1 mN per count, zero at count 0.
    set(
        &mut t,
        "sensors",
        "newtons_per_count",
        toml::Value::Array(vec![toml::Value::Float(1e-3); 3]),
    );
    // An emulated CPU answers late at times: the drives' process data may be missing for a
    // few periods.
    set(
        &mut t,
        "drives",
        "max_missed_cycles",
        toml::Value::Integer(GUEST_MISSED_CYCLES.into()),
    );
    // ... and answer late in the period ...
    set(
        &mut t,
        "drives",
        "pdo_wait_fraction",
        toml::Value::Float(GUEST_PDO_WAIT_FRACTION),
    );
    // ... and step through their power states late ...
    set(
        &mut t,
        "drives",
        "power_timeout_ms",
        toml::Value::Integer(GUEST_POWER_TIMEOUT_MS.into()),
    );
    // ... and so may their heartbeats ...
    set(
        &mut t,
        "drives",
        "heartbeat_timeout_ms",
        toml::Value::Integer(GUEST_HEARTBEAT_TIMEOUT_MS.into()),
    );
    // ... and the strain-gauge samples they carry (20 ms on the device).
    set(
        &mut t,
        "sensors",
        "stale_after_ms",
        toml::Value::Integer(GUEST_STALE_AFTER_MS.into()),
    );
    // An emulated CPU wakes the loop milliseconds late at times: count, do not trip.
    set(
        &mut t,
        "realtime",
        "max_consecutive_overruns",
        toml::Value::Integer(10000),
    );
    set(
        &mut t,
        "realtime",
        "cpu_wakeup_latency_us",
        toml::Value::Integer(-1),
    );
    set(
        &mut t,
        "vision",
        "devices",
        toml::Value::Array(cameras.iter().map(|c| s(c)).collect()),
    );
    set(
        &mut t,
        "vision",
        "stereo_calibration",
        p(&dir.join("stereo.json")),
    );
    set(&mut t, "colour", "enabled", toml::Value::Boolean(colour));
    set(&mut t, "telemetry", "directory", p(&dir.join("logs")));
    set(&mut t, "socket", "path", p(&socket_path(dir)));
    set(
        &mut t,
        "files",
        "calibration",
        p(&dir.join("calibration.toml")),
    );
    set(&mut t, "files", "motors_lock", p(&dir.join("motors.lock")));
    let path = dir.join("videt.toml");
    std::fs::write(&path, toml::to_string(&t).unwrap()).unwrap();
    path
}

/// The control socket of the service whose files are in `dir`: on a local filesystem (the
/// test directories may be on a share that cannot hold sockets).
fn socket_path(dir: &Path) -> PathBuf {
    let name = dir.file_name().unwrap().to_string_lossy();
    std::env::temp_dir().join(format!("videtd-{name}.sock"))
}

/// The twin served as a rig on `can` (and its true calibration written beside the config),
/// its drives on the control thread's CPU (`realtime.control_cpu`) as the CAN twin's are: the
/// emulated CPU the cameras and the tests load does not delay their answers.
fn start_rig(config: &Path, can: &str) -> Process {
    let dir = config.parent().unwrap();
    let control_cpu = videt_rt_config::Config::load(config)
        .unwrap()
        .realtime
        .control_cpu;
    let mut rig = Command::new(videt_bin());
    rig.args(["sim-rig", "--priority", "70", "--can", can]);
    // -1: the control thread is not pinned, nor are the drives.
    if control_cpu >= 0 {
        rig.args(["--cpu", &control_cpu.to_string()]);
    }
    let child = rig
        .arg("--config")
        .arg(config)
        .arg("--calibration-out")
        .arg(dir.join("calibration.toml"))
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(dir.join("sim-rig.log")).unwrap())
        .spawn()
        .unwrap();
    let deadline = Instant::now() + Duration::from_secs(30);
    while !dir.join("calibration.toml").exists() {
        assert!(Instant::now() < deadline, "videt sim-rig did not start");
        std::thread::sleep(Duration::from_millis(20));
    }
    Process(child)
}

/// `videtd` in device mode (no `--sim`) with `config`, its log and status lines in
/// `videtd.log` beside it.
fn start_videtd(config: &Path) -> Process {
    let log = std::fs::File::create(config.with_file_name("videtd.log")).unwrap();
    let child = Command::new(videtd_bin())
        .arg("--config")
        .arg(config)
        .env("RUST_LOG", "info")
        .stdout(log.try_clone().unwrap())
        .stderr(log)
        .spawn()
        .unwrap();
    Process(child)
}

fn status(socket: &Path) -> Option<StatusReport> {
    request(socket, &Request::Status, Duration::from_secs(5))
        .ok()
        .and_then(|r| r.status)
}

fn wait_for(
    socket: &Path,
    secs: f64,
    what: &str,
    check: impl Fn(&StatusReport) -> bool,
) -> StatusReport {
    let deadline = Instant::now() + Duration::from_secs_f64(secs);
    let mut last = None;
    loop {
        if let Some(s) = status(socket) {
            if check(&s) {
                return s;
            }
            last = Some(s);
        }
        assert!(Instant::now() < deadline, "{what}: last status {last:?}");
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// The one session log in `dir/logs`, checked to replay bit for bit.
fn session_log(dir: &Path) -> videt::telemetry::Log {
    let logs: Vec<_> = std::fs::read_dir(dir.join("logs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "vlog"))
        .collect();
    assert_eq!(logs.len(), 1, "{logs:?}");
    let log = read_log(&logs[0]).unwrap();
    // What the drives, sensors and e-stop delivered through the kernel replays bit for bit.
    let r = videt::replay::replay(&log, &Default::default()).unwrap();
    assert!(
        r.identical() && !r.replayed.is_empty(),
        "replay of {}: {:?} (stopped early: {:?})",
        logs[0].display(),
        r.first_divergence,
        r.stopped_early
    );
    log
}

/// Periods of the log that started after `t_ns` and still rendered forces before the drives
/// were powered off for `reason` (the fault's reaction time in periods; a fault seen before
/// `t_ns` gives 0), and whether the log shows that power-off at all.
fn periods_to_power_off(log: &videt::telemetry::Log, t_ns: u64, reason: &str) -> (usize, bool) {
    let normal_after = log
        .records
        .iter()
        .filter(|r| r.time.0 > t_ns && r.safety == SafetyState::Normal)
        .count();
    let reached = log.records.iter().any(|r| {
        r.safety.power_off() && r.safety.reason().is_some_and(|why| why.as_str() == reason)
    });
    (normal_after, reached)
}

/// The stereo calibration of an ideal rig of two 640x480 cameras (f = 500 px, no
/// distortion, a 6 cm baseline, already rectified), as the vivid cameras are: the identity
/// rectification leaves their test patterns as they are.
fn ideal_stereo_calibration(dir: &Path) {
    let (f, cx, cy, b) = (500.0, 320.0, 240.0, 0.06);
    let k = serde_json::json!([[f, 0.0, cx], [0.0, f, cy], [0.0, 0.0, 1.0]]);
    let eye = serde_json::json!([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]);
    let p =
        |tx: f64| serde_json::json!([[f, 0.0, cx, tx], [0.0, f, cy, 0.0], [0.0, 0.0, 1.0, 0.0]]);
    let calibration = serde_json::json!({
        "format_version": 1,
        "image_width": 640,
        "image_height": 480,
        "m1": k, "d1": [0.0, 0.0, 0.0, 0.0, 0.0],
        "m2": k, "d2": [0.0, 0.0, 0.0, 0.0, 0.0],
        "r": eye, "t_m": [-b, 0.0, 0.0],
        "r1": eye, "r2": eye,
        "p1": p(0.0), "p2": p(-f * b),
        "q": [[1.0, 0.0, 0.0, -cx], [0.0, 1.0, 0.0, -cy], [0.0, 0.0, 0.0, f], [0.0, 0.0, 1.0 / b, 0.0]],
        "rms_left_px": 0.1, "rms_right_px": 0.1, "rms_stereo_px": 0.1,
        "epipolar_error_px": 0.0,
        "created_unix_s": 1_700_000_000u64,
    });
    std::fs::write(dir.join("stereo.json"), calibration.to_string()).unwrap();
}

/// A directory for one test's files: under `VIDET_KIL_KEEP` when set (the suite keeps them
/// there for the host to read: configuration, service log, session log), else a temporary one.
fn test_dir() -> tempfile::TempDir {
    match std::env::var_os("VIDET_KIL_KEEP") {
        Some(root) => {
            std::fs::create_dir_all(&root).unwrap();
            let mut dir = tempfile::Builder::new()
                .prefix("test-")
                .tempdir_in(root)
                .unwrap();
            dir.disable_cleanup(true);
            dir
        }
        None => tempfile::tempdir().unwrap(),
    }
}

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
    d.assert_drive_fault_within(on_bus_ns, 2, "the EMCY", "drive 1: emergency 0x2310");
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
        let pulses = sample_pulses(&d.chip, Duration::from_secs(6));
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
