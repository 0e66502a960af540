//! Retention of the session logs (`docs/telemetry.md`, "Retention"): the finished logs in
//! `telemetry.directory` older than `telemetry.max_age_days` are removed, and then the oldest
//! finished ones while the logs together exceed `telemetry.max_total_mb` or the directory's
//! filesystem has less than `telemetry.min_free_mb` free. The running session's log is never
//! removed (it still counts toward the total), and nothing but the regular `.vlog` files
//! directly in the directory is ever touched.
//!
//! [`choose_removals`] decides, without touching the filesystem; [`enforce`] lists the
//! directory, decides and removes.

use std::ffi::CString;
use std::io;
use std::os::unix::ffi::OsStrExt;
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime};

use videt_config::TelemetryConfig;

/// Bytes in a MB of the configuration (`telemetry.max_total_mb`, `telemetry.min_free_mb`).
pub const MB: u64 = 1_000_000;

/// The extension of a session log; only such files are ever removed.
pub const SESSION_EXTENSION: &str = "vlog";

/// What the session logs may take.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RetentionLimits {
    /// The directory's session logs together at most this many bytes.
    pub max_total_bytes: u64,
    /// Finished session logs last modified longer ago than this are removed.
    pub max_age: Duration,
    /// Keep at least this many bytes free on the directory's filesystem.
    pub min_free_bytes: u64,
}

impl RetentionLimits {
    /// The limits of the `[telemetry]` settings (MB of 10^6 bytes, days of 86 400 s).
    pub fn from_config(c: &TelemetryConfig) -> Self {
        RetentionLimits {
            max_total_bytes: c.max_total_mb.saturating_mul(MB),
            max_age: Duration::from_secs(u64::from(c.max_age_days) * 86_400),
            min_free_bytes: c.min_free_mb.saturating_mul(MB),
        }
    }
}

/// A session log in the directory.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StoredSession {
    /// The file.
    pub path: PathBuf,
    /// Its size, bytes.
    pub bytes: u64,
    /// When it was last written.
    pub modified: SystemTime,
}

/// Which of `sessions` to remove under `limits` at `now` with `free_bytes` free on their
/// filesystem: their indices, oldest first (by modification time, then path).
///
/// The session at `running` is never chosen but counts toward the total. Every finished
/// session older than `limits.max_age` is chosen; then, oldest first, the next finished one
/// while the total of what remains exceeds `limits.max_total_bytes` or the free space
/// (`free_bytes` and what the chosen ones free) is below `limits.min_free_bytes`. Pure: the
/// filesystem is not touched.
pub fn choose_removals(
    sessions: &[StoredSession],
    running: Option<&Path>,
    limits: &RetentionLimits,
    now: SystemTime,
    free_bytes: u64,
) -> Vec<usize> {
    let kept: Vec<bool> = sessions
        .iter()
        .map(|s| running.is_some_and(|r| s.path == r))
        .collect();
    choose_keeping(sessions, &kept, limits, now, free_bytes)
}

/// [`choose_removals`] with `kept[i]`: session `i` is never chosen (but counts).
fn choose_keeping(
    sessions: &[StoredSession],
    kept: &[bool],
    limits: &RetentionLimits,
    now: SystemTime,
    free_bytes: u64,
) -> Vec<usize> {
    let mut finished: Vec<usize> = (0..sessions.len()).filter(|&i| !kept[i]).collect();
    finished.sort_by(|&a, &b| {
        let (a, b) = (&sessions[a], &sessions[b]);
        a.modified
            .cmp(&b.modified)
            .then_with(|| a.path.cmp(&b.path))
    });
    let mut remaining: u64 = sessions.iter().map(|s| s.bytes).sum();
    let mut freed = 0u64;
    let mut chosen = Vec::new();
    // A modification time after `now` (the clock was set back) is no age.
    let too_old = |s: &StoredSession| {
        now.duration_since(s.modified)
            .is_ok_and(|age| age > limits.max_age)
    };
    let over = |remaining: u64, freed: u64| {
        remaining > limits.max_total_bytes
            || free_bytes.saturating_add(freed) < limits.min_free_bytes
    };
    // Oldest first: those too old come first, then the next oldest while still over a limit.
    for i in finished {
        let s = &sessions[i];
        if !too_old(s) && !over(remaining, freed) {
            break;
        }
        chosen.push(i);
        remaining -= s.bytes;
        freed = freed.saturating_add(s.bytes);
    }
    chosen
}

