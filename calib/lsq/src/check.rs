//! Numerical checks of manifolds and of residual Jacobians, used by the tests of every residual
//! block in the project.

use std::sync::Arc;

use nalgebra::DMatrix;

use crate::dense::DenseProblem;
use crate::{LsqError, Manifold, Residual, Result};

/// What a check found: the worst discrepancy and where.
#[derive(Clone, Debug, PartialEq)]
pub struct CheckReport {
    /// Largest `|analytic - numeric| / max(1, max |numeric column|)` over all entries checked:
    /// the error of an entry relative to the largest entry of its column (so that the rounding
    /// of small entries beside large ones does not count), and absolute below 1.
    pub max_error: f64,
    /// Where it was: (block, residual row, tangent coordinate) for Jacobians.
    pub worst: (usize, usize, usize),
    /// Entries compared.
    pub entries: usize,
}

impl CheckReport {
    /// Fails with a description when the worst error is above `tolerance`.
    pub fn assert_below(&self, tolerance: f64, what: &str) -> Result<()> {
        if self.max_error <= tolerance {
            Ok(())
        } else {
            Err(LsqError::Numeric(format!(
                "{what}: analytic and numeric derivatives differ by {:.2e} (relative) at block {}, row {}, \
                 coordinate {} (tolerance {tolerance:.1e})",
                self.max_error, self.worst.0, self.worst.1, self.worst.2
            )))
        }
    }
}

fn rel(a: f64, n: f64, column_max: f64) -> f64 {
    (a - n).abs() / column_max.max(n.abs()).max(1.0)
}

/// Compares a residual's analytic tangent Jacobians with central differences through the
/// manifolds (`r(x ⊞ hε_i) - r(x ⊞ -hε_i)) / 2h`, with `h = step * scale_i`).
pub fn check_residual(
    residual: &dyn Residual,
    params: &[&[f64]],
    manifolds: &[Arc<dyn Manifold>],
    scales: &[Vec<f64>],
    step: f64,
) -> Result<CheckReport> {
    if params.len() != manifolds.len() || scales.len() != manifolds.len() {
        return Err(LsqError::Setup("check_residual: one manifold and one scale vector per block".into()));
    }
    let n = residual.n_residuals();
    let mut r0 = vec![0.0; n];
    let mut jacs: Vec<Option<DMatrix<f64>>> =
        manifolds.iter().map(|m| Some(DMatrix::zeros(n, m.tangent_size()))).collect();
    residual.evaluate(params, &mut r0, Some(&mut jacs))?;
    let mut owned: Vec<Vec<f64>> = params.iter().map(|p| p.to_vec()).collect();
    let (mut rp, mut rm) = (vec![0.0; n], vec![0.0; n]);
    let mut report = CheckReport { max_error: 0.0, worst: (0, 0, 0), entries: 0 };
    for (k, m) in manifolds.iter().enumerate() {
        let jac = jacs[k].as_ref().expect("filled");
        let mut delta = vec![0.0; m.tangent_size()];
        for i in 0..m.tangent_size() {
            let h = step * scales[k][i];
            for (sign, out) in [(1.0, &mut rp), (-1.0, &mut rm)] {
                delta[i] = sign * h;
                m.plus(params[k], &delta, &mut owned[k]);
                let views: Vec<&[f64]> = owned.iter().map(|v| v.as_slice()).collect();
                residual.evaluate(&views, out, None)?;
            }
            delta[i] = 0.0;
            owned[k].copy_from_slice(params[k]);
            let column_max = (0..n).map(|r| ((rp[r] - rm[r]) / (2.0 * h)).abs()).fold(0.0, f64::max);
            for r in 0..n {
                let numeric = (rp[r] - rm[r]) / (2.0 * h);
                let e = rel(jac[(r, i)], numeric, column_max);
                report.entries += 1;
                if e > report.max_error || !e.is_finite() {
                    report.max_error = if e.is_finite() { e } else { f64::INFINITY };
                    report.worst = (k, r, i);
                }
            }
        }
    }
    Ok(report)
}

/// Compares a [`DenseProblem`]'s Jacobian at `x` with central differences of its residuals
/// through its retraction (steps `step` times its scales).
pub fn check_dense_problem(problem: &dyn DenseProblem, x: &[f64], step: f64) -> Result<CheckReport> {
    let jac = problem.jacobian(x)?;
    let scales = problem.scales();
    let mut report = CheckReport { max_error: 0.0, worst: (0, 0, 0), entries: 0 };
    let n = problem.n_params();
    for i in 0..n {
        let h = step * scales[i];
        let mut dx = vec![0.0; n];
        dx[i] = h;
        let rp = problem.residuals(&problem.retract(x, &dx))?;
        dx[i] = -h;
        let rm = problem.residuals(&problem.retract(x, &dx))?;
        let column_max = (0..rp.len()).map(|r| ((rp[r] - rm[r]) / (2.0 * h)).abs()).fold(0.0, f64::max);
        for r in 0..rp.len() {
            let numeric = (rp[r] - rm[r]) / (2.0 * h);
            let e = rel(jac[(r, i)], numeric, column_max);
            report.entries += 1;
            if e > report.max_error || !e.is_finite() {
                report.max_error = if e.is_finite() { e } else { f64::INFINITY };
                report.worst = (0, r, i);
            }
        }
    }
    Ok(report)
}

/// Checks a manifold at `x` with the tangent steps `deltas`: `x ⊞ 0 = x`, `x ⊞ δ` on the
/// manifold, `(x ⊞ δ) ⊟ x = δ`, and `plus_jacobian` against central differences. Returns the
/// largest error found.
pub fn check_manifold(manifold: &dyn Manifold, x: &[f64], deltas: &[Vec<f64>]) -> Result<f64> {
    let (na, nt) = (manifold.ambient_size(), manifold.tangent_size());
    if !manifold.contains(x) {
        return Err(LsqError::Setup(format!("check_manifold: {x:?} is not on the {} manifold", manifold.name())));
    }
    let mut worst: f64 = 0.0;
    let mut y = vec![0.0; na];
    let mut d = vec![0.0; nt];
    manifold.plus(x, &vec![0.0; nt], &mut y);
    worst = worst.max(y.iter().zip(x).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max));
    for delta in deltas {
        manifold.plus(x, delta, &mut y);
        if !manifold.contains(&y) {
            return Err(LsqError::Numeric(format!("{}: x ⊞ {delta:?} left the manifold", manifold.name())));
        }
        manifold.minus(&y, x, &mut d);
        worst = worst.max(d.iter().zip(delta).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max));
    }
    let j = manifold.plus_jacobian(x);
    let h = 1e-6;
    let (mut yp, mut ym) = (vec![0.0; na], vec![0.0; na]);
    for i in 0..nt {
        let mut delta = vec![0.0; nt];
        delta[i] = h;
        manifold.plus(x, &delta, &mut yp);
        delta[i] = -h;
        manifold.plus(x, &delta, &mut ym);
        for r in 0..na {
            worst = worst.max(rel(j[(r, i)], (yp[r] - ym[r]) / (2.0 * h), 1.0));
        }
    }
    Ok(worst)
}
