//! Fig. 18: the planar prototype follows a polygonal profile with algorithm P1 (`|f_c| = 0`),
//! some of whose normals lie outside region A (the "vertical" segments, normals along `±x`, and
//! a slanted one).
//!
//! The profile is a ceiling above the thimble (the solid lies away from the guides) with a raised
//! recess and a slope. The virtual operator presses into it and slides along it: a pass from
//! left to right pressing up and forward, then back pressing up and backward, so that every wall
//! is pressed once (the walls facing `-x` on the way out, those facing `+x` on the way back).

use videt_control::planar::Vec2;
use videt_control::{Algorithm, ControlStep, PlanarDevice, Profile, SolidSide, Vec3};
use videt_sim::{VirtualOperator, Waypoint};

use crate::closed_loop::{run_closed_loop, twin_for, LoopSettings, Run};
use crate::geometry::{path_stats, planar_region, waypoints_along, xz, PathStats, Region};
use crate::params::ControlConfig;
use crate::ExperimentError;

/// How the operator explores the profile.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fig18Script {
    /// Sliding speed along the profile, m/s.
    pub speed_m_s: f64,
    /// How far beyond the profile, towards `+z` (into the ceiling), the hand aims, metres.
    pub press_up_m: f64,
    /// How far ahead along `x` (in the direction of travel) the hand aims, metres.
    pub press_ahead_m: f64,
}

impl Default for Fig18Script {
    fn default() -> Self {
        Fig18Script {
            speed_m_s: 0.08,
            press_up_m: 0.015,
            press_ahead_m: 0.006,
        }
    }
}

/// What Fig. 18 shows, in numbers.
#[derive(Debug, Clone, PartialEq)]
pub struct Fig18Summary {
    /// The algorithm (P1).
    pub algorithm: Algorithm,
    /// Duration of the traversal (both passes), seconds.
    pub traversal_s: f64,
    /// How the thimble followed the profile over the traversal.
    pub path: PathStats,
    /// Share of the contact periods whose normal lay outside region A.
    pub outside_a_fraction: f64,
    /// Deepest penetration while the normal lay outside region A, metres.
    pub max_depth_outside_a_m: f64,
    /// Mean index V over the contact periods with the normal in region A.
    pub mean_v_in_a: f64,
    /// Mean index V over the contact periods with the normal outside region A.
    pub mean_v_outside_a: f64,
    /// Segments of the profile.
    pub segments: usize,
    /// Segments the thimble touched along at least 80 % of their length.
    pub segments_followed: usize,
    /// Largest measured tension, newtons.
    pub max_tension_n: f64,
    /// Periods whose tensions tripped the safety check.
    pub trip_periods: usize,
    /// Periods run in the safe state.
    pub safe_state_periods: usize,
}

/// The Fig. 18 experiment as run.
#[derive(Debug, Clone)]
pub struct Fig18 {
    /// The device.
    pub device: PlanarDevice,
    /// The profile.
    pub profile: Profile,
    /// The recorded run.
    pub run: Run<2>,
    /// Start and end of the traversal, seconds.
    pub traversal_s: (f64, f64),
    /// The numbers.
    pub summary: Fig18Summary,
}

/// The profile of Fig. 18: a ceiling at `z = 0.30` m, a recess up to `0.36` m between
/// `x = 0.16` and `0.26` m (walls facing `+x` and `-x`), a lower ceiling at `0.28` m, and a
/// 45-degree slope up to `0.34` m. Normals: `-z` (region A), `±x` and `(1, -1)/√2` (region B).
pub fn fig18_profile() -> Profile {
    let v = [
        Vec2::new(0.06, 0.30),
        Vec2::new(0.16, 0.30),
        Vec2::new(0.16, 0.36),
        Vec2::new(0.26, 0.36),
        Vec2::new(0.26, 0.28),
        Vec2::new(0.36, 0.28),
        Vec2::new(0.42, 0.34),
        Vec2::new(0.48, 0.34),
    ];
    Profile::open(&v, SolidSide::Left).expect("a valid profile")
}

