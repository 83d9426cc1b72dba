//! Tests of the camera models: round trips, Jacobians against finite differences, OpenCV parity.

use super::*;
use nalgebra::{Point2, Point3, Vector3};

/// OpenCV's stereo sample, left camera (as in the brief).
pub(crate) fn opencv_sample_left() -> CameraModel {
    CameraModel::new(
        Intrinsics { fx_px: 535.9157, fy_px: 535.9157, cx_px: 342.2832, cy_px: 235.5708 },
        Distortion::Brown5 { k1: -0.26637, k2: -0.038589, p1: 0.0017832, p2: -0.00028122, k3: 0.23839 },
        ImageSize { width_px: 640, height_px: 480 },
    )
    .unwrap()
}

/// A wide-angle lens in OpenCV's rational model (k1 and k4 large and close, as calibrations of
/// such lenses give).
fn rational_wide() -> CameraModel {
    CameraModel::new(
        Intrinsics { fx_px: 610.2, fy_px: 609.7, cx_px: 641.3, cy_px: 398.9 },
        Distortion::Rational8 {
            k1: 1.9372,
            k2: 0.4415,
            p1: 3.1e-4,
            p2: -1.7e-4,
            k3: 0.0123,
            k4: 2.2687,
            k5: 0.9513,
            k6: 0.0781,
        },
        ImageSize { width_px: 1280, height_px: 800 },
    )
    .unwrap()
}

/// A fisheye lens (about 150 degrees across the diagonal) in the Kannala-Brandt model.
fn fisheye() -> CameraModel {
    CameraModel::new(
        Intrinsics { fx_px: 300.4, fy_px: 300.1, cx_px: 319.7, cy_px: 241.2 },
        Distortion::KannalaBrandt { k1: -0.0135, k2: 0.0120, k3: -0.0085, k4: 0.0017 },
        ImageSize { width_px: 640, height_px: 480 },
    )
    .unwrap()
}

fn pinhole() -> CameraModel {
    let mut c = opencv_sample_left();
    c.distortion = Distortion::None;
    c
}

fn all_cameras() -> Vec<(&'static str, CameraModel)> {
    vec![
        ("pinhole", pinhole()),
        ("brown5 (OpenCV sample)", opencv_sample_left()),
        ("rational8", rational_wide()),
        ("kannala-brandt", fisheye()),
    ]
}

/// Pixels on a grid over the whole image, including the outer edges of the border pixels.
fn image_grid(cam: &CameraModel, step_px: f64) -> Vec<Point2<f64>> {
    let w = cam.image_size.width_px as f64;
    let h = cam.image_size.height_px as f64;
    let mut out = Vec::new();
    let mut v = -0.5;
    loop {
        let mut u = -0.5;
        loop {
            out.push(Point2::new(u, v));
            if u >= w - 0.5 {
                break;
            }
            u = (u + step_px).min(w - 0.5);
        }
        if v >= h - 0.5 {
            break;
        }
        v = (v + step_px).min(h - 0.5);
    }
    out
}

fn max_round_trip_error_px(cam: &CameraModel, step_px: f64) -> f64 {
    let mut worst: f64 = 0.0;
    for px in image_grid(cam, step_px) {
        let ray = cam.unproject(&px).unwrap_or_else(|e| panic!("{px}: {e}"));
        assert!((ray.norm() - 1.0).abs() < 1e-14);
        let back = cam.project(&Point3::from(ray * 2.5)).unwrap();
        worst = worst.max((back - px).norm());
        if ray.z > 0.0 {
            let n = cam.unproject_normalized(&px).unwrap();
            let back = cam.project_normalized(&n).unwrap();
            worst = worst.max((back - px).norm());
        }
    }
    worst
}

#[test]
fn unproject_project_round_trip_below_1e_9_px_over_the_whole_image() {
    for (name, cam) in all_cameras() {
        let worst = max_round_trip_error_px(&cam, 1.0);
        println!("{name}: worst round-trip error {worst:.2e} px");
        assert!(worst < 1e-9, "{name}: {worst:e} px");
    }
}

