//! One strain-gauge ADC per wire as the HAL's tension sensors of an `N`-wire device: each read
//! takes a new conversion when one is ready, else keeps the last sample; a sample older than
//! the staleness limit, a saturated converter or a bus error is an error naming the wire.

use videt_hal::{ErrorKind, TensionSensors};

use super::calibration::TensionCalibration;
use super::RawAdc;

/// A monotonic time source in nanoseconds (injected so tests control time).
pub trait NanoClock {
    /// Now, ns since an arbitrary origin. **RT**.
    fn now_ns(&self) -> u64;
}

/// The process's monotonic clock.
#[derive(Debug, Clone, Copy)]
pub struct MonotonicClock(std::time::Instant);

impl Default for MonotonicClock {
    fn default() -> Self {
        MonotonicClock(std::time::Instant::now())
    }
}

impl NanoClock for MonotonicClock {
    fn now_ns(&self) -> u64 {
        self.0.elapsed().as_nanos() as u64
    }
}

/// What went wrong with a tension sensor.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TensionFault {
    /// The converter's bus or pins failed.
    Bus,
    /// The newest sample is older than the limit (or none arrived yet).
    Stale {
        /// Age of the newest sample, ms (`u64::MAX` when none ever arrived).
        age_ms: u64,
    },
    /// The converter reads full scale (bridge broken or overloaded).
    Saturated,
}

/// A tension-sensor error, naming the wire.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TensionError {
    /// Wire index.
    pub wire: usize,
    /// What failed.
    pub fault: TensionFault,
}

impl videt_hal::Error for TensionError {
    fn kind(&self) -> ErrorKind {
        match self.fault {
            TensionFault::Bus => ErrorKind::Disconnected,
            TensionFault::Stale { .. } => ErrorKind::Timeout,
            TensionFault::Saturated => ErrorKind::Fault,
        }
    }
}

impl core::fmt::Display for TensionError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self.fault {
            TensionFault::Bus => write!(f, "tension sensor {}: converter bus error", self.wire),
            TensionFault::Stale { age_ms: u64::MAX } => {
                write!(f, "tension sensor {}: no sample yet", self.wire)
            }
            TensionFault::Stale { age_ms } => {
                write!(
                    f,
                    "tension sensor {}: newest sample is {age_ms} ms old",
                    self.wire
                )
            }
            TensionFault::Saturated => write!(
                f,
                "tension sensor {}: converter at full scale (bridge broken or overloaded)",
                self.wire
            ),
        }
    }
}

impl std::error::Error for TensionError {}

/// Full-scale codes of a 24-bit converter.
const FULL_SCALE_POS: i32 = 0x7F_FFFF;
const FULL_SCALE_NEG: i32 = -0x80_0000;

/// `N` ADCs (one per wire) with their calibrations: `TensionSensors<N>` for every `N`.
#[derive(Debug)]
pub struct StrainGaugeSet<A, C, const N: usize> {
    adcs: [A; N],
    calibration: [TensionCalibration; N],
    clock: C,
    stale_after_ns: u64,
    last_n: [f64; N],
    last_at_ns: [Option<u64>; N],
}

impl<A: RawAdc, C: NanoClock, const N: usize> StrainGaugeSet<A, C, N> {
    /// Take the ADCs (wire order: their count is the wire count `N`), their calibrations, a
    /// clock, and the age at which a sample is stale.
    pub fn new(
        adcs: [A; N],
        calibration: [TensionCalibration; N],
        clock: C,
        stale_after: core::time::Duration,
    ) -> Self {
        StrainGaugeSet {
            adcs,
            calibration,
            clock,
            stale_after_ns: stale_after.as_nanos() as u64,
            last_n: [0.0; N],
            last_at_ns: [None; N],
        }
    }

    /// Replace the calibration of every wire.
    pub fn set_calibration(&mut self, calibration: [TensionCalibration; N]) {
        self.calibration = calibration;
    }

    /// Give the ADCs back.
    pub fn release(self) -> [A; N] {
        self.adcs
    }
}

impl<A: RawAdc, C: NanoClock, const N: usize> videt_hal::ErrorType for StrainGaugeSet<A, C, N> {
    type Error = TensionError;
}

