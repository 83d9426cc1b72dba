//! The nominal and modified 3-DOF Gantry-Tau: one link per arm, constant platform orientation.

use nalgebra::{DMatrix, Isometry3, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use super::legs::{cart_carriages, cart_root, trilaterate, Leg, LegSide, Mechanism};
use super::{check_direction, check_positive, check_vector, three_cart_joints, vec_names, Branch, ParallelRobot};
use crate::error::{Result, RobotError};
use crate::geometry::Pose;
use crate::kinematics::{check_len, JointKind, JointLimits, Kinematics, Mobility};
use crate::params::{check_values, ParamInfo, Parameterized, Unit};

/// One arm of the 3-DOF model: a cart on a guideway and the (virtual) link of its cluster.
///
/// Closure: `||A^s + q v - T||^2 = L^2`, `T` the platform (tool) point.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GantryArm {
    /// Link length `L`.
    pub length_m: f64,
    /// `A^s`: cart joint centre at `q = 0` minus the platform joint offset, base frame.
    pub a_m: Vector3<f64>,
    /// Cart displacement per metre of travel, base frame. Not normalised (its norm absorbs a
    /// transmission scale error).
    pub v: Vector3<f64>,
    /// Cart travel limits, metres.
    pub limits: JointLimits,
    /// Which root of the inverse kinematics the arm uses: the sign of `v . (A - T)` (see
    /// [`Branch`]).
    pub branch: Branch,
    /// Axis of the base-side spherical joint (base axes); `None`: the link direction at `q = 0`.
    pub base_axis: Option<Vector3<f64>>,
    /// Axis of the platform-side spherical joint (platform axes); `None`: the direction `A - T`
    /// at `q = 0`.
    pub platform_axis: Option<Vector3<f64>>,
}

/// The 3-DOF Gantry-Tau (nominal model when all `v_i` are equal unit vectors, modified model with
/// one direction per guideway): 21 parameters `L_i, A^s_i, v_i`.
///
/// Inverse kinematics in closed form, each arm on its own [`GantryArm::branch`]; forward
/// kinematics by intersecting the three link spheres on the side [`GantryTau3::assembly`]. Both
/// reject a configuration in which an arm is on the other branch, so that they invert each other.
/// The tool is the platform point `T`; the orientation is constant (identity).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GantryTau3 {
    /// Model name.
    pub name: String,
    /// The three arms, in joint order.
    pub arms: [GantryArm; 3],
    /// Assembly mode of the forward kinematics: the sign of `((C2 - C1) x (C3 - C1)) . (T - C1)`
    /// with `C_i = A^s_i + q_i v_i`.
    pub assembly: Branch,
}

impl GantryTau3 {
    /// Checks lengths, directions and limits.
    pub fn validate(&self) -> Result<()> {
        for (i, arm) in self.arms.iter().enumerate() {
            let p = format!("arm{}", i + 1);
            check_positive(&format!("{p}.L_m"), arm.length_m)?;
            check_vector(&format!("{p}.A_m"), &arm.a_m)?;
            check_direction(&format!("{p}.v"), &arm.v)?;
            JointLimits::new(&format!("cart{}", i + 1), arm.limits.lower, arm.limits.upper)?;
        }
        Ok(())
    }

    /// Sphere centres `C_i = A^s_i + q_i v_i`.
    fn centres(&self, q: &[f64]) -> [Vector3<f64>; 3] {
        [0, 1, 2].map(|i| self.arms[i].a_m + self.arms[i].v * q[i])
    }

    /// The assembly sign of a platform point for given sphere centres.
    fn assembly_of(c: &[Vector3<f64>; 3], t: &Vector3<f64>) -> Branch {
        Branch::of((c[1] - c[0]).cross(&(c[2] - c[0])).dot(&(t - c[0])))
    }

    /// Joint values for platform point `t` without the limit check.
    pub fn inverse_position(&self, t: &Vector3<f64>) -> Result<[f64; 3]> {
        self.validate()?;
        if t.iter().any(|v| !v.is_finite()) {
            return Err(RobotError::Unreachable { reason: "the target position is not finite".into() });
        }
        let mut q = [0.0; 3];
        for (i, arm) in self.arms.iter().enumerate() {
            q[i] = cart_root(&arm.a_m, &arm.v, t, arm.length_m, arm.branch).ok_or_else(|| {
                let dir = arm.v.normalize();
                let w = t - arm.a_m;
                let dist = (w - dir * dir.dot(&w)).norm();
                RobotError::Unreachable {
                    reason: format!(
                        "arm {}: the target is {dist:.4} m from guideway {}, farther than the link length {:.4} m",
                        i + 1,
                        i + 1,
                        arm.length_m
                    ),
                }
            })?;
        }
        let c = self.centres(&q);
        if Self::assembly_of(&c, t) != self.assembly {
            return Err(RobotError::Unreachable {
                reason: format!(
                    "the target lies in the '{}' assembly mode; the model works in '{}'",
                    Self::assembly_of(&c, t).as_str(),
                    self.assembly.as_str()
                ),
            });
        }
        Ok(q)
    }
}

