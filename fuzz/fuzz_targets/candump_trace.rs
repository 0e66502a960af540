//! Fuzzes the candump trace reader: arbitrary text through `parse_candump` (the three layouts
//! candump prints, comments, timestamps), and every frame it returns through the CANopen
//! decoder `trace::decode` and the readable EMCY / SDO-abort texts.
#![no_main]

use libfuzzer_sys::fuzz_target;
use videt_drivers::canopen::codes::{emcy_description, sdo_abort_description};
use videt_drivers::canopen::trace::{decode, parse_candump, Message};

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(frames) = parse_candump(text) else {
        return;
    };
    for f in &frames {
        // What `TraceFrame` promises: an 11-bit identifier, at most 8 data bytes.
        assert!(
            f.cob_id <= 0x7FF,
            "line {}: identifier {:#x}",
            f.line,
            f.cob_id
        );
        assert!(
            f.data.len() <= 8,
            "line {}: {} data bytes",
            f.line,
            f.data.len()
        );
        match decode(f.cob_id, &f.data) {
            Message::Emcy(_, m) => {
                let _ = emcy_description(m.error_code);
            }
            Message::SdoResponse(_, p) | Message::SdoRequest(_, p) if p[0] == 0x80 => {
                let _ = sdo_abort_description(u32::from_le_bytes([p[4], p[5], p[6], p[7]]));
            }
            m => {
                let _ = format!("{m:?}");
            }
        }
    }
});
