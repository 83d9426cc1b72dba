//! Weighted linear least squares of reduced compliance parameters, with the covariance
//! `(A^T S^-1 A)^-1` and the parameter-to-noise ratios `nu_i = |pi_i| / sigma_i`.
//!
//! Solved by the SVD of the whitened regressor with unit-norm columns; when it is rank deficient
//! the minimum-norm solution is returned (its predictions for loads like the measured ones are
//! still unique) and parameters with a component in the null space get an infinite standard
//! deviation.

use faer::Mat;
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use crate::stiffness::error::{Result, StiffnessIdError};
use crate::stiffness::param::Parameterization;
use crate::stiffness::problem::LinearProblem;

/// A fitted parameter vector.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Fit {
    /// Parameter names.
    pub names: Vec<String>,
    /// Units.
    pub units: Vec<String>,
    /// Estimates.
    pub values: Vec<f64>,
    /// Standard deviations from the noise model (infinite when not determined).
    pub std: Vec<f64>,
    /// Covariance (pseudo-inverse over the determined directions).
    #[serde(skip)]
    pub covariance: DMatrix<f64>,
    /// Parameter-to-noise ratios `|value| / std`.
    pub nu: Vec<f64>,
    /// Numerical rank of the regressor.
    pub rank: usize,
    /// Condition number of the column-scaled regressor over its rank.
    pub condition_number: f64,
    /// Whitened residual RMS (1 when the noise model is right).
    pub s0: f64,
    /// Number of rows.
    pub n_rows: usize,
}

/// The regressor of `param`: `A B`.
pub fn reduced_regressor(problem: &LinearProblem, param: &Parameterization) -> DMatrix<f64> {
    let mut out = DMatrix::zeros(problem.a.nrows(), param.len());
    for (j, p) in param.params.iter().enumerate() {
        let mut col = out.column_mut(j);
        for &(i, c) in &p.basis {
            col.axpy(c, &problem.a.column(i), 1.0);
        }
    }
    out
}

/// Fits `param` to `problem`; singular values below `rel_tol` times the largest count as zero.
pub fn fit(problem: &LinearProblem, param: &Parameterization, rel_tol: f64) -> Result<Fit> {
    let a = reduced_regressor(problem, param);
    fit_matrix(&a, &problem.y, param, rel_tol)
}

/// As [`fit`] for an explicit regressor (already reduced and whitened).
pub fn fit_matrix(a: &DMatrix<f64>, y: &DVector<f64>, param: &Parameterization, rel_tol: f64) -> Result<Fit> {
    let (m, p) = a.shape();
    if p == 0 {
        return Err(StiffnessIdError::Options("no parameters to fit".into()));
    }
    if m == 0 {
        return Err(StiffnessIdError::Options("no measurements to fit".into()));
    }
    if a.iter().chain(y.iter()).any(|v| !v.is_finite()) {
        return Err(StiffnessIdError::Options("non-finite regressor or measurement".into()));
    }
    let norms: Vec<f64> = (0..p).map(|j| a.column(j).norm()).collect();
    let scale: Vec<f64> = norms.iter().map(|n| if *n > 0.0 { 1.0 / n } else { 1.0 }).collect();
    let fa = Mat::from_fn(m, p, |i, j| a[(i, j)] * scale[j]);
    let svd = if m >= p { fa.thin_svd() } else { fa.svd() }
        .map_err(|e| StiffnessIdError::Options(format!("SVD failed: {e:?}")))?;
    let k = m.min(p);
    let s: Vec<f64> = (0..k).map(|i| svd.S()[i]).collect();
    let smax = s.first().copied().unwrap_or(0.0);
    let rank = s.iter().filter(|v| **v > rel_tol * smax && **v > 0.0).count();
    let u = svd.U();
    let v = svd.V();
    // x_s = V_r S_r^-1 U_r^T y.
    let mut xs = vec![0.0; p];
    for c in 0..rank {
        let uty: f64 = (0..m).map(|i| u[(i, c)] * y[i]).sum();
        let f = uty / s[c];
        for (r, x) in xs.iter_mut().enumerate() {
            *x += v[(r, c)] * f;
        }
    }
    let values: Vec<f64> = xs.iter().zip(&scale).map(|(x, s)| x * s).collect();
    let mut cov = DMatrix::<f64>::zeros(p, p);
    for c in 0..rank {
        let w = 1.0 / (s[c] * s[c]);
        for i in 0..p {
            let vi = v[(i, c)] * scale[i] * w;
            if vi == 0.0 {
                continue;
            }
            for j in 0..p {
                cov[(i, j)] += vi * v[(j, c)] * scale[j];
            }
        }
    }
    let vcols = v.ncols();
    let std: Vec<f64> = (0..p)
        .map(|i| {
            let null: f64 = (rank..vcols).map(|c| v[(i, c)] * v[(i, c)]).sum::<f64>().sqrt();
            if null > 1e-6 || norms[i] == 0.0 {
                f64::INFINITY
            } else {
                cov[(i, i)].max(0.0).sqrt()
            }
        })
        .collect();
    let nu: Vec<f64> =
        values.iter().zip(&std).map(|(x, s)| if s.is_finite() && *s > 0.0 { x.abs() / s } else { 0.0 }).collect();
    let res = y - a * DVector::from_column_slice(&values);
    let dof = m.saturating_sub(rank).max(1);
    let s0 = (res.norm_squared() / dof as f64).sqrt();
    let condition_number = if rank > 0 { smax / s[rank - 1] } else { f64::INFINITY };
    Ok(Fit {
        names: param.names(),
        units: param.params.iter().map(|p| p.unit.clone()).collect(),
        values,
        std,
        covariance: cov,
        nu,
        rank,
        condition_number,
        s0,
        n_rows: m,
    })
}

/// Prediction errors of a fit on another problem (same complete layout): per 3-row position,
/// against the measurements and, when known, against the truth (metres).
pub fn prediction_errors(
    problem: &LinearProblem,
    param: &Parameterization,
    values: &[f64],
) -> (Vec<f64>, Option<Vec<f64>>) {
    let a = reduced_regressor(problem, param);
    let pred = a * DVector::from_column_slice(values);
    let meas = problem.position_errors_m(&(&problem.y - &pred));
    let truth = problem.y_true.as_ref().map(|t| problem.position_errors_m(&(t - &pred)));
    (meas, truth)
}

/// RMS and maximum of errors.
pub fn rms_max(e: &[f64]) -> (f64, f64) {
    if e.is_empty() {
        return (0.0, 0.0);
    }
    let rms = (e.iter().map(|v| v * v).sum::<f64>() / e.len() as f64).sqrt();
    (rms, e.iter().copied().fold(0.0, f64::max))
}
