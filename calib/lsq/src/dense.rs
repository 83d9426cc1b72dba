//! The dense back end: Levenberg-Marquardt with Marquardt's parameter scaling, iteratively
//! re-weighted robust losses and a manifold retraction, for small problems (robot calibration:
//! tens of parameters, thousands of residuals) solved with nalgebra's Cholesky on the scaled
//! normal equations.
//!
//! A problem reaches it either as a [`crate::Problem`] of parameter and residual blocks, or, for
//! code that already assembles one whole residual vector and its Jacobian, through the
//! [`DenseProblem`] trait.

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use crate::{Loss, LsqError, Result};

/// A least-squares problem over one parameter vector `x` (in the problem's own units).
pub trait DenseProblem {
    /// Number of parameters (the size of a step).
    fn n_params(&self) -> usize;
    /// Number of stored values of `x` (larger than [`DenseProblem::n_params`] where parameters
    /// live on a manifold with more ambient coordinates). Default: `n_params`.
    fn n_ambient(&self) -> usize {
        self.n_params()
    }
    /// Number of residuals (already whitened: divided by their standard deviations).
    fn n_residuals(&self) -> usize;
    /// Residuals are grouped in blocks of this size for the robust loss (3 for a position).
    fn block_size(&self) -> usize {
        1
    }
    /// The residual blocks as `(first row, rows, loss)`; by default consecutive blocks of
    /// [`DenseProblem::block_size`] rows, all with the options' loss.
    fn residual_blocks(&self, loss: &Loss) -> Vec<(usize, usize, Loss)> {
        let (n, b) = (self.n_residuals(), self.block_size().max(1));
        (0..n).step_by(b).map(|k| (k, b.min(n - k), *loss)).collect()
    }
    /// Residuals at `x`.
    fn residuals(&self, x: &[f64]) -> Result<DVector<f64>>;
    /// Jacobian of the residuals with respect to a step at `x` (`n_residuals x n_params`). The
    /// default is central differences with steps of `1e-4` times [`DenseProblem::scales`]
    /// (Euclidean parameters only).
    fn jacobian(&self, x: &[f64]) -> Result<DMatrix<f64>> {
        central_differences(|x| self.residuals(x), x, &self.scales(), self.n_residuals())
    }
    /// Typical size of a change in each parameter (used to scale the problem).
    fn scales(&self) -> Vec<f64>;
    /// Applies a step (a manifold retraction where parameters live on one). Default: `x + dx`.
    fn retract(&self, x: &[f64], dx: &[f64]) -> Vec<f64> {
        x.iter().zip(dx).map(|(a, b)| a + b).collect()
    }
}

/// Central differences of `residuals` at `x` with steps of `1e-4` times `scales` (Euclidean
/// parameters): the default Jacobian of a [`DenseProblem`].
pub fn central_differences<E>(
    residuals: impl Fn(&[f64]) -> std::result::Result<DVector<f64>, E>,
    x: &[f64],
    scales: &[f64],
    n_residuals: usize,
) -> std::result::Result<DMatrix<f64>, E> {
    let n = x.len();
    let mut jac = DMatrix::zeros(n_residuals, n);
    let mut xp = x.to_vec();
    for i in 0..n {
        let h = 1e-4 * scales[i];
        xp[i] = x[i] + h;
        let rp = residuals(&xp)?;
        xp[i] = x[i] - h;
        let rm = residuals(&xp)?;
        xp[i] = x[i];
        jac.set_column(i, &((rp - rm) / (2.0 * h)));
    }
    Ok(jac)
}

/// Options of the Levenberg-Marquardt solver.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LmOptions {
    /// Maximum iterations (accepted or rejected steps).
    pub max_iterations: usize,
    /// Stop when the relative cost decrease of an accepted step is below this.
    pub cost_tolerance: f64,
    /// Stop when the scaled step is below this.
    pub step_tolerance: f64,
    /// Initial damping.
    pub initial_lambda: f64,
    /// Robust loss (for [`DenseProblem`]s that do not name their own per block).
    pub loss: Loss,
}

impl Default for LmOptions {
    fn default() -> Self {
        Self {
            max_iterations: 100,
            cost_tolerance: 1e-12,
            step_tolerance: 1e-10,
            initial_lambda: 1e-3,
            loss: Loss::Squared,
        }
    }
}

