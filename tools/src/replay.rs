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
use videt_runtime::snapshot::{FixedSurface, SnapshotWriter, SurfaceFeed, SurfaceView};
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
        // The period's time and the frame age are measurements of the session, taken from the
        // clock when it ran: both come from the record, never from this machine's clock (the
        // replay publishes the recorded surfaces without a capture stamp, so the feed reads no
        // clock either).
        let (now, overrun) = (record.time, record.inputs.deadline_overrun);
        let age = record.inputs.surface_frame_age_ns;
        match self {
            ReplayFeed::Plane(f) => {
                cycle.run(devices, with_age(f.current(), age), now, overrun, out)
            }
            ReplayFeed::Relief { feed, .. } => {
                cycle.run(devices, with_age(feed.current(), age), now, overrun, out)
            }
        }
    }
}

/// `view` with the recorded frame age: how old the camera frame of a new surface was when the
/// service first rendered it. The outputs do not depend on it; the record keeps it as an input
/// (the frame-to-force latency), so a replay hands the recorded one back.
fn with_age<S: ?Sized>(
    mut view: SurfaceView<'_, S>,
    frame_age_ns: Option<u64>,
) -> SurfaceView<'_, S> {
    view.frame_age_ns = frame_age_ns;
    view
}

/// A key of today's configuration that a log's recorded configuration lacks (the log was
/// recorded before the key existed): the replay runs with today's default for it, which need
/// not be how the recorded session ran.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UnrecordedKey {
    /// The key, dotted (`control.stretch_compensation`).
    pub key: String,
    /// Today's default the replay uses, as TOML.
    pub default: String,
}

impl std::fmt::Display for UnrecordedKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} = {}", self.key, self.default)
    }
}

/// The session frame's text (TOML) of a version 2 log's bytes: the first frame after the
/// header, when it is a session frame.
pub fn session_text(bytes: &[u8]) -> Option<&str> {
    use videt_runtime::telemetry::HEADER_BYTES;
    const SESSION_KIND: u8 = 1;
    let head = bytes.get(HEADER_BYTES..HEADER_BYTES + 8)?;
    if head[0] != SESSION_KIND {
        return None;
    }
    let len = u32::from_le_bytes(head[4..8].try_into().ok()?) as usize;
    let start = HEADER_BYTES + 8;
    std::str::from_utf8(bytes.get(start..start.checked_add(len)?)?).ok()
}

/// The keys of today's configuration that the recorded session's `[config]` (its TOML text,
/// [`session_text`]) does not have, with the defaults a replay takes for them. A section missing
/// as a whole is named once.
pub fn unrecorded_config_keys(session_toml: &str) -> Vec<UnrecordedKey> {
    fn walk(
        prefix: &str,
        today: &toml::Table,
        recorded: &toml::Table,
        out: &mut Vec<UnrecordedKey>,
    ) {
        for (name, value) in today {
            let key = if prefix.is_empty() {
                name.clone()
            } else {
                format!("{prefix}.{name}")
            };
            match (value, recorded.get(name)) {
                (toml::Value::Table(t), Some(toml::Value::Table(r))) => walk(&key, t, r, out),
                (_, Some(_)) => {}
                (toml::Value::Table(_), None) => out.push(UnrecordedKey {
                    key: format!("[{key}]"),
                    default: "(the whole section)".into(),
                }),
                (v, None) => out.push(UnrecordedKey {
                    key,
                    default: v.to_string(),
                }),
            }
        }
    }
    let Ok(session) = session_toml.parse::<toml::Table>() else {
        return Vec::new();
    };
    let Some(toml::Value::Table(recorded)) = session.get("config") else {
        return Vec::new();
    };
    let Ok(today) = toml::Table::try_from(Config::default()) else {
        return Vec::new();
    };
    let mut out = Vec::new();
    walk("", &today, recorded, &mut out);
    out
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
                let (x, y) = floats(va[j], vb[j]);
                return diff(format!("{}[{j}]", CycleRecord::VECTOR_NAMES[k]), x, y);
            }
        }
    }
    let scalars = [
        ("contact_depth_m", a.contact_depth_m, b.contact_depth_m),
        ("force_scale", a.force_scale, b.force_scale),
    ];
    for (name, x, y) in scalars {
        if x.to_bits() != y.to_bits() {
            let (x, y) = floats(x, y);
            return diff(name.into(), x, y);
        }
    }
    if a.safety != b.safety {
        return diff(
            "safety".into(),
            safety_text(a.safety),
            safety_text(b.safety),
        );
    }
    let other = differ(
        || "in_contact".into(),
        a.in_contact,
        b.in_contact,
        ToString::to_string,
    )
    .or_else(|| {
        differ(
            || "surface_version".into(),
            a.surface_version,
            b.surface_version,
            ToString::to_string,
        )
    })
    .or_else(|| {
        differ(
            || "surface_stale".into(),
            a.surface_stale,
            b.surface_stale,
            ToString::to_string,
        )
    })
    .or_else(|| {
        differ(
            || "released_wire".into(),
            a.released_wire,
            b.released_wire,
            ToString::to_string,
        )
    });
    if other.is_some() {
        return other;
    }
    // The inputs are fed back; they come out different only if the replay does not read
    // them as the service did.
    first_input_difference(&a.inputs, &b.inputs)
}

