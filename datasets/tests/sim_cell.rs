//! The simulated cell: a complete, deterministic session on disk; the effects' equations; bad
//! cell files.

use std::path::{Path, PathBuf};

use ferrocal_datasets::import::read_measurements;
use ferrocal_datasets::sim::{
    simulate, CellConfig, Conditions, Effect, GeometricErrors, PlanConfig, SessionTruth, TrueRobot,
};
use ferrocal_robot::{Kinematics, RobotModel};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

fn example_cell() -> CellConfig {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("cells/gantry_tau_l1.toml");
    CellConfig::from_file(&path).expect("the built-in cell parses")
}

/// The built-in cell cut to a few poses (rendering 5 MP images is the slow part).
fn small_cell() -> CellConfig {
    let mut cfg = example_cell();
    cfg.plan = PlanConfig::List {
        joints_si: vec![vec![0.0, 0.0, 0.0], vec![0.1, -0.05, 0.08], vec![-0.2, 0.1, -0.1]],
        seconds_per_pose: 10.0,
        home_si: vec![],
    };
    if let Some(b) = &mut cfg.calibration_board {
        b.views = 2;
    }
    cfg
}

fn read_dir_bytes(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.push((p.strip_prefix(dir).unwrap().to_path_buf(), std::fs::read(&p).unwrap()));
            }
        }
    }
    out.sort();
    out
}

#[test]
fn l1_cell_with_two_cameras_and_a_tracker_writes_a_complete_deterministic_session() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = small_cell();
    let a = tmp.path().join("a");
    let m = simulate(&cfg, &a, false, |_, _| {}).unwrap();
    assert_eq!(m.n_poses, 3);
    assert_eq!(m.cameras.len(), 2);
    // Every file the manifest names exists.
    for c in &m.cameras {
        assert_eq!(c.images.len(), 3);
        for img in c.images.iter().flatten() {
            let i = image::open(a.join(img)).unwrap();
            assert_eq!((i.width(), i.height()), (c.width_px, c.height_px));
        }
        assert!(a.join(&c.corners_truth).exists());
        assert_eq!(c.board_images.iter().flatten().count(), 2, "two board views per camera");
        assert!(a.join(c.board_corners_truth.as_ref().unwrap()).exists());
        // 20 plate corners per image, all inside.
        let text = std::fs::read_to_string(a.join(&c.corners_truth)).unwrap();
        assert_eq!(text.lines().count(), 1 + 3 * 20, "{}", c.corners_truth);
    }
    assert!(a.join("joints.csv").exists() && a.join("manifest.json").exists() && a.join("cell.toml").exists());
    // The tracker table reads back through the importer and agrees with the truth within noise.
    let table = read_measurements(a.join(m.tracker.as_ref().unwrap())).unwrap();
    assert_eq!(table.set.rows.len(), 3);
    let truth: SessionTruth = serde_json::from_str(&std::fs::read_to_string(a.join(&m.truth)).unwrap()).unwrap();
    let t_wt = truth.t_world_tracker.unwrap();
    for (row, p) in table.set.rows.iter().zip(&truth.poses) {
        let true_pos = (t_wt.inverse() * p.t_world_tool).translation.vector;
        let z = (row.position_m - true_pos).norm() / row.sigma_m.unwrap();
        assert!(z < 6.0, "tracker reading {z:.1} sigma from the truth");
        assert_eq!(row.q, p.q_cmd);
    }
    // Deterministic for a seed: a second run writes the same bytes.
    let b = tmp.path().join("b");
    simulate(&cfg, &b, false, |_, _| {}).unwrap();
    let (fa, fb) = (read_dir_bytes(&a), read_dir_bytes(&b));
    assert_eq!(fa.len(), fb.len());
    for ((pa, ba), (pb, bb)) in fa.iter().zip(&fb) {
        assert_eq!(pa, pb);
        assert!(ba == bb, "{} differs between two runs with the same seed", pa.display());
    }
    // An existing folder is not overwritten without --force, and nothing is half-written.
    let e = simulate(&cfg, &a, false, |_, _| {}).unwrap_err().to_string();
    assert!(e.contains("exists"), "{e}");
    let leftovers: Vec<_> = std::fs::read_dir(tmp.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(leftovers.len(), 2, "{leftovers:?}");
}

#[test]
fn a_failing_session_leaves_nothing_behind() {
    let tmp = tempfile::tempdir().unwrap();
    let mut cfg = small_cell();
    // The third pose is far outside the workspace: the plan is refused before anything is written.
    cfg.plan = PlanConfig::List {
        joints_si: vec![vec![0.0, 0.0, 0.0], vec![9.0, -9.0, 9.0]],
        seconds_per_pose: 1.0,
        home_si: vec![],
    };
    let out = tmp.path().join("s");
    let e = simulate(&cfg, &out, false, |_, _| {}).unwrap_err().to_string();
    assert!(e.contains("pose 2"), "{e}");
    assert_eq!(std::fs::read_dir(tmp.path()).unwrap().count(), 0);
}

