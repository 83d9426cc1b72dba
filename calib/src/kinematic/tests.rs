//! The kinematic calibration's residual Jacobian through the least-squares layer's gradient
//! checker: analytic columns (device frame, tool, joint offsets, a serial chain's correction
//! transforms) and numeric ones (effects, other model parameters) against central differences of
//! the residuals, with scalar sigmas and with full 6 x 6 covariances, positions only and full poses.

use nalgebra::{Isometry3, Matrix6, UnitQuaternion, Vector3};

use super::problem::{whitening_matrices, KinProblem};
use super::*;
use crate::lsq::check_jacobian;
use crate::measurement::PoseCovariance;

/// A deterministic sequence in [-1, 1) (no random-number crate needed here).
fn wave(k: usize) -> f64 {
    ((k as f64 * 12.9898).sin() * 43758.5453).fract() * 2.0 - 1.0
}

fn rows(model: &RobotModel, n: usize, covariance: bool) -> Vec<PoseMeasurement> {
    (0..n)
        .map(|i| {
            let q: Vec<f64> = (0..model.dof()).map(|j| 1.4 * wave(7 * i + j)).collect();
            let t = model.forward(&q).unwrap();
            // A few millimetres and milliradians off the nominal model, so residuals are not zero.
            let p = t.translation.vector + Vector3::new(wave(3 * i), wave(3 * i + 1), wave(3 * i + 2)) * 2e-3;
            let mut row = PoseMeasurement::new(format!("p{i}"), q, p);
            row.orientation = Some(UnitQuaternion::from_scaled_axis(Vector3::new(1e-3, -2e-3, 5e-4)) * t.rotation);
            if covariance {
                let a = Matrix6::from_fn(|r, c| wave(36 * i + 6 * r + c) * 1e-4);
                let si = a * a.transpose() + Matrix6::from_diagonal(&nalgebra::Vector6::repeat(1e-9));
                row.covariance = Some(PoseCovariance::Pose { si });
            }
            row
        })
        .collect()
}

fn check(model: &RobotModel, use_ori: bool, covariance: bool, effects: Vec<EffectSpec>) {
    let data = rows(model, 12, covariance);
    let refs: Vec<&PoseMeasurement> = data.iter().collect();
    let layout = StateLayout::new(model, if use_ori { 6 } else { 3 }, &ModelParams::Default, &effects);
    let sigma_pos = vec![1e-4; refs.len()];
    let sigma_ori = vec![2e-4; refs.len()];
    let whiten = whitening_matrices(&refs, use_ori, &sigma_ori, true, Cost::ForwardKinematics).unwrap();
    assert_eq!(whiten.iter().all(Option::is_some), covariance);
    let start = layout.start_values(model);
    let problem = KinProblem {
        base_model: model.clone(),
        rows: &refs,
        layout: &layout,
        f0: Isometry3::new(Vector3::new(0.3, -0.2, 0.1), Vector3::new(0.2, 2.5, -0.4)),
        tool0: Isometry3::identity(),
        use_ori,
        start: start.clone(),
        free: (0..layout.len()).collect(),
        sigma_pos,
        sigma_ori,
        whiten,
        effects,
        cost: Cost::ForwardKinematics,
        n_legs: 0,
    };
    // Away from the start values in every coordinate.
    let x: Vec<f64> = start.iter().zip(&layout.scales).enumerate().map(|(k, (v, s))| v + 0.3 * s * wave(k)).collect();
    let report = check_jacobian(&problem, &x, 1e-3).unwrap();
    report.assert_below(1e-5, &format!("{}: orientation {use_ori}, covariance {covariance}", model.name())).unwrap();
    assert!(report.entries > 1000, "{} entries", report.entries);
}

#[test]
fn kinematic_residual_passes_the_gradient_checker() {
    let ur5 = ferrocal_robot::presets::preset("ur5").unwrap();
    for (use_ori, covariance) in [(false, false), (true, false), (false, true), (true, true)] {
        check(&ur5, use_ori, covariance, Vec::new());
    }
    let effects = vec![
        EffectSpec::JointScaleError { joint: 2 },
        EffectSpec::PeriodicJointError { joint: 3, period_si: std::f64::consts::PI },
    ];
    check(&ur5, true, false, effects);
}
