//! Reading a session log back: every version, and whatever is readable of a damaged one (a
//! service killed mid-write, a corrupt frame): the records before the damage, and where and
//! what the damage is; and whether the session closed its log (the end frame of versions 3 and
//! 4) or the log stops without closing, on a frame boundary or not. [`LogReader`] reads item by
//! item in bounded memory; [`read_log`] gathers a whole log.

use std::collections::{BTreeMap, VecDeque};
use std::fs::File;
use std::io::{self, BufReader, Read};
use std::path::Path;
use std::sync::Arc;

use super::block::DecodedBlock;
use super::format::{
    decode_calibration, decode_end, decode_period, decode_record, frame_crc, FrameKind, LogHeader,
    BATCH_BYTES, CALIBRATION_BYTES, FORMAT_VERSION, FORMAT_VERSION_1, FORMAT_VERSION_2,
    FORMAT_VERSION_3, FRAME_HEAD_BYTES, FRAME_TAIL_BYTES, HEADER_BYTES, MAGIC, MAX_FRAME_PAYLOAD,
    PERIOD_BYTES, RECORD_BYTES,
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

    /// Everything `reader` reads, gathered.
    pub fn gather<R: Read>(mut reader: LogReader<R>) -> Log {
        let mut log = Log {
            version: reader.version(),
            ..Log::of_records(reader.header(), Vec::new())
        };
        for item in &mut reader {
            match item {
                LogItem::Period(r) => log.records.push(r),
                LogItem::Session(s) => log.session = Some(*s),
                LogItem::Calibration {
                    from_cycle,
                    calibration,
                } => log.calibrations.push(CalibrationEntry {
                    before_record: log.records.len(),
                    from_cycle,
                    calibration,
                }),
                LogItem::Surface(version, entry) => {
                    log.surfaces.insert(version, entry);
                }
                LogItem::End(end) => log.end = Some(end),
            }
        }
        log.damage = reader.damage().cloned();
        log.truncated_bytes = reader.truncated_bytes() as usize;
        log
    }

    /// The log's items in the order a writer would have written them: the session, each
    /// calibration before the record it applies to, each surface version before the first
    /// record rendering it or a later one, the records, the end.
    pub fn items(&self) -> impl Iterator<Item = LogItem> + '_ {
        let mut calibrations = self.calibrations.iter().peekable();
        let mut surfaces = self.surfaces.iter().peekable();
        let session = self.session.clone().map(|s| LogItem::Session(Box::new(s)));
        let periods = self.records.iter().enumerate().flat_map(move |(i, r)| {
            let mut before = Vec::new();
            while let Some(c) = calibrations.next_if(|c| c.before_record <= i) {
                before.push(LogItem::Calibration {
                    from_cycle: c.from_cycle,
                    calibration: c.calibration,
                });
            }
            while let Some((v, s)) = surfaces.next_if(|(v, _)| **v <= r.surface_version) {
                before.push(LogItem::Surface(*v, s.clone()));
            }
            before.push(LogItem::Period(*r));
            before
        });
        let after_records = self
            .calibrations
            .iter()
            .filter(|c| c.before_record >= self.records.len())
            .map(|c| LogItem::Calibration {
                from_cycle: c.from_cycle,
                calibration: c.calibration,
            });
        let last_rendered = self.records.iter().map(|r| r.surface_version).max();
        let unrendered = self
            .surfaces
            .iter()
            .filter(move |(v, _)| last_rendered.is_none_or(|last| **v > last))
            .map(|(v, s)| LogItem::Surface(*v, s.clone()));
        session
            .into_iter()
            .chain(periods)
            .chain(after_records)
            .chain(unrendered)
            .chain(self.end.clone().map(LogItem::End))
    }

    /// Whether the session closed its log: an end frame was read.
    pub fn closed(&self) -> bool {
        self.end.is_some()
    }

    /// One line on how the session ended: as its end frame says (`session closed at cycle N:
    /// why`), or `session ended without closing, at cycle N`, the last period read.
    pub fn end_note(&self) -> String {
        end_note(
            self.end.as_ref(),
            self.version,
            self.records.last().map(|r| r.cycle),
        )
    }

    /// One line on what could not be read, when something could not (`None` for a whole log).
    pub fn damage_note(&self) -> Option<String> {
        damage_note(
            self.damage.as_ref(),
            self.records.len() as u64,
            self.truncated_bytes as u64,
        )
    }
}

