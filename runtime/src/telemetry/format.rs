//! The session log's bytes (`docs/telemetry.md`): the header, the period record (its outputs,
//! the same 256 bytes as in version 1, and its inputs), the framing of versions 2 to 4, and the
//! end frame of versions 3 and 4. Version 4 stores the frames in compressed blocks, whose
//! layout is the block module's.

use videt_control::safety::{SafetyReason, SafetyState};
use videt_hal::{DriveSample, DriveState, MonoTime};

use super::session::{CalibrationInForce, EndReason, SessionEnd};
use crate::cycle::{CycleInputs, CycleOp, CycleOps, CycleRecord, EStopReading, TorqueWrite};
use crate::WIREMAN_WIRES;

/// File magic.
pub const MAGIC: &[u8; 8] = b"VIDETLOG";
/// The format version written: version 3's frames, stored in compressed blocks.
pub const FORMAT_VERSION: u32 = 4;
/// Version 2's frames and an end frame when the service stops, uncompressed (still read).
pub const FORMAT_VERSION_3: u32 = 3;
/// Frames without an end frame (still read; such a log never reads as closed).
pub const FORMAT_VERSION_2: u32 = 2;
/// The first format version: fixed 256-byte output records, no inputs (still read).
pub const FORMAT_VERSION_1: u32 = 1;
/// Header size, bytes.
pub const HEADER_BYTES: usize = 32;
/// Size of a period's outputs (the whole record of version 1), bytes.
pub const RECORD_BYTES: usize = 256;
/// Size of a period's inputs, bytes.
pub const INPUTS_BYTES: usize = 160;
/// Size of a period frame's payload, bytes.
pub const PERIOD_BYTES: usize = RECORD_BYTES + INPUTS_BYTES;

/// A batch (one compressed block) is written once its frames take this many bytes before
/// compression (about 0.6 s of periods at 1 kHz), or once it is `BATCH_AGE` old.
pub(super) const BATCH_BYTES: usize = 256 * 1024;
/// Size of a calibration frame's payload, bytes.
pub const CALIBRATION_BYTES: usize = 112;
/// Size of an end frame's payload before its text, bytes.
pub const END_FIXED_BYTES: usize = 32;
/// Frame head (kind, reserved, payload length), bytes.
pub const FRAME_HEAD_BYTES: usize = 8;
/// Frame tail (CRC-32), bytes.
pub const FRAME_TAIL_BYTES: usize = 4;
/// Largest frame payload a reader accepts (a relief of about a million triangles), bytes.
pub const MAX_FRAME_PAYLOAD: usize = 64 << 20;

/// Kinds of frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameKind {
    /// The session: videt version, what ran, the configuration (TOML text).
    Session = 1,
    /// The calibration in force from the next period on.
    Calibration = 2,
    /// A surface version.
    Surface = 3,
    /// One control period.
    Period = 4,
    /// A surface version that could not be recorded.
    SurfaceLost = 5,
    /// The session ended and the service closed the log (version 3 on; the last frame).
    End = 6,
    /// Version 4: a compressed block of the frames above.
    Block = 7,
}

impl FrameKind {
    /// The kind of a frame's first byte.
    pub fn from_byte(b: u8) -> Option<FrameKind> {
        Some(match b {
            1 => FrameKind::Session,
            2 => FrameKind::Calibration,
            3 => FrameKind::Surface,
            4 => FrameKind::Period,
            5 => FrameKind::SurfaceLost,
            6 => FrameKind::End,
            7 => FrameKind::Block,
            _ => return None,
        })
    }
}

/// The log file's header.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LogHeader {
    /// Control rate, Hz.
    pub rate_hz: u32,
    /// Wall-clock start of the session, nanoseconds since the Unix epoch.
    pub start_unix_ns: u64,
}

/// Encode the header (the version written).
pub fn encode_header(h: &LogHeader) -> [u8; HEADER_BYTES] {
    let mut b = [0u8; HEADER_BYTES];
    b[0..8].copy_from_slice(MAGIC);
    b[8..12].copy_from_slice(&FORMAT_VERSION.to_le_bytes());
    b[12..16].copy_from_slice(&(PERIOD_BYTES as u32).to_le_bytes());
    b[16..20].copy_from_slice(&h.rate_hz.to_le_bytes());
    b[24..32].copy_from_slice(&h.start_unix_ns.to_le_bytes());
    b
}

