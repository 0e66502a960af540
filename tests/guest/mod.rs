//! What the kernel-in-the-loop tests share: the guest's CAN interfaces and processes, the
//! device configuration with the emulator's allowances, the service's binaries, socket and
//! session log. These tests need root and the guest's kernel drivers (vcan, gpio-sim, vivid):
//! they run in the kernel-in-the-loop guest (`scripts/kernel-in-the-loop.sh`).

// Each test crate uses a part of these.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::{Duration, Instant};

use videt_control::safety::SafetyState;
use videt_runtime::telemetry::read_log;
use videt_service::socket::{request, Request, StatusReport};

pub const GUEST: &str =
    "needs root, vcan, gpio-sim and vivid: runs in the kernel-in-the-loop guest (scripts/kernel-in-the-loop.sh)";

/// The configuration's GPIO lines.
pub const ESTOP_LINE: u32 = 17;
pub const VIBROTACTOR_LINES: [u32; 3] = [22, 23, 24];

/// Periods a drive's process data may be missing in the guest (`drives.max_missed_cycles`;
/// 1 on the device; 100 is the most the configuration allows): the emulated CPU answers late
/// at times, for tens of ms while the vision thread runs, and on a loaded host for longer.
pub const GUEST_MISSED_CYCLES: u32 = 100;

/// Silence after which a drive's heartbeat is lost in the guest (`drives.heartbeat_timeout_ms`;
/// 50 on the device): the emulated CPU that produces the heartbeats stalls for tens of ms. Well
/// beyond [`GUEST_MISSED_CYCLES`] periods even at a third of the rate, so that silent drives
/// are told by their missing process data, as on the device.
pub const GUEST_HEARTBEAT_TIMEOUT_MS: u32 = 2000;

/// The wall's stiffness in the guest, N/m (`control.stiffness_n_per_m`; 2000 on the device):
/// the emulated loop's rate holds 800 N/m at the default damping.
pub const GUEST_STIFFNESS_N_PER_M: f64 = 800.0;

/// Part of the period the service waits for the drives' answers to SYNC in the guest
/// (`drives.pdo_wait_fraction`; 0.6 on the device, 0.95 the most it allows): the drive process
/// shares the control thread's emulated CPU and answers in the time the control thread waits,
/// which under emulation is often more than 0.6 ms.
pub const GUEST_PDO_WAIT_FRACTION: f64 = 0.95;

/// Time a drive's power state machine is given in the guest (`drives.power_timeout_ms`; 500
/// on the device): each step of it is a frame the emulated drive process answers, late at times.
pub const GUEST_POWER_TIMEOUT_MS: u32 = 5000;

/// Age at which a strain-gauge sample is stale in the guest (`sensors.stale_after_ms`; 20 on
/// the device; 1000 is the most the configuration allows). The samples come with the drives'
/// process data, which may be missing for [`GUEST_MISSED_CYCLES`] periods: at the 150-400 Hz
/// an emulated CPU runs the loop at, 250-660 ms. Below that, late process data was a sensor
/// fault before it was a drive fault (at 200 ms, the systemd guest's checks met one a run).
pub const GUEST_STALE_AFTER_MS: u32 = 1000;

