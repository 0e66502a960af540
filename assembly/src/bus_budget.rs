//! What the configured CAN bus can carry: the load the drives' traffic puts on it at the
//! configured control rate, and the refusal of a rate it cannot carry.
//!
//! Per control period the host sends one SYNC (0 bytes) and every drive exchanges its
//! synchronous PDOs ([`pdo::CYCLIC_DATA_LENGTHS`]); on their own timers come the heartbeats
//! (drives' and host's) and the event-driven status
//! ([`DriveSetConfig::bus_traffic`](videt_drivers::cia402::DriveSetConfig::bus_traffic)). The load is
//! counted twice: *nominal* (no stuff bits) and *worst case* (every stuff bit the frame format
//! allows); the configuration is refused when the worst case exceeds `drives.max_bus_load`.

use videt_can_timing::{worst_case_bits, BusLoad};
use videt_config::{Config, ConfigError, TensionAdc};
use videt_drivers::cia402::pdo;
// One drive on the bus per WireMan wire.
use videt_runtime::WIREMAN_WIRES;

/// The traffic of `config`'s drive set: data lengths sent every period, and
/// `(length, interval s)` of the frames sent on timers.
fn traffic(config: &Config) -> (Vec<u8>, Vec<(u8, f64)>) {
    crate::hardware::drive_set_config(config).bus_traffic()
}

/// The load the configured drives' traffic puts on the configured bus.
pub fn bus_load(config: &Config) -> BusLoad {
    let (cyclic, timed) = traffic(config);
    BusLoad::of(
        f64::from(config.control.rate_hz),
        &cyclic,
        &timed,
        config.drives.bitrate,
    )
}

/// The highest control rate, Hz, whose worst-case load stays within `drives.max_bus_load`.
pub fn max_rate_hz(config: &Config) -> u32 {
    let (cyclic, timed) = traffic(config);
    let per_cycle: f64 = cyclic.iter().map(|&d| f64::from(worst_case_bits(d))).sum();
    let timed_bits: f64 = timed
        .iter()
        .map(|&(d, every)| f64::from(worst_case_bits(d)) / every)
        .sum();
    let budget = config.drives.max_bus_load * f64::from(config.drives.bitrate) - timed_bits;
    (budget / per_cycle).floor().max(0.0) as u32
}

/// A one-line account of the load, for `videt config check` and the service's start-up log.
pub fn describe(config: &Config) -> String {
    let load = bus_load(config);
    format!(
        "CAN bus at {} bit/s, {} Hz, {} drives{}: load {:.1}% nominal, {:.1}% worst case \
         (limit drives.max_bus_load = {:.0}%); one period's process data takes up to {:.0} µs; \
         highest control rate within the limit: {} Hz",
        config.drives.bitrate,
        config.control.rate_hz,
        WIREMAN_WIRES,
        if config.sensors.adc == TensionAdc::Drive {
            " (their analog inputs in TPDO1)"
        } else {
            ""
        },
        100.0 * load.nominal(),
        100.0 * load.worst_case(),
        100.0 * config.drives.max_bus_load,
        load.worst_case_cycle_s * 1e6,
        max_rate_hz(config),
    )
}

/// Refuse a configuration whose drives' traffic exceeds `drives.max_bus_load` of the bus
/// (worst-case stuffing), naming the fields and the numbers. Returns the load otherwise.
pub fn check(config: &Config) -> Result<BusLoad, ConfigError> {
    let load = bus_load(config);
    if load.worst_case() <= config.drives.max_bus_load {
        return Ok(load);
    }
    let per_drive = pdo::CYCLIC_DATA_LENGTHS
        .iter()
        .map(|d| format!("{d} B"))
        .collect::<Vec<_>>()
        .join(" + ");
    Err(ConfigError::Invalid {
        field: "control.rate_hz".into(),
        value: config.control.rate_hz.to_string(),
        allowed: format!(
            "at most {} Hz on this bus: drives.bitrate = {} carries a SYNC and {} drives' PDOs \
             ({per_drive} each) in up to {:.0} µs a period, {:.0}% of the bus at {} Hz \
             (worst-case bit stuffing; {:.0}% nominal) where drives.max_bus_load = {}",
            max_rate_hz(config),
            config.drives.bitrate,
            WIREMAN_WIRES,
            load.worst_case_cycle_s * 1e6,
            100.0 * load.worst_case(),
            config.control.rate_hz,
            100.0 * load.nominal(),
            config.drives.max_bus_load,
        ),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_configuration_fits_its_bus() {
        let config = Config::default();
        let load = check(&config).expect("the default configuration must be runnable");
        // SYNC + 3 x (RPDO1 4 B + TPDO1 8 B) = 745 bits worst case a period at 1 kHz, plus
        // heartbeats and the event-driven status at 10 ms.
        assert!((load.worst_case_cycle_s - 745e-6).abs() < 1e-12);
        assert!(load.worst_case() > 0.745 && load.worst_case() < 0.80);
        assert!(load.nominal() > 0.617 && load.nominal() < 0.65);
        assert!(max_rate_hz(&config) >= 1000);
    }

    #[test]
    fn four_kilohertz_of_three_drives_on_one_megabit_is_refused_with_the_fields_named() {
        let mut config = Config::default();
        config.control.rate_hz = 4000;
        let e = check(&config).unwrap_err().to_string();
        for needle in [
            "control.rate_hz = 4000",
            "drives.bitrate = 1000000",
            "drives.max_bus_load = 0.8",
            "at most 10",
        ] {
            assert!(e.contains(needle), "{needle:?} missing from: {e}");
        }
    }

    #[test]
    fn the_drives_analog_inputs_ride_in_the_same_frames() {
        let mut config = Config::default();
        let without = bus_load(&config);
        config.sensors.adc = TensionAdc::Drive;
        assert_eq!(bus_load(&config), without);
        check(&config).unwrap();
        assert!(describe(&config).contains("analog inputs in TPDO1"));
    }

    #[test]
    fn the_highest_rate_is_the_boundary_of_the_check_on_every_bit_rate() {
        let mut config = Config::default();
        let mut highest = Vec::new();
        for bitrate in videt_config::CAN_BITRATES {
            config.drives.bitrate = bitrate;
            let max = max_rate_hz(&config);
            highest.push(max);
            if max >= 1 {
                config.control.rate_hz = max;
                check(&config).unwrap();
            }
            config.control.rate_hz = max + 1;
            assert!(check(&config).is_err(), "{bitrate} bit/s at {} Hz", max + 1);
        }
        // The heartbeats take a fixed share: half the bit rate carries less than half the rate.
        assert!(highest.windows(2).all(|w| w[0] <= w[1]), "{highest:?}");
        assert!(highest[5] < highest[7] / 2, "{highest:?}");
        assert!(describe(&config).contains("highest control rate"));
    }
}
