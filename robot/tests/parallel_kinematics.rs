//! Parallel robots: forward/inverse round trips, Jacobians against central differences, the
//! six-link model against the 3-DOF model, parameters, link segments and spherical-joint angles.
//! Deterministic (ChaCha8Rng with fixed seeds).

use ferrocal_robot::geometry::pose_from_vectors;
use ferrocal_robot::parallel::presets::{gantry_tau_f1, gantry_tau_l1, gantry_tau_l1_6link, hexapod};
use ferrocal_robot::parallel::{GantryTau6, ParallelRobot};
use ferrocal_robot::{JointLimits, Kinematics, Mobility, Parameterized, Pose, RobotError};
use nalgebra::{DMatrix, DVector, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn sample_q(rng: &mut ChaCha8Rng, limits: &[JointLimits]) -> Vec<f64> {
    limits.iter().map(|l| rng.random_range(l.lower..l.upper)).collect()
}

fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
}

fn pose_err(a: &Pose, b: &Pose) -> (f64, f64) {
    ((a.translation.vector - b.translation.vector).norm(), a.rotation.angle_to(&b.rotation))
}

/// Statistics of a q -> FK -> IK -> q round trip over `n` samples within the limits.
struct Trip {
    ok: usize,
    worst_q: f64,
}

fn joint_round_trips<K: Kinematics>(k: &K, seed: u64, n: usize) -> Trip {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let limits = k.joint_limits();
    let mut t = Trip { ok: 0, worst_q: 0.0 };
    for _ in 0..n {
        let q = sample_q(&mut rng, &limits);
        let pose = match k.forward(&q) {
            Ok(p) => p,
            // Cart combinations that do not assemble in the model's configuration.
            Err(RobotError::Unreachable { .. } | RobotError::FkNotConverged { .. }) => continue,
            Err(e) => panic!("unexpected forward error at {q:?}: {e}"),
        };
        let qi = k.inverse(&pose, &[]).unwrap_or_else(|e| panic!("inverse of FK({q:?}) failed: {e}"));
        t.worst_q = t.worst_q.max(max_abs_diff(&q, &qi));
        t.ok += 1;
    }
    t
}

#[test]
fn gantry_tau3_joint_and_pose_round_trips() {
    for (name, k) in [("nominal", gantry_tau_l1()), ("modified", modified_l1())] {
        let t = joint_round_trips(&k, 11, 3000);
        assert!(t.ok > 2700, "{name}: only {} of 3000 cart samples assemble", t.ok);
        assert!(t.worst_q < 1e-9, "{name}: worst q round trip {:.3e}", t.worst_q);
        // Poses in a box in front of the guideways.
        let mut rng = ChaCha8Rng::seed_from_u64(12);
        let (mut ok, mut worst_p) = (0, 0.0f64);
        for _ in 0..3000 {
            let p = Vector3::new(rng.random_range(-1.2..0.8), rng.random_range(1.8..3.6), rng.random_range(-1.4..0.4));
            let target = pose_from_vectors(&p, &Vector3::zeros());
            let Ok(q) = k.inverse(&target, &[]) else {
                continue;
            };
            let back = k.forward(&q).expect("FK of an IK solution");
            worst_p = worst_p.max(pose_err(&back, &target).0);
            ok += 1;
        }
        assert!(ok > 1000, "{name}: only {ok} reachable poses");
        assert!(worst_p < 1e-9, "{name}: worst pose round trip {worst_p:.3e} m");
        eprintln!(
            "gantry-tau-3 {name}: {} q trips worst {:.2e} (joint units), {ok} pose trips worst {worst_p:.2e} m",
            t.ok, t.worst_q
        );
    }
}

/// The L1 with non-parallel guideways and transmission scale errors (modified model).
fn modified_l1() -> ferrocal_robot::parallel::GantryTau3 {
    let mut k = gantry_tau_l1();
    k.arms[0].v = Vector3::new(1.002, 0.004, -0.003);
    k.arms[1].v = Vector3::new(0.997, -0.006, 0.002);
    k.arms[2].v = Vector3::new(1.0, 0.003, 0.005);
    k
}

