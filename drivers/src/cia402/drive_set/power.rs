//! Walking every drive through the CiA 402 power state machine to a goal (operation enabled
//! or switch on disabled), cycling at the control period (not on the real-time path).

use std::time::Instant;

use super::Cia402DriveSet;
use crate::can::CanPort;
use crate::canopen::cob;
use crate::cia402::error::DriveError;
use crate::cia402::pdo::Command;
use crate::cia402::state::{PowerGoal, PowerSequencer};

/// Fault-reset edges tried when enabling a faulted drive.
const MAX_FAULT_RESETS: u32 = 3;

impl<P: CanPort, const N: usize> Cia402DriveSet<P, N> {
    /// Run every drive's power sequencer to `goal`, cycling at the control period.
    pub(super) fn power_sequence(&mut self, goal: PowerGoal) -> Result<(), DriveError> {
        let t0 = Instant::now();
        let now_ns = |t: Instant| t.duration_since(t0).as_nanos() as u64;
        let timeout_ns = self.cfg.power_timeout.as_nanos() as u64;
        let mut seq = [PowerSequencer::new(goal, 0, timeout_ns, MAX_FAULT_RESETS); N];
        for n in &mut self.nodes {
            n.emcy = None;
        }
        loop {
            let cycle_start = Instant::now();
            self.exchange(false)?;
            let mut all = true;
            for (i, sequencer) in seq.iter_mut().enumerate() {
                let step = sequencer
                    .step(self.nodes[i].status.statusword, now_ns(Instant::now()))
                    .map_err(|e| {
                        DriveError::from_power(
                            i as u8,
                            self.nodes[i].id,
                            e,
                            self.nodes[i].status.error_code,
                        )
                    })?;
                all &= step.reached;
                let cmd = Command {
                    controlword: step.controlword,
                    target_torque_permille: 0,
                };
                let cob = cob::RPDO_BASE[0] + u16::from(self.nodes[i].id);
                self.send(cob, &cmd.encode())?;
            }
            if all {
                return Ok(());
            }
            self.sleep_rest_of_cycle(cycle_start);
        }
    }
}
