//! The wire drives on one CAN bus, one per wire of an `N`-wire device, driven through CiA 402
//! cyclic synchronous torque mode: `impl WireDrives<N> + Lifecycle` over any [`CanPort`], for
//! every wire count `N` (the count comes from the configuration's node ids).
//!
//! Per control cycle ([`WireDrives::read_drives`] then [`WireDrives::write_torques`]):
//! stale frames are drained, SYNC is sent, the TPDOs of every drive are awaited until
//! `pdo_timeout`, heartbeats and EMCYs are checked, then the RPDOs (controlword + target
//! torque) are sent. Any failure latches an error, sends "disable voltage, zero torque" to every
//! drive (the safe state) and fails every later cycle until the set is deactivated and
//! reconfigured, or re-activated. The cycle methods allocate nothing and block only in the
//! bus receive, never past `pdo_timeout`.
//!
//! With [`DriveSetConfig::analog_input`] set, TPDO1 carries each drive's analog input (and its
//! statusword) in the velocity's place, and the velocity is derived from the positions of
//! successive SYNCs; every cycle the values that arrived with this cycle's TPDO1 are published
//! to the shared [`DriveAnalogInputs`] ([`Cia402DriveSet::analog_inputs`]).

use std::sync::Arc;
use std::time::{Duration, Instant};

use canopen_rs::nmt::NmtCommand;
use canopen_rs::sdo::{SdoEvent, SdoPayload};
use canopen_rs::{Address, DataType, EmergencyMessage, NodeId, SdoClient, Value};
use embedded_can::{Frame, Id, StandardId};
use videt_hal::{DriveSample, Lifecycle, LifecycleState, Transmission, WireDrives};

use super::analog::DriveAnalogInputs;
use super::config::{ConfigError, DriveSetConfig};
use super::error::DriveError;
use super::identity::{DriveIdentity, SharedStartupReport, StartupNote, StartupReport};
use super::pdo::{Command, DriveSetup, Motion, MotionWithAnalog, Status};
use super::state::{controlword, PowerGoal, PowerSequencer, PowerState};
use crate::can::CanPort;
use crate::canopen::cob::{self, classify, CobKind};
use crate::canopen::objects::{is_optional, is_pdo_mapping, means_absent, UNUSED_PDOS};

/// Most frames handled in one cycle (bounds the receive loop): 64, and 16 per drive beyond
/// four drives.
const fn max_frames_per_cycle(drives: usize) -> usize {
    if drives > 4 {
        16 * drives
    } else {
        64
    }
}
/// Fault-reset edges tried when enabling a faulted drive.
const MAX_FAULT_RESETS: u32 = 3;
/// COB-ID bit 31: the PDO is disabled.
const PDO_INVALID: u32 = 0x8000_0000;
/// The polarity object of CiA 402.
const POLARITY: u16 = 0x607E;
/// Its bit that negates the position (demand and actual values).
const POLARITY_POSITION: u8 = 1 << 7;
/// Its bit that negates the velocity (demand and actual values).
const POLARITY_VELOCITY: u8 = 1 << 6;

/// Bit of cyclic synchronous torque mode (10) in the supported drive modes (0x6502).
const CYCLIC_SYNCHRONOUS_TORQUE_BIT: u32 = 1 << 9;
/// NMT state byte of "operational".
const NMT_OPERATIONAL: u8 = 0x05;

/// Length of wire (m) for an encoder position: `length_at_zero - counts * metres_per_count`.
pub fn wire_length_m(t: &Transmission, length_at_zero_m: f64, position_counts: i64) -> f64 {
    length_at_zero_m - position_counts as f64 * t.metres_per_count()
}

/// What the host knows of one drive.
#[derive(Debug, Clone, Copy)]
struct NodeLink {
    id: u8,
    /// The wire this drive moves (its index in the configuration's node ids).
    wire: u8,
    last_heard: Instant,
    nmt_state: u8,
    booted: bool,
    rebooted: bool,
    emcy: Option<(u16, u8)>,
    motion: Motion,
    status: Status,
    analog_input: i16,
    got_motion: bool,
    got_status: bool,
    status_heard: Option<Instant>,
    missed: u32,
    /// Consecutive cycles this wire has wound faster than the trip speed.
    overspeed_cycles: u32,
    position_counts: i64,
    last_raw_position: Option<i32>,
    /// Without a velocity in TPDO1: the position (drive units, unwrapped) at a SYNC and when
    /// that SYNC was sent, and the velocity derived from the last two (drive units per second).
    velocity_base: Option<(i64, Instant)>,
    derived_velocity: f64,
    /// -1 when the set itself negates this drive's position and velocity (its encoder is
    /// reversed and the drive has no polarity object), else 1.
    encoder_sign: f64,
}

impl NodeLink {
    fn new(id: u8, wire: usize, now: Instant) -> NodeLink {
        NodeLink {
            id,
            wire: wire as u8,
            last_heard: now,
            nmt_state: 0xFF,
            booted: false,
            rebooted: false,
            emcy: None,
            motion: Motion::default(),
            status: Status::default(),
            analog_input: 0,
            got_motion: false,
            got_status: false,
            status_heard: None,
            missed: 0,
            overspeed_cycles: 0,
            position_counts: 0,
            last_raw_position: None,
            velocity_base: None,
            derived_velocity: 0.0,
            encoder_sign: 1.0,
        }
    }

