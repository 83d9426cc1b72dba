//! The OpenCV stereo sample (left01..14, right01..14 without 10; 9x6 inner corners, 25 mm
//! squares): ferrocal's calibration against OpenCV's published numbers and against OpenCV's
//! `calibrateCamera` / `stereoCalibrate` on the same corners, side by side.

use std::path::{Path, PathBuf};

use ferrocal_vision::calib::corners::{chessboard_corners_opencv, chessboard_corners_opencv_with, SubpixWindow};
use ferrocal_vision::calib::{calibrate_camera, calibrate_stereo, CalibrationOptions, PlanarTarget, View};
use opencv::core::{Mat, Point2f, Point3f, Size, TermCriteria, Vector, CV_64F};
use opencv::prelude::*;

const DATA: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data/opencv_stereo/");
const INDICES: [u32; 13] = [1, 2, 3, 4, 5, 6, 7, 8, 9, 11, 12, 13, 14];
const SQUARE_M: f64 = 0.025;

/// The data folder; CI always has `../shared` beside the checkout, so a missing folder fails
/// the test (naming the path) instead of passing it unseen.
fn data_dir() -> PathBuf {
    let p = Path::new(DATA);
    assert!(p.is_dir(), "{DATA} is missing: these tests need ../shared/data/opencv_stereo beside the checkout");
    p.to_path_buf()
}

fn views(dir: &Path, side: &str) -> Vec<View> {
    INDICES
        .iter()
        .map(|i| {
            let path = dir.join(format!("{side}{i:02}.jpg"));
            let c = chessboard_corners_opencv(&path, 9, 6).unwrap();
            View::new(path.file_name().unwrap().to_string_lossy(), c.image_size, c.corners_px)
        })
        .collect()
}

fn fix_aspect() -> CalibrationOptions {
    CalibrationOptions { fix_aspect: true, ..CalibrationOptions::default() }
}

/// OpenCV's calibrateCamera (CALIB_FIX_ASPECT_RATIO from an identity camera matrix) on the same
/// corners: (fx, fy, cx, cy, k[5], rms, per-view errors, std of fx fy cx cy k1 k2 p1 p2 k3).
struct OpenCvCal {
    k: [f64; 4],
    dist: Vec<f64>,
    rms: f64,
    per_view: Vec<f64>,
    std: Vec<f64>,
    camera: Mat,
    dist_mat: Mat,
}

fn object_points(n: usize) -> Vector<Vector<Point3f>> {
    let one: Vector<Point3f> =
        (0..6).flat_map(|r| (0..9).map(move |c| Point3f::new(c as f32 * 25.0, r as f32 * 25.0, 0.0))).collect();
    (0..n).map(|_| one.clone()).collect()
}

fn image_points(views: &[View]) -> Vector<Vector<Point2f>> {
    views.iter().map(|v| v.corners_px.iter().map(|p| Point2f::new(p.x as f32, p.y as f32)).collect()).collect()
}

fn opencv_calibrate(views: &[View]) -> OpenCvCal {
    let obj = object_points(views.len());
    let img = image_points(views);
    let mut camera = Mat::eye(3, 3, CV_64F).unwrap().to_mat().unwrap();
    let mut dist = Mat::zeros(5, 1, CV_64F).unwrap().to_mat().unwrap();
    let mut rvecs: Vector<Mat> = Vector::new();
    let mut tvecs: Vector<Mat> = Vector::new();
    let (mut std_i, mut std_e, mut per_view) = (Mat::default(), Mat::default(), Mat::default());
    let criteria =
        TermCriteria::new(opencv::core::TermCriteria_COUNT + opencv::core::TermCriteria_EPS, 30, f64::EPSILON).unwrap();
    let rms = opencv::calib3d::calibrate_camera_extended(
        &obj,
        &img,
        Size::new(640, 480),
        &mut camera,
        &mut dist,
        &mut rvecs,
        &mut tvecs,
        &mut std_i,
        &mut std_e,
        &mut per_view,
        opencv::calib3d::CALIB_FIX_ASPECT_RATIO,
        criteria,
    )
    .unwrap();
    let at = |m: &Mat, r: i32, c: i32| *m.at_2d::<f64>(r, c).unwrap();
    OpenCvCal {
        k: [at(&camera, 0, 0), at(&camera, 1, 1), at(&camera, 0, 2), at(&camera, 1, 2)],
        dist: (0..5).map(|i| *dist.at::<f64>(i).unwrap()).collect(),
        rms,
        per_view: (0..views.len() as i32).map(|i| *per_view.at::<f64>(i).unwrap()).collect(),
        std: (0..9).map(|i| *std_i.at::<f64>(i).unwrap()).collect(),
        camera,
        dist_mat: dist,
    }
}

