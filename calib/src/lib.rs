//! The identification engine of ferrocal.
//!
//! Entry points:
//! - [`measurement`]: the measured-pose row every calibration consumes.
//!
//! # Conventions
//! SI units inside; see `docs/conventions.md` at the workspace root.
#![deny(missing_docs)]

pub mod measurement;

pub use measurement::{MeasurementSet, PoseMeasurement, Split};
