//! Record and replay on the whole stack: twin sessions recorded by the telemetry writer (with
//! supervisor commands, device faults, and reliefs swapped by a vision thread) replay bit for
//! bit through the same control cycle; so do `videtd --sim` sessions of every scene (wall, box,
//! stereo, camera) and every device (wireman3, planar2, polar1) the service runs; a changed gain
//! is reported at the period where it first matters; a log cut anywhere (on a record boundary
//! or inside a record) reads as a session that ended without closing and replays up to the cut;
//! a log recorded before a configuration key existed names the key and the default it replays
//! with.

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use videt_config::Config;
use videt_hal::MonoTime;
use videt_runtime::control_loop::{
    run_control_loop, start_hardware, ControlCommand, CycleObserver, LoopControl, LoopEnd,
    LoopSettings, LoopStats, WindowStats,
};
use videt_runtime::cycle::{CycleOp, CycleRecord, WireZero};
use videt_runtime::setup;
use videt_runtime::snapshot::{FixedSurface, SurfaceFeed};
use videt_runtime::telemetry::{
    self, CalibrationInForce, EndReason, LogHeader, SessionInfo, SessionRecording,
};
use videt_service::relief_scene;
use videt_sim::TwinFault;
use videt_tools::felt::felt_report;
use videt_tools::replay::{replay, ReplayOverrides};

/// Sends supervisor commands at given periods (as the control socket would), and stalls the
/// control thread at others.
struct Commander {
    queue: rtrb::Producer<ControlCommand>,
    plan: Vec<(u64, ControlCommand)>,
    stalls: Vec<(u64, Duration)>,
}

impl CycleObserver for Commander {
    fn observe(&mut self, record: &CycleRecord, _window: &WindowStats) {
        for (at, command) in &self.plan {
            if *at == record.cycle {
                let _ = self.queue.push(*command);
            }
        }
        for (at, stall) in &self.stalls {
            if *at == record.cycle {
                std::thread::sleep(*stall);
            }
        }
    }
}

/// Run `seconds` of the twin's wall demonstration (or the relief box with a vision thread
/// publishing rebuilt reliefs) with `commands` and `faults`, recorded into `path`.
fn record_session(
    path: &Path,
    config: &Config,
    seconds: f64,
    relief: bool,
    commands: Vec<(u64, ControlCommand)>,
    faults: &[(f64, TwinFault)],
) {
    record_stalled_session(path, config, seconds, relief, commands, faults, Vec::new());
}

/// [`record_session`] with the control thread stalled for the given time (real time: the
/// twin's clock does not move meanwhile) at the given periods.
fn record_stalled_session(
    path: &Path,
    config: &Config,
    seconds: f64,
    relief: bool,
    commands: Vec<(u64, ControlCommand)>,
    faults: &[(f64, TwinFault)],
    stalls: Vec<(u64, Duration)>,
) {
    let mut scene = videt_assembly::twin_scene::wireman_wall_scene(config, 3);
    for &(t, fault) in faults {
        assert!(scene.twin.schedule_fault(MonoTime((t * 1e9) as u64), fault));
    }
    let rig = setup::rig(config).unwrap();
    let cycle = setup::control_cycle(config, rig, WireZero::default(), true);
    let settings = LoopSettings {
        rate_hz: config.control.rate_hz,
        duration_ns: Some((seconds * 1e9) as u64),
        max_consecutive_overruns: 10,
    };
    let (queue, mut consumer) = rtrb::RingBuffer::new(16);
    let commander = Commander {
        queue,
        plan: commands,
        stalls,
    };
    let header = LogHeader {
        rate_hz: config.control.rate_hz,
        start_unix_ns: 0,
    };
    let stop = AtomicBool::new(false);
    let mut control = LoopControl {
        stop: &stop,
        commands: Some(&mut consumer),
    };
    let mut twin = scene.twin;
    start_hardware(&mut twin).unwrap();
    let mut session = Session {
        path,
        header,
        info: SessionInfo::new("replay test", config.clone()),
        twin,
        cycle,
        settings,
    };
    if relief {
        let layout = videt_runtime::setup::relief_layout(config);
        let (model, _) = relief_scene::box_relief(&layout, 0.0).unwrap();
        let (mut writer, mut feed) =
            videt_service::relief_feed::relief_channel_for(config, model).unwrap();
        let start = session.twin.plant().position_m();
        session
            .twin
            .set_operator(relief_scene::box_operator(&layout, start, 6.0));
        // Vision: rebuilds the box while the loop runs, its height changing every eighth
        // rebuild (an unchanged relief is recorded as a repeat).
        let done = Arc::new(AtomicBool::new(false));
        let vision_done = Arc::clone(&done);
        let vision = std::thread::spawn(move || {
            let mut k = 0;
            while !vision_done.load(Ordering::Relaxed) {
                k += 1;
                let height = 0.002 * f64::from(k / 8 % 3);
                let (m, _) = relief_scene::box_relief(&layout, height).unwrap();
                writer.publish(m);
                std::thread::sleep(Duration::from_millis(3));
            }
        });
        session.run(&mut feed, &mut control, commander);
        done.store(true, Ordering::Relaxed);
        vision.join().unwrap();
    } else {
        let wall = scene.wall;
        session.run(&mut FixedSurface(wall), &mut control, commander);
    }
}

