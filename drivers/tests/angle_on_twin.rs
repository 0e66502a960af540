//! The AS5048A angle driver end to end on the twin's simulated encoders: the one-wire device's
//! azimuth and elevation follow eq. 7 (`polar_inverse`) of the thimble position through the
//! encoders' mounting, the calibration taken at a reference pose and the pipelined read; the
//! encoders' faults come out as errors naming the sensor; and the control thread's read, error
//! paths included, allocates nothing.

use std::sync::Arc;

use videt_drivers::angle::{
    AngleError, AngleSensorPair, As5048aError, Calibration, ErrorRegister, Sense, RAD_PER_COUNT,
};
use videt_hal::{AngleAxis, AngleSensors, Error as _, ErrorKind};
use videt_sim::as5048a_encoder::{
    encoder_on_axis, EncoderFault, EncoderFaults, Mounting, SimSpiError,
};
use videt_sim::{AngleSensorTwin, SharedPosition, Vec3};

#[global_allocator]
static GLOBAL: videt_testkit::CountingAllocator = videt_testkit::CountingAllocator;

/// Where the encoders sit on their axes: the azimuth's counts run with the angle, the
/// elevation's against it.
const AZIMUTH_MOUNT: Mounting = Mounting {
    zero_counts: 5000,
    reversed: false,
};
const ELEVATION_MOUNT: Mounting = Mounting {
    zero_counts: 12000,
    reversed: true,
};

/// The guide's reference pose: wire along +x, level (azimuth 0, elevation 0).
const REFERENCE: Vec3 = Vec3::new(0.4, 0.0, 0.0);

struct Rig<S: embedded_hal::spi::SpiDevice> {
    position: Arc<SharedPosition>,
    sensors: AngleSensorPair<S>,
    faults: [Arc<EncoderFaults>; 2],
}

/// The pair on two simulated encoders, calibrated at the reference pose.
fn calibrated_rig() -> Rig<impl embedded_hal::spi::SpiDevice<Error = SimSpiError>> {
    let position = Arc::new(SharedPosition::new(REFERENCE));
    let az = encoder_on_axis(Arc::clone(&position), AngleAxis::Azimuth, AZIMUTH_MOUNT);
    let el = encoder_on_axis(Arc::clone(&position), AngleAxis::Elevation, ELEVATION_MOUNT);
    let faults = [az.faults(), el.faults()];
    let mut sensors = AngleSensorPair::new(az, el, [Calibration::IDENTITY; 2]).unwrap();
    // Calibration at the reference pose; the senses are found by moving the thimble towards
    // +y and +z and seeing which way the counts go.
    let reference = sensors.read_counts().unwrap();
    position.set(Vec3::new(0.4, 0.01, 0.01));
    sensors.read_counts().unwrap();
    let moved = sensors.read_counts().unwrap();
    let sense = |i: usize| {
        let d = i32::from(moved[i]) - i32::from(reference[i]);
        if d.rem_euclid(16384) < 8192 {
            Sense::Positive
        } else {
            Sense::Negative
        }
    };
    sensors.set_calibration([
        Calibration::from_reference(reference[0], 0.0, sense(0)),
        Calibration::from_reference(reference[1], 0.0, sense(1)),
    ]);
    Rig {
        position,
        sensors,
        faults,
    }
}

fn read<S: embedded_hal::spi::SpiDevice>(pair: &mut AngleSensorPair<S>) -> [f64; 2] {
    let mut out = [f64::NAN; 2];
    pair.read_angles(&mut out).unwrap();
    out
}

/// Within one count of eq. 7's angles of `position` (`polar_inverse`, through the HAL-level
/// twin).
fn assert_within_a_count(got: [f64; 2], position: Vec3) {
    let truth = AngleSensorTwin::new(position).true_angles_rad();
    for (g, t) in got.into_iter().zip(truth) {
        let d = (g - t).rem_euclid(std::f64::consts::TAU);
        let d = d.min(std::f64::consts::TAU - d);
        assert!(
            d <= RAD_PER_COUNT,
            "{position:?}: read {got:?}, eq. 7 gives {truth:?}"
        );
    }
}

