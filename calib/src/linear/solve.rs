//! Weighted linear least squares `f = A u` with column scaling, the a-posteriori variance
//! factor, covariance, Pearson correlations and the R factor of the QR decomposition
//! (Friedrich & Ihlenfeldt; Gauss-Markov as in Abdellatif & Heimann).
//!
//! 1. Whitening: with the noise covariance `S` of the measurements (unit, one standard deviation
//!    per row, or one full `k x k` covariance for every group of `k` rows, e.g. six
//!    cross-correlated sensor channels), rows are multiplied by `L^-1` (`S = L L^T`), so
//!    `W = S^-1` and the estimate `u = (A^T W A)^-1 A^T W f` is the Gauss-Markov one.
//! 2. Column scaling `h_l = 1 / ||a_l||` of the whitened regressor, so that the numbers below do
//!    not depend on the parameters' units.
//! 3. QR of the scaled regressor (faer); the rank comes from the singular values of `R`; a
//!    rank-deficient regressor is refused with the parameters that cannot be told apart named
//!    (see [`crate::identifiability`]).
//! 4. `s0 = sqrt(chi^2 / (m - u))`, covariance `s0^2 F^-1` with `F = A^T W A`
//!    (`F^-1 = H R^-1 R^-T H`), Pearson correlations `C_ij / sqrt(C_ii C_jj)` and `|R_ij|` (the
//!    columns of `R` have unit norm after scaling, so `|R_jj|` is the sine of the angle between
//!    column `j` and the span of the columns before it).

use faer::linalg::solvers::SolveLstsq;
use faer::Mat;
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use crate::error::{CalibError, Result};
use crate::identifiability::{analyze, Identifiability, ParamClass};

/// The noise model of the measurements.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Weighting {
    /// Unit weights (ordinary least squares; `s0` is then the residual RMS in the
    /// measurements' unit).
    Unit,
    /// One standard deviation per row.
    Sigmas(Vec<f64>),
    /// One covariance (`k x k`, symmetric positive definite) for every consecutive group of `k`
    /// rows.
    Block(DMatrix<f64>),
}

/// Options of [`fit`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FitOptions {
    /// A scaled singular value below `rank_tolerance * sigma_max` counts as zero.
    pub rank_tolerance: f64,
}

impl Default for FitOptions {
    fn default() -> Self {
        Self { rank_tolerance: 1e-9 }
    }
}

/// The result of [`fit`].
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct LinearFit {
    /// Parameter names.
    pub names: Vec<String>,
    /// Estimates.
    pub values: Vec<f64>,
    /// Standard deviations `sqrt(diag(s0^2 F^-1))`.
    pub std: Vec<f64>,
    /// Covariance `s0^2 F^-1`.
    pub covariance: DMatrix<f64>,
    /// Pearson correlations.
    pub correlation: DMatrix<f64>,
    /// `|R|` of the QR decomposition of the whitened, column-scaled regressor (upper triangle).
    pub r_factor: DMatrix<f64>,
    /// Column scale factors `h_l = 1 / ||a_l||` (whitened).
    pub column_scale: Vec<f64>,
    /// Singular values of the whitened, scaled regressor, descending.
    pub singular_values: Vec<f64>,
    /// `sigma_max / sigma_min` of the whitened, scaled regressor.
    pub condition_number: f64,
    /// A-posteriori variance factor `sqrt(chi^2 / (m - u))`.
    pub s0: f64,
    /// Weighted squared residual sum.
    pub chi2: f64,
    /// Rows.
    pub n_rows: usize,
    /// Redundancy `m - u`.
    pub dof: usize,
    /// Residuals `f - A u` (unweighted, the measurements' unit).
    pub residuals: DVector<f64>,
    /// RMS of the unweighted residuals.
    pub rms_residual: f64,
}

impl LinearFit {
    /// Index of a parameter by name.
    pub fn index(&self, name: &str) -> Option<usize> {
        self.names.iter().position(|n| n == name)
    }

    /// Estimate and standard deviation of a parameter by name.
    pub fn get(&self, name: &str) -> Option<(f64, f64)> {
        self.index(name).map(|i| (self.values[i], self.std[i]))
    }

    /// Predictions `A u` for another regressor with the same columns.
    pub fn predict(&self, a: &DMatrix<f64>) -> Result<DVector<f64>> {
        if a.ncols() != self.values.len() {
            return Err(CalibError::Data(format!(
                "a regressor with {} columns cannot use a fit of {} parameters",
                a.ncols(),
                self.values.len()
            )));
        }
        Ok(a * DVector::from_column_slice(&self.values))
    }
}

