//! Experiment design for elastostatic calibration: which configurations to measure under which
//! loads, chosen by the planner's criteria ([`crate::design::criteria`]) on this regressor.
//!
//! Every candidate is a configuration with a [`LoadCase`] (a payload's weight, an applied force,
//! the links' own weight). Its rows are the whitened marker rows of the reduced parameters, with
//! each column scaled to unit norm over the whole pool (the planner's convention: criteria see
//! numbers without units). Selection is the planner's greedy deletion with exchange
//! ([`crate::design::selection::select`]); the predicted standard deviations are reported
//! relative to each parameter's prior magnitude.

use ferrocal_robot::stiffness::{Loading, VjmModel, Wrench};
use ferrocal_robot::Kinematics;
use nalgebra::{DMatrix, Point3, Vector3};
use serde::{Deserialize, Serialize};

use crate::design::criteria::Criterion;
use crate::design::pool::InformationPool;
use crate::design::selection::{select, SelectionSettings};
use crate::stiffness::error::{Result, StiffnessIdError};
use crate::stiffness::param::Parameterization;

/// The loads of one measurement.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct LoadCase {
    /// Payload mass at the tool.
    pub mass_kg: f64,
    /// The payload's centre of mass in the tool frame.
    pub com_in_tool_m: [f64; 3],
    /// A force applied at the tool point, base axes (a cable, a pushing actuator).
    pub force_n: [f64; 3],
    /// Whether the links' weight and the gravity compensator act (absolute measurements against
    /// the rigid model); `false` for a loaded-minus-unloaded difference.
    pub self_weight: bool,
}

impl LoadCase {
    /// A payload's weight with the links' own weight (absolute measurement).
    pub fn payload(mass_kg: f64, com_in_tool_m: [f64; 3]) -> Self {
        Self { mass_kg, com_in_tool_m, force_n: [0.0; 3], self_weight: true }
    }

    /// The tool wrench at `q` (base axes, about the tool point).
    pub fn wrench(&self, model: &VjmModel, q: &[f64]) -> Result<Wrench> {
        if !(self.mass_kg.is_finite() && self.mass_kg >= 0.0) {
            return Err(StiffnessIdError::Options(format!("payload mass {} kg must be non-negative", self.mass_kg)));
        }
        let tool = model.chain.forward(q)?;
        let p = Point3::from(tool.translation.vector);
        let com = tool * Point3::from(self.com_in_tool_m);
        let g = Vector3::from(model.chain.gravity_m_s2);
        let w = Wrench::gravity(self.mass_kg, &com, &p, &g);
        Ok(w.plus(&Wrench::new(Vector3::from(self.force_n), Vector3::zeros())))
    }

    /// The loading at `q`.
    pub fn loading(&self, model: &VjmModel, q: &[f64]) -> Result<Loading> {
        let w = self.wrench(model, q)?;
        Ok(if self.self_weight { Loading::gravity(w) } else { Loading::tool(w) })
    }
}

/// A chosen experiment.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ExperimentDesign {
    /// The criterion.
    pub criterion: Criterion,
    /// Chosen candidates (indices).
    pub chosen: Vec<usize>,
    /// The criterion's value of the chosen set (the source's form).
    pub value: f64,
    /// The same for the median of random sets of the same size (for comparison).
    pub random_value: f64,
    /// Parameter names.
    pub names: Vec<String>,
    /// Predicted relative standard deviation `std / |prior|` of each parameter with the chosen
    /// set (absolute standard deviation where the prior is zero).
    pub relative_std: Vec<f64>,
    /// The same with a random set.
    pub random_relative_std: Vec<f64>,
}

