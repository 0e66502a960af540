//! Crash safety of the files the product writes: a process killed with SIGKILL at a random
//! point of a calibration save leaves the old or the new calibration, never a mix or nothing;
//! killed while writing a session log, the log reads up to its last whole record, as a session
//! that ended without closing.
//!
//! The writer runs in a child process (this test binary re-run with `VIDET_CRASH_CHILD` set),
//! which the test kills after a random delay.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use videt_config::calibration::{utc_timestamp, Calibration, WorkspaceRecord, FORMAT_VERSION};
use videt_hal::MonoTime;
use videt_runtime::control_loop::{CycleObserver, WindowStats};
use videt_runtime::cycle::CycleRecord;
use videt_runtime::telemetry::{self, LogHeader, SessionInfo, SessionRecording};

const CHILD_ENV: &str = "VIDET_CRASH_CHILD";
const TRIALS: usize = 24;

/// A valid calibration, its identity in `created_unix_s`.
fn calibration(created_unix_s: u64) -> Calibration {
    let (a, b, c) = (0.37_f64, 0.35_f64, 0.31_f64);
    let x2 = (a * a + b * b - c * c) / (2.0 * a);
    let y2 = (b * b - x2 * x2).sqrt();
    Calibration {
        format: FORMAT_VERSION,
        created_unix_s,
        created_utc: utc_timestamp(created_unix_s),
        source: "twin".into(),
        sides_m: [a, b, c],
        residuals_m: [1e-5, -2e-5, -1e-5, 3e-5, 2e-5, -3e-5],
        guides_m: [[0.0; 3], [a, 0.0, 0.0], [x2, y2, 0.0]],
        wire_zero_counts: [123, -4_567_890, 42],
        metres_per_count: 2.5e-6,
        workspace: WorkspaceRecord {
            force_n: 3.0,
            max_condition: 20.0,
            volume_m3: 0.01,
            min_m: [0.0, 0.0, 0.1],
            max_m: [0.3, 0.3, 0.6],
            required_length_m: [0.7, 0.7, 0.7],
        },
    }
}

/// The child's work, chosen by `VIDET_CRASH_CHILD=<what>:<path>`; never returns.
fn child_main(spec: &str) -> ! {
    let (what, path) = spec.split_once(':').expect("what:path");
    let path = Path::new(path);
    match what {
        "calibration" => {
            // Save calibrations 1, 2, 3, ... one after the other, as fast as possible.
            let mut k = 1_795_000_000u64;
            loop {
                k += 1;
                calibration(k).save(path).expect("save");
            }
        }
        "log" => {
            let (mut producer, _writer) = telemetry::start_session(
                path,
                LogHeader {
                    rate_hz: 1000,
                    start_unix_ns: 1,
                },
                SessionRecording {
                    session: Some(SessionInfo::new(
                        "crash test",
                        videt_config::Config::default(),
                    )),
                    ..SessionRecording::default()
                },
                1 << 14,
            )
            .expect("log");
            // Periods in bursts of 4000 (the writer then fills and flushes its buffer in the
            // middle of frames, as a busy service does), forever.
            let mut cycle = 0u64;
            loop {
                let record = CycleRecord {
                    cycle,
                    time: MonoTime(cycle * 1_000_000),
                    position_m: [cycle as f64 * 1e-6, 0.1, 0.3],
                    released_wire: -1,
                    ..CycleRecord::default()
                };
                producer.observe(&record, &WindowStats::default());
                cycle += 1;
                if cycle.is_multiple_of(4000) {
                    std::thread::sleep(Duration::from_millis(15));
                }
            }
        }
        other => panic!("unknown child work {other}"),
    }
}

/// Start the child doing `what` on `path`.
fn spawn_child(what: &str, path: &Path) -> Child {
    Command::new(std::env::current_exe().unwrap())
        .args([
            "--exact",
            "crash_child",
            "--nocapture",
            "--test-threads",
            "1",
        ])
        .env(CHILD_ENV, format!("{what}:{}", path.display()))
        .stdout(Stdio::null())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap()
}

/// Not a test of its own: the entry point of the child processes.
#[test]
fn crash_child() {
    if let Ok(spec) = std::env::var(CHILD_ENV) {
        child_main(&spec);
    }
}