fn side_by_side(name: &str, ours: &ferrocal_vision::calib::CameraCalibration, cv: &OpenCvCal) {
    let p: Vec<f64> = ours.camera.parameters().iter().map(|p| p.value).collect();
    let names = ["fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3"];
    let cvv: Vec<f64> = cv.k.iter().copied().chain(cv.dist.iter().copied()).collect();
    println!("{name}: parameter, ferrocal (std), OpenCV (std)");
    for i in 0..9 {
        println!("  {:>3} {:>12.5} ({:.5})  {:>12.5} ({:.5})", names[i], p[i], ours.std[i], cvv[i], cv.std[i]);
    }
    println!("  rms {:.4} px  OpenCV {:.4} px", ours.rms_px, cv.rms);
    for (v, e) in ours.views.iter().zip(&cv.per_view) {
        println!("  {:>12} {:.3} {:.3}{}", v.name, v.rms_px, e, if v.outlier { "  (outlier view)" } else { "" });
    }
}

#[test]
fn left_camera_matches_the_published_calibration_and_opencv() {
    let dir = data_dir();
    let views = views(&dir, "left");
    let target = PlanarTarget::chessboard(9, 6, SQUARE_M);
    let ours = calibrate_camera(&views, &target, &fix_aspect()).unwrap();
    let cv = opencv_calibrate(&views);
    side_by_side("left", &ours, &cv);
    let k = ours.camera.intrinsics;
    // The published numbers (OpenCV samples/data/left_intrinsics.yml).
    assert!((k.fx_px / 535.9157 - 1.0).abs() < 0.003, "fx {}", k.fx_px);
    assert_eq!(k.fx_px, k.fy_px);
    assert!((k.cx_px - 342.2832).abs() < 1.5, "cx {}", k.cx_px);
    assert!((k.cy_px - 235.5708).abs() < 1.5, "cy {}", k.cy_px);
    assert!(ours.rms_px <= 0.40, "rms {}", ours.rms_px);
    // The same optimum as OpenCV on the same corners.
    assert!((k.fx_px - cv.k[0]).abs() < 0.05, "fx {} vs OpenCV {}", k.fx_px, cv.k[0]);
    assert!((k.cx_px - cv.k[2]).abs() < 0.05 && (k.cy_px - cv.k[3]).abs() < 0.05);
    assert!((ours.rms_px - cv.rms).abs() < 1e-4, "rms {} vs OpenCV {}", ours.rms_px, cv.rms);
    for (v, e) in ours.views.iter().zip(&cv.per_view) {
        assert!((v.rms_px - e).abs() < 2e-3, "{}: {} vs OpenCV {}", v.name, v.rms_px, e);
    }
    // Standard deviations: both are s0^2 (J^T J)^-1, but OpenCV divides the squared residuals
    // by (points - parameters) where there are 2 residuals per point; ours use
    // (2 points - parameters). Scaled by that factor they agree. (OpenCV reports fx's std as
    // 0 with a fixed aspect ratio; fy carries it.)
    let n_points: f64 = 13.0 * 54.0;
    let n_params = 8.0 + 6.0 * 13.0;
    let factor = ((2.0 * n_points - n_params) / (n_points - n_params)).sqrt();
    for i in 1..9 {
        let scaled = ours.std[i] * factor;
        assert!((scaled / cv.std[i] - 1.0).abs() < 0.02, "std {i}: {scaled} vs OpenCV {}", cv.std[i]);
    }
    // left02 is the published outlier view.
    let flagged: Vec<&str> = ours.views.iter().filter(|v| v.outlier).map(|v| v.name.as_str()).collect();
    assert_eq!(flagged, vec!["left02.jpg"]);
}

