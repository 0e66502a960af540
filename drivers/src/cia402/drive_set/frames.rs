//! The set's CAN frame I/O: sending a frame, receiving one within a timeout, the bus errors
//! either meets, and the book-keeping of every received frame (heartbeats, EMCYs, TPDOs) into
//! the drives' links.

use std::time::{Duration, Instant};

use canopen_rs::EmergencyMessage;
use embedded_can::{Frame, Id, StandardId};

use super::Cia402DriveSet;
use crate::can::CanPort;
use crate::canopen::cob::{classify, CobKind};
use crate::cia402::error::DriveError;
use crate::cia402::pdo::{Motion, MotionWithAnalog, Status};

impl<P: CanPort, const N: usize> Cia402DriveSet<P, N> {
    fn bus_error(&self, e: &P::Error) -> DriveError {
        if self.port.is_bus_off() {
            DriveError::BusOff
        } else if let Some(errno) = P::os_error(e) {
            DriveError::BusIo { errno }
        } else {
            DriveError::Bus(embedded_can::Error::kind(e))
        }
    }

    pub(super) fn send(&mut self, cob_id: u16, data: &[u8]) -> Result<(), DriveError> {
        // COB-IDs are built here from validated node ids: always below 0x800.
        let id = StandardId::new(cob_id).unwrap_or(StandardId::ZERO);
        let Some(frame) = P::Frame::new(id, data) else {
            return Err(DriveError::Bus(embedded_can::ErrorKind::Other));
        };
        self.port.transmit(&frame).map_err(|e| self.bus_error(&e))
    }

    pub(super) fn receive(&mut self, timeout: Duration) -> Result<Option<P::Frame>, DriveError> {
        self.port
            .receive_timeout(timeout)
            .map_err(|e| self.bus_error(&e))
    }

    fn node_index(&self, id: u8) -> Option<usize> {
        self.nodes.iter().position(|n| n.id == id)
    }

    /// Book-keep one received frame. `fresh` marks frames of the current cycle (after SYNC).
    pub(super) fn absorb(&mut self, frame: &P::Frame, fresh: bool, now: Instant) {
        let Id::Standard(id) = frame.id() else {
            return;
        };
        let data = frame.data();
        match classify(id.as_raw()) {
            CobKind::Heartbeat(n) => {
                let Some(i) = self.node_index(n) else { return };
                let node = &mut self.nodes[i];
                node.last_heard = now;
                if let [state] = data {
                    if *state == 0 {
                        node.booted = true;
                        if self.operational_expected {
                            node.rebooted = true;
                        }
                    }
                    node.nmt_state = state & 0x7F;
                }
            }
            CobKind::Emcy(n) => {
                let Some(i) = self.node_index(n) else { return };
                if let Ok(m) = EmergencyMessage::decode(data) {
                    self.nodes[i].emcy = if m.is_error_reset() {
                        None
                    } else {
                        Some((m.error_code, m.error_register.0))
                    };
                }
            }
            CobKind::Tpdo(0, n) => {
                let Some(i) = self.node_index(n) else { return };
                let sync_at = self.sync_sent_at;
                let node = &mut self.nodes[i];
                if self.cfg.analog_input.is_some() {
                    // Only the configured layout is accepted.
                    if let Some(m) = MotionWithAnalog::decode(data) {
                        node.track_position(m.position);
                        node.derive_velocity(sync_at);
                        node.status.statusword = m.statusword;
                        node.analog_input = m.analog_input;
                        node.got_motion |= fresh;
                        node.got_status |= fresh;
                        node.status_heard = Some(now);
                    }
                } else if let Some(m) = Motion::decode(data) {
                    node.track_position(m.position);
                    node.motion = m;
                    node.got_motion |= fresh;
                }
            }
            CobKind::Tpdo(1, n) => {
                let Some(i) = self.node_index(n) else { return };
                if let Some(status) = Status::decode(data) {
                    let node = &mut self.nodes[i];
                    node.status = status;
                    node.got_status |= fresh;
                    node.status_heard = Some(now);
                }
            }
            _ => {}
        }
    }
}