/// A recorded twin session about to run.
struct Session<'a> {
    path: &'a Path,
    header: LogHeader,
    info: SessionInfo,
    twin: videt_assembly::WiremanTwin,
    cycle: videt_runtime::WiremanCycle,
    settings: LoopSettings,
}

impl Session<'_> {
    /// Record the session, the calibration and `feed`'s surfaces, run the loop, close the log.
    fn run<F: SurfaceFeed>(
        mut self,
        feed: &mut F,
        control: &mut LoopControl<'_>,
        commander: Commander,
    ) {
        let recording = SessionRecording {
            session: Some(self.info),
            surfaces: feed.recording(),
            retention: None,
        };
        let (mut producer, writer) =
            telemetry::start_session(self.path, self.header, recording, 1 << 16).unwrap();
        producer.calibration(0, &CalibrationInForce::of(&self.cycle));
        let mut observers = (producer, commander);
        let report = run_control_loop(
            &mut self.twin,
            feed,
            &mut self.cycle,
            &self.settings,
            control,
            &mut observers,
            &mut LoopStats::default(),
        );
        drop(observers);
        assert_eq!(report.ended_by, LoopEnd::DurationElapsed);
        writer.finish(EndReason::DurationElapsed).unwrap();
    }
}

fn assert_identical(log: &telemetry::Log) -> videt_tools::replay::Replay {
    let r = replay(log, &ReplayOverrides::default()).unwrap();
    assert!(r.identical(), "{:?}", r.first_divergence);
    assert_eq!(r.stopped_early, None);
    assert_eq!(r.replayed.len(), log.records.len());
    r
}

#[test]
fn a_twin_session_with_commands_and_faults_replays_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.vlog");
    let config = Config::default();
    record_session(
        &path,
        &config,
        4.0,
        false,
        vec![
            (1200, ControlCommand::ReleaseWire(1)),
            (1500, ControlCommand::Resume),
            (2600, ControlCommand::ResetFaults),
        ],
        &[(2.5, TwinFault::FailTensionSensor(2))],
    );
    let log = telemetry::read_log(&path).unwrap();
    assert!(log.damage.is_none());
    assert!(log.records.len() > 3900, "{}", log.records.len());
    // The session went through what it was meant to: a released wire, a sensor fault, the
    // stop ramp.
    assert!(log.records.iter().any(|r| r.released_wire == 1));
    assert!(log.records.iter().any(|r| !r.inputs.tensions_read_ok));
    let ops: Vec<CycleOp> = log
        .records
        .iter()
        .flat_map(|r| r.inputs.ops.as_slice().to_vec())
        .collect();
    for op in [
        CycleOp::ReleaseWire(Some(1)),
        CycleOp::ReleaseWire(None),
        CycleOp::ResetFaults,
        CycleOp::RequestStop,
    ] {
        assert!(ops.contains(&op), "{op:?} not recorded: {ops:?}");
    }
    assert_identical(&log);
}

#[test]
fn a_relief_session_with_swaps_from_a_vision_thread_replays_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("r.vlog");
    record_session(&path, &Config::default(), 3.0, true, Vec::new(), &[]);
    let log = telemetry::read_log(&path).unwrap();
    let rendered: std::collections::BTreeSet<u64> =
        log.records.iter().map(|r| r.surface_version).collect();
    assert!(
        rendered.len() >= 3,
        "surface versions rendered: {rendered:?}"
    );
    assert!(log.records.iter().filter(|r| r.in_contact).count() > 300);
    let whole = assert_identical(&log);
    // Read as a stream, holding only the surfaces not yet rendered: the same periods.
    struct Kept(Vec<(usize, CycleRecord)>);
    impl videt_tools::replay::ReplayObserver for Kept {
        fn period(&mut self, i: usize, _recorded: &CycleRecord, replayed: &CycleRecord) {
            self.0.push((i, *replayed));
        }
    }
    let mut reader = telemetry::LogReader::open(&path).unwrap();
    let mut kept = Kept(Vec::new());
    let streamed = videt_tools::replay::replay_items(
        reader.version(),
        &mut reader,
        &ReplayOverrides::default(),
        &mut kept,
    )
    .unwrap();
    assert!(streamed.identical() && streamed.stopped_early.is_none());
    assert_eq!(
        (streamed.records, streamed.replayed),
        (log.records.len(), log.records.len())
    );
    assert!(
        kept.0 == whole.replayed,
        "the streamed replay differs from the whole one"
    );
}

#[test]
fn a_changed_gain_is_reported_at_the_first_period_it_matters() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("g.vlog");
    let config = Config::default();
    record_session(&path, &config, 2.5, false, Vec::new(), &[]);
    let log = telemetry::read_log(&path).unwrap();
    // The stiffness only matters in contact, while forces are rendered.
    let expected = log
        .records
        .iter()
        .position(|r| r.in_contact && r.contact_depth_m > 0.0 && r.force_scale > 0.0)
        .expect("the operator touches the wall");
    let mut stiffer = config.clone();
    stiffer.control.stiffness_n_per_m *= 1.5;
    let r = replay(
        &log,
        &ReplayOverrides {
            config: Some(stiffer),
            algorithm: None,
        },
    )
    .unwrap();
    let d = r
        .first_divergence
        .expect("a stiffer wall renders other forces");
    assert_eq!(d.record, expected, "{d}");
    assert_eq!(d.cycle, log.records[expected].cycle);
    // The stiffer wall asks another force, and from the first touch on the set-points follow
    // it (the free-space pull hands over to the contact force): the set-points are compared
    // first.
    assert!(
        d.field.starts_with("tension_setpoint_n") || d.field.starts_with("desired_force_n"),
        "{d}"
    );
    // The replay went on to the end, every period compared.
    assert_eq!(r.replayed.len(), log.records.len());
    assert!(r.divergent_periods > 100);
    // Another algorithm changes the set-points, not the desired force.
    let r = replay(
        &log,
        &ReplayOverrides {
            config: None,
            algorithm: Some("qp".into()),
        },
    )
    .unwrap();
    let d = r
        .first_divergence
        .expect("QP distributes differently from P2");
    assert!(
        d.field.starts_with("tension_setpoint_n") || d.field.starts_with("rendered_force_n"),
        "{d}"
    );
    assert_eq!(r.config.control.algorithm, "QP");
    let e = replay(
        &log,
        &ReplayOverrides {
            config: None,
            algorithm: Some("P9".into()),
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("P9") && e.contains("P1"), "{e}");
}

