//! Fig. 23: the one-wire device (one actuated wire from a guide at the origin, two passive angle
//! sensors, eq. 7) explores a polygonal contour.
//!
//! The contour lies in a plane `y = const` ([`PLANE_Y_M`], beside the guide) in front of the
//! guide, extruded along `y`, the solid beyond it (away from the guide). The wire can only pull
//! the thimble back towards the guide, so with algorithm P1 it renders the component of `f_e`
//! along the wire, and the thimble, pressed outwards by the finger, slides along the contour
//! (the paper: "the only static configuration is when `f_o` is directed along the wire. The user
//! perceives a surface mainly sliding on it"). The sides' normals make 9 to 62 degrees with the
//! wire. The thimble moves in 3D: the wire pulls it out of the plane, towards the guide, and the
//! operator's hand keeps it near the plane.

use videt_control::planar::Vec2;
use videt_control::{Algorithm, ControlStep, PolarDevice, Profile, SolidSide, WireDevice};
use videt_sim::{VirtualOperator, Waypoint};

use crate::closed_loop::{run_closed_loop, twin_for, LoopSettings, Run};
use crate::geometry::{path_stats, waypoints_along, xz, PathStats};
use crate::params::ControlConfig;
use crate::ExperimentError;

/// How the operator explores the contour.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fig23Script {
    /// Sliding speed along the contour, m/s.
    pub speed_m_s: f64,
    /// How far beyond the contour the hand aims, radially away from the guide in the contour's
    /// plane (nearly along the wire), metres.
    pub press_m: f64,
}

impl Default for Fig23Script {
    fn default() -> Self {
        Fig23Script {
            speed_m_s: 0.06,
            press_m: 0.015,
        }
    }
}

/// What Fig. 23 shows, in numbers.
#[derive(Debug, Clone, PartialEq)]
pub struct Fig23Summary {
    /// The algorithm (P1).
    pub algorithm: Algorithm,
    /// Duration of the traversal, seconds.
    pub traversal_s: f64,
    /// How the thimble followed the contour over the traversal.
    pub path: PathStats,
    /// Sides of the contour.
    pub sides: usize,
    /// Sides the thimble touched along at least 80 % of their length.
    pub sides_explored: usize,
    /// Largest distance of the thimble from the contour's plane `y = PLANE_Y_M`, metres.
    pub max_off_plane_m: f64,
    /// Largest angle between the force of the tension set-point and the wire, radians (the one
    /// wire can only pull along itself).
    pub max_force_angle_from_wire_rad: f64,
    /// Mean wire tension in contact, newtons.
    pub mean_contact_tension_n: f64,
    /// Largest measured tension, newtons.
    pub max_tension_n: f64,
    /// Periods whose tensions tripped the safety check.
    pub trip_periods: usize,
    /// Periods run in the safe state.
    pub safe_state_periods: usize,
}

/// The Fig. 23 experiment as run.
#[derive(Debug, Clone)]
pub struct Fig23 {
    /// The device.
    pub device: PolarDevice,
    /// The contour.
    pub contour: Profile,
    /// The recorded run.
    pub run: Run<1>,
    /// Start and end of the traversal, seconds.
    pub traversal_s: (f64, f64),
    /// The numbers.
    pub summary: Fig23Summary,
}

/// The plane the contour lies in, `y` (metres): just beside the guide, so that the wire leaves
/// the plane and the operator's hand has to keep the thimble in it.
pub const PLANE_Y_M: f64 = 0.04;

/// The contour of Fig. 23 in the x-z plane: six sides from low to high elevation around the
/// guide at the origin, 0.36 to 0.47 m from it, with a tooth pointing at the guide; the solid
/// lies beyond it.
pub fn fig23_contour() -> Profile {
    let v = [
        Vec2::new(0.40, 0.06),
        Vec2::new(0.40, 0.17),
        Vec2::new(0.30, 0.20),
        Vec2::new(0.34, 0.31),
        Vec2::new(0.22, 0.34),
        Vec2::new(0.19, 0.42),
        Vec2::new(0.09, 0.42),
    ];
    Profile::open(&v, SolidSide::Right).expect("a valid contour")
}

