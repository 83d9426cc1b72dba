//! The simulated check of corrected programs ([`corrected_commands_study`]): a UR5 with random
//! geometric errors calibrated from 6-DoF tracker poses, then a program of other commands
//! corrected through the calibration and run through the true robot. The truth is the
//! simulator's geometric error model, the calibration's own model family: the check shows that the
//! correction does what the calibration knows, not that the model family is right.

use ferrocal_calib::kinematic::correct::{correct_program, CorrectOptions};
use ferrocal_calib::kinematic::{calibrate, KinematicOptions};
use ferrocal_calib::PoseMeasurement;
use ferrocal_robot::RobotModel;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::{make_plan, Conditions, GeometricErrors, PlanConfig, TrackerConfig, TrueRobot};
use crate::error::{DatasetError, Result};

/// The outcome of [`corrected_commands_study`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CorrectedCommandsStudy {
    /// Poses that calibrated, poses of the calibration's held-out check, program commands.
    pub n_train: usize,
    /// See [`CorrectedCommandsStudy::n_train`].
    pub n_test: usize,
    /// See [`CorrectedCommandsStudy::n_train`].
    pub n_program: usize,
    /// The calibration's mean held-out error against the tracker (noise included), mm.
    pub held_out_mm: f64,
    /// The program's uncorrected commands on the true robot: mean distance from the intended
    /// poses, mm.
    pub uncorrected_mm: f64,
    /// The corrected commands on the true robot, mm.
    pub corrected_mm: f64,
    /// The largest remaining miss of a corrected command under the calibrated model, mm.
    pub max_model_residual_mm: f64,
}

/// Runs the check with `seed` (180 poses: 120 calibrate, 30 check the calibration, 30 are the
/// program; geometric errors 0.5 mm and 1 mrad; tracker 15 um + 6 um/m, 0.02 mrad).
pub fn corrected_commands_study(seed: u64) -> Result<CorrectedCommandsStudy> {
    let err = |e: ferrocal_calib::CalibError| DatasetError::Input(format!("corrected-commands study: {e}"));
    let nominal = RobotModel::load("ur5").map_err(|e| DatasetError::Input(e.to_string()))?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let errors = GeometricErrors { length_sigma_mm: 0.5, angle_sigma_mrad: 1.0, ..Default::default() };
    let truth = TrueRobot::new(nominal.clone(), &errors, vec![], 0.0, &mut rng)?;
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
    )?;
    let conditions = Conditions { temp_c: 20.0, dir: vec![0; 6], ..Default::default() };
    let mut rows = Vec::with_capacity(plan.poses.len());
    for (k, q) in plan.poses.iter().enumerate() {
        let t = truth.tool_pose(q, &conditions)?;
        let r = tracker.measure(&t, &mut rng);
        let mut m = PoseMeasurement::new(format!("{k}"), q.clone(), r.position_m);
        m.orientation = r.orientation;
        m.sigma_m = Some(r.sigma_m);
        m.sigma_rad = Some(2e-5);
        rows.push(m);
    }
    let train: Vec<&PoseMeasurement> = rows[..120].iter().collect();
    let test: Vec<&PoseMeasurement> = rows[120..150].iter().collect();
    let program = &rows[150..];
    let cal = calibrate(&nominal, &train, &KinematicOptions::default()).map_err(err)?;
    let held_out_mm = cal.calibrated.evaluate(&test).map_err(err)?.mean_mm;
    let corrected = correct_program(&cal.calibrated, program, &CorrectOptions::default()).map_err(err)?;
    let (mut sum_c, mut sum_u, mut worst) = (0.0, 0.0, 0.0f64);
    for (row, c) in program.iter().zip(&corrected) {
        // The tracker's frame is the world: the true robot's poses compare directly.
        let at = |q: &[f64]| truth.tool_pose(q, &conditions).map(|t| t.translation.vector);
        sum_c += (at(&c.q)? - c.intended.translation.vector).norm() * 1e3;
        sum_u += (at(&row.q)? - c.intended.translation.vector).norm() * 1e3;
        worst = worst.max(c.residual_m * 1e3);
    }
    let n = program.len() as f64;
    Ok(CorrectedCommandsStudy {
        n_train: train.len(),
        n_test: test.len(),
        n_program: program.len(),
        held_out_mm,
        uncorrected_mm: sum_u / n,
        corrected_mm: sum_c / n,
        max_model_residual_mm: worst,
    })
}
