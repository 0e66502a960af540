//! ADS1220 24-bit precision ADC over SPI (mode 1), with its data-ready line (`DRDY`, active
//! low). Configured for a ratiometric strain-gauge bridge by default: AIN0/AIN1, PGA gain 128,
//! external reference REFP0/REFN0, continuous conversion at 20 SPS with 50/60 Hz rejection.

use embedded_hal::digital::InputPin;
use embedded_hal::spi::{Operation, SpiDevice};

use super::RawAdc;

/// Commands (datasheet §8.5.3).
mod cmd {
    pub const RESET: u8 = 0x06;
    pub const START: u8 = 0x08;
    pub const POWERDOWN: u8 = 0x02;
    pub const RDATA: u8 = 0x10;
    /// Read `n` registers from `reg`.
    pub const fn rreg(reg: u8, n: u8) -> u8 {
        0x20 | (reg << 2) | (n - 1)
    }
    /// Write `n` registers from `reg`.
    pub const fn wreg(reg: u8, n: u8) -> u8 {
        0x40 | (reg << 2) | (n - 1)
    }
}

/// Time after RESET before the chip accepts commands, ns (50 µs + margin).
const RESET_WAIT_NS: u32 = 60_000;

/// The four configuration registers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Config {
    /// Register 0: MUX[7:4], GAIN[3:1], PGA_BYPASS[0].
    pub reg0: u8,
    /// Register 1: DR[7:5], MODE[4:3], CM[2], TS[1], BCS[0].
    pub reg1: u8,
    /// Register 2: VREF[7:6], 50/60[5:4], PSW[3], IDAC[2:0].
    pub reg2: u8,
    /// Register 3: I1MUX[7:5], I2MUX[4:2], DRDYM[1].
    pub reg3: u8,
}

/// PGA gain.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PgaGain {
    /// x1.
    X1 = 0,
    /// x2.
    X2 = 1,
    /// x4.
    X4 = 2,
    /// x8.
    X8 = 3,
    /// x16.
    X16 = 4,
    /// x32.
    X32 = 5,
    /// x64.
    X64 = 6,
    /// x128.
    X128 = 7,
}

impl Config {
    /// A full strain-gauge bridge on AIN0/AIN1, ratiometric to REFP0/REFN0, continuous
    /// 20 SPS with simultaneous 50/60 Hz rejection, PGA `gain`.
    pub const fn bridge(gain: PgaGain) -> Config {
        Config {
            reg0: (gain as u8) << 1,
            // DR 000 (20 SPS), MODE 00 (normal), CM 1 (continuous), TS 0, BCS 0.
            reg1: 0b0000_0100,
            // VREF 01 (REFP0/REFN0), 50/60 01 (both), PSW 0, IDAC 000.
            reg2: 0b0101_0000,
            reg3: 0x00,
        }
    }

    /// The bridge of [`Config::bridge`] converted fast enough for the 1 kHz tension loop:
    /// turbo mode at 2000 samples/s (a fresh sample every 0.5 ms), without the 50/60 Hz
    /// filter (it works only at 20 samples/s). The loop's PI and the staleness limit
    /// (`sensors.stale_after_ms`) expect this rate; [`Config::bridge`] suits static weighing.
    pub const fn bridge_for_control(gain: PgaGain) -> Config {
        Config {
            reg0: (gain as u8) << 1,
            // DR 110 (2000 SPS in turbo), MODE 10 (turbo), CM 1 (continuous), TS 0, BCS 0.
            reg1: 0b1101_0100,
            // VREF 01 (REFP0/REFN0), 50/60 00 (off), PSW 0, IDAC 000.
            reg2: 0b0100_0000,
            reg3: 0x00,
        }
    }

    /// The bridge of [`Config::bridge_for_control`] at another data rate: `data_rate_code` is
    /// register 1's DR field (0..=6: 20, 45, 90, 175, 330, 600, 1000 samples/s in normal mode,
    /// twice that, except 90 for code 1, in turbo mode). `None` for a code above 6.
    pub const fn bridge_at(gain: PgaGain, turbo: bool, data_rate_code: u8) -> Option<Config> {
        if data_rate_code > 6 {
            return None;
        }
        let mode = if turbo { 0b10 } else { 0b00 };
        Some(Config {
            reg0: (gain as u8) << 1,
            // DR, MODE, CM 1 (continuous), TS 0, BCS 0.
            reg1: (data_rate_code << 5) | (mode << 3) | 0b100,
            // VREF 01 (REFP0/REFN0), 50/60 00 (off), PSW 0, IDAC 000.
            reg2: 0b0100_0000,
            reg3: 0x00,
        })
    }

