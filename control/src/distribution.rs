//! Projection of the desired force onto the forces the wires can make (paper section 5).
//!
//! The reachable set is `F = { V t : t_min <= t_i <= t_max }`. When `t = J^T f` has every
//! component in range the force is rendered exactly (every algorithm); otherwise the algorithm's
//! projection decides which force of `F` to render. Every result has each tension in
//! `[t_min, t_max]`, reports saturation at `t_max`, and is finite for any input.
//!
//! The functions are generic over the number of wires `N` (2: planar device, 3: wearable device;
//! `N <= 3`), over a [`WireMap`] built by the rig.

use nalgebra::SVector;

pub use crate::algorithm::{Algorithm, FieldRule, Projection, ALGORITHM_NAMES};
use crate::kinematics::Rig3;
use crate::wire_map::WireMap;
use crate::Vec3;

/// Tension limits of the wires.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForceLimits {
    /// Minimum tension that keeps a wire taut, newtons (>= 0).
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

/// Why tension limits were refused.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LimitsError {
    /// Minimum tension given, newtons.
    pub t_min_n: f64,
    /// Maximum tension given, newtons.
    pub t_max_n: f64,
}

impl core::fmt::Display for LimitsError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "tension limits t_min = {} N, t_max = {} N: need finite 0 <= t_min <= t_max",
            self.t_min_n, self.t_max_n
        )
    }
}

impl ForceLimits {
    /// Validated limits: finite, `0 <= t_min <= t_max`.
    pub fn new(t_min_n: f64, t_max_n: f64) -> Result<ForceLimits, LimitsError> {
        if t_min_n.is_finite() && t_max_n.is_finite() && t_min_n >= 0.0 && t_min_n <= t_max_n {
            Ok(ForceLimits { t_min_n, t_max_n })
        } else {
            Err(LimitsError { t_min_n, t_max_n })
        }
    }
}

/// The tensions chosen for a target force, and what was lost on the way.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Distribution<const N: usize> {
    /// Tension set-points, newtons, each within `[t_min, t_max]`.
    pub tensions_n: [f64; N],
    /// The force those tensions make on the thimble, newtons.
    pub rendered_n: SVector<f64, N>,
    /// True when some tension had to be clamped at `t_max`.
    pub saturated: bool,
    /// True when the target was not reachable exactly (outside the wire cone, or needing a
    /// tension below `t_min` or above `t_max`).
    pub projected: bool,
}

impl<const N: usize> Default for Distribution<N> {
    fn default() -> Self {
        Distribution {
            tensions_n: [0.0; N],
            rendered_n: SVector::zeros(),
            saturated: false,
            projected: false,
        }
    }
}

/// Clamp a tension into the limits without panicking on bad limits or NaN (NaN -> `t_min`).
#[inline]
pub fn clamp_tension(t: f64, limits: &ForceLimits) -> f64 {
    let t = if t.is_nan() { limits.t_min_n } else { t };
    t.max(limits.t_min_n).min(limits.t_max_n)
}

/// Every wire at `t_min` (the safe state, or where the map is singular).
pub fn minimum_tension<const N: usize>(
    map: Option<&WireMap<N>>,
    limits: &ForceLimits,
) -> Distribution<N> {
    let t = clamp_tension(limits.t_min_n, limits);
    let tensions_n = [t; N];
    Distribution {
        tensions_n,
        rendered_n: map.map_or_else(SVector::zeros, |m| m.force(&tensions_n)),
        saturated: false,
        projected: true,
    }
}

