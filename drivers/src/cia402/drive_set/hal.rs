//! The HAL traits the set implements: its error type, the lifecycle (configure, activate,
//! deactivate) and the wire drives of every control cycle (`read_drives`, `write_torques`).

use videt_hal::{DriveSample, Lifecycle, LifecycleState, WireDrives};

use super::Cia402DriveSet;
use crate::can::CanPort;
use crate::canopen::cob;
use crate::cia402::error::DriveError;
use crate::cia402::pdo::Command;
use crate::cia402::state::{controlword, PowerGoal};

impl<P: CanPort, const N: usize> videt_hal::ErrorType for Cia402DriveSet<P, N> {
    type Error = DriveError;
}

impl<P: CanPort, const N: usize> Lifecycle for Cia402DriveSet<P, N> {
    /// Reset the drives' communication, wait for their boot-up, configure them over SDO
    /// (CST mode, PDO mapping, heartbeats, communication-loss reaction), start them and wait
    /// until every drive answers SYNC. Ends `Inactive`.
    fn configure(&mut self) -> Result<(), DriveError> {
        if self.lifecycle == LifecycleState::Active {
            return Err(DriveError::NotReady {
                state: self.lifecycle,
            });
        }
        let outcome = self.configure_inner();
        self.publish_startup_report();
        match outcome {
            Ok(()) => {
                self.lifecycle = LifecycleState::Inactive;
                Ok(())
            }
            Err(e) => {
                self.leave_drives_off();
                self.lifecycle = LifecycleState::Unconfigured;
                Err(e)
            }
        }
    }

    /// Walk every drive to "operation enabled" (resetting a latched fault). Ends `Active`.
    fn activate(&mut self) -> Result<(), DriveError> {
        match self.lifecycle {
            LifecycleState::Inactive | LifecycleState::Faulted => {}
            LifecycleState::Active => return Ok(()),
            state @ LifecycleState::Unconfigured => return Err(DriveError::NotReady { state }),
        }
        self.latched = None;
        match self.power_sequence(PowerGoal::Enabled) {
            Ok(()) => {
                self.lifecycle = LifecycleState::Active;
                Ok(())
            }
            Err(e) => Err(self.fail(e)),
        }
    }

    /// Walk every drive to "switch on disabled". Ends `Inactive`.
    fn deactivate(&mut self) -> Result<(), DriveError> {
        if self.lifecycle == LifecycleState::Unconfigured {
            return Ok(());
        }
        match self.power_sequence(PowerGoal::Disabled) {
            Ok(()) => {
                // The latched error stays readable until the next configure/activate.
                self.lifecycle = LifecycleState::Inactive;
                Ok(())
            }
            Err(e) => Err(self.fail(e)),
        }
    }

    fn lifecycle_state(&self) -> LifecycleState {
        self.lifecycle
    }
}

impl<P: CanPort, const N: usize> WireDrives<N> for Cia402DriveSet<P, N> {
    fn enable(&mut self) -> Result<(), DriveError> {
        self.activate()
    }

    fn disable(&mut self) -> Result<(), DriveError> {
        self.send_safe_commands();
        if self.lifecycle == LifecycleState::Active {
            self.lifecycle = LifecycleState::Inactive;
        }
        Ok(())
    }

    fn read_drives(&mut self, out: &mut [DriveSample; N]) -> Result<(), DriveError> {
        match self.lifecycle {
            LifecycleState::Unconfigured => {
                return Err(DriveError::NotReady {
                    state: self.lifecycle,
                })
            }
            LifecycleState::Faulted => {
                let _ = self.exchange(false);
                for (i, o) in out.iter_mut().enumerate() {
                    *o = self.sample(i);
                }
                self.send_safe_commands();
                return Err(self.latched.unwrap_or(DriveError::NotReady {
                    state: LifecycleState::Faulted,
                }));
            }
            LifecycleState::Inactive | LifecycleState::Active => {}
        }
        let strict = self.lifecycle == LifecycleState::Active;
        let r = self.exchange(strict);
        for (i, o) in out.iter_mut().enumerate() {
            *o = self.sample(i);
        }
        r.map_err(|e| self.fail(e))
    }

    fn write_torques(&mut self, torque_nm: &[f64; N]) -> Result<(), DriveError> {
        if self.lifecycle != LifecycleState::Active {
            if self.lifecycle == LifecycleState::Faulted {
                self.send_safe_commands();
                return Err(self.latched.unwrap_or(DriveError::NotReady {
                    state: self.lifecycle,
                }));
            }
            return Err(DriveError::NotReady {
                state: self.lifecycle,
            });
        }
        let mut permille = [0i16; N];
        for i in 0..N {
            match self.limited_torque(i, torque_nm[i]) {
                Ok(t) if self.cfg.motor_reversed[i] => {
                    permille[i] = self.cfg.torque_to_permille(-t)
                }
                Ok(t) => permille[i] = self.cfg.torque_to_permille(t),
                Err(e) => return Err(self.fail(e)),
            }
        }
        for (i, target) in permille.into_iter().enumerate() {
            let cmd = Command {
                controlword: controlword::ENABLE_OPERATION,
                target_torque_permille: target,
            };
            let cob = cob::RPDO_BASE[0] + u16::from(self.nodes[i].id);
            if let Err(e) = self.send(cob, &cmd.encode()) {
                return Err(self.fail(e));
            }
        }
        Ok(())
    }
}