#[test]
fn right_camera_matches_opencv() {
    let dir = data_dir();
    let views = views(&dir, "right");
    let target = PlanarTarget::chessboard(9, 6, SQUARE_M);
    let ours = calibrate_camera(&views, &target, &fix_aspect()).unwrap();
    let cv = opencv_calibrate(&views);
    side_by_side("right", &ours, &cv);
    let k = ours.camera.intrinsics;
    // OpenCV with the same recipe (README): fx 541.42, cx 327.34, cy 247.15, RMS 0.446.
    assert!((k.fx_px / 541.42 - 1.0).abs() < 0.003, "fx {}", k.fx_px);
    assert!((k.cx_px - 327.34).abs() < 1.5 && (k.cy_px - 247.15).abs() < 1.5);
    assert!((k.fx_px - cv.k[0]).abs() < 0.05 && (ours.rms_px - cv.rms).abs() < 1e-4);
}

#[test]
fn stereo_baseline_matches_opencv_stereo_calibrate() {
    let dir = data_dir();
    let left = views(&dir, "left");
    let right = views(&dir, "right");
    let target = PlanarTarget::chessboard(9, 6, SQUARE_M);
    let opts = fix_aspect();
    let st = calibrate_stereo(
        &left.iter().cloned().map(Some).collect::<Vec<_>>(),
        &right.iter().cloned().map(Some).collect::<Vec<_>>(),
        &target,
        &opts,
    )
    .unwrap();
    println!(
        "ferrocal stereo: rotation {:.4?} deg (std {:.4?}), translation {:.3?} mm (std {:.3?}), baseline {:.3} +- {:.3} mm, \
         rms {:.4} px (left {:.4}, right {:.4}), reversed views {:?}",
        st.rotation_deg.as_slice(),
        st.rotation_std_deg.as_slice(),
        st.translation_mm.as_slice(),
        st.translation_std_mm.as_slice(),
        st.baseline_mm,
        st.baseline_std_mm,
        st.calibration.rms_px,
        st.left().rms_px,
        st.right().rms_px,
        st.calibration.reversed_views
    );
    // OpenCV: each camera calibrated alone, then stereoCalibrate refining everything jointly
    // with the same model (CALIB_USE_INTRINSIC_GUESS | CALIB_FIX_ASPECT_RATIO).
    let cl = opencv_calibrate(&left);
    let cr = opencv_calibrate(&right);
    let obj = object_points(left.len());
    let (il, ir) = (image_points(&left), image_points(&right));
    let (mut k1, mut d1, mut k2, mut d2) =
        (cl.camera.clone(), cl.dist_mat.clone(), cr.camera.clone(), cr.dist_mat.clone());
    let (mut r, mut t, mut e, mut f) = (Mat::default(), Mat::default(), Mat::default(), Mat::default());
    let criteria =
        TermCriteria::new(opencv::core::TermCriteria_COUNT + opencv::core::TermCriteria_EPS, 100, 1e-10).unwrap();
    let rms = opencv::calib3d::stereo_calibrate(
        &obj,
        &il,
        &ir,
        &mut k1,
        &mut d1,
        &mut k2,
        &mut d2,
        Size::new(640, 480),
        &mut r,
        &mut t,
        &mut e,
        &mut f,
        opencv::calib3d::CALIB_USE_INTRINSIC_GUESS | opencv::calib3d::CALIB_FIX_ASPECT_RATIO,
        criteria,
    )
    .unwrap();
    let tcv: Vec<f64> = (0..3).map(|i| *t.at::<f64>(i).unwrap()).collect();
    let mut rvec = Mat::default();
    opencv::calib3d::rodrigues_def(&r, &mut rvec).unwrap();
    let rcv: Vec<f64> = (0..3).map(|i| rvec.at::<f64>(i).unwrap().to_degrees()).collect();
    println!("OpenCV stereoCalibrate: rotation {rcv:.4?} deg, translation {tcv:.3?} mm, rms {rms:.4} px");
    for i in 0..3 {
        assert!((st.translation_mm[i] - tcv[i]).abs() < 0.1, "t[{i}] {} vs OpenCV {}", st.translation_mm[i], tcv[i]);
        assert!((st.rotation_deg[i] - rcv[i]).abs() < 0.01, "r[{i}] {} vs OpenCV {}", st.rotation_deg[i], rcv[i]);
    }
    assert!((st.calibration.rms_px - rms).abs() < 1e-3, "rms {} vs OpenCV {rms}", st.calibration.rms_px);
    // E and F as the stereo file writes them, from OpenCV's own R, T, K1, K2: OpenCV's E and F
    // (same convention and normalisation, F[2][2] = 1).
    {
        use ferrocal_vision::camera::rectify::{essential_matrix, fundamental_matrix};
        use ferrocal_vision::camera::{CameraModel, Distortion, ImageSize, Intrinsics};
        let (rn, tn) = (read_mat::<3, 3>(&r), read_mat::<3, 1>(&t));
        let e_ours = essential_matrix(&rn, &tn);
        let e_cv = read_mat::<3, 3>(&e);
        assert!((e_ours - e_cv).amax() < 1e-9 * e_cv.amax(), "E {e_ours} vs OpenCV {e_cv}");
        let cam = |k: &Mat| {
            let k = read_mat::<3, 3>(k);
            let i = Intrinsics { fx_px: k[(0, 0)], fy_px: k[(1, 1)], cx_px: k[(0, 2)], cy_px: k[(1, 2)] };
            CameraModel::new(i, Distortion::None, ImageSize { width_px: 640, height_px: 480 }).unwrap()
        };
        let f_ours = fundamental_matrix(&cam(&k1), &cam(&k2), &rn, &tn);
        let f_cv = read_mat::<3, 3>(&f);
        assert!((f_ours - f_cv).amax() < 1e-9 * f_cv.amax(), "F {f_ours} vs OpenCV {f_cv}");
    }
    // With 25 mm squares the data give a baseline of about 3.3 squares, ~83 mm, not Caltech's
    // 99.8 mm (which is 3.33 squares of 30 mm).
    assert!((st.baseline_mm - 83.0).abs() < 2.0, "baseline {}", st.baseline_mm);
}

