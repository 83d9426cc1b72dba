//! The kinematic calibration's residual Jacobian through the least-squares layer's gradient
//! checker: analytic columns (device frame, tool, joint offsets, a serial chain's correction
//! transforms) and numeric ones (effects, other model parameters) against central differences of
//! the residuals, with scalar sigmas and with full 6 x 6 covariances, positions only and full poses.
//!
//! The analytic columns are exact at any increment of the device frame, the tool and the
//! corrections (left and right Jacobians of the rotation vectors, the inverse right Jacobian of
//! the orientation residual, the effects' length scale), so the checker's tolerance is the same
//! at the start, near it and far from it (0.3 of each candidate's scale). What is not in the
//! analytic columns is the dependence of a link-compliance effect's pose correction on the other
//! parameters (second order in the compliance, 1e-5 rad per N m and less).

use nalgebra::{Isometry3, Matrix6, UnitQuaternion, Vector3};

use super::problem::{whitening_matrices, KinProblem};
use super::*;
use crate::lsq::check_jacobian;
use crate::measurement::PoseCovariance;

/// A deterministic sequence in [-1, 1) (no random-number crate needed here).
fn wave(k: usize) -> f64 {
    ((k as f64 * 12.9898).sin() * 43758.5453).fract() * 2.0 - 1.0
}

/// The device frame of the simulated measurements (any pose: the registration is not at zero).
fn device_frame() -> Isometry3<f64> {
    Isometry3::new(Vector3::new(0.3, -0.2, 0.1), Vector3::new(0.2, 2.5, -0.4))
}

fn rows(model: &RobotModel, n: usize, covariance: bool) -> Vec<PoseMeasurement> {
    (0..n)
        .map(|i| {
            let q: Vec<f64> = (0..model.dof()).map(|j| 1.4 * wave(7 * i + j)).collect();
            let t = device_frame() * model.forward(&q).unwrap();
            // A few millimetres and milliradians off the nominal model, so residuals are not zero.
            let p = t.translation.vector + Vector3::new(wave(3 * i), wave(3 * i + 1), wave(3 * i + 2)) * 2e-3;
            let mut row = PoseMeasurement::new(format!("p{i}"), q, p);
            row.orientation = Some(UnitQuaternion::from_scaled_axis(Vector3::new(1e-3, -2e-3, 5e-4)) * t.rotation);
            row.temp_c = Some(20.0 + 5.0 * wave(11 * i));
            if covariance {
                let a = Matrix6::from_fn(|r, c| wave(36 * i + 6 * r + c) * 1e-4);
                let si = a * a.transpose() + Matrix6::from_diagonal(&nalgebra::Vector6::repeat(1e-9));
                row.covariance = Some(PoseCovariance::Pose { si });
            }
            row
        })
        .collect()
}

/// The largest Jacobian error the checker accepts, relative to the column's largest entry. With
/// orientations the worst error measured is about 1e-9; positions alone reach about 3e-6, in the
/// columns of the last joints' rotation corrections, which barely move a target that sits near
/// the flange axis (nearly zero columns, where central differences lose digits). The first-order
/// columns this replaced were off by 4e-3 at 0.003 and 9e-2 at 0.3 of the scales.
const TOLERANCE: f64 = 1e-5;

/// The worst relative Jacobian error at the start (`offset = 0`) or at increments of `offset`
/// times each candidate's scale.
fn check(model: &RobotModel, use_ori: bool, covariance: bool, effects: Vec<EffectSpec>, offset: f64) -> f64 {
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
        f0: device_frame(),
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
    let x: Vec<f64> =
        start.iter().zip(&layout.scales).enumerate().map(|(k, (v, s))| v + offset * s * wave(k)).collect();
    let report = check_jacobian(&problem, &x, 1e-3).unwrap();
    assert!(report.entries > 1000, "{} entries", report.entries);
    let (_, row, col) = report.worst;
    eprintln!(
        "{} orientation {use_ori} covariance {covariance} offset {offset}: worst {:.2e} at row {row}, candidate {}",
        model.name(),
        report.max_error,
        layout.names[col]
    );
    report
        .assert_below(
            TOLERANCE,
            &format!("{}: orientation {use_ori}, covariance {covariance}, offset {offset}", model.name()),
        )
        .unwrap();
    report.max_error
}

#[test]
fn kinematic_residual_passes_the_gradient_checker() {
    let ur5 = ferrocal_robot::presets::preset("ur5").unwrap();
    for offset in [0.0, 0.003, 0.3] {
        for (use_ori, covariance) in [(false, false), (true, false), (false, true), (true, true)] {
            check(&ur5, use_ori, covariance, Vec::new(), offset);
        }
    }
}

/// Another arm (from a URDF, not a UR geometry).
#[test]
fn kinematic_residual_of_other_robots_passes_the_gradient_checker() {
    let text = include_str!("../../../robot/models/example_arm6.urdf");
    let arm = RobotModel::Serial(
        ferrocal_robot::serial::parse_urdf_str(text, &Default::default()).expect("example_arm6.urdf"),
    );
    for offset in [0.0, 0.3] {
        check(&arm, true, true, Vec::new(), offset);
        check(&arm, false, false, Vec::new(), offset);
    }
}

#[test]
fn kinematic_residual_with_effects_passes_the_gradient_checker() {
    let ur5 = ferrocal_robot::presets::preset("ur5").unwrap();
    let effects = vec![
        EffectSpec::JointScaleError { joint: 2 },
        EffectSpec::PeriodicJointError { joint: 3, period_si: std::f64::consts::PI },
        EffectSpec::ThermalExpansion { reference_temp_c: 20.0 },
        EffectSpec::CoupledTransmission { joint: 5, driver: 4 },
    ];
    for offset in [0.0, 0.3] {
        check(&ur5, false, false, effects.clone(), offset);
        check(&ur5, true, true, effects.clone(), offset);
    }
    // Effects that move the predicted pose rigidly (axis misalignment, link compliance): their
    // own columns are central differences, exact at any value; the analytic columns of the
    // geometry leave the pose correction's rotation out (relative error of the order of the
    // tilt: 1.2e-4 at tilts of 3e-5 rad), which slows the iterations a little but does not move
    // the optimum. Exact at zero tilt:
    let mut with_pose = effects.clone();
    with_pose.push(EffectSpec::AxisMisalignment { joint: 3 });
    check(&ur5, false, false, with_pose.clone(), 0.0);
    check(&ur5, true, true, with_pose, 0.0);
}
