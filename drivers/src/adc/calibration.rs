//! Two-point calibration of a strain-gauge tension sensor: raw ADC counts to newtons.
//! Pure math.

/// `tension_n = (raw - offset_counts) * newtons_per_count`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TensionCalibration {
    /// Raw reading at zero tension.
    pub offset_counts: f64,
    /// Newtons per count (negative when the bridge is wired inverted).
    pub newtons_per_count: f64,
}

/// A calibration that cannot be computed from the given points.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CalibrationError {
    /// A load is not a finite number or is negative.
    #[error("calibration load {load_n} N is invalid (allowed: finite, >= 0)")]
    BadLoad {
        /// The load.
        load_n: f64,
    },
    /// The two loads are too close to tell apart.
    #[error("calibration loads {a_n} N and {b_n} N differ by less than {min_n} N")]
    LoadsTooClose {
        /// First load.
        a_n: f64,
        /// Second load.
        b_n: f64,
        /// Smallest difference allowed.
        min_n: f64,
    },
    /// The readings barely changed between the loads (sensor disconnected or saturated).
    #[error("readings {a} and {b} differ by fewer than {min} counts between the two loads")]
    NoResponse {
        /// First reading.
        a: i32,
        /// Second reading.
        b: i32,
        /// Smallest difference allowed.
        min: i32,
    },
}

/// Smallest load difference accepted, N.
pub const MIN_LOAD_SPAN_N: f64 = 0.5;
/// Smallest reading difference accepted, counts.
pub const MIN_COUNT_SPAN: i32 = 100;

impl TensionCalibration {
    /// From two known loads: `(raw_a, load_a_n)` and `(raw_b, load_b_n)` (e.g. unloaded and a
    /// reference mass).
    pub fn from_two_points(
        (raw_a, load_a_n): (i32, f64),
        (raw_b, load_b_n): (i32, f64),
    ) -> Result<TensionCalibration, CalibrationError> {
        for load_n in [load_a_n, load_b_n] {
            if !load_n.is_finite() || load_n < 0.0 {
                return Err(CalibrationError::BadLoad { load_n });
            }
        }
        if (load_b_n - load_a_n).abs() < MIN_LOAD_SPAN_N {
            return Err(CalibrationError::LoadsTooClose {
                a_n: load_a_n,
                b_n: load_b_n,
                min_n: MIN_LOAD_SPAN_N,
            });
        }
        if (i64::from(raw_b) - i64::from(raw_a)).abs() < i64::from(MIN_COUNT_SPAN) {
            return Err(CalibrationError::NoResponse {
                a: raw_a,
                b: raw_b,
                min: MIN_COUNT_SPAN,
            });
        }
        let newtons_per_count = (load_b_n - load_a_n) / (f64::from(raw_b) - f64::from(raw_a));
        let offset_counts = f64::from(raw_a) - load_a_n / newtons_per_count;
        Ok(TensionCalibration {
            offset_counts,
            newtons_per_count,
        })
    }

    /// Tension for a raw reading, N. **RT**.
    pub fn tension_n(&self, raw: i32) -> f64 {
        (f64::from(raw) - self.offset_counts) * self.newtons_per_count
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn two_points_give_offset_and_gain() {
        // 1000 counts at rest, 21000 counts under 9.81 N (1 kg).
        let c = TensionCalibration::from_two_points((1000, 0.0), (21000, 9.81)).unwrap();
        assert!((c.offset_counts - 1000.0).abs() < 1e-9);
        assert!((c.tension_n(11000) - 4.905).abs() < 1e-9);
        // Inverted bridge: the gain is negative, tensions still positive.
        let c = TensionCalibration::from_two_points((0, 0.0), (-5000, 5.0)).unwrap();
        assert!((c.tension_n(-2500) - 2.5).abs() < 1e-12);
    }

    #[test]
    fn degenerate_points_are_refused_with_their_values() {
        assert!(matches!(
            TensionCalibration::from_two_points((0, 1.0), (5000, 1.2)),
            Err(CalibrationError::LoadsTooClose { .. })
        ));
        let e = TensionCalibration::from_two_points((10, 0.0), (50, 9.81)).unwrap_err();
        assert_eq!(
            e,
            CalibrationError::NoResponse {
                a: 10,
                b: 50,
                min: 100
            }
        );
        assert!(e.to_string().contains("10 and 50"), "{e}");
        assert!(matches!(
            TensionCalibration::from_two_points((0, f64::NAN), (5000, 1.0)),
            Err(CalibrationError::BadLoad { .. })
        ));
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 256, rng_seed: proptest::test_runner::RngSeed::Fixed(7), ..ProptestConfig::default() })]
        #[test]
        fn calibration_reproduces_both_points(
            offset in -100_000i32..100_000,
            gain in prop_oneof![1e-5f64..1e-2, -1e-2f64..-1e-5],
            load_a in 0.0f64..5.0,
            span in 1.0f64..20.0,
        ) {
            let load_b = load_a + span;
            let raw = |l: f64| (f64::from(offset) + l / gain).round() as i32;
            prop_assume!((raw(load_b) - raw(load_a)).abs() >= MIN_COUNT_SPAN);
            let c = TensionCalibration::from_two_points((raw(load_a), load_a), (raw(load_b), load_b)).unwrap();
            prop_assert!((c.tension_n(raw(load_a)) - load_a).abs() < 1e-9 + 1e-6 * span);
            prop_assert!((c.tension_n(raw(load_b)) - load_b).abs() < 1e-9 + 1e-6 * span);
        }
    }
}