#[test]
fn project_unproject_round_trip_of_points() {
    // Points inside the field of view, at several depths; Kannala-Brandt also beyond 90 deg.
    for (name, cam) in all_cameras() {
        let fov = cam.max_field_angle_rad();
        for i in 0..200 {
            let a = i as f64 * 0.7;
            let theta = (i as f64 / 200.0) * fov.min(1.2) * 0.95;
            let dir = Vector3::new(theta.sin() * a.cos(), theta.sin() * a.sin(), theta.cos());
            let p = Point3::from(dir * (0.3 + (i % 7) as f64));
            let px = cam.project(&p).unwrap();
            let ray = cam.unproject(&px).unwrap();
            assert!((ray - dir).norm() < 1e-12, "{name}: {dir} vs {ray}");
        }
    }
    let cam = fisheye();
    for deg in [95.0f64, 110.0, 130.0] {
        let t = deg.to_radians();
        let dir = Vector3::new(t.sin() * 0.6, t.sin() * 0.8, t.cos());
        let px = cam.project(&Point3::from(dir)).unwrap();
        let ray = cam.unproject(&px).unwrap();
        assert!((ray - dir).norm() < 1e-12, "{deg} deg");
        assert!(cam.unproject_normalized(&px).is_err());
    }
}

fn sample_points(cam: &CameraModel) -> Vec<Point3<f64>> {
    let mut pts = Vec::new();
    for (i, px) in image_grid(cam, 97.0).into_iter().enumerate() {
        let ray = cam.unproject(&px).unwrap();
        pts.push(Point3::from(ray * (0.4 + 0.37 * (i % 5) as f64)));
    }
    pts
}

#[test]
fn jacobians_match_central_differences() {
    for (name, cam) in all_cameras() {
        let mut pts = sample_points(&cam);
        // On and next to the optical axis (the Kannala-Brandt series branch).
        pts.push(Point3::new(0.0, 0.0, 1.3));
        pts.push(Point3::new(3e-9, -2e-9, 0.9));
        pts.push(Point3::new(2e-7, 1e-7, 1.1));
        for p in pts {
            let j = cam.project_with_jacobians(&p).unwrap();
            assert!((j.pixel - cam.project(&p).unwrap()).norm() == 0.0);
            // Point Jacobian.
            let h = 1e-6 * p.coords.norm().max(1e-3);
            for c in 0..3 {
                let mut pp = p;
                let mut pm = p;
                pp[c] += h;
                pm[c] -= h;
                let num = (cam.project(&pp).unwrap() - cam.project(&pm).unwrap()) / (2.0 * h);
                for r in 0..2 {
                    let a = j.d_pixel_d_point[(r, c)];
                    let tol = 1e-6 * (1.0 + a.abs());
                    assert!(
                        (a - num[r]).abs() < tol,
                        "{name}: d pixel[{r}]/d p[{c}] at {p}: analytic {a}, numeric {}",
                        num[r]
                    );
                }
            }
            // Parameter Jacobian.
            let values = cam.parameter_values();
            let names = cam.parameters();
            for k in 0..values.len() {
                let h = 1e-6 * values[k].abs().max(1.0);
                let mut plus = cam;
                let mut minus = cam;
                let mut vp = values.clone();
                let mut vm = values.clone();
                vp[k] += h;
                vm[k] -= h;
                plus.set_parameter_values(&vp).unwrap();
                minus.set_parameter_values(&vm).unwrap();
                let num = (plus.project(&p).unwrap() - minus.project(&p).unwrap()) / (2.0 * h);
                for r in 0..2 {
                    let a = j.d_pixel_d_params[(r, k)];
                    let tol = 1e-6 * (1.0 + a.abs());
                    assert!(
                        (a - num[r]).abs() < tol,
                        "{name}: d pixel[{r}]/d {} at {p}: analytic {a}, numeric {}",
                        names[k].name,
                        num[r]
                    );
                }
            }
        }
    }
}

#[test]
fn kannala_brandt_axis_series_is_continuous() {
    let cam = fisheye();
    // Just below and above the switch at rho = 1e-7 Z.
    let below = cam.project_with_jacobians(&Point3::new(0.99e-7, 0.0, 1.0)).unwrap();
    let above = cam.project_with_jacobians(&Point3::new(1.01e-7, 0.0, 1.0)).unwrap();
    let du = above.pixel.x - below.pixel.x;
    assert!((du - 0.02e-7 * cam.intrinsics.fx_px).abs() < 1e-12);
    assert!((above.d_pixel_d_point - below.d_pixel_d_point).norm() < 1e-6);
}

