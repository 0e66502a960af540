//! The small quadratic programmes of the force distribution: minimise `½ tᵀ H t − gᵀ t` over
//! a box `lo <= t_i <= hi` for `N <= 3` unknowns, with `H` symmetric positive definite.
//!
//! Strictly convex over a fixed box, such a programme has exactly one minimiser, and it moves
//! continuously with `H` and `g` (the reason the projections are written this way: the tensions
//! then have no jumps, whatever the pose and the force). The minimiser is the stationary point
//! of one bound pattern (each unknown free, at `lo` or at `hi`) that satisfies the KKT sign
//! conditions. The solver starts from the pattern of the clamped unconstrained minimiser and
//! pivots one unknown at a time along the violations (at most `2N + 2` steps, about two small
//! solves on the cases of the control loop); if that ever fails to certify, it evaluates every
//! one of the `3^N` patterns. Bounded either way, allocation-free, finite for finite input.

/// Most unknowns.
pub(crate) const MAX_UNKNOWNS: usize = 3;

/// A box-constrained strictly convex quadratic programme.
#[derive(Debug, Clone, Copy)]
pub(crate) struct BoxQp<const N: usize> {
    /// The Hessian `H` (symmetric positive definite).
    pub hessian: [[f64; N]; N],
    /// The linear term `g` (the objective is `½ tᵀ H t − gᵀ t`).
    pub linear: [f64; N],
    /// Lower bound of every unknown.
    pub lo: f64,
    /// Upper bound of every unknown (`>= lo`).
    pub hi: f64,
}

/// What a bound pattern's stationary point says.
enum PatternResult<const N: usize> {
    /// Feasible and KKT-certified: the minimiser.
    Optimal([f64; N]),
    /// Feasible but not optimal: the pattern the worst sign violation points to.
    Feasible([f64; N], usize),
    /// Not feasible (or singular): the pattern the worst bound violation points to.
    Infeasible(usize),
}

impl<const N: usize> BoxQp<N> {
    /// The minimiser. Every component is within `[lo, hi]` and finite (the midpoint of the box
    /// for a programme with non-finite data).
    pub fn solve(&self) -> [f64; N] {
        const { assert!(N >= 1 && N <= MAX_UNKNOWNS, "1 to 3 unknowns") };
        let finite = self.linear.iter().all(|v| v.is_finite())
            && self.hessian.iter().flatten().all(|v| v.is_finite())
            && self.lo.is_finite()
            && self.hi.is_finite()
            && self.lo <= self.hi;
        if !finite {
            let mid = if self.lo.is_finite() && self.hi.is_finite() && self.lo <= self.hi {
                0.5 * (self.lo + self.hi)
            } else {
                0.0
            };
            return [mid; N];
        }
        // Start from the clamped unconstrained minimiser's pattern.
        let mut pattern = 0usize;
        if let Some(free) = self.solve_pattern_system(0) {
            let mut place = 1;
            for v in free {
                if v < self.lo {
                    pattern += place;
                } else if v > self.hi {
                    pattern += 2 * place;
                }
                place *= 3;
            }
        }
        let mut best: Option<([f64; N], f64)> = None;
        for _step in 0..2 * N + 2 {
            let next = match self.evaluate(pattern) {
                PatternResult::Optimal(t) => return t,
                PatternResult::Feasible(t, next) => {
                    self.keep_best(&mut best, t);
                    next
                }
                PatternResult::Infeasible(next) => next,
            };
            if next == pattern {
                break;
            }
            pattern = next;
        }
        // Every pattern (not expected on the control path; bounded).
        for pattern in 0..pow3(N) {
            match self.evaluate(pattern) {
                PatternResult::Optimal(t) => return t,
                PatternResult::Feasible(t, _) => self.keep_best(&mut best, t),
                PatternResult::Infeasible(_) => {}
            }
        }
        match best {
            Some((t, _)) => t,
            None => {
                // Round-off left no pattern feasible: the clamped unconstrained point.
                let t = self.solve_pattern_system(0).unwrap_or([self.lo; N]);
                t.map(|v| v.max(self.lo).min(self.hi))
            }
        }
    }

