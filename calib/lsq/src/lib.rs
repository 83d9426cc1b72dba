//! The least-squares layer of ferrocal: every non-linear fit of the project is posed and solved
//! here.
//!
//! A [`Problem`] holds named [`ParameterBlock`]s, each on a [`Manifold`] ([`Euclidean`], [`So3`],
//! [`Se3`], [`UnitVector3`]), and residual blocks ([`Residual`]: whitened residuals of some
//! blocks with analytic Jacobians, each with a robust [`Loss`]). The [`StateIndex`] and
//! [`MeasurementIndex`] name every number of the state and of the residual vector. [`Problem::solve`]
//! runs one of two back ends behind one [`SolverOptions`] (checked by `validate()`): the dense
//! Levenberg-Marquardt of [`dense`] for small problems, and Ceres ([`Backend::Ceres`]) for large
//! sparse ones. The result carries a [`Summary`] (why it stopped, iterations, cost, conditioning)
//! and its [`Covariance`], dense or with local blocks marginalised by the Schur complement.
//! [`check`] verifies manifolds and Jacobians numerically; every residual of the project passes it
//! in a test.
//!
//! Code that assembles one residual vector and Jacobian itself (the kinematic calibration)
//! implements [`DenseProblem`] and calls [`dense::solve`]: the same solver, without blocks.
//!
//! Linear problems `y = A u` (force-sensor models, dynamics, compliance, the diagnose's
//! linearised screen) go through [`linear::fit`]: weighting, column scaling, an explicit rank
//! policy, `s0`, the covariance and the identifiability of the columns. Every covariance of the
//! layer comes from the same QR routine ([`linear::jacobian_covariance`]); [`identifiability`]
//! classifies parameters from the SVD and the pivoted QR of a scaled Jacobian.
//!
//! # Conventions
//! Residuals are whitened (so `s0 = 1` when the noise model is right). Tangent steps are left
//! increments; a pose step is `[t, r]`: translation first (metres), then rotation vector
//! (radians), as `docs/conventions.md` writes down for the whole project.
#![deny(missing_docs)]

mod ceres;
pub mod check;
mod covariance;
pub mod dense;
mod error;
pub mod identifiability;
pub mod linear;
mod loss;
pub mod manifold;
mod problem;
mod residual;
pub mod so3;

pub use ceres::show_ceres_log;
pub use covariance::{covariance, schur_covariance};
pub use dense::{DenseProblem, LmOptions, LmResult, LmSummary, Summary, Termination};
pub use error::{LsqError, Result};
pub use loss::Loss;
pub use manifold::{Euclidean, Manifold, Se3, So3, UnitVector3};
pub use problem::{
    Backend, BlockId, CeresLinearSolver, Covariance, MeasurementEntry, MeasurementIndex, ParameterBlock, Problem,
    ResidualId, Solution, SolverOptions, StateEntry, StateIndex,
};
pub use residual::{NumericResidual, Residual};