/// Where to cut a closed log, chosen from its frames: every frame boundary (the log of a service
/// that stopped writing between two frames: power lost, the process killed), bytes inside the
/// header, inside the first frame of every kind, inside periods spread over the session (their
/// head, payload and CRC), and every byte of the end frame. Each with whether it is a boundary.
fn cuts_from_frames(frames: &[telemetry::FrameAt]) -> Vec<(usize, bool)> {
    let mut cuts: Vec<(usize, bool)> = [0, 1, 8, 12, 20, telemetry::HEADER_BYTES - 1]
        .into_iter()
        .map(|at| (at, false))
        .collect();
    cuts.extend(frames.iter().map(|f| (f.offset, true)));
    let inside =
        |f: &telemetry::FrameAt| [f.offset + 1, f.offset + f.bytes / 2, f.offset + f.bytes - 1];
    let mut kinds = Vec::new();
    for f in frames {
        if !kinds.contains(&f.kind) {
            kinds.push(f.kind);
            cuts.extend(inside(f).map(|at| (at, false)));
        }
    }
    let periods: Vec<&telemetry::FrameAt> = frames
        .iter()
        .filter(|f| f.kind == telemetry::format::FrameKind::Period)
        .collect();
    for k in 0..8 {
        cuts.extend(inside(periods[k * (periods.len() - 1) / 7]).map(|at| (at, false)));
    }
    let end = frames.last().expect("frames");
    cuts.extend((end.offset + 1..end.offset + end.bytes).map(|at| (at, false)));
    cuts.sort_unstable();
    cuts.dedup();
    cuts
}

/// The same log as version 3 wrote it (uncompressed frames, in the file's order).
fn as_version_3(v4: &[u8]) -> Vec<u8> {
    let reader = telemetry::LogReader::new(v4).unwrap();
    let header = reader.header();
    telemetry::version_3_bytes(&header, reader).unwrap()
}

/// `bytes`, a closed log (version 4) of a session whose duration elapsed, cut on every block
/// boundary and inside every block: each cut reads as a session that ended without closing at
/// the last record of the blocks before it, damaged exactly when the cut is inside a block,
/// and replays up to there; then the same log as version 3 wrote it, cut on every record
/// boundary and inside records ([`check_frame_cuts`]).
fn check_cuts(bytes: &[u8]) {
    let whole = telemetry::parse_log(bytes).unwrap();
    let blocks = telemetry::frames(bytes).unwrap();
    assert!(blocks
        .iter()
        .all(|b| b.kind == telemetry::format::FrameKind::Block));
    let last = blocks.last().unwrap();
    assert_eq!(last.offset + last.bytes, bytes.len());
    let mut cuts: Vec<(usize, bool)> = blocks.iter().map(|b| (b.offset, true)).collect();
    cuts.extend(
        blocks
            .iter()
            .flat_map(|b| [b.offset + 1, b.offset + b.bytes / 2, b.offset + b.bytes - 1])
            .map(|at| (at, false)),
    );
    for (cut, on_boundary) in cuts {
        let log = telemetry::parse_log(&bytes[..cut]).unwrap();
        assert!(!log.closed(), "cut at {cut}");
        assert_eq!(log.damage.is_none(), on_boundary, "cut at {cut}");
        assert_eq!(log.records[..], whole.records[..log.records.len()]);
        let before = telemetry::parse_log(
            &bytes[..blocks
                .iter()
                .rev()
                .find(|b| b.offset <= cut)
                .unwrap()
                .offset],
        )
        .unwrap();
        assert_eq!(log.records.len(), before.records.len(), "cut at {cut}");
        if let Ok(r) = replay(&log, &ReplayOverrides::default()) {
            assert!(r.identical(), "cut at {cut}: {:?}", r.first_divergence);
        } else {
            assert!(log.records.is_empty(), "cut at {cut}");
        }
    }
    check_frame_cuts(&as_version_3(bytes));
}

