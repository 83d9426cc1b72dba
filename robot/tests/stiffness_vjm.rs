//! The virtual joint model: Jacobians against the exact compliant kinematics, the identification
//! equation against the model's own deflection, the compensator's derivatives, the structure the
//! reduction uses (258 complete parameters, 6 aggregations), and wrench checks.

use ferrocal_robot::geometry::pose_error;
use ferrocal_robot::stiffness::presets::{kr270_like, orthoglide_link_compliance};
use ferrocal_robot::stiffness::{Deflections, Loading, StiffnessError, VjmModel, Wrench, WrenchLimits, WrenchSpec};
use nalgebra::{Point3, Vector3, Vector6};

fn configs() -> Vec<Vec<f64>> {
    vec![
        vec![0.3, 0.4, 0.2, 0.5, -0.8, 0.3],
        vec![-1.0, -0.3, 0.9, -1.2, 0.6, -2.0],
        vec![2.0, 1.2, -0.6, 2.5, 1.5, 1.0],
    ]
}

#[test]
fn jacobians_match_finite_differences_of_the_compliant_kinematics() {
    let m = kr270_like().unwrap();
    let h = 1e-6;
    for q in configs() {
        let jac = m.jacobians(&q, None).unwrap();
        let zero = Deflections { joints: vec![0.0; 6], springs: vec![Vector6::zeros(); m.springs.len()] };
        let t0 = m.deflected_pose(&q, &zero).unwrap();
        // Joints.
        for j in 0..6 {
            let mut d = zero.clone();
            d.joints[j] = h;
            let t = m.deflected_pose(&q, &d).unwrap();
            let fd = -pose_error(&t0, &t) / h;
            let col = jac.joints.column(j);
            for r in 0..6 {
                assert!((fd[r] - col[r]).abs() < 1e-5, "joint {j} row {r}: {} vs {}", fd[r], col[r]);
            }
        }
        // Springs.
        for (s, js) in jac.springs.iter().enumerate() {
            for c in 0..6 {
                let mut d = zero.clone();
                d.springs[s][c] = h;
                let t = m.deflected_pose(&q, &d).unwrap();
                let fd = -pose_error(&t0, &t) / h;
                for r in 0..6 {
                    assert!(
                        (fd[r] - js[(r, c)]).abs() < 1e-5,
                        "spring {s} col {c} row {r}: {} vs {}",
                        fd[r],
                        js[(r, c)]
                    );
                }
            }
        }
    }
}

#[test]
fn identification_equation_reproduces_the_models_deflection() {
    let m = kr270_like().unwrap();
    let pi = nalgebra::DVector::from_vec(m.complete_values());
    let layout = m.layout().unwrap();
    assert_eq!(layout.len(), 258 + 2, "6 joints + 7 springs x 36 + 2 compensator terms");
    assert_eq!(pi.len(), layout.len());
    for q in configs() {
        let tool = m.chain.frames(&q).unwrap().tool;
        let p_tool = Point3::from(tool.translation.vector);
        let com = tool * Point3::new(0.2, 0.0, 0.1);
        let w = Wrench::gravity(250.0, &com, &p_tool, &Vector3::new(0.0, 0.0, -9.80665));
        for loading in [Loading::tool(w), Loading::gravity(w), Loading::gravity(Wrench::default())] {
            let a = m.observation_matrix(&q, &loading).unwrap();
            let lin = &a * &pi;
            let d = m.deflection(&q, &loading).unwrap();
            for r in 0..6 {
                assert!((lin[r] - d[r]).abs() < 1e-12 + 1e-9 * d.norm(), "{loading:?} row {r}: {} vs {}", lin[r], d[r]);
            }
        }
        // The tool wrench alone: k_C w.
        let kc = m.cartesian_compliance(&q).unwrap();
        assert!((kc - kc.transpose()).norm() < 1e-15 * kc.norm().max(1.0));
        assert!(kc.symmetric_eigenvalues().iter().all(|l| *l > -1e-15));
        let d = m.deflection(&q, &Loading::tool(w)).unwrap();
        assert!((kc * w.as_vector() - d).norm() < 1e-12);
        // Deflections of a few millimetres under 2.5 kN.
        assert!(d.fixed_rows::<3>(0).norm() > 5e-4 && d.fixed_rows::<3>(0).norm() < 2e-2, "{}", d.norm());
    }
}

#[test]
fn compensator_derivatives_match_finite_differences_and_it_holds_the_arm_up() {
    let m = kr270_like().unwrap();
    let c = m.compensator.clone().unwrap();
    for q in configs() {
        let fr = m.chain.frames(&q).unwrap();
        let g = c.geometry(&m.chain, &fr).unwrap();
        let h = 1e-5;
        let s_at = |dq: f64| {
            let mut qq = q.clone();
            qq[1] += dq;
            c.geometry(&m.chain, &m.chain.frames(&qq).unwrap()).unwrap().length_m
        };
        let d1 = (s_at(h) - s_at(-h)) / (2.0 * h);
        let d2 = (s_at(h) - 2.0 * g.length_m + s_at(-h)) / (h * h);
        assert!((d1 - g.d1_m_per_rad).abs() < 1e-8, "{d1} vs {}", g.d1_m_per_rad);
        assert!((d2 - g.d2_m_per_rad2).abs() < 1e-4, "{d2} vs {}", g.d2_m_per_rad2);
        // The spring's torque opposes the links' weight on joint 2 (holding torque + spring torque
        // is smaller than the holding torque alone) when the arm leans out.
        let hold = m.chain.gravity_torques(&q, 0.0).unwrap()[1];
        let tau = c.torque_nm(&m.chain, &fr).unwrap();
        if hold.abs() > 2000.0 {
            assert!((hold - tau).abs() < hold.abs(), "holding {hold} N m, spring {tau} N m");
        }
        // Its own stiffness is small beside the gearbox's.
        let k = c.stiffness_nm_per_rad(&m.chain, &fr).unwrap();
        assert!(k.abs() * m.joint_compliance[1] < 0.01, "{k}");
    }
}

