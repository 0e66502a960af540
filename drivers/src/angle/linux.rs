//! The angle-sensor pair on Linux: each AS5048A on its own spidev device (its own chip select),
//! through the non-allocating [`RtSpidev`].

use linux_embedded_hal::spidev::SpiModeFlags;
use videt_hal::AngleAxis;

use super::as5048a::As5048a;
use super::calibration::Calibration;
use super::pair::AngleSensorPair;
use crate::adc::linux::RtSpidev;

/// SPI clock of the AS5048A, Hz: a tenth of the chip's 10 MHz limit, for the cable from the
/// wire guide to the backpack; a 16-bit frame then takes 16 µs of bus time.
pub const AS5048A_SPI_HZ: u32 = 1_000_000;

/// An encoder that could not be opened or set up, naming the sensor and the device.
#[derive(Debug, thiserror::Error)]
#[error("{axis} angle sensor: {device}: {reason}")]
pub struct AngleOpenError {
    /// Which sensor.
    pub axis: AngleAxis,
    /// The spidev device.
    pub device: String,
    /// Why.
    pub reason: String,
}

/// Open one encoder on `path` (SPI mode 1) and set it up ([`As5048a::new`]). **non-RT**.
pub fn open_as5048a(axis: AngleAxis, path: &str) -> Result<As5048a<RtSpidev>, AngleOpenError> {
    let error = |reason: String| AngleOpenError {
        axis,
        device: path.to_string(),
        reason,
    };
    let spi = RtSpidev::open(path, SpiModeFlags::SPI_MODE_1, AS5048A_SPI_HZ)
        .map_err(|e| error(e.to_string()))?;
    As5048a::new(spi).map_err(|e| error(e.to_string()))
}

/// Open the azimuth encoder on `azimuth_spi` and the elevation encoder on `elevation_spi`
/// (e.g. `/dev/spidev1.0`, `/dev/spidev1.1`), set both up and apply their calibrations
/// (azimuth, elevation). **non-RT**.
pub fn open_angle_pair(
    azimuth_spi: &str,
    elevation_spi: &str,
    calibration: [Calibration; 2],
) -> Result<AngleSensorPair<RtSpidev>, AngleOpenError> {
    let azimuth = open_as5048a(AngleAxis::Azimuth, azimuth_spi)?;
    let elevation = open_as5048a(AngleAxis::Elevation, elevation_spi)?;
    Ok(AngleSensorPair::from_sensors(
        azimuth,
        elevation,
        calibration,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_spi_device_names_the_sensor_and_the_device() {
        let Err(e) = open_angle_pair(
            "/dev/no-such-spidev8.0",
            "/dev/no-such-spidev8.1",
            [Calibration::IDENTITY; 2],
        ) else {
            panic!("opened a missing SPI device");
        };
        let text = e.to_string();
        assert!(
            text.starts_with("azimuth angle sensor: /dev/no-such-spidev8.0: "),
            "{text}"
        );
    }

    #[test]
    fn a_file_that_is_no_spi_device_is_refused_naming_the_sensor() {
        // /dev/null opens, but the kernel refuses to configure it as an SPI device.
        let Err(e) = open_as5048a(AngleAxis::Elevation, "/dev/null") else {
            panic!("set up an encoder on /dev/null");
        };
        let text = e.to_string();
        assert!(
            text.starts_with("elevation angle sensor: /dev/null: "),
            "{text}"
        );
    }
}
