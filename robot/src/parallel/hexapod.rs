//! Stewart / hexapod platforms: six legs of variable length between fixed base points and the
//! moving platform.

use nalgebra::{DMatrix, Point3, Vector3};
use serde::{Deserialize, Serialize};

use super::legs::{Leg, LegSide, Mechanism};
use super::{check_direction, check_positive, check_vector, vec_names, Branch, ParallelRobot, SolverOptions};
use crate::error::{Result, RobotError};
use crate::geometry::Pose;
use crate::kinematics::{check_len, JointKind, JointLimits, Kinematics, Mobility};
use crate::params::{check_values, ParamInfo, Parameterized, Unit};

/// One hexapod leg: `||A - B|| = L0 + q`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HexapodLeg {
    /// Base-side joint centre, base frame.
    pub a_m: Vector3<f64>,
    /// Platform-side joint centre, platform (flange) frame.
    pub b0_m: Vector3<f64>,
    /// Leg length at `q = 0`.
    pub length0_m: f64,
    /// Stroke limits of `q`, metres.
    pub limits: JointLimits,
    /// Axis of the base-side spherical joint, base frame; `None`: the leg direction at `q = 0`.
    pub base_axis: Option<Vector3<f64>>,
    /// Axis of the platform-side spherical joint, platform frame; `None`: the direction `A - B`
    /// at `q = 0`.
    pub platform_axis: Option<Vector3<f64>>,
}

/// A 6-6 Stewart platform (mobility [`Mobility::Full6`]); actuators `leg1..leg6` (extension
/// `q_i`, metres). Parameters per leg: `A` (3), `B0` (3), `L0` (1): 42.
///
/// - Inverse kinematics in closed form: `q_i = ||A_i - B_i|| - L0_i`.
/// - Forward kinematics: Newton on the pose from [`Hexapod::home`]; if that fails or breaks the
///   guard, continuation from the home pose's leg lengths. The assembly mode is the one of the home
///   pose: every leg must keep a positive projection `(A - B) . (A - B)_home` (it may not swing
///   through 90 degrees from its home direction), and the solution must lie within the solver's
///   bounds of the start.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Hexapod {
    /// Model name.
    pub name: String,
    /// The six legs, in joint order.
    pub legs: Vec<HexapodLeg>,
    /// `T_base_flange` of the home pose: the start of the forward kinematics, and what fixes the
    /// assembly mode.
    pub home: Pose,
    /// `T_flange_tool` (not a parameter: exactly redundant with the `B0` points).
    pub tool: Pose,
    /// Newton settings and guard.
    pub solver: SolverOptions,
}

impl Hexapod {
    /// The solver settings models of this kind start with.
    pub fn default_solver() -> SolverOptions {
        SolverOptions::default()
    }

    /// Checks the numbers.
    pub fn validate(&self) -> Result<()> {
        if self.legs.len() != 6 {
            return Err(RobotError::BadParameter {
                name: "legs".into(),
                value: self.legs.len() as f64,
                reason: "a hexapod needs 6 legs".into(),
            });
        }
        for (i, l) in self.legs.iter().enumerate() {
            let n = format!("leg{}", i + 1);
            check_vector(&format!("{n}.A"), &l.a_m)?;
            check_vector(&format!("{n}.B0"), &l.b0_m)?;
            check_positive(&format!("{n}.L0_m"), l.length0_m)?;
            JointLimits::new(&n, l.limits.lower, l.limits.upper)?;
            for (what, ax) in [("base_axis", l.base_axis), ("platform_axis", l.platform_axis)] {
                if let Some(ax) = ax {
                    check_direction(&format!("{n}.{what}"), &ax)?;
                }
            }
        }
        if !self.home.translation.vector.iter().chain(self.home.rotation.coords.iter()).all(|v| v.is_finite()) {
            return Err(RobotError::BadParameter {
                name: "home".into(),
                value: f64::NAN,
                reason: "the home pose is not finite".into(),
            });
        }
        Ok(())
    }