/// The session logs in `dir`: the regular files directly in it whose name ends in `.vlog`
/// (not symbolic links, not subdirectories, nothing else), in no particular order. A file
/// removed while listing is left out.
pub fn sessions_in(dir: &Path) -> io::Result<Vec<StoredSession>> {
    let mut sessions = Vec::new();
    for entry in std::fs::read_dir(dir)? {
        let entry = entry?;
        let path = entry.path();
        if path.extension().is_none_or(|e| e != SESSION_EXTENSION) {
            continue;
        }
        // Not followed: a symbolic link named `.vlog` is not a session log.
        let metadata = match entry.metadata() {
            Ok(m) => m,
            Err(e) if e.kind() == io::ErrorKind::NotFound => continue,
            Err(e) => return Err(e),
        };
        if !metadata.file_type().is_file() {
            continue;
        }
        sessions.push(StoredSession {
            path,
            bytes: metadata.len(),
            modified: metadata.modified()?,
        });
    }
    Ok(sessions)
}

/// The bytes free to an unprivileged process on the filesystem of `dir` (`statvfs`:
/// `f_bavail * f_frsize`).
pub fn free_bytes(dir: &Path) -> io::Result<u64> {
    let path = CString::new(dir.as_os_str().as_bytes())
        .map_err(|_| io::Error::new(io::ErrorKind::InvalidInput, "path contains a NUL byte"))?;
    let mut stat = std::mem::MaybeUninit::<libc::statvfs>::uninit();
    // SAFETY: `path` is a NUL-terminated string and `stat` is writable memory of a statvfs,
    // which statvfs fills completely when it returns 0.
    let rc = unsafe { libc::statvfs(path.as_ptr(), stat.as_mut_ptr()) };
    if rc != 0 {
        return Err(io::Error::last_os_error());
    }
    // SAFETY: statvfs returned 0, so it wrote the whole struct.
    let stat = unsafe { stat.assume_init() };
    #[allow(clippy::useless_conversion)] // The fields' widths differ between targets.
    Ok(u64::from(stat.f_bavail).saturating_mul(u64::from(stat.f_frsize)))
}

/// What [`enforce`] did.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct RetentionOutcome {
    /// The session logs removed and their sizes, bytes, oldest first.
    pub removed: Vec<(PathBuf, u64)>,
    /// The session logs that could not be removed, and why.
    pub failed: Vec<(PathBuf, String)>,
    /// The session logs left in the directory together (the running one and those that
    /// could not be removed included), bytes.
    pub total_bytes: u64,
    /// Free on the directory's filesystem after the removals, bytes.
    pub free_bytes: u64,
    /// Even after the removals less than `min_free_bytes` is free (the space is taken by
    /// other files, the running session, or logs that could not be removed).
    pub short_of_free: bool,
}

/// Apply `limits` to the session logs in `dir`: list them ([`sessions_in`]), choose
/// ([`choose_removals`], never the log at `running`) and remove them. A log that cannot be
/// removed is reported in [`RetentionOutcome::failed`] and kept out of the choice, which then
/// goes on to the next oldest. Errors only when the directory or its free space cannot be
/// read.
pub fn enforce(
    dir: &Path,
    running: Option<&Path>,
    limits: &RetentionLimits,
) -> io::Result<RetentionOutcome> {
    enforce_with(dir, running, limits, &mut |p| std::fs::remove_file(p))
}

