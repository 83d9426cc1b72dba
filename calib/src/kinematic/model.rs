//! The calibrated model (prediction of measured poses) and error statistics.

use std::borrow::Cow;

use ferrocal_robot::{Kinematics, RobotModel};
use nalgebra::{Isometry3, Vector3};
use serde::{Deserialize, Serialize};

use crate::effects::{compliance_equilibrium, compliances, EffectSpec};
use crate::error::{CalibError, Result};
use crate::measurement::PoseMeasurement;

/// Position (and orientation) error statistics.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct ErrorStats {
    /// Number of poses.
    pub n: usize,
    /// Mean position error.
    pub mean_mm: f64,
    /// RMS position error.
    pub rms_mm: f64,
    /// Largest position error.
    pub max_mm: f64,
    /// RMS per axis (device frame).
    pub rms_axis_mm: [f64; 3],
    /// Mean orientation error, when orientations were compared.
    pub mean_deg: Option<f64>,
    /// Largest orientation error.
    pub max_deg: Option<f64>,
}

impl ErrorStats {
    /// Statistics of position error vectors (metres) and optional orientation errors (radians).
    pub fn from_errors(pos_m: &[Vector3<f64>], ori_rad: &[f64]) -> Self {
        let n = pos_m.len();
        if n == 0 {
            return Self::default();
        }
        let norms: Vec<f64> = pos_m.iter().map(|e| e.norm() * 1e3).collect();
        let mut axis = [0.0; 3];
        for e in pos_m {
            for k in 0..3 {
                axis[k] += (e[k] * 1e3).powi(2);
            }
        }
        Self {
            n,
            mean_mm: norms.iter().sum::<f64>() / n as f64,
            rms_mm: (norms.iter().map(|v| v * v).sum::<f64>() / n as f64).sqrt(),
            max_mm: norms.iter().copied().fold(0.0, f64::max),
            rms_axis_mm: axis.map(|a| (a / n as f64).sqrt()),
            mean_deg: (!ori_rad.is_empty())
                .then(|| ori_rad.iter().sum::<f64>() / ori_rad.len() as f64 * 180.0 / std::f64::consts::PI),
            max_deg: (!ori_rad.is_empty()).then(|| ori_rad.iter().copied().fold(0.0, f64::max).to_degrees()),
        }
    }
}

/// A calibrated model: everything needed to predict measurements.
#[derive(Clone, Debug)]
pub struct CalibratedModel {
    /// The robot model with the identified parameters.
    pub model: RobotModel,
    /// `T_device_base`.
    pub device_frame: Isometry3<f64>,
    /// `T_flange_target` (the model's own tool frame included before it).
    pub tool: Isometry3<f64>,
    /// Joint offsets added to the readings.
    pub joint_offsets: Vec<f64>,
    /// Whether the target's orientation was calibrated (orientations are compared only then).
    pub orientation_calibrated: bool,
    /// Physical effects with their identified parameters.
    pub effects: Vec<(EffectSpec, Vec<f64>)>,
    /// The model whose link frames place the masses for the gravity loads of the effects: the
    /// nominal geometry. The calibrated model may move link frames along directions the
    /// kinematics cannot see (kinematically redundant parameters), which would move the masses
    /// and bias every load-dependent effect.
    pub load_model: RobotModel,
}

impl CalibratedModel {
    /// The nominal model as it is: identity device frame and tool, zero joint offsets, no
    /// effects.
    pub fn nominal(model: RobotModel) -> Self {
        let n = model.dof();
        Self {
            load_model: model.clone(),
            model,
            device_frame: Isometry3::identity(),
            tool: Isometry3::identity(),
            joint_offsets: vec![0.0; n],
            orientation_calibrated: false,
            effects: Vec::new(),
        }
    }

