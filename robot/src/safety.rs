//! Safety zones: actuator limits, spherical-joint angle limits, obstacle boxes with margins, a
//! margin from the workspace edge, and checks for single poses and straight joint-space moves.
//!
//! # What is guaranteed
//! - Joint limits are boxes in joint space, so a straight joint-space move between two poses
//!   inside the (margin-shrunk) box stays inside it: checking the ends is exact.
//! - Obstacles: every body point of the robot (the link segments, inflated by the link radius,
//!   and the carried plate, a sphere of the plate's bounding radius about the tool point) must
//!   keep `margin` from every box. Along a move, the check samples the segment so finely that no
//!   body point travels more than `resolution_m` between samples, using a *global* bound of the
//!   body's speed ([`SafetyBody::motion_bound_m`]); each sample is checked with the margin
//!   inflated by half the resolution. For serial chains that bound is rigorous (a point moves at
//!   most `|dq_i| * r_i` per revolute joint, `r_i` bounded by the chain's reach), so the move is
//!   safe at every instant, not only at the samples.
//! - Spherical-joint angles (parallel robots) and the workspace-edge margin are checked at the
//!   same samples.

use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};

use crate::error::{Result, RobotError};
use crate::kinematics::{JointKind, Kinematics};
use crate::serial::SerialChain;

/// An axis-aligned box in the base frame that the robot must not enter.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ObstacleBox {
    /// Name used in messages.
    pub name: String,
    /// Lower corner, base frame.
    pub min_m: [f64; 3],
    /// Upper corner, base frame.
    pub max_m: [f64; 3],
    /// Clearance the robot must keep from the box.
    #[serde(default)]
    pub margin_m: f64,
}

impl ObstacleBox {
    /// Distance from `p` to the box (0 inside).
    pub fn distance(&self, p: &Point3<f64>) -> f64 {
        let mut d2 = 0.0;
        for k in 0..3 {
            let v = if p[k] < self.min_m[k] {
                self.min_m[k] - p[k]
            } else if p[k] > self.max_m[k] {
                p[k] - self.max_m[k]
            } else {
                0.0
            };
            d2 += v * v;
        }
        d2.sqrt()
    }

    /// Distance from the segment `a`-`b` to the box. The distance to a convex set is convex
    /// along a line, so a golden-section search finds the minimum to `1e-9` of the segment.
    pub fn segment_distance(&self, a: &Point3<f64>, b: &Point3<f64>) -> f64 {
        let f = |s: f64| self.distance(&(a + (b - a) * s));
        let (mut lo, mut hi) = (0.0f64, 1.0f64);
        let g = 0.5 * (5f64.sqrt() - 1.0);
        let mut x1 = hi - g * (hi - lo);
        let mut x2 = lo + g * (hi - lo);
        let (mut f1, mut f2) = (f(x1), f(x2));
        while hi - lo > 1e-9 {
            if f1 <= f2 {
                hi = x2;
                x2 = x1;
                f2 = f1;
                x1 = hi - g * (hi - lo);
                f1 = f(x1);
            } else {
                lo = x1;
                x1 = x2;
                f1 = f2;
                x2 = lo + g * (hi - lo);
                f2 = f(x2);
            }
        }
        f(0.0).min(f(1.0)).min(f1).min(f2)
    }
}

/// The safety configuration of a cell (TOML section `[safety]` of a cell or plan file).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SafetyConfig {
    /// Clearance from every joint limit (rad for revolute, m for prismatic joints).
    #[serde(default)]
    pub joint_margin: f64,
    /// Optional tighter limits per joint (model order; `None` keeps the model's).
    #[serde(default)]
    pub joint_limits: Vec<Option<[f64; 2]>>,
    /// Largest allowed spherical-joint angle (parallel robots), degrees. The source's joints
    /// have a 30 deg range used with a ~15 deg safety interval.
    #[serde(default = "default_spherical_deg")]
    pub spherical_max_deg: f64,
    /// Radius of the carried plate's bounding sphere about the tool point.
    #[serde(default)]
    pub plate_radius_m: f64,
    /// Radius of the capsule around each link segment.
    #[serde(default)]
    pub link_radius_m: f64,
    /// Whether link segments are checked against obstacles (the plate always is).
    #[serde(default = "default_true")]
    pub check_links: bool,
    /// Distance the tool must keep from the edge of the reachable workspace (checked by probing
    /// points at this distance in 14 directions for reachability within the limits).
    #[serde(default)]
    pub workspace_edge_margin_m: f64,
    /// Obstacle boxes.
    #[serde(default, rename = "obstacle")]
    pub obstacles: Vec<ObstacleBox>,
    /// Largest travel of any body point between two checked samples of a move.
    #[serde(default = "default_resolution")]
    pub resolution_m: f64,
}