#[test]
fn gantry_tau3_workspace_at_zero_and_jacobian_shape() {
    let k = gantry_tau_l1();
    let p = k.forward(&[0.0; 3]).unwrap();
    let expect = Vector3::new(-0.020927, 2.685453, -0.605513);
    assert!((p.translation.vector - expect).norm() < 1e-5, "{p:?}");
    assert_eq!(p.rotation.angle(), 0.0);
    assert_eq!(k.mobility(), Mobility::Translation3);
    let j = k.jacobian(&[0.1, -0.2, 0.3]).unwrap();
    assert_eq!((j.nrows(), j.ncols()), (6, 3));
    assert!(j.rows(3, 3).iter().all(|v| *v == 0.0));
}

#[test]
fn six_link_nominal_reproduces_3dof_with_constant_orientation() {
    let k3 = gantry_tau_l1();
    let k6 = gantry_tau_l1_6link();
    assert_eq!(k6.mobility(), Mobility::Translation3Coupled);
    let mut rng = ChaCha8Rng::seed_from_u64(21);
    let (mut n, mut worst_p, mut worst_r) = (0, 0.0f64, 0.0f64);
    for _ in 0..1000 {
        let q = sample_q(&mut rng, &k3.joint_limits());
        let Ok(p3) = k3.forward(&q) else {
            assert!(k6.forward(&q).is_err(), "6-link assembles where the 3-DOF model does not: {q:?}");
            continue;
        };
        let p6 = k6.forward(&q).unwrap_or_else(|e| panic!("6-link FK at {q:?}: {e}"));
        let (dp, dr) = pose_err(&p3, &p6);
        worst_p = worst_p.max(dp);
        worst_r = worst_r.max(dr);
        n += 1;
    }
    assert!(n > 900);
    assert!(worst_p < 1e-12 && worst_r < 1e-10, "6-link vs 3-DOF: {worst_p:.3e} m, {worst_r:.3e} rad");
    eprintln!("6-link nominal vs 3-DOF over {n} poses: {worst_p:.2e} m, {worst_r:.2e} rad");
}

/// The six-link L1 with every link's geometry off by up to 0.5 mm (a D1-like error model).
fn perturbed_six_link() -> GantryTau6 {
    let k = gantry_tau_l1_6link();
    let mut rng = ChaCha8Rng::seed_from_u64(31);
    let delta: Vec<f64> = k
        .parameters()
        .iter()
        .map(|p| if p.name.starts_with("link") { rng.random_range(-5e-4..5e-4) } else { 0.0 })
        .collect();
    k.perturbed(&delta).unwrap()
}

#[test]
fn six_link_perturbed_round_trips_and_orientation() {
    let k = perturbed_six_link();
    let t = joint_round_trips(&k, 32, 2000);
    assert!(t.ok > 1800, "only {} assemble", t.ok);
    assert!(t.worst_q < 1e-9, "worst q round trip {:.3e} m", t.worst_q);
    let mut rng = ChaCha8Rng::seed_from_u64(33);
    let (mut ok, mut worst_p, mut worst_r, mut tilts) = (0, 0.0f64, 0.0f64, Vec::new());
    for _ in 0..2000 {
        let p = Vector3::new(rng.random_range(-1.2..0.8), rng.random_range(1.8..3.6), rng.random_range(-1.4..0.4));
        let Ok((q, pose_ik)) = k.inverse_pose(&p) else {
            continue;
        };
        if k.check_joints(&q).is_err() {
            continue;
        }
        let back = k.forward(&q).expect("FK of an IK solution");
        worst_p = worst_p.max((back.translation.vector - p).norm());
        worst_r = worst_r.max(back.rotation.angle_to(&pose_ik.rotation));
        tilts.push(back.rotation.angle().to_degrees());
        ok += 1;
    }
    assert!(ok > 800, "only {ok} reachable poses");
    assert!(worst_p < 1e-9 && worst_r < 1e-9, "pose round trip {worst_p:.3e} m, {worst_r:.3e} rad");
    // Sub-millimetre link errors tilt the platform by tenths of a degree (the D1 showed 0.1-0.5),
    // more near the workspace edge.
    tilts.sort_by(f64::total_cmp);
    let (median, max) = (tilts[tilts.len() / 2], tilts[tilts.len() - 1]);
    assert!(median > 0.05 && median < 1.0, "median tilt {median:.3} deg");
    eprintln!(
        "6-link perturbed: {} q trips worst {:.2e} m; {ok} pose trips worst {worst_p:.2e} m / {worst_r:.2e} rad; tilt median {median:.3} deg, max {max:.3} deg",
        t.ok, t.worst_q
    );
}

