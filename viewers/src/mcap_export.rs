//! A session log exported to MCAP (Foxglove, PlotJuggler): every period on the session's topics
//! ([`crate::topics`]), every recorded surface version, and the configuration and calibrations
//! as attachments and metadata. The file appears whole or not at all: it is written beside the
//! output as `OUT.partial` and renamed when complete.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{self, Seek, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use foxglove::{Context, McapCompression, McapWriteOptions};
use videt_config::Config;
use videt_runtime::telemetry::{
    Log, LogError, LogItem, LogOutline, LogReader, RecordedSurface, SurfaceEntry,
};

use crate::checked_writer::{take_error, CheckedWriter};
use crate::mcap_session::write_session_records;
use crate::topics::{SceneSetup, SessionTopics};

/// How to export.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ExportOptions {
    /// Export every `every`-th period (1: all of them). Safety changes and surface versions are
    /// exported whatever the decimation.
    pub every: u32,
}

impl Default for ExportOptions {
    fn default() -> Self {
        ExportOptions { every: 1 }
    }
}

/// What an export wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct ExportSummary {
    /// The MCAP file.
    pub path: PathBuf,
    /// Periods exported.
    pub periods: usize,
    /// Messages written, on every topic.
    pub messages: u64,
    /// Surface versions written on `/scene/relief`.
    pub surfaces: usize,
    /// Size of the file, bytes.
    pub bytes: u64,
    /// Seconds of session the periods cover (first to last record).
    pub session_s: f64,
    /// Wall-clock seconds the export took.
    pub elapsed_s: f64,
    /// What the export could not take from the log (no session frame, lost surfaces,
    /// damage), one line each.
    pub notes: Vec<String>,
}

/// Why an export failed (the output is then left as it was).
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// The options cannot be used.
    #[error("{0}")]
    Options(String),
    /// The log cannot be read.
    #[error("{path}: {what}")]
    Input {
        /// The log.
        path: PathBuf,
        /// Why.
        what: String,
    },
    /// The output path cannot be used.
    #[error("{path}: {what}")]
    Output {
        /// The path.
        path: PathBuf,
        /// What is wrong.
        what: String,
    },
    /// Writing failed.
    #[error("writing {path}: {source}")]
    Io {
        /// The file being written.
        path: PathBuf,
        /// The I/O error.
        source: io::Error,
    },
    /// The MCAP writer failed.
    #[error("writing {path}: {what}")]
    Mcap {
        /// The file being written.
        path: PathBuf,
        /// The writer's error.
        what: String,
    },
}

/// The partial file an export to `out` writes first: `out` with `.partial` appended.
pub fn partial_path(out: &Path) -> PathBuf {
    let mut name = out.as_os_str().to_owned();
    name.push(".partial");
    PathBuf::from(name)
}

/// Export `log` to the MCAP file `out`, atomically: written to [`partial_path`] and renamed over
/// `out` once complete; on any error the partial file is removed and an existing `out` is left
/// untouched. `progress(done, total)` is called as periods are written.
///
/// A log without a session frame (a version 1 log, or a session that could not be read) is
/// still exported, with the built-in configuration for the scene (the WireMan; its guides from
/// the recorded calibration when there is one) and a note in the summary.
pub fn export_mcap(
    log: &Log,
    out: &Path,
    options: &ExportOptions,
    progress: impl FnMut(usize, usize),
) -> Result<ExportSummary, ExportError> {
    export(
        &LogOutline::of_log(log),
        || Ok(log.items()),
        out,
        options,
        progress,
    )
}

/// [`export_mcap`] of the log file `log`, read twice as a stream (its outline, then its items):
/// the memory the export takes does not grow with the session's length.
pub fn export_mcap_file(
    log: &Path,
    out: &Path,
    options: &ExportOptions,
    progress: impl FnMut(usize, usize),
) -> Result<ExportSummary, ExportError> {
    let input = |e: LogError| ExportError::Input {
        path: log.to_path_buf(),
        what: e.to_string(),
    };
    let outline = LogOutline::read(log).map_err(input)?;
    export(
        &outline,
        || LogReader::open(log).map_err(input),
        out,
        options,
        progress,
    )
}