/// Two floats as text for a difference report: scientific notation, with the bits when the
/// text alone does not tell them apart (`0` and `-0`, NaN payloads).
fn floats(x: f64, y: f64) -> (String, String) {
    let (tx, ty) = (format!("{x:e}"), format!("{y:e}"));
    if tx == ty {
        (
            format!("{tx} (bits {:#018x})", x.to_bits()),
            format!("{ty} (bits {:#018x})", y.to_bits()),
        )
    } else {
        (tx, ty)
    }
}

fn optional_ns(v: Option<u64>) -> String {
    v.map_or_else(|| "none".to_string(), |ns| format!("{ns} ns"))
}

fn ops_text(ops: &videt_runtime::cycle::CycleOps) -> String {
    let mut text = format!("{:?}", ops.as_slice());
    if ops.overflowed() {
        text.push_str(" (more not kept)");
    }
    text
}

/// `Some((name, x, y))` as text when `x` and `y` differ (formatted only then).
fn differ<T: PartialEq>(
    name: impl FnOnce() -> String,
    x: T,
    y: T,
    show: impl Fn(&T) -> String,
) -> Option<(String, String, String)> {
    (x != y).then(|| (name(), show(&x), show(&y)))
}

/// `Some((name, x, y))` when the floats differ bit for bit.
fn differ_bits(name: impl FnOnce() -> String, x: f64, y: f64) -> Option<(String, String, String)> {
    (x.to_bits() != y.to_bits()).then(|| {
        let (tx, ty) = floats(x, y);
        (name(), tx, ty)
    })
}

