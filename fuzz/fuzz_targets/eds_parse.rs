//! Fuzzes the EDS/DCF reader: arbitrary text through `Eds::parse` (sections, keys, numbers,
//! `$NODEID` expressions), then what the service reads from an accepted sheet: every entry's
//! value for a few node ids, the drive's units (`DriveResolution::from_eds`) and the CiA 402
//! objects it lacks (`compat::missing_objects`).
#![no_main]

use libfuzzer_sys::fuzz_target;
use videt_drive_description::eds::{parse_value, Eds};
use videt_drivers::cia402::compat::missing_objects;
use videt_drive_description::DriveResolution;

fuzz_target!(|data: &[u8]| {
    // The service reads vendors' files lossily (a µ in a comment is not UTF-8).
    let text = String::from_utf8_lossy(data);
    let Ok(eds) = Eds::parse(&text) else {
        return;
    };
    let keys: Vec<(u16, u8)> = eds.entries().map(|(k, _)| *k).collect();
    for (index, subindex) in keys {
        for node in [0u8, 1, 127] {
            let _ = eds.value(index, subindex, node);
        }
        if let Some(e) = eds.entry(index, subindex) {
            for v in [&e.default_value, &e.parameter_value].into_iter().flatten() {
                let _ = parse_value(v, 5);
            }
        }
    }
    for node in [1u8, 3] {
        if let Ok(r) = DriveResolution::from_eds(&eds, "fuzz.eds", node) {
            let _ = r.torque_step_nm();
            let _ = r.gives_nothing();
            let _ = format!("{r:?}");
        }
    }
    let _ = missing_objects(&eds);
});
