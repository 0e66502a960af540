//! Errors of the CiA 402 drive set. Plain data (no heap): built and returned on the real-time
//! path. `Display` gives the readable text (EMCY and SDO-abort tables included).

use videt_hal::{ErrorKind, LifecycleState};

use super::state::{PowerError, PowerGoal, PowerState};
use crate::canopen::codes::{emcy_description, sdo_abort_description};
use crate::canopen::objects::{
    driver_object, means_absent, object_name, DriverObject, Need, ABORT_INVALID_VALUE,
};
use videt_drive_description::TorqueUnit;

/// What went wrong with the drives, naming the node involved.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum DriveError {
    /// The CAN controller is bus-off.
    BusOff,
    /// The CAN port failed (its `embedded-can` error kind).
    Bus(embedded_can::ErrorKind),
    /// The CAN interface failed with an operating-system error (`errno`: the interface went
    /// down, its device was removed, ...).
    BusIo {
        /// The error number.
        errno: i32,
    },
    /// A drive did not send its boot-up message in time.
    NeverBooted {
        /// Wire index (0-based) of the drive.
        wire: u8,
        /// Node id.
        node: u8,
        /// Time waited, ms.
        waited_ms: u64,
    },
    /// A drive did not answer an SDO request in time.
    SdoTimeout {
        /// Wire index (0-based) of the drive.
        wire: u8,
        /// Node id.
        node: u8,
        /// Object index.
        index: u16,
        /// Object subindex.
        subindex: u8,
    },
    /// A drive refused an SDO request.
    SdoAbort {
        /// Wire index (0-based) of the drive.
        wire: u8,
        /// Node id.
        node: u8,
        /// Object index.
        index: u16,
        /// Object subindex.
        subindex: u8,
        /// Abort code.
        code: u32,
    },
    /// A drive answered an SDO read with a value of an unexpected type.
    SdoUnexpectedValue {
        /// Wire index (0-based) of the drive.
        wire: u8,
        /// Node id.
        node: u8,
        /// Object index.
        index: u16,
    },
    /// The drive's rated torque (0x6076) differs from the configured one.
    RatedTorqueMismatch {
        /// Wire index (0-based) of the drive.
        wire: u8,
        /// Node id.
        node: u8,
        /// The drive's value, in `unit`.
        drive_value: u32,
        /// The configured value, in `unit`.
        configured_value: u32,
        /// The unit of 0x6076 on this drive.
        unit: TorqueUnit,
    },
    /// A drive did not reach the power state in time.
    PowerTimeout {
        /// Wire index (0-based) of the drive.
        wire: u8,
        /// Node id.
        node: u8,
        /// Goal.
        goal: PowerGoal,
        /// State it was stuck in.
        state: PowerState,
        /// Time waited, ms.
        waited_ms: u64,
    },
    /// A drive stays in fault after fault resets.
    FaultPersists {
        /// Wire index (0-based) of the drive.
        wire: u8,
        /// Node id.
        node: u8,
        /// Its error code (0x603F).
        error_code: u16,
    },
    /// A drive reports a fault in its statusword.
    DriveFault {
        /// Wire index (0-based) of the drive.
        wire: u8,
        /// Node id.
        node: u8,
        /// Its error code (0x603F).
        error_code: u16,
    },
    /// A drive sent an emergency message.
    Emergency {
        /// Wire index (0-based) of the drive.
        wire: u8,
        /// Node id.
        node: u8,
        /// EMCY error code.
        code: u16,
        /// Error register (0x1001).
        register: u8,
    },
    /// The node's device type (0x1000) is not a CiA 402 drive's.
    NotCia402 {
        /// Wire index (0-based) of the drive.
        wire: u8,
        /// Node id.
        node: u8,
        /// The device type it reported.
        device_type: u32,
    },
    /// The drive does not offer cyclic synchronous torque mode (0x6502 bit 9 clear).
    NoCyclicTorque {
        /// Wire index (0-based) of the drive.
        wire: u8,
        /// Node id.
        node: u8,
        /// Its supported drive modes (0x6502).
        supported_modes: u32,
    },
    /// The drive refused an entry of a PDO mapping.
    MappingRefused {
        /// Wire index (0-based) of the drive.
        wire: u8,
        /// Node id.
        node: u8,
        /// The mapping parameter (0x1600.., 0x1A00..).
        index: u16,
        /// The entry's sub-index.
        subindex: u8,
        /// The mapping entry written (`object << 16 | sub << 8 | bits`).
        entry: u32,
        /// Abort code.
        code: u32,
    },
    /// After NMT start, a drive's process data did not answer SYNC in time.
    NoProcessData {
        /// Wire index (0-based) of the drive.
        wire: u8,
        /// Node id.
        node: u8,
        /// Time waited, ms.
        waited_ms: u64,
        /// Whether its TPDO1 (the motion) arrived.
        motion: bool,
        /// Whether its status PDO arrived.
        status: bool,
    },
    /// A drive's heartbeat stopped.
    HeartbeatLost {
        /// Wire index (0-based) of the drive.
        wire: u8,
        /// Node id.
        node: u8,
        /// Time since it was last heard, ms.
        silent_ms: u64,
    },
    /// A drive's process data did not arrive within the cycle.
    PdoTimeout {
        /// Wire index (0-based) of the drive.
        wire: u8,
        /// Node id.
        node: u8,
        /// Consecutive cycles without its TPDOs.
        missed_cycles: u32,
    },
    /// A drive left the operational NMT state (rebooted or stopped).
    NotOperational {
        /// Wire index (0-based) of the drive.
        wire: u8,
        /// Node id.
        node: u8,
        /// The NMT state byte it reported (0 = boot-up).
        nmt_state: u8,
    },
    /// A wire was wound in faster than the trip speed.
    OverSpeed {
        /// Wire index.
        wire: usize,
        /// Wire speed, mm/s (positive = winding).
        speed_mm_per_s: i32,
    },
    /// A torque command was not a finite number.
    InvalidTorque {
        /// Wire index.
        wire: usize,
    },
    /// The call is not allowed in this lifecycle state.
    NotReady {
        /// The state the set is in.
        state: LifecycleState,
    },
}