/// Tension set-points for `target_n` (contact force plus field) with `projection`.
pub fn project<const N: usize>(
    map: &WireMap<N>,
    target_n: &SVector<f64, N>,
    projection: Projection,
    limits: &ForceLimits,
) -> Distribution<N> {
    const { assert!(N >= 1 && N <= 3, "1 to 3 wires") };
    if !target_n.iter().all(|c| c.is_finite()) {
        return minimum_tension(Some(map), limits);
    }
    let raw = map.tensions(target_n);
    let in_range = raw
        .iter()
        .all(|&t| t >= limits.t_min_n && t <= limits.t_max_n);
    let (tensions, projected) = if in_range {
        (raw, false)
    } else {
        let t = match projection {
            Projection::ClampNegative => raw,
            Projection::ExactAlongNormal => exact_along_normal(map, target_n, &raw, limits),
            Projection::NormalFirstNearest => normal_first_nearest(map, target_n, limits)
                .unwrap_or_else(|| exact_along_normal(map, target_n, &raw, limits)),
        };
        (t, true)
    };
    let mut out = Distribution {
        tensions_n: [0.0; N],
        rendered_n: SVector::zeros(),
        saturated: false,
        projected,
    };
    // Saturated: a tension was clamped at t_max, or (QP) t_max binds the chosen solution.
    let at_max = limits.t_max_n * (1.0 - 1e-12) - 1e-12;
    for (o, &t) in out.tensions_n.iter_mut().zip(tensions.iter()) {
        if t > limits.t_max_n || (projected && t >= at_max) {
            out.saturated = true;
        }
        *o = clamp_tension(t, limits);
    }
    out.rendered_n = map.force(&out.tensions_n);
    out
}

/// Paper's P2 with the tension floor accounted for. Every wire starts at `t_min`; the wires
/// whose raw tension is positive and that pull along `n` (`a_i = n·u_i > 0`) share the rest of the
/// normal force, `r = |f| - sum_k a_k t_min`, by the pseudo-inverse `(n^T V_P)^+ r`:
/// `t_i = t_min + a_i r / sum_P a_j²`. The force along `n` is then exactly `|f|`. With
/// `t_min = 0` this is the paper's `t' = (n^T V_P)^+ |f_e|` (a positive wire with `a_i <= 0` would
/// get a negative share there and is left at the floor here). When no such wire exists, or the
/// floor alone already exceeds `|f|` along `n`, every wire stays at `t_min`.
fn exact_along_normal<const N: usize>(
    map: &WireMap<N>,
    target_n: &SVector<f64, N>,
    raw: &[f64; N],
    limits: &ForceLimits,
) -> [f64; N] {
    let t_min = limits.t_min_n;
    let mut tensions = [t_min; N];
    let magnitude = target_n.norm();
    if magnitude < 1e-12 {
        return tensions;
    }
    let n = target_n / magnitude;
    let mut along = [0.0; N];
    let mut rest = magnitude;
    let mut norm_sq = 0.0;
    for i in 0..N {
        along[i] = n.dot(&map.pull_direction(i));
        rest -= along[i] * t_min;
        if raw[i] > 0.0 && along[i] > 0.0 {
            norm_sq += along[i] * along[i];
        } else {
            along[i] = 0.0;
        }
    }
    if norm_sq < 1e-12 || rest <= 0.0 {
        return tensions;
    }
    for (t, a) in tensions.iter_mut().zip(along.iter()) {
        *t += a * rest / norm_sq;
    }
    tensions
}

/// Most unknowns of a KKT system: 3 tensions and one multiplier.
const MAX_KKT: usize = 4;

/// Normal-first nearest: among the tensions in the box, those whose force along `n` equals
/// `clamp(|f|, r_min, r_max)` (the most of `|f|` the box allows), the one whose force is closest
/// to `f`. Strictly convex (V is invertible), so the optimum is the stationary point of one of
/// the `3^N` bound patterns (each wire free, at `t_min` or at `t_max`), and a stationary point
/// that satisfies the KKT sign conditions is that optimum.
///
/// Phase 1 starts from three likely patterns (the raw tensions', the paper's P2 one, the vertex
/// attaining a clamped normal goal) and pivots one wire at a time along the KKT violations, at
/// most `2N + 2` steps each; on random cases it certifies the optimum after about three small
/// solves. Phase 2, if ever needed, evaluates all `3^N` patterns and keeps the least-cost
/// feasible one. Bounded either way. `None` if no candidate was found (not expected; the caller
/// falls back to P2).
fn normal_first_nearest<const N: usize>(
    map: &WireMap<N>,
    target_n: &SVector<f64, N>,
    limits: &ForceLimits,
) -> Option<[f64; N]> {
    normal_first_nearest_search(map, target_n, limits, true)
}

