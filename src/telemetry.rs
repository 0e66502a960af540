//! Per-cycle telemetry: the control thread pushes every period's record into a wait-free SPSC
//! ring (`rtrb`); a writer thread drains it into a session log file. A full ring drops the record
//! (counted) rather than block the control thread.
//!
//! The log format is documented in `docs/telemetry.md`: a 32-byte header followed by fixed-size
//! 256-byte little-endian records, one per control period. Dropped records show as gaps in the
//! cycle numbers.

use std::fs::File;
use std::io::{self, BufWriter, Read, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

use videt_control::safety::{SafetyReason, SafetyState};
use videt_hal::MonoTime;

use crate::control_loop::{CycleObserver, WindowStats};
use crate::cycle::CycleRecord;

/// File magic.
pub const MAGIC: &[u8; 8] = b"VIDETLOG";
/// Format version.
pub const FORMAT_VERSION: u32 = 1;
/// Header size, bytes.
pub const HEADER_BYTES: usize = 32;
/// Record size, bytes.
pub const RECORD_BYTES: usize = 256;

/// The log file's header.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LogHeader {
    /// Control rate, Hz.
    pub rate_hz: u32,
    /// Wall-clock start of the session, nanoseconds since the Unix epoch.
    pub start_unix_ns: u64,
}

/// Control-thread side: pushes records, counts drops. Allocation-free.
pub struct TelemetryProducer {
    producer: rtrb::Producer<CycleRecord>,
    dropped: Arc<AtomicU64>,
}

impl CycleObserver for TelemetryProducer {
    fn observe(&mut self, record: &CycleRecord, _window: &WindowStats) {
        if self.producer.push(*record).is_err() {
            self.dropped.fetch_add(1, Ordering::Relaxed);
        }
    }
}

/// The running writer thread.
pub struct TelemetryWriter {
    handle: JoinHandle<io::Result<u64>>,
    finish: Arc<AtomicBool>,
    dropped: Arc<AtomicU64>,
    path: PathBuf,
}

impl TelemetryWriter {
    /// Records dropped so far because the ring was full.
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }
    /// The log file.
    pub fn path(&self) -> &Path {
        &self.path
    }
    /// Drain what is left, flush, fsync and close; returns the number of records written.
    pub fn finish(self) -> io::Result<u64> {
        self.finish.store(true, Ordering::Release);
        self.handle
            .join()
            .map_err(|_| io::Error::other("telemetry writer panicked"))?
    }
}

/// Create the session log at `path` and start the writer thread; returns the control thread's
/// producer (ring of `ring_records`) and the writer.
pub fn start(
    path: &Path,
    header: LogHeader,
    ring_records: usize,
) -> io::Result<(TelemetryProducer, TelemetryWriter)> {
    let file = File::create(path)?;
    let mut out = BufWriter::with_capacity(1 << 20, file);
    out.write_all(&encode_header(&header))?;
    let (producer, mut consumer) = rtrb::RingBuffer::<CycleRecord>::new(ring_records.max(1));
    let dropped = Arc::new(AtomicU64::new(0));
    let finish = Arc::new(AtomicBool::new(false));
    let writer_finish = Arc::clone(&finish);
    let handle = std::thread::Builder::new()
        .name("videt-telemetry".into())
        .spawn(move || {
            let mut written = 0u64;
            let mut buf = [0u8; RECORD_BYTES];
            loop {
                let done = writer_finish.load(Ordering::Acquire);
                let mut drained = 0;
                while let Ok(record) = consumer.pop() {
                    encode_record(&record, &mut buf);
                    out.write_all(&buf)?;
                    written += 1;
                    drained += 1;
                }
                if done {
                    break;
                }
                if drained == 0 {
                    out.flush()?;
                    std::thread::sleep(Duration::from_millis(20));
                }
            }
            out.flush()?;
            out.get_ref().sync_all()?;
            Ok(written)
        })?;
    Ok((
        TelemetryProducer {
            producer,
            dropped: Arc::clone(&dropped),
        },
        TelemetryWriter {
            handle,
            finish,
            dropped,
            path: path.to_path_buf(),
        },
    ))
}

/// Encode the header.
pub fn encode_header(h: &LogHeader) -> [u8; HEADER_BYTES] {
    let mut b = [0u8; HEADER_BYTES];
    b[0..8].copy_from_slice(MAGIC);
    b[8..12].copy_from_slice(&FORMAT_VERSION.to_le_bytes());
    b[12..16].copy_from_slice(&(RECORD_BYTES as u32).to_le_bytes());
    b[16..20].copy_from_slice(&h.rate_hz.to_le_bytes());
    b[24..32].copy_from_slice(&h.start_unix_ns.to_le_bytes());
    b
}

