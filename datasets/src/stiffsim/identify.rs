//! The `stiffness identify` workflow: a deflection table (`docs/stiffness.md`) read for a
//! stiffness model and the reduced compliance model identified from it
//! ([`identify_deflections`]).

use std::path::Path;

use ferrocal_calib::stiffness::problem::LinearProblem;
use ferrocal_calib::stiffness::reduce::{reduce, Reduction, ReductionSettings};
use ferrocal_calib::stiffness::StiffnessIdError;
use ferrocal_robot::stiffness::WrenchLimits;

use crate::error::Result;
use crate::formats::deflections::{read_deflections, stiffness_model};

/// A deflection table's identification.
#[derive(Clone, Debug)]
pub struct DeflectionIdentification {
    /// The complete linear problem.
    pub problem: LinearProblem,
    /// The model reduction and the identified parameters.
    pub reduction: Reduction,
    /// The design estimates of the reduced parameters (zero for a model without them).
    pub prior: Vec<f64>,
}

/// Identifies the reduced compliance model of `model` (a stiffness preset with design estimates,
/// or any serial robot with one spring per link) from the deflection table `measurements`,
/// keeping parameters whose parameter-to-noise ratio reaches `nu_threshold`. When the loads
/// leave parameters unexcited the inner result says so.
pub fn identify_deflections(
    model: &str,
    measurements: &Path,
    nu_threshold: f64,
) -> Result<std::result::Result<DeflectionIdentification, StiffnessIdError>> {
    let (model, prior) = stiffness_model(model)?;
    let limits = WrenchLimits::default();
    let obs = read_deflections(measurements, &model, &limits)?;
    let problem = LinearProblem::from_observations(&model, &obs, &limits)?;
    let settings = ReductionSettings { nu_threshold, ..ReductionSettings::default() };
    let reduction = match reduce(&problem, None, prior.as_deref(), &settings) {
        Ok(r) => r,
        Err(e @ StiffnessIdError::Unexcited { .. }) => return Ok(Err(e)),
        Err(e) => return Err(e.into()),
    };
    let prior = reduction.param.project(prior.as_deref().unwrap_or(&vec![0.0; problem.layout.len()]));
    Ok(Ok(DeflectionIdentification { problem, reduction, prior }))
}
