//! The one-wire device's two passive angle sensors in the twin: azimuth and elevation of the
//! wire at its guide (at the origin), from a thimble position, as the HAL's
//! [`AngleSensors`].
//!
//! The angles follow eq. 7 through [`polar_inverse`], the same function the control code uses:
//! azimuth `atan2(y, x)`, elevation `atan2(z, sqrt(x² + y²))`. Each is quantized like the real
//! sensor, a 14-bit absolute encoder (AS5048A): to the nearest of 16384 counts a turn, then
//! reported in `(-pi, pi]`, so the twin is exactly as coarse as the device. Optionally:
//!
//! - a zero error, in counts, added to each axis (a calibration that is a few counts off);
//! - the real driver's pipelined timing: each read returns the angles of the read before.
//!
//! Faults are posted through [`AngleFaults`] (shared with `Arc`, wait-free, from any thread):
//! a sensor that raises its error flag fails the next read once, as the real driver reports
//! the flag and clears it; a silent sensor fails every read until restored.
//!
//! Where the thimble is comes from a [`PositionSource`]: a fixed [`Vec3`] the caller moves
//! ([`AngleSensorTwin::set_position`]), a [`SharedPosition`] another thread writes (the
//! plant's stepping thread, an operator script), or any closure.

use core::f64::consts::TAU;
use std::sync::atomic::{AtomicU64, AtomicU8, Ordering};
use std::sync::Arc;

use videt_control::polar_inverse;
use videt_hal::{AngleAxis, AngleSensors, Error, ErrorKind, ErrorType};

use crate::Vec3;

/// Counts a turn of the simulated encoders (14 bits, as the AS5048A).
pub const ENCODER_COUNTS_PER_TURN: u32 = 1 << 14;

/// One count of the simulated encoders, radians (2π/16384).
pub const ENCODER_RAD_PER_COUNT: f64 = TAU / ENCODER_COUNTS_PER_TURN as f64;

const TURN: i64 = ENCODER_COUNTS_PER_TURN as i64;
const HALF_TURN: i64 = TURN / 2;

/// `angle_rad` plus `zero_error_counts`, on the encoder's grid: the nearest count, wrapped to
/// `(-pi, pi]`. A non-finite angle stays non-finite.
pub fn quantize_angle(angle_rad: f64, zero_error_counts: i32) -> f64 {
    if !angle_rad.is_finite() {
        return angle_rad;
    }
    // Reduce to one turn first so the cast to whole counts cannot saturate.
    let counts = (angle_rad / ENCODER_RAD_PER_COUNT).round() % TURN as f64;
    let counts = (counts as i64 + i64::from(zero_error_counts)).rem_euclid(TURN);
    let counts = if counts > HALF_TURN {
        counts - TURN
    } else {
        counts
    };
    counts as f64 * ENCODER_RAD_PER_COUNT
}

/// Where the thimble is, for the twin's angle sensors.
pub trait PositionSource {
    /// The thimble position, metres, in the frame of the wire guide (guide at the origin).
    /// **RT**: no allocation, no lock.
    fn thimble_position_m(&mut self) -> Vec3;
}

impl PositionSource for Vec3 {
    fn thimble_position_m(&mut self) -> Vec3 {
        *self
    }
}

impl<F: FnMut() -> Vec3> PositionSource for F {
    fn thimble_position_m(&mut self) -> Vec3 {
        self()
    }
}

/// A thimble position written by one thread and read by the sensors on another, wait-free.
/// Each coordinate is one atomic: a read racing a write may mix the two positions, as a
/// sensor sampling mid-motion does.
#[derive(Debug, Default)]
pub struct SharedPosition {
    xyz_bits: [AtomicU64; 3],
}

impl SharedPosition {
    /// Starting at `position_m`.
    pub fn new(position_m: Vec3) -> SharedPosition {
        let p = SharedPosition::default();
        p.set(position_m);
        p
    }

    /// Move the thimble to `position_m`. **RT-safe**.
    pub fn set(&self, position_m: Vec3) {
        for (slot, v) in self.xyz_bits.iter().zip(position_m.iter()) {
            slot.store(v.to_bits(), Ordering::Relaxed);
        }
    }

    /// The thimble position. **RT-safe**.
    pub fn get(&self) -> Vec3 {
        let [x, y, z] = &self.xyz_bits;
        Vec3::new(
            f64::from_bits(x.load(Ordering::Relaxed)),
            f64::from_bits(y.load(Ordering::Relaxed)),
            f64::from_bits(z.load(Ordering::Relaxed)),
        )
    }
}

