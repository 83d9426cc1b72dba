//! Unit tests of the calibration internals: the residual's Jacobians against finite differences
//! (the gradient checker every residual passes), Zhang's closed form on exact data, pattern
//! strings.

use super::bundle::{CameraLayout, CornerResidual};
use super::deform::TargetDeformation;
use super::*;
use crate::camera::{Distortion, DistortionKind, ImageSize, Intrinsics};
use crate::pose::LocalPose;
use nalgebra::{Matrix3, Point2, Point3, Vector3};

fn camera(distortion: Distortion) -> CameraModel {
    CameraModel::new(
        Intrinsics { fx_px: 812.0, fy_px: 806.0, cx_px: 331.0, cy_px: 247.0 },
        distortion,
        ImageSize { width_px: 640, height_px: 480 },
    )
    .unwrap()
}

fn distortions() -> Vec<Distortion> {
    vec![
        Distortion::Brown5 { k1: -0.21, k2: 0.08, p1: 0.001, p2: -0.0007, k3: 0.02 },
        Distortion::Rational8 { k1: 0.4, k2: 0.05, p1: 0.001, p2: -0.0007, k3: 0.01, k4: 0.6, k5: 0.02, k6: 0.001 },
        Distortion::KannalaBrandt { k1: -0.02, k2: 0.01, k3: -0.004, k4: 0.001 },
    ]
}

/// Gradient checker (the least-squares layer's, shared by every residual of the project): every
/// column of the bundle residual's analytic Jacobians (camera free parameters, rig extrinsics,
/// target pose; increments away from zero) against central differences, for every lens model,
/// with and without a fixed aspect ratio, for camera 0 and for a second camera.
#[test]
fn residual_jacobians_match_finite_differences() {
    use ferrocal_lsq::check::check_residual;
    use ferrocal_lsq::{Euclidean, Manifold};
    use std::sync::Arc;
    let x = Point3::new(0.07, -0.04, 0.0);
    let pixel = Point2::new(300.0, 200.0);
    let ext = LocalPose::from_isometry(&nalgebra::Isometry3::new(
        Vector3::new(-0.3, 0.02, 0.01),
        Vector3::new(0.01, -0.2, 0.05),
    ));
    let ext_block = [-0.3, 0.02, 0.01, 0.01, -0.02, 0.03];
    let view =
        LocalPose::from_isometry(&nalgebra::Isometry3::new(Vector3::new(0.1, 0.0, 0.6), Vector3::new(2.9, 0.2, -0.1)));
    let view_block = [0.1, 0.0, 0.6, 0.2, -0.1, 0.05];
    for d in distortions() {
        for fix_aspect in [false, true] {
            for second_camera in [false, true] {
                let cam = camera(d);
                let layout = CameraLayout { kind: d.kind(), fix_aspect, aspect: 1.0, image_size: cam.image_size };
                let free = layout.free_from_model(&cam);
                let residual = CornerResidual {
                    layout,
                    ext_ref: second_camera.then_some(ext.r_ref),
                    view_ref: view.r_ref,
                    point: x,
                    pixel,
                    deform: None,
                };
                let mut params: Vec<&[f64]> = vec![&free];
                let mut manifolds: Vec<Arc<dyn Manifold>> = vec![Arc::new(Euclidean { n: free.len() })];
                let mut scales = vec![free.iter().map(|v| v.abs().max(1.0)).collect::<Vec<f64>>()];
                if second_camera {
                    params.push(&ext_block);
                    manifolds.push(Arc::new(Euclidean { n: 6 }));
                    scales.push(vec![0.1; 6]);
                }
                params.push(&view_block);
                manifolds.push(Arc::new(Euclidean { n: 6 }));
                scales.push(vec![0.1; 6]);
                let report = check_residual(&residual, &params, &manifolds, &scales, 1e-6).unwrap();
                report
                    .assert_below(2e-5, &format!("{d:?}, fixed aspect {fix_aspect}, second camera {second_camera}"))
                    .unwrap();
                assert!(report.entries > 20);
            }
        }
    }
}