/// Whitened candidate blocks (3 rows per marker) of the reduced parameters `param`.
pub fn candidate_blocks(
    model: &VjmModel,
    param: &Parameterization,
    candidates: &[(Vec<f64>, LoadCase)],
    markers_in_tool_m: &[Vector3<f64>],
    sigma_m: f64,
) -> Result<Vec<DMatrix<f64>>> {
    if !(sigma_m.is_finite() && sigma_m > 0.0) {
        return Err(StiffnessIdError::Options(format!("marker noise {sigma_m} m must be positive")));
    }
    let b = param.basis_matrix();
    candidates
        .iter()
        .map(|(q, load)| {
            let a = model.marker_matrix(q, &load.loading(model, q)?, markers_in_tool_m)?;
            Ok(a * &b / sigma_m)
        })
        .collect()
}

fn relative_std(pool: &InformationPool, set: &[usize], scale: &[f64], prior: &[f64]) -> Vec<f64> {
    let f = pool.information(set);
    match ferrocal_lsq::linear::predicted_std(&f) {
        Some(sd) => sd
            .iter()
            .enumerate()
            .map(|(i, sd)| {
                let s = sd * scale[i];
                if prior[i] != 0.0 {
                    s / prior[i].abs()
                } else {
                    s
                }
            })
            .collect(),
        None => vec![f64::INFINITY; f.nrows()],
    }
}

/// Chooses `count` of `candidates` by `settings.criterion`; `prior` (one value per parameter)
/// only scales the reported standard deviations. `seed` draws the random sets compared against.
#[allow(clippy::too_many_arguments)]
pub fn design_experiment(
    model: &VjmModel,
    param: &Parameterization,
    candidates: &[(Vec<f64>, LoadCase)],
    markers_in_tool_m: &[Vector3<f64>],
    sigma_m: f64,
    prior: &[f64],
    count: usize,
    settings: &SelectionSettings,
    seed: u64,
) -> Result<ExperimentDesign> {
    if prior.len() != param.len() {
        return Err(StiffnessIdError::Options(format!("{} prior values for {} parameters", prior.len(), param.len())));
    }
    let mut blocks = candidate_blocks(model, param, candidates, markers_in_tool_m, sigma_m)?;
    let norms: Vec<f64> =
        (0..param.len()).map(|j| blocks.iter().map(|b| b.column(j).norm_squared()).sum::<f64>().sqrt()).collect();
    if let Some(j) = norms.iter().position(|n| *n == 0.0) {
        return Err(StiffnessIdError::Unexcited {
            unexcited: vec![param.params[j].name.clone()],
            coupled: vec![],
            trusted: vec![],
        });
    }
    let scale: Vec<f64> = norms.iter().map(|n| 1.0 / n).collect();
    for b in &mut blocks {
        for (j, s) in scale.iter().enumerate() {
            b.column_mut(j).scale_mut(*s);
        }
    }
    let pool = InformationPool::from_blocks(&blocks, param.names())?;
    let all: Vec<usize> = (0..candidates.len()).collect();
    let sel = select(&pool, &all, count, settings)?;
    // Random sets of the same size (xorshift; 15 draws, median loss).
    let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    let mut losses = Vec::new();
    let mut sets = Vec::new();
    for _ in 0..15 {
        let mut idx = all.clone();
        for i in (1..idx.len()).rev() {
            let j = (next() % (i as u64 + 1)) as usize;
            idx.swap(i, j);
        }
        idx.truncate(count);
        losses.push(pool.loss(&idx, settings.criterion));
        sets.push(idx);
    }
    let mut order: Vec<usize> = (0..losses.len()).collect();
    order.sort_by(|a, b| losses[*a].total_cmp(&losses[*b]));
    let med = order[order.len() / 2];
    Ok(ExperimentDesign {
        criterion: settings.criterion,
        value: sel.value,
        random_value: settings.criterion.value(losses[med]),
        names: param.names(),
        relative_std: relative_std(&pool, &sel.chosen, &scale, prior),
        random_relative_std: relative_std(&pool, &sets[med], &scale, prior),
        chosen: sel.chosen,
    })
}
