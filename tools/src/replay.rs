//! Replay a recorded session through the same control cycle code: the recorded inputs of every
//! period (drive samples, tension readings, e-stop, surface version, the operations from the
//! supervisor) go into [`ControlCycle::run`] again, built from the recorded configuration and
//! calibration and rendering the recorded surfaces; every output is compared bit for bit with
//! the recorded one.
//!
//! With another configuration or algorithm the replay answers "what would these settings have
//! commanded along this session": the recorded motion is fed back open-loop (the wearer's hand
//! and the wires would have reacted to other torques; the replay cannot know how).

use std::sync::Arc;

use videt_control::safety::SafetyState;
use videt_control::surface::Plane;
use videt_control::Algorithm;
use videt_control::WireDevice;
use videt_hal::{
    AngleSensors, DriveSample, EStop, ErrorKind, ErrorType, TensionSensors, WireDrives,
};

use videt_rt_config::Config;
use videt_runtime::runtime_device::RuntimeDevice;
use videt_vision::surface::ReliefModel;

use videt_runtime::cycle::{
    ControlCycle, CycleInputs, CycleOp, CycleRecord, EStopReading, TorqueWrite,
};
use videt_runtime::snapshot::{FixedSurface, SnapshotWriter, SurfaceFeed};
use videt_runtime::telemetry::{Log, RecordedSurface, SessionInfo, SurfaceEntry};
use videt_service::relief_feed::ReliefFeed;

/// Settings that replace the recorded ones.
#[derive(Debug, Clone, Default)]
pub struct ReplayOverrides {
    /// Another configuration for the whole session.
    pub config: Option<Config>,
    /// Another force-distribution algorithm (`control.algorithm`).
    pub algorithm: Option<String>,
}

impl ReplayOverrides {
    /// Whether anything is overridden (outputs are then expected to differ).
    pub fn any(&self) -> bool {
        self.config.is_some() || self.algorithm.is_some()
    }
}

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

/// Why a log cannot be replayed at all.
#[derive(Debug, thiserror::Error)]
#[error("cannot replay: {0}")]
pub struct ReplayError(pub String);

/// The recorded inputs of one period as the devices of [`ControlCycle::run`].
struct RecordedDevices<'a> {
    inputs: &'a CycleInputs,
}

impl ErrorType for RecordedDevices<'_> {
    type Error = ErrorKind;
}

impl<const N: usize> WireDrives<N> for RecordedDevices<'_> {
    fn enable(&mut self) -> Result<(), ErrorKind> {
        Ok(())
    }
    fn disable(&mut self) -> Result<(), ErrorKind> {
        Ok(())
    }
    fn read_drives(&mut self, out: &mut [DriveSample; N]) -> Result<(), ErrorKind> {
        out.copy_from_slice(&self.inputs.drives[..N]);
        if self.inputs.drives_read_ok {
            Ok(())
        } else {
            Err(ErrorKind::Fault)
        }
    }
    fn write_torques(&mut self, _torque_nm: &[f64; N]) -> Result<(), ErrorKind> {
        match self.inputs.torque_write {
            TorqueWrite::Failed => Err(ErrorKind::Fault),
            // A write the recorded cycle did not make succeeds here; the record then says
            // `Written` where the log says `NotWritten`, and the comparison reports it.
            TorqueWrite::Written | TorqueWrite::NotWritten => Ok(()),
        }
    }
}

impl<const N: usize> TensionSensors<N> for RecordedDevices<'_> {
    fn read_tensions(&mut self, out_n: &mut [f64; N]) -> Result<(), ErrorKind> {
        self.read_fresh_tensions(out_n).map(|_| ())
    }
    fn read_fresh_tensions(&mut self, out_n: &mut [f64; N]) -> Result<[bool; N], ErrorKind> {
        out_n.copy_from_slice(&self.inputs.tensions_read_n[..N]);
        if self.inputs.tensions_read_ok {
            let mut fresh = [false; N];
            fresh.copy_from_slice(&self.inputs.tensions_fresh[..N]);
            Ok(fresh)
        } else {
            Err(ErrorKind::Fault)
        }
    }
}

impl AngleSensors for RecordedDevices<'_> {
    fn read_angles(&mut self, out_rad: &mut [f64; 2]) -> Result<(), ErrorKind> {
        *out_rad = self.inputs.angles_rad;
        if self.inputs.angles_read_ok {
            Ok(())
        } else {
            Err(ErrorKind::Fault)
        }
    }
}

impl EStop for RecordedDevices<'_> {
    fn is_pressed(&mut self) -> Result<bool, ErrorKind> {
        match self.inputs.estop {
            EStopReading::Released => Ok(false),
            EStopReading::Pressed => Ok(true),
            EStopReading::Failed => Err(ErrorKind::Fault),
        }
    }
    fn reset(&mut self) -> Result<(), ErrorKind> {
        Ok(())
    }
}

