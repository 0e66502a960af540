//! The virtual operator: a finger that follows a scripted path through a spring-damper hand.

use crate::Vec3;

/// A point of the operator's scripted path: where the hand aims at a given time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Waypoint {
    /// Time, seconds from the start of the script.
    pub time_s: f64,
    /// Hand target, metres.
    pub target_m: Vec3,
}

/// A hand that pulls the thimble towards a moving target with a spring and a damper.
/// The path is piecewise linear between waypoints and holds the last one.
#[derive(Debug, Clone, PartialEq)]
pub struct VirtualOperator {
    waypoints: Vec<Waypoint>,
    /// Hand stiffness, N/m.
    pub stiffness_n_per_m: f64,
    /// Hand damping, N·s/m (relative to the target's velocity).
    pub damping_n_s_per_m: f64,
    /// When set, the script repeats with this period, seconds.
    pub repeat_period_s: Option<f64>,
    /// Simulated time at which the script starts, seconds (0 unless [`Self::starting_at`]).
    start_s: f64,
    /// When set, the hand presses with a constant force along this direction instead of
    /// following the target along it ([`Self::pressing`]).
    press: Option<Press>,
}

/// A hand pressing with a constant force along one direction ([`VirtualOperator::pressing`]).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Press {
    /// Unit direction of the push.
    direction: Vec3,
    /// The push, newtons.
    force_n: f64,
    /// Blocked across by more than this (newtons), the hand eases the push and lifts, by the
    /// excess, as a finger that meets a wall lifts over it ([`VirtualOperator::lifting_over`]).
    lift_above_n: Option<f64>,
}

impl VirtualOperator {
    /// An operator following `waypoints` (sorted by time; at least one).
    pub fn new(
        mut waypoints: Vec<Waypoint>,
        stiffness_n_per_m: f64,
        damping_n_s_per_m: f64,
    ) -> VirtualOperator {
        waypoints.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
        assert!(
            !waypoints.is_empty(),
            "a virtual operator needs at least one waypoint"
        );
        VirtualOperator {
            waypoints,
            stiffness_n_per_m,
            damping_n_s_per_m,
            repeat_period_s: None,
            start_s: 0.0,
            press: None,
        }
    }

    /// The same script with a hand that presses with a constant `force_n` along `direction`
    /// (normalised; e.g. `+z`, into a bas-relief) and follows the target only across it, as a
    /// finger exploring a surface at a light push: along `direction` only the push and the
    /// damping act. A zero direction leaves the operator as it was.
    pub fn pressing(mut self, direction: Vec3, force_n: f64) -> VirtualOperator {
        let norm = direction.norm();
        if norm > 1e-12 && force_n.is_finite() {
            self.press = Some(Press {
                direction: direction / norm,
                force_n,
                lift_above_n: None,
            });
        }
        self
    }

    /// A [`Self::pressing`] hand that, held back across its push by more than `limit_n` (a
    /// wall in the way), eases the push by the excess and lifts: it climbs over a step instead
    /// of dragging the finger against it. No effect on a hand that does not press.
    pub fn lifting_over(mut self, limit_n: f64) -> VirtualOperator {
        if let Some(press) = &mut self.press {
            press.lift_above_n = Some(limit_n.max(0.0));
        }
        self
    }

    /// The same script, repeated every `period_s` seconds (at least as long as the script).
    /// When the script ends away from where it starts, the hand moves back to the start over the
    /// rest of the period instead of jumping there (a jump would yank the thimble).
    pub fn repeating(mut self, period_s: f64) -> VirtualOperator {
        let first = self.waypoints[0];
        let last = self.waypoints[self.waypoints.len() - 1];
        let period = period_s.max(last.time_s).max(1e-3);
        if period > last.time_s && last.target_m != first.target_m {
            self.waypoints.push(Waypoint {
                time_s: period,
                target_m: first.target_m,
            });
        }
        self.repeat_period_s = Some(period);
        self
    }

    /// A hand holding still at `position_m`.
    pub fn holding(position_m: Vec3) -> VirtualOperator {
        VirtualOperator::new(
            vec![Waypoint {
                time_s: 0.0,
                target_m: position_m,
            }],
            200.0,
            6.0,
        )
    }

    /// No hand on the thimble (auto-initialization with an empty thimble): no spring, only a
    /// light drag of `drag_n_s_per_m` (air, the dangling terminal) against the thimble's motion.
    pub fn absent(drag_n_s_per_m: f64) -> VirtualOperator {
        VirtualOperator::new(
            vec![Waypoint {
                time_s: 0.0,
                target_m: Vec3::zeros(),
            }],
            0.0,
            drag_n_s_per_m.max(0.0),
        )
    }

