//! A simulated CiA 402 drive node on the userspace CAN bus: the protocol twin of a real wire
//! drive, so the real driver code runs end to end without hardware.
//!
//! Speaks CiA 301 through `canopen-rs`'s device runtime (object dictionary served over SDO,
//! NMT, RPDO/TPDO configured from the dictionary, EMCY, heartbeat producer) plus what a CiA 402
//! drive adds: the power state machine driven by the controlword, cyclic synchronous torque
//! mode (target torque in per mille of rated torque 0x6076, applied at SYNC), a heartbeat
//! consumer with a communication-loss reaction (0x6007), and a motor given by a
//! [`MotorPlant`] so the twin's physics can be connected. The plant also gives each drive's
//! analog input ([`MotorPlant::analog_input`], e.g. a load-cell amplifier wired into the drive):
//! the node serves it as CiA 401 "read analog input 16-bit" 0x6401 sub 1 and as the EPOS4's
//! "analog input 1 voltage" 0x3160 sub 1, both mappable into a TPDO. Mapping an object the
//! dictionary lacks is refused with SDO abort 0x0604_0041, as a real drive does.
//!
//! Faults to inject at run time ([`NodeFaults`]): never boots, heartbeat stops, stays silent on
//! SYNC, an emergency with a latched fault; bus-level faults (drops, delay, bus-off) live in
//! [`crate::can_bus::BusFaults`].

use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

pub use canopen_rs::nmt::NmtState;
use canopen_rs::{Address, ErrorRegister, Node, NodeId, Value};
use embedded_can::{Frame, Id};

use crate::can_bus::{BusError, InProcessEndpoint, SimFrame};

mod bank;
pub use bank::{NodeView, SimDriveBank, SimPort, SteppedDriveBus};
pub mod dictionary;
pub use dictionary::{DriveDictionary, OD_CAPACITY};
mod motors;
pub use motors::{FreeMotorPlant, MotorPlant, SharedMotors};

/// Faults of one node, adjustable at run time from another thread.
#[derive(Debug, Default)]
pub struct NodeFaults {
    never_boot: AtomicBool,
    mute_heartbeat: AtomicBool,
    ignore_sync: AtomicBool,
    pending_emcy: AtomicU32,
    fault_cause: AtomicU32,
    reversed_motor: AtomicBool,
    reversed_encoder: AtomicBool,
}

impl NodeFaults {
    /// The node never sends its boot-up message and answers nothing.
    pub fn set_never_boot(&self, on: bool) {
        self.never_boot.store(on, Ordering::Relaxed);
    }
    /// The node stops producing its heartbeat.
    pub fn set_mute_heartbeat(&self, on: bool) {
        self.mute_heartbeat.store(on, Ordering::Relaxed);
    }
    /// The node stops answering SYNC (no TPDOs).
    pub fn set_ignore_sync(&self, on: bool) {
        self.ignore_sync.store(on, Ordering::Relaxed);
    }
    /// Raise an emergency `code` with a latched drive fault that persists until
    /// [`NodeFaults::clear_fault`] (then a fault reset clears it).
    pub fn raise_fault(&self, code: u16) {
        self.fault_cause.store(u32::from(code), Ordering::Relaxed);
        self.pending_emcy
            .store(0x1_0000 | u32::from(code), Ordering::Relaxed);
    }
    /// The drive's motor is wired to turn the other way: a positive torque unwinds the wire
    /// (a wiring mistake of the rig, as built).
    pub fn set_reversed_motor(&self, on: bool) {
        self.reversed_motor.store(on, Ordering::Relaxed);
    }
    /// The drive's encoder counts the other way: down as the wire winds in (a wiring mistake
    /// of the rig, as built).
    pub fn set_reversed_encoder(&self, on: bool) {
        self.reversed_encoder.store(on, Ordering::Relaxed);
    }
    /// Remove the cause of the fault.
    pub fn clear_fault(&self) {
        self.fault_cause.store(0, Ordering::Relaxed);
    }
    fn take_emcy(&self) -> Option<u16> {
        let v = self.pending_emcy.swap(0, Ordering::Relaxed);
        (v != 0).then_some(v as u16)
    }
    fn fault_code(&self) -> u16 {
        self.fault_cause.load(Ordering::Relaxed) as u16
    }
}

/// CiA 402 power state of the simulated drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DrivePower {
    /// Switch on disabled.
    SwitchOnDisabled,
    /// Ready to switch on.
    ReadyToSwitchOn,
    /// Switched on.
    SwitchedOn,
    /// Operation enabled.
    OperationEnabled,
    /// Quick stop active.
    QuickStopActive,
    /// Fault.
    Fault,
}