    /// Unwrap a 32-bit position into the running count.
    fn track_position(&mut self, raw: i32) {
        let delta = match self.last_raw_position {
            Some(prev) => i64::from(raw.wrapping_sub(prev)),
            None => i64::from(raw),
        };
        self.position_counts += delta;
        self.last_raw_position = Some(raw);
    }

    /// Derive the velocity from the position sampled at the SYNC sent at `sync_at` and the
    /// one before (over the time between the two SYNCs, whatever the host's wake-ups).
    fn derive_velocity(&mut self, sync_at: Instant) {
        if let Some((base, base_at)) = self.velocity_base {
            let dt = sync_at.saturating_duration_since(base_at).as_secs_f64();
            if dt > 0.0 {
                self.derived_velocity = (self.position_counts - base) as f64 / dt;
            }
        }
        self.velocity_base = Some((self.position_counts, sync_at));
    }

    fn power_state(&self) -> PowerState {
        PowerState::from_statusword(self.status.statusword)
    }

    /// Whether this cycle's process data is in: the motion of this cycle, and the status of
    /// this cycle when it is synchronous (`status_every_sync`), or ever heard when it is
    /// event-driven (its age is checked against the heartbeat timeout).
    fn has_cycle_data(&self, status_every_sync: bool) -> bool {
        self.got_motion
            && if status_every_sync {
                self.got_status
            } else {
                self.status_heard.is_some()
            }
    }
}

/// `N` CiA 402 wire drives on one CAN port, wire `i` being the drive of node
/// `config().node_ids[i]`. Build with [`Cia402DriveSet::new`], which takes `N` from the
/// [`DriveSetConfig<N>`]; the per-wire state lives in fixed `[_; N]` arrays.
#[derive(Debug)]
pub struct Cia402DriveSet<P: CanPort, const N: usize> {
    port: P,
    cfg: DriveSetConfig<N>,
    nodes: [NodeLink; N],
    lifecycle: LifecycleState,
    latched: Option<DriveError>,
    host_heartbeat_due: Instant,
    operational_expected: bool,
    /// When the latest SYNC was sent: the one a TPDO1 answers (a late one is absorbed before
    /// the next SYNC goes out).
    sync_sent_at: Instant,
    epoch: Instant,
    analog: Option<Arc<DriveAnalogInputs<N>>>,
    /// Where each latched error is pushed for a non-RT reader to report, once one asked.
    fault_reports: Option<rtrb::Producer<DriveError>>,
    /// The identities and notes the configuration under way gathers.
    gathering: StartupReport,
    /// The identities and notes of the last configuration, for readers off the control thread.
    report: SharedStartupReport,
}

/// Latched errors a [`Cia402DriveSet`] holds for its reader before it drops newer ones.
pub const FAULT_REPORTS_CAPACITY: usize = 8;

impl<P: CanPort, const N: usize> Cia402DriveSet<P, N> {
    /// Take the port and a validated configuration of `N` drives (`N` is the length of
    /// [`DriveSetConfig::node_ids`]). Nothing is sent yet (`Unconfigured`).
    pub fn new(port: P, cfg: DriveSetConfig<N>) -> Result<Self, ConfigError> {
        cfg.validate()?;
        let analog = cfg.analog_input.map(|_| Arc::new(DriveAnalogInputs::new()));
        let now = Instant::now();
        let nodes = core::array::from_fn(|i| NodeLink::new(cfg.node_ids[i], i, now));
        Ok(Cia402DriveSet {
            port,
            cfg,
            nodes,
            lifecycle: LifecycleState::Unconfigured,
            latched: None,
            host_heartbeat_due: now,
            operational_expected: false,
            sync_sent_at: now,
            epoch: now,
            analog,
            fault_reports: None,
            gathering: StartupReport::default(),
            report: SharedStartupReport::default(),
        })
    }

    /// Give the port back.
    pub fn release(self) -> P {
        self.port
    }

    /// The port (for inspection; the set keeps using it).
    pub fn port(&self) -> &P {
        &self.port
    }

    /// The port, mutably (tests script the drives through it).
    #[cfg(test)]
    pub(crate) fn port_mut(&mut self) -> &mut P {
        &mut self.port
    }

    /// The configuration.
    pub fn config(&self) -> &DriveSetConfig<N> {
        &self.cfg
    }

    /// The drives' analog inputs, updated by every cycle, when
    /// [`DriveSetConfig::analog_input`] is set (`None` otherwise). Each wire's sample counter
    /// advances only for a TPDO1 that answered the current cycle's SYNC.
    pub fn analog_inputs(&self) -> Option<Arc<DriveAnalogInputs<N>>> {
        self.analog.clone()
    }

    /// From now on, every error that puts the set into its safe state is also pushed, as it is
    /// latched, to the returned queue: the control thread cannot say why it stopped (it does
    /// not format), a supervisor reading the queue can. The push is wait-free and allocates
    /// nothing; errors beyond [`FAULT_REPORTS_CAPACITY`] unread ones are dropped. A second call
    /// replaces the first queue.
    pub fn fault_reports(&mut self) -> rtrb::Consumer<DriveError> {
        let (producer, consumer) = rtrb::RingBuffer::new(FAULT_REPORTS_CAPACITY);
        self.fault_reports = Some(producer);
        consumer
    }

