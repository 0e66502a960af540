//! The safety supervisor (ARCHITECTURE control cycle, step 3): decides each period whether the
//! device may render forces, must hold every wire at minimum tension, or must remove power.
//!
//! Pure and allocation-free: the runtime feeds it what it read and what went wrong; it answers
//! with a [`SafetyState`]. Faults latch until [`SafetySupervisor::reset`].

/// Why the device left normal operation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SafetyReason {
    /// The e-stop was pressed.
    EmergencyStop,
    /// A drive reported a fault or could not be read.
    DriveFault {
        /// Drive index, when known.
        wire: Option<u8>,
    },
    /// A tension sensor failed or went stale.
    SensorFault {
        /// Sensor index, when known.
        wire: Option<u8>,
    },
    /// A measured tension exceeded the allowed maximum.
    OverTension {
        /// Wire index.
        wire: u8,
    },
    /// A wire moved faster than allowed.
    OverSpeed {
        /// Wire index.
        wire: u8,
    },
    /// A wire lost its tension while it should have had some: broken or slipped.
    WireBreak {
        /// Wire index.
        wire: u8,
    },
    /// The control loop missed too many deadlines in a row.
    DeadlineOverrun,
    /// Forces may not be rendered without a valid rig calibration.
    NotCalibrated,
    /// The surface model is older than allowed (vision stalled).
    StaleSurface,
    /// A thread of the service failed (panicked); the service is stopping.
    SoftwareFault,
}

impl SafetyReason {
    /// A short, stable name for logs and the control socket.
    pub const fn as_str(&self) -> &'static str {
        match self {
            SafetyReason::EmergencyStop => "e-stop",
            SafetyReason::DriveFault { .. } => "drive-fault",
            SafetyReason::SensorFault { .. } => "sensor-fault",
            SafetyReason::OverTension { .. } => "over-tension",
            SafetyReason::OverSpeed { .. } => "over-speed",
            SafetyReason::WireBreak { .. } => "wire-break",
            SafetyReason::DeadlineOverrun => "deadline-overrun",
            SafetyReason::NotCalibrated => "not-calibrated",
            SafetyReason::StaleSurface => "stale-surface",
            SafetyReason::SoftwareFault => "software-fault",
        }
    }

    /// The wire concerned, when there is one.
    pub const fn wire(&self) -> Option<u8> {
        match *self {
            SafetyReason::DriveFault { wire } | SafetyReason::SensorFault { wire } => wire,
            SafetyReason::OverTension { wire }
            | SafetyReason::OverSpeed { wire }
            | SafetyReason::WireBreak { wire } => Some(wire),
            _ => None,
        }
    }
}

/// What the device may do this period.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SafetyState {
    /// Forces are rendered.
    #[default]
    Normal,
    /// No force rendering; every wire held at minimum tension (wires stay taut, position known).
    MinimumTension(SafetyReason),
    /// Power removed from the drives (e-stop, or drives that cannot be trusted).
    PowerOff(SafetyReason),
}

impl SafetyState {
    /// Whether forces may be rendered.
    pub const fn renders_forces(&self) -> bool {
        matches!(self, SafetyState::Normal)
    }
    /// Whether the drives must be powered off.
    pub const fn power_off(&self) -> bool {
        matches!(self, SafetyState::PowerOff(_))
    }
    /// The reason, outside normal operation.
    pub const fn reason(&self) -> Option<SafetyReason> {
        match *self {
            SafetyState::Normal => None,
            SafetyState::MinimumTension(r) | SafetyState::PowerOff(r) => Some(r),
        }
    }
    /// A short, stable name: `normal`, or the reason's name.
    pub const fn as_str(&self) -> &'static str {
        match self.reason() {
            None => "normal",
            Some(r) => r.as_str(),
        }
    }
}

