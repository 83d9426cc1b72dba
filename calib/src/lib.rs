//! The identification engine of ferrocal.
//!
//! Entry points:
//! - [`measurement`]: the measured-pose row every calibration consumes;
//! - [`lsq`]: dense Levenberg-Marquardt with scaling, robust losses and covariance;
//! - [`identifiability`]: structural (SVD, pivoted QR) and practical identifiability.
//!
//! # Conventions
//! SI units inside; see `docs/conventions.md` at the workspace root.
#![deny(missing_docs)]

pub mod design;
pub mod diagnose;
pub mod effects;
pub mod error;
pub mod file;
pub mod frames;
pub mod identifiability;
pub mod kinematic;
pub mod lsq;
pub mod measurement;

pub use error::{CalibError, Result};
pub use measurement::{MeasurementSet, PoseMeasurement, Split};
