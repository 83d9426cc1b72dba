//! Missing-physics diagnosis: where a calibrated model and a recording disagree, which physical
//! effect left out of the model explains it, and how much better the held-out fit gets once it is
//! modelled (the JSON contract is `shared/spec/diagnose.md`).
//!
//! One engine, three families:
//! - [`engine`]: the cross-validated forward selection (folds, paired test, Bonferroni, overlap,
//!   plausibility, stability, confirmation, accept or decline), once for every family; a family
//!   implements [`engine::Family`];
//! - [`report`]: the one report of a selection ([`report::Diagnosis`]: candidate rows with
//!   verdicts, accepted effects with held-out figures before and after and their evidence, in the
//!   family's [`report::Unit`]); each variant's JSON is a thin view of it;
//! - [`kinematic`] (arms and parallel machines; re-exported here: [`diagnose`]), [`camera`]
//!   ([`camera::diagnose_camera`]) and [`force`] ([`force::diagnose_force_sensor`]): the families;
//! - [`stereo`] ([`stereo::diagnose_stereo`]): the camera family over both cameras of a stereo
//!   pair (one target, per-camera lenses);
//! - [`stats`]: the distribution tails and tests.

pub mod camera;
pub mod engine;
pub mod force;
mod force_crosstalk;
pub mod kinematic;
pub mod report;
pub mod stats;
pub mod stereo;

pub use kinematic::{
    compensated_calibration, diagnose, Bounds, CandidateScore, DiagnoseOptions, DiagnoseReport, FinalFit, Finding,
    InputStructure, NominalFit, Step, Unexplained, Untestable,
};
pub use report::Evidence;
