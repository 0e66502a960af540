//! Faults posted to a running twin from another thread — a soak harness through the service's
//! control socket, a test — and applied by the twin at its next physics step. Wait-free on both
//! sides: a fixed set of atomic slots, no allocation, no lock on the thread that steps the twin.

use std::sync::atomic::{AtomicU64, Ordering};

use crate::fault::TwinFault;

/// What can be posted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InboxFault {
    /// A fault ([`TwinFault`]).
    Fault(TwinFault),
    /// The failed tension sensor works again.
    RestoreTensionSensor,
    /// The e-stop button is released (its latch stays until reset).
    ReleaseEStop,
}

/// Slots of a [`FaultInbox`].
pub const INBOX_SLOTS: usize = 8;

/// The inbox (share it with `Arc`).
#[derive(Debug, Default)]
pub struct FaultInbox {
    slots: [AtomicU64; INBOX_SLOTS],
    applied: AtomicU64,
    last_applied_ns: AtomicU64,
}

/// The inbox is full: the twin has not stepped since the last [`INBOX_SLOTS`] posts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct InboxFull;

fn encode(f: InboxFault) -> u64 {
    let (kind, wire, value) = match f {
        InboxFault::Fault(TwinFault::BreakWire(w)) => (1, w, 0),
        InboxFault::Fault(TwinFault::PressEStop) => (2, 0, 0),
        InboxFault::Fault(TwinFault::FailTensionSensor(w)) => (3, w, 0),
        InboxFault::Fault(TwinFault::FaultDrive(w)) => (4, w, 0),
        InboxFault::Fault(TwinFault::DetachWire(w)) => (5, w, 0),
        InboxFault::Fault(TwinFault::SlipWire(w, counts)) => (6, w, counts),
        InboxFault::RestoreTensionSensor => (7, 0, 0),
        InboxFault::ReleaseEStop => (8, 0, 0),
    };
    // Slip counts keep 48 bits (±1.4e14 counts: kilometres of wire).
    kind | ((wire.min(255) as u64) << 8) | ((value as u64) << 16)
}

fn decode(code: u64) -> Option<InboxFault> {
    let wire = ((code >> 8) & 0xff) as usize;
    let value = (code as i64) >> 16;
    Some(match code & 0xff {
        1 => InboxFault::Fault(TwinFault::BreakWire(wire)),
        2 => InboxFault::Fault(TwinFault::PressEStop),
        3 => InboxFault::Fault(TwinFault::FailTensionSensor(wire)),
        4 => InboxFault::Fault(TwinFault::FaultDrive(wire)),
        5 => InboxFault::Fault(TwinFault::DetachWire(wire)),
        6 => InboxFault::Fault(TwinFault::SlipWire(wire, value)),
        7 => InboxFault::RestoreTensionSensor,
        8 => InboxFault::ReleaseEStop,
        _ => return None,
    })
}

impl FaultInbox {
    /// Post `fault`; it is applied at the twin's next step.
    pub fn post(&self, fault: InboxFault) -> Result<(), InboxFull> {
        let code = encode(fault);
        for slot in &self.slots {
            if slot
                .compare_exchange(0, code, Ordering::AcqRel, Ordering::Relaxed)
                .is_ok()
            {
                return Ok(());
            }
        }
        Err(InboxFull)
    }

    /// Posted faults applied so far.
    pub fn applied(&self) -> u64 {
        self.applied.load(Ordering::Acquire)
    }

    /// When the last one was applied, nanoseconds on the twin's clock.
    pub fn last_applied_ns(&self) -> u64 {
        self.last_applied_ns.load(Ordering::Acquire)
    }

    /// Whether anything waits to be applied. **RT-safe**.
    pub(crate) fn has_posts(&self) -> bool {
        self.slots.iter().any(|s| s.load(Ordering::Relaxed) != 0)
    }

    /// Take what was posted (called by the twin). **RT-safe**.
    pub(crate) fn take(&self, now_ns: u64, mut apply: impl FnMut(InboxFault)) {
        for slot in &self.slots {
            if slot.load(Ordering::Relaxed) == 0 {
                continue;
            }
            if let Some(f) = decode(slot.swap(0, Ordering::AcqRel)) {
                apply(f);
                self.last_applied_ns.store(now_ns, Ordering::Release);
                self.applied.fetch_add(1, Ordering::AcqRel);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn faults_round_trip_and_a_full_inbox_says_so() {
        let all = [
            InboxFault::Fault(TwinFault::BreakWire(2)),
            InboxFault::Fault(TwinFault::PressEStop),
            InboxFault::Fault(TwinFault::FailTensionSensor(1)),
            InboxFault::Fault(TwinFault::FaultDrive(0)),
            InboxFault::Fault(TwinFault::DetachWire(1)),
            InboxFault::Fault(TwinFault::SlipWire(2, -123_456)),
            InboxFault::RestoreTensionSensor,
            InboxFault::ReleaseEStop,
        ];
        let inbox = FaultInbox::default();
        for f in all {
            inbox.post(f).unwrap();
        }
        assert_eq!(inbox.post(InboxFault::ReleaseEStop), Err(InboxFull));
        let mut taken = Vec::new();
        inbox.take(77, |f| taken.push(f));
        assert_eq!(taken, all);
        assert_eq!((inbox.applied(), inbox.last_applied_ns()), (8, 77));
        inbox.take(78, |_| panic!("empty"));
    }
}