/// The first field in which the inputs `b` differ from `a`, named as in [`CycleInputs`]
/// (`drives[1].position_counts`, `tensions_read_n[0]`, `surface_frame_age_ns`, `ops`, ...;
/// floats compared bit for bit): (field, a, b).
pub fn first_input_difference(
    a: &CycleInputs,
    b: &CycleInputs,
) -> Option<(String, String, String)> {
    // Every field, by name: a field added to the inputs does not compile here until it is
    // compared.
    let CycleInputs {
        from_cycle,
        deadline_overrun,
        drives_read_ok,
        drives,
        tensions_read_ok,
        tensions_read_n,
        tensions_fresh,
        angles_read_ok,
        angles_rad,
        estop,
        torque_write,
        surface_live,
        surface_frame_age_ns,
        ops,
    } = a;
    let flag = |name: &'static str, x: bool, y: bool| {
        differ(|| name.to_string(), x, y, ToString::to_string)
    };
    let first = flag("from_cycle", *from_cycle, b.from_cycle)
        .or_else(|| flag("deadline_overrun", *deadline_overrun, b.deadline_overrun))
        .or_else(|| flag("drives_read_ok", *drives_read_ok, b.drives_read_ok));
    if first.is_some() {
        return first;
    }
    for (w, (x, y)) in drives.iter().zip(&b.drives).enumerate() {
        let DriveSample {
            position_counts,
            velocity_counts_per_s,
            state,
            error_code,
        } = x;
        let d = differ(
            || format!("drives[{w}].position_counts"),
            *position_counts,
            y.position_counts,
            ToString::to_string,
        )
        .or_else(|| {
            differ_bits(
                || format!("drives[{w}].velocity_counts_per_s"),
                *velocity_counts_per_s,
                y.velocity_counts_per_s,
            )
        })
        .or_else(|| {
            differ(
                || format!("drives[{w}].state"),
                *state,
                y.state,
                |s| format!("{s:?}"),
            )
        })
        .or_else(|| {
            differ(
                || format!("drives[{w}].error_code"),
                *error_code,
                y.error_code,
                |c| format!("{c:#06x}"),
            )
        });
        if d.is_some() {
            return d;
        }
    }
    if let Some(d) = flag("tensions_read_ok", *tensions_read_ok, b.tensions_read_ok) {
        return Some(d);
    }
    for w in 0..tensions_read_n.len() {
        let d = differ_bits(
            || format!("tensions_read_n[{w}]"),
            tensions_read_n[w],
            b.tensions_read_n[w],
        )
        .or_else(|| {
            differ(
                || format!("tensions_fresh[{w}]"),
                tensions_fresh[w],
                b.tensions_fresh[w],
                ToString::to_string,
            )
        });
        if d.is_some() {
            return d;
        }
    }
    if let Some(d) = flag("angles_read_ok", *angles_read_ok, b.angles_read_ok) {
        return Some(d);
    }
    for k in 0..angles_rad.len() {
        if let Some(d) = differ_bits(
            || format!("angles_rad[{k}]"),
            angles_rad[k],
            b.angles_rad[k],
        ) {
            return Some(d);
        }
    }
    differ(|| "estop".into(), *estop, b.estop, |e| format!("{e:?}"))
        .or_else(|| {
            differ(
                || "torque_write".into(),
                *torque_write,
                b.torque_write,
                |t| format!("{t:?}"),
            )
        })
        .or_else(|| flag("surface_live", *surface_live, b.surface_live))
        .or_else(|| {
            differ(
                || "surface_frame_age_ns".into(),
                *surface_frame_age_ns,
                b.surface_frame_age_ns,
                |v| optional_ns(*v),
            )
        })
        .or_else(|| differ(|| "ops".into(), *ops, b.ops, ops_text))
}

#[cfg(test)]
mod tests {
    use super::*;
    use videt_hal::DriveState;
    use videt_runtime::cycle::CycleOps;
    use videt_runtime::telemetry::SessionInfo;

    fn inputs() -> CycleInputs {
        let mut i = CycleInputs {
            from_cycle: true,
            drives_read_ok: true,
            tensions_read_ok: true,
            tensions_read_n: [1.5, 2.5, 3.5],
            tensions_fresh: [true; 3],
            surface_live: true,
            ..CycleInputs::default()
        };
        for (w, d) in i.drives.iter_mut().enumerate() {
            d.position_counts = -1000 * w as i64;
            d.velocity_counts_per_s = 12.5 * w as f64;
            d.state = DriveState::Enabled;
        }
        i
    }

