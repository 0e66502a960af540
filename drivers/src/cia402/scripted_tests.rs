//! The drive set against a scripted drive on a recording port: the frames it puts on the bus,
//! frame by frame (SDO setup, NMT, fault-reset edge, controlwords), and the position unwrap;
//! for the WireMan's three wires and for other wire counts.

use std::collections::VecDeque;
use std::time::Duration;

use embedded_can::{Frame, Id};
use videt_hal::{DriveSample, Lifecycle, WireDrives};
use videt_sim::can_bus::{BusError, SimFrame};

use super::pdo::{Command, Motion, Status};
use super::{Cia402DriveSet, DriveSetConfig, PowerState};
use crate::can::CanPort;

/// The WireMan's wire count.
const WIRES: usize = 3;

/// A minimal scripted CiA 402 drive per node (nodes 1..=N): boots on reset, acknowledges every
/// SDO write, answers the device type 0x1000 as a CiA 402 drive's, the supported modes 0x6502
/// with cyclic synchronous torque, 0x6076 with 100 mN·m, the polarity 0x607E with 0 (and any
/// other read with 100), and
/// answers SYNC with a scripted position and, when
/// it changed since it was last sent (the event-driven TPDO2), its statusword.
struct ScriptedDrives<const N: usize> {
    sent: Vec<(u16, Vec<u8>)>,
    inbox: VecDeque<SimFrame>,
    statusword: [u16; N],
    error_code: [u16; N],
    positions: VecDeque<i32>,
    velocity: i32,
    last_cw: [u16; N],
    status_sent: [Option<(u16, u16)>; N],
}

impl<const N: usize> ScriptedDrives<N> {
    /// Whether `cob` is `base + node` of one of the nodes.
    fn of_node(cob: u16, base: u16) -> bool {
        cob > base && cob <= base + N as u16
    }

    fn push(&mut self, cob: u16, data: &[u8]) {
        self.inbox.push_back(SimFrame::standard(cob, data).unwrap());
    }

    fn react(&mut self, cob: u16, data: &[u8]) {
        match cob {
            0x000 if data[0] == 0x82 => self.push(0x700 + u16::from(data[1]), &[0]),
            0x080 => {
                // The script's last position holds once the script is played.
                let pos = if self.positions.len() > 1 {
                    self.positions.pop_front().unwrap_or(0)
                } else {
                    self.positions.front().copied().unwrap_or(0)
                };
                for n in 1..=N as u16 {
                    let i = n as usize - 1;
                    let m = Motion {
                        position: pos,
                        velocity: self.velocity,
                    };
                    self.push(0x180 + n, &m.encode());
                    let now = (self.statusword[i], self.error_code[i]);
                    if self.status_sent[i] != Some(now) {
                        let s = Status {
                            statusword: now.0,
                            error_code: now.1,
                        };
                        self.push(0x280 + n, &s.encode());
                        self.status_sent[i] = Some(now);
                    }
                    self.push(0x700 + n, &[0x05]);
                }
            }
            c if Self::of_node(c, 0x600) => {
                let mut r = [0u8; 8];
                r[1..4].copy_from_slice(&data[1..4]);
                if data[0] == 0x40 && u16::from_le_bytes([data[1], data[2]]) == 0x607E {
                    // The polarity, one byte: none.
                    r[0] = 0x4F;
                } else if data[0] == 0x40 {
                    r[0] = 0x43;
                    let value: u32 = match u16::from_le_bytes([data[1], data[2]]) {
                        0x1000 => 0x0002_0192,
                        0x6502 => 0x0000_0380,
                        _ => 100, // 0x6076 = 100 mN·m
                    };
                    r[4..].copy_from_slice(&value.to_le_bytes());
                } else {
                    r[0] = 0x60;
                }
                self.push(cob - 0x600 + 0x580, &r);
            }
            c if Self::of_node(c, 0x200) => {
                let i = usize::from(cob - 0x201);
                let cw = Command::decode(data).unwrap().controlword;
                let edge = cw & 0x80 != 0 && self.last_cw[i] & 0x80 == 0;
                self.statusword[i] = match (self.statusword[i], cw & 0x8F) {
                    (0x0218, _) if edge => 0x0250,
                    (0x0218, _) => 0x0218,
                    (_, 0x06) => 0x0231,
                    (0x0231, 0x07) => 0x0233,
                    (0x0233, 0x0F) | (0x0237, 0x0F) => 0x0237,
                    (_, c) if c & 0x02 == 0 => 0x0250,
                    (s, _) => s,
                };
                if self.statusword[i] != 0x0218 {
                    self.error_code[i] = 0;
                }
                self.last_cw[i] = cw;
            }
            _ => {}
        }
    }
}

