//! [planning] safety as a guarantee: every planned pose and every joint-space segment between
//! consecutive steps respects every zone with its margin, over random cells and obstacles
//! (checked independently on 600 samples per segment), and an empty workspace names the
//! constraint that emptied it.

use ferrocal_robot::presets;
use ferrocal_robot::program::{plan_path, verify_path, Approach, PathSettings, StepKind};
use ferrocal_robot::safety::{ObstacleBox, SafetyBody, SafetyChecker, SafetyConfig};
use ferrocal_robot::workspace::{
    search, spread_grid, CameraView, CameraVisibility, GridSpace, TargetShape, VisibilitySettings, WorkspaceSettings,
};
use ferrocal_robot::RobotModel;
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion};
use proptest::prelude::*;

/// Independent samples per segment.
const SAMPLES: usize = 600;

/// Clearance of every body part from every obstacle beyond its margin (negative: violated).
fn clearance<R: SafetyBody + ?Sized>(robot: &R, cfg: &SafetyConfig, q: &[f64]) -> f64 {
    let tool = Point3::from(robot.forward(q).unwrap().translation.vector);
    let segs = robot.link_segments(q).unwrap();
    let mut worst = f64::INFINITY;
    for o in &cfg.obstacles {
        worst = worst.min(o.distance(&tool) - cfg.plate_radius_m - o.margin_m);
        if cfg.check_links {
            for (a, b) in &segs {
                worst = worst.min(o.segment_distance(a, b) - cfg.link_radius_m - o.margin_m);
            }
        }
    }
    worst
}

