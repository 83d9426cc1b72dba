//! Corrected joint commands on a simulated UR5 with known geometric errors (the [compensate]
//! check): the robot is calibrated from 6-DoF tracker poses (noise 15 um + 6 um/m, 0.02 mrad),
//! then a program of other commands is corrected through the calibrated model and run through
//! the true robot. The truth is the simulator's error model (random per-joint geometric errors of
//! a serial chain), which is the calibration's own model family: this shows the correction does
//! what the calibration knows, not that the model family is right.

use ferrocal_calib::kinematic::correct::{correct_program, CorrectOptions};
use ferrocal_calib::kinematic::{calibrate, KinematicOptions};
use ferrocal_calib::PoseMeasurement;
use ferrocal_datasets::sim::{make_plan, Conditions, GeometricErrors, PlanConfig, TrackerConfig, TrueRobot};
use ferrocal_robot::RobotModel;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

#[test]
fn corrected_commands_land_within_1_5x_of_the_held_out_calibration_error() {
    let nominal = RobotModel::load("ur5").unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(31);
    let errors = GeometricErrors { length_sigma_mm: 0.5, angle_sigma_mrad: 1.0, ..Default::default() };
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
    let ranges = vec![[-1.5, 1.5], [-2.0, -0.5], [0.5, 2.0], [-2.0, 0.0], [-1.5, 1.5], [-1.5, 1.5]];
    let plan = make_plan(
        &PlanConfig::Random { n: 180, joint_ranges_si: ranges, seconds_per_pose: 5.0, home_si: vec![] },
        &nominal,
        None,
        &mut rng,
    )
    .unwrap();
    let conditions = Conditions { temp_c: 20.0, dir: vec![0; 6], ..Default::default() };
    let rows: Vec<PoseMeasurement> = plan
        .poses
        .iter()
        .enumerate()
        .map(|(k, q)| {
            let t = truth.tool_pose(q, &conditions).unwrap();
            let r = tracker.measure(&t, &mut rng);
            let mut m = PoseMeasurement::new(format!("{k}"), q.clone(), r.position_m);
            m.orientation = r.orientation;
            m.sigma_m = Some(r.sigma_m);
            m.sigma_rad = Some(2e-5);
            m
        })
        .collect();
    // 120 poses calibrate, 30 are the calibration's held-out check, 30 are the program.
    let train: Vec<&PoseMeasurement> = rows[..120].iter().collect();
    let test: Vec<&PoseMeasurement> = rows[120..150].iter().collect();
    let program = &rows[150..];
    let cal = calibrate(&nominal, &train, &KinematicOptions::default()).unwrap();
    let held_out_mm = cal.calibrated.evaluate(&test).unwrap().mean_mm;

    let mut corrected_mm = Vec::new();
    let mut uncorrected_mm = Vec::new();
    let corrected = correct_program(&cal.calibrated, program, &CorrectOptions::default()).unwrap();
    for (row, c) in program.iter().zip(&corrected) {
        assert!(c.residual_m < 1e-7, "pose {}: the calibrated model misses by {} m", row.pose_id, c.residual_m);
        // Both commands run on the true robot; the tracker frame is the world (identity).
        let at = |q: &[f64]| truth.tool_pose(q, &conditions).unwrap().translation.vector;
        corrected_mm.push((at(&c.q) - c.intended.translation.vector).norm() * 1e3);
        uncorrected_mm.push((at(&row.q) - c.intended.translation.vector).norm() * 1e3);
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let (corrected, uncorrected) = (mean(&corrected_mm), mean(&uncorrected_mm));
    eprintln!(
        "program of {} commands on the true robot: uncorrected {uncorrected:.4} mm, corrected {corrected:.4} mm; calibration held-out {held_out_mm:.4} mm",
        program.len()
    );
    assert!(corrected < 1.5 * held_out_mm, "corrected {corrected} mm against held-out {held_out_mm} mm");
    assert!(
        corrected < 0.2 * uncorrected,
        "the correction must remove most of the error: {uncorrected} -> {corrected}"
    );
}
