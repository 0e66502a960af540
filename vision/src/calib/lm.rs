//! A dense Levenberg–Marquardt least-squares solver with central-difference Jacobians.
//!
//! The calibration problems are small (at most a few hundred parameters, a few thousand
//! residuals), so a dense normal-equation solve with Marquardt's diagonal scaling is both simple
//! and fast enough.

use nalgebra::{DMatrix, DVector};

/// A nonlinear least-squares problem `min_p |r(p)|^2`.
pub trait Residuals {
    /// Number of parameters.
    fn num_params(&self) -> usize;
    /// Number of residuals.
    fn num_residuals(&self) -> usize;
    /// Evaluate the residuals at `params` into `out` (length [`Self::num_residuals`]).
    fn evaluate(&self, params: &[f64], out: &mut [f64]);
    /// Which residual rows parameter `index` can change (`None`: all). Lets the numeric Jacobian
    /// skip rows known to be zero.
    fn affected_rows(&self, _index: usize) -> Option<std::ops::Range<usize>> {
        None
    }
    /// Evaluate only the residual rows `rows` (as returned by [`Self::affected_rows`]) into
    /// `out` (length `rows.len()`). The default evaluates everything and copies.
    fn evaluate_rows(&self, params: &[f64], rows: std::ops::Range<usize>, out: &mut [f64]) {
        let mut all = vec![0.0; self.num_residuals()];
        self.evaluate(params, &mut all);
        out.copy_from_slice(&all[rows]);
    }
}

/// Solver settings.
#[derive(Debug, Clone, Copy)]
pub struct LmSettings {
    /// Maximum number of accepted or rejected steps.
    pub max_iterations: usize,
    /// Stop when the relative decrease of the cost falls below this.
    pub cost_tolerance: f64,
    /// Stop when the step is this small relative to the parameters.
    pub step_tolerance: f64,
}

impl Default for LmSettings {
    fn default() -> Self {
        LmSettings {
            max_iterations: 200,
            cost_tolerance: 1e-14,
            step_tolerance: 1e-12,
        }
    }
}

/// Outcome of a solve.
#[derive(Debug, Clone)]
pub struct LmOutcome {
    /// Final sum of squared residuals.
    pub cost: f64,
    /// Iterations performed.
    pub iterations: usize,
}

/// A Jacobian stored by column, each column only over the rows its parameter can change.
pub struct SparseColumns {
    /// Number of residual rows.
    pub rows: usize,
    /// Per parameter: the first row and the derivative values of the rows that follow.
    pub columns: Vec<(usize, Vec<f64>)>,
}

impl SparseColumns {
    /// `J^T J` and `J^T r`.
    pub fn normal_equations(&self, r: &[f64]) -> (DMatrix<f64>, DVector<f64>) {
        let n = self.columns.len();
        let mut jtj = DMatrix::<f64>::zeros(n, n);
        let mut g = DVector::<f64>::zeros(n);
        for a in 0..n {
            let (sa, ca) = (&self.columns[a].0, &self.columns[a].1);
            g[a] = ca
                .iter()
                .zip(&r[*sa..sa + ca.len()])
                .map(|(x, y)| x * y)
                .sum();
            for b in a..n {
                let (sb, cb) = (&self.columns[b].0, &self.columns[b].1);
                let lo = (*sa).max(*sb);
                let hi = (sa + ca.len()).min(sb + cb.len());
                if lo >= hi {
                    continue;
                }
                let dot: f64 = ca[lo - sa..hi - sa]
                    .iter()
                    .zip(&cb[lo - sb..hi - sb])
                    .map(|(x, y)| x * y)
                    .sum();
                jtj[(a, b)] = dot;
                jtj[(b, a)] = dot;
            }
        }
        (jtj, g)
    }

    /// The dense matrix (for tests and diagnostics).
    pub fn to_dense(&self) -> DMatrix<f64> {
        let mut m = DMatrix::<f64>::zeros(self.rows, self.columns.len());
        for (j, (start, col)) in self.columns.iter().enumerate() {
            for (k, v) in col.iter().enumerate() {
                m[(start + k, j)] = *v;
            }
        }
        m
    }
}

