//! The public bundle adjustment with the target's blocks (`adjust_bundle`) on exact simulated
//! corners. The simulated target is bent and printed to a wrong scale by the test's own
//! arithmetic, but with the same model family (bowl, saddle, twist over the half-size; scale
//! about the centroid) the estimator uses, so these tests check the solver, the parameter
//! meanings and the documented identifiability, not that the model fits real targets.

use crate::calib_support;

use calib_support as sim;
use ferrocal_vision::calib::{
    adjust_bundle, calibrate_camera, BundleMode, BundleModel, BundleSpec, CalibrationOptions, PlanarTarget, PrintScale,
    TargetShape, View,
};
use ferrocal_vision::camera::DistortionKind;
use nalgebra::{Isometry3, Point3};

/// The points a bent, mis-printed 9x6 board (25 mm) really has, computed here from the
/// documented model: `(x0 + (1 + ex) dx, y0 + (1 + ey) dy, b (u^2+v^2) + s (u^2-v^2) + t u v)`.
fn printed_board(shape: [f64; 3], ex: f64, ey: f64) -> (PlanarTarget, PlanarTarget) {
    let nominal = PlanarTarget::chessboard(9, 6, 0.025);
    let (x0, y0, h) = (0.1, 0.0625, 0.1);
    let points = nominal
        .points_m
        .iter()
        .map(|p| {
            let (dx, dy) = (p.x - x0, p.y - y0);
            let (u, v) = (dx / h, dy / h);
            Point3::new(
                x0 + (1.0 + ex) * dx,
                y0 + (1.0 + ey) * dy,
                shape[0] * (u * u + v * v) + shape[1] * (u * u - v * v) + shape[2] * u * v,
            )
        })
        .collect();
    (nominal, PlanarTarget { points_m: points, reversible: false })
}

/// Exact views of the real board (the nominal board keeps the poses in view).
fn views_of(real: &PlanarTarget, nominal: &PlanarTarget, seed: u64, n: usize) -> (Vec<View>, Vec<Isometry3<f64>>) {
    let camera = sim::vga_camera();
    let mut rng = sim::rng(seed);
    let mut views = Vec::new();
    let mut poses = Vec::new();
    while views.len() < n {
        let mut t = sim::random_calibration_pose(&mut rng, &camera, nominal, (0.35, 0.6), (15.0, 40.0));
        // Turn every other board by 90 deg in its plane, as one does when calibrating (it
        // separates the target's x/y scale from the camera's fx/fy).
        if views.len() % 2 == 1 {
            let c = sim::centre(nominal);
            t = t
                * Isometry3::translation(c.x, c.y, 0.0)
                * Isometry3::rotation(nalgebra::Vector3::z() * std::f64::consts::FRAC_PI_2)
                * Isometry3::translation(-c.x, -c.y, 0.0);
            if !sim::fully_visible(&camera, nominal, &t, 5.0) {
                continue;
            }
        }
        let v = sim::observe(&mut rng, &format!("view{}", views.len()), &camera, real, &t, 0.0);
        if v.corners_px.len() == real.points_m.len() {
            views.push(v);
            poses.push(t);
        }
    }
    (views, poses)
}

#[test]
fn a_bent_misprinted_target_is_recovered_exactly() {
    let truth_shape = [0.0009, -0.0004, 0.0003];
    let (nominal, real) = printed_board(truth_shape, 0.004, 0.0);
    let (views, poses) = views_of(&real, &nominal, 11, 12);
    // Start from the calibration with a flat, nominal target (biased by the effects).
    let cal = calibrate_camera(&views, &nominal, &CalibrationOptions::default()).unwrap();
    let start: Vec<Isometry3<f64>> = cal.views.iter().map(|v| v.t_cam_target).collect();
    let spec = BundleSpec { estimate_shape: true, estimate_print_scale: true, covariance: true, ..Default::default() };
    let fit = adjust_bundle(&views, &nominal, &BundleModel::new(cal.camera), Some(&start), &spec).unwrap();
    println!("flat calibration RMS {:.4} px; adjusted {:.2e} px; {:?}", cal.rms_px, fit.rms_px, fit.model);
    assert!(cal.rms_px > 0.05, "the effects must show: {}", cal.rms_px);
    assert!(fit.rms_px < 1e-6, "exact data: RMS {}", fit.rms_px);
    let s = fit.model.shape;
    for (est, truth) in [s.bowl_m, s.saddle_m, s.twist_m].iter().zip(truth_shape) {
        assert!((est - truth).abs() < 1e-8, "shape {s:?}");
    }
    assert!((fit.model.print_scale.x - 0.004).abs() < 1e-9, "{:?}", fit.model.print_scale);
    assert_eq!(fit.model.print_scale.y, 0.0);
    let truth = sim::vga_camera().parameters();
    for (e, t) in fit.model.camera.parameters().iter().zip(&truth) {
        assert!((e.value - t.value).abs() < 1e-6 * t.value.abs().max(1.0), "{}: {} vs {}", e.name, e.value, t.value);
    }
    for (v, t) in fit.views.iter().zip(&poses) {
        assert!((v.t_cam_target.translation.vector - t.translation.vector).norm() < 1e-8);
    }
    // Names and a covariance over them (exact data: s0 is ~0, so only its shape is checked).
    assert_eq!(fit.parameter_names.len(), 9 + 3 + 1);
    assert_eq!(fit.parameter_names.last().map(String::as_str), Some("print_scale_x"));
    assert_eq!(fit.covariance.as_ref().map(|c| c.nrows()), Some(13), "{:?}", fit.covariance_note);
}

