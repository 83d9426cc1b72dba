//! Serial chains: forward/inverse round trips, Jacobians against finite differences, gravity
//! torques against the potential energy, URDF import and its error messages.

use std::f64::consts::PI;

use ferrocal_robot::geometry::pose_error;
use ferrocal_robot::serial::{parse_urdf, parse_urdf_str, Joint, JointGeometry, SerialChain, UrdfOptions};
use ferrocal_robot::{presets, JointKind, JointLimits, Kinematics, Parameterized, Pose, RobotError};
use nalgebra::{Point3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn example_urdf() -> SerialChain {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models/example_arm6.urdf");
    parse_urdf(&path, &UrdfOptions::default()).expect("example URDF parses")
}

fn mdh_arm() -> SerialChain {
    // A 6-axis arm in the modified DH convention, with one Hayati beta.
    let mut c = SerialChain::from_mdh(
        "mdh6",
        &[0.0, 0.15, 0.6, 0.12, 0.0, 0.0],
        &[0.0, -PI / 2.0, 0.0, -PI / 2.0, PI / 2.0, -PI / 2.0],
        &[0.45, 0.0, 0.0, 0.62, 0.0, 0.1],
        &[0.0, -PI / 2.0, 0.0, 0.0, 0.0, 0.0],
    )
    .with_limits(-PI, PI)
    .unwrap();
    if let JointGeometry::Mdh { beta_rad, .. } = &mut c.joints[2].geometry {
        *beta_rad = 0.002;
    }
    c.tool = Pose::translation(0.01, -0.02, 0.05);
    // Small per-joint corrections, as a calibration would identify them.
    c.joints[1].correction = [0.0004, -0.0002, 0.0003, 0.001, -0.0007, 0.0005];
    c.joints[4].correction = [-0.0003, 0.0001, 0.0002, -0.0004, 0.0009, 0.0002];
    c
}

fn prismatic_arm() -> SerialChain {
    // A SCARA-like arm with a prismatic third axis (standard DH).
    let mut c =
        SerialChain::from_dh("scara", &[0.4, 0.3, 0.0, 0.0], &[0.0, PI, 0.0, 0.0], &[0.3, 0.0, 0.0, 0.05], &[0.0; 4]);
    c.joints[2].kind = JointKind::Prismatic;
    for (j, (lo, hi)) in c.joints.iter_mut().zip([(-2.5, 2.5), (-2.5, 2.5), (0.0, 0.3), (-PI, PI)]) {
        j.limits = JointLimits::new(&j.name, lo, hi).unwrap();
    }
    c
}

fn ur5_with_base_and_tool() -> SerialChain {
    let mut c = presets::ur5();
    c.base = Pose::new(Vector3::new(1.2, -0.3, 0.4), Vector3::new(0.01, -0.02, 0.3));
    c.tool = Pose::new(Vector3::new(0.0, 0.0001, 0.031), Vector3::new(0.0, 0.0, 0.2));
    c
}

fn all_models() -> Vec<SerialChain> {
    vec![ur5_with_base_and_tool(), presets::ur10(), example_urdf(), mdh_arm(), prismatic_arm()]
}

fn random_q(c: &SerialChain, rng: &mut ChaCha8Rng) -> Vec<f64> {
    c.joints
        .iter()
        .map(|j| {
            let (lo, hi) = (j.limits.lower.max(-PI), j.limits.upper.min(PI));
            rng.random_range(lo..hi)
        })
        .collect()
}

fn min_singular_value(c: &SerialChain, q: &[f64]) -> f64 {
    let j = c.jacobian(q).unwrap();
    let s = j.svd(false, false).singular_values;
    s.iter().copied().fold(f64::INFINITY, f64::min)
}

fn angle_diff(a: f64, b: f64) -> f64 {
    ferrocal_robot::geometry::wrap_angle(a - b).abs()
}

#[test]
fn forward_inverse_round_trips_on_thousands_of_poses() {
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    for c in all_models() {
        let (mut worst_m, mut worst_rad, mut worst_q) = (0.0f64, 0.0f64, 0.0f64);
        let mut n = 0;
        while n < 2000 {
            let q = random_q(&c, &mut rng);
            // Round trips are unique only away from singular configurations.
            if min_singular_value(&c, &q) < 0.05 {
                continue;
            }
            let target = c.forward(&q).unwrap();
            let seed: Vec<f64> = q.iter().map(|v| v + rng.random_range(-0.05..0.05)).collect();
            let seed: Vec<f64> =
                seed.iter().zip(&c.joints).map(|(v, j)| v.clamp(j.limits.lower, j.limits.upper)).collect();
            let sol = c.inverse(&target, &seed).unwrap_or_else(|e| panic!("{}: {e} at q = {q:?}", c.name));
            let back = c.forward(&sol).unwrap();
            let e = pose_error(&target, &back);
            worst_m = worst_m.max(e.fixed_rows::<3>(0).norm());
            worst_rad = worst_rad.max(e.fixed_rows::<3>(3).norm());
            for ((a, b), j) in sol.iter().zip(&q).zip(&c.joints) {
                let d = match j.kind {
                    JointKind::Revolute => angle_diff(*a, *b),
                    JointKind::Prismatic => (a - b).abs(),
                };
                worst_q = worst_q.max(d);
            }
            n += 1;
        }
        eprintln!("{}: worst pose error {worst_m:.2e} m, {worst_rad:.2e} rad; worst joint error {worst_q:.2e}", c.name);
        assert!(worst_m < 1e-9 && worst_rad < 1e-9, "{}: {worst_m:e} m {worst_rad:e} rad", c.name);
        assert!(worst_q < 1e-9, "{}: joint error {worst_q:e}", c.name);
    }
}

#[test]
fn jacobians_match_central_differences() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    for c in all_models() {
        let mut worst: f64 = 0.0;
        for _ in 0..200 {
            let q = random_q(&c, &mut rng);
            let jac = c.jacobian(&q).unwrap();
            let h = 1e-6;
            for i in 0..c.dof() {
                let mut qp = q.clone();
                let mut qm = q.clone();
                qp[i] += h;
                qm[i] -= h;
                let (tp, tm) = (c.forward(&qp).unwrap(), c.forward(&qm).unwrap());
                let dp = (tp.translation.vector - tm.translation.vector) / (2.0 * h);
                let dr = (tp.rotation * tm.rotation.inverse()).scaled_axis() / (2.0 * h);
                let col = jac.column(i);
                let scale = col.norm().max(1.0);
                let err = ((dp - col.fixed_rows::<3>(0)).norm() + (dr - col.fixed_rows::<3>(3)).norm()) / scale;
                worst = worst.max(err);
            }
        }
        eprintln!("{}: worst Jacobian mismatch {worst:.2e} (relative)", c.name);
        assert!(worst < 1e-6, "{}: {worst:e}", c.name);
    }
}

