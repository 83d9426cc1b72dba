//! ChArUco boards and circle grids on rendered images with exact truth (the project's renderer:
//! area-exact coverage, blur, vignetting, shot and read noise, seeded): the corners' and
//! centres' errors, ids and order, OpenCV's detectors on the same images for comparison, and
//! the circle centres' perspective bias before and after the correction.
//!
//! The renderer is not the detectors' model: it integrates the printed polygons over each
//! pixel and blurs them; the detectors fit blurred edges (ChArUco) and half-level contours
//! (circles). The correction of the circle bias uses the renderer's own camera model and pose
//! here, so that the test isolates the detector and the bias formula.

use crate::calib_support;

use calib_support as sim;
use ferrocal_datasets::render::printed_targets::facing_pose;
use ferrocal_datasets::render::{RenderConfig, Renderer, TargetConfig};
use ferrocal_vision::calib::{
    calibrate_pattern, CalibrationOptions, CalibrationPattern as CalPattern, PlanarTarget, View,
};
use ferrocal_vision::camera::{CameraModel, Distortion, ImageSize, Intrinsics};
use ferrocal_vision::detect::aruco::{opencv_charuco_corners, ArucoDictionary, MarkerParams};
use ferrocal_vision::detect::baseline::opencv_find_circles_grid;
use ferrocal_vision::detect::circles::bias::correct_centres;
use ferrocal_vision::detect::{detect, CharucoBoard, CircleGrid, DetectOptions, Pattern};
use nalgebra::{Isometry3, Point2, Vector2, Vector3};

fn camera() -> CameraModel {
    CameraModel::new(
        Intrinsics { fx_px: 1150.0, fy_px: 1148.0, cx_px: 647.0, cy_px: 478.0 },
        Distortion::Brown5 { k1: -0.12, k2: 0.08, p1: 4e-4, p2: -3e-4, k3: 0.0 },
        ImageSize { width_px: 1280, height_px: 960 },
    )
    .unwrap()
}

fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt()
}

