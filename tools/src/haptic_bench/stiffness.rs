//! The stiffness the finger feels: the stiffness rendered by P1 and P2 against the programmed
//! one, over surface normals in the paper's regions A, B and C (section 5, Figs 14-15), as the
//! secant between two pushes of the bench's operator.

use serde::Serialize;
use videt_config::Config;
use videt_control::safety::SafetyState;
use videt_control::FeltTally;
use videt_sim::Vec3;

use super::region::{normal_at, region_of, Region};
use super::rig::{run, start_position, Experiment, Parts};
use super::settings::BenchPlan;
use super::wall::{equilibrium, pusher, surface_ahead, Equilibrium};

/// Stiffness rendered against a surface of normal `normal`.
#[derive(Debug, Clone, Serialize)]
pub struct StiffnessRow {
    /// Distribution algorithm.
    pub algorithm: String,
    /// Outward surface normal (the direction of the contact force).
    pub normal: [f64; 3],
    /// Angle of the normal from the frame's axis, degrees.
    pub polar_deg: f64,
    /// Azimuth of the normal, degrees.
    pub azimuth_deg: f64,
    /// The normal's region at the thimble's start.
    pub region: Region,
    /// Programmed stiffness K, N/m.
    pub programmed_n_per_m: f64,
    /// Rendered stiffness along the normal (secant between two pushes), N/m.
    pub rendered_n_per_m: f64,
    /// `rendered / programmed`.
    pub ratio: f64,
    /// Normal force and penetration at the two pushes (N, mm).
    pub pushes: [(f64, f64); 2],
    /// Both pushes settled (the thimble still within 0.2 mm over the window).
    pub settled: bool,
    /// Safety state at the end.
    pub safety: String,
    /// What the finger felt beyond what was asked over the run (`docs/felt-force.md`).
    pub felt: FeltTally,
}

/// Hand stiffness of the bench's operator in the stiffness sweep, N/m.
const STIFFNESS_HAND_N_PER_M: f64 = 400.0;

/// Rendered vs programmed stiffness for P1 and P2 over the plan's normals.
pub fn stiffness_sweep(base: &Config, plan: &BenchPlan) -> Result<Vec<StiffnessRow>, String> {
    let start = start_position(base);
    let mut normals = Vec::new();
    for &polar in plan.polar_deg {
        if polar == 0.0 {
            normals.push((polar, 0.0));
        } else {
            normals.extend(plan.azimuth_deg.iter().map(|&a| (polar, a)));
        }
    }
    let mut rows = Vec::new();
    for algorithm in ["P1", "P2"] {
        for &(polar, azimuth) in &normals {
            let n = normal_at(polar, azimuth);
            let mut config = base.clone();
            config.control.algorithm = algorithm.into();
            let (rendered, a, b, final_safety, felt) = secant_stiffness(&config, n)?;
            let k = config.control.stiffness_n_per_m;
            rows.push(StiffnessRow {
                algorithm: algorithm.into(),
                normal: [n.x, n.y, n.z],
                polar_deg: polar,
                azimuth_deg: azimuth,
                region: region_of(&config, start, n),
                programmed_n_per_m: k,
                rendered_n_per_m: rendered,
                ratio: rendered / k,
                pushes: [(a.0, a.1 * 1e3), (b.0, b.1 * 1e3)],
                settled: a.2 < 2e-4 && b.2 < 2e-4,
                safety: safety_name(final_safety),
                felt,
            });
        }
    }
    Ok(rows)
}

/// The stiffness `config` renders along `n` (the secant between a 10 and a 25 mm push of a
/// 400 N/m hand, without a force field), with both equilibria, the safety state at the end and
/// the felt-force measure of the run.
pub fn secant_stiffness(
    config: &Config,
    n: Vec3,
) -> Result<(f64, Equilibrium, Equilibrium, SafetyState, FeltTally), String> {
    let start = start_position(config);
    let depths = [0.010, 0.025];
    let times = [0.0, 1.2];
    let windows = [(0.9, 1.2), (2.1, 2.4)];
    let mut config = config.clone();
    config.control.field_n = 0.0;
    let surface = surface_ahead(start, n);
    let trace = run(&Experiment {
        config,
        surface,
        operator: pusher(start, n, &depths, &times, STIFFNESS_HAND_N_PER_M),
        duration_s: 2.4,
        parts: Parts::Faithful,
    })?;
    let a = equilibrium(&trace, &surface, windows[0].0, windows[0].1);
    let b = equilibrium(&trace, &surface, windows[1].0, windows[1].1);
    Ok((
        (b.0 - a.0) / (b.1 - a.1),
        a,
        b,
        trace.final_safety,
        trace.felt,
    ))
}

fn safety_name(s: SafetyState) -> String {
    match s {
        SafetyState::Normal => "normal".into(),
        other => format!("{other:?}"),
    }
}
