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
//! - Measuring devices: a camera rig ([`CameraRig`]: the whole target inside every image with a
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
use std::sync::Arc;

use nalgebra::{Isometry3, Matrix3, Matrix6, Point2, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::error::{Result, RobotError};
use crate::geometry::Pose;
use crate::kinematics::{JointKind, Mobility};
use crate::safety::{ObstacleBox, SafetyBody, SafetyChecker, Violation};

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

/// Why a device cannot measure the target at a pose.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Unmeasurable {
    /// Short reason used for counting (`camera 'left': outside the image`).
    pub reason: String,
    /// The numbers behind it.
    pub detail: String,
}

impl std::fmt::Display for Unmeasurable {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} ({})", self.reason, self.detail)
    }
}

/// A measuring device as planning sees it: where the target can be measured, and how well.
pub trait MeasuringDevice: Send + Sync {
    /// Name used in reports.
    fn name(&self) -> String;

    /// `T_device_base`: the frame the device reports positions in.
    fn t_device_base(&self) -> Pose;

    /// The measured point (target origin or reflector) in the tool frame.
    fn measured_point_in_tool_m(&self) -> Vector3<f64>;

    /// Whether the target can be measured with the tool at `t_base_tool`.
    fn check(&self, t_base_tool: &Pose) -> std::result::Result<(), Unmeasurable>;

    /// Covariance (device frame, m^2) of the measured point's position at `t_base_tool`.
    fn position_covariance(&self, t_base_tool: &Pose) -> Result<Matrix3<f64>>;
}

/// A pixel projection of a camera-frame point (`None` when it does not project).
pub type ProjectFn = dyn Fn(&Point3<f64>) -> Option<Point2<f64>> + Send + Sync;

/// One camera: its placement, image size and projection (any lens model, supplied as a
/// function so that this crate needs no camera library).
#[derive(Clone)]
pub struct CameraView {
    /// Name used in messages.
    pub name: String,
    /// `T_base_cam` (camera z forward, x right, y down).
    pub t_base_cam: Pose,
    /// Image width, pixels (the image spans `[-0.5, width - 0.5]`).
    pub width_px: f64,
    /// Image height, pixels.
    pub height_px: f64,
    project: Arc<ProjectFn>,
}

impl std::fmt::Debug for CameraView {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CameraView")
            .field("name", &self.name)
            .field("t_base_cam", &self.t_base_cam)
            .field("width_px", &self.width_px)
            .field("height_px", &self.height_px)
            .finish_non_exhaustive()
    }
}

impl CameraView {
    /// A camera with its own projection function (pixel-centre convention).
    pub fn new(
        name: impl Into<String>,
        t_base_cam: Pose,
        width_px: u32,
        height_px: u32,
        project: impl Fn(&Point3<f64>) -> Option<Point2<f64>> + Send + Sync + 'static,
    ) -> Self {
        Self {
            name: name.into(),
            t_base_cam,
            width_px: width_px as f64,
            height_px: height_px as f64,
            project: Arc::new(project),
        }
    }

    /// A distortion-free pinhole camera.
    #[allow(clippy::too_many_arguments)]
    pub fn pinhole(
        name: impl Into<String>,
        t_base_cam: Pose,
        fx_px: f64,
        fy_px: f64,
        cx_px: f64,
        cy_px: f64,
        width_px: u32,
        height_px: u32,
    ) -> Self {
        Self::new(name, t_base_cam, width_px, height_px, move |p: &Point3<f64>| {
            (p.z > 1e-9).then(|| Point2::new(fx_px * p.x / p.z + cx_px, fy_px * p.y / p.z + cy_px))
        })
    }

    /// `T_base_cam` of a camera at `position_m` whose optical axis passes through `look_at_m`,
    /// with `up` appearing up in the image.
    pub fn look_at(position_m: [f64; 3], look_at_m: [f64; 3], up: [f64; 3]) -> Result<Pose> {
        let pos = Vector3::from(position_m);
        let z = Vector3::from(look_at_m) - pos;
        let up = Vector3::from(up);
        if z.norm() < 1e-9 || z.cross(&up).norm() < 1e-9 * z.norm() * up.norm().max(1e-300) {
            return Err(RobotError::Safety(
                "camera: look_at_m must differ from position_m and not lie along up".into(),
            ));
        }
        let z = z.normalize();
        let x = z.cross(&up).normalize();
        let y = z.cross(&x);
        let rot = Rotation3::from_basis_unchecked(&[x, y, z]);
        Ok(Isometry3::from_parts(Translation3::from(pos), UnitQuaternion::from_rotation_matrix(&rot)))
    }

    /// Pixel of a camera-frame point.
    pub fn project_cam(&self, p_cam: &Point3<f64>) -> Option<Point2<f64>> {
        if p_cam.z <= 1e-9 {
            return None;
        }
        (self.project)(p_cam).filter(|px| px.x.is_finite() && px.y.is_finite())
    }