/// [`normal_first_nearest`], optionally without the early return on a certified candidate
/// (tests compare the two).
fn normal_first_nearest_search<const N: usize>(
    map: &WireMap<N>,
    target_n: &SVector<f64, N>,
    limits: &ForceLimits,
    early_exit: bool,
) -> Option<[f64; N]> {
    let lo = limits.t_min_n;
    let hi = limits.t_max_n.max(lo);
    let magnitude = target_n.norm();
    let constrained = magnitude > 1e-12;
    let raw = map.tensions(target_n);
    let mut problem = NearestProblem {
        pulls: [SVector::<f64, N>::zeros(); N],
        gram: [[0.0; N]; N],
        along: [0.0; N],
        target: *target_n,
        goal: 0.0,
        lo,
        hi,
        constrained,
        tol: 1e-9 * (1.0 + magnitude + hi),
    };
    let (mut r_min, mut r_max) = (0.0, 0.0);
    for i in 0..N {
        problem.pulls[i] = map.pull_direction(i);
        if constrained {
            problem.along[i] = problem.pulls[i].dot(target_n) / magnitude;
        }
        let (a, b) = (problem.along[i] * lo, problem.along[i] * hi);
        r_min += a.min(b);
        r_max += a.max(b);
    }
    for i in 0..N {
        for j in 0..N {
            problem.gram[i][j] = problem.pulls[i].dot(&problem.pulls[j]);
        }
    }
    problem.goal = magnitude.max(r_min).min(r_max);

    // Likely patterns: from the raw tensions; the paper's P2 one (wires that cannot share the
    // normal force at the floor); and, when the normal goal is clamped, the vertex of the box
    // that attains it.
    let mut raw_guess = 0usize;
    let mut p2_guess = 0usize;
    let mut vertex_guess = 0usize;
    let at_max = constrained && problem.goal >= r_max - problem.tol;
    let at_min = constrained && problem.goal <= r_min + problem.tol;
    let mut place = 1usize;
    for i in 0..N {
        let digit = if raw[i] < lo {
            1
        } else if raw[i] > hi {
            2
        } else {
            0
        };
        raw_guess += digit * place;
        if !(raw[i] > 0.0 && problem.along[i] > 0.0) {
            p2_guess += place;
        }
        let pulls_along = problem.along[i] > 0.0;
        let vertex_digit = if at_max == pulls_along { 2 } else { 1 };
        vertex_guess += if at_max || at_min {
            vertex_digit
        } else {
            digit
        } * place;
        place *= 3;
    }
    let patterns = place;
    // Phase 1: from each guess, move wires along the KKT violations (a bounded number of steps).
    if early_exit {
        for start in [raw_guess, p2_guess, vertex_guess] {
            let mut pattern = start;
            for _step in 0..2 * N + 2 {
                let (candidate, next) = problem.solve_pattern(pattern);
                if let Some(candidate) = candidate {
                    if candidate.certified {
                        return Some(candidate.tensions);
                    }
                }
                if next == pattern {
                    break;
                }
                pattern = next;
            }
        }
    }
    // Phase 2: every pattern; the least-cost feasible candidate is the optimum.
    let mut best: Option<([f64; N], f64)> = None;
    for pattern in 0..patterns {
        if let (Some(candidate), _) = problem.solve_pattern(pattern) {
            if candidate.certified && early_exit {
                return Some(candidate.tensions);
            }
            if best.is_none_or(|(_, c)| candidate.cost < c) {
                best = Some((candidate.tensions, candidate.cost));
            }
        }
    }
    best.map(|(t, _)| t)
}

/// The data of the normal-first nearest problem.
struct NearestProblem<const N: usize> {
    pulls: [SVector<f64, N>; N],
    gram: [[f64; N]; N],
    along: [f64; N],
    target: SVector<f64, N>,
    goal: f64,
    lo: f64,
    hi: f64,
    constrained: bool,
    tol: f64,
}

/// A feasible stationary point of one bound pattern.
struct Candidate<const N: usize> {
    tensions: [f64; N],
    cost: f64,
    /// The KKT sign conditions hold: this is the optimum.
    certified: bool,
}