/// [`enforce`] removing with `remove`.
fn enforce_with(
    dir: &Path,
    running: Option<&Path>,
    limits: &RetentionLimits,
    remove: &mut dyn FnMut(&Path) -> io::Result<()>,
) -> io::Result<RetentionOutcome> {
    let mut sessions = sessions_in(dir)?;
    let free = free_bytes(dir)?;
    let now = SystemTime::now();
    // The running log however it is named (relative path, another spelling of the directory).
    let running_id = running.and_then(|r| std::fs::metadata(r).ok().map(|m| (m.dev(), m.ino())));
    let mut kept: Vec<bool> = sessions
        .iter()
        .map(|s| {
            running.is_some_and(|r| s.path == r)
                || running_id.is_some_and(|id| {
                    std::fs::symlink_metadata(&s.path).is_ok_and(|m| (m.dev(), m.ino()) == id)
                })
        })
        .collect();
    let mut outcome = RetentionOutcome::default();
    let mut freed = 0u64;
    loop {
        let chosen = choose_keeping(&sessions, &kept, limits, now, free.saturating_add(freed));
        if chosen.is_empty() {
            break;
        }
        let mut gone = vec![false; sessions.len()];
        let mut any_failed = false;
        for i in chosen {
            let s = &sessions[i];
            match remove(&s.path) {
                Ok(()) => {
                    outcome.removed.push((s.path.clone(), s.bytes));
                    freed = freed.saturating_add(s.bytes);
                    gone[i] = true;
                }
                // Removed by someone else meanwhile: gone all the same.
                Err(e) if e.kind() == io::ErrorKind::NotFound => gone[i] = true,
                Err(e) => {
                    outcome.failed.push((s.path.clone(), e.to_string()));
                    kept[i] = true;
                    any_failed = true;
                }
            }
        }
        let mut i = 0;
        sessions.retain(|_| {
            i += 1;
            !gone[i - 1]
        });
        let mut i = 0;
        kept.retain(|_| {
            i += 1;
            !gone[i - 1]
        });
        // Without a failure the choice already met the limits as far as they can be met.
        if !any_failed {
            break;
        }
    }
    outcome.total_bytes = sessions.iter().map(|s| s.bytes).sum();
    outcome.free_bytes = free_bytes(dir)?;
    outcome.short_of_free = outcome.free_bytes < limits.min_free_bytes;
    Ok(outcome)
}

/// What a session log takes per period, about, compressed: measured on 30 s twin sessions,
/// 116-141 bytes on the wall and box scenes and 198-206 bytes on the stereo scene, whose
/// reliefs at the camera's rate add about 60; the largest, rounded up. (Uncompressed, as
/// version 3 stored them, a period took 428 bytes.)
pub const STORED_PERIOD_BYTES: u64 = 210;

/// Bytes a session log grows by per hour at `rate_hz`, about: [`STORED_PERIOD_BYTES`] per
/// period.
pub fn bytes_per_hour(rate_hz: u32) -> u64 {
    STORED_PERIOD_BYTES * u64::from(rate_hz) * 3600
}

#[cfg(test)]
mod tests {
    use super::*;

    const DAY: Duration = Duration::from_secs(86_400);

    /// A fixed "now" for the pure tests.
    fn now() -> SystemTime {
        SystemTime::UNIX_EPOCH + Duration::from_secs(1_700_000_000)
    }

    fn session(name: &str, bytes: u64, age: Duration) -> StoredSession {
        StoredSession {
            path: PathBuf::from(format!("/logs/{name}.vlog")),
            bytes,
            modified: now() - age,
        }
    }

    /// Limits of `total` bytes, `days` days and `free` bytes free.
    fn limits(total: u64, days: u32, free: u64) -> RetentionLimits {
        RetentionLimits {
            max_total_bytes: total,
            max_age: DAY * days,
            min_free_bytes: free,
        }
    }

    /// Plenty of free space.
    const ROOM: u64 = u64::MAX / 2;