/// [`Log::end_note`] of a log of `version` whose last period read is `last_read`.
fn end_note(end: Option<&SessionEnd>, version: u32, last_read: Option<u64>) -> String {
    let at = |cycle: Option<u64>| {
        cycle.map_or_else(
            || "before its first period".to_string(),
            |c| format!("at cycle {c}"),
        )
    };
    match end {
        Some(end) => {
            let mut note = format!("session closed {}: {}", at(end.last_cycle), end.reason);
            if let (Some(last), Some(read)) = (end.last_cycle, last_read) {
                if last > read {
                    note += &format!(" (the periods after cycle {read} were dropped)");
                }
            }
            note
        }
        None if version >= FORMAT_VERSION_3 => format!(
            "session ended without closing, {} (no end frame: the service was killed or lost power, or the file was cut)",
            at(last_read)
        ),
        None => format!(
            "session ended without closing, {} (a version {version} log: that format records no end)",
            at(last_read),
        ),
    }
}

/// [`Log::damage_note`] of a log of which `records` periods were read.
fn damage_note(damage: Option<&Damage>, records: u64, truncated_bytes: u64) -> Option<String> {
    let d = damage?;
    Some(format!(
        "read {records} records, the rest is damaged: {} at byte {} ({truncated_bytes} bytes not read)",
        d.what, d.offset,
    ))
}

/// Read a log file (versions 1 to 4) whole. A long session's log is large in memory: read it
/// with [`LogReader`] instead.
pub fn read_log(path: &Path) -> Result<Log, LogError> {
    Ok(Log::gather(LogReader::open(path)?))
}

/// Parse a log's bytes (versions 1 to 4).
pub fn parse_log(bytes: &[u8]) -> Result<Log, LogError> {
    Ok(Log::gather(LogReader::new(bytes)?))
}

/// How many items a [`LogReader`] reads ahead for a surface written after the first period
/// rendering it: two batches of periods.
const SURFACE_LOOKAHEAD_ITEMS: usize = 2 * BATCH_BYTES / PERIOD_BYTES + 64;

/// One thing a log records, in the order it was written (a surface the writer took after the
/// first period rendering it comes before that period).
// Nearly every item is a period: boxing it would allocate for each.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq)]
pub enum LogItem {
    /// The session (version 2 on): `Err` when its frame could not be understood. (Boxed: the
    /// configuration is large, and every period is an item too.)
    Session(Box<Result<SessionInfo, String>>),
    /// The calibration in force from the period `from_cycle` on.
    Calibration {
        /// The period number from which it applies.
        from_cycle: u64,
        /// The calibration.
        calibration: CalibrationInForce,
    },
    /// A surface version, recorded or lost.
    Surface(u64, SurfaceEntry),
    /// One period.
    Period(CycleRecord),
    /// The session closed its log (the last item).
    End(SessionEnd),
}

