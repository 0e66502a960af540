//! The strain-gauge ADCs on Linux: an ADS1220 on a spidev device with its data-ready line on a
//! GPIO character device, an HX711 on two GPIO lines, or a wire drive's analog input received
//! over CAN ([`DriveInputAdc`]).
//!
//! Two pieces are written here rather than taken from linux-embedded-hal, because its versions
//! break the control loop's rules:
//! - [`RtSpidev`]: linux-embedded-hal's `SpidevDevice::transaction` collects the transfers in a
//!   `Vec` on every call (an allocation per tension read); this one builds them in a fixed array
//!   and makes the same single `SPI_IOC_MESSAGE` call.
//! - [`SpinDelay`]: linux-embedded-hal's `Delay` sleeps through the kernel, which on a
//!   non-PREEMPT_RT kernel turns the HX711's 1 µs clock half-periods into tens of microseconds
//!   each; this one spins on the monotonic clock (a vDSO read, no system call).

use std::io;
use std::time::{Duration, Instant};

use embedded_hal::delay::DelayNs;
use embedded_hal::spi::{self, Operation, SpiDevice};
use linux_embedded_hal::spidev::{SpiModeFlags, Spidev, SpidevOptions, SpidevTransfer};
use linux_embedded_hal::CdevPin;

use super::ads1220::{self, Ads1220};
use super::drive_input::DriveInputAdc;
use super::hx711::{self, Gain, Hx711};
use super::RawAdc;
use crate::gpio::linux::open_line;

/// Most operations one [`RtSpidev`] transaction may hold (the ADS1220 uses at most two).
pub const MAX_SPI_OPERATIONS: usize = 4;

/// SPI clock of the ADS1220, Hz (the chip allows up to 4 MHz in its default clock mode; a
/// 4-byte read then takes about 30 µs of bus time).
pub const ADS1220_SPI_HZ: u32 = 1_000_000;

/// A spidev device whose transactions never allocate (see the module documentation).
#[derive(Debug)]
pub struct RtSpidev {
    device: Spidev,
}

impl RtSpidev {
    /// Open `path` (e.g. `/dev/spidev0.0`) in SPI `mode` at `speed_hz`, 8-bit words.
    /// **non-RT**.
    pub fn open(path: &str, mode: SpiModeFlags, speed_hz: u32) -> io::Result<RtSpidev> {
        let mut device = Spidev::open(path)?;
        device.configure(
            &SpidevOptions::new()
                .bits_per_word(8)
                .max_speed_hz(speed_hz)
                .mode(mode)
                .build(),
        )?;
        Ok(RtSpidev { device })
    }

    /// An already opened and configured spidev device.
    pub fn from_spidev(device: Spidev) -> RtSpidev {
        RtSpidev { device }
    }
}

/// An [`RtSpidev`] failure.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RtSpiError {
    /// The kernel refused the transfer.
    Io(io::ErrorKind),
    /// More operations than [`MAX_SPI_OPERATIONS`] in one transaction.
    TooManyOperations(usize),
    /// A full-duplex transfer whose read and write buffers differ in length.
    LengthMismatch,
}

impl spi::Error for RtSpiError {
    fn kind(&self) -> spi::ErrorKind {
        spi::ErrorKind::Other
    }
}

impl spi::ErrorType for RtSpidev {
    type Error = RtSpiError;
}