impl PositionSource for Arc<SharedPosition> {
    fn thimble_position_m(&mut self) -> Vec3 {
        self.get()
    }
}

/// A fault one of the twin's angle sensors can suffer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AngleSensorFault {
    /// The sensor raises its error flag once: the next read fails, the one after works.
    ErrorFlag(AngleAxis),
    /// The sensor stops answering until [`AngleFaults::restore`].
    Silent(AngleAxis),
}

const HEALTHY: u8 = 0;
const FLAG_RAISED: u8 = 1;
const SILENT: u8 = 2;

/// The faults of the twin's two angle sensors, posted from any thread (share with `Arc`);
/// every operation is one atomic, so injecting never blocks the reading thread.
#[derive(Debug, Default)]
pub struct AngleFaults {
    state: [AtomicU8; 2],
}

impl AngleFaults {
    /// Make `fault` happen from the next read on.
    pub fn inject(&self, fault: AngleSensorFault) {
        let (axis, state) = match fault {
            AngleSensorFault::ErrorFlag(axis) => (axis, FLAG_RAISED),
            AngleSensorFault::Silent(axis) => (axis, SILENT),
        };
        self.state[axis.index()].store(state, Ordering::Release);
    }

    /// `axis` works again.
    pub fn restore(&self, axis: AngleAxis) {
        self.state[axis.index()].store(HEALTHY, Ordering::Release);
    }

    /// The fault a read of `axis` meets now, if any; a raised error flag is consumed.
    fn take(&self, axis: AngleAxis) -> Option<AngleTwinFault> {
        let slot = &self.state[axis.index()];
        match slot.load(Ordering::Acquire) {
            HEALTHY => None,
            FLAG_RAISED => {
                // Consumed only if still raised: a concurrent "silent" wins.
                let _ = slot.compare_exchange(
                    FLAG_RAISED,
                    HEALTHY,
                    Ordering::AcqRel,
                    Ordering::Relaxed,
                );
                Some(AngleTwinFault::ErrorFlag)
            }
            _ => Some(AngleTwinFault::Silent),
        }
    }
}

/// What went wrong with a simulated angle sensor.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AngleTwinFault {
    /// The sensor raised its error flag (reported once, then cleared).
    ErrorFlag,
    /// The sensor does not answer.
    Silent,
    /// The thimble position is not finite (the plant diverged, or a source gave NaN).
    PositionNotFinite,
}

/// A simulated angle-sensor error, naming the sensor.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AngleTwinError {
    /// Which sensor.
    pub axis: AngleAxis,
    /// What failed.
    pub fault: AngleTwinFault,
}

impl Error for AngleTwinError {
    fn kind(&self) -> ErrorKind {
        match self.fault {
            AngleTwinFault::ErrorFlag => ErrorKind::Fault,
            AngleTwinFault::Silent => ErrorKind::Disconnected,
            AngleTwinFault::PositionNotFinite => ErrorKind::OutOfRange,
        }
    }
}

impl core::fmt::Display for AngleTwinError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let what = match self.fault {
            AngleTwinFault::ErrorFlag => "raised its error flag",
            AngleTwinFault::Silent => "does not answer",
            AngleTwinFault::PositionNotFinite => "sees a thimble position that is not finite",
        };
        write!(f, "simulated {} angle sensor {what}", self.axis)
    }
}

impl std::error::Error for AngleTwinError {}

/// The twin of the one-wire device's azimuth and elevation sensors.
#[derive(Debug)]
pub struct AngleSensorTwin<P> {
    source: P,
    zero_error_counts: [i32; 2],
    faults: Arc<AngleFaults>,
    pipelined: bool,
    previous_rad: Option<[f64; 2]>,
}

impl<P: PositionSource> AngleSensorTwin<P> {
    /// Ideal sensors (no zero error, every read the angles of that instant) on `source`.
    pub fn new(source: P) -> Self {
        AngleSensorTwin {
            source,
            zero_error_counts: [0; 2],
            faults: Arc::default(),
            pipelined: false,
            previous_rad: None,
        }
    }

    /// Add `counts` (azimuth, elevation) to every reading: a zero offset the calibration left.
    pub fn with_zero_error_counts(mut self, counts: [i32; 2]) -> Self {
        self.zero_error_counts = counts;
        self
    }

    /// Return the angles of the previous read, as the real driver's pipelined read does (the
    /// first read returns its own).
    pub fn pipelined(mut self) -> Self {
        self.pipelined = true;
        self
    }