impl DrivePower {
    /// The statusword reporting this state (remote bit set; voltage-enabled when powered).
    pub const fn statusword(self) -> u16 {
        match self {
            DrivePower::SwitchOnDisabled => 0x0250,
            DrivePower::ReadyToSwitchOn => 0x0231,
            DrivePower::SwitchedOn => 0x0233,
            DrivePower::OperationEnabled => 0x0237,
            DrivePower::QuickStopActive => 0x0217,
            DrivePower::Fault => 0x0218,
        }
    }

    /// The drive side of the CiA 402 state machine: the state after controlword `cw`
    /// (`prev_cw` is the previous one, for the fault-reset edge; `fault_active` keeps a fault
    /// whose cause is still present).
    pub fn on_controlword(self, cw: u16, prev_cw: u16, fault_active: bool) -> DrivePower {
        use DrivePower::*;
        let reset_edge = cw & 0x80 != 0 && prev_cw & 0x80 == 0;
        if self == Fault {
            return if reset_edge && !fault_active {
                SwitchOnDisabled
            } else {
                Fault
            };
        }
        if cw & 0x80 != 0 {
            return self; // fault reset outside fault: no effect
        }
        let disable_voltage = cw & 0x02 == 0;
        let quick_stop = cw & 0x06 == 0x02;
        let shutdown = cw & 0x07 == 0x06;
        let switch_on = cw & 0x0F == 0x07;
        let enable = cw & 0x0F == 0x0F;
        match self {
            _ if disable_voltage => SwitchOnDisabled,
            OperationEnabled if quick_stop => QuickStopActive,
            QuickStopActive => QuickStopActive,
            _ if quick_stop => SwitchOnDisabled,
            SwitchOnDisabled if shutdown => ReadyToSwitchOn,
            SwitchedOn | OperationEnabled if shutdown => ReadyToSwitchOn,
            ReadyToSwitchOn if switch_on => SwitchedOn,
            ReadyToSwitchOn if enable => OperationEnabled,
            OperationEnabled if switch_on => SwitchedOn,
            SwitchedOn if enable => OperationEnabled,
            s => s,
        }
    }
}

/// Static description of a simulated drive.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimDriveSpec {
    /// CANopen node id.
    pub node_id: u8,
    /// Plant axis driven by this node.
    pub axis: usize,
    /// Motor rated torque (0x6076), mN·m.
    pub rated_torque_mnm: u32,
    /// Delay from power-up / reset to the boot-up message.
    pub boot_delay: Duration,
}

/// An integer object of the node's dictionary, whatever its integer type.
fn od_number(node: &Node<OD_CAPACITY>, index: u16, sub: u8) -> Option<i64> {
    Some(match node.od().entry(Address::new(index, sub))?.value {
        Value::Boolean(v) => i64::from(v),
        Value::Integer8(v) => i64::from(v),
        Value::Integer16(v) => i64::from(v),
        Value::Integer32(v) => i64::from(v),
        Value::Integer64(v) => v,
        Value::Unsigned8(v) => i64::from(v),
        Value::Unsigned16(v) => i64::from(v),
        Value::Unsigned32(v) => i64::from(v),
        Value::Unsigned64(v) => v as i64,
        _ => return None,
    })
}

fn od_u16(node: &Node<OD_CAPACITY>, index: u16, sub: u8) -> u16 {
    od_number(node, index, sub).unwrap_or(0) as u16
}

fn od_i16(node: &Node<OD_CAPACITY>, index: u16) -> i16 {
    od_number(node, index, 0).unwrap_or(0) as i16
}

/// One simulated CiA 402 drive.
#[derive(Debug)]
pub struct SimDriveNode {
    spec: SimDriveSpec,
    /// What the drive's dictionary holds and allows (its part's description, or the generic
    /// profile).
    dictionary: Arc<DriveDictionary>,
    node: Node<OD_CAPACITY>,
    power: DrivePower,
    last_controlword: u16,
    faults: Arc<NodeFaults>,
    boot_at: Option<Instant>,
    next_heartbeat: Instant,
    host_heard: Option<Instant>,
    comm_lost: bool,
    applied_torque_nm: f64,
    error_code: u16,
    event_tpdos: [EventTpdo; EVENT_TPDO_SLOTS],
}

/// TPDOs (0x1800 + n, n below this) a node may send event-driven.
const EVENT_TPDO_SLOTS: usize = 4;

/// What an event-driven TPDO last sent, and when.
#[derive(Debug, Clone, Copy, Default)]
struct EventTpdo {
    last: Option<([u8; 8], usize)>,
    sent_at: Option<Instant>,
}