/// Reads a log item by item from any reader, holding one frame (or one block of version 4) at
/// a time: its memory does not grow with the session's length. The items come in the log's
/// order, but for a surface written after the first period rendering it: that surface is
/// given before the period, as [`Log::items`] gives it. After the last item,
/// [`LogReader::damage`] says whether and where the log stopped being readable.
pub struct LogReader<R: Read> {
    input: R,
    header: LogHeader,
    version: u32,
    /// File offset of the next frame (or record) to read.
    offset: u64,
    /// Items read and not yet returned (those of a block).
    pending: VecDeque<LogItem>,
    /// Nothing more is read: the end of the file, or damage.
    finished: bool,
    damage: Option<Damage>,
    truncated_bytes: u64,
    records: u64,
    last_cycle: Option<u64>,
    end: Option<SessionEnd>,
    last_surface: Option<Arc<RecordedSurface>>,
    /// The newest surface version returned so far.
    newest_surface_given: Option<u64>,
    /// A surface version looked ahead for and not found: not looked for again.
    surface_not_found: Option<u64>,
    session_text: Option<String>,
    frame: Vec<u8>,
    block: DecodedBlock,
}

impl LogReader<BufReader<File>> {
    /// Read the log file at `path`.
    pub fn open(path: &Path) -> Result<Self, LogError> {
        LogReader::new(BufReader::with_capacity(1 << 16, File::open(path)?))
    }
}

impl<R: Read> LogReader<R> {
    /// Read a log from `input`: its header now (an error when it is not a log this build
    /// reads), the rest as it is iterated.
    pub fn new(mut input: R) -> Result<Self, LogError> {
        let mut head = [0u8; HEADER_BYTES];
        let got = read_full(&mut input, &mut head)?;
        if got < HEADER_BYTES && MAGIC.starts_with(&head[..got.min(8)]) {
            return Err(LogError::Format(format!(
                "an empty session log ({got} bytes: cut short before its header was written)"
            )));
        }
        if got < HEADER_BYTES || &head[0..8] != MAGIC {
            return Err(LogError::Format(
                "not a VIDET session log (no VIDETLOG header)".into(),
            ));
        }
        let u32_at = |at: usize| u32::from_le_bytes(head[at..at + 4].try_into().expect("4 bytes"));
        let version = u32_at(8);
        let record_bytes = u32_at(12) as usize;
        match (version, record_bytes) {
            (FORMAT_VERSION_1, RECORD_BYTES)
            | (FORMAT_VERSION_2 | FORMAT_VERSION_3 | FORMAT_VERSION, PERIOD_BYTES) => {}
            _ => {
                return Err(LogError::Format(format!(
                    "a VIDET session log of version {version} (record size {record_bytes}): this videt reads versions {FORMAT_VERSION_1} to {FORMAT_VERSION}"
                )))
            }
        }
        Ok(LogReader {
            input,
            header: LogHeader {
                rate_hz: u32_at(16),
                start_unix_ns: u64::from_le_bytes(head[24..32].try_into().expect("8 bytes")),
            },
            version,
            offset: HEADER_BYTES as u64,
            pending: VecDeque::new(),
            finished: false,
            damage: None,
            truncated_bytes: 0,
            records: 0,
            last_cycle: None,
            end: None,
            last_surface: None,
            newest_surface_given: None,
            surface_not_found: None,
            session_text: None,
            frame: Vec::new(),
            block: DecodedBlock::default(),
        })
    }

    /// The header.
    pub fn header(&self) -> LogHeader {
        self.header
    }
    /// The format version of the log.
    pub fn version(&self) -> u32 {
        self.version
    }
    /// The first damage, once read: nothing after it is read.
    pub fn damage(&self) -> Option<&Damage> {
        self.damage.as_ref()
    }
    /// Bytes at the end that were not read (from the damage on), once read.
    pub fn truncated_bytes(&self) -> u64 {
        self.truncated_bytes
    }
    /// Period records read so far.
    pub fn records(&self) -> u64 {
        self.records
    }
    /// Whether the session closed its log: an end frame was read.
    pub fn closed(&self) -> bool {
        self.end.is_some()
    }
    /// The session frame's text (its TOML, as recorded) once read: what a replay compares
    /// with today's configuration keys.
    pub fn session_text(&self) -> Option<&str> {
        self.session_text.as_deref()
    }
    /// [`Log::end_note`] of what was read so far.
    pub fn end_note(&self) -> String {
        end_note(self.end.as_ref(), self.version, self.last_cycle)
    }
    /// [`Log::damage_note`] of what was read so far.
    pub fn damage_note(&self) -> Option<String> {
        damage_note(self.damage.as_ref(), self.records, self.truncated_bytes)
    }