/// The board of the ROS-Industrial set, rendered from the front, tilted and cut by the image
/// border: every visible corner found with its true id, sub-pixel errors against the truth.
#[test]
fn rendered_charuco_corners_carry_their_ids_and_land_on_the_truth() {
    let cam = camera();
    let board = CharucoBoard {
        cols: 5,
        rows: 7,
        square_mm: 36.195,
        marker_mm: 18.256,
        dictionary: ArucoDictionary::Dict6x6_250,
    };
    let config = TargetConfig::Charuco {
        cols: 5,
        rows: 7,
        square_m: 0.036195,
        marker_m: 0.018256,
        dictionary: ArucoDictionary::Dict6x6_250,
        margin_m: 0.02,
    };
    let renderer = Renderer::new(cam, &config, RenderConfig::default()).unwrap();
    let points = PlanarTarget { points_m: board.target_points_m(), reversible: false };
    let pattern = Pattern::Charuco(board);
    // (centre in the camera, tilt deg, tilt axis deg, roll deg): frontal, tilted, strongly
    // tilted and rolled, and one half out of the image on the right.
    let poses = [
        (Vector3::new(0.0, 0.0, 0.55), 5.0f64, 0.0f64, 0.0f64),
        (Vector3::new(-0.03, 0.02, 0.6), 35.0, 30.0, 20.0),
        (Vector3::new(0.02, -0.01, 0.65), 55.0, 120.0, -40.0),
        (Vector3::new(0.29, 0.0, 0.6), 20.0, 90.0, 10.0),
    ];
    let (mut ours, mut theirs) = (Vec::new(), Vec::new());
    let mut partial_seen = false;
    for (k, (c, tilt, axis, roll)) in poses.iter().enumerate() {
        let t = sim::board_pose(&points, *c, f64::to_radians(*tilt), f64::to_radians(*axis), f64::to_radians(*roll));
        let out = renderer.render(&t, 40 + k as u64).unwrap();
        let truth: Vec<(u32, Point2<f64>, bool)> = out
            .truth
            .corners
            .iter()
            .map(|c| (c.corner.index, c.pixel.unwrap_or(Point2::origin()), c.in_image))
            .collect();
        let det = detect(&out.image, &pattern, &DetectOptions::default(), None).unwrap();
        assert_eq!(det.len(), 1);
        let d = &det[0];
        let visible = truth.iter().filter(|t| t.2).count();
        let mut errs = Vec::new();
        for c in &d.corners {
            let id = c.point_id.expect("ChArUco corners carry ids");
            let (_, p, inside) = truth[id as usize];
            assert!(inside, "pose {k}: corner {id} reported but outside the image");
            // The right id: its truth is the nearest true corner by far.
            let e = (c.position_px - p).norm();
            assert!(e < 0.5, "pose {k}: corner {id} is {e:.3} px from its truth");
            let nearest_other =
                truth.iter().filter(|t| t.0 != id).map(|t| (t.1 - c.position_px).norm()).fold(f64::MAX, f64::min);
            assert!(nearest_other > 10.0 * e.max(0.1), "pose {k}: corner {id} is ambiguous");
            let sd = (c.covariance_px2.unwrap().trace() / 2.0).sqrt();
            assert!(sd > 0.0 && sd < 0.2, "pose {k}: corner {id} sigma {sd}");
            errs.push(e);
        }
        if k < 3 {
            assert!(d.complete && d.corners.len() == 24, "pose {k}: {} of 24 corners", d.corners.len());
        } else {
            // Cut by the border: the corners whose markers are both in view, and not all.
            partial_seen = !d.complete;
            assert!(
                d.corners.len() >= 6 && d.corners.len() < visible.max(1) + 1,
                "pose {k}: {} corners",
                d.corners.len()
            );
        }
        let cv = opencv_charuco_corners(&out.image, &board, MarkerParams::Tolerant, 2).unwrap();
        let cv_errs: Vec<f64> = cv.iter().map(|(id, p)| (p - truth[*id as usize].1).norm()).collect();
        let cv_mean = cv.iter().map(|(id, p)| p - truth[*id as usize].1).sum::<Vector2<f64>>() / cv.len().max(1) as f64;
        let sd = d.corners.iter().map(|c| (c.covariance_px2.unwrap().trace() / 2.0).sqrt()).sum::<f64>()
            / d.corners.len() as f64;
        let cv_centred: Vec<f64> = cv.iter().map(|(id, p)| (p - truth[*id as usize].1 - cv_mean).norm()).collect();
        println!(
            "pose {k}: ferrocal mean reported sigma {sd:.4} px; OpenCV's mean offset from the truth {cv_mean:.3?} px, \
             RMS {:.4} px about it",
            rms(&cv_centred)
        );
        println!(
            "pose {k}: ferrocal {} corners, RMS error {:.4} px (max {:.4}); OpenCV {} corners, RMS {:.4} px (max {:.4})",
            d.corners.len(),
            rms(&errs),
            errs.iter().copied().fold(0.0, f64::max),
            cv.len(),
            rms(&cv_errs),
            cv_errs.iter().copied().fold(0.0, f64::max)
        );
        ours.extend(errs);
        theirs.extend(cv_errs);
    }
    assert!(partial_seen, "the half-visible board must give a partial detection");
    println!(
        "all poses: ferrocal RMS {:.4} px over {}, OpenCV RMS {:.4} px over {}",
        rms(&ours),
        ours.len(),
        rms(&theirs),
        theirs.len()
    );
    assert!(rms(&ours) < 0.06, "ferrocal RMS {:.4} px", rms(&ours));
}