    /// Whether a pixel lies at least `border_px` inside the image.
    pub fn inside(&self, px: &Point2<f64>, border_px: f64) -> bool {
        px.x >= -0.5 + border_px
            && px.x <= self.width_px - 0.5 - border_px
            && px.y >= -0.5 + border_px
            && px.y <= self.height_px - 0.5 - border_px
    }
}

/// The planar target's geometry in the target frame (z = 0, normal +z).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TargetShape {
    /// Outline of the plate (must project inside every image).
    pub outline_m: Vec<Point3<f64>>,
    /// Dark features (polygons) whose projected sides must be long enough.
    pub features_m: Vec<Vec<Point3<f64>>>,
    /// Corner points measured in the image (the pose estimation's observations).
    pub corners_m: Vec<Point3<f64>>,
}

impl TargetShape {
    /// From a 2D outline, 2D feature polygons and corner points (all target frame, metres).
    pub fn new(outline_m: &[Point2<f64>], features_m: &[Vec<Point2<f64>>], corners_m: &[Point3<f64>]) -> Self {
        let lift = |p: &Point2<f64>| Point3::new(p.x, p.y, 0.0);
        Self {
            outline_m: outline_m.iter().map(lift).collect(),
            features_m: features_m.iter().map(|f| f.iter().map(lift).collect()).collect(),
            corners_m: corners_m.to_vec(),
        }
    }

    /// The source's plate: the five black squares (side `square_m`) of a 3x3 checkerboard,
    /// with a white margin.
    pub fn plate(square_m: f64, margin_m: f64) -> Self {
        let half = 1.5 * square_m + margin_m;
        let outline =
            [Point2::new(-half, -half), Point2::new(half, -half), Point2::new(half, half), Point2::new(-half, half)];
        let mut features = Vec::new();
        let mut corners = Vec::new();
        for row in 0..3 {
            for col in 0..3 {
                if (row + col) % 2 != 0 {
                    continue;
                }
                let x0 = (col as f64 - 1.5) * square_m;
                let y1 = (1.5 - row as f64) * square_m;
                let sq = vec![
                    Point2::new(x0, y1),
                    Point2::new(x0 + square_m, y1),
                    Point2::new(x0 + square_m, y1 - square_m),
                    Point2::new(x0, y1 - square_m),
                ];
                corners.extend(sq.iter().map(|p| Point3::new(p.x, p.y, 0.0)));
                features.push(sq);
            }
        }
        Self::new(&outline, &features, &corners)
    }

    /// Radius of the outline's bounding circle about the target origin.
    pub fn radius_m(&self) -> f64 {
        self.outline_m.iter().map(|p| p.coords.norm()).fold(0.0, f64::max)
    }
}

/// What a camera must see (TOML table `[measure]` of a plan file).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VisibilitySettings {
    /// Shortest projected side of any dark feature, pixels.
    #[serde(default = "default_min_feature_px")]
    pub min_feature_px: f64,
    /// Largest angle between the viewing ray and the target normal, degrees.
    #[serde(default = "default_view_angle")]
    pub max_view_angle_deg: f64,
    /// Distance the outline must keep from the image border, pixels.
    #[serde(default = "default_border")]
    pub border_px: f64,
    /// Corner noise per image axis, pixels (one standard deviation).
    #[serde(default = "default_sigma_px")]
    pub sigma_px: f64,
    /// Cameras that must see the target (default: all).
    #[serde(default)]
    pub min_cameras: Option<usize>,
}

fn default_min_feature_px() -> f64 {
    15.0
}
fn default_view_angle() -> f64 {
    60.0
}
fn default_border() -> f64 {
    10.0
}
fn default_sigma_px() -> f64 {
    0.1
}

impl Default for VisibilitySettings {
    fn default() -> Self {
        Self {
            min_feature_px: default_min_feature_px(),
            max_view_angle_deg: default_view_angle(),
            border_px: default_border(),
            sigma_px: default_sigma_px(),
            min_cameras: None,
        }
    }
}

/// One or more cameras photographing a target on the tool.
#[derive(Clone, Debug)]
pub struct CameraRig {
    /// The cameras; the first one's frame is the device frame.
    pub cameras: Vec<CameraView>,
    /// The target.
    pub target: TargetShape,
    /// `T_tool_target`.
    pub t_tool_target: Pose,
    /// Visibility requirements and corner noise.
    pub settings: VisibilitySettings,
    /// Boxes that block the line of sight (usually the safety configuration's obstacles).
    pub occluders: Vec<ObstacleBox>,
}