impl<const N: usize> embedded_can::blocking::Can for ScriptedDrives<N> {
    type Frame = SimFrame;
    type Error = BusError;
    fn transmit(&mut self, f: &SimFrame) -> Result<(), BusError> {
        let Id::Standard(id) = f.id() else {
            panic!("extended id sent")
        };
        self.sent.push((id.as_raw(), f.data().to_vec()));
        self.react(id.as_raw(), f.data());
        Ok(())
    }
    fn receive(&mut self) -> Result<SimFrame, BusError> {
        self.inbox.pop_front().ok_or(BusError::Disconnected)
    }
}

impl<const N: usize> CanPort for ScriptedDrives<N> {
    fn receive_timeout(&mut self, _t: Duration) -> Result<Option<SimFrame>, BusError> {
        Ok(self.inbox.pop_front())
    }
}

fn drives(positions: &[i32]) -> ScriptedDrives<WIRES> {
    drives_for(positions)
}

/// `N` scripted drives, nodes 1..=N.
fn drives_for<const N: usize>(positions: &[i32]) -> ScriptedDrives<N> {
    // Node 1 boots into fault, as in the recorded trace (statusword 0x0218).
    let mut statusword = [0x0250; N];
    let mut error_code = [0; N];
    statusword[0] = 0x0218;
    error_code[0] = 0x81B0;
    ScriptedDrives {
        sent: vec![],
        inbox: VecDeque::new(),
        statusword,
        error_code,
        positions: positions.iter().copied().collect(),
        velocity: 0,
        last_cw: [0; N],
        status_sent: [None; N],
    }
}

fn config() -> DriveSetConfig<WIRES> {
    config_for()
}

/// The configuration of drives on nodes 1..=N.
fn config_for<const N: usize>() -> DriveSetConfig<N> {
    let node_ids = core::array::from_fn(|i| i as u8 + 1);
    let mut c = DriveSetConfig::new(node_ids, Duration::from_millis(1), 0.1, 40.0);
    c.drive_heartbeat_timeout = Duration::from_secs(1);
    c
}

