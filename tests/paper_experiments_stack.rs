//! The paper's experiments through the service's own control cycle: Fig. 18 (the planar
//! prototype following a profile with P1) and Fig. 23 (the one-wire device exploring a contour)
//! run by `run_control_loop` with `ControlCycle<N, D>` built from the example configuration,
//! its safety supervisor watching, on the twin of each device — the surfaces and the virtual
//! operators of `videt-experiments`, what the paper reports asserted with its tolerances.

use std::sync::atomic::AtomicBool;

use videt_config::Config;
use videt_control::profile::Profile;
use videt_control::Vec3;
use videt_experiments::geometry::{path_stats, PathStats};
use videt_experiments::Sample;
use videt_runtime::control_loop::{
    run_control_loop, start_hardware, CycleObserver, LoopControl, LoopSettings, LoopStats,
    WindowStats,
};
use videt_runtime::cycle::{CycleRecord, WireZero};
use videt_runtime::runtime_device::RuntimeDevice;
use videt_runtime::setup;
use videt_runtime::snapshot::FixedSurface;
use videt_sim::VirtualOperator;

/// Every period's record, kept (capacity reserved before the loop).
struct Records(Vec<CycleRecord>);

impl CycleObserver for Records {
    fn observe(&mut self, record: &CycleRecord, _window: &WindowStats) {
        self.0.push(*record);
    }
}

/// Run `device` against `profile` with the operator's script for `seconds`, with P1 and the
/// example configuration's other control settings; the records of every period.
fn run_through_the_cycle<const N: usize, D: RuntimeDevice<N>>(
    device: D,
    profile: Profile,
    operator: VirtualOperator,
    start: Vec3,
    seconds: f64,
) -> Vec<CycleRecord> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("config/videt.example.toml");
    let mut config = Config::load(&path).unwrap();
    config.control.algorithm = "P1".into();
    let mut twin = videt_experiments::closed_loop::twin_for(device, start, operator);
    let mut cycle = setup::control_cycle_for(&config, device, WireZero::default(), true);
    start_hardware(&mut twin).unwrap();
    let settings = LoopSettings {
        rate_hz: config.control.rate_hz,
        duration_ns: Some((seconds * 1e9) as u64),
        max_consecutive_overruns: 10,
    };
    let stop = AtomicBool::new(false);
    let mut records = Records(Vec::with_capacity((seconds * 1000.0) as usize + 100));
    run_control_loop(
        &mut twin,
        &mut FixedSurface(profile),
        &mut cycle,
        &settings,
        &mut LoopControl::stop_flag(&stop),
        &mut records,
        &mut LoopStats::default(),
    );
    records.0
}

/// How the records between `from_s` and `to_s` follow `profile`.
fn stats<const N: usize>(
    profile: &Profile,
    records: &[CycleRecord],
    (from_s, to_s): (f64, f64),
) -> PathStats {
    let samples: Vec<Sample<N>> = records
        .iter()
        .filter(|r| {
            let t = r.time.as_secs_f64();
            t >= from_s && t < to_s
        })
        .map(|r| Sample {
            time_s: r.time.as_secs_f64(),
            position_m: Vec3::from(r.position_m),
            true_position_m: Vec3::from(r.position_m),
            hand_target_m: Vec3::zeros(),
            velocity_m_s: Vec3::from(r.velocity_m_s),
            in_contact: r.in_contact,
            depth_m: r.contact_depth_m,
            normal: Vec3::zeros(),
            desired_n: Vec3::from(r.desired_force_n),
            field_n: Vec3::zeros(),
            target_n: Vec3::zeros(),
            rendered_n: Vec3::from(r.rendered_force_n),
            measured_n: Vec3::zeros(),
            v_index: 0.0,
            setpoint_n: core::array::from_fn(|i| r.tension_setpoint_n[i]),
            tension_n: core::array::from_fn(|i| r.tension_measured_n[i]),
            safety_trip: false,
            safe_state: false,
        })
        .collect();
    path_stats(profile, samples.iter())
}