impl CameraRig {
    /// A rig; checks the settings.
    pub fn new(
        cameras: Vec<CameraView>,
        target: TargetShape,
        t_tool_target: Pose,
        settings: VisibilitySettings,
        occluders: Vec<ObstacleBox>,
    ) -> Result<Self> {
        let bad = |m: String| Err(RobotError::Safety(format!("camera rig: {m}")));
        if cameras.is_empty() {
            return bad("no camera".into());
        }
        if target.outline_m.len() < 3 || target.corners_m.is_empty() {
            return bad("the target needs an outline of at least 3 points and at least one corner".into());
        }
        let s = &settings;
        for (v, n) in [(s.min_feature_px, "min_feature_px"), (s.border_px, "border_px")] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(format!("{n} must be finite and >= 0, got {v}"));
            }
        }
        if !(s.sigma_px.is_finite() && s.sigma_px > 0.0) {
            return bad(format!("sigma_px must be > 0, got {}", s.sigma_px));
        }
        if !(s.max_view_angle_deg.is_finite() && s.max_view_angle_deg > 0.0 && s.max_view_angle_deg <= 90.0) {
            return bad(format!("max_view_angle_deg must lie in (0, 90], got {}", s.max_view_angle_deg));
        }
        if let Some(m) = s.min_cameras {
            if m == 0 || m > cameras.len() {
                return bad(format!("min_cameras must lie in 1..={}, got {m}", cameras.len()));
            }
        }
        Ok(Self { cameras, target, t_tool_target, settings, occluders })
    }

    fn t_base_target(&self, t_base_tool: &Pose) -> Pose {
        t_base_tool * self.t_tool_target
    }

    /// Whether camera `cam` sees the whole target at `t_base_target`.
    fn camera_sees(&self, cam: &CameraView, t_base_target: &Pose) -> std::result::Result<(), Unmeasurable> {
        let who = format!("camera '{}'", cam.name);
        let fail = |what: &str, detail: String| Err(Unmeasurable { reason: format!("{who}: {what}"), detail });
        let t_cam_target = cam.t_base_cam.inverse() * t_base_target;
        let centre = t_cam_target.translation.vector;
        let normal = t_cam_target.rotation * Vector3::z();
        if centre.norm() < 1e-9 {
            return fail("target at the camera", "the target origin coincides with the camera centre".into());
        }
        let cos = normal.dot(&(-centre)) / centre.norm();
        let angle_deg = cos.clamp(-1.0, 1.0).acos().to_degrees();
        if cos <= 0.0 {
            return fail("target seen from behind", format!("viewing angle {angle_deg:.1} deg"));
        }
        if angle_deg > self.settings.max_view_angle_deg {
            return fail(
                "viewing angle too large",
                format!("{angle_deg:.1} deg > {:.1} deg", self.settings.max_view_angle_deg),
            );
        }
        for p in &self.target.outline_m {
            let pc = t_cam_target * p;
            if pc.z <= 1e-6 {
                return fail("target behind the camera", format!("outline point at depth {:.3} m", pc.z));
            }
            match cam.project_cam(&pc) {
                Some(px) if cam.inside(&px, self.settings.border_px) => {}
                Some(px) => {
                    return fail(
                        "target outside the image",
                        format!(
                            "outline point at ({:.0}, {:.0}) px, image {}x{} px with a {:.0} px border",
                            px.x, px.y, cam.width_px, cam.height_px, self.settings.border_px
                        ),
                    )
                }
                None => return fail("target outside the image", "an outline point does not project".into()),
            }
        }
        let mut smallest = f64::INFINITY;
        for f in &self.target.features_m {
            let px: Vec<Point2<f64>> = f.iter().filter_map(|p| cam.project_cam(&(t_cam_target * p))).collect();
            if px.len() != f.len() {
                return fail("feature does not project", "a feature corner does not project".into());
            }
            for k in 0..px.len() {
                smallest = smallest.min((px[(k + 1) % px.len()] - px[k]).norm());
            }
        }
        if smallest < self.settings.min_feature_px {
            return fail(
                "features too small",
                format!("shortest feature side {smallest:.1} px < {:.1} px", self.settings.min_feature_px),
            );
        }
        let eye = Point3::from(cam.t_base_cam.translation.vector);
        let sight: Vec<Point3<f64>> = std::iter::once(Point3::origin())
            .chain(self.target.outline_m.iter().copied())
            .map(|p| t_base_target * p)
            .collect();
        for o in &self.occluders {
            if sight.iter().any(|p| segment_hits_box(&eye, p, o)) {
                return fail(&format!("line of sight blocked by '{}'", o.name), format!("obstacle '{}'", o.name));
            }
        }
        Ok(())
    }

    /// Fisher information (6x6, per (translation, rotation) of the target about its origin in
    /// the device frame) of the corners seen by camera `cam`.
    fn camera_information(&self, cam: &CameraView, t_base_target: &Pose) -> Result<Matrix6<f64>> {
        let t_dev_base = self.t_device_base();
        let t_cam_dev = cam.t_base_cam.inverse() * t_dev_base.inverse();
        let t_dev_target = t_dev_base * t_base_target;
        let origin = t_dev_target.translation.vector;
        let r_cam_dev = t_cam_dev.rotation.to_rotation_matrix();
        let s2 = self.settings.sigma_px * self.settings.sigma_px;
        let mut info = Matrix6::zeros();
        let h = 1e-6;
        for c in &self.target.corners_m {
            let p_dev = t_dev_target * c;
            let p_cam = t_cam_dev * p_dev;
            // d(pixel)/d(p_cam) by central differences of the projection.
            let mut jp = nalgebra::Matrix2x3::zeros();
            for k in 0..3 {
                let mut a = p_cam;
                let mut b = p_cam;
                a[k] += h;
                b[k] -= h;
                let (Some(pa), Some(pb)) = (cam.project_cam(&a), cam.project_cam(&b)) else {
                    return Err(RobotError::Safety(format!(
                        "camera '{}': a target corner does not project; cannot compute the measurement noise",
                        cam.name
                    )));
                };
                jp.set_column(k, &((pa - pb) / (2.0 * h)));
            }
            // d(p_dev)/d(xi) = [I, -[p_dev - origin]x].
            let lever = p_dev.coords - origin;
            let mut dp = nalgebra::Matrix3x6::zeros();
            dp.fixed_view_mut::<3, 3>(0, 0).copy_from(&Matrix3::identity());
            dp.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-crate::geometry::skew(&lever)));
            let j = jp * r_cam_dev.matrix() * dp;
            info += j.transpose() * j / s2;
        }
        Ok(info)
    }
}

