//! What the finger feels beyond what was asked: the bound every force distribution keeps, the
//! governor that keeps it, and the per-period measure the tools report (`docs/felt-force.md`).
//!
//! **The bound.** The wires only pull and each keeps at least `t_min`, so even a zero force
//! asked renders the floor's own pull `F0 = V t_min` (at most `N t_min`). A projection may add
//! to that where it trades force along the normal for force across it, but what the wearer feels
//! must never exceed what was asked by more than the floor's pull and a small margin:
//!
//! `|f| <= |f_e| + |f_c| + |F0(x)| + FELT_MARGIN_N`
//!
//! with `f` the rendered force, `f_e` the contact force, `f_c` the field the algorithm adds (F1,
//! F2, QP) or the free-space pull, and `F0(x)` the floor's pull at the thimble's position.
//!
//! **The governor** keeps it: when a projection's tensions render more than `|f'_e| + |F0| +
//! margin` (`f'_e = f_e + f_c`, so `|f'_e| <= |f_e| + |f_c|`), every tension's part above `t_min`
//! is scaled by the largest `σ in [0, 1]` that meets it. `σ` is continuous in the tensions and
//! the pose, so a continuous projection stays continuous.
//!
//! **The measure** ([`FeltTally`]) counts the periods beyond the bound and the steps of the
//! rendered force that the change of what was asked does not explain.

use nalgebra::SVector;

use crate::kinematics::libm_sqrt;
use crate::Vec3;

/// How much the rendered force may exceed what was asked beyond the floor's own pull, newtons.
pub const FELT_MARGIN_N: f64 = 0.5;

/// A step of the rendered force between two periods that the change of what was asked does
/// not explain by more than this is counted as a jolt, newtons.
pub const JOLT_STEP_N: f64 = 0.5;

/// The most a period may render beyond `|f_e|`: the field's magnitude, the floor's pull and the
/// margin, newtons.
pub fn allowed_excess_n(field_n: f64, floor_pull_n: f64) -> f64 {
    field_n.max(0.0) + floor_pull_n.max(0.0) + FELT_MARGIN_N
}

/// Scale the part of `tensions_n` above `t_min_n` so that the force they make, `force_of`,
/// has magnitude at most `limit_n` (which must exceed the floor's pull `floor`, the force of
/// every wire at `t_min_n`). Returns whether the tensions changed. Allocation-free; `σ` solves
/// `|F0 + σ D| = limit` in closed form.
pub fn govern<const N: usize>(
    tensions_n: &mut [f64; N],
    t_min_n: f64,
    floor: &SVector<f64, N>,
    limit_n: f64,
    force_of: impl Fn(&[f64; N]) -> SVector<f64, N>,
) -> bool {
    let full = force_of(tensions_n);
    let limit_sq = limit_n * limit_n;
    if !(limit_n.is_finite() && full.norm_squared() > limit_sq) {
        return false;
    }
    let d = full - floor;
    let (dd, fd, ff) = (d.norm_squared(), floor.dot(&d), floor.norm_squared());
    let room = limit_sq - ff;
    // The floor alone at or beyond the limit (only with a limit below the floor's pull): the
    // floor is the least the wires can do.
    let sigma = if room <= 0.0 || dd <= 0.0 {
        0.0
    } else {
        ((-fd + libm_sqrt(fd * fd + dd * room)) / dd).clamp(0.0, 1.0)
    };
    for t in tensions_n.iter_mut() {
        *t = t_min_n + sigma * (*t - t_min_n);
    }
    true
}

/// One period as the measure sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FeltPeriod {
    /// Period number.
    pub cycle: u64,
    /// The contact force asked, `f_e`, newtons.
    pub desired_n: Vec3,
    /// The field or free-space pull added, `f_c`, newtons.
    pub field_n: Vec3,
    /// The force the set-points render, newtons.
    pub rendered_n: Vec3,
    /// The floor's pull at the position, `|V t_min|`, newtons.
    pub floor_pull_n: f64,
}

/// The felt-force measure over a session: how far the rendered force went beyond what was
/// asked, and the jolts (steps the change of what was asked does not explain).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct FeltTally {
    /// Periods measured.
    pub periods: u64,
    /// Periods rendering more than the bound beyond `|f_e|`.
    pub over_bound: u64,
    /// Largest `|f| - |f_e|`, newtons.
    pub worst_excess_n: f64,
    /// The period of the largest excess.
    pub worst_excess_cycle: u64,
    /// Largest `|f| - |f_e| - allowed` (negative: always within the bound; `-inf` before any
    /// period), newtons.
    pub worst_over_bound_n: f64,
    /// Periods whose rendered force stepped by more than [`JOLT_STEP_N`] beyond the change of
    /// what was asked.
    pub jolts: u64,
    /// Largest unexplained step, `|Δf| - |Δ(f_e + f_c)|`, newtons.
    pub worst_jolt_n: f64,
    /// The period of the largest unexplained step.
    pub worst_jolt_cycle: u64,
    #[cfg_attr(feature = "serde", serde(skip))]
    previous: Option<(u64, Vec3, Vec3)>,
}

impl FeltTally {
    /// An empty tally.
    pub fn new() -> FeltTally {
        FeltTally {
            worst_over_bound_n: f64::NEG_INFINITY,
            ..FeltTally::default()
        }
    }