/// Safety state codes in the log: (state, reason, wire).
fn encode_safety(s: SafetyState) -> [u8; 3] {
    let state = match s {
        SafetyState::Normal => 0,
        SafetyState::MinimumTension(_) => 1,
        SafetyState::PowerOff(_) => 2,
    };
    let (reason, wire) = match s.reason() {
        None => (0, 255),
        Some(r) => (reason_code(r), r.wire().unwrap_or(255)),
    };
    [state, reason, wire]
}

fn reason_code(r: SafetyReason) -> u8 {
    match r {
        SafetyReason::EmergencyStop => 1,
        SafetyReason::DriveFault { .. } => 2,
        SafetyReason::SensorFault { .. } => 3,
        SafetyReason::OverTension { .. } => 4,
        SafetyReason::OverSpeed { .. } => 5,
        SafetyReason::WireBreak { .. } => 6,
        SafetyReason::DeadlineOverrun => 7,
        SafetyReason::NotCalibrated => 8,
        SafetyReason::StaleSurface => 9,
        SafetyReason::SoftwareFault => 10,
    }
}

fn decode_safety(state: u8, reason: u8, wire: u8) -> SafetyState {
    let w = (wire != 255).then_some(wire);
    let r = match reason {
        1 => SafetyReason::EmergencyStop,
        2 => SafetyReason::DriveFault { wire: w },
        3 => SafetyReason::SensorFault { wire: w },
        4 => SafetyReason::OverTension { wire: wire.min(2) },
        5 => SafetyReason::OverSpeed { wire: wire.min(2) },
        6 => SafetyReason::WireBreak { wire: wire.min(2) },
        7 => SafetyReason::DeadlineOverrun,
        8 => SafetyReason::NotCalibrated,
        9 => SafetyReason::StaleSurface,
        _ => SafetyReason::SoftwareFault,
    };
    match state {
        0 => SafetyState::Normal,
        1 => SafetyState::MinimumTension(r),
        _ => SafetyState::PowerOff(r),
    }
}

/// Encode one record (see `docs/telemetry.md` for the layout).
pub fn encode_record(r: &CycleRecord, b: &mut [u8; RECORD_BYTES]) {
    let mut at = 0;
    let mut put = |bytes: &[u8]| {
        b[at..at + bytes.len()].copy_from_slice(bytes);
        at += bytes.len();
    };
    put(&r.cycle.to_le_bytes());
    put(&r.time.0.to_le_bytes());
    put(&r.wake_latency_ns.to_le_bytes());
    put(&r.compute_ns.to_le_bytes());
    for arr in r.vectors() {
        for v in arr {
            put(&v.to_le_bytes());
        }
    }
    put(&r.contact_depth_m.to_le_bytes());
    put(&r.force_scale.to_le_bytes());
    put(&r.surface_version.to_le_bytes());
    let flags = u32::from(r.in_contact) | (u32::from(r.surface_stale) << 1);
    put(&flags.to_le_bytes());
    put(&encode_safety(r.safety));
    put(&r.released_wire.to_le_bytes());
    debug_assert_eq!(at, RECORD_BYTES);
}

/// Decode one record.
pub fn decode_record(b: &[u8; RECORD_BYTES]) -> CycleRecord {
    let mut at = 0;
    let mut take8 = || {
        let v: [u8; 8] = b[at..at + 8].try_into().expect("8 bytes");
        at += 8;
        v
    };
    let mut r = CycleRecord {
        cycle: u64::from_le_bytes(take8()),
        time: MonoTime(u64::from_le_bytes(take8())),
        wake_latency_ns: u64::from_le_bytes(take8()),
        compute_ns: u64::from_le_bytes(take8()),
        ..CycleRecord::default()
    };
    for arr in r.vectors_mut() {
        for v in arr.iter_mut() {
            *v = f64::from_le_bytes(take8());
        }
    }
    r.contact_depth_m = f64::from_le_bytes(take8());
    r.force_scale = f64::from_le_bytes(take8());
    r.surface_version = u64::from_le_bytes(take8());
    let flags = u32::from_le_bytes(b[248..252].try_into().expect("4 bytes"));
    r.in_contact = flags & 1 != 0;
    r.surface_stale = flags & 2 != 0;
    r.safety = decode_safety(b[252], b[253], b[254]);
    r.released_wire = b[255] as i8;
    r
}

