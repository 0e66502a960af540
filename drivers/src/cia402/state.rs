//! The CiA 402 power state machine, pure: statusword decoding, controlword commands, and a
//! sequencer that walks a drive to a goal state one controlword per cycle with a timeout.
//! No I/O and no clock: the caller passes the statusword it received and the time.

/// Power state decoded from the statusword (0x6041), CiA 402 §6.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PowerState {
    /// Not ready to switch on (drive initialising).
    NotReadyToSwitchOn,
    /// Switch on disabled (no power stage).
    SwitchOnDisabled,
    /// Ready to switch on.
    ReadyToSwitchOn,
    /// Switched on (power stage on, no torque).
    SwitchedOn,
    /// Operation enabled (torque follows the target).
    OperationEnabled,
    /// Quick stop active.
    QuickStopActive,
    /// Fault reaction active.
    FaultReactionActive,
    /// Fault (latched).
    Fault,
}

impl PowerState {
    /// Decode the state bits (0, 1, 2, 3, 5, 6) of a statusword.
    pub const fn from_statusword(sw: u16) -> PowerState {
        if sw & 0x004F == 0x0000 {
            PowerState::NotReadyToSwitchOn
        } else if sw & 0x004F == 0x0040 {
            PowerState::SwitchOnDisabled
        } else if sw & 0x006F == 0x0021 {
            PowerState::ReadyToSwitchOn
        } else if sw & 0x006F == 0x0023 {
            PowerState::SwitchedOn
        } else if sw & 0x006F == 0x0027 {
            PowerState::OperationEnabled
        } else if sw & 0x006F == 0x0007 {
            PowerState::QuickStopActive
        } else if sw & 0x004F == 0x000F {
            PowerState::FaultReactionActive
        } else if sw & 0x004F == 0x0008 {
            PowerState::Fault
        } else {
            // Bit patterns outside the table (e.g. 0x0001): treat as not ready.
            PowerState::NotReadyToSwitchOn
        }
    }

    /// A short lower-case name for messages.
    pub const fn as_str(self) -> &'static str {
        match self {
            PowerState::NotReadyToSwitchOn => "not ready to switch on",
            PowerState::SwitchOnDisabled => "switch on disabled",
            PowerState::ReadyToSwitchOn => "ready to switch on",
            PowerState::SwitchedOn => "switched on",
            PowerState::OperationEnabled => "operation enabled",
            PowerState::QuickStopActive => "quick stop active",
            PowerState::FaultReactionActive => "fault reaction active",
            PowerState::Fault => "fault",
        }
    }

    /// The HAL's coarse view of this state.
    pub const fn to_hal(self) -> videt_hal::DriveState {
        match self {
            PowerState::OperationEnabled => videt_hal::DriveState::Enabled,
            PowerState::QuickStopActive => videt_hal::DriveState::QuickStop,
            PowerState::Fault | PowerState::FaultReactionActive => videt_hal::DriveState::Fault,
            _ => videt_hal::DriveState::Disabled,
        }
    }
}

/// Statusword bit 7: warning.
pub const SW_WARNING: u16 = 1 << 7;
/// Statusword bit 4: voltage enabled.
pub const SW_VOLTAGE_ENABLED: u16 = 1 << 4;

/// Controlword (0x6040) device-control commands, CiA 402 Table 31.
pub mod controlword {
    /// Shutdown: → ready to switch on.
    pub const SHUTDOWN: u16 = 0x0006;
    /// Switch on: → switched on.
    pub const SWITCH_ON: u16 = 0x0007;
    /// Enable operation: → operation enabled.
    pub const ENABLE_OPERATION: u16 = 0x000F;
    /// Disable voltage: → switch on disabled (power stage off).
    pub const DISABLE_VOLTAGE: u16 = 0x0000;
    /// Quick stop: → quick stop active.
    pub const QUICK_STOP: u16 = 0x0002;
    /// Disable operation: → switched on.
    pub const DISABLE_OPERATION: u16 = 0x0007;
    /// Fault reset (acts on the rising edge of bit 7).
    pub const FAULT_RESET: u16 = 0x0080;
}

/// Where the sequencer should take the drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PowerGoal {
    /// Operation enabled (resetting a latched fault on the way).
    Enabled,
    /// Power stage off (switch on disabled); a faulted drive also counts as off.
    Disabled,
    /// Quick stop active (or already off).
    QuickStop,
}

