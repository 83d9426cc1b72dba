//! The workspace by search, the measurable region and the candidate grids of measurement planning
//! (the source's automated calibration flow, steps 2 to 5).
//!
//! - [`search`] walks a regular lattice over Cartesian space (tool positions, with a list of tool
//!   orientations for robots that control it) or over joint space, and classifies every node by
//!   the first constraint it breaks, in a fixed order ([`Stage`]): reachable (inverse or forward
//!   kinematics), joint limits with their margin, spherical-joint angles, the workspace-edge
//!   margin, each obstacle box with its margin (the carried plate's bounding radius counts), and
//!   last whether the measuring device can measure the target there ([`MeasuringDevice`]). The
//!   survivors after every stage are counted, so the report can say how much of the workspace
//!   each constraint takes, and an empty workspace names the constraint that emptied it
//!   ([`WorkspaceMap::require_nonempty`]).
//! - [`spread_grid`] places the source's regular grid over the measurable region: spacing
//!   `(volume / wanted)^(1/d)`, then the nodes that survive every check (the source: 100 wanted
//!   poses, spacing 0.1367 m, 112 poses). The same function with a larger count gives the denser
//!   pools that pose selection optimises over; [`sample_measurable`] draws random pools.
//! - Measuring devices: what a camera rig sees ([`CameraVisibility`]: the whole target inside every image with a
//!   border, a smallest projected feature side in pixels, a largest angle between the viewing ray
//!   and the target normal, line of sight not blocked by an obstacle box; noise from the corner
//!   noise through the pose estimation's Fisher information) and a laser tracker
//!   ([`TrackerView`]: range, line of sight, reflector acceptance angle; noise `a + b d`).
//!
//! Every candidate returned here passed the [`SafetyChecker`]'s pose check, so planned poses
//! inherit its guarantees. Lattice coordinates are metres for Cartesian grids and normalised joint
//! coordinates (each joint's allowed range mapped to `[0, 1]`) for joint grids; volumes are m^3
//! (summed over the orientations) or fractions of the joint box.

use std::collections::BTreeMap;

use nalgebra::UnitQuaternion;
use serde::{Deserialize, Serialize};

use crate::error::{Result, RobotError};
use crate::geometry::Pose;
use crate::kinematics::Mobility;

mod devices;
mod search;

pub use devices::{
    segment_hits_box, CameraView, CameraVisibility, MeasuringDevice, ProjectFn, TargetShape, TrackerView, Unmeasurable,
    VisibilitySettings,
};
pub use search::{
    allowed_joint_box, build_lattice, grid_at_spacing, home_configuration, sample_measurable, search, spacing_for,
    spread_grid, SpreadGrid,
};

/// Which space the search lattice covers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GridSpace {
    /// Cartesian for robots that command positions only (Gantry-Tau), joint space otherwise.
    #[default]
    Auto,
    /// Tool positions on a lattice in the base frame, each with every listed orientation;
    /// joints from the inverse kinematics seeded at the home configuration.
    Cartesian,
    /// Joint values on a lattice over the allowed joint box.
    Joint,
}

/// Settings of the workspace search (TOML table `[workspace]` of a plan file).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WorkspaceSettings {
    /// Lattice space.
    #[serde(default)]
    pub space: GridSpace,
    /// Spacing of the Cartesian search lattice, metres.
    #[serde(default = "default_search_spacing")]
    pub search_spacing_m: f64,
    /// Lower corner of the Cartesian search box (default: the reach of random joint samples).
    #[serde(default)]
    pub box_min_m: Option<[f64; 3]>,
    /// Upper corner of the Cartesian search box.
    #[serde(default)]
    pub box_max_m: Option<[f64; 3]>,
    /// Tool orientations (roll-pitch-yaw `Rz Ry Rx`, degrees, base frame) tried at every
    /// Cartesian node, for robots that control the orientation.
    #[serde(default = "default_orientations")]
    pub orientations_rpy_deg: Vec<[f64; 3]>,
    /// Nodes per joint of the joint-space search lattice.
    #[serde(default = "default_joint_steps")]
    pub joint_steps: usize,
    /// Home configuration (SI joint units): the inverse kinematics seed and the program's start.
    /// Default: the middle of the joint ranges.
    #[serde(default)]
    pub home_si: Vec<f64>,
    /// Refuse lattices with more nodes than this.
    #[serde(default = "default_max_points")]
    pub max_points: usize,
}