/// Why a log could not be read.
#[derive(Debug, thiserror::Error)]
pub enum LogError {
    /// I/O failure.
    #[error("{0}")]
    Io(#[from] io::Error),
    /// Not a VIDET log, or a version this build cannot read.
    #[error("not a VIDET telemetry log (or an unsupported version): {0}")]
    Format(String),
}

/// A whole log read back.
#[derive(Debug, Clone)]
pub struct Log {
    /// The header.
    pub header: LogHeader,
    /// The records.
    pub records: Vec<CycleRecord>,
    /// Bytes of an incomplete last record (a log cut short by a crash), ignored.
    pub truncated_bytes: usize,
}

/// Read a log file.
pub fn read_log(path: &Path) -> Result<Log, LogError> {
    let mut bytes = Vec::new();
    File::open(path)?.read_to_end(&mut bytes)?;
    if bytes.len() < HEADER_BYTES || &bytes[0..8] != MAGIC {
        return Err(LogError::Format("missing VIDETLOG header".into()));
    }
    let version = u32::from_le_bytes(bytes[8..12].try_into().expect("4 bytes"));
    let record_bytes = u32::from_le_bytes(bytes[12..16].try_into().expect("4 bytes")) as usize;
    if version != FORMAT_VERSION || record_bytes != RECORD_BYTES {
        return Err(LogError::Format(format!(
            "version {version}, record size {record_bytes}"
        )));
    }
    let header = LogHeader {
        rate_hz: u32::from_le_bytes(bytes[16..20].try_into().expect("4 bytes")),
        start_unix_ns: u64::from_le_bytes(bytes[24..32].try_into().expect("8 bytes")),
    };
    let body = &bytes[HEADER_BYTES..];
    let records = body
        .chunks_exact(RECORD_BYTES)
        .map(|c| decode_record(c.try_into().expect("exact chunk")))
        .collect();
    Ok(Log {
        header,
        records,
        truncated_bytes: body.len() % RECORD_BYTES,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(cycle: u64) -> CycleRecord {
        CycleRecord {
            cycle,
            time: MonoTime(cycle * 1_000_000),
            wake_latency_ns: 12_345,
            compute_ns: 4_321,
            lengths_m: [0.3, 0.31, 0.32],
            tension_setpoint_n: [1.0, 2.0, 3.0],
            tension_measured_n: [1.1, 2.1, 3.1],
            torque_nm: [0.001, 0.002, 0.003],
            position_m: [0.1, 0.2, 0.3],
            velocity_m_s: [-0.1, 0.0, 0.1],
            desired_force_n: [0.0, 0.0, -2.0],
            rendered_force_n: [0.0, 0.01, -2.0],
            contact_depth_m: 0.0025,
            in_contact: true,
            safety: SafetyState::PowerOff(SafetyReason::WireBreak { wire: 2 }),
            force_scale: 0.75,
            surface_version: 9,
            surface_stale: true,
            released_wire: 1,
        }
    }

    #[test]
    fn records_round_trip() {
        let mut b = [0u8; RECORD_BYTES];
        let r = sample(7);
        encode_record(&r, &mut b);
        assert_eq!(decode_record(&b), r);
        let n = CycleRecord {
            released_wire: -1,
            ..CycleRecord::default()
        };
        encode_record(&n, &mut b);
        assert_eq!(decode_record(&b), n);
    }

    #[test]
    fn writer_records_everything_and_a_truncated_tail_is_reported() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.vlog");
        let (mut producer, writer) = start(
            &path,
            LogHeader {
                rate_hz: 1000,
                start_unix_ns: 5,
            },
            4096,
        )
        .unwrap();
        for c in 0..3000 {
            producer.observe(&sample(c), &WindowStats::default());
            if c % 500 == 0 {
                std::thread::sleep(Duration::from_millis(5));
            }
        }
        assert_eq!(writer.dropped(), 0);
        assert_eq!(writer.finish().unwrap(), 3000);
        let log = read_log(&path).unwrap();
        assert_eq!(
            log.header,
            LogHeader {
                rate_hz: 1000,
                start_unix_ns: 5
            }
        );
        assert_eq!(log.records.len(), 3000);
        assert_eq!(log.records[2999], sample(2999));
        // Cut the file in the middle of a record.
        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&path, &bytes[..bytes.len() - 100]).unwrap();
        let log = read_log(&path).unwrap();
        assert_eq!((log.records.len(), log.truncated_bytes), (2999, 156));
        std::fs::write(&path, b"garbage").unwrap();
        assert!(matches!(read_log(&path), Err(LogError::Format(_))));
    }

    #[test]
    fn a_full_ring_drops_and_counts_instead_of_blocking() {
        let dir = tempfile::tempdir().unwrap();
        let (mut producer, writer) = start(
            &dir.path().join("d.vlog"),
            LogHeader {
                rate_hz: 1000,
                start_unix_ns: 0,
            },
            64,
        )
        .unwrap();
        for c in 0..100_000 {
            producer.observe(&sample(c), &WindowStats::default());
        }
        let dropped = writer.dropped();
        let written = writer.finish().unwrap();
        assert!(dropped > 0);
        assert_eq!(dropped + written, 100_000);
    }
}
