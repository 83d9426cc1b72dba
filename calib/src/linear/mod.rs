//! Linear identification `f = A u`: force-sensor models and hexapod dynamics.
//!
//! - [`solve`]: weighted least squares with column scaling `h_l = 1 / ||a_l||`, Gauss-Markov
//!   weighting by a full noise covariance, `s0`, covariance `s0^2 F^-1`, Pearson correlations and
//!   the QR R factor; rank-deficient regressors are refused with the parameters named;
//! - [`models`]: the force-sensing end-effector's models 0 to 9 (Friedrich & Ihlenfeldt 2021);
//! - [`signals`]: stream checks, DFT filtering and differentiation, zero-phase Butterworth,
//!   statistics over repeated periods;
//! - [`dynamic`]: poses by forward kinematics, motion states, Gauss-Markov identification from
//!   trajectories and the maximum-likelihood cutoff (Abdellatif & Heimann 2009);
//! - [`design`]: pose pools and their reduction by the A, D, K, N criteria, optimised Fourier
//!   excitation and point-to-point trajectories.
//!
//! The models' physics lives in [`ferrocal_robot::dynamics`]; simulated data come from
//! `ferrocal_datasets::dynsim`, which describes the same physics independently.

pub mod design;
pub mod dynamic;
pub mod models;
pub mod signals;
pub mod solve;

pub use dynamic::{
    identify, ml_cutoff, motion_states, poses_from_legs, Differentiation, NoiseModel, RowModel, SensorRows,
};
pub use models::{SensorModel, SensorRegressor, SensorTruth};
pub use solve::{fit, FitOptions, LinearFit, Weighting};