/// Every side at least 80 % touched, the path within `max_distance_m` of the profile and
/// within 5 mm RMS.
fn assert_follows(s: &PathStats, max_distance_m: f64) {
    assert!(
        s.segment_coverage.iter().all(|&c| c >= 0.8),
        "sides touched: {:?}",
        s.segment_coverage
    );
    assert!(
        s.max_distance_m <= max_distance_m,
        "max distance {:.4} m",
        s.max_distance_m
    );
    assert!(
        s.rms_distance_m <= 0.005,
        "RMS distance {:.4} m",
        s.rms_distance_m
    );
}

fn assert_safe_throughout(records: &[CycleRecord], what: &str) {
    let unsafe_state = records.iter().find(|r| r.safety.reason().is_some());
    assert!(unsafe_state.is_none(), "{what}: {unsafe_state:?}");
}

#[test]
fn fig18_the_planar_prototype_follows_the_profile_through_the_services_cycle() {
    let profile = videt_experiments::fig18::fig18_profile();
    let (operator, traversal_s) = videt_experiments::fig18::fig18_operator(
        &profile,
        &videt_experiments::fig18::Fig18Script::default(),
    );
    let start = operator.target(0.0).0 - Vec3::new(0.0, 0.0, 0.0025);
    let device = videt_control::PlanarDevice::paper_prototype();
    let records = run_through_the_cycle(device, profile, operator, start, traversal_s.1 + 1.2);
    assert_safe_throughout(&records, "Fig. 18");
    let s = stats::<2>(&profile, &records, traversal_s);
    // "The profile is followed without major problems": every side followed, within a
    // fingertip of it.
    assert_follows(&s, 0.010);
    assert!(
        s.contact_fraction >= 0.8,
        "in contact {:.2}",
        s.contact_fraction
    );
    assert!(s.max_depth_m <= 0.008, "max depth {:.4} m", s.max_depth_m);
    // The thimble stays in the prototype's plane.
    assert!(records.iter().all(|r| r.position_m[1] == 0.0));
}

#[test]
fn fig23_the_one_wire_device_explores_the_contour_through_the_services_cycle() {
    let contour = videt_experiments::fig23::fig23_contour();
    let (operator, traversal_s) = videt_experiments::fig23::fig23_operator(
        &contour,
        &videt_experiments::fig23::Fig23Script::default(),
    );
    let start = operator.target(0.0).0;
    let device = videt_control::PolarDevice::at_origin();
    let records = run_through_the_cycle(device, contour, operator, start, traversal_s.1 + 1.2);
    assert_safe_throughout(&records, "Fig. 23");
    // The angles were read every period, and the wire only pulled towards its guide.
    assert!(records.iter().all(|r| r.inputs.angles_read_ok));
    for r in records.iter().filter(|r| r.in_contact) {
        let p = Vec3::from(r.position_m);
        let f = Vec3::from(r.rendered_force_n);
        assert!(f.cross(&p).norm() <= 1e-9 * (1.0 + f.norm()), "{r:?}");
        assert!(f.dot(&p) <= 0.0, "{r:?}");
    }
    let s = stats::<1>(&contour, &records, traversal_s);
    // "Explored very well": every side, within a fingertip.
    assert_follows(&s, 0.008);
}

/// The operator alone, to check the test's premise: without forces the hand goes through the
/// profile (the runs above follow it because the wires render it).
#[test]
fn without_forces_the_operator_passes_through_the_profile() {
    let profile = videt_experiments::fig18::fig18_profile();
    let (operator, traversal_s) = videt_experiments::fig18::fig18_operator(
        &profile,
        &videt_experiments::fig18::Fig18Script::default(),
    );
    let deepest = (0..200)
        .map(|k| {
            let t = traversal_s.0 + (traversal_s.1 - traversal_s.0) * k as f64 / 200.0;
            let target = operator.target(t).0;
            -profile.signed_distance_m(&videt_control::planar::Vec2::new(target.x, target.z))
        })
        .fold(0.0f64, f64::max);
    assert!(
        deepest > 0.015,
        "the hand aims {deepest:.4} m into the solid"
    );
}
