//! The writer thread: drains the control thread's ring into the session log.
//!
//! Frames are gathered in memory and appended to the file in batches. A batch the file system
//! refuses (a full disk, an I/O error) is taken back to the last whole frame, so the file always
//! ends on a frame boundary and reads whole up to there. The writer then says so once
//! ([`WriterEvent::Failing`]), counts the periods it cannot write as lost, keeps the newest
//! surface and calibration for later, and tries again every [`RETRY_EVERY`]; once a batch goes
//! through it writes what it kept (the surfaces it lost as lost) and says so
//! ([`WriterEvent::Writing`]). The control thread is never held up: the ring is drained all the
//! while.

use std::io;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use super::format::{
    encode_calibration, encode_end, encode_period, FrameKind, LogHeader, BATCH_BYTES, PERIOD_BYTES,
};
use super::health::{SessionLogHealth, WriterEvent, WriterHealth};
use super::retention::{self, RetentionLimits};
use super::session::{CalibrationInForce, EndReason, SessionEnd, SessionInfo};
use super::sink::{LogSink, SurfaceFrames};
use super::surfaces::{FeedRecording, RecordedSurface};
use super::{TelemetryItem, TelemetryProducer, NO_CYCLE};

/// How often a writer whose writes fail tries again.
pub const RETRY_EVERY: Duration = Duration::from_secs(1);

/// A writer whose writes failed writes again once this much is free (where the free space can
/// be read): a disk with room for a batch or two only would fail again at once.
pub const RESUME_FREE_BYTES: u64 = 4 * BATCH_BYTES as u64;

/// How often retention runs while a session is written (and once as it starts).
pub const RETENTION_EVERY: Duration = Duration::from_secs(60);

/// How often the free space is read while a session is written: below the retention's
/// minimum, retention runs at once, and the writes pause if it cannot make room.
pub const FREE_SPACE_EVERY: Duration = Duration::from_secs(1);

/// The running writer thread.
pub struct TelemetryWriter {
    handle: JoinHandle<io::Result<u64>>,
    /// Set once, by [`TelemetryWriter::finish`]: the writer drains, closes and stops.
    end: Arc<OnceLock<EndReason>>,
    dropped: Arc<AtomicU64>,
    health: Arc<WriterHealth>,
    path: PathBuf,
}

impl TelemetryWriter {
    /// Records dropped so far because the ring was full.
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }
    /// Period records lost so far because the file system refused them.
    pub fn lost(&self) -> u64 {
        self.health().lost()
    }
    /// The error while the writes fail (`None`: writing).
    pub fn failure(&self) -> Option<String> {
        self.health().failure()
    }
    /// The writes' state, for another thread.
    pub fn health(&self) -> SessionLogHealth {
        SessionLogHealth(Arc::clone(&self.health))
    }
    /// What happened since the last call, oldest first.
    pub fn take_events(&self) -> Vec<WriterEvent> {
        self.health.take_events()
    }
    /// The log file.
    pub fn path(&self) -> &Path {
        &self.path
    }
    /// The session ended for `reason` (the control thread has stopped pushing): drain what is
    /// left, write the end frame (the reason, the last period, the periods written, and those
    /// dropped or lost), flush, fsync and close; returns the number of period records written.
    /// A writer dropped without this leaves the log without an end frame, as a killed service
    /// does. A log whose writes still fail is closed without one, and the error returned.
    pub fn finish(self, reason: EndReason) -> io::Result<u64> {
        // Only `finish` sets it, once: it consumes the writer.
        let _ = self.end.set(reason);
        self.handle
            .join()
            .map_err(|_| io::Error::other("telemetry writer panicked"))?
    }
}

/// What a session log records besides the periods.
#[derive(Default)]
pub struct SessionRecording {
    /// The session (`None`: a log that cannot be replayed).
    pub session: Option<SessionInfo>,
    /// The surface feed's surfaces.
    pub surfaces: FeedRecording,
    /// The limits on the session logs of the log's directory, applied as the session starts
    /// and every [`RETENTION_EVERY`] (`None`: none). With too little free space left the
    /// writer pauses, as it does on a full disk.
    pub retention: Option<RetentionLimits>,
}

