//! The paper's section 6 on the twin: what each figure reports, asserted with tolerances.
//!
//! The paper's claims are qualitative; the tolerances turn them into numbers a fingertip would
//! notice, with margin over what the twin measures (the measured values are in the comments and
//! in `summary.txt`):
//!
//! - Fig. 18, "the profile is followed without major problems": every side of the profile is
//!   touched along most of its length, the thimble never strays more than 1 cm from the profile
//!   (a fingertip's width, 2 % of the 0.52 m workspace; measured 7 mm, where the finger rises
//!   past a wall it is not pressing), RMS distance under 5 mm (3.2 mm), no pop-through: depth
//!   under 8 mm even where the normal is outside region A (4.9 mm; in region A, K = 800 N/m
//!   against a hand aiming 15 mm past the surface sits at 3 mm), and P1 outside region A renders
//!   only part of the normal force (0 < V < 1, the paper's Fig. 14; measured 0.74) while inside A
//!   it renders all of it (V = 1).
//! - Fig. 22, "the exploration can be performed quite well also in this case" (n in region C):
//!   with F1 and |f_c| = 2 N the finger resting on the floor is pushed back out by at least 1 N
//!   (measured 1.45 N of the 1.45 N asked, V = 1.00) against 2 N of field in free space, the depth
//!   stays below |f_c| / K = 2.5 mm (1.8 mm); with P1 and no field, the same operator gets no
//!   reaction at all (the wires at t_min pull the finger *into* the floor, V < 0) and the force
//!   it feels changes by less than 0.2 N on touching (0.09 N): the surface cannot be felt.
//! - Fig. 23, "explored very well": the one-wire device's thimble passes along every side in
//!   contact, within 8 mm of the contour (4.2 mm), every force along the wire.
//!
//! In every run the safety check (a tension at 1.2 x 15 N, or not finite) never trips, and no
//! tension reaches the device's 15 N.

use std::sync::OnceLock;

use videt_control::planar::Vec2;
use videt_control::{Algorithm, ControlStep, PlanarDevice, Profile, SolidSide, Vec3};
use videt_experiments::closed_loop::{run_closed_loop, twin_for, LoopSettings};
use videt_experiments::fig22::{fig22_floor, fig22_operator};
use videt_experiments::{
    fig18, fig22, fig23, write_figures_of, ControlConfig, Fig18, Fig22, Fig23,
};
use videt_sim::VirtualOperator;

fn f18() -> &'static Fig18 {
    static F: OnceLock<Fig18> = OnceLock::new();
    F.get_or_init(|| fig18().expect("Fig. 18 runs"))
}

fn f22() -> &'static Fig22 {
    static F: OnceLock<Fig22> = OnceLock::new();
    F.get_or_init(|| fig22().expect("Fig. 22 runs"))
}

fn f23() -> &'static Fig23 {
    static F: OnceLock<Fig23> = OnceLock::new();
    F.get_or_init(|| fig23().expect("Fig. 23 runs"))
}

#[test]
fn fig18_p1_follows_a_profile_with_normals_outside_region_a() {
    let s = &f18().summary;
    assert_eq!(s.algorithm, Algorithm::P1);
    assert_eq!(s.segments_followed, s.segments, "{s:#?}");
    assert!(s.path.segment_coverage.iter().all(|&c| c >= 0.8), "{s:#?}");
    assert!(s.path.contact_fraction >= 0.8, "{s:#?}");
    assert!(s.path.max_distance_m <= 0.010, "{s:#?}");
    assert!(s.path.rms_distance_m <= 0.005, "{s:#?}");
    assert!(s.path.max_depth_m <= 0.008, "{s:#?}");
    // The profile's walls were pressed: a good share of the contact is outside region A.
    assert!(s.outside_a_fraction >= 0.2, "{s:#?}");
    assert!(s.max_depth_outside_a_m > 0.001, "{s:#?}");
    // P1: exact inside A, part of the normal force outside (0 < V < 1).
    assert!(s.mean_v_in_a >= 0.98, "{s:#?}");
    assert!(
        s.mean_v_outside_a > 0.3 && s.mean_v_outside_a < 0.95,
        "{s:#?}"
    );
    assert_eq!(s.trip_periods, 0);
    assert_eq!(s.safe_state_periods, 0);
    assert!(s.max_tension_n < 15.0, "{s:#?}");
}

#[test]
fn fig22_the_field_renders_a_surface_in_region_c_and_p1_cannot() {
    let s = &f22().summary;
    let (field, p1) = (&s.field, &s.baseline);
    assert_eq!(field.algorithm, Algorithm::F1);
    assert_eq!(field.field_n, 2.0);
    for run in [field, p1] {
        assert!(run.region_c_fraction >= 0.99, "{run:#?}");
        assert!(run.path.contact_fraction >= 0.95, "{run:#?}");
        assert_eq!(run.trip_periods, 0);
        assert_eq!(run.safe_state_periods, 0);
        assert!(run.max_tension_n < 15.0);
    }
    // With the field: felt, the reaction as asked, the penetration bounded by |f_c| / K.
    assert!(field.mean_reaction_n >= 1.0, "{field:#?}");
    // The wires pull no less than t_min: the reaction tops out at the field less the floor
    // tension's pull (the force measured in contact, where f_e cancels f_c). At the example's
    // stiffness the finger rests right there, asking a little more than that.
    let renderable_n = field.field_n + field.contact_force_along_n_n.min(0.0);
    assert!(
        field.mean_reaction_n >= 0.9 * field.mean_desired_n.min(renderable_n),
        "{field:#?}"
    );
    assert!(field.mean_v_index >= 0.9, "{field:#?}");
    assert!(field.felt_change_n >= 1.0, "{field:#?}");
    // The penetration at rest is bounded by |f_c| / K; the transients of the finger's steps go
    // up to a quarter beyond it at the example's stiffness.
    let k = ControlConfig::EXAMPLE.stiffness_n_per_m;
    assert!(field.path.mean_depth_m <= 2.0 / k, "{field:#?}");
    assert!(field.path.max_depth_m <= 1.25 * 2.0 / k, "{field:#?}");
    // Without: f_e is not in F, the wires at t_min pull into the floor; nothing to feel.
    assert!(p1.mean_desired_n > 0.2, "{p1:#?}");
    assert!(p1.mean_reaction_n <= 0.0, "{p1:#?}");
    assert!(p1.mean_v_index <= 0.0, "{p1:#?}");
    assert!(p1.felt_change_n.abs() <= 0.2, "{p1:#?}");
    assert!(field.felt_change_n - p1.felt_change_n >= 1.0);
}