impl DriveError {
    /// Build the error for a failed power sequence of `node`, the drive of `wire`.
    pub fn from_power(wire: u8, node: u8, e: PowerError, error_code: u16) -> DriveError {
        match e {
            PowerError::Timeout {
                goal,
                state,
                waited_ms,
            } => DriveError::PowerTimeout {
                wire,
                node,
                goal,
                state,
                waited_ms,
            },
            PowerError::FaultPersists { .. } => DriveError::FaultPersists {
                wire,
                node,
                error_code,
            },
        }
    }
}

impl videt_hal::Error for DriveError {
    fn kind(&self) -> ErrorKind {
        match self {
            DriveError::BusOff => ErrorKind::Disconnected,
            DriveError::Bus(_) | DriveError::BusIo { .. } => ErrorKind::Other,
            DriveError::NeverBooted { .. }
            | DriveError::SdoTimeout { .. }
            | DriveError::PowerTimeout { .. }
            | DriveError::HeartbeatLost { .. }
            | DriveError::PdoTimeout { .. }
            | DriveError::NoProcessData { .. } => ErrorKind::Timeout,
            DriveError::SdoAbort { .. }
            | DriveError::SdoUnexpectedValue { .. }
            | DriveError::FaultPersists { .. }
            | DriveError::DriveFault { .. }
            | DriveError::Emergency { .. }
            | DriveError::NotOperational { .. }
            | DriveError::NotCia402 { .. }
            | DriveError::NoCyclicTorque { .. }
            | DriveError::MappingRefused { .. } => ErrorKind::Fault,
            DriveError::RatedTorqueMismatch { .. }
            | DriveError::OverSpeed { .. }
            | DriveError::InvalidTorque { .. } => ErrorKind::OutOfRange,
            DriveError::NotReady { .. } => ErrorKind::NotReady,
        }
    }
}

/// "drive of wire W (node N)": how every drive is named in the texts.
pub(crate) struct Drive(pub(crate) u8, pub(crate) u8);

impl core::fmt::Display for Drive {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "drive of wire {} (node {})", self.0, self.1)
    }
}

/// `0xIIII:SS (name)`.
pub(crate) struct Object(pub(crate) u16, pub(crate) u8);

impl core::fmt::Display for Object {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "{:#06x}:{:02x} ({})",
            self.0,
            self.1,
            object_name(self.0, self.1)
        )
    }
}

/// What an SDO abort on `index:subindex` means for the service, and what would fix it.
fn abort_consequence(
    f: &mut core::fmt::Formatter<'_>,
    index: u16,
    subindex: u8,
    code: u32,
) -> core::fmt::Result {
    let Some(o) = driver_object(index, subindex) else {
        return write!(f, "the service cannot start without it");
    };
    match (code, o.need) {
        (ABORT_INVALID_VALUE, _) if index == 0x6060 => write!(
            f,
            "the drive refuses cyclic synchronous torque mode (10), the mode the service drives \
             the wires in; use a drive that offers it (0x6502 bit 9)"
        ),
        (c, Need::Optional { without }) if means_absent(c) => write!(f, "{without}"),
        (c, Need::Required { fix }) if means_absent(c) => {
            write!(f, "the service needs it: {}; {fix}", o.purpose)
        }
        (_, Need::Required { fix }) => write!(
            f,
            "the service needs it: {}; check the drive's settings for this object, or {fix}",
            o.purpose
        ),
        (_, Need::Optional { .. }) => write!(
            f,
            "the service uses it: {}; a drive may lack it, but this one refused it for another \
             reason: check the drive's settings for this object",
            o.purpose
        ),
    }
}

