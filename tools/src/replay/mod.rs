//! Replay a recorded session through the same control cycle code: the recorded inputs of every
//! period (drive samples, tension readings, e-stop, surface version, the operations from the
//! supervisor) go into [`ControlCycle::run`] again, built from the recorded configuration and
//! calibration and rendering the recorded surfaces; every output and input is compared bit for
//! bit with the recorded one, and a difference is named by its field. What the service measured
//! on its clock (the period's time, a new surface's frame age) comes from the record, never
//! from the clock of the replay.
//!
//! With another configuration or algorithm the replay answers "what would these settings have
//! commanded along this session": the recorded motion is fed back open-loop (the wearer's hand
//! and the wires would have reacted to other torques; the replay cannot know how).
//!
//! The log is read as a stream ([`replay_items`]): each replayed period goes to a
//! [`ReplayObserver`] as it is made, so a replay's memory does not grow with the session's
//! length. [`replay`] replays a log read whole and keeps every period.

mod compare;
mod devices;
mod feed;
mod recorded_config;

pub use compare::{first_difference, first_input_difference};
pub use recorded_config::{replay_config, unrecorded_config_keys, ReplayOverrides, UnrecordedKey};

use videt_config::Config;
use videt_control::WireDevice;
use videt_runtime::cycle::{ControlCycle, CycleOp, CycleRecord};
use videt_runtime::runtime_device::RuntimeDevice;
use videt_runtime::telemetry::{CalibrationInForce, Log, LogItem};

use devices::RecordedDevices;
use feed::{HeldSurfaces, ReplayFeed};

/// The first output that differs.
#[derive(Debug, Clone, PartialEq)]
pub struct Divergence {
    /// Index of the record in the log.
    pub record: usize,
    /// Its period number.
    pub cycle: u64,
    /// Its time on the service's clock, seconds.
    pub time_s: f64,
    /// The field (`tension_setpoint_n[1]`, `safety`, ...).
    pub field: String,
    /// The recorded value.
    pub recorded: String,
    /// The replayed value.
    pub replayed: String,
}

impl std::fmt::Display for Divergence {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "period {} (record {}, t = {:.3} s): {} recorded {} replayed {}",
            self.cycle, self.record, self.time_s, self.field, self.recorded, self.replayed
        )
    }
}

/// The replay of a log.
#[derive(Debug, Clone)]
pub struct Replay {
    /// The configuration the replay ran with.
    pub config: Config,
    /// Pairs of (index of the record in the log, replayed record), in order.
    pub replayed: Vec<(usize, CycleRecord)>,
    /// Procedure periods (auto-initialization through the socket) skipped: not the cycle's.
    pub procedure_periods: usize,
    /// The first period whose outputs differ.
    pub first_divergence: Option<Divergence>,
    /// Periods whose outputs differ.
    pub divergent_periods: usize,
    /// Why the replay stopped before the end of the log (a dropped record, a surface not
    /// recorded), if it did.
    pub stopped_early: Option<String>,
}

impl Replay {
    /// Whether every replayed output equals the recorded one, bit for bit.
    pub fn identical(&self) -> bool {
        self.first_divergence.is_none()
    }
}

/// Receives a replay as it runs.
pub trait ReplayObserver {
    /// The configuration the replay runs with, before any period.
    fn session(&mut self, _config: &Config) {}
    /// The calibration in force from the next period on, as the log gives it.
    fn calibration(&mut self, _calibration: &CalibrationInForce) {}
    /// Period `index` of the log (its records counted from 0) replayed: the recorded record
    /// and the replayed one.
    fn period(&mut self, index: usize, recorded: &CycleRecord, replayed: &CycleRecord);
}