#[test]
fn only_the_ratio_of_the_print_scales_is_seen_and_it_is_reported_against_y() {
    // The truth stretches x by 0.3 % and y by 0.1 %: the images show (1.003 / 1.001) along x
    // and a board 0.1 % larger, i.e. every view 0.1 % farther away.
    let (nominal, real) = printed_board([0.0; 3], 0.003, 0.001);
    let (views, poses) = views_of(&real, &nominal, 12, 10);
    let cal = calibrate_camera(&views, &nominal, &CalibrationOptions::default()).unwrap();
    let start: Vec<Isometry3<f64>> = cal.views.iter().map(|v| v.t_cam_target).collect();
    let spec = BundleSpec { estimate_print_scale: true, ..Default::default() };
    let fit = adjust_bundle(&views, &nominal, &BundleModel::new(cal.camera), Some(&start), &spec).unwrap();
    let ratio = 1.003 / 1.001 - 1.0;
    assert!((fit.model.print_scale.x - ratio).abs() < 1e-9, "{} vs {ratio}", fit.model.print_scale.x);
    assert!(fit.rms_px < 1e-6);
    for (v, t) in fit.views.iter().zip(&poses) {
        // Poses of the nominal frame: the board's centroid, 0.1 % larger, appears farther by
        // the same factor (the views' centroids in the camera frame scale by 1 / 1.001).
        let c = sim::centre(&nominal);
        let est = v.t_cam_target * Point3::from(c);
        let truth = t * Point3::from(c);
        assert!((est.coords * 1.001 - truth.coords).norm() < 1e-8, "{est:?} vs {truth:?}");
    }
}

#[test]
fn poses_only_refits_held_out_views_with_the_model_held() {
    let truth_shape = [0.0006, 0.0002, -0.0001];
    let (nominal, real) = printed_board(truth_shape, -0.003, 0.0);
    let (views, poses) = views_of(&real, &nominal, 13, 4);
    let model = BundleModel {
        camera: sim::vga_camera(),
        shape: TargetShape { bowl_m: truth_shape[0], saddle_m: truth_shape[1], twist_m: truth_shape[2] },
        print_scale: PrintScale { x: -0.003, y: 0.0 },
    };
    let spec = BundleSpec { mode: BundleMode::PosesOnly, covariance: true, ..Default::default() };
    // Starting from the closed-form poses (no poses given).
    let fit = adjust_bundle(&views, &nominal, &model, None, &spec).unwrap();
    assert_eq!(fit.model, model, "the held model must come back unchanged");
    assert!(fit.parameter_names.is_empty() && fit.covariance.is_none());
    for (v, t) in fit.views.iter().zip(&poses) {
        assert!(v.rms_px < 1e-7, "{}: {}", v.name, v.rms_px);
        assert!((v.t_cam_target.translation.vector - t.translation.vector).norm() < 1e-9);
        assert!(v.t_cam_target.rotation.angle_to(&t.rotation) < 1e-9);
        assert!(v.covariance.is_some());
    }
    // One view at a time: the result of a view does not depend on the others.
    let alone = adjust_bundle(&views[2..3], &nominal, &model, None, &spec).unwrap();
    assert_eq!(alone.views[0].t_cam_target, fit.views[2].t_cam_target);
    // The wrong model leaves residuals.
    let flat = adjust_bundle(&views, &nominal, &BundleModel::new(sim::vga_camera()), None, &spec).unwrap();
    assert!(flat.rms_px > 0.05, "{}", flat.rms_px);
}

#[test]
fn a_lens_change_starts_from_the_shared_coefficients_and_bad_input_is_named() {
    let (nominal, real) = printed_board([0.0; 3], 0.0, 0.0);
    let (views, _) = views_of(&real, &nominal, 14, 8);
    let cal = calibrate_camera(&views, &nominal, &CalibrationOptions::default()).unwrap();
    let start: Vec<Isometry3<f64>> = cal.views.iter().map(|v| v.t_cam_target).collect();
    let spec = BundleSpec { lens: Some(DistortionKind::Rational8), ..Default::default() };
    let fit = adjust_bundle(&views, &nominal, &BundleModel::new(cal.camera), Some(&start), &spec).unwrap();
    assert_eq!(fit.model.camera.distortion.kind(), DistortionKind::Rational8);
    assert!(fit.rms_px < 1e-4, "{}", fit.rms_px);
    let e = adjust_bundle(&views, &nominal, &BundleModel::new(cal.camera), Some(&start[1..]), &spec).unwrap_err();
    assert!(e.to_string().contains("7 starting poses for 8 views"), "{e}");
    let tilted = PlanarTarget {
        points_m: nominal.points_m.iter().map(|p| Point3::new(p.x, p.y, 0.01 * p.x)).collect(),
        reversible: false,
    };
    let shape = BundleSpec { estimate_shape: true, ..Default::default() };
    let e = adjust_bundle(&views, &tilted, &BundleModel::new(cal.camera), Some(&start), &shape).unwrap_err();
    assert!(e.to_string().contains("z = 0 plane"), "{e}");
}
