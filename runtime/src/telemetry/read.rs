//! Reading a session log back: every version, and whatever is readable of a damaged one (a
//! service killed mid-write, a corrupt frame): the records before the damage, and where and
//! what the damage is; and whether the session closed its log (version 3's end frame) or the
//! log stops without closing, on a frame boundary or not.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{self, Read};
use std::path::Path;
use std::sync::Arc;

use super::format::{
    decode_calibration, decode_end, decode_period, decode_record, frame_crc, FrameKind, LogHeader,
    CALIBRATION_BYTES, FORMAT_VERSION, FORMAT_VERSION_1, FORMAT_VERSION_2, FRAME_HEAD_BYTES,
    FRAME_TAIL_BYTES, HEADER_BYTES, MAGIC, MAX_FRAME_PAYLOAD, PERIOD_BYTES, RECORD_BYTES,
};
use super::session::{CalibrationInForce, SessionEnd, SessionInfo};
use super::surfaces::RecordedSurface;
use crate::cycle::CycleRecord;

/// Why a log could not be read at all.
#[derive(Debug, thiserror::Error)]
pub enum LogError {
    /// I/O failure.
    #[error("{0}")]
    Io(#[from] io::Error),
    /// Not a VIDET log, or a version this build cannot read.
    #[error("{0}")]
    Format(String),
}

/// A calibration recorded in the log.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CalibrationEntry {
    /// Index in [`Log::records`] of the first record it applies to.
    pub before_record: usize,
    /// The period number from which it applies.
    pub from_cycle: u64,
    /// The calibration.
    pub calibration: CalibrationInForce,
}

/// A surface version in the log.
#[derive(Debug, Clone, PartialEq)]
pub enum SurfaceEntry {
    /// Recorded.
    Recorded(Arc<RecordedSurface>),
    /// Published but not recorded (the writer fell behind).
    Lost,
}

/// Where a log stops being readable, and why.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Damage {
    /// Byte offset in the file of the first unreadable byte.
    pub offset: u64,
    /// What is wrong there.
    pub what: String,
}

/// A whole log read back.
#[derive(Debug, Clone)]
pub struct Log {
    /// The header.
    pub header: LogHeader,
    /// The format version of the file.
    pub version: u32,
    /// The period records, in file order.
    pub records: Vec<CycleRecord>,
    /// The session (version 2): `Err` when its frame could not be understood.
    pub session: Option<Result<SessionInfo, String>>,
    /// Calibrations in force, in file order.
    pub calibrations: Vec<CalibrationEntry>,
    /// Surfaces by version.
    pub surfaces: BTreeMap<u64, SurfaceEntry>,
    /// Bytes at the end that were not read (an incomplete last record, or everything from the
    /// damage on).
    pub truncated_bytes: usize,
    /// The first damage, if any: nothing after it is read.
    pub damage: Option<Damage>,
    /// The end frame, when the session closed the log (`None`: it ended without closing, or
    /// the log is of a version before 3, which records no end).
    pub end: Option<SessionEnd>,
}

impl Log {
    /// A log of `records` alone (no session, calibration or surface).
    pub fn of_records(header: LogHeader, records: Vec<CycleRecord>) -> Log {
        Log {
            header,
            version: FORMAT_VERSION,
            records,
            session: None,
            calibrations: Vec::new(),
            surfaces: BTreeMap::new(),
            truncated_bytes: 0,
            damage: None,
            end: None,
        }
    }

    /// Whether the session closed its log: an end frame was read.
    pub fn closed(&self) -> bool {
        self.end.is_some()
    }

    /// One line on how the session ended: as its end frame says (`session closed at cycle N:
    /// why`), or `session ended without closing, at cycle N`, the last period read.
    pub fn end_note(&self) -> String {
        let at = |cycle: Option<u64>| {
            cycle.map_or_else(
                || "before its first period".to_string(),
                |c| format!("at cycle {c}"),
            )
        };
        let last_read = self.records.last().map(|r| r.cycle);
        match &self.end {
            Some(end) => {
                let mut note = format!("session closed {}: {}", at(end.last_cycle), end.reason);
                if let (Some(last), Some(read)) = (end.last_cycle, last_read) {
                    if last > read {
                        note += &format!(" (the periods after cycle {read} were dropped)");
                    }
                }
                note
            }
            None if self.version >= FORMAT_VERSION => format!(
                "session ended without closing, {} (no end frame: the service was killed or lost power, or the file was cut)",
                at(last_read)
            ),
            None => format!(
                "session ended without closing, {} (a version {} log: that format records no end)",
                at(last_read),
                self.version
            ),
        }
    }