/// Create a session log at `path` recording periods only, and start the writer thread.
pub fn start(
    path: &Path,
    header: LogHeader,
    ring_records: usize,
) -> io::Result<(TelemetryProducer, TelemetryWriter)> {
    start_session(path, header, SessionRecording::default(), ring_records)
}

/// Create the session log at `path`, write the session and the initial surface, and start the
/// writer thread; returns the control thread's producer (ring of `ring_records`) and the
/// writer.
pub fn start_session(
    path: &Path,
    header: LogHeader,
    recording: SessionRecording,
    ring_records: usize,
) -> io::Result<(TelemetryProducer, TelemetryWriter)> {
    let health = Arc::new(WriterHealth::default());
    let dir = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
        .to_path_buf();
    let retention = recording.retention.map(|limits| Retention {
        dir: dir.clone(),
        running: path.to_path_buf(),
        limits,
        next: Instant::now() + RETENTION_EVERY,
        next_free_check: Instant::now() + FREE_SPACE_EVERY,
    });
    // The older logs go first: a disk the last sessions filled has room for this one.
    if let Some(r) = &retention {
        r.apply(&health);
    }
    let mut sink = LogSink::create(path)?;
    sink.header(&super::format::encode_header(&header));
    if let Some(session) = &recording.session {
        let text = session.to_toml().map_err(io::Error::other)?;
        sink.frame(FrameKind::Session, text.as_bytes());
    }
    let mut surfaces = SurfaceFrames::default();
    if let Some(initial) = &recording.surfaces.initial {
        surfaces.write(0, initial, &mut sink);
    }
    // On disk before the first period: a log killed at once still has its header and session.
    sink.commit()?;
    let tap = recording.surfaces.tap;
    if let Some(tap) = &tap {
        tap.start_recording();
    }
    let (producer, consumer) = rtrb::RingBuffer::<TelemetryItem>::new(ring_records.max(1));
    let dropped = Arc::new(AtomicU64::new(0));
    let last_cycle = Arc::new(AtomicU64::new(NO_CYCLE));
    let end = Arc::new(OnceLock::<EndReason>::new());
    let mut thread = WriterThread {
        dir,
        retention,
        sink,
        surfaces,
        consumer,
        tap,
        health: Arc::clone(&health),
        written: 0,
        batch: BatchContents::default(),
        failing: None,
        newest_surface: 0,
    };
    let (writer_end, writer_dropped, writer_last_cycle) = (
        Arc::clone(&end),
        Arc::clone(&dropped),
        Arc::clone(&last_cycle),
    );
    let handle = std::thread::Builder::new()
        .name("videt-telemetry".into())
        .spawn(move || {
            let reason = thread.run(&writer_end);
            let last_cycle = writer_last_cycle.load(Ordering::Relaxed);
            thread.close(SessionEnd {
                reason,
                last_cycle: (last_cycle != NO_CYCLE).then_some(last_cycle),
                periods: 0,
                dropped: writer_dropped.load(Ordering::Relaxed),
            })
        })?;
    Ok((
        TelemetryProducer {
            producer,
            dropped: Arc::clone(&dropped),
            last_cycle,
        },
        TelemetryWriter {
            handle,
            end,
            dropped,
            health,
            path: path.to_path_buf(),
        },
    ))
}

/// What the batch not yet committed holds besides periods: what a refused batch loses.
#[derive(Default)]
struct BatchContents {
    periods: u64,
    /// The surface versions in it, oldest first, and the newest surface itself.
    surface_versions: Vec<u64>,
    newest_surface: Option<(u64, Arc<RecordedSurface>)>,
    calibration: Option<(u64, CalibrationInForce)>,
}

