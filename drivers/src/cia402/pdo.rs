//! The process data of a wire drive: fixed PDO layouts, their encoding/decoding (pure,
//! allocation-free), and the SDO writes that install them on a drive.
//!
//! - RPDO1 (host → drive, `0x200 + node`): controlword 0x6040 (u16), target torque 0x6071
//!   (i16, per mille of rated torque).
//! - TPDO1 (drive → host, `0x180 + node`): position actual 0x6064 (i32), velocity actual
//!   0x606C (i32).
//! - TPDO2 (drive → host, `0x280 + node`): statusword 0x6041 (u16), error code 0x603F (u16),
//!   and optionally one 16-bit signed analog input (e.g. a load-cell amplifier wired into the
//!   drive; [`AnalogInputObject`], default CiA 401 0x6401 sub 1): 4 or 6 bytes.
//!
//! All are synchronous (transmission type 1): TPDOs answer every SYNC, RPDOs take effect at the
//! next SYNC.

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

/// Drive → host status with the drive's analog input (TPDO2 extended by an
/// [`AnalogInputObject`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct StatusWithAnalog {
    /// Statusword and error code.
    pub status: Status,
    /// The analog input, raw 16-bit signed value as the drive reports it.
    pub analog_input: i16,
}

impl StatusWithAnalog {
    /// The 6 data bytes of the extended TPDO2.
    pub fn encode(&self) -> [u8; 6] {
        let s = self.status.encode();
        let a = self.analog_input.to_le_bytes();
        [s[0], s[1], s[2], s[3], a[0], a[1]]
    }

    /// Decode extended TPDO2 data; `None` unless exactly 6 bytes.
    pub fn decode(data: &[u8]) -> Option<StatusWithAnalog> {
        let d: [u8; 6] = data.try_into().ok()?;
        Some(StatusWithAnalog {
            status: Status::decode(&d[..4])?,
            analog_input: i16::from_le_bytes([d[4], d[5]]),
        })
    }
}

/// Synchronous transmission type: every SYNC.
pub const SYNC_EVERY_CYCLE: u8 = 1;
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
    /// The analog input mapped into TPDO2 after the status, if any.
    pub analog_input: Option<AnalogInputObject>,
}

impl DriveSetup {
    /// The ordered SDO writes: heartbeat producer and consumer, communication-loss reaction,
    /// cyclic synchronous torque mode, maximum torque, and the three PDOs (each disabled,
    /// remapped, then re-enabled as CiA 301 requires); TPDO2 maps the analog input only when
    /// one is configured.
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
        let mut pdo = |comm: u16, map: u16, cob: u32, entries: &[u32]| {
            w.push((a(comm, 1), Value::Unsigned32(PDO_INVALID | cob)));
            w.push((a(map, 0), Value::Unsigned8(0)));
            for (i, e) in entries.iter().enumerate() {
                w.push((a(map, i as u8 + 1), Value::Unsigned32(*e)));
            }
            w.push((a(map, 0), Value::Unsigned8(entries.len() as u8)));
            w.push((a(comm, 2), Value::Unsigned8(SYNC_EVERY_CYCLE)));
            w.push((a(comm, 1), Value::Unsigned32(cob)));
        };
        pdo(
            0x1400,
            0x1600,
            0x200 + n,
            &[mapping::CONTROLWORD, mapping::TARGET_TORQUE],
        );
        pdo(
            0x1800,
            0x1A00,
            0x180 + n,
            &[mapping::POSITION_ACTUAL, mapping::VELOCITY_ACTUAL],
        );
        let tpdo2 = [
            mapping::STATUSWORD,
            mapping::ERROR_CODE,
            self.analog_input
                .map_or(0, AnalogInputObject::mapping_entry),
        ];
        let tpdo2_len = if self.analog_input.is_some() { 3 } else { 2 };
        pdo(0x1801, 0x1A01, 0x280 + n, &tpdo2[..tpdo2_len]);
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
    fn the_analog_input_is_mapped_third_in_tpdo2_only_when_configured() {
        let plain = DriveSetup {
            node_id: 3,
            host_node_id: 0x7F,
            drive_heartbeat_ms: 10,
            host_silence_timeout_ms: 50,
            comm_loss_reaction: 2,
            max_torque_permille: 800,
            analog_input: None,
        };
        let with = DriveSetup {
            analog_input: Some(AnalogInputObject::default()),
            ..plain
        };
        let tpdo2 = |s: &DriveSetup| -> Vec<(Address, Value)> {
            s.sdo_writes()
                .into_iter()
                .filter(|(a, _)| a.index == 0x1A01 || a.index == 0x1801)
                .collect()
        };
        let a = Address::new;
        assert_eq!(
            tpdo2(&with),
            vec![
                (a(0x1801, 1), Value::Unsigned32(0x8000_0283)),
                (a(0x1A01, 0), Value::Unsigned8(0)),
                (a(0x1A01, 1), Value::Unsigned32(0x6041_0010)),
                (a(0x1A01, 2), Value::Unsigned32(0x603F_0010)),
                (a(0x1A01, 3), Value::Unsigned32(0x6401_0110)),
                (a(0x1A01, 0), Value::Unsigned8(3)),
                (a(0x1801, 2), Value::Unsigned8(SYNC_EVERY_CYCLE)),
                (a(0x1801, 1), Value::Unsigned32(0x283)),
            ]
        );
        // Everything else is the same with or without the analog input.
        let rest = |s: &DriveSetup| -> Vec<(Address, Value)> {
            s.sdo_writes()
                .into_iter()
                .filter(|(a, _)| a.index != 0x1A01)
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
    fn the_extended_status_decodes_exactly_six_bytes() {
        let s = StatusWithAnalog::decode(&[0x37, 0x02, 0, 0, 0x18, 0xFC]).unwrap();
        assert_eq!(s.status.statusword, 0x0237);
        assert_eq!(s.analog_input, -1000);
        assert_eq!(s.encode(), [0x37, 0x02, 0, 0, 0x18, 0xFC]);
        assert_eq!(StatusWithAnalog::decode(&[0x37, 0x02, 0, 0]), None);
        assert_eq!(StatusWithAnalog::decode(&[0; 7]), None);
        assert_eq!(Status::decode(&[0x37, 0x02, 0, 0, 0x18, 0xFC]), None);
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
            let x = StatusWithAnalog { status: s, analog_input: ai };
            prop_assert_eq!(StatusWithAnalog::decode(&x.encode()), Some(x));
        }
    }
}
