//! Zero offset and sense of rotation of one angle axis: raw encoder counts to the calibrated
//! angle of eq. 7, and back.

use core::f64::consts::TAU;

/// Counts of one turn of a 14-bit encoder.
pub const COUNTS_PER_TURN: u16 = 1 << 14;

/// One count, radians (2π/16384, 0.022°).
pub const RAD_PER_COUNT: f64 = TAU / COUNTS_PER_TURN as f64;

const TURN: i32 = COUNTS_PER_TURN as i32;
const HALF_TURN: i32 = TURN / 2;

/// Which way the encoder's counts run with respect to the axis' positive angle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Sense {
    /// Counts increase with the angle (+1).
    Positive,
    /// Counts decrease as the angle increases (-1): the encoder faces the other way.
    Negative,
}

impl Sense {
    /// +1 or -1.
    pub const fn sign(self) -> i32 {
        match self {
            Sense::Positive => 1,
            Sense::Negative => -1,
        }
    }
}

/// The calibration of one axis: the raw count at which the angle is zero and the sense of
/// rotation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Calibration {
    /// Raw count at angle zero (taken modulo [`COUNTS_PER_TURN`]).
    pub zero_counts: u16,
    /// Sense of rotation.
    pub sense: Sense,
}

impl Default for Calibration {
    fn default() -> Self {
        Calibration::IDENTITY
    }
}

impl Calibration {
    /// Zero at count 0, counts increasing with the angle.
    pub const IDENTITY: Calibration = Calibration {
        zero_counts: 0,
        sense: Sense::Positive,
    };

    /// The calibration under which raw `counts`, read at a reference pose whose angle is
    /// `angle_rad`, reads that angle (to the nearest count). A non-finite angle counts as zero.
    pub fn from_reference(counts: u16, angle_rad: f64, sense: Sense) -> Calibration {
        let steps = steps_of(angle_rad);
        let zero = (i64::from(counts) - i64::from(sense.sign()) * steps).rem_euclid(TURN.into());
        Calibration {
            zero_counts: zero as u16,
            sense,
        }
    }

    /// Counts from the zero in the axis' sense, wrapped to `(-8192, 8192]`.
    pub fn signed_counts(&self, counts: u16) -> i32 {
        wrap_counts(self.sense.sign() * (i32::from(counts) - i32::from(self.zero_counts)))
    }

    /// The calibrated angle of raw `counts`, radians in `(-pi, pi]`. **RT**.
    pub fn angle_rad(&self, counts: u16) -> f64 {
        f64::from(self.signed_counts(counts)) * RAD_PER_COUNT
    }

    /// The raw count nearest to `angle_rad` (the inverse of [`angle_rad`](Self::angle_rad)),
    /// in `0..16384`. A non-finite angle counts as zero.
    pub fn counts(&self, angle_rad: f64) -> u16 {
        let steps = steps_of(angle_rad);
        let raw = i64::from(self.zero_counts) + i64::from(self.sense.sign()) * steps;
        raw.rem_euclid(TURN.into()) as u16
    }
}

/// A count difference wrapped to `(-8192, 8192]` (half a turn either way; `+8192` is `+pi`).
pub fn wrap_counts(counts: i32) -> i32 {
    let m = counts.rem_euclid(TURN);
    if m > HALF_TURN {
        m - TURN
    } else {
        m
    }
}

/// Whole counts nearest to `angle_rad`, reduced to one turn so the cast cannot saturate.
fn steps_of(angle_rad: f64) -> i64 {
    if !angle_rad.is_finite() {
        return 0;
    }
    ((angle_rad / RAD_PER_COUNT).round() % f64::from(TURN)) as i64
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::f64::consts::PI;
    use proptest::prelude::*;

    #[test]
    fn the_zero_and_the_sense_are_applied_and_angles_wrap_to_minus_pi_exclusive_pi_inclusive() {
        let c = Calibration {
            zero_counts: 1000,
            sense: Sense::Positive,
        };
        assert_eq!(c.angle_rad(1000), 0.0);
        assert_eq!(c.angle_rad(1001), RAD_PER_COUNT);
        assert_eq!(c.angle_rad(999), -RAD_PER_COUNT);
        // Half a turn from the zero is +pi, never -pi.
        assert_eq!(c.angle_rad(1000 + 8192), PI);
        assert_eq!(c.angle_rad(1000 + 8193), -PI + RAD_PER_COUNT);
        // Across the encoder's own wrap (16383 -> 0).
        let z = Calibration {
            zero_counts: 16380,
            sense: Sense::Positive,
        };
        assert_eq!(z.signed_counts(2), 6);
        assert_eq!(z.signed_counts(16370), -10);

        let n = Calibration {
            zero_counts: 1000,
            sense: Sense::Negative,
        };
        assert_eq!(n.angle_rad(1010), -10.0 * RAD_PER_COUNT);
        assert_eq!(n.angle_rad(990), 10.0 * RAD_PER_COUNT);
        assert_eq!(n.angle_rad(1000 + 8192), PI);
        assert_eq!(n.angle_rad(1000 + 8193), PI - RAD_PER_COUNT);
        // A zero given past 14 bits is taken modulo one turn.
        let big = Calibration {
            zero_counts: 16384 + 5,
            sense: Sense::Positive,
        };
        assert_eq!(big.signed_counts(5), 0);
    }

    #[test]
    fn a_reference_pose_sets_the_zero() {
        let c = Calibration::from_reference(300, PI / 2.0, Sense::Negative);
        assert_eq!(c.zero_counts, 300 + 4096);
        assert!((c.angle_rad(300) - PI / 2.0).abs() < 1e-12);
        let c = Calibration::from_reference(16000, 0.0, Sense::Positive);
        assert_eq!(c.angle_rad(16000), 0.0);
        assert_eq!(c.counts(f64::NAN), 16000);
        assert_eq!(Calibration::default(), Calibration::IDENTITY);
    }

    fn sense() -> impl Strategy<Value = Sense> {
        prop_oneof![Just(Sense::Positive), Just(Sense::Negative)]
    }

    proptest! {
        #![proptest_config(ProptestConfig {
            cases: 512,
            rng_seed: proptest::test_runner::RngSeed::Fixed(48),
            ..ProptestConfig::default()
        })]

        #[test]
        fn counts_to_angle_to_counts_round_trips(counts in 0u16..16384, zero in 0u16..16384, sense in sense()) {
            let c = Calibration { zero_counts: zero, sense };
            let a = c.angle_rad(counts);
            prop_assert!(a > -PI && a <= PI, "{a}");
            prop_assert_eq!(c.counts(a), counts);
        }

        #[test]
        fn angle_to_counts_to_angle_is_within_half_a_count(a in -PI..=PI, zero in 0u16..16384, sense in sense()) {
            let c = Calibration { zero_counts: zero, sense };
            let back = c.angle_rad(c.counts(a));
            // The same angle, up to half a count, possibly on the other side of +-pi.
            let d = (back - a).rem_euclid(TAU);
            let d = d.min(TAU - d);
            prop_assert!(d <= RAD_PER_COUNT / 2.0 + 1e-12, "{a} -> {back}");
        }
    }
}