/// `bytes`, a closed log (version 3) of a session whose duration elapsed, cut on every record
/// boundary and inside records ([`cuts_from_frames`]): each cut reads as a session that ended
/// without closing at its last whole record, with damage exactly when the cut is inside a
/// frame, and its records a prefix of the whole log's; a cut log replays up to the cut at the
/// period boundaries before and after every frame kind, at spread periods and inside records.
fn check_frame_cuts(bytes: &[u8]) {
    // Hundreds of parses and replays: not while a videtd session records in real time.
    let _cpu = real_time();
    let started = Instant::now();
    let whole = telemetry::parse_log(bytes).unwrap();
    assert!(whole.damage.is_none(), "{:?}", whole.damage_note());
    let end = whole.end.clone().expect("the log is closed");
    assert_eq!(end.reason, EndReason::DurationElapsed);
    assert_eq!(end.last_cycle, Some(whole.records.last().unwrap().cycle));
    assert_eq!(end.periods, whole.records.len() as u64);
    let frames = telemetry::frames(bytes).unwrap();
    let last = frames.last().unwrap();
    assert_eq!(last.kind, telemetry::format::FrameKind::End);
    assert_eq!(last.offset + last.bytes, bytes.len());
    let cuts = cuts_from_frames(&frames);
    // Replayed: the boundaries around the first frames and the end frame, 8 spread period
    // boundaries, and every cut inside a frame other than the end frame.
    let spread: Vec<usize> = (0..8)
        .map(|k| frames[4 + k * (frames.len() - 5) / 7].offset)
        .collect();
    let replayed = |cut: usize, on_boundary: bool| {
        let near_start = frames.iter().take(6).any(|f| f.offset == cut);
        if on_boundary {
            near_start || cut == last.offset || spread.contains(&cut)
        } else {
            cut < last.offset
        }
    };
    let (mut parsed, mut replays) = (0, 0);
    for &(cut, on_boundary) in &cuts {
        if cut < telemetry::HEADER_BYTES {
            let e = telemetry::parse_log(&bytes[..cut]).unwrap_err().to_string();
            assert!(e.contains("an empty session log"), "cut at {cut}: {e}");
            continue;
        }
        let log = telemetry::parse_log(&bytes[..cut]).unwrap();
        parsed += 1;
        assert!(!log.closed(), "cut at {cut}");
        assert_eq!(log.damage.is_none(), on_boundary, "cut at {cut}");
        assert_eq!(log.records[..], whole.records[..log.records.len()]);
        let note = log.end_note();
        let at = log
            .records
            .last()
            .map_or("before its first period".to_string(), |r| {
                format!("at cycle {}", r.cycle)
            });
        assert!(
            note.starts_with(&format!(
                "session ended without closing, {at} (no end frame"
            )),
            "cut at {cut}: {note}"
        );
        if !replayed(cut, on_boundary) {
            continue;
        }
        replays += 1;
        match replay(&log, &ReplayOverrides::default()) {
            Ok(r) => {
                assert!(r.identical(), "cut at {cut}: {:?}", r.first_divergence);
                // Up to the cut: every record, unless a surface published just before the cut
                // did not make it into the file.
                match &r.stopped_early {
                    None => assert_eq!(r.replayed.len(), log.records.len(), "cut at {cut}"),
                    Some(why) => assert!(why.contains("not in the log"), "cut at {cut}: {why}"),
                }
            }
            // Cut before the session, the calibration or the first surface was written.
            Err(e) => assert!(log.records.is_empty(), "cut at {cut}: {e}"),
        }
    }
    // The log without its end frame: every record, not closed.
    let unclosed = telemetry::parse_log(&bytes[..last.offset]).unwrap();
    assert_eq!(unclosed.records.len(), whole.records.len());
    eprintln!(
        "{} frames, {} bytes: {parsed} cuts read, {replays} replayed, in {:.1} s",
        frames.len(),
        bytes.len(),
        started.elapsed().as_secs_f64()
    );
}

#[test]
fn a_log_cut_on_a_record_boundary_or_inside_one_reads_as_not_closed_and_replays_up_to_the_cut() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("c.vlog");
    record_session(&path, &Config::default(), 0.6, true, Vec::new(), &[]);
    check_cuts(&std::fs::read(&path).unwrap());
}

#[test]
fn a_log_recorded_with_stalls_cut_on_a_record_boundary_or_inside_one_reads_as_not_closed() {
    // The control thread stalls while the vision thread keeps publishing and the writer drains
    // an empty ring: the frames fall elsewhere from run to run.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.vlog");
    let stalls = [100, 250, 251, 400, 550]
        .into_iter()
        .zip([25, 7, 40, 13, 31].map(Duration::from_millis))
        .collect();
    record_stalled_session(
        &path,
        &Config::default(),
        0.6,
        true,
        Vec::new(),
        &[],
        stalls,
    );
    check_cuts(&std::fs::read(&path).unwrap());
}

