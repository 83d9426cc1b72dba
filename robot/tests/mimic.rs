//! Coupled (URDF `<mimic>`) joints: parsing, refusals, forward kinematics against a hand-computed
//! pose, Jacobian and gravity torques against finite differences, parameters, and the round trips
//! through `to_urdf` and serde.

use ferrocal_robot::serial::{parse_urdf_str, to_urdf, SerialChain, UrdfFrames, UrdfOptions};
use ferrocal_robot::{Kinematics, Parameterized};

/// A planar arm about z: `j1` at the base, `j2` (mimic of `j1`: `q2 = m q1 + o`) 0.5 m out,
/// `j3` 0.3 m further, the tool 0.2 m beyond `j3`; links with 2, 1.5 and 1 kg at their middles.
fn arm(mimic: &str) -> String {
    format!(
        r#"<robot name="coupled">
  <link name="base"/>
  <link name="l1"><inertial><origin xyz="0.25 0 0"/><mass value="2"/></inertial></link>
  <link name="l2"><inertial><origin xyz="0.15 0 0"/><mass value="1.5"/></inertial></link>
  <link name="l3"><inertial><origin xyz="0.1 0 0"/><mass value="1"/></inertial></link>
  <link name="tool"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0" rpy="0 0 0"/><axis xyz="0 0 1"/><limit lower="-3" upper="3"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="0.5 0 0" rpy="0 0 0"/><axis xyz="0 0 1"/><limit lower="-3" upper="3"/>
    {mimic}</joint>
  <joint name="j3" type="revolute"><parent link="l2"/><child link="l3"/>
    <origin xyz="0.3 0 0" rpy="0 0 0"/><axis xyz="0 0 1"/><limit lower="-3" upper="3"/></joint>
  <joint name="tip" type="fixed"><parent link="l3"/><child link="tool"/><origin xyz="0.2 0 0"/></joint>
</robot>
"#
    )
}

const MIMIC: &str = r#"<mimic joint="j1" multiplier="-0.5" offset="0.1"/>"#;

fn parse(text: &str) -> SerialChain {
    parse_urdf_str(text, &UrdfOptions::default()).unwrap()
}

