//! Parallel robots: unreachable poses, non-converging forward kinematics and bad inputs give the
//! right error with a useful message, never a panic.

use ferrocal_robot::geometry::pose_from_vectors;
use ferrocal_robot::parallel::presets::{gantry_tau_f1, gantry_tau_l1, gantry_tau_l1_6link, hexapod};
use ferrocal_robot::parallel::{Branch, ParallelRobot, SolverOptions};
use ferrocal_robot::{Kinematics, Pose, RobotError};
use nalgebra::Vector3;

fn at(x: f64, y: f64, z: f64) -> Pose {
    pose_from_vectors(&Vector3::new(x, y, z), &Vector3::zeros())
}

#[test]
fn gantry_tau3_unreachable_names_the_arm() {
    let k = gantry_tau_l1();
    // 3 m below guideway 1: farther than any link.
    match k.inverse(&at(0.0, 3.5, -3.0), &[]) {
        Err(RobotError::Unreachable { reason }) => {
            assert!(reason.contains("arm 1") && reason.contains("link length"), "{reason}")
        }
        other => panic!("expected Unreachable, got {other:?}"),
    }
    // Reachable by the links but the carts would leave their travel.
    match k.inverse(&at(-2.5, 2.7, -0.6), &[]) {
        Err(RobotError::OutsideLimits { joint, name, .. }) => assert!(joint >= 1 && name.starts_with("cart")),
        other => panic!("expected OutsideLimits, got {other:?}"),
    }
    // A model working in the other assembly mode cannot take a pose of this one.
    let mut other = gantry_tau_l1();
    other.assembly = Branch::Minus;
    let t0 = k.forward(&[0.0; 3]).unwrap();
    match other.inverse(&t0, &[]) {
        Err(RobotError::Unreachable { reason }) => assert!(reason.contains("assembly mode"), "{reason}"),
        other => panic!("expected Unreachable (assembly mode), got {other:?}"),
    }
    // Carts so far apart that the three link spheres miss each other.
    match k.forward(&[3.0, -3.0, 0.0]) {
        Err(RobotError::Unreachable { reason }) => assert!(reason.contains("do not meet"), "{reason}"),
        other => panic!("expected Unreachable, got {other:?}"),
    }
    // Cart positions that put an arm on the other branch.
    let mut found = None;
    'grid: for a in [-1.0, -0.5, 0.0, 0.5, 1.0] {
        for b in [-1.0, -0.5, 0.0, 0.5, 1.0] {
            for c in [-1.0, -0.5, 0.0, 0.5, 1.0] {
                if let Err(RobotError::Unreachable { reason }) = k.forward(&[a, b, c]) {
                    if reason.contains("configuration") {
                        found = Some(reason);
                        break 'grid;
                    }
                }
            }
        }
    }
    let reason = found.expect("some cart combination within the travel breaks a branch");
    assert!(reason.contains("arm ") && reason.contains("'plus'"), "{reason}");
}

#[test]
fn six_link_and_f1_unreachable() {
    let k = gantry_tau_l1_6link();
    match k.inverse(&at(0.0, 3.5, -3.0), &[]) {
        Err(RobotError::Unreachable { reason }) => assert!(reason.contains("arm 1"), "{reason}"),
        other => panic!("expected Unreachable, got {other:?}"),
    }
    assert!(matches!(k.forward(&[3.0, -3.0, 0.0]), Err(RobotError::Unreachable { .. })));
    let f1 = gantry_tau_f1();
    let home = f1.forward(&[0.0; 6]).unwrap();
    match f1.inverse(&(at(0.0, 0.0, 2.5) * home), &[]) {
        Err(RobotError::Unreachable { reason }) => assert!(reason.contains("arm"), "{reason}"),
        other => panic!("expected Unreachable, got {other:?}"),
    }
    // Beyond the plates' limits.
    let tilted = pose_from_vectors(&home.translation.vector, &Vector3::new(0.0, 0.0, 0.4));
    assert!(matches!(f1.inverse(&tilted, &[]), Err(RobotError::OutsideLimits { .. })));
}