impl MeasuringDevice for CameraRig {
    fn name(&self) -> String {
        let names: Vec<&str> = self.cameras.iter().map(|c| c.name.as_str()).collect();
        format!("camera{} {}", if names.len() > 1 { "s" } else { "" }, names.join(" + "))
    }

    fn t_device_base(&self) -> Pose {
        self.cameras[0].t_base_cam.inverse()
    }

    fn measured_point_in_tool_m(&self) -> Vector3<f64> {
        self.t_tool_target.translation.vector
    }

    fn check(&self, t_base_tool: &Pose) -> std::result::Result<(), Unmeasurable> {
        let t = self.t_base_target(t_base_tool);
        let need = self.settings.min_cameras.unwrap_or(self.cameras.len());
        let mut seen = 0;
        let mut first_failure = None;
        for cam in &self.cameras {
            match self.camera_sees(cam, &t) {
                Ok(()) => seen += 1,
                Err(e) => {
                    if first_failure.is_none() {
                        first_failure = Some(e);
                    }
                }
            }
        }
        if seen >= need {
            Ok(())
        } else {
            Err(first_failure.unwrap_or(Unmeasurable {
                reason: "too few cameras see the target".into(),
                detail: format!("{seen} of {need}"),
            }))
        }
    }

    fn position_covariance(&self, t_base_tool: &Pose) -> Result<Matrix3<f64>> {
        let t = self.t_base_target(t_base_tool);
        let mut info = Matrix6::zeros();
        for cam in &self.cameras {
            if self.camera_sees(cam, &t).is_ok() {
                info += self.camera_information(cam, &t)?;
            }
        }
        let inv = info.try_inverse().ok_or_else(|| RobotError::Singular {
            reason: "the cameras do not determine the target pose at this configuration".into(),
        })?;
        let c = inv.fixed_view::<3, 3>(0, 0).into_owned();
        Ok((c + c.transpose()) * 0.5)
    }
}

/// A laser tracker measuring a reflector on the tool.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrackerView {
    /// Name used in reports.
    pub name: String,
    /// `T_base_tracker`.
    pub t_base_tracker: Pose,
    /// Usable distance range `[min, max]`, metres.
    pub range_m: [f64; 2],
    /// Constant part of the noise, micrometres per axis (one standard deviation).
    pub sigma_const_um: f64,
    /// Distance-proportional part, micrometres per metre.
    pub sigma_per_m_um: f64,
    /// Reflector position in the tool frame.
    pub reflector_in_tool_m: Vector3<f64>,
    /// Reflector opening axis in the tool frame (None: accepts every direction).
    pub reflector_axis_in_tool: Option<Vector3<f64>>,
    /// Half acceptance angle of the reflector, degrees.
    pub max_incidence_deg: f64,
    /// Boxes that block the line of sight.
    pub occluders: Vec<ObstacleBox>,
}

impl MeasuringDevice for TrackerView {
    fn name(&self) -> String {
        format!("laser tracker '{}'", self.name)
    }

    fn t_device_base(&self) -> Pose {
        self.t_base_tracker.inverse()
    }

    fn measured_point_in_tool_m(&self) -> Vector3<f64> {
        self.reflector_in_tool_m
    }

    fn check(&self, t_base_tool: &Pose) -> std::result::Result<(), Unmeasurable> {
        let who = format!("tracker '{}'", self.name);
        let p = t_base_tool * Point3::from(self.reflector_in_tool_m);
        let eye = Point3::from(self.t_base_tracker.translation.vector);
        let d = (p - eye).norm();
        if d < self.range_m[0] || d > self.range_m[1] {
            return Err(Unmeasurable {
                reason: format!("{who}: out of range"),
                detail: format!("{d:.3} m outside [{:.3}, {:.3}] m", self.range_m[0], self.range_m[1]),
            });
        }
        if let Some(axis) = self.reflector_axis_in_tool {
            let a = t_base_tool.rotation * axis;
            let to_tracker = eye - p;
            let cos = a.dot(&to_tracker) / (a.norm() * to_tracker.norm()).max(1e-300);
            let ang = cos.clamp(-1.0, 1.0).acos().to_degrees();
            if ang > self.max_incidence_deg {
                return Err(Unmeasurable {
                    reason: format!("{who}: reflector turned away"),
                    detail: format!("incidence {ang:.1} deg > {:.1} deg", self.max_incidence_deg),
                });
            }
        }
        for o in &self.occluders {
            if segment_hits_box(&eye, &p, o) {
                return Err(Unmeasurable {
                    reason: format!("{who}: line of sight blocked by '{}'", o.name),
                    detail: format!("obstacle '{}'", o.name),
                });
            }
        }
        Ok(())
    }