fn videt(args: &[&std::ffi::OsStr]) -> (std::process::ExitStatus, String, String) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_videt"))
        .args(args)
        .output()
        .unwrap();
    (
        out.status,
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn the_replay_tool_reports_plots_and_refuses_bad_logs_clearly() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t.vlog");
    record_session(&path, &Config::default(), 2.0, false, Vec::new(), &[]);
    let (status, out, _) = videt(&["replay".as_ref(), path.as_os_str()]);
    assert!(status.success(), "{out}");
    assert!(out.contains("identical"), "{out}");

    // Another algorithm: the outputs side by side beside the log, and the figures.
    let plots = dir.path().join("plots");
    let (status, out, err) = videt(&[
        "replay".as_ref(),
        path.as_os_str(),
        "--algorithm".as_ref(),
        "P1".as_ref(),
        "--plot".as_ref(),
        plots.as_os_str(),
    ]);
    assert!(status.success(), "{out}{err}");
    assert!(out.contains("first divergence: period"), "{out}");
    let csv = std::fs::read_to_string(dir.path().join("t.vlog.replay.csv")).unwrap();
    assert!(
        csv.starts_with("cycle,time_s,recorded_tension_setpoint_n_0,replayed_tension_setpoint_n_0")
    );
    assert!(csv.lines().count() > 2000);
    // Every replayed period, and nothing left of the file it was written through.
    let replayed = out
        .lines()
        .find_map(|l| {
            l.split("replayed ")
                .nth(1)?
                .split(' ')
                .next()?
                .parse::<usize>()
                .ok()
        })
        .unwrap();
    assert_eq!(csv.lines().count(), replayed + 1, "{out}");
    let names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(names.iter().all(|n| !n.contains(".tmp")), "{names:?}");
    for name in [
        "path.png",
        "tensions.png",
        "forces.png",
        "timing.png",
        "replay.png",
    ] {
        let img = image::open(plots.join(name)).unwrap().to_rgb8();
        let background = *img.get_pixel(0, 0);
        let drawn = img.pixels().filter(|p| **p != background).count();
        assert!(
            drawn > img.pixels().len() / 50,
            "{name}: {drawn} drawn pixels"
        );
    }

    // Killed mid-write: what was written replays, and the damage is named.
    let bytes = std::fs::read(&path).unwrap();
    let cut = dir.path().join("cut.vlog");
    std::fs::write(&cut, &bytes[..bytes.len() * 2 / 3 + 5]).unwrap();
    let (status, out, _) = videt(&["replay".as_ref(), cut.as_os_str()]);
    assert!(status.success(), "{out}");
    assert!(
        out.contains("the rest is damaged") && out.contains("identical"),
        "{out}"
    );
    // A corrupt record in the middle: the same.
    let mut corrupt = bytes.clone();
    let middle = corrupt.len() / 2;
    corrupt[middle] ^= 0x10;
    std::fs::write(&cut, &corrupt).unwrap();
    let (status, out, _) = videt(&["replay".as_ref(), cut.as_os_str()]);
    assert!(status.success() && out.contains("CRC"), "{out}");
    // Another version, and not a log: a clear error, exit 1.
    let mut other = bytes.clone();
    other[8] = 7;
    std::fs::write(&cut, &other).unwrap();
    let (status, _, err) = videt(&["replay".as_ref(), cut.as_os_str()]);
    assert_eq!(status.code(), Some(1));
    assert!(
        err.contains("version 7") && err.contains("reads versions 1 to 4"),
        "{err}"
    );
    std::fs::write(&cut, "[control]\nrate_hz = 1000\n").unwrap();
    let (status, _, err) = videt(&["replay".as_ref(), cut.as_os_str()]);
    assert_eq!(status.code(), Some(1));
    assert!(err.contains("not a VIDET session log"), "{err}");
    // A version 1 log reads but cannot be replayed.
    let mut v1 = Vec::new();
    v1.extend_from_slice(&bytes[..8]);
    v1.extend_from_slice(&1u32.to_le_bytes());
    v1.extend_from_slice(&256u32.to_le_bytes());
    v1.extend_from_slice(&bytes[16..32]);
    v1.extend_from_slice(&[0u8; 512]);
    std::fs::write(&cut, &v1).unwrap();
    let (status, _, err) = videt(&["replay".as_ref(), cut.as_os_str()]);
    assert_eq!(status.code(), Some(1));
    assert!(err.contains("version 1 log records no inputs"), "{err}");
    let (status, out, _) = videt(&["log".as_ref(), cut.as_os_str()]);
    assert!(status.success() && out.contains("2 records"), "{out}");
}

