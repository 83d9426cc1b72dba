//! Elastostatic identification with practical identifiability (Klimchik et al. 2015).
//!
//! The virtual joint model itself (`ferrocal_robot::stiffness`) gives the identification equation
//! `dt_j = A(q_j, w_j) pi + eps_j`, linear in the compliance entries. This module turns
//! measurements into a weighted linear problem and reduces the complete model to parameters the
//! data can resolve:
//!
//! - [`problem`] - observations (configuration, loads, measured pose or marker displacements)
//!   and the whitened problem over the complete parameters;
//! - [`param`] - reduced parameters as linear combinations of the complete ones;
//! - [`fit`](mod@fit) - weighted least squares with covariance and parameter-to-noise ratios;
//! - [`reduce`](mod@reduce) - the source's reduction M1 to M6 (symmetry, sparsity templates, aggregation, SVD
//!   partitioning, fixing coupled parameters, the parameter-to-noise threshold), each step with
//!   its parameter count and accuracy cost, and the checked identification that refuses
//!   unexcited or unphysical estimates and names the parameters that can be trusted;
//! - [`design`] - configurations and loads chosen by the planner's criteria for this regressor;
//! - [`compensate`] - predicted deflection under a task wrench and the "mirror" corrected joint
//!   targets;
//! - [`onelink`] - the source's one-link (Orthoglide) example.
//!
//! # Conventions
//! SI inside (m/N, rad/(N m)); measurement rows are whitened by their standard deviations, so the
//! residual RMS of a right noise model is 1.

pub mod compensate;
pub mod design;
pub mod error;
pub mod fit;
pub mod onelink;
pub mod param;
pub mod problem;
pub mod reduce;

pub use compensate::{mirror, CompliancePredictor, MirrorResult};
pub use design::{design_experiment, ExperimentDesign, LoadCase};
pub use error::StiffnessIdError;
pub use fit::{fit, Fit};
pub use param::{Parameterization, ReducedParam};
pub use problem::{LinearProblem, Measured, Observation};
pub use reduce::{identify_checked, physical_problems, reduce, Reduction, ReductionSettings, ReductionStep};