impl Parameterized for GantryTau3 {
    fn parameters(&self) -> Vec<ParamInfo> {
        let mut out = Vec::with_capacity(21);
        for (i, arm) in self.arms.iter().enumerate() {
            let p = format!("arm{}", i + 1);
            out.push(ParamInfo::new(format!("{p}.L_m"), Unit::Metre, arm.length_m));
            for (n, v) in vec_names(&format!("{p}.A"), "_m").into_iter().zip(arm.a_m.iter()) {
                out.push(ParamInfo::new(n, Unit::Metre, *v));
            }
            for (n, v) in vec_names(&format!("{p}.v"), "").into_iter().zip(arm.v.iter()) {
                out.push(ParamInfo::new(n, Unit::Dimensionless, *v));
            }
        }
        out
    }

    fn set_parameter_values(&mut self, values: &[f64]) -> Result<()> {
        let info = self.parameters();
        check_values(values, info.len(), &info)?;
        let mut next = self.clone();
        for (i, arm) in next.arms.iter_mut().enumerate() {
            let v = &values[7 * i..7 * i + 7];
            arm.length_m = v[0];
            arm.a_m = Vector3::new(v[1], v[2], v[3]);
            arm.v = Vector3::new(v[4], v[5], v[6]);
        }
        next.validate()?;
        *self = next;
        Ok(())
    }
}

impl Kinematics for GantryTau3 {
    three_cart_joints!(arms);

    fn mobility(&self) -> Mobility {
        Mobility::Translation3
    }

    /// Trilateration; [`RobotError::Unreachable`] when the spheres do not meet or an arm would be
    /// on the other branch.
    fn forward(&self, q: &[f64]) -> Result<Pose> {
        check_len(q, 3)?;
        self.validate()?;
        let c = self.centres(q);
        let r = [0, 1, 2].map(|i| self.arms[i].length_m);
        let t = trilaterate(&c, &r, self.assembly).map_err(|reason| RobotError::Unreachable { reason })?;
        for (i, arm) in self.arms.iter().enumerate() {
            let side = arm.v.dot(&(c[i] - t));
            if Branch::of(side) != arm.branch || side == 0.0 {
                return Err(RobotError::Unreachable {
                    reason: format!(
                        "arm {}: at these cart positions the link would be in the '{}' configuration; the model works in '{}'",
                        i + 1,
                        Branch::of(side).as_str(),
                        arm.branch.as_str()
                    ),
                });
            }
        }
        Ok(Isometry3::from_parts(Translation3::from(t), UnitQuaternion::identity()))
    }

    /// Closed form; `seed` is ignored (each arm's root is fixed by its branch). The orientation
    /// of the target is ignored. Errors: [`RobotError::Unreachable`] naming the arm without a real
    /// root, [`RobotError::OutsideLimits`] when a cart would leave its travel.
    fn inverse(&self, t_base_tool: &Pose, _seed: &[f64]) -> Result<Vec<f64>> {
        let q = self.inverse_position(&t_base_tool.translation.vector)?.to_vec();
        self.check_joints(&q)?;
        Ok(q)
    }

    fn jacobian(&self, q: &[f64]) -> Result<DMatrix<f64>> {
        self.mechanism_jacobian(q, true)
    }
}

impl ParallelRobot for GantryTau3 {
    fn mechanism(&self) -> Result<Mechanism> {
        self.validate()?;
        let carriages = cart_carriages([0, 1, 2].map(|i| self.arms[i].v), |i| 7 * i + 4);
        let legs = self
            .arms
            .iter()
            .enumerate()
            .map(|(i, arm)| Leg {
                name: format!("arm{}", i + 1),
                carriage: Some(i),
                a_m: arm.a_m,
                b0_m: Vector3::zeros(),
                length_m: arm.length_m,
                length_joint: None,
                a_param: Some(7 * i + 1),
                b0_param: None,
                length_param: Some(7 * i),
                side: Some(LegSide { direction: arm.v, branch: arm.branch }),
                base_axis: arm.base_axis,
                platform_axis: arm.platform_axis,
            })
            .collect();
        Ok(Mechanism { joint_names: self.joint_names(), n_params: 21, carriages, legs, tool: Pose::identity() })
    }
}
