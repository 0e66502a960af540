//! The objects of a drive's dictionary the driver reads or writes: their names, what the
//! service needs each for, whether a drive may lack it (CiA 301 and CiA 402 make most of them
//! optional) and what the service does without it, or what would fix a drive that refuses it.
//! Static strings: usable on the real-time path, and the source of the table in
//! `docs/can-bus.md`.

/// SDO abort "object does not exist in the object dictionary".
pub const ABORT_NO_OBJECT: u32 = 0x0602_0000;
/// SDO abort "sub-index does not exist".
pub const ABORT_NO_SUBINDEX: u32 = 0x0609_0011;
/// SDO abort "object cannot be mapped to the PDO".
pub const ABORT_NOT_MAPPABLE: u32 = 0x0604_0041;
/// SDO abort "invalid value for parameter".
pub const ABORT_INVALID_VALUE: u32 = 0x0609_0030;

/// Whether an SDO abort code says the object or sub-index is absent from the drive's
/// dictionary: CiA 301 answers 0x06020000 for a missing object and 0x06090011 for a missing
/// sub-index of an object that exists; drives differ in which they use for which.
pub const fn means_absent(code: u32) -> bool {
    code == ABORT_NO_OBJECT || code == ABORT_NO_SUBINDEX
}

/// Whether the driver can do without an object.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Need {
    /// The drive is refused without it; `fix` says what would make it usable.
    Required {
        /// The drive setting or configuration field that would fix it.
        fix: &'static str,
    },
    /// The driver goes on without it; `without` says what the service then does.
    Optional {
        /// What the service does without the object.
        without: &'static str,
    },
}

/// One object of the driver's start-up and process data.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DriverObject {
    /// Object index.
    pub index: u16,
    /// Sub-index; `None` for every sub-index of the object.
    pub subindex: Option<u8>,
    /// The object's name (CiA 301 / CiA 402).
    pub name: &'static str,
    /// What the service needs it for.
    pub purpose: &'static str,
    /// Whether a drive may lack it.
    pub need: Need,
}

const fn obj(
    index: u16,
    subindex: Option<u8>,
    name: &'static str,
    purpose: &'static str,
    need: Need,
) -> DriverObject {
    DriverObject {
        index,
        subindex,
        name,
        purpose,
        need,
    }
}

/// A PDO the driver does not use: its COB-ID (sub 1), disabled at configuration.
const fn unused_pdo(index: u16, name: &'static str) -> DriverObject {
    obj(
        index,
        Some(1),
        name,
        "an unused PDO: disabled so that it puts nothing on the bus beyond the period's budget",
        Need::Optional {
            without: "the drive has no such PDO: nothing to disable",
        },
    )
}

const REQUIRED_PDO: Need = Need::Required {
    fix: "the drive must accept the process-data layout of docs/can-bus.md; use a drive whose \
          PDOs can be configured over SDO",
};

