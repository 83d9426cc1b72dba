//! Trees of chains: a [`SerialChain`] whose joints branch (a torso carrying two arms).
//!
//! A tree is a chain with a [`ChainTree`]: every joint names the joint whose link carries it
//! (`parent`, `None` for the base), and the tree has one or more measurable tips, each a link
//! fixed to a joint's link by a constant transform. The joint vector `q` holds every actuated
//! joint of the tree in [`SerialChain::joints`] order (the URDF file's order); the parameters are
//! those of every joint, shared by all tips, so a table of several tips calibrates the joints
//! they have in common once. [`SerialChain::forward`](crate::Kinematics::forward), the Jacobian
//! and [`SerialChain::frames`]' tool are those of the active tip ([`SerialChain::with_tip`]);
//! a joint off the active tip's path has a zero Jacobian column. The gravity torques load every
//! joint with every link hanging on it, whichever tip is active, each link placed by its own
//! joints' values (whole-body gravity).
//!
//! Parameters: `tool.*` is the first tip's tool transform; every further tip `k` (2, 3, ...)
//! has `tip<k>.x_m`, `tip<k>.y_m`, `tip<k>.z_m`, its measured point in its link.

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use super::SerialChain;
use crate::error::{Result, RobotError};
use crate::geometry::Pose;
use crate::params::{ParamInfo, Unit};

/// One measurable tip of a tree: a link fixed to a joint's link.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TreeTip {
    /// The URDF link name.
    pub link: String,
    /// The joint (index into [`SerialChain::joints`]) whose link carries the tip.
    pub joint: usize,
    /// `T_joint-link_tip`: the tip in the carrying joint's link frame.
    pub tool: Pose,
}

/// The branching of a tree-shaped chain.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ChainTree {
    /// Per joint of [`SerialChain::joints`], the joint whose link carries it (`None`: the base).
    /// A parent always comes before its children.
    pub parent: Vec<Option<usize>>,
    /// The measurable tips (at least one).
    pub tips: Vec<TreeTip>,
    /// Index into `tips` of the tip the kinematics report.
    pub active: usize,
}

impl ChainTree {
    /// The joints from the base to joint `j` (indices, base first, `j` included).
    pub fn path_to(&self, j: usize) -> Vec<usize> {
        let mut out = vec![j];
        while let Some(p) = self.parent[*out.last().expect("non-empty")] {
            out.push(p);
        }
        out.reverse();
        out
    }

    /// Whether joint `i` moves joint `j`'s link (is `j` or one of its ancestors).
    pub fn moves(&self, i: usize, j: usize) -> bool {
        let mut cur = Some(j);
        while let Some(c) = cur {
            if c == i {
                return true;
            }
            cur = self.parent[c];
        }
        false
    }
}

impl SerialChain {
    /// Whether the chain is a tree ([`ChainTree`]).
    pub fn is_tree(&self) -> bool {
        self.tree.is_some()
    }

    /// The parent of every joint: the tree's, or the previous joint of a plain chain.
    pub fn joint_parents(&self) -> Vec<Option<usize>> {
        match &self.tree {
            Some(t) => t.parent.clone(),
            None => (0..self.joints.len()).map(|i| i.checked_sub(1)).collect(),
        }
    }

    /// The joint (index into [`SerialChain::joints`]) whose link carries the tool: the active
    /// tip's of a tree, the last joint of a chain.
    pub fn tip_joint(&self) -> usize {
        match &self.tree {
            Some(t) => t.tips[t.active].joint,
            None => self.joints.len().saturating_sub(1),
        }
    }

    /// The tips' link names (empty for a plain chain).
    pub fn tip_names(&self) -> Vec<String> {
        self.tree.as_ref().map(|t| t.tips.iter().map(|p| p.link.clone()).collect()).unwrap_or_default()
    }