/// Export the log of `outline`, whose items `items` gives.
fn export<I: Iterator<Item = LogItem>>(
    outline: &LogOutline,
    items: impl FnOnce() -> Result<I, ExportError>,
    out: &Path,
    options: &ExportOptions,
    mut progress: impl FnMut(usize, usize),
) -> Result<ExportSummary, ExportError> {
    let started = Instant::now();
    if options.every == 0 {
        return Err(ExportError::Options(
            "--every must be at least 1 (1 exports every period)".into(),
        ));
    }
    if out.is_dir() {
        return Err(ExportError::Output {
            path: out.to_path_buf(),
            what: "is a directory (give the MCAP file's name)".into(),
        });
    }
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        if !dir.is_dir() {
            return Err(ExportError::Output {
                path: out.to_path_buf(),
                what: format!("no directory {}", dir.display()),
            });
        }
    }
    let items = items()?;
    let partial = partial_path(out);
    let file = File::create(&partial).map_err(|source| ExportError::Io {
        path: partial.clone(),
        source,
    })?;
    let written =
        write_mcap(outline, items, file, &partial, options, &mut progress).and_then(|(s, file)| {
            file.sync_all().map_err(|source| ExportError::Io {
                path: partial.clone(),
                source,
            })?;
            Ok(s)
        });
    match written {
        Ok(mut summary) => {
            if let Err(source) = std::fs::rename(&partial, out) {
                let _ = std::fs::remove_file(&partial);
                return Err(ExportError::Io {
                    path: out.to_path_buf(),
                    source,
                });
            }
            summary.path = out.to_path_buf();
            summary.bytes = std::fs::metadata(out).map(|m| m.len()).unwrap_or(0);
            summary.elapsed_s = started.elapsed().as_secs_f64();
            Ok(summary)
        }
        Err(e) => {
            let _ = std::fs::remove_file(&partial);
            Err(e)
        }
    }
}