fn potential_energy(c: &SerialChain, q: &[f64], payload_kg: f64) -> f64 {
    let f = c.frames(q).unwrap();
    let g = Vector3::from(c.gravity_m_s2);
    let mut v = 0.0;
    for (i, j) in c.joints.iter().enumerate() {
        if let Some(inr) = &j.inertial {
            let p = f.links[i] * Point3::from(inr.com_m);
            v -= inr.mass_kg * g.dot(&p.coords);
        }
    }
    v - payload_kg * g.dot(&f.tool.translation.vector)
}

#[test]
fn gravity_torques_are_the_gradient_of_potential_energy() {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    for c in [presets::ur5(), presets::ur10(), example_urdf()] {
        for _ in 0..100 {
            let q = random_q(&c, &mut rng);
            let payload = rng.random_range(0.0..5.0);
            let tau = c.gravity_torques(&q, payload).unwrap();
            for i in 0..c.dof() {
                let h = 1e-6;
                let mut qp = q.clone();
                let mut qm = q.clone();
                qp[i] += h;
                qm[i] -= h;
                let d = (potential_energy(&c, &qp, payload) - potential_energy(&c, &qm, payload)) / (2.0 * h);
                assert!((d - tau[i]).abs() < 1e-6 * (1.0 + d.abs()), "{} joint {}: {d} vs {}", c.name, i + 1, tau[i]);
            }
        }
    }
    // A horizontal UR5 arm carries its whole weight on the shoulder: a plausible magnitude.
    let tau = presets::ur5().gravity_torques(&[0.0; 6], 0.0).unwrap();
    assert!(tau[1].abs() > 20.0 && tau[1].abs() < 80.0, "UR5 shoulder torque {}", tau[1]);
    assert!(tau[0].abs() < 1e-12, "the base joint carries no gravity torque");
}

