//! A reader and decoder for `candump` text traces, in the layouts candump prints:
//! `  can0  701   [1]  00`, `(000.014403) RX 703 [1]  00  -> comment`, and the compact
//! `(1436509052.249713) can0 701#00`. Trailing comments are ignored. **non-RT**.

use canopen_rs::nmt::{NmtCommand, NmtState};
use canopen_rs::EmergencyMessage;

use super::cob::{classify, CobKind};

/// One frame of a trace.
#[derive(Debug, Clone, PartialEq)]
pub struct TraceFrame {
    /// 1-based line number in the trace.
    pub line: usize,
    /// Timestamp in seconds, when the trace has one.
    pub time_s: Option<f64>,
    /// 11-bit identifier.
    pub cob_id: u16,
    /// Data bytes (`len() == dlc`).
    pub data: Vec<u8>,
}

/// A malformed trace line.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("trace line {line}: {reason}: {text:?}")]
pub struct TraceError {
    /// 1-based line number.
    pub line: usize,
    /// What is wrong.
    pub reason: &'static str,
    /// The line.
    pub text: String,
}

fn hex_byte(t: &str) -> Option<u8> {
    if t.len() == 2 && t.bytes().all(|b| b.is_ascii_hexdigit()) {
        u8::from_str_radix(t, 16).ok()
    } else {
        None
    }
}

/// Parse a candump trace. Lines without a frame (shell prompts, blank lines) are skipped.
pub fn parse_candump(text: &str) -> Result<Vec<TraceFrame>, TraceError> {
    let mut out = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let err = |reason| TraceError {
            line,
            reason,
            text: raw.to_string(),
        };
        let tokens: Vec<&str> = raw.split_whitespace().collect();
        let time_s = tokens
            .first()
            .and_then(|t| t.strip_prefix('(')?.strip_suffix(')')?.parse::<f64>().ok());
        // Compact layout: `id#data`.
        if let Some(tok) = tokens
            .iter()
            .find(|t| t.contains('#') && !t.starts_with('#'))
        {
            let (id, data) = tok.split_once('#').expect("contains #");
            let cob_id = u16::from_str_radix(id, 16).map_err(|_| err("bad identifier"))?;
            if cob_id > 0x7FF {
                return Err(err("identifier above 0x7FF"));
            }
            if data.len() % 2 != 0 || data.len() > 16 {
                return Err(err("bad data field"));
            }
            // Hex digits only: the pairs below are then whole characters.
            if !data.bytes().all(|b| b.is_ascii_hexdigit()) {
                return Err(err("bad data byte"));
            }
            let data = (0..data.len() / 2)
                .map(|k| hex_byte(&data[2 * k..2 * k + 2]))
                .collect::<Option<Vec<u8>>>()
                .ok_or_else(|| err("bad data byte"))?;
            out.push(TraceFrame {
                line,
                time_s,
                cob_id,
                data,
            });
            continue;
        }
        let Some(pos) = tokens
            .iter()
            .position(|t| t.starts_with('[') && t.ends_with(']'))
        else {
            continue;
        };
        let dlc: usize = tokens[pos][1..tokens[pos].len() - 1]
            .parse()
            .map_err(|_| err("bad length field"))?;
        if dlc > 8 {
            return Err(err("length above 8"));
        }
        let id_tok = pos
            .checked_sub(1)
            .map(|p| tokens[p])
            .ok_or_else(|| err("no identifier"))?;
        let cob_id = u16::from_str_radix(id_tok, 16).map_err(|_| err("bad identifier"))?;
        if cob_id > 0x7FF {
            return Err(err("identifier above 0x7FF"));
        }
        let data = tokens
            .get(pos + 1..pos + 1 + dlc)
            .ok_or_else(|| err("fewer data bytes than the length"))?
            .iter()
            .map(|t| hex_byte(t))
            .collect::<Option<Vec<u8>>>()
            .ok_or_else(|| err("bad data byte"))?;
        out.push(TraceFrame {
            line,
            time_s,
            cob_id,
            data,
        });
    }
    Ok(out)
}

/// What a CANopen frame says.
#[derive(Debug, Clone, PartialEq)]
pub enum Message {
    /// NMT node control to `target` (0 = all).
    Nmt {
        /// Command.
        command: NmtCommand,
        /// Target node (0 = broadcast).
        target: u8,
    },
    /// SYNC (with its counter, when present).
    Sync(Option<u8>),
    /// Boot-up of a node.
    BootUp(u8),
    /// Heartbeat of a node.
    Heartbeat(u8, NmtState),
    /// Emergency of a node.
    Emcy(u8, EmergencyMessage),
    /// SDO request to a node (8-byte payload).
    SdoRequest(u8, [u8; 8]),
    /// SDO response of a node.
    SdoResponse(u8, [u8; 8]),
    /// A transmit PDO (0-based number) of a node.
    Tpdo(u8, u8, Vec<u8>),
    /// A receive PDO (0-based number) to a node.
    Rpdo(u8, u8, Vec<u8>),
    /// Not decodable as CANopen (wrong length, unknown COB-ID or value).
    Unknown,
}