    fn position_covariance(&self, t_base_tool: &Pose) -> Result<Matrix3<f64>> {
        let p = t_base_tool * Point3::from(self.reflector_in_tool_m);
        let d = (p.coords - self.t_base_tracker.translation.vector).norm();
        let s = (self.sigma_const_um + self.sigma_per_m_um * d) * 1e-6;
        Ok(Matrix3::identity() * s * s)
    }
}

/// Whether the segment from `a` to `b` passes through the box (the last millimetre before `b`
/// is ignored, so a target resting on a face is not blocked by it).
pub fn segment_hits_box(a: &Point3<f64>, b: &Point3<f64>, o: &ObstacleBox) -> bool {
    let d = b - a;
    let len = d.norm();
    if len < 1e-12 {
        return (0..3).all(|k| a[k] >= o.min_m[k] && a[k] <= o.max_m[k]);
    }
    let t_end = ((len - 1e-3) / len).max(0.0);
    let (mut t0, mut t1) = (0.0f64, t_end);
    for k in 0..3 {
        if d[k].abs() < 1e-15 {
            if a[k] < o.min_m[k] || a[k] > o.max_m[k] {
                return false;
            }
        } else {
            let mut ta = (o.min_m[k] - a[k]) / d[k];
            let mut tb = (o.max_m[k] - a[k]) / d[k];
            if ta > tb {
                std::mem::swap(&mut ta, &mut tb);
            }
            t0 = t0.max(ta);
            t1 = t1.min(tb);
            if t0 > t1 {
                return false;
            }
        }
    }
    true
}

/// The allowed joint box: the model's limits, tightened by the safety configuration's
/// `joint_limits`, shrunk by its `joint_margin`; unbounded revolute joints span `[-pi, pi]` and
/// unbounded prismatic ones `[-1, 1]` m.
pub fn allowed_joint_box<R: SafetyBody + ?Sized>(model: &R, checker: &SafetyChecker<'_, R>) -> (Vec<f64>, Vec<f64>) {
    let cfg = checker.config();
    let kinds = model.joint_kinds();
    let mut lo = Vec::new();
    let mut hi = Vec::new();
    for (i, l) in model.joint_limits().iter().enumerate() {
        let (dlo, dhi) = match kinds[i] {
            JointKind::Revolute => (-std::f64::consts::PI, std::f64::consts::PI),
            JointKind::Prismatic => (-1.0, 1.0),
        };
        let mut a = if l.lower.is_finite() { l.lower } else { dlo };
        let mut b = if l.upper.is_finite() { l.upper } else { dhi };
        if let Some(Some([x, y])) = cfg.joint_limits.get(i) {
            a = a.max(*x);
            b = b.min(*y);
        }
        lo.push(a + cfg.joint_margin);
        hi.push(b - cfg.joint_margin);
    }
    (lo, hi)
}

fn stage_name(stage: &Stage, checker_cfg: &crate::safety::SafetyConfig, device: Option<&str>) -> String {
    match stage {
        Stage::Reachable => "reachable (kinematics has a solution)".into(),
        Stage::JointLimits => format!("joint limits with a {} margin", checker_cfg.joint_margin),
        Stage::SphericalJoints => format!("spherical-joint limit {} deg", checker_cfg.spherical_max_deg),
        Stage::WorkspaceEdge => format!("workspace-edge margin {} m", checker_cfg.workspace_edge_margin_m),
        Stage::Obstacle { index } => {
            let o = &checker_cfg.obstacles[*index];
            format!(
                "obstacle '{}' (margin {} m, plate radius {} m, link radius {} m)",
                o.name, o.margin_m, checker_cfg.plate_radius_m, checker_cfg.link_radius_m
            )
        }
        Stage::Measurable => format!("measurable by {}", device.unwrap_or("the device")),
    }
}

/// How one lattice node fared.
enum NodeResult {
    Accepted(Candidate),
    Rejected(Stage, Option<String>),
}

/// Everything needed to evaluate nodes.
struct Evaluator<'a, R: SafetyBody + ?Sized> {
    model: &'a R,
    checker: &'a SafetyChecker<'a, R>,
    device: Option<&'a dyn MeasuringDevice>,
    lattice: &'a Lattice,
    home: Vec<f64>,
}

