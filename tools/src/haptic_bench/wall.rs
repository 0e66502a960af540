//! The wall an experiment pushes on, by the paper's region of its normal, and how still the
//! thimble held against it: what the Z-width's short criterion and the long hold both judge.

use videt_config::Config;
use videt_control::surface::Plane;
use videt_sim::Vec3;

use super::rig::{start_position, Trace};
use super::{surface_ahead, Region};

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
