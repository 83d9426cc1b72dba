//! Linear least squares with covariance: the one routine behind every linear identification of
//! the project (force-sensor models and dynamics, compliance, the diagnose's linearised screen)
//! and behind the covariance of every non-linear fit ([`crate::covariance`]).
//!
//! [`fit`] solves `y = A u` in these steps (Gauss-Markov; Friedrich & Ihlenfeldt 2021, the
//! methods' section 5):
//!
//! 1. **Whitening** by the noise model ([`Weighting`]): unit weights, one standard deviation per
//!    row, or one covariance `S = L L^T` for every group of `k` rows (`k = m`: one full
//!    covariance); rows are multiplied by `L^-1`, so `W = S^-1` and the estimate is
//!    `u = (A^T W A)^-1 A^T W y`.
//! 2. **Column scaling** `h_l = 1 / ||a_l||` of the whitened regressor, so that conditioning and
//!    rank do not depend on the parameters' units.
//! 3. A **decomposition with an explicit rank policy** ([`RankPolicy`]): a QR decomposition that
//!    refuses a rank-deficient regressor and names the columns that have no effect or cannot be
//!    told apart; a truncated SVD (minimum-norm solution, infinite standard deviation for the
//!    directions the data do not determine); or a QR with column pivoting that holds the columns
//!    beyond the numerical rank at zero and names them.
//! 4. **Results** in the caller's (unscaled) parameters: `s0 = sqrt(chi^2 / (m - rank))`, the
//!    covariance `s0^2 (A^T W A)^-1` (or `(A^T W A)^-1` when the noise model is taken as right:
//!    [`CovarianceScale`]), standard deviations, Pearson correlations, `|R|` of the QR
//!    decomposition (unit-norm columns: `|R_jj|` is the sine of the angle between column `j` and
//!    the span of the columns before it), and the **identifiability** from the pivoted QR's `R`
//!    diagonal (a column whose `|R_ii|` falls below the tolerance times the first is not
//!    identifiable; methods section 3), with a summary of the decomposition (rank, singular
//!    values, condition number).
//!
//! [`TruncatedSvd`] keeps the truncated decomposition of one matrix for many right-hand sides
//! (the diagnose's screen fits hundreds of candidate columns against one Jacobian), and
//! [`predicted_std`] / [`predicted_covariance`] give the same covariance from an information
//! matrix `A^T W A` before any data exist (experiment design).
//!
//! Dense decompositions are faer's (QR, QR with column pivoting, SVD): one library for every
//! decomposition here, the one the architecture names for identifiability and linear
//! identification; matrices come in and go out as nalgebra's `DMatrix`, the project's type.

mod prepare;
mod solve;
#[cfg(test)]
mod tests;

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use crate::identifiability::{analyze, Identifiability, ParamClass};
use crate::{LsqError, Result};

pub use solve::{jacobian_covariance, predicted_covariance, predicted_std, TruncatedSvd};

/// The noise model of the measurements.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Weighting {
    /// Unit weights (ordinary least squares; `s0` is then the residual RMS in the
    /// measurements' unit). Also for rows the caller has whitened already.
    Unit,
    /// One standard deviation per row (a diagonal covariance).
    Sigmas(Vec<f64>),
    /// One covariance (`k x k`, symmetric positive definite) for every consecutive group of `k`
    /// rows; `k = m` is one full covariance of all rows.
    Block(DMatrix<f64>),
}

/// What to do when the whitened, column-scaled regressor does not have full column rank.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RankPolicy {
    /// Refuse with [`LsqError::RankDeficient`], naming the columns without effect and the groups
    /// that cannot be told apart (QR; the identification of physical parameters, where a
    /// minimum-norm answer would be silently wrong). Needs `m > n`.
    #[default]
    Refuse,
    /// Truncate singular values below the tolerance: the minimum-norm solution, whose
    /// predictions for rows like the measured ones are still unique; a parameter with a
    /// component along an undetermined direction gets an infinite standard deviation (SVD;
    /// compliance reduction, the diagnose's screen).
    Truncate,
    /// QR with column pivoting: the columns after the numerical rank in pivot order are held at
    /// zero (their estimate 0, standard deviation infinite, covariance rows zero) and listed in
    /// [`LinearFit::dropped`]; the others are fitted (Dressler's choice of which parameters to
    /// keep). Needs `m > rank`.
    DropPivoted,
}

/// Which covariance [`fit`] reports.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CovarianceScale {
    /// `s0^2 (A^T W A)^-1`: scaled by the a-posteriori variance factor (the noise level taken
    /// from the residuals).
    #[default]
    APosteriori,
    /// `(A^T W A)^-1`: the noise model's standard deviations taken as right (`s0` is then a
    /// check of them: 1 when right). Klimchik's parameter-to-noise ratios use this.
    APriori,
}

/// Options of [`fit`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct LinearOptions {
    /// The rank policy.
    pub rank_policy: RankPolicy,
    /// Relative tolerance of the rank: a singular value (for [`RankPolicy::DropPivoted`]: a
    /// pivoted `|R_ii|`) below `rank_tolerance` times the largest counts as zero.
    pub rank_tolerance: f64,
    /// Which covariance to report.
    pub covariance: CovarianceScale,
}

impl Default for LinearOptions {
    fn default() -> Self {
        Self { rank_policy: RankPolicy::Refuse, rank_tolerance: 1e-9, covariance: CovarianceScale::APosteriori }
    }
}

impl LinearOptions {
    /// Options with a rank policy and tolerance, the a-posteriori covariance.
    pub fn new(rank_policy: RankPolicy, rank_tolerance: f64) -> Self {
        Self { rank_policy, rank_tolerance, covariance: CovarianceScale::APosteriori }
    }