    /// The drives' identities and the optional objects they lack, as of the last
    /// configuration, shared: a service's supervisor logs them and puts them in its status.
    /// Updated by every configuration (not on the real-time path).
    pub fn startup_report(&self) -> SharedStartupReport {
        SharedStartupReport::clone(&self.report)
    }

    fn publish_startup_report(&mut self) {
        if let Ok(mut r) = self.report.lock() {
            let generation = r.generation + 1;
            *r = StartupReport {
                generation,
                ..core::mem::take(&mut self.gathering)
            };
        }
    }

    /// The error that put the set into its safe state, if any.
    pub fn latched_error(&self) -> Option<DriveError> {
        self.latched
    }

    /// The decoded power state of each drive (from the last statusword).
    pub fn power_states(&self) -> [PowerState; N] {
        core::array::from_fn(|i| self.nodes[i].power_state())
    }

    // ----- frame I/O -------------------------------------------------------------------

    fn bus_error(&self, e: &P::Error) -> DriveError {
        if self.port.is_bus_off() {
            DriveError::BusOff
        } else if let Some(errno) = P::os_error(e) {
            DriveError::BusIo { errno }
        } else {
            DriveError::Bus(embedded_can::Error::kind(e))
        }
    }

    fn send(&mut self, cob_id: u16, data: &[u8]) -> Result<(), DriveError> {
        // COB-IDs are built here from validated node ids: always below 0x800.
        let id = StandardId::new(cob_id).unwrap_or(StandardId::ZERO);
        let Some(frame) = P::Frame::new(id, data) else {
            return Err(DriveError::Bus(embedded_can::ErrorKind::Other));
        };
        self.port.transmit(&frame).map_err(|e| self.bus_error(&e))
    }

    fn receive(&mut self, timeout: Duration) -> Result<Option<P::Frame>, DriveError> {
        self.port
            .receive_timeout(timeout)
            .map_err(|e| self.bus_error(&e))
    }

    fn node_index(&self, id: u8) -> Option<usize> {
        self.nodes.iter().position(|n| n.id == id)
    }

    /// Book-keep one received frame. `fresh` marks frames of the current cycle (after SYNC).
    fn absorb(&mut self, frame: &P::Frame, fresh: bool, now: Instant) {
        let Id::Standard(id) = frame.id() else {
            return;
        };
        let data = frame.data();
        match classify(id.as_raw()) {
            CobKind::Heartbeat(n) => {
                let Some(i) = self.node_index(n) else { return };
                let node = &mut self.nodes[i];
                node.last_heard = now;
                if let [state] = data {
                    if *state == 0 {
                        node.booted = true;
                        if self.operational_expected {
                            node.rebooted = true;
                        }
                    }
                    node.nmt_state = state & 0x7F;
                }
            }
            CobKind::Emcy(n) => {
                let Some(i) = self.node_index(n) else { return };
                if let Ok(m) = EmergencyMessage::decode(data) {
                    self.nodes[i].emcy = if m.is_error_reset() {
                        None
                    } else {
                        Some((m.error_code, m.error_register.0))
                    };
                }
            }
            CobKind::Tpdo(0, n) => {
                let Some(i) = self.node_index(n) else { return };
                let sync_at = self.sync_sent_at;
                let node = &mut self.nodes[i];
                if self.cfg.analog_input.is_some() {
                    // Only the configured layout is accepted.
                    if let Some(m) = MotionWithAnalog::decode(data) {
                        node.track_position(m.position);
                        node.derive_velocity(sync_at);
                        node.status.statusword = m.statusword;
                        node.analog_input = m.analog_input;
                        node.got_motion |= fresh;
                        node.got_status |= fresh;
                        node.status_heard = Some(now);
                    }
                } else if let Some(m) = Motion::decode(data) {
                    node.track_position(m.position);
                    node.motion = m;
                    node.got_motion |= fresh;
                }
            }
            CobKind::Tpdo(1, n) => {
                let Some(i) = self.node_index(n) else { return };
                if let Some(status) = Status::decode(data) {
                    let node = &mut self.nodes[i];
                    node.status = status;
                    node.got_status |= fresh;
                    node.status_heard = Some(now);
                }
            }
            _ => {}
        }
    }

    // ----- the cycle -------------------------------------------------------------------