    /// Stop at damage `what` at `offset`, `read` bytes of which were read: the rest of the
    /// input is counted, not kept.
    fn damaged(&mut self, offset: u64, read: u64, what: String) {
        let rest = io::copy(&mut self.input, &mut io::sink()).unwrap_or(0);
        self.truncated_bytes = read + rest;
        self.damage = Some(Damage { offset, what });
        self.finished = true;
    }

    /// [`Self::read_more`], a read error taken as damage.
    fn read_more_or_stop(&mut self) {
        if let Err(e) = self.read_more() {
            let at = self.offset;
            self.damaged(at, 0, format!("a read error ({e})"));
        }
    }

    /// The period at the front of `pending` renders surface version `needed`, not yet given:
    /// read ahead (at most [`SURFACE_LOOKAHEAD_ITEMS`]) for it and, when it is there, put the
    /// surfaces up to it before that period, as [`Log::items`] gives them. A writer takes the surfaces published
    /// between its batches, so a surface published while it was taking a batch's periods is
    /// written after the first period rendering it, within the next batch at the latest.
    fn bring_surface_forward(&mut self, needed: u64) {
        let found = |pending: &VecDeque<LogItem>| {
            pending
                .iter()
                .any(|i| matches!(i, LogItem::Surface(v, _) if *v >= needed))
        };
        while !self.finished
            && self.pending.len() < SURFACE_LOOKAHEAD_ITEMS
            && !found(&self.pending)
        {
            self.read_more_or_stop();
        }
        if !self
            .pending
            .iter()
            .any(|i| matches!(i, LogItem::Surface(v, _) if *v == needed))
        {
            // Not in the log (or too far on): the items stay in the log's order.
            self.surface_not_found = Some(needed);
            return;
        }
        let (mut ahead, rest): (VecDeque<LogItem>, VecDeque<LogItem>) = self
            .pending
            .drain(..)
            .partition(|i| matches!(i, LogItem::Surface(v, _) if *v <= needed));
        ahead.extend(rest);
        self.pending = ahead;
    }

    /// Read the next record, frame or block into `pending`, or finish.
    fn read_more(&mut self) -> io::Result<()> {
        if self.version == FORMAT_VERSION_1 {
            let mut b = [0u8; RECORD_BYTES];
            match read_full(&mut self.input, &mut b)? {
                0 => self.finished = true,
                RECORD_BYTES => {
                    self.offset += RECORD_BYTES as u64;
                    let record = decode_record(&b);
                    self.records += 1;
                    self.last_cycle = Some(record.cycle);
                    self.pending.push_back(LogItem::Period(record));
                }
                got => self.damaged(self.offset, got as u64, "an incomplete last record".into()),
            }
            return Ok(());
        }
        let at = self.offset;
        let mut head = [0u8; FRAME_HEAD_BYTES];
        let got = read_full(&mut self.input, &mut head)?;
        if got == 0 {
            self.finished = true;
            return Ok(());
        }
        if self.end.is_some() {
            self.damaged(at, got as u64, "bytes after the end frame".into());
            return Ok(());
        }
        if got < FRAME_HEAD_BYTES {
            self.damaged(at, got as u64, "an incomplete frame".into());
            return Ok(());
        }
        let Some((kind, len)) = frame_head(&head, self.version) else {
            self.damaged(
                at,
                got as u64,
                format!("a corrupt frame head (kind {})", head[0]),
            );
            return Ok(());
        };
        self.frame.clear();
        self.frame.extend_from_slice(&head);
        self.frame
            .resize(FRAME_HEAD_BYTES + len + FRAME_TAIL_BYTES, 0);
        let got = read_full(&mut self.input, &mut self.frame[FRAME_HEAD_BYTES..])?;
        if got < len + FRAME_TAIL_BYTES {
            let read = (FRAME_HEAD_BYTES + got) as u64;
            self.damaged(at, read, "an incomplete frame".into());
            return Ok(());
        }
        let total = self.frame.len();
        if !crc_holds(&self.frame) {
            self.damaged(at, total as u64, "a corrupt frame (CRC mismatch)".into());
            return Ok(());
        }
        self.offset += total as u64;
        let frame = std::mem::take(&mut self.frame);
        let payload = &frame[FRAME_HEAD_BYTES..total - FRAME_TAIL_BYTES];
        let read = if kind == FrameKind::Block {
            self.read_block(payload)
        } else {
            self.read_frame(kind, payload)
        };
        self.frame = frame;
        if let Err(what) = read {
            self.damaged(at, total as u64, what);
        }
        Ok(())
    }