#[test]
fn forward_kinematics_failures_are_reported() {
    let hex = hexapod();
    // Leg 1 nearly zero, leg 2 3 m: their joint centres cannot be placed (triangle inequality).
    match hex.forward(&[-0.84, 2.0, 0.0, 0.0, 0.0, 0.0]) {
        Err(RobotError::FkNotConverged { reason }) => assert!(reason.contains("home"), "{reason}"),
        other => panic!("expected FkNotConverged, got {other:?}"),
    }
    // A start in the mirrored assembly mode (platform below the base) converges there and is
    // rejected by the guard.
    let m = hex.mechanism().unwrap();
    let mirrored = at(0.0, 0.0, -0.8);
    match m.solve_pose(&[0.0; 6], &mirrored, &SolverOptions::default()) {
        Err(RobotError::FkNotConverged { reason }) => assert!(reason.contains("assembly mode"), "{reason}"),
        other => panic!("expected FkNotConverged, got {other:?}"),
    }
    // Iteration budget exhausted.
    let opts = SolverOptions { max_iterations: 1, ..SolverOptions::default() };
    let start = at(0.1, 0.0, 0.7);
    match m.solve_pose(&[0.05; 6], &start, &opts) {
        Err(RobotError::FkNotConverged { reason }) => assert!(reason.contains("iterations"), "{reason}"),
        other => panic!("expected FkNotConverged, got {other:?}"),
    }
    // The six-link model with an impossible cart combination.
    let six = gantry_tau_l1_6link();
    let m6 = six.mechanism().unwrap();
    let start = m6.cluster_start(&[0.0; 3], Branch::Plus).unwrap();
    assert!(matches!(m6.solve_pose(&[3.0, -3.0, 0.0], &start, &six.solver), Err(RobotError::FkNotConverged { .. })));
}

#[test]
fn bad_inputs_never_panic() {
    let l1 = gantry_tau_l1();
    assert!(matches!(l1.forward(&[0.0, 0.0]), Err(RobotError::JointCount { expected: 3, got: 2 })));
    assert!(matches!(l1.forward(&[0.0, f64::NAN, 0.0]), Err(RobotError::BadParameter { .. })));
    assert!(l1.inverse(&at(f64::NAN, 0.0, 0.0), &[]).is_err());
    assert!(l1.jacobian(&[f64::INFINITY, 0.0, 0.0]).is_err());
    let six = gantry_tau_l1_6link();
    assert!(six.forward(&[0.0; 4]).is_err());
    assert!(six.inverse(&at(f64::NAN, 0.0, 0.0), &[]).is_err());
    let f1 = gantry_tau_f1();
    assert!(f1.forward(&[0.0; 3]).is_err());
    assert!(f1.inverse(&at(f64::INFINITY, 0.0, 0.0), &[1.0]).is_err());
    assert!(f1.constraint_residuals(&[0.0; 5], &Pose::identity()).is_err());
    let hex = hexapod();
    assert!(hex.forward(&[0.0, 0.0, 0.0, 0.0, 0.0, f64::NAN]).is_err());
    assert!(hex.inverse(&at(0.0, 0.0, f64::NAN), &[]).is_err());
    // A platform below the base is outside the home assembly mode.
    assert!(matches!(hex.inverse(&at(0.0, 0.0, -0.8), &[]), Err(RobotError::Unreachable { .. })));

    // Models broken through their public fields report errors instead of panicking.
    let mut broken = gantry_tau_f1();
    broken.links.pop();
    assert!(matches!(broken.forward(&[0.0; 6]), Err(RobotError::BadParameter { .. })));
    let mut broken = hexapod();
    broken.legs[2].length0_m = f64::NAN;
    assert!(broken.forward(&[0.0; 6]).is_err());
    let mut broken = gantry_tau_l1();
    broken.arms[1].v = Vector3::zeros();
    assert!(broken.inverse(&at(0.0, 2.7, -0.6), &[]).is_err());
    let mut broken = gantry_tau_l1_6link();
    broken.links[0].arm = 2;
    assert!(broken.jacobian(&[0.0; 3]).is_err());
    let mut m = hexapod().mechanism().unwrap();
    m.legs[0].carriage = Some(7);
    assert!(m.residuals(&[0.0; 6], &Pose::identity()).is_err());
}