impl SimDriveNode {
    /// A drive of the generic CiA 402 profile that powers up now (boot-up after
    /// `spec.boot_delay`), rated torque `spec.rated_torque_mnm`.
    pub fn new(spec: SimDriveSpec, faults: Arc<NodeFaults>) -> SimDriveNode {
        Self::with_dictionary(spec, faults, None)
    }

    /// A drive whose dictionary is `dictionary` (a part's description; the generic profile
    /// when `None`) that powers up now.
    pub fn with_dictionary(
        spec: SimDriveSpec,
        faults: Arc<NodeFaults>,
        dictionary: Option<Arc<DriveDictionary>>,
    ) -> SimDriveNode {
        let node_id = NodeId::new(spec.node_id).unwrap_or(NodeId::new(1).expect("1 is valid"));
        let dictionary =
            dictionary.unwrap_or_else(|| Arc::new(DriveDictionary::generic(spec.rated_torque_mnm)));
        let now = Instant::now();
        SimDriveNode {
            spec,
            node: Node::new(node_id, dictionary.build(spec.node_id)),
            dictionary,
            power: DrivePower::SwitchOnDisabled,
            last_controlword: 0,
            faults,
            boot_at: Some(now + spec.boot_delay),
            next_heartbeat: now,
            host_heard: None,
            comm_lost: false,
            applied_torque_nm: 0.0,
            error_code: 0,
            event_tpdos: [EventTpdo::default(); EVENT_TPDO_SLOTS],
        }
    }

    /// The node's CiA 402 power state.
    pub fn power(&self) -> DrivePower {
        self.power
    }

    /// The node's NMT state.
    pub fn nmt_state(&self) -> NmtState {
        self.node.state()
    }

    /// The torque the node applies to its motor now, N·m.
    pub fn applied_torque_nm(&self) -> f64 {
        self.applied_torque_nm
    }

    /// Read an object of the dictionary (as the drive sees it).
    pub fn read_object(&self, index: u16, sub: u8) -> Option<Value> {
        self.node
            .od()
            .entry(Address::new(index, sub))
            .map(|e| e.value)
    }

    /// Every object address the dictionary holds.
    pub fn object_addresses(&self) -> Vec<(u16, u8)> {
        self.dictionary
            .objects
            .iter()
            .map(|o| (o.index, o.subindex))
            .filter(|&(i, s)| self.node.od().entry(Address::new(i, s)).is_some())
            .collect()
    }

    /// The dictionary the drive was built from.
    pub fn dictionary(&self) -> &DriveDictionary {
        &self.dictionary
    }

    /// Set an integer object from the drive side, in the object's own integer type (a part's
    /// description decides it); an object the drive lacks is left alone.
    fn set(&mut self, index: u16, sub: u8, v: i64) {
        let addr = Address::new(index, sub);
        let Some(entry) = self.node.od().entry(addr) else {
            return;
        };
        let value = match entry.value {
            Value::Boolean(_) => Value::Boolean(v != 0),
            Value::Integer8(_) => Value::Integer8(v as i8),
            Value::Integer16(_) => Value::Integer16(v as i16),
            Value::Integer32(_) => Value::Integer32(v as i32),
            Value::Integer64(_) => Value::Integer64(v),
            Value::Unsigned8(_) => Value::Unsigned8(v as u8),
            Value::Unsigned16(_) => Value::Unsigned16(v as u16),
            Value::Unsigned32(_) => Value::Unsigned32(v as u32),
            Value::Unsigned64(_) => Value::Unsigned64(v as u64),
            _ => return,
        };
        let _ = self.node.od_mut().set(addr, value);
    }

    fn publish_status(&mut self) {
        let sw = self.power.statusword();
        self.set(0x6041, 0, i64::from(sw));
        if self.power != DrivePower::Fault {
            self.error_code = 0;
        }
        self.set(0x603F, 0, i64::from(self.error_code));
    }

    fn enter_fault(&mut self, code: u16, out: &mut impl FnMut(SimFrame)) {
        if self.power != DrivePower::Fault {
            self.error_code = code;
        }
        self.power = DrivePower::Fault;
        let f = self.node.raise_emergency(code, ErrorRegister(0x01), [0; 5]);
        if let Some(fr) = SimFrame::standard(f.cob_id, f.data()) {
            out(fr);
        }
        self.applied_torque_nm = 0.0;
        self.publish_status();
    }

    /// The torque the target torque (per mille of the rated torque 0x6076, in the
    /// dictionary's unit; the spec's when the drive has no 0x6076) asks for, N·m.
    fn torque_nm(&self) -> f64 {
        let rated_nm = match od_number(&self.node, 0x6076, 0) {
            Some(raw) => raw as f64 * self.dictionary.torque_unit_nm,
            None => f64::from(self.spec.rated_torque_mnm) / 1000.0,
        };
        f64::from(od_i16(&self.node, 0x6071)) / 1000.0 * rated_nm
    }