/// The operator of Fig. 18 and the traversal's start and end, seconds.
pub fn fig18_operator(profile: &Profile, script: &Fig18Script) -> (VirtualOperator, (f64, f64)) {
    let v = profile.vertices();
    let ahead = Vec2::new(script.press_ahead_m, script.press_up_m);
    let behind = Vec2::new(-script.press_ahead_m, script.press_up_m);
    let out: Vec<Vec3> = v.iter().map(|p| xz(&(p + ahead), 0.0)).collect();
    let back: Vec<Vec3> = v.iter().rev().map(|p| xz(&(p + behind), 0.0)).collect();
    let start = out[0] - Vec3::new(0.0, 0.0, 0.05);
    let hold_s = 0.6;
    let approach_s = 0.8;
    let mut waypoints = vec![Waypoint {
        time_s: 0.0,
        target_m: start,
    }];
    waypoints.push(Waypoint {
        time_s: hold_s,
        target_m: start,
    });
    let path: Vec<Vec3> = out.iter().chain(back.iter()).copied().collect();
    let begin = hold_s + approach_s;
    let (w, end) = waypoints_along(&path, begin, script.speed_m_s);
    waypoints.extend(w);
    let home = back[back.len() - 1] - Vec3::new(0.0, 0.0, 0.05);
    waypoints.push(Waypoint {
        time_s: end + 0.8,
        target_m: home,
    });
    (VirtualOperator::new(waypoints, 200.0, 6.0), (begin, end))
}

/// Run Fig. 18 with the default script.
pub fn fig18() -> Result<Fig18, ExperimentError> {
    fig18_with(&Fig18Script::default())
}

/// Run Fig. 18: the planar prototype, P1 without field, the example configuration's surface
/// stiffness and tension loop, the operator of `script`.
pub fn fig18_with(script: &Fig18Script) -> Result<Fig18, ExperimentError> {
    let device = PlanarDevice::paper_prototype();
    let profile = fig18_profile();
    let (operator, traversal_s) = fig18_operator(&profile, script);
    let start = operator.target(0.0).0 - Vec3::new(0.0, 0.0, 0.0025);
    let mut twin = twin_for(device, start, operator);
    let config = ControlConfig::EXAMPLE;
    let params = config.params(
        &twin.plant().params().transmission,
        crate::closed_loop::wire_stretch(twin.plant()),
        Algorithm::P1,
        0.0,
    );
    let mut step = ControlStep::new(device, params);
    let settings = LoopSettings::for_duration(traversal_s.1 + 1.2);
    let run = run_closed_loop(&mut twin, &mut step, &profile, &settings)?;
    let summary = summarize(&device, &profile, &run, traversal_s);
    Ok(Fig18 {
        device,
        profile,
        run,
        traversal_s,
        summary,
    })
}

fn summarize(
    device: &PlanarDevice,
    profile: &Profile,
    run: &Run<2>,
    (from, to): (f64, f64),
) -> Fig18Summary {
    let path = path_stats(profile, run.window(from, to));
    let (mut n_out, mut n_contact, mut max_out) = (0usize, 0usize, 0.0f64);
    let (mut v_in, mut n_in, mut v_out) = (0.0, 0usize, 0.0);
    for s in run.window(from, to).filter(|s| s.in_contact) {
        n_contact += 1;
        if planar_region(device, &s.position_m, &s.normal) == Region::A {
            n_in += 1;
            v_in += s.v_index;
        } else {
            n_out += 1;
            v_out += s.v_index;
            max_out = max_out.max(s.depth_m);
        }
    }
    let ratio = |a: f64, n: usize| if n == 0 { 0.0 } else { a / n as f64 };
    Fig18Summary {
        algorithm: Algorithm::P1,
        traversal_s: to - from,
        segments: profile.segment_count(),
        segments_followed: path.segment_coverage.iter().filter(|&&c| c >= 0.8).count(),
        outside_a_fraction: ratio(n_out as f64, n_contact),
        max_depth_outside_a_m: max_out,
        mean_v_in_a: ratio(v_in, n_in),
        mean_v_outside_a: ratio(v_out, n_out),
        path,
        max_tension_n: run.max_tension_n(),
        trip_periods: run.trip_periods,
        safe_state_periods: run.safe_state_periods,
    }
}
