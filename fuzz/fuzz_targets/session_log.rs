//! Fuzzes the session-log reader and the replay: arbitrary bytes through
//! `telemetry::parse_log` and the frame walk `telemetry::frames`, and every log the reader
//! accepts through `replay::replay` with the recorded settings (a damaged or hostile log must be
//! read up to its damage or refused, never panic).
//! Frames carry a CRC, which random mutations almost always break; so each input is also read
//! a second time with the CRC of every whole frame recomputed, which lets the fuzzer reach the
//! decoding of the frames' contents (periods, session, calibrations, surfaces, and version 4's
//! compressed blocks) and the replay.
#![no_main]

use libfuzzer_sys::fuzz_target;
use videt_runtime::telemetry::{frames, parse_log, HEADER_BYTES};
use videt_tools::replay::{replay, ReplayOverrides};

const FRAME_HEAD_BYTES: usize = 8;
const FRAME_TAIL_BYTES: usize = 4;

/// `bytes` with the CRC of every frame that fits recomputed (the frame walk of the reader).
fn with_valid_crcs(bytes: &[u8]) -> Vec<u8> {
    let mut out = bytes.to_vec();
    let mut at = HEADER_BYTES;
    while at + FRAME_HEAD_BYTES <= out.len() {
        let len = u32::from_le_bytes(out[at + 4..at + 8].try_into().expect("4 bytes")) as usize;
        let Some(total) = len.checked_add(FRAME_HEAD_BYTES + FRAME_TAIL_BYTES) else {
            break;
        };
        if out.len() - at < total {
            break;
        }
        let crc = crc32fast::hash(&out[at..at + total - FRAME_TAIL_BYTES]);
        out[at + total - FRAME_TAIL_BYTES..at + total].copy_from_slice(&crc.to_le_bytes());
        at += total;
    }
    out
}

fn read_and_replay(bytes: &[u8]) {
    let Ok(log) = parse_log(bytes) else {
        return;
    };
    let _ = log.damage_note();
    let _ = log.end_note();
    // Whole frames are a prefix of the file, one after the other; a closed log's end frame is
    // its last whole frame (in version 4, in its last block).
    let walked = frames(bytes).expect("a log the reader accepts");
    let mut at = HEADER_BYTES;
    for f in &walked {
        assert_eq!(f.offset, at);
        at += f.bytes;
    }
    assert!(at <= bytes.len());
    if log.closed() {
        let end = if log.version >= 4 { 7 } else { 6 };
        assert!(walked.last().is_some_and(|f| f.kind as u8 == end));
    }
    if let Ok(r) = replay(&log, &ReplayOverrides::default()) {
        assert!(r.replayed.len() <= log.records.len());
        if let Some(d) = &r.first_divergence {
            let _ = d.to_string();
        }
    }
}

fuzz_target!(|data: &[u8]| {
    read_and_replay(data);
    let fixed = with_valid_crcs(data);
    if fixed != data {
        read_and_replay(&fixed);
    }
});