/// Retention of the log's directory.
struct Retention {
    dir: PathBuf,
    /// The log being written: never removed.
    running: PathBuf,
    limits: RetentionLimits,
    /// When it runs next.
    next: Instant,
    /// When the free space is read next.
    next_free_check: Instant,
}

impl Retention {
    /// Remove the older logs the limits choose, telling `health` each; returns the free space
    /// left (`None`: the directory could not be read, said too).
    fn apply(&self, health: &WriterHealth) -> Option<u64> {
        match retention::enforce(&self.dir, Some(&self.running), &self.limits) {
            Ok(outcome) => {
                for (path, bytes) in outcome.removed {
                    health.event(WriterEvent::Removed { path, bytes });
                }
                for (path, error) in outcome.failed {
                    health.event(WriterEvent::NotRemoved { path, error });
                }
                Some(outcome.free_bytes)
            }
            Err(e) => {
                health.event(WriterEvent::NotRemoved {
                    path: self.dir.clone(),
                    error: e.to_string(),
                });
                None
            }
        }
    }
}

/// Why the writer does not write.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Cause {
    /// The file system refused a write.
    Refused,
    /// Less than the retention's minimum is free.
    LowSpace,
}

/// While the writes fail: since when, the next try, and what is kept for the log.
struct Failing {
    cause: Cause,
    since: Instant,
    next_try: Instant,
    lost_at_start: u64,
    /// Surface versions published meanwhile and not kept (written as lost).
    lost_surfaces: Vec<u64>,
    /// The newest surface and calibration, written once the writes go through.
    surface: Option<(u64, Arc<RecordedSurface>)>,
    calibration: Option<(u64, CalibrationInForce)>,
}

struct WriterThread {
    /// The log's directory.
    dir: PathBuf,
    retention: Option<Retention>,
    sink: LogSink,
    surfaces: SurfaceFrames,
    consumer: rtrb::Consumer<TelemetryItem>,
    tap: Option<Arc<super::SurfaceTap>>,
    health: Arc<WriterHealth>,
    written: u64,
    batch: BatchContents,
    failing: Option<Failing>,
    /// The newest surface version taken from the tap (0: the initial one).
    newest_surface: u64,
}

impl WriterThread {
    /// Drain until the session ends; returns why it ended.
    fn run(&mut self, end: &OnceLock<EndReason>) -> EndReason {
        let mut period = [0u8; PERIOD_BYTES];
        loop {
            // Everything pushed before `finish` is in the ring once the reason is seen.
            let done = end.get();
            // Surfaces first: a period refers to a surface published before it.
            self.drain_surfaces();
            let mut drained = 0;
            while let Ok(item) = self.consumer.pop() {
                match item {
                    TelemetryItem::Period(record) => {
                        if record.surface_version > self.newest_surface {
                            // Published since the last take, after this loop began: the
                            // surface goes before the first period rendering it.
                            self.drain_surfaces();
                        }
                        if self.failing.is_some() {
                            self.health.lost.fetch_add(1, Ordering::Relaxed);
                        } else {
                            encode_period(&record, &mut period);
                            self.sink.frame(FrameKind::Period, &period);
                            self.batch.periods += 1;
                        }
                    }
                    TelemetryItem::Calibration(from_cycle, c) => self.calibration(from_cycle, c),
                }
                drained += 1;
                if self.sink.batch_bytes() >= BATCH_BYTES {
                    self.commit();
                    // A long drain (after a stall) seals block after block: the surfaces
                    // published meanwhile are taken between them, before the tap fills.
                    self.drain_surfaces();
                }
            }
            if let Some(reason) = done {
                return reason.clone();
            }
            self.apply_retention_when_due();
            if drained == 0 {
                // A batch is one compressed block: written when full, or when old enough.
                if self.failing.is_some() || self.sink.batch_due() {
                    self.commit();
                }
                std::thread::sleep(Duration::from_millis(20));
            }
        }
    }