    /// SYNC, collect the TPDOs, check the drives. **RT**.
    fn exchange(&mut self, strict_faults: bool) -> Result<(), DriveError> {
        // Frames still queued belong to earlier cycles (late or unsolicited).
        for _ in 0..max_frames_per_cycle(N) {
            match self.receive(Duration::ZERO)? {
                Some(f) => self.absorb(&f, false, Instant::now()),
                None => break,
            }
        }
        for n in &mut self.nodes {
            n.got_motion = false;
            n.got_status = false;
        }
        let start = Instant::now();
        self.sync_sent_at = start;
        self.send(cob::SYNC, &[])?;
        if start >= self.host_heartbeat_due {
            let host = cob::HEARTBEAT_BASE + u16::from(self.cfg.host_node_id);
            self.send(host, &[NMT_OPERATIONAL])?;
            self.host_heartbeat_due =
                start + Duration::from_millis(u64::from(self.cfg.host_heartbeat_ms));
        }
        let deadline = start + self.cfg.pdo_timeout;
        let status_every_sync = self.cfg.analog_input.is_some();
        for _ in 0..max_frames_per_cycle(N) {
            if self
                .nodes
                .iter()
                .all(|n| n.has_cycle_data(status_every_sync))
            {
                break;
            }
            let now = Instant::now();
            if now >= deadline {
                break;
            }
            match self.receive(deadline - now)? {
                Some(f) => self.absorb(&f, true, Instant::now()),
                None => break,
            }
        }
        if let Some(analog) = &self.analog {
            for (wire, node) in self.nodes.iter().enumerate() {
                if node.got_status {
                    analog.publish(wire, node.analog_input);
                }
            }
        }
        self.check_nodes(strict_faults, Instant::now())
    }

    fn check_nodes(&mut self, strict_faults: bool, now: Instant) -> Result<(), DriveError> {
        let hb_timeout = self.cfg.drive_heartbeat_timeout;
        let max_missed = self.cfg.max_missed_cycles;
        let status_every_sync = self.cfg.analog_input.is_some();
        for node in &mut self.nodes {
            if node.rebooted {
                return Err(DriveError::NotOperational {
                    wire: node.wire,
                    node: node.id,
                    nmt_state: 0,
                });
            }
            if strict_faults {
                if let Some((code, register)) = node.emcy {
                    return Err(DriveError::Emergency {
                        wire: node.wire,
                        node: node.id,
                        code,
                        register,
                    });
                }
            }
            let silent = now.saturating_duration_since(node.last_heard);
            if silent > hb_timeout {
                return Err(DriveError::HeartbeatLost {
                    wire: node.wire,
                    node: node.id,
                    silent_ms: silent.as_millis() as u64,
                });
            }
            if node.nmt_state != NMT_OPERATIONAL {
                return Err(DriveError::NotOperational {
                    wire: node.wire,
                    node: node.id,
                    nmt_state: node.nmt_state,
                });
            }
            if node.has_cycle_data(status_every_sync) {
                node.missed = 0;
            } else {
                node.missed += 1;
                if node.missed > max_missed {
                    return Err(DriveError::PdoTimeout {
                        wire: node.wire,
                        node: node.id,
                        missed_cycles: node.missed,
                    });
                }
            }
            if strict_faults && node.power_state() == PowerState::Fault {
                return Err(DriveError::DriveFault {
                    wire: node.wire,
                    node: node.id,
                    error_code: node.status.error_code,
                });
            }
        }
        Ok(())
    }

    /// Latch `e`, command every drive off with zero torque, and return `e`. **RT**.
    fn fail(&mut self, e: DriveError) -> DriveError {
        if self.latched.is_none() {
            self.latched = Some(e);
            if let Some(reports) = self.fault_reports.as_mut() {
                // A full queue means an unread backlog: the newest error is the one dropped.
                let _ = reports.push(e);
            }
        }
        self.lifecycle = LifecycleState::Faulted;
        self.send_safe_commands();
        e
    }

    fn send_safe_commands(&mut self) {
        let off = Command {
            controlword: controlword::DISABLE_VOLTAGE,
            target_torque_permille: 0,
        }
        .encode();
        for i in 0..N {
            let cob = cob::RPDO_BASE[0] + u16::from(self.nodes[i].id);
            let _ = self.send(cob, &off);
        }
    }

    fn sample(&self, i: usize) -> DriveSample {
        let n = &self.nodes[i];
        let sign = n.encoder_sign;
        DriveSample {
            position_counts: (sign * n.position_counts as f64 * self.cfg.counts_per_position_unit)
                .round() as i64,
            velocity_counts_per_s: sign
                * if self.cfg.analog_input.is_some() {
                    n.derived_velocity * self.cfg.counts_per_position_unit
                } else {
                    f64::from(n.motion.velocity) * self.cfg.counts_per_s_per_velocity_unit
                },
            state: n.power_state().to_hal(),
            error_code: n.status.error_code,
        }
    }

    /// The torque actually sent for wire `i`: clamped to ±torque(t_max), cut when the wire
    /// already runs faster than the speed limit in the torque's direction; a winding speed
    /// above the trip speed for `overspeed_trip_cycles` cycles in a row is an error. **RT**.
    fn limited_torque(&mut self, i: usize, torque_nm: f64) -> Result<f64, DriveError> {
        if !torque_nm.is_finite() {
            return Err(DriveError::InvalidTorque { wire: i });
        }
        let limit = self.cfg.max_torque_nm();
        let t = torque_nm.clamp(-limit, limit);
        let speed = self
            .cfg
            .transmission
            .wire_speed(self.sample(i).velocity_counts_per_s);
        let max = self.cfg.max_wire_speed_m_per_s;
        // Only winding is driven by the motor: a wire wound in faster than the trip speed
        // despite the cut torque is a drive or encoder fault. Fast unwinding is the operator
        // pulling the thimble away, which the motor merely resists.
        let node = &mut self.nodes[i];
        if speed > max * self.cfg.overspeed_trip_factor {
            node.overspeed_cycles += 1;
            if node.overspeed_cycles >= self.cfg.overspeed_trip_cycles {
                return Err(DriveError::OverSpeed {
                    wire: i,
                    speed_mm_per_s: (speed * 1000.0) as i32,
                });
            }
        } else {
            node.overspeed_cycles = 0;
        }
        if speed.abs() > max && t * speed > 0.0 {
            return Ok(0.0);
        }
        Ok(t)
    }

