//! Safety zones: property tests that a move reported safe is safe at every instant, and that
//! single-pose checks report exactly the violated zone.

use ferrocal_robot::presets;
use ferrocal_robot::safety::{ObstacleBox, SafetyBody, SafetyChecker, SafetyConfig, Violation};
use ferrocal_robot::Kinematics;
use nalgebra::Point3;
use proptest::prelude::*;

fn clearance(robot: &ferrocal_robot::serial::SerialChain, cfg: &SafetyConfig, q: &[f64]) -> f64 {
    let tool = Point3::from(robot.forward(q).unwrap().translation.vector);
    let segs = robot.link_segments(q).unwrap();
    let mut worst = f64::INFINITY;
    for o in &cfg.obstacles {
        worst = worst.min(o.distance(&tool) - cfg.plate_radius_m - o.margin_m);
        for (a, b) in &segs {
            worst = worst.min(o.segment_distance(a, b) - cfg.link_radius_m - o.margin_m);
        }
    }
    worst
}

fn arb_box() -> impl Strategy<Value = ObstacleBox> {
    (prop::array::uniform3(-0.9f64..0.9), prop::array::uniform3(0.05f64..0.4), 0.0f64..0.05).prop_map(
        |(c, h, margin_m)| ObstacleBox {
            name: "box".into(),
            min_m: [c[0] - h[0], c[1] - h[1], c[2] - h[2]],
            max_m: [c[0] + h[0], c[1] + h[1], c[2] + h[2]],
            margin_m,
        },
    )
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, .. ProptestConfig::default() })]

    /// If a straight joint-space move is accepted, no configuration along it comes closer to an
    /// obstacle than its margin (checked on 1000 samples, finer than the checker's own).
    #[test]
    fn accepted_moves_are_safe_everywhere(
        obstacle in arb_box(),
        qa in prop::array::uniform6(-3.0f64..3.0),
        dq in prop::array::uniform6(-0.4f64..0.4),
        plate in 0.0f64..0.1,
    ) {
        let robot = presets::ur5();
        let cfg = SafetyConfig { plate_radius_m: plate, link_radius_m: 0.04, obstacles: vec![obstacle], ..SafetyConfig::default() };
        let checker = SafetyChecker::new(&robot, cfg.clone()).unwrap();
        let qb: Vec<f64> = qa.iter().zip(dq).map(|(a, d)| a + d).collect();
        if checker.check_move(&qa, &qb).is_ok() {
            for k in 0..=1000 {
                let s = k as f64 / 1000.0;
                let q: Vec<f64> = qa.iter().zip(&qb).map(|(a, b)| a + (b - a) * s).collect();
                let c = clearance(&robot, &cfg, &q);
                prop_assert!(c >= -1e-9, "clearance {c} at s = {s}");
            }
        }
    }

    /// A single pose is reported unsafe exactly when some body part is inside a margin zone, and
    /// the report names the obstacle.
    #[test]
    fn pose_check_matches_clearance(
        obstacle in arb_box(),
        q in prop::array::uniform6(-3.0f64..3.0),
        plate in 0.0f64..0.1,
    ) {
        let robot = presets::ur5();
        let cfg = SafetyConfig { plate_radius_m: plate, link_radius_m: 0.04, obstacles: vec![obstacle], ..SafetyConfig::default() };
        let checker = SafetyChecker::new(&robot, cfg.clone()).unwrap();
        let c = clearance(&robot, &cfg, &q);
        let v = checker.violations(&q, 0.0);
        if c < -1e-7 {
            prop_assert!(v.iter().any(|v| matches!(v, Violation::Obstacle { obstacle, .. } if obstacle == "box")), "{v:?}");
        } else if c > 1e-7 {
            prop_assert!(v.is_empty(), "clearance {c} but {v:?}");
        }
    }

    /// Joint limits: a value outside the margin-shrunk limits is reported with its joint number.
    #[test]
    fn joint_limit_violations_name_the_joint(
        q in prop::array::uniform6(-3.0f64..3.0),
        joint in 0usize..6,
        over in 0.001f64..1.0,
    ) {
        let mut robot = presets::ur5();
        for j in &mut robot.joints { j.limits = ferrocal_robot::JointLimits::new(&j.name, -3.1, 3.1).unwrap(); }
        let cfg = SafetyConfig { joint_margin: 0.05, ..SafetyConfig::default() };
        let checker = SafetyChecker::new(&robot, cfg).unwrap();
        let mut q = q.to_vec();
        q[joint] = 3.05 + over;
        let v = checker.violations(&q, 0.0);
        prop_assert!(v.iter().any(|v| matches!(v, Violation::JointLimit { joint: j, .. } if *j == joint + 1)), "{v:?}");
        // A straight move into it is refused too.
        let mut qa = q.clone();
        qa[joint] = 0.0;
        prop_assert!(checker.check_move(&qa, &q).is_err());
    }
}