/// Write one frame to `out` in place: head, payload, CRC.
pub fn frame(
    kind: FrameKind,
    payload: &[u8],
    out: &mut impl std::io::Write,
) -> std::io::Result<()> {
    let mut head = [0u8; FRAME_HEAD_BYTES];
    head[0] = kind as u8;
    head[4..8].copy_from_slice(&(payload.len() as u32).to_le_bytes());
    let mut crc = crc32fast::Hasher::new();
    crc.update(&head);
    crc.update(payload);
    out.write_all(&head)?;
    out.write_all(payload)?;
    out.write_all(&crc.finalize().to_le_bytes())
}

/// The CRC of a frame's head and payload.
pub fn frame_crc(head_and_payload: &[u8]) -> u32 {
    crc32fast::hash(head_and_payload)
}

/// Safety state codes in the log: (state, reason, wire).
pub fn encode_safety(s: SafetyState) -> [u8; 3] {
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

/// Decode a safety state's codes.
pub fn decode_safety(state: u8, reason: u8, wire: u8) -> SafetyState {
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

/// Encode a period's outputs (the record of version 1; see `docs/telemetry.md`).
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

/// Decode a period's outputs (its inputs stay default).
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

fn drive_state_code(s: DriveState) -> u8 {
    match s {
        DriveState::Disabled => 0,
        DriveState::Enabled => 1,
        DriveState::QuickStop => 2,
        DriveState::Fault => 3,
    }
}

fn op_bytes(op: CycleOp) -> [u8; 4] {
    match op {
        CycleOp::None => [0, 0, 0, 0],
        CycleOp::ReleaseWire(w) => [1, w.unwrap_or(255), 0, 0],
        CycleOp::ResetFaults => [2, 0, 0, 0],
        CycleOp::Restart => [3, 0, 0, 0],
        CycleOp::RequestStop => [4, 0, 0, 0],
        CycleOp::Trip(s) => {
            let [a, b, c] = encode_safety(s);
            [5, a, b, c]
        }
    }
}

fn op_from_bytes(b: [u8; 4]) -> Result<CycleOp, String> {
    Ok(match b[0] {
        1 => CycleOp::ReleaseWire((b[1] != 255).then_some(b[1])),
        2 => CycleOp::ResetFaults,
        3 => CycleOp::Restart,
        4 => CycleOp::RequestStop,
        5 => CycleOp::Trip(decode_safety(b[1], b[2], b[3])),
        k => return Err(format!("unknown cycle operation {k}")),
    })
}

/// Encode a period: outputs then inputs.
pub fn encode_period(r: &CycleRecord, b: &mut [u8; PERIOD_BYTES]) {
    let (out, inp) = b.split_at_mut(RECORD_BYTES);
    encode_record(r, out.try_into().expect("record bytes"));
    inp.fill(0);
    let i = &r.inputs;
    inp[0] = u8::from(i.from_cycle)
        | u8::from(i.deadline_overrun) << 1
        | u8::from(i.drives_read_ok) << 2
        | u8::from(i.tensions_read_ok) << 3
        | u8::from(i.surface_live) << 4
        | u8::from(i.ops.overflowed()) << 5
        | u8::from(i.angles_read_ok) << 6;
    inp[1] = match i.estop {
        EStopReading::Released => 0,
        EStopReading::Pressed => 1,
        EStopReading::Failed => 2,
    };
    inp[2] = match i.torque_write {
        TorqueWrite::NotWritten => 0,
        TorqueWrite::Written => 1,
        TorqueWrite::Failed => 2,
    };
    inp[3] = i.ops.as_slice().len() as u8;
    inp[4] = (0..WIREMAN_WIRES).fold(0, |bits, w| bits | u8::from(i.tensions_fresh[w]) << w);
    for (w, d) in i.drives.iter().enumerate() {
        let at = 8 + 24 * w;
        inp[at..at + 8].copy_from_slice(&d.position_counts.to_le_bytes());
        inp[at + 8..at + 16].copy_from_slice(&d.velocity_counts_per_s.to_le_bytes());
        inp[at + 16] = drive_state_code(d.state);
        inp[at + 18..at + 20].copy_from_slice(&d.error_code.to_le_bytes());
    }
    for (w, t) in i.tensions_read_n.iter().enumerate() {
        inp[80 + 8 * w..88 + 8 * w].copy_from_slice(&t.to_le_bytes());
    }
    for (k, op) in i.ops.as_slice().iter().enumerate() {
        inp[104 + 4 * k..108 + 4 * k].copy_from_slice(&op_bytes(*op));
    }
    // 0 = none (and in logs written before the field existed).
    let age = i.surface_frame_age_ns.map_or(0, |ns| ns.max(1));
    inp[FRAME_AGE_AT..FRAME_AGE_AT + 8].copy_from_slice(&age.to_le_bytes());
    for (k, a) in i.angles_rad.iter().enumerate() {
        inp[ANGLES_AT + 8 * k..ANGLES_AT + 8 * k + 8].copy_from_slice(&a.to_le_bytes());
    }
}

/// Where a period's inputs keep the surface's frame age.
const FRAME_AGE_AT: usize = 136;
/// Where a period's inputs keep the passive angles (azimuth, elevation; zero on devices
/// without angle sensors, and in logs written before the field existed).
const ANGLES_AT: usize = 144;

/// Decode a period encoded by [`encode_period`]; undefined codes are an error.
pub fn decode_period(b: &[u8; PERIOD_BYTES]) -> Result<CycleRecord, String> {
    let (out, inp) = b.split_at(RECORD_BYTES);
    let mut r = decode_record(out.try_into().expect("record bytes"));
    let flags = inp[0];
    if flags >> 7 != 0
        || inp[1] > 2
        || inp[2] > 2
        || usize::from(inp[3]) > CycleOps::CAPACITY
        || inp[4] >> WIREMAN_WIRES != 0
    {
        return Err(format!(
            "undefined input codes (flags {flags:#04x}, e-stop {}, torque write {}, operations {})",
            inp[1], inp[2], inp[3]
        ));
    }
    let mut drives = [DriveSample::default(); WIREMAN_WIRES];
    for (w, d) in drives.iter_mut().enumerate() {
        let at = 8 + 24 * w;
        d.position_counts = i64::from_le_bytes(inp[at..at + 8].try_into().expect("8"));
        d.velocity_counts_per_s = f64::from_le_bytes(inp[at + 8..at + 16].try_into().expect("8"));
        d.state = match inp[at + 16] {
            0 => DriveState::Disabled,
            1 => DriveState::Enabled,
            2 => DriveState::QuickStop,
            3 => DriveState::Fault,
            s => return Err(format!("undefined drive state {s}")),
        };
        d.error_code = u16::from_le_bytes(inp[at + 18..at + 20].try_into().expect("2"));
    }
    let mut ops = CycleOps::default();
    for k in 0..usize::from(inp[3]) {
        ops.push(op_from_bytes(
            inp[104 + 4 * k..108 + 4 * k].try_into().expect("4"),
        )?);
    }
    if flags & 32 != 0 {
        ops.set_overflowed();
    }
    r.inputs = CycleInputs {
        from_cycle: flags & 1 != 0,
        deadline_overrun: flags & 2 != 0,
        drives_read_ok: flags & 4 != 0,
        drives,
        tensions_read_ok: flags & 8 != 0,
        tensions_read_n: core::array::from_fn(|w| {
            f64::from_le_bytes(inp[80 + 8 * w..88 + 8 * w].try_into().expect("8"))
        }),
        tensions_fresh: core::array::from_fn(|w| inp[4] & (1 << w) != 0),
        estop: [
            EStopReading::Released,
            EStopReading::Pressed,
            EStopReading::Failed,
        ][usize::from(inp[1])],
        torque_write: [
            TorqueWrite::NotWritten,
            TorqueWrite::Written,
            TorqueWrite::Failed,
        ][usize::from(inp[2])],
        surface_live: flags & 16 != 0,
        surface_frame_age_ns: match u64::from_le_bytes(
            inp[FRAME_AGE_AT..FRAME_AGE_AT + 8].try_into().expect("8"),
        ) {
            0 => None,
            ns => Some(ns),
        },
        angles_read_ok: flags & 64 != 0,
        angles_rad: core::array::from_fn(|k| {
            f64::from_le_bytes(
                inp[ANGLES_AT + 8 * k..ANGLES_AT + 8 * k + 8]
                    .try_into()
                    .expect("8"),
            )
        }),
        ops,
    };
    Ok(r)
}

/// Encode a calibration frame's payload: the first period it applies to, the guides, the
/// encoder zeros, whether forces are rendered.
pub fn encode_calibration(from_cycle: u64, c: &CalibrationInForce) -> [u8; CALIBRATION_BYTES] {
    let mut b = [0u8; CALIBRATION_BYTES];
    b[0..8].copy_from_slice(&from_cycle.to_le_bytes());
    for (k, v) in c
        .guides_m
        .iter()
        .flatten()
        .chain(c.length_at_zero_m.iter())
        .enumerate()
    {
        b[8 + 8 * k..16 + 8 * k].copy_from_slice(&v.to_le_bytes());
    }
    b[104] = u8::from(c.calibrated);
    b
}

/// Decode a calibration frame's payload: (first period, calibration).
pub fn decode_calibration(
    b: &[u8; CALIBRATION_BYTES],
) -> Result<(u64, CalibrationInForce), String> {
    let f = |k: usize| f64::from_le_bytes(b[8 + 8 * k..16 + 8 * k].try_into().expect("8"));
    if b[104] > 1 {
        return Err(format!("undefined calibrated flag {}", b[104]));
    }
    Ok((
        u64::from_le_bytes(b[0..8].try_into().expect("8")),
        CalibrationInForce {
            guides_m: core::array::from_fn(|i| core::array::from_fn(|j| f(3 * i + j))),
            length_at_zero_m: core::array::from_fn(|i| f(9 + i)),
            calibrated: b[104] == 1,
        },
    ))
}

/// Encode an end frame's payload: u64 last period (all ones: none), u64 periods written, u64
/// periods dropped, u8 reason, 7 bytes reserved, then the reason's text (UTF-8).
pub fn encode_end(end: &SessionEnd) -> Vec<u8> {
    let (code, text) = match &end.reason {
        EndReason::Signal(name) => (1, name.as_str()),
        EndReason::StopRequest => (2, ""),
        EndReason::DurationElapsed => (3, ""),
        EndReason::FatalFault(what) => (4, what.as_str()),
    };
    let mut b = vec![0u8; END_FIXED_BYTES];
    b[0..8].copy_from_slice(&end.last_cycle.unwrap_or(u64::MAX).to_le_bytes());
    b[8..16].copy_from_slice(&end.periods.to_le_bytes());
    b[16..24].copy_from_slice(&end.dropped.to_le_bytes());
    b[24] = code;
    b.extend_from_slice(text.as_bytes());
    b
}

/// Decode an end frame's payload; an undefined reason or text that is not UTF-8 is an error.
pub fn decode_end(b: &[u8]) -> Result<SessionEnd, String> {
    if b.len() < END_FIXED_BYTES {
        return Err(format!("an end frame of {} bytes", b.len()));
    }
    let u64_at = |at: usize| u64::from_le_bytes(b[at..at + 8].try_into().expect("8 bytes"));
    let text = std::str::from_utf8(&b[END_FIXED_BYTES..])
        .map_err(|e| format!("an end frame's text: {e}"))?
        .to_string();
    let reason = match b[24] {
        1 => EndReason::Signal(text),
        2 => EndReason::StopRequest,
        3 => EndReason::DurationElapsed,
        4 => EndReason::FatalFault(text),
        k => return Err(format!("an end frame of undefined reason {k}")),
    };
    Ok(SessionEnd {
        reason,
        last_cycle: Some(u64_at(0)).filter(|&c| c != u64::MAX),
        periods: u64_at(8),
        dropped: u64_at(16),
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A period with every field set.
    pub(crate) fn sample(cycle: u64) -> CycleRecord {
        let mut ops = CycleOps::default();
        ops.push(CycleOp::ReleaseWire(Some(1)));
        ops.push(CycleOp::Trip(SafetyState::MinimumTension(
            SafetyReason::OverSpeed { wire: 2 },
        )));
        ops.push(CycleOp::ReleaseWire(None));
        ops.push(CycleOp::RequestStop);
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
            inputs: CycleInputs {
                from_cycle: true,
                deadline_overrun: true,
                drives_read_ok: true,
                drives: [
                    DriveSample {
                        position_counts: -123_456_789,
                        velocity_counts_per_s: 1234.5,
                        state: DriveState::Enabled,
                        error_code: 0,
                    },
                    DriveSample {
                        position_counts: 42,
                        velocity_counts_per_s: -0.25,
                        state: DriveState::Fault,
                        error_code: 0x7500,
                    },
                    DriveSample::default(),
                ],
                tensions_read_ok: false,
                tensions_read_n: [0.5, 1e300, -1.0],
                tensions_fresh: [true, false, true],
                estop: EStopReading::Failed,
                torque_write: TorqueWrite::Failed,
                surface_live: true,
                surface_frame_age_ns: Some(7_250_000),
                angles_read_ok: true,
                angles_rad: [0.25, -1.5],
                ops,
            },
        }
    }

    /// [`sample`] moving as a session's periods do: the thimble on a slow path, and the
    /// measured tensions (as read and as recorded), the torques and the velocities with noise
    /// of about a thousandth of their value in the low 40 bits of their mantissas.
    pub(crate) fn noisy_sample(cycle: u64) -> CycleRecord {
        let mut noise = cycle.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
        let mut noisy = |v: f64| {
            noise ^= noise << 13;
            noise ^= noise >> 7;
            noise ^= noise << 17;
            f64::from_bits(v.to_bits() ^ (noise & ((1 << 40) - 1)))
        };
        let t = cycle as f64 * 1e-3;
        let mut r = sample(cycle);
        r.position_m = [0.1 + 0.01 * t.sin(), 0.2, 0.3 - 0.001 * t];
        r.lengths_m = [0.3 + 0.001 * t, 0.31 - 0.001 * t, 0.32];
        r.tension_measured_n = r.tension_measured_n.map(&mut noisy);
        r.torque_nm = r.torque_nm.map(&mut noisy);
        r.velocity_m_s = r.velocity_m_s.map(&mut noisy);
        r.inputs.tensions_read_n = r.tension_measured_n;
        r
    }

    #[test]
    fn periods_round_trip_with_their_inputs() {
        let mut b = [0u8; PERIOD_BYTES];
        let r = sample(7);
        encode_period(&r, &mut b);
        assert_eq!(decode_period(&b).unwrap(), r);
        // A NaN read from a sensor comes back bit for bit.
        let mut nan = r;
        nan.inputs.tensions_read_n[1] = f64::from_bits(0x7ff8_0000_0000_1234);
        encode_period(&nan, &mut b);
        let back = decode_period(&b).unwrap().inputs.tensions_read_n[1];
        assert_eq!(back.to_bits(), 0x7ff8_0000_0000_1234);
        let n = CycleRecord {
            released_wire: -1,
            ..CycleRecord::default()
        };
        encode_period(&n, &mut b);
        assert_eq!(decode_period(&b).unwrap(), n);
        // The outputs alone are the record of version 1.
        let mut v1 = [0u8; RECORD_BYTES];
        encode_period(&r, &mut b);
        encode_record(&r, &mut v1);
        assert_eq!(v1[..], b[..RECORD_BYTES]);
        // Undefined codes are refused.
        encode_period(&r, &mut b);
        b[RECORD_BYTES + 1] = 9;
        assert!(decode_period(&b).unwrap_err().contains("e-stop 9"));
    }

    #[test]
    fn end_frames_round_trip_and_refuse_undefined_reasons() {
        for (reason, last_cycle) in [
            (EndReason::Signal("SIGTERM".into()), Some(41_999)),
            (EndReason::StopRequest, Some(0)),
            (EndReason::DurationElapsed, Some(u64::MAX - 1)),
            (
                EndReason::FatalFault("cannot start the control loop: enable failed".into()),
                None,
            ),
        ] {
            let end = SessionEnd {
                reason,
                last_cycle,
                periods: 42_000,
                dropped: 3,
            };
            let b = encode_end(&end);
            assert_eq!(decode_end(&b).unwrap(), end);
        }
        let mut b = encode_end(&SessionEnd {
            reason: EndReason::StopRequest,
            last_cycle: Some(7),
            periods: 8,
            dropped: 0,
        });
        assert_eq!(b.len(), END_FIXED_BYTES);
        assert!(decode_end(&b[..31]).unwrap_err().contains("31 bytes"));
        b[24] = 9;
        assert!(decode_end(&b).unwrap_err().contains("reason 9"));
        b[24] = 1;
        b.push(0xff);
        assert!(decode_end(&b).unwrap_err().contains("text"));
    }

    #[test]
    fn calibrations_round_trip() {
        let c = CalibrationInForce {
            guides_m: [[0.1, 0.2, 0.0], [-0.3, 0.25, 0.0], [0.0, -0.2, 0.001]],
            length_at_zero_m: [0.4, 0.41, 0.42],
            calibrated: true,
        };
        assert_eq!(
            decode_calibration(&encode_calibration(77, &c)).unwrap(),
            (77, c)
        );
    }
}