/// What a replay found; the periods themselves went to its [`ReplayObserver`].
#[derive(Debug, Clone)]
pub struct ReplayOutcome {
    /// The configuration the replay ran with.
    pub config: Config,
    /// What the session was (`SessionInfo::what`).
    pub what: String,
    /// Records in the log.
    pub records: usize,
    /// Periods replayed and compared.
    pub replayed: usize,
    /// Procedure periods (auto-initialization through the socket) skipped: not the cycle's.
    pub procedure_periods: usize,
    /// The first period whose outputs differ.
    pub first_divergence: Option<Divergence>,
    /// Periods whose outputs differ.
    pub divergent_periods: usize,
    /// Why the replay stopped before the end of the log, if it did.
    pub stopped_early: Option<String>,
}

impl ReplayOutcome {
    /// Whether every replayed output equals the recorded one, bit for bit.
    pub fn identical(&self) -> bool {
        self.first_divergence.is_none()
    }
}

/// Keeps every replayed period (for [`replay`]).
struct KeepAll(Vec<(usize, CycleRecord)>);

impl ReplayObserver for KeepAll {
    fn period(&mut self, index: usize, _recorded: &CycleRecord, replayed: &CycleRecord) {
        self.0.push((index, *replayed));
    }
}

/// Why a log cannot be replayed at all.
#[derive(Debug, thiserror::Error)]
#[error("cannot replay: {0}")]
pub struct ReplayError(pub String);

fn apply<const N: usize, D: WireDevice<N>>(cycle: &mut ControlCycle<N, D>, op: CycleOp) {
    match op {
        CycleOp::None => {}
        CycleOp::ReleaseWire(w) => cycle.release_wire(w.map(usize::from)),
        CycleOp::ResetFaults => cycle.reset_faults(),
        CycleOp::Restart => cycle.restart(),
        CycleOp::RequestStop => cycle.request_stop(),
        CycleOp::Trip(s) => cycle.trip(s),
    }
}

/// Replay `log` (version 2 on, with its session) through [`ControlCycle::run`], the cycle of
/// the device the recorded configuration (or the override) names, keeping every period.
pub fn replay(log: &Log, overrides: &ReplayOverrides) -> Result<Replay, ReplayError> {
    let mut kept = KeepAll(Vec::with_capacity(log.records.len()));
    let o = replay_items(log.version, log.items(), overrides, &mut kept)?;
    Ok(Replay {
        config: o.config,
        replayed: kept.0,
        procedure_periods: o.procedure_periods,
        first_divergence: o.first_divergence,
        divergent_periods: o.divergent_periods,
        stopped_early: o.stopped_early,
    })
}

/// Replay the items of a log of format `version`, in the order the log holds them (a
/// [`LogReader`](videt_runtime::telemetry::LogReader), or [`Log::items`]): each replayed
/// period goes to `observer` as it is made; only the surfaces not yet rendered are held.
pub fn replay_items(
    version: u32,
    items: impl Iterator<Item = LogItem>,
    overrides: &ReplayOverrides,
    observer: &mut dyn ReplayObserver,
) -> Result<ReplayOutcome, ReplayError> {
    let mut items = items.peekable();
    let session = match items.next_if(|i| matches!(i, LogItem::Session(_))) {
        Some(LogItem::Session(s)) => *s,
        _ if version < 2 => {
            return Err(ReplayError(format!(
                "a version {version} log records no inputs (recorded by an older videtd)"
            )))
        }
        _ => {
            return Err(ReplayError(
                "the log has no session frame (configuration): it was not recorded by videtd"
                    .into(),
            ))
        }
    };
    let session = session.map_err(ReplayError)?;
    let config = replay_config(&session, overrides).map_err(ReplayError)?;
    let mut outcome = ReplayOutcome {
        config,
        what: session.what.clone(),
        records: 0,
        replayed: 0,
        procedure_periods: 0,
        first_divergence: None,
        divergent_periods: 0,
        stopped_early: None,
    };
    observer.session(&outcome.config);
    match outcome.config.rig.device.as_str() {
        "planar2" => {
            replay_device::<2, videt_control::PlanarDevice>(items, &mut outcome, observer)?
        }
        "polar1" => replay_device::<1, videt_control::PolarDevice>(items, &mut outcome, observer)?,
        "wireman3" | "" => replay_device::<3, videt_control::Rig3>(items, &mut outcome, observer)?,
        other => {
            return Err(ReplayError(format!(
                "rig.device = {other:?}: the service does not run it, so no log of it is replayed"
            )))
        }
    }
    Ok(outcome)
}