    /// Checks the tolerance (finite, in `[0, 1)`).
    pub fn validate(&self) -> Result<()> {
        if !(self.rank_tolerance.is_finite() && (0.0..1.0).contains(&self.rank_tolerance)) {
            return Err(LsqError::Setup(format!("the rank tolerance must lie in [0, 1), got {}", self.rank_tolerance)));
        }
        Ok(())
    }
}

/// The result of [`fit`]: estimates, their covariance and the summary of the decomposition.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct LinearFit {
    /// Parameter names.
    pub names: Vec<String>,
    /// Estimates (0 for dropped columns).
    pub values: Vec<f64>,
    /// Standard deviations `sqrt(diag(covariance))`; infinite where the data do not determine a
    /// parameter (truncated directions, dropped columns).
    pub std: Vec<f64>,
    /// Covariance of the estimates ([`CovarianceScale`]); over the determined directions for
    /// [`RankPolicy::Truncate`], zero rows and columns for dropped columns.
    pub covariance: DMatrix<f64>,
    /// Pearson correlations (0 where a variance is zero or infinite).
    pub correlation: DMatrix<f64>,
    /// `|R|` of the QR decomposition of the whitened, column-scaled regressor (upper triangle).
    pub r_factor: DMatrix<f64>,
    /// Column scale factors `h_l = 1 / ||a_l||` (whitened; 1 for a zero column).
    pub column_scale: Vec<f64>,
    /// Singular values of the whitened, scaled regressor, descending.
    pub singular_values: Vec<f64>,
    /// `sigma_max / sigma_min` of the whitened, scaled regressor over its rank.
    pub condition_number: f64,
    /// Numerical rank.
    pub rank: usize,
    /// The rank policy used.
    pub rank_policy: RankPolicy,
    /// Columns held at zero by [`RankPolicy::DropPivoted`] (indices, ascending).
    pub dropped: Vec<usize>,
    /// `|R_ii|` of the QR decomposition with column pivoting of the whitened, scaled regressor,
    /// in pivot order: the identifiability of the columns (the first `rank` pivots are kept).
    pub r_diagonal: Vec<f64>,
    /// Column pivot order of that decomposition (column indices).
    pub pivot_order: Vec<usize>,
    /// A-posteriori variance factor `sqrt(chi^2 / dof)`.
    pub s0: f64,
    /// Weighted squared residual sum.
    pub chi2: f64,
    /// Rows.
    pub n_rows: usize,
    /// Redundancy `m - rank` (at least 1 for [`RankPolicy::Truncate`]).
    pub dof: usize,
    /// Residuals `y - A u` (unweighted, the measurements' unit).
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

    /// Names of the dropped columns.
    pub fn dropped_names(&self) -> Vec<&str> {
        self.dropped.iter().map(|&i| self.names[i].as_str()).collect()
    }

    /// Predictions `A u` for another regressor with the same columns.
    pub fn predict(&self, a: &DMatrix<f64>) -> Result<DVector<f64>> {
        if a.ncols() != self.values.len() {
            return Err(LsqError::Setup(format!(
                "a regressor with {} columns cannot use a fit of {} parameters",
                a.ncols(),
                self.values.len()
            )));
        }
        Ok(a * DVector::from_column_slice(&self.values))
    }
}

/// Fits `y = A u` under the noise model `w` with the options' rank policy (see the module
/// documentation). `names` name the columns in messages and in the result.
pub fn fit(
    a: &DMatrix<f64>,
    y: &DVector<f64>,
    names: &[String],
    w: &Weighting,
    opts: &LinearOptions,
) -> Result<LinearFit> {
    opts.validate()?;
    let s = prepare::prepare(a, y, names, w, opts.rank_policy)?;
    let input = solve::Input { a, y, names, w };
    match opts.rank_policy {
        RankPolicy::Refuse => solve::refusing(&input, &s, opts),
        RankPolicy::Truncate => solve::truncated(&input, &s, opts),
        RankPolicy::DropPivoted => solve::drop_pivoted(&input, &s, opts),
    }
}

/// The identifiability of a regressor under a noise model (whitened and column-scaled), without
/// fitting: for reports of models that are not identifiable. A singular value below
/// `rel_tol * sigma_max` counts as zero.
pub fn identifiability(a: &DMatrix<f64>, names: &[String], w: &Weighting, rel_tol: f64) -> Result<Identifiability> {
    let y = DVector::zeros(a.nrows());
    let s = prepare::prepare(a, &y, names, w, RankPolicy::Refuse)?;
    if let Some(j) = s.zero.iter().position(|z| *z) {
        return Err(zero_column(names, j));
    }
    analyze(&solve::thin_r(&s.a), names, rel_tol)
}

/// The refusal of a zero column.
fn zero_column(names: &[String], j: usize) -> LsqError {
    LsqError::RankDeficient {
        rank: names.len() - 1,
        n_params: names.len(),
        no_effect: vec![names[j].clone()],
        coupled: Vec::new(),
        message: format!(
            "parameter '{}' has no effect on these data (its regressor column is zero): the model is not identifiable from them; drop the parameter or excite it",
            names[j]
        ),
    }
}

/// The refusal of a rank-deficient regressor, naming the parameters involved.
pub fn rank_deficiency(id: &Identifiability) -> LsqError {
    let no_effect: Vec<String> = id
        .classes
        .iter()
        .enumerate()
        .filter(|(_, c)| **c == ParamClass::NotIdentifiable)
        .map(|(i, _)| id.names[i].clone())
        .collect();
    let coupled: Vec<Vec<String>> =
        id.groups.iter().map(|g| g.params.iter().map(|&i| id.names[i].clone()).collect()).collect();
    LsqError::RankDeficient { rank: id.rank, n_params: id.names.len(), no_effect, coupled, message: rank_message(id) }
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