#[test]
fn every_joint_of_the_kr270_aggregates_with_the_spring_before_it() {
    let m = kr270_like().unwrap();
    let agg = m.aggregations().unwrap();
    assert_eq!(agg.len(), 6, "{agg:?}");
    for (j, a) in agg.iter().enumerate() {
        assert_eq!(a.joint, j);
        assert_eq!(a.spring, j, "joint {} with link {}", j + 1, j);
        assert_eq!(a.entry, 5, "rotation about the spring's z axis");
    }
    // The aggregated columns are identical over configurations and loads.
    let layout = m.layout().unwrap();
    for q in configs() {
        let a = m
            .observation_matrix(
                &q,
                &Loading::gravity(Wrench::new(Vector3::new(0.0, 0.0, -2000.0), Vector3::new(100.0, -50.0, 30.0))),
            )
            .unwrap();
        for g in &agg {
            let cj = a.column(layout.joint_index(g.joint).unwrap());
            let cs = a.column(layout.spring_index(g.spring, g.entry, g.entry).unwrap());
            assert!((cj - cs).norm() <= 1e-12 * cj.norm().max(1e-30), "joint {}", g.joint + 1);
        }
    }
}

#[test]
fn a_rigid_link_model_is_joints_only() {
    let m = kr270_like().unwrap();
    let r = VjmModel::rigid_links(m.chain.clone(), m.joint_compliance.clone()).unwrap();
    assert_eq!(r.layout().unwrap().len(), 6);
    let q = &configs()[0];
    let kc = r.cartesian_compliance(q).unwrap();
    let j = ferrocal_robot::Kinematics::jacobian(&m.chain, q).unwrap();
    let k = nalgebra::DMatrix::from_diagonal(&nalgebra::DVector::from_vec(m.joint_compliance.clone()));
    let expect = &j * k * j.transpose();
    assert!((nalgebra::DMatrix::from_column_slice(6, 6, kc.as_slice()) - expect).norm() < 1e-15);
}

#[test]
fn the_orthoglide_matrix_is_the_sources() {
    let k = orthoglide_link_compliance();
    assert_eq!(k[(0, 0)], 4.50e-8);
    assert_eq!(k[(1, 5)], 3.98e-4);
    assert_eq!(k[(4, 2)], -1.71e-4);
    assert!(k.symmetric_eigenvalues().iter().all(|l| *l > 0.0));
}

#[test]
fn wrenches_in_unknown_frames_or_wrong_units_are_refused_with_the_reason() {
    let m = kr270_like().unwrap();
    let q = &configs()[0];
    let lim = WrenchLimits::default();
    let spec = |frame: &str, f: [f64; 3], t: [f64; 3]| WrenchSpec {
        frame: frame.into(),
        force_n: f,
        torque_nm: t,
        point_m: [0.0; 3],
    };
    let e = m.resolve_wrench(q, &spec("gripper", [0.0, 0.0, -100.0], [0.0; 3]), &lim).unwrap_err();
    match &e {
        StiffnessError::UnknownFrame { name, known } => {
            assert_eq!(name, "gripper");
            assert!(known.contains(&"tool".to_string()) && known.contains(&"a2".to_string()));
        }
        other => panic!("{other}"),
    }
    assert!(e.to_string().contains("gripper") && e.to_string().contains("flange"), "{e}");
    // A moment in N mm: 100 N with 50 000 "N m" is a 500 m lever arm.
    let e = m.resolve_wrench(q, &spec("tool", [0.0, 0.0, -100.0], [50_000.0, 0.0, 0.0]), &lim).unwrap_err();
    assert!(matches!(e, StiffnessError::ImplausibleWrench { .. }) && e.to_string().contains("N mm"), "{e}");
    // A mass in grams times g.
    let e = m.resolve_wrench(q, &spec("tool", [0.0, 0.0, -250_000.0 * 9.81], [0.0; 3]), &lim).unwrap_err();
    assert!(e.to_string().contains("newtons"), "{e}");
    let e = m.resolve_wrench(q, &spec("tool", [f64::NAN, 0.0, 0.0], [0.0; 3]), &lim).unwrap_err();
    assert!(e.to_string().contains("finite"), "{e}");
    // A good one: 2.5 kN along the tool's z axis, applied at its point: no moment about it.
    let w = m.resolve_wrench(q, &spec("tool", [0.0, 0.0, 2500.0], [0.0; 3]), &lim).unwrap();
    let tool = m.chain.frames(q).unwrap().tool;
    assert!((w.force_n - tool.rotation * Vector3::new(0.0, 0.0, 2500.0)).norm() < 1e-9);
    assert!(w.torque_nm.norm() < 1e-9);
    // Joint names name link frames.
    assert!(m.resolve_wrench(q, &spec("a3", [10.0, 0.0, 0.0], [0.0; 3]), &lim).is_ok());
    assert!(m.resolve_wrench(q, &spec("link7", [10.0, 0.0, 0.0], [0.0; 3]), &lim).is_err());
}
