//! The process data of a wire drive: fixed PDO layouts, their encoding/decoding (pure,
//! allocation-free), and the SDO writes that install them on a drive.
//!
//! - RPDO1 (host → drive, `0x200 + node`): controlword 0x6040 (u16), target torque 0x6071
//!   (i16, per mille of rated torque).
//! - TPDO1 (drive → host, `0x180 + node`), 8 bytes, one of two layouts:
//!   - position actual 0x6064 (i32), velocity actual 0x606C (i32) ([`Motion`]);
//!   - with the drive's analog input (e.g. a load-cell amplifier wired into the drive;
//!     [`AnalogInputObject`], default CiA 401 0x6401 sub 1): position actual (i32), statusword
//!     0x6041 (u16), the analog input (i16) ([`MotionWithAnalog`]). The host then derives the
//!     velocity from the positions sampled at successive SYNCs.
//! - TPDO2 (drive → host, `0x280 + node`): statusword 0x6041 (u16), error code 0x603F (u16).
//!
//! RPDO1 and TPDO1 are synchronous (transmission type 1): TPDO1 answers every SYNC, RPDO1 takes
//! effect at the next SYNC. TPDO2 is event-driven (type 255): sent when the status changes and,
//! on a drive with an event timer, at least every `status_event_timer_ms`. One 4-byte and one
//! 8-byte frame per drive and period ([`CYCLIC_DATA_LENGTHS`]) keep a classical CAN bus at
//! 1 Mbit/s within reach of a 1 kHz period for three drives
//! ([`DriveSetConfig::bus_traffic`](super::DriveSetConfig::bus_traffic)); a second synchronous
//! TPDO per drive would not fit.

use canopen_rs::{Address, Value};

/// Mapping entries (`index << 16 | sub << 8 | bits`).
pub mod mapping {
    /// Controlword, 16 bits.
    pub const CONTROLWORD: u32 = 0x6040_0010;
    /// Target torque, 16 bits.
    pub const TARGET_TORQUE: u32 = 0x6071_0010;
    /// Position actual value, 32 bits.
    pub const POSITION_ACTUAL: u32 = 0x6064_0020;
    /// Velocity actual value, 32 bits.
    pub const VELOCITY_ACTUAL: u32 = 0x606C_0020;
    /// Statusword, 16 bits.
    pub const STATUSWORD: u32 = 0x6041_0010;
    /// Error code, 16 bits.
    pub const ERROR_CODE: u32 = 0x603F_0010;
}

/// The 16-bit signed object a drive maps into TPDO2 after its status: its analog input.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct AnalogInputObject {
    /// Object index (0x2000..=0x9FFF: a manufacturer or profile object).
    pub index: u16,
    /// Subindex.
    pub subindex: u8,
}

impl AnalogInputObject {
    /// CiA 401 "read analog input 16-bit", first input: 0x6401 sub 1.
    pub const CIA401_FIRST: AnalogInputObject = AnalogInputObject {
        index: 0x6401,
        subindex: 1,
    };

    /// The PDO mapping entry (`index << 16 | subindex << 8 | 16 bits`).
    pub const fn mapping_entry(self) -> u32 {
        ((self.index as u32) << 16) | ((self.subindex as u32) << 8) | 0x10
    }
}

impl Default for AnalogInputObject {
    fn default() -> Self {
        AnalogInputObject::CIA401_FIRST
    }
}

/// Host → drive command (RPDO1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Command {
    /// Controlword (0x6040).
    pub controlword: u16,
    /// Target torque (0x6071), per mille of rated torque.
    pub target_torque_permille: i16,
}

impl Command {
    /// The 4 data bytes of RPDO1.
    pub fn encode(&self) -> [u8; 4] {
        let c = self.controlword.to_le_bytes();
        let t = self.target_torque_permille.to_le_bytes();
        [c[0], c[1], t[0], t[1]]
    }

    /// Decode RPDO1 data; `None` unless exactly 4 bytes.
    pub fn decode(data: &[u8]) -> Option<Command> {
        let d: [u8; 4] = data.try_into().ok()?;
        Some(Command {
            controlword: u16::from_le_bytes([d[0], d[1]]),
            target_torque_permille: i16::from_le_bytes([d[2], d[3]]),
        })
    }
}

/// Drive → host motion feedback (TPDO1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Motion {
    /// Position actual value (0x6064), drive position units.
    pub position: i32,
    /// Velocity actual value (0x606C), drive velocity units.
    pub velocity: i32,
}