impl<R: SafetyBody + ?Sized> Evaluator<'_, R> {
    fn evaluate(&self, coords: &[f64], orientation: usize) -> NodeResult {
        let (q, pose) = match self.lattice {
            Lattice::Cartesian { orientations, .. } => {
                let target = Isometry3::from_parts(
                    Translation3::new(coords[0], coords[1], coords[2]),
                    orientations[orientation],
                );
                match self.model.inverse(&target, &self.home) {
                    Ok(q) => match self.model.forward(&q) {
                        Ok(p) => (q, p),
                        Err(_) => return NodeResult::Rejected(Stage::Reachable, None),
                    },
                    Err(RobotError::OutsideLimits { .. }) => return NodeResult::Rejected(Stage::JointLimits, None),
                    Err(_) => return NodeResult::Rejected(Stage::Reachable, None),
                }
            }
            Lattice::Joint { lo, hi } => {
                let q: Vec<f64> = coords.iter().zip(lo.iter().zip(hi)).map(|(u, (a, b))| a + u * (b - a)).collect();
                match self.model.forward(&q) {
                    Ok(p) => (q, p),
                    Err(_) => return NodeResult::Rejected(Stage::Reachable, None),
                }
            }
        };
        let cfg = self.checker.config();
        let mut worst: Option<Stage> = None;
        for v in self.checker.violations(&q, 0.0) {
            let s = match v {
                Violation::JointLimit { .. } => Stage::JointLimits,
                Violation::SphericalJoint { .. } => Stage::SphericalJoints,
                Violation::WorkspaceEdge { .. } => Stage::WorkspaceEdge,
                Violation::Obstacle { obstacle, .. } => {
                    Stage::Obstacle { index: cfg.obstacles.iter().position(|o| o.name == obstacle).unwrap_or(0) }
                }
                _ => Stage::Reachable,
            };
            worst = Some(match worst {
                Some(w) if w <= s => w,
                _ => s,
            });
        }
        if let Some(s) = worst {
            return NodeResult::Rejected(s, None);
        }
        if let Some(dev) = self.device {
            if let Err(e) = dev.check(&pose) {
                return NodeResult::Rejected(Stage::Measurable, Some(e.reason));
            }
        }
        NodeResult::Accepted(Candidate { q, t_base_tool: pose, orientation, coords: coords.to_vec() })
    }
}

/// Nodes of a regular lattice with spacing `h` centred in the box `[lo, hi]`.
fn lattice_axes(lo: &[f64], hi: &[f64], h: f64) -> Vec<Vec<f64>> {
    lo.iter()
        .zip(hi)
        .map(|(a, b)| {
            let extent = (b - a).max(0.0);
            let n = (extent / h + 1e-9).floor() as usize + 1;
            let off = a + 0.5 * (extent - (n - 1) as f64 * h);
            (0..n).map(|k| off + k as f64 * h).collect()
        })
        .collect()
}

fn for_each_node(axes: &[Vec<f64>], mut f: impl FnMut(&[f64])) {
    let d = axes.len();
    if axes.iter().any(|a| a.is_empty()) {
        return;
    }
    let mut idx = vec![0usize; d];
    let mut coords: Vec<f64> = axes.iter().map(|a| a[0]).collect();
    loop {
        f(&coords);
        let mut k = 0;
        loop {
            if k == d {
                return;
            }
            idx[k] += 1;
            if idx[k] < axes[k].len() {
                coords[k] = axes[k][idx[k]];
                break;
            }
            idx[k] = 0;
            coords[k] = axes[k][0];
            k += 1;
        }
    }
}

fn node_count(axes: &[Vec<f64>]) -> usize {
    axes.iter().map(|a| a.len()).fold(1usize, |acc, n| acc.saturating_mul(n))
}

/// The home configuration: the settings' `home_si` or the middle of the allowed joint box.
pub fn home_configuration<R: SafetyBody + ?Sized>(
    model: &R,
    checker: &SafetyChecker<'_, R>,
    settings: &WorkspaceSettings,
) -> Result<Vec<f64>> {
    if settings.home_si.is_empty() {
        let (lo, hi) = allowed_joint_box(model, checker);
        Ok(lo.iter().zip(&hi).map(|(a, b)| 0.5 * (a + b)).collect())
    } else if settings.home_si.len() != model.dof() {
        Err(RobotError::JointCount { expected: model.dof(), got: settings.home_si.len() })
    } else {
        Ok(settings.home_si.clone())
    }
}

