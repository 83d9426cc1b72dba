//! The kinematic calibration's residual Jacobian through the least-squares layer's gradient
//! checker: analytic columns (device frame, tool, joint offsets, a serial chain's correction
//! transforms) and numeric ones (effects, other model parameters) against central differences of
//! the residuals, with scalar sigmas and with full 6 x 6 covariances, positions only and full poses.
//!
//! The analytic columns are exact where the solver linearises first, at zero increments of the
//! device frame, the tool and the corrections (the registration `f0` may be any pose); the
//! orientation rows are first order in the residual rotation (the inverse right Jacobian of the
//! residual is taken as identity), hence their looser tolerance. Away from zero increments the
//! frame, tool and correction columns are first-order (see the second test).

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
            if covariance {
                let a = Matrix6::from_fn(|r, c| wave(36 * i + 6 * r + c) * 1e-4);
                let si = a * a.transpose() + Matrix6::from_diagonal(&nalgebra::Vector6::repeat(1e-9));
                row.covariance = Some(PoseCovariance::Pose { si });
            }
            row
        })
        .collect()
}

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
    if offset == 0.0 {
        let tolerance = if use_ori { 3e-3 } else { 1e-6 };
        report
            .assert_below(tolerance, &format!("{}: orientation {use_ori}, covariance {covariance}", model.name()))
            .unwrap();
    }
    if offset > 0.0 {
        let (_, row, col) = report.worst;
        eprintln!("offset {offset}: worst {:.2e} at row {row}, candidate {}", report.max_error, layout.names[col]);
    }
    report.max_error
}

#[test]
fn kinematic_residual_passes_the_gradient_checker() {
    let ur5 = ferrocal_robot::presets::preset("ur5").unwrap();
    for (use_ori, covariance) in [(false, false), (true, false), (false, true), (true, true)] {
        check(&ur5, use_ori, covariance, Vec::new(), 0.0);
    }
    let effects = vec![
        EffectSpec::JointScaleError { joint: 2 },
        EffectSpec::PeriodicJointError { joint: 3, period_si: std::f64::consts::PI },
    ];
    check(&ur5, false, false, effects.clone(), 0.0);
    check(&ur5, true, true, effects, 0.0);
}

/// What the checker finds away from zero increments: the frame, tool and correction columns are
/// linearisations at zero increment, so their error grows with the increments (this records the
/// size; the solver re-linearises at every iterate, and with equal weights the device frame's
/// translation columns make the frame-rotation error term vanish at the optimum).
#[test]
fn kinematic_jacobian_away_from_zero_increments_is_first_order() {
    let ur5 = ferrocal_robot::presets::preset("ur5").unwrap();
    let small = check(&ur5, false, false, Vec::new(), 0.003);
    let large = check(&ur5, false, false, Vec::new(), 0.3);
    eprintln!("kinematic Jacobian away from zero increments: {small:.2e} at 0.003 scales, {large:.2e} at 0.3 scales");
    assert!(small < large, "small {small:.2e} large {large:.2e}");
    assert!(large > 1e-6, "{large:.2e}: the columns became exact; tighten the first test and drop this one");
}