/// OpenCV's recipe uses a 23 x 23 px `cornerSubPix` window whatever the square size; in the
/// views where the squares are smaller than that (left02 among them) the window reaches the
/// neighbouring corners and pulls the corners off. With the window shrunk to the squares the
/// same images fit twice as well and left02 is no longer an outlier.
#[test]
fn an_adaptive_subpixel_window_halves_the_rms() {
    let dir = data_dir();
    let target = PlanarTarget::chessboard(9, 6, SQUARE_M);
    let mut sides = Vec::new();
    for side in ["left", "right"] {
        let views: Vec<View> = INDICES
            .iter()
            .map(|i| {
                let path = dir.join(format!("{side}{i:02}.jpg"));
                let c = chessboard_corners_opencv_with(&path, 9, 6, SubpixWindow::Adaptive).unwrap();
                View::new(path.file_name().unwrap().to_string_lossy(), c.image_size, c.corners_px)
            })
            .collect();
        let ours = calibrate_camera(&views, &target, &fix_aspect()).unwrap();
        let cv = opencv_calibrate(&views);
        side_by_side(&format!("{side} (adaptive window)"), &ours, &cv);
        assert!(ours.rms_px < 0.3, "{side}: rms {}", ours.rms_px);
        assert!((ours.rms_px - cv.rms).abs() < 1e-4);
        if side == "left" {
            // left02 (1.18 px with the fixed window) is an ordinary view now.
            assert!(ours.views.iter().all(|v| v.rms_px < 0.3 && !v.outlier), "{:?}", ours.views);
        }
        sides.push(views);
    }
    let pair = |v: &[View]| v.iter().cloned().map(Some).collect::<Vec<_>>();
    let st = calibrate_stereo(&pair(&sides[0]), &pair(&sides[1]), &target, &fix_aspect()).unwrap();
    println!(
        "stereo (adaptive window): translation {:.3?} mm (std {:.3?}), baseline {:.3} +- {:.3} mm, rms {:.4} px",
        st.translation_mm.as_slice(),
        st.translation_std_mm.as_slice(),
        st.baseline_mm,
        st.baseline_std_mm,
        st.calibration.rms_px
    );
    assert!((st.baseline_mm - 83.0).abs() < 2.0);
}

