//! The project's detectors and OpenCV's side by side on the same images (OpenCV is the
//! baseline every vision result is compared with): per side, the images where the pattern
//! was found, the corners per image, the calibration from those corners (5-coefficient Brown
//! model, [`calibrate_pattern`] for ours, [`calibrate_camera`] for OpenCV's) and the detection
//! time per image (wall clock, one thread, the image already decoded; a number to read, not to
//! assert: speed targets live in the criterion benchmarks).
//!
//! | pattern | ferrocal | OpenCV |
//! |---|---|---|
//! | ChArUco | [`crate::detect::charuco`] | `detectMarkers` + `interpolateCornersCharuco` (its own `cornerSubPix` inside), with OpenCV's default marker parameters and with ferrocal's |
//! | circle grid | [`crate::detect::circles`], centres corrected for the perspective bias | `findCirclesGrid` (symmetric grid, default blob detector) |
//! | chessboard | [`crate::detect::chessboard`] (own corners) | `findChessboardCorners` + `cornerSubPix` (11 x 11) |
//!
//! OpenCV's circle-grid order of a symmetric grid may differ between images by a symmetry of
//! the grid; for a square grid the target is mapped onto itself, so the calibration is not
//! affected (only the poses are). For a non-square grid the half-turn is the same.

use std::path::PathBuf;
use std::time::Instant;

use image::GrayImage;
use nalgebra::Point2;
use serde::{Deserialize, Serialize};

use super::{
    calibrate_camera, calibrate_pattern, CalibrationOptions, CalibrationPattern as Pattern, PlanarTarget, View,
};
use crate::camera::ImageSize;
use crate::detect::aruco::{opencv_charuco_corners, MarkerParams};
use crate::detect::baseline::{opencv_find_chessboard, opencv_find_circles_grid};
use crate::detect::{load_gray, Detector};
use crate::error::Result;

/// One detector's results on the image set.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SideReport {
    /// Which detector.
    pub name: String,
    /// Images where the pattern was found (at least 4 corners).
    pub images_found: usize,
    /// Corners per image, in the order of the images (0 where not found).
    pub corners_per_image: Vec<usize>,
    /// Calibration RMS reprojection error, pixels (`None` when the calibration failed).
    pub rms_px: Option<f64>,
    /// Calibrated `fx, fy, cx, cy`, pixels.
    pub intrinsics_px: Option<[f64; 4]>,
    /// Their standard deviations, pixels.
    pub intrinsics_std_px: Option<[f64; 4]>,
    /// Why the calibration failed, when it did.
    pub calibration_error: Option<String>,
    /// Mean detection time per image, seconds.
    pub time_per_image_s: f64,
}

/// Every side on the same images.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Comparison {
    /// The pattern.
    pub pattern: String,
    /// The images, in order.
    pub images: Vec<String>,
    /// Images that could not be read, with the reason.
    pub unreadable: Vec<(String, String)>,
    /// ferrocal first, then OpenCV's variants.
    pub sides: Vec<SideReport>,
}

impl std::fmt::Display for Comparison {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(f, "{} on {} images", self.pattern, self.images.len())?;
        writeln!(
            f,
            "{:<58} {:>6} {:>8} {:>9} {:>22} {:>22} {:>9}",
            "detector", "found", "corners", "RMS px", "fx fy (std) px", "cx cy (std) px", "ms/image"
        )?;
        for s in &self.sides {
            let (fxy, cxy) = match (s.intrinsics_px, s.intrinsics_std_px) {
                (Some(k), Some(sd)) => (
                    format!("{:.1} {:.1} ({:.1})", k[0], k[1], sd[0].max(sd[1])),
                    format!("{:.1} {:.1} ({:.1})", k[2], k[3], sd[2].max(sd[3])),
                ),
                _ => ("-".into(), "-".into()),
            };
            writeln!(
                f,
                "{:<58} {:>6} {:>8} {:>9} {:>22} {:>22} {:>9.1}",
                s.name,
                format!("{}/{}", s.images_found, self.images.len()),
                s.corners_per_image.iter().sum::<usize>(),
                s.rms_px.map_or("-".into(), |r| format!("{r:.4}")),
                fxy,
                cxy,
                1e3 * s.time_per_image_s
            )?;
            if let Some(e) = &s.calibration_error {
                writeln!(f, "    calibration failed: {e}")?;
            }
        }
        Ok(())
    }
}

/// What one detector returns for one image: `(point id, pixel)` pairs.
type Found = Vec<(usize, Point2<f64>)>;

fn side(
    name: &str,
    images: &[(String, GrayImage)],
    target: &PlanarTarget,
    mut detect: impl FnMut(&GrayImage) -> Found,
    calibrate: impl FnOnce(&[View]) -> Result<super::CameraCalibration>,
) -> SideReport {
    let mut views = Vec::new();
    let mut counts = Vec::new();
    let start = Instant::now();
    let found: Vec<Found> = images.iter().map(|(_, img)| detect(img)).collect();
    let time = start.elapsed().as_secs_f64() / images.len().max(1) as f64;
    for ((name, img), f) in images.iter().zip(found) {
        let f: Found = f.into_iter().filter(|(id, _)| *id < target.points_m.len()).collect();
        counts.push(if f.len() >= 4 { f.len() } else { 0 });
        if f.len() >= 4 {
            let size = ImageSize { width_px: img.width(), height_px: img.height() };
            let mut v = View::new(name.clone(), size, f.iter().map(|p| p.1).collect());
            v.point_ids = f.iter().map(|p| p.0).collect();
            views.push(v);
        }
    }
    let cal = calibrate(&views);
    let (rms, k, sd, err) = match cal {
        Ok(c) => {
            let i = c.camera.intrinsics;
            (
                Some(c.rms_px),
                Some([i.fx_px, i.fy_px, i.cx_px, i.cy_px]),
                Some([c.std[0], c.std[1], c.std[2], c.std[3]]),
                None,
            )
        }
        Err(e) => (None, None, None, Some(e.to_string())),
    };
    SideReport {
        name: name.to_string(),
        images_found: views.len(),
        corners_per_image: counts,
        rms_px: rms,
        intrinsics_px: k,
        intrinsics_std_px: sd,
        calibration_error: err,
        time_per_image_s: time,
    }
}