/// Why the sequencer gave up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PowerError {
    /// The goal was not reached in time; the drive was last seen in `state`.
    Timeout {
        /// Goal.
        goal: PowerGoal,
        /// Last state seen.
        state: PowerState,
        /// Time waited, milliseconds.
        waited_ms: u64,
    },
    /// The fault stayed latched after `attempts` fault resets; `error_code` is 0x603F.
    FaultPersists {
        /// Fault-reset attempts made.
        attempts: u32,
    },
}

/// One step of the sequencer: the controlword to send now, and whether the goal is reached.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PowerStep {
    /// Controlword to send this cycle.
    pub controlword: u16,
    /// The drive is in the goal state.
    pub reached: bool,
}

/// Walks one drive to a [`PowerGoal`], one controlword per received statusword.
#[derive(Debug, Clone, Copy)]
pub struct PowerSequencer {
    goal: PowerGoal,
    started_ns: u64,
    timeout_ns: u64,
    last_controlword: u16,
    fault_resets: u32,
    max_fault_resets: u32,
}

impl PowerSequencer {
    /// Start walking to `goal` at time `now_ns`, giving up after `timeout_ns`; at most
    /// `max_fault_resets` fault-reset edges are tried.
    pub const fn new(goal: PowerGoal, now_ns: u64, timeout_ns: u64, max_fault_resets: u32) -> Self {
        PowerSequencer {
            goal,
            started_ns: now_ns,
            timeout_ns,
            last_controlword: controlword::DISABLE_VOLTAGE,
            fault_resets: 0,
            max_fault_resets,
        }
    }

    /// The goal.
    pub const fn goal(&self) -> PowerGoal {
        self.goal
    }