impl<A: RawAdc, C: NanoClock, const N: usize> TensionSensors<N> for StrainGaugeSet<A, C, N> {
    fn read_tensions(&mut self, out_n: &mut [f64; N]) -> Result<(), TensionError> {
        self.read_fresh_tensions(out_n).map(|_| ())
    }

    /// A wire's sample is fresh when its converter delivered a conversion in this read.
    fn read_fresh_tensions(&mut self, out_n: &mut [f64; N]) -> Result<[bool; N], TensionError> {
        let now = self.clock.now_ns();
        let mut fresh = [false; N];
        for wire in 0..N {
            match self.adcs[wire].read_raw() {
                Ok(raw) if raw == FULL_SCALE_POS || raw == FULL_SCALE_NEG => {
                    return Err(TensionError {
                        wire,
                        fault: TensionFault::Saturated,
                    })
                }
                Ok(raw) => {
                    self.last_n[wire] = self.calibration[wire].tension_n(raw);
                    self.last_at_ns[wire] = Some(now);
                    fresh[wire] = true;
                }
                Err(nb::Error::WouldBlock) => {}
                Err(nb::Error::Other(_)) => {
                    return Err(TensionError {
                        wire,
                        fault: TensionFault::Bus,
                    })
                }
            }
            let age = self.last_at_ns[wire].map_or(u64::MAX, |t| now.saturating_sub(t));
            if age > self.stale_after_ns {
                return Err(TensionError {
                    wire,
                    fault: TensionFault::Stale {
                        age_ms: if age == u64::MAX {
                            age
                        } else {
                            age / 1_000_000
                        },
                    },
                });
            }
            out_n[wire] = self.last_n[wire];
        }
        Ok(fresh)
    }
}

#[cfg(test)]
mod tests {
    use super::super::hx711::{Gain, Hx711};
    use super::*;
    use core::cell::Cell;
    use embedded_hal_mock::eh1::delay::NoopDelay;
    use embedded_hal_mock::eh1::digital::{Mock as PinMock, State, Transaction as T};
    use std::rc::Rc;

    /// The WireMan's wire count, for the tests of the three-sensor set.
    const WIRES: usize = 3;

    #[derive(Clone)]
    struct FakeClock(Rc<Cell<u64>>);
    impl NanoClock for FakeClock {
        fn now_ns(&self) -> u64 {
            self.0.get()
        }
    }

    /// Scripted raw readings (`None` = not ready).
    struct Script(Vec<Option<i32>>);
    impl RawAdc for Script {
        type Error = ();
        fn read_raw(&mut self) -> nb::Result<i32, ()> {
            match self.0.remove(0) {
                Some(v) => Ok(v),
                None => Err(nb::Error::WouldBlock),
            }
        }
    }

    fn cal() -> TensionCalibration {
        TensionCalibration::from_two_points((1000, 0.0), (11000, 10.0)).unwrap()
    }

    #[test]
    fn keeps_the_last_sample_until_it_is_stale() {
        let t = Rc::new(Cell::new(0));
        let adcs = [
            Script(vec![Some(6000), None, None]),
            Script(vec![Some(1000), Some(2000), None]),
            Script(vec![Some(11000), None, None]),
        ];
        let mut set = StrainGaugeSet::new(
            adcs,
            [cal(); WIRES],
            FakeClock(t.clone()),
            core::time::Duration::from_millis(100),
        );
        let mut out = [0.0; WIRES];
        set.read_tensions(&mut out).unwrap();
        assert_eq!(out, [5.0, 0.0, 10.0]);
        t.set(50_000_000);
        set.read_tensions(&mut out).unwrap();
        assert_eq!(out, [5.0, 1.0, 10.0]);
        t.set(120_000_000);
        let e = set.read_tensions(&mut out).unwrap_err();
        assert_eq!(
            e,
            TensionError {
                wire: 0,
                fault: TensionFault::Stale { age_ms: 120 }
            }
        );
        assert_eq!(videt_hal::Error::kind(&e), ErrorKind::Timeout);
    }