/// A deterministic sequence of kill delays, 5-120 ms.
fn delays() -> impl Iterator<Item = Duration> {
    let mut x = 0x853c_49e6_748f_ea9bu64;
    std::iter::repeat_with(move || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        Duration::from_micros(5_000 + x % 115_000)
    })
}

/// Wait until `path` holds at least a log header (the child has started the session), up to
/// 20 s.
fn wait_for(path: &Path) {
    let deadline = Instant::now() + Duration::from_secs(20);
    let started = |p: &Path| std::fs::metadata(p).is_ok_and(|m| m.len() >= 32);
    while !started(path) {
        assert!(
            Instant::now() < deadline,
            "{} never appeared",
            path.display()
        );
        std::thread::sleep(Duration::from_millis(2));
    }
}

fn kill(mut child: Child) {
    // SIGKILL: no destructor, no flush, no unwinding.
    child.kill().unwrap();
    child.wait().unwrap();
}

#[test]
fn a_calibration_save_killed_anywhere_leaves_the_old_or_the_new_calibration() {
    let dir = tempfile::tempdir().unwrap();
    let path: PathBuf = dir.path().join("calibration.toml");
    calibration(1_700_000_000).save(&path).unwrap();
    let mut previous = Calibration::load(&path).unwrap().created_unix_s;
    for (trial, delay) in delays().take(TRIALS).enumerate() {
        let child = spawn_child("calibration", &path);
        std::thread::sleep(delay);
        kill(child);
        let now = Calibration::load(&path)
            .unwrap_or_else(|e| panic!("trial {trial} (killed after {delay:?}): {e}"));
        // The file is a whole calibration, the one before or one saved since; a complete
        // calibration was never replaced by an older one.
        assert!(
            now.created_unix_s == previous || now.created_unix_s > 1_795_000_000,
            "trial {trial}: {} after {previous}",
            now.created_unix_s
        );
        assert_eq!(now, calibration(now.created_unix_s), "trial {trial}");
        previous = now.created_unix_s;
    }
    // Temporary files a killed save leaves are its own (named after its process), never read
    // as the calibration.
    for entry in std::fs::read_dir(dir.path()).unwrap() {
        let name = entry.unwrap().file_name().into_string().unwrap();
        assert!(
            name == "calibration.toml" || name == "calibration.toml.bak" || name.starts_with('.'),
            "{name}"
        );
    }
}

#[test]
fn a_session_log_killed_mid_write_reads_up_to_its_last_whole_record() {
    let dir = tempfile::tempdir().unwrap();
    let mut damaged = 0;
    for (trial, delay) in delays().take(TRIALS).enumerate() {
        let path = dir.path().join(format!("s{trial}.vlog"));
        let child = spawn_child("log", &path);
        wait_for(&path);
        std::thread::sleep(delay);
        kill(child);
        let bytes = std::fs::read(&path).unwrap();
        let log = telemetry::parse_log(&bytes)
            .unwrap_or_else(|e| panic!("trial {trial} ({} bytes): {e}", bytes.len()));
        // Every whole record is there, in order; what follows the last one is at most one
        // block's worth (a batch of 256 KiB of frames, compressed), reported as damage.
        for (k, r) in log.records.iter().enumerate() {
            assert_eq!(r.cycle, k as u64, "trial {trial}");
            assert_eq!(r.position_m[0], k as f64 * 1e-6, "trial {trial}");
        }
        let block = 8 + 256 * 1024 + 4;
        assert!(
            log.truncated_bytes < block,
            "trial {trial}: {}",
            log.truncated_bytes
        );
        assert_eq!(
            log.truncated_bytes > 0,
            log.damage.is_some(),
            "trial {trial}"
        );
        // Killed, it never closed the log: on a frame boundary or not, it reads as such.
        assert!(!log.closed(), "trial {trial}");
        assert!(
            log.end_note().starts_with("session ended without closing"),
            "trial {trial}"
        );
        if let Some(d) = &log.damage {
            assert!(d.what.contains("incomplete"), "trial {trial}: {d:?}");
            damaged += 1;
        }
    }
    eprintln!("{damaged} of {TRIALS} logs ended in a partial frame");
}
