//! Fuzzes the stereo calibration file: arbitrary text through `CalibratedRig::from_text` (what
//! `CalibratedRig::load` runs after reading the file): JSON parsing, validation, the rectified
//! geometry and the remap tables of both cameras, whose size the file gives.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use videt_service::camera_relief::CalibratedRig;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(rig) = CalibratedRig::from_text(text, Path::new("fuzz.json")) {
        assert!(rig.size_px[0] > 0 && rig.size_px[1] > 0);
    }
});