    // ----- non-RT sequences --------------------------------------------------------------

    fn sdo(
        &mut self,
        i: usize,
        client: &mut SdoClient,
        first: SdoPayload,
        addr: Address,
    ) -> Result<Option<Value>, DriveError> {
        let node = self.nodes[i].id;
        let req = cob::SDO_REQUEST_BASE + u16::from(node);
        let resp = cob::SDO_RESPONSE_BASE + u16::from(node);
        let mut payload = first;
        loop {
            self.send(req, &payload)?;
            let deadline = Instant::now() + self.cfg.sdo_timeout;
            let answer = loop {
                let now = Instant::now();
                if now >= deadline {
                    return Err(DriveError::SdoTimeout {
                        wire: i as u8,
                        node,
                        index: addr.index,
                        subindex: addr.subindex,
                    });
                }
                let Some(f) = self.receive(deadline - now)? else {
                    continue;
                };
                match f.id() {
                    Id::Standard(id) if id.as_raw() == resp && f.data().len() == 8 => {
                        let mut p = [0u8; 8];
                        p.copy_from_slice(f.data());
                        break p;
                    }
                    _ => self.absorb(&f, false, Instant::now()),
                }
            };
            match client.on_response(&answer) {
                SdoEvent::Send(next) => payload = next,
                SdoEvent::Complete(v) => return Ok(v),
                SdoEvent::Aborted(code) => {
                    return Err(DriveError::SdoAbort {
                        wire: i as u8,
                        node,
                        index: addr.index,
                        subindex: addr.subindex,
                        code,
                    })
                }
            }
        }
    }

    fn sdo_write(&mut self, i: usize, addr: Address, value: Value) -> Result<(), DriveError> {
        let mut client = SdoClient::new(NodeId::new(self.nodes[i].id).unwrap_or(NodeId::BROADCAST));
        let first = client.write(addr, value);
        self.sdo(i, &mut client, first, addr).map(|_| ())
    }

    fn sdo_read(&mut self, i: usize, addr: Address, ty: DataType) -> Result<Value, DriveError> {
        let mut client = SdoClient::new(NodeId::new(self.nodes[i].id).unwrap_or(NodeId::BROADCAST));
        let first = client.read(addr, ty);
        self.sdo(i, &mut client, first, addr)?
            .ok_or(DriveError::SdoUnexpectedValue {
                wire: i as u8,
                node: self.nodes[i].id,
                index: addr.index,
            })
    }

    fn nmt(&mut self, command: NmtCommand, node: u8) -> Result<(), DriveError> {
        self.send(cob::NMT, &[command as u8, node])
    }

