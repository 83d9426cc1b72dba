//! Kinematic calibration on simulated cells with known truth (the [calibration] issue's
//! simulated checks, in small seeded versions; the full studies are `ferrocal study ...`).

use ferrocal_calib::kinematic::{calibrate, KinematicOptions, ModelParams};
use ferrocal_calib::PoseMeasurement;
use ferrocal_datasets::sim::{make_plan, Conditions, GeometricErrors, PlanConfig, TrackerConfig, TrueRobot};
use ferrocal_robot::{Parameterized, RobotModel};
use nalgebra::Isometry3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// Simulates tracker rows of the true robot at the plan's poses.
fn simulate_rows(
    truth: &TrueRobot,
    poses: &[Vec<f64>],
    tracker: &TrackerConfig,
    rng: &mut ChaCha8Rng,
) -> Vec<PoseMeasurement> {
    poses
        .iter()
        .enumerate()
        .map(|(k, q)| {
            let t =
                truth.tool_pose(q, &Conditions { temp_c: 20.0, dir: vec![0; q.len()], ..Default::default() }).unwrap();
            let r = tracker.measure(&t, rng);
            let mut m = PoseMeasurement::new(format!("{k}"), q.clone(), r.position_m);
            m.sigma_m = Some(r.sigma_m);
            m
        })
        .collect()
}

#[test]
fn gantry_tau_l1_modified_model_parameters_within_their_3_sigma() {
    let nominal = RobotModel::load("gantry-tau-l1").unwrap();
    let tracker = TrackerConfig {
        position_m: [0.0, 0.0, 0.0],
        rpy_deg: [0.0, 0.0, 0.0],
        sigma_const_um: 15.0,
        sigma_per_m_um: 6.0,
        six_dof: false,
        sigma_angle_mrad: 0.0,
        reflector_in_tool_m: [0.0, 0.0, 0.0],
    };
    let plan_cfg = PlanConfig::Grid {
        min_m: [-0.45, 2.45, -0.85],
        max_m: [0.45, 2.95, -0.35],
        spacing_m: 0.15,
        rpy_deg: [0.0, 0.0, 0.0],
        seconds_per_pose: 10.0,
        home_si: vec![],
    };
    let names: Vec<String> = nominal.parameters().into_iter().map(|p| p.name).collect();
    assert_eq!(names.len(), 21, "the modified model has 21 parameters");
    let seeds = 20;
    let mut inside = [0usize; 21];
    let mut all_inside_seeds = 0;
    let mut heldout_ratio = Vec::new();
    for seed in 0..seeds {
        let mut rng = ChaCha8Rng::seed_from_u64(100 + seed);
        let errors = GeometricErrors { length_sigma_mm: 1.0, dimensionless_sigma: 3e-3, ..Default::default() };
        let truth = TrueRobot::new(nominal.clone(), &errors, vec![], 0.0, &mut rng).unwrap();
        let plan = make_plan(&plan_cfg, &nominal, None, &mut rng).unwrap();
        let rows = simulate_rows(&truth, &plan.poses, &tracker, &mut rng);
        let (train, test): (Vec<_>, Vec<_>) = rows.iter().enumerate().partition(|(k, _)| k % 2 == 0);
        let train: Vec<&PoseMeasurement> = train.into_iter().map(|(_, r)| r).collect();
        let test: Vec<&PoseMeasurement> = test.into_iter().map(|(_, r)| r).collect();
        let opts = KinematicOptions {
            model_params: ModelParams::All,
            estimate_device_frame: false,
            fixed_device_frame: Some(Isometry3::identity()),
            joint_offsets: false,
            estimate_tool: false,
            ..KinematicOptions::default()
        };
        let cal = calibrate(&nominal, &train, &opts).unwrap();
        assert_eq!(
            cal.free.len(),
            21,
            "all 21 parameters identifiable: {:?}",
            cal.identifiability_before.describe_groups()
        );
        let true_vals = truth.truth.parameter_values();
        let mut all = true;
        for (k, name) in names.iter().enumerate() {
            let p = cal.params.iter().find(|p| &p.name == name).unwrap();
            let z = (p.value - true_vals[k]).abs() / p.std.unwrap();
            if z <= 3.0 {
                inside[k] += 1;
            } else {
                all = false;
            }
        }
        all_inside_seeds += all as usize;
        // Held-out error at the noise floor: the expected RMS of pure noise is sqrt(3) sigma.
        let stats = cal.calibrated.evaluate(&test).unwrap();
        let floor_mm =
            (test.iter().map(|r| 3.0 * r.sigma_m.unwrap().powi(2)).sum::<f64>() / test.len() as f64).sqrt() * 1e3;
        heldout_ratio.push(stats.rms_mm / floor_mm);
    }
    let worst = inside.iter().copied().min().unwrap();
    eprintln!(
        "L1 21-parameter model, {seeds} seeds: per-parameter within 3 sigma: min {worst}/{seeds}; all 21 within 3 sigma on {all_inside_seeds}/{seeds} seeds; held-out RMS / noise floor: {:?}",
        heldout_ratio.iter().map(|r| format!("{r:.3}")).collect::<Vec<_>>()
    );
    // Every parameter within its 3 sigma on at least 95 % of seeds (19 of 20).
    assert!(
        worst as f64 >= 0.95 * seeds as f64,
        "a parameter was outside 3 sigma on {} of {seeds} seeds",
        seeds - worst as u64
    );
    for r in &heldout_ratio {
        assert!(*r < 1.15, "held-out RMS {r:.3} times the noise floor");
    }
}

