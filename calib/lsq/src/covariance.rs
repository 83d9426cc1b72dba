//! Covariance of a least-squares result: dense, and with local blocks marginalised by the Schur
//! complement (the camera and rig parameters of a bundle adjustment without its many poses).

use nalgebra::{DMatrix, DVector};

use crate::{LsqError, Result};

/// Covariance of the parameters from the Jacobian of whitened residuals: `s0^2 (J^T J)^-1` with
/// `s0^2 = |r|^2 / (m - n)` (the a-posteriori variance factor; 1 when the noise model is right),
/// computed by the linear least-squares routine ([`crate::linear::jacobian_covariance`]: QR of
/// the column-scaled Jacobian). Returns the covariance and `s0`.
pub fn covariance(jacobian: &DMatrix<f64>, residuals: &DVector<f64>) -> Result<(DMatrix<f64>, f64)> {
    crate::linear::jacobian_covariance(jacobian, residuals)
}

/// Covariance of the *global* columns `0..n_global` of `J` with every other column marginalised,
/// the others being grouped in independent *local* blocks (`local_sizes`, consecutive after the
/// global columns, each block touched by its own residual rows plus the global ones, as the poses
/// of a bundle adjustment are). Uses the Schur complement `S = A - B D^-1 B^T` of the normal
/// matrix with `D` block-diagonal, so the cost is linear in the number of local blocks; the
/// result equals the global corner of the dense inverse (tested). Scaled by `s0^2` as
/// [`covariance`] is; returns it and `s0`.
pub fn schur_covariance(
    jacobian: &DMatrix<f64>,
    residuals: &DVector<f64>,
    n_global: usize,
    local_sizes: &[usize],
) -> Result<(DMatrix<f64>, f64)> {
    let (m, n) = jacobian.shape();
    if n_global + local_sizes.iter().sum::<usize>() != n {
        return Err(LsqError::Setup(format!(
            "{n_global} global and {} local columns, but the Jacobian has {n}",
            local_sizes.iter().sum::<usize>()
        )));
    }
    if m <= n {
        return Err(LsqError::TooFew(format!("{m} residuals cannot give the covariance of {n} parameters")));
    }
    let s0 = (residuals.norm_squared() / (m - n) as f64).sqrt();
    let jg = jacobian.columns(0, n_global);
    let mut s = jg.transpose() * jg;
    let mut start = n_global;
    for &k in local_sizes {
        let jl = jacobian.columns(start, k);
        let d = jl.transpose() * jl;
        let b = jg.transpose() * jl;
        let dinv = d.cholesky().ok_or_else(|| {
            LsqError::Numeric(format!("local block at column {start} is singular: it is not determined by its rows"))
        })?;
        s -= &b * dinv.solve(&b.transpose());
        start += k;
    }
    let dg: Vec<f64> = (0..n_global).map(|c| s[(c, c)].sqrt().max(1e-300)).collect();
    let scaled = DMatrix::from_fn(n_global, n_global, |i, j| s[(i, j)] / (dg[i] * dg[j]));
    let inv = scaled
        .cholesky()
        .ok_or_else(|| {
            LsqError::Numeric(
                "the reduced normal matrix is singular: some global parameters are not identifiable".into(),
            )
        })?
        .inverse();
    let cov = DMatrix::from_fn(n_global, n_global, |i, j| inv[(i, j)] * s0 * s0 / (dg[i] * dg[j]));
    Ok((cov, s0))
}