    /// One line on what could not be read, when something could not (`None` for a whole log).
    pub fn damage_note(&self) -> Option<String> {
        let d = self.damage.as_ref()?;
        Some(format!(
            "read {} records, the rest is damaged: {} at byte {} ({} bytes not read)",
            self.records.len(),
            d.what,
            d.offset,
            self.truncated_bytes
        ))
    }
}

/// Read a log file (version 1, 2 or 3).
pub fn read_log(path: &Path) -> Result<Log, LogError> {
    let mut bytes = Vec::new();
    File::open(path)?.read_to_end(&mut bytes)?;
    parse_log(&bytes)
}

/// Parse a log's bytes (version 1, 2 or 3).
pub fn parse_log(bytes: &[u8]) -> Result<Log, LogError> {
    if bytes.len() < HEADER_BYTES && MAGIC.starts_with(&bytes[..bytes.len().min(8)]) {
        return Err(LogError::Format(format!(
            "an empty session log ({} bytes: cut short before its header was written)",
            bytes.len()
        )));
    }
    if bytes.len() < HEADER_BYTES || &bytes[0..8] != MAGIC {
        return Err(LogError::Format(
            "not a VIDET session log (no VIDETLOG header)".into(),
        ));
    }
    let u32_at = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().expect("4 bytes"));
    let version = u32_at(8);
    let record_bytes = u32_at(12) as usize;
    let header = LogHeader {
        rate_hz: u32_at(16),
        start_unix_ns: u64::from_le_bytes(bytes[24..32].try_into().expect("8 bytes")),
    };
    let mut log = Log {
        version,
        ..Log::of_records(header, Vec::new())
    };
    let body = &bytes[HEADER_BYTES..];
    match (version, record_bytes) {
        (FORMAT_VERSION_1, RECORD_BYTES) => {
            log.records = body
                .chunks_exact(RECORD_BYTES)
                .map(|c| decode_record(c.try_into().expect("exact chunk")))
                .collect();
            log.truncated_bytes = body.len() % RECORD_BYTES;
            if log.truncated_bytes > 0 {
                log.damage = Some(Damage {
                    offset: (bytes.len() - log.truncated_bytes) as u64,
                    what: "an incomplete last record".into(),
                });
            }
        }
        (FORMAT_VERSION_2 | FORMAT_VERSION, PERIOD_BYTES) => read_frames(body, &mut log),
        _ => {
            return Err(LogError::Format(format!(
                "a VIDET session log of version {version} (record size {record_bytes}): this videt reads versions {FORMAT_VERSION_1} to {FORMAT_VERSION}"
            )))
        }
    }
    Ok(log)
}

/// A whole frame of a log (head, length and CRC good): where it is and what kind it is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameAt {
    /// Byte offset of its head in the file.
    pub offset: usize,
    /// Its kind.
    pub kind: FrameKind,
    /// Its size in the file (head, payload and CRC), bytes.
    pub bytes: usize,
}

/// The whole frames of a log of version 2 or 3, in file order, up to its end or the first frame
/// that is incomplete, has an unknown kind or a bad CRC (their payloads are not decoded); empty
/// for a version 1 log. An error when `bytes` is not a session log.
pub fn frames(bytes: &[u8]) -> Result<Vec<FrameAt>, LogError> {
    let log = parse_log(&bytes[..bytes.len().min(HEADER_BYTES)])?;
    if log.version == FORMAT_VERSION_1 {
        return Ok(Vec::new());
    }
    let mut out = Vec::new();
    let mut at = 0;
    while let Ok((kind, payload)) = next_frame(&bytes[HEADER_BYTES..], at) {
        let size = FRAME_HEAD_BYTES + payload.len() + FRAME_TAIL_BYTES;
        out.push(FrameAt {
            offset: HEADER_BYTES + at,
            kind,
            bytes: size,
        });
        at += size;
    }
    Ok(out)
}