    /// Effective joint values and length scale of `row` under the joint offsets and effects:
    /// the reading plus the offsets and the joint effects' corrections, then the
    /// `joint_compliance` effects' equilibrium ([`compliance_equilibrium`]) from there.
    pub fn effective(&self, row: &PoseMeasurement) -> Result<(Vec<f64>, f64)> {
        if row.q.len() != self.joint_offsets.len() {
            return Err(CalibError::Data(format!(
                "the robot has {} joints, the row {}",
                self.joint_offsets.len(),
                row.q.len()
            )));
        }
        let mut dq = self.joint_offsets.clone();
        let mut scale = 1.0;
        let compliance = compliances(&self.effects, dq.len())?;
        for (e, theta) in &self.effects {
            if !matches!(e, EffectSpec::JointCompliance { .. }) {
                e.add_joint_delta(&self.load_model, row, theta, &mut dq)?;
            }
            scale *= e.length_scale(row, theta);
        }
        let q0: Vec<f64> = row.q.iter().zip(&dq).map(|(a, b)| a + b).collect();
        let q = compliance_equilibrium(&self.load_model, &q0, &compliance, row.payload_kg.unwrap_or(0.0))?;
        Ok((q, scale))
    }

    /// Predicted `T_device_target` for a measured row (its joints and, for effects, its
    /// approach directions, temperature, time and payload).
    pub fn predict_row(&self, row: &PoseMeasurement) -> Result<Isometry3<f64>> {
        let (q, scale) = self.effective(row)?;
        let mut t = model_for_row(&self.model, row)?.forward(&q)? * self.tool;
        for (e, theta) in &self.effects {
            if e.corrects_pose() {
                t = e.pose_correction(&self.load_model, row, &q, theta)? * t;
            }
        }
        if scale != 1.0 {
            t.translation.vector *= scale;
        }
        Ok(self.device_frame * t)
    }

    /// Predicted `T_device_target` for joint readings `q`, without the effects (which need a
    /// row's inputs: see [`CalibratedModel::predict_row`]).
    pub fn predict(&self, q: &[f64]) -> Result<Isometry3<f64>> {
        if q.len() != self.joint_offsets.len() {
            return Err(CalibError::Data(format!(
                "the robot has {} joints, the row {}",
                self.joint_offsets.len(),
                q.len()
            )));
        }
        let qq: Vec<f64> = q.iter().zip(&self.joint_offsets).map(|(a, b)| a + b).collect();
        Ok(self.device_frame * self.model.forward(&qq)? * self.tool)
    }

    /// Position (and orientation) errors of `rows` under this model: `measured - predicted`.
    pub fn errors(&self, rows: &[&PoseMeasurement]) -> Result<(Vec<Vector3<f64>>, Vec<f64>)> {
        let mut pos = Vec::with_capacity(rows.len());
        let mut ori = Vec::new();
        for r in rows {
            let t = self.predict_row(r).map_err(|e| row_error(r, e))?;
            pos.push(r.position_m - t.translation.vector);
            if let (true, Some(qm)) = (self.orientation_calibrated, &r.orientation) {
                ori.push(qm.angle_to(&t.rotation));
            }
        }
        if ori.len() != rows.len() {
            ori.clear();
        }
        Ok((pos, ori))
    }

    /// Error statistics of `rows`.
    pub fn evaluate(&self, rows: &[&PoseMeasurement]) -> Result<ErrorStats> {
        let (p, o) = self.errors(rows)?;
        Ok(ErrorStats::from_errors(&p, &o))
    }
}

/// The model that measures `row`: a tree's with the row's tip ([`PoseMeasurement::tip`]) active,
/// `model` itself for a row without a tip; a tip on a robot that is not a tree is an error.
pub fn model_for_row<'a>(model: &'a RobotModel, row: &PoseMeasurement) -> Result<Cow<'a, RobotModel>> {
    let Some(tip) = row.tip() else { return Ok(Cow::Borrowed(model)) };
    match model {
        RobotModel::Serial(c) if c.is_tree() => {
            if c.tip_names()[c.tree.as_ref().map_or(0, |t| t.active)] == tip {
                return Ok(Cow::Borrowed(model));
            }
            Ok(Cow::Owned(RobotModel::Serial(c.with_tip(tip).map_err(|e| CalibError::Data(e.to_string()))?)))
        }
        _ => Err(CalibError::Data(format!(
            "the row names the tip '{tip}', but the robot model '{}' is not a tree of chains (load its URDF with every branch)",
            model.name()
        ))),
    }
}

pub(super) fn row_error(r: &PoseMeasurement, e: impl std::fmt::Display) -> CalibError {
    let line = r.source_line.map(|l| format!(" (line {l})")).unwrap_or_default();
    CalibError::Data(format!("pose '{}'{line}: {e}", r.pose_id))
}