    /// Add a period. Periods must come in order; a gap in the cycle numbers starts the step
    /// measure afresh.
    pub fn add(&mut self, p: &FeltPeriod) {
        let finite = |v: &Vec3| v.iter().all(|c| c.is_finite());
        if !(finite(&p.desired_n) && finite(&p.field_n) && finite(&p.rendered_n)) {
            self.previous = None;
            return;
        }
        self.periods += 1;
        let excess = p.rendered_n.norm() - p.desired_n.norm();
        let over = excess - allowed_excess_n(p.field_n.norm(), p.floor_pull_n);
        // Round-off on the boundary is not a violation.
        if over > 1e-9 {
            self.over_bound += 1;
        }
        if self.periods == 1 || excess > self.worst_excess_n {
            self.worst_excess_n = excess;
            self.worst_excess_cycle = p.cycle;
        }
        self.worst_over_bound_n = self.worst_over_bound_n.max(over);
        let asked = p.desired_n + p.field_n;
        if let Some((cycle, asked_before, rendered_before)) = self.previous {
            if cycle + 1 == p.cycle {
                let step = (p.rendered_n - rendered_before).norm() - (asked - asked_before).norm();
                if step > JOLT_STEP_N {
                    self.jolts += 1;
                }
                if step > self.worst_jolt_n {
                    self.worst_jolt_n = step;
                    self.worst_jolt_cycle = p.cycle;
                }
            }
        }
        self.previous = Some((p.cycle, asked, p.rendered_n));
    }

    /// Add another run's tally: the counts add up, the worst is the worst of both (its cycle is
    /// that run's). The step measure starts afresh after it.
    pub fn merge(&mut self, other: &FeltTally) {
        if other.periods == 0 {
            return;
        }
        if self.periods == 0 || other.worst_excess_n > self.worst_excess_n {
            self.worst_excess_n = other.worst_excess_n;
            self.worst_excess_cycle = other.worst_excess_cycle;
        }
        if other.worst_jolt_n > self.worst_jolt_n {
            self.worst_jolt_n = other.worst_jolt_n;
            self.worst_jolt_cycle = other.worst_jolt_cycle;
        }
        self.worst_over_bound_n = self.worst_over_bound_n.max(other.worst_over_bound_n);
        self.periods += other.periods;
        self.over_bound += other.over_bound;
        self.jolts += other.jolts;
        self.previous = None;
    }
}

impl core::fmt::Display for FeltTally {
    /// One line: the periods beyond the bound with the worst excess, and the jolts.
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "{} of {} periods beyond the felt bound (worst |f| - |f_e| {:.2} N at cycle {}, {:+.2} N from the bound); {} jolts over {} N (worst {:.2} N at cycle {})",
            self.over_bound,
            self.periods,
            self.worst_excess_n,
            self.worst_excess_cycle,
            if self.worst_over_bound_n.is_finite() {
                self.worst_over_bound_n
            } else {
                0.0
            },
            self.jolts,
            JOLT_STEP_N,
            self.worst_jolt_n,
            self.worst_jolt_cycle,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Matrix3;

    #[test]
    fn the_governor_scales_down_to_the_limit_and_no_further() {
        let v = Matrix3::new(0.0, 0.6, -0.6, 0.0, 0.0, 0.0, -1.0, -0.8, -0.8);
        let force_of = |t: &[f64; 3]| v * Vec3::from(*t);
        let floor = force_of(&[0.3; 3]);
        let mut t = [0.3, 15.0, 0.3];
        let limit = 2.0;
        assert!(govern(&mut t, 0.3, &floor, limit, force_of));
        assert!((force_of(&t).norm() - limit).abs() < 1e-9);
        assert!(t.iter().all(|&x| x >= 0.3));
        // Already within: untouched.
        let mut small = [0.3, 0.5, 0.3];
        let before = small;
        assert!(!govern(&mut small, 0.3, &floor, limit, force_of));
        assert_eq!(small, before);
        // A limit below the floor: the floor.
        let mut t = [0.3, 15.0, 0.3];
        govern(&mut t, 0.3, &floor, 0.01, force_of);
        assert_eq!(t, [0.3; 3]);
    }

    #[test]
    fn the_tally_counts_excess_and_unexplained_steps() {
        let mut tally = FeltTally::new();
        let period = |cycle, desired: f64, rendered: f64| FeltPeriod {
            cycle,
            desired_n: Vec3::new(desired, 0.0, 0.0),
            field_n: Vec3::zeros(),
            rendered_n: Vec3::new(rendered, 0.0, 0.0),
            floor_pull_n: 0.5,
        };
        tally.add(&period(1, 0.0, 0.5));
        tally.add(&period(2, 1.0, 1.5)); // asked +1, rendered +1: explained
        tally.add(&period(3, 1.0, 15.0)); // the jab
        tally.add(&period(4, 1.0, 1.2));
        assert_eq!(tally.periods, 4);
        assert_eq!(tally.over_bound, 1);
        assert_eq!(tally.worst_excess_cycle, 3);
        assert!((tally.worst_excess_n - 14.0).abs() < 1e-12);
        assert_eq!(tally.jolts, 2, "up and back down");
        assert!((tally.worst_jolt_n - 13.8).abs() < 1e-12);
        assert!(std::format!("{tally}").contains("1 of 4 periods"));
        // A gap restarts the step measure.
        tally.add(&period(9, 1.0, 9.0));
        assert_eq!(tally.jolts, 2);
        // Two runs merged: the counts add up, the worst is the worst of both.
        let mut quiet = FeltTally::new();
        quiet.add(&period(1, 2.0, 2.1));
        let mut merged = FeltTally::new();
        merged.merge(&quiet);
        merged.merge(&tally);
        merged.merge(&FeltTally::new());
        assert_eq!((merged.periods, merged.over_bound, merged.jolts), (6, 2, 2));
        assert_eq!(merged.worst_excess_cycle, 3);
        assert!((merged.worst_jolt_n - 13.8).abs() < 1e-12);
    }
}