fn default_search_spacing() -> f64 {
    0.05
}
fn default_orientations() -> Vec<[f64; 3]> {
    vec![[0.0, 0.0, 0.0]]
}
fn default_joint_steps() -> usize {
    9
}
fn default_max_points() -> usize {
    2_000_000
}

impl Default for WorkspaceSettings {
    fn default() -> Self {
        Self {
            space: GridSpace::Auto,
            search_spacing_m: default_search_spacing(),
            box_min_m: None,
            box_max_m: None,
            orientations_rpy_deg: default_orientations(),
            joint_steps: default_joint_steps(),
            home_si: Vec::new(),
            max_points: default_max_points(),
        }
    }
}

impl WorkspaceSettings {
    /// Checks the settings: positive finite spacing, at least 2 joint steps, well-formed box,
    /// finite orientations.
    pub fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(RobotError::Safety(format!("workspace settings: {m}")));
        if !(self.search_spacing_m.is_finite() && self.search_spacing_m > 0.0) {
            return bad(format!("search_spacing_m must be > 0, got {}", self.search_spacing_m));
        }
        if self.joint_steps < 2 {
            return bad(format!("joint_steps must be at least 2, got {}", self.joint_steps));
        }
        if self.orientations_rpy_deg.is_empty() {
            return bad("orientations_rpy_deg needs at least one orientation".into());
        }
        if self.orientations_rpy_deg.iter().flatten().any(|v| !v.is_finite()) {
            return bad("orientations_rpy_deg holds a non-finite angle".into());
        }
        match (self.box_min_m, self.box_max_m) {
            (Some(lo), Some(hi)) => {
                if (0..3).any(|k| !(lo[k].is_finite() && hi[k].is_finite() && lo[k] < hi[k])) {
                    return bad("box_min_m must lie below box_max_m on every axis (finite values)".into());
                }
            }
            (None, None) => {}
            _ => return bad("give both box_min_m and box_max_m, or neither".into()),
        }
        if self.home_si.iter().any(|v| !v.is_finite()) {
            return bad("home_si holds a non-finite value".into());
        }
        Ok(())
    }

    /// The space actually searched for a robot of this mobility.
    pub fn resolved_space(&self, mobility: Mobility) -> GridSpace {
        match (self.space, mobility) {
            (GridSpace::Auto, Mobility::Full6) => GridSpace::Joint,
            (GridSpace::Auto, _) => GridSpace::Cartesian,
            (s, _) => s,
        }
    }
}

/// The constraints in the order the search applies them.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Stage {
    /// The kinematics has a solution (inverse for Cartesian nodes, forward for joint nodes).
    Reachable,
    /// Joint limits shrunk by the margin.
    JointLimits,
    /// Spherical-joint angles (parallel robots).
    SphericalJoints,
    /// Distance from the edge of the reachable workspace.
    WorkspaceEdge,
    /// One obstacle box with its margin (index into the safety configuration's obstacles).
    Obstacle {
        /// Index of the box.
        index: usize,
    },
    /// The measuring device can measure the target.
    Measurable,
}

/// Survivors after one stage.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StageCount {
    /// The stage.
    pub stage: Stage,
    /// What it checks, in words (with its numbers: margin, angle, obstacle name).
    pub name: String,
    /// Lattice nodes left after this stage (and all before it).
    pub survivors: usize,
    /// Nodes this stage removed.
    pub removed: usize,
}