fn mat_from(rows: usize, cols: usize, v: impl Fn(usize, usize) -> f64) -> Mat {
    let mut m = Mat::zeros(rows as i32, cols as i32, CV_64F).unwrap().to_mat().unwrap();
    for i in 0..rows {
        for j in 0..cols {
            *m.at_2d_mut::<f64>(i as i32, j as i32).unwrap() = v(i, j);
        }
    }
    m
}

fn read_mat<const R: usize, const C: usize>(m: &Mat) -> nalgebra::SMatrix<f64, R, C> {
    nalgebra::SMatrix::<f64, R, C>::from_fn(|i, j| *m.at_2d::<f64>(i as i32, j as i32).unwrap())
}

/// RMS of the row difference (rectified `v_left - v_right`) of corresponding corners.
fn row_rms(pairs: &[(nalgebra::Point2<f64>, nalgebra::Point2<f64>)]) -> f64 {
    (pairs.iter().map(|(l, r)| (l.y - r.y).powi(2)).sum::<f64>() / pairs.len() as f64).sqrt()
}

/// Our rectification (vision::camera::rectify) against OpenCV's `stereoRectify` on the same
/// calibration (ours, from the OpenCV-recipe corners of the sample): OpenCV's defaults, flags
/// `CALIB_ZERO_DISPARITY`, `alpha = -1` (no scaling), new image size = the image size.
/// R1, R2 agree to 1e-9; the focal length to 1e-9 px; the principal point to 0.05 px (OpenCV
/// undistorts the four image corners in single precision with 5 fixed-point iterations, we
/// invert the model exactly); then every corner of every pair is rectified both ways and the
/// RMS row difference compared (measured: see the printout and the README of the numbers).
#[test]
fn rectification_matches_opencv_stereo_rectify_on_the_sample() {
    use ferrocal_vision::camera::rectify::stereo_rectify;
    let dir = data_dir();
    let left = views(&dir, "left");
    let right = views(&dir, "right");
    let target = PlanarTarget::chessboard(9, 6, SQUARE_M);
    let some = |v: &[View]| v.iter().cloned().map(Some).collect::<Vec<_>>();
    let st = calibrate_stereo(&some(&left), &some(&right), &target, &fix_aspect()).unwrap();
    assert!(st.calibration.reversed_views.is_empty(), "{:?}", st.calibration.reversed_views);
    let (cl, cr) = (st.left().camera, st.right().camera);
    let r = st.t_right_left.rotation.to_rotation_matrix().into_inner();
    let t_mm = st.t_right_left.translation.vector * 1e3;
    let ours = stereo_rectify(&cl, &cr, &r, &t_mm).unwrap();

    let k_mat = |c: &ferrocal_vision::camera::CameraModel| {
        let i = c.intrinsics;
        mat_from(3, 3, |a, b| [[i.fx_px, 0.0, i.cx_px], [0.0, i.fy_px, i.cy_px], [0.0, 0.0, 1.0]][a][b])
    };
    let d_mat = |c: &ferrocal_vision::camera::CameraModel| {
        let d = c.distortion.coefficients();
        mat_from(1, d.len(), |_, j| d[j])
    };
    let (k1, d1, k2, d2) = (k_mat(&cl), d_mat(&cl), k_mat(&cr), d_mat(&cr));
    let (rm, tm) = (mat_from(3, 3, |i, j| r[(i, j)]), mat_from(3, 1, |i, _| t_mm[i]));
    let (mut r1, mut r2, mut p1, mut p2, mut q) =
        (Mat::default(), Mat::default(), Mat::default(), Mat::default(), Mat::default());
    opencv::calib3d::stereo_rectify_def(
        &k1,
        &d1,
        &k2,
        &d2,
        Size::new(640, 480),
        &rm,
        &tm,
        &mut r1,
        &mut r2,
        &mut p1,
        &mut p2,
        &mut q,
    )
    .unwrap();
    let (cv_r1, cv_r2) = (read_mat::<3, 3>(&r1), read_mat::<3, 3>(&r2));
    let (cv_p1, cv_p2, cv_q) = (read_mat::<3, 4>(&p1), read_mat::<3, 4>(&p2), read_mat::<4, 4>(&q));
    println!("R1 difference {:.3e}, R2 difference {:.3e}", (ours.r1 - cv_r1).amax(), (ours.r2 - cv_r2).amax());
    println!("P1 ours {:.6}\nP1 OpenCV {:.6}", ours.p1, cv_p1);
    println!("P2 ours {:.6}\nP2 OpenCV {:.6}", ours.p2, cv_p2);
    println!("Q ours {:.6}\nQ OpenCV {:.6}", ours.q, cv_q);
    assert!((ours.r1 - cv_r1).amax() < 1e-9 && (ours.r2 - cv_r2).amax() < 1e-9);
    assert!((ours.focal_px() - cv_p1[(0, 0)]).abs() < 1e-9);
    assert!((ours.p2[(0, 3)] - cv_p2[(0, 3)]).abs() < 1e-9 * cv_p2[(0, 3)].abs());
    for (a, b) in [(0, 2), (1, 2)] {
        assert!(
            (ours.p1[(a, b)] - cv_p1[(a, b)]).abs() < 0.05,
            "P1[{a}][{b}] {} vs {}",
            ours.p1[(a, b)],
            cv_p1[(a, b)]
        );
        assert!((ours.p2[(a, b)] - cv_p2[(a, b)]).abs() < 0.05);
    }
    assert!((ours.q - cv_q).amax() < 0.05, "Q");

    // Every corner of every pair rectified: ours (exact inverse of the model) and OpenCV's
    // undistortPoints with its R1 P1 / R2 P2 (its default 5 iterations, and 100 iterations).
    let mut ours_pairs = Vec::new();
    let mut cv_pairs = [Vec::new(), Vec::new()];
    for (lv, rv) in left.iter().zip(&right) {
        for (pl, pr) in lv.corners_px.iter().zip(&rv.corners_px) {
            ours_pairs.push((ours.rectify_pixel(&cl, false, pl).unwrap(), ours.rectify_pixel(&cr, true, pr).unwrap()));
        }
        for (n, iterations) in [5, 100].into_iter().enumerate() {
            let crit = TermCriteria::new(opencv::core::TermCriteria_COUNT, iterations, 0.0).unwrap();
            let rect = |pts: &[nalgebra::Point2<f64>], k: &Mat, d: &Mat, r: &Mat, p: &Mat| {
                let src: Vector<opencv::core::Point2d> =
                    pts.iter().map(|p| opencv::core::Point2d::new(p.x, p.y)).collect();
                let mut dst: Vector<opencv::core::Point2d> = Vector::new();
                opencv::calib3d::undistort_points_iter(&src, &mut dst, k, d, r, p, crit).unwrap();
                dst.iter().map(|p| nalgebra::Point2::new(p.x, p.y)).collect::<Vec<_>>()
            };
            let a = rect(&lv.corners_px, &k1, &d1, &r1, &p1);
            let b = rect(&rv.corners_px, &k2, &d2, &r2, &p2);
            cv_pairs[n].extend(a.into_iter().zip(b));
        }
    }
    let (ours_rms, cv5, cv100) = (row_rms(&ours_pairs), row_rms(&cv_pairs[0]), row_rms(&cv_pairs[1]));
    println!(
        "rectified row difference RMS over {} corner pairs: ours {ours_rms:.4} px, OpenCV stereoRectify + undistortPoints \
         {cv5:.4} px (5 iterations), {cv100:.4} px (100 iterations); baseline {:.3} +- {:.3} mm",
        ours_pairs.len(),
        st.baseline_mm,
        st.baseline_std_mm
    );
    assert!(ours_rms < 0.5, "row RMS {ours_rms} px");
    assert!((ours_rms - cv100).abs() < 0.01, "ours {ours_rms} vs OpenCV {cv100}");
}

