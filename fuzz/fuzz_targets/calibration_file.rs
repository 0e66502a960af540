//! Fuzzes the rig calibration file and the tension-sensor calibration file: arbitrary text
//! through `Calibration::from_text` and `TensionCalibration::from_text` (what `load` runs after
//! reading the file): the checksum line, TOML parsing and the range checks. Inputs get a valid
//! checksum line appended half of the time, so the TOML and validation code is reached too.
#![no_main]

use libfuzzer_sys::fuzz_target;
use videt_config::calibration::{Calibration, TensionCalibration};

/// FNV-1a 64, as the files' checksum line.
fn fnv1a64(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in bytes {
        h ^= u64::from(*b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

fn check(text: &str) {
    if let Ok(c) = Calibration::from_text(text, "fuzz") {
        // An accepted file round-trips.
        let again = c.to_text().expect("an accepted calibration serialises");
        let back = Calibration::from_text(&again, "fuzz").expect("its own text reads back");
        assert_eq!(back, c);
        let _ = c.length_at_zero_m();
    }
    if let Ok(t) = TensionCalibration::from_text(text, "fuzz") {
        for i in 0..3 {
            let _ = t.correct(i, 1.0);
        }
    }
}

fuzz_target!(|data: &[u8]| {
    let Some((&mode, rest)) = data.split_first() else {
        return;
    };
    let Ok(text) = std::str::from_utf8(rest) else {
        return;
    };
    if mode & 1 == 0 {
        check(text);
    } else {
        // The body as given, with its correct checksum line.
        let mut body = text.to_string();
        if !body.is_empty() && !body.ends_with('\n') {
            body.push('\n');
        }
        let line = format!("checksum = \"fnv1a64:{:016x}\"\n", fnv1a64(body.as_bytes()));
        check(&(body + &line));
    }
});