    /// The frames of a block: those before the first damaged one are read.
    fn read_block(&mut self, payload: &[u8]) -> Result<(), String> {
        let mut block = std::mem::take(&mut self.block);
        let read = block.decode(payload).and_then(|()| {
            block.frames().try_for_each(|frame| {
                if self.end.is_some() {
                    return Err("frames after the end frame".into());
                }
                let (kind, payload) = frame?;
                self.read_frame(kind, payload)
            })
        });
        self.block = block;
        read
    }

    /// One frame's item, into `pending`.
    fn read_frame(&mut self, kind: FrameKind, payload: &[u8]) -> Result<(), String> {
        let item = match kind {
            FrameKind::Period => {
                let b: &[u8; PERIOD_BYTES] = payload
                    .try_into()
                    .map_err(|_| format!("a period frame of {} bytes", payload.len()))?;
                let record = decode_period(b).map_err(|e| format!("a corrupt period: {e}"))?;
                self.records += 1;
                self.last_cycle = Some(record.cycle);
                LogItem::Period(record)
            }
            FrameKind::Session => {
                let text = std::str::from_utf8(payload).map_err(|e| e.to_string());
                self.session_text = text.as_ref().ok().map(|t| t.to_string());
                LogItem::Session(Box::new(
                    text.and_then(SessionInfo::from_toml)
                        .map_err(|e| format!("the session's configuration cannot be used: {e}")),
                ))
            }
            FrameKind::Calibration => {
                let b: &[u8; CALIBRATION_BYTES] = payload
                    .try_into()
                    .map_err(|_| format!("a calibration frame of {} bytes", payload.len()))?;
                let (from_cycle, calibration) =
                    decode_calibration(b).map_err(|e| format!("a corrupt calibration: {e}"))?;
                LogItem::Calibration {
                    from_cycle,
                    calibration,
                }
            }
            FrameKind::Surface => {
                if payload.len() < 9 {
                    return Err("a surface frame too short".into());
                }
                let version = u64::from_le_bytes(payload[0..8].try_into().expect("8 bytes"));
                let surface = match payload[8] {
                    // The same surface as the previous one recorded.
                    0 => self
                        .last_surface
                        .clone()
                        .ok_or("a repeated surface with none before it")?,
                    1 => Arc::new(
                        RecordedSurface::decode(&payload[9..])
                            .map_err(|e| format!("a corrupt surface: {e}"))?,
                    ),
                    k => return Err(format!("a surface frame of undefined form {k}")),
                };
                self.last_surface = Some(Arc::clone(&surface));
                LogItem::Surface(version, SurfaceEntry::Recorded(surface))
            }
            FrameKind::SurfaceLost => {
                let b: [u8; 8] = payload
                    .try_into()
                    .map_err(|_| "a lost-surface frame of the wrong size".to_string())?;
                LogItem::Surface(u64::from_le_bytes(b), SurfaceEntry::Lost)
            }
            FrameKind::End => {
                let end = decode_end(payload).map_err(|e| format!("a corrupt end frame: {e}"))?;
                self.end = Some(end.clone());
                LogItem::End(end)
            }
            FrameKind::Block => return Err("a block inside a block".into()),
        };
        self.pending.push_back(item);
        Ok(())
    }
}

