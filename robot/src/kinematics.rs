//! The one abstraction every later part of ferrocal uses.

use nalgebra::{DMatrix, Vector3};
use serde::{Deserialize, Serialize};

use crate::error::{Result, RobotError};
use crate::geometry::Pose;
use crate::params::Parameterized;

/// Kind of an actuated joint.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum JointKind {
    /// Rotation, value in radians.
    Revolute,
    /// Translation (including guideway carts and leg lengths), value in metres.
    Prismatic,
}

/// Limits of one actuated joint (radians or metres).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct JointLimits {
    /// Lower bound.
    pub lower: f64,
    /// Upper bound.
    pub upper: f64,
}

impl JointLimits {
    /// Limits that never bind.
    pub const UNBOUNDED: JointLimits = JointLimits { lower: f64::NEG_INFINITY, upper: f64::INFINITY };

    /// Checked constructor: `lower <= upper`, neither NaN.
    pub fn new(joint: &str, lower: f64, upper: f64) -> Result<Self> {
        if lower.is_nan() || upper.is_nan() || lower > upper {
            return Err(RobotError::BadLimits { joint: joint.to_string(), lower, upper, location: None });
        }
        Ok(Self { lower, upper })
    }

    /// Whether `v` lies within the limits shrunk by `margin` on both sides.
    pub fn contains(&self, v: f64, margin: f64) -> bool {
        v >= self.lower + margin && v <= self.upper - margin
    }
}

/// Which pose components a model controls.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Mobility {
    /// Position only; the orientation is constant (nominal 3-DOF Gantry-Tau).
    Translation3,
    /// Position only is commanded; the orientation follows from the mechanism (six-link
    /// Gantry-Tau error model).
    Translation3Coupled,
    /// Full pose (serial 6-axis arms, hexapods, F1).
    Full6,
}

/// A robot's kinematics: forward and inverse kinematics, Jacobian, limits, parameters.
pub trait Kinematics: Parameterized {
    /// Number of actuated joints.
    fn dof(&self) -> usize;

    /// Actuated joint names in model order.
    fn joint_names(&self) -> Vec<String>;

    /// Actuated joint kinds in model order.
    fn joint_kinds(&self) -> Vec<JointKind>;

    /// Actuated joint limits in model order.
    fn joint_limits(&self) -> Vec<JointLimits>;

    /// Which pose components the model controls.
    fn mobility(&self) -> Mobility;

    /// Forward kinematics: `T_base_tool` for joint values `q`.
    fn forward(&self, q: &[f64]) -> Result<Pose>;

    /// Inverse kinematics: joint values that put the tool at `t_base_tool`, starting from `seed`
    /// (also the configuration selector for closed-form solutions). For models that control only
    /// the position, the orientation of `t_base_tool` is ignored.
    fn inverse(&self, t_base_tool: &Pose, seed: &[f64]) -> Result<Vec<f64>>;

    /// Geometric Jacobian (6 x dof) of the tool point at `q`: rows 0..3 linear velocity, 3..6
    /// angular velocity, base frame.
    fn jacobian(&self, q: &[f64]) -> Result<DMatrix<f64>>;

    /// Checks length, finiteness and limits of `q`.
    fn check_joints(&self, q: &[f64]) -> Result<()> {
        check_joint_vector(q, &self.joint_names(), &self.joint_limits(), 0.0)
    }
}

/// Checks length, finiteness and limits (shrunk by `margin`) of a joint vector.
pub fn check_joint_vector(q: &[f64], names: &[String], limits: &[JointLimits], margin: f64) -> Result<()> {
    if q.len() != limits.len() {
        return Err(RobotError::JointCount { expected: limits.len(), got: q.len() });
    }
    for (i, (v, l)) in q.iter().zip(limits).enumerate() {
        if !v.is_finite() || !l.contains(*v, margin) {
            return Err(RobotError::OutsideLimits {
                joint: i + 1,
                name: names.get(i).cloned().unwrap_or_default(),
                value: *v,
                lower: l.lower + margin,
                upper: l.upper - margin,
            });
        }
    }
    Ok(())
}

/// Returns `Err(JointCount)` unless `q` has `n` entries, all finite.
pub(crate) fn check_len(q: &[f64], n: usize) -> Result<()> {
    if q.len() != n {
        return Err(RobotError::JointCount { expected: n, got: q.len() });
    }
    if let Some((i, v)) = q.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(RobotError::BadParameter {
            name: format!("q{}", i + 1),
            value: *v,
            reason: "joint value is not finite".into(),
        });
    }
    Ok(())
}

/// Standard gravity in the base frame, m/s^2.
pub fn default_gravity() -> Vector3<f64> {
    Vector3::new(0.0, 0.0, -9.80665)
}