    #[test]
    fn limits_come_from_the_configuration_in_mb_of_a_million_bytes_and_days() {
        let l = RetentionLimits::from_config(&TelemetryConfig::default());
        assert_eq!(l.max_total_bytes, 4_096_000_000);
        assert_eq!(l.max_age, Duration::from_secs(30 * 86_400));
        assert_eq!(l.min_free_bytes, 1_024_000_000);
        let c = TelemetryConfig {
            max_total_mb: 16,
            max_age_days: 1,
            min_free_mb: 0,
            ..TelemetryConfig::default()
        };
        assert_eq!(RetentionLimits::from_config(&c), limits(16_000_000, 1, 0));
    }

    #[test]
    fn nothing_to_choose_from_an_empty_directory_or_within_the_limits() {
        assert!(choose_removals(&[], None, &limits(0, 1, ROOM), now(), 0).is_empty());
        let s = [
            session("a", 100, 2 * DAY),
            session("b", 100, DAY),
            session("c", 100, Duration::ZERO),
        ];
        assert!(choose_removals(&s, None, &limits(300, 3, 1000), now(), 1000).is_empty());
    }

    #[test]
    fn every_finished_session_older_than_the_age_limit_is_chosen_oldest_first() {
        let s = [
            session("a", 10, 5 * DAY),
            session("b", 10, DAY / 2),
            session("c", 10, 40 * DAY),
            session("d", 10, 31 * DAY),
            session("e", 10, 30 * DAY), // exactly the limit: not older
        ];
        assert_eq!(
            choose_removals(&s, None, &limits(1000, 30, 0), now(), ROOM),
            vec![2, 3]
        );
        // The running one is kept however old its modification time.
        let running = s[2].path.clone();
        assert_eq!(
            choose_removals(&s, Some(&running), &limits(1000, 30, 0), now(), ROOM),
            vec![3]
        );
        // A modification time in the future (the clock set back) is no age.
        let future = [StoredSession {
            modified: now() + 400 * DAY,
            ..session("f", 10, Duration::ZERO)
        }];
        assert!(choose_removals(&future, None, &limits(1000, 1, 0), now(), ROOM).is_empty());
    }

    #[test]
    fn the_oldest_are_chosen_until_what_remains_is_within_the_total() {
        // In no particular order in the list.
        let s = [
            session("c", 300, 3 * DAY),
            session("a", 300, 9 * DAY),
            session("e", 300, DAY),
            session("b", 300, 5 * DAY),
            session("d", 300, 2 * DAY),
        ];
        // 1500 bytes, at most 1000: two go (900 remain), the oldest two.
        assert_eq!(
            choose_removals(&s, None, &limits(1000, 30, 0), now(), ROOM),
            vec![1, 3]
        );
        // Exactly at the limit is within it.
        assert_eq!(
            choose_removals(&s, None, &limits(900, 30, 0), now(), ROOM),
            vec![1, 3]
        );
        assert_eq!(
            choose_removals(&s, None, &limits(899, 30, 0), now(), ROOM),
            vec![1, 3, 0]
        );
        // Age and total together: the old one, then as many more as the total needs.
        assert_eq!(
            choose_removals(&s, None, &limits(600, 4, 0), now(), ROOM),
            vec![1, 3, 0]
        );
    }

    #[test]
    fn the_oldest_are_chosen_until_enough_is_free() {
        let s = [
            session("a", 400, 4 * DAY),
            session("b", 400, 3 * DAY),
            session("c", 400, 2 * DAY),
            session("d", 400, DAY),
        ];
        // 100 free, at least 1000: 400 + 400 + 400 frees enough (1300).
        assert_eq!(
            choose_removals(&s, None, &limits(ROOM, 30, 1000), now(), 100),
            vec![0, 1, 2]
        );
        // Enough free already, or just enough after one.
        assert!(choose_removals(&s, None, &limits(ROOM, 30, 1000), now(), 1000).is_empty());
        assert_eq!(
            choose_removals(&s, None, &limits(ROOM, 30, 1000), now(), 600),
            vec![0]
        );
        // What the age limit frees counts toward the free space.
        assert_eq!(
            choose_removals(&s, None, &limits(ROOM, 3, 1000), now(), 600),
            vec![0]
        );
        // Never enough: every finished one goes, the running one stays.
        let running = s[1].path.clone();
        assert_eq!(
            choose_removals(&s, Some(&running), &limits(ROOM, 30, 5000), now(), 0),
            vec![0, 2, 3]
        );
    }