    #[test]
    fn saturation_and_missing_samples_are_errors() {
        let t = Rc::new(Cell::new(0));
        let mut set = StrainGaugeSet::new(
            [
                Script(vec![Some(0)]),
                Script(vec![Some(FULL_SCALE_POS)]),
                Script(vec![]),
            ],
            [cal(); WIRES],
            FakeClock(t.clone()),
            core::time::Duration::from_millis(100),
        );
        let mut out = [0.0; WIRES];
        let e = set.read_tensions(&mut out).unwrap_err();
        assert_eq!(e.fault, TensionFault::Saturated);
        assert_eq!(e.wire, 1);
        let mut set = StrainGaugeSet::new(
            [Script(vec![None]), Script(vec![]), Script(vec![])],
            [cal(); WIRES],
            FakeClock(t),
            core::time::Duration::from_millis(100),
        );
        let e = set.read_tensions(&mut out).unwrap_err();
        assert_eq!(e.to_string(), "tension sensor 0: no sample yet");
    }

    #[test]
    fn three_hx711_over_mock_pins_give_calibrated_tensions() {
        fn hx(value: i32) -> (Hx711<PinMock, PinMock, NoopDelay>, PinMock, PinMock) {
            let mut sck_t = vec![T::set(State::Low)];
            for _ in 0..25 {
                sck_t.extend([T::set(State::High), T::set(State::Low)]);
            }
            let raw = (value as u32) & 0xFF_FFFF;
            let mut d = vec![T::get(State::Low)];
            for i in (0..24).rev() {
                d.push(T::get(if raw >> i & 1 == 1 {
                    State::High
                } else {
                    State::Low
                }));
            }
            let sck = PinMock::new(&sck_t);
            let dout = PinMock::new(&d);
            let adc = Hx711::new(sck.clone(), dout.clone(), NoopDelay::new(), Gain::A128).unwrap();
            (adc, sck, dout)
        }
        let (a, mut s0, mut d0) = hx(1000);
        let (b, mut s1, mut d1) = hx(3500);
        let (c, mut s2, mut d2) = hx(-9000);
        let t = Rc::new(Cell::new(0));
        let mut set = StrainGaugeSet::new(
            [a, b, c],
            [cal(); WIRES],
            FakeClock(t),
            core::time::Duration::from_millis(100),
        );
        let mut out = [0.0; WIRES];
        set.read_tensions(&mut out).unwrap();
        assert_eq!(out, [0.0, 2.5, -10.0]);
        for adc in set.release() {
            let _ = adc.release();
        }
        for m in [&mut s0, &mut d0, &mut s1, &mut d1, &mut s2, &mut d2] {
            m.done();
        }
    }

    #[test]
    fn one_and_four_wire_sets_read_every_wire_and_name_the_failing_one() {
        let t = Rc::new(Cell::new(0));
        let stale_after = core::time::Duration::from_millis(100);
        let mut one = StrainGaugeSet::new(
            [Script(vec![Some(6000), None])],
            [cal()],
            FakeClock(t.clone()),
            stale_after,
        );
        let mut out1 = [0.0; 1];
        assert_eq!(one.read_fresh_tensions(&mut out1), Ok([true]));
        assert_eq!(out1, [5.0]);
        assert_eq!(one.read_fresh_tensions(&mut out1), Ok([false]));
        assert_eq!(out1, [5.0]);

        let mut four = StrainGaugeSet::new(
            [
                Script(vec![Some(1000), None]),
                Script(vec![Some(3000), Some(5000)]),
                Script(vec![Some(11000), None]),
                Script(vec![Some(21000), Some(FULL_SCALE_NEG)]),
            ],
            [cal(); 4],
            FakeClock(t.clone()),
            stale_after,
        );
        let mut out4 = [0.0; 4];
        assert_eq!(four.read_fresh_tensions(&mut out4), Ok([true; 4]));
        assert_eq!(out4, [0.0, 2.0, 10.0, 20.0]);
        t.set(10_000_000);
        let e = four.read_fresh_tensions(&mut out4).unwrap_err();
        assert_eq!(
            e,
            TensionError {
                wire: 3,
                fault: TensionFault::Saturated
            }
        );
        // Wires before the failing one were read.
        assert_eq!(out4[..3], [0.0, 4.0, 10.0]);
    }
}