/// The objects the driver reads or writes, in the order it first touches them, most specific
/// first (a sub-index entry before its object's catch-all).
pub const DRIVER_OBJECTS: &[DriverObject] = &[
    obj(
        0x1000,
        Some(0),
        "device type",
        "to check that the node is a CiA 402 drive",
        Need::Required {
            fix: "check drives.node_ids: every node listed must be a CiA 402 drive",
        },
    ),
    obj(
        0x1018,
        Some(1),
        "identity: vendor id",
        "to log the drive and compare it with drives.device_description",
        Need::Optional {
            without: "the drive's vendor is logged as unknown",
        },
    ),
    obj(
        0x1018,
        Some(2),
        "identity: product code",
        "to log the drive and compare it with drives.device_description",
        Need::Optional {
            without: "the drive's product is logged as unknown",
        },
    ),
    obj(
        0x1018,
        Some(3),
        "identity: revision number",
        "to log the drive",
        Need::Optional {
            without: "the drive's revision is logged as unknown",
        },
    ),
    obj(
        0x1018,
        Some(4),
        "identity: serial number",
        "to log the drive",
        Need::Optional {
            without: "the drive's serial number is logged as unknown",
        },
    ),
    obj(
        0x6502,
        Some(0),
        "supported drive modes",
        "to check that the drive offers cyclic synchronous torque mode before configuring it",
        Need::Optional {
            without: "the write of the mode of operation (0x6060) decides",
        },
    ),
    obj(
        0x6076,
        Some(0),
        "motor rated torque",
        "to check drives.rated_torque_nm, the unit of every torque command",
        Need::Optional {
            without: "drives.rated_torque_nm is used unchecked",
        },
    ),
    obj(
        0x1017,
        Some(0),
        "producer heartbeat time",
        "the drive's heartbeat tells the service a drive that rebooted, stopped or fell silent",
        Need::Required {
            fix: "use a drive with a heartbeat producer (node guarding is not supported)",
        },
    ),
    obj(
        0x1016,
        Some(1),
        "consumer heartbeat time",
        "the drive watches the service's heartbeat and disables itself when the service falls \
         silent, so a dead service never leaves a wire pulled",
        Need::Required {
            fix: "use a drive with a heartbeat consumer (0x1016): without one it would hold the \
                  last torque if the service stopped",
        },
    ),
    obj(
        0x6007,
        Some(0),
        "abort connection option code",
        "the drive's reaction to a silent service (drives.comm_loss_reaction)",
        Need::Optional {
            without: "the drive reacts to a silent service as it is set to by its maker; check \
                      that it disables the motor",
        },
    ),
    obj(
        0x6060,
        Some(0),
        "modes of operation",
        "selects cyclic synchronous torque mode (10), the mode the service drives the wires in",
        Need::Required {
            fix: "use a drive that offers cyclic synchronous torque mode (0x6502 bit 9)",
        },
    ),
    obj(
        0x6072,
        Some(0),
        "max torque",
        "the drive's own torque limit, set to the torque that holds control.t_max_n",
        Need::Optional {
            without: "only the service's own torque clamp limits the tension",
        },
    ),
    obj(
        0x607E,
        Some(0),
        "polarity",
        "the direction of the position and velocity (bits 7 and 6), set from drives.encoder_reversed",
        Need::Optional {
            without: "a wire's encoder direction (drives.encoder_reversed) is applied by the service",
        },
    ),
    obj(
        0x1400,
        None,
        "RPDO1 communication parameter",
        "RPDO1 carries the controlword and the target torque every period",
        REQUIRED_PDO,
    ),
    obj(
        0x1600,
        None,
        "RPDO1 mapping",
        "RPDO1 carries the controlword and the target torque every period",
        REQUIRED_PDO,
    ),
    obj(
        0x1800,
        None,
        "TPDO1 communication parameter",
        "TPDO1 answers every SYNC with the position (and the velocity or the analog input)",
        REQUIRED_PDO,
    ),
    obj(
        0x1A00,
        None,
        "TPDO1 mapping",
        "TPDO1 answers every SYNC with the position (and the velocity or the analog input)",
        REQUIRED_PDO,
    ),
    obj(
        0x1801,
        Some(5),
        "TPDO2 event timer",
        "refreshes the status PDO at least every 50 ms",
        Need::Optional {
            without: "the status PDO is then sent on change only",
        },
    ),
    obj(
        0x1801,
        None,
        "TPDO2 communication parameter",
        "TPDO2 carries the statusword and the error code when they change",
        REQUIRED_PDO,
    ),
    obj(
        0x1A01,
        None,
        "TPDO2 mapping",
        "TPDO2 carries the statusword and the error code when they change",
        REQUIRED_PDO,
    ),
    unused_pdo(0x1401, "RPDO2 COB-ID"),
    unused_pdo(0x1402, "RPDO3 COB-ID"),
    unused_pdo(0x1403, "RPDO4 COB-ID"),
    unused_pdo(0x1802, "TPDO3 COB-ID"),
    unused_pdo(0x1803, "TPDO4 COB-ID"),
    obj(
        0x6040,
        Some(0),
        "controlword",
        "drives the power state machine, in RPDO1",
        REQUIRED_PDO,
    ),
    obj(
        0x6071,
        Some(0),
        "target torque",
        "the torque command of every period, in RPDO1",
        Need::Required {
            fix: "use a drive that maps the target torque (0x6071) into an RPDO: the service \
                  drives the wires in cyclic synchronous torque mode",
        },
    ),
    obj(
        0x6041,
        Some(0),
        "statusword",
        "the power state, in TPDO2 (and in TPDO1 with sensors.adc = \"drive\")",
        REQUIRED_PDO,
    ),
    obj(
        0x603F,
        Some(0),
        "error code",
        "the cause of a drive fault, in TPDO2",
        REQUIRED_PDO,
    ),
    obj(
        0x6064,
        Some(0),
        "position actual value",
        "the wire's length, in TPDO1",
        REQUIRED_PDO,
    ),
    obj(
        0x606C,
        Some(0),
        "velocity actual value",
        "the wire's speed, in TPDO1",
        Need::Required {
            fix: "use a drive that maps its velocity (0x606C) into a TPDO, or set sensors.adc = \
                  \"drive\" (the velocity is then derived from the positions)",
        },
    ),
    obj(
        0x6401,
        None,
        "read analog input 16-bit",
        "the wire's tension from the load-cell amplifier, in TPDO1 (sensors.adc = \"drive\")",
        Need::Required {
            fix: "set sensors.drive_analog_index and sensors.drive_analog_subindex to the \
                  drive's analog input object",
        },
    ),
    obj(
        0x3160,
        None,
        "analog input (maxon)",
        "the wire's tension from the load-cell amplifier, in TPDO1 (sensors.adc = \"drive\")",
        Need::Required {
            fix: "set sensors.drive_analog_index and sensors.drive_analog_subindex to the \
                  drive's analog input object",
        },
    ),
];