fn replay_device<const N: usize, D: RuntimeDevice<N>>(
    items: impl Iterator<Item = LogItem>,
    replay: &mut ReplayOutcome,
    observer: &mut dyn ReplayObserver,
) -> Result<(), ReplayError> {
    let mut held = HeldSurfaces::default();
    let mut feed: Option<ReplayFeed> = None;
    let mut cycle: Option<ControlCycle<N, D>> = None;
    let mut previous: Option<u64> = None;
    let mut resume = true;
    for item in items {
        let record = match item {
            LogItem::Calibration { calibration, .. } => {
                if replay.stopped_early.is_none() {
                    let (device, zero) = calibration.device::<N, D>().map_err(ReplayError)?;
                    cycle = Some(videt_runtime::setup::control_cycle_for(
                        &replay.config,
                        device,
                        zero,
                        calibration.calibrated,
                    ));
                    resume = true;
                    observer.calibration(&calibration);
                }
                continue;
            }
            LogItem::Surface(version, entry) => {
                if replay.stopped_early.is_none() {
                    held.hold(version, entry);
                }
                continue;
            }
            LogItem::Period(record) => record,
            LogItem::Session(_) | LogItem::End(_) => continue,
        };
        let i = replay.records;
        replay.records += 1;
        if replay.stopped_early.is_some() {
            // Counted, not replayed: the state after the stop is unknown.
            continue;
        }
        // The service rendered its first surface from its start.
        let feed = match &mut feed {
            Some(feed) => feed,
            None => feed.insert(ReplayFeed::start(&held, &replay.config).map_err(ReplayError)?),
        };
        if !record.inputs.from_cycle {
            replay.procedure_periods += 1;
            resume = true;
            continue;
        }
        let stop = |why: String| Some(format!("period {} (record {i}): {why}", record.cycle));
        let Some(cycle) = cycle.as_mut() else {
            replay.stopped_early = stop("no calibration recorded before it".into());
            continue;
        };
        if previous.is_some_and(|p| p.checked_add(1) != Some(record.cycle)) && !resume {
            replay.stopped_early = stop(format!(
                "{} periods before it were not recorded (dropped by a full ring): the state after them is unknown",
                record.cycle.saturating_sub(previous.unwrap_or(0).saturating_add(1))
            ));
            continue;
        }
        if record.inputs.ops.overflowed() {
            replay.stopped_early = stop("more supervisor operations than were recorded".into());
            continue;
        }
        if let Err(why) = feed.show(&mut held, record.surface_version) {
            replay.stopped_early = stop(why);
            continue;
        }
        if resume {
            cycle.set_cycle_count(record.cycle);
            resume = false;
        }
        for op in record.inputs.ops.as_slice() {
            apply(cycle, *op);
        }
        let mut out = CycleRecord {
            wake_latency_ns: record.wake_latency_ns,
            compute_ns: record.compute_ns,
            ..CycleRecord::default()
        };
        feed.run(
            cycle,
            &mut RecordedDevices {
                inputs: &record.inputs,
            },
            &record,
            &mut out,
        );
        if let Some((field, recorded, replayed)) = first_difference(&record, &out) {
            replay.divergent_periods += 1;
            replay.first_divergence.get_or_insert(Divergence {
                record: i,
                cycle: record.cycle,
                time_s: record.time.as_secs_f64(),
                field,
                recorded,
                replayed,
            });
        }
        replay.replayed += 1;
        observer.period(i, &record, &out);
        previous = Some(record.cycle);
    }
    Ok(())
}