    /// Handle one received frame; frames to transmit go to `out`.
    pub fn on_frame(
        &mut self,
        frame: &SimFrame,
        plant: &mut dyn MotorPlant,
        out: &mut impl FnMut(SimFrame),
    ) {
        if self.boot_at.is_some() || self.faults.never_boot.load(Ordering::Relaxed) {
            return; // still initialising: deaf
        }
        let Id::Standard(id) = frame.id() else { return };
        let cob = id.as_raw();
        if cob == 0x080 {
            self.on_sync(plant, out);
            return;
        }
        if cob == 0x700 + u16::from(self.host_node_id()) && self.host_node_id() != 0 {
            // The host is back: a communication-loss fault may now be reset.
            self.host_heard = Some(Instant::now());
            self.comm_lost = false;
            return;
        }
        let sdo_active = matches!(
            self.node.state(),
            NmtState::PreOperational | NmtState::Operational
        );
        if sdo_active && cob == 0x600 + u16::from(self.spec.node_id) {
            // What the part's dictionary refuses, it refuses with CiA 301's code for the case.
            let data = frame.data();
            if let Some(code) = self.dictionary.check_sdo(data, self.node.od()) {
                let index = u16::from_le_bytes([data[1], data[2]]);
                let abort = dictionary::abort_frame(index, data[3], code);
                if let Some(fr) = SimFrame::standard(0x580 + u16::from(self.spec.node_id), &abort) {
                    out(fr);
                }
                return;
            }
        }
        let before = self.node.state();
        let reply = self.node.on_frame(cob, frame.data());
        if let Some(r) = reply {
            if let Some(fr) = SimFrame::standard(r.cob_id, r.data()) {
                out(fr);
            }
        }
        if let Some(addr) = self.node.take_written_object() {
            if (0x1400..=0x1BFF).contains(&addr.index) {
                self.node.configure_pdos_from_od();
            }
            if addr.index == 0x6060 {
                let m = od_number(&self.node, 0x6060, 0).unwrap_or(0);
                self.set(0x6061, 0, m);
            }
            if addr.index == 0x1016 {
                self.host_heard = None;
            }
        }
        if self.node.state() == NmtState::Initialising && before != NmtState::Initialising {
            // NMT reset node / communication: communication parameters back to defaults,
            // then a fresh boot-up. A latched fault survives (its cause is in the drive).
            self.reset_communication();
        }
        if self.node.state() != NmtState::Operational && before == NmtState::Operational {
            self.stop_motor(plant);
        }
    }

    fn host_node_id(&self) -> u8 {
        match self.node.od().read(Address::new(0x1016, 1)) {
            Ok(Value::Unsigned32(v)) => ((v >> 16) & 0x7F) as u8,
            _ => 0,
        }
    }

    fn host_timeout(&self) -> Option<Duration> {
        match self.node.od().read(Address::new(0x1016, 1)) {
            Ok(Value::Unsigned32(v)) if v & 0xFFFF != 0 => {
                Some(Duration::from_millis(u64::from(v & 0xFFFF)))
            }
            _ => None,
        }
    }

    fn reset_communication(&mut self) {
        self.event_tpdos = [EventTpdo::default(); EVENT_TPDO_SLOTS];
        let keep_fault = self.power == DrivePower::Fault;
        let node_id = self.node.node_id();
        self.node = Node::new(node_id, self.dictionary.build(self.spec.node_id));
        self.power = if keep_fault {
            DrivePower::Fault
        } else {
            DrivePower::SwitchOnDisabled
        };
        self.last_controlword = 0;
        self.host_heard = None;
        self.comm_lost = false;
        self.publish_status();
        self.boot_at = Some(Instant::now());
    }

    fn stop_motor(&mut self, plant: &mut dyn MotorPlant) {
        self.applied_torque_nm = 0.0;
        plant.apply_torque(self.spec.axis, 0.0);
    }