/// Gradient checker on the bundle residual with the target's blocks: the shape block
/// `[b, s, t]` and the print-scale block `[e_x]` free alone and together (and held at non-zero
/// values when not free), beside the camera, rig extrinsics and view blocks, for every lens
/// model, at a point off the target's centre and axes, with non-zero increments.
#[test]
fn deformed_target_residual_jacobians_match_finite_differences() {
    use ferrocal_lsq::check::check_residual;
    use ferrocal_lsq::{Euclidean, Manifold};
    use std::sync::Arc;
    let target = PlanarTarget::chessboard(9, 6, 0.025);
    let base = TargetDeformation::of_points(&target.points_m).unwrap();
    assert!((base.centre_m[0] - 0.1).abs() < 1e-12 && (base.centre_m[1] - 0.0625).abs() < 1e-12);
    assert!((base.half_m - 0.1).abs() < 1e-12);
    let x = target.points_m[11];
    let pixel = Point2::new(300.0, 200.0);
    let ext = LocalPose::from_isometry(&nalgebra::Isometry3::new(
        Vector3::new(-0.3, 0.02, 0.01),
        Vector3::new(0.01, -0.2, 0.05),
    ));
    let ext_block = [-0.3, 0.02, 0.01, 0.01, -0.02, 0.03];
    let view = LocalPose::from_isometry(&nalgebra::Isometry3::new(
        Vector3::new(-0.05, -0.08, 0.6),
        Vector3::new(2.9, 0.2, -0.1),
    ));
    let view_block = [-0.05, -0.08, 0.6, 0.2, -0.1, 0.05];
    let shape_block = [0.0012, -0.0007, 0.0004];
    let scale_block = [0.004];
    for d in distortions() {
        for (shape_free, scale_free) in [(true, false), (false, true), (true, true)] {
            for second_camera in [false, true] {
                let cam = camera(d);
                let layout =
                    CameraLayout { kind: d.kind(), fix_aspect: false, aspect: 1.0, image_size: cam.image_size };
                let free = layout.free_from_model(&cam);
                let deform = TargetDeformation {
                    shape_m: [0.0008, 0.0003, -0.0002],
                    scale: [-0.002, 0.0015],
                    shape_free,
                    scale_free,
                    ..base
                };
                let residual = CornerResidual {
                    layout,
                    ext_ref: second_camera.then_some(ext.r_ref),
                    view_ref: view.r_ref,
                    point: x,
                    pixel,
                    deform: Some(deform),
                };
                let mut params: Vec<&[f64]> = vec![&free];
                let mut manifolds: Vec<Arc<dyn Manifold>> = vec![Arc::new(Euclidean { n: free.len() })];
                let mut scales = vec![free.iter().map(|v| v.abs().max(1.0)).collect::<Vec<f64>>()];
                if second_camera {
                    params.push(&ext_block);
                    manifolds.push(Arc::new(Euclidean { n: 6 }));
                    scales.push(vec![0.1; 6]);
                }
                if shape_free {
                    params.push(&shape_block);
                    manifolds.push(Arc::new(Euclidean { n: 3 }));
                    scales.push(vec![1e-3; 3]);
                }
                if scale_free {
                    params.push(&scale_block);
                    manifolds.push(Arc::new(Euclidean { n: 1 }));
                    scales.push(vec![1e-2]);
                }
                params.push(&view_block);
                manifolds.push(Arc::new(Euclidean { n: 6 }));
                scales.push(vec![0.1; 6]);
                let report = check_residual(&residual, &params, &manifolds, &scales, 1e-6).unwrap();
                let what =
                    format!("{d:?}, shape free {shape_free}, scale free {scale_free}, second camera {second_camera}");
                report.assert_below(2e-5, &what).unwrap();
                // The target's columns are not zero (the check would pass trivially otherwise).
                let mut out = [0.0; 2];
                let mut jacs: Vec<Option<DMatrix<f64>>> =
                    manifolds.iter().map(|m| Some(DMatrix::zeros(2, m.tangent_size()))).collect();
                ferrocal_lsq::Residual::evaluate(&residual, &params, &mut out, Some(&mut jacs)).unwrap();
                let first_target = 1 + usize::from(second_camera);
                for j in &jacs[first_target..jacs.len() - 1] {
                    assert!(j.as_ref().unwrap().norm() > 1e-3, "{what}: zero Jacobian of a target block");
                }
            }
        }
    }
}

#[test]
fn zhang_recovers_an_exact_pinhole() {
    let cam = camera(Distortion::None);
    let target = PlanarTarget::chessboard(8, 6, 0.03);
    let poses = [
        nalgebra::Isometry3::new(Vector3::new(-0.1, -0.07, 0.5), Vector3::new(0.4, 0.2, 0.1)),
        nalgebra::Isometry3::new(Vector3::new(-0.05, -0.1, 0.6), Vector3::new(-0.3, 0.35, -0.2)),
        nalgebra::Isometry3::new(Vector3::new(-0.12, -0.05, 0.55), Vector3::new(0.1, -0.45, 0.3)),
        nalgebra::Isometry3::new(Vector3::new(-0.08, -0.08, 0.45), Vector3::new(-0.25, -0.2, 0.0)),
    ];
    let hs: Vec<Matrix3<f64>> = poses
        .iter()
        .map(|t| {
            let src: Vec<Point2<f64>> = target.points_m.iter().map(|p| Point2::new(p.x, p.y)).collect();
            let dst: Vec<Point2<f64>> = target.points_m.iter().map(|p| cam.project(&(t * p)).unwrap()).collect();
            crate::pose::homography::homography_dlt(&src, &dst).unwrap()
        })
        .collect();
    for fix in [false, true] {
        let z = zhang::zhang_intrinsics(&hs, cam.image_size, fix);
        assert!(!z.fallback);
        assert!(z.condition > 0.01, "condition {}", z.condition);
        let k = z.intrinsics;
        if fix {
            // fx != fy in the truth: the fixed-aspect solution lies between them.
            assert!(k.fx_px > 800.0 && k.fx_px < 818.0, "{k:?}");
        } else {
            assert!((k.fx_px - 812.0).abs() < 1e-6 && (k.fy_px - 806.0).abs() < 1e-6, "{k:?}");
            assert!((k.cx_px - 331.0).abs() < 1e-6 && (k.cy_px - 247.0).abs() < 1e-6, "{k:?}");
            for (h, t) in hs.iter().zip(&poses) {
                let p = zhang::extrinsics_from_homography(h, &k).unwrap();
                assert!((p.translation.vector - t.translation.vector).norm() < 1e-9);
            }
        }
    }
    // Two views of parallel boards: no solution.
    let par = [poses[0], poses[0] * nalgebra::Translation3::new(0.02, 0.01, 0.1)];
    let hp: Vec<Matrix3<f64>> = par
        .iter()
        .map(|t| {
            let src: Vec<Point2<f64>> = target.points_m.iter().map(|p| Point2::new(p.x, p.y)).collect();
            let dst: Vec<Point2<f64>> = target.points_m.iter().map(|p| cam.project(&(t * p)).unwrap()).collect();
            crate::pose::homography::homography_dlt(&src, &dst).unwrap()
        })
        .collect();
    assert!(zhang::zhang_intrinsics(&hp, cam.image_size, false).condition < 1e-6);
}

