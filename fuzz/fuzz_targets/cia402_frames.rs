//! Fuzzes the decoding of the frames a CiA 402 drive sends and the host's answers to them: a
//! stream of CAN frames (`id_hi id_lo dlc data...`, see `docs/fuzzing.md`) through the COB-ID
//! classification and CANopen decoder (`canopen::cob::classify`, `canopen::trace::decode`: NMT,
//! SYNC, heartbeat, EMCY, SDO, PDO), the process-data decoders the drive set uses on every
//! cycle (`pdo::{Command, Motion, Status, MotionWithAnalog}::decode`, which must round-trip
//! through `encode`), the power state machine fed with the received statuswords
//! (`PowerSequencer::step`), EMCY decoding with its readable text, and the SDO client state
//! machine fed with the SDO responses (reads and writes as the drive set configures a drive,
//! aborts turned into `DriveError` texts).
#![no_main]

use canopen_rs::sdo::SdoEvent;
use canopen_rs::{Address, DataType, EmergencyMessage, NodeId, SdoClient, Value};
use libfuzzer_sys::fuzz_target;
use videt_drivers::canopen::cob::{classify, CobKind};
use videt_drivers::canopen::codes::emcy_description;
use videt_drivers::canopen::trace::decode;
use videt_drivers::cia402::pdo::{Command, Motion, MotionWithAnalog, Status};
use videt_drivers::cia402::state::{PowerGoal, PowerSequencer, PowerState};
use videt_drivers::cia402::DriveError;

const MS: u64 = 1_000_000;

/// The SDO transactions the host starts, in turn (those of a drive's configuration).
fn start(client: &mut SdoClient, k: usize) -> (Address, [u8; 8]) {
    let a = Address::new;
    match k % 5 {
        0 => {
            let addr = a(0x6076, 0);
            (addr, client.read(addr, DataType::Unsigned32))
        }
        1 => {
            let addr = a(0x1017, 0);
            (addr, client.write(addr, Value::Unsigned16(10)))
        }
        2 => {
            let addr = a(0x1A00, 1);
            (addr, client.write(addr, Value::Unsigned32(0x6064_0020)))
        }
        3 => {
            let addr = a(0x1008, 0);
            (addr, client.read(addr, DataType::VisibleString))
        }
        _ => {
            let addr = a(0x6060, 0);
            (addr, client.write(addr, Value::Integer8(10)))
        }
    }
}

fuzz_target!(|data: &[u8]| {
    let goal = match data.first().map(|b| b % 3) {
        Some(0) => PowerGoal::Enabled,
        Some(1) => PowerGoal::Disabled,
        _ => PowerGoal::QuickStop,
    };
    let mut sequencer = PowerSequencer::new(goal, 0, 200 * MS, 3);
    let mut now_ns = 0u64;
    let mut client = SdoClient::new(NodeId::new(1).expect("node 1"));
    let mut transactions = 0usize;
    let (mut addr, _) = start(&mut client, transactions);
    let mut rest = data.get(1..).unwrap_or_default();
    while rest.len() >= 3 {
        let cob_id = u16::from_be_bytes([rest[0], rest[1]]) & 0x7FF;
        let dlc = usize::from(rest[2] & 0x0F).min(8).min(rest.len() - 3);
        let frame = &rest[3..3 + dlc];
        rest = &rest[3 + dlc..];
        now_ns += MS;

        let _ = decode(cob_id, frame);
        if let Some(c) = Command::decode(frame) {
            assert_eq!(c.encode().as_slice(), frame);
        }
        if let Some(m) = Motion::decode(frame) {
            assert_eq!(m.encode().as_slice(), frame);
        }
        if let Some(m) = MotionWithAnalog::decode(frame) {
            assert_eq!(m.encode().as_slice(), frame);
        }
        let statusword = match classify(cob_id) {
            CobKind::Tpdo(0, _) => MotionWithAnalog::decode(frame).map(|m| m.statusword),
            CobKind::Tpdo(1, _) => Status::decode(frame).map(|s| {
                assert_eq!(s.encode().as_slice(), frame);
                s.statusword
            }),
            CobKind::Emcy(n) => {
                if let Ok(m) = EmergencyMessage::decode(frame) {
                    let _ = emcy_description(m.error_code);
                    let e = DriveError::Emergency {
                        wire: 0,
                        node: n,
                        code: m.error_code,
                        register: m.error_register.0,
                    };
                    let _ = e.to_string();
                }
                None
            }
            CobKind::SdoResponse(n) => {
                if let Ok(p) = <[u8; 8]>::try_from(frame) {
                    let done = match client.on_response(&p) {
                        SdoEvent::Send(_) => false,
                        SdoEvent::Complete(v) => {
                            let _ = format!("{v:?}");
                            true
                        }
                        SdoEvent::Aborted(code) => {
                            let e = DriveError::SdoAbort {
                                wire: 0,
                                node: n,
                                index: addr.index,
                                subindex: addr.subindex,
                                code,
                            };
                            let _ = e.to_string();
                            true
                        }
                    };
                    if done {
                        transactions += 1;
                        addr = start(&mut client, transactions).0;
                    }
                }
                None
            }
            _ => None,
        };
        if let Some(sw) = statusword {
            let state = PowerState::from_statusword(sw);
            let _ = (state.as_str(), state.to_hal());
            match sequencer.step(sw, now_ns) {
                Ok(step) if step.reached => {
                    sequencer = PowerSequencer::new(goal, now_ns, 200 * MS, 3);
                }
                Ok(_) => {}
                Err(e) => {
                    let _ = DriveError::from_power(0, 1, e, 0).to_string();
                    sequencer = PowerSequencer::new(goal, now_ns, 200 * MS, 3);
                }
            }
        }
    }
});