impl Motion {
    /// The 8 data bytes of TPDO1.
    pub fn encode(&self) -> [u8; 8] {
        let mut out = [0u8; 8];
        out[..4].copy_from_slice(&self.position.to_le_bytes());
        out[4..].copy_from_slice(&self.velocity.to_le_bytes());
        out
    }

    /// Decode TPDO1 data; `None` unless exactly 8 bytes.
    pub fn decode(data: &[u8]) -> Option<Motion> {
        let d: [u8; 8] = data.try_into().ok()?;
        Some(Motion {
            position: i32::from_le_bytes([d[0], d[1], d[2], d[3]]),
            velocity: i32::from_le_bytes([d[4], d[5], d[6], d[7]]),
        })
    }
}

/// Drive → host status (TPDO2).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Status {
    /// Statusword (0x6041).
    pub statusword: u16,
    /// Error code (0x603F).
    pub error_code: u16,
}

impl Status {
    /// The 4 data bytes of TPDO2.
    pub fn encode(&self) -> [u8; 4] {
        let s = self.statusword.to_le_bytes();
        let e = self.error_code.to_le_bytes();
        [s[0], s[1], e[0], e[1]]
    }

    /// Decode TPDO2 data; `None` unless exactly 4 bytes.
    pub fn decode(data: &[u8]) -> Option<Status> {
        let d: [u8; 4] = data.try_into().ok()?;
        Some(Status {
            statusword: u16::from_le_bytes([d[0], d[1]]),
            error_code: u16::from_le_bytes([d[2], d[3]]),
        })
    }
}

/// Drive → host motion feedback with the status and the analog input (TPDO1 when the drive's
/// analog input is mapped).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct MotionWithAnalog {
    /// Position actual value (0x6064), drive position units.
    pub position: i32,
    /// Statusword (0x6041).
    pub statusword: u16,
    /// The analog input, raw 16-bit signed value as the drive reports it.
    pub analog_input: i16,
}

impl MotionWithAnalog {
    /// The 8 data bytes of this TPDO1.
    pub fn encode(&self) -> [u8; 8] {
        let mut out = [0u8; 8];
        out[..4].copy_from_slice(&self.position.to_le_bytes());
        out[4..6].copy_from_slice(&self.statusword.to_le_bytes());
        out[6..].copy_from_slice(&self.analog_input.to_le_bytes());
        out
    }

    /// Decode this TPDO1's data; `None` unless exactly 8 bytes.
    pub fn decode(data: &[u8]) -> Option<MotionWithAnalog> {
        let d: [u8; 8] = data.try_into().ok()?;
        Some(MotionWithAnalog {
            position: i32::from_le_bytes([d[0], d[1], d[2], d[3]]),
            statusword: u16::from_le_bytes([d[4], d[5]]),
            analog_input: i16::from_le_bytes([d[6], d[7]]),
        })
    }
}

/// Synchronous transmission type: every SYNC.
pub const SYNC_EVERY_CYCLE: u8 = 1;
/// Event-driven transmission type (device-profile specific: on change, and on the event timer).
pub const EVENT_DRIVEN: u8 = 255;

/// Data lengths of the frames the host and one drive exchange every control period, after the
/// SYNC (0 bytes) the host sends once for all drives: RPDO1 and TPDO1.
pub const CYCLIC_DATA_LENGTHS: [u8; 2] = [4, 8];

/// COB-ID bit 31: PDO disabled.
const PDO_INVALID: u32 = 0x8000_0000;

/// Communication settings written to a drive while it is pre-operational.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DriveSetup {
    /// Node id of the drive.
    pub node_id: u8,
    /// Node id the host's heartbeat is sent with.
    pub host_node_id: u8,
    /// The drive's heartbeat producer time (0x1017), ms.
    pub drive_heartbeat_ms: u16,
    /// How long the drive tolerates host silence (0x1016 consumer time), ms.
    pub host_silence_timeout_ms: u16,
    /// Communication-loss reaction (0x6007 abort connection option code): 1 fault,
    /// 2 disable voltage, 3 quick stop.
    pub comm_loss_reaction: i16,
    /// Drive-side maximum torque (0x6072), per mille of rated torque.
    pub max_torque_permille: u16,
    /// The analog input mapped into TPDO1 (with the position and the statusword, instead of
    /// the velocity), if any.
    pub analog_input: Option<AnalogInputObject>,
    /// Event timer of the event-driven TPDO2, ms: the status is sent at least this often (on a
    /// drive that has one).
    pub status_event_timer_ms: u16,
}