/// A node that passed every check: a safe, measurable configuration.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Candidate {
    /// Joint values (SI joint units).
    pub q: Vec<f64>,
    /// `T_base_tool` at `q`.
    pub t_base_tool: Pose,
    /// Index of the tool orientation (Cartesian lattices; 0 for joint lattices).
    pub orientation: usize,
    /// Lattice coordinates (metres, or normalised joint coordinates).
    pub coords: Vec<f64>,
}

/// The lattice a search runs on (kept to place later grids in the same coordinates).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Lattice {
    /// Tool positions in a box, each with every orientation.
    Cartesian {
        /// Lower corner, metres.
        min_m: [f64; 3],
        /// Upper corner, metres.
        max_m: [f64; 3],
        /// Tool orientations.
        orientations: Vec<UnitQuaternion<f64>>,
    },
    /// Joint values: coordinate `u_i` in `[0, 1]` maps to `lo_i + u_i (hi_i - lo_i)`.
    Joint {
        /// Lower ends of the joint ranges.
        lo: Vec<f64>,
        /// Upper ends.
        hi: Vec<f64>,
    },
}

impl Lattice {
    /// Number of coordinates of a node.
    pub fn dimension(&self) -> usize {
        match self {
            Lattice::Cartesian { .. } => 3,
            Lattice::Joint { lo, .. } => lo.len(),
        }
    }

    /// Number of orientations per node.
    pub fn n_orientations(&self) -> usize {
        match self {
            Lattice::Cartesian { orientations, .. } => orientations.len(),
            Lattice::Joint { .. } => 1,
        }
    }

    fn bounds(&self) -> (Vec<f64>, Vec<f64>) {
        match self {
            Lattice::Cartesian { min_m, max_m, .. } => (min_m.to_vec(), max_m.to_vec()),
            Lattice::Joint { lo, .. } => (vec![0.0; lo.len()], vec![1.0; lo.len()]),
        }
    }
}

/// The result of [`search`].
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct WorkspaceMap {
    /// The lattice searched.
    pub lattice: Lattice,
    /// Lattice spacing (metres or normalised joint units).
    pub spacing: f64,
    /// Volume of one lattice cell (`spacing^d`).
    pub cell_volume: f64,
    /// Unit of volumes: `m^3` or `joint-box fraction`.
    pub volume_unit: String,
    /// Nodes tried (positions times orientations).
    pub total: usize,
    /// Survivors after each stage, in order.
    pub stages: Vec<StageCount>,
    /// Why nodes were not measurable (reason -> count), when a device was given.
    pub unmeasurable: BTreeMap<String, usize>,
    /// Every node that passed all stages.
    pub measurable: Vec<Candidate>,
    /// The measuring device's name (None: no device, the safe workspace is returned).
    pub device: Option<String>,
    /// Home configuration used as seed.
    pub home: Vec<f64>,
}

impl WorkspaceMap {
    /// Survivors after the last stage of a kind up to and including `upto` (all nodes when no
    /// stage of that order exists).
    fn survivors_through(&self, pred: impl Fn(&Stage) -> bool) -> usize {
        self.stages.iter().filter(|s| pred(&s.stage)).last().map_or(self.total, |s| s.survivors)
    }

    /// The kinematic workspace: nodes left after reachability, joint limits, spherical joints
    /// and the edge margin (before obstacles and the device).
    pub fn kinematic(&self) -> usize {
        self.survivors_through(|s| !matches!(s, Stage::Obstacle { .. } | Stage::Measurable))
    }

    /// Nodes left after the obstacles too (the safe workspace).
    pub fn safe(&self) -> usize {
        self.survivors_through(|s| !matches!(s, Stage::Measurable))
    }

    /// Fraction of the kinematic workspace left after the obstacles.
    pub fn fraction_after_obstacles(&self) -> f64 {
        ratio(self.safe(), self.kinematic())
    }

    /// Fraction of the kinematic workspace that is safe and measurable.
    pub fn measurable_fraction(&self) -> f64 {
        ratio(self.measurable.len(), self.kinematic())
    }

