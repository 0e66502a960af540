//! The frame carried by the userspace bus: a classic CAN 2.0 frame.

use embedded_can::{ExtendedId, Frame, Id, StandardId};

/// A classic CAN frame (standard or extended id, data or remote, up to 8 bytes). `Copy`, no heap.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SimFrame {
    id: Id,
    remote: bool,
    dlc: u8,
    data: [u8; 8],
}

impl SimFrame {
    /// A standard-id data frame; `None` when `cob_id > 0x7FF` or `data.len() > 8`.
    pub fn standard(cob_id: u16, data: &[u8]) -> Option<SimFrame> {
        SimFrame::new(StandardId::new(cob_id)?, data)
    }

    /// The raw identifier (11 or 29 bits).
    pub fn raw_id(&self) -> u32 {
        match self.id {
            Id::Standard(s) => u32::from(s.as_raw()),
            Id::Extended(e) => e.as_raw(),
        }
    }

    /// Encode into the 16-byte wire format of the cross-process transport:
    /// `[flags, dlc, 0, 0, id u32 LE, data[8]]`, flags bit 0 = extended, bit 1 = remote.
    pub fn to_wire(&self) -> [u8; 16] {
        let mut out = [0u8; 16];
        out[0] = u8::from(self.is_extended()) | (u8::from(self.remote) << 1);
        out[1] = self.dlc;
        out[4..8].copy_from_slice(&self.raw_id().to_le_bytes());
        out[8..16].copy_from_slice(&self.data);
        out
    }

    /// Decode the wire format; `None` for a malformed datagram.
    pub fn from_wire(bytes: &[u8]) -> Option<SimFrame> {
        if bytes.len() != 16 || bytes[0] & !0x03 != 0 || bytes[1] > 8 {
            return None;
        }
        let raw = u32::from_le_bytes([bytes[4], bytes[5], bytes[6], bytes[7]]);
        let id: Id = if bytes[0] & 1 != 0 {
            ExtendedId::new(raw)?.into()
        } else {
            StandardId::new(u16::try_from(raw).ok()?)?.into()
        };
        let dlc = bytes[1] as usize;
        if bytes[0] & 2 != 0 {
            SimFrame::new_remote(id, dlc)
        } else {
            SimFrame::new(id, &bytes[8..8 + dlc])
        }
    }
}

impl Frame for SimFrame {
    fn new(id: impl Into<Id>, data: &[u8]) -> Option<Self> {
        if data.len() > 8 {
            return None;
        }
        let mut buf = [0u8; 8];
        buf[..data.len()].copy_from_slice(data);
        Some(SimFrame {
            id: id.into(),
            remote: false,
            dlc: data.len() as u8,
            data: buf,
        })
    }

    fn new_remote(id: impl Into<Id>, dlc: usize) -> Option<Self> {
        if dlc > 8 {
            return None;
        }
        Some(SimFrame {
            id: id.into(),
            remote: true,
            dlc: dlc as u8,
            data: [0; 8],
        })
    }

    fn is_extended(&self) -> bool {
        matches!(self.id, Id::Extended(_))
    }

    fn is_remote_frame(&self) -> bool {
        self.remote
    }

    fn id(&self) -> Id {
        self.id
    }

    fn dlc(&self) -> usize {
        self.dlc as usize
    }

    fn data(&self) -> &[u8] {
        if self.remote {
            &[]
        } else {
            &self.data[..self.dlc as usize]
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wire_format_round_trips_standard_extended_and_remote_frames() {
        let frames = [
            SimFrame::standard(0x181, &[1, 2, 3, 4, 5, 6, 7, 8]).unwrap(),
            SimFrame::standard(0x080, &[]).unwrap(),
            SimFrame::new(ExtendedId::new(0x1234_5678).unwrap(), &[9]).unwrap(),
            SimFrame::new_remote(StandardId::new(0x701).unwrap(), 1).unwrap(),
        ];
        for f in frames {
            assert_eq!(SimFrame::from_wire(&f.to_wire()), Some(f));
        }
    }

    #[test]
    fn malformed_wire_datagrams_are_rejected() {
        let mut w = SimFrame::standard(0x181, &[1]).unwrap().to_wire();
        w[1] = 9;
        assert_eq!(SimFrame::from_wire(&w), None);
        assert_eq!(SimFrame::from_wire(&w[..15]), None);
        let mut w = SimFrame::standard(0x181, &[1]).unwrap().to_wire();
        w[4..8].copy_from_slice(&0x800u32.to_le_bytes());
        assert_eq!(SimFrame::from_wire(&w), None);
    }

    #[test]
    fn oversized_payloads_and_ids_are_refused() {
        assert!(SimFrame::standard(0x800, &[]).is_none());
        assert!(SimFrame::standard(0x100, &[0; 9]).is_none());
    }
}
