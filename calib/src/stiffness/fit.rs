//! Weighted linear least squares of reduced compliance parameters, with the covariance
//! `(A^T S^-1 A)^-1` and the parameter-to-noise ratios `nu_i = |pi_i| / sigma_i`.
//!
//! Solved by the least-squares layer's truncated SVD of the whitened regressor with unit-norm
//! columns ([`ferrocal_lsq::linear`]); when it is rank deficient the minimum-norm solution is
//! returned (its predictions for loads like the measured ones are still unique) and parameters
//! with a component in the null space get an infinite standard deviation.

use ferrocal_lsq::linear::{self, CovarianceScale, LinearOptions, RankPolicy, Weighting};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use crate::stiffness::error::Result;
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

/// As [`fit`] for an explicit regressor (already reduced and whitened): the least-squares
/// layer's truncated SVD ([`RankPolicy::Truncate`]) with the covariance of the noise model
/// (`(A^T A)^-1` over the determined directions, [`CovarianceScale::APriori`]).
pub fn fit_matrix(a: &DMatrix<f64>, y: &DVector<f64>, param: &Parameterization, rel_tol: f64) -> Result<Fit> {
    let opts =
        LinearOptions { covariance: CovarianceScale::APriori, ..LinearOptions::new(RankPolicy::Truncate, rel_tol) };
    let f = linear::fit(a, y, &param.names(), &Weighting::Unit, &opts)?;
    let nu: Vec<f64> =
        f.values.iter().zip(&f.std).map(|(x, s)| if s.is_finite() && *s > 0.0 { x.abs() / s } else { 0.0 }).collect();
    Ok(Fit {
        names: f.names,
        units: param.params.iter().map(|p| p.unit.clone()).collect(),
        values: f.values,
        std: f.std,
        covariance: f.covariance,
        nu,
        rank: f.rank,
        condition_number: f.condition_number,
        s0: f.s0,
        n_rows: f.n_rows,
    })
}

/// RMS and maximum of errors.
pub fn rms_max(e: &[f64]) -> (f64, f64) {
    if e.is_empty() {
        return (0.0, 0.0);
    }
    let rms = (e.iter().map(|v| v * v).sum::<f64>() / e.len() as f64).sqrt();
    (rms, e.iter().copied().fold(0.0, f64::max))
}