/// Runs ferrocal's detector and OpenCV's on the same images and calibrates from each (see the
/// module documentation). An unreadable image is listed, not fatal.
pub fn compare_with_opencv(paths: &[PathBuf], pattern: &Pattern, options: &CalibrationOptions) -> Result<Comparison> {
    let mut images = Vec::new();
    let mut unreadable = Vec::new();
    for p in paths {
        match load_gray(p) {
            Ok(img) => images.push((p.display().to_string(), img)),
            Err(e) => unreadable.push((p.display().to_string(), e.to_string())),
        }
    }
    let target = pattern.target();
    let mut sides = Vec::new();
    // ferrocal: the project's detector (chessboards included), with the pattern's calibration.
    let mut det = Detector::new(pattern.pattern(), pattern.detect_options(), None)?;
    let radii = std::cell::Cell::new(Vec::<[f64; 2]>::new());
    let own_detect = |img: &GrayImage| -> Found {
        match det.detect(img) {
            // An AprilTag board: one detection per tag, together the view.
            Ok(d) if matches!(pattern, Pattern::TagBoard(_)) => d
                .iter()
                .flat_map(|d| d.corners.iter().filter_map(|c| c.point_id.map(|i| (i as usize, c.position_px))))
                .collect(),
            Ok(d) => d
                .into_iter()
                .max_by_key(|d| d.corners.len())
                .map(|d| {
                    if let Some(r) = d.circle_radii_m {
                        let mut v = radii.take();
                        v.push(r);
                        radii.set(v);
                    }
                    d.corners.iter().filter_map(|c| c.point_id.map(|i| (i as usize, c.position_px))).collect()
                })
                .unwrap_or_default(),
            Err(_) => Vec::new(),
        }
    };
    let own_target = match pattern {
        // The project's chessboard frame is centred (OpenCV's starts at a corner): same shape.
        Pattern::Chessboard { inner_cols, inner_rows, square_m } => PlanarTarget {
            points_m: crate::detect::Pattern::Chessboard {
                cols: *inner_cols,
                rows: *inner_rows,
                square_mm: square_m * 1e3,
            }
            .target_points_m()
            .unwrap_or_default(),
            reversible: false,
        },
        _ => target.clone(),
    };
    let own_name = if matches!(pattern, Pattern::CircleGrid(_)) {
        "ferrocal (ellipse centres, perspective bias corrected)"
    } else {
        "ferrocal (edge-model corners)"
    };
    sides.push(side(own_name, &images, &own_target, own_detect, |views| {
        let r = radii.take();
        let med = |k: usize| super::median(&r.iter().map(|x| x[k]).collect::<Vec<f64>>());
        let rr = (!r.is_empty()).then(|| [med(0), med(1)]);
        match pattern {
            Pattern::Chessboard { .. } => calibrate_camera(views, &own_target, options),
            _ => calibrate_pattern(views, pattern, rr, options).map(|p| p.calibration),
        }
    }));
    let all = |v: Option<Vec<Point2<f64>>>| -> Found { v.unwrap_or_default().into_iter().enumerate().collect() };
    match *pattern {
        Pattern::Charuco(b) => {
            for (name, params) in [
                ("OpenCV interpolateCornersCharuco (default marker parameters)", MarkerParams::OpenCv),
                ("OpenCV interpolateCornersCharuco (ferrocal's marker parameters)", MarkerParams::Tolerant),
            ] {
                let det = |img: &GrayImage| -> Found {
                    opencv_charuco_corners(img, &b, params, 2)
                        .map(|v| v.into_iter().map(|(i, p)| (i as usize, p)).collect())
                        .unwrap_or_default()
                };
                sides.push(side(name, &images, &target, det, |v| calibrate_camera(v, &target, options)));
            }
        }
        Pattern::CircleGrid(g) if g.asymmetric => {
            let det = |img: &GrayImage| {
                all(crate::detect::baseline::opencv_find_asymmetric_circles_grid(img, g.cols, g.rows).ok().flatten())
            };
            let name = "OpenCV findCirclesGrid (asymmetric, default blob detector)";
            sides.push(side(name, &images, &target, det, |v| calibrate_camera(v, &target, options)));
        }
        Pattern::CircleGrid(g) => {
            let det = |img: &GrayImage| all(opencv_find_circles_grid(img, g.cols, g.rows).ok().flatten());
            let name = "OpenCV findCirclesGrid (symmetric, default blob detector)";
            sides.push(side(name, &images, &target, det, |v| calibrate_camera(v, &target, options)));
        }
        // OpenCV has no AprilTag-board finder: ferrocal's side only.
        Pattern::TagBoard(_) => {}
        Pattern::Chessboard { inner_cols, inner_rows, .. } => {
            let det =
                |img: &GrayImage| all(opencv_find_chessboard(img, inner_cols, inner_rows, Some(5)).ok().flatten());
            let name = "OpenCV findChessboardCorners + cornerSubPix (11 x 11)";
            sides.push(side(name, &images, &target, det, |v| calibrate_camera(v, &target, options)));
        }
    }
    Ok(Comparison {
        pattern: pattern.to_string(),
        images: images.into_iter().map(|i| i.0).collect(),
        unreadable,
        sides,
    })
}