impl LmOptions {
    /// Checks that every option makes sense (positive iteration count, non-negative finite
    /// tolerances, positive damping, a valid loss).
    pub fn validate(&self) -> Result<()> {
        let bad = |what: &str| Err(LsqError::Setup(format!("solver options: {what}")));
        if self.max_iterations == 0 {
            return bad("max_iterations must be at least 1");
        }
        if !(self.cost_tolerance.is_finite() && self.cost_tolerance >= 0.0) {
            return bad("cost_tolerance must be finite and not negative");
        }
        if !(self.step_tolerance.is_finite() && self.step_tolerance >= 0.0) {
            return bad("step_tolerance must be finite and not negative");
        }
        if !(self.initial_lambda.is_finite() && self.initial_lambda > 0.0) {
            return bad("initial_lambda must be positive and finite");
        }
        self.loss.validate()
    }
}

/// Why a solver stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Termination {
    /// The relative cost decrease of a step fell below the tolerance (converged).
    CostTolerance,
    /// The scaled step fell below the tolerance (converged).
    StepTolerance,
    /// No step reduces the cost any more, to machine precision (converged).
    NoFurtherDecrease,
    /// The iteration limit was reached first (not converged).
    IterationLimit,
    /// The model could not be evaluated around the current point (not converged).
    NotEvaluable,
    /// The back end reported a failure of its own (not converged).
    Failed,
}

impl Termination {
    /// Whether this is a convergence test.
    pub fn converged(self) -> bool {
        matches!(self, Self::CostTolerance | Self::StepTolerance | Self::NoFurtherDecrease)
    }
}

/// Why and how the solver stopped, and the statistics of the result.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Summary {
    /// Iterations used.
    pub iterations: usize,
    /// Cost `sum rho(|r_b|^2) / 2` at the start.
    pub initial_cost: f64,
    /// Cost at the end.
    pub final_cost: f64,
    /// Why it stopped, in words.
    pub termination: String,
    /// Why it stopped.
    pub stop: Termination,
    /// Whether it stopped by a convergence test (not by the iteration limit).
    pub converged: bool,
    /// Residual blocks down-weighted by the robust loss at the end (IRLS weight below 0.5).
    pub downweighted_blocks: usize,
    /// Condition number of the column-equilibrated Jacobian at the solution (`None` when it has
    /// fewer rows than columns or a zero column, and from the Ceres back end, which does not form
    /// the dense Jacobian).
    pub condition_number: Option<f64>,
}

/// The historical name of [`Summary`].
pub type LmSummary = Summary;

/// Result of [`solve`].
#[derive(Clone, Debug)]
pub struct LmResult {
    /// The solution.
    pub x: Vec<f64>,
    /// Residuals at the solution.
    pub residuals: DVector<f64>,
    /// Jacobian at the solution.
    pub jacobian: DMatrix<f64>,
    /// Statistics.
    pub summary: Summary,
}

fn robust_cost(r: &DVector<f64>, blocks: &[(usize, usize, Loss)]) -> f64 {
    blocks.iter().map(|&(s, n, loss)| loss.rho(r.rows(s, n).norm_squared_sum()).0).sum::<f64>() * 0.5
}

trait NormSquaredSum {
    fn norm_squared_sum(&self) -> f64;
}

impl<S: nalgebra::Storage<f64, nalgebra::Dyn, nalgebra::U1>> NormSquaredSum
    for nalgebra::Matrix<f64, nalgebra::Dyn, nalgebra::U1, S>
{
    /// `sum v^2` in row order (the order the historical solver summed in).
    fn norm_squared_sum(&self) -> f64 {
        self.iter().map(|v| v * v).sum()
    }
}

/// Condition number of `J` with its columns scaled to unit length, from the eigenvalues of the
/// scaled normal matrix (`sqrt(lambda_max / lambda_min)`; `None` when `J` has fewer rows than
/// columns or a zero column, infinite when it is rank-deficient).
pub fn condition_number(jacobian: &DMatrix<f64>) -> Option<f64> {
    let (m, n) = jacobian.shape();
    if m < n || n == 0 {
        return None;
    }
    let mut js = jacobian.clone();
    for c in 0..n {
        let d = js.column(c).norm();
        if d == 0.0 || !d.is_finite() {
            return None;
        }
        js.column_mut(c).scale_mut(1.0 / d);
    }
    let ev = (js.transpose() * js).symmetric_eigenvalues();
    let (max, min) = ev.iter().fold((0.0f64, f64::INFINITY), |(a, b), &s| (a.max(s), b.min(s)));
    Some(if min > 0.0 { (max / min).sqrt() } else { f64::INFINITY })
}