#[test]
fn pattern_strings_give_the_chessboard_target() {
    let p: Pattern = "chessboard:9x6:25mm".parse().unwrap();
    assert_eq!(p.to_string(), "chessboard:9x6:25mm");
    let t = PlanarTarget::of_pattern(&p).unwrap();
    assert_eq!(t.points_m.len(), 54);
    assert_eq!(t.points_m[10], Point3::new(0.025, 0.025, 0.0));
    assert_eq!(t, PlanarTarget::chessboard(9, 6, 0.025));
    let t = PlanarTarget::of_pattern(&"chessboard:7X5:3cm".parse().unwrap()).unwrap();
    assert_eq!(t.points_m.len(), 35);
    assert!((t.points_m[1].x - 0.03).abs() < 1e-15);
    for bad in
        ["chessboard:9x6", "chessboard:9x6:25", "chessboard:1x6:25mm", "chessboard:9x6:-2mm", "circles:4x11:20mm"]
    {
        let e = bad.parse::<Pattern>().unwrap_err();
        assert!(matches!(e, VisionError::PatternSyntax { .. }), "{bad}: {e}");
        assert!(e.to_string().contains(bad), "{e}");
    }
    for bad in ["charuco:5x7:36mm:40mm:DICT_6X6_250", "circlegrid:4x11:20mm:asymmetric"] {
        let e = bad.parse::<Pattern>().unwrap_err();
        assert!(matches!(e, VisionError::PatternSyntax { .. }), "{bad}: {e}");
    }
    let e = PlanarTarget::of_pattern(&"apriltag:36h11".parse().unwrap()).unwrap_err().to_string();
    assert!(e.contains("apriltag:tag36h11") && e.contains("not calibration targets"), "{e}");
    let c = CalibrationPattern::parse("charuco:5x7:36.195mm:18.256mm:DICT_6X6_250").unwrap();
    assert_eq!(c.to_string(), "charuco:5x7:36.195mm:18.256mm:DICT_6X6_250");
    assert_eq!(c.target().points_m.len(), 24);
    assert!(!c.target().reversible);
    let g = CalibrationPattern::parse("circlegrid:10x10:25.4mm:modified").unwrap();
    assert_eq!(g.to_string(), "circlegrid:10x10:25.4mm:modified");
    assert_eq!(g.target().points_m.len(), 100);
    assert_eq!(
        CalibrationPattern::parse("chessboard:9x6:25mm").unwrap(),
        CalibrationPattern::Chessboard { inner_cols: 9, inner_rows: 6, square_m: 0.025 }
    );
}

#[test]
fn robust_loss_strings_and_weights() {
    assert_eq!(RobustLoss::parse("none").unwrap(), RobustLoss::None);
    assert_eq!(RobustLoss::parse("huber:1.5").unwrap(), RobustLoss::Huber { scale_px: 1.5 });
    assert_eq!(RobustLoss::parse("Cauchy:0.5px").unwrap(), RobustLoss::Cauchy { scale_px: 0.5 });
    assert!(RobustLoss::parse("huber:-1").is_err() && RobustLoss::parse("tukey:1").is_err());
    assert_eq!(bundle::loss_weight(RobustLoss::Huber { scale_px: 1.0 }, 0.25), 1.0);
    assert!((bundle::loss_weight(RobustLoss::Huber { scale_px: 1.0 }, 4.0) - 0.5).abs() < 1e-12);
    assert!((bundle::loss_weight(RobustLoss::Cauchy { scale_px: 1.0 }, 1.0) - 0.5).abs() < 1e-12);
    let _ = DistortionKind::Brown5;
}