    #[test]
    fn inputs_differ_by_field_name_with_both_values() {
        let a = inputs();
        assert_eq!(first_input_difference(&a, &a), None);
        let diff = |change: &dyn Fn(&mut CycleInputs)| {
            let mut b = a;
            change(&mut b);
            first_input_difference(&a, &b).expect("a difference")
        };
        assert_eq!(
            diff(&|b| b.drives[1].position_counts += 1),
            (
                "drives[1].position_counts".into(),
                "-1000".into(),
                "-999".into()
            )
        );
        assert_eq!(
            diff(&|b| b.drives[2].state = DriveState::Fault).0,
            "drives[2].state"
        );
        assert_eq!(
            diff(&|b| b.drives[0].error_code = 0x2310),
            (
                "drives[0].error_code".into(),
                "0x0000".into(),
                "0x2310".into()
            )
        );
        assert_eq!(
            diff(&|b| b.surface_frame_age_ns = Some(7_250_000)),
            (
                "surface_frame_age_ns".into(),
                "none".into(),
                "7250000 ns".into()
            )
        );
        let (field, _, replayed) = diff(&|b| b.ops.push(CycleOp::ResetFaults));
        assert_eq!(field, "ops");
        assert!(replayed.contains("ResetFaults"), "{replayed}");
        let mut full = CycleOps::default();
        for _ in 0..=CycleOps::CAPACITY {
            full.push(CycleOp::RequestStop);
        }
        assert!(diff(&|b| b.ops = full).2.contains("more not kept"));
        // Floats bit for bit: -0 is not 0; NaNs with other payloads differ, and the bits say
        // so where the text cannot.
        let (field, recorded, replayed) = diff(&|b| b.tensions_read_n[0] = 1.5 + 1e-15);
        assert_eq!(field, "tensions_read_n[0]");
        assert_ne!(recorded, replayed);
        assert_eq!(
            diff(&|b| b.angles_rad[1] = -0.0),
            ("angles_rad[1]".into(), "0e0".into(), "-0e0".into())
        );
        let mut nan = a;
        nan.drives[1].velocity_counts_per_s = f64::NAN;
        let mut other_nan = nan;
        other_nan.drives[1].velocity_counts_per_s = f64::from_bits(f64::NAN.to_bits() | 1);
        let (field, recorded, replayed) = first_input_difference(&nan, &other_nan).unwrap();
        assert_eq!(field, "drives[1].velocity_counts_per_s");
        assert!(
            recorded.ends_with("(bits 0x7ff8000000000000)")
                && replayed.ends_with("(bits 0x7ff8000000000001)"),
            "{recorded} / {replayed}"
        );
        assert_eq!(first_input_difference(&nan, &nan), None);
        // The first field in the record's order is named.
        assert_eq!(
            diff(&|b| {
                b.tensions_fresh[2] = false;
                b.drives[2].position_counts = 5;
            })
            .0,
            "drives[2].position_counts"
        );
        assert_eq!(diff(&|b| b.estop = EStopReading::Failed).0, "estop");
        assert_eq!(diff(&|b| b.deadline_overrun = true).0, "deadline_overrun");
    }

    #[test]
    fn a_record_differing_in_an_input_names_it() {
        let a = CycleRecord {
            cycle: 7,
            inputs: inputs(),
            ..CycleRecord::default()
        };
        let mut b = a;
        b.inputs.tensions_read_n[2] = 4.0;
        let (field, recorded, replayed) = first_difference(&a, &b).unwrap();
        assert_eq!(
            (field.as_str(), recorded.as_str(), replayed.as_str()),
            ("tensions_read_n[2]", "3.5e0", "4e0")
        );
        // An output differing is named before any input.
        b.torque_nm[1] = 0.25;
        assert_eq!(first_difference(&a, &b).unwrap().0, "torque_nm[1]");
        assert_eq!(first_difference(&a, &a), None);
    }

    #[test]
    fn keys_missing_from_a_recorded_configuration_are_named_with_their_defaults() {
        let text = SessionInfo::new("twin", Config::default())
            .to_toml()
            .unwrap();
        assert_eq!(unrecorded_config_keys(&text), Vec::new());
        // A log recorded before these keys existed.
        let old: String = text
            .lines()
            .filter(|l| {
                !l.starts_with("stretch_compensation ")
                    && !l.starts_with("tension_integral_speed_gate_m_s ")
            })
            .map(|l| format!("{l}\n"))
            .collect();
        assert_ne!(old.len(), text.len());
        let keys: Vec<String> = unrecorded_config_keys(&old)
            .iter()
            .map(ToString::to_string)
            .collect();
        assert_eq!(
            keys,
            [
                "control.stretch_compensation = true",
                "control.tension_integral_speed_gate_m_s = 0.003"
            ]
        );
        // A whole section missing is named once.
        let start = old.find("[config.control]").unwrap();
        let end = start + 1 + old[start + 1..].find("\n[").unwrap();
        let without = format!("{}{}", &old[..start], &old[end + 1..]);
        let keys = unrecorded_config_keys(&without);
        assert_eq!(keys.len(), 1, "{keys:?}");
        assert_eq!(keys[0].key, "[control]");
        assert_eq!(unrecorded_config_keys("not toml ["), Vec::new());
    }
}