/// Minimises `sum_b rho_b(|r_b(x)|^2) / 2` by Levenberg-Marquardt with Marquardt's scaling
/// (damping proportional to the diagonal of the scaled normal matrix) and iteratively
/// re-weighted blocks for robust losses.
pub fn solve(problem: &dyn DenseProblem, x0: &[f64], opts: &LmOptions) -> Result<LmResult> {
    opts.validate()?;
    let n = problem.n_params();
    if x0.len() != problem.n_ambient() {
        return Err(LsqError::Setup(format!("expected {} start values, got {}", problem.n_ambient(), x0.len())));
    }
    let blocks = problem.residual_blocks(&opts.loss);
    let scales = problem.scales();
    let mut x = x0.to_vec();
    let mut r = problem.residuals(&x)?;
    if r.iter().any(|v| !v.is_finite()) {
        return Err(LsqError::Diverged("the residuals at the start are not finite".into()));
    }
    let mut cost = robust_cost(&r, &blocks);
    let initial_cost = cost;
    let mut lambda = opts.initial_lambda;
    let mut termination = "iteration limit".to_string();
    let mut stop = Termination::IterationLimit;
    let mut iterations = 0;
    let mut jac = problem.jacobian(&x)?;
    let robust = blocks.iter().any(|b| b.2 != Loss::Squared);
    'outer: while iterations < opts.max_iterations {
        // IRLS weights per block.
        let mut w = DVector::from_element(r.len(), 1.0);
        if robust {
            for &(s, len, loss) in &blocks {
                let wt = loss.rho(r.rows(s, len).norm_squared_sum()).1;
                for i in 0..len {
                    w[s + i] = wt;
                }
            }
        }
        // Scaled Jacobian: columns times the parameter scales.
        let mut js = jac.clone();
        for (c, s) in scales.iter().enumerate() {
            js.column_mut(c).scale_mut(*s);
        }
        let mut jw = js.clone();
        for i in 0..jw.nrows() {
            jw.row_mut(i).scale_mut(w[i]);
        }
        let jtj = js.transpose() * &jw;
        let g = jw.transpose() * &r;
        loop {
            iterations += 1;
            let mut a = jtj.clone();
            for d in 0..n {
                a[(d, d)] += lambda * jtj[(d, d)].max(1e-12);
            }
            let step = match a.cholesky() {
                Some(ch) => -ch.solve(&g),
                None => {
                    lambda *= 10.0;
                    if iterations >= opts.max_iterations {
                        break 'outer;
                    }
                    continue;
                }
            };
            let dx: Vec<f64> = step.iter().zip(&scales).map(|(s, k)| s * k).collect();
            let x_new = problem.retract(&x, &dx);
            let r_new = match problem.residuals(&x_new) {
                Ok(rn) if rn.iter().all(|v| v.is_finite()) => rn,
                _ => {
                    lambda *= 10.0;
                    if iterations >= opts.max_iterations || lambda > 1e16 {
                        termination =
                            "no step reduces the cost (the model cannot be evaluated around the current point)".into();
                        stop = Termination::NotEvaluable;
                        break 'outer;
                    }
                    continue;
                }
            };
            let cost_new = robust_cost(&r_new, &blocks);
            if cost_new < cost {
                let rel = (cost - cost_new) / cost.max(1e-300);
                let step_norm = step.norm();
                x = x_new;
                r = r_new;
                cost = cost_new;
                lambda = (lambda * 0.3).max(1e-12);
                if rel < opts.cost_tolerance {
                    termination = format!("relative cost decrease {rel:.1e} below tolerance");
                    stop = Termination::CostTolerance;
                    break 'outer;
                }
                if step_norm < opts.step_tolerance {
                    termination = format!("scaled step {step_norm:.1e} below tolerance");
                    stop = Termination::StepTolerance;
                    break 'outer;
                }
                jac = problem.jacobian(&x)?;
                continue 'outer;
            }
            lambda *= 10.0;
            if lambda > 1e16 {
                termination = "no step reduces the cost any more (converged to machine precision)".into();
                stop = Termination::NoFurtherDecrease;
                break 'outer;
            }
            if iterations >= opts.max_iterations {
                break 'outer;
            }
        }
    }
    let jacobian = problem.jacobian(&x)?;
    let downweighted_blocks =
        blocks.iter().filter(|&&(s, len, loss)| loss.rho(r.rows(s, len).norm_squared_sum()).1 < 0.5).count();
    let condition_number = condition_number(&jacobian);
    Ok(LmResult {
        x,
        residuals: r,
        jacobian,
        summary: Summary {
            iterations,
            initial_cost,
            final_cost: cost,
            termination,
            stop,
            converged: stop.converged(),
            downweighted_blocks,
            condition_number,
        },
    })
}