    fn on_sync(&mut self, plant: &mut dyn MotorPlant, out: &mut impl FnMut(SimFrame)) {
        if self.node.state() != NmtState::Operational {
            return;
        }
        // The RPDO received since the last SYNC takes effect now.
        let cw = od_u16(&self.node, 0x6040, 0);
        let fault_active = self.faults.fault_code() != 0 || self.comm_lost;
        let was_fault = self.power == DrivePower::Fault;
        self.power = self
            .power
            .on_controlword(cw, self.last_controlword, fault_active);
        self.last_controlword = cw;
        if was_fault && self.power != DrivePower::Fault {
            self.comm_lost = false;
            let f = self.node.clear_errors();
            if let Some(fr) = SimFrame::standard(f.cob_id, f.data()) {
                out(fr);
            }
        }
        let cst = od_number(&self.node, 0x6060, 0) == Some(10);
        let torque = if self.power == DrivePower::OperationEnabled && cst {
            self.torque_nm()
        } else {
            0.0
        };
        self.applied_torque_nm = torque;
        let sign = |reversed: &AtomicBool| {
            if reversed.load(Ordering::Relaxed) {
                -1.0
            } else {
                1.0
            }
        };
        plant.apply_torque(self.spec.axis, sign(&self.faults.reversed_motor) * torque);
        // Position and velocity in the dictionary's units (increments and increments/s by
        // CiA 402; e.g. rev/min on a drive whose description says so), in the direction the
        // polarity (0x607E bits 7 and 6, on a drive that has it) says.
        let (counts, cps) = plant.encoder(self.spec.axis);
        let encoder = sign(&self.faults.reversed_encoder);
        let polarity = od_number(&self.node, 0x607E, 0).unwrap_or(0);
        let flip = |bit: i64| if polarity & bit != 0 { -1.0 } else { 1.0 };
        let position =
            flip(0x80) * encoder * counts as f64 / self.dictionary.counts_per_position_unit;
        let velocity = flip(0x40) * encoder * cps / self.dictionary.counts_per_s_per_velocity_unit;
        self.set(0x6064, 0, i64::from(position.round() as i32));
        self.set(0x606C, 0, i64::from(velocity.round() as i32));
        let t_permille = if self.power == DrivePower::OperationEnabled {
            od_i16(&self.node, 0x6071)
        } else {
            0
        };
        self.set(0x6077, 0, i64::from(t_permille));
        let analog = i64::from(plant.analog_input(self.spec.axis));
        for (index, sub) in dictionary::ANALOG_INPUTS {
            self.set(index, sub, analog);
        }
        self.publish_status();
        if self.faults.ignore_sync.load(Ordering::Relaxed) {
            return;
        }
        for t in self.node.sync_tpdos() {
            if let Some(fr) = SimFrame::standard(t.cob_id, t.data()) {
                out(fr);
            }
        }
        self.send_event_tpdos(Instant::now(), out);
    }

    /// Event-driven TPDOs (transmission type 254/255): sent when their data changed, and
    /// when their event timer (sub 5, ms; absent or 0 = none) ran out since they were last
    /// sent.
    fn send_event_tpdos(&mut self, now: Instant, out: &mut impl FnMut(SimFrame)) {
        if self.node.state() != NmtState::Operational
            || self.faults.ignore_sync.load(Ordering::Relaxed)
        {
            return;
        }
        // The node numbers its configured TPDOs in order, skipping disabled ones.
        let mut slot = 0;
        for n in 0..EVENT_TPDO_SLOTS {
            let comm = 0x1800 + n as u16;
            let cob = match self.node.od().read(Address::new(comm, 1)) {
                Ok(Value::Unsigned32(v)) if v & 0x8000_0000 == 0 => v,
                _ => continue,
            };
            let this_slot = slot;
            slot += 1;
            let event_driven = matches!(
                self.node.od().read(Address::new(comm, 2)),
                Ok(Value::Unsigned8(254 | 255))
            );
            if !event_driven {
                continue;
            }
            let Some(t) = self.node.tpdo(this_slot) else {
                continue;
            };
            if u32::from(t.cob_id) != cob & 0x7FF {
                continue;
            }
            let timer = Duration::from_millis(u64::from(od_u16(&self.node, comm, 5)));
            let mut data = [0u8; 8];
            let len = t.data().len().min(8);
            data[..len].copy_from_slice(&t.data()[..len]);
            let state = &mut self.event_tpdos[n];
            let changed = state.last != Some((data, len));
            let due = !timer.is_zero() && state.sent_at.is_none_or(|at| now >= at + timer);
            if changed || due {
                if let Some(fr) = SimFrame::standard(t.cob_id, t.data()) {
                    out(fr);
                }
                state.last = Some((data, len));
                state.sent_at = Some(now);
            }
        }
    }