/// Builds the search lattice for `model`.
pub fn build_lattice<R: SafetyBody + ?Sized>(
    model: &R,
    checker: &SafetyChecker<'_, R>,
    settings: &WorkspaceSettings,
) -> Result<(Lattice, f64)> {
    settings.validate()?;
    let (lo, hi) = allowed_joint_box(model, checker);
    match settings.resolved_space(model.mobility()) {
        GridSpace::Joint | GridSpace::Auto => Ok((Lattice::Joint { lo, hi }, 1.0 / (settings.joint_steps - 1) as f64)),
        GridSpace::Cartesian => {
            let (min_m, max_m) = match (settings.box_min_m, settings.box_max_m) {
                (Some(a), Some(b)) => (a, b),
                _ => {
                    // The reach of random joint samples, padded by two lattice cells.
                    let mut rng = ChaCha8Rng::seed_from_u64(0);
                    let mut a = [f64::INFINITY; 3];
                    let mut b = [f64::NEG_INFINITY; 3];
                    for _ in 0..4000 {
                        let q: Vec<f64> = lo.iter().zip(&hi).map(|(x, y)| x + (y - x) * rng.random::<f64>()).collect();
                        if let Ok(p) = model.forward(&q) {
                            for k in 0..3 {
                                a[k] = a[k].min(p.translation.vector[k]);
                                b[k] = b[k].max(p.translation.vector[k]);
                            }
                        }
                    }
                    if !a[0].is_finite() {
                        return Err(RobotError::Safety(
                            "the workspace is empty: reachable (kinematics has a solution) fails for 4000 random joint samples; give box_min_m and box_max_m".into(),
                        ));
                    }
                    let pad = 2.0 * settings.search_spacing_m;
                    (a.map(|v| v - pad), b.map(|v| v + pad))
                }
            };
            let orientations = settings
                .orientations_rpy_deg
                .iter()
                .map(|r| UnitQuaternion::from_euler_angles(r[0].to_radians(), r[1].to_radians(), r[2].to_radians()))
                .collect();
            Ok((Lattice::Cartesian { min_m, max_m, orientations }, settings.search_spacing_m))
        }
    }
}

/// Searches the workspace: every lattice node is classified by the first constraint it breaks
/// (see [`Stage`]); `device` (if any) decides the measurable region. Errors only for bad
/// settings or an oversized lattice; an empty region is reported in the map (see
/// [`WorkspaceMap::require_nonempty`]).
pub fn search<R: SafetyBody + ?Sized>(
    model: &R,
    checker: &SafetyChecker<'_, R>,
    device: Option<&dyn MeasuringDevice>,
    settings: &WorkspaceSettings,
) -> Result<WorkspaceMap> {
    let (lattice, h) = build_lattice(model, checker, settings)?;
    let home = home_configuration(model, checker, settings)?;
    let (lo, hi) = lattice.bounds();
    let axes = lattice_axes(&lo, &hi, h);
    let n_o = lattice.n_orientations();
    let total = node_count(&axes).saturating_mul(n_o);
    if total > settings.max_points {
        return Err(RobotError::Safety(format!(
            "the search lattice has {total} nodes (more than max_points = {}); use a larger spacing or fewer joint steps",
            settings.max_points
        )));
    }
    let ev = Evaluator { model, checker, device, lattice: &lattice, home: home.clone() };
    let mut rejected: BTreeMap<Stage, usize> = BTreeMap::new();
    let mut unmeasurable: BTreeMap<String, usize> = BTreeMap::new();
    let mut measurable = Vec::new();
    for_each_node(&axes, |c| {
        for o in 0..n_o {
            match ev.evaluate(c, o) {
                NodeResult::Accepted(cand) => measurable.push(cand),
                NodeResult::Rejected(s, reason) => {
                    *rejected.entry(s).or_default() += 1;
                    if let Some(r) = reason {
                        *unmeasurable.entry(r).or_default() += 1;
                    }
                }
            }
        }
    });
    let cfg = checker.config();
    let mut order = vec![Stage::Reachable, Stage::JointLimits];
    if model.spherical_joint_angles(&home).map(|a| !a.is_empty()).unwrap_or(true) {
        order.push(Stage::SphericalJoints);
    }
    if cfg.workspace_edge_margin_m > 0.0 {
        order.push(Stage::WorkspaceEdge);
    }
    order.extend((0..cfg.obstacles.len()).map(|index| Stage::Obstacle { index }));
    if device.is_some() {
        order.push(Stage::Measurable);
    }
    let device_name = device.map(|d| d.name());
    let mut left = total;
    let stages = order
        .into_iter()
        .map(|s| {
            let removed = rejected.get(&s).copied().unwrap_or(0);
            left -= removed.min(left);
            StageCount { name: stage_name(&s, cfg, device_name.as_deref()), stage: s, survivors: left, removed }
        })
        .collect();
    let d = lattice.dimension();
    Ok(WorkspaceMap {
        volume_unit: match lattice {
            Lattice::Cartesian { .. } => "m^3".into(),
            Lattice::Joint { .. } => "joint-box fraction".into(),
        },
        lattice,
        spacing: h,
        cell_volume: h.powi(d as i32),
        total,
        stages,
        unmeasurable,
        measurable,
        device: device_name,
        home,
    })
}

/// The source's regular grid over the measurable region for `wanted` poses.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SpreadGrid {
    /// The wanted count.
    pub wanted: usize,
    /// Grid spacing `(volume / wanted)^(1/d)` (metres, or normalised joint units).
    pub spacing: f64,
    /// The volume it was computed from.
    pub volume: f64,
    /// Grid nodes tried (times orientations).
    pub tried: usize,
    /// Nodes that passed every check, in lattice order.
    pub poses: Vec<Candidate>,
    /// Why the others failed (stage name -> count).
    pub rejected: BTreeMap<String, usize>,
}

