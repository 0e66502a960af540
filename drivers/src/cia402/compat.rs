//! Whether a drive, as its EDS/DCF describes it, has every object this driver uses.

use super::pdo::{AnalogInputObject, DriveSetup, SYNC_EVERY_CYCLE};
use crate::canopen::objects::is_optional;
use videt_drive_description::Eds;

/// An object the driver needs that a data sheet lacks or does not allow.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MissingObject {
    /// Object index.
    pub index: u16,
    /// Subindex.
    pub subindex: u8,
    /// What is wrong ("absent", "not writable", "not PDO-mappable").
    pub problem: &'static str,
}

/// The objects read over PDO (must be mappable), besides the SDO-written setup objects.
const PDO_OBJECTS: [u16; 6] = [0x6040, 0x6071, 0x6041, 0x6064, 0x606C, 0x603F];

/// Every object of the driver's setup and process data that `eds` lacks or forbids.
pub fn missing_objects(eds: &Eds) -> Vec<MissingObject> {
    missing_objects_with(eds, None)
}

/// As [`missing_objects`], for a driver that also maps `analog_input` into TPDO1 (it must be
/// present and PDO-mappable).
pub fn missing_objects_with(
    eds: &Eds,
    analog_input: Option<AnalogInputObject>,
) -> Vec<MissingObject> {
    let setup = DriveSetup {
        node_id: 1,
        host_node_id: 0x7F,
        drive_heartbeat_ms: 10,
        host_silence_timeout_ms: 50,
        comm_loss_reaction: 2,
        max_torque_permille: 1000,
        analog_input,
        status_event_timer_ms: 10,
    };
    let _ = SYNC_EVERY_CYCLE;
    let mut out = Vec::new();
    let mut seen = std::collections::BTreeSet::new();
    for (addr, _) in setup.sdo_writes() {
        let optional = is_optional(addr.index, addr.subindex);
        if optional || !seen.insert((addr.index, addr.subindex)) {
            continue;
        }
        match eds.entry(addr.index, addr.subindex) {
            None => out.push(MissingObject {
                index: addr.index,
                subindex: addr.subindex,
                problem: "absent",
            }),
            Some(e) if !e.access.as_deref().is_some_and(|a| a.contains('w')) => {
                out.push(MissingObject {
                    index: addr.index,
                    subindex: addr.subindex,
                    problem: "not writable",
                })
            }
            Some(_) => {}
        }
    }
    let analog = analog_input.map(|a| (a.index, a.subindex));
    for (index, subindex) in PDO_OBJECTS.iter().map(|i| (*i, 0)).chain(analog) {
        match eds.entry(index, subindex) {
            None => out.push(MissingObject {
                index,
                subindex,
                problem: "absent",
            }),
            Some(e) if !e.pdo_mappable => out.push(MissingObject {
                index,
                subindex,
                problem: "not PDO-mappable",
            }),
            Some(_) => {}
        }
    }
    out
}