/// Monotonic clock, ns: the same clock as the session log's period starts.
pub fn monotonic_ns() -> u64 {
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
pub fn bin(name: &str, built: impl FnOnce() -> PathBuf) -> PathBuf {
    match std::env::var_os("VIDET_BIN_DIR") {
        Some(dir) => Path::new(&dir).join(name),
        None => built(),
    }
}

pub fn videt_bin() -> PathBuf {
    bin("videt", || PathBuf::from(env!("CARGO_BIN_EXE_videt")))
}

pub fn videtd_bin() -> PathBuf {
    bin("videtd", videt_testkit::videtd_bin)
}

pub fn run(cmd: &str, args: &[&str]) {
    let out = Command::new(cmd).args(args).output().unwrap();
    assert!(
        out.status.success(),
        "{cmd} {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// A vcan interface of this test's own, removed when dropped.
pub struct Vcan(pub String);

impl Vcan {
    pub fn new() -> Vcan {
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
    pub fn set_up(&self, up: bool) {
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
pub struct Process(pub Child);

impl Process {
    pub fn kill(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
    /// Wait up to `secs` for the process to exit.
    pub fn wait_exit(&mut self, secs: f64) -> Option<ExitStatus> {
        let deadline = Instant::now() + Duration::from_secs_f64(secs);
        while Instant::now() < deadline {
            if let Some(s) = self.0.try_wait().unwrap() {
                return Some(s);
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        None
    }
    pub fn signal(&self, signal: i32) {
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
pub fn guest_config(
    dir: &Path,
    can: &str,
    chip: &Path,
    cameras: [&str; 2],
    colour: bool,
) -> PathBuf {
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
    // ... and so may their heartbeats, their reading of the service's and their answers to
    // SDO requests (a drive stack on the emulated CPU stalls for tens of ms) ...
    for key in [
        "heartbeat_timeout_ms",
        "host_silence_timeout_ms",
        "sdo_timeout_ms",
    ] {
        set(
            &mut t,
            "drives",
            key,
            toml::Value::Integer(GUEST_HEARTBEAT_TIMEOUT_MS.into()),
        );
    }
    // ... and the strain-gauge samples they carry (20 ms on the device).
    set(
        &mut t,
        "sensors",
        "stale_after_ms",
        toml::Value::Integer(GUEST_STALE_AFTER_MS.into()),
    );
    // The emulated loop runs at a quarter to a half of its rate (230-450 Hz), and a wall's
    // Z-width falls with the rate (docs/haptic-bench.md): the default 2000 N/m wall oscillates
    // there until the speed limit trips. The guest renders a wall its loop holds.
    set(
        &mut t,
        "control",
        "stiffness_n_per_m",
        toml::Value::Float(GUEST_STIFFNESS_N_PER_M),
    );
    // An emulated CPU runs the period late more often than not, for tens of seconds at a
    // time on a slow host: count, do not trip.
    set(
        &mut t,
        "realtime",
        "max_consecutive_overruns",
        toml::Value::Integer(1_000_000),
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
pub fn socket_path(dir: &Path) -> PathBuf {
    let name = dir.file_name().unwrap().to_string_lossy();
    std::env::temp_dir().join(format!("videtd-{name}.sock"))
}

/// Seconds of the rig's world per wall-clock second in the guest. The emulated CPU runs the
/// 1 kHz control loop at 250-400 Hz: in a world on the wall clock, the wires and the operator
/// then move three or four times as far between two periods as on the backpack, and a slack
/// wire wound in between two of them outruns the wire-speed trip. A quarter keeps about one
/// period per millisecond of the rig's world, and a quarter of its physics to compute.
pub const GUEST_TIME_SCALE: &str = "0.25";

/// The twin served as a rig on `can` (and its true calibration written beside the config),
/// its world in slow motion ([`GUEST_TIME_SCALE`]),
/// its drives on the control thread's CPU (`realtime.control_cpu`) as the CAN twin's are: the
/// emulated CPU the cameras and the tests load does not delay their answers.
pub fn start_rig(config: &Path, can: &str) -> Process {
    start_rig_with(config, can, &[])
}

/// [`start_rig`] with more of `videt sim-rig`'s arguments (`--at-rest`, `--sim-fault`, ...);
/// with `--technician-stdin` among them, its stdin is a pipe the test writes to.
pub fn start_rig_with(config: &Path, can: &str, extra: &[&str]) -> Process {
    let dir = config.parent().unwrap();
    let control_cpu = videt_config::Config::load(config)
        .unwrap()
        .realtime
        .control_cpu;
    let mut rig = Command::new(videt_bin());
    rig.args(["sim-rig", "--priority", "70", "--can", can]);
    if !extra.contains(&"--time-scale") {
        rig.args(["--time-scale", GUEST_TIME_SCALE]);
    }
    // -1: the control thread is not pinned, nor are the drives.
    if control_cpu >= 0 {
        rig.args(["--cpu", &control_cpu.to_string()]);
    }
    if extra.contains(&"--technician-stdin") {
        rig.stdin(Stdio::piped());
    }
    let child = rig
        .args(extra)
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
pub fn start_videtd(config: &Path) -> Process {
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

pub fn status(socket: &Path) -> Option<StatusReport> {
    request(socket, &Request::Status, Duration::from_secs(5))
        .ok()
        .and_then(|r| r.status)
}

pub fn wait_for(
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
pub fn session_log(dir: &Path) -> videt_runtime::telemetry::Log {
    let logs: Vec<_> = std::fs::read_dir(dir.join("logs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "vlog"))
        .collect();
    assert_eq!(logs.len(), 1, "{logs:?}");
    let log = read_log(&logs[0]).unwrap();
    // What the drives, sensors and e-stop delivered through the kernel replays bit for bit.
    let r = videt_tools::replay::replay(&log, &Default::default()).unwrap();
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
pub fn periods_to_power_off(
    log: &videt_runtime::telemetry::Log,
    t_ns: u64,
    reason: &str,
) -> (usize, bool) {
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
pub fn ideal_stereo_calibration(dir: &Path) {
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
pub fn test_dir() -> tempfile::TempDir {
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
