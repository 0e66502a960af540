//! Per-cycle telemetry: the control thread pushes every period's record into a wait-free SPSC
//! ring (`rtrb`); a writer thread drains it into a session log file. A full ring drops the record
//! (counted) rather than block the control thread.
//!
//! The log (`docs/telemetry.md`) records what a replay needs: the session's configuration, the
//! calibration in force, every surface version once, and per period the inputs the control
//! cycle read and the outputs it produced; when the service stops, the writer closes it with an
//! end frame (why, and the last period), so that a log without one reads as a session that
//! ended without closing. Version 1 (outputs only) and version 2 logs (no end frame) are still
//! read.

mod block;
pub mod format;
mod health;
pub mod outline;
pub mod read;
pub mod retention;
pub mod session;
mod sink;
pub use sink::{version_3_bytes, write_log};
pub mod surfaces;
mod writer;

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

pub use format::{LogHeader, FORMAT_VERSION, HEADER_BYTES, MAGIC, PERIOD_BYTES, RECORD_BYTES};
pub use health::{SessionLogHealth, WriterEvent};
pub use outline::{CalibrationAt, LogOutline};
pub use read::{
    frames, parse_log, read_log, CalibrationEntry, Damage, FrameAt, Log, LogError, LogItem,
    LogReader, SurfaceEntry,
};
pub use session::{CalibrationInForce, EndReason, SessionEnd, SessionInfo};
pub use surfaces::{FeedRecording, RecordSurface, RecordedSurface, SurfaceTap};
pub use writer::{
    start, start_session, SessionRecording, TelemetryWriter, FREE_SPACE_EVERY, RESUME_FREE_BYTES,
    RETENTION_EVERY, RETRY_EVERY,
};

use crate::control_loop::{CycleObserver, WindowStats};
use crate::cycle::CycleRecord;

/// What the control thread sends the writer. The ring's slots are preallocated at the size of
/// the largest item: boxing the period would allocate on the control thread.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, Copy)]
enum TelemetryItem {
    /// One period.
    Period(CycleRecord),
    /// The calibration in force from the period `from_cycle` on.
    Calibration(u64, CalibrationInForce),
}

/// Control-thread side: pushes records, counts drops, keeps the last period's number for the
/// end frame. Allocation-free.
pub struct TelemetryProducer {
    producer: rtrb::Producer<TelemetryItem>,
    dropped: Arc<AtomicU64>,
    /// The last period observed (`NO_CYCLE`: none yet), dropped or not.
    last_cycle: Arc<AtomicU64>,
}

/// [`TelemetryProducer::last_cycle`] before the first period.
const NO_CYCLE: u64 = u64::MAX;

impl TelemetryProducer {
    /// The control cycle starts (or restarts after a re-initialization) with `calibration`
    /// from period `from_cycle` on. A full ring drops it (counted): a replay then stops there.
    pub fn calibration(&mut self, from_cycle: u64, calibration: &CalibrationInForce) {
        if self
            .producer
            .push(TelemetryItem::Calibration(from_cycle, *calibration))
            .is_err()
        {
            self.dropped.fetch_add(1, Ordering::Relaxed);
        }
    }
}