impl core::fmt::Display for DriveError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            DriveError::BusOff => write!(f, "CAN bus off"),
            DriveError::Bus(k) => write!(f, "CAN bus error: {k}"),
            DriveError::BusIo { errno } => write!(
                f,
                "CAN interface: {}",
                std::io::Error::from_raw_os_error(errno)
            ),
            DriveError::NeverBooted {
                wire,
                node,
                waited_ms,
            } => write!(
                f,
                "{}: no boot-up message within {waited_ms} ms of the NMT reset; check the \
                 drive's power, the bus wiring and termination, its node id (drives.node_ids) and \
                 its bit rate (drives.bitrate)",
                Drive(wire, node)
            ),
            DriveError::SdoTimeout {
                wire,
                node,
                index,
                subindex,
            } => write!(
                f,
                "{}: no SDO answer for {}; check that node {node} is this drive \
                 (drives.node_ids) and that nothing else on the bus uses its id",
                Drive(wire, node),
                Object(index, subindex)
            ),
            DriveError::SdoAbort {
                wire,
                node,
                index,
                subindex,
                code,
            } => {
                write!(
                    f,
                    "{}: {}: {} ({code:#010x}); ",
                    Drive(wire, node),
                    Object(index, subindex),
                    sdo_abort_description(code)
                )?;
                abort_consequence(f, index, subindex, code)
            }
            DriveError::MappingRefused {
                wire,
                node,
                index,
                subindex,
                entry,
                code,
            } => {
                let (mapped, mapped_sub) = ((entry >> 16) as u16, (entry >> 8) as u8);
                write!(
                    f,
                    "{}: {} entry {subindex} refused {} ({} bits): {} ({code:#010x}); ",
                    Drive(wire, node),
                    Object(index, subindex),
                    Object(mapped, mapped_sub),
                    entry & 0xFF,
                    sdo_abort_description(code)
                )?;
                match driver_object(mapped, mapped_sub) {
                    Some(DriverObject {
                        purpose,
                        need: Need::Required { fix } | Need::Optional { without: fix },
                        ..
                    }) => write!(f, "the service needs it: {purpose}; {fix}"),
                    None => write!(f, "the service cannot start without it"),
                }
            }
            DriveError::SdoUnexpectedValue { wire, node, index } => write!(
                f,
                "{}: {} answered with a value of another data type than CiA 301 gives it",
                Drive(wire, node),
                Object(index, 0)
            ),
            DriveError::NotCia402 {
                wire,
                node,
                device_type,
            } => write!(
                f,
                "{}: 0x1000:00 (device type) is {device_type:#010x}, profile {}: not a CiA 402 \
                 drive (profile 402); check drives.node_ids",
                Drive(wire, node),
                device_type & 0xFFFF
            ),
            DriveError::NoCyclicTorque {
                wire,
                node,
                supported_modes,
            } => write!(
                f,
                "{}: 0x6502:00 (supported drive modes) is {supported_modes:#010x}: no cyclic \
                 synchronous torque mode (bit 9), the mode the service drives the wires in; use \
                 a drive that offers it",
                Drive(wire, node)
            ),
            DriveError::RatedTorqueMismatch {
                wire,
                node,
                drive_value,
                configured_value,
                unit,
            } => write!(
                f,
                "{}: 0x6076:00 (motor rated torque) is {drive_value} {u} but the configuration \
                 says {configured_value} {u}; set drives.rated_torque_nm to the motor's, or name \
                 the drive's file in drives.device_description",
                Drive(wire, node),
                u = unit.symbol()
            ),
            DriveError::PowerTimeout {
                wire,
                node,
                goal,
                state,
                waited_ms,
            } => write!(
                f,
                "{}: power state machine stuck in '{}' on the way to {} after {waited_ms} ms \
                 (drives.power_timeout_ms); check the drive's enable and safe-torque-off inputs \
                 and its supply voltage",
                Drive(wire, node),
                state.as_str(),
                match goal {
                    PowerGoal::Enabled => "'operation enabled'",
                    PowerGoal::Disabled => "'switch on disabled'",
                    PowerGoal::QuickStop => "'quick stop active'",
                }
            ),
            DriveError::FaultPersists {
                wire,
                node,
                error_code,
            } => write!(
                f,
                "{}: fault {error_code:#06x} ({}) persists after fault reset; its cause is still \
                 present in the drive",
                Drive(wire, node),
                emcy_description(error_code)
            ),
            DriveError::DriveFault {
                wire,
                node,
                error_code,
            } => write!(
                f,
                "{}: fault {error_code:#06x} ({})",
                Drive(wire, node),
                emcy_description(error_code)
            ),
            DriveError::Emergency {
                wire,
                node,
                code,
                register,
            } => write!(
                f,
                "{}: emergency {code:#06x} ({}), error register {register:#04x}",
                Drive(wire, node),
                emcy_description(code)
            ),
            DriveError::NoProcessData {
                wire,
                node,
                waited_ms,
                motion,
                status,
            } => {
                write!(
                    f,
                    "{}: its process data did not answer SYNC within {waited_ms} ms of NMT \
                     start (",
                    Drive(wire, node)
                )?;
                match (motion, status) {
                    (false, false) => write!(f, "neither TPDO1 nor the status PDO")?,
                    (false, true) => write!(f, "no TPDO1 with the motion")?,
                    _ => write!(f, "no status PDO")?,
                }
                write!(
                    f,
                    " arrived); check that the drive is operational and sends its TPDOs on SYNC \
                     (0x080)"
                )
            }
            DriveError::HeartbeatLost {
                wire,
                node,
                silent_ms,
            } => write!(
                f,
                "{}: heartbeat lost (silent for {silent_ms} ms)",
                Drive(wire, node)
            ),
            DriveError::PdoTimeout {
                wire,
                node,
                missed_cycles,
            } => write!(
                f,
                "{}: process data missing for {missed_cycles} consecutive cycles",
                Drive(wire, node)
            ),
            DriveError::NotOperational {
                wire,
                node,
                nmt_state,
            } => write!(
                f,
                "{}: left the operational state (NMT state {nmt_state:#04x}{})",
                Drive(wire, node),
                if nmt_state == 0 { ", rebooted" } else { "" }
            ),
            DriveError::OverSpeed {
                wire,
                speed_mm_per_s,
            } => write!(
                f,
                "wire {wire}: speed {speed_mm_per_s} mm/s above the trip limit"
            ),
            DriveError::InvalidTorque { wire } => {
                write!(f, "wire {wire}: torque command is not a finite number")
            }
            DriveError::NotReady { state } => {
                write!(f, "drive set is {state:?}; the call needs another state")
            }
        }
    }
}