/// Whitens `a` and `y` (see the module documentation); returns faer matrices.
fn whiten(a: &DMatrix<f64>, y: &DVector<f64>, w: &Weighting) -> Result<(Mat<f64>, Vec<f64>)> {
    let (m, n) = a.shape();
    match w {
        Weighting::Unit => Ok((Mat::from_fn(m, n, |i, j| a[(i, j)]), y.iter().copied().collect())),
        Weighting::Sigmas(s) => {
            if s.len() != m {
                return Err(CalibError::Data(format!("{} standard deviations for {m} rows", s.len())));
            }
            if let Some(k) = s.iter().position(|v| !(v.is_finite() && *v > 0.0)) {
                return Err(CalibError::Data(format!(
                    "row {}: standard deviation {} is not positive and finite",
                    k + 1,
                    s[k]
                )));
            }
            Ok((Mat::from_fn(m, n, |i, j| a[(i, j)] / s[i]), y.iter().zip(s).map(|(v, s)| v / s).collect()))
        }
        Weighting::Block(cov) => {
            let k = cov.nrows();
            if k == 0 || cov.ncols() != k || !m.is_multiple_of(k) {
                return Err(CalibError::Data(format!(
                    "a {}x{} noise covariance does not fit {m} rows (groups of equal size expected)",
                    cov.nrows(),
                    cov.ncols()
                )));
            }
            let chol = cov
                .clone()
                .cholesky()
                .ok_or_else(|| CalibError::Data("the noise covariance is not symmetric positive definite".into()))?;
            let l = chol.l();
            let linv = l
                .solve_lower_triangular(&DMatrix::identity(k, k))
                .ok_or_else(|| CalibError::Numeric("the noise covariance's Cholesky factor is singular".into()))?;
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

/// Checks shapes and values of a problem.
fn check_problem(a: &DMatrix<f64>, y: &DVector<f64>, names: &[String]) -> Result<()> {
    let (m, n) = a.shape();
    if names.len() != n {
        return Err(CalibError::Data(format!("{} names for {n} regressor columns", names.len())));
    }
    if y.len() != m {
        return Err(CalibError::Data(format!("{} measurements for {m} regressor rows", y.len())));
    }
    if n == 0 {
        return Err(CalibError::Data("no parameters to identify".into()));
    }
    if m <= n {
        return Err(CalibError::TooFew(format!(
            "{m} equations cannot identify {n} parameters with redundancy: measure more poses or samples"
        )));
    }
    if let Some(k) = a.iter().position(|v| !v.is_finite()) {
        return Err(CalibError::Data(format!("regressor row {}, column '{}' is not finite", k % m + 1, names[k / m])));
    }
    if let Some(k) = y.iter().position(|v| !v.is_finite()) {
        return Err(CalibError::Data(format!("measurement {} is not finite", k + 1)));
    }
    Ok(())
}

/// Whitened and column-scaled regressor with its scale factors; fails on a zero column.
fn scaled(
    a: &DMatrix<f64>,
    y: &DVector<f64>,
    names: &[String],
    w: &Weighting,
) -> Result<(Mat<f64>, Vec<f64>, Vec<f64>)> {
    check_problem(a, y, names)?;
    let (mut aw, yw) = whiten(a, y, w)?;
    let n = a.ncols();
    let mut h = vec![0.0; n];
    for (j, hj) in h.iter_mut().enumerate() {
        let norm = aw.col(j).norm_l2();
        if norm.is_nan() || norm <= 0.0 {
            return Err(CalibError::TooFew(format!(
                "parameter '{}' has no effect on these data (its regressor column is zero): the model is not identifiable from them; drop the parameter or excite it",
                names[j]
            )));
        }
        *hj = 1.0 / norm;
        for i in 0..aw.nrows() {
            aw[(i, j)] *= *hj;
        }
    }
    Ok((aw, yw, h))
}

/// The identifiability of a regressor under a noise model (whitened and column-scaled), without
/// fitting: for reports of models that are not identifiable.
pub fn analyse(a: &DMatrix<f64>, names: &[String], w: &Weighting, rel_tol: f64) -> Result<Identifiability> {
    let y = DVector::zeros(a.nrows());
    let (aw, _, _) = scaled(a, &y, names, w)?;
    let r = thin_r(&aw);
    analyze(&r, names, rel_tol)
}

fn thin_r(aw: &Mat<f64>) -> DMatrix<f64> {
    let qr = aw.qr();
    let r = qr.thin_R();
    let n = aw.ncols();
    DMatrix::from_fn(n, n, |i, j| if i <= j { r[(i, j)] } else { 0.0 })
}

/// The message of a rank-deficient regressor, naming the parameters involved.
pub fn rank_message(id: &Identifiability) -> String {
    let n = id.names.len();
    let mut parts = Vec::new();
    let dead: Vec<&str> = id
        .classes
        .iter()
        .enumerate()
        .filter(|(_, c)| **c == ParamClass::NotIdentifiable)
        .map(|(i, _)| id.names[i].as_str())
        .collect();
    if !dead.is_empty() {
        parts.push(format!("no effect: {}", dead.join(", ")));
    }
    for g in &id.groups {
        let members: Vec<&str> = g.params.iter().map(|&i| id.names[i].as_str()).collect();
        let shown = if members.len() > 8 {
            format!("{} and {} more", members[..8].join(", "), members.len() - 8)
        } else {
            members.join(", ")
        };
        parts.push(format!("{} combination(s) of {{{shown}}} cannot be told apart", g.deficiency.max(1)));
    }
    format!(
        "the regressor has rank {} for {n} parameters on these data ({}): the model is not identifiable from them; choose a model without the redundant terms or data that separate them",
        id.rank,
        parts.join("; ")
    )
}

/// Fits `y = A u` (see the module documentation). Fails with a message that names the
/// parameters involved when the whitened regressor is rank-deficient.
pub fn fit(
    a: &DMatrix<f64>,
    y: &DVector<f64>,
    names: &[String],
    w: &Weighting,
    opts: &FitOptions,
) -> Result<LinearFit> {
    let (aw, yw, h) = scaled(a, y, names, w)?;
    let (m, n) = (aw.nrows(), aw.ncols());
    let qr = aw.qr();
    let r = {
        let r = qr.thin_R();
        DMatrix::from_fn(n, n, |i, j| if i <= j { r[(i, j)] } else { 0.0 })
    };
    let sv = r.clone().svd(false, false).singular_values;
    let mut singular_values: Vec<f64> = sv.iter().copied().collect();
    singular_values.sort_by(|a, b| b.total_cmp(a));
    let smax = singular_values[0];
    let smin = *singular_values.last().unwrap_or(&0.0);
    if smin.is_nan() || smin <= opts.rank_tolerance * smax {
        let id = analyze(&r, names, opts.rank_tolerance)?;
        return Err(CalibError::TooFew(rank_message(&id)));
    }
    let rhs = Mat::from_fn(m, 1, |i, _| yw[i]);
    let z = qr.solve_lstsq(&rhs);
    let values: Vec<f64> = (0..n).map(|j| z[(j, 0)] * h[j]).collect();
    let u = DVector::from_column_slice(&values);
    let residuals = y - a * &u;
    // Weighted residuals from the whitened system, column by column.
    let mut res = yw.clone();
    for j in 0..n {
        let zj = z[(j, 0)];
        for (i, r) in res.iter_mut().enumerate() {
            *r -= aw[(i, j)] * zj;
        }
    }
    let chi2: f64 = res.iter().map(|r| r * r).sum();
    let dof = m - n;
    let s0 = (chi2 / dof as f64).sqrt();
    let rinv = r
        .solve_upper_triangular(&DMatrix::identity(n, n))
        .ok_or_else(|| CalibError::Numeric("the R factor is singular".into()))?;
    let fs_inv = &rinv * rinv.transpose();
    let covariance = DMatrix::from_fn(n, n, |i, j| s0 * s0 * fs_inv[(i, j)] * h[i] * h[j]);
    let std: Vec<f64> = (0..n).map(|i| covariance[(i, i)].max(0.0).sqrt()).collect();
    let correlation = DMatrix::from_fn(n, n, |i, j| {
        let d = (fs_inv[(i, i)] * fs_inv[(j, j)]).sqrt();
        if d > 0.0 {
            fs_inv[(i, j)] / d
        } else {
            0.0
        }
    });
    let rms_residual = (residuals.norm_squared() / m as f64).sqrt();
    Ok(LinearFit {
        names: names.to_vec(),
        values,
        std,
        covariance,
        correlation,
        r_factor: r.abs(),
        column_scale: h,
        condition_number: smax / smin,
        singular_values,
        s0,
        chi2,
        n_rows: m,
        dof,
        residuals,
        rms_residual,
    })
}

/// The predicted standard deviations `sigma * sqrt(diag(F^-1))` of a design (whitened
/// regressor rows, unit noise after whitening) without data; `None` when singular.
pub fn predicted_std(information: &DMatrix<f64>) -> Option<Vec<f64>> {
    let n = information.nrows();
    let d: Vec<f64> = (0..n).map(|i| information[(i, i)].max(0.0).sqrt()).collect();
    if d.iter().any(|v| v.is_nan() || *v <= 0.0) {
        return None;
    }
    let scaled = DMatrix::from_fn(n, n, |i, j| information[(i, j)] / (d[i] * d[j]));
    let inv = scaled.cholesky()?.inverse();
    Some((0..n).map(|i| inv[(i, i)].max(0.0).sqrt() / d[i]).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_a_line_with_its_standard_deviation() {
        let m = 200;
        let a = DMatrix::from_fn(m, 2, |i, j| if j == 0 { 1.0 } else { i as f64 * 0.01 });
        // Deterministic "noise" with zero mean and no trend.
        let noise: Vec<f64> = (0..m).map(|i| if i % 2 == 0 { 0.1 } else { -0.1 }).collect();
        let y = DVector::from_fn(m, |i, _| 3.0 + 2.0 * a[(i, 1)] + noise[i]);
        let names = vec!["b".to_string(), "k".to_string()];
        let f = fit(&a, &y, &names, &Weighting::Unit, &FitOptions::default()).unwrap();
        assert!((f.values[0] - 3.0).abs() < 0.05 && (f.values[1] - 2.0).abs() < 0.05, "{:?}", f.values);
        assert!((f.s0 - 0.1).abs() < 0.01, "s0 {}", f.s0);
        // Textbook std of the slope: s0 / sqrt(sum (x - mean)^2).
        let xm: f64 = (0..m).map(|i| a[(i, 1)]).sum::<f64>() / m as f64;
        let sxx: f64 = (0..m).map(|i| (a[(i, 1)] - xm).powi(2)).sum();
        assert!((f.std[1] - f.s0 / sxx.sqrt()).abs() < 1e-9 * f.std[1].max(1.0));
        assert!((f.correlation[(0, 0)] - 1.0).abs() < 1e-12);
    }

    #[test]
    fn block_weights_equal_explicit_gauss_markov() {
        let m = 60;
        let a = DMatrix::from_fn(m, 3, |i, j| ((i * 7 + j * 3) % 11) as f64 - 5.0 + j as f64 * 0.3);
        let y = DVector::from_fn(m, |i, _| (i as f64 * 0.37).sin());
        let cov = DMatrix::from_row_slice(3, 3, &[2.0, 0.5, 0.1, 0.5, 1.0, -0.2, 0.1, -0.2, 0.5]);
        let names: Vec<String> = (0..3).map(|i| format!("p{i}")).collect();
        let f = fit(&a, &y, &names, &Weighting::Block(cov.clone()), &FitOptions::default()).unwrap();
        let wi = cov.try_inverse().unwrap();
        let mut w = DMatrix::zeros(m, m);
        for g in 0..m / 3 {
            w.view_mut((3 * g, 3 * g), (3, 3)).copy_from(&wi);
        }
        let u = (a.transpose() * &w * &a).try_inverse().unwrap() * a.transpose() * &w * &y;
        for j in 0..3 {
            assert!((u[j] - f.values[j]).abs() < 1e-9, "{u} vs {:?}", f.values);
        }
    }

    #[test]
    fn rank_deficiency_names_the_parameters() {
        let m = 30;
        let a = DMatrix::from_fn(m, 3, |i, j| match j {
            0 => i as f64,
            _ => 1.0,
        });
        let y = DVector::from_fn(m, |i, _| i as f64);
        let names: Vec<String> = ["slope", "offset_a", "offset_b"].iter().map(|s| s.to_string()).collect();
        let e = fit(&a, &y, &names, &Weighting::Unit, &FitOptions::default()).unwrap_err().to_string();
        assert!(e.contains("rank 2") && e.contains("offset_a") && e.contains("offset_b"), "{e}");
        assert!(!e.contains("slope,"), "{e}");
    }
}
