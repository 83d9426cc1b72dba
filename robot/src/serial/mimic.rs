//! Coupled (mimic) joints: a joint that follows another joint of the chain.
//!
//! URDF's `<mimic joint="leader" multiplier="m" offset="o"/>` makes a joint's value
//! `q = m * q_leader + o`. Real robots have such joints: a parallelogram linkage's passive
//! joint, a torso joint coupled to another by a belt, the Fanuc-style J2/J3 interaction. A mimic
//! joint is part of the chain's geometry (its origin, axis, inertial and correction transform are
//! the chain's like any other joint's) but not an actuated coordinate:
//!
//! - [`Kinematics::dof`](crate::Kinematics::dof), the joint names, kinds and limits, the
//!   measurement tables' `q1..qN`, the Jacobian and the inverse kinematics are over the actuated
//!   joints only, numbered 1..N in chain order without the mimic joints;
//! - forward kinematics moves the mimic joint by its coupled value;
//! - [`SerialChain::frames`] lists every joint of the chain (mimic joints included, in chain
//!   order), so `ChainFrames::links[i]` belongs to `joints[i]`;
//! - the parameters of a mimic joint are named `mimic<k>.` (k = 1, 2, ... over the mimic joints,
//!   base to tip) and end with `mimic<k>.coupling`, the multiplier, which calibration may
//!   identify; actuated joints keep `joint<i>.` with `i` their actuated number (the same number
//!   as `q<i>`, `offset.q<i>` and the effects' joint numbers);
//! - gravity torques ([`SerialChain::gravity_torques`]) are the actuated coordinates' generalized
//!   forces: the torque the mimic joint carries reaches its leader's drive times the multiplier,
//!   `tau_leader + m * tau_mimic` (virtual work); [`SerialChain::gravity_torques_all`] gives the
//!   per-joint torques.
//!
//! The leader must be an actuated joint of the chain (not a mimic joint itself, not a fixed
//! joint, not a joint off the chain); a mimic joint's own limits are kept for writing it back but
//! not enforced (its leader's are).

use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

use super::SerialChain;
use crate::error::{Result, RobotError};
use crate::kinematics::check_len;

/// The coupling of a mimic joint: `q = multiplier * q_leader + offset`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Mimic {
    /// Name of the leader: an actuated joint of the same chain.
    pub leader: String,
    /// `m` in `q = m q_leader + o` (URDF default 1).
    pub multiplier: f64,
    /// `o` in `q = m q_leader + o`, rad or m (URDF default 0).
    pub offset: f64,
}

/// Where the joint values of every chain joint come from.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Source {
    /// Actuated joint, 0-based actuated index.
    Actuated(usize),
    /// Mimic joint: 0-based actuated index of the leader, multiplier, offset.
    Coupled(usize, f64, f64),
}

impl SerialChain {
    /// Whether any joint of the chain is a mimic joint.
    pub fn has_mimic_joints(&self) -> bool {
        self.joints.iter().any(|j| j.mimic.is_some())
    }

    /// Indices (into [`SerialChain::joints`]) of the actuated joints, in order.
    pub fn actuated_indices(&self) -> Vec<usize> {
        self.joints.iter().enumerate().filter(|(_, j)| j.mimic.is_none()).map(|(i, _)| i).collect()
    }

    /// Index into [`SerialChain::joints`] of actuated joint `actuated` (0-based), if it exists.
    pub fn joint_index_of_actuated(&self, actuated: usize) -> Option<usize> {
        self.joints.iter().enumerate().filter(|(_, j)| j.mimic.is_none()).nth(actuated).map(|(i, _)| i)
    }

    /// The source of every joint's value; an error names a mimic joint whose leader is not an
    /// actuated joint of the chain.
    pub(crate) fn sources(&self) -> Result<Vec<Source>> {
        let mut act = 0;
        let mut out = Vec::with_capacity(self.joints.len());
        for j in &self.joints {
            match &j.mimic {
                None => {
                    out.push(Source::Actuated(act));
                    act += 1;
                }
                Some(m) => out.push(Source::Coupled(self.leader_index(&j.name, m)?, m.multiplier, m.offset)),
            }
        }
        Ok(out)
    }