    /// The same tree reporting tip `link`; an error names the tips there are.
    pub fn with_tip(&self, link: &str) -> Result<SerialChain> {
        let Some(tree) = &self.tree else {
            return Err(RobotError::Structure {
                location: crate::error::Location { file: self.name.clone().into(), line: 0, column: 0 },
                message: format!("'{}' is a single chain: it has no tip '{link}' to choose", self.name),
            });
        };
        let Some(k) = tree.tips.iter().position(|t| t.link == link) else {
            return Err(RobotError::Structure {
                location: crate::error::Location { file: self.name.clone().into(), line: 0, column: 0 },
                message: format!(
                    "the tree '{}' has no tip '{link}' (its tips: {})",
                    self.name,
                    self.tip_names().join(", ")
                ),
            });
        };
        let mut out = self.clone();
        let t = out.tree.as_mut().expect("tree");
        t.active = k;
        out.tool = t.tips[k].tool;
        Ok(out)
    }

    /// Whether joint `i` (index into [`SerialChain::joints`]) moves the active tip.
    pub fn moves_tip(&self, i: usize) -> bool {
        match &self.tree {
            Some(t) => t.moves(i, t.tips[t.active].joint),
            None => i < self.joints.len(),
        }
    }

    /// The tips' own parameters (`tip<k>.*_m` of tips 2, 3, ...).
    pub(super) fn tip_parameters(&self, out: &mut Vec<ParamInfo>) {
        let Some(t) = &self.tree else { return };
        for (k, tip) in t.tips.iter().enumerate().skip(1) {
            let v = tip.tool.translation.vector;
            for (a, n) in ["x_m", "y_m", "z_m"].iter().enumerate() {
                out.push(ParamInfo::new(format!("tip{}.{n}", k + 1), Unit::Metre, v[a]));
            }
        }
    }

    /// Sets the tips' tools from `tool` (the first tip's) and the `tip<k>` values at `v`;
    /// returns how many values it used.
    pub(super) fn set_tip_parameters(&mut self, tool: Pose, v: &[f64]) -> usize {
        let Some(t) = &mut self.tree else {
            self.tool = tool;
            return 0;
        };
        t.tips[0].tool = tool;
        let mut used = 0;
        for tip in t.tips.iter_mut().skip(1) {
            tip.tool.translation.vector = Vector3::new(v[used], v[used + 1], v[used + 2]);
            used += 3;
        }
        self.tool = t.tips[t.active].tool;
        used
    }