#[test]
fn videt_log_says_whether_the_session_closed_and_that_a_log_cut_on_a_record_boundary_did_not() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("w.vlog");
    record_session(&path, &Config::default(), 1.0, false, Vec::new(), &[]);
    let bytes = std::fs::read(&path).unwrap();
    let last = telemetry::parse_log(&bytes)
        .unwrap()
        .records
        .last()
        .unwrap()
        .cycle;
    let (status, out, _) = videt(&["log".as_ref(), path.as_os_str()]);
    assert!(status.success(), "{out}");
    assert!(
        out.contains(&format!(
            "session closed at cycle {last}: its set duration elapsed"
        )),
        "{out}"
    );
    // Cut on block boundaries (the service gone between two writes): before the last block
    // (the end frame's); and the same log as version 3 wrote it, cut on record boundaries
    // before the end frame and in the middle of the session.
    let blocks = telemetry::frames(&bytes).unwrap();
    let v3 = as_version_3(&bytes);
    let frames = telemetry::frames(&v3).unwrap();
    let periods: Vec<&telemetry::FrameAt> = frames
        .iter()
        .filter(|f| f.kind == telemetry::format::FrameKind::Period)
        .collect();
    let cut = dir.path().join("cut.vlog");
    for (bytes, at) in [
        (&bytes, blocks.last().unwrap().offset),
        (&v3, frames.last().unwrap().offset),
        (&v3, periods[periods.len() / 2].offset),
    ] {
        std::fs::write(&cut, &bytes[..at]).unwrap();
        let read = telemetry::parse_log(&bytes[..at]).unwrap();
        let ended = format!(
            "session ended without closing, at cycle {}",
            read.records.last().unwrap().cycle
        );
        let (status, out, _) = videt(&["log".as_ref(), cut.as_os_str()]);
        assert!(status.success(), "{out}");
        assert!(out.contains(&ended), "cut at {at}: {out}");
        assert!(
            !out.contains("session closed") && !out.contains("damaged"),
            "cut at {at}: {out}"
        );
        let (status, json, _) = videt(&["log".as_ref(), cut.as_os_str(), "--json".as_ref()]);
        assert!(status.success(), "{json}");
        let summary: serde_json::Value = serde_json::from_str(&json).unwrap();
        assert_eq!(summary["closed"], false, "{json}");
        assert!(
            summary["end"].as_str().unwrap().starts_with(&ended),
            "{json}"
        );
        // The replay says so too, beside an identical replay of what was read.
        let (status, out, _) = videt(&["replay".as_ref(), cut.as_os_str()]);
        assert!(status.success(), "{out}");
        assert!(
            out.contains(&ended) && out.contains("identical"),
            "cut at {at}: {out}"
        );
    }
    // Logs of the versions before the end frame (the fuzzer's seeds: `videtd --sim` sessions
    // cut after six periods, whole or inside a frame, and a version 1 log) read as not closed.
    let seeds = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/seeds/session_log");
    for (name, version, damaged) in [
        ("wall_6_periods.vlog", 2, false),
        ("box_6_periods.vlog", 2, false),
        ("wall_cut.vlog", 2, true),
        ("box_cut.vlog", 2, true),
        ("version1_4_records.vlog", 1, false),
    ] {
        let old = seeds.join(name);
        let log = telemetry::read_log(&old).unwrap();
        assert_eq!(
            (log.version, log.damage.is_some(), log.closed()),
            (version, damaged, false),
            "{name}"
        );
        let (status, out, _) = videt(&["log".as_ref(), old.as_os_str()]);
        assert!(status.success(), "{name}: {out}");
        assert!(
            out.contains(&format!(
                "session ended without closing, at cycle {} (a version {version} log: that format records no end)",
                log.records.last().unwrap().cycle
            )),
            "{name}: {out}"
        );
    }
    let closed = seeds.join("wall_6_periods_closed.vlog");
    let (status, out, _) = videt(&["log".as_ref(), closed.as_os_str()]);
    assert!(status.success(), "{out}");
    assert!(
        out.contains("session closed at cycle 5: stopped on request (control socket)"),
        "{out}"
    );
}

/// Held while a `videtd` session records, and while the other tests parse and replay logs by
/// the hundred (the cut checks, the felt force with every algorithm): a session's reliefs come
/// from its vision thread in real time, and on two cores those would starve it.
static REAL_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn real_time() -> std::sync::MutexGuard<'static, ()> {
    REAL_TIME
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// What `videtd --sim SIM` (`hal` or `can`) ran and recorded for 2 s: the session log, or the
/// service's refusal (its standard error) when it does not run the combination.
fn videtd_session(
    dir: &Path,
    name: &str,
    sim: &str,
    device: &str,
    scene: &str,
    extra: &[&std::ffi::OsStr],
) -> Result<std::path::PathBuf, String> {
    let mut config = Config::default();
    config.rig.device = device.into();
    let config_path = dir.join(format!("{name}.toml"));
    std::fs::write(&config_path, toml::to_string(&config).unwrap()).unwrap();
    let logs = dir.join(name);
    let session = real_time();
    let out = std::process::Command::new(videt_testkit::videtd_bin())
        .args(["--sim", sim, "--config"])
        .arg(&config_path)
        .args(["--scene", scene, "--duration", "2", "--no-socket"])
        .arg("--telemetry-dir")
        .arg(&logs)
        .args(extra)
        .env("RUST_LOG", "warn")
        .output()
        .unwrap();
    drop(session);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    if !out.status.success() {
        return Err(format!("exit {:?}: {stderr}", out.status.code()));
    }
    let mut files: Vec<_> = std::fs::read_dir(&logs)
        .unwrap_or_else(|e| panic!("{}: {e} ({stderr})", logs.display()))
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(files.len(), 1, "{files:?}");
    Ok(files.pop().unwrap())
}

/// Replays `log` with its recorded settings: identical outputs and inputs in every period the
/// control cycle ran, none left out.
fn assert_replays_every_cycle_period(what: &str, log: &telemetry::Log) {
    assert!(log.damage.is_none(), "{what}: {:?}", log.damage_note());
    let cycle_periods = log.records.iter().filter(|r| r.inputs.from_cycle).count();
    assert!(cycle_periods > 1500, "{what}: {cycle_periods} periods");
    let r = replay(log, &ReplayOverrides::default()).unwrap();
    assert!(
        r.identical(),
        "{what}: {} of {} periods differ, the first: {}",
        r.divergent_periods,
        r.replayed.len(),
        r.first_divergence.as_ref().unwrap()
    );
    assert_eq!(r.stopped_early, None, "{what}");
    assert_eq!(r.replayed.len(), cycle_periods, "{what}");
    assert_eq!(
        r.procedure_periods,
        log.records.len() - cycle_periods,
        "{what}"
    );
    eprintln!("{what}: {} periods replayed bit for bit", r.replayed.len());
    assert_felt_bound_with_every_algorithm(what, log);
}

