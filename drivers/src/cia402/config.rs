//! Configuration of a set of `N` CiA 402 wire drives (one per wire of the device), validated
//! with errors that name the field, its value and the allowed range.

use core::time::Duration;

use videt_hal::Transmission;

use super::pdo::AnalogInputObject;
use videt_drive_description::TorqueUnit;

/// Settings of a set of `N` drives, one per wire. Build with [`DriveSetConfig::new`] (which
/// takes `N` from the length of its node-id array) and adjust fields.
///
/// The wire count is a const generic rather than a run-time length: the configuration of an
/// `N`-wire device can only build a [`Cia402DriveSet`](super::Cia402DriveSet) of `N` drives, so
/// no length can mismatch at run time and the set keeps its per-wire state in fixed arrays
/// (nothing allocated per control period). A caller holding the node ids in a slice converts it
/// with `<[u8; N]>::try_from`.
#[derive(Debug, Clone, PartialEq)]
pub struct DriveSetConfig<const N: usize> {
    /// CANopen node id of each wire's drive, in wire order (1..=127, distinct; at least one).
    pub node_ids: [u8; N],
    /// Node id of the host's own heartbeat (1..=127, not a drive's).
    pub host_node_id: u8,
    /// Encoder, gear and pulley of every wire.
    pub transmission: Transmission,
    /// Per wire: a positive drive torque unwinds the wire; the set negates the wire's torque.
    pub motor_reversed: [bool; N],
    /// Per wire: the drive's position counts down as the wire winds in. Written to the
    /// drive's polarity (0x607E bits 7 and 6) where it has that object; the set negates the
    /// position and velocity itself where it does not.
    pub encoder_reversed: [bool; N],
    /// Motor rated torque (the drives' 0x6076), N·m; target torque is per mille of it.
    pub rated_torque_nm: f64,
    /// The unit the drives give 0x6076 in (mN·m by CiA 402, µN·m on maxon drives): how the
    /// rated torque is compared with theirs.
    pub rated_torque_unit: TorqueUnit,
    /// Maximum wire tension, N; torque commands are clamped to the torque holding it.
    pub t_max_n: f64,
    /// Wire speed limit, m/s: above it, torque that would drive the wire faster is cut.
    pub max_wire_speed_m_per_s: f64,
    /// A wire wound in faster than this multiple of the speed limit trips the set into its safe
    /// state (unwinding, driven by the operator, never trips).
    pub overspeed_trip_factor: f64,
    /// Consecutive cycles a wire must wind faster than the trip speed before the set trips
    /// (1..=100): a single sample above it is more often a late SYNC answer than a runaway,
    /// and the torque is cut meanwhile.
    pub overspeed_trip_cycles: u32,
    /// Control period (one SYNC per period).
    pub control_period: Duration,
    /// How long after SYNC the TPDOs may take to arrive.
    pub pdo_timeout: Duration,
    /// Consecutive cycles with a missing TPDO tolerated before failing (0 = none).
    pub max_missed_cycles: u32,
    /// Drive heartbeat producer time (0x1017), ms.
    pub drive_heartbeat_ms: u16,
    /// Host's tolerance of drive silence: a drive heard from longer ago is lost.
    pub drive_heartbeat_timeout: Duration,
    /// Host heartbeat producer period, ms.
    pub host_heartbeat_ms: u16,
    /// The drives' tolerance of host silence (0x1016), ms.
    pub host_silence_timeout_ms: u16,
    /// The drives' communication-loss reaction (0x6007): 1 fault, 2 disable voltage, 3 quick stop.
    pub comm_loss_reaction: i16,
    /// Time allowed for all drives to send their boot-up message.
    pub boot_timeout: Duration,
    /// Time allowed for each SDO answer.
    pub sdo_timeout: Duration,
    /// Time allowed for the power state machine to reach its goal.
    pub power_timeout: Duration,
    /// Encoder counts per drive position unit (0x6064); 1 when the drive reports counts.
    pub counts_per_position_unit: f64,
    /// Counts per second per drive velocity unit (0x606C); e.g. counts_per_rev / 60 for rpm.
    pub counts_per_s_per_velocity_unit: f64,
    /// Compare the configured rated torque with the drive's 0x6076 during configuration.
    pub verify_rated_torque: bool,
    /// Map this 16-bit signed object (the drive's analog input, e.g. a load-cell amplifier)
    /// into TPDO1 (in the velocity's place: the velocity is then derived from the positions)
    /// and publish every drive's value through
    /// [`Cia402DriveSet::analog_inputs`](super::Cia402DriveSet::analog_inputs). `None`: TPDO1
    /// carries the velocity.
    pub analog_input: Option<AnalogInputObject>,
    /// TPDO2 (the status and error code) is event-driven: sent on every status change and, on
    /// a drive with an event timer (0x1801 sub 5), at least this often, ms.
    pub status_event_timer_ms: u16,
}

