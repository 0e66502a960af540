//! Bringing the drives up (not on the real-time path): reset their communication, await their
//! boot-up, configure each over SDO (CST mode, PDO mapping, heartbeats, communication-loss
//! reaction, unused PDOs off, polarity), start them and cycle until every drive answers SYNC;
//! after a refused start, leave them off.

use std::time::{Duration, Instant};

use canopen_rs::nmt::NmtCommand;
use canopen_rs::{Address, DataType, Value};

use super::node::NodeLink;
use super::Cia402DriveSet;
use crate::can::CanPort;
use crate::canopen::cob;
use crate::canopen::objects::{is_optional, is_pdo_mapping, means_absent, UNUSED_PDOS};
use crate::cia402::error::DriveError;
use crate::cia402::identity::StartupReport;
use crate::cia402::pdo::DriveSetup;

/// COB-ID bit 31: the PDO is disabled.
const PDO_INVALID: u32 = 0x8000_0000;
/// The polarity object of CiA 402.
const POLARITY: u16 = 0x607E;
/// Its bit that negates the position (demand and actual values).
const POLARITY_POSITION: u8 = 1 << 7;
/// Its bit that negates the velocity (demand and actual values).
const POLARITY_VELOCITY: u8 = 1 << 6;

impl<P: CanPort, const N: usize> Cia402DriveSet<P, N> {
    fn nmt(&mut self, command: NmtCommand, node: u8) -> Result<(), DriveError> {
        self.send(cob::NMT, &[command as u8, node])
    }

    pub(super) fn configure_inner(&mut self) -> Result<(), DriveError> {
        self.operational_expected = false;
        self.latched = None;
        self.gathering = StartupReport::default();
        let now = Instant::now();
        for i in 0..N {
            self.nodes[i] = NodeLink::new(self.cfg.node_ids[i], i, now);
        }
        // Drain whatever is queued, then reset communication so every drive boots afresh.
        while self.receive(Duration::ZERO)?.is_some() {}
        for i in 0..N {
            self.nmt(NmtCommand::ResetCommunication, self.nodes[i].id)?;
        }
        let start = Instant::now();
        let deadline = start + self.cfg.boot_timeout;
        while !self.nodes.iter().all(|n| n.booted) {
            let now = Instant::now();
            if now >= deadline {
                let missing = self.nodes.iter().find(|n| !n.booted);
                return Err(DriveError::NeverBooted {
                    wire: missing.map_or(0, |n| n.wire),
                    node: missing.map_or(0, |n| n.id),
                    waited_ms: (now - start).as_millis() as u64,
                });
            }
            if let Some(f) = self.receive(deadline - now)? {
                self.absorb(&f, false, Instant::now());
            }
        }
        let max_permille = self
            .cfg
            .torque_to_permille(self.cfg.max_torque_nm())
            .unsigned_abs()
            .max(1);
        for i in 0..N {
            self.identify(i)?;
            if self.cfg.verify_rated_torque {
                self.check_rated_torque(i)?;
            }
            let setup = DriveSetup {
                node_id: self.nodes[i].id,
                host_node_id: self.cfg.host_node_id,
                drive_heartbeat_ms: self.cfg.drive_heartbeat_ms,
                host_silence_timeout_ms: self.cfg.host_silence_timeout_ms,
                comm_loss_reaction: self.cfg.comm_loss_reaction,
                max_torque_permille: max_permille,
                analog_input: self.cfg.analog_input,
                status_event_timer_ms: self.cfg.status_event_timer_ms,
            };
            for (addr, value) in setup.sdo_writes() {
                match self.sdo_write(i, addr, value) {
                    // An object the driver can do without (the drive-side torque limit, the
                    // status event timer, the communication-loss reaction): told, not fatal.
                    Err(DriveError::SdoAbort {
                        index,
                        subindex,
                        code,
                        ..
                    }) if means_absent(code) && is_optional(index, subindex) => {
                        self.note(i, index, subindex, code)
                    }
                    // A refused mapping entry names the object it was to carry.
                    Err(DriveError::SdoAbort {
                        index,
                        subindex,
                        code,
                        ..
                    }) if is_pdo_mapping(index) && subindex >= 1 => {
                        let entry = match value {
                            Value::Unsigned32(e) => e,
                            _ => 0,
                        };
                        return Err(DriveError::MappingRefused {
                            wire: i as u8,
                            node: self.nodes[i].id,
                            index,
                            subindex,
                            entry,
                            code,
                        });
                    }
                    r => r?,
                }
            }
            self.disable_unused_pdos(i)?;
            self.set_polarity(i)?;
        }
        // Host heartbeat first, so the drives' consumers start on a live host.
        self.host_heartbeat_due = Instant::now();
        for i in 0..N {
            self.nmt(NmtCommand::StartRemoteNode, self.nodes[i].id)?;
        }
        // Cycle until every drive is operational and has answered SYNC (each its own SYNC: a
        // drive late now and then is the supervision's business, not start-up's).
        for n in &mut self.nodes {
            n.status_heard = None;
        }
        let start = Instant::now();
        let status_every_sync = self.cfg.analog_input.is_some();
        let mut answered = [false; N];
        let mut last_err;
        loop {
            let cycle_start = Instant::now();
            for n in &mut self.nodes {
                n.missed = 0;
                n.overspeed_cycles = 0;
            }
            let outcome = self.exchange(false);
            for (a, n) in answered.iter_mut().zip(&self.nodes) {
                *a |= n.has_cycle_data(status_every_sync);
            }
            match outcome {
                Ok(()) if answered.iter().all(|&a| a) => break,
                Ok(()) => last_err = None,
                Err(e) => last_err = Some(e),
            }
            if cycle_start - start > self.cfg.boot_timeout {
                let silent = self
                    .nodes
                    .iter()
                    .zip(answered)
                    .find(|(_, a)| !a)
                    .map(|(n, _)| n);
                return Err(last_err.unwrap_or(DriveError::NoProcessData {
                    wire: silent.map_or(0, |n| n.wire),
                    node: silent.map_or(0, |n| n.id),
                    waited_ms: (cycle_start - start).as_millis() as u64,
                    motion: silent.is_some_and(|n| n.got_motion),
                    status: silent.is_some_and(|n| n.status_heard.is_some()),
                }));
            }
            self.sleep_rest_of_cycle(cycle_start);
        }
        self.operational_expected = true;
        Ok(())
    }