#[test]
fn cell_file_errors_name_file_line_and_column() {
    let text =
        "seed = 1\n[robot]\nmodel = \"gantry-tau-l1\"\nplatfrom_mass_kg = 3.0\n[plan]\nkind = \"random\"\nn = 3\n";
    let e = CellConfig::from_toml_str(text, Path::new("cell.toml")).unwrap_err().to_string();
    assert!(e.contains("cell.toml:4:1") && e.contains("platfrom_mass_kg"), "{e}");
    let text = "[robot]\nmodel = \"ur5\"\n[plan]\nkind = \"random\"\nn = \"many\"\n";
    let e = CellConfig::from_toml_str(text, Path::new("c.toml")).unwrap_err().to_string();
    // Inside an internally tagged table the TOML reader can only point at the table's header.
    assert!(e.contains("c.toml:3:") && e.contains("\"many\""), "{e}");
    // An effect on a joint the robot does not have.
    let model = RobotModel::load("ur5").unwrap();
    let e = TrueRobot::new(
        model,
        &GeometricErrors::default(),
        vec![Effect::Backlash { joint: 7, width_si: 1e-4 }],
        0.0,
        &mut ChaCha8Rng::seed_from_u64(1),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("joint 7") && e.contains("6 joints"), "{e}");
}

fn cond(dir: Vec<i8>) -> Conditions {
    Conditions { t_s: 0.0, temp_c: 20.0, payload_kg: 0.0, dir }
}

#[test]
fn effects_follow_their_equations() {
    let model = RobotModel::load("ur5").unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let q = vec![0.3, -1.1, 1.2, -0.8, 1.4, 0.2];
    let plain = TrueRobot::new(model.clone(), &GeometricErrors::default(), vec![], 0.0, &mut rng).unwrap();
    let p0 = plain.tool_pose(&q, &cond(vec![1; 6])).unwrap();
    assert!((p0.translation.vector - model.forward(&q).unwrap().translation.vector).norm() < 1e-15);

    // Backlash: approaching from + and - differs by the dead band on that joint.
    let b = TrueRobot::new(
        model.clone(),
        &GeometricErrors::default(),
        vec![Effect::Backlash { joint: 2, width_si: 2e-4 }],
        0.0,
        &mut rng,
    )
    .unwrap();
    let m = b.model_at(&q, &cond(vec![1; 6])).unwrap();
    let up = b.effective_joints(&m, &q, &cond(vec![1; 6])).unwrap();
    let down = b.effective_joints(&m, &q, &cond(vec![-1; 6])).unwrap();
    assert!((down[1] - up[1] - 2e-4).abs() < 1e-15 && up[0] == q[0]);

    // Joint compliance: the simulator's holding torques (central differences of the potential
    // energy) agree with the robot crate's Jacobian-transpose gravity torques.
    let c = TrueRobot::new(
        model.clone(),
        &GeometricErrors::default(),
        vec![Effect::JointCompliance { joint: 2, compliance_si: 1e-5 }],
        0.0,
        &mut rng,
    )
    .unwrap();
    let RobotModel::Serial(chain) = &model else { unreachable!() };
    let tau_robot = chain.gravity_torques(&q, 2.0).unwrap();
    let tau_sim = c.holding_torques(&model, &q, 2.0).unwrap();
    for (a, b) in tau_robot.iter().zip(&tau_sim) {
        assert!((a - b).abs() < 1e-5 * (1.0 + a.abs()), "{a} vs {b}");
    }
    let mut cnd = cond(vec![0; 6]);
    cnd.payload_kg = 2.0;
    let qe = c.effective_joints(&model, &q, &cnd).unwrap();
    assert!((qe[1] - (q[1] - 1e-5 * tau_robot[1])).abs() < 1e-12);

    // Periodic error and scale error.
    let p = TrueRobot::new(
        model.clone(),
        &GeometricErrors::default(),
        vec![
            Effect::PeriodicJointError { joint: 1, amplitude_si: 1e-4, period_si: 0.5, phase_rad: 0.3 },
            Effect::JointScaleError { joint: 3, scale_error: 1e-3 },
        ],
        0.0,
        &mut rng,
    )
    .unwrap();
    let qe = p.effective_joints(&model, &q, &cond(vec![0; 6])).unwrap();
    assert!((qe[0] - (q[0] + 1e-4 * (std::f64::consts::TAU * q[0] / 0.5 + 0.3).sin())).abs() < 1e-15);
    assert!((qe[2] - q[2] * 1.001).abs() < 1e-15);

    // Thermal expansion scales every length: the tool point moves by alpha dT times its
    // distance from the base origin (all lengths scale about it).
    let t = TrueRobot::new(
        model.clone(),
        &GeometricErrors::default(),
        vec![Effect::ThermalExpansion { alpha_per_k: 11.5e-6, reference_temp_c: 20.0 }],
        0.0,
        &mut rng,
    )
    .unwrap();
    let mut hot = cond(vec![0; 6]);
    hot.temp_c = 30.0;
    let ph = t.tool_pose(&q, &hot).unwrap().translation.vector;
    let pc = t.tool_pose(&q, &cond(vec![0; 6])).unwrap().translation.vector;
    assert!((ph - pc * (1.0 + 11.5e-5)).norm() < 1e-12, "{}", (ph - pc * (1.0 + 11.5e-5)).norm());
}