    fn configure_inner(&mut self) -> Result<(), DriveError> {
        self.operational_expected = false;
        self.latched = None;
        self.gathering = StartupReport::default();
        let now = Instant::now();
        for i in 0..N {
            self.nodes[i] = NodeLink::new(self.cfg.node_ids[i], i, now);
        }
        // Drain whatever is queued, then reset communication so every drive boots afresh.
        while self.receive(Duration::ZERO)?.is_some() {}
        for i in 0..N {
            self.nmt(NmtCommand::ResetCommunication, self.nodes[i].id)?;
        }
        let start = Instant::now();
        let deadline = start + self.cfg.boot_timeout;
        while !self.nodes.iter().all(|n| n.booted) {
            let now = Instant::now();
            if now >= deadline {
                let missing = self.nodes.iter().find(|n| !n.booted);
                return Err(DriveError::NeverBooted {
                    wire: missing.map_or(0, |n| n.wire),
                    node: missing.map_or(0, |n| n.id),
                    waited_ms: (now - start).as_millis() as u64,
                });
            }
            if let Some(f) = self.receive(deadline - now)? {
                self.absorb(&f, false, Instant::now());
            }
        }
        let max_permille = self
            .cfg
            .torque_to_permille(self.cfg.max_torque_nm())
            .unsigned_abs()
            .max(1);
        for i in 0..N {
            self.identify(i)?;
            if self.cfg.verify_rated_torque {
                self.check_rated_torque(i)?;
            }
            let setup = DriveSetup {
                node_id: self.nodes[i].id,
                host_node_id: self.cfg.host_node_id,
                drive_heartbeat_ms: self.cfg.drive_heartbeat_ms,
                host_silence_timeout_ms: self.cfg.host_silence_timeout_ms,
                comm_loss_reaction: self.cfg.comm_loss_reaction,
                max_torque_permille: max_permille,
                analog_input: self.cfg.analog_input,
                status_event_timer_ms: self.cfg.status_event_timer_ms,
            };
            for (addr, value) in setup.sdo_writes() {
                match self.sdo_write(i, addr, value) {
                    // An object the driver can do without (the drive-side torque limit, the
                    // status event timer, the communication-loss reaction): told, not fatal.
                    Err(DriveError::SdoAbort {
                        index,
                        subindex,
                        code,
                        ..
                    }) if means_absent(code) && is_optional(index, subindex) => {
                        self.note(i, index, subindex, code)
                    }
                    // A refused mapping entry names the object it was to carry.
                    Err(DriveError::SdoAbort {
                        index,
                        subindex,
                        code,
                        ..
                    }) if is_pdo_mapping(index) && subindex >= 1 => {
                        let entry = match value {
                            Value::Unsigned32(e) => e,
                            _ => 0,
                        };
                        return Err(DriveError::MappingRefused {
                            wire: i as u8,
                            node: self.nodes[i].id,
                            index,
                            subindex,
                            entry,
                            code,
                        });
                    }
                    r => r?,
                }
            }
            self.disable_unused_pdos(i)?;
            self.set_polarity(i)?;
        }
        // Host heartbeat first, so the drives' consumers start on a live host.
        self.host_heartbeat_due = Instant::now();
        for i in 0..N {
            self.nmt(NmtCommand::StartRemoteNode, self.nodes[i].id)?;
        }
        // Cycle until every drive is operational and has answered SYNC (each its own SYNC: a
        // drive late now and then is the supervision's business, not start-up's).
        for n in &mut self.nodes {
            n.status_heard = None;
        }
        let start = Instant::now();
        let status_every_sync = self.cfg.analog_input.is_some();
        let mut answered = [false; N];
        let mut last_err;
        loop {
            let cycle_start = Instant::now();
            for n in &mut self.nodes {
                n.missed = 0;
                n.overspeed_cycles = 0;
            }
            let outcome = self.exchange(false);
            for (a, n) in answered.iter_mut().zip(&self.nodes) {
                *a |= n.has_cycle_data(status_every_sync);
            }
            match outcome {
                Ok(()) if answered.iter().all(|&a| a) => break,
                Ok(()) => last_err = None,
                Err(e) => last_err = Some(e),
            }
            if cycle_start - start > self.cfg.boot_timeout {
                let silent = self
                    .nodes
                    .iter()
                    .zip(answered)
                    .find(|(_, a)| !a)
                    .map(|(n, _)| n);
                return Err(last_err.unwrap_or(DriveError::NoProcessData {
                    wire: silent.map_or(0, |n| n.wire),
                    node: silent.map_or(0, |n| n.id),
                    waited_ms: (cycle_start - start).as_millis() as u64,
                    motion: silent.is_some_and(|n| n.got_motion),
                    status: silent.is_some_and(|n| n.status_heard.is_some()),
                }));
            }
            self.sleep_rest_of_cycle(cycle_start);
        }
        self.operational_expected = true;
        Ok(())
    }

    /// Disable every PDO of drive `i` the driver does not use ([`UNUSED_PDOS`]) that its own
    /// configuration left enabled (a DCF may keep TPDO3 sending at every SYNC): its COB-ID is
    /// written back with the "invalid" bit set, the CAN-ID unchanged as CiA 301 requires. A
    /// drive without such a PDO has nothing to disable.
    fn disable_unused_pdos(&mut self, i: usize) -> Result<(), DriveError> {
        for comm in UNUSED_PDOS {
            let addr = Address::new(comm, 1);
            let cob = match self.sdo_read(i, addr, DataType::Unsigned32) {
                Ok(Value::Unsigned32(cob)) => cob,
                Ok(_) => continue,
                Err(DriveError::SdoAbort { code, .. }) if means_absent(code) => continue,
                Err(e) => return Err(e),
            };
            if cob & PDO_INVALID == 0 {
                self.sdo_write(i, addr, Value::Unsigned32(cob | PDO_INVALID))?;
            }
        }
        Ok(())
    }

    /// Drive `i`'s position and velocity polarity (0x607E bits 7 and 6, the other bits kept)
    /// as `encoder_reversed` says, at every start: the configuration decides the direction,
    /// whatever the drive kept from before. A drive without the object has its position and
    /// velocity negated by the set instead (and a note when that matters).
    fn set_polarity(&mut self, i: usize) -> Result<(), DriveError> {
        let reversed = self.cfg.encoder_reversed[i];
        let addr = Address::new(POLARITY, 0);
        let current = match self.sdo_read(i, addr, DataType::Unsigned8) {
            Ok(Value::Unsigned8(v)) => Some(v),
            Ok(_) => None,
            Err(DriveError::SdoAbort {
                index,
                subindex,
                code,
                ..
            }) if means_absent(code) => {
                if reversed {
                    self.note(i, index, subindex, code);
                }
                None
            }
            Err(e) => return Err(e),
        };
        let Some(current) = current else {
            self.nodes[i].encoder_sign = if reversed { -1.0 } else { 1.0 };
            return Ok(());
        };
        let bits = POLARITY_POSITION | POLARITY_VELOCITY;
        let wanted = if reversed {
            current | bits
        } else {
            current & !bits
        };
        if wanted != current {
            self.sdo_write(i, addr, Value::Unsigned8(wanted))?;
        }
        self.nodes[i].encoder_sign = 1.0;
        Ok(())
    }