fn default_spherical_deg() -> f64 {
    180.0
}
fn default_true() -> bool {
    true
}
fn default_resolution() -> f64 {
    0.005
}

impl Default for SafetyConfig {
    fn default() -> Self {
        Self {
            joint_margin: 0.0,
            joint_limits: Vec::new(),
            spherical_max_deg: default_spherical_deg(),
            plate_radius_m: 0.0,
            link_radius_m: 0.0,
            check_links: true,
            workspace_edge_margin_m: 0.0,
            obstacles: Vec::new(),
            resolution_m: default_resolution(),
        }
    }
}

impl SafetyConfig {
    /// Reads a safety configuration from TOML text: either a `[safety]` table (with
    /// `[[safety.obstacle]]` boxes) or the bare keys. Errors name `file`, line and column.
    pub fn from_toml_str(text: &str, file: &std::path::Path) -> Result<Self> {
        #[derive(Deserialize)]
        struct Wrapped {
            safety: SafetyConfig,
        }
        let value: toml::Value = toml::from_str(text).map_err(|e| crate::error::toml_error(file, text, &e))?;
        let cfg = if value.get("safety").is_some() {
            toml::from_str::<Wrapped>(text).map(|w| w.safety)
        } else {
            toml::from_str::<SafetyConfig>(text)
        }
        .map_err(|e| crate::error::toml_error(file, text, &e))?;
        cfg.validate().map_err(|e| match e {
            RobotError::Safety(m) => RobotError::Safety(format!("{}: {m}", file.display())),
            other => other,
        })?;
        Ok(cfg)
    }

    /// Reads a safety configuration file (see [`SafetyConfig::from_toml_str`]).
    pub fn from_file(path: &std::path::Path) -> Result<Self> {
        let text =
            std::fs::read_to_string(path).map_err(|source| RobotError::Io { path: path.to_path_buf(), source })?;
        Self::from_toml_str(&text, path)
    }

    /// Checks the configuration itself: finite, non-negative margins, well-formed boxes.
    pub fn validate(&self) -> Result<()> {
        let nonneg = |v: f64, what: &str| {
            if v.is_finite() && v >= 0.0 {
                Ok(())
            } else {
                Err(RobotError::Safety(format!("{what} must be finite and >= 0, got {v}")))
            }
        };
        nonneg(self.joint_margin, "joint_margin")?;
        nonneg(self.plate_radius_m, "plate_radius_m")?;
        nonneg(self.link_radius_m, "link_radius_m")?;
        nonneg(self.workspace_edge_margin_m, "workspace_edge_margin_m")?;
        if !(self.resolution_m.is_finite() && self.resolution_m > 0.0) {
            return Err(RobotError::Safety(format!("resolution_m must be > 0, got {}", self.resolution_m)));
        }
        if !(self.spherical_max_deg.is_finite() && self.spherical_max_deg > 0.0) {
            return Err(RobotError::Safety(format!("spherical_max_deg must be > 0, got {}", self.spherical_max_deg)));
        }
        for (i, l) in self.joint_limits.iter().enumerate() {
            if let Some([lo, hi]) = l {
                if !(lo.is_finite() && hi.is_finite()) || lo > hi {
                    return Err(RobotError::BadLimits {
                        joint: format!("joint {}", i + 1),
                        lower: *lo,
                        upper: *hi,
                        location: None,
                    });
                }
            }
        }
        for o in &self.obstacles {
            nonneg(o.margin_m, &format!("obstacle '{}' margin_m", o.name))?;
            for k in 0..3 {
                if !(o.min_m[k].is_finite() && o.max_m[k].is_finite()) || o.min_m[k] > o.max_m[k] {
                    return Err(RobotError::Safety(format!(
                        "obstacle '{}': min_m must be <= max_m and finite on every axis",
                        o.name
                    )));
                }
            }
        }
        Ok(())
    }
}

