//! The boards people print, calibrated side by side on renders of one known camera: a 9 x 6
//! chessboard, OpenCV's 4 x 11 asymmetric circle grid and a Kalibr Aprilgrid of 6 x 4 tags,
//! each seen in the same number of random tilted views (the last two shifted so that part of the
//! board leaves the image). Each row gives the calibration's intrinsics against the truth with
//! their standard deviations. The renderer integrates the printed shapes over each pixel and is
//! not the detectors' model, but the same lens family (Brown 5) renders and calibrates: the
//! study checks the targets' detection, numbering and frames, not the lens model.

use nalgebra::{Isometry3, Translation3, Unit, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use serde::{Deserialize, Serialize};

use super::{RenderConfig, Renderer, TargetConfig, TargetGeometry};
use crate::error::{DatasetError, Result};
use ferrocal_vision::calib::{calibrate_pattern, CalibrationOptions, CalibrationPattern, View};
use ferrocal_vision::camera::{CameraModel, Distortion, ImageSize, Intrinsics};
use ferrocal_vision::detect::{Detector, Pattern};

/// One target's calibration.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TargetRow {
    /// What was printed, in words.
    pub target: String,
    /// Its pattern string.
    pub pattern: String,
    /// Views in which it was found, of those rendered.
    pub views_found: usize,
    /// Views rendered.
    pub views: usize,
    /// Corners (or dot centres) used.
    pub corners: usize,
    /// Reprojection RMS, pixels.
    pub rms_px: f64,
    /// Errors of fx, fy, cx, cy against the truth, pixels.
    pub error_px: [f64; 4],
    /// Their standard deviations from the calibration, pixels.
    pub std_px: [f64; 4],
    /// Norm of `error_px`, pixels.
    pub error_norm_px: f64,
}

/// The camera every board is rendered with: 1280 x 960, fx 1150 px, Brown 5.
pub fn study_camera() -> CameraModel {
    CameraModel::new(
        Intrinsics { fx_px: 1150.0, fy_px: 1148.0, cx_px: 647.0, cy_px: 478.0 },
        Distortion::Brown5 { k1: -0.12, k2: 0.08, p1: 4e-4, p2: -3e-4, k3: 0.0 },
        ImageSize { width_px: 1280, height_px: 960 },
    )
    .expect("a valid camera")
}

/// The three boards: (words, renderer's target, pattern string).
pub fn study_boards() -> Vec<(&'static str, TargetConfig, &'static str)> {
    // Kalibr numbers the tags row by row from the bottom; the renderer places ids from the top.
    let kalibr_ids: Vec<u32> = (0..4u32).flat_map(|r| (0..6u32).map(move |c| (3 - r) * 6 + c)).collect();
    vec![
        (
            "chessboard 9 x 6, 25 mm squares",
            TargetConfig::Chessboard { inner_cols: 9, inner_rows: 6, square_m: 0.025, margin_m: 0.02 },
            "chessboard:9x6:25mm",
        ),
        (
            "OpenCV asymmetric circle grid 4 x 11, 20 mm, 6 mm dots",
            TargetConfig::CircleGrid {
                cols: 4,
                rows: 11,
                spacing_m: 0.02,
                radius_m: 0.006,
                large_radius_m: None,
                margin_m: 0.02,
                asymmetric: true,
            },
            "acircles:4x11:20mm",
        ),
        (
            "Kalibr Aprilgrid 6 x 4, 30 mm tags, spacing 0.3",
            TargetConfig::AprilTagBoard {
                cols: 6,
                rows: 4,
                tag_size_m: 0.03,
                spacing_m: 0.009,
                first_id: 0,
                ids: Some(kalibr_ids),
                margin_m: 0.01,
            },
            "aprilgrid:6x4:30mm:0.3",
        ),
    ]
}

/// `T_cam_target` showing `target`'s printed face (target z towards the camera, or away from
/// it for OpenCV's frames, [`TargetGeometry::face_minus_z`]): the centre of its corners at
/// `at_cam_m`, tilted by `tilt_rad` about the in-plane axis at `axis_rad`, rolled by `roll_rad`.
pub fn facing_pose(
    target: &TargetGeometry,
    at_cam_m: Vector3<f64>,
    tilt_rad: f64,
    axis_rad: f64,
    roll_rad: f64,
) -> Isometry3<f64> {
    let centre =
        target.corners.iter().fold(Vector3::zeros(), |a, c| a + c.p_target_m.coords) / target.corners.len() as f64;
    let face = if target.face_minus_z { 0.0 } else { std::f64::consts::PI };
    let r = UnitQuaternion::from_axis_angle(
        &Unit::new_normalize(Vector3::new(axis_rad.cos(), axis_rad.sin(), 0.0)),
        tilt_rad,
    ) * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), roll_rad)
        * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), face);
    Isometry3::from_parts(Translation3::from(at_cam_m - r * centre), r)
}