    /// Leg extensions for tool pose `t_base_tool` without the limit check.
    pub fn inverse_unchecked(&self, t_base_tool: &Pose) -> Result<Vec<f64>> {
        let mech = self.mechanism()?;
        if !t_base_tool.translation.vector.iter().chain(t_base_tool.rotation.coords.iter()).all(|v| v.is_finite()) {
            return Err(RobotError::Unreachable { reason: "the target pose is not finite".into() });
        }
        let flange = t_base_tool * self.tool.inverse();
        let q: Vec<f64> = self
            .legs
            .iter()
            .map(|l| (l.a_m - flange.transform_point(&Point3::from(l.b0_m)).coords).norm() - l.length0_m)
            .collect();
        let states = mech.leg_states(&q, t_base_tool)?;
        if let Some(msg) = mech.side_violation(&states) {
            return Err(RobotError::Unreachable {
                reason: format!("the pose is outside the home assembly mode: {msg}"),
            });
        }
        Ok(q)
    }
}

impl Parameterized for Hexapod {
    fn parameters(&self) -> Vec<ParamInfo> {
        let mut out = Vec::with_capacity(7 * self.legs.len());
        for (i, l) in self.legs.iter().enumerate() {
            let n = format!("leg{}", i + 1);
            for (name, v) in vec_names(&format!("{n}.A"), "_m").into_iter().zip(l.a_m.iter()) {
                out.push(ParamInfo::new(name, Unit::Metre, *v));
            }
            for (name, v) in vec_names(&format!("{n}.B0"), "_m").into_iter().zip(l.b0_m.iter()) {
                out.push(ParamInfo::new(name, Unit::Metre, *v));
            }
            out.push(ParamInfo::new(format!("{n}.L0_m"), Unit::Metre, l.length0_m));
        }
        out
    }

    fn set_parameter_values(&mut self, values: &[f64]) -> Result<()> {
        let info = self.parameters();
        check_values(values, info.len(), &info)?;
        let mut next = self.clone();
        for (l, v) in next.legs.iter_mut().zip(values.chunks_exact(7)) {
            l.a_m = Vector3::new(v[0], v[1], v[2]);
            l.b0_m = Vector3::new(v[3], v[4], v[5]);
            l.length0_m = v[6];
        }
        next.validate()?;
        *self = next;
        Ok(())
    }
}

impl Kinematics for Hexapod {
    fn dof(&self) -> usize {
        6
    }

    fn joint_names(&self) -> Vec<String> {
        (1..=6).map(|i| format!("leg{i}")).collect()
    }

    fn joint_kinds(&self) -> Vec<JointKind> {
        vec![JointKind::Prismatic; 6]
    }

    fn joint_limits(&self) -> Vec<JointLimits> {
        self.legs.iter().map(|l| l.limits).collect()
    }

    fn mobility(&self) -> Mobility {
        Mobility::Full6
    }

    fn forward(&self, q: &[f64]) -> Result<Pose> {
        check_len(q, 6)?;
        let mech = self.mechanism()?;
        let start = self.home * self.tool;
        let direct = mech.solve_pose(q, &start, &self.solver);
        let Err(first) = direct else {
            return direct;
        };
        let q_home = self.inverse_unchecked(&start)?;
        mech.solve_pose_continuation(&q_home, &start, q, &self.solver).map_err(|second| RobotError::FkNotConverged {
            reason: format!("from the home pose: {first}; by continuation from home: {second}"),
        })
    }

    /// Closed form; `seed` is ignored. Limits are checked.
    fn inverse(&self, t_base_tool: &Pose, _seed: &[f64]) -> Result<Vec<f64>> {
        let q = self.inverse_unchecked(t_base_tool)?;
        self.check_joints(&q)?;
        Ok(q)
    }

    fn jacobian(&self, q: &[f64]) -> Result<DMatrix<f64>> {
        self.mechanism_jacobian(q, false)
    }
}

impl ParallelRobot for Hexapod {
    fn mechanism(&self) -> Result<Mechanism> {
        self.validate()?;
        let legs = self
            .legs
            .iter()
            .enumerate()
            .map(|(i, l)| {
                let b_home = self.home.transform_point(&Point3::from(l.b0_m)).coords;
                Leg {
                    name: format!("leg{}", i + 1),
                    carriage: None,
                    a_m: l.a_m,
                    b0_m: l.b0_m,
                    length_m: l.length0_m,
                    length_joint: Some(i),
                    a_param: Some(7 * i),
                    b0_param: Some(7 * i + 3),
                    length_param: Some(7 * i + 6),
                    side: Some(LegSide { direction: l.a_m - b_home, branch: Branch::Plus }),
                    base_axis: l.base_axis,
                    platform_axis: l.platform_axis,
                }
            })
            .collect();
        Ok(Mechanism { joint_names: self.joint_names(), n_params: 42, carriages: Vec::new(), legs, tool: self.tool })
    }
}
