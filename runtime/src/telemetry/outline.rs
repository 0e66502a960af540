//! What a log holds besides its periods, gathered in one pass in memory that does not grow
//! with the session's length: the session, the calibrations and when they took effect, every
//! surface version and when a period first rendered it, the periods' count and span, and how
//! the log ends. A reader that streams a long log (an export, a summary) reads the outline
//! first, then the log again item by item.

use std::collections::BTreeMap;
use std::io::Read;
use std::path::Path;

use super::read::{CalibrationEntry, Damage, Log, LogError, LogItem, LogReader, SurfaceEntry};
use super::session::{SessionEnd, SessionInfo};
use super::LogHeader;

/// A calibration and the time of the first period it applied to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CalibrationAt {
    /// The calibration, and the index of the first record it applies to.
    pub entry: CalibrationEntry,
    /// The time of that record, ns (`None`: no record followed it).
    pub time_ns: Option<u64>,
}

/// What a log holds besides its periods.
#[derive(Debug, Clone)]
pub struct LogOutline {
    /// The header.
    pub header: LogHeader,
    /// The format version.
    pub version: u32,
    /// The session (`None`: not recorded).
    pub session: Option<Result<SessionInfo, String>>,
    /// Period records.
    pub records: usize,
    /// The first record's time, ns.
    pub first_ns: Option<u64>,
    /// The last record's time, ns.
    pub last_ns: Option<u64>,
    /// The last record's period number.
    pub last_cycle: Option<u64>,
    /// The calibrations, in file order.
    pub calibrations: Vec<CalibrationAt>,
    /// The surface versions in the log: recorded (`true`) or published but not recorded.
    pub surfaces: BTreeMap<u64, bool>,
    /// The time of the first period that rendered each version, ns.
    pub first_render_ns: BTreeMap<u64, u64>,
    /// The end frame.
    pub end: Option<SessionEnd>,
    /// The first damage.
    pub damage: Option<Damage>,
    /// Bytes not read from the damage on.
    pub truncated_bytes: u64,
    /// [`Log::end_note`].
    pub end_note: String,
    /// [`Log::damage_note`].
    pub damage_note: Option<String>,
}

impl LogOutline {
    /// The outline of the log file at `path`, read through once.
    pub fn read(path: &Path) -> Result<LogOutline, LogError> {
        Ok(LogOutline::of_reader(LogReader::open(path)?))
    }

    /// The outline of what `reader` reads (all of it).
    pub fn of_reader<R: Read>(mut reader: LogReader<R>) -> LogOutline {
        let mut outline = LogOutline::new(reader.header(), reader.version());
        for item in &mut reader {
            outline.add(&item);
        }
        outline.finish(&reader);
        outline
    }

    /// How the log ends, from `reader` once it has read everything: a caller that reads the
    /// items itself ([`LogOutline::add`]) ends with this.
    pub fn finish<R: Read>(&mut self, reader: &LogReader<R>) {
        self.damage = reader.damage().cloned();
        self.truncated_bytes = reader.truncated_bytes();
        self.end_note = reader.end_note();
        self.damage_note = reader.damage_note();
    }

    /// The outline of a log read whole.
    pub fn of_log(log: &Log) -> LogOutline {
        let mut outline = LogOutline::new(log.header, log.version);
        for item in log.items() {
            outline.add(&item);
        }
        outline.damage = log.damage.clone();
        outline.truncated_bytes = log.truncated_bytes as u64;
        outline.end_note = log.end_note();
        outline.damage_note = log.damage_note();
        outline
    }

    /// The outline of a log of `header` and `version` before any item.
    pub fn new(header: LogHeader, version: u32) -> LogOutline {
        LogOutline {
            header,
            version,
            session: None,
            records: 0,
            first_ns: None,
            last_ns: None,
            last_cycle: None,
            calibrations: Vec::new(),
            surfaces: BTreeMap::new(),
            first_render_ns: BTreeMap::new(),
            end: None,
            damage: None,
            truncated_bytes: 0,
            end_note: String::new(),
            damage_note: None,
        }
    }

    /// Take in the next item of the log.
    pub fn add(&mut self, item: &LogItem) {
        match item {
            LogItem::Period(r) => {
                let t = r.time.as_nanos();
                self.first_ns.get_or_insert(t);
                self.last_ns = Some(t);
                self.last_cycle = Some(r.cycle);
                for c in self.calibrations.iter_mut().rev() {
                    if c.time_ns.is_some() {
                        break;
                    }
                    c.time_ns = Some(t);
                }
                self.first_render_ns.entry(r.surface_version).or_insert(t);
                self.records += 1;
            }
            LogItem::Session(s) => self.session = Some((**s).clone()),
            LogItem::Calibration {
                from_cycle,
                calibration,
            } => self.calibrations.push(CalibrationAt {
                entry: CalibrationEntry {
                    before_record: self.records,
                    from_cycle: *from_cycle,
                    calibration: *calibration,
                },
                time_ns: None,
            }),
            LogItem::Surface(version, entry) => {
                self.surfaces
                    .insert(*version, matches!(entry, SurfaceEntry::Recorded(_)));
            }
            LogItem::End(end) => self.end = Some(end.clone()),
        }
    }

    /// Whether the session closed its log.
    pub fn closed(&self) -> bool {
        self.end.is_some()
    }

    /// Seconds the periods cover, first to last.
    pub fn duration_s(&self) -> f64 {
        match (self.first_ns, self.last_ns) {
            (Some(a), Some(b)) => b.saturating_sub(a) as f64 * 1e-9,
            _ => 0.0,
        }
    }

    /// The versions published but not recorded.
    pub fn lost_surfaces(&self) -> Vec<u64> {
        self.surfaces
            .iter()
            .filter(|(_, recorded)| !**recorded)
            .map(|(v, _)| *v)
            .collect()
    }

    /// When each recorded surface version is shown (an export's time for it), ns: the first
    /// period that renders it; the session start for version 0; for a version no period
    /// rendered, the first period rendering a later one (it was published before), else the
    /// last period.
    pub fn surface_times_ns(&self) -> BTreeMap<u64, u64> {
        let start = self.first_ns.unwrap_or(0);
        let end = self.last_ns.unwrap_or(start);
        let mut times = BTreeMap::new();
        // From the newest version down: the earliest render of this version or a later one.
        let mut renders = self.first_render_ns.iter().rev().peekable();
        let mut earliest_after: Option<u64> = None;
        for (&version, &recorded) in self.surfaces.iter().rev() {
            while let Some((_, &t)) = renders.next_if(|(v, _)| **v >= version) {
                earliest_after = Some(earliest_after.map_or(t, |e| e.min(t)));
            }
            if recorded {
                let at = if version == 0 {
                    start
                } else {
                    earliest_after.unwrap_or(end)
                };
                times.insert(version, at);
            }
        }
        times
    }
}