impl<const N: usize> NearestProblem<N> {
    /// The stationary point of `pattern` (base-3 digit per wire: 0 free, 1 at `t_min`, 2 at
    /// `t_max`) if it is feasible, and the pattern the KKT violations point to (free wires out of
    /// bounds fixed at the bound they crossed, fixed wires with the wrong multiplier sign freed;
    /// `pattern` itself when there is nothing to change).
    fn solve_pattern(&self, pattern: usize) -> (Option<Candidate<N>>, usize) {
        let mut code = pattern;
        let mut state = [0u8; N];
        let mut tensions = [0.0; N];
        let mut free = [0usize; N];
        let mut free_count = 0;
        let mut residual = self.target;
        let mut goal = self.goal;
        for i in 0..N {
            state[i] = (code % 3) as u8;
            code /= 3;
            if state[i] == 0 {
                free[free_count] = i;
                free_count += 1;
            } else {
                let t = if state[i] == 1 { self.lo } else { self.hi };
                tensions[i] = t;
                residual -= self.pulls[i] * t;
                goal -= self.along[i] * t;
            }
        }
        let use_constraint =
            self.constrained && (0..free_count).any(|k| self.along[free[k]].abs() > 1e-9);
        if self.constrained && !use_constraint && goal.abs() > self.tol {
            // The fixed wires miss the normal goal and no free wire can help: free the fixed wire
            // that moves the normal force most towards the goal.
            let mut next = pattern;
            let mut best_along = 1e-9;
            for i in 0..N {
                let helps = match state[i] {
                    1 => self.along[i] * goal,
                    2 => -self.along[i] * goal,
                    _ => continue,
                };
                if helps > 0.0 && self.along[i].abs() > best_along {
                    best_along = self.along[i].abs();
                    next = pattern - usize::from(state[i]) * pow3(i);
                }
            }
            return (None, next);
        }
        let mut multiplier = None;
        if !self.constrained {
            multiplier = Some(0.0);
        }
        if free_count > 0 {
            // Stationary point of |sum_k u_k t_k - residual|² (+ lambda (a·t - goal)).
            let size = free_count + usize::from(use_constraint);
            let mut m = [[0.0; MAX_KKT + 1]; MAX_KKT];
            for r in 0..free_count {
                for c in 0..free_count {
                    m[r][c] = self.gram[free[r]][free[c]];
                }
                m[r][size] = self.pulls[free[r]].dot(&residual);
                if use_constraint {
                    m[r][free_count] = self.along[free[r]];
                    m[free_count][r] = self.along[free[r]];
                }
            }
            if use_constraint {
                m[free_count][size] = goal;
            }
            let Some(solution) = solve_in_place(&mut m, size) else {
                return (None, pattern);
            };
            // One pivot at a time (the free wire furthest out of its bounds), which avoids the
            // cycling of fixing every violator at once.
            let mut next = pattern;
            let mut worst = self.tol;
            for k in 0..free_count {
                let t = solution[k];
                if t.is_nan() {
                    return (None, pattern);
                }
                let (excess, digit) = if t < self.lo {
                    (self.lo - t, 1)
                } else {
                    (t - self.hi, 2)
                };
                if excess > worst {
                    worst = excess;
                    next = pattern + digit * pow3(free[k]);
                }
                tensions[free[k]] = t.max(self.lo).min(self.hi);
            }
            if next != pattern {
                return (None, next);
            }
            if use_constraint {
                multiplier = Some(solution[free_count]);
            }
        }
        let mut err = -self.target;
        for i in 0..N {
            err += self.pulls[i] * tensions[i];
        }
        // KKT signs of the fixed wires: at t_min the Lagrangian must not decrease with t_i, at
        // t_max it must not increase.
        // KKT signs of the fixed wires: at t_min the Lagrangian must not decrease with t_i, at
        // t_max it must not increase. Without a free wire carrying the normal goal the multiplier
        // is any value that satisfies every sign condition, if one exists.
        let lambda = match multiplier {
            Some(lambda) => lambda,
            None => {
                let (mut lambda_lo, mut lambda_hi) = (f64::NEG_INFINITY, f64::INFINITY);
                for i in 0..N {
                    let sign = match state[i] {
                        1 => 1.0,
                        2 => -1.0,
                        _ => continue,
                    };
                    // sign (g + lambda a) >= 0; the bounds make the slope exactly 0, the sign
                    // check below allows the tolerance.
                    let (g, a) = (sign * self.pulls[i].dot(&err), sign * self.along[i]);
                    if a > 1e-12 {
                        lambda_lo = lambda_lo.max(-g / a);
                    } else if a < -1e-12 {
                        lambda_hi = lambda_hi.min(-g / a);
                    }
                }
                match (lambda_lo.is_finite(), lambda_hi.is_finite()) {
                    (true, true) => 0.5 * (lambda_lo + lambda_hi),
                    (true, false) => lambda_lo,
                    (false, true) => lambda_hi,
                    (false, false) => 0.0,
                }
            }
        };
        // Free the fixed wire whose multiplier has the most wrong sign.
        let mut next = pattern;
        let mut worst = self.tol;
        for i in 0..N {
            let slope = self.pulls[i].dot(&err) + lambda * self.along[i];
            let wrong = match state[i] {
                1 => -slope,
                2 => slope,
                _ => continue,
            };
            if wrong > worst {
                worst = wrong;
                next = pattern - usize::from(state[i]) * pow3(i);
            }
        }
        let certified = next == pattern;
        (
            Some(Candidate {
                tensions,
                cost: err.norm_squared(),
                certified,
            }),
            next,
        )
    }
}