    /// Take the surfaces published since the last call (earlier than the periods rendering
    /// them, as a surface must come).
    fn drain_surfaces(&mut self) {
        if let Some(tap) = &self.tap {
            let drained = tap.drain();
            for (version, surface) in drained.surfaces {
                self.surface(version, surface);
            }
            for version in drained.lost {
                self.surface_lost(version);
            }
        }
    }

    fn surface(&mut self, version: u64, surface: Arc<RecordedSurface>) {
        self.newest_surface = self.newest_surface.max(version);
        match &mut self.failing {
            Some(f) => {
                if let Some((older, _)) = f.surface.replace((version, surface)) {
                    f.lost_surfaces.push(older);
                }
            }
            None => {
                self.surfaces.write(version, &surface, &mut self.sink);
                self.batch.surface_versions.push(version);
                self.batch.newest_surface = Some((version, surface));
            }
        }
    }

    fn surface_lost(&mut self, version: u64) {
        self.newest_surface = self.newest_surface.max(version);
        match &mut self.failing {
            Some(f) => f.lost_surfaces.push(version),
            None => self
                .sink
                .frame(FrameKind::SurfaceLost, &version.to_le_bytes()),
        }
    }

    fn calibration(&mut self, from_cycle: u64, c: CalibrationInForce) {
        match &mut self.failing {
            Some(f) => f.calibration = Some((from_cycle, c)),
            None => {
                self.sink
                    .frame(FrameKind::Calibration, &encode_calibration(from_cycle, &c));
                self.batch.calibration = Some((from_cycle, c));
            }
        }
    }

    /// Write the batch, or while failing, try again when it is time.
    fn commit(&mut self) {
        if let Some(f) = &self.failing {
            if Instant::now() >= f.next_try {
                self.try_again(false);
            }
            return;
        }
        let batch = std::mem::take(&mut self.batch);
        let committed = self.sink.commit();
        self.account();
        match committed {
            Ok(()) => self.written += batch.periods,
            Err(e) => self.start_failing(Cause::Refused, e.to_string(), batch),
        }
    }

    /// Publish the log's size and the thread's CPU time so far.
    fn account(&self) {
        self.health
            .bytes
            .store(self.sink.written_bytes(), Ordering::Relaxed);
        self.health.cpu_ns.store(thread_cpu_ns(), Ordering::Relaxed);
    }

    /// Run retention when it is due: remove the older logs it chooses (said as events), and
    /// pause the writes while too little space is left.
    fn apply_retention_when_due(&mut self) {
        let Some(r) = &mut self.retention else {
            return;
        };
        let now = Instant::now();
        let min_free = r.limits.min_free_bytes;
        let free = if now >= r.next {
            r.next = now + RETENTION_EVERY;
            r.next_free_check = now + FREE_SPACE_EVERY;
            r.apply(&self.health)
        } else if now >= r.next_free_check {
            r.next_free_check = now + FREE_SPACE_EVERY;
            match retention::free_bytes(&r.dir) {
                // Short of space: retention now, not in a minute.
                Ok(free) if free < min_free => {
                    r.next = now + RETENTION_EVERY;
                    r.apply(&self.health)
                }
                Ok(free) => Some(free),
                Err(_) => None,
            }
        } else {
            return;
        };
        let Some(free) = free else {
            return;
        };
        if free < min_free && self.failing.is_none() {
            // What was gathered so far still goes in; then the writes pause.
            self.commit();
            if self.failing.is_none() {
                self.start_failing(
                    Cause::LowSpace,
                    low_space(free, min_free),
                    BatchContents::default(),
                );
            }
        }
    }

    /// A batch was refused (or the space is too low): its periods are lost, its newest surface
    /// and calibration kept.
    fn start_failing(&mut self, cause: Cause, error: String, batch: BatchContents) {
        let lost_at_start = self.health.lost.fetch_add(batch.periods, Ordering::Relaxed);
        // A repeat refers to the surface before it in the file: the next one is written whole.
        self.surfaces.last = None;
        let mut lost_surfaces = batch.surface_versions;
        let surface = batch.newest_surface;
        if let Some((newest, _)) = &surface {
            lost_surfaces.retain(|v| v != newest);
        }
        let now = Instant::now();
        self.failing = Some(Failing {
            cause,
            since: now,
            next_try: now + RETRY_EVERY,
            lost_at_start,
            lost_surfaces,
            surface,
            calibration: batch.calibration,
        });
        self.health.failing(error);
    }

