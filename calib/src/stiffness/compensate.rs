//! Compliance error compensation by the "mirror" method: the robot is commanded to the target
//! pose reflected about its predicted deflection, so that it deflects onto the target.
//!
//! With `T_des` the target tool pose and `dt(q)` the deflection predicted at the commanded
//! configuration `q` under the task load, the command solves `f(q) = T_des (-) dt(q)` (position
//! `p_des - dp`, orientation `Exp(-dphi) R_des`). The first pass uses `dt(q_des)` (the classic
//! mirror); further passes re-evaluate the deflection at the new command. The residual error is
//! what the true (compliant) robot does at the command, minus the target.

use ferrocal_robot::geometry::pose_error;
use ferrocal_robot::serial::IkOptions;
use ferrocal_robot::stiffness::{Loading, VjmModel};
use ferrocal_robot::{Kinematics, Pose};
use nalgebra::{DVector, Isometry3, Translation3, UnitQuaternion, Vector3, Vector6};
use serde::{Deserialize, Serialize};

use crate::stiffness::design::LoadCase;
use crate::stiffness::error::{Result, StiffnessIdError};

/// Predicts deflections from identified complete-model values.
#[derive(Clone, Debug, PartialEq)]
pub struct CompliancePredictor {
    /// The model whose geometry, inertials and layout the values belong to.
    pub model: VjmModel,
    /// Complete-model values (see `ferrocal_robot::stiffness::regressor`).
    pub complete_values: Vec<f64>,
}

impl CompliancePredictor {
    /// A predictor, checked against the model's layout.
    pub fn new(model: VjmModel, complete_values: Vec<f64>) -> Result<Self> {
        let n = model.layout()?.len();
        if complete_values.len() != n {
            return Err(StiffnessIdError::Options(format!(
                "{} compliance values for a model with {n} complete parameters",
                complete_values.len()
            )));
        }
        Ok(Self { model, complete_values })
    }

    /// The tool's `(dp m, dphi rad)` at `q` under `loading` (base frame).
    pub fn deflection(&self, q: &[f64], loading: &Loading) -> Result<Vector6<f64>> {
        let a = self.model.observation_matrix(q, loading)?;
        let d = a * DVector::from_column_slice(&self.complete_values);
        Ok(Vector6::from_iterator(d.iter().copied()))
    }
}

/// The mirror method's command.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MirrorResult {
    /// Joint values to command.
    pub q_command: Vec<f64>,
    /// The deflection predicted at the command.
    pub predicted_deflection: [f64; 6],
    /// Passes made.
    pub passes: usize,
}

fn apply_small_motion(t: &Pose, d: &Vector6<f64>) -> Pose {
    let dp = Vector3::new(d[0], d[1], d[2]);
    let dr = UnitQuaternion::from_scaled_axis(Vector3::new(d[3], d[4], d[5]));
    Isometry3::from_parts(Translation3::from(t.translation.vector + dp), dr * t.rotation)
}

/// Joint values whose rigid tool pose is `target`, from `seed`: the robot crate's damped
/// least-squares inverse kinematics (to 1e-12 m / 1e-12 rad), without joint-limit enforcement
/// (compensation moves a reachable command by fractions of a millimetre).
pub fn rigid_ik(model: &VjmModel, target: &Pose, seed: &[f64]) -> Result<Vec<f64>> {
    let opts = IkOptions { enforce_limits: false, ..IkOptions::default() };
    model
        .chain
        .inverse_with(target, seed, &opts)
        .map_err(|e| StiffnessIdError::Options(format!("inverse kinematics failed: {e}")))
}

/// The mirror command for target joint values `q_target` under `load`, with `passes >= 1`
/// evaluations of the predicted deflection.
pub fn mirror(
    predictor: &CompliancePredictor,
    q_target: &[f64],
    load: &LoadCase,
    passes: usize,
) -> Result<MirrorResult> {
    let m = &predictor.model;
    let t_des = m.chain.forward(q_target)?;
    let mut q = q_target.to_vec();
    let mut dt = Vector6::zeros();
    for _ in 0..passes.max(1) {
        dt = predictor.deflection(&q, &load.loading(m, &q)?)?;
        let t_cmd = apply_small_motion(&t_des, &(-dt));
        q = rigid_ik(m, &t_cmd, &q)?;
    }
    Ok(MirrorResult { q_command: q, predicted_deflection: dt.into(), passes: passes.max(1) })
}

/// The pose a compliant robot (`truth`, exact compliant kinematics of its linear deflections)
/// reaches at `q` under `load`.
pub fn compliant_pose(truth: &VjmModel, q: &[f64], load: &LoadCase) -> Result<Pose> {
    let d = truth.deflections(q, &load.loading(truth, q)?)?;
    Ok(truth.deflected_pose(q, &d)?)
}

/// Position and orientation error `(|dp| m, |dphi| rad)` of `actual` against `target`.
pub fn error_norms(target: &Pose, actual: &Pose) -> (f64, f64) {
    let e = pose_error(target, actual);
    (e.fixed_rows::<3>(0).norm(), e.fixed_rows::<3>(3).norm())
}
