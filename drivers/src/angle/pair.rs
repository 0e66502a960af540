//! The azimuth and elevation AS5048A as the HAL's angle sensors, each with its calibration.

use embedded_hal::spi::SpiDevice;
use videt_hal::{AngleAxis, AngleSensors, ErrorKind};

use super::as5048a::{As5048a, As5048aError, Diagnostics};
use super::calibration::Calibration;

/// An angle-sensor error, naming the sensor that failed and why.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("{axis} angle sensor: {fault}")]
pub struct AngleError<E> {
    /// Which sensor.
    pub axis: AngleAxis,
    /// What failed.
    pub fault: As5048aError<E>,
}

impl<E: core::fmt::Debug> videt_hal::Error for AngleError<E> {
    fn kind(&self) -> ErrorKind {
        self.fault.kind()
    }
}

/// Two AS5048A encoders on the wire guide of the one-wire device: azimuth and elevation, each on
/// its own SPI device (its own chip select).
#[derive(Debug)]
pub struct AngleSensorPair<SPI> {
    sensors: [As5048a<SPI>; 2],
    calibration: [Calibration; 2],
}

impl<SPI: SpiDevice> AngleSensorPair<SPI> {
    /// Set up both encoders ([`As5048a::new`]: they answer and see their magnets) with their
    /// calibrations (azimuth, elevation). **non-RT**.
    pub fn new(
        azimuth: SPI,
        elevation: SPI,
        calibration: [Calibration; 2],
    ) -> Result<Self, AngleError<SPI::Error>> {
        let azimuth = As5048a::new(azimuth).map_err(|fault| AngleError {
            axis: AngleAxis::Azimuth,
            fault,
        })?;
        let elevation = As5048a::new(elevation).map_err(|fault| AngleError {
            axis: AngleAxis::Elevation,
            fault,
        })?;
        Ok(Self::from_sensors(azimuth, elevation, calibration))
    }

    /// Two encoders already set up.
    pub fn from_sensors(
        azimuth: As5048a<SPI>,
        elevation: As5048a<SPI>,
        calibration: [Calibration; 2],
    ) -> Self {
        AngleSensorPair {
            sensors: [azimuth, elevation],
            calibration,
        }
    }

    /// The calibrations (azimuth, elevation).
    pub fn calibration(&self) -> [Calibration; 2] {
        self.calibration
    }

    /// Replace the calibrations (azimuth, elevation).
    pub fn set_calibration(&mut self, calibration: [Calibration; 2]) {
        self.calibration = calibration;
    }

    /// Raw counts of both encoders (azimuth, elevation), for calibration. **RT**: both sensors
    /// are read even when the first fails, so each pipeline stays one frame deep; the error is
    /// the azimuth's when both fail.
    pub fn read_counts(&mut self) -> Result<[u16; 2], AngleError<SPI::Error>> {
        let [azimuth, elevation] = &mut self.sensors;
        let a = azimuth.read_angle_counts();
        let e = elevation.read_angle_counts();
        match (a, e) {
            (Ok(a), Ok(e)) => Ok([a, e]),
            (Err(fault), _) => Err(AngleError {
                axis: AngleAxis::Azimuth,
                fault,
            }),
            (_, Err(fault)) => Err(AngleError {
                axis: AngleAxis::Elevation,
                fault,
            }),
        }
    }

    /// Both encoders' diagnostics, each checked: an error when one does not see its magnet
    /// within range. Two frames per encoder, the pipelines kept. **RT**: bounded bus I/O; for
    /// a periodic check outside the hot path of every period.
    pub fn check_diagnostics(&mut self) -> Result<[Diagnostics; 2], AngleError<SPI::Error>> {
        let mut out = [Diagnostics(0); 2];
        for axis in AngleAxis::ALL {
            let i = axis.index();
            out[i] = self.sensors[i]
                .diagnostics()
                .and_then(|d| d.check().map(|()| d))
                .map_err(|fault| AngleError { axis, fault })?;
        }
        Ok(out)
    }

    /// Give the SPI devices back (azimuth, elevation).
    pub fn release(self) -> [SPI; 2] {
        self.sensors.map(As5048a::release)
    }
}

impl<SPI: SpiDevice> videt_hal::ErrorType for AngleSensorPair<SPI> {
    type Error = AngleError<SPI::Error>;
}

