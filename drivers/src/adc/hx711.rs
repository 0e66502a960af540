//! HX711 24-bit bridge ADC: a data-ready/data line (`DOUT`, input) and a clock line (`PD_SCK`,
//! output) driven bit by bit. The chip signals a finished conversion by pulling `DOUT` low;
//! 24 clock pulses shift the result out (MSB first, two's complement) and 1-3 more pulses pick
//! the channel and gain of the next conversion.

use embedded_hal::delay::DelayNs;
use embedded_hal::digital::{InputPin, OutputPin};

use super::RawAdc;

/// Channel and gain of the next conversion (number of extra clock pulses).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Gain {
    /// Channel A, gain 128 (1 pulse).
    A128,
    /// Channel B, gain 32 (2 pulses).
    B32,
    /// Channel A, gain 64 (3 pulses).
    A64,
}

impl Gain {
    const fn pulses(self) -> u8 {
        match self {
            Gain::A128 => 1,
            Gain::B32 => 2,
            Gain::A64 => 3,
        }
    }
}

/// An HX711 pin error.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Error<EO, EI> {
    /// The clock pin failed.
    Clock(EO),
    /// The data pin failed.
    Data(EI),
}

/// HX711 driver. Owns its pins and delay; [`Hx711::release`] gives them back.
#[derive(Debug)]
pub struct Hx711<SCK, DOUT, D> {
    sck: SCK,
    dout: DOUT,
    delay: D,
    gain: Gain,
}

/// Clock high/low time, µs (datasheet: 0.2..50 µs; 1 µs keeps a 24-bit read near 50 µs).
const HALF_PERIOD_US: u32 = 1;

impl<SCK: OutputPin, DOUT: InputPin, D: DelayNs> Hx711<SCK, DOUT, D> {
    /// Take the pins; the clock is set low (chip powered, converting). The first conversion
    /// after power-up uses channel A, gain 128.
    pub fn new(
        mut sck: SCK,
        dout: DOUT,
        delay: D,
        gain: Gain,
    ) -> Result<Self, Error<SCK::Error, DOUT::Error>> {
        sck.set_low().map_err(Error::Clock)?;
        Ok(Hx711 {
            sck,
            dout,
            delay,
            gain,
        })
    }

    /// Whether a conversion is ready (`DOUT` low). **RT**.
    pub fn is_ready(&mut self) -> Result<bool, Error<SCK::Error, DOUT::Error>> {
        self.dout.is_low().map_err(Error::Data)
    }

    fn pulse(&mut self) -> Result<(), Error<SCK::Error, DOUT::Error>> {
        self.sck.set_high().map_err(Error::Clock)?;
        self.delay.delay_us(HALF_PERIOD_US);
        self.sck.set_low().map_err(Error::Clock)?;
        self.delay.delay_us(HALF_PERIOD_US);
        Ok(())
    }

    /// Read the conversion if ready, else `WouldBlock` (never waits for the chip). **RT**:
    /// about 27 clock pulses, ~60 µs.
    pub fn read(&mut self) -> nb::Result<i32, Error<SCK::Error, DOUT::Error>> {
        if !self.is_ready()? {
            return Err(nb::Error::WouldBlock);
        }
        let mut raw: u32 = 0;
        for _ in 0..24 {
            self.sck.set_high().map_err(Error::Clock)?;
            self.delay.delay_us(HALF_PERIOD_US);
            let bit = self.dout.is_high().map_err(Error::Data)?;
            self.sck.set_low().map_err(Error::Clock)?;
            self.delay.delay_us(HALF_PERIOD_US);
            raw = (raw << 1) | u32::from(bit);
        }
        for _ in 0..self.gain.pulses() {
            self.pulse()?;
        }
        // Sign-extend 24 to 32 bits.
        Ok(((raw << 8) as i32) >> 8)
    }

