//! A spring gravity compensator acting on one revolute joint (the shoulder of heavy arms).
//!
//! A spring of stiffness `K_s` and free length `s0` joins an anchor `A` on the link before the
//! joint to an attachment `B` on the link the joint moves. With `s(q) = |B(q) - A|`, its energy is
//! `U = K_s (s - s0)^2 / 2`, and it exerts on the joint the torque `-U'(q) = -K_s (s - s0) s'`.
//! The joint deflects by `theta = k (tau_ext - K_s (s - s0) s')`, which is linear in the
//! products `k K_s` and `k K_s s0`: the identification keeps its linear form with the two
//! compensator terms `-s s'` and `s'` (Klimchik's "reduced model including the gravity
//! compensator spring"). The spring's own stiffness contribution `U''` (of the order of
//! `K_s s'^2`, well below a gearbox's stiffness for a soft, preloaded spring) is not part of the
//! linear model; [`GravityCompensator::stiffness_nm_per_rad`] gives its size.

use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};

use crate::kinematics::JointKind;
use crate::serial::{ChainFrames, SerialChain};
use crate::stiffness::error::{Result, StiffnessError};

/// Geometry and spring of a gravity compensator.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GravityCompensator {
    /// The joint it acts on (1-based, revolute).
    pub joint: usize,
    /// Anchor `A` in the frame of the link before the joint (the base frame for joint 1).
    pub anchor_m: [f64; 3],
    /// Attachment `B` in the frame of the link the joint moves.
    pub attach_m: [f64; 3],
    /// Spring stiffness `K_s`.
    pub stiffness_n_per_m: f64,
    /// Free length `s0` (longer than the mounted length for a compression spring).
    pub free_length_m: f64,
}

/// The spring length and its first two derivatives with respect to the joint.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpringGeometry {
    /// `s`.
    pub length_m: f64,
    /// `ds/dq`.
    pub d1_m_per_rad: f64,
    /// `d2s/dq2`.
    pub d2_m_per_rad2: f64,
}

impl GravityCompensator {
    /// Checks the compensator against the chain.
    pub fn validate(&self, chain: &SerialChain) -> Result<()> {
        let n = chain.joints.len();
        if self.joint == 0 || self.joint > n {
            return Err(StiffnessError::Structure(format!(
                "gravity compensator on joint {}: the robot has joints 1 to {n}",
                self.joint
            )));
        }
        if chain.joints[self.joint - 1].kind != JointKind::Revolute {
            return Err(StiffnessError::Structure(format!(
                "gravity compensator on joint {}: only revolute joints are supported",
                self.joint
            )));
        }
        let finite = self.anchor_m.iter().chain(&self.attach_m).all(|v| v.is_finite());
        if !(finite && self.stiffness_n_per_m.is_finite() && self.stiffness_n_per_m >= 0.0) {
            return Err(StiffnessError::BadCompliance {
                what: format!("gravity compensator on joint {}", self.joint),
                reason: "anchor, attachment and a non-negative stiffness must be finite".into(),
            });
        }
        if !(self.free_length_m.is_finite() && self.free_length_m >= 0.0) {
            return Err(StiffnessError::BadCompliance {
                what: format!("gravity compensator on joint {}", self.joint),
                reason: format!("free length {} m must be finite and non-negative", self.free_length_m),
            });
        }
        Ok(())
    }

    /// Length of the spring and its derivatives at the frames of a configuration.
    pub fn geometry(&self, chain: &SerialChain, frames: &ChainFrames) -> Result<SpringGeometry> {
        self.validate(chain)?;
        let j = self.joint - 1;
        let before = if j == 0 { chain.base } else { frames.links[j - 1] };
        let a = before * Point3::from(self.anchor_m);
        let b = frames.links[j] * Point3::from(self.attach_m);
        let u = frames.axes[j];
        let c = frames.axis_points[j];
        let b1: Vector3<f64> = u.cross(&(b - c));
        let b2: Vector3<f64> = u.cross(&b1);
        let d = b - a;
        let s = d.norm();
        if s < 1e-9 {
            return Err(StiffnessError::Structure(format!(
                "gravity compensator on joint {}: anchor and attachment coincide",
                self.joint
            )));
        }
        let db = d.dot(&b1);
        let s1 = db / s;
        let s2 = (b1.dot(&b1) + d.dot(&b2)) / s - db * db / (s * s * s);
        Ok(SpringGeometry { length_m: s, d1_m_per_rad: s1, d2_m_per_rad2: s2 })
    }

    /// The torque the spring exerts on the joint, `-K_s (s - s0) s'` (N m).
    pub fn torque_nm(&self, chain: &SerialChain, frames: &ChainFrames) -> Result<f64> {
        let g = self.geometry(chain, frames)?;
        Ok(-self.stiffness_n_per_m * (g.length_m - self.free_length_m) * g.d1_m_per_rad)
    }

    /// The spring's own contribution to the joint stiffness, `U'' = K_s (s'^2 + (s - s0) s'')`.
    pub fn stiffness_nm_per_rad(&self, chain: &SerialChain, frames: &ChainFrames) -> Result<f64> {
        let g = self.geometry(chain, frames)?;
        Ok(self.stiffness_n_per_m
            * (g.d1_m_per_rad * g.d1_m_per_rad + (g.length_m - self.free_length_m) * g.d2_m_per_rad2))
    }

    /// The two regressor terms `(-s s', s')` multiplying the parameters `k K_s` and `k K_s s0`.
    pub fn basis(&self, chain: &SerialChain, frames: &ChainFrames) -> Result<[f64; 2]> {
        let g = self.geometry(chain, frames)?;
        Ok([-g.length_m * g.d1_m_per_rad, g.d1_m_per_rad])
    }
}
