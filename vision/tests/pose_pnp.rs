//! Target pose from one calibrated camera (PnP): accuracy, covariance against Monte-Carlo
//! sampling, corner covariances, calibration uncertainty propagated, and bad input.

use crate::calib_support;

use calib_support as sim;
use ferrocal_vision::calib::PlanarTarget;
use ferrocal_vision::pose::{estimate_pose, estimate_pose_rig, so3, CameraRig, CornerNoise, RigObservation};
use ferrocal_vision::VisionError;
use nalgebra::{DMatrix, Matrix2, Matrix6, Vector3, Vector6};

fn target() -> PlanarTarget {
    PlanarTarget::chessboard(9, 6, 0.025)
}

/// `[position mm, rotation error rad]` of an estimate against the truth (the convention of
/// `PoseEstimate::covariance`).
fn error(est: &nalgebra::Isometry3<f64>, truth: &nalgebra::Isometry3<f64>) -> Vector6<f64> {
    let dp = (est.translation.vector - truth.translation.vector) * 1e3;
    let dr = so3::log(&(est.rotation * truth.rotation.inverse()).to_rotation_matrix());
    Vector6::new(dp.x, dp.y, dp.z, dr.x, dr.y, dr.z)
}

#[test]
fn pnp_covariance_matches_monte_carlo() {
    let camera = sim::vga_camera();
    let t = target();
    let truth = sim::board_pose(&t, Vector3::new(0.03, -0.02, 0.45), 35f64.to_radians(), 0.7, 0.3);
    let sigma_px = 0.2;
    let mut rng = sim::rng(1);
    let n = 400;
    let mut errs = Vec::new();
    let mut predicted = Matrix6::zeros();
    for i in 0..n {
        let v = sim::observe(&mut rng, &format!("{i}"), &camera, &t, &truth, sigma_px);
        let est =
            estimate_pose(&camera, &t.points_m, &v.point_ids, &v.corners_px, &CornerNoise::Isotropic { sigma_px })
                .unwrap();
        assert!(est.s0 > 0.7 && est.s0 < 1.3, "s0 {}", est.s0);
        errs.push(error(&est.t_cam_target, &truth));
        predicted += est.covariance / n as f64;
        assert_eq!(est.covariance, est.covariance_corners);
    }
    let mean = errs.iter().sum::<Vector6<f64>>() / n as f64;
    let mut sample = Matrix6::zeros();
    for e in &errs {
        sample += (e - mean) * (e - mean).transpose() / (n - 1) as f64;
    }
    for i in 0..6 {
        let ratio = sample[(i, i)] / predicted[(i, i)];
        println!(
            "axis {i}: sample std {:.3e}, predicted {:.3e} (ratio of variances {ratio:.3})",
            sample[(i, i)].sqrt(),
            predicted[(i, i)].sqrt()
        );
        assert!(ratio > 0.8 && ratio < 1.25, "axis {i}: variance ratio {ratio}");
        assert!(mean[i].abs() < 4.0 * (predicted[(i, i)] / n as f64).sqrt(), "axis {i}: bias {}", mean[i]);
    }
}

#[test]
fn anisotropic_corner_covariances_weight_the_fit() {
    let camera = sim::vga_camera();
    let t = target();
    let truth = sim::board_pose(&t, Vector3::new(0.0, 0.0, 0.5), 20f64.to_radians(), 0.0, 0.0);
    let mut rng = sim::rng(2);
    let v = sim::observe(&mut rng, "v", &camera, &t, &truth, 0.0);
    let cov = vec![Matrix2::new(0.04, 0.01, 0.01, 0.09); v.corners_px.len()];
    let est =
        estimate_pose(&camera, &t.points_m, &v.point_ids, &v.corners_px, &CornerNoise::PerCorner(cov.clone())).unwrap();
    assert!(error(&est.t_cam_target, &truth).norm() < 1e-6);
    let iso =
        estimate_pose(&camera, &t.points_m, &v.point_ids, &v.corners_px, &CornerNoise::Isotropic { sigma_px: 0.2 })
            .unwrap();
    // Noisier corners (0.3 px in y) give a larger uncertainty than 0.2 px everywhere.
    assert!(est.covariance.trace() > iso.covariance.trace());
    let mut bad = cov;
    bad[3] = Matrix2::new(1.0, 2.0, 2.0, 1.0);
    let e = estimate_pose(&camera, &t.points_m, &v.point_ids, &v.corners_px, &CornerNoise::PerCorner(bad)).unwrap_err();
    assert!(e.to_string().contains("corner 3"), "{e}");
}