    fn keep_best(&self, best: &mut Option<([f64; N], f64)>, t: [f64; N]) {
        let cost = self.objective(&t);
        if best.is_none_or(|(_, c)| cost < c) {
            *best = Some((t, cost));
        }
    }

    /// `½ tᵀ H t − gᵀ t`.
    pub fn objective(&self, t: &[f64; N]) -> f64 {
        let mut v = 0.0;
        for i in 0..N {
            let mut row = 0.0;
            for j in 0..N {
                row += self.hessian[i][j] * t[j];
            }
            v += t[i] * (0.5 * row - self.linear[i]);
        }
        v
    }

    /// The unknowns of `pattern`: the fixed ones at their bound, the free ones at the stationary
    /// point of the rest. `None` when the free block is singular.
    fn solve_pattern_system(&self, pattern: usize) -> Option<[f64; N]> {
        let mut state = [0u8; N];
        let mut code = pattern;
        let mut t = [0.0; N];
        let mut free = [0usize; MAX_UNKNOWNS];
        let mut free_count = 0;
        for i in 0..N {
            state[i] = (code % 3) as u8;
            code /= 3;
            match state[i] {
                0 => {
                    free[free_count] = i;
                    free_count += 1;
                }
                1 => t[i] = self.lo,
                _ => t[i] = self.hi,
            }
        }
        if free_count == 0 {
            return Some(t);
        }
        let mut m = [[0.0; MAX_UNKNOWNS + 1]; MAX_UNKNOWNS];
        for r in 0..free_count {
            let i = free[r];
            let mut rhs = self.linear[i];
            for j in 0..N {
                if state[j] != 0 {
                    rhs -= self.hessian[i][j] * t[j];
                }
            }
            for c in 0..free_count {
                m[r][c] = self.hessian[i][free[c]];
            }
            m[r][free_count] = rhs;
        }
        let x = solve_in_place(&mut m, free_count)?;
        for k in 0..free_count {
            t[free[k]] = x[k];
        }
        Some(t)
    }

    fn evaluate(&self, pattern: usize) -> PatternResult<N> {
        let tol = 1e-12 * (1.0 + self.lo.abs() + self.hi.abs());
        let Some(t) = self.solve_pattern_system(pattern) else {
            return PatternResult::Infeasible(pattern);
        };
        let mut state = [0u8; N];
        let mut code = pattern;
        for s in state.iter_mut() {
            *s = (code % 3) as u8;
            code /= 3;
        }
        // A free unknown out of the box: fix the worst at the bound it crossed.
        let mut worst = tol;
        let mut next = pattern;
        for i in 0..N {
            if state[i] != 0 {
                continue;
            }
            if self.lo - t[i] > worst {
                worst = self.lo - t[i];
                next = pattern + pow3(i);
            } else if t[i] - self.hi > worst {
                worst = t[i] - self.hi;
                next = pattern + 2 * pow3(i);
            }
        }
        if next != pattern {
            return PatternResult::Infeasible(next);
        }
        let t = t.map(|v| v.max(self.lo).min(self.hi));
        // A fixed unknown whose gradient would lower the objective inside the box: free it.
        let scale = 1.0
            + self
                .linear
                .iter()
                .chain(self.hessian.iter().flatten())
                .fold(0.0f64, |m, v| m.max(v.abs()))
                * (1.0 + self.hi.abs());
        let mut worst = 1e-12 * scale;
        for i in 0..N {
            let mut gradient = -self.linear[i];
            for j in 0..N {
                gradient += self.hessian[i][j] * t[j];
            }
            let wrong = match state[i] {
                1 => -gradient,
                2 => gradient,
                _ => continue,
            };
            if wrong > worst {
                worst = wrong;
                next = pattern - usize::from(state[i]) * pow3(i);
            }
        }
        if next == pattern {
            PatternResult::Optimal(t)
        } else {
            PatternResult::Feasible(t, next)
        }
    }
}