impl<SPI: SpiDevice> AngleSensors for AngleSensorPair<SPI> {
    /// One pipelined frame per encoder (see [`AngleSensorPair::read_counts`]), calibrated.
    fn read_angles(&mut self, out_rad: &mut [f64; 2]) -> Result<(), Self::Error> {
        let counts = self.read_counts()?;
        for i in 0..2 {
            out_rad[i] = self.calibration[i].angle_rad(counts[i]);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::super::as5048a::tests::{answer, frame, init_frames, DeadBus, DIAG_OK};
    use super::super::as5048a::{ErrorRegister, CLEAR_ERROR_FLAG, READ_ANGLE, READ_DIAG_AGC};
    use super::super::calibration::{Sense, RAD_PER_COUNT};
    use super::*;
    use core::f64::consts::PI;
    use embedded_hal_mock::eh1::spi::{Mock as SpiMock, Transaction as S};
    use videt_hal::Error as _;

    const CAL: [Calibration; 2] = [
        Calibration {
            zero_counts: 16000,
            sense: Sense::Positive,
        },
        Calibration {
            zero_counts: 4096,
            sense: Sense::Negative,
        },
    ];

    fn with_init(reads: &[[S<u8>; 3]]) -> Vec<S<u8>> {
        let mut t = init_frames();
        for r in reads {
            t.extend(r.iter().cloned());
        }
        t
    }

    #[test]
    fn reads_calibrated_wrapped_angles_of_both_sensors() {
        let mut az = SpiMock::new(&with_init(&[
            frame(READ_ANGLE, answer(16000, false)),
            // 400 counts past the zero, across the encoder's wrap.
            frame(READ_ANGLE, answer(16, false)),
            // Half a turn from the zero: +pi.
            frame(READ_ANGLE, answer(16000 - 8192, false)),
        ]));
        let mut el = SpiMock::new(&with_init(&[
            frame(READ_ANGLE, answer(4096, false)),
            // Negative sense: 1024 counts below the zero is +pi/8.
            frame(READ_ANGLE, answer(4096 - 1024, false)),
            frame(READ_ANGLE, answer(4096 + 2048, false)),
        ]));
        let mut pair = AngleSensorPair::new(az.clone(), el.clone(), CAL).unwrap();
        let mut out = [f64::NAN; 2];
        pair.read_angles(&mut out).unwrap();
        assert_eq!(out, [0.0, 0.0]);
        pair.read_angles(&mut out).unwrap();
        assert_eq!(out, [400.0 * RAD_PER_COUNT, PI / 8.0]);
        pair.read_angles(&mut out).unwrap();
        assert_eq!(out, [PI, -PI / 4.0]);
        assert_eq!(pair.calibration(), CAL);
        let [a, e] = pair.release();
        drop((a, e));
        az.done();
        el.done();
    }

    #[test]
    fn an_error_names_the_sensor_and_the_other_keeps_its_pipeline() {
        let mut az = SpiMock::new(&with_init(&[
            frame(READ_ANGLE, answer(10, false)),
            frame(READ_ANGLE, answer(11, false)),
            frame(READ_ANGLE, answer(12, false)),
        ]));
        let corrupted = answer(300, false) ^ 1;
        let mut el = SpiMock::new(&with_init(&[
            frame(READ_ANGLE, corrupted),
            // Error flag: cleared with two frames, then the pipeline runs again.
            frame(READ_ANGLE, answer(0, true)),
            frame(CLEAR_ERROR_FLAG, answer(0, false)),
            frame(READ_ANGLE, answer(0b001, false)),
            frame(READ_ANGLE, answer(302, false)),
        ]));
        let mut pair =
            AngleSensorPair::new(az.clone(), el.clone(), [Calibration::IDENTITY; 2]).unwrap();
        let mut out = [0.0; 2];
        let e = pair.read_angles(&mut out).unwrap_err();
        assert_eq!(
            e,
            AngleError {
                axis: AngleAxis::Elevation,
                fault: As5048aError::Parity { word: corrupted }
            }
        );
        assert_eq!(e.kind(), ErrorKind::Disconnected);
        assert!(
            e.to_string()
                .starts_with("elevation angle sensor: parity error"),
            "{e}"
        );
        let e = pair.read_angles(&mut out).unwrap_err();
        assert_eq!(
            e.fault,
            As5048aError::ErrorFlag {
                register: Some(ErrorRegister(0b001))
            }
        );
        assert_eq!(
            e.to_string(),
            "elevation angle sensor: the sensor raised its error flag (framing error)"
        );
        assert_eq!(pair.read_counts(), Ok([12, 302]));
        pair.release();
        az.done();
        el.done();
    }

    #[test]
    fn set_up_names_the_sensor_whose_magnet_is_missing() {
        let az = SpiMock::new(&init_frames());
        let mut t = Vec::new();
        t.extend(frame(CLEAR_ERROR_FLAG, 0));
        t.extend(frame(READ_DIAG_AGC, answer(0, false)));
        t.extend(frame(READ_ANGLE, answer(0x09FF, false)));
        let el = SpiMock::new(&t);
        let e =
            AngleSensorPair::new(az.clone(), el.clone(), [Calibration::IDENTITY; 2]).unwrap_err();
        assert_eq!(e.axis, AngleAxis::Elevation);
        assert_eq!(e.kind(), ErrorKind::OutOfRange);
        assert_eq!(
            e.to_string(),
            "elevation angle sensor: magnetic field too weak (AGC 255): magnet missing, too far or off-axis"
        );
        let (mut az, mut el) = (az, el);
        az.done();
        el.done();
    }

    #[test]
    fn diagnostics_are_checked_on_demand() {
        let mut az = SpiMock::new(&with_init(&[
            frame(READ_DIAG_AGC, answer(5, false)),
            frame(READ_ANGLE, answer(DIAG_OK, false)),
        ]));
        let mut el = SpiMock::new(&with_init(&[
            frame(READ_DIAG_AGC, answer(6, false)),
            frame(READ_ANGLE, answer(0x0500, false)),
        ]));
        let mut pair = AngleSensorPair::new(az.clone(), el.clone(), CAL).unwrap();
        let e = pair.check_diagnostics().unwrap_err();
        assert_eq!(e.axis, AngleAxis::Elevation);
        assert_eq!(e.fault, As5048aError::FieldTooStrong { agc: 0 });
        pair.release();
        az.done();
        el.done();
    }

    #[test]
    fn a_dead_bus_is_a_lost_link_of_the_azimuth_sensor() {
        let mut pair = AngleSensorPair::from_sensors(
            As5048a::without_check(DeadBus),
            As5048a::without_check(DeadBus),
            CAL,
        );
        let e = pair.read_angles(&mut [0.0; 2]).unwrap_err();
        assert_eq!(e.axis, AngleAxis::Azimuth);
        assert_eq!(e.kind(), ErrorKind::Disconnected);
    }
}