fn arb_box(lo: [f64; 3], hi: [f64; 3]) -> impl Strategy<Value = ObstacleBox> {
    (prop::array::uniform3(0.0f64..1.0), prop::array::uniform3(0.05f64..0.35), 0.0f64..0.06).prop_map(
        move |(u, h, margin_m)| {
            let c: Vec<f64> = (0..3).map(|k| lo[k] + u[k] * (hi[k] - lo[k])).collect();
            ObstacleBox {
                name: "box".into(),
                min_m: [c[0] - h[0], c[1] - h[1], c[2] - h[2]],
                max_m: [c[0] + h[0], c[1] + h[1], c[2] + h[2]],
                margin_m,
            }
        },
    )
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 16, .. ProptestConfig::default() })]

    /// A UR5 among random boxes: the joint-space workspace search, the regular grid and the
    /// ordered path (approached from a fixed side) never leave the safe set, at any instant.
    #[test]
    fn ur5_plans_are_safe_at_every_instant(
        boxes in prop::collection::vec(arb_box([-0.8, -0.8, -0.3], [0.8, 0.8, 0.9]), 1..4),
        plate in 0.0f64..0.08,
        approach in prop::sample::select(vec![Approach::Free, Approach::Fixed, Approach::Both]),
    ) {
        let robot = presets::ur5();
        let cfg = SafetyConfig {
            plate_radius_m: plate,
            link_radius_m: 0.03,
            joint_margin: 0.05,
            joint_limits: vec![Some([-1.6, 1.6]); 6],
            obstacles: boxes,
            ..SafetyConfig::default()
        };
        let checker = SafetyChecker::new(&robot, cfg.clone()).unwrap();
        let ws = WorkspaceSettings { space: GridSpace::Joint, joint_steps: 4, ..Default::default() };
        let map = search(&robot, &checker, None, &ws).unwrap();
        if map.measurable.is_empty() {
            let msg = map.require_nonempty().unwrap_err().to_string();
            prop_assert!(msg.contains("removes the last"), "{msg}");
            return Ok(());
        }
        let grid = spread_grid(&robot, &checker, None, &map, 8).unwrap();
        prop_assume!(!grid.poses.is_empty());
        // In six dimensions the regular grid overshoots the wanted count; six poses suffice here.
        let poses: Vec<Vec<f64>> = grid.poses.iter().step_by((grid.poses.len() / 6).max(1)).take(6).map(|c| c.q.clone()).collect();
        for c in &grid.poses {
            prop_assert!(checker.is_safe(&c.q));
        }
        for q in &poses {
            prop_assert!(checker.is_safe(q));
            prop_assert!(clearance(&robot, &cfg, q) >= -1e-9);
        }
        let roadmap: Vec<Vec<f64>> = map.measurable.iter().step_by(7).map(|c| c.q.clone()).collect();
        let settings = PathSettings { approach, ..PathSettings::default() };
        let Ok(path) = plan_path(&robot, &checker, &poses[0], &poses, &roadmap, &settings) else {
            // No route is an honest failure, never an unsafe plan.
            return Ok(());
        };
        prop_assert!(verify_path(&checker, &path).is_ok());
        let n_meas = path.steps.iter().filter(|s| s.kind == StepKind::Measure).count();
        let per = if approach == Approach::Both { 2 } else { 1 };
        prop_assert_eq!(n_meas, poses.len() * per);
        for w in path.steps.windows(2) {
            for k in 0..=SAMPLES {
                let s = k as f64 / SAMPLES as f64;
                let q: Vec<f64> = w[0].q.iter().zip(&w[1].q).map(|(a, b)| a + (b - a) * s).collect();
                let c = clearance(&robot, &cfg, &q);
                prop_assert!(c >= -1e-9, "clearance {c} at s = {s}");
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 6, .. ProptestConfig::default() })]

    /// The Gantry-Tau L1 among random boxes, Cartesian search with the source's numbers
    /// (spherical joints 30 deg, 10 cm from the workspace edge): every pose and every segment
    /// (600 samples each) keeps the plate and the links outside every margin zone, and the
    /// spherical joints within their limit.
    #[test]
    fn l1_plans_are_safe_at_every_instant(
        boxes in prop::collection::vec(arb_box([-1.0, 1.9, -1.4], [0.8, 3.6, 0.2]), 1..3),
        plate in 0.03f64..0.12,
    ) {
        let model = RobotModel::load("gantry-tau-l1").unwrap();
        let cfg = SafetyConfig {
            plate_radius_m: plate,
            link_radius_m: 0.02,
            spherical_max_deg: 30.0,
            workspace_edge_margin_m: 0.1,
            obstacles: boxes,
            ..SafetyConfig::default()
        };
        let checker = SafetyChecker::new(&model, cfg.clone()).unwrap();
        let ws = WorkspaceSettings { space: GridSpace::Cartesian, search_spacing_m: 0.12, ..Default::default() };
        let map = search(&model, &checker, None, &ws).unwrap();
        if map.measurable.is_empty() {
            prop_assert!(map.require_nonempty().is_err());
            return Ok(());
        }
        let grid = spread_grid(&model, &checker, None, &map, 10).unwrap();
        prop_assume!(grid.poses.len() >= 2);
        let poses: Vec<Vec<f64>> = grid.poses.iter().map(|c| c.q.clone()).collect();
        let roadmap: Vec<Vec<f64>> = map.measurable.iter().step_by(5).map(|c| c.q.clone()).collect();
        let settings = PathSettings { approach: Approach::Fixed, ..PathSettings::default() };
        let Ok(path) = plan_path(&model, &checker, &poses[0], &poses, &roadmap, &settings) else {
            return Ok(());
        };
        prop_assert!(verify_path(&checker, &path).is_ok());
        let par = model.parallel().unwrap();
        for w in path.steps.windows(2) {
            for k in 0..=SAMPLES {
                let s = k as f64 / SAMPLES as f64;
                let q: Vec<f64> = w[0].q.iter().zip(&w[1].q).map(|(a, b)| a + (b - a) * s).collect();
                let c = clearance(&model, &cfg, &q);
                prop_assert!(c >= -1e-9, "clearance {c} at s = {s}");
                for a in par.spherical_joint_angles(&q).unwrap() {
                    prop_assert!(a.base_rad.to_degrees() <= 30.0 + 1e-6 && a.platform_rad.to_degrees() <= 30.0 + 1e-6,
                        "{} at {:.4} / {:.4} deg", a.link, a.base_rad.to_degrees(), a.platform_rad.to_degrees());
                }
            }
        }
    }
}

fn l1_checker_cfg() -> SafetyConfig {
    SafetyConfig {
        spherical_max_deg: 30.0,
        workspace_edge_margin_m: 0.1,
        plate_radius_m: 0.1,
        ..SafetyConfig::default()
    }
}