impl SpiDevice for RtSpidev {
    /// All operations in one `SPI_IOC_MESSAGE` call, chip select held throughout. **RT**: no
    /// allocation; the one system call is the bus I/O.
    fn transaction(&mut self, operations: &mut [Operation<'_, u8>]) -> Result<(), RtSpiError> {
        let n = operations.len();
        if n > MAX_SPI_OPERATIONS {
            return Err(RtSpiError::TooManyOperations(n));
        }
        let mut transfers: [SpidevTransfer<'_, '_>; MAX_SPI_OPERATIONS] = Default::default();
        for (transfer, operation) in transfers.iter_mut().zip(operations.iter_mut()) {
            *transfer = match operation {
                Operation::Read(buf) => SpidevTransfer::read(buf),
                Operation::Write(buf) => SpidevTransfer::write(buf),
                Operation::Transfer(read, write) if read.len() == write.len() => {
                    SpidevTransfer::read_write(write, read)
                }
                Operation::Transfer(..) => return Err(RtSpiError::LengthMismatch),
                Operation::TransferInPlace(buf) => SpidevTransfer::read_write_in_place(buf),
                Operation::DelayNs(ns) => SpidevTransfer::delay(delay_us(*ns)),
            };
        }
        self.device
            .transfer_multiple(&mut transfers[..n])
            .map_err(|e| RtSpiError::Io(e.kind()))
    }
}

/// A delay in whole microseconds for the kernel's transfer delay field (rounded up, at most
/// `u16::MAX`).
fn delay_us(ns: u32) -> u16 {
    u16::try_from(ns.div_ceil(1000)).unwrap_or(u16::MAX)
}

/// A busy-waiting delay on the monotonic clock (see the module documentation). **RT** for the
/// microsecond delays it is meant for.
#[derive(Debug, Clone, Copy, Default)]
pub struct SpinDelay;

impl DelayNs for SpinDelay {
    fn delay_ns(&mut self, ns: u32) {
        let end = Instant::now() + Duration::from_nanos(u64::from(ns));
        while Instant::now() < end {
            core::hint::spin_loop();
        }
    }
}

/// One wire's strain-gauge converter, of any kind.
pub enum LinuxAdc {
    /// ADS1220 on spidev, data-ready on a GPIO line.
    Ads1220(Ads1220<RtSpidev, CdevPin>),
    /// HX711 on a clock and a data GPIO line.
    Hx711(Hx711<CdevPin, CdevPin, SpinDelay>),
    /// The load-cell amplifier into the wire drive's analog input, received in TPDO2.
    DriveInput(DriveInputAdc),
}

impl core::fmt::Debug for LinuxAdc {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            LinuxAdc::Ads1220(_) => "LinuxAdc::Ads1220",
            LinuxAdc::Hx711(_) => "LinuxAdc::Hx711",
            LinuxAdc::DriveInput(_) => "LinuxAdc::DriveInput",
        })
    }
}

/// Which part of a [`LinuxAdc`] failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LinuxAdcError {
    /// The SPI bus.
    Spi(RtSpiError),
    /// A GPIO line (data-ready, clock or data).
    Pin,
    /// The ADS1220's registers read back differ from those written.
    ConfigMismatch,
}

fn ads_error<EP>(e: ads1220::Error<RtSpiError, EP>) -> LinuxAdcError {
    match e {
        ads1220::Error::Spi(s) => LinuxAdcError::Spi(s),
        ads1220::Error::DataReady(_) => LinuxAdcError::Pin,
        ads1220::Error::ConfigMismatch { .. } => LinuxAdcError::ConfigMismatch,
    }
}

impl RawAdc for LinuxAdc {
    type Error = LinuxAdcError;
    fn read_raw(&mut self) -> nb::Result<i32, LinuxAdcError> {
        match self {
            LinuxAdc::Ads1220(adc) => adc.read().map_err(|e| e.map(ads_error)),
            LinuxAdc::Hx711(adc) => adc.read().map_err(|e| e.map(|_| LinuxAdcError::Pin)),
            LinuxAdc::DriveInput(adc) => adc.read_raw().map_err(|e| e.map(|never| match never {})),
        }
    }
}

/// A converter that could not be opened, naming the wire and the device.
#[derive(Debug, thiserror::Error)]
#[error("tension sensor {wire}: {device}: {reason}")]
pub struct AdcOpenError {
    /// Wire index.
    pub wire: usize,
    /// The device or line that failed.
    pub device: String,
    /// Why.
    pub reason: String,
}

const DATA_READY_ROLES: [&str; 3] = [
    "wire 0 ADC data-ready",
    "wire 1 ADC data-ready",
    "wire 2 ADC data-ready",
];
const CLOCK_ROLES: [&str; 3] = [
    "wire 0 HX711 clock",
    "wire 1 HX711 clock",
    "wire 2 HX711 clock",
];
const DATA_ROLES: [&str; 3] = [
    "wire 0 HX711 data",
    "wire 1 HX711 data",
    "wire 2 HX711 data",
];