#[test]
fn boot_setup_and_enable_put_the_expected_frames_on_the_bus() {
    let mut set = Cia402DriveSet::new(drives(&[]), config()).unwrap();
    set.configure().unwrap();
    set.activate().unwrap();
    let report = set.startup_report();
    let port = set.release();
    let sent = &port.sent;
    // Reset communication of each node first.
    assert_eq!(sent[0], (0x000, vec![0x82, 1]));
    assert_eq!(sent[2], (0x000, vec![0x82, 3]));
    // Node 1's SDO setup: device type and identity reads, the supported modes, the rated
    // torque, then CST mode among the writes.
    let sdo1: Vec<&Vec<u8>> = sent
        .iter()
        .filter(|(c, _)| *c == 0x601)
        .map(|(_, d)| d)
        .collect();
    let read = |index: u16, sub: u8| {
        let [lo, hi] = index.to_le_bytes();
        vec![0x40, lo, hi, sub, 0, 0, 0, 0]
    };
    let reads: Vec<_> = [
        (0x1000, 0),
        (0x1018, 1),
        (0x1018, 2),
        (0x1018, 3),
        (0x1018, 4),
        (0x6502, 0),
        (0x6076, 0),
    ]
    .into_iter()
    .map(|(i, s)| read(i, s))
    .collect();
    assert_eq!(
        sdo1[..7].iter().map(|d| (*d).clone()).collect::<Vec<_>>(),
        reads
    );
    let (wire, node, id) = report.lock().unwrap().drives[0];
    assert_eq!((wire, node), (0, 1));
    assert!(id.is_cia402(), "{id}");
    assert_eq!((id.device_type, id.vendor_id), (0x0002_0192, Some(100)));
    assert!(sdo1.contains(&&vec![0x2F, 0x60, 0x60, 0x00, 10, 0, 0, 0]));
    // The polarity read, and left alone: no encoder is configured reversed.
    assert!(sdo1.contains(&&read(0x607E, 0)));
    assert!(!sdo1.iter().any(|d| d[0] == 0x2F && d[1..3] == [0x7E, 0x60]));
    assert!(sdo1.contains(&&vec![0x23, 0x16, 0x10, 0x01, 50, 0, 0x7F, 0]));
    // NMT start after the setup, then SYNC.
    let start = sent
        .iter()
        .position(|f| f == &(0x000, vec![0x01, 1]))
        .unwrap();
    assert!(start > sent.iter().rposition(|(c, _)| *c == 0x601).unwrap());
    // Node 1 (booted in fault): fault-reset edge, shutdown, switch on, enable operation.
    let cws: Vec<u16> = sent
        .iter()
        .filter(|(c, _)| *c == 0x201)
        .map(|(_, d)| Command::decode(d).unwrap().controlword)
        .collect();
    // The event-driven status of the last node arrives after every node's TPDO1, when the
    // host has its cycle's data and stops waiting: the set sees it one cycle late and holds
    // "enable operation" two cycles longer than with a synchronous status.
    assert_eq!(cws, vec![0x80, 0x06, 0x07, 0x0F, 0x0F, 0x0F, 0x0F]);
    // Node 2 started from switch-on-disabled: no fault reset.
    let cws2: Vec<u16> = sent
        .iter()
        .filter(|(c, _)| *c == 0x202)
        .map(|(_, d)| Command::decode(d).unwrap().controlword)
        .collect();
    assert_eq!(cws2[..4], [0x06, 0x07, 0x0F, 0x0F]);
}

#[test]
fn positions_unwrap_across_the_32_bit_rollover_and_torques_are_per_mille() {
    // Enough idle SYNCs for configure and activate, then the rollover.
    let mut script = vec![i32::MAX - 10; 64];
    script.extend([i32::MIN + 10, i32::MIN + 1000]);
    let mut set = Cia402DriveSet::new(drives(&script), config()).unwrap();
    set.configure().unwrap();
    set.activate().unwrap();
    let mut out = [DriveSample::default(); WIRES];
    let mut positions = vec![];
    for _ in 0..80 {
        set.read_drives(&mut out).unwrap();
        positions.push(out[0].position_counts);
    }
    assert_eq!(positions[0], i64::from(i32::MAX) - 10, "{positions:?}");
    let last = *positions.last().unwrap();
    // MAX-10 -> MIN+10 is +21 counts; MIN+10 -> MIN+1000 is +990.
    assert_eq!(last, i64::from(i32::MAX) - 10 + 21 + 990);
    set.write_torques(&[0.0123, -0.05, 0.0]).unwrap();
    let port = set.release();
    let rpdo = |cob| {
        port.sent
            .iter()
            .rev()
            .find(|(c, _)| *c == cob)
            .map(|(_, d)| Command::decode(d).unwrap())
            .unwrap()
    };
    assert_eq!(rpdo(0x201).target_torque_permille, 123);
    // 0.05 N·m is above the 40 N limit (0.032 N·m): clamped to -320 per mille.
    assert_eq!(rpdo(0x202).target_torque_permille, -320);
    assert_eq!(rpdo(0x201).controlword, 0x0F);
}