/// The whole frame at `at` of `body` (kind and payload), or what is wrong there (`None`: the
/// end of the body).
fn next_frame(body: &[u8], at: usize) -> Result<(FrameKind, &[u8]), Option<String>> {
    let rest = &body[at..];
    if rest.is_empty() {
        return Err(None);
    }
    if rest.len() < FRAME_HEAD_BYTES {
        return Err(Some("an incomplete frame".into()));
    }
    let kind = FrameKind::from_byte(rest[0]);
    let len = u32::from_le_bytes(rest[4..8].try_into().expect("4 bytes")) as usize;
    let Some(kind) = kind.filter(|_| rest[1..4] == [0, 0, 0] && len <= MAX_FRAME_PAYLOAD) else {
        return Err(Some(format!("a corrupt frame head (kind {})", rest[0])));
    };
    let total = FRAME_HEAD_BYTES + len + FRAME_TAIL_BYTES;
    if rest.len() < total {
        return Err(Some("an incomplete frame".into()));
    }
    let crc = u32::from_le_bytes(
        rest[total - FRAME_TAIL_BYTES..total]
            .try_into()
            .expect("4 bytes"),
    );
    if frame_crc(&rest[..total - FRAME_TAIL_BYTES]) != crc {
        return Err(Some("a corrupt frame (CRC mismatch)".into()));
    }
    Ok((kind, &rest[FRAME_HEAD_BYTES..FRAME_HEAD_BYTES + len]))
}

/// Read the frames of version 2 or 3 until the end or the first damage; anything after an end
/// frame is damage.
fn read_frames(body: &[u8], log: &mut Log) {
    let mut at = 0usize;
    let mut last_surface: Option<Arc<RecordedSurface>> = None;
    let damaged = |at: usize, what: String| {
        Some(Damage {
            offset: (HEADER_BYTES + at) as u64,
            what,
        })
    };
    while at < body.len() {
        if log.end.is_some() {
            log.damage = damaged(at, "bytes after the end frame".into());
            break;
        }
        let (kind, payload) = match next_frame(body, at) {
            Ok(frame) => frame,
            Err(what) => {
                log.damage = damaged(at, what.unwrap_or_default());
                break;
            }
        };
        if let Err(what) = read_frame(kind, payload, log, &mut last_surface) {
            log.damage = damaged(at, what);
            break;
        }
        at += FRAME_HEAD_BYTES + payload.len() + FRAME_TAIL_BYTES;
    }
    log.truncated_bytes = body.len() - at;
}

fn read_frame(
    kind: FrameKind,
    payload: &[u8],
    log: &mut Log,
    last_surface: &mut Option<Arc<RecordedSurface>>,
) -> Result<(), String> {
    match kind {
        FrameKind::Period => {
            let b: &[u8; PERIOD_BYTES] = payload
                .try_into()
                .map_err(|_| format!("a period frame of {} bytes", payload.len()))?;
            log.records
                .push(decode_period(b).map_err(|e| format!("a corrupt period: {e}"))?);
        }
        FrameKind::Session => {
            let session = std::str::from_utf8(payload)
                .map_err(|e| e.to_string())
                .and_then(SessionInfo::from_toml)
                .map_err(|e| format!("the session's configuration cannot be used: {e}"));
            log.session = Some(session);
        }
        FrameKind::Calibration => {
            let b: &[u8; CALIBRATION_BYTES] = payload
                .try_into()
                .map_err(|_| format!("a calibration frame of {} bytes", payload.len()))?;
            let (from_cycle, calibration) =
                decode_calibration(b).map_err(|e| format!("a corrupt calibration: {e}"))?;
            log.calibrations.push(CalibrationEntry {
                before_record: log.records.len(),
                from_cycle,
                calibration,
            });
        }
        FrameKind::Surface => {
            if payload.len() < 9 {
                return Err("a surface frame too short".into());
            }
            let version = u64::from_le_bytes(payload[0..8].try_into().expect("8 bytes"));
            let surface = match payload[8] {
                // The same surface as the previous one recorded.
                0 => last_surface
                    .clone()
                    .ok_or("a repeated surface with none before it")?,
                1 => Arc::new(
                    RecordedSurface::decode(&payload[9..])
                        .map_err(|e| format!("a corrupt surface: {e}"))?,
                ),
                k => return Err(format!("a surface frame of undefined form {k}")),
            };
            *last_surface = Some(Arc::clone(&surface));
            log.surfaces
                .insert(version, SurfaceEntry::Recorded(surface));
        }
        FrameKind::SurfaceLost => {
            let b: [u8; 8] = payload
                .try_into()
                .map_err(|_| "a lost-surface frame of the wrong size".to_string())?;
            log.surfaces
                .insert(u64::from_le_bytes(b), SurfaceEntry::Lost);
        }
        FrameKind::End => {
            log.end = Some(decode_end(payload).map_err(|e| format!("a corrupt end frame: {e}"))?);
        }
    }
    Ok(())
}