    /// The active tip's tool (what `tool.*` set for the first tip).
    pub(super) fn tool_for_parameters(&self) -> Pose {
        match &self.tree {
            Some(t) => t.tips[0].tool,
            None => self.tool,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::parse_urdf_tree_str;
    use crate::{Kinematics, Parameterized};

    /// A pitch torso with two one-joint arms, each ending in a fixed hand.
    fn torso() -> String {
        let inertial = |m: f64, x: f64| {
            format!("<inertial><origin xyz=\"{x} 0 0\"/><mass value=\"{m}\"/><inertia ixx=\"0.01\" iyy=\"0.01\" izz=\"0.01\"/></inertial>")
        };
        let joint = |name: &str, kind: &str, parent: &str, child: &str, xyz: &str| {
            format!(
                "<joint name=\"{name}\" type=\"{kind}\"><parent link=\"{parent}\"/><child link=\"{child}\"/>\
                 <origin xyz=\"{xyz}\"/><axis xyz=\"0 1 0\"/><limit lower=\"-3\" upper=\"3\"/></joint>"
            )
        };
        format!(
            "<robot name=\"torso\"><link name=\"base\"/><link name=\"torso\">{}</link><link name=\"left\">{}</link>\
             <link name=\"right\">{}</link><link name=\"right_hand\">{}</link><link name=\"left_hand\"/>{}{}{}{}{}</robot>",
            inertial(10.0, 0.05),
            inertial(2.0, 0.15),
            inertial(3.0, 0.2),
            inertial(1.0, 0.0),
            joint("pitch", "revolute", "base", "torso", "0 0 0.5"),
            joint("left1", "revolute", "torso", "left", "0 0.2 0.4"),
            joint("right1", "revolute", "torso", "right", "-0.1 -0.2 0.4"),
            joint("right_fix", "fixed", "right", "right_hand", "0.3 0 0"),
            joint("left_fix", "fixed", "left", "left_hand", "0.25 0 0"),
        )
    }

    #[test]
    fn a_tree_has_every_joint_and_each_tip_its_own_path() {
        let tree = parse_urdf_tree_str(&torso(), &[]).unwrap();
        assert_eq!(tree.joint_names(), ["pitch", "left1", "right1"]);
        assert_eq!(tree.tip_names(), ["right_hand", "left_hand"], "leaves in the file's link order");
        let left = tree.with_tip("left_hand").unwrap();
        // At q = 0 the left hand is at (0.25, 0.2, 0.9); the right arm's joint does not move it.
        let p = left.forward(&[0.0, 0.0, 0.7]).unwrap().translation.vector;
        assert!((p - nalgebra::Vector3::new(0.25, 0.2, 0.9)).norm() < 1e-12, "{p}");
        let jac = left.jacobian(&[0.1, 0.2, 0.3]).unwrap();
        assert!(jac.column(2).norm() == 0.0 && jac.column(1).norm() > 0.1);
        // Pitch 0.1 of the torso moves the right hand about y through the origin at z = 0.5.
        let right = tree.with_tip("right_hand").unwrap();
        let p = right.forward(&[0.0, 0.3, 0.0]).unwrap().translation.vector;
        assert!((p - nalgebra::Vector3::new(0.2, -0.2, 0.9)).norm() < 1e-12, "{p}");
        assert!(tree.with_tip("torso").is_err(), "only the tips are measurable");
    }

    #[test]
    fn whole_body_gravity_places_every_branch_by_its_own_joint() {
        // The right arm turned by 90 degrees about y points its masses down (x -> -z... the
        // rotation about +y takes x to -z): its lever about the torso pitch axis shrinks to
        // its 0.1 m offset behind the axis.
        let tree = parse_urdf_tree_str(&torso(), &[]).unwrap();
        let g = -tree.gravity_m_s2[2];
        let q_right = std::f64::consts::FRAC_PI_2;
        let tau = tree.gravity_torques(&[0.0, 0.0, q_right], 0.0).unwrap();
        let torso = -(10.0 * 0.05 + 2.0 * 0.15 + 3.0 * (-0.1) + 1.0 * (-0.1)) * g;
        assert!((tau[0] - torso).abs() < 1e-9, "torso {} vs {torso}", tau[0]);
        assert!((tau[1] + 2.0 * 0.15 * g).abs() < 1e-9, "left arm {}", tau[1]);
        assert!(tau[2].abs() < 1e-9, "the right arm hangs straight down: {}", tau[2]);
        // The same with the left hand active: the gravity of the whole body does not depend on
        // the tip.
        let left = tree.with_tip("left_hand").unwrap();
        assert_eq!(left.gravity_torques(&[0.0, 0.0, q_right], 0.0).unwrap(), tau);
    }

    #[test]
    fn the_second_tip_has_its_own_point_parameters() {
        let mut tree = parse_urdf_tree_str(&torso(), &["left_hand".into(), "right_hand".into()]).unwrap();
        let names: Vec<String> = tree.parameters().into_iter().map(|p| p.name).collect();
        assert!(names.ends_with(&["tip2.x_m".into(), "tip2.y_m".into(), "tip2.z_m".into()]), "{names:?}");
        let mut v = tree.parameter_values();
        let n = v.len();
        v[n - 3] += 0.01;
        tree.set_parameter_values(&v).unwrap();
        let right = tree.with_tip("right_hand").unwrap();
        let p = right.forward(&[0.0, 0.0, 0.0]).unwrap().translation.vector;
        assert!((p - nalgebra::Vector3::new(0.21, -0.2, 0.9)).norm() < 1e-12, "{p}");
        assert_eq!(tree.with_tip("left_hand").unwrap().parameter_values(), tree.parameter_values());
    }
}