    /// Remember that drive `i` lacks the optional object `index:subindex`.
    fn note(&mut self, i: usize, index: u16, subindex: u8, code: u32) {
        self.gathering.notes.push(StartupNote {
            wire: i as u8,
            node: self.nodes[i].id,
            index,
            subindex,
            code,
        });
    }

    /// Read an optional `u32` object of drive `i`: `None` (and a note) when the drive lacks it.
    fn read_optional_u32(
        &mut self,
        i: usize,
        index: u16,
        subindex: u8,
    ) -> Result<Option<u32>, DriveError> {
        match self.sdo_read(i, Address::new(index, subindex), DataType::Unsigned32) {
            Ok(Value::Unsigned32(v)) => Ok(Some(v)),
            Ok(_) => Err(DriveError::SdoUnexpectedValue {
                wire: i as u8,
                node: self.nodes[i].id,
                index,
            }),
            Err(DriveError::SdoAbort { code, .. }) if means_absent(code) => {
                self.note(i, index, subindex, code);
                Ok(None)
            }
            Err(e) => Err(e),
        }
    }

    /// Read drive `i`'s device type and identity; refuse a drive that is not a CiA 402 one or
    /// does not offer cyclic synchronous torque mode.
    fn identify(&mut self, i: usize) -> Result<(), DriveError> {
        let (wire, node) = (i as u8, self.nodes[i].id);
        let device_type = match self.sdo_read(i, Address::new(0x1000, 0), DataType::Unsigned32)? {
            Value::Unsigned32(v) => v,
            _ => {
                return Err(DriveError::SdoUnexpectedValue {
                    wire,
                    node,
                    index: 0x1000,
                })
            }
        };
        let mut identity = DriveIdentity {
            device_type,
            ..DriveIdentity::default()
        };
        if !identity.is_cia402() {
            return Err(DriveError::NotCia402 {
                wire,
                node,
                device_type,
            });
        }
        identity.vendor_id = self.read_optional_u32(i, 0x1018, 1)?;
        identity.product_code = self.read_optional_u32(i, 0x1018, 2)?;
        identity.revision = self.read_optional_u32(i, 0x1018, 3)?;
        identity.serial = self.read_optional_u32(i, 0x1018, 4)?;
        self.gathering.drives.push((wire, node, identity));
        if let Some(modes) = self.read_optional_u32(i, 0x6502, 0)? {
            if modes & CYCLIC_SYNCHRONOUS_TORQUE_BIT == 0 {
                return Err(DriveError::NoCyclicTorque {
                    wire,
                    node,
                    supported_modes: modes,
                });
            }
        }
        Ok(())
    }

    /// Compare drive `i`'s rated torque (0x6076) with the configuration's; a drive without
    /// 0x6076 cannot be checked: the configuration rules.
    fn check_rated_torque(&mut self, i: usize) -> Result<(), DriveError> {
        let unit = self.cfg.rated_torque_unit;
        let rated = unit.raw(self.cfg.rated_torque_nm);
        match self.read_optional_u32(i, 0x6076, 0)? {
            Some(v) if v != rated => Err(DriveError::RatedTorqueMismatch {
                wire: i as u8,
                node: self.nodes[i].id,
                drive_value: v,
                configured_value: rated,
                unit,
            }),
            _ => Ok(()),
        }
    }

    /// After a refused start: every drive commanded off with zero torque and back to
    /// pre-operational, so nothing is left enabled or exchanging process data. Errors of the
    /// bus are ignored: it may be why the start failed.
    fn leave_drives_off(&mut self) {
        self.send_safe_commands();
        for i in 0..N {
            let _ = self.nmt(NmtCommand::EnterPreOperational, self.nodes[i].id);
        }
    }

    fn sleep_rest_of_cycle(&self, cycle_start: Instant) {
        let end = cycle_start + self.cfg.control_period;
        let now = Instant::now();
        if end > now {
            std::thread::sleep(end - now);
        }
    }

    /// Run every drive's power sequencer to `goal`, cycling at the control period.
    fn power_sequence(&mut self, goal: PowerGoal) -> Result<(), DriveError> {
        let t0 = Instant::now();
        let now_ns = |t: Instant| t.duration_since(t0).as_nanos() as u64;
        let timeout_ns = self.cfg.power_timeout.as_nanos() as u64;
        let mut seq = [PowerSequencer::new(goal, 0, timeout_ns, MAX_FAULT_RESETS); N];
        for n in &mut self.nodes {
            n.emcy = None;
        }
        loop {
            let cycle_start = Instant::now();
            self.exchange(false)?;
            let mut all = true;
            for (i, sequencer) in seq.iter_mut().enumerate() {
                let step = sequencer
                    .step(self.nodes[i].status.statusword, now_ns(Instant::now()))
                    .map_err(|e| {
                        DriveError::from_power(
                            i as u8,
                            self.nodes[i].id,
                            e,
                            self.nodes[i].status.error_code,
                        )
                    })?;
                all &= step.reached;
                let cmd = Command {
                    controlword: step.controlword,
                    target_torque_permille: 0,
                };
                let cob = cob::RPDO_BASE[0] + u16::from(self.nodes[i].id);
                self.send(cob, &cmd.encode())?;
            }
            if all {
                return Ok(());
            }
            self.sleep_rest_of_cycle(cycle_start);
        }
    }
}