impl CycleObserver for TelemetryProducer {
    fn observe(&mut self, record: &CycleRecord, _window: &WindowStats) {
        self.last_cycle.store(record.cycle, Ordering::Relaxed);
        if self.producer.push(TelemetryItem::Period(*record)).is_err() {
            self.dropped.fetch_add(1, Ordering::Relaxed);
        }
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::format::tests::{noisy_sample, sample};
    use super::format::{self, FrameKind};
    use super::format::{
        encode_record, END_FIXED_BYTES, FORMAT_VERSION_2, FORMAT_VERSION_3, FRAME_HEAD_BYTES,
        FRAME_TAIL_BYTES,
    };
    use super::*;
    use std::path::Path;
    use std::time::Duration;
    use videt_control::surface::Plane;
    use videt_control::Vec3;

    const HEADER: LogHeader = LogHeader {
        rate_hz: 1000,
        start_unix_ns: 5,
    };

    /// Bytes of a period frame.
    const PERIOD_FRAME: usize = FRAME_HEAD_BYTES + PERIOD_BYTES + FRAME_TAIL_BYTES;
    /// Bytes of the end frame of a session whose set duration elapsed (no text).
    const END_FRAME: usize = FRAME_HEAD_BYTES + END_FIXED_BYTES + FRAME_TAIL_BYTES;

    fn plane(z: f64) -> RecordedSurface {
        RecordedSurface::Plane(Plane::new(Vec3::new(0.0, 0.0, z), -Vec3::z()).unwrap())
    }

    /// A session's recording: the session frame, the surface 0.3 m away before the start,
    /// then what `tap` is published.
    pub(super) fn recording_with(tap: &Arc<SurfaceTap>) -> SessionRecording {
        SessionRecording {
            session: Some(SessionInfo::new("test", videt_config::Config::default())),
            surfaces: FeedRecording {
                initial: Some(plane(0.3)),
                tap: Some(Arc::clone(tap)),
            },
            retention: None,
        }
    }

    /// A session of 3000 periods with a calibration, a surface before start, surfaces
    /// published during it (one a repeat) and the session frame, closed as its duration
    /// elapsed.
    fn write_session(path: &Path) -> u64 {
        write_session_of(path, 3000)
    }

    /// A directory holding `s.vlog`, a session written by [`write_session`], and its path.
    fn session_file() -> (tempfile::TempDir, std::path::PathBuf) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.vlog");
        write_session(&path);
        (dir, path)
    }

    /// [`write_session`] of `periods` periods, the surfaces published at a third of them.
    fn write_session_of(path: &Path, periods: u64) -> u64 {
        let tap = Arc::new(SurfaceTap::default());
        tap.published(1, plane(0.31));
        let recording = recording_with(&tap);
        let (mut producer, writer) = start_session(path, HEADER, recording, 4096).unwrap();
        producer.calibration(
            0,
            &CalibrationInForce {
                calibrated: true,
                ..CalibrationInForce::default()
            },
        );
        for c in 0..periods {
            if c == periods / 3 {
                tap.published(2, plane(0.32));
                tap.published(3, plane(0.32));
            }
            producer.observe(&sample(c), &WindowStats::default());
            if c % 500 == 0 {
                std::thread::sleep(Duration::from_millis(5));
            }
        }
        assert_eq!(writer.dropped(), 0);
        writer.finish(EndReason::DurationElapsed).unwrap()
    }

    /// The same log as version 3 wrote it: each block's frames uncompressed, each with its CRC.
    fn as_version_3(v4: &[u8]) -> Vec<u8> {
        let mut out = v4[..HEADER_BYTES].to_vec();
        out[8..12].copy_from_slice(&FORMAT_VERSION_3.to_le_bytes());
        let mut block = super::block::DecodedBlock::default();
        for f in frames(v4).unwrap() {
            assert_eq!(f.kind, FrameKind::Block);
            let payload = &v4[f.offset + FRAME_HEAD_BYTES..f.offset + f.bytes - FRAME_TAIL_BYTES];
            block.decode(payload).unwrap();
            for frame in block.frames() {
                let (kind, payload) = frame.unwrap();
                format::frame(kind, payload, &mut out).unwrap();
            }
        }
        out
    }