impl DriveSetup {
    /// The ordered SDO writes: heartbeat producer and consumer, communication-loss reaction,
    /// cyclic synchronous torque mode, maximum torque, and the three PDOs (each disabled,
    /// remapped, then re-enabled as CiA 301 requires); TPDO1 maps the analog input when one
    /// is configured.
    pub fn sdo_writes(&self) -> Vec<(Address, Value)> {
        let n = u32::from(self.node_id);
        let a = Address::new;
        let mut w = vec![
            (a(0x1017, 0), Value::Unsigned16(self.drive_heartbeat_ms)),
            (
                a(0x1016, 1),
                Value::Unsigned32(
                    (u32::from(self.host_node_id) << 16) | u32::from(self.host_silence_timeout_ms),
                ),
            ),
            (a(0x6007, 0), Value::Integer16(self.comm_loss_reaction)),
            (a(0x6060, 0), Value::Integer8(10)),
            (a(0x6072, 0), Value::Unsigned16(self.max_torque_permille)),
        ];
        let mut pdo = |comm: u16, map: u16, cob: u32, entries: &[u32], event_timer: Option<u16>| {
            w.push((a(comm, 1), Value::Unsigned32(PDO_INVALID | cob)));
            w.push((a(map, 0), Value::Unsigned8(0)));
            for (i, e) in entries.iter().enumerate() {
                w.push((a(map, i as u8 + 1), Value::Unsigned32(*e)));
            }
            w.push((a(map, 0), Value::Unsigned8(entries.len() as u8)));
            match event_timer {
                None => w.push((a(comm, 2), Value::Unsigned8(SYNC_EVERY_CYCLE))),
                Some(ms) => {
                    w.push((a(comm, 2), Value::Unsigned8(EVENT_DRIVEN)));
                    w.push((a(comm, 5), Value::Unsigned16(ms)));
                }
            }
            w.push((a(comm, 1), Value::Unsigned32(cob)));
        };
        pdo(
            0x1400,
            0x1600,
            0x200 + n,
            &[mapping::CONTROLWORD, mapping::TARGET_TORQUE],
            None,
        );
        match self.analog_input {
            None => pdo(
                0x1800,
                0x1A00,
                0x180 + n,
                &[mapping::POSITION_ACTUAL, mapping::VELOCITY_ACTUAL],
                None,
            ),
            Some(analog) => pdo(
                0x1800,
                0x1A00,
                0x180 + n,
                &[
                    mapping::POSITION_ACTUAL,
                    mapping::STATUSWORD,
                    analog.mapping_entry(),
                ],
                None,
            ),
        }
        pdo(
            0x1801,
            0x1A01,
            0x280 + n,
            &[mapping::STATUSWORD, mapping::ERROR_CODE],
            Some(self.status_event_timer_ms.max(1)),
        );
        w
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn encodes_little_endian_as_on_the_wire() {
        let c = Command {
            controlword: 0x000F,
            target_torque_permille: -2,
        };
        assert_eq!(c.encode(), [0x0F, 0x00, 0xFE, 0xFF]);
        let m = Motion::decode(&[0xFF, 0x11, 0, 0, 0x10, 0, 0, 0]).unwrap();
        assert_eq!((m.position, m.velocity), (0x11FF, 16));
        let s = Status::decode(&[0x18, 0x02, 0x10, 0x81]).unwrap();
        assert_eq!((s.statusword, s.error_code), (0x0218, 0x8110));
        assert_eq!(Status::decode(&[1, 2, 3]), None);
        assert_eq!(Motion::decode(&[0; 7]), None);
    }

    #[test]
    fn pdo_setup_disables_remaps_and_reenables_each_pdo() {
        let s = DriveSetup {
            node_id: 2,
            host_node_id: 0x7F,
            drive_heartbeat_ms: 10,
            host_silence_timeout_ms: 50,
            comm_loss_reaction: 2,
            max_torque_permille: 800,
            analog_input: None,
            status_event_timer_ms: 10,
        };
        let w = s.sdo_writes();
        assert_eq!(w[0], (Address::new(0x1017, 0), Value::Unsigned16(10)));
        assert_eq!(
            w[1],
            (Address::new(0x1016, 1), Value::Unsigned32(0x007F_0032))
        );
        assert_eq!(w[3], (Address::new(0x6060, 0), Value::Integer8(10)));
        let rpdo: Vec<_> = w.iter().filter(|(a, _)| a.index == 0x1400).collect();
        assert_eq!(rpdo[0].1, Value::Unsigned32(0x8000_0202));
        assert_eq!(rpdo.last().unwrap().1, Value::Unsigned32(0x202));
        assert!(w.contains(&(Address::new(0x1A01, 2), Value::Unsigned32(0x603F_0010))));
        assert!(!w.iter().any(|(a, _)| *a == Address::new(0x1A01, 3)));
        assert!(w.contains(&(Address::new(0x1A01, 0), Value::Unsigned8(2))));
    }

    #[test]
    fn the_analog_input_takes_the_velocitys_place_in_tpdo1_only_when_configured() {
        let plain = DriveSetup {
            node_id: 3,
            host_node_id: 0x7F,
            drive_heartbeat_ms: 10,
            host_silence_timeout_ms: 50,
            comm_loss_reaction: 2,
            max_torque_permille: 800,
            analog_input: None,
            status_event_timer_ms: 10,
        };
        let with = DriveSetup {
            analog_input: Some(AnalogInputObject::default()),
            ..plain
        };
        let of = |s: &DriveSetup, index: u16| -> Vec<(Address, Value)> {
            s.sdo_writes()
                .into_iter()
                .filter(|(a, _)| a.index == index || a.index == index + 0x200)
                .collect()
        };
        let a = Address::new;
        assert_eq!(
            of(&with, 0x1800),
            vec![
                (a(0x1800, 1), Value::Unsigned32(0x8000_0183)),
                (a(0x1A00, 0), Value::Unsigned8(0)),
                (a(0x1A00, 1), Value::Unsigned32(0x6064_0020)),
                (a(0x1A00, 2), Value::Unsigned32(0x6041_0010)),
                (a(0x1A00, 3), Value::Unsigned32(0x6401_0110)),
                (a(0x1A00, 0), Value::Unsigned8(3)),
                (a(0x1800, 2), Value::Unsigned8(SYNC_EVERY_CYCLE)),
                (a(0x1800, 1), Value::Unsigned32(0x183)),
            ]
        );
        assert!(of(&plain, 0x1800).contains(&(a(0x1A00, 2), Value::Unsigned32(0x606C_0020))));
        // TPDO2 is the event-driven status in both.
        let tpdo2 = vec![
            (a(0x1801, 1), Value::Unsigned32(0x8000_0283)),
            (a(0x1A01, 0), Value::Unsigned8(0)),
            (a(0x1A01, 1), Value::Unsigned32(0x6041_0010)),
            (a(0x1A01, 2), Value::Unsigned32(0x603F_0010)),
            (a(0x1A01, 0), Value::Unsigned8(2)),
            (a(0x1801, 2), Value::Unsigned8(EVENT_DRIVEN)),
            (a(0x1801, 5), Value::Unsigned16(10)),
            (a(0x1801, 1), Value::Unsigned32(0x283)),
        ];
        assert_eq!(of(&with, 0x1801), tpdo2);
        assert_eq!(of(&plain, 0x1801), tpdo2);
        // Everything else is the same with or without the analog input.
        let rest = |s: &DriveSetup| -> Vec<(Address, Value)> {
            s.sdo_writes()
                .into_iter()
                .filter(|(a, _)| a.index != 0x1A00)
                .collect()
        };
        assert_eq!(rest(&with), rest(&plain));
        let vendor = AnalogInputObject {
            index: 0x3160,
            subindex: 2,
        };
        assert_eq!(vendor.mapping_entry(), 0x3160_0210);
    }

    #[test]
    fn the_motion_with_analog_decodes_exactly_eight_bytes() {
        let m = MotionWithAnalog::decode(&[0xFF, 0x11, 0, 0, 0x37, 0x02, 0x18, 0xFC]).unwrap();
        assert_eq!(
            (m.position, m.statusword, m.analog_input),
            (0x11FF, 0x0237, -1000)
        );
        assert_eq!(m.encode(), [0xFF, 0x11, 0, 0, 0x37, 0x02, 0x18, 0xFC]);
        assert_eq!(MotionWithAnalog::decode(&[0; 6]), None);
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 256, rng_seed: proptest::test_runner::RngSeed::Fixed(402), ..ProptestConfig::default() })]
        #[test]
        fn pdo_codecs_round_trip(cw in any::<u16>(), t in any::<i16>(), p in any::<i32>(), v in any::<i32>(), sw in any::<u16>(), ec in any::<u16>(), ai in any::<i16>()) {
            let c = Command { controlword: cw, target_torque_permille: t };
            prop_assert_eq!(Command::decode(&c.encode()), Some(c));
            let m = Motion { position: p, velocity: v };
            prop_assert_eq!(Motion::decode(&m.encode()), Some(m));
            let s = Status { statusword: sw, error_code: ec };
            prop_assert_eq!(Status::decode(&s.encode()), Some(s));
            let x = MotionWithAnalog { position: p, statusword: sw, analog_input: ai };
            prop_assert_eq!(MotionWithAnalog::decode(&x.encode()), Some(x));
        }
    }
}
