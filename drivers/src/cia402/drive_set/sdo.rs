//! SDO transfers with one drive (not on the real-time path): a request, its answer within
//! `sdo_timeout`, every other frame received meanwhile book-kept as usual.

use std::time::Instant;

use canopen_rs::sdo::{SdoEvent, SdoPayload};
use canopen_rs::{Address, DataType, NodeId, SdoClient, Value};
use embedded_can::{Frame, Id};

use super::Cia402DriveSet;
use crate::can::CanPort;
use crate::canopen::cob;
use crate::cia402::error::DriveError;

impl<P: CanPort, const N: usize> Cia402DriveSet<P, N> {
    fn sdo(
        &mut self,
        i: usize,
        client: &mut SdoClient,
        first: SdoPayload,
        addr: Address,
    ) -> Result<Option<Value>, DriveError> {
        let node = self.nodes[i].id;
        let req = cob::SDO_REQUEST_BASE + u16::from(node);
        let resp = cob::SDO_RESPONSE_BASE + u16::from(node);
        let mut payload = first;
        loop {
            self.send(req, &payload)?;
            let deadline = Instant::now() + self.cfg.sdo_timeout;
            let answer = loop {
                let now = Instant::now();
                if now >= deadline {
                    return Err(DriveError::SdoTimeout {
                        wire: i as u8,
                        node,
                        index: addr.index,
                        subindex: addr.subindex,
                    });
                }
                let Some(f) = self.receive(deadline - now)? else {
                    continue;
                };
                match f.id() {
                    Id::Standard(id) if id.as_raw() == resp && f.data().len() == 8 => {
                        let mut p = [0u8; 8];
                        p.copy_from_slice(f.data());
                        break p;
                    }
                    _ => self.absorb(&f, false, Instant::now()),
                }
            };
            match client.on_response(&answer) {
                SdoEvent::Send(next) => payload = next,
                SdoEvent::Complete(v) => return Ok(v),
                SdoEvent::Aborted(code) => {
                    return Err(DriveError::SdoAbort {
                        wire: i as u8,
                        node,
                        index: addr.index,
                        subindex: addr.subindex,
                        code,
                    })
                }
            }
        }
    }

    pub(super) fn sdo_write(
        &mut self,
        i: usize,
        addr: Address,
        value: Value,
    ) -> Result<(), DriveError> {
        let mut client = SdoClient::new(NodeId::new(self.nodes[i].id).unwrap_or(NodeId::BROADCAST));
        let first = client.write(addr, value);
        self.sdo(i, &mut client, first, addr).map(|_| ())
    }

    pub(super) fn sdo_read(
        &mut self,
        i: usize,
        addr: Address,
        ty: DataType,
    ) -> Result<Value, DriveError> {
        let mut client = SdoClient::new(NodeId::new(self.nodes[i].id).unwrap_or(NodeId::BROADCAST));
        let first = client.read(addr, ty);
        self.sdo(i, &mut client, first, addr)?
            .ok_or(DriveError::SdoUnexpectedValue {
                wire: i as u8,
                node: self.nodes[i].id,
                index: addr.index,
            })
    }
}
