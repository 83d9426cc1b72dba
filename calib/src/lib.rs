//! The identification engine of ferrocal.
//!
//! Entry points:
//! - [`measurement`]: the measured-pose row every calibration consumes;
//! - [`check`]: named checks that pass, fail, are skipped or only reported;
//! - [`lsq`]: the least-squares layer (`ferrocal-lsq`) as this crate uses it: dense
//!   Levenberg-Marquardt with scaling, robust losses and covariance; linear fits go through
//!   `ferrocal_lsq::linear`;
//! - [`handeye`]: hand-eye calibration (eye-in-hand, eye-to-hand) refined in pixels, with
//!   OpenCV's closed forms as the baseline;
//! - [`identifiability`]: structural (SVD, pivoted QR) and practical identifiability;
//! - [`kinematic`]: kinematic calibration; [`design`]: pose and experiment design;
//! - [`dynamics`]: force-sensor models and hexapod dynamics identification;
//! - [`diagnose`]: missing physics found by cross-validated candidate effects;
//! - [`motion`]: black-box and physical identification of compliant axes, learning control;
//! - [`stiffness`]: elastostatic identification with model reduction to practically identifiable
//!   parameters, experiment design and compliance compensation;
//! - [`verdict`]: the pass / warning / fail line every command ends with, and its named limits.
//!
//! # Conventions
//! SI units inside; see `docs/conventions.md` at the workspace root.
#![deny(missing_docs)]

pub mod check;
pub mod design;
pub mod diagnose;
pub mod dynamics;
pub mod effect_list;
pub mod effect_registry;
pub mod effects;
pub mod error;
pub mod export;
pub mod file;
pub mod frames;
pub mod handeye;
pub mod identifiability;
pub mod kinematic;
pub mod lsq;
pub mod measurement;
pub mod motion;
pub mod stiffness;
pub mod verdict;

pub use error::{CalibError, Result};
pub use measurement::{MeasurementSet, PoseCovariance, PoseMeasurement, Split};
