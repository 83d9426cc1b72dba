//! Dense non-linear least squares: Levenberg-Marquardt with parameter scaling, robust losses,
//! a manifold hook, and the covariance of the result.
//!
//! Small dense problems (robot calibration: tens of parameters, thousands of residuals) are
//! solved here with nalgebra's Cholesky on the scaled normal equations; large sparse ones
//! (bundle adjustment) go through Ceres in `ferrocal-vision`.

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use crate::error::{CalibError, Result};

/// A robust loss applied to the squared norm `s` of each residual block.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Loss {
    /// Plain least squares.
    Squared,
    /// Huber: quadratic up to `delta` (in whitened units, i.e. standard deviations), linear beyond.
    Huber {
        /// Threshold in standard deviations.
        delta: f64,
    },
    /// Cauchy: `delta^2 log(1 + s / delta^2)`.
    Cauchy {
        /// Scale in standard deviations.
        delta: f64,
    },
}

impl Loss {
    /// The loss of a block's squared norm `s`, and its derivative `rho'(s)` (the IRLS weight).
    pub fn rho(&self, s: f64) -> (f64, f64) {
        match *self {
            Loss::Squared => (s, 1.0),
            Loss::Huber { delta } => {
                let d2 = delta * delta;
                if s <= d2 {
                    (s, 1.0)
                } else {
                    let r = s.sqrt();
                    (2.0 * delta * r - d2, delta / r)
                }
            }
            Loss::Cauchy { delta } => {
                let d2 = delta * delta;
                (d2 * (1.0 + s / d2).ln(), 1.0 / (1.0 + s / d2))
            }
        }
    }
}

/// A least-squares problem over a parameter vector `x` (in the problem's own units).
pub trait Problem {
    /// Number of parameters.
    fn n_params(&self) -> usize;
    /// Number of residuals (already whitened: divided by their standard deviations).
    fn n_residuals(&self) -> usize;
    /// Residuals are grouped in blocks of this size for the robust loss (3 for a position).
    fn block_size(&self) -> usize {
        1
    }
    /// Residuals at `x`.
    fn residuals(&self, x: &[f64]) -> Result<DVector<f64>>;
    /// Jacobian of the residuals at `x` (`n_residuals x n_params`). The default is central
    /// differences with steps of `1e-4` times [`Problem::scales`].
    fn jacobian(&self, x: &[f64]) -> Result<DMatrix<f64>> {
        let n = self.n_params();
        let scales = self.scales();
        let mut jac = DMatrix::zeros(self.n_residuals(), n);
        let mut xp = x.to_vec();
        for i in 0..n {
            let h = 1e-4 * scales[i];
            xp[i] = x[i] + h;
            let rp = self.residuals(&xp)?;
            xp[i] = x[i] - h;
            let rm = self.residuals(&xp)?;
            xp[i] = x[i];
            jac.set_column(i, &((rp - rm) / (2.0 * h)));
        }
        Ok(jac)
    }
    /// Typical size of a change in each parameter (used to scale the problem).
    fn scales(&self) -> Vec<f64>;
    /// Applies a step (a manifold retraction where parameters live on one). Default: `x + dx`.
    fn retract(&self, x: &[f64], dx: &[f64]) -> Vec<f64> {
        x.iter().zip(dx).map(|(a, b)| a + b).collect()
    }
}

/// Options of [`solve`].
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
    /// Robust loss.
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

/// Why and how the solver stopped, and the statistics of the result.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct LmSummary {
    /// Iterations used.
    pub iterations: usize,
    /// Cost `sum rho(|r_b|^2) / 2` at the start.
    pub initial_cost: f64,
    /// Cost at the end.
    pub final_cost: f64,
    /// Why it stopped.
    pub termination: String,
    /// Whether it stopped by a convergence test (not by the iteration limit).
    pub converged: bool,
    /// Residual blocks down-weighted by the robust loss at the end (IRLS weight below 0.5).
    pub downweighted_blocks: usize,
}

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
    pub summary: LmSummary,
}

fn robust_cost(r: &DVector<f64>, b: usize, loss: &Loss) -> f64 {
    r.as_slice().chunks(b).map(|c| loss.rho(c.iter().map(|v| v * v).sum()).0).sum::<f64>() * 0.5
}