/// A configuration field outside its allowed range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("drive config: {field} = {value} is out of range (allowed: {allowed})")]
pub struct ConfigError {
    /// Field name.
    pub field: &'static str,
    /// Offending value, as text.
    pub value: String,
    /// Allowed range, as text.
    pub allowed: &'static str,
}

impl<const N: usize> DriveSetConfig<N> {
    /// Defaults for the paper's actuation module with the given node ids (one per wire: their
    /// count is the wire count `N`), control period, rated torque and maximum tension.
    pub fn new(
        node_ids: [u8; N],
        control_period: Duration,
        rated_torque_nm: f64,
        t_max_n: f64,
    ) -> DriveSetConfig<N> {
        DriveSetConfig {
            node_ids,
            host_node_id: 0x7F,
            transmission: Transmission::PAPER,
            motor_reversed: [false; N],
            encoder_reversed: [false; N],
            rated_torque_nm,
            rated_torque_unit: TorqueUnit::MilliNewtonMetre,
            t_max_n,
            max_wire_speed_m_per_s: 0.8,
            overspeed_trip_factor: 1.5,
            overspeed_trip_cycles: 3,
            control_period,
            pdo_timeout: control_period.mul_f64(0.6),
            max_missed_cycles: 1,
            drive_heartbeat_ms: 10,
            drive_heartbeat_timeout: Duration::from_millis(35),
            host_heartbeat_ms: 10,
            host_silence_timeout_ms: 50,
            comm_loss_reaction: 2,
            boot_timeout: Duration::from_secs(3),
            sdo_timeout: Duration::from_millis(100),
            power_timeout: Duration::from_millis(500),
            counts_per_position_unit: 1.0,
            counts_per_s_per_velocity_unit: 1.0,
            verify_rated_torque: true,
            analog_input: None,
            status_event_timer_ms: 50,
        }
    }

    /// The traffic this configuration puts on the bus: the data lengths of the frames sent
    /// every control period (the SYNC, then every drive's synchronous PDOs), and
    /// `(data length, interval in s)` of the frames sent on timers (heartbeats of the drives
    /// and the host, and the event-driven status, counted as if refreshed on its timer).
    pub fn bus_traffic(&self) -> (Vec<u8>, Vec<(u8, f64)>) {
        let mut cyclic = vec![0u8];
        let mut timed = vec![(1u8, f64::from(self.host_heartbeat_ms) / 1000.0)];
        for _ in 0..N {
            cyclic.extend_from_slice(&super::pdo::CYCLIC_DATA_LENGTHS);
            timed.push((1, f64::from(self.drive_heartbeat_ms) / 1000.0));
            timed.push((4, f64::from(self.status_event_timer_ms) / 1000.0));
        }
        (cyclic, timed)
    }

