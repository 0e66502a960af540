//! COB-IDs of the predefined connection set (CiA 301 §7.3.3) and frame classification.

/// NMT node control (master → nodes).
pub const NMT: u16 = 0x000;
/// SYNC.
pub const SYNC: u16 = 0x080;
/// EMCY base (+ node id).
pub const EMCY_BASE: u16 = 0x080;
/// TPDO1..4 bases (+ node id), node → master.
pub const TPDO_BASE: [u16; 4] = [0x180, 0x280, 0x380, 0x480];
/// RPDO1..4 bases (+ node id), master → node.
pub const RPDO_BASE: [u16; 4] = [0x200, 0x300, 0x400, 0x500];
/// SDO server → client (+ node id).
pub const SDO_RESPONSE_BASE: u16 = 0x580;
/// SDO client → server (+ node id).
pub const SDO_REQUEST_BASE: u16 = 0x600;
/// Heartbeat / boot-up (+ node id).
pub const HEARTBEAT_BASE: u16 = 0x700;

/// What a COB-ID carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CobKind {
    /// NMT node control.
    Nmt,
    /// SYNC.
    Sync,
    /// Emergency from a node.
    Emcy(u8),
    /// Transmit PDO `n` (0-based) from a node.
    Tpdo(u8, u8),
    /// Receive PDO `n` (0-based) to a node.
    Rpdo(u8, u8),
    /// SDO response from a node.
    SdoResponse(u8),
    /// SDO request to a node.
    SdoRequest(u8),
    /// Heartbeat or boot-up of a node.
    Heartbeat(u8),
    /// Anything else (TIME, LSS, manufacturer COB-IDs).
    Other,
}

/// Classify an 11-bit COB-ID.
pub fn classify(cob_id: u16) -> CobKind {
    let node = (cob_id & 0x7F) as u8;
    let function = cob_id & 0x780;
    match (function, node) {
        (0x000, 0) => CobKind::Nmt,
        (0x080, 0) => CobKind::Sync,
        (0x080, n) => CobKind::Emcy(n),
        (0x180, n) if n > 0 => CobKind::Tpdo(0, n),
        (0x280, n) if n > 0 => CobKind::Tpdo(1, n),
        (0x380, n) if n > 0 => CobKind::Tpdo(2, n),
        (0x480, n) if n > 0 => CobKind::Tpdo(3, n),
        (0x200, n) if n > 0 => CobKind::Rpdo(0, n),
        (0x300, n) if n > 0 => CobKind::Rpdo(1, n),
        (0x400, n) if n > 0 => CobKind::Rpdo(2, n),
        (0x500, n) if n > 0 => CobKind::Rpdo(3, n),
        (0x580, n) if n > 0 => CobKind::SdoResponse(n),
        (0x600, n) if n > 0 => CobKind::SdoRequest(n),
        (0x700, n) if n > 0 => CobKind::Heartbeat(n),
        _ => CobKind::Other,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn classifies_the_predefined_connection_set() {
        assert_eq!(classify(0x000), CobKind::Nmt);
        assert_eq!(classify(0x080), CobKind::Sync);
        assert_eq!(classify(0x083), CobKind::Emcy(3));
        assert_eq!(classify(0x181), CobKind::Tpdo(0, 1));
        assert_eq!(classify(0x481), CobKind::Tpdo(3, 1));
        assert_eq!(classify(0x201), CobKind::Rpdo(0, 1));
        assert_eq!(classify(0x581), CobKind::SdoResponse(1));
        assert_eq!(classify(0x603), CobKind::SdoRequest(3));
        assert_eq!(classify(0x77F), CobKind::Heartbeat(127));
        assert_eq!(classify(0x100), CobKind::Other);
        assert_eq!(classify(0x7E5), CobKind::Other); // LSS
    }
}
