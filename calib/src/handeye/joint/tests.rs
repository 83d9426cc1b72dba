use super::*;

/// The pose Jacobian of the robot block (analytic corrections and joint offsets) against
/// central differences of the forward kinematics, on a UR5 with every correction free.
#[test]
fn robot_pose_jacobian_matches_central_differences() {
    let model = ferrocal_robot::presets::preset("ur5").unwrap();
    let params = model.parameters();
    let model_cols: Vec<(usize, usize)> = params
        .iter()
        .enumerate()
        .filter(|(_, p)| p.name.contains(".corr_") || p.name.ends_with(".a_m") || p.name.ends_with(".d_m"))
        .map(|(i, _)| i)
        .enumerate()
        .collect();
    let n_m = model_cols.len();
    let offset_cols: Vec<(usize, usize)> = (0..6).map(|j| (n_m + j, j)).collect();
    let map = RobotMap { model: model.clone(), model_cols: model_cols.clone(), offset_cols, n: n_m + 6 };
    let vals = model.parameter_values();
    let mut v: Vec<f64> = model_cols.iter().map(|&(_, pi)| vals[pi]).collect();
    // Off the nominal values: corrections of a few mm and mrad.
    for (k, x) in v.iter_mut().enumerate() {
        *x += 1e-3 * ((k as f64) * 0.7).sin();
    }
    v.extend([0.01, -0.02, 0.005, 0.0, 0.01, -0.003]);
    let q = [0.3, -1.1, 1.4, -0.6, 0.9, 0.2];
    let (t, jac) = map.pose_jacobian(&v, &q).unwrap();
    for k in 0..map.n {
        let h = 1e-6;
        let mut vp = v.clone();
        vp[k] += h;
        let (mp, qp) = map.apply(&vp, &q).unwrap();
        let tp = mp.forward(&qp).unwrap();
        vp[k] -= 2.0 * h;
        let (mm, qm) = map.apply(&vp, &q).unwrap();
        let tm = mm.forward(&qm).unwrap();
        let dt = (tp.translation.vector - tm.translation.vector) / (2.0 * h);
        let dw = (tp.rotation * tm.rotation.inverse()).scaled_axis() / (2.0 * h);
        for a in 0..3 {
            assert!((jac[(a, k)] - dt[a]).abs() < 1e-6, "column {k} dt[{a}]: {} vs {}", jac[(a, k)], dt[a]);
            assert!((jac[(3 + a, k)] - dw[a]).abs() < 1e-6, "column {k} dw[{a}]: {} vs {}", jac[(3 + a, k)], dw[a]);
        }
    }
    assert!(t.translation.vector.norm() > 0.1);
}

/// The corner residual's analytic Jacobians (robot block through the pose Jacobian, `X`,
/// `W`, camera) agree with central differences through the manifolds, both mounts.
#[test]
fn robot_corner_passes_the_gradient_check() {
    use ferrocal_lsq::check::check_residual;
    use ferrocal_lsq::{Euclidean, Manifold};
    use ferrocal_vision::camera::{Distortion, ImageSize, Intrinsics};
    let model = ferrocal_robot::presets::preset("ur5").unwrap();
    let params = model.parameters();
    let model_cols: Vec<(usize, usize)> = params
        .iter()
        .enumerate()
        .filter(|(_, p)| p.name.starts_with("joint2.corr_") || p.name.starts_with("joint5.corr_"))
        .map(|(i, _)| i)
        .enumerate()
        .collect();
    let n_m = model_cols.len();
    let map = Arc::new(RobotMap {
        model: model.clone(),
        model_cols: model_cols.clone(),
        offset_cols: vec![(n_m, 1), (n_m + 1, 3)],
        n: n_m + 2,
    });
    let mut v: Vec<f64> = (0..n_m).map(|k| 2e-3 * ((k as f64) * 1.3).cos()).collect();
    v.extend([0.004, -0.003]);
    let camera = CameraModel::new(
        Intrinsics { fx_px: 1100.0, fy_px: 1102.0, cx_px: 645.0, cy_px: 478.0 },
        Distortion::Brown5 { k1: -0.08, k2: 0.05, p1: 0.0004, p2: -0.0003, k3: 0.01 },
        ImageSize { width_px: 1280, height_px: 960 },
    )
    .unwrap();
    let q = vec![0.3, -1.1, 1.4, -0.6, 0.9, 0.2];
    let (fk, _) = map.pose_jacobian(&v, &q).unwrap();
    let t_cam_target = Isometry3::new(Vector3::new(0.02, -0.03, 1.6), Vector3::new(0.2, 2.9, 0.1));
    for mount in [Mount::EyeInHand, Mount::EyeToHand] {
        let x = Isometry3::new(Vector3::new(0.03, 0.01, 0.09), Vector3::new(0.1, -1.4, 0.3));
        let w = match mount {
            Mount::EyeInHand => fk * x * t_cam_target,
            Mount::EyeToHand => fk * x * t_cam_target.inverse(),
        };
        // Off the start of both increments.
        let f = vec![0.002, -0.001, 0.003, 0.01, -0.02, 0.015];
        let t = vec![-0.001, 0.002, 0.001, -0.01, 0.02, 0.005];
        let frames = Arc::new(FrameMap {
            f0: exp6(&f).inverse() * w.inverse(),
            x0: x * exp6(&t).inverse(),
            frame_free: (0..6).collect(),
            tool_free: (0..6).collect(),
        });
        let r = RobotCorner {
            map: map.clone(),
            frames,
            mount,
            q: q.clone(),
            point_m: Point3::new(0.05, 0.03, 0.0),
            detected_px: Point2::new(600.0, 450.0),
            whiten: whitening(&Matrix2::new(0.04, 0.01, 0.01, 0.09)).unwrap(),
            camera,
        };
        let blocks: Vec<Vec<f64>> = vec![v.clone(), f, t, camera.parameter_values()];
        let views: Vec<&[f64]> = blocks.iter().map(|b| b.as_slice()).collect();
        let manifolds: Vec<Arc<dyn Manifold>> = vec![
            Arc::new(Euclidean { n: map.n }),
            Arc::new(Euclidean { n: 6 }),
            Arc::new(Euclidean { n: 6 }),
            Arc::new(Euclidean { n: 9 }),
        ];
        let scales = vec![
            vec![1e-4; map.n],
            vec![1e-3; 6],
            vec![1e-3; 6],
            vec![1.0, 1.0, 1.0, 1.0, 1e-3, 1e-3, 1e-4, 1e-4, 1e-3],
        ];
        let report = check_residual(&r, &views, &manifolds, &scales, 1e-3).unwrap();
        report.assert_below(1e-5, &format!("{mount:?} robot corner")).unwrap();
    }
}