/// The stereo file as OpenCV itself reads it (`cv::FileStorage`): every matrix comes back with
/// the same f64 values; and a file OpenCV's FileStorage writes (the `stereo_calib` sample's
/// names, no ferrocal keys) is read by ours. No calibration: a fixed pair.
#[test]
fn opencv_file_storage_reads_and_writes_our_stereo_file() {
    use ferrocal_vision::camera::io::{from_opencv_stereo_yaml, to_opencv_stereo_yaml, StereoPair};
    use ferrocal_vision::camera::{CameraModel, Distortion, ImageSize, Intrinsics};
    use opencv::core::{FileStorage, FileStorage_Mode};
    let size = ImageSize { width_px: 640, height_px: 480 };
    let cam = |fx: f64, cx: f64, k1: f64| {
        CameraModel::new(
            Intrinsics { fx_px: fx, fy_px: fx, cx_px: cx, cy_px: 241.3 },
            Distortion::Brown5 { k1, k2: 0.09, p1: 0.0012, p2: -0.0002, k3: 0.01 },
            size,
        )
        .unwrap()
    };
    let r = nalgebra::Rotation3::new(nalgebra::Vector3::new(0.0061, -0.0082, -0.0034)).into_inner();
    let pair = StereoPair::new(
        cam(534.1, 341.9, -0.28),
        cam(537.6, 326.4, -0.27),
        r,
        nalgebra::Vector3::new(-0.0832, 0.0011, 0.0005),
    )
    .unwrap();
    let text = to_opencv_stereo_yaml(&pair).unwrap();
    let fs = FileStorage::new(&text, FileStorage_Mode::READ as i32 | FileStorage_Mode::MEMORY as i32, "").unwrap();
    let get = |name: &str| fs.get(name).unwrap().mat().unwrap();
    let m1 = get("M1");
    assert_eq!(*m1.at_2d::<f64>(0, 0).unwrap(), 534.1);
    assert_eq!(*get("D2").at_2d::<f64>(0, 0).unwrap(), -0.27);
    assert_eq!(read_mat::<3, 3>(&get("R")), pair.r);
    assert_eq!(read_mat::<3, 1>(&get("T")), pair.t_m);
    assert_eq!(read_mat::<3, 4>(&get("P2")), pair.rectification.p2);
    assert_eq!(read_mat::<4, 4>(&get("Q")), pair.rectification.q);
    assert_eq!(read_mat::<3, 3>(&get("R1")), pair.rectification.r1);

    // OpenCV writes, we read.
    let mut out =
        FileStorage::new(".yml", FileStorage_Mode::WRITE as i32 | FileStorage_Mode::MEMORY as i32, "").unwrap();
    let k = |c: &CameraModel| {
        let i = c.intrinsics;
        mat_from(3, 3, |a, b| [[i.fx_px, 0.0, i.cx_px], [0.0, i.fy_px, i.cy_px], [0.0, 0.0, 1.0]][a][b])
    };
    let d = |c: &CameraModel| {
        let v = c.distortion.coefficients();
        mat_from(1, 5, |_, j| v[j])
    };
    out.write_i32("image_width", 640).unwrap();
    out.write_i32("image_height", 480).unwrap();
    out.write_mat("M1", &k(&pair.left)).unwrap();
    out.write_mat("D1", &d(&pair.left)).unwrap();
    out.write_mat("M2", &k(&pair.right)).unwrap();
    out.write_mat("D2", &d(&pair.right)).unwrap();
    out.write_mat("R", &mat_from(3, 3, |i, j| pair.r[(i, j)])).unwrap();
    out.write_mat("T", &mat_from(3, 1, |i, _| pair.t_m[i])).unwrap();
    let written = out.release_and_get_string().unwrap();
    let back = from_opencv_stereo_yaml(&written).unwrap();
    assert_eq!(back, pair, "{written}");
}