    /// Write what was kept while failing: the lost surfaces as lost, the newest surface and
    /// calibration. Through: writing again; refused: the next try in [`RETRY_EVERY`]. Unless
    /// `now`, only once there is room.
    fn try_again(&mut self, now: bool) {
        let Some(f) = &mut self.failing else {
            return;
        };
        // Go on once retention or the user made room: the retention's minimum when paused for
        // it, room for a few batches after a refused write.
        let free = match (&self.retention, f.cause) {
            (Some(r), Cause::LowSpace) => r
                .apply(&self.health)
                .map(|free| (free, r.limits.min_free_bytes.max(RESUME_FREE_BYTES))),
            _ => retention::free_bytes(&self.dir)
                .ok()
                .map(|free| (free, RESUME_FREE_BYTES)),
        };
        if let Some((free, needed)) = free.filter(|_| !now) {
            if free < needed {
                f.next_try = Instant::now() + RETRY_EVERY;
                return;
            }
        }
        for version in &f.lost_surfaces {
            self.sink
                .frame(FrameKind::SurfaceLost, &version.to_le_bytes());
        }
        if let Some((from_cycle, c)) = &f.calibration {
            self.sink
                .frame(FrameKind::Calibration, &encode_calibration(*from_cycle, c));
        }
        if let Some((version, surface)) = &f.surface {
            self.surfaces.write(*version, surface, &mut self.sink);
        }
        match self.sink.commit() {
            Ok(()) => {
                let lost = self.health.lost.load(Ordering::Relaxed) - f.lost_at_start;
                let after = f.since.elapsed();
                self.failing = None;
                self.health.writing(lost, after);
            }
            Err(_) => {
                self.surfaces.last = None;
                f.next_try = Instant::now() + RETRY_EVERY;
            }
        }
    }

    /// Write what is left and the end frame, then flush to disk; returns the periods written.
    fn close(mut self, mut end: SessionEnd) -> io::Result<u64> {
        if self.failing.is_some() {
            self.try_again(true);
        } else {
            self.commit();
        }
        if let Some(f) = &self.failing {
            let error = self.health.failure();
            return Err(io::Error::other(format!(
                "the last {} s of writes failed ({}): the log ends without its end frame",
                f.since.elapsed().as_secs(),
                error.unwrap_or_default()
            )));
        }
        end.periods = self.written;
        end.dropped += self.health.lost.load(Ordering::Relaxed);
        self.sink.frame(FrameKind::End, &encode_end(&end));
        self.sink.commit()?;
        self.sink.file.sync_all()?;
        self.account();
        // The session's own growth since the last run: the directory ends within the limits.
        if let Some(r) = &self.retention {
            r.apply(&self.health);
        }
        Ok(self.written)
    }
}

/// The calling thread's CPU time, nanoseconds (0 where the clock cannot be read).
fn thread_cpu_ns() -> u64 {
    let mut t = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `t` is a valid timespec for the call to fill.
    if unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut t) } != 0 {
        return 0;
    }
    (t.tv_sec as u64) * 1_000_000_000 + t.tv_nsec as u64
}