/// Minimises `sum_b rho(|r_b(x)|^2) / 2` by Levenberg-Marquardt with Marquardt's scaling
/// (damping proportional to the diagonal of the scaled normal matrix) and iteratively
/// re-weighted blocks for robust losses.
pub fn solve(problem: &dyn Problem, x0: &[f64], opts: &LmOptions) -> Result<LmResult> {
    let n = problem.n_params();
    if x0.len() != n {
        return Err(CalibError::Data(format!("expected {n} start values, got {}", x0.len())));
    }
    let b = problem.block_size().max(1);
    let scales = problem.scales();
    let mut x = x0.to_vec();
    let mut r = problem.residuals(&x)?;
    if r.iter().any(|v| !v.is_finite()) {
        return Err(CalibError::Diverged("the residuals at the start are not finite".into()));
    }
    let mut cost = robust_cost(&r, b, &opts.loss);
    let initial_cost = cost;
    let mut lambda = opts.initial_lambda;
    let mut termination = "iteration limit".to_string();
    let mut converged = false;
    let mut iterations = 0;
    let mut jac = problem.jacobian(&x)?;
    'outer: while iterations < opts.max_iterations {
        // IRLS weights per block.
        let mut w = DVector::from_element(r.len(), 1.0);
        if opts.loss != Loss::Squared {
            for (k, c) in r.as_slice().chunks(b).enumerate() {
                let s: f64 = c.iter().map(|v| v * v).sum();
                let wt = opts.loss.rho(s).1;
                for i in 0..c.len() {
                    w[k * b + i] = wt;
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
                        break 'outer;
                    }
                    continue;
                }
            };
            let cost_new = robust_cost(&r_new, b, &opts.loss);
            if cost_new < cost {
                let rel = (cost - cost_new) / cost.max(1e-300);
                let step_norm = step.norm();
                x = x_new;
                r = r_new;
                cost = cost_new;
                lambda = (lambda * 0.3).max(1e-12);
                if rel < opts.cost_tolerance {
                    termination = format!("relative cost decrease {rel:.1e} below tolerance");
                    converged = true;
                    break 'outer;
                }
                if step_norm < opts.step_tolerance {
                    termination = format!("scaled step {step_norm:.1e} below tolerance");
                    converged = true;
                    break 'outer;
                }
                jac = problem.jacobian(&x)?;
                continue 'outer;
            }
            lambda *= 10.0;
            if lambda > 1e16 {
                termination = "no step reduces the cost any more (converged to machine precision)".into();
                converged = true;
                break 'outer;
            }
            if iterations >= opts.max_iterations {
                break 'outer;
            }
        }
    }
    let jacobian = problem.jacobian(&x)?;
    let downweighted_blocks =
        r.as_slice().chunks(b).filter(|c| opts.loss.rho(c.iter().map(|v| v * v).sum()).1 < 0.5).count();
    Ok(LmResult {
        x,
        residuals: r,
        jacobian,
        summary: LmSummary { iterations, initial_cost, final_cost: cost, termination, converged, downweighted_blocks },
    })
}