    /// The fault handle, to share with the thread that injects faults.
    pub fn faults(&self) -> Arc<AngleFaults> {
        Arc::clone(&self.faults)
    }

    /// Make `fault` happen from the next read on.
    pub fn inject(&self, fault: AngleSensorFault) {
        self.faults.inject(fault);
    }

    /// The position source.
    pub fn source_mut(&mut self) -> &mut P {
        &mut self.source
    }

    /// The angles the sensors would measure now, before quantization: `polar_inverse` of the
    /// thimble position (azimuth, elevation).
    pub fn true_angles_rad(&mut self) -> [f64; 2] {
        let c = polar_inverse(&self.source.thimble_position_m());
        [c.azimuth_rad, c.elevation_rad]
    }
}

impl AngleSensorTwin<Vec3> {
    /// Move the thimble to `position_m` (guide at the origin).
    pub fn set_position(&mut self, position_m: Vec3) {
        self.source = position_m;
    }
}

impl<P> ErrorType for AngleSensorTwin<P> {
    type Error = AngleTwinError;
}

impl<P: PositionSource> AngleSensors for AngleSensorTwin<P> {
    fn read_angles(&mut self, out_rad: &mut [f64; 2]) -> Result<(), AngleTwinError> {
        // Both sensors are sampled, as the real pair reads both before reporting; the
        // azimuth's error comes first.
        let faults = AngleAxis::ALL.map(|axis| self.faults.take(axis));
        if let Some((axis, fault)) = AngleAxis::ALL
            .into_iter()
            .zip(faults)
            .find_map(|(axis, f)| f.map(|f| (axis, f)))
        {
            self.previous_rad = None;
            return Err(AngleTwinError { axis, fault });
        }
        let truth = self.true_angles_rad();
        if let Some(i) = truth.iter().position(|a| !a.is_finite()) {
            self.previous_rad = None;
            return Err(AngleTwinError {
                axis: AngleAxis::ALL[i],
                fault: AngleTwinFault::PositionNotFinite,
            });
        }
        let measured = [0, 1].map(|i| quantize_angle(truth[i], self.zero_error_counts[i]));
        *out_rad = if self.pipelined {
            self.previous_rad.replace(measured).unwrap_or(measured)
        } else {
            measured
        };
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI};
    use proptest::prelude::*;
    use videt_control::{polar_forward, PolarCoordinates};

    fn read(twin: &mut impl AngleSensors<Error = AngleTwinError>) -> [f64; 2] {
        let mut out = [f64::NAN; 2];
        twin.read_angles(&mut out).unwrap();
        out
    }

    #[test]
    fn known_positions_read_their_angles() {
        let s = 0.5;
        let mut twin = AngleSensorTwin::new(Vec3::new(s, 0.0, 0.0));
        let cases = [
            (Vec3::new(s, 0.0, 0.0), [0.0, 0.0]),
            (Vec3::new(0.0, s, 0.0), [FRAC_PI_2, 0.0]),
            (Vec3::new(-s, 0.0, 0.0), [PI, 0.0]),
            (Vec3::new(0.0, -s, 0.0), [-FRAC_PI_2, 0.0]),
            (Vec3::new(s, s, 0.0), [FRAC_PI_4, 0.0]),
            (Vec3::new(s, 0.0, s), [0.0, FRAC_PI_4]),
            (Vec3::new(0.0, 0.0, s), [0.0, FRAC_PI_2]),
            (
                Vec3::new(-s, -s, -s * 2f64.sqrt()),
                [-3.0 * FRAC_PI_4, -FRAC_PI_4],
            ),
        ];
        for (p, expected) in cases {
            twin.set_position(p);
            let got = read(&mut twin);
            for i in 0..2 {
                assert!(
                    (got[i] - expected[i]).abs() < 1e-12,
                    "{p:?}: {got:?} != {expected:?}"
                );
            }
        }
    }

    #[test]
    fn a_zero_error_shifts_the_reading_by_whole_counts_and_wraps() {
        let mut twin =
            AngleSensorTwin::new(Vec3::new(-1.0, 0.0, 0.0)).with_zero_error_counts([3, -2]);
        // +pi plus 3 counts wraps to just above -pi.
        let [a, b] = read(&mut twin);
        assert!(
            (a - (-PI + 3.0 * ENCODER_RAD_PER_COUNT)).abs() < 1e-12,
            "{a}"
        );
        assert!((b - (-2.0 * ENCODER_RAD_PER_COUNT)).abs() < 1e-12, "{b}");
        assert_eq!(quantize_angle(-PI, 0), PI);
        assert!(quantize_angle(f64::NAN, 0).is_nan());
    }