#[test]
fn fig23_one_wire_explores_a_polygonal_contour() {
    let f = f23();
    let s = &f.summary;
    assert_eq!(s.sides_explored, s.sides, "{s:#?}");
    assert_eq!(s.sides, 6);
    assert!(s.path.contact_fraction >= 0.9, "{s:#?}");
    assert!(s.path.max_distance_m <= 0.008, "{s:#?}");
    assert!(s.path.rms_distance_m <= 0.005, "{s:#?}");
    assert!(s.max_off_plane_m <= 0.005, "{s:#?}");
    assert!(s.max_force_angle_from_wire_rad <= 1e-6, "{s:#?}");
    assert!(s.mean_contact_tension_n > 0.5, "{s:#?}");
    assert_eq!(s.trip_periods, 0);
    assert_eq!(s.safe_state_periods, 0);
    assert!(s.max_tension_n < 15.0, "{s:#?}");
    // The thimble really moved in 3D: the angle sensors saw it beside the guide's x-z plane.
    assert!(f.run.samples.iter().all(|s| s.position_m.y > 0.02));
}

#[test]
fn the_safety_check_trips_and_holds_the_wires_at_t_min() {
    // The Fig. 22 run with the field, tripping at 1 N: the field alone needs more.
    let device = PlanarDevice::paper_prototype();
    let (operator, timeline) = fig22_operator();
    let mut twin = twin_for(device, operator.target(0.0).0, operator);
    let params = ControlConfig::EXAMPLE.params(
        &twin.plant().params().transmission,
        videt_experiments::closed_loop::wire_stretch(twin.plant()),
        Algorithm::F1,
        2.0,
    );
    let mut step = ControlStep::new(device, params);
    let settings = LoopSettings {
        trip_tension_n: 1.0,
        ..LoopSettings::for_duration(timeline.free_s.1)
    };
    let run = run_closed_loop(&mut twin, &mut step, &fig22_floor(), &settings).unwrap();
    let tripped = run.first_trip_s.expect("the trip fires");
    assert!(run.trip_periods >= 1);
    assert!(run.safe_state_periods > 0);
    for s in run.samples.iter().filter(|s| s.time_s > tripped) {
        assert!(s.safe_state);
        assert_eq!(s.setpoint_n, [ControlConfig::EXAMPLE.t_min_n; 2]);
    }
}

#[test]
fn a_profile_in_free_space_is_not_touched() {
    // The closed loop against a profile out of the operator's reach: no contact, the
    // free-space pull only. Guards the contact bookkeeping the summaries rely on.
    let device = PlanarDevice::paper_prototype();
    let far = Profile::<4>::open(
        &[Vec2::new(0.0, 0.6), Vec2::new(0.52, 0.6)],
        SolidSide::Left,
    )
    .unwrap();
    let start = Vec3::new(0.26, 0.0, 0.3);
    let mut twin = twin_for(device, start, VirtualOperator::holding(start));
    let params = ControlConfig::EXAMPLE.params(
        &twin.plant().params().transmission,
        videt_experiments::closed_loop::wire_stretch(twin.plant()),
        Algorithm::P1,
        0.0,
    );
    let mut step = ControlStep::new(device, params);
    let run =
        run_closed_loop(&mut twin, &mut step, &far, &LoopSettings::for_duration(1.0)).unwrap();
    assert!(run.samples.iter().all(|s| !s.in_contact));
    let last = run.samples.last().unwrap();
    assert!((last.measured_n.norm() - 0.5).abs() < 0.1, "{last:?}");
    assert!((last.position_m - start).norm() < 0.005, "{last:?}");
}

#[test]
fn the_figures_and_the_summary_are_written() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("figures");
    let written = write_figures_of(&out, f18(), f22(), f23()).unwrap();
    let names: Vec<String> = written
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(
        names,
        [
            "fig18_planar_p1_profile.png",
            "fig22_planar_region_c_field.png",
            "fig23_one_wire_contour.png",
            "summary.txt"
        ]
    );
    for p in &written {
        let bytes = std::fs::read(p).unwrap();
        if p.extension().is_some_and(|e| e == "png") {
            assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "{}", p.display());
            assert!(bytes.len() > 10_000, "{}", p.display());
        }
    }
    let summary = std::fs::read_to_string(out.join("summary.txt")).unwrap();
    assert!(
        summary.contains("Fig. 18") && summary.contains("Fig. 22") && summary.contains("Fig. 23")
    );
    // Nothing but the four files: the temporary files were renamed away.
    assert_eq!(std::fs::read_dir(&out).unwrap().count(), 4);
}
