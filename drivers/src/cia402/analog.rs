//! The drives' analog inputs as the drive set received them: a lock-free hand-over from the
//! drive set (writer, in `read_drives`) to whoever reads the values (the tension sensors of
//! [`crate::adc::drive_input`]), each wire a single atomic word holding the newest value and a
//! sample counter.

use core::sync::atomic::{AtomicU64, Ordering};

/// One wire's newest analog input sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct AnalogSample {
    /// The raw 16-bit signed value the drive sent.
    pub value: i16,
    /// How many samples of this wire have arrived (0: none yet; after `u32::MAX` it wraps to 1).
    /// A reader that sees the same count twice has seen no new sample in between.
    pub count: u32,
}

impl AnalogSample {
    fn pack(self) -> u64 {
        (u64::from(self.count) << 32) | u64::from(self.value as u16)
    }

    fn unpack(word: u64) -> AnalogSample {
        AnalogSample {
            value: word as u16 as i16,
            count: (word >> 32) as u32,
        }
    }
}

/// The newest analog input of each of the `N` wires' drives, shared between the drive set and
/// its readers. Wait-free: value and counter of a wire are one atomic word, so a reader never
/// sees the value of one sample with the counter of another. One writer (the drive set).
#[derive(Debug)]
pub struct DriveAnalogInputs<const N: usize> {
    slots: [AtomicU64; N],
}

impl<const N: usize> Default for DriveAnalogInputs<N> {
    fn default() -> Self {
        DriveAnalogInputs {
            slots: core::array::from_fn(|_| AtomicU64::new(0)),
        }
    }
}

impl<const N: usize> DriveAnalogInputs<N> {
    /// No sample yet on any wire.
    pub fn new() -> DriveAnalogInputs<N> {
        DriveAnalogInputs::default()
    }

    /// The number of wires, `N`.
    pub const fn wires(&self) -> usize {
        N
    }

    /// Record a new sample `value` of wire `wire` (counter + 1). **RT**.
    ///
    /// # Panics
    /// If `wire >= N`.
    pub fn publish(&self, wire: usize, value: i16) {
        let slot = &self.slots[wire];
        let count = match AnalogSample::unpack(slot.load(Ordering::Relaxed)).count {
            u32::MAX => 1,
            c => c + 1,
        };
        slot.store(AnalogSample { value, count }.pack(), Ordering::Release);
    }

    /// The newest sample of wire `wire`. **RT**.
    ///
    /// # Panics
    /// If `wire >= N`.
    pub fn latest(&self, wire: usize) -> AnalogSample {
        AnalogSample::unpack(self.slots[wire].load(Ordering::Acquire))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_wire_keeps_its_newest_value_and_counts_its_samples() {
        let a = DriveAnalogInputs::<3>::new();
        assert_eq!(a.latest(1), AnalogSample::default());
        a.publish(1, -32768);
        a.publish(1, 1234);
        a.publish(2, -1);
        assert_eq!(
            a.latest(1),
            AnalogSample {
                value: 1234,
                count: 2
            }
        );
        assert_eq!(
            a.latest(2),
            AnalogSample {
                value: -1,
                count: 1
            }
        );
        assert_eq!(a.latest(0).count, 0);
    }

    #[test]
    fn the_counter_wraps_past_zero() {
        let a = DriveAnalogInputs::<1>::new();
        a.slots[0].store(
            AnalogSample {
                value: 7,
                count: u32::MAX,
            }
            .pack(),
            Ordering::Relaxed,
        );
        a.publish(0, i16::MIN);
        assert_eq!(
            a.latest(0),
            AnalogSample {
                value: i16::MIN,
                count: 1
            }
        );
    }

    #[test]
    fn any_wire_count_has_its_own_slots() {
        let a = DriveAnalogInputs::<4>::default();
        assert_eq!(a.wires(), 4);
        a.publish(3, 44);
        assert_eq!(
            a.latest(3),
            AnalogSample {
                value: 44,
                count: 1
            }
        );
        assert!((0..3).all(|w| a.latest(w).count == 0));
    }

    #[test]
    #[should_panic]
    fn a_wire_beyond_the_count_panics() {
        DriveAnalogInputs::<2>::new().publish(2, 1);
    }
}