/// Thresholds of the supervisor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SafetyLimits {
    /// Largest measured tension tolerated, N (above the set-point limit, to allow for transients).
    pub max_measured_tension_n: f64,
    /// How long an over-tension must last before it trips, seconds (filters sensor spikes).
    pub over_tension_time_s: f64,
    /// Largest wire speed tolerated, m/s: faster for `over_speed_time_s` stops force rendering
    /// until the speed is back under it (a transient state, not latched).
    pub max_wire_speed_m_s: f64,
    /// How long an over-speed must last, seconds.
    pub over_speed_time_s: f64,
    /// A wire without tension (below this, N) while its set-point is at least
    /// `break_setpoint_n` is slack; it is taken as broken when slack take-up has wound in more
    /// than `break_takeup_m` or the slack lasts `break_time_s`.
    pub break_tension_n: f64,
    /// Set-point above which a missing tension means slack or a break, N.
    pub break_setpoint_n: f64,
    /// Wire wound in without tension beyond which it is broken, metres (more slack than a
    /// finger's movement makes).
    pub break_takeup_m: f64,
    /// Longest slack before a wire is taken as broken, seconds.
    pub break_time_s: f64,
}

impl SafetyLimits {
    /// Limits for a device with minimum and maximum tension and maximum wire speed.
    pub fn for_device(t_min_n: f64, t_max_n: f64, max_wire_speed_m_s: f64) -> SafetyLimits {
        SafetyLimits {
            max_measured_tension_n: t_max_n * 1.2,
            over_tension_time_s: 0.005,
            max_wire_speed_m_s,
            over_speed_time_s: 0.02,
            break_tension_n: 0.25 * t_min_n,
            break_setpoint_n: t_min_n,
            break_takeup_m: 0.15,
            break_time_s: 1.0,
        }
    }
}

/// What the supervisor is told each period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SafetyInput<const N: usize> {
    /// Period, seconds.
    pub dt_s: f64,
    /// E-stop latched pressed (a read error counts as pressed).
    pub estop_pressed: bool,
    /// A drive read/write failed or a drive reports a fault.
    pub drive_fault: Option<Option<u8>>,
    /// A tension sensor read failed.
    pub sensor_fault: Option<Option<u8>>,
    /// Measured tensions, N.
    pub measured_tension_n: [f64; N],
    /// Tension set-points of the previous period, N.
    pub setpoint_tension_n: [f64; N],
    /// Wire length rates, m/s (positive = paying out, negative = winding in).
    pub wire_speed_m_s: [f64; N],
    /// The loop reports too many consecutive overruns.
    pub deadline_overrun: bool,
    /// The rig has a valid calibration.
    pub calibrated: bool,
    /// The drives are enabled (wire-break detection is meaningful only then).
    pub drives_enabled: bool,
}

impl<const N: usize> Default for SafetyInput<N> {
    fn default() -> Self {
        SafetyInput {
            dt_s: 0.0,
            estop_pressed: false,
            drive_fault: None,
            sensor_fault: None,
            measured_tension_n: [0.0; N],
            setpoint_tension_n: [0.0; N],
            wire_speed_m_s: [0.0; N],
            deadline_overrun: false,
            calibrated: false,
            drives_enabled: false,
        }
    }
}

/// The safety supervisor: faults latch until [`SafetySupervisor::reset`]; an over-speed holds
/// only while it lasts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SafetySupervisor<const N: usize> {
    limits: SafetyLimits,
    latched: SafetyState,
    transient: SafetyState,
    slack_time_s: [f64; N],
    slack_wound_m: [f64; N],
    over_tension_time_s: [f64; N],
    over_speed_time_s: [f64; N],
}

impl<const N: usize> SafetySupervisor<N> {
    /// A supervisor in the normal state.
    pub fn new(limits: SafetyLimits) -> SafetySupervisor<N> {
        SafetySupervisor {
            limits,
            latched: SafetyState::Normal,
            transient: SafetyState::Normal,
            slack_time_s: [0.0; N],
            slack_wound_m: [0.0; N],
            over_tension_time_s: [0.0; N],
            over_speed_time_s: [0.0; N],
        }
    }

    /// The current state: the more severe of the latched and the transient one.
    pub fn state(&self) -> SafetyState {
        more_severe(self.latched, self.transient)
    }

    /// Clear latched faults (an operator action; the e-stop must be reset at the device first).
    pub fn reset(&mut self) {
        *self = SafetySupervisor::new(self.limits);
    }

    /// Force a state from outside the checks (e.g. a stale surface), keeping the more severe one.
    pub fn trip(&mut self, state: SafetyState) {
        self.latched = more_severe(self.latched, state);
    }

