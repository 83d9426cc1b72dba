//! The least-squares layer as the calib crate uses it.
//!
//! The solver, the robust losses, the covariance and the block-structured problems live in
//! `ferrocal-lsq` (`calib/lsq`); this module keeps the calib crate's own [`Problem`] trait, whose
//! methods return the calib error type, and hands such problems to that one solver.

use nalgebra::{DMatrix, DVector};

use crate::error::{CalibError, Result};

pub use ferrocal_lsq::{LmOptions, LmResult, LmSummary, Loss, Termination};

/// A least-squares problem over a parameter vector `x` (in the problem's own units), as
/// [`ferrocal_lsq::DenseProblem`] with the calib error type.
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
        ferrocal_lsq::dense::central_differences(|x| self.residuals(x), x, &self.scales(), self.n_residuals())
    }
    /// Typical size of a change in each parameter (used to scale the problem).
    fn scales(&self) -> Vec<f64>;
    /// Applies a step (a manifold retraction where parameters live on one). Default: `x + dx`.
    fn retract(&self, x: &[f64], dx: &[f64]) -> Vec<f64> {
        x.iter().zip(dx).map(|(a, b)| a + b).collect()
    }
}

impl From<ferrocal_lsq::LsqError> for CalibError {
    fn from(e: ferrocal_lsq::LsqError) -> Self {
        use ferrocal_lsq::LsqError as L;
        match e.into_model::<CalibError>() {
            Ok(own) => own,
            Err(L::Setup(m)) => CalibError::Data(m),
            Err(L::TooFew(m)) => CalibError::TooFew(m),
            Err(L::RankDeficient { rank, no_effect, coupled, message, .. }) => {
                CalibError::RankDeficient { no_effect, coupled, rank, message }
            }
            Err(L::Diverged(m)) => CalibError::Diverged(m),
            Err(other) => CalibError::Numeric(other.to_string().trim_start_matches("linear algebra: ").to_string()),
        }
    }
}

/// A calib [`Problem`] seen by the layer's dense solver; the problem's own errors travel through
/// it unchanged.
struct Bridge<'a>(&'a dyn Problem);

impl ferrocal_lsq::DenseProblem for Bridge<'_> {
    fn n_params(&self) -> usize {
        self.0.n_params()
    }
    fn n_residuals(&self) -> usize {
        self.0.n_residuals()
    }
    fn block_size(&self) -> usize {
        self.0.block_size()
    }
    fn residuals(&self, x: &[f64]) -> ferrocal_lsq::Result<DVector<f64>> {
        self.0.residuals(x).map_err(ferrocal_lsq::LsqError::model)
    }
    fn jacobian(&self, x: &[f64]) -> ferrocal_lsq::Result<DMatrix<f64>> {
        self.0.jacobian(x).map_err(ferrocal_lsq::LsqError::model)
    }
    fn scales(&self) -> Vec<f64> {
        self.0.scales()
    }
    fn retract(&self, x: &[f64], dx: &[f64]) -> Vec<f64> {
        self.0.retract(x, dx)
    }
}

/// Minimises `sum_b rho(|r_b(x)|^2) / 2` with the layer's dense Levenberg-Marquardt
/// ([`ferrocal_lsq::dense::solve`]).
pub fn solve(problem: &dyn Problem, x0: &[f64], opts: &LmOptions) -> Result<LmResult> {
    Ok(ferrocal_lsq::dense::solve(&Bridge(problem), x0, opts)?)
}

/// Covariance of the parameters from the Jacobian of whitened residuals, and `s0`
/// ([`ferrocal_lsq::covariance`]).
pub fn covariance(jacobian: &DMatrix<f64>, residuals: &DVector<f64>) -> Result<(DMatrix<f64>, f64)> {
    Ok(ferrocal_lsq::covariance(jacobian, residuals)?)
}

/// Checks a problem's Jacobian at `x` against central differences through its retraction
/// ([`ferrocal_lsq::check::check_dense_problem`]).
pub fn check_jacobian(problem: &dyn Problem, x: &[f64], step: f64) -> Result<ferrocal_lsq::check::CheckReport> {
    Ok(ferrocal_lsq::check::check_dense_problem(&Bridge(problem), x, step)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A refused rank deficiency reaches calib's callers as a kind they can match, with the
    /// parameters named, and says what the layer said.
    #[test]
    fn a_rank_deficiency_keeps_its_kind_and_its_parameters() {
        // Two offsets that only their sum is seen of.
        let names = ["slope", "offset_a", "offset_b"].map(String::from);
        let a = DMatrix::from_fn(30, 3, |i, j| if j == 0 { i as f64 } else { 1.0 });
        let y = DVector::from_fn(30, |i, _| i as f64);
        let options = ferrocal_lsq::linear::LinearOptions::default();
        let layer = ferrocal_lsq::linear::fit(&a, &y, &names, &ferrocal_lsq::linear::Weighting::Unit, &options)
            .expect_err("rank 2 of 3 is refused");
        let text = layer.to_string();
        let e = CalibError::from(layer);
        let CalibError::RankDeficient { rank, no_effect, coupled, .. } = &e else { panic!("{e:?}") };
        assert_eq!(*rank, 2);
        assert!(no_effect.is_empty());
        assert_eq!(coupled, &vec![vec!["offset_a".to_string(), "offset_b".to_string()]]);
        assert_eq!(e.to_string(), text);
    }
}