#[test]
fn calibration_uncertainty_adds_to_the_pose_covariance() {
    let camera = sim::vga_camera();
    let t = target();
    let truth = sim::board_pose(&t, Vector3::new(0.02, 0.01, 0.5), 25f64.to_radians(), 1.0, 0.0);
    let mut rng = sim::rng(3);
    let v = sim::observe(&mut rng, "v", &camera, &t, &truth, 0.1);
    let obs = [RigObservation {
        camera: 0,
        point_ids: v.point_ids.clone(),
        corners_px: v.corners_px.clone(),
        noise: CornerNoise::Isotropic { sigma_px: 0.1 },
    }];
    let mut cov = DMatrix::zeros(9, 9);
    cov[(0, 0)] = 1.0; // fx uncertain by 1 px
    cov[(1, 1)] = 1.0;
    cov[(0, 1)] = 1.0;
    cov[(1, 0)] = 1.0;
    let rig =
        CameraRig { cameras: vec![camera], t_cam_cam0: vec![nalgebra::Isometry3::identity()], covariance: Some(cov) };
    let est = estimate_pose_rig(&rig, &t.points_m, &obs).unwrap();
    // A focal length error scales the distance: z (depth) variance grows by about (z / f)^2.
    let extra = est.covariance[(2, 2)] - est.covariance_corners[(2, 2)];
    let expected = (truth.translation.vector.z * 1e3 / camera.intrinsics.fx_px).powi(2);
    assert!((extra / expected - 1.0).abs() < 0.2, "extra depth variance {extra} vs about {expected}");
    // Wrong covariance size is an error.
    let bad = CameraRig { covariance: Some(DMatrix::zeros(3, 3)), ..rig };
    assert!(matches!(estimate_pose_rig(&bad, &t.points_m, &obs), Err(VisionError::InvalidInput { .. })));
}

#[test]
fn bad_pose_input_is_an_error() {
    let camera = sim::vga_camera();
    let t = target();
    let noise = CornerNoise::Isotropic { sigma_px: 0.1 };
    let px = vec![nalgebra::Point2::new(1.0, 2.0); 3];
    assert!(matches!(
        estimate_pose(&camera, &t.points_m, &[0, 1, 2], &px, &noise),
        Err(VisionError::InvalidInput { .. })
    ));
    assert!(matches!(estimate_pose(&camera, &t.points_m, &[0, 1], &px, &noise), Err(VisionError::InvalidInput { .. })));
    assert!(estimate_pose(&camera, &t.points_m, &[0, 1, 2, 99], &[px[0]; 4], &noise).is_err());
    let cube: Vec<nalgebra::Point3<f64>> = (0..8)
        .map(|i| nalgebra::Point3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64 + 3.0))
        .collect();
    let e = estimate_pose(&camera, &cube, &(0..8).collect::<Vec<_>>(), &[px[0]; 8], &noise).unwrap_err();
    assert!(e.to_string().contains("planar"), "{e}");
    assert!(estimate_pose(
        &camera,
        &t.points_m,
        &[0, 1, 2, 3],
        &[px[0]; 4],
        &CornerNoise::Isotropic { sigma_px: -1.0 }
    )
    .is_err());
}