#[test]
#[allow(clippy::approx_constant)] // 3.14159 is the limit the URDF file states
fn urdf_folds_fixed_joints_and_merges_inertials() {
    let c = example_urdf();
    assert_eq!(c.dof(), 6);
    assert_eq!(c.joint_names()[0], "shoulder_pan");
    assert!((c.joints[0].limits.lower + 3.14159).abs() < 1e-12);
    // link6 (0.19 kg) and tool0 (0.5 kg, on the fixed flange joint) are one rigid body.
    let last = c.joints[5].inertial.as_ref().unwrap();
    assert!((last.mass_kg - 0.69).abs() < 1e-12);
    // The flange offset became the tool frame.
    assert!((c.tool.translation.vector - Vector3::new(0.0, 0.0823, 0.0)).norm() < 1e-12);
    // Base link mass does not move and is not carried by any joint.
    assert!((c.total_mass_kg() - (3.7 + 8.4 + 2.3 + 1.2 + 1.2 + 0.69)).abs() < 1e-12);
}

#[test]
fn urdf_simple_chain_matches_hand_computation() {
    let text = r#"<robot name="two">
      <link name="a"/><link name="b"/><link name="c"/><link name="tip"/>
      <joint name="j1" type="revolute"><parent link="a"/><child link="b"/>
        <origin xyz="0 0 1"/><axis xyz="0 0 1"/><limit lower="-3" upper="3"/></joint>
      <joint name="j2" type="prismatic"><parent link="b"/><child link="c"/>
        <origin xyz="1 0 0"/><axis xyz="1 0 0"/><limit lower="0" upper="0.5"/></joint>
      <joint name="t" type="fixed"><parent link="c"/><child link="tip"/><origin xyz="0 0 -0.2"/></joint>
    </robot>"#;
    let c = parse_urdf_str(text, &UrdfOptions::default()).unwrap();
    let t = c.forward(&[PI / 2.0, 0.25]).unwrap();
    assert!((t.translation.vector - Vector3::new(0.0, 1.25, 0.8)).norm() < 1e-12, "{}", t.translation.vector);
}