/// `p` moved `by` metres further from the origin.
fn radially(p: &Vec2, by: f64) -> Vec2 {
    p * (1.0 + by / p.norm())
}

/// The operator of Fig. 23 and the traversal's start and end, seconds: the hand aims
/// `press_m` beyond the contour, radially away from the guide (at the origin), and moves along
/// it from the first vertex to the last.
pub fn fig23_operator(contour: &Profile, script: &Fig23Script) -> (VirtualOperator, (f64, f64)) {
    let v = contour.vertices();
    // Each side in four pieces, each point pushed out radially.
    let mut path = Vec::new();
    for i in 0..v.len() - 1 {
        for k in 0..4 {
            let p = v[i] + (v[i + 1] - v[i]) * (k as f64 / 4.0);
            path.push(xz(&radially(&p, script.press_m), PLANE_Y_M));
        }
    }
    path.push(xz(&radially(&v[v.len() - 1], script.press_m), PLANE_Y_M));
    let start = xz(&radially(&v[0], -0.06), PLANE_Y_M);
    let (hold_s, approach_s) = (0.6, 0.8);
    let mut waypoints = vec![
        Waypoint {
            time_s: 0.0,
            target_m: start,
        },
        Waypoint {
            time_s: hold_s,
            target_m: start,
        },
    ];
    let begin = hold_s + approach_s;
    let (w, end) = waypoints_along(&path, begin, script.speed_m_s);
    waypoints.extend(w);
    waypoints.push(Waypoint {
        time_s: end + 0.8,
        target_m: xz(&radially(&v[v.len() - 1], -0.06), PLANE_Y_M),
    });
    (VirtualOperator::new(waypoints, 200.0, 6.0), (begin, end))
}

/// Run Fig. 23 with the default script.
pub fn fig23() -> Result<Fig23, ExperimentError> {
    fig23_with(&Fig23Script::default())
}

/// Run Fig. 23: the one-wire device at the origin, P1 without field, the example
/// configuration's surface and tension loop, the operator of `script`.
pub fn fig23_with(script: &Fig23Script) -> Result<Fig23, ExperimentError> {
    let device = PolarDevice::at_origin();
    let contour = fig23_contour();
    let (operator, traversal_s) = fig23_operator(&contour, script);
    let start = operator.target(0.0).0;
    let mut twin = twin_for(device, start, operator);
    let params = ControlConfig::EXAMPLE.params(
        &twin.plant().params().transmission,
        crate::closed_loop::wire_stretch(twin.plant()),
        Algorithm::P1,
        0.0,
    );
    let mut step = ControlStep::new(device, params);
    let run = run_closed_loop(
        &mut twin,
        &mut step,
        &contour,
        &LoopSettings::for_duration(traversal_s.1 + 1.2),
    )?;
    let (from, to) = traversal_s;
    let path = path_stats(&contour, run.window(from, to));
    let mut max_angle = 0.0f64;
    let mut max_off_plane = 0.0f64;
    let (mut tension_sum, mut contacts) = (0.0, 0usize);
    for s in run.window(from, to) {
        max_off_plane = max_off_plane.max((s.true_position_m.y - PLANE_Y_M).abs());
        let f = s.rendered_n;
        let wire = device.pull_direction(&s.position_m, 0);
        if f.norm() > 1e-9 {
            max_angle = max_angle.max((f.dot(&wire) / f.norm()).clamp(-1.0, 1.0).acos());
        }
        if s.in_contact {
            contacts += 1;
            tension_sum += s.tension_n[0];
        }
    }
    let summary = Fig23Summary {
        algorithm: Algorithm::P1,
        traversal_s: to - from,
        sides: contour.segment_count(),
        sides_explored: path.segment_coverage.iter().filter(|&&c| c >= 0.8).count(),
        path,
        max_off_plane_m: max_off_plane,
        max_force_angle_from_wire_rad: max_angle,
        mean_contact_tension_n: if contacts == 0 {
            0.0
        } else {
            tension_sum / contacts as f64
        },
        max_tension_n: run.max_tension_n(),
        trip_periods: run.trip_periods,
        safe_state_periods: run.safe_state_periods,
    };
    Ok(Fig23 {
        device,
        contour,
        run,
        traversal_s,
        summary,
    })
}