#[test]
fn parameter_vector_names_order_and_validation() {
    let mut cam = rational_wide();
    let names: Vec<_> = cam.parameters().iter().map(|p| p.name).collect();
    assert_eq!(names, ["fx_px", "fy_px", "cx_px", "cy_px", "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"]);
    assert_eq!(cam.parameter_index("p2"), Some(7));
    assert_eq!(cam.n_parameters(), 12);
    let before = cam;
    let mut v = cam.parameter_values();
    v[0] = -1.0;
    assert!(matches!(cam.set_parameter_values(&v), Err(VisionError::BadCameraParameter { .. })));
    assert!(matches!(cam.set_parameter_values(&v[..3]), Err(VisionError::ParameterCount { expected: 12, got: 3 })));
    v[0] = f64::NAN;
    assert!(cam.set_parameter_values(&v).is_err());
    assert_eq!(cam, before, "a rejected update leaves the model unchanged");
    v[0] = 600.0;
    v[9] = 2.0;
    cam.set_parameter_values(&v).unwrap();
    assert_eq!(cam.parameter_values(), v);
    let kb: Vec<_> = fisheye().parameters().iter().map(|p| p.name).collect();
    assert_eq!(kb, ["fx_px", "fy_px", "cx_px", "cy_px", "k1", "k2", "k3", "k4"]);
}

#[test]
fn bad_inputs_are_errors_not_panics() {
    let cam = opencv_sample_left();
    assert!(matches!(cam.project(&Point3::new(0.1, 0.2, -1.0)), Err(VisionError::NotProjectable { .. })));
    assert!(cam.project(&Point3::new(0.0, 0.0, 0.0)).is_err());
    assert!(cam.project(&Point3::new(f64::NAN, 0.0, 1.0)).is_err());
    assert!(cam.unproject(&Point2::new(f64::INFINITY, 0.0)).is_err());
    // Strong barrel distortion r_d = r - 0.4 r^3 peaks at r_d = 0.608 (r = 0.913): a pixel
    // beyond that radius has no preimage and is reported, not answered.
    let mut folding = cam;
    folding.distortion = Distortion::Brown5 { k1: -0.4, k2: 0.0, p1: 0.0, p2: 0.0, k3: 0.0 };
    let k = cam.intrinsics;
    let far = folding.unproject(&Point2::new(k.cx_px + 0.7 * k.fx_px, k.cy_px));
    assert!(matches!(far, Err(VisionError::UnprojectionFailed { .. })), "{far:?}");
    let fov = folding.max_field_angle_rad();
    assert!((fov.tan() - (1.0f64 / 1.2).sqrt()).abs() < 1e-9, "{fov}");
    assert!(folding.unproject(&Point2::new(k.cx_px + 0.6 * k.fx_px, k.cy_px)).is_ok());
    let kb = fisheye();
    assert!(kb.project(&Point3::new(0.0, 0.0, -1.0)).is_err());
    assert!(kb.project(&Point3::new(0.0, 0.0, 0.0)).is_err());
    let bad = CameraModel::new(
        cam.intrinsics,
        Distortion::Brown5 { k1: f64::NAN, k2: 0.0, p1: 0.0, p2: 0.0, k3: 0.0 },
        cam.image_size,
    );
    assert!(bad.is_err());
}

#[test]
fn field_of_view_limits() {
    use std::f64::consts::{FRAC_PI_2, PI};
    assert_eq!(pinhole().max_field_angle_rad(), FRAC_PI_2);
    // The OpenCV sample's radial polynomial 1 + 3 k1 r^2 + 5 k2 r^4 + 7 k3 r^6 stays positive
    // (minimum 0.75 at r^2 = 0.44): one-to-one over the whole half-space.
    assert_eq!(opencv_sample_left().max_field_angle_rad(), FRAC_PI_2);
    // The rational wide-angle lens folds, but beyond its image corners.
    let wide = rational_wide();
    let fov = wide.max_field_angle_rad();
    let corner = wide.unproject(&Point2::new(-0.5, -0.5)).unwrap();
    assert!(fov > corner.z.acos(), "{fov} {}", corner.z.acos());
    let kb = fisheye().max_field_angle_rad();
    assert!(kb > 1.4 && kb <= PI);
}