/// Write the whole MCAP to `file`, named `path` in errors; returns `file` back, flushed.
fn write_mcap<W: Write + Seek + Send + 'static>(
    outline: &LogOutline,
    items: impl Iterator<Item = LogItem>,
    file: W,
    path: &Path,
    options: &ExportOptions,
    progress: &mut impl FnMut(usize, usize),
) -> Result<(ExportSummary, W), ExportError> {
    let mut notes = Vec::new();
    let config = match &outline.session {
        Some(Ok(session)) => session.config.clone(),
        Some(Err(e)) => {
            notes.push(format!(
                "the session frame could not be read ({e}): the scene uses the built-in configuration"
            ));
            Config::default()
        }
        None => {
            notes.push(format!(
                "no session recorded (format version {}): the scene uses the built-in configuration",
                outline.version
            ));
            Config::default()
        }
    };
    if let Some(note) = &outline.damage_note {
        notes.push(note.clone());
    }
    if !outline.closed() {
        notes.push(outline.end_note.clone());
    }
    let lost = outline.lost_surfaces();
    if !lost.is_empty() {
        notes.push(format!(
            "{} surface version{} published but not recorded: {}",
            lost.len(),
            if lost.len() == 1 { "" } else { "s" },
            list(&lost)
        ));
    }

    let writer = CheckedWriter::new(file);
    let write_error = writer.error.clone();
    // The file's own error, when there is one, says more than the MCAP writer's ("I/O error
    // from writing").
    let mcap_error = |e: foxglove::FoxgloveError| match take_error(&write_error) {
        Some(source) => ExportError::Io {
            path: path.to_path_buf(),
            source,
        },
        None => ExportError::Mcap {
            path: path.to_path_buf(),
            what: e.to_string(),
        },
    };
    let ctx = Context::new();
    let mcap = ctx
        .mcap_writer_with_options(
            McapWriteOptions::new()
                .compression(Some(McapCompression::Zstd))
                .profile(""),
        )
        .create(writer)
        .map_err(mcap_error)?;

    let first_calibration = outline.calibrations.first().map(|c| &c.entry.calibration);
    let setup = SceneSetup::new(&config, first_calibration);
    let start_ns = outline.first_ns.unwrap_or(0);
    // The recorded configuration (not the built-in one a log without a session is drawn with).
    let config_toml = match &outline.session {
        Some(Ok(_)) => Some(toml::to_string(&config).map_err(|e| ExportError::Mcap {
            path: path.to_path_buf(),
            what: format!("the configuration as TOML: {e}"),
        })?),
        _ => None,
    };
    write_session_records(outline, config_toml, &setup, start_ns, &mcap).map_err(mcap_error)?;

    let mut topics = SessionTopics::new(&ctx, setup);
    let surface_times = outline.surface_times_ns();
    // Surfaces read and not yet written, by the time they are shown: a surface comes in the
    // log before the periods that render it.
    let mut waiting: BTreeMap<(u64, u64), Arc<RecordedSurface>> = BTreeMap::new();
    let mut calibrations = 0usize;
    let (mut messages, mut periods, mut surfaces) = (0u64, 0usize, 0usize);
    let total = outline.records;
    let every = options.every as usize;
    let mut i = 0usize;
    for item in items {
        let record = match item {
            LogItem::Period(record) => record,
            LogItem::Calibration { calibration, .. } => {
                // Each later calibration (a re-initialization) moves the guides from its first
                // period on.
                if calibrations > 0 {
                    topics.set_guides(&SceneSetup::new(&config, Some(&calibration)));
                }
                calibrations += 1;
                continue;
            }
            LogItem::Surface(version, SurfaceEntry::Recorded(surface)) => {
                if let Some(at) = surface_times.get(&version) {
                    waiting.insert((*at, version), surface);
                }
                continue;
            }
            _ => continue,
        };
        let time = record.time.as_nanos();
        while let Some(entry) = waiting.first_entry().filter(|e| e.key().0 <= time) {
            let ((at, version), surface) = entry.remove_entry();
            topics.log_surface(version, &surface, at);
            messages += 1;
            surfaces += 1;
        }
        if i.is_multiple_of(every) {
            messages += topics.log_period(&record) as u64;
            periods += 1;
        } else {
            messages += u64::from(topics.log_safety_change(&record));
        }
        i += 1;
        if i.is_multiple_of(4096) {
            progress(i, total);
            if let Some(e) = take_error(&write_error) {
                return Err(ExportError::Io {
                    path: path.to_path_buf(),
                    source: e,
                });
            }
        }
    }
    for ((at, version), surface) in waiting {
        topics.log_surface(version, &surface, at);
        messages += 1;
        surfaces += 1;
    }
    progress(total, total);

    drop(topics);
    let writer = mcap.close().map_err(mcap_error)?;
    if let Some(e) = take_error(&write_error) {
        return Err(ExportError::Io {
            path: path.to_path_buf(),
            source: e,
        });
    }
    let file = writer.finish().map_err(|source| ExportError::Io {
        path: path.to_path_buf(),
        source,
    })?;

    let summary = ExportSummary {
        path: path.to_path_buf(),
        periods,
        messages,
        surfaces,
        bytes: 0,
        session_s: outline.duration_s(),
        elapsed_s: 0.0,
        notes,
    };
    Ok((summary, file))
}

