//! The drive train the configuration describes: motor encoder, gear and pulley, and the torque
//! steps of the twins' simulated drives.

use videt_config::Config;
use videt_hal::Transmission;

/// The transmission the configuration describes.
pub fn transmission(config: &Config) -> Transmission {
    let t = &config.transmission;
    Transmission {
        counts_per_motor_rev: t.counts_per_motor_rev,
        gear_ratio: t.gear_ratio,
        pulley_radius_m: t.pulley_radius_m,
        efficiency: t.efficiency,
    }
}

/// The rated torque (0x6076) of the twins' simulated drives, mN·m: the configured drive's
/// (`drives.rated_torque_nm`, from `drives.device_description` when the file gives it) to the
/// nearest mN·m, the unit of the twins' CiA 402 drives, and at least 1.
pub fn twin_rated_torque_mnm(config: &Config) -> u32 {
    whole_mnm(config.drives.rated_torque_nm)
}

/// A rated torque in N·m to the nearest mN·m (the unit of the twins' CiA 402 drives), at least 1.
pub fn whole_mnm(torque_nm: f64) -> u32 {
    (torque_nm * 1000.0).round().clamp(1.0, f64::from(u32::MAX)) as u32
}

/// One step of the twins' target torque (one per mille of [`twin_rated_torque_mnm`]), N·m:
/// the HAL twin's motors apply torque in these steps, as the CAN twin's drives do.
pub fn twin_torque_step_nm(config: &Config) -> f64 {
    f64::from(twin_rated_torque_mnm(config)) * 1e-6
}