/// Covariance of the parameters from the Jacobian of whitened residuals: `s0^2 (J^T J)^-1` with
/// `s0^2 = |r|^2 / (m - n)` (the a-posteriori variance factor; 1 when the noise model is right).
/// Returns the covariance and `s0`.
pub fn covariance(jacobian: &DMatrix<f64>, residuals: &DVector<f64>) -> Result<(DMatrix<f64>, f64)> {
    let (m, n) = jacobian.shape();
    if m <= n {
        return Err(CalibError::TooFew(format!("{m} residuals cannot give the covariance of {n} parameters")));
    }
    let s0 = (residuals.norm_squared() / (m - n) as f64).sqrt();
    // Scale columns for conditioning, invert, unscale.
    let d: Vec<f64> = (0..n).map(|c| jacobian.column(c).norm().max(1e-300)).collect();
    let mut js = jacobian.clone();
    for (c, dc) in d.iter().enumerate() {
        js.column_mut(c).scale_mut(1.0 / dc);
    }
    let jtj = js.transpose() * js;
    let inv = jtj
        .cholesky()
        .ok_or_else(|| {
            CalibError::Numeric("the normal matrix is singular: some parameters are not identifiable".into())
        })?
        .inverse();
    let mut cov = inv * (s0 * s0);
    for i in 0..n {
        for j in 0..n {
            cov[(i, j)] /= d[i] * d[j];
        }
    }
    Ok((cov, s0))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Fit y = a exp(b t) + c.
    struct Exp {
        t: Vec<f64>,
        y: Vec<f64>,
    }

    impl Problem for Exp {
        fn n_params(&self) -> usize {
            3
        }
        fn n_residuals(&self) -> usize {
            self.t.len()
        }
        fn residuals(&self, x: &[f64]) -> Result<DVector<f64>> {
            Ok(DVector::from_iterator(
                self.t.len(),
                self.t.iter().zip(&self.y).map(|(t, y)| x[0] * (x[1] * t).exp() + x[2] - y),
            ))
        }
        fn scales(&self) -> Vec<f64> {
            vec![1.0, 0.1, 1.0]
        }
    }

    #[test]
    fn fits_an_exponential_and_its_covariance_matches_monte_carlo() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let truth = [2.0, -0.7, 0.5];
        let t: Vec<f64> = (0..60).map(|k| k as f64 * 0.1).collect();
        let noise = Normal::new(0.0, 0.01).unwrap();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let mut estimates = Vec::new();
        let mut predicted_sd = [0.0; 3];
        for trial in 0..200 {
            let y: Vec<f64> =
                t.iter().map(|t| truth[0] * (truth[1] * t).exp() + truth[2] + noise.sample(&mut rng)).collect();
            // Whitened problem: residuals divided by sigma.
            let p = Exp { t: t.clone(), y: y.iter().map(|v| v / 0.01).collect() };
            struct Scaled<'a>(&'a Exp);
            impl Problem for Scaled<'_> {
                fn n_params(&self) -> usize {
                    3
                }
                fn n_residuals(&self) -> usize {
                    self.0.t.len()
                }
                fn residuals(&self, x: &[f64]) -> Result<DVector<f64>> {
                    Ok(DVector::from_iterator(
                        self.0.t.len(),
                        self.0.t.iter().zip(&self.0.y).map(|(t, y)| (x[0] * (x[1] * t).exp() + x[2]) / 0.01 - y),
                    ))
                }
                fn scales(&self) -> Vec<f64> {
                    vec![1.0, 0.1, 1.0]
                }
            }
            let res = solve(&Scaled(&p), &[1.0, -0.3, 0.0], &LmOptions::default()).unwrap();
            assert!(res.summary.converged, "{:?}", res.summary);
            if trial == 0 {
                let (cov, s0) = covariance(&res.jacobian, &res.residuals).unwrap();
                assert!((s0 - 1.0).abs() < 0.3, "s0 = {s0}");
                for i in 0..3 {
                    predicted_sd[i] = cov[(i, i)].sqrt() / s0;
                }
            }
            estimates.push(res.x);
        }
        for i in 0..3 {
            let mean = estimates.iter().map(|e| e[i]).sum::<f64>() / 200.0;
            let sd = (estimates.iter().map(|e| (e[i] - mean).powi(2)).sum::<f64>() / 199.0).sqrt();
            assert!((mean - truth[i]).abs() < 4.0 * sd / 200f64.sqrt() + 1e-9, "param {i}: mean {mean}");
            assert!((sd / predicted_sd[i] - 1.0).abs() < 0.2, "param {i}: sd {sd} vs predicted {}", predicted_sd[i]);
        }
    }

    #[test]
    fn huber_down_weights_outliers() {
        let t: Vec<f64> = (0..40).map(|k| k as f64 * 0.1).collect();
        let mut y: Vec<f64> = t.iter().map(|t| 2.0 * (-0.7 * t).exp() + 0.5).collect();
        y[10] += 5.0;
        y[30] -= 3.0;
        let p = Exp { t, y };
        let plain = solve(&p, &[1.0, -0.3, 0.0], &LmOptions::default()).unwrap();
        let robust =
            solve(&p, &[1.0, -0.3, 0.0], &LmOptions { loss: Loss::Huber { delta: 0.05 }, ..LmOptions::default() })
                .unwrap();
        let err = |x: &[f64]| (x[0] - 2.0).abs() + (x[1] + 0.7).abs() + (x[2] - 0.5).abs();
        assert!(err(&robust.x) < 0.1 * err(&plain.x), "robust {:?} plain {:?}", robust.x, plain.x);
        assert!(robust.summary.downweighted_blocks >= 2);
    }
}