    #[test]
    fn the_writer_records_the_session_surfaces_calibrations_and_every_period() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.vlog");
        assert_eq!(write_session(&path), 3000);
        let log = read_log(&path).unwrap();
        assert_eq!((log.header, log.version), (HEADER, FORMAT_VERSION));
        assert_eq!(log.records.len(), 3000);
        assert_eq!(log.records[2999], sample(2999));
        assert!(log.damage.is_none() && log.truncated_bytes == 0);
        assert_eq!(log.session.unwrap().unwrap().what, "test");
        assert_eq!(log.calibrations.len(), 1);
        assert!(log.calibrations[0].calibration.calibrated);
        let versions: Vec<u64> = log.surfaces.keys().copied().collect();
        assert_eq!(versions, vec![0, 1, 2, 3]);
        assert_eq!(
            log.surfaces[&3],
            SurfaceEntry::Recorded(Arc::new(plane(0.32)))
        );
        assert_eq!(
            log.surfaces[&0],
            SurfaceEntry::Recorded(Arc::new(plane(0.3)))
        );
    }

    #[test]
    fn the_reader_gives_the_items_in_file_order_and_the_log_read_whole_is_the_same() {
        let (_dir, path) = session_file();
        let whole = read_log(&path).unwrap();
        let mut reader = LogReader::open(&path).unwrap();
        assert_eq!(reader.version(), FORMAT_VERSION);
        let items: Vec<LogItem> = (&mut reader).collect();
        assert!(matches!(&items[0], LogItem::Session(s) if s.is_ok()));
        assert!(matches!(items[1], LogItem::Surface(0, _)));
        // The session frame's text, as recorded, from inside a block.
        let LogItem::Session(session) = &items[0] else {
            unreachable!("the first item is the session")
        };
        let text = reader.session_text().expect("the session's text");
        assert_eq!(SessionInfo::from_toml(text).ok(), (**session).clone().ok());
        assert!(matches!(items.last(), Some(LogItem::End(_))));
        let records: Vec<CycleRecord> = items
            .iter()
            .filter_map(|i| match i {
                LogItem::Period(r) => Some(*r),
                _ => None,
            })
            .collect();
        assert_eq!(records, whole.records);
        assert_eq!(reader.records(), 3000);
        assert_eq!(reader.end_note(), whole.end_note());
        assert!(reader.damage().is_none() && reader.damage_note().is_none());
        // Version 3's bytes give the same items, and are what `version_3_bytes` makes of them.
        let v3 = as_version_3(&std::fs::read(&path).unwrap());
        assert_eq!(version_3_bytes(&HEADER, items.clone()).unwrap(), v3);
        let v3_items: Vec<LogItem> = LogReader::new(&v3[..]).unwrap().collect();
        assert_eq!(v3_items, items);
    }

    #[test]
    fn periods_that_move_as_a_sessions_do_take_a_third_of_version_3s_bytes() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.vlog");
        let (mut producer, writer) = start(&path, HEADER, 1 << 15).unwrap();
        for c in 0..20_000 {
            producer.observe(&noisy_sample(c), &WindowStats::default());
            if c % 1000 == 0 {
                std::thread::sleep(Duration::from_millis(2));
            }
        }
        assert_eq!(writer.finish(EndReason::StopRequest).unwrap(), 20_000);
        let v4 = std::fs::read(&path).unwrap();
        let v3 = as_version_3(&v4);
        assert_eq!(
            parse_log(&v4).unwrap().records,
            parse_log(&v3).unwrap().records
        );
        assert!(
            v4.len() * 3 < v3.len(),
            "{} bytes, uncompressed {}",
            v4.len(),
            v3.len()
        );
    }

    #[test]
    fn a_log_written_whole_from_the_items_of_another_reads_the_same() {
        let (dir, path) = session_file();
        // A version 3 log rewritten as version 4, through the gathered log's items.
        let v3 = as_version_3(&std::fs::read(&path).unwrap());
        let old = parse_log(&v3).unwrap();
        let again = dir.path().join("again.vlog");
        let bytes = write_log(&again, &old.header, old.items()).unwrap();
        assert_eq!(bytes, std::fs::metadata(&again).unwrap().len());
        let new = read_log(&again).unwrap();
        assert_eq!(new.version, FORMAT_VERSION);
        assert_eq!(new.records, old.records);
        assert_eq!(new.calibrations, old.calibrations);
        assert_eq!(new.surfaces, old.surfaces);
        assert_eq!(new.end, old.end);
        assert_eq!(
            new.session.unwrap().unwrap().what,
            old.session.unwrap().unwrap().what
        );
    }

    #[test]
    fn the_outline_read_as_a_stream_is_the_whole_logs() {
        let (_dir, path) = session_file();
        let log = read_log(&path).unwrap();
        let streamed = LogOutline::read(&path).unwrap();
        let whole = LogOutline::of_log(&log);
        for o in [&streamed, &whole] {
            assert_eq!(o.records, 3000);
            assert_eq!(o.first_ns, Some(0));
            assert_eq!(o.last_ns, Some(2999 * 1_000_000));
            assert_eq!(o.last_cycle, Some(2999));
            assert_eq!(o.calibrations.len(), 1);
            assert_eq!(o.calibrations[0].time_ns, Some(0));
            assert_eq!(o.end, log.end);
            assert_eq!(o.end_note, log.end_note());
            assert!(o.damage_note.is_none() && o.lost_surfaces().is_empty());
            // Every period renders version 9, published before them: versions 0 to 3 are
            // shown at the start (0) or with the first period rendering a later version.
            let times: Vec<(u64, u64)> = o.surface_times_ns().into_iter().collect();
            assert_eq!(times, vec![(0, 0), (1, 0), (2, 0), (3, 0)]);
        }
        // A cut log: the damage and the notes as the whole log's.
        let bytes = std::fs::read(&path).unwrap();
        let cut = &bytes[..bytes.len() - 10];
        let log = parse_log(cut).unwrap();
        let streamed = LogOutline::of_reader(LogReader::new(cut).unwrap());
        assert_eq!(streamed.damage, log.damage);
        assert_eq!(streamed.damage_note, log.damage_note());
        assert_eq!(streamed.end_note, log.end_note());
        assert_eq!(streamed.records, log.records.len());
    }

    #[test]
    fn the_writer_closes_the_log_with_the_reason_and_the_last_period() {
        let (dir, path) = session_file();
        let bytes = std::fs::read(&path).unwrap();
        let log = parse_log(&bytes).unwrap();
        assert!(log.closed());
        assert_eq!(
            log.end,
            Some(SessionEnd {
                reason: EndReason::DurationElapsed,
                last_cycle: Some(2999),
                periods: 3000,
                dropped: 0,
            })
        );
        assert_eq!(
            log.end_note(),
            "session closed at cycle 2999: its set duration elapsed"
        );
        // Blocks one after the other to the end of the file.
        let blocks = frames(&bytes).unwrap();
        assert!(blocks.len() > 2, "{} blocks", blocks.len());
        assert_eq!(blocks[0].offset, HEADER_BYTES);
        assert_eq!(blocks.last().map(|b| b.offset + b.bytes), Some(bytes.len()));
        for w in blocks.windows(2) {
            assert_eq!(w[0].offset + w[0].bytes, w[1].offset);
        }
        // In them, the session first, the end frame last, after every period.
        let v3 = as_version_3(&bytes);
        let frames = frames(&v3).unwrap();
        let last = frames.last().unwrap();
        assert_eq!(last.kind, FrameKind::End);
        assert_eq!(last.offset + last.bytes, v3.len());
        assert_eq!(
            frames
                .iter()
                .filter(|f| f.kind == FrameKind::Period)
                .count(),
            3000
        );
        assert_eq!(frames[0].kind, FrameKind::Session);
        // A session that ran no period and ended on a fault says so.
        let empty = dir.path().join("e.vlog");
        let (_producer, writer) = start(&empty, HEADER, 16).unwrap();
        writer
            .finish(EndReason::FatalFault(
                "cannot start the control loop".into(),
            ))
            .unwrap();
        let log = read_log(&empty).unwrap();
        assert_eq!(log.end.as_ref().unwrap().last_cycle, None);
        assert_eq!(
            log.end_note(),
            "session closed before its first period: a fatal fault: cannot start the control loop"
        );
        // Anything after the end frame is damage, in either version.
        for (bytes, tail) in [
            (&bytes, blocks.last().unwrap().bytes),
            (&v3, END_FRAME + PERIOD_FRAME),
        ] {
            let mut appended = bytes.clone();
            appended.extend_from_slice(&bytes[bytes.len() - tail..]);
            let log = parse_log(&appended).unwrap();
            assert_eq!(log.records.len(), 3000);
            assert!(log.closed());
            let damage = log.damage.unwrap();
            assert_eq!(damage.offset as usize, bytes.len());
            assert!(damage.what.contains("after the end frame"), "{damage:?}");
        }
    }

    #[test]
    fn a_log_cut_on_any_frame_boundary_or_inside_a_frame_reads_as_not_closed() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.vlog");
        write_session_of(&path, 300);
        let v4 = std::fs::read(&path).unwrap();
        // Version 4 (blocks) and version 3 (frames).
        for bytes in [as_version_3(&v4), v4] {
            let whole = parse_log(&bytes).unwrap();
            let frames = frames(&bytes).unwrap();
            // Every frame boundary (a clean cut: power lost between two writes), the middle of
            // every frame, and every byte of the last frame.
            let end = frames.last().unwrap();
            let cuts = frames
                .iter()
                .flat_map(|f| [f.offset, f.offset + f.bytes / 2])
                .chain(end.offset..end.offset + end.bytes);
            for cut in cuts {
                let log = parse_log(&bytes[..cut]).unwrap();
                assert!(!log.closed(), "cut at {cut}");
                assert_eq!(log.records[..], whole.records[..log.records.len()]);
                let on_boundary = frames.iter().any(|f| f.offset == cut);
                assert_eq!(log.damage.is_none(), on_boundary, "cut at {cut}");
                let last = log.records.last().map_or(0, |r| r.cycle);
                assert!(
                    log.end_note().starts_with(&format!(
                        "session ended without closing, at cycle {last} (no end frame"
                    )) || log.records.is_empty(),
                    "cut at {cut}: {}",
                    log.end_note()
                );
            }
            let log = parse_log(&bytes[..HEADER_BYTES]).unwrap();
            assert!(log
                .end_note()
                .contains("without closing, before its first period"));
        }
    }

    #[test]
    fn a_log_cut_anywhere_or_corrupted_reads_up_to_the_damage_and_says_so() {
        let (_dir, path) = session_file();
        let v4 = std::fs::read(&path).unwrap();
        let v3 = as_version_3(&v4);
        // Cut inside the last period of version 3: one record fewer, the cut reported.
        let cut = &v3[..v3.len() - END_FRAME - 100];
        let log = parse_log(cut).unwrap();
        assert_eq!(log.records.len(), 2999);
        assert_eq!(log.truncated_bytes, PERIOD_FRAME - 100);
        let note = log.damage_note().unwrap();
        assert!(
            note.starts_with("read 2999 records, the rest is damaged"),
            "{note}"
        );
        // Version 4 cut inside its last block: the periods of the blocks before it.
        let blocks = frames(&v4).unwrap();
        let last = blocks.last().unwrap();
        let log = parse_log(&v4[..v4.len() - 10]).unwrap();
        assert_eq!(log.truncated_bytes, last.bytes - 10);
        assert_eq!(log.damage.as_ref().unwrap().offset as usize, last.offset);
        assert_eq!(
            log.records.len(),
            parse_log(&v4[..last.offset]).unwrap().records.len()
        );
        // Cut at every byte of the first frames, and at pseudo-random bytes: never a panic, and
        // the records are a prefix of the whole log's.
        for bytes in [&v3, &v4] {
            let whole = parse_log(bytes).unwrap();
            let mut rng = 0x9e37_79b9_7f4a_7c15u64;
            let cuts = (HEADER_BYTES..HEADER_BYTES + 3000).chain((0..200).map(|_| {
                rng ^= rng << 13;
                rng ^= rng >> 7;
                rng ^= rng << 17;
                HEADER_BYTES + (rng as usize) % (bytes.len() - HEADER_BYTES)
            }));
            for cut in cuts.filter(|c| *c < bytes.len()) {
                let log = parse_log(&bytes[..cut]).unwrap();
                assert_eq!(log.records[..], whole.records[..log.records.len()]);
                assert_eq!(
                    log.truncated_bytes > 0,
                    log.damage.is_some(),
                    "cut at {cut}"
                );
                assert!(!log.closed(), "cut at {cut}");
            }
        }
        // A flipped byte in a period: the records before it are read.
        let mut corrupt = v3.clone();
        let at = v3.len() - END_FRAME - 10 * PERIOD_FRAME + 50;
        corrupt[at] ^= 0x40;
        let log = parse_log(&corrupt).unwrap();
        assert_eq!(log.records.len(), 2990);
        assert!(!log.closed());
        assert!(log.damage.unwrap().what.contains("CRC"));
        // In version 4, the records of the blocks before it.
        let mut corrupt = v4.clone();
        let second = blocks[1];
        corrupt[second.offset + second.bytes / 2] ^= 0x40;
        let log = parse_log(&corrupt).unwrap();
        assert_eq!(
            log.records.len(),
            parse_log(&v4[..second.offset]).unwrap().records.len()
        );
        assert_eq!(log.damage.as_ref().unwrap().offset as usize, second.offset);
        assert!(log.damage.unwrap().what.contains("CRC"));
        // Another version, and not a log at all.
        let mut other = v4.clone();
        other[8] = 9;
        let e = parse_log(&other).unwrap_err().to_string();
        assert!(
            e.contains("version 9") && e.contains("reads versions 1 to 4"),
            "{e}"
        );
        let e = parse_log(b"#!/bin/sh\necho hello\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("not a VIDET session log"), "{e}");
        assert!(parse_log(&v4[..10]).is_err());
    }

    #[test]
    fn a_version_2_log_reads_whole_and_as_not_closed() {
        // What a version 2 writer wrote: the same frames, no end frame.
        let (_dir, path) = session_file();
        let mut bytes = as_version_3(&std::fs::read(&path).unwrap());
        bytes.truncate(bytes.len() - END_FRAME);
        bytes[8..12].copy_from_slice(&FORMAT_VERSION_2.to_le_bytes());
        let log = parse_log(&bytes).unwrap();
        assert_eq!(log.version, 2);
        assert_eq!(log.records.len(), 3000);
        assert!(log.damage.is_none() && !log.closed());
        assert_eq!(
            log.end_note(),
            "session ended without closing, at cycle 2999 (a version 2 log: that format records no end)"
        );
        // A block is not a frame of version 3.
        let v4 = std::fs::read(&path).unwrap();
        let mut relabelled = v4.clone();
        relabelled[8..12].copy_from_slice(&FORMAT_VERSION_3.to_le_bytes());
        let log = parse_log(&relabelled).unwrap();
        assert!(log.records.is_empty());
        assert!(log.damage.unwrap().what.contains("corrupt frame head"));
    }

    #[test]
    fn the_logs_of_earlier_versions_kept_as_fuzzing_seeds_still_read() {
        let seeds = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fuzz/seeds/session_log");
        let read = |name: &str| read_log(&seeds.join(name)).unwrap();
        let closed = read("wall_6_periods_closed.vlog");
        assert_eq!((closed.version, closed.records.len()), (3, 6));
        assert!(closed.closed() && closed.damage.is_none());
        let open = read("box_6_periods.vlog");
        assert_eq!(open.records.len(), 6);
        assert!(!open.closed() && open.session.is_some());
        let cut = read("box_cut.vlog");
        assert!(cut.damage.is_some());
        assert_eq!(read("version1_4_records.vlog").version, 1);
    }

    #[test]
    fn a_version_1_log_still_reads() {
        let mut bytes = Vec::new();
        bytes.extend_from_slice(MAGIC);
        bytes.extend_from_slice(&1u32.to_le_bytes());
        bytes.extend_from_slice(&256u32.to_le_bytes());
        bytes.extend_from_slice(&500u32.to_le_bytes());
        bytes.extend_from_slice(&[0; 4]);
        bytes.extend_from_slice(&7u64.to_le_bytes());
        let mut b = [0u8; RECORD_BYTES];
        for c in 0..10 {
            encode_record(&sample(c), &mut b);
            bytes.extend_from_slice(&b);
        }
        bytes.truncate(bytes.len() - 3);
        let log = parse_log(&bytes).unwrap();
        assert_eq!(log.version, 1);
        assert_eq!(log.header.rate_hz, 500);
        assert_eq!(log.records.len(), 9);
        let mut outputs = sample(8);
        outputs.inputs = Default::default();
        assert_eq!(log.records[8], outputs);
        assert_eq!(log.truncated_bytes, 253);
        assert!(log.session.is_none());
        assert!(!log.closed());
        assert!(log.end_note().contains("at cycle 8 (a version 1 log"));
        assert!(frames(&bytes).unwrap().is_empty());
    }

    #[test]
    fn a_full_ring_drops_and_counts_instead_of_blocking() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("d.vlog");
        let (mut producer, writer) = start(&path, HEADER, 64).unwrap();
        for c in 0..100_000 {
            producer.observe(&sample(c), &WindowStats::default());
        }
        let dropped = writer.dropped();
        let written = writer.finish(EndReason::StopRequest).unwrap();
        assert!(dropped > 0);
        assert_eq!(dropped + written, 100_000);
        // The end frame counts both, and names the last period even when it was dropped.
        let log = read_log(&path).unwrap();
        let end = log.end.as_ref().unwrap();
        assert_eq!((end.periods, end.dropped), (written, dropped));
        assert_eq!(end.last_cycle, Some(99_999));
        if log.records.last().unwrap().cycle < 99_999 {
            assert!(
                log.end_note().contains("were dropped"),
                "{}",
                log.end_note()
            );
        }
    }

    /// The surface versions and the periods' rendered versions of a version 4 log's bytes, in
    /// the order its frames are in the file.
    fn surface_order_in_file(v4: &[u8]) -> Vec<(FrameKind, u64)> {
        let mut order = Vec::new();
        let mut block = super::block::DecodedBlock::default();
        for f in frames(v4).unwrap() {
            let payload = &v4[f.offset + FRAME_HEAD_BYTES..f.offset + f.bytes - FRAME_TAIL_BYTES];
            block.decode(payload).unwrap();
            for frame in block.frames() {
                let (kind, payload) = frame.unwrap();
                let version = match kind {
                    FrameKind::Period => {
                        let b: &[u8; PERIOD_BYTES] = payload.try_into().unwrap();
                        format::decode_period(b).unwrap().surface_version
                    }
                    FrameKind::Surface | FrameKind::SurfaceLost => {
                        u64::from_le_bytes(payload[0..8].try_into().unwrap())
                    }
                    _ => continue,
                };
                order.push((kind, version));
            }
        }
        order
    }

    #[test]
    fn the_writer_puts_each_surface_before_the_first_period_rendering_it() {
        // As a relief session runs: the vision thread publishes (the tap first), and the control
        // thread renders the new version at once, while the writer is taking periods.
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.vlog");
        let tap = Arc::new(SurfaceTap::default());
        let recording = recording_with(&tap);
        let (mut producer, writer) = start_session(&path, HEADER, recording, 1 << 16).unwrap();
        producer.calibration(0, &CalibrationInForce::default());
        let mut cycle = 0;
        for version in 1..=1000u64 {
            tap.published(version, plane(0.3 + version as f64 * 1e-4));
            for _ in 0..25 {
                let mut r = noisy_sample(cycle);
                r.surface_version = version;
                producer.observe(&r, &WindowStats::default());
                cycle += 1;
            }
            if version % 40 == 0 {
                std::thread::sleep(Duration::from_millis(2));
            }
        }
        assert_eq!(writer.dropped(), 0);
        writer.finish(EndReason::StopRequest).unwrap();
        let order = surface_order_in_file(&std::fs::read(&path).unwrap());
        let mut newest = None;
        for (at, (kind, version)) in order.iter().enumerate() {
            if *kind == FrameKind::Period {
                assert!(
                    newest.is_some_and(|n| *version <= n),
                    "frame {at}: a period renders surface {version} before it is written (newest {newest:?})"
                );
            } else {
                newest = newest.max(Some(*version));
            }
        }
        assert_eq!(newest, Some(1000));
    }

    #[test]
    fn a_surface_written_after_the_first_period_rendering_it_is_read_before_that_period() {
        // An earlier writer took a surface published while it was taking periods after them.
        let period = |cycle: u64, version: u64| {
            let mut r = sample(cycle);
            r.surface_version = version;
            LogItem::Period(r)
        };
        let surface =
            |v: u64| LogItem::Surface(v, SurfaceEntry::Recorded(Arc::new(plane(0.3 + v as f64))));
        let session = LogItem::Session(Box::new(Ok(SessionInfo::new(
            "test",
            videt_config::Config::default(),
        ))));
        let mut written = vec![session, surface(0)];
        written.extend((0..10).map(|c| period(c, 0)));
        written.extend((10..15).map(|c| period(c, 1)));
        written.push(surface(1));
        written.push(LogItem::Surface(2, SurfaceEntry::Lost));
        written.extend((15..20).map(|c| period(c, 2)));
        // Version 3 never comes: its periods are given as they are, after one look ahead.
        written.extend((20..3000).map(|c| period(c, 3)));
        let mut expected = written.clone();
        let moved = expected.remove(17);
        expected.insert(12, moved);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("late.vlog");
        write_log(&path, &HEADER, written.clone()).unwrap();
        let v4: Vec<LogItem> = LogReader::open(&path).unwrap().collect();
        assert_eq!(v4, expected);
        let v3 = version_3_bytes(&HEADER, written).unwrap();
        let v3: Vec<LogItem> = LogReader::new(&v3[..]).unwrap().collect();
        assert_eq!(v3, expected);
        // The order of the log read whole.
        assert_eq!(
            read_log(&path).unwrap().items().collect::<Vec<_>>(),
            expected
        );
    }
}