    /// Touch-and-slide: approach a wall at `wall_z_m` (solid beyond it, towards `+z`) from
    /// `start_m`, press `press_depth_m` past it, then slide `slide_m` along `x` and back, over
    /// about `duration_s` seconds, pressing all the while.
    pub fn touch_and_slide(
        start_m: Vec3,
        wall_z_m: f64,
        press_depth_m: f64,
        slide_m: f64,
        duration_s: f64,
    ) -> VirtualOperator {
        let press = Vec3::new(start_m.x, start_m.y, wall_z_m + press_depth_m);
        let d = duration_s.max(1.0);
        let wp = |f: f64, p: Vec3| Waypoint {
            time_s: f * d,
            target_m: p,
        };
        VirtualOperator::new(
            vec![
                wp(0.0, start_m),
                wp(0.15, press),
                wp(0.45, press + Vec3::new(slide_m, 0.0, 0.0)),
                wp(0.75, press),
                wp(0.85, press),
            ],
            200.0,
            6.0,
        )
    }

    /// The same script, starting at simulated time `start_s` instead of 0 (e.g. after an
    /// auto-initialization has run on the twin).
    pub fn starting_at(mut self, start_s: f64) -> VirtualOperator {
        self.start_s = start_s;
        self
    }

    /// The hand target and its velocity at time `t_s`.
    pub fn target(&self, t_s: f64) -> (Vec3, Vec3) {
        let t_s = t_s - self.start_s;
        let t_s = match self.repeat_period_s {
            Some(period) if t_s > 0.0 => t_s % period,
            _ => t_s,
        };
        let w = &self.waypoints;
        if t_s <= w[0].time_s {
            return (w[0].target_m, Vec3::zeros());
        }
        for pair in w.windows(2) {
            let (a, b) = (pair[0], pair[1]);
            if t_s < b.time_s {
                let span = (b.time_s - a.time_s).max(1e-9);
                let s = (t_s - a.time_s) / span;
                let velocity = (b.target_m - a.target_m) / span;
                return (a.target_m + (b.target_m - a.target_m) * s, velocity);
            }
        }
        (w[w.len() - 1].target_m, Vec3::zeros())
    }

    /// The force of the hand on the thimble at `position_m`, `velocity_m_s`, time `t_s`.
    pub fn force_n(&self, t_s: f64, position_m: &Vec3, velocity_m_s: &Vec3) -> Vec3 {
        let (target, target_velocity) = self.target(t_s);
        let follow = (target - position_m) * self.stiffness_n_per_m
            + (target_velocity - velocity_m_s) * self.damping_n_s_per_m;
        match self.press {
            None => follow,
            Some(Press {
                direction,
                force_n,
                lift_above_n,
            }) => {
                let across = follow - direction * direction.dot(&follow);
                let lift = lift_above_n.map_or(0.0, |limit| (across.norm() - limit).max(0.0));
                let along = force_n - lift - self.damping_n_s_per_m * direction.dot(velocity_m_s);
                across + direction * along
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn path_interpolates_and_holds() {
        let op = VirtualOperator::new(
            vec![
                Waypoint {
                    time_s: 0.0,
                    target_m: Vec3::zeros(),
                },
                Waypoint {
                    time_s: 1.0,
                    target_m: Vec3::new(1.0, 0.0, 0.0),
                },
            ],
            100.0,
            0.0,
        );
        assert_eq!(op.target(0.5).0, Vec3::new(0.5, 0.0, 0.0));
        assert_eq!(op.target(0.5).1, Vec3::new(1.0, 0.0, 0.0));
        assert_eq!(op.target(7.0), (Vec3::new(1.0, 0.0, 0.0), Vec3::zeros()));
        assert_eq!(
            op.force_n(7.0, &Vec3::zeros(), &Vec3::zeros()),
            Vec3::new(100.0, 0.0, 0.0)
        );
        let looped = op.repeating(2.0);
        assert_eq!(looped.target(2.5).0, Vec3::new(0.5, 0.0, 0.0));
    }

    #[test]
    fn a_pressing_hand_pushes_along_and_follows_across() {
        let op = VirtualOperator::holding(Vec3::new(0.1, 0.0, 0.0)).pressing(Vec3::z() * 3.0, 1.5);
        // Across: the spring towards the target (200 N/m * 0.1 m); along z: the push, whatever
        // the target's z, less the damping of the motion along z (6 N s/m * 0.1 m/s).
        let f = op.force_n(0.0, &Vec3::new(0.0, 0.0, -0.2), &Vec3::new(0.0, 0.0, 0.1));
        assert!(
            (f - Vec3::new(20.0, 0.0, 1.5 - 0.6)).norm() < 1e-12,
            "{f:?}"
        );
        // Held back across by 20 N, 5 N over the limit: the push becomes a 3.5 N lift.
        let lifting = op.clone().lifting_over(15.0);
        let f = lifting.force_n(0.0, &Vec3::new(0.0, 0.0, -0.2), &Vec3::zeros());
        assert!(
            (f - Vec3::new(20.0, 0.0, 1.5 - 5.0)).norm() < 1e-12,
            "{f:?}"
        );
        let plain = VirtualOperator::holding(Vec3::zeros()).pressing(Vec3::zeros(), 1.0);
        assert_eq!(plain, VirtualOperator::holding(Vec3::zeros()));
    }
}