    /// Disable every PDO of drive `i` the driver does not use ([`UNUSED_PDOS`]) that its own
    /// configuration left enabled (a DCF may keep TPDO3 sending at every SYNC): its COB-ID is
    /// written back with the "invalid" bit set, the CAN-ID unchanged as CiA 301 requires. A
    /// drive without such a PDO has nothing to disable.
    fn disable_unused_pdos(&mut self, i: usize) -> Result<(), DriveError> {
        for comm in UNUSED_PDOS {
            let addr = Address::new(comm, 1);
            let cob = match self.sdo_read(i, addr, DataType::Unsigned32) {
                Ok(Value::Unsigned32(cob)) => cob,
                Ok(_) => continue,
                Err(DriveError::SdoAbort { code, .. }) if means_absent(code) => continue,
                Err(e) => return Err(e),
            };
            if cob & PDO_INVALID == 0 {
                self.sdo_write(i, addr, Value::Unsigned32(cob | PDO_INVALID))?;
            }
        }
        Ok(())
    }

    /// Drive `i`'s position and velocity polarity (0x607E bits 7 and 6, the other bits kept)
    /// as `encoder_reversed` says, at every start: the configuration decides the direction,
    /// whatever the drive kept from before. A drive without the object has its position and
    /// velocity negated by the set instead (and a note when that matters).
    fn set_polarity(&mut self, i: usize) -> Result<(), DriveError> {
        let reversed = self.cfg.encoder_reversed[i];
        let addr = Address::new(POLARITY, 0);
        let current = match self.sdo_read(i, addr, DataType::Unsigned8) {
            Ok(Value::Unsigned8(v)) => Some(v),
            Ok(_) => None,
            Err(DriveError::SdoAbort {
                index,
                subindex,
                code,
                ..
            }) if means_absent(code) => {
                if reversed {
                    self.note(i, index, subindex, code);
                }
                None
            }
            Err(e) => return Err(e),
        };
        let Some(current) = current else {
            self.nodes[i].encoder_sign = if reversed { -1.0 } else { 1.0 };
            return Ok(());
        };
        let bits = POLARITY_POSITION | POLARITY_VELOCITY;
        let wanted = if reversed {
            current | bits
        } else {
            current & !bits
        };
        if wanted != current {
            self.sdo_write(i, addr, Value::Unsigned8(wanted))?;
        }
        self.nodes[i].encoder_sign = 1.0;
        Ok(())
    }

    /// After a refused start: every drive commanded off with zero torque and back to
    /// pre-operational, so nothing is left enabled or exchanging process data. Errors of the
    /// bus are ignored: it may be why the start failed.
    pub(super) fn leave_drives_off(&mut self) {
        self.send_safe_commands();
        for i in 0..N {
            let _ = self.nmt(NmtCommand::EnterPreOperational, self.nodes[i].id);
        }
    }
}