/// What the finger felt stays within the felt bound (`docs/felt-force.md`) as recorded, and
/// in the replay of the same motion with every algorithm.
fn assert_felt_bound_with_every_algorithm(what: &str, log: &telemetry::Log) {
    let config = log
        .session
        .as_ref()
        .unwrap()
        .as_ref()
        .unwrap()
        .config
        .clone();
    let recorded = felt_report(log, &config, log.records.iter().enumerate()).unwrap();
    assert!(recorded.periods > 1500, "{what}: {recorded}");
    assert_eq!(recorded.over_bound, 0, "{what} as recorded: {recorded}");
    let _replays = real_time();
    for algorithm in videt_control::distribution::ALGORITHM_NAMES {
        let r = replay(
            log,
            &ReplayOverrides {
                config: None,
                algorithm: Some(algorithm.into()),
            },
        )
        .unwrap();
        let felt = felt_report(log, &r.config, r.replayed.iter().map(|(i, o)| (*i, o))).unwrap();
        assert_eq!(
            felt.over_bound, 0,
            "{what} replayed with {algorithm}: {felt}"
        );
        eprintln!("{what}, {algorithm}: {felt}");
    }
}

/// The reliefs the session rendered and how many came with a camera frame's age.
fn surfaces_of(log: &telemetry::Log) -> (usize, usize) {
    let versions: std::collections::BTreeSet<u64> =
        log.records.iter().map(|r| r.surface_version).collect();
    let aged = log
        .records
        .iter()
        .filter(|r| r.inputs.surface_frame_age_ns.is_some())
        .count();
    (versions.len(), aged)
}

/// A device other than the WireMan on every scene: the wall, the box and the stereo relief on
/// the HAL twin, the camera relief when the shared data is there, and the box on the CAN twin;
/// each replays bit for bit and keeps to the felt bound with every algorithm.
fn device_sessions_replay(device: &str) {
    let dir = tempfile::tempdir().unwrap();
    let camera = camera_scene(dir.path());
    let mut sessions: Vec<(&str, String, Vec<&std::ffi::OsStr>)> = vec![
        ("hal", "wall".into(), vec![]),
        ("hal", "box".into(), vec![]),
        ("hal", "stereo".into(), vec![]),
        ("can", "box".into(), vec![]),
    ];
    if let Some((scene, calibration)) = &camera {
        sessions.push((
            "hal",
            scene.clone(),
            vec!["--stereo-calibration".as_ref(), calibration.as_os_str()],
        ));
    }
    for (sim, scene, extra) in &sessions {
        let short = scene.split(':').next().unwrap();
        let name = format!("{sim}-{short}");
        let path = videtd_session(dir.path(), &name, sim, device, scene, extra)
            .unwrap_or_else(|why| panic!("{device} {name}: {why}"));
        let log = telemetry::read_log(&path).unwrap();
        let recorded = &log.session.as_ref().unwrap().as_ref().unwrap().config;
        assert_eq!(recorded.rig.device, device);
        assert_replays_every_cycle_period(&format!("{device} {name}"), &log);
    }
}

/// The camera scene of the tests, made in `dir`: the shared chessboard set's first pair as a
/// folder played as a free-running camera (the file camera; V4L2 needs the device), calibrated by
/// `videt calibrate-stereo`. Returns `--scene`'s argument and the calibration file; `None`
/// (the test skips the scene, with the reason printed) without the shared data.
fn camera_scene(dir: &Path) -> Option<(String, std::path::PathBuf)> {
    let images = videt_testdata::data_dir("calib/chessboard")?;
    let calibration = dir.join("stereo.json");
    let (status, _, err) = videt(&[
        "calibrate-stereo".as_ref(),
        "--images".as_ref(),
        images.as_os_str(),
        "--board".as_ref(),
        "9x6".as_ref(),
        "--square".as_ref(),
        "0.025".as_ref(),
        "--out".as_ref(),
        calibration.as_os_str(),
    ]);
    assert!(status.success(), "{err}");
    let still = dir.join("still");
    std::fs::create_dir(&still).unwrap();
    for name in ["left01.jpg", "right01.jpg"] {
        std::fs::copy(images.join(name), still.join(name)).unwrap();
    }
    Some((format!("camera:{}", still.display()), calibration))
}

#[test]
fn a_planar2_session_replays_bit_for_bit() {
    device_sessions_replay("planar2");
}

#[test]
fn a_polar1_session_replays_bit_for_bit() {
    device_sessions_replay("polar1");
}

#[test]
fn videtd_wall_and_box_sessions_replay_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    for scene in ["wall", "box"] {
        let path = videtd_session(dir.path(), scene, "hal", "wireman3", scene, &[]).unwrap();
        let log = telemetry::read_log(&path).unwrap();
        assert_replays_every_cycle_period(&format!("wireman3 {scene}"), &log);
    }
}

#[test]
fn videtd_box_session_on_the_can_twin_replays_bit_for_bit() {
    // The drives behind CiA 402 nodes on the simulated bus: the samples the driver decoded from
    // the bus are what the replay feeds back.
    let dir = tempfile::tempdir().unwrap();
    let path = videtd_session(dir.path(), "box-can", "can", "wireman3", "box", &[]).unwrap();
    let log = telemetry::read_log(&path).unwrap();
    assert_replays_every_cycle_period("wireman3 box (CAN twin)", &log);
}

#[test]
fn videtd_stereo_and_camera_sessions_on_the_can_twin_replay_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let path = videtd_session(dir.path(), "stereo-can", "can", "wireman3", "stereo", &[]).unwrap();
    let log = telemetry::read_log(&path).unwrap();
    assert_replays_every_cycle_period("wireman3 stereo (CAN twin)", &log);
    let Some((scene, calibration)) = camera_scene(dir.path()) else {
        return;
    };
    let extra = ["--stereo-calibration".as_ref(), calibration.as_os_str()];
    let path = videtd_session(dir.path(), "camera-can", "can", "wireman3", &scene, &extra).unwrap();
    let log = telemetry::read_log(&path).unwrap();
    assert_replays_every_cycle_period("wireman3 camera (CAN twin)", &log);
}