impl<P: CanPort, const N: usize> videt_hal::ErrorType for Cia402DriveSet<P, N> {
    type Error = DriveError;
}

impl<P: CanPort, const N: usize> Lifecycle for Cia402DriveSet<P, N> {
    /// Reset the drives' communication, wait for their boot-up, configure them over SDO
    /// (CST mode, PDO mapping, heartbeats, communication-loss reaction), start them and wait
    /// until every drive answers SYNC. Ends `Inactive`.
    fn configure(&mut self) -> Result<(), DriveError> {
        if self.lifecycle == LifecycleState::Active {
            return Err(DriveError::NotReady {
                state: self.lifecycle,
            });
        }
        let outcome = self.configure_inner();
        self.publish_startup_report();
        match outcome {
            Ok(()) => {
                self.lifecycle = LifecycleState::Inactive;
                Ok(())
            }
            Err(e) => {
                self.leave_drives_off();
                self.lifecycle = LifecycleState::Unconfigured;
                Err(e)
            }
        }
    }

    /// Walk every drive to "operation enabled" (resetting a latched fault). Ends `Active`.
    fn activate(&mut self) -> Result<(), DriveError> {
        match self.lifecycle {
            LifecycleState::Inactive | LifecycleState::Faulted => {}
            LifecycleState::Active => return Ok(()),
            state @ LifecycleState::Unconfigured => return Err(DriveError::NotReady { state }),
        }
        self.latched = None;
        match self.power_sequence(PowerGoal::Enabled) {
            Ok(()) => {
                self.lifecycle = LifecycleState::Active;
                Ok(())
            }
            Err(e) => Err(self.fail(e)),
        }
    }

    /// Walk every drive to "switch on disabled". Ends `Inactive`.
    fn deactivate(&mut self) -> Result<(), DriveError> {
        if self.lifecycle == LifecycleState::Unconfigured {
            return Ok(());
        }
        match self.power_sequence(PowerGoal::Disabled) {
            Ok(()) => {
                // The latched error stays readable until the next configure/activate.
                self.lifecycle = LifecycleState::Inactive;
                Ok(())
            }
            Err(e) => Err(self.fail(e)),
        }
    }

    fn lifecycle_state(&self) -> LifecycleState {
        self.lifecycle
    }
}

impl<P: CanPort, const N: usize> WireDrives<N> for Cia402DriveSet<P, N> {
    fn enable(&mut self) -> Result<(), DriveError> {
        self.activate()
    }

    fn disable(&mut self) -> Result<(), DriveError> {
        self.send_safe_commands();
        if self.lifecycle == LifecycleState::Active {
            self.lifecycle = LifecycleState::Inactive;
        }
        Ok(())
    }

    fn read_drives(&mut self, out: &mut [DriveSample; N]) -> Result<(), DriveError> {
        match self.lifecycle {
            LifecycleState::Unconfigured => {
                return Err(DriveError::NotReady {
                    state: self.lifecycle,
                })
            }
            LifecycleState::Faulted => {
                let _ = self.exchange(false);
                for (i, o) in out.iter_mut().enumerate() {
                    *o = self.sample(i);
                }
                self.send_safe_commands();
                return Err(self.latched.unwrap_or(DriveError::NotReady {
                    state: LifecycleState::Faulted,
                }));
            }
            LifecycleState::Inactive | LifecycleState::Active => {}
        }
        let strict = self.lifecycle == LifecycleState::Active;
        let r = self.exchange(strict);
        for (i, o) in out.iter_mut().enumerate() {
            *o = self.sample(i);
        }
        r.map_err(|e| self.fail(e))
    }

    fn write_torques(&mut self, torque_nm: &[f64; N]) -> Result<(), DriveError> {
        if self.lifecycle != LifecycleState::Active {
            if self.lifecycle == LifecycleState::Faulted {
                self.send_safe_commands();
                return Err(self.latched.unwrap_or(DriveError::NotReady {
                    state: self.lifecycle,
                }));
            }
            return Err(DriveError::NotReady {
                state: self.lifecycle,
            });
        }
        let mut permille = [0i16; N];
        for i in 0..N {
            match self.limited_torque(i, torque_nm[i]) {
                Ok(t) if self.cfg.motor_reversed[i] => {
                    permille[i] = self.cfg.torque_to_permille(-t)
                }
                Ok(t) => permille[i] = self.cfg.torque_to_permille(t),
                Err(e) => return Err(self.fail(e)),
            }
        }
        for (i, target) in permille.into_iter().enumerate() {
            let cmd = Command {
                controlword: controlword::ENABLE_OPERATION,
                target_torque_permille: target,
            };
            let cob = cob::RPDO_BASE[0] + u16::from(self.nodes[i].id);
            if let Err(e) = self.send(cob, &cmd.encode()) {
                return Err(self.fail(e));
            }
        }
        Ok(())
    }
}

impl<P: CanPort, const N: usize> Cia402DriveSet<P, N> {
    /// Seconds since the set was created (for logs).
    pub fn uptime_s(&self) -> f64 {
        self.epoch.elapsed().as_secs_f64()
    }
}