/// A short list of numbers (the first ten).
fn list(v: &[u64]) -> String {
    let mut s: Vec<String> = v.iter().take(10).map(u64::to_string).collect();
    if v.len() > 10 {
        s.push("...".into());
    }
    s.join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;
    use std::io::SeekFrom;
    use videt_control::safety::{SafetyReason, SafetyState};
    use videt_control::surface::Plane;
    use videt_control::Vec3;
    use videt_relief::ReliefModel;
    use videt_runtime::cycle::CycleRecord;
    use videt_runtime::telemetry::{
        CalibrationEntry, CalibrationInForce, EndReason, LogHeader, RecordedSurface, SessionEnd,
        SessionInfo,
    };

    const PERIODS: usize = 3000;

    fn plane(z: f64) -> RecordedSurface {
        RecordedSurface::Plane(Plane::new(Vec3::new(0.0, 0.0, z), -Vec3::z()).unwrap())
    }

    fn relief() -> RecordedSurface {
        let vertices = vec![
            [0.0, 0.0, 0.40],
            [0.2, 0.0, 0.41],
            [0.2, 0.1, 0.38],
            [0.0, 0.1, 0.40],
            [0.1, 0.05, 0.36],
        ];
        let triangles = vec![[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]];
        RecordedSurface::Relief(ReliefModel::from_mesh_with_grid(
            vertices,
            triangles,
            [0.0, 0.0, 0.2, 0.1],
            0.45,
            1.7,
        ))
    }

    /// A session at 1 kHz: surface versions 0 (rendered from the start), 1 (rendered from
    /// period 1000), 2 (never rendered), 3 (a relief, from period 2000), 4 lost; a trip to
    /// minimum tension at period 1500 and back at 1600; one calibration; closed on a stop
    /// request.
    fn session_log() -> Log {
        let records = (0..PERIODS)
            .map(|i| {
                let mut r = CycleRecord {
                    cycle: i as u64,
                    time: videt_hal::MonoTime(5_000_000_000 + i as u64 * 1_000_000),
                    wake_latency_ns: 20_000 + i as u64,
                    compute_ns: 9_000,
                    position_m: [0.18, 0.1, 0.3 + 1e-5 * i as f64],
                    velocity_m_s: [0.0, 0.0, 0.01],
                    tension_measured_n: [1.0, 2.0, 3.0],
                    tension_setpoint_n: [1.1, 2.1, 3.1],
                    desired_force_n: [0.0, 0.0, -2.0],
                    rendered_force_n: [0.0, 0.1, -1.9],
                    force_scale: 1.0,
                    released_wire: -1,
                    ..CycleRecord::default()
                };
                r.surface_version = match i {
                    0..1000 => 0,
                    1000..2000 => 1,
                    _ => 3,
                };
                if (1500..1600).contains(&i) {
                    r.safety = SafetyState::MinimumTension(SafetyReason::OverTension { wire: 2 });
                }
                r
            })
            .collect();
        let mut log = Log::of_records(
            LogHeader {
                rate_hz: 1000,
                start_unix_ns: 1_700_000_000_000_000_000,
            },
            records,
        );
        log.session = Some(Ok(SessionInfo::new("test: a wall", Config::default())));
        log.calibrations.push(CalibrationEntry {
            before_record: 0,
            from_cycle: 0,
            calibration: CalibrationInForce {
                guides_m: [[0.0; 3], [0.37, 0.0, 0.0], [0.185, 0.3, 0.0]],
                length_at_zero_m: [0.3; 3],
                calibrated: true,
            },
        });
        for (v, s) in [
            (0, plane(0.3)),
            (1, plane(0.31)),
            (2, plane(0.32)),
            (3, relief()),
        ] {
            log.surfaces.insert(v, SurfaceEntry::Recorded(Arc::new(s)));
        }
        log.surfaces.insert(4, SurfaceEntry::Lost);
        log.end = Some(SessionEnd {
            reason: EndReason::StopRequest,
            last_cycle: Some(PERIODS as u64 - 1),
            periods: PERIODS as u64,
            dropped: 0,
        });
        log
    }

    /// Per topic: schema name and the log times, in file order.
    fn read_back(bytes: &[u8]) -> HashMap<String, (String, Vec<u64>)> {
        let mut topics: HashMap<String, (String, Vec<u64>)> = HashMap::new();
        for m in mcap::MessageStream::new(bytes).unwrap() {
            let m = m.unwrap();
            let schema = m.channel.schema.as_ref().map(|s| s.name.clone());
            topics
                .entry(m.channel.topic.clone())
                .or_insert_with(|| (schema.unwrap_or_default(), Vec::new()))
                .1
                .push(m.log_time);
        }
        topics
    }

    #[test]
    fn a_log_file_exported_as_a_stream_gives_the_same_messages_as_the_log_read_whole() {
        let dir = tempfile::tempdir().unwrap();
        let log = session_log();
        let file = dir.path().join("s.vlog");
        videt_runtime::telemetry::write_log(&file, &log.header, log.items()).unwrap();
        let (whole, streamed) = (
            dir.path().join("whole.mcap"),
            dir.path().join("stream.mcap"),
        );
        let a = export_mcap(&log, &whole, &ExportOptions::default(), |_, _| {}).unwrap();
        let b = export_mcap_file(&file, &streamed, &ExportOptions::default(), |_, _| {}).unwrap();
        assert_eq!(
            (a.periods, a.messages, a.surfaces, &a.notes),
            (b.periods, b.messages, b.surfaces, &b.notes)
        );
        assert_eq!(
            read_back(&std::fs::read(&whole).unwrap()),
            read_back(&std::fs::read(&streamed).unwrap())
        );
        // A file that is not a log: an input error, and no output.
        let e = export_mcap_file(&whole, &streamed, &ExportOptions::default(), |_, _| {});
        assert!(matches!(e, Err(ExportError::Input { .. })), "{e:?}");
    }

    #[test]
    fn every_period_surface_safety_change_and_the_session_records_are_exported() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("s.mcap");
        let log = session_log();
        let mut calls = Vec::new();
        let summary = export_mcap(&log, &out, &ExportOptions::default(), |d, t| {
            calls.push((d, t))
        })
        .unwrap();
        assert_eq!(calls.last(), Some(&(PERIODS, PERIODS)));
        assert!(!partial_path(&out).exists());
        let bytes = std::fs::read(&out).unwrap();
        assert_eq!(summary.bytes, bytes.len() as u64);
        assert_eq!((summary.periods, summary.surfaces), (PERIODS, 4));
        assert!(summary.notes.iter().any(|n| n.contains("not recorded: 4")));
        assert!(!summary.notes.iter().any(|n| n.contains("closing")));

        let topics = read_back(&bytes);
        let t0 = 5_000_000_000u64;
        for (topic, schema) in [
            ("/thimble/pose", "foxglove.PoseInFrame"),
            ("/scene/wires", "foxglove.SceneUpdate"),
            ("/scene/forces", "foxglove.SceneUpdate"),
            ("/tension", "tension.Tension"),
            ("/timing", "timing.Timing"),
        ] {
            let (s, times) = &topics[topic];
            assert_eq!(s, schema, "{topic}");
            assert_eq!(times.len(), PERIODS, "{topic}");
            assert!(times.windows(2).all(|w| w[0] <= w[1]), "{topic}");
            assert_eq!(times[0], t0);
        }
        // Version 0 at the start, 1 and 3 when first rendered, 2 (never rendered) before 3.
        let (s, relief) = &topics["/scene/relief"];
        assert_eq!(s, "foxglove.SceneUpdate");
        let ms = |i: u64| t0 + i * 1_000_000;
        assert_eq!(relief, &vec![t0, ms(1000), ms(2000), ms(2000)]);
        // The first period, the trip and the return.
        let (s, safety) = &topics["/safety"];
        assert_eq!(s, "safety.Safety");
        assert_eq!(safety, &vec![t0, ms(1500), ms(1600)]);
        let total: usize = topics.values().map(|(_, t)| t.len()).sum();
        assert_eq!(summary.messages, total as u64);

        // A well-known message decodes to what was logged.
        let pose = mcap::MessageStream::new(&bytes)
            .unwrap()
            .map(|m| m.unwrap())
            .find(|m| m.channel.topic == "/thimble/pose")
            .unwrap();
        let pose = <PoseInFrame as foxglove::Decode>::decode(&pose.data[..]).unwrap();
        assert_eq!(pose.frame_id, "rig");
        let p = pose.pose.unwrap().position.unwrap();
        assert_eq!([p.x, p.y, p.z], [0.18, 0.1, 0.3]);

        let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
        let names: Vec<&str> = summary
            .attachment_indexes
            .iter()
            .map(|a| a.name.as_str())
            .collect();
        assert_eq!(names, ["config.toml", "calibration-0.json"]);
        let config = mcap::read::attachment(&bytes, &summary.attachment_indexes[0]).unwrap();
        let text = std::str::from_utf8(&config.data).unwrap();
        assert_eq!(toml::from_str::<Config>(text).unwrap(), Config::default());
        let meta: Vec<&str> = summary
            .metadata_indexes
            .iter()
            .map(|m| m.name.as_str())
            .collect();
        assert_eq!(meta, ["videt.session", "videt.calibration.0"]);
        let session = mcap::read::metadata(&bytes, &summary.metadata_indexes[0]).unwrap();
        assert_eq!(session.metadata["what"], "test: a wall");
        assert_eq!(session.metadata["records"], PERIODS.to_string());
        assert_eq!(session.metadata["closed"], "true");
        assert_eq!(
            session.metadata["end"],
            "session closed at cycle 2999: stopped on request (control socket)"
        );
        // Chunks are zstd-compressed.
        assert!(summary
            .chunk_indexes
            .iter()
            .all(|c| c.compression == "zstd"));
    }

    use foxglove::messages::PoseInFrame;

    #[test]
    fn after_a_re_initialization_the_wires_start_at_the_new_guides() {
        let mut log = session_log();
        let moved = [[0.02, 0.01, 0.0], [0.4, 0.02, 0.0], [0.2, 0.35, 0.0]];
        log.calibrations.push(CalibrationEntry {
            before_record: 2000,
            from_cycle: 2000,
            calibration: CalibrationInForce {
                guides_m: moved,
                length_at_zero_m: [0.3; 3],
                calibrated: true,
            },
        });
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("s.mcap");
        export_mcap(&log, &out, &ExportOptions::default(), |_, _| {}).unwrap();
        let bytes = std::fs::read(&out).unwrap();
        let starts: Vec<(u64, [f64; 3])> = mcap::MessageStream::new(&bytes)
            .unwrap()
            .map(|m| m.unwrap())
            .filter(|m| m.channel.topic == "/scene/wires")
            .map(|m| {
                let update =
                    <foxglove::schemas::SceneUpdate as foxglove::Decode>::decode(&m.data[..])
                        .unwrap();
                let p = update.entities[0].lines[1].points[0];
                (m.log_time, [p.x, p.y, p.z])
            })
            .collect();
        let switch = log.records[2000].time.as_nanos();
        for (time, start) in &starts {
            let want = if *time < switch {
                [0.37, 0.0, 0.0]
            } else {
                moved[1]
            };
            assert_eq!(*start, want, "wire 1 at {time} ns");
        }
        assert!(starts.iter().any(|(t, _)| *t >= switch));
    }

    #[test]
    fn decimation_keeps_every_nth_period_and_every_safety_change() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("s.mcap");
        let summary =
            export_mcap(&session_log(), &out, &ExportOptions { every: 7 }, |_, _| {}).unwrap();
        let topics = read_back(&std::fs::read(&out).unwrap());
        let expected = PERIODS.div_ceil(7);
        assert_eq!(summary.periods, expected);
        assert_eq!(topics["/thimble/pose"].1.len(), expected);
        assert_eq!(topics["/timing"].1.len(), expected);
        assert_eq!(topics["/safety"].1.len(), 3);
        assert_eq!(topics["/scene/relief"].1.len(), 4);
        let e = export_mcap(&session_log(), &out, &ExportOptions { every: 0 }, |_, _| {});
        assert!(matches!(e, Err(ExportError::Options(_))));
    }

    #[test]
    fn a_log_without_session_or_records_still_exports_and_says_so() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("s.mcap");
        let mut log = session_log();
        log.session = None;
        log.calibrations.clear();
        log.end = None;
        let summary = export_mcap(&log, &out, &ExportOptions::default(), |_, _| {}).unwrap();
        assert!(summary.notes[0].starts_with("no session recorded"));
        assert!(summary
            .notes
            .iter()
            .any(|n| n.starts_with("session ended without closing, at cycle 2999")));
        let bytes = std::fs::read(&out).unwrap();
        let index = mcap::Summary::read(&bytes).unwrap().unwrap();
        assert!(index.attachment_indexes.is_empty());
        assert_eq!(read_back(&bytes)["/tension"].1.len(), PERIODS);

        let empty = Log::of_records(log.header, Vec::new());
        let summary = export_mcap(&empty, &out, &ExportOptions::default(), |_, _| {}).unwrap();
        assert_eq!((summary.periods, summary.messages), (0, 0));
        assert!(read_back(&std::fs::read(&out).unwrap()).is_empty());
    }

    #[test]
    fn a_failed_export_leaves_no_partial_file_and_the_existing_output_untouched() {
        let dir = tempfile::tempdir().unwrap();
        let log = session_log();
        // A directory that does not exist.
        let missing = dir.path().join("missing").join("s.mcap");
        let e = export_mcap(&log, &missing, &ExportOptions::default(), |_, _| {}).unwrap_err();
        assert!(e.to_string().contains("no directory"), "{e}");
        assert!(!dir.path().join("missing").exists());
        // The output is a directory.
        let e = export_mcap(&log, dir.path(), &ExportOptions::default(), |_, _| {}).unwrap_err();
        assert!(e.to_string().contains("is a directory"), "{e}");
        // The partial file cannot be created: an existing output stays as it was.
        let out = dir.path().join("s.mcap");
        std::fs::write(&out, b"previous export").unwrap();
        std::fs::create_dir(partial_path(&out)).unwrap();
        assert!(export_mcap(&log, &out, &ExportOptions::default(), |_, _| {}).is_err());
        assert_eq!(std::fs::read(&out).unwrap(), b"previous export");
        std::fs::remove_dir(partial_path(&out)).unwrap();
        // A successful export replaces it whole.
        export_mcap(&log, &out, &ExportOptions::default(), |_, _| {}).unwrap();
        assert!(std::fs::read(&out).unwrap().starts_with(b"\x89MCAP0\r\n"));
        assert!(!partial_path(&out).exists());
    }

    /// A file that fails once `room` bytes are written (a full disk).
    struct FullDisk {
        data: io::Cursor<Vec<u8>>,
        room: usize,
    }

    impl Write for FullDisk {
        fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
            if self.data.get_ref().len() + buf.len() > self.room {
                return Err(io::Error::new(io::ErrorKind::StorageFull, "no space left"));
            }
            self.data.write(buf)
        }
        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    impl Seek for FullDisk {
        fn seek(&mut self, pos: SeekFrom) -> io::Result<u64> {
            self.data.seek(pos)
        }
    }

    #[test]
    fn a_write_error_midway_is_reported_not_swallowed() {
        let disk = FullDisk {
            data: io::Cursor::new(Vec::new()),
            room: 4096,
        };
        let log = session_log();
        let e = write_mcap(
            &LogOutline::of_log(&log),
            log.items(),
            disk,
            Path::new("x.mcap.partial"),
            &ExportOptions::default(),
            &mut |_, _| {},
        )
        .err()
        .expect("a full disk is an error");
        assert!(e.to_string().contains("no space left"), "{e}");
    }
}