/// `3^i`.
fn pow3(i: usize) -> usize {
    let mut p = 1;
    for _ in 0..i {
        p *= 3;
    }
    p
}

/// Gaussian elimination with partial pivoting on an augmented `size x (size+1)` system stored
/// in `m` (right-hand side in column `size`). `None` when (nearly) singular.
fn solve_in_place(m: &mut [[f64; MAX_KKT + 1]; MAX_KKT], size: usize) -> Option<[f64; MAX_KKT]> {
    let mut scale = 0.0f64;
    for row in m.iter().take(size) {
        for v in row.iter().take(size) {
            scale = scale.max(v.abs());
        }
    }
    let eps = 1e-12 * scale.max(1e-300);
    for col in 0..size {
        let mut pivot = col;
        for r in col + 1..size {
            if m[r][col].abs() > m[pivot][col].abs() {
                pivot = r;
            }
        }
        if m[pivot][col].is_nan() || m[pivot][col].abs() <= eps {
            return None;
        }
        m.swap(col, pivot);
        for r in col + 1..size {
            let factor = m[r][col] / m[col][col];
            for c in col..=size {
                m[r][c] -= factor * m[col][c];
            }
        }
    }
    let mut x = [0.0; MAX_KKT];
    for r in (0..size).rev() {
        let mut acc = m[r][size];
        for c in r + 1..size {
            acc -= m[r][c] * x[c];
        }
        x[r] = acc / m[r][r];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// Tension set-points for `desired_n` at `position_m` of a three-wire rig with the algorithm's
/// projection (no field: see [`crate::field`]). Where the Jacobian is singular every wire gets
/// `t_min`. Never NaN for finite input.
pub fn distribute(
    rig: &Rig3,
    position_m: &Vec3,
    desired_n: &Vec3,
    algorithm: Algorithm,
    limits: &ForceLimits,
) -> Distribution<3> {
    match rig.wire_map(position_m) {
        Some(map) => project(&map, desired_n, algorithm.projection(), limits),
        None => minimum_tension(None, limits),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::planar::{RigPlanar, Vec2};
    use crate::v_index;
    use proptest::prelude::*;

    fn rig() -> Rig3 {
        Rig3::paper_frame()
    }

    fn no_floor() -> ForceLimits {
        ForceLimits {
            t_min_n: 0.0,
            t_max_n: 15.0,
        }
    }

    /// The prototype at x = z = 0.26: pulls u0 = (-1,-1)/√2, u1 = (1,-1)/√2.
    fn prototype_map() -> WireMap<2> {
        RigPlanar::paper_prototype()
            .wire_map(&Vec2::new(0.26, 0.26))
            .unwrap()
    }

    #[test]
    fn inside_the_cone_the_force_is_exact() {
        let p = Vec3::new(0.18, 0.1, 0.3);
        let f = Vec3::new(0.5, 0.2, -4.0);
        for alg in Algorithm::ALL {
            let d = distribute(&rig(), &p, &f, alg, &ForceLimits::default());
            assert!(!d.projected && !d.saturated);
            assert!((d.rendered_n - f).norm() < 1e-9, "{alg:?}");
        }
    }

    #[test]
    fn hand_computed_planar_cases() {
        let map = prototype_map();
        let s = core::f64::consts::FRAC_1_SQRT_2;
        // f = (1, 0): t = J^T f = V^T f = (-s, s): wire 1 positive, wire 0 negative.
        let f = Vec2::new(1.0, 0.0);
        let limits = no_floor();
        // P1: t = (0, s), f = s (s, -s) = (0.5, -0.5); V = 0.5.
        let d1 = project(&map, &f, Projection::ClampNegative, &limits);
        assert!((d1.tensions_n[0]).abs() < 1e-12 && (d1.tensions_n[1] - s).abs() < 1e-12);
        assert!((d1.rendered_n - Vec2::new(0.5, -0.5)).norm() < 1e-12);
        assert!((v_index(&d1.rendered_n, &f) - 0.5).abs() < 1e-12);
        // P2: n·u1 = s  =>  t1 = 1/s = √2, f = (1, -1): along n exactly 1; V = 1.
        let d2 = project(&map, &f, Projection::ExactAlongNormal, &limits);
        assert!((d2.tensions_n[1] - core::f64::consts::SQRT_2).abs() < 1e-12);
        assert!((d2.rendered_n - Vec2::new(1.0, -1.0)).norm() < 1e-12);
        // QP: along n exactly 1 and nearest; with t0 >= 0 only (1, -1) is possible: same as P2.
        let dq = project(&map, &f, Projection::NormalFirstNearest, &limits);
        assert!((dq.rendered_n - d2.rendered_n).norm() < 1e-9);
        // With t_min = 0.5 on both wires, P2 still renders 1 N along n:
        // t1 = t_min + (1 - (n·u0 + n·u1) t_min) / (n·u1) = 0.5 + 1/s.
        let floor = ForceLimits {
            t_min_n: 0.5,
            t_max_n: 15.0,
        };
        let d = project(&map, &f, Projection::ExactAlongNormal, &floor);
        assert!((d.tensions_n[1] - (0.5 + 1.0 / s)).abs() < 1e-12);
        assert_eq!(d.tensions_n[0], 0.5);
        assert!((d.rendered_n.dot(&f) - 1.0).abs() < 1e-12);
        // Straight up (region C): no wire can pull; every algorithm holds t_min.
        for p in [
            Projection::ClampNegative,
            Projection::ExactAlongNormal,
            Projection::NormalFirstNearest,
        ] {
            let d = project(&map, &Vec2::new(0.0, 2.0), p, &floor);
            assert!(
                d.tensions_n.iter().all(|t| (t - 0.5).abs() < 1e-12),
                "{p:?}"
            );
        }
    }

    #[test]
    fn qp_trades_tangential_error_for_nothing_along_n() {
        // A spatial case where P2 adds a large sideways force and QP finds a closer one.
        let p = Vec3::new(0.18, 0.1, 0.3);
        let f = Vec3::new(3.0, 0.5, -0.5);
        let limits = ForceLimits {
            t_min_n: 0.2,
            t_max_n: 15.0,
        };
        let map = rig().wire_map(&p).unwrap();
        let d2 = project(&map, &f, Projection::ExactAlongNormal, &limits);
        let dq = project(&map, &f, Projection::NormalFirstNearest, &limits);
        let n = f.normalize();
        assert!((dq.rendered_n.dot(&n) - f.norm()).abs() < 1e-9);
        assert!((d2.rendered_n.dot(&n) - f.norm()).abs() < 1e-9);
        assert!((dq.rendered_n - f).norm() <= (d2.rendered_n - f).norm() + 1e-12);
    }

    #[test]
    fn limits_are_respected_and_saturation_reported() {
        let p = Vec3::new(0.18, 0.1, 0.3);
        let f = Vec3::new(0.0, 0.0, -100.0);
        for alg in Algorithm::ALL {
            let d = distribute(&rig(), &p, &f, alg, &ForceLimits::default());
            assert!(d.saturated, "{alg:?}");
            assert!(d.tensions_n.iter().all(|&t| (0.3..=15.0).contains(&t)));
        }
        // Bad limits (t_min > t_max) or NaN input never panic nor produce NaN.
        let bad = ForceLimits {
            t_min_n: 5.0,
            t_max_n: 1.0,
        };
        let d = distribute(
            &rig(),
            &p,
            &Vec3::new(f64::NAN, 0.0, 1.0),
            Algorithm::Qp,
            &bad,
        );
        assert!(d.tensions_n.iter().all(|t| t.is_finite()));
        assert!(ForceLimits::new(5.0, 1.0).is_err() && ForceLimits::new(0.0, 15.0).is_ok());
    }

    fn limits_strategy() -> impl Strategy<Value = ForceLimits> {
        (0.0f64..1.0, 2.0f64..20.0).prop_map(|(t_min_n, t_max_n)| ForceLimits { t_min_n, t_max_n })
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 1024, rng_seed: proptest::test_runner::RngSeed::Fixed(42), ..ProptestConfig::default() })]

        #[test]
        fn setpoints_stay_in_limits_and_finite(
            x in -0.3f64..0.7, y in -0.3f64..0.6, z in -0.1f64..0.8,
            fx in -1e3f64..1e3, fy in -1e3f64..1e3, fz in -1e3f64..1e3,
            limits in limits_strategy(), alg in 0usize..5,
        ) {
            let d = distribute(&rig(), &Vec3::new(x, y, z), &Vec3::new(fx, fy, fz), Algorithm::ALL[alg], &limits);
            for &t in &d.tensions_n {
                prop_assert!(t.is_finite());
                prop_assert!(t >= limits.t_min_n && t <= limits.t_max_n, "{t} outside {limits:?}");
            }
            prop_assert!(d.rendered_n.iter().all(|c| c.is_finite()));
        }

        #[test]
        fn inside_the_cone_every_algorithm_is_exact(
            x in 0.05f64..0.32, y in 0.03f64..0.25, z in 0.05f64..0.6,
            t0 in 0.5f64..10.0, t1 in 0.5f64..10.0, t2 in 0.5f64..10.0, alg in 0usize..5,
        ) {
            let p = Vec3::new(x, y, z);
            let map = rig().wire_map(&p).unwrap();
            let f = map.force(&[t0, t1, t2]);
            let d = project(&map, &f, Algorithm::ALL[alg].projection(), &ForceLimits { t_min_n: 0.4, t_max_n: 15.0 });
            prop_assert!(!d.projected);
            prop_assert!((v_index(&d.rendered_n, &f) - 1.0).abs() < 1e-9);
            prop_assert!((d.rendered_n - f).norm() < 1e-9);
        }

        #[test]
        fn p2_is_exact_along_n_when_a_positive_wire_pulls_along_it(
            x in -0.2f64..0.6, y in -0.2f64..0.5, z in 0.05f64..0.6,
            fx in -10.0f64..10.0, fy in -10.0f64..10.0, fz in -10.0f64..10.0, t_min in 0.0f64..0.5,
        ) {
            let p = Vec3::new(x, y, z);
            let f = Vec3::new(fx, fy, fz);
            prop_assume!(f.norm() > 1e-3);
            let limits = ForceLimits { t_min_n: t_min, t_max_n: 1e6 };
            let map = rig().wire_map(&p).unwrap();
            let raw = map.tensions(&f);
            let n = f.normalize();
            let along: [f64; 3] = core::array::from_fn(|i| n.dot(&map.pull_direction(i)));
            // Exactness is possible with the positive wires when one of them pulls along n and
            // the floor of the others does not already overshoot.
            let pulls_along = (0..3).any(|i| raw[i] > 0.0 && along[i] > 1e-3);
            let floor_along: f64 = (0..3).map(|i| along[i] * t_min).sum();
            prop_assume!(pulls_along && floor_along < f.norm() - 1e-9);
            let d = project(&map, &f, Projection::ExactAlongNormal, &limits);
            prop_assert!(!d.saturated);
            prop_assert!((d.rendered_n.dot(&n) - f.norm()).abs() < 1e-9 * (1.0 + f.norm()),
                "along n {} vs {}", d.rendered_n.dot(&n), f.norm());
        }

        #[test]
        fn p2_without_floor_is_exact_whenever_a_wire_has_positive_tension(
            x in -0.3f64..0.7, y in -0.3f64..0.6, z in 0.02f64..0.8,
            fx in -10.0f64..10.0, fy in -10.0f64..10.0, fz in -10.0f64..10.0,
        ) {
            let p = Vec3::new(x, y, z);
            let f = Vec3::new(fx, fy, fz);
            prop_assume!(f.norm() > 1e-3);
            let Some(map) = rig().wire_map(&p) else { return Ok(()) };
            let raw = map.tensions(&f);
            let n = f.normalize();
            // A positive wire must also pull along n: at (0, -0.26, 0.02) a force along -y has
            // two positive raw tensions, yet no wire can pull along -y at all.
            prop_assume!((0..3).any(|i| raw[i] > 0.0 && n.dot(&map.pull_direction(i)) > 0.0));
            let d = project(&map, &f, Projection::ExactAlongNormal, &ForceLimits { t_min_n: 0.0, t_max_n: 1e9 });
            prop_assert!(!d.saturated);
            prop_assert!((d.rendered_n.dot(&n) - f.norm()).abs() < 1e-9 * (1.0 + f.norm()),
                "along n {} vs {} raw {raw:?}", d.rendered_n.dot(&n), f.norm());
        }

        #[test]
        fn qp_certificate_returns_the_exhaustive_optimum(
            x in -0.2f64..0.6, y in -0.2f64..0.5, z in 0.05f64..0.6,
            fx in -20.0f64..20.0, fy in -20.0f64..20.0, fz in -20.0f64..20.0,
            limits in limits_strategy(),
        ) {
            let p = Vec3::new(x, y, z);
            let f = Vec3::new(fx, fy, fz);
            let map = rig().wire_map(&p).unwrap();
            let fast = normal_first_nearest_search(&map, &f, &limits, true).unwrap();
            let full = normal_first_nearest_search(&map, &f, &limits, false).unwrap();
            let cost = |t: &[f64; 3]| (map.force(t) - f).norm();
            prop_assert!(cost(&fast) <= cost(&full) + 1e-7, "{fast:?} vs {full:?}");
            let n = f.normalize();
            prop_assert!((map.force(&fast).dot(&n) - map.force(&full).dot(&n)).abs() < 1e-7);
        }

        #[test]
        fn qp_is_never_worse_than_the_paper_projections(
            x in -0.2f64..0.6, y in -0.2f64..0.5, z in 0.05f64..0.6,
            fx in -20.0f64..20.0, fy in -20.0f64..20.0, fz in -20.0f64..20.0,
            limits in limits_strategy(),
        ) {
            let p = Vec3::new(x, y, z);
            let f = Vec3::new(fx, fy, fz);
            prop_assume!(f.norm() > 1e-3);
            let map = rig().wire_map(&p).unwrap();
            let q = project(&map, &f, Projection::NormalFirstNearest, &limits);
            let miss = |d: &Distribution<3>| (1.0 - v_index(&d.rendered_n, &f)).abs();
            for other in [Projection::ClampNegative, Projection::ExactAlongNormal] {
                let o = project(&map, &f, other, &limits);
                prop_assert!(miss(&q) <= miss(&o) + 1e-9, "{other:?}: V {} vs {}", v_index(&q.rendered_n, &f), v_index(&o.rendered_n, &f));
                if other == Projection::ExactAlongNormal && (v_index(&o.rendered_n, &f) - 1.0).abs() < 1e-9 {
                    prop_assert!((q.rendered_n - f).norm() <= (o.rendered_n - f).norm() + 1e-9);
                }
            }
        }
    }
}
