//! The measurement plan of a simulated session: which joint configurations, in which order.
//! Approach directions follow from the order: joint `i` of pose `k` was approached with sign
//! `sign(q_k,i - q_k-1,i)`, starting from the home configuration.

use ferrocal_robot::safety::{SafetyChecker, SafetyConfig};
use ferrocal_robot::{JointKind, Kinematics, RobotModel};
use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use rand::Rng;
use serde::{Deserialize, Serialize};

use crate::error::DatasetError;

/// How the poses are chosen (TOML table `[plan]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum PlanConfig {
    /// Uniformly random joint values within the limits (or the given ranges), kept when the
    /// forward kinematics exists and the pose is safe.
    Random {
        /// Number of poses.
        n: usize,
        /// Optional ranges per joint `[lo, hi]` (SI joint units) tighter than the limits.
        #[serde(default)]
        joint_ranges_si: Vec<[f64; 2]>,
        /// Seconds spent per pose (for the time and temperature of each measurement).
        #[serde(default = "default_dt")]
        seconds_per_pose: f64,
        /// Home configuration the session starts from (default: middle of the limits).
        #[serde(default)]
        home_si: Vec<f64>,
    },
    /// A grid of tool positions in the base frame, visited in serpentine order, with a fixed
    /// orientation for robots that control it. Poses the inverse kinematics cannot reach, or
    /// that are unsafe, are left out.
    Grid {
        /// Lower corner of the grid box.
        min_m: [f64; 3],
        /// Upper corner.
        max_m: [f64; 3],
        /// Grid spacing.
        spacing_m: f64,
        /// Tool orientation (roll-pitch-yaw, degrees) for robots that control it.
        #[serde(default)]
        rpy_deg: [f64; 3],
        /// Seconds per pose.
        #[serde(default = "default_dt")]
        seconds_per_pose: f64,
        /// Home configuration (also the first IK seed).
        #[serde(default)]
        home_si: Vec<f64>,
    },
    /// Explicit joint values (SI joint units), in visiting order.
    List {
        /// The poses.
        joints_si: Vec<Vec<f64>>,
        /// Seconds per pose.
        #[serde(default = "default_dt")]
        seconds_per_pose: f64,
        /// Home configuration.
        #[serde(default)]
        home_si: Vec<f64>,
    },
}

fn default_dt() -> f64 {
    10.0
}

impl PlanConfig {
    /// Seconds spent per pose.
    pub fn seconds_per_pose(&self) -> f64 {
        match self {
            PlanConfig::Random { seconds_per_pose, .. }
            | PlanConfig::Grid { seconds_per_pose, .. }
            | PlanConfig::List { seconds_per_pose, .. } => *seconds_per_pose,
        }
    }

    fn home(&self) -> &[f64] {
        match self {
            PlanConfig::Random { home_si, .. }
            | PlanConfig::Grid { home_si, .. }
            | PlanConfig::List { home_si, .. } => home_si,
        }
    }
}

/// A plan: the home configuration and the poses in visiting order.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Plan {
    /// Where the robot starts.
    pub home: Vec<f64>,
    /// Joint values per pose.
    pub poses: Vec<Vec<f64>>,
    /// Poses the generator tried and left out, with the reason (grid points out of reach, ...).
    pub left_out: Vec<String>,
}

impl Plan {
    /// Approach direction of every joint into every pose.
    pub fn directions(&self) -> Vec<Vec<i8>> {
        let mut prev = self.home.clone();
        self.poses
            .iter()
            .map(|q| {
                let d = q
                    .iter()
                    .zip(&prev)
                    .map(|(a, b)| {
                        if a > b {
                            1
                        } else if a < b {
                            -1
                        } else {
                            0
                        }
                    })
                    .collect();
                prev = q.clone();
                d
            })
            .collect()
    }
}

fn default_home(model: &RobotModel) -> Vec<f64> {
    model
        .joint_limits()
        .iter()
        .map(|l| if l.lower.is_finite() && l.upper.is_finite() { 0.5 * (l.lower + l.upper) } else { 0.0 })
        .collect()
}