    /// Continuous conversion mode is on.
    pub const fn is_continuous(&self) -> bool {
        self.reg1 & 0x04 != 0
    }
}

/// An ADS1220 error.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Error<ES, EP> {
    /// The SPI bus failed.
    Spi(ES),
    /// The data-ready pin failed.
    DataReady(EP),
    /// The registers read back differ from those written (chip absent or wiring fault).
    ConfigMismatch {
        /// Written.
        written: [u8; 4],
        /// Read back.
        read: [u8; 4],
    },
}

/// ADS1220 driver. Owns its SPI device and data-ready pin; [`Ads1220::release`] gives them back.
#[derive(Debug)]
pub struct Ads1220<SPI, DRDY> {
    spi: SPI,
    drdy: DRDY,
    config: Config,
}

impl<SPI: SpiDevice, DRDY: InputPin> Ads1220<SPI, DRDY> {
    /// Reset the chip, write `config`, verify it by reading it back, start conversions.
    /// **non-RT**.
    pub fn new(
        spi: SPI,
        drdy: DRDY,
        config: Config,
    ) -> Result<Self, Error<SPI::Error, DRDY::Error>> {
        let mut adc = Ads1220 { spi, drdy, config };
        adc.spi
            .transaction(&mut [
                Operation::Write(&[cmd::RESET]),
                Operation::DelayNs(RESET_WAIT_NS),
            ])
            .map_err(Error::Spi)?;
        let c = config;
        let written = [c.reg0, c.reg1, c.reg2, c.reg3];
        adc.spi
            .write(&[cmd::wreg(0, 4), c.reg0, c.reg1, c.reg2, c.reg3])
            .map_err(Error::Spi)?;
        let read = adc.read_registers()?;
        if read != written {
            return Err(Error::ConfigMismatch { written, read });
        }
        adc.spi.write(&[cmd::START]).map_err(Error::Spi)?;
        Ok(adc)
    }

    /// Read the four configuration registers.
    pub fn read_registers(&mut self) -> Result<[u8; 4], Error<SPI::Error, DRDY::Error>> {
        let mut regs = [0u8; 4];
        self.spi
            .transaction(&mut [
                Operation::Write(&[cmd::rreg(0, 4)]),
                Operation::Read(&mut regs),
            ])
            .map_err(Error::Spi)?;
        Ok(regs)
    }

    /// The configuration in use.
    pub fn config(&self) -> Config {
        self.config
    }

    /// Whether a conversion is ready (`DRDY` low). **RT**.
    pub fn is_ready(&mut self) -> Result<bool, Error<SPI::Error, DRDY::Error>> {
        self.drdy.is_low().map_err(Error::DataReady)
    }

    /// Read the conversion if ready, else `WouldBlock`. **RT**: one 4-byte SPI transaction.
    pub fn read(&mut self) -> nb::Result<i32, Error<SPI::Error, DRDY::Error>> {
        if !self.is_ready()? {
            return Err(nb::Error::WouldBlock);
        }
        let mut data = [0u8; 3];
        self.spi
            .transaction(&mut [Operation::Write(&[cmd::RDATA]), Operation::Read(&mut data)])
            .map_err(Error::Spi)?;
        let raw = (u32::from(data[0]) << 16) | (u32::from(data[1]) << 8) | u32::from(data[2]);
        Ok(((raw << 8) as i32) >> 8)
    }

    /// Enter power-down (conversions stop until [`Ads1220::start`]).
    pub fn power_down(&mut self) -> Result<(), Error<SPI::Error, DRDY::Error>> {
        self.spi.write(&[cmd::POWERDOWN]).map_err(Error::Spi)
    }

    /// Start (or restart) conversions.
    pub fn start(&mut self) -> Result<(), Error<SPI::Error, DRDY::Error>> {
        self.spi.write(&[cmd::START]).map_err(Error::Spi)
    }

    /// Give the SPI device and the data-ready pin back.
    pub fn release(self) -> (SPI, DRDY) {
        (self.spi, self.drdy)
    }
}