/// `3^i`.
pub(crate) fn pow3(i: usize) -> usize {
    let mut p = 1;
    for _ in 0..i {
        p *= 3;
    }
    p
}

/// Gaussian elimination with partial pivoting on an augmented `size x (size+1)` system stored
/// in `m` (right-hand side in column `size`). `None` when (nearly) singular.
fn solve_in_place(
    m: &mut [[f64; MAX_UNKNOWNS + 1]; MAX_UNKNOWNS],
    size: usize,
) -> Option<[f64; MAX_UNKNOWNS]> {
    let mut scale = 0.0f64;
    for row in m.iter().take(size) {
        for v in row.iter().take(size) {
            scale = scale.max(v.abs());
        }
    }
    let eps = 1e-14 * scale.max(1e-300);
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
    let mut x = [0.0; MAX_UNKNOWNS];
    for r in (0..size).rev() {
        let mut acc = m[r][size];
        for c in r + 1..size {
            acc -= m[r][c] * x[c];
        }
        x[r] = acc / m[r][r];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The minimiser by brute force: the least objective over every feasible pattern point.
    fn exhaustive<const N: usize>(qp: &BoxQp<N>) -> [f64; N] {
        let mut best = ([0.0; N], f64::INFINITY);
        for pattern in 0..pow3(N) {
            if let Some(t) = qp.solve_pattern_system(pattern) {
                if t.iter().all(|&v| v >= qp.lo - 1e-9 && v <= qp.hi + 1e-9) {
                    let c = qp.objective(&t);
                    if c < best.1 {
                        best = (t, c);
                    }
                }
            }
        }
        best.0
    }

    #[test]
    fn an_interior_minimiser_is_returned_as_it_is() {
        let qp = BoxQp::<2> {
            hessian: [[2.0, 0.0], [0.0, 2.0]],
            linear: [2.0, 4.0],
            lo: 0.0,
            hi: 10.0,
        };
        assert_eq!(qp.solve(), [1.0, 2.0]);
        let clamped = BoxQp::<2> { hi: 1.5, ..qp };
        assert_eq!(clamped.solve(), [1.0, 1.5]);
    }

    #[test]
    fn non_finite_data_gives_the_box_midpoint() {
        let qp = BoxQp::<1> {
            hessian: [[f64::NAN]],
            linear: [1.0],
            lo: 1.0,
            hi: 3.0,
        };
        assert_eq!(qp.solve(), [2.0]);
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 2000, rng_seed: proptest::test_runner::RngSeed::Fixed(7), ..ProptestConfig::default() })]

        #[test]
        fn the_solver_finds_the_exhaustive_minimiser(
            m in proptest::array::uniform9(-3.0f64..3.0), g in proptest::array::uniform3(-50.0f64..50.0),
            lo in 0.0f64..1.0, width in 0.5f64..20.0, ridge in 1e-3f64..2.0,
        ) {
            // H = Mᵀ M + ridge I: symmetric positive definite.
            let mut h = [[0.0; 3]; 3];
            for i in 0..3 {
                for j in 0..3 {
                    for k in 0..3 {
                        h[i][j] += m[3 * k + i] * m[3 * k + j];
                    }
                }
                h[i][i] += ridge;
            }
            let qp = BoxQp::<3> { hessian: h, linear: g, lo, hi: lo + width };
            let fast = qp.solve();
            let full = exhaustive(&qp);
            prop_assert!(fast.iter().all(|&v| v >= lo && v <= lo + width));
            prop_assert!(qp.objective(&fast) <= qp.objective(&full) + 1e-9 * (1.0 + qp.objective(&full).abs()),
                "{fast:?} vs {full:?}");
        }
    }
}