#[test]
fn fast_unwinding_is_resisted_but_fast_winding_trips() {
    let t = videt_hal::Transmission::PAPER;
    let two_m_per_s = (2.0 / t.metres_per_count()) as i32;
    // The operator pulls the thimble away at 2 m/s: the winding torque still goes out.
    let mut d = drives(&[]);
    d.velocity = -two_m_per_s;
    let mut set = Cia402DriveSet::new(d, config()).unwrap();
    set.configure().unwrap();
    set.activate().unwrap();
    let mut out = [DriveSample::default(); WIRES];
    set.read_drives(&mut out).unwrap();
    set.write_torques(&[0.01; WIRES]).unwrap();
    let sent = &set.port().sent;
    let last = sent.iter().rev().find(|(c, _)| *c == 0x201).unwrap();
    assert_eq!(
        Command::decode(&last.1).unwrap().target_torque_permille,
        100
    );
    // Winding at 2 m/s (above 1.5 x 0.8 m/s) for three cycles in a row is a runaway: the
    // winding torque is cut at once, and the third cycle trips into the safe state.
    let mut d = drives(&[]);
    d.velocity = two_m_per_s;
    let mut set = Cia402DriveSet::new(d, config()).unwrap();
    set.configure().unwrap();
    set.activate().unwrap();
    for _ in 0..2 {
        set.read_drives(&mut out).unwrap();
        set.write_torques(&[0.01; WIRES]).unwrap();
        let last = set.port().sent.iter().rev().find(|(c, _)| *c == 0x201);
        assert_eq!(
            Command::decode(&last.unwrap().1)
                .unwrap()
                .target_torque_permille,
            0,
            "torque cut while the wire runs too fast"
        );
    }
    set.read_drives(&mut out).unwrap();
    let e = set.write_torques(&[0.01; WIRES]).unwrap_err();
    assert!(
        matches!(e, super::DriveError::OverSpeed { wire: 0, .. }),
        "{e}"
    );
    assert_eq!(set.lifecycle_state(), videt_hal::LifecycleState::Faulted);
    let last = set
        .port()
        .sent
        .iter()
        .rev()
        .find(|(c, _)| *c == 0x201)
        .unwrap();
    assert_eq!(
        Command::decode(&last.1).unwrap(),
        Command::default(),
        "disable voltage, zero torque"
    );
}

#[test]
fn a_single_fast_sample_between_normal_ones_does_not_trip() {
    let t = videt_hal::Transmission::PAPER;
    let two_m_per_s = (2.0 / t.metres_per_count()) as i32;
    let mut set = Cia402DriveSet::new(drives(&[]), config()).unwrap();
    set.configure().unwrap();
    set.activate().unwrap();
    let mut out = [DriveSample::default(); WIRES];
    // Two glitches, each followed by a normal sample: never three in a row.
    for velocity in [two_m_per_s, two_m_per_s, 0, two_m_per_s, two_m_per_s, 0] {
        set.port_mut().velocity = velocity;
        set.read_drives(&mut out).unwrap();
        set.write_torques(&[0.01; WIRES]).unwrap();
    }
    assert_eq!(set.lifecycle_state(), videt_hal::LifecycleState::Active);
}

