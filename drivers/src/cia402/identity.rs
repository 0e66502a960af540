//! What each drive tells of itself at start-up: its identity (0x1000 device type, 0x1018
//! identity object) and the optional objects it lacks, for the service's log and status.

use crate::canopen::codes::sdo_abort_description;
use crate::canopen::objects::driver_object;

use super::error::{Drive, Object};

/// CiA 402's device profile number, in the low 16 bits of a drive's device type (0x1000).
pub const CIA402_PROFILE: u32 = 402;

/// A drive's identity, read at start-up.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct DriveIdentity {
    /// Device type (0x1000): the profile number in the low 16 bits.
    pub device_type: u32,
    /// Vendor id (0x1018 sub 1, assigned by CiA), when the drive has it.
    pub vendor_id: Option<u32>,
    /// Product code (0x1018 sub 2), when the drive has it.
    pub product_code: Option<u32>,
    /// Revision number (0x1018 sub 3), when the drive has it.
    pub revision: Option<u32>,
    /// Serial number (0x1018 sub 4), when the drive has it.
    pub serial: Option<u32>,
}

impl DriveIdentity {
    /// Whether the device type names the CiA 402 profile.
    pub const fn is_cia402(&self) -> bool {
        self.device_type & 0xFFFF == CIA402_PROFILE
    }
}

/// The maker of a few drives by their CiA vendor id.
pub fn vendor_name(vendor_id: u32) -> Option<&'static str> {
    match vendor_id {
        0x0000_00FB => Some("maxon"),
        0x0000_0147 => Some("Faulhaber"),
        0x0000_009A => Some("Elmo"),
        0x0000_02E1 => Some("Nanotec"),
        _ => None,
    }
}

impl core::fmt::Display for DriveIdentity {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "device type {:#010x} (profile {})",
            self.device_type,
            self.device_type & 0xFFFF
        )?;
        let field = |f: &mut core::fmt::Formatter<'_>, name: &str, v: Option<u32>| match v {
            Some(v) => write!(f, ", {name} {v:#010x}"),
            None => write!(f, ", {name} unknown"),
        };
        field(f, "vendor", self.vendor_id)?;
        if let Some(name) = self.vendor_id.and_then(vendor_name) {
            write!(f, " ({name})")?;
        }
        field(f, "product", self.product_code)?;
        field(f, "revision", self.revision)?;
        field(f, "serial", self.serial)
    }
}

/// An optional object a drive lacks (its SDO access was aborted as absent), told once at
/// start-up with what the service does without it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StartupNote {
    /// Wire index (0-based) of the drive.
    pub wire: u8,
    /// Node id.
    pub node: u8,
    /// Object index.
    pub index: u16,
    /// Sub-index.
    pub subindex: u8,
    /// The abort code the drive answered.
    pub code: u32,
}

impl core::fmt::Display for StartupNote {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "{}: {}: {} ({:#010x})",
            Drive(self.wire, self.node),
            Object(self.index, self.subindex),
            sdo_abort_description(self.code),
            self.code
        )?;
        match driver_object(self.index, self.subindex).map(|o| o.need) {
            Some(crate::canopen::objects::Need::Optional { without }) => write!(f, "; {without}"),
            _ => Ok(()),
        }
    }
}

/// What the drives told of themselves at their last configuration, shared with a reader off
/// the control thread ([`Cia402DriveSet::startup_report`](super::Cia402DriveSet::startup_report)).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct StartupReport {
    /// Configurations reported so far: a reader tells a new report by it.
    pub generation: u64,
    /// `(wire, node, identity)` of each drive identified, in wire order.
    pub drives: Vec<(u8, u8, DriveIdentity)>,
    /// The optional objects the drives lack.
    pub notes: Vec<StartupNote>,
}

/// A [`StartupReport`] shared between the drive set and its readers.
pub type SharedStartupReport = std::sync::Arc<std::sync::Mutex<StartupReport>>;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_note_of_a_missing_event_timer_reads_as_a_technician_needs_it() {
        let note = StartupNote {
            wire: 1,
            node: 2,
            index: 0x1801,
            subindex: 5,
            code: 0x0609_0011,
        };
        assert_eq!(
            note.to_string(),
            "drive of wire 1 (node 2): 0x1801:05 (TPDO2 event timer): sub-index does not exist \
             (0x06090011); the status PDO is then sent on change only"
        );
    }

    #[test]
    fn an_identity_names_its_profile_and_maker() {
        let id = DriveIdentity {
            device_type: 0x0002_0192,
            vendor_id: Some(0xFB),
            product_code: Some(0x6552_0000),
            revision: None,
            serial: Some(7),
        };
        assert!(id.is_cia402());
        assert_eq!(
            id.to_string(),
            "device type 0x00020192 (profile 402), vendor 0x000000fb (maxon), product \
             0x65520000, revision unknown, serial 0x00000007"
        );
        assert!(!DriveIdentity::default().is_cia402());
    }
}
