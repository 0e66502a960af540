//! Projection of the desired force onto the forces the wires can make (paper section 5).
//!
//! The reachable set is `F = { V t : t_min <= t_i <= t_max }`. When `t = V^-1 f_e` has every
//! component in range the force is rendered exactly; otherwise an algorithm decides which force
//! of `F` to render.

use crate::kinematics::Rig3;
use crate::{Vec3, WIRES};

/// Tension limits of the wires.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForceLimits {
    /// Minimum tension that keeps a wire taut, newtons (> 0).
    pub t_min_n: f64,
    /// Maximum tension, newtons (the paper's device: 15 N).
    pub t_max_n: f64,
}

impl Default for ForceLimits {
    fn default() -> Self {
        ForceLimits {
            t_min_n: 0.3,
            t_max_n: 15.0,
        }
    }
}

/// Projection algorithm.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Algorithm {
    /// P1: negative tensions set to `t_min`, the positive ones actuated as computed.
    P1,
    /// P2: negative tensions set to `t_min`; the positive wires' tensions
    /// `t' = (n^T V_P)^+ |f_e|` so that the force along `n = f_e/|f_e|` is exactly `|f_e|`.
    #[default]
    P2,
}

/// The tensions chosen for a desired force, and what was lost on the way.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Distribution {
    /// Tension set-points, newtons, each within `[t_min, t_max]`.
    pub tensions_n: [f64; WIRES],
    /// The force those tensions make on the thimble, newtons.
    pub rendered_n: Vec3,
    /// True when some tension had to be clamped at `t_max`.
    pub saturated: bool,
    /// True when the desired force was outside the wires' cone (some tension came out negative).
    pub projected: bool,
}

/// Compute tension set-points for `desired_n` at `position_m` with `algorithm`.
/// Never returns NaN for finite input; where the Jacobian is singular every wire gets `t_min`.
pub fn distribute(
    rig: &Rig3,
    position_m: &Vec3,
    desired_n: &Vec3,
    algorithm: Algorithm,
    limits: &ForceLimits,
) -> Distribution {
    let v = rig.force_matrix(position_m);
    let mut out = Distribution {
        tensions_n: [limits.t_min_n; WIRES],
        ..Distribution::default()
    };
    let raw = match rig.tensions_for_force(position_m, desired_n) {
        Some(t) if t.iter().all(|x| x.is_finite()) => t,
        _ => {
            out.rendered_n = v * Vec3::from(out.tensions_n);
            return out;
        }
    };
    out.projected = raw.iter().any(|&t| t < 0.0);
    let magnitude = desired_n.norm();
    if !out.projected || magnitude < 1e-12 {
        out.tensions_n = raw;
    } else {
        match algorithm {
            Algorithm::P1 => {
                out.tensions_n = raw;
            }
            Algorithm::P2 => {
                let n = desired_n / magnitude;
                // a_i = n · (-v_i) for the positive wires, 0 for the others.
                let mut a = [0.0; WIRES];
                let mut a_sq = 0.0;
                for i in 0..WIRES {
                    if raw[i] > 0.0 {
                        a[i] = n.dot(&v.column(i).into_owned());
                        a_sq += a[i] * a[i];
                    }
                }
                for i in 0..WIRES {
                    out.tensions_n[i] = if raw[i] > 0.0 && a_sq > 1e-12 {
                        a[i] * magnitude / a_sq
                    } else {
                        limits.t_min_n
                    };
                }
            }
        }
    }
    for t in out.tensions_n.iter_mut() {
        if *t > limits.t_max_n {
            out.saturated = true;
        }
        *t = t.clamp(limits.t_min_n, limits.t_max_n);
    }
    out.rendered_n = v * Vec3::from(out.tensions_n);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rig() -> Rig3 {
        Rig3::new([
            Vec3::zeros(),
            Vec3::new(0.37, 0.0, 0.0),
            Vec3::new(0.185, 0.30, 0.0),
        ])
        .unwrap()
    }

    #[test]
    fn inside_the_cone_the_force_is_exact() {
        let p = Vec3::new(0.18, 0.1, 0.3);
        let f = Vec3::new(0.5, 0.2, -4.0);
        for alg in [Algorithm::P1, Algorithm::P2] {
            let d = distribute(&rig(), &p, &f, alg, &ForceLimits::default());
            assert!(!d.projected && !d.saturated);
            assert!((d.rendered_n - f).norm() < 1e-9, "{alg:?}");
        }
    }

    #[test]
    fn p2_renders_the_normal_component_exactly() {
        let p = Vec3::new(0.18, 0.1, 0.3);
        // Mostly sideways: outside the cone.
        let f = Vec3::new(3.0, 0.0, -0.5);
        let limits = ForceLimits {
            t_min_n: 0.0,
            t_max_n: 15.0,
        };
        let d = distribute(&rig(), &p, &f, Algorithm::P2, &limits);
        assert!(d.projected);
        let n = f.normalize();
        assert!((d.rendered_n.dot(&n) - f.norm()).abs() < 1e-9);
        let d1 = distribute(&rig(), &p, &f, Algorithm::P1, &limits);
        assert!(d1.rendered_n.dot(&n) < f.norm(), "P1 renders less along n");
    }

    #[test]
    fn limits_are_respected_and_saturation_reported() {
        let p = Vec3::new(0.18, 0.1, 0.3);
        let f = Vec3::new(0.0, 0.0, -100.0);
        let d = distribute(&rig(), &p, &f, Algorithm::P2, &ForceLimits::default());
        assert!(d.saturated);
        assert!(d.tensions_n.iter().all(|&t| (0.3..=15.0).contains(&t)));
    }
}