    /// Power the chip down (clock high for more than 60 µs).
    pub fn power_down(&mut self) -> Result<(), Error<SCK::Error, DOUT::Error>> {
        self.sck.set_high().map_err(Error::Clock)?;
        self.delay.delay_us(80);
        Ok(())
    }

    /// Power up again (clock low); the chip resets to channel A, gain 128.
    pub fn power_up(&mut self) -> Result<(), Error<SCK::Error, DOUT::Error>> {
        self.sck.set_low().map_err(Error::Clock)?;
        self.gain = Gain::A128;
        Ok(())
    }

    /// Give the pins and the delay back.
    pub fn release(self) -> (SCK, DOUT, D) {
        (self.sck, self.dout, self.delay)
    }
}

impl<SCK: OutputPin, DOUT: InputPin, D: DelayNs> RawAdc for Hx711<SCK, DOUT, D> {
    type Error = Error<SCK::Error, DOUT::Error>;
    fn read_raw(&mut self) -> nb::Result<i32, Self::Error> {
        self.read()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use embedded_hal_mock::eh1::delay::NoopDelay;
    use embedded_hal_mock::eh1::digital::{Mock as PinMock, State, Transaction as T};

    /// Clock transactions for `n` pulses.
    fn clock(n: usize) -> Vec<T> {
        (0..n)
            .flat_map(|_| [T::set(State::High), T::set(State::Low)])
            .collect()
    }

    /// Data-pin transactions: ready check then the 24 bits of `value`.
    fn data(value: i32) -> Vec<T> {
        let raw = (value as u32) & 0x00FF_FFFF;
        let mut t = vec![T::get(State::Low)];
        for i in (0..24).rev() {
            t.push(T::get(if raw >> i & 1 == 1 {
                State::High
            } else {
                State::Low
            }));
        }
        t
    }

    fn read_with(value: i32, gain: Gain) -> i32 {
        let mut sck_t = vec![T::set(State::Low)];
        sck_t.extend(clock(24 + gain.pulses() as usize));
        let mut sck = PinMock::new(&sck_t);
        let mut dout = PinMock::new(&data(value));
        let mut adc = Hx711::new(sck.clone(), dout.clone(), NoopDelay::new(), gain).unwrap();
        let v = adc.read().unwrap();
        let _ = adc.release();
        sck.done();
        dout.done();
        v
    }

    #[test]
    fn reads_positive_and_negative_24_bit_values_and_sets_the_gain() {
        assert_eq!(read_with(0x12_3456, Gain::A128), 0x12_3456);
        assert_eq!(read_with(-1, Gain::B32), -1);
        assert_eq!(read_with(-0x80_0000, Gain::A64), -0x80_0000);
        assert_eq!(read_with(0x7F_FFFF, Gain::A128), 0x7F_FFFF);
    }

    #[test]
    fn does_not_block_while_no_conversion_is_ready() {
        let mut sck = PinMock::new(&[T::set(State::Low)]);
        let mut dout = PinMock::new(&[T::get(State::High)]);
        let mut adc = Hx711::new(sck.clone(), dout.clone(), NoopDelay::new(), Gain::A128).unwrap();
        assert_eq!(adc.read(), Err(nb::Error::WouldBlock));
        let _ = adc.release();
        sck.done();
        dout.done();
    }

    #[test]
    fn pin_errors_are_reported() {
        use embedded_hal_mock::eh1::MockError;
        let err = MockError::Io(std::io::ErrorKind::NotConnected);
        let mut sck = PinMock::new(&[T::set(State::Low)]);
        let mut dout = PinMock::new(&[T::get(State::Low).with_error(err.clone())]);
        let mut adc = Hx711::new(sck.clone(), dout.clone(), NoopDelay::new(), Gain::A128).unwrap();
        assert!(matches!(adc.read(), Err(nb::Error::Other(Error::Data(_)))));
        let _ = adc.release();
        sck.done();
        dout.done();
    }
}