/// Central-difference Jacobian of `problem` at `params`; each parameter is stepped by
/// `1e-6 * max(|p|, 0.01)`.
pub fn numeric_jacobian<P: Residuals>(problem: &P, params: &[f64]) -> SparseColumns {
    let m = problem.num_residuals();
    let n = problem.num_params();
    let mut p = params.to_vec();
    let mut columns = Vec::with_capacity(n);
    for j in 0..n {
        let rows = problem.affected_rows(j).unwrap_or(0..m);
        let mut plus = vec![0.0; rows.len()];
        let mut minus = vec![0.0; rows.len()];
        let h = 1e-6 * params[j].abs().max(1e-2);
        let orig = p[j];
        p[j] = orig + h;
        problem.evaluate_rows(&p, rows.clone(), &mut plus);
        p[j] = orig - h;
        problem.evaluate_rows(&p, rows.clone(), &mut minus);
        p[j] = orig;
        let inv = 1.0 / (2.0 * h);
        for (a, b) in plus.iter_mut().zip(&minus) {
            *a = (*a - b) * inv;
        }
        columns.push((rows.start, plus));
    }
    SparseColumns { rows: m, columns }
}

/// Minimise `problem` from `params` (updated in place). Fails when the residuals are not finite
/// at the start.
pub fn solve<P: Residuals>(
    problem: &P,
    params: &mut [f64],
    settings: LmSettings,
) -> Result<LmOutcome, String> {
    let m = problem.num_residuals();
    let n = problem.num_params();
    let mut r = vec![0.0; m];
    problem.evaluate(params, &mut r);
    let mut cost = sum_sq(&r);
    if !cost.is_finite() {
        return Err("residuals are not finite at the initial estimate".into());
    }
    let mut lambda = 1e-3;
    let mut trial = vec![0.0; n];
    let mut trial_r = vec![0.0; m];
    let mut iterations = 0;
    'outer: while iterations < settings.max_iterations {
        let (jtj, g) = numeric_jacobian(problem, params).normal_equations(&r);
        loop {
            iterations += 1;
            let mut a = jtj.clone();
            for i in 0..n {
                let d = jtj[(i, i)].max(1e-12);
                a[(i, i)] += lambda * d;
            }
            let Some(chol) = a.cholesky() else {
                lambda *= 10.0;
                if lambda > 1e16 || iterations >= settings.max_iterations {
                    break 'outer;
                }
                continue;
            };
            let delta = chol.solve(&(-&g));
            for i in 0..n {
                trial[i] = params[i] + delta[i];
            }
            problem.evaluate(&trial, &mut trial_r);
            let trial_cost = sum_sq(&trial_r);
            if trial_cost.is_finite() && trial_cost < cost {
                let rel_decrease = (cost - trial_cost) / cost.max(1e-300);
                let step =
                    delta.norm() / (params.iter().map(|v| v * v).sum::<f64>().sqrt() + 1e-12);
                params.copy_from_slice(&trial);
                r.copy_from_slice(&trial_r);
                cost = trial_cost;
                lambda = (lambda * 0.1).max(1e-12);
                if rel_decrease < settings.cost_tolerance || step < settings.step_tolerance {
                    break 'outer;
                }
                break;
            }
            lambda *= 10.0;
            if lambda > 1e16 || iterations >= settings.max_iterations {
                break 'outer;
            }
        }
    }
    Ok(LmOutcome { cost, iterations })
}

fn sum_sq(r: &[f64]) -> f64 {
    r.iter().map(|v| v * v).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Fit y = a * exp(b * x) + c.
    struct ExpFit {
        xs: Vec<f64>,
        ys: Vec<f64>,
    }

    impl Residuals for ExpFit {
        fn num_params(&self) -> usize {
            3
        }
        fn num_residuals(&self) -> usize {
            self.xs.len()
        }
        fn evaluate(&self, p: &[f64], out: &mut [f64]) {
            for ((o, x), y) in out.iter_mut().zip(&self.xs).zip(&self.ys) {
                *o = p[0] * (p[1] * x).exp() + p[2] - y;
            }
        }
    }

    #[test]
    fn fits_exponential() {
        let xs: Vec<f64> = (0..30).map(|i| i as f64 * 0.1).collect();
        let ys = xs.iter().map(|x| 2.5 * (-1.3 * x).exp() + 0.7).collect();
        let problem = ExpFit { xs, ys };
        let mut p = [1.0, -0.5, 0.0];
        let out = solve(&problem, &mut p, LmSettings::default()).unwrap();
        assert!(out.cost < 1e-18, "cost {}", out.cost);
        assert!(
            (p[0] - 2.5).abs() < 1e-7 && (p[1] + 1.3).abs() < 1e-7 && (p[2] - 0.7).abs() < 1e-7
        );
    }
}