/// One reason a pose or move is unsafe.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Violation {
    /// A joint outside its limits (shrunk by the margin).
    JointLimit {
        /// 1-based joint number.
        joint: usize,
        /// Joint value.
        value: f64,
        /// Allowed lower bound.
        lower: f64,
        /// Allowed upper bound.
        upper: f64,
    },
    /// A spherical joint bent beyond its allowed angle.
    SphericalJoint {
        /// Which joint (model-provided name).
        name: String,
        /// Its angle, degrees.
        angle_deg: f64,
        /// Allowed angle, degrees.
        max_deg: f64,
    },
    /// A body part closer to an obstacle than its margin.
    Obstacle {
        /// Obstacle name.
        obstacle: String,
        /// Which body part (`plate`, `link 3`).
        part: String,
        /// Clearance found (negative: penetration of the margin zone).
        clearance_m: f64,
        /// Required clearance.
        margin_m: f64,
    },
    /// The tool is too close to the edge of the reachable workspace.
    WorkspaceEdge {
        /// Direction of the probe that failed (unit vector, base frame).
        direction: [f64; 3],
        /// Why the probe point is not reachable.
        reason: String,
    },
    /// The kinematics failed at this configuration.
    Kinematics {
        /// The kinematic error.
        reason: String,
    },
}

impl std::fmt::Display for Violation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Violation::JointLimit { joint, value, lower, upper } => {
                write!(f, "joint {joint} = {value:.6} outside [{lower:.6}, {upper:.6}]")
            }
            Violation::SphericalJoint { name, angle_deg, max_deg } => {
                write!(f, "spherical joint {name} at {angle_deg:.2} deg (max {max_deg:.2} deg)")
            }
            Violation::Obstacle { obstacle, part, clearance_m, margin_m } => write!(
                f,
                "{part} is {:.1} mm from obstacle '{obstacle}' (needs {:.1} mm)",
                clearance_m * 1e3,
                margin_m * 1e3
            ),
            Violation::WorkspaceEdge { direction, reason } => write!(
                f,
                "closer than the workspace-edge margin in direction ({:.2}, {:.2}, {:.2}): {reason}",
                direction[0], direction[1], direction[2]
            ),
            Violation::Kinematics { reason } => write!(f, "kinematics failed: {reason}"),
        }
    }
}

/// The moving body of a robot as the safety checker sees it.
pub trait SafetyBody: Kinematics {
    /// Moving link segments (base frame) at `q`, whose capsules must avoid obstacles. Static
    /// parts (the mount) are not included.
    fn link_segments(&self, q: &[f64]) -> Result<Vec<(Point3<f64>, Point3<f64>)>>;

    /// Named spherical-joint angles (radians) at `q`; empty for serial chains.
    fn spherical_joint_angles(&self, _q: &[f64]) -> Result<Vec<(String, f64)>> {
        Ok(Vec::new())
    }

    /// An upper bound on how far any body point (including a sphere of `extra_radius_m` about
    /// the tool) can move along the straight joint-space move `q_a -> q_b`.
    fn motion_bound_m(&self, q_a: &[f64], q_b: &[f64], extra_radius_m: f64) -> Result<f64>;
}

impl SafetyBody for SerialChain {
    fn link_segments(&self, q: &[f64]) -> Result<Vec<(Point3<f64>, Point3<f64>)>> {
        let f = self.frames(q)?;
        // The mount up to the first joint's moving frame does not move: it is not checked (the
        // robot stands on something). Every segment after it moves with the joints.
        let mut pts: Vec<Point3<f64>> = Vec::with_capacity(f.links.len() * 2 + 1);
        for (i, link) in f.links.iter().enumerate() {
            if i > 0 {
                pts.push(f.axis_points[i]);
            }
            pts.push(Point3::from(link.translation.vector));
        }
        pts.push(Point3::from(f.tool.translation.vector));
        pts.dedup_by(|a, b| (*a - *b).norm() < 1e-12);
        Ok(pts.windows(2).map(|w| (w[0], w[1])).collect())
    }

