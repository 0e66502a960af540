//! The wall an experiment pushes on (a plane just ahead of the thimble, by the paper's region
//! of its normal) and the operator pushing on it; where the thimble settled against it and how
//! still it held: what the stiffness, the pop-through, the Z-width's short criterion and the long
//! hold judge.

use videt_config::Config;
use videt_control::surface::Plane;
use videt_sim::{Vec3, VirtualOperator, Waypoint};

use super::region::Region;
use super::rig::{start_position, Trace};

/// How far in front of the thimble every surface starts, metres.
pub(super) const SURFACE_GAP_M: f64 = 0.003;

/// A plane `gap` in front of `start` (along `-n`) with outward normal `n`.
pub(super) fn surface_ahead(start: Vec3, n: Vec3) -> Plane {
    Plane::new(start - n * SURFACE_GAP_M, n).expect("a unit normal")
}

/// The operator pushing along `-n`: the hand target moves to `depths_m[k]` past the surface
/// over 0.3 s from `times_s[k]` on, and holds there until the next move.
pub(super) fn pusher(
    start: Vec3,
    n: Vec3,
    depths_m: &[f64],
    times_s: &[f64],
    k_hand: f64,
) -> VirtualOperator {
    let mut waypoints = vec![Waypoint {
        time_s: 0.0,
        target_m: start,
    }];
    let mut held = start;
    for (&d, &t) in depths_m.iter().zip(times_s) {
        waypoints.push(Waypoint {
            time_s: t,
            target_m: held,
        });
        held = start - n * (SURFACE_GAP_M + d);
        waypoints.push(Waypoint {
            time_s: t + 0.3,
            target_m: held,
        });
    }
    VirtualOperator::new(waypoints, k_hand, 4.0)
}

/// The wall of `region` ([`Region::wall_normal`]) rendered by P2 with stiffness `k` and
/// damping `b` on `base`'s parts: the configuration, where the thimble starts, the wall's
/// outward normal and the wall (3 mm ahead).
pub(super) fn region_wall(
    base: &Config,
    region: Region,
    k: f64,
    b: f64,
) -> (Config, Vec3, Vec3, Plane) {
    let mut config = base.clone();
    config.control.stiffness_n_per_m = k;
    config.control.damping_n_s_per_m = b;
    config.control.algorithm = "P2".into();
    let start = start_position(&config);
    let n = region.wall_normal();
    let surface = surface_ahead(start, n);
    (config, start, n, surface)
}

/// How still the thimble held against `surface` over `[from_s, to_s)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct HoldStats {
    /// Half the penetration's peak-to-peak, mm.
    pub(super) oscillation_mm: f64,
    /// RMS thimble speed, mm/s.
    pub(super) rms_speed_mm_s: f64,
    /// Periods out of contact.
    pub(super) contact_lost: usize,
    /// Periods in the window.
    pub(super) periods: usize,
}

pub(super) fn hold_stats(trace: &Trace, surface: &Plane, from_s: f64, to_s: f64) -> HoldStats {
    let (mut lo, mut hi, mut v2, mut periods, mut lost) = (f64::MAX, f64::MIN, 0.0, 0, 0);
    for s in trace.window(from_s, to_s) {
        let depth = -surface.signed_distance_m(&s.position_m);
        lo = lo.min(depth);
        hi = hi.max(depth);
        v2 += s.velocity_m_s.norm_squared();
        periods += 1;
        if depth <= 0.0 {
            lost += 1;
        }
    }
    HoldStats {
        oscillation_mm: (hi - lo) * 0.5e3,
        rms_speed_mm_s: (v2 / periods.max(1) as f64).sqrt() * 1e3,
        contact_lost: lost,
        periods,
    }
}

/// Mean normal force, mean penetration and the penetration's spread over a window.
pub type Equilibrium = (f64, f64, f64);

/// Mean normal force and penetration over `[from, to)`, and the spread of the penetration.
pub(super) fn equilibrium(trace: &Trace, plane: &Plane, from_s: f64, to_s: f64) -> Equilibrium {
    let n = plane.normal();
    let (mut f, mut p, mut lo, mut hi, mut count) = (0.0, 0.0, f64::MAX, f64::MIN, 0.0);
    for s in trace.window(from_s, to_s) {
        let depth = -plane.signed_distance_m(&s.position_m);
        f += s.wire_force_n.dot(&n);
        p += depth;
        lo = lo.min(depth);
        hi = hi.max(depth);
        count += 1.0;
    }
    if count == 0.0 {
        return (f64::NAN, f64::NAN, f64::NAN);
    }
    (f / count, p / count, hi - lo)
}