#[test]
fn f1_round_trips() {
    let k = gantry_tau_f1();
    assert_eq!(k.mobility(), Mobility::Full6);
    let t = joint_round_trips(&k, 41, 2000);
    assert!(t.ok > 1800, "only {} of 2000 samples assemble", t.ok);
    assert!(t.worst_q < 1e-9, "worst q round trip {:.3e}", t.worst_q);
    let home = k.forward(&[0.0; 6]).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(42);
    let (mut ok, mut worst_p, mut worst_r) = (0, 0.0f64, 0.0f64);
    for _ in 0..2000 {
        let dp = Vector3::new(rng.random_range(-0.6..0.6), rng.random_range(-0.3..0.3), rng.random_range(-0.3..0.3));
        let dr = Vector3::new(rng.random_range(-0.1..0.1), rng.random_range(-0.1..0.1), rng.random_range(-0.1..0.1));
        let target = pose_from_vectors(&dp, &dr) * home;
        let Ok(q) = k.inverse(&target, &[]) else {
            continue;
        };
        let back = k.forward(&q).expect("FK of an IK solution");
        let (ep, er) = pose_err(&back, &target);
        worst_p = worst_p.max(ep);
        worst_r = worst_r.max(er);
        ok += 1;
    }
    assert!(ok > 1000, "only {ok} reachable poses");
    assert!(worst_p < 1e-9 && worst_r < 1e-9, "pose round trip {worst_p:.3e} m, {worst_r:.3e} rad");
    eprintln!(
        "F1: {} q trips worst {:.2e}; {ok} pose trips worst {worst_p:.2e} m / {worst_r:.2e} rad",
        t.ok, t.worst_q
    );
}

#[test]
fn hexapod_round_trips() {
    let k = hexapod();
    let home = k.forward(&[0.0; 6]).unwrap();
    assert!(pose_err(&home, &k.home).0 < 1e-12 && pose_err(&home, &k.home).1 < 1e-12);
    let t = joint_round_trips(&k, 51, 3000);
    assert_eq!(t.ok, 3000, "every stroke combination within limits assembles");
    assert!(t.worst_q < 1e-9, "worst q round trip {:.3e} m", t.worst_q);
    let mut rng = ChaCha8Rng::seed_from_u64(52);
    let (mut ok, mut worst_p, mut worst_r) = (0, 0.0f64, 0.0f64);
    for _ in 0..3000 {
        let dp =
            Vector3::new(rng.random_range(-0.08..0.08), rng.random_range(-0.08..0.08), rng.random_range(-0.08..0.08));
        let dr =
            Vector3::new(rng.random_range(-0.15..0.15), rng.random_range(-0.15..0.15), rng.random_range(-0.15..0.15));
        let target = pose_from_vectors(&(home.translation.vector + dp), &dr);
        let Ok(q) = k.inverse(&target, &[]) else {
            continue;
        };
        let back = k.forward(&q).expect("FK of an IK solution");
        let (ep, er) = pose_err(&back, &target);
        worst_p = worst_p.max(ep);
        worst_r = worst_r.max(er);
        ok += 1;
    }
    assert!(ok > 1500, "only {ok} poses within the strokes");
    assert!(worst_p < 1e-9 && worst_r < 1e-9, "pose round trip {worst_p:.3e} m, {worst_r:.3e} rad");
    eprintln!(
        "hexapod: {} q trips worst {:.2e} m; {ok} pose trips worst {worst_p:.2e} m / {worst_r:.2e} rad",
        t.ok, t.worst_q
    );
}