    fn motion_bound_m(&self, q_a: &[f64], q_b: &[f64], extra_radius_m: f64) -> Result<f64> {
        // Every joint's values (a mimic joint moves by its multiplier times its leader's move).
        let (q_a, q_b) = (&self.all_joint_values(q_a)?, &self.all_joint_values(q_b)?);
        // Any body point lies within `reach` of any joint axis point; prismatic travel adds.
        let prismatic: f64 = self
            .joints
            .iter()
            .zip(q_a.iter().zip(q_b))
            .filter(|(j, _)| j.kind == JointKind::Prismatic)
            .map(|(_, (a, b))| a.abs().max(b.abs()))
            .sum();
        let reach = self.reach_bound_m() + extra_radius_m + prismatic;
        Ok(self
            .joints
            .iter()
            .zip(q_a.iter().zip(q_b))
            .map(|(j, (a, b))| match j.kind {
                JointKind::Revolute => (b - a).abs() * reach,
                JointKind::Prismatic => (b - a).abs(),
            })
            .sum())
    }
}

/// Checks poses and moves of one robot against one safety configuration.
pub struct SafetyChecker<'a, R: SafetyBody + ?Sized> {
    robot: &'a R,
    config: SafetyConfig,
    limits: Vec<crate::kinematics::JointLimits>,
}

impl<'a, R: SafetyBody + ?Sized> SafetyChecker<'a, R> {
    /// A checker; validates the configuration against the robot.
    pub fn new(robot: &'a R, config: SafetyConfig) -> Result<Self> {
        config.validate()?;
        let mut limits = robot.joint_limits();
        if !config.joint_limits.is_empty() && config.joint_limits.len() != limits.len() {
            return Err(RobotError::Safety(format!(
                "joint_limits lists {} joints, the robot has {}",
                config.joint_limits.len(),
                limits.len()
            )));
        }
        for (i, l) in config.joint_limits.iter().enumerate() {
            if let Some([lo, hi]) = l {
                limits[i].lower = limits[i].lower.max(*lo);
                limits[i].upper = limits[i].upper.min(*hi);
            }
        }
        for (i, l) in limits.iter().enumerate() {
            if l.lower + config.joint_margin > l.upper - config.joint_margin {
                return Err(RobotError::Safety(format!(
                    "joint {} ('{}'): the margin {} leaves no travel within [{}, {}]: the workspace is empty",
                    i + 1,
                    robot.joint_names()[i],
                    config.joint_margin,
                    l.lower,
                    l.upper
                )));
            }
        }
        Ok(Self { robot, config, limits })
    }

    /// The configuration in use.
    pub fn config(&self) -> &SafetyConfig {
        &self.config
    }

    /// Every violation at configuration `q` (empty: safe). `inflate_m` adds to every obstacle
    /// margin (used by the move check).
    pub fn violations(&self, q: &[f64], inflate_m: f64) -> Vec<Violation> {
        let mut out = Vec::new();
        let m = self.config.joint_margin;
        if q.len() != self.limits.len() {
            out.push(Violation::Kinematics {
                reason: format!("expected {} joint values, got {}", self.limits.len(), q.len()),
            });
            return out;
        }
        for (i, (v, l)) in q.iter().zip(&self.limits).enumerate() {
            if !(v.is_finite() && l.contains(*v, m)) {
                out.push(Violation::JointLimit { joint: i + 1, value: *v, lower: l.lower + m, upper: l.upper - m });
            }
        }
        if !out.is_empty() {
            return out;
        }
        let tool = match self.robot.forward(q) {
            Ok(t) => Point3::from(t.translation.vector),
            Err(e) => {
                out.push(Violation::Kinematics { reason: e.to_string() });
                return out;
            }
        };
        match self.robot.spherical_joint_angles(q) {
            Ok(angles) => {
                for (name, a) in angles {
                    let deg = a.to_degrees();
                    if deg.abs() > self.config.spherical_max_deg {
                        out.push(Violation::SphericalJoint {
                            name,
                            angle_deg: deg,
                            max_deg: self.config.spherical_max_deg,
                        });
                    }
                }
            }
            Err(e) => out.push(Violation::Kinematics { reason: e.to_string() }),
        }
        let segments = if self.config.check_links && !self.config.obstacles.is_empty() {
            match self.robot.link_segments(q) {
                Ok(s) => s,
                Err(e) => {
                    out.push(Violation::Kinematics { reason: e.to_string() });
                    Vec::new()
                }
            }
        } else {
            Vec::new()
        };
        for o in &self.config.obstacles {
            let need = o.margin_m + inflate_m;
            let c = o.distance(&tool) - self.config.plate_radius_m;
            if c < need {
                out.push(Violation::Obstacle {
                    obstacle: o.name.clone(),
                    part: "plate".into(),
                    clearance_m: c,
                    margin_m: o.margin_m,
                });
            }
            for (k, (a, b)) in segments.iter().enumerate() {
                let c = o.segment_distance(a, b) - self.config.link_radius_m;
                if c < need {
                    out.push(Violation::Obstacle {
                        obstacle: o.name.clone(),
                        part: format!("link segment {}", k + 1),
                        clearance_m: c,
                        margin_m: o.margin_m,
                    });
                }
            }
        }
        if self.config.workspace_edge_margin_m > 0.0 {
            if let Some(v) = self.edge_violation(q, &tool) {
                out.push(v);
            }
        }
        out
    }