#[test]
fn ur5_joint_compliance_identified_jointly_with_the_geometry() {
    use ferrocal_calib::effects::EffectSpec;
    use ferrocal_datasets::sim::Effect;
    use rand::Rng;
    let nominal = RobotModel::load("ur5").unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let errors = GeometricErrors {
        length_sigma_mm: 0.3,
        angle_sigma_mrad: 0.3,
        keep_nominal: vec!["base.".into(), "tool.".into()],
        ..Default::default()
    };
    let true_c = 2e-5; // rad per N m on the shoulder (about 0.1 deg at 80 N m)
    let truth = TrueRobot::new(
        nominal.clone(),
        &errors,
        vec![Effect::JointCompliance { joint: 2, compliance_si: true_c }],
        0.0,
        &mut rng,
    )
    .unwrap();
    let tracker = TrackerConfig {
        position_m: [2.0, 0.5, 0.2],
        rpy_deg: [0.0, 0.0, 160.0],
        sigma_const_um: 15.0,
        sigma_per_m_um: 6.0,
        six_dof: false,
        sigma_angle_mrad: 0.0,
        reflector_in_tool_m: [0.0, 0.0, 0.05],
    };
    let poses: Vec<Vec<f64>> = (0..160)
        .map(|_| {
            vec![
                rng.random_range(-1.5..1.5),
                rng.random_range(-2.6..-0.5),
                rng.random_range(0.3..2.5),
                rng.random_range(-2.5..0.0),
                rng.random_range(0.5..2.5),
                rng.random_range(-1.0..1.0),
            ]
        })
        .collect();
    let mut rows = simulate_rows(&truth, &poses, &tracker, &mut rng);
    for r in &mut rows {
        r.payload_kg = Some(0.0);
    }
    let (train, test): (Vec<&PoseMeasurement>, Vec<&PoseMeasurement>) = {
        let (a, b): (Vec<_>, Vec<_>) = rows.iter().enumerate().partition(|(k, _)| k % 2 == 0);
        (a.into_iter().map(|x| x.1).collect(), b.into_iter().map(|x| x.1).collect())
    };
    let geo = calibrate(&nominal, &train, &KinematicOptions::default()).unwrap();
    let with = calibrate(
        &nominal,
        &train,
        &KinematicOptions { effects: vec![EffectSpec::JointCompliance { joint: 2 }], ..KinematicOptions::default() },
    )
    .unwrap();
    let p = with.params.iter().find(|p| p.name == "joint2.compliance_rad_per_nm").unwrap();
    let (c, sd) = (p.value, p.std.unwrap());
    let before = geo.calibrated.evaluate(&test).unwrap().rms_mm;
    let after = with.calibrated.evaluate(&test).unwrap().rms_mm;
    eprintln!("UR5 joint 2 compliance: true {true_c:.3e}, identified {c:.3e} +- {sd:.1e}; held-out RMS {before:.4} -> {after:.4} mm");
    assert!((c - true_c).abs() < 3.0 * sd, "compliance {c:e} +- {sd:e}, truth {true_c:e}");
    assert!(after < 0.8 * before, "modelling the compliance must improve the held-out fit: {before} -> {after}");
}

