//! A tension sensor read through a wire drive's analog input: the load cell's amplifier is
//! wired into the CiA 402 drive, which sends the converted value with its status in TPDO2 at
//! every SYNC (synchronous with the encoders, no extra bus frames). The drive set publishes the
//! values ([`DriveAnalogInputs`]); [`DriveInputAdc`] reads one wire's as a [`RawAdc`], so
//! [`StrainGaugeSet`](super::tension_set::StrainGaugeSet) adds calibration and staleness as
//! for the other converters. Pure: no I/O of its own.

use std::sync::Arc;

use super::RawAdc;
use crate::cia402::{AnalogSample, DriveAnalogInputs};

/// The code a reading at either 16-bit rail is reported as: the 24-bit full-scale code the
/// tension set takes for a saturated converter (amplifier at its limit or cable broken).
const RAIL_POS: i32 = 0x7F_FFFF;
const RAIL_NEG: i32 = -0x80_0000;

/// The published inputs of a drive set of any wire count, as one wire's reader sees them.
trait AnalogSource: core::fmt::Debug + Send + Sync {
    fn latest(&self, wire: usize) -> AnalogSample;
}

impl<const N: usize> AnalogSource for DriveAnalogInputs<N> {
    fn latest(&self, wire: usize) -> AnalogSample {
        DriveAnalogInputs::latest(self, wire)
    }
}

/// One wire's analog input, as published by the drive set.
///
/// One wire's converter, so not generic over the wire count `N` of the inputs it reads: it
/// holds them as a shared trait object (the wire index checked against `N` when it is made), so
/// one type serves every device and an enum of converters can hold it whatever the wire count.
/// A read is one dynamic call and one atomic load; nothing is allocated.
#[derive(Debug, Clone)]
pub struct DriveInputAdc {
    inputs: Arc<dyn AnalogSource>,
    wire: usize,
    seen: u32,
}

/// A wire index outside `0..wires`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("drive analog input: wire {wire} does not exist (allowed: {})", allowed(*.wires))]
pub struct NoSuchWire {
    /// The wire asked for.
    pub wire: usize,
    /// The wire count of the inputs asked.
    pub wires: usize,
}

fn allowed(wires: usize) -> String {
    match wires {
        0 => "none".to_string(),
        n => format!("0..={}", n - 1),
    }
}

impl DriveInputAdc {
    /// Read wire `wire`'s drive analog input from `inputs` (from
    /// [`Cia402DriveSet::analog_inputs`](crate::cia402::Cia402DriveSet::analog_inputs)), an
    /// error unless `wire < N`. Samples published before this call count as new once.
    pub fn new<const N: usize>(
        inputs: Arc<DriveAnalogInputs<N>>,
        wire: usize,
    ) -> Result<DriveInputAdc, NoSuchWire> {
        if wire >= N {
            return Err(NoSuchWire { wire, wires: N });
        }
        Ok(DriveInputAdc {
            inputs,
            wire,
            seen: 0,
        })
    }

    /// Every wire's input, in wire order (one per wire of `inputs`).
    pub fn for_each_wire<const N: usize>(inputs: &Arc<DriveAnalogInputs<N>>) -> [DriveInputAdc; N] {
        core::array::from_fn(|wire| DriveInputAdc {
            inputs: Arc::clone(inputs) as Arc<dyn AnalogSource>,
            wire,
            seen: 0,
        })
    }

    /// The wire read.
    pub fn wire(&self) -> usize {
        self.wire
    }
}

impl RawAdc for DriveInputAdc {
    type Error = core::convert::Infallible;