/// The driver's description of `index:subindex`, if it uses the object.
pub fn driver_object(index: u16, subindex: u8) -> Option<&'static DriverObject> {
    DRIVER_OBJECTS
        .iter()
        .find(|o| o.index == index && o.subindex.is_none_or(|s| s == subindex))
}

/// The name of `index:subindex` as the driver knows it ("object" for one it does not use).
pub fn object_name(index: u16, subindex: u8) -> &'static str {
    driver_object(index, subindex).map_or("object", |o| o.name)
}

/// Whether the driver goes on when a drive lacks `index:subindex`.
pub fn is_optional(index: u16, subindex: u8) -> bool {
    matches!(
        driver_object(index, subindex).map(|o| o.need),
        Some(Need::Optional { .. })
    )
}

/// The communication parameters of the PDOs the driver does not use (RPDO2..4, TPDO3..4): a
/// drive's own configuration may have them enabled; the driver disables them.
pub const UNUSED_PDOS: [u16; 5] = [0x1401, 0x1402, 0x1403, 0x1802, 0x1803];

/// Whether `index` is a PDO mapping parameter (RPDO 0x1600..=0x17FF, TPDO 0x1A00..=0x1BFF).
pub const fn is_pdo_mapping(index: u16) -> bool {
    matches!(index, 0x1600..=0x17FF | 0x1A00..=0x1BFF)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn both_cia301_codes_of_absence_count_and_no_other() {
        assert!(means_absent(0x0602_0000));
        assert!(means_absent(0x0609_0011));
        assert!(!means_absent(0x0601_0002));
        assert!(!means_absent(0x0604_0041));
    }

    #[test]
    fn a_sub_index_entry_is_found_before_its_objects_catch_all() {
        assert_eq!(object_name(0x1801, 5), "TPDO2 event timer");
        assert!(is_optional(0x1801, 5));
        assert_eq!(object_name(0x1801, 1), "TPDO2 communication parameter");
        assert!(!is_optional(0x1801, 1));
        assert!(is_optional(0x6072, 0));
        assert!(!is_optional(0x1017, 0));
        assert!(!is_optional(0x1016, 1));
        assert_eq!(object_name(0x2000, 0), "object");
        assert!(!is_optional(0x2000, 0));
    }

    #[test]
    fn every_object_says_what_it_is_for_and_how_to_do_without_or_fix_it() {
        for o in DRIVER_OBJECTS {
            assert!(!o.name.is_empty() && !o.purpose.is_empty(), "{o:?}");
            match o.need {
                Need::Required { fix } => assert!(fix.len() > 10, "{o:?}"),
                Need::Optional { without } => assert!(without.len() > 10, "{o:?}"),
            }
        }
    }
}