/// Builds the plan for `model` (the nominal model: the plan is what an operator would command).
pub fn make_plan(
    cfg: &PlanConfig,
    model: &RobotModel,
    safety: Option<&SafetyConfig>,
    rng: &mut impl Rng,
) -> Result<Plan, DatasetError> {
    let n_j = model.dof();
    let home = if cfg.home().is_empty() { default_home(model) } else { cfg.home().to_vec() };
    if home.len() != n_j {
        return Err(DatasetError::Config(format!("plan: home has {} values, the robot has {n_j} joints", home.len())));
    }
    let checker = match safety {
        Some(s) => {
            Some(SafetyChecker::new(model, s.clone()).map_err(|e| DatasetError::Config(format!("safety: {e}")))?)
        }
        None => None,
    };
    let safe = |q: &[f64]| checker.as_ref().is_none_or(|c| c.is_safe(q));
    let mut left_out = Vec::new();
    let poses = match cfg {
        PlanConfig::Random { n, joint_ranges_si, .. } => {
            let limits = model.joint_limits();
            let kinds = model.joint_kinds();
            if !joint_ranges_si.is_empty() && joint_ranges_si.len() != n_j {
                return Err(DatasetError::Config(format!(
                    "plan: joint_ranges_si has {} entries, the robot has {n_j} joints",
                    joint_ranges_si.len()
                )));
            }
            let ranges: Vec<(f64, f64)> = (0..n_j)
                .map(|i| {
                    let (dlo, dhi) = match kinds[i] {
                        JointKind::Revolute => (-std::f64::consts::PI, std::f64::consts::PI),
                        JointKind::Prismatic => (-1.0, 1.0),
                    };
                    let mut lo = if limits[i].lower.is_finite() { limits[i].lower } else { dlo };
                    let mut hi = if limits[i].upper.is_finite() { limits[i].upper } else { dhi };
                    if let Some([a, b]) = joint_ranges_si.get(i) {
                        lo = lo.max(*a);
                        hi = hi.min(*b);
                    }
                    (lo, hi)
                })
                .collect();
            if let Some((i, _)) = ranges.iter().enumerate().find(|(_, (lo, hi))| lo > hi) {
                return Err(DatasetError::Config(format!("plan: joint {} has an empty range", i + 1)));
            }
            let mut out = Vec::with_capacity(*n);
            let mut tries = 0usize;
            while out.len() < *n {
                tries += 1;
                if tries > 200 * n + 1000 {
                    return Err(DatasetError::Config(format!(
                        "plan: found only {} of {n} random poses that are reachable and safe after {tries} tries",
                        out.len()
                    )));
                }
                let q: Vec<f64> = ranges.iter().map(|(lo, hi)| lo + (hi - lo) * rng.random::<f64>()).collect();
                if model.forward(&q).is_ok() && safe(&q) {
                    out.push(q);
                }
            }
            out
        }
        PlanConfig::Grid { min_m, max_m, spacing_m, rpy_deg, .. } => {
            if !(spacing_m.is_finite() && *spacing_m > 0.0) {
                return Err(DatasetError::Config(format!("plan: spacing_m must be > 0, got {spacing_m}")));
            }
            let count = |k: usize| (((max_m[k] - min_m[k]) / spacing_m).floor() as i64).max(0) as usize + 1;
            let (nx, ny, nz) = (count(0), count(1), count(2));
            if nx * ny * nz > 1_000_000 {
                return Err(DatasetError::Config(format!(
                    "plan: the grid has {} points; use a larger spacing",
                    nx * ny * nz
                )));
            }
            let r = rpy_deg.map(f64::to_radians);
            let rot = UnitQuaternion::from_euler_angles(r[0], r[1], r[2]);
            let mut out = Vec::new();
            let mut seed = home.clone();
            for iz in 0..nz {
                for iy0 in 0..ny {
                    let iy = if iz % 2 == 0 { iy0 } else { ny - 1 - iy0 };
                    for ix0 in 0..nx {
                        let ix = if (iz * ny + iy0) % 2 == 0 { ix0 } else { nx - 1 - ix0 };
                        let p = [
                            min_m[0] + ix as f64 * spacing_m,
                            min_m[1] + iy as f64 * spacing_m,
                            min_m[2] + iz as f64 * spacing_m,
                        ];
                        let target = Isometry3::from_parts(Translation3::new(p[0], p[1], p[2]), rot);
                        match model.inverse(&target, &seed) {
                            Ok(q) if safe(&q) => {
                                seed = q.clone();
                                out.push(q);
                            }
                            Ok(_) => {
                                left_out.push(format!("grid point ({:.3}, {:.3}, {:.3}) m: unsafe", p[0], p[1], p[2]))
                            }
                            Err(e) => {
                                left_out.push(format!("grid point ({:.3}, {:.3}, {:.3}) m: {e}", p[0], p[1], p[2]))
                            }
                        }
                    }
                }
            }
            out
        }
        PlanConfig::List { joints_si, .. } => {
            for (k, q) in joints_si.iter().enumerate() {
                if q.len() != n_j {
                    return Err(DatasetError::Config(format!(
                        "plan: pose {} has {} joint values, the robot has {n_j}",
                        k + 1,
                        q.len()
                    )));
                }
                if let Err(e) = model.forward(q) {
                    return Err(DatasetError::Config(format!("plan: pose {}: {e}", k + 1)));
                }
            }
            joints_si.clone()
        }
    };
    if poses.is_empty() {
        return Err(DatasetError::Config("plan: no pose is reachable and safe".into()));
    }
    Ok(Plan { home, poses, left_out })
}