/// Decode one frame.
pub fn decode(cob_id: u16, data: &[u8]) -> Message {
    let sdo = |d: &[u8]| -> Option<[u8; 8]> { d.try_into().ok() };
    match classify(cob_id) {
        CobKind::Nmt if data.len() == 2 => match NmtCommand::from_byte(data[0]) {
            Ok(command) => Message::Nmt {
                command,
                target: data[1],
            },
            Err(_) => Message::Unknown,
        },
        CobKind::Sync => match data {
            [] => Message::Sync(None),
            [c] => Message::Sync(Some(*c)),
            _ => Message::Unknown,
        },
        CobKind::Heartbeat(n) if data == [0] => Message::BootUp(n),
        CobKind::Heartbeat(n) if data.len() == 1 => match NmtState::from_wire(data[0]) {
            Ok(s) => Message::Heartbeat(n, s),
            Err(_) => Message::Unknown,
        },
        CobKind::Emcy(n) => match EmergencyMessage::decode(data) {
            Ok(m) => Message::Emcy(n, m),
            Err(_) => Message::Unknown,
        },
        CobKind::SdoRequest(n) => sdo(data).map_or(Message::Unknown, |p| Message::SdoRequest(n, p)),
        CobKind::SdoResponse(n) => {
            sdo(data).map_or(Message::Unknown, |p| Message::SdoResponse(n, p))
        }
        CobKind::Tpdo(k, n) => Message::Tpdo(k, n, data.to_vec()),
        CobKind::Rpdo(k, n) => Message::Rpdo(k, n, data.to_vec()),
        _ => Message::Unknown,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_the_three_candump_layouts_and_ignores_comments() {
        let t = "$ candump can0\n  can0  701   [1]  7F           # Heartbeat\n (000.014403) RX 703 [1]  00   -> pre-op\n(1436509052.249713) can0 181#4006\n  can0  080   [0] \n";
        let f = parse_candump(t).unwrap();
        assert_eq!(f.len(), 4);
        assert_eq!(
            (f[0].cob_id, f[0].data.clone(), f[0].line),
            (0x701, vec![0x7F], 2)
        );
        assert_eq!(f[1].time_s, Some(0.014403));
        assert_eq!((f[2].cob_id, f[2].data.clone()), (0x181, vec![0x40, 0x06]));
        assert_eq!((f[3].cob_id, f[3].data.len()), (0x080, 0));
    }

    #[test]
    fn malformed_lines_are_reported_with_their_number() {
        let e = parse_candump("  can0  701   [2]  7F\n").unwrap_err();
        assert_eq!(e.line, 1);
        assert_eq!(e.reason, "fewer data bytes than the length");
        let e = parse_candump("ok\n  can0  7G1   [1]  7F\n").unwrap_err();
        assert_eq!((e.line, e.reason), (2, "bad identifier"));
        let e = parse_candump("  can0  701   [9]  7F\n").unwrap_err();
        assert_eq!(e.reason, "length above 8");
    }

    #[test]
    fn non_ascii_or_signed_data_bytes_are_bad_data_not_a_panic() {
        // Found by fuzzing (candump_trace): a multi-byte character in a compact data field
        // made the byte pairs split it.
        let e = parse_candump("e A1 a#D\u{1f8}\u{0}\u{11}#").unwrap_err();
        assert_eq!((e.line, e.reason), (1, "bad data byte"));
        let e = parse_candump("(0.5) can0 701#A\u{1f8}1\n").unwrap_err();
        assert_eq!(e.reason, "bad data byte");
        // A sign is not a hex digit, in either layout.
        let e = parse_candump("can0 181#+F00\n").unwrap_err();
        assert_eq!(e.reason, "bad data byte");
        let e = parse_candump("  can0  701   [1]  +F\n").unwrap_err();
        assert_eq!(e.reason, "bad data byte");
    }

    #[test]
    fn compact_frames_keep_to_11_bit_identifiers_like_the_spaced_layout() {
        // Found by fuzzing (candump_trace): `AEA#...` gave a frame with identifier 0xAEA,
        // which no 11-bit COB-ID is.
        let e = parse_candump("$ 0   [24 Aea#D9000100 TX !\u{0}\u{0}3  ").unwrap_err();
        assert_eq!((e.line, e.reason), (1, "identifier above 0x7FF"));
        let e = parse_candump("(1.0) can0 800#00\n").unwrap_err();
        assert_eq!(e.reason, "identifier above 0x7FF");
        let f = parse_candump("(1.0) can0 7FF#00\n").unwrap();
        assert_eq!(f[0].cob_id, 0x7FF);
    }

    #[test]
    fn decodes_nmt_heartbeat_boot_up_and_sync() {
        assert_eq!(
            decode(0x000, &[0x82, 0x03]),
            Message::Nmt {
                command: NmtCommand::ResetCommunication,
                target: 3
            }
        );
        assert_eq!(decode(0x703, &[0x00]), Message::BootUp(3));
        assert_eq!(
            decode(0x701, &[0x05]),
            Message::Heartbeat(1, NmtState::Operational)
        );
        assert_eq!(decode(0x080, &[]), Message::Sync(None));
        assert_eq!(decode(0x701, &[0x33]), Message::Unknown);
    }
}