    fn edge_violation(&self, q: &[f64], tool: &Point3<f64>) -> Option<Violation> {
        let Ok(pose) = self.robot.forward(q) else {
            return None;
        };
        let r = self.config.workspace_edge_margin_m;
        let s = 1.0 / 3f64.sqrt();
        let mut dirs = vec![Vector3::x(), -Vector3::x(), Vector3::y(), -Vector3::y(), Vector3::z(), -Vector3::z()];
        for sx in [-s, s] {
            for sy in [-s, s] {
                for sz in [-s, s] {
                    dirs.push(Vector3::new(sx, sy, sz));
                }
            }
        }
        for d in dirs {
            let mut probe = pose;
            probe.translation.vector = tool.coords + d * r;
            let reason = match self.robot.inverse(&probe, q) {
                Ok(qp) => {
                    if let Some((i, v)) =
                        qp.iter().enumerate().find(|(i, v)| !self.limits[*i].contains(**v, self.config.joint_margin))
                    {
                        Some(format!("joint {} would be at {v:.4}, outside its limits", i + 1))
                    } else {
                        None
                    }
                }
                Err(e) => Some(e.to_string()),
            };
            if let Some(reason) = reason {
                return Some(Violation::WorkspaceEdge { direction: [d.x, d.y, d.z], reason });
            }
        }
        None
    }

    /// Whether configuration `q` is safe.
    pub fn is_safe(&self, q: &[f64]) -> bool {
        self.violations(q, 0.0).is_empty()
    }

    /// Checks the straight joint-space move `q_a -> q_b`; returns the first violation found
    /// with the fraction of the move where it occurs. Obstacle clearance is guaranteed between
    /// samples (see the module documentation); the workspace-edge margin is checked only at
    /// the end points.
    pub fn check_move(&self, q_a: &[f64], q_b: &[f64]) -> std::result::Result<(), (f64, Violation)> {
        let ends_ok = |q: &[f64], s: f64| -> std::result::Result<(), (f64, Violation)> {
            match self.violations(q, 0.0).into_iter().next() {
                Some(v) => Err((s, v)),
                None => Ok(()),
            }
        };
        ends_ok(q_a, 0.0)?;
        ends_ok(q_b, 1.0)?;
        let bound = match self.robot.motion_bound_m(q_a, q_b, self.config.plate_radius_m) {
            Ok(b) => b,
            Err(e) => return Err((0.0, Violation::Kinematics { reason: e.to_string() })),
        };
        let res = self.config.resolution_m;
        let n = ((bound / res).ceil() as usize).max(1);
        // Interior samples: obstacles and spherical joints (edge margin only at the ends).
        let interior = SafetyChecker {
            robot: self.robot,
            config: SafetyConfig { workspace_edge_margin_m: 0.0, ..self.config.clone() },
            limits: self.limits.clone(),
        };
        for k in 1..n {
            let s = k as f64 / n as f64;
            let q: Vec<f64> = q_a.iter().zip(q_b).map(|(a, b)| a + (b - a) * s).collect();
            if let Some(v) = interior.violations(&q, 0.5 * res).into_iter().next() {
                return Err((s, v));
            }
        }
        Ok(())
    }
}