/// The recorded surfaces, rendered as the service rendered them.
enum ReplayFeed {
    Plane(FixedSurface<Plane>),
    Relief {
        writer: SnapshotWriter<ReliefModel>,
        feed: Box<ReliefFeed>,
        published: u64,
    },
}

fn surface_at(log: &Log, version: u64) -> Result<&Arc<RecordedSurface>, String> {
    match log.surfaces.get(&version) {
        Some(SurfaceEntry::Recorded(s)) => Ok(s),
        Some(SurfaceEntry::Lost) => Err(format!(
            "surface version {version} was published but not recorded (the log writer fell behind)"
        )),
        None => Err(format!("surface version {version} is not in the log")),
    }
}

impl ReplayFeed {
    fn new(log: &Log, config: &Config) -> Result<ReplayFeed, String> {
        Ok(match surface_at(log, 0)?.as_ref() {
            RecordedSurface::Plane(p) => ReplayFeed::Plane(FixedSurface(*p)),
            RecordedSurface::Relief(m) => {
                let (writer, feed) =
                    videt_service::relief_feed::relief_channel_for(config, m.clone())
                        .map_err(|e| format!("relief rendering settings: {e}"))?;
                ReplayFeed::Relief {
                    writer,
                    feed: Box::new(feed),
                    published: 0,
                }
            }
        })
    }

    /// Make `version` the newest surface, as the control thread found it.
    fn show(&mut self, log: &Log, version: u64) -> Result<(), String> {
        match self {
            ReplayFeed::Plane(_) if version == 0 => Ok(()),
            ReplayFeed::Plane(_) => Err(format!(
                "surface version {version} on a fixed surface (a corrupt record)"
            )),
            ReplayFeed::Relief {
                writer, published, ..
            } => {
                if version != *published {
                    let RecordedSurface::Relief(m) = surface_at(log, version)?.as_ref() else {
                        return Err(format!("surface version {version} is not a relief"));
                    };
                    if version < *published {
                        return Err(format!(
                            "surface version {version} after version {published} (a corrupt record)"
                        ));
                    }
                    writer.publish_as(version, m.clone());
                    *published = version;
                }
                Ok(())
            }
        }
    }

    fn run<const N: usize, D: WireDevice<N>>(
        &mut self,
        cycle: &mut ControlCycle<N, D>,
        devices: &mut RecordedDevices<'_>,
        record: &CycleRecord,
        out: &mut CycleRecord,
    ) {
        let (now, overrun) = (record.time, record.inputs.deadline_overrun);
        match self {
            ReplayFeed::Plane(f) => cycle.run(devices, f.current(), now, overrun, out),
            ReplayFeed::Relief { feed, .. } => {
                cycle.run(devices, feed.current(), now, overrun, out)
            }
        }
    }
}

/// The configuration a replay runs with: the recorded one, or the override, with the algorithm
/// override applied.
pub fn replay_config(session: &SessionInfo, overrides: &ReplayOverrides) -> Result<Config, String> {
    let mut config = overrides
        .config
        .clone()
        .unwrap_or_else(|| session.config.clone());
    if let Some(name) = &overrides.algorithm {
        let a = Algorithm::from_name(name).ok_or_else(|| {
            format!(
                "unknown algorithm {name:?}: expected one of {}",
                Algorithm::ALL.map(|a| a.name()).join(", ")
            )
        })?;
        config.control.algorithm = a.name().to_string();
    }
    Ok(config)
}

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

/// Replay `log` (version 2, with its session) through [`ControlCycle::run`], the cycle of the
/// device the recorded configuration (or the override) names.
pub fn replay(log: &Log, overrides: &ReplayOverrides) -> Result<Replay, ReplayError> {
    let device = match &log.session {
        Some(Ok(s)) => replay_config(s, overrides)
            .map_err(ReplayError)?
            .rig
            .device
            .clone(),
        _ => String::new(),
    };
    match device.as_str() {
        "planar2" => replay_device::<2, videt_control::PlanarDevice>(log, overrides),
        "polar1" => replay_device::<1, videt_control::PolarDevice>(log, overrides),
        "wireman3" | "" => replay_device::<3, videt_control::Rig3>(log, overrides),
        other => Err(ReplayError(format!(
            "rig.device = {other:?}: the service does not run it, so no log of it is replayed"
        ))),
    }
}