    /// Time-driven work: boot-up, heartbeat production, heartbeat consumer, injected faults.
    /// Returns when this node next needs a `poll`.
    pub fn poll(
        &mut self,
        now: Instant,
        plant: &mut dyn MotorPlant,
        out: &mut impl FnMut(SimFrame),
    ) -> Instant {
        if self.faults.never_boot.load(Ordering::Relaxed) {
            return now + Duration::from_millis(10);
        }
        if let Some(at) = self.boot_at {
            if now < at {
                return at;
            }
            self.boot_at = None;
            let f = self.node.boot();
            if let Some(fr) = SimFrame::standard(f.cob_id, f.data()) {
                out(fr);
            }
            self.next_heartbeat = now;
        }
        if let Some(code) = self.faults.take_emcy() {
            self.enter_fault(code, out);
            self.stop_motor(plant);
        }
        // Heartbeat consumer: a silent host triggers the communication-loss reaction.
        if let (Some(heard), Some(timeout)) = (self.host_heard, self.host_timeout()) {
            if !self.comm_lost && now.duration_since(heard) > timeout {
                self.comm_lost = true;
                let reaction = od_i16(&self.node, 0x6007);
                let f = self
                    .node
                    .raise_emergency(0x8130, ErrorRegister(0x10), [0; 5]);
                if let Some(fr) = SimFrame::standard(f.cob_id, f.data()) {
                    out(fr);
                }
                if self.power != DrivePower::Fault && reaction == 1 {
                    self.error_code = 0x8130;
                }
                self.power = match reaction {
                    _ if self.power == DrivePower::Fault => DrivePower::Fault,
                    1 => DrivePower::Fault,
                    3 if self.power == DrivePower::OperationEnabled => DrivePower::QuickStopActive,
                    0 => self.power,
                    _ => DrivePower::SwitchOnDisabled,
                };
                if self.power != DrivePower::Fault {
                    self.comm_lost = false;
                    self.host_heard = None;
                }
                self.stop_motor(plant);
                self.publish_status();
            }
        }
        let period_ms = od_u16(&self.node, 0x1017, 0);
        if period_ms == 0 {
            return now + Duration::from_millis(10);
        }
        if now >= self.next_heartbeat {
            if !self.faults.mute_heartbeat.load(Ordering::Relaxed) {
                let f = self.node.heartbeat();
                if let Some(fr) = SimFrame::standard(f.cob_id, f.data()) {
                    out(fr);
                }
            }
            self.next_heartbeat = now + Duration::from_millis(u64::from(period_ms));
        }
        self.send_event_tpdos(now, out);
        self.next_heartbeat.min(now + Duration::from_millis(5))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::can_bus::{BusFaults, InProcessBus};

    fn spec(id: u8) -> SimDriveSpec {
        SimDriveSpec {
            node_id: id,
            axis: 0,
            rated_torque_mnm: 100,
            boot_delay: Duration::from_millis(1),
        }
    }

    #[test]
    fn drive_state_machine_follows_the_cia402_transitions() {
        use DrivePower::*;
        assert_eq!(
            SwitchOnDisabled.on_controlword(0x06, 0, false),
            ReadyToSwitchOn
        );
        assert_eq!(
            ReadyToSwitchOn.on_controlword(0x07, 0x06, false),
            SwitchedOn
        );
        assert_eq!(
            SwitchedOn.on_controlword(0x0F, 0x07, false),
            OperationEnabled
        );
        assert_eq!(
            OperationEnabled.on_controlword(0x02, 0x0F, false),
            QuickStopActive
        );
        assert_eq!(
            QuickStopActive.on_controlword(0x00, 0x02, false),
            SwitchOnDisabled
        );
        assert_eq!(
            OperationEnabled.on_controlword(0x07, 0x0F, false),
            SwitchedOn
        );
        assert_eq!(Fault.on_controlword(0x80, 0x00, true), Fault);
        assert_eq!(Fault.on_controlword(0x80, 0x80, false), Fault);
        assert_eq!(Fault.on_controlword(0x80, 0x00, false), SwitchOnDisabled);
        assert_eq!(
            SwitchOnDisabled.on_controlword(0x0F, 0, false),
            SwitchOnDisabled
        );
    }

    #[test]
    fn node_boots_serves_sdo_and_answers_sync_with_mapped_tpdos() {
        let mut plant = FreeMotorPlant::new(1, 1e-5, 1e-5, 2000.0);
        let faults = Arc::new(NodeFaults::default());
        let mut node = SimDriveNode::new(spec(5), faults);
        let mut out = Vec::new();
        std::thread::sleep(Duration::from_millis(2));
        node.poll(Instant::now(), &mut plant, &mut |f| out.push(f));
        assert_eq!(out[0], SimFrame::standard(0x705, &[0]).unwrap(), "boot-up");
        out.clear();
        // SDO read of the device type, as in the traced boot sequence.
        let req = SimFrame::standard(0x605, &[0x40, 0x00, 0x10, 0, 0, 0, 0, 0]).unwrap();
        node.on_frame(&req, &mut plant, &mut |f| out.push(f));
        assert_eq!(
            out.pop().unwrap(),
            SimFrame::standard(0x585, &[0x43, 0x00, 0x10, 0x00, 0x92, 0x01, 0x02, 0x00]).unwrap()
        );
        // Map TPDO2 = statusword + error code, synchronous, then start and SYNC.
        let writes: [[u8; 8]; 6] = [
            [0x2F, 0x01, 0x1A, 0x00, 0, 0, 0, 0],
            [0x23, 0x01, 0x1A, 0x01, 0x10, 0x00, 0x41, 0x60],
            [0x23, 0x01, 0x1A, 0x02, 0x10, 0x00, 0x3F, 0x60],
            [0x2F, 0x01, 0x1A, 0x00, 2, 0, 0, 0],
            [0x2F, 0x01, 0x18, 0x02, 1, 0, 0, 0],
            [0x23, 0x01, 0x18, 0x01, 0x85, 0x02, 0, 0],
        ];
        for w in writes {
            node.on_frame(
                &SimFrame::standard(0x605, &w).unwrap(),
                &mut plant,
                &mut |f| out.push(f),
            );
            assert_eq!(out.pop().unwrap().data()[0], 0x60, "download acknowledged");
        }
        node.on_frame(
            &SimFrame::standard(0x000, &[0x01, 5]).unwrap(),
            &mut plant,
            &mut |f| out.push(f),
        );
        node.on_frame(
            &SimFrame::standard(0x080, &[]).unwrap(),
            &mut plant,
            &mut |f| out.push(f),
        );
        assert_eq!(
            out,
            vec![SimFrame::standard(0x285, &[0x50, 0x02, 0, 0]).unwrap()]
        );
    }

    #[test]
    fn an_event_driven_tpdo2_is_sent_when_the_status_changes_only() {
        let mut plant = FreeMotorPlant::new(1, 1e-5, 1e-5, 2000.0);
        let mut node = SimDriveNode::new(spec(5), Arc::new(NodeFaults::default()));
        let mut out = Vec::new();
        std::thread::sleep(Duration::from_millis(2));
        node.poll(Instant::now(), &mut plant, &mut |f| out.push(f));
        // Map TPDO2 = statusword + error code, event-driven (255), then start.
        let writes: [[u8; 8]; 6] = [
            [0x2F, 0x01, 0x1A, 0x00, 0, 0, 0, 0],
            [0x23, 0x01, 0x1A, 0x01, 0x10, 0x00, 0x41, 0x60],
            [0x23, 0x01, 0x1A, 0x02, 0x10, 0x00, 0x3F, 0x60],
            [0x2F, 0x01, 0x1A, 0x00, 2, 0, 0, 0],
            [0x2F, 0x01, 0x18, 0x02, 255, 0, 0, 0],
            [0x23, 0x01, 0x18, 0x01, 0x85, 0x02, 0, 0],
        ];
        let mut send = |node: &mut SimDriveNode, cob: u16, data: &[u8], out: &mut Vec<SimFrame>| {
            out.clear();
            node.on_frame(
                &SimFrame::standard(cob, data).unwrap(),
                &mut plant,
                &mut |f| out.push(f),
            );
        };
        for w in writes {
            send(&mut node, 0x605, &w, &mut out);
            assert_eq!(out[0].data()[0], 0x60, "download acknowledged");
        }
        // The event timer the EPOS4 lacks is absent here too: its download is refused.
        send(
            &mut node,
            0x605,
            &[0x2B, 0x01, 0x18, 0x05, 10, 0, 0, 0],
            &mut out,
        );
        assert_eq!(out[0].data()[0], 0x80, "abort");
        send(&mut node, 0x000, &[0x01, 5], &mut out);
        let status = |sw: u16| SimFrame::standard(0x285, &[sw as u8, (sw >> 8) as u8, 0, 0]);
        // First SYNC: the status is new; second: unchanged, nothing sent.
        send(&mut node, 0x080, &[], &mut out);
        assert_eq!(out, vec![status(0x0250).unwrap()]);
        send(&mut node, 0x080, &[], &mut out);
        assert!(out.is_empty(), "{out:?}");
        // "Shutdown" (written over SDO: RPDO1 is not mapped here): the state changes at the
        // next SYNC and the status goes out with it.
        send(
            &mut node,
            0x605,
            &[0x2B, 0x40, 0x60, 0x00, 0x06, 0, 0, 0],
            &mut out,
        );
        send(&mut node, 0x080, &[], &mut out);
        assert_eq!(out, vec![status(0x0231).unwrap()]);
    }

    #[test]
    fn the_extended_tpdo2_carries_the_plants_analog_input() {
        let mut plant = FreeMotorPlant::new(1, 1e-5, 1e-5, 2000.0);
        plant.set_analog_input(0, -1234);
        let mut node = SimDriveNode::new(spec(5), Arc::new(NodeFaults::default()));
        let mut out = Vec::new();
        std::thread::sleep(Duration::from_millis(2));
        node.poll(Instant::now(), &mut plant, &mut |f| out.push(f));
        out.clear();
        let sdo = |node: &mut SimDriveNode, plant: &mut FreeMotorPlant, w: [u8; 8]| {
            let mut out = Vec::new();
            node.on_frame(&SimFrame::standard(0x605, &w).unwrap(), plant, &mut |f| {
                out.push(f)
            });
            out.pop().unwrap()
        };
        // An object the dictionary lacks, or a length that is not the object's, is refused.
        let absent = sdo(
            &mut node,
            &mut plant,
            [0x23, 0x01, 0x1A, 0x03, 0x10, 0x01, 0x02, 0x64],
        );
        assert_eq!(absent.raw_id(), 0x585);
        assert_eq!(
            absent.data(),
            [0x80, 0x01, 0x1A, 0x03, 0x41, 0x00, 0x04, 0x06]
        );
        let wrong_length = sdo(
            &mut node,
            &mut plant,
            [0x23, 0x01, 0x1A, 0x03, 0x20, 0x01, 0x01, 0x64],
        );
        assert_eq!(wrong_length.data()[0], 0x80);
        // Map TPDO2 = statusword + error code + analog input 0x6401 sub 1.
        let writes: [[u8; 8]; 7] = [
            [0x2F, 0x01, 0x1A, 0x00, 0, 0, 0, 0],
            [0x23, 0x01, 0x1A, 0x01, 0x10, 0x00, 0x41, 0x60],
            [0x23, 0x01, 0x1A, 0x02, 0x10, 0x00, 0x3F, 0x60],
            [0x23, 0x01, 0x1A, 0x03, 0x10, 0x01, 0x01, 0x64],
            [0x2F, 0x01, 0x1A, 0x00, 3, 0, 0, 0],
            [0x2F, 0x01, 0x18, 0x02, 1, 0, 0, 0],
            [0x23, 0x01, 0x18, 0x01, 0x85, 0x02, 0, 0],
        ];
        for w in writes {
            assert_eq!(sdo(&mut node, &mut plant, w).data()[0], 0x60, "{w:x?}");
        }
        node.on_frame(
            &SimFrame::standard(0x000, &[0x01, 5]).unwrap(),
            &mut plant,
            &mut |f| out.push(f),
        );
        node.on_frame(
            &SimFrame::standard(0x080, &[]).unwrap(),
            &mut plant,
            &mut |f| out.push(f),
        );
        let [lo, hi] = (-1234i16).to_le_bytes();
        assert_eq!(
            out,
            vec![SimFrame::standard(0x285, &[0x50, 0x02, 0, 0, lo, hi]).unwrap()]
        );
        // The EPOS4's place of the same input serves the same value.
        assert_eq!(node.read_object(0x3160, 1), Some(Value::Integer16(-1234)));
    }

    #[test]
    fn shared_motors_carry_the_analog_inputs() {
        let m = Arc::new(SharedMotors::new(3));
        assert_eq!(m.analog_input(2), 0);
        m.publish_analog_input(2, 321);
        assert_eq!(MotorPlant::analog_input(&m, 2), 321);
        let shared = Arc::new(Mutex::new(FreeMotorPlant::new(2, 1e-5, 1e-5, 2000.0)));
        shared.lock().unwrap().set_analog_input(1, -7);
        assert_eq!(shared.analog_input(1), -7);
    }

    #[test]
    fn a_bank_on_the_in_process_bus_boots_its_nodes() {
        let faults = Arc::new(BusFaults::new(1));
        let mut eps = InProcessBus::with_endpoints(2, 64, faults);
        let host = eps.pop().unwrap();
        let drives = eps.pop().unwrap();
        let bank = SimDriveBank::spawn(
            drives,
            &[spec(1), spec(2)],
            FreeMotorPlant::new(1, 1e-5, 1e-5, 2000.0),
        );
        let mut host = host;
        let mut booted = vec![];
        let t0 = Instant::now();
        while booted.len() < 2 && t0.elapsed() < Duration::from_secs(2) {
            if let Some(f) = host.receive_timeout(Duration::from_millis(50)).unwrap() {
                if f.data() == [0] {
                    booted.push(f.raw_id());
                }
            }
        }
        booted.sort();
        assert_eq!(booted, vec![0x701, 0x702]);
        std::thread::sleep(Duration::from_millis(30));
        assert_eq!(bank.views()[0].nmt, NmtState::PreOperational);
    }
}
