//! [planning] ordering and programs: detours around obstacles through safe via configurations,
//! approach directions, and the RAPID, CSV and G-code writers.

use ferrocal_robot::program::{
    gcode, path_csv, plan_path, rapid_module, verify_path, Approach, GcodeAxes, PathSettings, ProgramSettings, StepKind,
};
use ferrocal_robot::safety::{ObstacleBox, SafetyChecker, SafetyConfig};
use ferrocal_robot::serial::{parse_urdf_str, UrdfOptions};
use ferrocal_robot::{Kinematics, RobotModel};

/// A planar arm: two revolute joints about z, links of 1 m along x.
fn planar_arm() -> ferrocal_robot::serial::SerialChain {
    let urdf = r#"<?xml version="1.0"?>
<robot name="planar2">
  <link name="base"/><link name="l1"/><link name="l2"/><link name="tool"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><origin xyz="0 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-3.1" upper="3.1" effort="1" velocity="1"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="1 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-3.1" upper="3.1" effort="1" velocity="1"/></joint>
  <joint name="flange" type="fixed"><parent link="l2"/><child link="tool"/><origin xyz="1 0 0"/></joint>
</robot>"#;
    parse_urdf_str(urdf, &UrdfOptions::default()).unwrap()
}

#[test]
fn a_blocked_segment_is_routed_through_safe_via_configurations() {
    let arm = planar_arm();
    // A post in front of the stretched arm: sweeping joint 1 through 0 with the arm stretched
    // hits it; folding the elbow passes it.
    let cfg = SafetyConfig {
        obstacles: vec![ObstacleBox {
            name: "post".into(),
            min_m: [1.5, -0.1, -1.0],
            max_m: [1.9, 0.1, 1.0],
            margin_m: 0.05,
        }],
        link_radius_m: 0.02,
        ..SafetyConfig::default()
    };
    let checker = SafetyChecker::new(&arm, cfg).unwrap();
    let a = vec![-0.6, 0.0];
    let b = vec![0.6, 0.0];
    assert!(checker.is_safe(&a) && checker.is_safe(&b));
    assert!(checker.check_move(&a, &b).is_err());
    let roadmap: Vec<Vec<f64>> =
        (0..25).flat_map(|i| (0..25).map(move |j| vec![-3.0 + 0.25 * i as f64, -3.0 + 0.25 * j as f64])).collect();
    let settings = PathSettings { two_opt: false, return_home: false, ..PathSettings::default() };
    let path = plan_path(&arm, &checker, &a, std::slice::from_ref(&b), &roadmap, &settings).unwrap();
    assert!(path.detours >= 1);
    assert!(path.steps.iter().any(|s| s.kind == StepKind::Via));
    verify_path(&checker, &path).unwrap();
    // Without a roadmap the planner refuses and names the segment and the zone.
    let err = plan_path(&arm, &checker, &a, &[b], &[], &settings).unwrap_err().to_string();
    assert!(err.contains("no safe route from home to pose 1") && err.contains("post"), "{err}");
}

#[test]
fn approach_directions_are_fixed_or_both() {
    let arm = planar_arm();
    let checker = SafetyChecker::new(&arm, SafetyConfig::default()).unwrap();
    let poses = vec![vec![0.5, 0.5], vec![-0.5, 1.0], vec![1.0, -1.0], vec![0.2, 0.3]];
    let home = vec![0.0, 0.0];
    let fixed = plan_path(
        &arm,
        &checker,
        &home,
        &poses,
        &[],
        &PathSettings { approach: Approach::Fixed, ..Default::default() },
    )
    .unwrap();
    for s in fixed.steps.iter().filter(|s| s.kind == StepKind::Measure) {
        assert_eq!(s.dir, vec![1, 1]);
    }
    let down = plan_path(
        &arm,
        &checker,
        &home,
        &poses,
        &[],
        &PathSettings { approach: Approach::Fixed, approach_sign: -1, ..Default::default() },
    )
    .unwrap();
    assert!(down.steps.iter().filter(|s| s.kind == StepKind::Measure).all(|s| s.dir == vec![-1, -1]));
    let both =
        plan_path(&arm, &checker, &home, &poses, &[], &PathSettings { approach: Approach::Both, ..Default::default() })
            .unwrap();
    for p in 0..poses.len() {
        let dirs: Vec<&Vec<i8>> =
            both.steps.iter().filter(|s| s.kind == StepKind::Measure && s.pose == Some(p)).map(|s| &s.dir).collect();
        assert_eq!(dirs, vec![&vec![1, 1], &vec![-1, -1]], "pose {p}");
    }
    assert_eq!(both.measurements(), 2 * poses.len());
    // 2-opt never lengthens the nearest-neighbour order.
    assert!(both.ordered_s <= both.nearest_neighbour_s + 1e-12);
}