impl<R: Read> Iterator for LogReader<R> {
    type Item = LogItem;

    fn next(&mut self) -> Option<LogItem> {
        loop {
            if let Some(LogItem::Period(record)) = self.pending.front() {
                let needed = record.surface_version;
                let given = self.newest_surface_given;
                if given.is_some_and(|newest| needed > newest)
                    && self.surface_not_found.is_none_or(|v| needed > v)
                {
                    self.bring_surface_forward(needed);
                }
            }
            if let Some(item) = self.pending.pop_front() {
                if let LogItem::Surface(version, _) = &item {
                    self.newest_surface_given = Some(
                        self.newest_surface_given
                            .map_or(*version, |v| v.max(*version)),
                    );
                }
                return Some(item);
            }
            if self.finished {
                return None;
            }
            self.read_more_or_stop();
        }
    }
}

/// Read into `buf` until it is full or the input ends; returns the bytes read.
fn read_full(input: &mut impl Read, buf: &mut [u8]) -> io::Result<usize> {
    let mut got = 0;
    while got < buf.len() {
        match input.read(&mut buf[got..]) {
            Ok(0) => break,
            Ok(n) => got += n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(got)
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

/// The whole frames of a log of version 2 to 4 (version 4's are its blocks), in file order, up
/// to its end or the first frame that is incomplete, has an unknown kind or a bad CRC (their
/// payloads are not decoded); empty for a version 1 log. An error when `bytes` is not a session
/// log.
pub fn frames(bytes: &[u8]) -> Result<Vec<FrameAt>, LogError> {
    let version = LogReader::new(&bytes[..bytes.len().min(HEADER_BYTES)])?.version();
    if version == FORMAT_VERSION_1 {
        return Ok(Vec::new());
    }
    let mut out = Vec::new();
    let mut at = HEADER_BYTES;
    while let Some(frame) = whole_frame(&bytes[at..], version) {
        out.push(FrameAt {
            offset: at,
            ..frame
        });
        at += frame.bytes;
    }
    Ok(out)
}

/// The whole frame at the start of `rest` in a log of `version` (its offset 0), if there is one.
fn whole_frame(rest: &[u8], version: u32) -> Option<FrameAt> {
    let (kind, len) = frame_head(rest.get(..FRAME_HEAD_BYTES)?, version)?;
    let total = FRAME_HEAD_BYTES + len + FRAME_TAIL_BYTES;
    crc_holds(rest.get(..total)?).then_some(FrameAt {
        offset: 0,
        kind,
        bytes: total,
    })
}

/// The kind and payload length of a frame head in a log of `version`, unless the head is
/// corrupt: an unknown kind (a block before version 4), reserved bytes set, or a payload
/// longer than a reader accepts.
fn frame_head(head: &[u8], version: u32) -> Option<(FrameKind, usize)> {
    let len = u32::from_le_bytes(head[4..8].try_into().expect("4 bytes")) as usize;
    FrameKind::from_byte(head[0])
        .filter(|k| *k != FrameKind::Block || version >= FORMAT_VERSION)
        .filter(|_| head[1..4] == [0, 0, 0] && len <= MAX_FRAME_PAYLOAD)
        .map(|kind| (kind, len))
}

/// Whether a whole frame's CRC matches its head and payload.
fn crc_holds(frame: &[u8]) -> bool {
    let (body, tail) = frame.split_at(frame.len() - FRAME_TAIL_BYTES);
    frame_crc(body) == u32::from_le_bytes(tail.try_into().expect("4 bytes"))
}