/// Why the writes pause for space.
fn low_space(free_bytes: u64, min_free_bytes: u64) -> String {
    format!(
        "less than telemetry.min_free_mb = {} MB free on the disk ({:.1} MB): paused to keep it free",
        min_free_bytes / retention::MB,
        free_bytes as f64 / retention::MB as f64
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control_loop::{CycleObserver, WindowStats};
    use crate::telemetry::format::tests::noisy_sample;
    use crate::telemetry::{read_log, SurfaceEntry, SurfaceTap};
    use videt_control::surface::Plane;
    use videt_control::Vec3;

    fn plane(z: f64) -> RecordedSurface {
        RecordedSurface::Plane(Plane::new(Vec3::new(0.0, 0.0, z), -Vec3::z()).unwrap())
    }

    /// Push period `cycle`, pausing now and then as a 1 kHz loop would.
    fn push(producer: &mut TelemetryProducer, cycle: &mut u64) {
        producer.observe(&noisy_sample(*cycle), &WindowStats::default());
        *cycle += 1;
        if cycle.is_multiple_of(10) {
            std::thread::sleep(Duration::from_millis(1));
        }
    }

    /// Push period `cycle` and wait a period, as the control loop at 1 kHz.
    fn push_in_real_time(producer: &mut TelemetryProducer, cycle: &mut u64) {
        producer.observe(&noisy_sample(*cycle), &WindowStats::default());
        *cycle += 1;
        std::thread::sleep(Duration::from_millis(1));
    }

    #[test]
    fn a_full_disk_loses_periods_not_the_log_and_the_writes_resume_when_there_is_room() {
        let Some(disk) = videt_testkit::SmallDisk::mount_or_skip(4_000_000) else {
            return;
        };
        let filler = disk.fill_leaving(400_000).unwrap();
        let path = disk.path().join("s.vlog");
        let tap = Arc::new(SurfaceTap::default());
        let recording = crate::telemetry::tests::recording_with(&tap);
        let header = LogHeader {
            rate_hz: 1000,
            start_unix_ns: 5,
        };
        let (mut producer, writer) = start_session(&path, header, recording, 1 << 14).unwrap();
        producer.calibration(0, &CalibrationInForce::default());
        let mut cycle = 0;
        while writer.failure().is_none() && cycle < 100_000 {
            push(&mut producer, &mut cycle);
        }
        let error = writer.failure().expect("the disk filled");
        assert!(error.contains("No space left"), "{error}");
        // Meanwhile: surfaces published (the newest is kept, the older one lost), a new
        // calibration, more periods.
        tap.published(1, plane(0.31));
        tap.published(2, plane(0.32));
        producer.calibration(
            cycle,
            &CalibrationInForce {
                calibrated: true,
                ..CalibrationInForce::default()
            },
        );
        for _ in 0..3000 {
            push(&mut producer, &mut cycle);
        }
        assert!(writer.failure().is_some());
        std::fs::remove_file(filler).unwrap();
        let give_up = Instant::now() + 4 * RETRY_EVERY;
        while writer.failure().is_some() && Instant::now() < give_up {
            push(&mut producer, &mut cycle);
        }
        assert_eq!(writer.failure(), None, "writing again once there is room");
        for _ in 0..1000 {
            push(&mut producer, &mut cycle);
        }
        let events = writer.take_events();
        assert_eq!(events.len(), 2, "said once each: {events:?}");
        assert!(matches!(&events[0], WriterEvent::Failing { error } if error.contains("No space")));
        let WriterEvent::Writing { lost, .. } = events[1] else {
            panic!("{events:?}");
        };
        assert!(lost >= 3000, "{lost}");
        assert_eq!(writer.lost(), lost);
        let dropped = writer.dropped();
        let written = writer.finish(EndReason::StopRequest).unwrap();
        assert_eq!(written + lost + dropped, cycle);

        // The log reads whole: no damage, its end frame counts the lost periods.
        let log = read_log(&path).unwrap();
        assert_eq!((log.damage.as_ref(), log.truncated_bytes), (None, 0));
        let end = log.end.as_ref().expect("closed");
        assert_eq!(
            (end.periods, end.dropped, end.last_cycle),
            (written, lost + dropped, Some(cycle - 1))
        );
        assert_eq!(log.records.len() as u64, written);
        if dropped == 0 {
            let gaps = log
                .records
                .windows(2)
                .filter(|w| w[1].cycle != w[0].cycle + 1);
            assert_eq!(gaps.count(), 1, "one run of lost periods");
        }
        assert!(log.records.windows(2).all(|w| w[1].cycle > w[0].cycle));
        // The surface published while failing: the newest whole, the older said lost; the
        // calibration of the failing time is there.
        assert!(matches!(log.surfaces.get(&1), Some(SurfaceEntry::Lost)));
        assert!(
            matches!(log.surfaces.get(&2), Some(SurfaceEntry::Recorded(s)) if **s == plane(0.32))
        );
        assert!(log.calibrations.iter().any(|c| c.calibration.calibrated));
    }

    #[test]
    fn retention_removes_the_older_logs_for_room_then_pauses_the_writes_until_there_is_some() {
        let Some(disk) = videt_testkit::SmallDisk::mount_or_skip(8_000_000) else {
            return;
        };
        let logs = disk.path().join("logs");
        std::fs::create_dir(&logs).unwrap();
        // Two older sessions, an hour and two hours old, and a file that is not a log.
        let now = std::time::SystemTime::now();
        for (name, age_h) in [("videt-1.vlog", 2), ("videt-2.vlog", 1)] {
            let file = std::fs::File::create(logs.join(name)).unwrap();
            file.set_len(600_000).unwrap();
            std::io::Write::write_all(&mut &file, &[1; 600_000]).unwrap();
            file.set_modified(now - Duration::from_secs(3600 * age_h))
                .unwrap();
        }
        std::fs::write(logs.join("notes.txt"), b"kept").unwrap();
        let filler = disk.fill_leaving(1_600_000).unwrap();
        let limits = RetentionLimits {
            max_total_bytes: 1_000_000_000,
            max_age: Duration::from_secs(30 * 86_400),
            min_free_bytes: 1_000_000,
        };
        let path = logs.join("videt-3.vlog");
        let recording = SessionRecording {
            retention: Some(limits),
            ..SessionRecording::default()
        };
        let header = LogHeader {
            rate_hz: 1000,
            start_unix_ns: 5,
        };
        let (mut producer, writer) = start_session(&path, header, recording, 1 << 14).unwrap();
        // About ten periods a millisecond, some 1 MB/s compressed: the free space falls below
        // the minimum within a second; retention removes the older logs one check after
        // another, then the writes pause.
        let mut cycle = 0;
        let give_up = Instant::now() + Duration::from_secs(20);
        while writer.failure().is_none() && Instant::now() < give_up {
            push(&mut producer, &mut cycle);
        }
        let paused = writer.failure().expect("paused for space");
        assert!(paused.contains("telemetry.min_free_mb"), "{paused}");
        let removed: Vec<_> = writer
            .take_events()
            .into_iter()
            .filter_map(|e| match e {
                WriterEvent::Removed { path, bytes } => Some((path, bytes)),
                _ => None,
            })
            .collect();
        assert_eq!(
            removed,
            vec![
                (logs.join("videt-1.vlog"), 600_000),
                (logs.join("videt-2.vlog"), 600_000)
            ],
            "oldest first"
        );
        assert!(logs.join("notes.txt").exists() && path.exists());
        // Room again: the writes resume within a check or two.
        std::fs::remove_file(filler).unwrap();
        let give_up = Instant::now() + 4 * FREE_SPACE_EVERY;
        while writer.failure().is_some() && Instant::now() < give_up {
            push_in_real_time(&mut producer, &mut cycle);
        }
        assert_eq!(writer.failure(), None);
        let events = writer.take_events();
        assert!(matches!(events.last(), Some(WriterEvent::Writing { lost, .. }) if *lost > 0));
        let lost = writer.lost();
        let dropped = writer.dropped();
        let written = writer.finish(EndReason::StopRequest).unwrap();
        assert_eq!(written + lost + dropped, cycle);
        let log = read_log(&path).unwrap();
        assert_eq!((log.damage.as_ref(), log.truncated_bytes), (None, 0));
        assert_eq!(log.records.len() as u64, written);
    }
}