/// A modified 10 x 10 grid (20 mm spacing, 5 and 10 mm radii, as printed on the ROS-Industrial
/// target) from the front and at 45 and 60 degrees: the order from the large dot, the measured
/// radii, the centres' errors, and the bias correction (with the renderer's camera and pose).
#[test]
fn rendered_circle_grid_order_radii_and_the_perspective_bias() {
    let cam = camera();
    let grid = CircleGrid::symmetric(10, 10, 20.0, true);
    let config = TargetConfig::CircleGrid {
        cols: 10,
        rows: 10,
        spacing_m: 0.02,
        radius_m: 0.005,
        large_radius_m: Some(0.01),
        margin_m: 0.02,
        asymmetric: false,
    };
    let renderer = Renderer::new(cam, &config, RenderConfig::default()).unwrap();
    let points = PlanarTarget { points_m: grid.target_points_m(), reversible: false };
    let pattern = Pattern::CircleGrid(grid);
    let poses = [(0.0f64, 0.0f64, 0.0f64), (45.0, 20.0, 30.0), (60.0, 100.0, -150.0)];
    let mut oblique_before_after = Vec::new();
    for (k, (tilt, axis, roll)) in poses.iter().enumerate() {
        let t = sim::board_pose(
            &points,
            Vector3::new(0.01, -0.01, 0.45),
            f64::to_radians(*tilt),
            f64::to_radians(*axis),
            f64::to_radians(*roll),
        );
        let out = renderer.render(&t, 70 + k as u64).unwrap();
        let truth: Vec<Point2<f64>> = out.truth.corners.iter().map(|c| c.pixel.unwrap()).collect();
        let d = &detect(&out.image, &pattern, &DetectOptions::default(), None).unwrap()[0];
        assert_eq!(d.corners.len(), 100);
        // Every dot in its place: dot k is nearest to truth k (an error of order would move it
        // by a whole spacing).
        let before: Vec<f64> = d.corners.iter().zip(&truth).map(|(c, p)| (c.position_px - p).norm()).collect();
        let worst = before.iter().copied().fold(0.0, f64::max);
        assert!(worst < 1.0, "pose {k}: a centre {worst:.3} px from its truth (order wrong?)");
        let r = d.circle_radii_m.unwrap();
        println!("pose {k}: measured radii {:.3} / {:.3} mm (printed 5 / 10)", r[0] * 1e3, r[1] * 1e3);
        assert!((r[0] - 0.005).abs() < 0.0004 && (r[1] - 0.01).abs() < 0.0006, "radii {r:?}");
        let ids: Vec<usize> = d.corners.iter().map(|c| c.point_id.unwrap() as usize).collect();
        let radii: Vec<f64> = ids.iter().map(|&i| if i == 0 { 0.01 } else { 0.005 }).collect();
        let fixed = correct_centres(&cam, &t, &points.points_m, &ids, &radii, &d.corners_px()).unwrap();
        let after: Vec<f64> = fixed.iter().zip(&truth).map(|(c, p)| (c - p).norm()).collect();
        let cv = opencv_find_circles_grid(&out.image, 10, 10).unwrap();
        let cv_rms = cv.map(|c| {
            // OpenCV's order of a symmetric grid: match each centre to its nearest truth.
            rms(&c.iter().map(|p| truth.iter().map(|q| (p - q).norm()).fold(f64::MAX, f64::min)).collect::<Vec<f64>>())
        });
        println!(
            "pose {k} (tilt {tilt} deg): ferrocal RMS {:.4} px before, {:.4} px after the bias correction; \
             OpenCV findCirclesGrid RMS {:?} px",
            rms(&before),
            rms(&after),
            cv_rms
        );
        let sd: Vec<f64> = d.corners.iter().map(|c| (c.covariance_px2.unwrap().trace() / 2.0).sqrt()).collect();
        println!("pose {k}: mean reported sigma {:.4} px", sd.iter().sum::<f64>() / sd.len() as f64);
        if *tilt > 30.0 {
            oblique_before_after.push((rms(&before), rms(&after)));
        } else {
            assert!(rms(&after) < 0.05, "frontal view: {:.4} px after correction", rms(&after));
        }
    }
    for (b, a) in oblique_before_after {
        assert!(a < 0.5 * b && a < 0.06, "oblique view: {b:.4} px before, {a:.4} px after");
    }
}