#[test]
fn the_calibrated_pair_reads_eq_7_of_the_thimble_one_read_late() {
    let mut rig = calibrated_rig();
    let cal = rig.sensors.calibration();
    assert_eq!(cal[0].sense, Sense::Positive);
    assert_eq!(cal[1].sense, Sense::Negative);
    assert_eq!(cal[0].zero_counts, AZIMUTH_MOUNT.zero_counts);
    assert_eq!(cal[1].zero_counts, ELEVATION_MOUNT.zero_counts);

    let mut previous = Vec3::new(0.4, 0.01, 0.01);
    for p in [
        Vec3::new(0.3, 0.2, 0.1),
        Vec3::new(-0.2, 0.1, 0.3),
        Vec3::new(-0.3, -0.001, -0.05),
        Vec3::new(0.05, -0.4, 0.2),
        Vec3::new(-0.5, 0.0, 0.0),
    ] {
        rig.position.set(p);
        // Pipelined: the first read carries the angle latched by the read before.
        assert_within_a_count(read(&mut rig.sensors), previous);
        assert_within_a_count(read(&mut rig.sensors), p);
        previous = p;
    }
}

#[test]
fn encoder_faults_come_out_as_errors_naming_the_sensor() {
    let mut rig = calibrated_rig();
    let [az, el] = &rig.faults;
    let mut out = [0.0; 2];

    el.inject(EncoderFault::CorruptAnswer);
    let e = rig.sensors.read_angles(&mut out).unwrap_err();
    assert_eq!(e.axis, AngleAxis::Elevation);
    assert!(matches!(e.fault, As5048aError::Parity { .. }), "{e}");
    assert_eq!(e.kind(), ErrorKind::Disconnected);
    read(&mut rig.sensors);

    // A corrupted command: the encoder flags it in its next answer; the driver reports it with
    // the error register's cause and clears it.
    az.inject(EncoderFault::CorruptCommand);
    read(&mut rig.sensors);
    let e = rig.sensors.read_angles(&mut out).unwrap_err();
    assert_eq!(
        e,
        AngleError {
            axis: AngleAxis::Azimuth,
            fault: As5048aError::ErrorFlag {
                register: Some(ErrorRegister(0b100))
            }
        }
    );
    assert_eq!(
        e.to_string(),
        "azimuth angle sensor: the sensor raised its error flag (command parity error)"
    );
    read(&mut rig.sensors);

    // The data line stuck high reads as a raised flag on every read.
    az.inject(EncoderFault::MisoStuckHigh);
    for _ in 0..3 {
        let e = rig.sensors.read_angles(&mut out).unwrap_err();
        assert_eq!(e.axis, AngleAxis::Azimuth);
        assert_eq!(e.kind(), ErrorKind::Fault);
    }
    az.restore();
    read(&mut rig.sensors);

    // Stuck low is all zeros with sound parity: an angle the read cannot tell from a real
    // one. The diagnostics can (offset compensation reads as not finished).
    el.inject(EncoderFault::MisoStuckLow);
    read(&mut rig.sensors);
    let e = rig.sensors.check_diagnostics().unwrap_err();
    assert_eq!(e.axis, AngleAxis::Elevation);
    assert_eq!(e.kind(), ErrorKind::NotReady);
    el.restore();
    rig.sensors.check_diagnostics().unwrap();

    el.inject(EncoderFault::WeakField);
    let e = rig.sensors.check_diagnostics().unwrap_err();
    assert_eq!(e.axis, AngleAxis::Elevation);
    assert!(
        matches!(e.fault, As5048aError::FieldTooWeak { agc: 255 }),
        "{e}"
    );
    assert_eq!(e.kind(), ErrorKind::OutOfRange);
}

#[test]
fn reading_the_angles_allocates_nothing_even_on_errors() {
    let mut rig = calibrated_rig();
    let [az, el] = rig.faults.clone();
    let mut out = [0.0; 2];
    let (errors, counts) = videt_testkit::count_allocations(|| {
        let mut errors = 0;
        for i in 0..200 {
            rig.position.set(Vec3::new(0.3, 0.001 * f64::from(i), 0.1));
            match i % 50 {
                10 => el.inject(EncoderFault::CorruptAnswer),
                20 => az.inject(EncoderFault::CorruptCommand),
                30 => az.inject(EncoderFault::MisoStuckHigh),
                35 => az.restore(),
                _ => {}
            }
            if rig.sensors.read_angles(&mut out).is_err() {
                errors += 1;
            }
            if i % 50 == 40 {
                rig.sensors.check_diagnostics().unwrap();
            }
        }
        errors
    });
    assert!(errors >= 4 * 4, "{errors} errors");
    assert_eq!(counts, videt_testkit::AllocCounts::default());
}