#[test]
fn a_videtd_stereo_session_replays_bit_for_bit_with_its_frame_ages() {
    let dir = tempfile::tempdir().unwrap();
    let path = videtd_session(dir.path(), "stereo", "hal", "wireman3", "stereo", &[]).unwrap();
    let log = telemetry::read_log(&path).unwrap();
    // Reliefs updated around the finger, each first rendered with the age of the frame it was
    // made from: what the replay must hand back rather than measure again.
    let (versions, aged) = surfaces_of(&log);
    assert!(versions >= 3, "{versions} surface versions rendered");
    assert!(aged >= 1, "no frame age recorded");
    assert_replays_every_cycle_period("wireman3 stereo", &log);
}

#[test]
fn a_videtd_camera_session_replays_bit_for_bit_with_its_frame_ages() {
    let dir = tempfile::tempdir().unwrap();
    let Some((scene, calibration)) = camera_scene(dir.path()) else {
        return;
    };
    let path = videtd_session(
        dir.path(),
        "camera",
        "hal",
        "wireman3",
        &scene,
        &["--stereo-calibration".as_ref(), calibration.as_os_str()],
    )
    .unwrap();
    let log = telemetry::read_log(&path).unwrap();
    let (versions, aged) = surfaces_of(&log);
    assert!(versions >= 3, "{versions} surface versions rendered");
    assert!(aged >= 2, "{aged} frame ages recorded");
    assert_replays_every_cycle_period("wireman3 camera", &log);
    let (status, out, _) = videt(&["replay".as_ref(), path.as_os_str()]);
    assert!(status.success() && out.contains("identical"), "{out}");
}

/// `bytes` (a log whose first frame is the session) with the session frame's text passed
/// through `edit`.
fn with_session_text(bytes: &[u8], edit: impl Fn(&str) -> String) -> Vec<u8> {
    let h = telemetry::HEADER_BYTES;
    let head = telemetry::format::FRAME_HEAD_BYTES;
    assert_eq!(bytes[h], telemetry::format::FrameKind::Session as u8);
    let len = u32::from_le_bytes(bytes[h + 4..h + 8].try_into().unwrap()) as usize;
    let text = std::str::from_utf8(&bytes[h + head..h + head + len]).unwrap();
    let mut out = bytes[..h].to_vec();
    telemetry::format::frame(
        telemetry::format::FrameKind::Session,
        edit(text).as_bytes(),
        &mut out,
    )
    .unwrap();
    out.extend_from_slice(&bytes[h + head + len + telemetry::format::FRAME_TAIL_BYTES..]);
    out
}

#[test]
fn a_log_recorded_before_a_configuration_key_existed_names_it() {
    // A session that ran without the stretch compensation, as a build before the key existed
    // did; its log then lacks the key, and a replay takes today's default (on).
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("o.vlog");
    let mut config = Config::default();
    config.control.stretch_compensation = false;
    record_session(&path, &config, 2.0, false, Vec::new(), &[]);
    let bytes = as_version_3(&std::fs::read(&path).unwrap());
    assert_identical(&telemetry::parse_log(&bytes).unwrap());
    let old = with_session_text(&bytes, |text| {
        let kept: Vec<&str> = text
            .lines()
            .filter(|l| !l.starts_with("stretch_compensation "))
            .collect();
        assert_eq!(kept.len() + 1, text.lines().count(), "{text}");
        kept.join("\n")
    });
    let old_path = dir.path().join("old.vlog");
    std::fs::write(&old_path, &old).unwrap();
    let log = telemetry::parse_log(&old).unwrap();
    assert!(log.damage.is_none(), "{:?}", log.damage_note());
    assert!(
        log.session
            .as_ref()
            .unwrap()
            .as_ref()
            .unwrap()
            .config
            .control
            .stretch_compensation
    );
    let (status, out, err) = videt(&["replay".as_ref(), old_path.as_os_str()]);
    assert_eq!(status.code(), Some(3), "{out}{err}");
    assert!(
        out.contains(
            "recorded before control.stretch_compensation existed: replayed with today's default true"
        ),
        "{out}"
    );
    let divergence = out
        .lines()
        .find(|l| l.contains("first divergence"))
        .unwrap_or_else(|| panic!("{out}"));
    assert!(
        divergence.contains("control.stretch_compensation = true"),
        "{divergence}"
    );
    // The same log's replay with the key as the session ran it is identical again.
    let config_path = dir.path().join("as-recorded.toml");
    std::fs::write(&config_path, toml::to_string(&config).unwrap()).unwrap();
    let (status, out, err) = videt(&[
        "replay".as_ref(),
        old_path.as_os_str(),
        "--config".as_ref(),
        config_path.as_os_str(),
    ]);
    assert!(status.success(), "{out}{err}");
    assert!(
        out.contains("identical") && !out.contains("recorded before"),
        "{out}"
    );
    // The JSON report lists the key too.
    let (_, out, _) = videt(&["replay".as_ref(), old_path.as_os_str(), "--json".as_ref()]);
    let report: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(
        report["unrecorded_config"],
        serde_json::json!(["control.stretch_compensation = true"])
    );
}