/// Calibration from rendered circle-grid views: the bias correction brings the focal length
/// and principal point closer to the truth (the same lens model family renders and
/// calibrates, so this tests the centres, not the model).
#[test]
fn circle_grid_calibration_with_the_bias_corrected() {
    let cam = camera();
    let grid = CircleGrid::symmetric(10, 10, 20.0, true);
    let config = TargetConfig::CircleGrid {
        cols: 10,
        rows: 10,
        spacing_m: 0.02,
        radius_m: 0.006,
        large_radius_m: Some(0.009),
        margin_m: 0.02,
        asymmetric: false,
    };
    let renderer = Renderer::new(cam, &config, RenderConfig::default()).unwrap();
    let points = PlanarTarget { points_m: grid.target_points_m(), reversible: false };
    let pattern = Pattern::CircleGrid(grid);
    let mut rng = sim::rng(11);
    let mut views = Vec::new();
    let mut radii = Vec::new();
    for i in 0..10 {
        let t: Isometry3<f64> = sim::random_calibration_pose(&mut rng, &cam, &points, (0.35, 0.6), (30.0, 55.0));
        let out = renderer.render(&t, 200 + i).unwrap();
        let Ok(d) = detect(&out.image, &pattern, &DetectOptions::default(), None) else { continue };
        radii.push(d[0].circle_radii_m.unwrap());
        let mut v = View::new(format!("render{i}"), cam.image_size, d[0].corners_px());
        v.point_ids = d[0].corners.iter().map(|c| c.point_id.unwrap() as usize).collect();
        views.push(v);
    }
    assert!(views.len() >= 9, "{} of 10 views", views.len());
    let med = |k: usize| {
        let mut v: Vec<f64> = radii.iter().map(|r| r[k]).collect();
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let cal_pattern = CalPattern::CircleGrid(grid);
    let opts = CalibrationOptions::default();
    let plain = calibrate_pattern(&views, &cal_pattern, None, &opts).unwrap().calibration;
    let fixed = calibrate_pattern(&views, &cal_pattern, Some([med(0), med(1)]), &opts).unwrap();
    let bias = fixed.circle_bias.clone().unwrap();
    println!("{bias}");
    let err = |c: &ferrocal_vision::calib::CameraCalibration| {
        let (a, b) = (c.camera.intrinsics, cam.intrinsics);
        [a.fx_px - b.fx_px, a.fy_px - b.fy_px, a.cx_px - b.cx_px, a.cy_px - b.cy_px]
    };
    let (e0, e1) = (err(&plain), err(&fixed.calibration));
    println!("uncorrected: errors fx fy cx cy {e0:.3?} px, RMS {:.4} px", plain.rms_px);
    println!(
        "corrected:   errors fx fy cx cy {e1:.3?} px, RMS {:.4} px, std {:.3?}",
        fixed.calibration.rms_px,
        &fixed.calibration.std[..4]
    );
    let norm = |e: [f64; 4]| e.iter().map(|x| x * x).sum::<f64>().sqrt();
    assert!(norm(e1) < norm(e0), "the correction must bring the camera closer to the truth");
    assert!(fixed.calibration.rms_px < plain.rms_px);
    for (i, e) in e1.iter().enumerate() {
        assert!(e.abs() < 4.0 * fixed.calibration.std[i] + 0.05, "parameter {i}: error {e:.3} px");
    }
}

/// OpenCV's asymmetric circle grid (`acircles`): 4 x 11 as OpenCV's own printed pattern, dark
/// dots on white and the same inverted (white on black), and 5 x 8 (an even number of rows,
/// which looks the same after a half turn). Rendered with exact truth (the renderer does not
/// share the detector's model: it integrates the printed discs over each pixel), from the
/// front to 55 degrees of tilt. Every dot must land in its own place in OpenCV's order (the
/// same order OpenCV's findCirclesGrid returns, checked side by side), the centres within
/// OpenCV's accuracy (printed beside), and the radii measured.
#[test]
fn rendered_asymmetric_circle_grids_in_opencv_order() {
    use ferrocal_vision::detect::baseline::opencv_find_asymmetric_circles_grid;
    let cam = camera();
    let poses = [(0.0, 0.0, 0.0), (35.0, 20.0, 15.0), (55.0, 100.0, -20.0), (45.0, 200.0, 25.0)];
    let (mut ours_all, mut cv_all) = (Vec::new(), Vec::new());
    for (cols, rows, light) in [(4u32, 11u32, false), (4, 11, true), (5, 8, false)] {
        let grid = CircleGrid::asymmetric(cols, rows, 20.0);
        let config = TargetConfig::CircleGrid {
            cols,
            rows,
            spacing_m: 0.02,
            radius_m: 0.006,
            large_radius_m: None,
            margin_m: 0.02,
            asymmetric: true,
        };
        let renderer = Renderer::new(cam, &config, RenderConfig::default()).unwrap();
        let pattern = Pattern::CircleGrid(grid);
        assert_eq!(pattern.to_string().parse::<Pattern>().unwrap(), pattern);
        for (k, &(tilt, axis, roll)) in poses.iter().enumerate() {
            let (tilt_rad, axis_rad, roll_rad) = (f64::to_radians(tilt), f64::to_radians(axis), f64::to_radians(roll));
            let t = facing_pose(renderer.target(), Vector3::new(0.01, -0.01, 0.5), tilt_rad, axis_rad, roll_rad);
            let out = renderer.render(&t, 300 + k as u64).unwrap();
            let mut img = out.image.clone();
            if light {
                img.pixels_mut().for_each(|p| p.0[0] = 255 - p.0[0]);
            }
            let truth: Vec<Point2<f64>> = out.truth.corners.iter().map(|c| c.pixel.unwrap()).collect();
            let what = format!("{cols}x{rows}{} pose {k} (tilt {tilt} deg)", if light { " light" } else { "" });
            let d =
                &detect(&img, &pattern, &DetectOptions::default(), None).unwrap_or_else(|e| panic!("{what}: {e}"))[0];
            assert_eq!(d.corners.len(), (cols * rows) as usize, "{what}");
            let errs: Vec<f64> = d.corners.iter().zip(&truth).map(|(c, p)| (c.position_px - p).norm()).collect();
            let worst = errs.iter().copied().fold(0.0, f64::max);
            assert!(worst < 1.0, "{what}: a centre {worst:.3} px from its truth (order wrong?)");
            let r = d.circle_radii_m.unwrap();
            assert!((r[0] - 0.006).abs() < 0.0005, "{what}: radius {:.3} mm, printed 6", r[0] * 1e3);
            // OpenCV on the same image (its blob detector wants dark dots: inverted back, as
            // its users do with white-on-black prints).
            let mut cv_img = img.clone();
            if light {
                cv_img.pixels_mut().for_each(|p| p.0[0] = 255 - p.0[0]);
            }
            let cv = opencv_find_asymmetric_circles_grid(&cv_img, cols, rows).unwrap();
            // Odd rows: one numbering only, and OpenCV's must be ours. Even rows: OpenCV may
            // number from the opposite corner (the half turn); each centre against its nearest
            // truth then.
            let cv_errs = cv.as_ref().map(|c| {
                c.iter()
                    .enumerate()
                    .map(|(i, p)| match rows % 2 {
                        1 => (p - truth[i]).norm(),
                        _ => truth.iter().map(|q| (p - q).norm()).fold(f64::MAX, f64::min),
                    })
                    .collect::<Vec<f64>>()
            });
            if let Some(e) = &cv_errs {
                let w = e.iter().copied().fold(0.0, f64::max);
                assert!(w < 1.0, "{what}: OpenCV's dot {w:.3} px from our truth of the same index");
                cv_all.extend(e.iter().copied());
                ours_all.extend(errs.iter().copied());
            }
            println!(
                "{what}: ferrocal RMS {:.4} px (before the perspective-bias correction), OpenCV findCirclesGrid {}",
                rms(&errs),
                cv_errs.map_or("not found".to_string(), |e| format!("RMS {:.4} px", rms(&e)))
            );
        }
    }
    println!("on the views both found: ferrocal RMS {:.4} px, OpenCV {:.4} px", rms(&ours_all), rms(&cv_all));
    assert!(cv_all.len() > 100, "OpenCV found too few grids to compare");
    assert!(rms(&ours_all) <= rms(&cv_all), "ferrocal's centres must be at least as good as OpenCV's");
}

/// Camera calibration from rendered views of the boards people print
/// (`ferrocal_datasets::render::printed_targets`: a 9 x 6 chessboard, OpenCV's 4 x 11 asymmetric
/// circle grid with the perspective bias corrected, a Kalibr Aprilgrid of 6 x 4 tags with two
/// views cut by the image border), against the truth and against the chessboard path on the same
/// camera and the same kind of poses. The same lens model family renders and calibrates: this
/// checks the targets' detection, order, ids and frames, not the lens model.
#[test]
fn asymmetric_grid_and_aprilgrid_calibrate_as_well_as_the_chessboard() {
    let rows = ferrocal_datasets::render::printed_targets::printed_targets(21, 12).unwrap();
    for r in &rows {
        println!(
            "{}: {} of {} views, {} corners, RMS {:.4} px; errors fx fy cx cy {:.3?} px (norm {:.3}), std {:.3?}",
            r.target, r.views_found, r.views, r.corners, r.rms_px, r.error_px, r.error_norm_px, r.std_px
        );
        assert!(r.views_found >= 10, "{}: {} of {} views found", r.target, r.views_found, r.views);
        for (i, (e, sd)) in r.error_px.iter().zip(&r.std_px).enumerate() {
            assert!(e.abs() < 4.0 * sd + 0.1, "{}: intrinsic {i} off by {e:.3} px (std {sd:.3})", r.target);
        }
    }
    let chess = rows[0].error_norm_px;
    for r in &rows[1..] {
        assert!(
            r.error_norm_px < 2.0 * chess + 0.2,
            "{}: intrinsics {:.3} px from the truth, the chessboard {chess:.3}",
            r.target,
            r.error_norm_px
        );
    }
}