/// A random pose showing the printed face of `renderer`'s target whole (5 px inside the image),
/// 0.35-0.6 m away, tilted 20-50 degrees about a random in-plane axis, rolled +-30 degrees.
fn random_pose(renderer: &Renderer, rng: &mut rand_chacha::ChaCha8Rng) -> Result<Isometry3<f64>> {
    let cam = renderer.camera();
    let k = cam.intrinsics;
    for _ in 0..10_000 {
        let z = rng.random_range(0.35..0.6);
        let u = rng.random_range(0.0..f64::from(cam.image_size.width_px));
        let v = rng.random_range(0.0..f64::from(cam.image_size.height_px));
        let at = Vector3::new((u - k.cx_px) / k.fx_px * z, (v - k.cy_px) / k.fy_px * z, z);
        let axis_rad: f64 = rng.random_range(0.0..std::f64::consts::TAU);
        let tilt_rad = rng.random_range(20.0f64..50.0).to_radians();
        let roll_rad = rng.random_range(-30.0f64..30.0).to_radians();
        let t = facing_pose(renderer.target(), at, tilt_rad, axis_rad, roll_rad);
        let (w, h) = (f64::from(cam.image_size.width_px), f64::from(cam.image_size.height_px));
        let inside = renderer.ground_truth(&t).is_ok_and(|g| {
            g.corners.iter().all(|c| c.pixel.is_some_and(|p| p.x > 5.0 && p.y > 5.0 && p.x < w - 6.0 && p.y < h - 6.0))
        });
        if inside {
            return Ok(t);
        }
    }
    Err(DatasetError::Render("no pose shows the whole board: the board is too large for the camera".into()))
}

/// Calibrates the camera from `n_views` renders of each board (seeded); see the module
/// documentation.
pub fn printed_targets(seed: u64, n_views: usize) -> Result<Vec<TargetRow>> {
    let cam = study_camera();
    let mut rows = Vec::new();
    for (name, config, text) in study_boards() {
        let renderer = Renderer::new(cam, &config, RenderConfig::default())?;
        let pattern: Pattern = text.parse()?;
        let cal_pattern = CalibrationPattern::of(&pattern)?;
        let mut detector = Detector::new(pattern, cal_pattern.detect_options(), None)?;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let (mut views, mut radii) = (Vec::new(), Vec::new());
        for i in 0..n_views {
            let mut t = random_pose(&renderer, &mut rng)?;
            if i + 2 >= n_views {
                // Part of the board leaves the image: partial views where the target allows.
                t.translation.vector.x += 0.08;
            }
            let out = renderer.render(&t, seed.wrapping_mul(1000) + i as u64)?;
            let Ok(found) = detector.detect(&out.image) else { continue };
            let corners: Vec<_> =
                found.iter().flat_map(|d| d.corners.iter()).filter(|c| c.point_id.is_some()).collect();
            radii.extend(found.iter().filter_map(|d| d.circle_radii_m));
            let mut v =
                View::new(format!("{text} {i}"), cam.image_size, corners.iter().map(|c| c.position_px).collect());
            v.point_ids = corners.iter().filter_map(|c| c.point_id.map(|p| p as usize)).collect();
            views.push(v);
        }
        let r = (!radii.is_empty()).then(|| {
            let med =
                |k: usize| ferrocal_vision::calib::median(&radii.iter().map(|r: &[f64; 2]| r[k]).collect::<Vec<f64>>());
            [med(0), med(1)]
        });
        let cal = calibrate_pattern(&views, &cal_pattern, r, &CalibrationOptions::default())?.calibration;
        let (a, b) = (cal.camera.intrinsics, cam.intrinsics);
        let error_px = [a.fx_px - b.fx_px, a.fy_px - b.fy_px, a.cx_px - b.cx_px, a.cy_px - b.cy_px];
        rows.push(TargetRow {
            target: name.to_string(),
            pattern: text.to_string(),
            views_found: views.len(),
            views: n_views,
            corners: views.iter().map(|v| v.corners_px.len()).sum(),
            rms_px: cal.rms_px,
            error_px,
            std_px: [cal.std[0], cal.std[1], cal.std[2], cal.std[3]],
            error_norm_px: error_px.iter().map(|x| x * x).sum::<f64>().sqrt(),
        });
    }
    Ok(rows)
}