/// Central-difference velocity Jacobian of the forward kinematics.
fn fd_jacobian<K: Kinematics>(k: &K, q: &[f64], h: f64) -> DMatrix<f64> {
    let mut j = DMatrix::zeros(6, q.len());
    for c in 0..q.len() {
        let mut qp = q.to_vec();
        let mut qm = q.to_vec();
        qp[c] += h;
        qm[c] -= h;
        let (pp, pm) = (k.forward(&qp).unwrap(), k.forward(&qm).unwrap());
        let dv = (pp.translation.vector - pm.translation.vector) / (2.0 * h);
        let dw = (pp.rotation * pm.rotation.inverse()).scaled_axis() / (2.0 * h);
        for r in 0..3 {
            j[(r, c)] = dv[r];
            j[(r + 3, c)] = dw[r];
        }
    }
    j
}

fn rel_err(a: &DMatrix<f64>, b: &DMatrix<f64>) -> f64 {
    (a - b).amax() / b.amax().max(1e-300)
}

/// Worst relative mismatch of the velocity Jacobian against central differences at `n` samples.
fn check_velocity_jacobian<K: Kinematics>(k: &K, seed: u64, n: usize) -> f64 {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let limits = k.joint_limits();
    let (mut worst, mut done) = (0.0f64, 0);
    while done < n {
        let q = sample_q(&mut rng, &limits);
        let Ok(j) = k.jacobian(&q) else {
            continue;
        };
        let fd = fd_jacobian(k, &q, 1e-6);
        worst = worst.max(rel_err(&fd, &j));
        done += 1;
    }
    worst
}

/// Worst relative mismatch of the closure derivatives (joints, pose, parameters) against central
/// differences of the residuals.
fn check_constraint_jacobians<K: Kinematics + ParallelRobot + Clone>(k: &K, seed: u64, n: usize) -> f64 {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let limits = k.joint_limits();
    let res = |m: &K, q: &[f64], x: &Pose| DVector::from_vec(m.constraint_residuals(q, x).unwrap());
    let h = 1e-6;
    let (mut worst, mut done) = (0.0f64, 0);
    while done < n {
        let q = sample_q(&mut rng, &limits);
        let Ok(x) = k.forward(&q) else {
            continue;
        };
        // Evaluate away from the closed configuration too: the derivatives hold everywhere.
        let x = pose_from_vectors(&Vector3::new(0.01, -0.02, 0.015), &Vector3::new(0.02, 0.01, -0.03)) * x;
        let m = res(k, &q, &x).len();
        let fq = k.constraint_jacobian_joints(&q, &x).unwrap();
        let mut fd = DMatrix::zeros(m, q.len());
        for c in 0..q.len() {
            let (mut qp, mut qm) = (q.clone(), q.clone());
            qp[c] += h;
            qm[c] -= h;
            fd.set_column(c, &((res(k, &qp, &x) - res(k, &qm, &x)) / (2.0 * h)));
        }
        worst = worst.max(rel_err(&fd, &fq));
        let fx = k.constraint_jacobian_pose(&q, &x).unwrap();
        let mut fd = DMatrix::zeros(m, 6);
        for c in 0..6 {
            let mut e = [0.0; 6];
            e[c] = h;
            let step = |s: f64| {
                let dp = Vector3::new(e[0], e[1], e[2]) * s;
                let dw = Vector3::new(e[3], e[4], e[5]) * s;
                nalgebra::Isometry3::from_parts(
                    nalgebra::Translation3::from(x.translation.vector + dp),
                    nalgebra::UnitQuaternion::from_scaled_axis(dw) * x.rotation,
                )
            };
            fd.set_column(c, &((res(k, &q, &step(1.0)) - res(k, &q, &step(-1.0))) / (2.0 * h)));
        }
        worst = worst.max(rel_err(&fd, &fx));
        let fs = k.constraint_jacobian_parameters(&q, &x).unwrap();
        let s0 = k.parameter_values();
        let mut fd = DMatrix::zeros(m, s0.len());
        for c in 0..s0.len() {
            let mut d = vec![0.0; s0.len()];
            d[c] = h;
            let kp = k.perturbed(&d).unwrap();
            d[c] = -h;
            let km = k.perturbed(&d).unwrap();
            fd.set_column(c, &((res(&kp, &q, &x) - res(&km, &q, &x)) / (2.0 * h)));
        }
        worst = worst.max(rel_err(&fd, &fs));
        done += 1;
    }
    worst
}

