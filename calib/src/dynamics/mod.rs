//! Dynamics and force-sensor identification: linear models `f = A u` of a force-sensing
//! end-effector and of hexapod dynamics, their signals and their experiment design.
//!
//! - [`force_sensor`]: the force-sensing end-effector's models 0 to 9 (Friedrich & Ihlenfeldt
//!   2021) as regressors;
//! - [`signals`]: stream checks, DFT filtering and differentiation, zero-phase Butterworth,
//!   statistics over repeated periods;
//! - [`identify`]: poses by forward kinematics, motion states, Gauss-Markov identification from
//!   trajectories and the maximum-likelihood cutoff (Abdellatif & Heimann 2009);
//! - [`design`]: pose pools and their reduction by the A, D, K, N criteria, optimised Fourier
//!   excitation and point-to-point trajectories.
//!
//! Every fit goes through the least-squares layer's linear routine
//! ([`ferrocal_lsq::linear::fit`]: Gauss-Markov weighting by a full noise covariance, column
//! scaling `h_l = 1 / ||a_l||`, `s0`, covariance `s0^2 F^-1`, Pearson correlations, the QR R
//! factor; rank-deficient regressors refused with the parameters named). The models' physics
//! lives in [`ferrocal_robot::dynamics`]; simulated data come from `ferrocal_datasets::dynsim`,
//! which describes the same physics independently.

pub mod design;
pub mod force_sensor;
pub mod identify;
pub mod signals;

pub use force_sensor::{SensorModel, SensorRegressor, SensorTruth};
pub use identify::{
    identify, ml_cutoff, motion_states, poses_from_legs, Differentiation, NoiseModel, RowModel, SensorRows,
};