    /// Feed the latest statusword at `now_ns`; returns the controlword to send.
    pub fn step(&mut self, statusword: u16, now_ns: u64) -> Result<PowerStep, PowerError> {
        use controlword as cw;
        let state = PowerState::from_statusword(statusword);
        let (controlword, reached) = match (self.goal, state) {
            (PowerGoal::Enabled, PowerState::OperationEnabled) => (cw::ENABLE_OPERATION, true),
            (PowerGoal::Enabled, PowerState::SwitchOnDisabled) => (cw::SHUTDOWN, false),
            (PowerGoal::Enabled, PowerState::ReadyToSwitchOn) => (cw::SWITCH_ON, false),
            (PowerGoal::Enabled, PowerState::SwitchedOn) => (cw::ENABLE_OPERATION, false),
            (PowerGoal::Enabled, PowerState::QuickStopActive) => (cw::DISABLE_VOLTAGE, false),
            (PowerGoal::Enabled, PowerState::Fault) => {
                // A rising edge of bit 7 resets the fault: alternate 0x00 / 0x80.
                if self.last_controlword & cw::FAULT_RESET != 0 {
                    (cw::DISABLE_VOLTAGE, false)
                } else {
                    if self.fault_resets >= self.max_fault_resets {
                        return Err(PowerError::FaultPersists {
                            attempts: self.fault_resets,
                        });
                    }
                    self.fault_resets += 1;
                    (cw::FAULT_RESET, false)
                }
            }
            (PowerGoal::Enabled, _) => (cw::DISABLE_VOLTAGE, false),
            (
                PowerGoal::Disabled,
                PowerState::SwitchOnDisabled | PowerState::NotReadyToSwitchOn | PowerState::Fault,
            ) => (cw::DISABLE_VOLTAGE, true),
            (PowerGoal::Disabled, _) => (cw::DISABLE_VOLTAGE, false),
            (
                PowerGoal::QuickStop,
                PowerState::QuickStopActive
                | PowerState::SwitchOnDisabled
                | PowerState::NotReadyToSwitchOn
                | PowerState::Fault,
            ) => (cw::QUICK_STOP, true),
            (PowerGoal::QuickStop, _) => (cw::QUICK_STOP, false),
        };
        self.last_controlword = controlword;
        let waited = now_ns.saturating_sub(self.started_ns);
        if !reached && waited > self.timeout_ns {
            return Err(PowerError::Timeout {
                goal: self.goal,
                state,
                waited_ms: waited / 1_000_000,
            });
        }
        Ok(PowerStep {
            controlword,
            reached,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: u64 = 1_000_000;

    #[test]
    fn decodes_every_state_of_the_statusword_table() {
        use PowerState::*;
        for (sw, s) in [
            (0x0000, NotReadyToSwitchOn),
            (0x0250, SwitchOnDisabled),
            (0x0231, ReadyToSwitchOn),
            (0x0233, SwitchedOn),
            (0x0237, OperationEnabled),
            (0x1637, OperationEnabled),
            (0x0217, QuickStopActive),
            (0x021F, FaultReactionActive),
            (0x0218, Fault),
            (0x0208, Fault),
        ] {
            assert_eq!(PowerState::from_statusword(sw), s, "statusword {sw:#06x}");
        }
    }

    /// A scripted drive: answers each controlword as a CiA 402 drive would.
    fn drive_reacts(state: PowerState, cw: u16, prev_cw: u16) -> PowerState {
        use PowerState::*;
        match (state, cw) {
            (Fault, c) if c & 0x80 != 0 && prev_cw & 0x80 == 0 => SwitchOnDisabled,
            (Fault, _) => Fault,
            (_, c) if c & 0x02 == 0 => SwitchOnDisabled,
            (SwitchOnDisabled, 0x06) => ReadyToSwitchOn,
            (ReadyToSwitchOn, 0x07) => SwitchedOn,
            (SwitchedOn, 0x0F) => OperationEnabled,
            (OperationEnabled, 0x0F) => OperationEnabled,
            (s, _) => s,
        }
    }

    fn statusword(s: PowerState) -> u16 {
        match s {
            PowerState::NotReadyToSwitchOn => 0x0000,
            PowerState::SwitchOnDisabled => 0x0250,
            PowerState::ReadyToSwitchOn => 0x0231,
            PowerState::SwitchedOn => 0x0233,
            PowerState::OperationEnabled => 0x0237,
            PowerState::QuickStopActive => 0x0217,
            PowerState::FaultReactionActive => 0x021F,
            PowerState::Fault => 0x0218,
        }
    }

    #[test]
    fn enables_a_drive_that_booted_into_fault_with_a_fault_reset_edge() {
        // The traced drive reported statusword 0x0218 (fault) after boot.
        let mut state = PowerState::from_statusword(0x0218);
        let mut seq = PowerSequencer::new(PowerGoal::Enabled, 0, 100 * MS, 3);
        let mut sent = vec![];
        let mut prev = 0;
        for cycle in 0..10u64 {
            let step = seq.step(statusword(state), cycle * MS).unwrap();
            sent.push(step.controlword);
            if step.reached {
                break;
            }
            state = drive_reacts(state, step.controlword, prev);
            prev = step.controlword;
        }
        assert_eq!(sent, vec![0x80, 0x06, 0x07, 0x0F, 0x0F]);
        assert_eq!(state, PowerState::OperationEnabled);
    }

    #[test]
    fn a_fault_that_never_clears_is_reported_after_the_allowed_resets() {
        let mut seq = PowerSequencer::new(PowerGoal::Enabled, 0, 1000 * MS, 2);
        let mut result = Ok(());
        let mut cws = vec![];
        for cycle in 0..10 {
            match seq.step(0x0218, cycle * MS) {
                Ok(s) => cws.push(s.controlword),
                Err(e) => {
                    result = Err(e);
                    break;
                }
            }
        }
        assert_eq!(cws, vec![0x80, 0x00, 0x80, 0x00]);
        assert_eq!(result, Err(PowerError::FaultPersists { attempts: 2 }));
    }

    #[test]
    fn a_drive_stuck_in_a_state_times_out_naming_that_state() {
        let mut seq = PowerSequencer::new(PowerGoal::Enabled, 0, 10 * MS, 3);
        assert!(seq.step(0x0231, 0).is_ok());
        let e = seq.step(0x0231, 11 * MS).unwrap_err();
        assert_eq!(
            e,
            PowerError::Timeout {
                goal: PowerGoal::Enabled,
                state: PowerState::ReadyToSwitchOn,
                waited_ms: 11
            }
        );
    }

    #[test]
    fn disable_and_quick_stop_goals() {
        let mut d = PowerSequencer::new(PowerGoal::Disabled, 0, 10 * MS, 0);
        assert_eq!(
            d.step(0x0237, 0).unwrap(),
            PowerStep {
                controlword: 0,
                reached: false
            }
        );
        assert!(d.step(0x0250, MS).unwrap().reached);
        let mut q = PowerSequencer::new(PowerGoal::QuickStop, 0, 10 * MS, 0);
        assert_eq!(q.step(0x0237, 0).unwrap().controlword, 0x0002);
        assert!(q.step(0x0217, MS).unwrap().reached);
    }

    #[test]
    fn quick_stop_active_is_left_through_disable_voltage_when_enabling() {
        let mut seq = PowerSequencer::new(PowerGoal::Enabled, 0, 10 * MS, 0);
        assert_eq!(seq.step(0x0217, 0).unwrap().controlword, 0x0000);
    }
}