    #[test]
    fn a_pipelined_twin_reads_one_read_late() {
        let mut twin = AngleSensorTwin::new(Vec3::new(1.0, 0.0, 0.0)).pipelined();
        assert_eq!(read(&mut twin), [0.0, 0.0]);
        twin.set_position(Vec3::new(0.0, 1.0, 0.0));
        assert_eq!(read(&mut twin), [0.0, 0.0]);
        assert_eq!(read(&mut twin), [FRAC_PI_2, 0.0]);
    }

    #[test]
    fn faults_surface_as_errors_naming_the_sensor() {
        let mut twin = AngleSensorTwin::new(Vec3::new(0.3, 0.1, 0.2));
        let faults = twin.faults();
        let mut out = [0.0; 2];

        faults.inject(AngleSensorFault::ErrorFlag(AngleAxis::Elevation));
        let e = twin.read_angles(&mut out).unwrap_err();
        assert_eq!(
            e,
            AngleTwinError {
                axis: AngleAxis::Elevation,
                fault: AngleTwinFault::ErrorFlag
            }
        );
        assert_eq!(e.kind(), ErrorKind::Fault);
        assert_eq!(
            e.to_string(),
            "simulated elevation angle sensor raised its error flag"
        );
        // The flag is cleared once reported.
        twin.read_angles(&mut out).unwrap();

        twin.inject(AngleSensorFault::Silent(AngleAxis::Azimuth));
        for _ in 0..3 {
            let e = twin.read_angles(&mut out).unwrap_err();
            assert_eq!(e.axis, AngleAxis::Azimuth);
            assert_eq!(e.kind(), ErrorKind::Disconnected);
        }
        faults.restore(AngleAxis::Azimuth);
        twin.read_angles(&mut out).unwrap();

        twin.set_position(Vec3::new(f64::NAN, 0.0, 0.0));
        let e = twin.read_angles(&mut out).unwrap_err();
        assert_eq!(e.kind(), ErrorKind::OutOfRange);
    }

    #[test]
    fn a_shared_position_and_a_closure_drive_the_sensors() {
        let shared = Arc::new(SharedPosition::new(Vec3::new(1.0, 0.0, 0.0)));
        let mut twin = AngleSensorTwin::new(Arc::clone(&shared));
        assert_eq!(read(&mut twin), [0.0, 0.0]);
        let writer = Arc::clone(&shared);
        std::thread::spawn(move || writer.set(Vec3::new(0.0, 0.0, 2.0)))
            .join()
            .unwrap();
        assert_eq!(read(&mut twin), [0.0, FRAC_PI_2]);

        let mut t = 0.0f64;
        let mut twin = AngleSensorTwin::new(move || {
            t += 0.25;
            Vec3::new(t.cos(), t.sin(), 0.0)
        });
        let [a, _] = read(&mut twin);
        assert!((a - 0.25).abs() <= ENCODER_RAD_PER_COUNT / 2.0);
    }

    proptest! {
        #![proptest_config(ProptestConfig {
            cases: 512,
            rng_seed: proptest::test_runner::RngSeed::Fixed(14),
            ..ProptestConfig::default()
        })]

        /// The reading is within one count of the truth (half a count, by rounding), and eq. 7
        /// forward from it lands within a count's arc of the thimble.
        #[test]
        fn the_quantization_error_is_at_most_one_count(
            l in 0.05f64..0.8, a in -PI..PI, b in -1.55f64..1.55,
        ) {
            let p = polar_forward(&PolarCoordinates { length_m: l, azimuth_rad: a, elevation_rad: b });
            let mut twin = AngleSensorTwin::new(p);
            let truth = twin.true_angles_rad();
            let got = read(&mut twin);
            for i in 0..2 {
                let d = (got[i] - truth[i]).rem_euclid(TAU);
                let d = d.min(TAU - d);
                prop_assert!(d <= ENCODER_RAD_PER_COUNT / 2.0 + 1e-12, "{truth:?} {got:?}");
                prop_assert!(d <= 2.0 * PI / 16384.0);
                let counts = got[i] / ENCODER_RAD_PER_COUNT;
                prop_assert!((counts - counts.round()).abs() < 1e-9, "not on the grid");
                prop_assert!(got[i] > -PI && got[i] <= PI);
            }
            let back = polar_forward(&PolarCoordinates { length_m: l, azimuth_rad: got[0], elevation_rad: got[1] });
            prop_assert!((back - p).norm() <= 2.0 * l * ENCODER_RAD_PER_COUNT);
        }
    }
}
