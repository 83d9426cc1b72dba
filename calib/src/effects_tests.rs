//! Tests of the compliance equilibrium.

use ferrocal_robot::serial::{parse_urdf_str, UrdfOptions};
use ferrocal_robot::RobotModel;

use super::*;

/// A two-link arm in the x-z plane (pitch axes along y), 3 and 2 kg, 0.5 m links; joint 2 has
/// a mimic joint 0.3 m further (`q = 0.5 q2`) carrying 1 kg.
fn arm() -> RobotModel {
    let link = |n: &str, m: f64, x: f64| {
        format!("<link name=\"{n}\"><inertial><origin xyz=\"{x} 0 0\"/><mass value=\"{m}\"/></inertial></link>")
    };
    let joint = |n: &str, p: &str, c: &str, x: f64, extra: &str| {
        format!(
            "<joint name=\"{n}\" type=\"revolute\"><parent link=\"{p}\"/><child link=\"{c}\"/><origin xyz=\"{x} 0 0\"/><axis xyz=\"0 1 0\"/><limit lower=\"-3\" upper=\"3\"/>{extra}</joint>"
        )
    };
    let text = format!(
        "<robot name=\"arm\"><link name=\"base\"/>{}{}{}{}{}{}</robot>",
        link("l1", 3.0, 0.25),
        link("l2", 2.0, 0.15),
        link("l3", 1.0, 0.1),
        joint("j1", "base", "l1", 0.0, ""),
        joint("j2", "l1", "l2", 0.5, ""),
        joint("j3", "l2", "l3", 0.3, "<mimic joint=\"j2\" multiplier=\"0.5\"/>"),
    );
    RobotModel::Serial(parse_urdf_str(&text, &UrdfOptions::default()).unwrap())
}

#[test]
fn the_equilibrium_holds_the_load_where_the_joint_deflects_to() {
    let model = arm();
    let q0 = [0.3, -0.4];
    // About 14 mrad of sag at joint 1 (holding torque about 28 N m).
    let c = [5e-4, 2e-3];
    let q = compliance_equilibrium(&model, &q0, &c, 0.0).unwrap();
    let tau = holding_torques(&model, &q, 0.0).unwrap();
    for j in 0..2 {
        assert!((q[j] - (q0[j] - c[j] * tau[j])).abs() < 1e-11, "joint {}: not at the equilibrium", j + 1);
    }
    let sag = (q0[0] - q[0]).abs();
    assert!(sag > 0.01 && sag < 0.04, "sag {sag}");
    // The one-step deflection (torque at the commanded angle) differs at second order.
    let one_step = q0[0] - c[0] * holding_torques(&model, &q0, 0.0).unwrap()[0];
    let d = (one_step - q[0]).abs();
    assert!(d > 1e-5 && d < 0.1 * sag, "one-step differs by {d:e}");
    // The sensitivity (I + C K)^-1 is the derivative of the solution.
    let m = equilibrium_sensitivity(&model, &q, &c, 0.0).unwrap();
    let h = 1e-6;
    for k in 0..2 {
        let (mut a, mut b) = (q0, q0);
        a[k] += h;
        b[k] -= h;
        let (qa, qb) = (
            compliance_equilibrium(&model, &a, &c, 0.0).unwrap(),
            compliance_equilibrium(&model, &b, &c, 0.0).unwrap(),
        );
        for j in 0..2 {
            let num = (qa[j] - qb[j]) / (2.0 * h);
            assert!((m[(j, k)] - num).abs() < 1e-6, "d q{} / d q0_{}: {} vs {num}", j + 1, k + 1, m[(j, k)]);
        }
    }
    // No compliance: the readings unchanged.
    assert_eq!(compliance_equilibrium(&model, &q0, &[0.0, 0.0], 0.0).unwrap(), q0);
}

#[test]
fn a_joint_too_soft_to_hold_its_load_is_named() {
    let model = arm();
    let e = compliance_equilibrium(&model, &[0.3, -0.4], &[0.0, 2.0], 0.0).unwrap_err();
    assert!(matches!(e, CalibError::Equilibrium { joint: 2, .. }), "{e}");
    let s = e.to_string();
    assert!(s.contains("joint 2 ('j2')") && s.contains("must be below 1"), "{s}");
}

#[test]
fn compliance_effects_index_the_actuated_joints() {
    let model = arm();
    assert_eq!(model.dof(), 2);
    let effects = vec![
        (EffectSpec::JointCompliance { joint: 2 }, vec![1e-3]),
        (EffectSpec::JointCompliance { joint: 2 }, vec![1e-3]),
    ];
    assert_eq!(compliances(&effects, 2).unwrap(), [0.0, 2e-3]);
    assert!(compliances(&[(EffectSpec::JointCompliance { joint: 3 }, vec![1e-3])], 2).is_err());
    // The mimic joint's torque reaches its leader times the multiplier.
    let RobotModel::Serial(chain) = &model else { unreachable!() };
    let q = [0.2, 0.7];
    let all = chain.gravity_torques_all(&q, 0.0).unwrap();
    let tau = holding_torques(&model, &q, 0.0).unwrap();
    assert!((tau[1] - (all[1] + 0.5 * all[2])).abs() < 1e-12);
}

#[test]
fn an_equilibrium_the_plain_iteration_overshoots_is_solved_by_newton() {
    // Where joint 2's links hang below its axis, gravity stiffens it (K > 0); a compliance with
    // c K = 1.4 makes `q <- q0 - c tau(q)` overshoot with a growing amplitude, while the
    // equilibrium exists and is stable (1 + c K > 0: the potential plus the spring is convex).
    let model = arm();
    let h = 1e-6;
    let k22 = |q2: f64| {
        (holding_torques(&model, &[0.0, q2 + h], 0.0).unwrap()[1]
            - holding_torques(&model, &[0.0, q2 - h], 0.0).unwrap()[1])
            / (2.0 * h)
    };
    let q2 = [-2.5, -1.2, 1.2, 2.5].into_iter().find(|&q| k22(q) > 1.0).expect("a hanging configuration");
    let q0 = [0.0, q2];
    let c = [0.0, 1.4 / k22(q2)];
    let q = compliance_equilibrium(&model, &q0, &c, 0.0).unwrap();
    let tau = holding_torques(&model, &q, 0.0).unwrap();
    assert!((q[1] - (q0[1] - c[1] * tau[1])).abs() < 1e-11, "not at the equilibrium: {q:?}");
    assert!((q[1] - q0[1]).abs() < EQUILIBRIUM_MAX_DEFLECTION, "{q:?}");
}