#[test]
fn jacobians_match_central_differences() {
    let mut f1 = gantry_tau_f1();
    // A tool offset exercises the tool-point terms.
    f1.tool = pose_from_vectors(&Vector3::new(0.05, -0.02, 0.1), &Vector3::new(0.1, -0.05, 0.2));
    let mut hex = hexapod();
    hex.tool = pose_from_vectors(&Vector3::new(0.0, 0.03, 0.12), &Vector3::new(0.0, 0.0, 0.3));
    let results = [
        (
            "gantry-tau-l1 (modified)",
            check_velocity_jacobian(&modified_l1(), 61, 50),
            check_constraint_jacobians(&modified_l1(), 62, 5),
        ),
        (
            "6-link (perturbed)",
            check_velocity_jacobian(&perturbed_six_link(), 63, 50),
            check_constraint_jacobians(&perturbed_six_link(), 64, 5),
        ),
        ("F1", check_velocity_jacobian(&f1, 65, 50), check_constraint_jacobians(&f1, 66, 5)),
        ("hexapod", check_velocity_jacobian(&hex, 67, 50), check_constraint_jacobians(&hex, 68, 5)),
    ];
    for (name, vel, con) in results {
        eprintln!(
            "{name}: velocity Jacobian vs central differences {vel:.2e}, closure derivatives {con:.2e} (relative)"
        );
        assert!(vel < 1e-6, "{name}: velocity Jacobian mismatch {vel:.3e}");
        assert!(con < 1e-6, "{name}: closure derivative mismatch {con:.3e}");
    }
}

#[test]
fn parameter_vectors_are_named_and_validated() {
    let l1 = gantry_tau_l1();
    let names: Vec<String> = l1.parameters().into_iter().map(|p| p.name).collect();
    assert_eq!(names.len(), 21);
    assert_eq!(&names[..7], ["arm1.L_m", "arm1.A_x_m", "arm1.A_y_m", "arm1.A_z_m", "arm1.v_x", "arm1.v_y", "arm1.v_z"]);
    let six = gantry_tau_l1_6link();
    assert_eq!(six.n_parameters(), 51);
    assert!(six.parameter_index("link2_1.B0_y_m").is_some());
    assert!(six.parameter_index("guide3.v_z").is_some());
    let f1 = gantry_tau_f1();
    assert_eq!(f1.n_parameters(), 69);
    assert!(f1.parameter_index("tilt3.axis_y").is_some() && f1.parameter_index("link3_3.A_z_m").is_some());
    let hex = hexapod();
    assert_eq!(hex.n_parameters(), 42);
    assert!(hex.parameter_index("leg6.L0_m").is_some());
    for names in
        [six.parameters(), f1.parameters(), hex.parameters()].map(|p| p.into_iter().map(|p| p.name).collect::<Vec<_>>())
    {
        let mut sorted = names.clone();
        sorted.sort();
        sorted.dedup();
        assert_eq!(sorted.len(), names.len(), "parameter names are unique");
    }

    // set_parameter_values: round trip, then rejections that leave the model unchanged.
    let mut k = gantry_tau_l1();
    let v = k.parameter_values();
    k.set_parameter_values(&v).unwrap();
    assert_eq!(k, gantry_tau_l1());
    let mut bad = v.clone();
    bad[0] = -2.0;
    assert!(
        matches!(k.set_parameter_values(&bad), Err(RobotError::BadParameter { ref name, .. }) if name == "arm1.L_m")
    );
    let mut bad = v.clone();
    bad[11..14].copy_from_slice(&[0.0, 0.0, 0.0]);
    assert!(matches!(k.set_parameter_values(&bad), Err(RobotError::BadParameter { ref name, .. }) if name == "arm2.v"));
    let mut bad = v.clone();
    bad[5] = f64::NAN;
    assert!(
        matches!(k.set_parameter_values(&bad), Err(RobotError::BadParameter { ref name, .. }) if name == "arm1.v_y")
    );
    assert!(matches!(k.set_parameter_values(&v[..20]), Err(RobotError::ParameterCount { expected: 21, got: 20 })));
    assert_eq!(k, gantry_tau_l1(), "rejected values leave the model unchanged");

    // perturbed (default trait method) on every model.
    let mut d = vec![0.0; 21];
    d[0] = 1e-3;
    assert!((k.perturbed(&d).unwrap().arms[0].length_m - 2.0623).abs() < 1e-12);
    let mut d = vec![0.0; 42];
    d[6] = -1.0; // leg1.L0_m -> negative
    assert!(matches!(hex.perturbed(&d), Err(RobotError::BadParameter { ref name, .. }) if name == "leg1.L0_m"));
    let mut d = vec![0.0; 69];
    d[12..15].copy_from_slice(&[-0.47, -0.88, 0.0]); // rot2 axis -> zero
    assert!(matches!(f1.perturbed(&d), Err(RobotError::BadParameter { ref name, .. }) if name == "rot2.axis"));
    let d = vec![1e-4; 51];
    assert!(six.perturbed(&d).is_ok());
}