impl std::error::Error for DriveError {}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::canopen::objects::DRIVER_OBJECTS;

    /// A refusal of any object the driver touches, with an abort code that means "absent" and
    /// with others (the standard's "resource not available" among them), reads as sentences:
    /// the code named, then what it means for the service, nothing left dangling.
    #[test]
    fn every_refusal_of_a_driver_object_reads_as_sentences() {
        for o in DRIVER_OBJECTS {
            for code in [
                0x0602_0000,
                0x0609_0011,
                0x0800_0000,
                0x060A_0023,
                0x0609_0030,
            ] {
                let e = DriveError::SdoAbort {
                    wire: 1,
                    node: 2,
                    index: o.index,
                    subindex: o.subindex.unwrap_or(1),
                    code,
                };
                let text = e.to_string();
                assert!(text.starts_with("drive of wire 1 (node 2): "), "{text}");
                assert!(!text.contains("unknown SDO abort code"), "{text}");
                for broken in ["because to", "  ", ";;", "; ;", ": :", ":;", " ,", " ;"] {
                    assert!(!text.contains(broken), "{broken:?} in: {text}");
                }
                let last = text.chars().last().unwrap();
                assert!(last.is_alphanumeric() || last == ')', "{text}");
                let (_, consequence) = text.split_once(&format!("({code:#010x}); ")).unwrap();
                assert!(consequence.len() > 20, "{text}");
            }
        }
        let e = DriveError::SdoAbort {
            wire: 0,
            node: 1,
            index: 0x6502,
            subindex: 0,
            code: 0x0800_0000,
        };
        assert_eq!(
            e.to_string(),
            "drive of wire 0 (node 1): 0x6502:00 (supported drive modes): general error \
             (0x08000000); the service uses it: to check that the drive offers cyclic synchronous \
             torque mode before configuring it; a drive may lack it, but this one refused it for \
             another reason: check the drive's settings for this object"
        );
    }
}