/// The grid spacing for `wanted` poses over the measurable volume of `map`:
/// `(volume / wanted)^(1/d)`.
pub fn spacing_for(map: &WorkspaceMap, wanted: usize) -> f64 {
    let d = map.lattice.dimension() as f64;
    (map.measurable_volume() / wanted.max(1) as f64).powf(1.0 / d)
}

fn measurable_box(map: &WorkspaceMap) -> (Vec<f64>, Vec<f64>) {
    let d = map.lattice.dimension();
    let mut lo = vec![f64::INFINITY; d];
    let mut hi = vec![f64::NEG_INFINITY; d];
    for c in &map.measurable {
        for k in 0..d {
            lo[k] = lo[k].min(c.coords[k]);
            hi[k] = hi[k].max(c.coords[k]);
        }
    }
    // Each measurable node stands for a cell around it.
    let half = 0.5 * map.spacing;
    (lo.iter().map(|v| v - half).collect(), hi.iter().map(|v| v + half).collect())
}

/// Places a regular grid for `wanted` poses over the measurable region of `map` (spacing from
/// [`spacing_for`], centred in the region's bounding box) and keeps the nodes that pass every
/// check again (safety with margins and the device).
pub fn spread_grid<R: SafetyBody + ?Sized>(
    model: &R,
    checker: &SafetyChecker<'_, R>,
    device: Option<&dyn MeasuringDevice>,
    map: &WorkspaceMap,
    wanted: usize,
) -> Result<SpreadGrid> {
    map.require_nonempty()?;
    if wanted == 0 {
        return Err(RobotError::Safety("the wanted number of poses must be at least 1".into()));
    }
    let spacing = spacing_for(map, wanted);
    grid_at_spacing(model, checker, device, map, wanted, spacing)
}

/// Like [`spread_grid`] with an explicit spacing.
pub fn grid_at_spacing<R: SafetyBody + ?Sized>(
    model: &R,
    checker: &SafetyChecker<'_, R>,
    device: Option<&dyn MeasuringDevice>,
    map: &WorkspaceMap,
    wanted: usize,
    spacing: f64,
) -> Result<SpreadGrid> {
    if !(spacing.is_finite() && spacing > 0.0) {
        return Err(RobotError::Safety(format!("grid spacing must be > 0, got {spacing}")));
    }
    let (lo, hi) = measurable_box(map);
    let axes = lattice_axes(&lo, &hi, spacing);
    let n_o = map.lattice.n_orientations();
    let tried = node_count(&axes).saturating_mul(n_o);
    if tried > 4 * map.total.max(1000) {
        return Err(RobotError::Safety(format!(
            "a grid of spacing {spacing:.4} has {tried} nodes; ask for fewer poses"
        )));
    }
    let ev = Evaluator { model, checker, device, lattice: &map.lattice, home: map.home.clone() };
    let cfg = checker.config();
    let mut poses = Vec::new();
    let mut rejected = BTreeMap::new();
    for_each_node(&axes, |c| {
        for o in 0..n_o {
            match ev.evaluate(c, o) {
                NodeResult::Accepted(cand) => poses.push(cand),
                NodeResult::Rejected(s, reason) => {
                    let key = reason.unwrap_or_else(|| stage_name(&s, cfg, map.device.as_deref()));
                    *rejected.entry(key).or_insert(0usize) += 1;
                }
            }
        }
    });
    Ok(SpreadGrid { wanted, spacing, volume: map.measurable_volume(), tried, poses, rejected })
}

/// Draws `n` random candidates uniformly over the measurable region (a random measurable cell,
/// a random point in it, every check again). Deterministic for `seed`. Fails when fewer than
/// `n` are found after `50 n + 1000` tries.
pub fn sample_measurable<R: SafetyBody + ?Sized>(
    model: &R,
    checker: &SafetyChecker<'_, R>,
    device: Option<&dyn MeasuringDevice>,
    map: &WorkspaceMap,
    n: usize,
    seed: u64,
) -> Result<Vec<Candidate>> {
    map.require_nonempty()?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let ev = Evaluator { model, checker, device, lattice: &map.lattice, home: map.home.clone() };
    let (blo, bhi) = map.lattice.bounds();
    let mut out = Vec::with_capacity(n);
    let mut tries = 0usize;
    while out.len() < n {
        tries += 1;
        if tries > 50 * n + 1000 {
            return Err(RobotError::Safety(format!(
                "found only {} of {n} random measurable poses after {tries} tries",
                out.len()
            )));
        }
        let cell = &map.measurable[rng.random_range(0..map.measurable.len())];
        let coords: Vec<f64> = cell
            .coords
            .iter()
            .enumerate()
            .map(|(k, c)| (c + (rng.random::<f64>() - 0.5) * map.spacing).clamp(blo[k], bhi[k]))
            .collect();
        if let NodeResult::Accepted(c) = ev.evaluate(&coords, cell.orientation) {
            out.push(c);
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

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