#[test]
fn link_segments_and_spherical_joint_angles() {
    let k = gantry_tau_f1();
    let q0 = [0.0; 6];
    for a in k.spherical_joint_angles(&q0).unwrap() {
        assert!(a.base_rad.abs() < 1e-12 && a.platform_rad.abs() < 1e-12, "{a:?}");
    }
    let q = [0.3, -0.2, 0.4, 0.1, -0.15, 0.2];
    let segs = k.link_segments(&q).unwrap();
    assert_eq!(segs.len(), 6);
    assert_eq!(segs[3].link, "link3_1");
    for (s, l) in segs.iter().zip(&k.links) {
        assert!(((s.a_m - s.b_m).norm() - l.length_m).abs() < 1e-10, "{s:?}");
    }
    let angles = k.spherical_joint_angles(&q).unwrap();
    assert!(angles.iter().all(|a| a.base_rad > 0.0 && a.platform_rad > 0.0 && a.base_rad < 0.6));

    // The 3-DOF model: the base-side axis is fixed in the base, so the angle is the angle between
    // the link now and the link at q = 0.
    let l1 = gantry_tau_l1();
    let q = [0.4, -0.3, 0.2];
    let seg0 = l1.link_segments(&[0.0; 3]).unwrap();
    let seg = l1.link_segments(&q).unwrap();
    let angles = l1.spherical_joint_angles(&q).unwrap();
    for ((s0, s), a) in seg0.iter().zip(&seg).zip(&angles) {
        let (u, w) = (s.b_m - s.a_m, s0.b_m - s0.a_m);
        let expect = u.angle(&w);
        assert!((a.base_rad - expect).abs() < 1e-12 && (a.platform_rad - expect).abs() < 1e-12);
    }
    // Stated axes are used as given.
    let mut l1 = gantry_tau_l1();
    l1.arms[0].base_axis = Some(Vector3::new(1.0, 0.0, 0.0));
    let a = l1.spherical_joint_angles(&q).unwrap();
    let u = seg[0].b_m - seg[0].a_m;
    assert!((a[0].base_rad - u.angle(&Vector3::x())).abs() < 1e-12);

    // Hexapod: zero at home, and the segments are the legs.
    let hex = hexapod();
    assert!(hex.spherical_joint_angles(&[0.0; 6]).unwrap().iter().all(|a| a.base_rad.abs() < 1e-12));
    let q = [0.05, -0.02, 0.03, 0.0, -0.04, 0.01];
    for (i, s) in hex.link_segments(&q).unwrap().iter().enumerate() {
        assert!(((s.a_m - s.b_m).norm() - hex.legs[i].length0_m - q[i]).abs() < 1e-10);
    }
}