    /// Volume of `count` nodes, in [`WorkspaceMap::volume_unit`].
    pub fn volume_of(&self, count: usize) -> f64 {
        count as f64 * self.cell_volume
    }

    /// Volume of the measurable region.
    pub fn measurable_volume(&self) -> f64 {
        self.volume_of(self.measurable.len())
    }

    /// The stage that left no node, if the region is empty.
    pub fn emptied_by(&self) -> Option<&StageCount> {
        if !self.measurable.is_empty() {
            return None;
        }
        self.stages.iter().find(|s| s.survivors == 0)
    }

    /// `Ok` when some node survived; otherwise an error naming the constraint that removed the
    /// last nodes, with the survivors of every stage before it.
    pub fn require_nonempty(&self) -> Result<()> {
        if !self.measurable.is_empty() {
            return Ok(());
        }
        let Some(s) = self.emptied_by() else {
            return Err(RobotError::Safety("the workspace lattice has no node at all".into()));
        };
        let before: Vec<String> = self
            .stages
            .iter()
            .take_while(|t| t.stage != s.stage)
            .map(|t| format!("{}: {} left", t.name, t.survivors))
            .collect();
        let mut msg = format!(
            "the workspace is empty: {} removes the last {} of {} lattice nodes",
            s.name, s.removed, self.total
        );
        if !before.is_empty() {
            msg.push_str(&format!(" (before it: {})", before.join("; ")));
        }
        if matches!(s.stage, Stage::Measurable) && !self.unmeasurable.is_empty() {
            let mut reasons: Vec<(&String, &usize)> = self.unmeasurable.iter().collect();
            reasons.sort_by(|a, b| b.1.cmp(a.1));
            let top: Vec<String> = reasons.iter().take(3).map(|(r, n)| format!("{r} ({n})")).collect();
            msg.push_str(&format!("; most common reasons: {}", top.join(", ")));
        }
        msg.push_str("; relax that constraint or move the search box");
        Err(RobotError::Safety(msg))
    }
}

fn ratio(a: usize, b: usize) -> f64 {
    if b == 0 {
        0.0
    } else {
        a as f64 / b as f64
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Point3;

    use super::search::{for_each_node, lattice_axes};
    use super::*;
    use crate::safety::ObstacleBox;

    #[test]
    fn slab_test_matches_box_distance() {
        let o = ObstacleBox { name: "b".into(), min_m: [0.0, 0.0, 0.0], max_m: [1.0, 1.0, 1.0], margin_m: 0.0 };
        assert!(segment_hits_box(&Point3::new(-1.0, 0.5, 0.5), &Point3::new(2.0, 0.5, 0.5), &o));
        assert!(!segment_hits_box(&Point3::new(-1.0, 0.5, 1.5), &Point3::new(2.0, 0.5, 1.5), &o));
        assert!(!segment_hits_box(&Point3::new(-1.0, 0.5, 0.5), &Point3::new(-0.5, 0.5, 0.5), &o));
        // A point resting on a face is not blocked by that face.
        assert!(!segment_hits_box(&Point3::new(-1.0, 0.5, 0.5), &Point3::new(0.0, 0.5, 0.5), &o));
    }

    #[test]
    fn lattice_is_centred() {
        let axes = lattice_axes(&[0.0], &[1.0], 0.3);
        assert_eq!(axes[0].len(), 4);
        assert!((axes[0][0] - 0.05).abs() < 1e-12 && (axes[0][3] - 0.95).abs() < 1e-12);
        let mut n = 0;
        for_each_node(&[vec![0.0, 1.0], vec![0.0, 1.0, 2.0]], |_| n += 1);
        assert_eq!(n, 6);
    }

    #[test]
    fn plate_geometry() {
        let t = TargetShape::plate(0.04, 0.02);
        assert_eq!(t.features_m.len(), 5);
        assert_eq!(t.corners_m.len(), 20);
        assert!((t.radius_m() - 0.08 * 2f64.sqrt()).abs() < 1e-12);
    }
}