    /// Evaluate one period; returns the state.
    pub fn update(&mut self, input: &SafetyInput<N>) -> SafetyState {
        let l = self.limits;
        let mut now = SafetyState::Normal;
        let mut transient = SafetyState::Normal;
        if input.estop_pressed {
            now = more_severe(now, SafetyState::PowerOff(SafetyReason::EmergencyStop));
        }
        if let Some(wire) = input.drive_fault {
            now = more_severe(
                now,
                SafetyState::PowerOff(SafetyReason::DriveFault { wire }),
            );
        }
        if let Some(wire) = input.sensor_fault {
            now = more_severe(
                now,
                SafetyState::MinimumTension(SafetyReason::SensorFault { wire }),
            );
        }
        if input.deadline_overrun {
            now = more_severe(
                now,
                SafetyState::MinimumTension(SafetyReason::DeadlineOverrun),
            );
        }
        if !input.calibrated {
            now = more_severe(
                now,
                SafetyState::MinimumTension(SafetyReason::NotCalibrated),
            );
        }
        for i in 0..N {
            let wire = i as u8;
            let t = input.measured_tension_n[i];
            if !t.is_finite() {
                let fault =
                    SafetyState::MinimumTension(SafetyReason::SensorFault { wire: Some(wire) });
                now = more_severe(now, fault);
                continue;
            }
            if t > l.max_measured_tension_n {
                self.over_tension_time_s[i] += input.dt_s;
                if self.over_tension_time_s[i] >= l.over_tension_time_s {
                    now = more_severe(
                        now,
                        SafetyState::PowerOff(SafetyReason::OverTension { wire }),
                    );
                }
            } else {
                self.over_tension_time_s[i] = 0.0;
            }
            let rate = if input.wire_speed_m_s[i].is_finite() {
                input.wire_speed_m_s[i]
            } else {
                0.0
            };
            if rate.abs() > l.max_wire_speed_m_s {
                self.over_speed_time_s[i] += input.dt_s;
                if self.over_speed_time_s[i] >= l.over_speed_time_s {
                    let over = SafetyState::MinimumTension(SafetyReason::OverSpeed { wire });
                    transient = more_severe(transient, over);
                }
            } else {
                self.over_speed_time_s[i] = 0.0;
            }
            let should_pull =
                input.drives_enabled && input.setpoint_tension_n[i] >= l.break_setpoint_n;
            if should_pull && t < l.break_tension_n {
                // Slack: the tension loop winds the wire in; a broken wire keeps winding.
                self.slack_time_s[i] += input.dt_s;
                self.slack_wound_m[i] += (-rate).max(0.0) * input.dt_s;
                if self.slack_wound_m[i] >= l.break_takeup_m - 1e-9
                    || self.slack_time_s[i] >= l.break_time_s - 1e-9
                {
                    now = more_severe(now, SafetyState::PowerOff(SafetyReason::WireBreak { wire }));
                }
            } else {
                self.slack_time_s[i] = 0.0;
                self.slack_wound_m[i] = 0.0;
            }
        }
        self.latched = more_severe(self.latched, now);
        self.transient = transient;
        self.state()
    }
}

