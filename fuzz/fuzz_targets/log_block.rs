//! Fuzzes the decoding of a version 4 block past its compression. Random bytes through
//! `session_log` rarely make a valid zstd stream, so the decoder's own work (undoing each field's
//! prediction, the table's byte planes, the frames of the stream and the periods they pair
//! with) is seldom reached there. Here the input is a block's contents before compression:
//!
//! `[52 prediction codes][u16 LE: frame stream length][frame stream][table of periods]`
//!
//! which the harness compresses and frames as the writer does (a valid CRC), behind a version
//! 4 header, and reads through the session-log reader, the frame walk and the replay: every
//! input reaches the decoder, and a hostile block must be refused or read, never panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
use videt_runtime::telemetry::{frames, parse_log, LogHeader, HEADER_BYTES, MAGIC, PERIOD_BYTES};
use videt_tools::replay::{replay, ReplayOverrides};

/// Fields of a period in the table.
const FIELDS: usize = PERIOD_BYTES / 8;
/// The block frame's kind.
const BLOCK_KIND: u8 = 7;

/// A version 4 log holding the block made of `data`, or `None` when `data` is too short.
fn log_of(data: &[u8]) -> Option<Vec<u8>> {
    let codes = data.get(..FIELDS)?;
    let split = usize::from(u16::from_le_bytes(data.get(FIELDS..FIELDS + 2)?.try_into().ok()?));
    let rest = &data[FIELDS + 2..];
    let (stream, table) = rest.split_at(split.min(rest.len()));
    let rows = table.len() / PERIOD_BYTES;
    let table = &table[..rows * PERIOD_BYTES];
    let packed_stream = zstd::bulk::compress(stream, 1).ok()?;
    let packed_table = zstd::bulk::compress(table, 1).ok()?;
    let mut payload = Vec::new();
    payload.extend_from_slice(&(stream.len() as u32).to_le_bytes());
    payload.extend_from_slice(&(rows as u32).to_le_bytes());
    payload.extend_from_slice(&(packed_stream.len() as u32).to_le_bytes());
    // A code is one of the predictions the field may take (those of the fields before it
    // included), unless its top bit asks for the raw byte (an unknown prediction).
    payload.extend(codes.iter().enumerate().map(|(f, &b)| match b & 0x80 {
        0 => b % (3 + f as u8),
        _ => b & 0x7f,
    }));
    payload.extend_from_slice(&packed_stream);
    payload.extend_from_slice(&packed_table);
    let header = LogHeader {
        rate_hz: 1000,
        start_unix_ns: 0,
    };
    let mut log = vec![0u8; HEADER_BYTES];
    log[0..8].copy_from_slice(MAGIC);
    log[8..12].copy_from_slice(&4u32.to_le_bytes());
    log[12..16].copy_from_slice(&(PERIOD_BYTES as u32).to_le_bytes());
    log[16..20].copy_from_slice(&header.rate_hz.to_le_bytes());
    log[24..32].copy_from_slice(&header.start_unix_ns.to_le_bytes());
    let start = log.len();
    log.extend_from_slice(&[BLOCK_KIND, 0, 0, 0]);
    log.extend_from_slice(&(payload.len() as u32).to_le_bytes());
    log.extend_from_slice(&payload);
    let crc = crc32fast::hash(&log[start..]);
    log.extend_from_slice(&crc.to_le_bytes());
    Some(log)
}

fuzz_target!(|data: &[u8]| {
    let Some(bytes) = log_of(data) else {
        return;
    };
    let Ok(log) = parse_log(&bytes) else {
        return;
    };
    let _ = (log.damage_note(), log.end_note());
    // Read whole or damaged, the walk agrees with the reader on where the block is.
    let walked = frames(&bytes).expect("a log the reader accepts");
    assert!(walked.len() <= 1);
    if let Ok(r) = replay(&log, &ReplayOverrides::default()) {
        assert!(r.replayed.len() <= log.records.len());
    }
});