#[test]
fn f1_redundant_parameters_are_found_and_fixed_automatically() {
    let nominal = RobotModel::load("gantry-tau-f1").unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(21);
    let errors = GeometricErrors { length_sigma_mm: 0.3, dimensionless_sigma: 5e-4, ..Default::default() };
    let truth = TrueRobot::new(nominal.clone(), &errors, vec![], 0.0, &mut rng).unwrap();
    let tracker = TrackerConfig {
        position_m: [0.0, 0.0, 0.0],
        rpy_deg: [0.0, 0.0, 0.0],
        sigma_const_um: 15.0,
        sigma_per_m_um: 6.0,
        six_dof: true,
        sigma_angle_mrad: 0.02,
        reflector_in_tool_m: [0.0, 0.0, 0.0],
    };
    let plan = make_plan(
        &PlanConfig::Random { n: 185, joint_ranges_si: vec![], seconds_per_pose: 5.0, home_si: vec![] },
        &nominal,
        None,
        &mut rng,
    )
    .unwrap();
    let rows: Vec<PoseMeasurement> = plan
        .poses
        .iter()
        .enumerate()
        .map(|(k, q)| {
            let t = truth.tool_pose(q, &Conditions { temp_c: 20.0, dir: vec![0; 6], ..Default::default() }).unwrap();
            let r = tracker.measure(&t, &mut rng);
            let mut m = PoseMeasurement::new(format!("{k}"), q.clone(), r.position_m);
            m.orientation = r.orientation;
            m.sigma_m = Some(r.sigma_m);
            m.sigma_rad = Some(2e-5);
            m
        })
        .collect();
    let refs: Vec<&PoseMeasurement> = rows.iter().collect();
    let opts = KinematicOptions {
        model_params: ModelParams::All,
        estimate_device_frame: false,
        fixed_device_frame: Some(Isometry3::identity()),
        joint_offsets: false,
        estimate_tool: false,
        ..KinematicOptions::default()
    };
    let cal = calibrate(&nominal, &refs, &opts).unwrap();
    let fixed: Vec<&str> = cal
        .params
        .iter()
        .filter(|p| !p.free && p.fixed_because.as_deref().is_some_and(|r| r.contains("not identifiable")))
        .map(|p| p.name.as_str())
        .collect();
    eprintln!("F1: {} of {} parameters fixed as redundant: {fixed:?}", fixed.len(), cal.params.len());
    eprintln!("{}", cal.identifiability_before.describe_groups().join("\n"));
    // The source fixed six on the F1 arms: frame positions along a rotation axis and rotations
    // about it. Here: for each of the three rotary stages, the position of its frame along its
    // axis, and the length of its (unnormalised) axis vector, this parameterisation's
    // counterpart of a rotation about the axis.
    assert_eq!(fixed.len(), 6, "{fixed:?}");
    let axis_like = fixed.iter().filter(|n| n.contains(".axis_")).count();
    assert_eq!(axis_like, 3, "{fixed:?}");
    let after = cal.train_after.rms_mm;
    assert!(after < 0.06, "the fit must reach the noise: {after} mm");
}

#[test]
fn closure_cost_converges_from_a_tape_measure_guess() {
    use ferrocal_calib::kinematic::Cost;
    let nominal = RobotModel::load("gantry-tau-l1").unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(31);
    // The true robot is 15 mm (positions, lengths) and 1e-2 (directions) away from the guess.
    let errors = GeometricErrors { length_sigma_mm: 15.0, dimensionless_sigma: 1e-2, ..Default::default() };
    let truth = TrueRobot::new(nominal.clone(), &errors, vec![], 0.0, &mut rng).unwrap();
    let tracker = TrackerConfig {
        position_m: [0.0, 0.0, 0.0],
        rpy_deg: [0.0, 0.0, 0.0],
        sigma_const_um: 15.0,
        sigma_per_m_um: 6.0,
        six_dof: false,
        sigma_angle_mrad: 0.0,
        reflector_in_tool_m: [0.0, 0.0, 0.0],
    };
    // Poses the TRUE robot can reach (the guess may not reach all of them).
    let plan = make_plan(
        &PlanConfig::Random { n: 80, joint_ranges_si: vec![[-0.7, 0.7]; 3], seconds_per_pose: 5.0, home_si: vec![] },
        &truth.truth,
        None,
        &mut rng,
    )
    .unwrap();
    let rows = simulate_rows(&truth, &plan.poses, &tracker, &mut rng);
    let refs: Vec<&PoseMeasurement> = rows.iter().collect();
    let opts = KinematicOptions {
        model_params: ModelParams::All,
        estimate_device_frame: false,
        fixed_device_frame: Some(Isometry3::identity()),
        joint_offsets: false,
        estimate_tool: false,
        cost: Cost::Closure,
        ..KinematicOptions::default()
    };
    let cal = calibrate(&nominal, &refs, &opts).unwrap();
    let true_vals = truth.truth.parameter_values();
    let names: Vec<String> = nominal.parameters().into_iter().map(|p| p.name).collect();
    let mut worst_z: f64 = 0.0;
    for (k, name) in names.iter().enumerate() {
        let p = cal.params.iter().find(|p| &p.name == name).unwrap();
        worst_z = worst_z.max((p.value - true_vals[k]).abs() / p.std.unwrap());
    }
    let stats = cal.calibrated.evaluate(&refs).unwrap();
    eprintln!("closure cost from a 15 mm guess: worst |z| {worst_z:.2}, forward-kinematics RMS {:.4} mm", stats.rms_mm);
    assert!(worst_z < 4.0, "worst parameter {worst_z:.2} sigma from the truth");
    assert!(stats.rms_mm < 0.06, "{} mm", stats.rms_mm);
}
