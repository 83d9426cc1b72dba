//! Identifiability of a parameter vector from the Jacobian of a (whitened, column-scaled) cost:
//! the analysis lives in the least-squares layer ([`ferrocal_lsq::identifiability`], where its
//! method is described); this module hands it the calib error type.

use nalgebra::DMatrix;

use crate::error::Result;

pub use ferrocal_lsq::identifiability::{CoupledGroup, Identifiability, ParamClass};

/// Analyses `a` (residuals x parameters, already whitened and column-scaled); a singular value
/// below `rel_tol * sigma_max` counts as zero ([`ferrocal_lsq::identifiability::analyze`]).
pub fn analyze(a: &DMatrix<f64>, names: &[String], rel_tol: f64) -> Result<Identifiability> {
    Ok(ferrocal_lsq::identifiability::analyze(a, names, rel_tol)?)
}