fn replay_device<const N: usize, D: RuntimeDevice<N>>(
    log: &Log,
    overrides: &ReplayOverrides,
) -> Result<Replay, ReplayError> {
    let session = match &log.session {
        Some(Ok(s)) => s,
        Some(Err(e)) => return Err(ReplayError(e.clone())),
        None if log.version < 2 => {
            return Err(ReplayError(format!(
                "a version {} log records no inputs (recorded by an older videtd)",
                log.version
            )))
        }
        None => {
            return Err(ReplayError(
                "the log has no session frame (configuration): it was not recorded by videtd"
                    .into(),
            ))
        }
    };
    let config = replay_config(session, overrides).map_err(ReplayError)?;
    let mut feed = ReplayFeed::new(log, &config).map_err(ReplayError)?;
    let mut replay = Replay {
        config,
        replayed: Vec::with_capacity(log.records.len()),
        procedure_periods: 0,
        first_divergence: None,
        divergent_periods: 0,
        stopped_early: None,
    };
    let mut cycle: Option<ControlCycle<N, D>> = None;
    let mut calibrations = log.calibrations.iter().peekable();
    let mut previous: Option<u64> = None;
    let mut resume = true;
    for (i, record) in log.records.iter().enumerate() {
        while let Some(c) = calibrations.next_if(|c| c.before_record <= i) {
            let (device, zero) = c.calibration.device::<N, D>().map_err(ReplayError)?;
            cycle = Some(videt_runtime::setup::control_cycle_for(
                &replay.config,
                device,
                zero,
                c.calibration.calibrated,
            ));
            resume = true;
        }
        if !record.inputs.from_cycle {
            replay.procedure_periods += 1;
            resume = true;
            continue;
        }
        let stop = |why: String| Some(format!("period {} (record {i}): {why}", record.cycle));
        let Some(cycle) = cycle.as_mut() else {
            replay.stopped_early = stop("no calibration recorded before it".into());
            break;
        };
        if previous.is_some_and(|p| p.checked_add(1) != Some(record.cycle)) && !resume {
            replay.stopped_early = stop(format!(
                "{} periods before it were not recorded (dropped by a full ring): the state after them is unknown",
                record.cycle.saturating_sub(previous.unwrap_or(0).saturating_add(1))
            ));
            break;
        }
        if record.inputs.ops.overflowed() {
            replay.stopped_early = stop("more supervisor operations than were recorded".into());
            break;
        }
        if let Err(why) = feed.show(log, record.surface_version) {
            replay.stopped_early = stop(why);
            break;
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
            record,
            &mut out,
        );
        if let Some((field, recorded, replayed)) = first_difference(record, &out) {
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
        replay.replayed.push((i, out));
        previous = Some(record.cycle);
    }
    Ok(replay)
}

fn safety_text(s: SafetyState) -> String {
    match s.reason() {
        Some(r) => format!("{} ({})", s.as_str(), r.as_str()),
        None => s.as_str().to_string(),
    }
}

/// The first field in which `b` differs from `a` (floats compared bit for bit): (field, a, b).
pub fn first_difference(a: &CycleRecord, b: &CycleRecord) -> Option<(String, String, String)> {
    let diff = |name: String, x: String, y: String| Some((name, x, y));
    if a.cycle != b.cycle {
        return diff("cycle".into(), a.cycle.to_string(), b.cycle.to_string());
    }
    for (k, (va, vb)) in a.vectors().iter().zip(b.vectors()).enumerate() {
        for j in 0..3 {
            if va[j].to_bits() != vb[j].to_bits() {
                return diff(
                    format!("{}[{j}]", CycleRecord::VECTOR_NAMES[k]),
                    format!("{:e}", va[j]),
                    format!("{:e}", vb[j]),
                );
            }
        }
    }
    let scalars = [
        ("contact_depth_m", a.contact_depth_m, b.contact_depth_m),
        ("force_scale", a.force_scale, b.force_scale),
    ];
    for (name, x, y) in scalars {
        if x.to_bits() != y.to_bits() {
            return diff(name.into(), format!("{x:e}"), format!("{y:e}"));
        }
    }
    if a.safety != b.safety {
        return diff(
            "safety".into(),
            safety_text(a.safety),
            safety_text(b.safety),
        );
    }
    let others = [
        (
            "in_contact",
            a.in_contact.to_string(),
            b.in_contact.to_string(),
        ),
        (
            "surface_version",
            a.surface_version.to_string(),
            b.surface_version.to_string(),
        ),
        (
            "surface_stale",
            a.surface_stale.to_string(),
            b.surface_stale.to_string(),
        ),
        (
            "released_wire",
            a.released_wire.to_string(),
            b.released_wire.to_string(),
        ),
        (
            "torque_write",
            format!("{:?}", a.inputs.torque_write),
            format!("{:?}", b.inputs.torque_write),
        ),
    ];
    for (name, x, y) in others {
        if x != y {
            return diff(name.into(), x, y);
        }
    }
    // The inputs are fed back; they come out different only if the replay does not read
    // them as the service did.
    if a.inputs != b.inputs {
        return diff(
            "inputs".into(),
            format!("{:?}", a.inputs),
            format!("{:?}", b.inputs),
        );
    }
    None
}