#[test]
fn programs_visit_every_step() {
    let arm = planar_arm();
    let checker = SafetyChecker::new(&arm, SafetyConfig::default()).unwrap();
    let poses = vec![vec![0.5, 0.5], vec![-0.5, 1.0], vec![1.0, -1.0]];
    let path = plan_path(&arm, &checker, &[0.0, 0.0], &poses, &[], &PathSettings::default()).unwrap();
    let settings = ProgramSettings { rapid_trigger: Some("PulseDO doCamera;".into()), ..Default::default() };
    let r = rapid_module(&arm, &path, 2.5, &settings, &["test plan".into()]).unwrap();
    assert!(r.starts_with("MODULE FerrocalPlan\n") && r.trim_end().ends_with("ENDMODULE"));
    assert_eq!(r.matches("MoveAbsJ jt").count(), path.steps.len());
    assert_eq!(r.matches("WaitTime \\InPos, 2.50;").count(), 3);
    assert_eq!(r.matches("PulseDO doCamera;").count(), 3);
    // 0.5 rad = 28.6479 deg on robot axis 1; unused axes 0, external axes 9E9.
    assert!(r.contains("[[28.6479,28.6479,0.0000,0.0000,0.0000,0.0000],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]]"), "{r}");
    let bad = ProgramSettings { rapid_module: "1 bad".into(), ..Default::default() };
    assert!(rapid_module(&arm, &path, 1.0, &bad, &[]).is_err());

    let csv = path_csv(&arm, &path, true).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines[0], "step,kind,pose,q1_deg,q2_deg,dir1,dir2,x_mm,y_mm,z_mm");
    assert_eq!(lines.len(), 1 + 3);
    let all = path_csv(&arm, &path, false).unwrap();
    assert_eq!(all.lines().count(), 1 + path.steps.len());

    let g = gcode(&arm, &path, 1.0, &ProgramSettings::default(), &["(nested) header".into()]).unwrap();
    assert_eq!(g.moves, path.steps.len());
    assert_eq!(g.text.matches("G4 P1.00").count(), 3);
    assert!(g.text.contains("G21 G90 G94") && g.text.trim_end().ends_with("M2"));
    assert!(g.text.lines().filter(|l| l.starts_with("G1 ")).all(|l| l.contains(" X") || l.starts_with("G1 X")));
}

#[test]
fn hexapod_gcode_in_pose_axes_stays_close_to_the_checked_path() {
    let hex = RobotModel::load("hexapod").unwrap();
    let checker = SafetyChecker::new(&hex, SafetyConfig::default()).unwrap();
    let poses =
        vec![vec![0.02; 6], vec![-0.02, 0.01, 0.03, -0.01, 0.0, 0.02], vec![0.04, 0.04, 0.0, 0.0, -0.03, -0.03]];
    let home = vec![0.0; 6];
    let path = plan_path(&hex, &checker, &home, &poses, &[], &PathSettings::default()).unwrap();
    verify_path(&checker, &path).unwrap();
    let settings = ProgramSettings { gcode_axes: GcodeAxes::Pose, gcode_max_step_mm: 2.0, ..Default::default() };
    let g = gcode(&hex, &path, 1.0, &settings, &[]).unwrap();
    assert!(g.moves > path.steps.len(), "segments are cut into steps");
    assert!(g.max_chord_deviation_mm < 0.05, "{}", g.max_chord_deviation_mm);
    for l in g.text.lines().filter(|l| l.starts_with("G1 ")) {
        for w in ["X", "Y", "Z", "A", "B", "C", "F"] {
            assert!(l.contains(&format!(" {w}")), "{l}");
        }
    }
    let _ = hex.dof();
}