    /// The 0-based actuated index of mimic joint `name`'s leader.
    fn leader_index(&self, name: &str, m: &Mimic) -> Result<usize> {
        let coupling = |message: String| RobotError::Coupling { joint: name.to_string(), message };
        if !m.multiplier.is_finite() || !m.offset.is_finite() {
            return Err(coupling(format!("multiplier {} and offset {} must be finite", m.multiplier, m.offset)));
        }
        let Some(pos) = self.joints.iter().position(|j| j.name == m.leader) else {
            return Err(coupling(format!("its leader '{}' is not a joint of the chain '{}'", m.leader, self.name)));
        };
        if let Some(mm) = &self.joints[pos].mimic {
            return Err(coupling(format!(
                "its leader '{}' is itself a mimic joint (of '{}'); a mimic joint must follow an actuated joint",
                m.leader, mm.leader
            )));
        }
        Ok(self.joints[..pos].iter().filter(|j| j.mimic.is_none()).count())
    }

    /// The value of every joint of the chain (mimic joints included) for actuated values `q`.
    pub fn all_joint_values(&self, q: &[f64]) -> Result<Vec<f64>> {
        check_len(q, self.dof_actuated())?;
        if !self.has_mimic_joints() {
            return Ok(q.to_vec());
        }
        Ok(self
            .sources()?
            .into_iter()
            .map(|s| match s {
                Source::Actuated(a) => q[a],
                Source::Coupled(l, m, o) => m * q[l] + o,
            })
            .collect())
    }

    /// `d q_all / d q_actuated`: one row per joint of the chain, one column per actuated joint
    /// (the identity for a chain without mimic joints).
    pub fn coupling_matrix(&self) -> Result<DMatrix<f64>> {
        let src = self.sources()?;
        let mut e = DMatrix::zeros(self.joints.len(), self.dof_actuated());
        for (i, s) in src.into_iter().enumerate() {
            match s {
                Source::Actuated(a) => e[(i, a)] = 1.0,
                Source::Coupled(l, m, _) => e[(i, l)] = m,
            }
        }
        Ok(e)
    }

    /// Number of actuated joints.
    pub(crate) fn dof_actuated(&self) -> usize {
        self.joints.iter().filter(|j| j.mimic.is_none()).count()
    }

    /// The parameter-name prefix of joint `i` (index into [`SerialChain::joints`]): `joint<a>`
    /// with `a` its 1-based actuated number, or `mimic<k>` for the k-th mimic joint.
    pub fn parameter_prefix(&self, i: usize) -> String {
        let before = &self.joints[..i];
        if self.joints[i].mimic.is_some() {
            format!("mimic{}", before.iter().filter(|j| j.mimic.is_some()).count() + 1)
        } else {
            format!("joint{}", before.iter().filter(|j| j.mimic.is_none()).count() + 1)
        }
    }

    /// The joint (index into [`SerialChain::joints`]) a parameter named `<prefix>.<rest>` belongs
    /// to, for the prefixes of [`SerialChain::parameter_prefix`].
    pub fn joint_of_parameter(&self, name: &str) -> Option<usize> {
        let prefix = name.split('.').next()?;
        let (mimic, k) =
            if let Some(k) = prefix.strip_prefix("joint") { (false, k) } else { (true, prefix.strip_prefix("mimic")?) };
        let k: usize = k.parse().ok()?;
        self.joints
            .iter()
            .enumerate()
            .filter(|(_, j)| j.mimic.is_some() == mimic)
            .nth(k.checked_sub(1)?)
            .map(|(i, _)| i)
    }

    /// Refuses a chain with mimic joints for an operation that does not model them (`what`),
    /// naming the first mimic joint.
    pub fn require_no_mimic(&self, what: &str) -> Result<()> {
        match self.joints.iter().find(|j| j.mimic.is_some()) {
            None => Ok(()),
            Some(j) => Err(RobotError::Coupling {
                joint: j.name.clone(),
                message: format!("{what} does not support mimic (coupled) joints"),
            }),
        }
    }
}