fn urdf_err(text: &str) -> String {
    match parse_urdf_str(text, &UrdfOptions::default()) {
        Ok(_) => panic!("expected an error for:\n{text}"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn urdf_bad_input_names_the_place() {
    let head = "<robot name=\"r\">\n<link name=\"a\"/>\n<link name=\"b\"/>\n<link name=\"c\"/>\n";
    // A loop: link b is the child of two joints.
    let m = urdf_err(&format!(
        "{head}<joint name=\"j1\" type=\"revolute\"><parent link=\"a\"/><child link=\"b\"/><limit lower=\"-1\" upper=\"1\"/></joint>\n\
         <joint name=\"j2\" type=\"revolute\"><parent link=\"c\"/><child link=\"b\"/><limit lower=\"-1\" upper=\"1\"/></joint>\n</robot>"
    ));
    assert!(m.contains("<string>:6:") && m.contains("loop"), "{m}");
    // A closed cycle without a root.
    let m = urdf_err(
        "<robot name=\"r\"><link name=\"a\"/><link name=\"b\"/>\
         <joint name=\"j1\" type=\"fixed\"><parent link=\"a\"/><child link=\"b\"/></joint>\
         <joint name=\"j2\" type=\"fixed\"><parent link=\"b\"/><child link=\"a\"/></joint></robot>",
    );
    assert!(m.contains("loop"), "{m}");
    // A missing parent.
    let m = urdf_err(&format!(
        "{head}<joint name=\"j1\" type=\"revolute\"><parent link=\"nowhere\"/><child link=\"b\"/><limit lower=\"-1\" upper=\"1\"/></joint>\n</robot>"
    ));
    assert!(m.contains("<string>:5:") && m.contains("parent link 'nowhere' is not defined"), "{m}");
    // A non-finite value.
    let m = urdf_err(&format!(
        "{head}<joint name=\"j1\" type=\"revolute\"><parent link=\"a\"/><child link=\"b\"/>\n<origin xyz=\"0 NaN 0\"/><limit lower=\"-1\" upper=\"1\"/></joint>\n</robot>"
    ));
    assert!(m.contains("<string>:6:") && m.contains("non-finite") && m.contains("j1"), "{m}");
    let m = urdf_err(&format!(
        "{head}<joint name=\"j1\" type=\"revolute\"><parent link=\"a\"/><child link=\"b\"/>\n<origin xyz=\"0 inf 0\"/><limit lower=\"-1\" upper=\"1\"/></joint>\n</robot>"
    ));
    assert!(m.contains("non-finite"), "{m}");
    // Limits with lower > upper.
    let m = urdf_err(&format!(
        "{head}<joint name=\"j1\" type=\"revolute\"><parent link=\"a\"/><child link=\"b\"/>\n<limit lower=\"1\" upper=\"-1\"/></joint>\n</robot>"
    ));
    assert!(
        m.contains("joint 'j1'") && m.contains("lower limit 1 is above upper limit -1") && m.contains("<string>:6:"),
        "{m}"
    );
    // Not a number.
    let m = urdf_err(&format!(
        "{head}<joint name=\"j1\" type=\"revolute\"><parent link=\"a\"/><child link=\"b\"/>\n<origin xyz=\"0 0,5 0\"/><limit lower=\"-1\" upper=\"1\"/></joint>\n</robot>"
    ));
    assert!(m.contains("'0,5'") && m.contains("not a number"), "{m}");
    // Broken XML.
    let m = urdf_err("<robot name=\"r\">\n<link name=\"a\">\n</robot>");
    assert!(m.contains("<string>:3:") && m.contains("not valid XML"), "{m}");
    // A file that does not exist names the file.
    let e = parse_urdf(std::path::Path::new("/nonexistent/arm.urdf"), &UrdfOptions::default()).unwrap_err();
    assert!(e.to_string().contains("/nonexistent/arm.urdf"), "{e}");
}

#[test]
fn inverse_kinematics_reports_failure_instead_of_a_wrong_pose() {
    let c = presets::ur5();
    // 3 m away: out of reach.
    let target = Pose::translation(3.0, 0.0, 0.0);
    match c.inverse(&target, &[0.1, -1.0, 1.0, -1.0, -1.5, 0.0]) {
        Err(RobotError::IkNotConverged { residual_m, .. }) => assert!(residual_m > 1.0),
        other => panic!("expected IkNotConverged, got {other:?}"),
    }
    // A reachable pose, but only outside the limits of a restricted joint.
    let mut c = presets::ur5();
    c.joints[0].limits = JointLimits::new("shoulder_pan", -0.1, 0.1).unwrap();
    let q = [1.0, -1.0, 1.0, -1.0, -1.5, 0.3];
    let mut free = presets::ur5();
    free.joints[0].limits = JointLimits::UNBOUNDED;
    let target = free.forward(&q).unwrap();
    match c.inverse(&target, &[0.9, -1.0, 1.0, -1.0, -1.5, 0.3]) {
        Err(RobotError::OutsideLimits { joint, .. }) => assert_eq!(joint, 1),
        other => panic!("expected OutsideLimits, got {other:?}"),
    }
    // Wrong joint count.
    assert!(matches!(c.forward(&[0.0; 5]), Err(RobotError::JointCount { expected: 6, got: 5 })));
}

#[test]
fn parameter_vectors_are_named_and_round_trip() {
    for c in all_models() {
        let p = c.parameters();
        let mut names: Vec<&str> = p.iter().map(|x| x.name.as_str()).collect();
        names.sort();
        names.dedup();
        assert_eq!(names.len(), p.len(), "{}: parameter names must be unique", c.name);
        let mut d = c.clone();
        d.set_parameter_values(&c.parameter_values()).unwrap();
        let q = vec![0.3; c.dof()];
        let e = pose_error(&c.forward(&q).unwrap(), &d.forward(&q).unwrap());
        assert!(e.norm() < 1e-12, "{}", c.name);
        // Perturbing a link length moves the tool by about that much.
        let idx = p
            .iter()
            .position(|x| x.name.ends_with("a_m") || x.name.ends_with("x_m") && x.name.starts_with("joint"))
            .unwrap();
        let mut delta = vec![0.0; p.len()];
        delta[idx] = 1e-3;
        let moved = c.perturbed(&delta).unwrap();
        let dist = (moved.forward(&q).unwrap().translation.vector - c.forward(&q).unwrap().translation.vector).norm();
        assert!(dist > 1e-4 && dist < 2e-3, "{}: {} moved tool {dist}", c.name, p[idx].name);
    }
    let c = presets::ur5();
    let mut bad = c.parameter_values();
    bad[7] = f64::NAN;
    let mut d = c.clone();
    assert!(matches!(d.set_parameter_values(&bad), Err(RobotError::BadParameter { .. })));
    assert!(matches!(d.set_parameter_values(&bad[..3]), Err(RobotError::ParameterCount { .. })));
}

#[test]
fn joint_geometry_conventions_agree_for_the_ur5() {
    // The UR5 written as URDF-style origins must equal its DH form: each DH joint
    // Rz(q) Tz(d) Tx(a) Rx(alpha) is re-expressed as origin * Rz(q) of the next joint.
    let dh = presets::ur5();
    let mut joints = Vec::new();
    let mut post_prev = Pose::identity();
    for j in &dh.joints {
        let JointGeometry::Dh { a_m, alpha_rad, d_m, .. } = j.geometry else { unreachable!() };
        let (roll, pitch, yaw) = post_prev.rotation.euler_angles();
        joints.push(Joint {
            name: j.name.clone(),
            kind: JointKind::Revolute,
            geometry: JointGeometry::Origin {
                xyz_m: post_prev.translation.vector.into(),
                rpy_rad: [roll, pitch, yaw],
                axis: [0.0, 0.0, 1.0],
            },
            limits: j.limits,
            inertial: None,
            correction: [0.0; 6],
            mimic: None,
        });
        post_prev = Pose::translation(0.0, 0.0, d_m)
            * Pose::translation(a_m, 0.0, 0.0)
            * Pose::from_parts(
                nalgebra::Translation3::identity(),
                nalgebra::UnitQuaternion::from_euler_angles(alpha_rad, 0.0, 0.0),
            );
    }
    let mut urdf_like = SerialChain::new("ur5-origins", joints);
    urdf_like.tool = post_prev;
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    for _ in 0..500 {
        let q = random_q(&dh, &mut rng);
        let e = pose_error(&dh.forward(&q).unwrap(), &urdf_like.forward(&q).unwrap());
        assert!(e.norm() < 1e-12);
    }
}