/// Largest speed of any body point of a parallel robot along a joint-space move, estimated from
/// the Jacobian at 9 points of the move with a safety factor of 2 (the platform's motion is
/// smooth away from singular configurations, where the forward kinematics fails and the move
/// is refused anyway). Not a rigorous bound, unlike the serial chains'.
fn parallel_motion_bound(
    robot: &dyn crate::parallel::ParallelRobot,
    q_a: &[f64],
    q_b: &[f64],
    extra_radius_m: f64,
) -> Result<f64> {
    crate::kinematics::check_len(q_a, robot.dof())?;
    crate::kinematics::check_len(q_b, robot.dof())?;
    let dq = nalgebra::DVector::from_iterator(q_a.len(), q_a.iter().zip(q_b).map(|(a, b)| b - a));
    let mut worst: f64 = 0.0;
    for k in 0..=8 {
        let s = k as f64 / 8.0;
        let q: Vec<f64> = q_a.iter().zip(q_b).map(|(a, b)| a + (b - a) * s).collect();
        let jac = robot.jacobian(&q)?;
        let twist = &jac * &dq;
        let v = twist.fixed_rows::<3>(0).norm();
        let w = twist.fixed_rows::<3>(3).norm();
        // Platform points within the links' reach of the tool point, plus the carried plate.
        let tool = robot.forward(&q)?.translation.vector;
        let reach = robot.link_segments(&q)?.iter().map(|s| (s.b_m - tool).norm()).fold(0.0, f64::max) + extra_radius_m;
        // Base-side points move with their carts at most |dq| (guideway directions are near unit).
        let carts = dq.amax() * 1.5;
        worst = worst.max((v + w * reach).max(carts));
    }
    Ok(2.0 * worst)
}

impl SafetyBody for crate::model::RobotModel {
    fn link_segments(&self, q: &[f64]) -> Result<Vec<(Point3<f64>, Point3<f64>)>> {
        match self.parallel() {
            None => match self {
                crate::model::RobotModel::Serial(s) => s.link_segments(q),
                _ => Ok(Vec::new()),
            },
            Some(p) => {
                Ok(p.link_segments(q)?.into_iter().map(|s| (Point3::from(s.a_m), Point3::from(s.b_m))).collect())
            }
        }
    }

    fn spherical_joint_angles(&self, q: &[f64]) -> Result<Vec<(String, f64)>> {
        match self.parallel() {
            None => Ok(Vec::new()),
            Some(p) => Ok(p
                .spherical_joint_angles(q)?
                .into_iter()
                .flat_map(|a| {
                    [
                        (format!("{} base side", a.link), a.base_rad),
                        (format!("{} platform side", a.link), a.platform_rad),
                    ]
                })
                .collect()),
        }
    }

    fn motion_bound_m(&self, q_a: &[f64], q_b: &[f64], extra_radius_m: f64) -> Result<f64> {
        match (self, self.parallel()) {
            (crate::model::RobotModel::Serial(s), _) => s.motion_bound_m(q_a, q_b, extra_radius_m),
            (_, Some(p)) => parallel_motion_bound(p, q_a, q_b, extra_radius_m),
            _ => Err(RobotError::Safety("this model kind has no motion bound".into())),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_distances() {
        let b = ObstacleBox { name: "b".into(), min_m: [0.0, 0.0, 0.0], max_m: [1.0, 1.0, 1.0], margin_m: 0.0 };
        assert_eq!(b.distance(&Point3::new(0.5, 0.5, 0.5)), 0.0);
        assert!((b.distance(&Point3::new(2.0, 0.5, 0.5)) - 1.0).abs() < 1e-15);
        assert!((b.distance(&Point3::new(2.0, 2.0, 0.5)) - 2f64.sqrt()).abs() < 1e-15);
        // A segment passing over the box at height 0.5 above it.
        let d = b.segment_distance(&Point3::new(-1.0, 0.5, 1.5), &Point3::new(2.0, 0.5, 1.5));
        assert!((d - 0.5).abs() < 1e-8, "{d}");
        // A segment through the box.
        let d = b.segment_distance(&Point3::new(-1.0, 0.5, 0.5), &Point3::new(2.0, 0.5, 0.5));
        assert!(d < 1e-8);
    }
}
