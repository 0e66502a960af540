//! Three vibrotactor outputs (one per colour channel), each an on/off GPIO.

use embedded_hal::digital::{Error as _, OutputPin};
use videt_hal::{Vibrotactors, VIBROTACTORS};

use super::GpioError;

const NAMES: [&str; VIBROTACTORS] = ["vibrotactor 0", "vibrotactor 1", "vibrotactor 2"];

/// Three output pins driving the vibrotactors (high = on).
#[derive(Debug)]
pub struct VibrotactorOutputs<P> {
    pins: [P; VIBROTACTORS],
    state: [Option<bool>; VIBROTACTORS],
}

impl<P: OutputPin> VibrotactorOutputs<P> {
    /// Take the pins and switch every output off.
    pub fn new(pins: [P; VIBROTACTORS]) -> Result<Self, GpioError> {
        let mut v = VibrotactorOutputs {
            pins,
            state: [None; VIBROTACTORS],
        };
        v.set_outputs(&[false; VIBROTACTORS])?;
        Ok(v)
    }

    /// Give the pins back.
    pub fn release(self) -> [P; VIBROTACTORS] {
        self.pins
    }
}

impl<P: OutputPin> videt_hal::ErrorType for VibrotactorOutputs<P> {
    type Error = GpioError;
}

impl<P: OutputPin> Vibrotactors for VibrotactorOutputs<P> {
    /// Writes only the outputs that change (one GPIO write each). **RT**.
    fn set_outputs(&mut self, on: &[bool; VIBROTACTORS]) -> Result<(), GpioError> {
        for i in 0..VIBROTACTORS {
            if self.state[i] == Some(on[i]) {
                continue;
            }
            let r = if on[i] {
                self.pins[i].set_high()
            } else {
                self.pins[i].set_low()
            };
            match r {
                Ok(()) => self.state[i] = Some(on[i]),
                Err(e) => {
                    self.state[i] = None;
                    return Err(GpioError {
                        pin: NAMES[i],
                        kind: e.kind(),
                        still_held: false,
                    });
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use embedded_hal_mock::eh1::digital::{Mock as PinMock, State, Transaction as T};
    use embedded_hal_mock::eh1::MockError;

    #[test]
    fn switches_only_the_outputs_that_change() {
        let mut p0 = PinMock::new(&[T::set(State::Low), T::set(State::High)]);
        let mut p1 = PinMock::new(&[T::set(State::Low)]);
        let mut p2 = PinMock::new(&[T::set(State::Low), T::set(State::High), T::set(State::Low)]);
        let mut v = VibrotactorOutputs::new([p0.clone(), p1.clone(), p2.clone()]).unwrap();
        v.set_outputs(&[true, false, true]).unwrap();
        v.set_outputs(&[true, false, false]).unwrap();
        let _ = v.release();
        p0.done();
        p1.done();
        p2.done();
    }

    #[test]
    fn a_failing_output_is_named_and_retried_next_time() {
        let err = MockError::Io(std::io::ErrorKind::NotConnected);
        let mut p0 = PinMock::new(&[T::set(State::Low)]);
        let mut p1 = PinMock::new(&[
            T::set(State::Low),
            T::set(State::High).with_error(err),
            T::set(State::High),
        ]);
        let mut p2 = PinMock::new(&[T::set(State::Low)]);
        let mut v = VibrotactorOutputs::new([p0.clone(), p1.clone(), p2.clone()]).unwrap();
        let e = v.set_outputs(&[false, true, false]).unwrap_err();
        assert_eq!(e.pin, "vibrotactor 1");
        v.set_outputs(&[false, true, false]).unwrap();
        let _ = v.release();
        p0.done();
        p1.done();
        p2.done();
    }
}