#[test]
fn mimic_is_parsed_with_leader_multiplier_and_offset() {
    let c = parse(&arm(MIMIC));
    assert_eq!(c.joints.len(), 3);
    assert_eq!(c.dof(), 2);
    assert_eq!(c.joint_names(), ["j1", "j3"]);
    assert_eq!(c.joint_limits().len(), 2);
    let m = c.joints[1].mimic.as_ref().expect("j2 is a mimic joint");
    assert_eq!(m.leader, "j1");
    assert_eq!(m.multiplier, -0.5);
    assert_eq!(m.offset, 0.1);
    assert_eq!(c.actuated_indices(), [0, 2]);
    // Defaults: multiplier 1, offset 0.
    let d = parse(&arm(r#"<mimic joint="j1"/>"#));
    let m = d.joints[1].mimic.as_ref().unwrap();
    assert_eq!((m.multiplier, m.offset), (1.0, 0.0));
}

#[test]
fn mimic_refusals_name_the_joint_and_the_file_position() {
    let err = |t: &str| parse_urdf_str(t, &UrdfOptions::default()).unwrap_err().to_string();
    let e = err(&arm(r#"<mimic joint="j9" multiplier="2"/>"#));
    assert!(e.contains("joint 'j2' mimics joint 'j9', which is not defined") && e.starts_with("<string>:"), "{e}");
    // j2 follows j3, which is itself a mimic of j1: chained mimics are refused.
    let text = arm(r#"<mimic joint="j3"/>"#).replace(
        r#"<limit lower="-3" upper="3"/></joint>
  <joint name="tip""#,
        r#"<limit lower="-3" upper="3"/><mimic joint="j1"/></joint>
  <joint name="tip""#,
    );
    let e = err(&text);
    assert!(e.contains("joint 'j2' mimics joint 'j3', which is itself a mimic joint (of 'j1')"), "{e}");
    // The leader is the fixed joint.
    let e = err(&arm(r#"<mimic joint="tip"/>"#));
    assert!(e.contains("joint 'j2' mimics joint 'tip', which is fixed"), "{e}");
    // A mimic without a leader.
    let e = err(&arm(r#"<mimic multiplier="2"/>"#));
    assert!(e.contains("joint 'j2': <mimic> needs a 'joint' attribute"), "{e}");
    // A chain read from JSON with a leader that is not there.
    let mut c = parse(&arm(MIMIC));
    c.joints[1].mimic.as_mut().unwrap().leader = "nope".into();
    let e = c.forward(&[0.1, 0.2]).unwrap_err().to_string();
    assert!(e.contains("joint 'j2': its leader 'nope' is not a joint of the chain"), "{e}");
}

/// The hand-computed tool pose of [`arm`]: planar angles `a1 = q1`, `a2 = a1 + (m q1 + o)`,
/// `a3 = a2 + q3`; position `0.5 (cos a1, sin a1) + 0.3 (cos a2, sin a2) + 0.2 (cos a3, sin a3)`.
fn hand_fk(q1: f64, q3: f64, m: f64, o: f64) -> ([f64; 2], f64) {
    let a1 = q1;
    let a2 = a1 + m * q1 + o;
    let a3 = a2 + q3;
    let x = 0.5 * a1.cos() + 0.3 * a2.cos() + 0.2 * a3.cos();
    let y = 0.5 * a1.sin() + 0.3 * a2.sin() + 0.2 * a3.sin();
    ([x, y], a3)
}

#[test]
fn forward_kinematics_moves_the_mimic_joint_by_its_coupled_angle() {
    let c = parse(&arm(MIMIC));
    for (q1, q3) in [(0.0, 0.0), (0.7, -0.4), (-1.3, 2.1)] {
        let t = c.forward(&[q1, q3]).unwrap();
        let ([x, y], yaw) = hand_fk(q1, q3, -0.5, 0.1);
        let p = t.translation.vector;
        assert!((p.x - x).abs() < 1e-14 && (p.y - y).abs() < 1e-14 && p.z.abs() < 1e-14, "{p:?} vs {x} {y}");
        let (_, _, got_yaw) = t.rotation.euler_angles();
        let d = (got_yaw - yaw).rem_euclid(std::f64::consts::TAU);
        assert!(d.min(std::f64::consts::TAU - d) < 1e-13, "yaw {got_yaw} vs {yaw}");
        let all = c.all_joint_values(&[q1, q3]).unwrap();
        assert_eq!(all, [q1, -0.5 * q1 + 0.1, q3]);
    }
    // Without the mimic the same file has three actuated joints; with j2 = m q1 + o given as a
    // reading it is the same pose.
    let free = parse(&arm(""));
    let (q1, q3) = (0.3, -0.8);
    let a = c.forward(&[q1, q3]).unwrap();
    let b = free.forward(&[q1, -0.5 * q1 + 0.1, q3]).unwrap();
    assert!((a.translation.vector - b.translation.vector).norm() < 1e-15);
}

#[test]
fn jacobian_and_gravity_torques_are_over_the_actuated_joints() {
    let c = parse(&arm(MIMIC));
    let q = [0.4, -0.9];
    let jac = c.jacobian(&q).unwrap();
    assert_eq!(jac.shape(), (6, 2));
    let h = 1e-6;
    for k in 0..2 {
        let (mut qp, mut qm) = (q, q);
        qp[k] += h;
        qm[k] -= h;
        let d = (c.forward(&qp).unwrap().translation.vector - c.forward(&qm).unwrap().translation.vector) / (2.0 * h);
        for r in 0..3 {
            assert!((jac[(r, k)] - d[r]).abs() < 1e-8, "column {k} row {r}: {} vs {}", jac[(r, k)], d[r]);
        }
    }
    // Gravity along -y (the arm's plane) so that the torques are not zero: the holding torque
    // is the gradient of the potential energy `V = -sum m g . p` in the actuated coordinates.
    let mut c = c;
    c.gravity_m_s2 = [0.0, -9.81, 0.0];
    let energy = |q: &[f64]| -> f64 {
        let f = c.frames(q).unwrap();
        let g = nalgebra::Vector3::from(c.gravity_m_s2);
        c.joints
            .iter()
            .zip(&f.links)
            .map(|(j, l)| {
                let inr = j.inertial.as_ref().unwrap();
                -inr.mass_kg * g.dot(&(l * nalgebra::Point3::from(inr.com_m)).coords)
            })
            .sum()
    };
    let tau = c.gravity_torques(&q, 0.0).unwrap();
    let all = c.gravity_torques_all(&q, 0.0).unwrap();
    assert_eq!((tau.len(), all.len()), (2, 3));
    for k in 0..2 {
        let (mut qp, mut qm) = (q, q);
        qp[k] += h;
        qm[k] -= h;
        let d = (energy(&qp) - energy(&qm)) / (2.0 * h);
        assert!((tau[k] - d).abs() < 1e-6 * (1.0 + d.abs()), "joint {k}: {} vs dV/dq {d}", tau[k]);
    }
    // The leader's drive carries its own torque plus the multiplier times the mimic joint's.
    assert!((tau[0] - (all[0] - 0.5 * all[1])).abs() < 1e-12);
    assert_eq!(tau[1], all[2]);
}

#[test]
fn parameters_name_the_mimic_joint_and_its_coupling() {
    let mut c = parse(&arm(MIMIC));
    let p = c.parameters();
    let names: Vec<&str> = p.iter().map(|p| p.name.as_str()).collect();
    assert!(names.contains(&"joint2.x_m") && names.contains(&"mimic1.x_m") && names.contains(&"mimic1.corr_rz_rad"));
    let k = names.iter().position(|n| *n == "mimic1.coupling").expect("coupling parameter");
    assert_eq!(p[k].value, -0.5);
    assert_eq!(c.joint_of_parameter("mimic1.corr_x_m"), Some(1));
    assert_eq!(c.joint_of_parameter("joint2.corr_x_m"), Some(2));
    assert_eq!(c.joint_of_parameter("joint1.x_m"), Some(0));
    let mut v = c.parameter_values();
    v[k] = -0.49;
    c.set_parameter_values(&v).unwrap();
    assert_eq!(c.joints[1].mimic.as_ref().unwrap().multiplier, -0.49);
    assert_eq!(c.parameter_values(), v);
    // A chain without mimic joints keeps its names.
    let free = parse(&arm(""));
    assert!(free.parameters().iter().all(|p| !p.name.starts_with("mimic")));
    assert!(free.parameters().iter().any(|p| p.name == "joint3.corr_x_m"));
}

#[test]
fn to_urdf_and_serde_round_trip_the_coupling() {
    let mut c = parse(&arm(MIMIC));
    c.joints[1].correction = [1e-3, -2e-3, 0.5e-3, 2e-3, -1e-3, 3e-3];
    c.joints[2].correction = [-1e-3, 0.0, 1e-3, 0.0, 1e-3, -2e-3];
    let offsets = [0.01, -0.02];
    let text = to_urdf(&c, &offsets, &UrdfFrames::default(), "test").unwrap();
    assert!(text.contains(r#"<mimic joint="j1" multiplier="-0.5" offset="0.1"/>"#), "{text}");
    let back = parse(&text);
    assert_eq!(back.dof(), 2);
    for (q1, q3) in [(0.0, 0.0), (0.7, -0.4), (-1.3, 2.1)] {
        let want = c.forward(&[q1 + offsets[0], q3 + offsets[1]]).unwrap();
        let got = back.forward(&[q1, q3]).unwrap();
        assert!((got.translation.vector - want.translation.vector).norm() < 1e-12);
        assert!(got.rotation.angle_to(&want.rotation) < 1e-12);
    }
    let json = serde_json::to_string(&c).unwrap();
    let again: SerialChain = serde_json::from_str(&json).unwrap();
    assert_eq!(again, c);
    // Chains without mimic joints serialise as before (no `mimic` key).
    let free = serde_json::to_string(&parse(&arm(""))).unwrap();
    assert!(!free.contains("mimic"), "{free}");
}

#[test]
fn inverse_kinematics_solves_for_the_actuated_joints() {
    let c = parse(&arm(MIMIC));
    let target = c.forward(&[0.6, -0.7]).unwrap();
    let q = c.inverse(&target, &[0.5, -0.5]).unwrap();
    let t = c.forward(&q).unwrap();
    assert_eq!(q.len(), 2);
    assert!((t.translation.vector - target.translation.vector).norm() < 1e-9, "{q:?}");
}
