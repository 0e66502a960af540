//! The emergency-stop button: an active-low input (pressed = low; wired with a pull-down and a
//! normally-closed contact to the supply, a cut wire reads as pressed), debounced over
//! consecutive samples and latched until an explicit reset.

use embedded_hal::digital::{Error as _, InputPin};
use videt_hal::EStop;

use super::GpioError;

/// Debounced, latched e-stop on an input pin, pressed at its low level (the usual
/// normally-closed button to a pulled-up input, where a cut wire reads as pressed) or, as
/// configured, at its high level.
#[derive(Debug)]
pub struct EStopInput<P> {
    pin: P,
    debounce_samples: u8,
    pressed_high: bool,
    pressed_count: u8,
    latched: bool,
}

impl<P: InputPin> EStopInput<P> {
    /// Take the pin, pressed when low. The press is accepted after `debounce_samples`
    /// consecutive pressed readings (at least 1; one reading per [`EStop::is_pressed`] call,
    /// i.e. per control period).
    pub fn new(pin: P, debounce_samples: u8) -> Self {
        EStopInput {
            pin,
            debounce_samples: debounce_samples.max(1),
            pressed_high: false,
            pressed_count: 0,
            latched: false,
        }
    }

    /// The same input, pressed when its line is high instead.
    pub fn pressed_when_high(mut self) -> Self {
        self.pressed_high = true;
        self
    }

    /// Whether the line is at its pressed level now (not debounced, not latched).
    fn at_pressed_level(&mut self) -> Result<bool, P::Error> {
        if self.pressed_high {
            self.pin.is_high()
        } else {
            self.pin.is_low()
        }
    }

    fn err(e: P::Error) -> GpioError {
        GpioError {
            pin: "e-stop",
            kind: e.kind(),
            still_held: false,
        }
    }

    /// Give the pin back.
    pub fn release(self) -> P {
        self.pin
    }
}

impl<P: InputPin> videt_hal::ErrorType for EStopInput<P> {
    type Error = GpioError;
}

impl<P: InputPin> EStop for EStopInput<P> {
    fn is_pressed(&mut self) -> Result<bool, GpioError> {
        let pressed = match self.at_pressed_level() {
            Ok(p) => p,
            Err(e) => {
                // A pin that cannot be read is treated as pressed.
                self.latched = true;
                return Err(Self::err(e));
            }
        };
        if pressed {
            self.pressed_count = self.pressed_count.saturating_add(1);
            if self.pressed_count >= self.debounce_samples {
                self.latched = true;
            }
        } else {
            self.pressed_count = 0;
        }
        Ok(self.latched)
    }

    fn reset(&mut self) -> Result<(), GpioError> {
        if self.at_pressed_level().map_err(Self::err)? {
            return Err(GpioError {
                pin: "e-stop",
                kind: embedded_hal::digital::ErrorKind::Other,
                still_held: true,
            });
        }
        self.latched = false;
        self.pressed_count = 0;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use embedded_hal_mock::eh1::digital::{Mock as PinMock, State, Transaction as T};
    use embedded_hal_mock::eh1::MockError;

    #[test]
    fn a_press_is_debounced_then_latched_until_reset() {
        use State::{High, Low};
        let script = [
            T::get(High),
            T::get(Low), // bounce
            T::get(High),
            T::get(Low),
            T::get(Low),
            T::get(Low), // third low in a row: pressed
            T::get(High),
            T::get(High), // reset: released, accepted
            T::get(High),
        ];
        let mut pin = PinMock::new(&script);
        let mut e = EStopInput::new(pin.clone(), 3);
        let seen: Vec<bool> = (0..7).map(|_| e.is_pressed().unwrap()).collect();
        assert_eq!(seen, [false, false, false, false, false, true, true]);
        e.reset().unwrap();
        assert!(!e.is_pressed().unwrap());
        let _ = e.release();
        pin.done();
    }

    #[test]
    fn reset_is_refused_while_the_button_is_held() {
        let mut pin = PinMock::new(&[T::get(State::Low), T::get(State::Low), T::get(State::Low)]);
        let mut e = EStopInput::new(pin.clone(), 1);
        assert!(e.is_pressed().unwrap());
        let err = e.reset().unwrap_err();
        assert!(err.still_held);
        assert_eq!(videt_hal::Error::kind(&err), videt_hal::ErrorKind::Fault);
        assert!(e.is_pressed().unwrap());
        let _ = e.release();
        pin.done();
    }

    #[test]
    fn an_input_pressed_when_high_reads_its_levels_the_other_way() {
        use State::{High, Low};
        let script = [
            T::get(Low),
            T::get(High),
            T::get(High),
            T::get(Low),
            T::get(Low),
        ];
        let mut pin = PinMock::new(&script);
        let mut e = EStopInput::new(pin.clone(), 2).pressed_when_high();
        let seen: Vec<bool> = (0..3).map(|_| e.is_pressed().unwrap()).collect();
        assert_eq!(seen, [false, false, true]);
        e.reset().unwrap();
        assert!(!e.is_pressed().unwrap());
        let _ = e.release();
        pin.done();
    }

    #[test]
    fn an_unreadable_pin_latches_the_stop() {
        let err = MockError::Io(std::io::ErrorKind::NotConnected);
        let mut pin = PinMock::new(&[T::get(State::High).with_error(err), T::get(State::High)]);
        let mut e = EStopInput::new(pin.clone(), 2);
        assert!(e.is_pressed().is_err());
        assert!(e.is_pressed().unwrap(), "latched by the read error");
        let _ = e.release();
        pin.done();
    }
}