    /// Check every field.
    pub fn validate(&self) -> Result<(), ConfigError> {
        fn err(field: &'static str, value: impl ToString, allowed: &'static str) -> ConfigError {
            ConfigError {
                field,
                value: value.to_string(),
                allowed,
            }
        }
        if N == 0 {
            return Err(err("node_ids", "[]", "at least one drive"));
        }
        for (i, id) in self.node_ids.iter().enumerate() {
            if !(1..=127).contains(id) {
                return Err(err("node_ids", id, "1..=127"));
            }
            if self.node_ids[..i].contains(id) {
                return Err(err("node_ids", id, "distinct node ids"));
            }
        }
        if !(1..=127).contains(&self.host_node_id) || self.node_ids.contains(&self.host_node_id) {
            return Err(err(
                "host_node_id",
                self.host_node_id,
                "1..=127 and not a drive's id",
            ));
        }
        let t = &self.transmission;
        if t.counts_per_motor_rev == 0 {
            return Err(err("transmission.counts_per_motor_rev", 0, "> 0"));
        }
        if !(t.gear_ratio.is_finite() && t.gear_ratio > 0.0) {
            return Err(err("transmission.gear_ratio", t.gear_ratio, "> 0"));
        }
        if !(t.pulley_radius_m.is_finite() && t.pulley_radius_m > 0.0) {
            return Err(err(
                "transmission.pulley_radius_m",
                t.pulley_radius_m,
                "> 0",
            ));
        }
        if !(t.efficiency > 0.0 && t.efficiency <= 1.0) {
            return Err(err("transmission.efficiency", t.efficiency, "(0, 1]"));
        }
        if !(self.rated_torque_nm.is_finite() && self.rated_torque_nm > 0.0) {
            return Err(err("rated_torque_nm", self.rated_torque_nm, "> 0"));
        }
        if !(self.t_max_n.is_finite() && self.t_max_n > 0.0) {
            return Err(err("t_max_n", self.t_max_n, "> 0"));
        }
        if self.max_torque_nm() > 32.767 * self.rated_torque_nm {
            return Err(err(
                "t_max_n",
                self.t_max_n,
                "a torque below 32.767 x rated torque",
            ));
        }
        if !(self.max_wire_speed_m_per_s.is_finite() && self.max_wire_speed_m_per_s > 0.0) {
            return Err(err(
                "max_wire_speed_m_per_s",
                self.max_wire_speed_m_per_s,
                "> 0",
            ));
        }
        if self.overspeed_trip_factor.is_nan() || self.overspeed_trip_factor < 1.0 {
            return Err(err(
                "overspeed_trip_factor",
                self.overspeed_trip_factor,
                ">= 1",
            ));
        }
        if !(1..=100).contains(&self.overspeed_trip_cycles) {
            return Err(err(
                "overspeed_trip_cycles",
                self.overspeed_trip_cycles,
                "1..=100",
            ));
        }
        if self.control_period < Duration::from_micros(100)
            || self.control_period > Duration::from_millis(100)
        {
            return Err(err(
                "control_period",
                format!("{:?}", self.control_period),
                "100 us ..= 100 ms",
            ));
        }
        if self.pdo_timeout.is_zero() || self.pdo_timeout >= self.control_period {
            return Err(err(
                "pdo_timeout",
                format!("{:?}", self.pdo_timeout),
                "> 0 and < control_period",
            ));
        }
        if self.drive_heartbeat_ms == 0 {
            return Err(err("drive_heartbeat_ms", 0, ">= 1"));
        }
        if self.drive_heartbeat_timeout <= Duration::from_millis(u64::from(self.drive_heartbeat_ms))
        {
            return Err(err(
                "drive_heartbeat_timeout",
                format!("{:?}", self.drive_heartbeat_timeout),
                "> drive_heartbeat_ms",
            ));
        }
        if self.host_heartbeat_ms == 0 || self.host_silence_timeout_ms <= self.host_heartbeat_ms {
            return Err(err(
                "host_silence_timeout_ms",
                self.host_silence_timeout_ms,
                "> host_heartbeat_ms >= 1",
            ));
        }
        if !(1..=10_000).contains(&self.status_event_timer_ms) {
            return Err(err(
                "status_event_timer_ms",
                self.status_event_timer_ms,
                "1..=10000",
            ));
        }
        if !(1..=3).contains(&self.comm_loss_reaction) {
            return Err(err(
                "comm_loss_reaction",
                self.comm_loss_reaction,
                "1 (fault), 2 (disable voltage) or 3 (quick stop)",
            ));
        }
        for (field, v) in [
            ("counts_per_position_unit", self.counts_per_position_unit),
            (
                "counts_per_s_per_velocity_unit",
                self.counts_per_s_per_velocity_unit,
            ),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(err(field, v, "> 0"));
            }
        }
        if let Some(a) = self.analog_input {
            if !(0x2000..=0x9FFF).contains(&a.index) {
                return Err(err(
                    "analog_input.index",
                    format!("{:#06x}", a.index),
                    "0x2000..=0x9fff (a manufacturer or profile object)",
                ));
            }
            if a.subindex == 0xFF || (a.index == 0x6401 && a.subindex == 0) {
                return Err(err(
                    "analog_input.subindex",
                    a.subindex,
                    "0..=254 (1..=254 for 0x6401, whose subindex 0 is the input count)",
                ));
            }
        }
        Ok(())
    }

    /// The largest motor torque commanded, N·m: the torque that holds `t_max_n`.
    pub fn max_torque_nm(&self) -> f64 {
        self.transmission.torque_for_tension(self.t_max_n)
    }

    /// Convert a torque to the drive's per-mille-of-rated-torque unit (rounded, saturated).
    pub fn torque_to_permille(&self, torque_nm: f64) -> i16 {
        let p = (torque_nm / self.rated_torque_nm * 1000.0).round();
        p.clamp(f64::from(i16::MIN), f64::from(i16::MAX)) as i16
    }

    /// Convert a per-mille torque back to N·m.
    pub fn permille_to_torque(&self, permille: i16) -> f64 {
        f64::from(permille) * self.rated_torque_nm / 1000.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg() -> DriveSetConfig<3> {
        DriveSetConfig::new([1, 2, 3], Duration::from_millis(1), 0.1, 40.0)
    }

    #[test]
    fn defaults_are_valid_and_convert_torque_per_mille() {
        let c = cfg();
        c.validate().unwrap();
        assert_eq!(c.torque_to_permille(0.05), 500);
        assert_eq!(c.torque_to_permille(-0.0123), -123);
        assert_eq!(c.torque_to_permille(1e9), i16::MAX);
        assert!((c.permille_to_torque(250) - 0.025).abs() < 1e-12);
        // 40 N on a 20 mm pulley through 1:25: 0.032 N·m.
        assert!((c.max_torque_nm() - 0.032).abs() < 1e-12);
    }

    #[test]
    fn bad_fields_are_named_with_value_and_range() {
        let mut c = cfg();
        c.node_ids = [1, 2, 2];
        let e = c.validate().unwrap_err();
        assert_eq!((e.field, e.value.as_str()), ("node_ids", "2"));
        let mut c = cfg();
        c.host_node_id = 3;
        assert_eq!(c.validate().unwrap_err().field, "host_node_id");
        let mut c = cfg();
        c.rated_torque_nm = f64::NAN;
        assert_eq!(c.validate().unwrap_err().field, "rated_torque_nm");
        let mut c = cfg();
        c.pdo_timeout = Duration::from_millis(2);
        let e = c.validate().unwrap_err();
        assert_eq!(e.field, "pdo_timeout");
        assert!(e.to_string().contains("< control_period"), "{e}");
        let mut c = cfg();
        c.comm_loss_reaction = 0;
        assert_eq!(c.validate().unwrap_err().field, "comm_loss_reaction");
    }

    #[test]
    fn the_analog_input_object_is_checked() {
        let mut c = cfg();
        c.analog_input = Some(AnalogInputObject::default());
        c.validate().unwrap();
        c.analog_input = Some(AnalogInputObject {
            index: 0x1A01,
            subindex: 1,
        });
        let e = c.validate().unwrap_err();
        assert_eq!(
            (e.field, e.value.as_str()),
            ("analog_input.index", "0x1a01")
        );
        c.analog_input = Some(AnalogInputObject {
            index: 0x6401,
            subindex: 0,
        });
        assert_eq!(c.validate().unwrap_err().field, "analog_input.subindex");
        c.analog_input = Some(AnalogInputObject {
            index: 0x3160,
            subindex: 0,
        });
        c.validate().unwrap();
    }

    #[test]
    fn the_wire_count_is_the_node_id_count() {
        let one = DriveSetConfig::new([5], Duration::from_millis(1), 0.1, 40.0);
        one.validate().unwrap();
        let four = DriveSetConfig::new([1, 2, 3, 4], Duration::from_millis(1), 0.1, 40.0);
        four.validate().unwrap();
        let mut bad = four.clone();
        bad.host_node_id = 4;
        assert_eq!(bad.validate().unwrap_err().field, "host_node_id");
        let none = DriveSetConfig::new([], Duration::from_millis(1), 0.1, 40.0);
        let e = none.validate().unwrap_err();
        assert_eq!((e.field, e.allowed), ("node_ids", "at least one drive"));
        // Per period: the SYNC and each drive's cyclic PDOs; on timers: the host's heartbeat
        // and each drive's heartbeat and status.
        let per_drive = super::super::pdo::CYCLIC_DATA_LENGTHS.len();
        for (cyclic, timed, n) in [
            (one.bus_traffic().0, one.bus_traffic().1, 1),
            (cfg().bus_traffic().0, cfg().bus_traffic().1, 3),
            (four.bus_traffic().0, four.bus_traffic().1, 4),
        ] {
            assert_eq!(cyclic.len(), 1 + n * per_drive);
            assert_eq!(timed.len(), 1 + 2 * n);
        }
    }
}
