//! Fig. 22: the planar prototype explores a surface whose normal lies in region C — a floor
//! between the thimble and the guides, its normal `+z` pointing away from the guides, opposite to
//! the wires' pulls. No tension can push, so `f_e` is not in `F`; with a force field `f_c` (F1,
//! constant, towards the frame, `|f_c| = 2 N`) the device renders `f_e + f_c`, and the user
//! feels the floor as a relief of the field's pull, like putting down a weight on a table.
//!
//! The same operator is run twice: with F1 and the field, and with P1 and no field, which cannot
//! render the floor at all (it only holds the wires at `t_min`).

use videt_control::planar::Vec2;
use videt_control::{Algorithm, ControlStep, PlanarDevice, Profile, SolidSide, Vec3};
use videt_sim::{VirtualOperator, Waypoint};

use crate::closed_loop::{run_closed_loop, twin_for, LoopSettings, Run};
use crate::geometry::{mean, path_stats, planar_region, PathStats, Region};
use crate::params::ControlConfig;
use crate::ExperimentError;

/// Height of the floor, metres.
pub const FLOOR_Z_M: f64 = 0.22;
/// Field magnitude `|f_c|` of the paper's Figs. 20-22, newtons.
pub const FIELD_N: f64 = 2.0;

/// When the operator does what.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fig22Timeline {
    /// Free-space hold above the floor: from, to (seconds).
    pub free_s: (f64, f64),
    /// Exploration (sliding along the floor, resting on it): from, to (seconds).
    pub explore_s: (f64, f64),
    /// End of the run, seconds.
    pub end_s: f64,
}

/// One run of Fig. 22 in numbers.
#[derive(Debug, Clone, PartialEq)]
pub struct RegionCSummary {
    /// The algorithm.
    pub algorithm: Algorithm,
    /// `|f_c|`, newtons.
    pub field_n: f64,
    /// How the thimble followed the floor during the exploration.
    pub path: PathStats,
    /// Share of the contact periods whose normal lay in region C.
    pub region_c_fraction: f64,
    /// Mean desired contact force along the normal, `f_e · n = K depth`, newtons.
    pub mean_desired_n: f64,
    /// Mean surface reaction the wires render along the normal, relative to the field,
    /// `(f - f_c) · n` with `f` the force of the measured tensions, newtons. Positive: the floor
    /// pushes the finger back out.
    pub mean_reaction_n: f64,
    /// Mean index V (eq. 8) in contact.
    pub mean_v_index: f64,
    /// Mean measured force along the normal in free space before the touch, newtons.
    pub free_force_along_n_n: f64,
    /// Mean measured force along the normal in contact, newtons.
    pub contact_force_along_n_n: f64,
    /// What the finger feels when it touches: the change of the force along the normal from
    /// free space to contact, newtons (positive: pushed out of the surface).
    pub felt_change_n: f64,
    /// Largest measured tension, newtons.
    pub max_tension_n: f64,
    /// Periods whose tensions tripped the safety check.
    pub trip_periods: usize,
    /// Periods run in the safe state.
    pub safe_state_periods: usize,
}

/// Fig. 22's numbers: the run with the field and the run without.
#[derive(Debug, Clone, PartialEq)]
pub struct Fig22Summary {
    /// F1 with `|f_c| = 2 N`.
    pub field: RegionCSummary,
    /// P1 without field, the same operator.
    pub baseline: RegionCSummary,
}

/// One recorded run of Fig. 22.
#[derive(Debug, Clone)]
pub struct RegionCRun {
    /// The recorded run.
    pub run: Run<2>,
    /// Its numbers.
    pub summary: RegionCSummary,
}

/// The Fig. 22 experiment as run.
#[derive(Debug, Clone)]
pub struct Fig22 {
    /// The device.
    pub device: PlanarDevice,
    /// The floor.
    pub surface: Profile,
    /// When the operator does what.
    pub timeline: Fig22Timeline,
    /// With the field (F1).
    pub field: RegionCRun,
    /// Without (P1).
    pub baseline: RegionCRun,
    /// The numbers of both.
    pub summary: Fig22Summary,
}

/// The floor: `z = FLOOR_Z_M` across the workspace, solid below (between the thimble and the
/// guides), outward normal `+z`.
pub fn fig22_floor() -> Profile {
    Profile::open(
        &[Vec2::new(0.0, FLOOR_Z_M), Vec2::new(0.52, FLOOR_Z_M)],
        SolidSide::Right,
    )
    .expect("a valid profile")
}

