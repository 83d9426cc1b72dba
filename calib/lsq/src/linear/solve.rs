//! The three rank policies of [`super::fit`], the truncated SVD they share with other callers,
//! the covariance of a Jacobian and the predicted covariance of an information matrix.

use faer::linalg::solvers::SolveLstsq;
use faer::Mat;
use nalgebra::{DMatrix, DVector};

use super::prepare::{scale_columns, whiten_residuals, Scaled};
use super::{rank_deficiency, zero_column, CovarianceScale, LinearFit, LinearOptions, RankPolicy, Weighting};
use crate::identifiability::{analyze, to_faer};
use crate::{LsqError, Result};

/// The caller's problem `y = A u` with its column names and noise model.
pub(super) struct Input<'a> {
    pub a: &'a DMatrix<f64>,
    pub y: &'a DVector<f64>,
    pub names: &'a [String],
    pub w: &'a Weighting,
}

/// The `n x n` upper-triangular `R` of the (unpivoted) QR decomposition of `aw` (`m >= n`).
pub(super) fn thin_r(aw: &Mat<f64>) -> DMatrix<f64> {
    let qr = aw.qr();
    let r = qr.thin_R();
    let n = aw.ncols();
    DMatrix::from_fn(n, n, |i, j| if i <= j { r[(i, j)] } else { 0.0 })
}

/// Singular values of a matrix, descending.
fn singular_values(a: &Mat<f64>) -> Result<Vec<f64>> {
    let mut s = a.singular_values().map_err(|e| LsqError::Numeric(format!("SVD failed: {e:?}")))?;
    s.sort_by(|a, b| b.total_cmp(a));
    Ok(s)
}

/// `|R_ii|` and the column order of the QR decomposition with column pivoting of `a`.
fn pivoted_diagonal(a: &Mat<f64>) -> (Vec<f64>, Vec<usize>) {
    let qr = a.col_piv_qr();
    let r = qr.R();
    let (fwd, _) = qr.P().arrays();
    let k = a.nrows().min(a.ncols());
    ((0..k).map(|i| r[(i, i)].abs()).collect(), fwd.to_vec())
}

/// Pearson correlations of a covariance (0 where a variance is not positive and finite).
fn correlation(c: &DMatrix<f64>) -> DMatrix<f64> {
    let n = c.nrows();
    DMatrix::from_fn(n, n, |i, j| {
        let d = (c[(i, i)] * c[(j, j)]).sqrt();
        if d > 0.0 && d.is_finite() {
            c[(i, j)] / d
        } else {
            0.0
        }
    })
}