    /// The newest value if one arrived since the last read (`WouldBlock` otherwise). A value at
    /// `i16::MAX` or `i16::MIN` is reported as the full-scale code (a saturated sensor). **RT**:
    /// one atomic load.
    fn read_raw(&mut self) -> nb::Result<i32, Self::Error> {
        let sample = self.inputs.latest(self.wire);
        if sample.count == self.seen {
            return Err(nb::Error::WouldBlock);
        }
        self.seen = sample.count;
        Ok(match sample.value {
            i16::MAX => RAIL_POS,
            i16::MIN => RAIL_NEG,
            v => i32::from(v),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::super::calibration::TensionCalibration;
    use super::super::tension_set::{NanoClock, StrainGaugeSet, TensionFault};
    use super::*;
    use core::cell::Cell;
    use std::rc::Rc;
    use videt_hal::TensionSensors;

    /// The WireMan's wire count, for the tests of the three-wire set.
    const WIRES: usize = 3;

    #[test]
    fn each_new_sample_is_read_once() {
        let inputs = Arc::new(DriveAnalogInputs::<WIRES>::new());
        let mut adc = DriveInputAdc::new(inputs.clone(), 1).unwrap();
        assert_eq!(adc.read_raw(), Err(nb::Error::WouldBlock));
        inputs.publish(1, 500);
        inputs.publish(0, 9);
        assert_eq!(adc.read_raw(), Ok(500));
        assert_eq!(adc.read_raw(), Err(nb::Error::WouldBlock));
        // The same value again is still a new sample.
        inputs.publish(1, 500);
        assert_eq!(adc.read_raw(), Ok(500));
        inputs.publish(1, i16::MAX);
        assert_eq!(adc.read_raw(), Ok(RAIL_POS));
        inputs.publish(1, i16::MIN);
        assert_eq!(adc.read_raw(), Ok(RAIL_NEG));
        assert_eq!(
            DriveInputAdc::new(inputs, 3).unwrap_err().to_string(),
            "drive analog input: wire 3 does not exist (allowed: 0..=2)"
        );
    }

    #[derive(Clone)]
    struct FakeClock(Rc<Cell<u64>>);
    impl NanoClock for FakeClock {
        fn now_ns(&self) -> u64 {
            self.0.get()
        }
    }

    #[test]
    fn the_tension_set_calibrates_and_ages_drive_inputs() {
        let inputs = Arc::new(DriveAnalogInputs::<WIRES>::new());
        let t = Rc::new(Cell::new(0));
        let cal = TensionCalibration {
            offset_counts: 100.0,
            newtons_per_count: 0.01,
        };
        let mut set = StrainGaugeSet::new(
            DriveInputAdc::for_each_wire(&inputs),
            [cal; WIRES],
            FakeClock(t.clone()),
            core::time::Duration::from_millis(20),
        );
        let mut out = [0.0; WIRES];
        assert_eq!(
            set.read_tensions(&mut out).unwrap_err().fault,
            TensionFault::Stale { age_ms: u64::MAX }
        );
        for (wire, v) in [1100, 2100, 100].into_iter().enumerate() {
            inputs.publish(wire, v);
        }
        set.read_tensions(&mut out).unwrap();
        assert_eq!(out, [10.0, 20.0, 0.0]);
        // Wires 0 and 1 keep arriving, wire 2's drive went quiet.
        t.set(25_000_000);
        inputs.publish(0, 1100);
        inputs.publish(1, 2100);
        let e = set.read_tensions(&mut out).unwrap_err();
        assert_eq!((e.wire, e.fault), (2, TensionFault::Stale { age_ms: 25 }));
        inputs.publish(2, i16::MAX);
        let e = set.read_tensions(&mut out).unwrap_err();
        assert_eq!((e.wire, e.fault), (2, TensionFault::Saturated));
    }

    #[test]
    fn a_two_wire_set_reads_its_two_drive_inputs() {
        let inputs = Arc::new(DriveAnalogInputs::<2>::new());
        assert_eq!(
            DriveInputAdc::new(inputs.clone(), 2)
                .unwrap_err()
                .to_string(),
            "drive analog input: wire 2 does not exist (allowed: 0..=1)"
        );
        let cal = TensionCalibration {
            offset_counts: 0.0,
            newtons_per_count: 0.01,
        };
        let mut set = StrainGaugeSet::new(
            DriveInputAdc::for_each_wire(&inputs),
            [cal; 2],
            FakeClock(Rc::new(Cell::new(0))),
            core::time::Duration::from_millis(20),
        );
        inputs.publish(0, 300);
        inputs.publish(1, -200);
        let mut out = [0.0; 2];
        assert_eq!(set.read_fresh_tensions(&mut out), Ok([true, true]));
        assert_eq!(out, [3.0, -2.0]);
        inputs.publish(1, 100);
        assert_eq!(set.read_fresh_tensions(&mut out), Ok([false, true]));
        assert_eq!(out, [3.0, 1.0]);
        let adcs = set.release();
        assert_eq!(adcs.map(|a| a.wire()), [0, 1]);
    }
}