    #[test]
    fn the_running_session_is_never_chosen_but_counts_toward_the_total() {
        let s = [
            session("old", 100, 2 * DAY),
            session("running", 5000, Duration::ZERO),
            session("older", 100, 3 * DAY),
        ];
        let running = s[1].path.clone();
        // The running one alone exceeds the total: every finished one goes, it stays.
        assert_eq!(
            choose_removals(&s, Some(&running), &limits(1000, 30, 0), now(), ROOM),
            vec![2, 0]
        );
        // It counts: 5200 with a limit of 5150 removes the oldest finished one only.
        assert_eq!(
            choose_removals(&s, Some(&running), &limits(5150, 30, 0), now(), ROOM),
            vec![2]
        );
        // Alone in the directory, it stays.
        assert!(
            choose_removals(&s[1..2], Some(&running), &limits(16, 1, ROOM), now(), 0).is_empty()
        );
        // Without a running session, the largest (newest) one goes too.
        assert_eq!(
            choose_removals(&s, None, &limits(1000, 30, 0), now(), ROOM),
            vec![2, 0, 1]
        );
    }

    #[test]
    fn the_order_is_by_modification_time_and_then_by_path() {
        let t = now() - DAY;
        let at = |name: &str, modified: SystemTime| StoredSession {
            modified,
            ..session(name, 100, Duration::ZERO)
        };
        // Names that sort the other way round from their times, and two of the same time.
        let s = [
            at("videt-1000", t),
            at("videt-0999", t),
            at("videt-0001", t + Duration::from_secs(1)),
            at("videt-9999", t - Duration::from_millis(1)),
        ];
        assert_eq!(
            choose_removals(&s, None, &limits(0, 30, 0), now(), ROOM),
            vec![3, 1, 0, 2]
        );
    }

    /// A session log of `bytes` bytes in `dir`, last modified `age` ago.
    fn file(dir: &Path, name: &str, bytes: usize, age: Duration) -> PathBuf {
        let path = dir.join(name);
        let f = std::fs::File::create(&path).unwrap();
        std::io::Write::write_all(&mut &f, &vec![7u8; bytes]).unwrap();
        f.set_modified(SystemTime::now() - age).unwrap();
        path
    }

