//! Pop-through: the penetration of the wall facing the frame at each pushing force, the
//! penetration at the wearer's push, the force the device holds before a wire saturates, and the
//! smallest push that passes through a relief feature of given depth.

use serde::Serialize;
use videt_config::Config;
use videt_sim::Vec3;

use super::rig::{run, start_position, Experiment, Parts};
use super::settings::BenchPlan;
use super::wall::{equilibrium, pusher, surface_ahead};

/// Penetration and held force at one pushing force.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PushRow {
    /// The hand's force at the end of the hold, N.
    pub push_n: f64,
    /// Normal force of the wires on the finger, N.
    pub wall_force_n: f64,
    /// Penetration, mm.
    pub penetration_mm: f64,
    /// Largest wire tension, N.
    pub max_tension_n: f64,
    /// Some wire is at its maximum tension: the wall gives way.
    pub saturated: bool,
    /// The penetration is deeper than the relief feature the bench asks about.
    pub popped_through: bool,
}

/// The pop-through sweep at the configured stiffness.
#[derive(Debug, Clone, Serialize)]
pub struct PopThroughReport {
    /// Wall stiffness, N/m.
    pub stiffness_n_per_m: f64,
    /// Depth of the relief feature the finger must not pass through, mm.
    pub feature_depth_mm: f64,
    /// The wearer's pushing force (the virtual operator's of the demo scene), N.
    pub wearer_push_n: f64,
    /// Penetration at the wearer's pushing force, mm (interpolated).
    pub wearer_penetration_mm: f64,
    /// Smallest pushing force tried that pops through the feature, N.
    pub pop_through_push_n: Option<f64>,
    /// Every push.
    pub pushes: Vec<PushRow>,
}

/// The demo operator's push: a 200 N/m hand 20 mm past the wall.
pub const WEARER_PUSH_N: f64 = 200.0 * 0.02;

/// Push on the wall facing the frame with each of `push_n` (a soft hand far past the wall:
/// nearly a constant force) and measure the penetration; `feature_mm`: the relief step the
/// finger must not pass.
pub fn pop_through(
    base: &Config,
    plan: &BenchPlan,
    feature_mm: f64,
) -> Result<PopThroughReport, String> {
    let mut config = base.clone();
    config.control.algorithm = "P2".into();
    let start = start_position(&config);
    let n = Vec3::new(0.0, 0.0, -1.0);
    let surface = surface_ahead(start, n);
    let k_hand = 100.0;
    let t_max = config.control.t_max_n;
    let mut pushes = Vec::new();
    for &push in plan.push_n {
        let trace = run(&Experiment {
            config: config.clone(),
            surface,
            operator: pusher(start, n, &[push / k_hand], &[0.0], k_hand),
            duration_s: 2.0,
            parts: Parts::Faithful,
        })?;
        let (force, depth, _) = equilibrium(&trace, &surface, 1.7, 2.0);
        let last = trace.samples.last().copied();
        let hand = last.map_or(f64::NAN, |s| -s.hand_force_n.dot(&n));
        let max_t = trace
            .window(1.7, 2.0)
            .map(|s| s.max_tension_n)
            .fold(0.0, f64::max);
        pushes.push(PushRow {
            push_n: hand,
            wall_force_n: force,
            penetration_mm: depth * 1e3,
            max_tension_n: max_t,
            saturated: max_t >= 0.98 * t_max,
            popped_through: depth * 1e3 > feature_mm,
        });
    }
    let wearer_penetration_mm = interpolate(
        &pushes
            .iter()
            .map(|p| (p.push_n, p.penetration_mm))
            .collect::<Vec<_>>(),
        WEARER_PUSH_N,
    );
    Ok(PopThroughReport {
        stiffness_n_per_m: config.control.stiffness_n_per_m,
        feature_depth_mm: feature_mm,
        wearer_push_n: WEARER_PUSH_N,
        wearer_penetration_mm,
        pop_through_push_n: pushes.iter().find(|p| p.popped_through).map(|p| p.push_n),
        pushes,
    })
}

/// Linear interpolation of `y(x)` through points sorted by `x` (clamped at the ends).
fn interpolate(points: &[(f64, f64)], x: f64) -> f64 {
    let Some(&(first_x, first_y)) = points.first() else {
        return f64::NAN;
    };
    if x <= first_x {
        return first_y;
    }
    for w in points.windows(2) {
        let ((x0, y0), (x1, y1)) = (w[0], w[1]);
        if x <= x1 {
            return y0 + (y1 - y0) * (x - x0) / (x1 - x0);
        }
    }
    points[points.len() - 1].1
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolation_is_linear_and_clamped() {
        let p = [(1.0, 10.0), (3.0, 30.0)];
        assert_eq!(interpolate(&p, 2.0), 20.0);
        assert_eq!(interpolate(&p, 0.0), 10.0);
        assert_eq!(interpolate(&p, 9.0), 30.0);
    }
}