/// [`RankPolicy::Refuse`]: QR of the whitened, scaled regressor; the rank from the singular
/// values of `R`; `F^-1 = H R^-1 R^-T H`.
pub(super) fn refusing(p: &Input, s: &Scaled, opts: &LinearOptions) -> Result<LinearFit> {
    let (a, y, names) = (p.a, p.y, p.names);
    if let Some(j) = s.zero.iter().position(|z| *z) {
        return Err(zero_column(names, j));
    }
    let (aw, yw, h) = (&s.a, &s.y, &s.h);
    let (m, n) = (aw.nrows(), aw.ncols());
    let qr = aw.qr();
    let r = {
        let r = qr.thin_R();
        DMatrix::from_fn(n, n, |i, j| if i <= j { r[(i, j)] } else { 0.0 })
    };
    let r_faer = to_faer(&r);
    let singular_values = singular_values(&r_faer)?;
    let smax = singular_values[0];
    let smin = *singular_values.last().unwrap_or(&0.0);
    if smin.is_nan() || smin <= opts.rank_tolerance * smax {
        return Err(rank_deficiency(&analyze(&r, names, opts.rank_tolerance)?));
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
        .ok_or_else(|| LsqError::Numeric("the R factor is singular".into()))?;
    let fs_inv = &rinv * rinv.transpose();
    let covariance = match opts.covariance {
        CovarianceScale::APosteriori => DMatrix::from_fn(n, n, |i, j| s0 * s0 * fs_inv[(i, j)] * h[i] * h[j]),
        CovarianceScale::APriori => DMatrix::from_fn(n, n, |i, j| fs_inv[(i, j)] * h[i] * h[j]),
    };
    let std: Vec<f64> = (0..n).map(|i| covariance[(i, i)].max(0.0).sqrt()).collect();
    let rms_residual = (residuals.norm_squared() / m as f64).sqrt();
    let (r_diagonal, pivot_order) = pivoted_diagonal(&r_faer);
    Ok(LinearFit {
        names: names.to_vec(),
        values,
        std,
        covariance,
        correlation: correlation(&fs_inv),
        r_factor: r.abs(),
        column_scale: h.clone(),
        condition_number: smax / smin,
        singular_values,
        rank: n,
        rank_policy: RankPolicy::Refuse,
        dropped: Vec::new(),
        r_diagonal,
        pivot_order,
        s0,
        chi2,
        n_rows: m,
        dof,
        residuals,
        rms_residual,
    })
}

/// A truncated SVD `A H = U S V^T` of a column-scaled matrix, kept for many right-hand sides:
/// singular values below the tolerance times the largest count as zero.
#[derive(Clone, Debug)]
pub struct TruncatedSvd {
    /// `U_r`: orthonormal basis of the column space (`m x rank`).
    u: DMatrix<f64>,
    /// Every right singular vector (`n x n`; the columns after `rank` span the null space).
    v: DMatrix<f64>,
    /// Every singular value (`min(m, n)`), descending.
    s: Vec<f64>,
    /// Column scale factors.
    h: Vec<f64>,
    /// Numerical rank.
    rank: usize,
}

impl TruncatedSvd {
    /// Decomposes `a` (already whitened) after scaling its columns to unit norm (a zero column
    /// keeps scale 1 and lies in the null space).
    pub fn new(a: &DMatrix<f64>, rel_tol: f64) -> Result<Self> {
        LinearOptions::new(RankPolicy::Truncate, rel_tol).validate()?;
        if let Some(k) = a.iter().position(|v| !v.is_finite()) {
            let m = a.nrows();
            return Err(LsqError::Setup(format!("row {}, column {} is not finite", k % m + 1, k / m + 1)));
        }
        let mut fa = to_faer(a);
        let (h, _) = scale_columns(&mut fa);
        Self::of_scaled(&fa, h, rel_tol)
    }

    /// Decomposes an already scaled matrix.
    fn of_scaled(fa: &Mat<f64>, h: Vec<f64>, rel_tol: f64) -> Result<Self> {
        let (m, n) = (fa.nrows(), fa.ncols());
        let svd = if m >= n { fa.thin_svd() } else { fa.svd() }
            .map_err(|e| LsqError::Numeric(format!("SVD failed: {e:?}")))?;
        let k = m.min(n);
        let s: Vec<f64> = (0..k).map(|i| svd.S()[i]).collect();
        let smax = s.first().copied().unwrap_or(0.0);
        let rank = s.iter().filter(|v| **v > rel_tol * smax && **v > 0.0).count();
        let (fu, fv) = (svd.U(), svd.V());
        let u = DMatrix::from_fn(m, rank, |i, c| fu[(i, c)]);
        let v = DMatrix::from_fn(n, fv.ncols(), |i, c| fv[(i, c)]);
        Ok(Self { u, v, s, h, rank })
    }

    /// Numerical rank.
    pub fn rank(&self) -> usize {
        self.rank
    }

    /// Every singular value of the scaled matrix, descending.
    pub fn singular_values(&self) -> &[f64] {
        &self.s
    }

    /// Column scale factors `h_l`.
    pub fn column_scale(&self) -> &[f64] {
        &self.h
    }

    /// `U_r`: an orthonormal basis of the column space (`m x rank`).
    pub fn range_basis(&self) -> &DMatrix<f64> {
        &self.u
    }

    /// `sigma_max / sigma_rank` (infinite at rank 0).
    pub fn condition_number(&self) -> f64 {
        if self.rank > 0 {
            self.s[0] / self.s[self.rank - 1]
        } else {
            f64::INFINITY
        }
    }

    /// The norm of column `i`'s row of the null-space basis (0: determined by the data).
    pub fn null_component(&self, i: usize) -> f64 {
        (self.rank..self.v.ncols()).map(|c| self.v[(i, c)] * self.v[(i, c)]).sum::<f64>().sqrt()
    }

    /// The pseudo-inverse in the unscaled parameters, `H V_r S_r^-1 U_r^T` (`n x m`).
    pub fn pseudo_inverse(&self) -> DMatrix<f64> {
        let n = self.v.nrows();
        let vs = DMatrix::from_fn(n, self.rank, |i, c| self.h[i] * self.v[(i, c)] / self.s[c]);
        vs * self.u.transpose()
    }

    /// Minimum-norm least-squares solutions (unscaled) for every column of `b`.
    pub fn solve(&self, b: &DMatrix<f64>) -> DMatrix<f64> {
        let utb = self.u.transpose() * b;
        let n = self.v.nrows();
        DMatrix::from_fn(n, b.ncols(), |i, k| {
            (0..self.rank).map(|c| self.h[i] * self.v[(i, c)] * utb[(c, k)] / self.s[c]).sum()
        })
    }

    /// The part of every column of `b` outside the column space: `b - U_r U_r^T b` (the
    /// least-squares residuals).
    pub fn project_out(&self, b: &DMatrix<f64>) -> DMatrix<f64> {
        b - &self.u * (self.u.transpose() * b)
    }
}

/// [`RankPolicy::Truncate`]: the minimum-norm solution `x = H V_r S_r^-1 U_r^T y` and the
/// covariance over the determined directions.
pub(super) fn truncated(p: &Input, s: &Scaled, opts: &LinearOptions) -> Result<LinearFit> {
    let (a, y, names, w) = (p.a, p.y, p.names, p.w);
    let (m, p) = (s.a.nrows(), s.a.ncols());
    let t = TruncatedSvd::of_scaled(&s.a, s.h.clone(), opts.rank_tolerance)?;
    let (rank, u, v, sv, scale) = (t.rank, &t.u, &t.v, &t.s, &s.h);
    // x_s = V_r S_r^-1 U_r^T y.
    let mut xs = vec![0.0; p];
    for c in 0..rank {
        let uty: f64 = (0..m).map(|i| u[(i, c)] * s.y[i]).sum();
        let f = uty / sv[c];
        for (r, x) in xs.iter_mut().enumerate() {
            *x += v[(r, c)] * f;
        }
    }
    let values: Vec<f64> = xs.iter().zip(scale).map(|(x, s)| x * s).collect();
    let mut cov = DMatrix::<f64>::zeros(p, p);
    for c in 0..rank {
        let w = 1.0 / (sv[c] * sv[c]);
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
    let residuals = y - a * DVector::from_column_slice(&values);
    let chi2 = whiten_residuals(&residuals, w)?.norm_squared();
    let dof = m.saturating_sub(rank).max(1);
    let s0 = (chi2 / dof as f64).sqrt();
    if opts.covariance == CovarianceScale::APosteriori {
        cov *= s0 * s0;
    }
    let std: Vec<f64> = (0..p)
        .map(|i| if t.null_component(i) > 1e-6 || s.zero[i] { f64::INFINITY } else { cov[(i, i)].max(0.0).sqrt() })
        .collect();
    // R of A H = U (S V^T): the QR of S V^T.
    let k = sv.len();
    let svt = Mat::from_fn(k, p, |i, j| sv[i] * v[(j, i)]);
    let r = {
        let qr = svt.qr();
        let r = qr.R();
        DMatrix::from_fn(p, p, |i, j| if i <= j && i < k { r[(i, j)].abs() } else { 0.0 })
    };
    let (r_diagonal, pivot_order) = pivoted_diagonal(&svt);
    Ok(LinearFit {
        names: names.to_vec(),
        values,
        std,
        correlation: correlation(&cov),
        covariance: cov,
        r_factor: r,
        column_scale: scale.clone(),
        singular_values: sv.clone(),
        condition_number: t.condition_number(),
        rank,
        rank_policy: RankPolicy::Truncate,
        dropped: Vec::new(),
        r_diagonal,
        pivot_order,
        s0,
        chi2,
        n_rows: m,
        dof,
        rms_residual: (residuals.norm_squared() / m as f64).sqrt(),
        residuals,
    })
}

/// [`RankPolicy::DropPivoted`]: QR with column pivoting chooses the columns to keep (the first
/// `rank` pivots, `|R_ii| > tol |R_11|`); they are fitted by the refusing QR, the others held at
/// zero.
pub(super) fn drop_pivoted(p: &Input, s: &Scaled, opts: &LinearOptions) -> Result<LinearFit> {
    let (a, y, names, w) = (p.a, p.y, p.names, p.w);
    let (m, n) = (s.a.nrows(), s.a.ncols());
    let (r_diagonal, pivot_order) = pivoted_diagonal(&s.a);
    let first = r_diagonal.first().copied().unwrap_or(0.0);
    let rank = r_diagonal.iter().take_while(|d| **d > opts.rank_tolerance * first && **d > 0.0).count();
    if rank == 0 {
        return Err(LsqError::RankDeficient {
            rank: 0,
            n_params: n,
            no_effect: names.to_vec(),
            coupled: Vec::new(),
            message: "no column of the regressor has an effect on these data".into(),
        });
    }
    if m <= rank {
        return Err(LsqError::TooFew(format!(
            "{m} equations cannot identify {rank} parameters with redundancy: measure more poses or samples"
        )));
    }
    let mut kept: Vec<usize> = pivot_order[..rank].to_vec();
    kept.sort_unstable();
    let mut dropped: Vec<usize> = pivot_order[rank..].to_vec();
    dropped.sort_unstable();
    // The kept columns, fitted with full rank by the refusing QR (tolerance 0: the pivoting has
    // decided).
    let sub_a = DMatrix::from_fn(m, rank, |i, j| a[(i, kept[j])]);
    let sub_names: Vec<String> = kept.iter().map(|&j| names[j].clone()).collect();
    let sub_opts = LinearOptions { rank_policy: RankPolicy::Refuse, rank_tolerance: 0.0, ..*opts };
    let sub = super::prepare::prepare(&sub_a, y, &sub_names, w, RankPolicy::Refuse)?;
    let f = refusing(&Input { a: &sub_a, y, names: &sub_names, w }, &sub, &sub_opts)?;
    let mut values = vec![0.0; n];
    let mut std = vec![f64::INFINITY; n];
    let mut covariance = DMatrix::zeros(n, n);
    let mut r_factor = DMatrix::zeros(n, n);
    let mut column_scale = vec![1.0; n];
    for (k, &j) in kept.iter().enumerate() {
        values[j] = f.values[k];
        std[j] = f.std[k];
        column_scale[j] = s.h[j];
        for (l, &i) in kept.iter().enumerate() {
            covariance[(j, i)] = f.covariance[(k, l)];
            r_factor[(j, i)] = f.r_factor[(k, l)];
        }
    }
    for &j in &dropped {
        column_scale[j] = s.h[j];
    }
    let dof = m - rank;
    Ok(LinearFit {
        names: names.to_vec(),
        values,
        std,
        correlation: correlation(&covariance),
        covariance,
        r_factor,
        column_scale,
        singular_values: f.singular_values,
        condition_number: f.condition_number,
        rank,
        rank_policy: RankPolicy::DropPivoted,
        dropped,
        r_diagonal,
        pivot_order,
        s0: f.s0,
        chi2: f.chi2,
        n_rows: m,
        dof,
        residuals: f.residuals,
        rms_residual: f.rms_residual,
    })
}

/// Covariance of the parameters from the Jacobian of whitened residuals at a least-squares
/// solution: `s0^2 (J^T J)^-1` with `s0^2 = |r|^2 / (m - n)`, through the QR decomposition of
/// the column-scaled Jacobian (`(J^T J)^-1 = H R^-1 R^-T H`, never forming `J^T J`). Refuses a
/// Jacobian whose scaled singular values fall below `1e-9` of the largest. Returns the
/// covariance and `s0`.
pub fn jacobian_covariance(jacobian: &DMatrix<f64>, residuals: &DVector<f64>) -> Result<(DMatrix<f64>, f64)> {
    let (m, n) = jacobian.shape();
    if m <= n {
        return Err(LsqError::TooFew(format!("{m} residuals cannot give the covariance of {n} parameters")));
    }
    if residuals.len() != m {
        return Err(LsqError::Setup(format!("{} residuals for a Jacobian of {m} rows", residuals.len())));
    }
    let s0 = (residuals.norm_squared() / (m - n) as f64).sqrt();
    let singular = |detail: String| {
        LsqError::Numeric(format!("the Jacobian is rank-deficient ({detail}): some parameters are not identifiable"))
    };
    let mut fa = to_faer(jacobian);
    let (h, zero) = scale_columns(&mut fa);
    if let Some(j) = zero.iter().position(|z| *z) {
        return Err(singular(format!("column {} is zero", j + 1)));
    }
    let r = thin_r(&fa);
    let sv = singular_values(&to_faer(&r))?;
    let (smax, smin) = (sv[0], sv[n - 1]);
    if smin.is_nan() || smin <= 1e-9 * smax {
        return Err(singular(format!("scaled singular values {smax:.3e} .. {smin:.3e}")));
    }
    let rinv = r
        .solve_upper_triangular(&DMatrix::identity(n, n))
        .ok_or_else(|| LsqError::Numeric("the R factor is singular".into()))?;
    let fs_inv = &rinv * rinv.transpose();
    let cov = DMatrix::from_fn(n, n, |i, j| s0 * s0 * fs_inv[(i, j)] * h[i] * h[j]);
    Ok((cov, s0))
}

/// The covariance `F^-1` that a design with information `F = A^T W A` (whitened rows, unit
/// noise after whitening) predicts, before any data; `None` when `F` is singular. Inverted by
/// Cholesky after equilibration (`D^-1 F D^-1`, `D = sqrt(diag F)`).
pub fn predicted_covariance(information: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    let n = information.nrows();
    let d = equilibration(information)?;
    let scaled = DMatrix::from_fn(n, n, |i, j| information[(i, j)] / (d[i] * d[j]));
    let inv = scaled.cholesky()?.inverse();
    Some(DMatrix::from_fn(n, n, |i, j| inv[(i, j)] / (d[i] * d[j])))
}

/// The predicted standard deviations `sqrt(diag(F^-1))` of a design (see
/// [`predicted_covariance`]); `None` when singular.
pub fn predicted_std(information: &DMatrix<f64>) -> Option<Vec<f64>> {
    let n = information.nrows();
    let d = equilibration(information)?;
    let scaled = DMatrix::from_fn(n, n, |i, j| information[(i, j)] / (d[i] * d[j]));
    let inv = scaled.cholesky()?.inverse();
    Some((0..n).map(|i| inv[(i, i)].max(0.0).sqrt() / d[i]).collect())
}

fn equilibration(information: &DMatrix<f64>) -> Option<Vec<f64>> {
    let n = information.nrows();
    let d: Vec<f64> = (0..n).map(|i| information[(i, i)].max(0.0).sqrt()).collect();
    if d.iter().any(|v| v.is_nan() || *v <= 0.0) {
        return None;
    }
    Some(d)
}