    #[test]
    fn only_regular_vlog_files_directly_in_the_directory_are_sessions() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let a = file(d, "videt-1.vlog", 10, DAY);
        let b = file(d, "b.vlog", 20, Duration::ZERO);
        file(d, "notes.txt", 30, 90 * DAY);
        file(d, "videt-2.vlog.partial", 40, 90 * DAY);
        file(d, "vlog", 50, 90 * DAY);
        std::fs::create_dir(d.join("old.vlog")).unwrap();
        file(&d.join("old.vlog"), "videt-3.vlog", 60, 90 * DAY);
        std::os::unix::fs::symlink(&a, d.join("link.vlog")).unwrap();
        let mut found = sessions_in(d).unwrap();
        found.sort_by(|x, y| x.path.cmp(&y.path));
        let found: Vec<(PathBuf, u64)> = found.into_iter().map(|s| (s.path, s.bytes)).collect();
        assert_eq!(found, vec![(b, 20), (a.clone(), 10)]);
        let s = sessions_in(d).unwrap();
        let modified = s.iter().find(|s| s.path == a).unwrap().modified;
        let age = SystemTime::now().duration_since(modified).unwrap();
        assert!(age >= DAY && age < DAY + Duration::from_secs(60), "{age:?}");
        assert!(sessions_in(&d.join("absent")).is_err());
    }

    #[test]
    fn free_space_is_read_from_the_filesystem() {
        let dir = tempfile::tempdir().unwrap();
        let free = free_bytes(dir.path()).unwrap();
        assert!(free > 0);
        // df's figure for the same filesystem, within what other tests write meanwhile.
        let df = std::process::Command::new("df")
            .args(["-B1", "--output=avail"])
            .arg(dir.path())
            .output()
            .expect("df (coreutils) runs");
        let text = String::from_utf8_lossy(&df.stdout);
        let avail: u64 = text.lines().nth(1).unwrap().trim().parse().unwrap();
        assert!(
            free.abs_diff(avail) < 256 * MB,
            "statvfs {free}, df {avail}"
        );
        let e = free_bytes(&dir.path().join("absent")).unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::NotFound);
    }

    #[test]
    fn enforce_removes_the_old_and_the_oldest_over_the_total_and_nothing_else() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let other = [
            file(d, "notes.txt", 5000, 400 * DAY),
            file(d, "videt-1.vlog.bak", 5000, 400 * DAY),
        ];
        std::fs::create_dir(d.join("archive")).unwrap();
        let archived = file(&d.join("archive"), "videt-0.vlog", 5000, 400 * DAY);
        let ancient = file(d, "videt-100.vlog", 100, 40 * DAY);
        let old = file(d, "videt-200.vlog", 1000, 10 * DAY);
        let mid = file(d, "videt-300.vlog", 1000, 5 * DAY);
        let new = file(d, "videt-400.vlog", 1000, DAY);
        // The running one is oldest by its time (a clock set back) and huge: it stays.
        let running = file(d, "videt-500.vlog", 3000, 60 * DAY);
        let limits = limits(5000, 30, 0);
        let out = enforce(d, Some(&running), &limits).unwrap();
        assert_eq!(
            out.removed,
            vec![(ancient.clone(), 100), (old.clone(), 1000)]
        );
        assert!(out.failed.is_empty());
        assert_eq!(out.total_bytes, 5000);
        assert!(!out.short_of_free);
        assert!(out.free_bytes > 0);
        for p in [&ancient, &old] {
            assert!(!p.exists(), "{}", p.display());
        }
        for p in other.iter().chain([&archived, &mid, &new, &running]) {
            assert!(p.exists(), "{}", p.display());
        }
        // The running one named another way is still the running one.
        let relative = d.join("archive/../videt-500.vlog");
        let out = enforce(d, Some(&relative), &limits).unwrap();
        assert!(out.removed.is_empty(), "{out:?}");
        // Once it is finished it is the oldest and goes first.
        let out = enforce(d, None, &limits).unwrap();
        assert_eq!(out.removed, vec![(running.clone(), 3000)]);
        assert_eq!(out.total_bytes, 2000);
    }

    #[test]
    fn many_sessions_over_a_small_limit_are_brought_under_it() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let limit = 16 * MB / 1000; // 16 kB: the configuration's smallest, scaled down.
        let mut paths = Vec::new();
        for i in 0..200u64 {
            // Sizes 100..=1090, the oldest first in time.
            let age = Duration::from_secs(3600 * (200 - i));
            paths.push(file(
                d,
                &format!("videt-{i}.vlog"),
                100 + (i as usize * 37) % 1000,
                age,
            ));
        }
        let running = paths[199].clone();
        let out = enforce(d, Some(&running), &limits(limit, 30, 0)).unwrap();
        let left = sessions_in(d).unwrap();
        let total: u64 = left.iter().map(|s| s.bytes).sum();
        assert_eq!(total, out.total_bytes);
        assert!(total <= limit, "{total}");
        // No more was removed than needed: without the last one removed it would be over.
        let (last_path, last_bytes) = out.removed.last().unwrap().clone();
        assert!(total + last_bytes > limit);
        // The newest ones are what is left, the running one among them.
        let first_kept = paths.iter().position(|p| *p == last_path).unwrap() + 1;
        assert_eq!(left.len(), 200 - first_kept);
        for p in &paths[first_kept..] {
            assert!(p.exists());
        }
        assert_eq!(out.removed.len(), first_kept);
        assert!(running.exists());
        // Again: nothing more to do.
        let again = enforce(d, Some(&running), &limits(limit, 30, 0)).unwrap();
        assert!(again.removed.is_empty() && again.total_bytes == total);
    }

    #[test]
    fn enforce_reports_the_free_space_it_cannot_reach() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let a = file(d, "videt-1.vlog", 100, 2 * DAY);
        let running = file(d, "videt-2.vlog", 100, Duration::ZERO);
        // More free space than any filesystem here has: every finished log goes, and it is
        // still short.
        let out = enforce(d, Some(&running), &limits(ROOM, 30, u64::MAX)).unwrap();
        assert_eq!(out.removed, vec![(a.clone(), 100)]);
        assert!(out.short_of_free);
        assert_eq!(out.total_bytes, 100);
        assert!(running.exists() && !a.exists());
        // Within reach: nothing to do and not short.
        let out = enforce(d, Some(&running), &limits(ROOM, 30, 1)).unwrap();
        assert!(out.removed.is_empty() && !out.short_of_free);
    }

    #[test]
    fn a_log_that_cannot_be_removed_is_reported_and_the_next_oldest_goes_instead() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let stuck = file(d, "videt-1.vlog", 1000, 3 * DAY);
        let next = file(d, "videt-2.vlog", 1000, 2 * DAY);
        let newest = file(d, "videt-3.vlog", 1000, DAY);
        let mut tried = Vec::new();
        let mut remove = |p: &Path| {
            tried.push(p.to_path_buf());
            if p == stuck {
                Err(io::Error::from(io::ErrorKind::PermissionDenied))
            } else {
                std::fs::remove_file(p)
            }
        };
        let out = enforce_with(d, None, &limits(2500, 30, 0), &mut remove).unwrap();
        assert_eq!(tried, vec![stuck.clone(), next.clone()]);
        assert_eq!(out.failed.len(), 1, "{out:?}");
        assert_eq!(out.failed[0].0, stuck);
        assert!(out.failed[0].1.contains("ermission denied"), "{out:?}");
        assert_eq!(out.removed, vec![(next.clone(), 1000)]);
        assert_eq!(out.total_bytes, 2000);
        assert!(stuck.exists() && !next.exists() && newest.exists());
        // When nothing can be removed, each is tried once and the total stays over.
        let mut tried = 0;
        let out = enforce_with(d, None, &limits(16, 30, 0), &mut |_| {
            tried += 1;
            Err(io::Error::other("read-only filesystem"))
        })
        .unwrap();
        assert_eq!(tried, 2);
        assert_eq!(out.failed.len(), 2);
        assert_eq!(out.total_bytes, 2000);
        // A log someone else removed meanwhile is neither removed nor failed.
        let out = enforce_with(d, None, &limits(1500, 30, 0), &mut |_| {
            Err(io::Error::from(io::ErrorKind::NotFound))
        })
        .unwrap();
        assert!(out.removed.is_empty() && out.failed.is_empty(), "{out:?}");
        assert_eq!(out.total_bytes, 1000);
    }

    #[test]
    fn bytes_per_hour_is_the_stored_size_of_a_period_per_period() {
        assert_eq!(bytes_per_hour(0), 0);
        assert_eq!(bytes_per_hour(2000), 2 * bytes_per_hour(1000));
        // About 0.76 GB per hour at 1 kHz, as the documentation says.
        let gb = bytes_per_hour(1000) as f64 / 1e9;
        assert!((0.75..0.77).contains(&gb), "{gb}");
    }
}