/// Open wire `wire`'s ADS1220 on `spi_path` with its data-ready input on `drdy_line` of
/// `gpio_chip`; reset it, configure it for the control loop at `config`
/// ([`ads1220::Config::bridge_at`], PGA gain 128), verify the registers and start conversions.
/// **non-RT**.
pub fn open_ads1220(
    wire: usize,
    spi_path: &str,
    gpio_chip: &str,
    drdy_line: u32,
    config: ads1220::Config,
) -> Result<LinuxAdc, AdcOpenError> {
    let spi = RtSpidev::open(spi_path, SpiModeFlags::SPI_MODE_1, ADS1220_SPI_HZ).map_err(|e| {
        AdcOpenError {
            wire,
            device: spi_path.to_string(),
            reason: e.to_string(),
        }
    })?;
    let drdy = open_line(gpio_chip, drdy_line, DATA_READY_ROLES[wire % 3], false).map_err(|e| {
        AdcOpenError {
            wire,
            device: format!("{gpio_chip} line {drdy_line}"),
            reason: e.to_string(),
        }
    })?;
    let adc = Ads1220::new(spi, drdy, config).map_err(|e| AdcOpenError {
        wire,
        device: spi_path.to_string(),
        reason: match e {
            ads1220::Error::ConfigMismatch { written, read } => format!(
                "ADS1220 registers read back {read:02x?} after writing {written:02x?} (chip absent or miswired)"
            ),
            other => format!("ADS1220 set-up failed: {other:?}"),
        },
    })?;
    Ok(LinuxAdc::Ads1220(adc))
}

/// Open wire `wire`'s HX711 with its clock on `clock_line` and its data on `data_line` of
/// `gpio_chip` (channel A, gain 128). Wire the chip's RATE pin high (80 samples/s): at
/// 10 samples/s every sample would be older than any useful staleness limit. **non-RT**.
pub fn open_hx711(
    wire: usize,
    gpio_chip: &str,
    clock_line: u32,
    data_line: u32,
) -> Result<LinuxAdc, AdcOpenError> {
    let line_error = |line: u32| {
        move |e: crate::gpio::linux::OpenError| AdcOpenError {
            wire,
            device: format!("{gpio_chip} line {line}"),
            reason: e.to_string(),
        }
    };
    let clock = open_line(gpio_chip, clock_line, CLOCK_ROLES[wire % 3], true)
        .map_err(line_error(clock_line))?;
    let data = open_line(gpio_chip, data_line, DATA_ROLES[wire % 3], false)
        .map_err(line_error(data_line))?;
    let adc = Hx711::new(clock, data, SpinDelay, Gain::A128).map_err(|e| AdcOpenError {
        wire,
        device: format!("{gpio_chip} line {clock_line}"),
        reason: match e {
            hx711::Error::Clock(e) => format!("cannot drive the clock low: {e}"),
            hx711::Error::Data(e) => format!("cannot read the data line: {e}"),
        },
    })?;
    Ok(LinuxAdc::Hx711(adc))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_drive_input_reads_through_the_enum() {
        let inputs = std::sync::Arc::new(crate::cia402::DriveAnalogInputs::<3>::new());
        let mut adc = LinuxAdc::DriveInput(DriveInputAdc::new(inputs.clone(), 2).unwrap());
        assert_eq!(format!("{adc:?}"), "LinuxAdc::DriveInput");
        assert_eq!(adc.read_raw(), Err(nb::Error::WouldBlock));
        inputs.publish(2, -40);
        assert_eq!(adc.read_raw(), Ok(-40));
    }

    #[test]
    fn transfer_delays_round_up_to_whole_microseconds_and_saturate() {
        assert_eq!(delay_us(0), 0);
        assert_eq!(delay_us(1), 1);
        assert_eq!(delay_us(60_000), 60);
        assert_eq!(delay_us(60_001), 61);
        assert_eq!(delay_us(u32::MAX), u16::MAX);
    }

    #[test]
    fn the_spin_delay_waits_at_least_the_time_asked() {
        let start = Instant::now();
        SpinDelay.delay_us(200);
        assert!(start.elapsed() >= Duration::from_micros(200));
    }

    #[test]
    fn a_missing_spi_device_names_the_wire_and_the_device() {
        let regs = ads1220::Config::bridge_for_control(ads1220::PgaGain::X128);
        let Err(e) = open_ads1220(2, "/dev/no-such-spidev9.9", "/dev/gpiochip0", 5, regs) else {
            panic!("opened a missing SPI device");
        };
        let text = e.to_string();
        assert!(
            text.starts_with("tension sensor 2: /dev/no-such-spidev9.9: "),
            "{text}"
        );
    }

    #[test]
    fn a_missing_gpio_chip_names_the_wire_and_the_line() {
        let Err(e) = open_hx711(1, "/dev/no-such-gpiochip", 20, 16) else {
            panic!("opened a missing GPIO chip");
        };
        let text = e.to_string();
        assert!(
            text.starts_with("tension sensor 1: /dev/no-such-gpiochip line 20: "),
            "{text}"
        );
        assert!(text.contains("wire 1 HX711 clock"), "{text}");
    }
}
