//! The example cell's safety zones and the demo's study of them: random UR5 configurations
//! checked against the zones, the moves between consecutive safe ones, and a configuration
//! planted in the table that the zones must refuse.

use std::collections::BTreeMap;

use ferrocal_robot::presets;
use ferrocal_robot::safety::{ObstacleBox, SafetyChecker, SafetyConfig, Violation};
use ferrocal_robot::Kinematics;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// The example cell: a UR5 on a table, with a wall, a fixture and a carried plate.
pub fn example_safety() -> SafetyConfig {
    SafetyConfig {
        joint_margin: 0.05,
        plate_radius_m: 0.08,
        link_radius_m: 0.05,
        workspace_edge_margin_m: 0.05,
        obstacles: vec![
            ObstacleBox { name: "table".into(), min_m: [-1.5, -1.5, -0.8], max_m: [1.5, 1.5, -0.02], margin_m: 0.03 },
            ObstacleBox { name: "wall".into(), min_m: [-1.5, 0.55, -0.8], max_m: [1.5, 0.7, 1.5], margin_m: 0.05 },
            ObstacleBox { name: "fixture".into(), min_m: [0.35, -0.2, -0.02], max_m: [0.6, 0.2, 0.25], margin_m: 0.03 },
        ],
        ..SafetyConfig::default()
    }
}

/// The largest number of random configurations the study checks.
pub const MAX_SAMPLES: usize = 3000;

/// What [`safety_study`] found.
#[derive(Clone, Debug)]
pub struct SafetyStudy {
    /// The zones checked ([`example_safety`]).
    pub config: SafetyConfig,
    /// Random configurations checked.
    pub n: usize,
    /// Tool positions (x, y in m) of the safe configurations.
    pub safe_xy_m: Vec<(f64, f64)>,
    /// Tool positions (x, y in m) of the refused configurations.
    pub refused_xy_m: Vec<(f64, f64)>,
    /// Per zone (`obstacle 'table'`, `joint limit`, ...), how many configurations it refused.
    pub refused_by: BTreeMap<String, usize>,
    /// Straight joint-space moves between consecutive safe configurations that are safe all the
    /// way (of the first 200).
    pub moves_safe: usize,
    /// Such moves that would pass through a zone.
    pub moves_refused: usize,
    /// Whether the configuration planted in the table (the upper arm turned 1.2 rad below the
    /// horizontal, the elbow about 0.3 m under the table's top) is refused by the table.
    pub planted_refused_by_table: bool,
}

/// Checks `samples` (at most [`MAX_SAMPLES`]) random UR5 configurations (each joint uniform in
/// -3..3 rad, seed `seed`) against the example cell's zones; `tick(k, n)` after each.
pub fn safety_study(samples: usize, seed: u64, tick: &dyn Fn(u64, u64)) -> ferrocal_robot::Result<SafetyStudy> {
    let robot = presets::ur5();
    let config = example_safety();
    let checker = SafetyChecker::new(&robot, config.clone())?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let n = samples.min(MAX_SAMPLES);
    let (mut safe_xy_m, mut refused_xy_m) = (Vec::new(), Vec::new());
    let mut refused_by = BTreeMap::<String, usize>::new();
    let mut safe_q = Vec::new();
    for k in 0..n {
        tick(k as u64 + 1, n as u64);
        let q: Vec<f64> = (0..6).map(|_| rng.random_range(-3.0..3.0)).collect();
        let p = robot.forward(&q)?.translation.vector;
        let v = checker.violations(&q, 0.0);
        if v.is_empty() {
            safe_xy_m.push((p.x, p.y));
            safe_q.push(q);
        } else {
            refused_xy_m.push((p.x, p.y));
            for x in &v {
                let key = match x {
                    Violation::Obstacle { obstacle, .. } => format!("obstacle '{obstacle}'"),
                    Violation::JointLimit { .. } => "joint limit".into(),
                    Violation::WorkspaceEdge { .. } => "workspace edge".into(),
                    Violation::SphericalJoint { .. } => "spherical joint".into(),
                    Violation::Kinematics { .. } => "kinematics".into(),
                };
                *refused_by.entry(key).or_default() += 1;
            }
        }
    }
    // Moves between consecutive safe poses.
    let (mut moves_safe, mut moves_refused) = (0, 0);
    for w in safe_q.windows(2).take(200) {
        match checker.check_move(&w[0], &w[1]) {
            Ok(()) => moves_safe += 1,
            Err(_) => moves_refused += 1,
        }
    }
    let planted = [0.0, 1.2, 0.0, 0.0, 0.0, 0.0];
    let planted_refused_by_table = checker
        .violations(&planted, 0.0)
        .iter()
        .any(|v| matches!(v, Violation::Obstacle { obstacle, .. } if obstacle == "table"));
    Ok(SafetyStudy {
        config,
        n,
        safe_xy_m,
        refused_xy_m,
        refused_by,
        moves_safe,
        moves_refused,
        planted_refused_by_table,
    })
}
