//! Errors of the CiA 402 drive set. Plain data (no heap): built and returned on the real-time
//! path. `Display` gives the readable text (EMCY and SDO-abort tables included).

use videt_hal::{ErrorKind, LifecycleState};

use super::resolution::TorqueUnit;
use super::state::{PowerError, PowerGoal, PowerState};
use crate::canopen::codes::{emcy_description, sdo_abort_description};

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
        /// Node id.
        node: u8,
        /// Time waited, ms.
        waited_ms: u64,
    },
    /// A drive did not answer an SDO request in time.
    SdoTimeout {
        /// Node id.
        node: u8,
        /// Object index.
        index: u16,
        /// Object subindex.
        subindex: u8,
    },
    /// A drive refused an SDO request.
    SdoAbort {
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
        /// Node id.
        node: u8,
        /// Object index.
        index: u16,
    },
    /// The drive's rated torque (0x6076) differs from the configured one.
    RatedTorqueMismatch {
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
        /// Node id.
        node: u8,
        /// Its error code (0x603F).
        error_code: u16,
    },
    /// A drive reports a fault in its statusword.
    DriveFault {
        /// Node id.
        node: u8,
        /// Its error code (0x603F).
        error_code: u16,
    },
    /// A drive sent an emergency message.
    Emergency {
        /// Node id.
        node: u8,
        /// EMCY error code.
        code: u16,
        /// Error register (0x1001).
        register: u8,
    },
    /// A drive's heartbeat stopped.
    HeartbeatLost {
        /// Node id.
        node: u8,
        /// Time since it was last heard, ms.
        silent_ms: u64,
    },
    /// A drive's process data did not arrive within the cycle.
    PdoTimeout {
        /// Node id.
        node: u8,
        /// Consecutive cycles without its TPDOs.
        missed_cycles: u32,
    },
    /// A drive left the operational NMT state (rebooted or stopped).
    NotOperational {
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
    /// Build the error for a failed power sequence of `node`.
    pub fn from_power(node: u8, e: PowerError, error_code: u16) -> DriveError {
        match e {
            PowerError::Timeout {
                goal,
                state,
                waited_ms,
            } => DriveError::PowerTimeout {
                node,
                goal,
                state,
                waited_ms,
            },
            PowerError::FaultPersists { .. } => DriveError::FaultPersists { node, error_code },
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
            | DriveError::PdoTimeout { .. } => ErrorKind::Timeout,
            DriveError::SdoAbort { .. }
            | DriveError::SdoUnexpectedValue { .. }
            | DriveError::FaultPersists { .. }
            | DriveError::DriveFault { .. }
            | DriveError::Emergency { .. }
            | DriveError::NotOperational { .. } => ErrorKind::Fault,
            DriveError::RatedTorqueMismatch { .. }
            | DriveError::OverSpeed { .. }
            | DriveError::InvalidTorque { .. } => ErrorKind::OutOfRange,
            DriveError::NotReady { .. } => ErrorKind::NotReady,
        }
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
            DriveError::NeverBooted { node, waited_ms } => {
                write!(f, "drive {node}: no boot-up message within {waited_ms} ms")
            }
            DriveError::SdoTimeout {
                node,
                index,
                subindex,
            } => write!(
                f,
                "drive {node}: no SDO answer for object {index:#06x}:{subindex}"
            ),
            DriveError::SdoAbort {
                node,
                index,
                subindex,
                code,
            } => write!(
                f,
                "drive {node}: SDO access to {index:#06x}:{subindex} aborted with {code:#010x} ({})",
                sdo_abort_description(code)
            ),
            DriveError::SdoUnexpectedValue { node, index } => {
                write!(f, "drive {node}: object {index:#06x} has an unexpected data type")
            }
            DriveError::RatedTorqueMismatch {
                node,
                drive_value,
                configured_value,
                unit,
            } => write!(
                f,
                "drive {node}: motor rated torque (0x6076) is {drive_value} {u} but the configuration says {configured_value} {u}",
                u = unit.symbol()
            ),
            DriveError::PowerTimeout {
                node,
                goal,
                state,
                waited_ms,
            } => write!(
                f,
                "drive {node}: power state {goal:?} not reached within {waited_ms} ms (stuck in '{}')",
                state.as_str()
            ),
            DriveError::FaultPersists { node, error_code } => write!(
                f,
                "drive {node}: fault {error_code:#06x} ({}) persists after fault reset",
                emcy_description(error_code)
            ),
            DriveError::DriveFault { node, error_code } => write!(
                f,
                "drive {node}: fault {error_code:#06x} ({})",
                emcy_description(error_code)
            ),
            DriveError::Emergency {
                node,
                code,
                register,
            } => write!(
                f,
                "drive {node}: emergency {code:#06x} ({}), error register {register:#04x}",
                emcy_description(code)
            ),
            DriveError::HeartbeatLost { node, silent_ms } => {
                write!(f, "drive {node}: heartbeat lost (silent for {silent_ms} ms)")
            }
            DriveError::PdoTimeout {
                node,
                missed_cycles,
            } => write!(
                f,
                "drive {node}: process data missing for {missed_cycles} consecutive cycles"
            ),
            DriveError::NotOperational { node, nmt_state } => write!(
                f,
                "drive {node}: left the operational state (NMT state {nmt_state:#04x}{})",
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