impl<SPI: SpiDevice, DRDY: InputPin> RawAdc for Ads1220<SPI, DRDY> {
    type Error = Error<SPI::Error, DRDY::Error>;
    fn read_raw(&mut self) -> nb::Result<i32, Self::Error> {
        self.read()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use embedded_hal_mock::eh1::digital::{Mock as PinMock, State, Transaction as P};
    use embedded_hal_mock::eh1::spi::{Mock as SpiMock, Transaction as S};

    const CFG: Config = Config::bridge(PgaGain::X128);

    fn init_transactions(readback: [u8; 4]) -> Vec<S<u8>> {
        vec![
            S::transaction_start(),
            S::write_vec(vec![0x06]),
            S::delay(RESET_WAIT_NS),
            S::transaction_end(),
            S::transaction_start(),
            S::write_vec(vec![0x43, 0x0E, 0x04, 0x50, 0x00]),
            S::transaction_end(),
            S::transaction_start(),
            S::write_vec(vec![0x23]),
            S::read_vec(readback.to_vec()),
            S::transaction_end(),
        ]
    }

    #[test]
    fn bridge_config_has_the_documented_register_values() {
        assert_eq!(
            [CFG.reg0, CFG.reg1, CFG.reg2, CFG.reg3],
            [0x0E, 0x04, 0x50, 0x00]
        );
        assert!(CFG.is_continuous());
    }

    #[test]
    fn control_config_converts_at_2000_per_second_without_the_mains_filter() {
        assert_eq!(
            Config::bridge_at(PgaGain::X128, true, 6),
            Some(Config::bridge_for_control(PgaGain::X128))
        );
        let normal_330 = Config::bridge_at(PgaGain::X128, false, 4).unwrap();
        assert_eq!(normal_330.reg1 >> 5, 0b100);
        assert_eq!((normal_330.reg1 >> 3) & 0b11, 0b00);
        assert!(normal_330.is_continuous());
        assert_eq!(Config::bridge_at(PgaGain::X128, false, 7), None);
        let c = Config::bridge_for_control(PgaGain::X128);
        assert_eq!([c.reg0, c.reg1, c.reg2, c.reg3], [0x0E, 0xD4, 0x40, 0x00]);
        assert_eq!(c.reg1 >> 5, 0b110, "data rate 2000 SPS in turbo mode");
        assert_eq!((c.reg1 >> 3) & 0b11, 0b10, "turbo mode");
        assert_eq!((c.reg2 >> 4) & 0b11, 0, "50/60 Hz filter off");
        assert!(c.is_continuous());
    }

    #[test]
    fn configures_verifies_starts_and_reads_conversions() {
        let mut t = init_transactions([0x0E, 0x04, 0x50, 0x00]);
        t.extend([
            S::transaction_start(),
            S::write_vec(vec![0x08]),
            S::transaction_end(),
            S::transaction_start(),
            S::write_vec(vec![0x10]),
            S::read_vec(vec![0x12, 0x34, 0x56]),
            S::transaction_end(),
            S::transaction_start(),
            S::write_vec(vec![0x10]),
            S::read_vec(vec![0xFF, 0xFF, 0xFE]),
            S::transaction_end(),
        ]);
        let mut spi = SpiMock::new(&t);
        let mut drdy = PinMock::new(&[P::get(State::High), P::get(State::Low), P::get(State::Low)]);
        let mut adc = Ads1220::new(spi.clone(), drdy.clone(), CFG).unwrap();
        assert_eq!(adc.read(), Err(nb::Error::WouldBlock));
        assert_eq!(adc.read(), Ok(0x12_3456));
        assert_eq!(adc.read(), Ok(-2));
        let (_s, _d) = adc.release();
        spi.done();
        drdy.done();
    }

    #[test]
    fn a_register_readback_mismatch_is_an_error() {
        let mut spi = SpiMock::new(&init_transactions([0xFF; 4]));
        let mut drdy = PinMock::new(&[]);
        let e = Ads1220::new(spi.clone(), drdy.clone(), CFG).unwrap_err();
        assert_eq!(
            e,
            Error::ConfigMismatch {
                written: [0x0E, 0x04, 0x50, 0x00],
                read: [0xFF; 4]
            }
        );
        spi.done();
        drdy.done();
    }
}