/// Severity order: Normal < MinimumTension < PowerOff; between equals the earlier (latched) wins.
fn more_severe(current: SafetyState, candidate: SafetyState) -> SafetyState {
    let rank = |s: &SafetyState| match s {
        SafetyState::Normal => 0,
        SafetyState::MinimumTension(_) => 1,
        SafetyState::PowerOff(_) => 2,
    };
    if rank(&candidate) > rank(&current) {
        candidate
    } else {
        current
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const N: usize = 3;

    fn normal_input() -> SafetyInput<N> {
        SafetyInput {
            dt_s: 1e-3,
            measured_tension_n: [1.0; N],
            setpoint_tension_n: [1.0; N],
            calibrated: true,
            drives_enabled: true,
            ..SafetyInput::default()
        }
    }

    fn supervisor() -> SafetySupervisor<N> {
        SafetySupervisor::new(SafetyLimits::for_device(0.3, 15.0, 0.8))
    }

    #[test]
    fn normal_operation_renders() {
        let mut s = supervisor();
        for _ in 0..1000 {
            assert_eq!(s.update(&normal_input()), SafetyState::Normal);
        }
    }

    #[test]
    fn estop_powers_off_and_latches() {
        let mut s = supervisor();
        let mut i = normal_input();
        i.estop_pressed = true;
        assert_eq!(
            s.update(&i),
            SafetyState::PowerOff(SafetyReason::EmergencyStop)
        );
        assert!(s.update(&normal_input()).power_off(), "latched");
        s.reset();
        assert_eq!(s.update(&normal_input()), SafetyState::Normal);
    }

    #[test]
    fn a_broken_wire_is_wound_in_without_tension_and_detected() {
        let mut s = supervisor();
        let mut i = normal_input();
        i.measured_tension_n[2] = 0.0;
        // The free end is wound in at 0.3 m/s: 0.15 m take 500 periods.
        i.wire_speed_m_s[2] = -0.3;
        for _ in 0..499 {
            assert_eq!(s.update(&i), SafetyState::Normal);
        }
        let st = s.update(&i);
        assert_eq!(
            st,
            SafetyState::PowerOff(SafetyReason::WireBreak { wire: 2 })
        );
        assert_eq!(st.reason().unwrap().wire(), Some(2));
    }

    #[test]
    fn slack_from_a_quick_retraction_is_not_a_break() {
        let mut s = supervisor();
        let mut slack = normal_input();
        slack.measured_tension_n = [0.0; N];
        slack.wire_speed_m_s = [-0.15; N];
        // 5 cm of slack on every wire, taken up in a third of a second, then taut again.
        for _ in 0..333 {
            assert_eq!(s.update(&slack), SafetyState::Normal);
        }
        for _ in 0..10 {
            assert_eq!(s.update(&normal_input()), SafetyState::Normal);
        }
        // A wire that stays slack without winding in (stuck) is broken after the break time.
        let mut stuck = normal_input();
        stuck.measured_tension_n[0] = 0.0;
        for _ in 0..999 {
            assert_eq!(s.update(&stuck), SafetyState::Normal);
        }
        assert!(s.update(&stuck).power_off());
    }

    #[test]
    fn over_tension_needs_to_persist() {
        let mut s = supervisor();
        let mut spike = normal_input();
        spike.measured_tension_n[0] = 30.0;
        assert_eq!(s.update(&spike), SafetyState::Normal);
        assert_eq!(s.update(&normal_input()), SafetyState::Normal);
        for _ in 0..4 {
            s.update(&spike);
        }
        assert_eq!(
            s.update(&spike),
            SafetyState::PowerOff(SafetyReason::OverTension { wire: 0 })
        );
    }

    #[test]
    fn over_speed_stops_rendering_only_while_it_lasts() {
        let mut s = supervisor();
        let mut fast = normal_input();
        fast.wire_speed_m_s[1] = -1.0;
        for _ in 0..19 {
            assert_eq!(s.update(&fast), SafetyState::Normal);
        }
        assert_eq!(
            s.update(&fast),
            SafetyState::MinimumTension(SafetyReason::OverSpeed { wire: 1 })
        );
        assert_eq!(
            s.update(&normal_input()),
            SafetyState::Normal,
            "not latched"
        );
    }

    #[test]
    fn faults_map_to_their_safe_states() {
        let mut i = normal_input();
        i.sensor_fault = Some(Some(1));
        let expected = SafetyState::MinimumTension(SafetyReason::SensorFault { wire: Some(1) });
        assert_eq!(supervisor().update(&i), expected);
        let mut i = normal_input();
        i.measured_tension_n[0] = f64::NAN;
        assert!(matches!(
            supervisor().update(&i),
            SafetyState::MinimumTension(SafetyReason::SensorFault { .. })
        ));
        let mut i = normal_input();
        i.calibrated = false;
        assert_eq!(
            supervisor().update(&i),
            SafetyState::MinimumTension(SafetyReason::NotCalibrated)
        );
        let mut i = normal_input();
        i.drive_fault = Some(None);
        assert!(supervisor().update(&i).power_off());
    }

    #[test]
    fn a_more_severe_fault_overrides_a_milder_one() {
        let mut s = supervisor();
        let mut i = normal_input();
        i.sensor_fault = Some(None);
        s.update(&i);
        i.estop_pressed = true;
        assert_eq!(
            s.update(&i),
            SafetyState::PowerOff(SafetyReason::EmergencyStop)
        );
    }
}