/// The operator: holds the thimble 8 cm above the floor, lowers the hand (and moves it 3 cm
/// along `x`) until it aims 1 mm above the floor (the thimble rests on it under the field's pull), slides 24 cm along it and
/// back, and lifts off.
pub fn fig22_operator() -> (VirtualOperator, Fig22Timeline) {
    let (x0, x1) = (0.14, 0.38);
    let above = FLOOR_Z_M + 0.08;
    let rest = FLOOR_Z_M + 0.001;
    let speed = 0.06;
    let slide_s = (x1 - x0) / speed;
    let p = |x: f64, z: f64| Vec3::new(x, 0.0, z);
    let times = [0.0, 1.2, 2.4, 3.0, 3.0 + slide_s, 3.0 + 2.0 * slide_s];
    let w = vec![
        Waypoint {
            time_s: times[0],
            target_m: p(x0 - 0.03, above),
        },
        Waypoint {
            time_s: times[1],
            target_m: p(x0 - 0.03, above),
        },
        Waypoint {
            time_s: times[2],
            target_m: p(x0, rest),
        },
        Waypoint {
            time_s: times[3],
            target_m: p(x0, rest),
        },
        Waypoint {
            time_s: times[4],
            target_m: p(x1, rest),
        },
        Waypoint {
            time_s: times[5],
            target_m: p(x0, rest),
        },
        Waypoint {
            time_s: times[5] + 1.0,
            target_m: p(x0 - 0.03, above),
        },
    ];
    (
        VirtualOperator::new(w, 200.0, 6.0),
        Fig22Timeline {
            free_s: (0.6, times[1]),
            explore_s: (times[3], times[5]),
            end_s: times[5] + 1.6,
        },
    )
}

/// Run Fig. 22: F1 with `|f_c| = 2 N`, and the P1 baseline without field.
pub fn fig22() -> Result<Fig22, ExperimentError> {
    let device = PlanarDevice::paper_prototype();
    let surface = fig22_floor();
    let (_, timeline) = fig22_operator();
    let field = region_c_run(&device, &surface, Algorithm::F1, FIELD_N)?;
    let baseline = region_c_run(&device, &surface, Algorithm::P1, 0.0)?;
    let summary = Fig22Summary {
        field: field.summary.clone(),
        baseline: baseline.summary.clone(),
    };
    Ok(Fig22 {
        device,
        surface,
        timeline,
        field,
        baseline,
        summary,
    })
}

/// Run the floor exploration with `algorithm` and a field of `field_n` newtons.
pub fn region_c_run(
    device: &PlanarDevice,
    surface: &Profile,
    algorithm: Algorithm,
    field_n: f64,
) -> Result<RegionCRun, ExperimentError> {
    let (operator, timeline) = fig22_operator();
    let start = operator.target(0.0).0;
    let mut twin = twin_for(*device, start, operator);
    let params = ControlConfig::EXAMPLE.params(
        &twin.plant().params().transmission,
        crate::closed_loop::wire_stretch(twin.plant()),
        algorithm,
        field_n,
    );
    let mut step = ControlStep::new(*device, params);
    let run = run_closed_loop(
        &mut twin,
        &mut step,
        surface,
        &LoopSettings::for_duration(timeline.end_s),
    )?;
    let summary = summarize(device, surface, &run, &timeline, algorithm, field_n);
    Ok(RegionCRun { run, summary })
}

fn summarize(
    device: &PlanarDevice,
    surface: &Profile,
    run: &Run<2>,
    timeline: &Fig22Timeline,
    algorithm: Algorithm,
    field_n: f64,
) -> RegionCSummary {
    let (from, to) = timeline.explore_s;
    let n = Vec3::z();
    let contact: Vec<_> = run.window(from, to).filter(|s| s.in_contact).collect();
    let in_c = contact
        .iter()
        .filter(|s| planar_region(device, &s.position_m, &s.normal) == Region::C)
        .count();
    let free = mean(
        run.window(timeline.free_s.0, timeline.free_s.1)
            .map(|s| s.measured_n.dot(&n)),
    );
    let touching = mean(contact.iter().map(|s| s.measured_n.dot(&n)));
    RegionCSummary {
        algorithm,
        field_n,
        path: path_stats(surface, run.window(from, to)),
        region_c_fraction: if contact.is_empty() {
            0.0
        } else {
            in_c as f64 / contact.len() as f64
        },
        mean_desired_n: mean(contact.iter().map(|s| s.desired_n.dot(&s.normal))),
        mean_reaction_n: mean(
            contact
                .iter()
                .map(|s| (s.measured_n - s.field_n).dot(&s.normal)),
        ),
        mean_v_index: mean(contact.iter().map(|s| s.v_index)),
        free_force_along_n_n: free,
        contact_force_along_n_n: touching,
        felt_change_n: touching - free,
        max_tension_n: run.max_tension_n(),
        trip_periods: run.trip_periods,
        safe_state_periods: run.safe_state_periods,
    }
}