/// Projects the same points with OpenCV's `projectPoints` / `fisheye::projectPoints` and
/// compares pixels (1e-9 px) and Jacobians (relative 1e-9).
#[test]
fn parity_with_opencv_project_points() {
    use opencv::core::{Mat, Point2d, Point3d, Vector};
    use opencv::prelude::*;

    let mut worst_px: f64 = 0.0;
    let mut worst_jac: f64 = 0.0;
    for (name, cam) in all_cameras() {
        let pts = sample_points(&cam);
        let object: Vector<Point3d> = pts.iter().map(|p| Point3d::new(p.x, p.y, p.z)).collect();
        let k = &cam.intrinsics;
        let kmat = Mat::from_slice_2d(&[[k.fx_px, 0.0, k.cx_px], [0.0, k.fy_px, k.cy_px], [0.0, 0.0, 1.0]]).unwrap();
        let coeffs = cam.distortion.coefficients();
        let dist: Vector<f64> = coeffs.iter().copied().collect();
        let zero: Vector<f64> = Vector::from_slice(&[0.0, 0.0, 0.0]);
        let mut image: Vector<Point2d> = Vector::new();
        let mut jac = Mat::default();
        // Columns of OpenCV's Jacobian that correspond to (point, fx fy cx cy, coefficients).
        let (point_cols, param_cols): (Vec<i32>, Vec<i32>) = match cam.distortion.kind() {
            DistortionKind::KannalaBrandt => {
                opencv::calib3d::fisheye_project_points_vec(
                    &object, &mut image, &zero, &zero, &kmat, &dist, 0.0, &mut jac,
                )
                .unwrap();
                // OpenCV's JacobianRow: [f(2), c(2), k(4), om(3), T(3), alpha]
                (vec![11, 12, 13], (0..8).collect())
            }
            _ => {
                opencv::calib3d::project_points(&object, &zero, &zero, &kmat, &dist, &mut image, &mut jac, 0.0)
                    .unwrap();
                // [rvec(3), tvec(3), f(2), c(2), dist(n)]
                (vec![3, 4, 5], (6..10 + coeffs.len() as i32).collect())
            }
        };
        assert_eq!(image.len(), pts.len());
        for (i, p) in pts.iter().enumerate() {
            let ours = cam.project_with_jacobians(p).unwrap();
            let theirs = image.get(i).unwrap();
            let err = (ours.pixel - Point2::new(theirs.x, theirs.y)).norm();
            worst_px = worst_px.max(err);
            assert!(err < 1e-9, "{name}: point {p}: {} vs {theirs:?}", ours.pixel);
            for r in 0..2 {
                let row = (2 * i + r) as i32;
                let mut check = |a: f64, col: i32| {
                    let b = *jac.at_2d::<f64>(row, col).unwrap();
                    let rel = (a - b).abs() / (1.0 + a.abs());
                    worst_jac = worst_jac.max(rel);
                    assert!(rel < 1e-9, "{name}: row {row} col {col}: {a} vs {b}");
                };
                for (c, col) in point_cols.iter().enumerate() {
                    check(ours.d_pixel_d_point[(r, c)], *col);
                }
                for (c, col) in param_cols.iter().enumerate() {
                    check(ours.d_pixel_d_params[(r, c)], *col);
                }
            }
        }
    }
    println!(
        "OpenCV parity: worst pixel difference {worst_px:.2e} px, worst relative Jacobian difference {worst_jac:.2e}"
    );
}

#[test]
fn a_lens_change_keeps_the_shared_coefficients() {
    let b = Distortion::Brown5 { k1: -0.2, k2: 0.05, p1: 0.001, p2: -0.002, k3: 0.01 };
    assert_eq!(b.converted(DistortionKind::Brown5), b);
    assert_eq!(
        b.converted(DistortionKind::Rational8).coefficients(),
        vec![-0.2, 0.05, 0.001, -0.002, 0.01, 0.0, 0.0, 0.0]
    );
    let r = Distortion::Rational8 { k1: 0.4, k2: 0.05, p1: 0.001, p2: -0.0007, k3: 0.01, k4: 0.6, k5: 0.02, k6: 0.001 };
    assert_eq!(r.converted(DistortionKind::Brown5).coefficients(), vec![0.4, 0.05, 0.001, -0.0007, 0.01]);
    assert_eq!(b.converted(DistortionKind::KannalaBrandt).coefficients(), vec![0.0; 4]);
    let kb = Distortion::KannalaBrandt { k1: 0.1, k2: 0.0, k3: 0.0, k4: 0.0 };
    assert_eq!(kb.converted(DistortionKind::Rational8).coefficients(), vec![0.0; 8]);
    assert_eq!(kb.converted(DistortionKind::None), Distortion::None);
    assert_eq!(Distortion::None.converted(DistortionKind::Brown5).coefficients(), vec![0.0; 5]);
}