#[test]
fn an_empty_workspace_names_the_constraint() {
    let mut robot = presets::ur5();
    robot.joints[2].limits = ferrocal_robot::JointLimits::new("elbow", -0.05, 0.05).unwrap();
    let cfg = SafetyConfig { joint_margin: 0.1, ..SafetyConfig::default() };
    let e = SafetyChecker::new(&robot, cfg).err().expect("must be refused").to_string();
    assert!(e.contains("joint 3") && e.contains("elbow") && e.contains("empty"), "{e}");
}

#[test]
fn bad_safety_configurations_are_refused() {
    let robot = presets::ur5();
    let bad_box = SafetyConfig {
        obstacles: vec![ObstacleBox {
            name: "table".into(),
            min_m: [0.0, 0.0, 0.0],
            max_m: [-1.0, 1.0, 1.0],
            margin_m: 0.0,
        }],
        ..SafetyConfig::default()
    };
    let e = SafetyChecker::new(&robot, bad_box).err().unwrap().to_string();
    assert!(e.contains("table"), "{e}");
    let neg = SafetyConfig { plate_radius_m: -0.1, ..SafetyConfig::default() };
    assert!(SafetyChecker::new(&robot, neg).err().unwrap().to_string().contains("plate_radius_m"));
}

#[test]
fn workspace_edge_margin_rejects_poses_near_full_reach() {
    let robot = presets::ur5();
    let cfg = SafetyConfig { workspace_edge_margin_m: 0.1, ..SafetyConfig::default() };
    let checker = SafetyChecker::new(&robot, cfg).unwrap();
    // Arm stretched out horizontally: a point 10 cm further out is unreachable.
    let stretched = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    assert!(checker.violations(&stretched, 0.0).iter().any(|v| matches!(v, Violation::WorkspaceEdge { .. })));
    // A folded, comfortable pose is fine.
    let comfy = [0.3, -1.2, 1.4, -1.8, -1.57, 0.0];
    assert!(checker.is_safe(&comfy), "{:?}", checker.violations(&comfy, 0.0));
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, .. ProptestConfig::default() })]

    /// The same guarantee on the Gantry-Tau L1 (links, plate, spherical-joint limits): a move
    /// that is accepted stays clear of every zone on 400 samples along it.
    #[test]
    fn gantry_tau_accepted_moves_are_safe_everywhere(
        center in prop::array::uniform3(-1.0f64..1.0),
        half in prop::array::uniform3(0.05f64..0.3),
        qa in prop::array::uniform3(-0.8f64..0.8),
        dq in prop::array::uniform3(-0.3f64..0.3),
    ) {
        let robot = ferrocal_robot::RobotModel::load("gantry-tau-l1").unwrap();
        let tool0 = robot.forward(&[0.0, 0.0, 0.0]).unwrap().translation.vector;
        let obstacle = ObstacleBox {
            name: "box".into(),
            min_m: [tool0.x + center[0] - half[0], tool0.y + center[1] - half[1], tool0.z + center[2] - half[2]],
            max_m: [tool0.x + center[0] + half[0], tool0.y + center[1] + half[1], tool0.z + center[2] + half[2]],
            margin_m: 0.02,
        };
        let cfg = SafetyConfig {
            plate_radius_m: 0.1,
            link_radius_m: 0.02,
            spherical_max_deg: 15.0,
            obstacles: vec![obstacle],
            ..SafetyConfig::default()
        };
        let checker = SafetyChecker::new(&robot, cfg).unwrap();
        let qb: Vec<f64> = qa.iter().zip(dq).map(|(a, d)| a + d).collect();
        if checker.check_move(&qa, &qb).is_ok() {
            for k in 0..=400 {
                let s = k as f64 / 400.0;
                let q: Vec<f64> = qa.iter().zip(&qb).map(|(a, b)| a + (b - a) * s).collect();
                let v = checker.violations(&q, 0.0);
                prop_assert!(v.is_empty(), "{v:?} at s = {s}");
            }
        }
    }
}

#[test]
fn gantry_tau_spherical_joint_limits_are_enforced() {
    let robot = ferrocal_robot::RobotModel::load("gantry-tau-l1").unwrap();
    let cfg = SafetyConfig { spherical_max_deg: 5.0, ..SafetyConfig::default() };
    let checker = SafetyChecker::new(&robot, cfg).unwrap();
    // At q = 0 every link is along its reference direction: safe.
    assert!(checker.is_safe(&[0.0, 0.0, 0.0]), "{:?}", checker.violations(&[0.0, 0.0, 0.0], 0.0));
    // Moving one cart far tilts its link beyond 5 degrees.
    let v = checker.violations(&[0.6, -0.6, 0.0], 0.0);
    assert!(v.iter().any(|v| matches!(v, Violation::SphericalJoint { .. })), "{v:?}");
    let text = v.iter().map(|v| v.to_string()).collect::<Vec<_>>().join("; ");
    assert!(text.contains("spherical joint") && text.contains("max 5.00 deg"), "{text}");
}