/// Boot, set up and enable `N` scripted drives, then run cycles: every node is reset, set up
/// and started, the faulted first one reset, and each wire's torque goes to its own node.
fn boot_enable_and_command<const N: usize>() {
    let mut script = vec![0; 64];
    script.extend([100, 250]);
    let mut set = Cia402DriveSet::new(drives_for::<N>(&script), config_for::<N>()).unwrap();
    set.configure().unwrap();
    set.activate().unwrap();
    assert_eq!(set.power_states(), [PowerState::OperationEnabled; N]);
    let mut out = [DriveSample::default(); N];
    for _ in 0..70 {
        set.read_drives(&mut out).unwrap();
    }
    assert!(out.iter().all(|s| s.position_counts == 250), "{out:?}");
    assert!(out
        .iter()
        .all(|s| s.state == videt_hal::DriveState::Enabled));
    // Wire i: (i + 1) per mille of the 0.1 N·m rated torque, alternating in sign.
    let torque: [f64; N] =
        core::array::from_fn(|i| (i as f64 + 1.0) * 1e-4 * if i % 2 == 0 { 1.0 } else { -1.0 });
    set.write_torques(&torque).unwrap();
    let port = set.release();
    let sent = &port.sent;
    for node in 1..=N as u16 {
        assert!(
            sent.contains(&(0x000, vec![0x82, node as u8])),
            "reset of node {node}"
        );
        assert!(
            sent.contains(&(0x000, vec![0x01, node as u8])),
            "start of node {node}"
        );
        assert!(
            sent.iter().any(|(c, _)| *c == 0x600 + node),
            "SDO to {node}"
        );
        let last = sent.iter().rev().find(|(c, _)| *c == 0x200 + node).unwrap();
        let cmd = Command::decode(&last.1).unwrap();
        let i = i16::try_from(node).unwrap();
        assert_eq!(
            cmd.target_torque_permille,
            if i % 2 == 1 { i } else { -i },
            "node {node}"
        );
        assert_eq!(cmd.controlword, 0x0F);
    }
    // Only node 1 booted in fault: it alone got the fault-reset edge.
    let resets: Vec<u16> = sent
        .iter()
        .filter(|(c, d)| {
            (0x201..0x280).contains(c) && Command::decode(d).unwrap().controlword == 0x80
        })
        .map(|(c, _)| c - 0x200)
        .collect();
    assert_eq!(resets, vec![1]);
    // Nothing addressed a node beyond the N configured.
    let beyond = N as u16 + 1;
    assert!(!sent.iter().any(|(c, d)| *c == 0x200 + beyond
        || *c == 0x600 + beyond
        || (*c == 0 && d[1] == beyond as u8)));
}

#[test]
fn one_two_and_four_scripted_drives_boot_enable_and_take_their_torques() {
    boot_enable_and_command::<1>();
    boot_enable_and_command::<2>();
    boot_enable_and_command::<WIRES>();
    boot_enable_and_command::<4>();
}

#[test]
fn a_two_wire_set_trips_on_overspeed_and_stops_both_drives() {
    let t = videt_hal::Transmission::PAPER;
    let two_m_per_s = (2.0 / t.metres_per_count()) as i32;
    let mut set = Cia402DriveSet::new(drives_for::<2>(&[]), config_for::<2>()).unwrap();
    set.configure().unwrap();
    set.activate().unwrap();
    set.port_mut().velocity = two_m_per_s;
    let mut out = [DriveSample::default(); 2];
    let mut result = Ok(());
    for _ in 0..3 {
        set.read_drives(&mut out).unwrap();
        // Both wires wind at 2 m/s: the third cycle in a row trips, on the first wire.
        result = set.write_torques(&[0.01, 0.01]);
    }
    let e = result.unwrap_err();
    assert!(
        matches!(e, super::DriveError::OverSpeed { wire: 0, .. }),
        "{e}"
    );
    assert_eq!(set.lifecycle_state(), videt_hal::LifecycleState::Faulted);
    // Both drives got the safe command.
    for cob in [0x201, 0x202] {
        let last = set.port().sent.iter().rev().find(|(c, _)| *c == cob);
        assert_eq!(
            Command::decode(&last.unwrap().1).unwrap(),
            Command::default()
        );
    }
}
