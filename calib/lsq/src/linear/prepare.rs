//! Checks, whitening and column scaling of a linear problem `y = A u`.

use faer::Mat;
use nalgebra::{DMatrix, DVector};

use super::{RankPolicy, Weighting};
use crate::{LsqError, Result};

/// A whitened, column-scaled problem.
pub(super) struct Scaled {
    /// `L^-1 A H`.
    pub a: Mat<f64>,
    /// `L^-1 y`.
    pub y: Vec<f64>,
    /// Column scale factors `h_l = 1 / ||(L^-1 A)_l||` (1 for a zero column).
    pub h: Vec<f64>,
    /// Whether the whitened column was zero.
    pub zero: Vec<bool>,
}

/// Checks shapes and values. The refusing policy needs redundancy (`m > n`); the others solve
/// any shape.
pub(super) fn check(a: &DMatrix<f64>, y: &DVector<f64>, names: &[String], policy: RankPolicy) -> Result<()> {
    let (m, n) = a.shape();
    if names.len() != n {
        return Err(LsqError::Setup(format!("{} names for {n} regressor columns", names.len())));
    }
    if y.len() != m {
        return Err(LsqError::Setup(format!("{} measurements for {m} regressor rows", y.len())));
    }
    if n == 0 {
        return Err(LsqError::Setup("no parameters to identify".into()));
    }
    if policy == RankPolicy::Refuse && m <= n {
        return Err(LsqError::TooFew(format!(
            "{m} equations cannot identify {n} parameters with redundancy: measure more poses or samples"
        )));
    }
    if m == 0 {
        return Err(LsqError::TooFew("no measurements to identify from".into()));
    }
    if let Some(k) = a.iter().position(|v| !v.is_finite()) {
        return Err(LsqError::Setup(format!("regressor row {}, column '{}' is not finite", k % m + 1, names[k / m])));
    }
    if let Some(k) = y.iter().position(|v| !v.is_finite()) {
        return Err(LsqError::Setup(format!("measurement {} is not finite", k + 1)));
    }
    Ok(())
}

/// Whitens `a` and `y`: rows divided by their standard deviations, or each group of `k` rows
/// multiplied by `L^-1` of its covariance `L L^T`. Returns faer matrices.
pub(super) fn whiten(a: &DMatrix<f64>, y: &DVector<f64>, w: &Weighting) -> Result<(Mat<f64>, Vec<f64>)> {
    let (m, n) = a.shape();
    match w {
        Weighting::Unit => Ok((Mat::from_fn(m, n, |i, j| a[(i, j)]), y.iter().copied().collect())),
        Weighting::Sigmas(s) => {
            if s.len() != m {
                return Err(LsqError::Setup(format!("{} standard deviations for {m} rows", s.len())));
            }
            if let Some(k) = s.iter().position(|v| !(v.is_finite() && *v > 0.0)) {
                return Err(LsqError::Setup(format!(
                    "row {}: standard deviation {} is not positive and finite",
                    k + 1,
                    s[k]
                )));
            }
            Ok((Mat::from_fn(m, n, |i, j| a[(i, j)] / s[i]), y.iter().zip(s).map(|(v, s)| v / s).collect()))
        }
        Weighting::Block(cov) => {
            let (k, linv) = block_whitener(cov, m)?;
            let mut aw = Mat::zeros(m, n);
            let mut yw = vec![0.0; m];
            // Column by column, so that both matrices are read and written in memory order.
            let whiten_column = |src: &[f64], dst: &mut [f64]| {
                for g in 0..m / k {
                    let (s, d) = (&src[g * k..(g + 1) * k], &mut dst[g * k..(g + 1) * k]);
                    for r in 0..k {
                        d[r] = (0..=r).map(|c| linv[(r, c)] * s[c]).sum();
                    }
                }
            };
            let mut col = vec![0.0; m];
            for j in 0..n {
                whiten_column(a.column(j).as_slice(), &mut col);
                for (i, v) in col.iter().enumerate() {
                    aw[(i, j)] = *v;
                }
            }
            whiten_column(y.as_slice(), &mut yw);
            Ok((aw, yw))
        }
    }
}

/// `L^-1` of a block covariance `L L^T` that fits `m` rows, with the block size.
fn block_whitener(cov: &DMatrix<f64>, m: usize) -> Result<(usize, DMatrix<f64>)> {
    let k = cov.nrows();
    if k == 0 || cov.ncols() != k || !m.is_multiple_of(k) {
        return Err(LsqError::Setup(format!(
            "a {}x{} noise covariance does not fit {m} rows (groups of equal size expected)",
            cov.nrows(),
            cov.ncols()
        )));
    }
    let chol = cov
        .clone()
        .cholesky()
        .ok_or_else(|| LsqError::Setup("the noise covariance is not symmetric positive definite".into()))?;
    let linv = chol
        .l()
        .solve_lower_triangular(&DMatrix::identity(k, k))
        .ok_or_else(|| LsqError::Numeric("the noise covariance's Cholesky factor is singular".into()))?;
    Ok((k, linv))
}

/// Whitened residuals `L^-1 r` of unweighted residuals `r` (the weighting already checked).
pub(super) fn whiten_residuals(r: &DVector<f64>, w: &Weighting) -> Result<DVector<f64>> {
    Ok(match w {
        Weighting::Unit => r.clone(),
        Weighting::Sigmas(s) => DVector::from_fn(r.len(), |i, _| r[i] / s[i]),
        Weighting::Block(cov) => {
            let (k, linv) = block_whitener(cov, r.len())?;
            let mut out = DVector::zeros(r.len());
            for g in 0..r.len() / k {
                for i in 0..k {
                    out[g * k + i] = (0..=i).map(|c| linv[(i, c)] * r[g * k + c]).sum();
                }
            }
            out
        }
    })
}

/// Scales the columns of `aw` to unit norm in place; returns `h` and which columns were zero.
pub(super) fn scale_columns(aw: &mut Mat<f64>) -> (Vec<f64>, Vec<bool>) {
    let n = aw.ncols();
    let mut h = vec![1.0; n];
    let mut zero = vec![false; n];
    for j in 0..n {
        let norm = aw.col(j).norm_l2();
        if norm.is_nan() || norm <= 0.0 {
            zero[j] = true;
            continue;
        }
        h[j] = 1.0 / norm;
        for i in 0..aw.nrows() {
            aw[(i, j)] *= h[j];
        }
    }
    (h, zero)
}

/// Checks, whitens and scales a problem.
pub(super) fn prepare(
    a: &DMatrix<f64>,
    y: &DVector<f64>,
    names: &[String],
    w: &Weighting,
    policy: RankPolicy,
) -> Result<Scaled> {
    check(a, y, names, policy)?;
    let (mut aw, yw) = whiten(a, y, w)?;
    let (h, zero) = scale_columns(&mut aw);
    Ok(Scaled { a: aw, y: yw, h, zero })
}