fn coarse() -> WorkspaceSettings {
    WorkspaceSettings { space: GridSpace::Cartesian, search_spacing_m: 0.1, ..Default::default() }
}

#[test]
fn an_empty_workspace_names_the_constraint_that_empties_it() {
    let model = RobotModel::load("gantry-tau-l1").unwrap();
    // Spherical joints that may hardly bend.
    let cfg = SafetyConfig { spherical_max_deg: 0.05, ..l1_checker_cfg() };
    let checker = SafetyChecker::new(&model, cfg).unwrap();
    let map = search(&model, &checker, None, &coarse()).unwrap();
    let msg = map.require_nonempty().unwrap_err().to_string();
    assert!(msg.contains("spherical-joint limit 0.05 deg"), "{msg}");

    // A box over the whole cell.
    let mut cfg = l1_checker_cfg();
    cfg.obstacles.push(ObstacleBox {
        name: "enclosure".into(),
        min_m: [-3.0, 0.0, -3.0],
        max_m: [3.0, 5.0, 1.0],
        margin_m: 0.0,
    });
    let checker = SafetyChecker::new(&model, cfg).unwrap();
    let map = search(&model, &checker, None, &coarse()).unwrap();
    let msg = map.require_nonempty().unwrap_err().to_string();
    assert!(msg.contains("obstacle 'enclosure'"), "{msg}");
    assert_eq!(map.emptied_by().map(|s| s.removed > 0), Some(true));

    // A camera that looks away from the workspace.
    let checker = SafetyChecker::new(&model, l1_checker_cfg()).unwrap();
    let t_cam = CameraView::look_at([2.6, 2.7, -0.5], [5.0, 2.7, -0.5], [0.0, 0.0, 1.0]).unwrap();
    let rig = CameraVisibility::new(
        vec![CameraView::pinhole("away", t_cam, 2000.0, 2000.0, 1000.0, 800.0, 2000, 1600)],
        TargetShape::plate(0.04, 0.02),
        Isometry3::from_parts(
            Translation3::identity(),
            UnitQuaternion::from_euler_angles(0.0, std::f64::consts::FRAC_PI_2, 0.0),
        ),
        VisibilitySettings::default(),
        Vec::new(),
    )
    .unwrap();
    let map = search(&model, &checker, Some(&rig), &coarse()).unwrap();
    let msg = map.require_nonempty().unwrap_err().to_string();
    assert!(msg.contains("measurable by camera away"), "{msg}");
    assert!(msg.contains("from behind") || msg.contains("behind the camera"), "{msg}");

    // A joint margin that leaves no travel is refused when the checker is built.
    let cfg = SafetyConfig { joint_margin: 1.5, ..l1_checker_cfg() };
    let err = SafetyChecker::new(&model, cfg).err().unwrap().to_string();
    assert!(err.contains("joint 1") && err.contains("empty"), "{err}");
}

#[test]
fn stage_counts_add_up_and_the_source_numbers_shape_the_l1_workspace() {
    let model = RobotModel::load("gantry-tau-l1").unwrap();
    let checker = SafetyChecker::new(&model, l1_checker_cfg()).unwrap();
    let map = search(&model, &checker, None, &coarse()).unwrap();
    let removed: usize = map.stages.iter().map(|s| s.removed).sum();
    assert_eq!(removed + map.measurable.len(), map.total);
    let names: Vec<&str> = map.stages.iter().map(|s| s.name.as_str()).collect();
    assert!(names.iter().any(|n| n.contains("spherical-joint limit 30")), "{names:?}");
    assert!(names.iter().any(|n| n.contains("workspace-edge margin 0.1")), "{names:?}");
    for c in &map.measurable {
        assert!(c.q.iter().all(|v| v.abs() <= 1.0));
        assert!(checker.is_safe(&c.q));
    }
    // Fewer wanted poses, larger spacing; the grid count follows the wanted count.
    let g100 = spread_grid(&model, &checker, None, &map, 100).unwrap();
    let g30 = spread_grid(&model, &checker, None, &map, 30).unwrap();
    assert!(g30.spacing > g100.spacing);
    assert!((g100.poses.len() as f64) > 0.6 * 100.0 && (g100.poses.len() as f64) < 1.6 * 100.0, "{}", g100.poses.len());
}
