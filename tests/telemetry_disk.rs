//! The session log on a disk that fills under a running `videtd`: the failure is said at once
//! (the journal's line, the status), the control loop goes on undisturbed, the writes resume
//! once there is room, and the log reads whole with the lost periods counted.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use videt_control::safety::SafetyState;
use videt_runtime::telemetry::read_log;
use videt_service::socket::{request, Request, StatusReport};
use videt_testkit::SmallDisk;

fn status(socket: &Path) -> Option<StatusReport> {
    request(socket, &Request::Status, Duration::from_secs(2))
        .ok()
        .and_then(|r| r.status)
}

/// Poll the status until `check` holds; `None` after `secs`.
fn wait_for(
    socket: &Path,
    secs: f64,
    check: impl Fn(&StatusReport) -> bool,
) -> Option<StatusReport> {
    let deadline = Instant::now() + Duration::from_secs_f64(secs);
    while Instant::now() < deadline {
        if let Some(s) = status(socket).filter(|s| check(s)) {
            return Some(s);
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    None
}

#[test]
fn a_full_disk_is_said_at_once_the_loop_goes_on_and_the_log_resumes_when_there_is_room() {
    let Some(disk) = SmallDisk::mount_or_skip(8_000_000) else {
        return;
    };
    // About 3 s of session log left (some 0.15 MB a second, compressed): the disk fills while
    // the service runs.
    let filler = disk.fill_leaving(450_000).unwrap();
    let work = tempfile::tempdir().unwrap();
    let socket = work.path().join("ctl.sock");
    let stderr_path = work.path().join("stderr.txt");
    let logs = disk.path().join("logs");
    // No free space kept: the disk fills (retention's pause is the writer's tests').
    let config = work.path().join("videt.toml");
    std::fs::write(&config, "[telemetry]\nmin_free_mb = 0\n").unwrap();
    let mut child = Command::new(videt_testkit::videtd_bin())
        .args(["--sim", "--scene", "box", "--duration", "16", "--config"])
        .arg(&config)
        .arg("--telemetry-dir")
        .arg(&logs)
        .arg("--socket")
        .arg(&socket)
        .env("RUST_LOG", "warn")
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(&stderr_path).unwrap())
        .spawn()
        .unwrap();
    let stderr = || std::fs::read_to_string(&stderr_path).unwrap_or_default();

    let failing = wait_for(&socket, 12.0, |s| s.telemetry_error.is_some());
    let Some(failing) = failing else {
        let _ = child.kill();
        panic!("the disk never filled: {}", stderr());
    };
    // Said at once: in the service's log while it runs, and in its status.
    assert!(
        failing
            .telemetry_error
            .as_deref()
            .unwrap()
            .contains("No space left"),
        "{failing:?}"
    );
    assert!(stderr().contains("session log not written"), "{}", stderr());
    assert_eq!(failing.safety, "normal", "{failing:?}");
    let cycles_then = failing.cycles;

    // Still failing a second later, the loop running on.
    std::thread::sleep(Duration::from_secs(1));
    let later = status(&socket).expect("the service answers");
    assert!(
        later.telemetry_error.is_some() && later.telemetry_lost > 0,
        "{later:?}"
    );
    assert!(later.cycles >= cycles_then + 800, "{later:?}");

    // Room again: the writes resume within a retry or two.
    std::fs::remove_file(filler).unwrap();
    let writing = wait_for(&socket, 5.0, |s| s.telemetry_error.is_none());
    let Some(writing) = writing else {
        let _ = child.kill();
        panic!("the writes did not resume: {}", stderr());
    };
    assert_eq!(writing.safety, "normal", "{writing:?}");
    let lost = writing.telemetry_lost;
    assert!(lost > 800, "{writing:?}");

    let exit = child.wait().unwrap();
    let text = stderr();
    assert!(exit.success(), "{exit:?}: {text}");
    assert_eq!(text.matches("session log not written").count(), 1, "{text}");
    assert_eq!(
        text.matches("session log written again").count(),
        1,
        "{text}"
    );

    // The log reads whole, the lost periods counted in its end frame, one gap where they were;
    // the loop never left normal operation (no overrun trip while the disk was full).
    let entries: Vec<_> = std::fs::read_dir(&logs)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(entries.len(), 1, "{entries:?}");
    let log = read_log(&entries[0]).unwrap();
    assert_eq!((log.damage.as_ref(), log.truncated_bytes), (None, 0));
    let end = log.end.as_ref().expect("closed with its end frame");
    assert_eq!(end.periods, log.records.len() as u64);
    assert_eq!(end.dropped, lost);
    assert_eq!(end.periods + end.dropped, end.last_cycle.unwrap() + 1);
    let gaps = log
        .records
        .windows(2)
        .filter(|w| w[1].cycle != w[0].cycle + 1)
        .count();
    assert_eq!(gaps, 1);
    assert!(log.records.iter().all(|r| r.safety == SafetyState::Normal));
}

/// A twin session's log, compressed: at most what retention counts per period
/// (`STORED_PERIOD_BYTES`), and well under half of what the same log takes uncompressed, as
/// version 3 wrote it. (The note's figures, a third and better, are of 30 s sessions.)
#[test]
fn a_twin_session_log_takes_no_more_than_retention_counts() {
    use videt_runtime::telemetry::retention::STORED_PERIOD_BYTES;
    use videt_runtime::telemetry::{version_3_bytes, LogReader};
    for scene in ["wall", "box"] {
        let work = tempfile::tempdir().unwrap();
        let status = Command::new(videt_testkit::videtd_bin())
            .args(["--sim", "--scene", scene, "--duration", "4", "--no-socket"])
            .arg("--telemetry-dir")
            .arg(work.path())
            .env("RUST_LOG", "warn")
            .stdout(Stdio::null())
            .status()
            .unwrap();
        assert!(status.success(), "{scene}");
        let path = std::fs::read_dir(work.path())
            .unwrap()
            .map(|e| e.unwrap().path())
            .find(|p| p.extension().is_some_and(|e| e == "vlog"))
            .unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let log = read_log(&path).unwrap();
        assert!(log.closed() && log.records.len() > 3000, "{scene}");
        let per_period = bytes.len() as f64 / log.records.len() as f64;
        let reader = LogReader::new(&bytes[..]).unwrap();
        let header = reader.header();
        let uncompressed = version_3_bytes(&header, reader).unwrap().len() as f64;
        let ratio = uncompressed / bytes.len() as f64;
        eprintln!(
            "{scene}: {per_period:.1} bytes per period, {ratio:.2} times smaller than version 3"
        );
        assert!(
            per_period <= STORED_PERIOD_BYTES as f64,
            "{scene}: {per_period}"
        );
        assert!(ratio > 2.5, "{scene}: {ratio}");
    }
}
