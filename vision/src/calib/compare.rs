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
//! | chessboard | [`crate::detect::chessboard`] (own corners) | `findChessboardCorners` + `cornerSubPix` (11 x 11, and 23 x 23 as OpenCV's sample) |
//!
//! Every side is judged the same way on evidence the fit has not seen: its views are split by
//! image (the 1st, 3rd, ... train, the 2nd, 4th, ... are held out), the camera calibrated on the
//! training views, and the held-out views' reprojection error measured with that camera fixed
//! and each view's pose fitted ([`super::heldout`]): the lower, the better the corners and the
//! calibration predict new views. OpenCV's own recipe (`calibrateCamera` on OpenCV's corners,
//! 5 coefficients, its own start and stopping rule) is a row of its own; the other OpenCV rows
//! are OpenCV's corners through ferrocal's adjustment, and say so.
//!
//! OpenCV's circle-grid order of a symmetric grid may differ between images by a symmetry of
//! the grid; for a square grid the target is mapped onto itself, so the calibration is not
//! affected (only the poses are). For a non-square grid the half-turn is the same.

use std::path::PathBuf;
use std::time::Instant;

use image::GrayImage;
use nalgebra::Point2;
use serde::{Deserialize, Serialize};

use super::heldout::held_out_reprojection;
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
    /// Held-out reprojection RMS, pixels: calibrated on every second view (the 1st, 3rd, ...),
    /// judged on the others with their poses fitted and the camera fixed (`None` with fewer
    /// than two views on either side or when the fit failed).
    pub held_out_rms_px: Option<f64>,
    /// Views held out (those whose pose could be fitted).
    pub held_out_views: usize,
}

/// A calibration from one side's views: the camera, its RMS reprojection error and the
/// standard deviations of `fx fy cx cy`, pixels.
pub struct Fitted {
    /// The camera.
    pub camera: crate::camera::CameraModel,
    /// RMS reprojection error over the views it was fitted on, pixels.
    pub rms_px: f64,
    /// Standard deviations of `fx fy cx cy`, pixels.
    pub std_px: [f64; 4],
}

impl From<super::CameraCalibration> for Fitted {
    fn from(c: super::CameraCalibration) -> Self {
        Self { camera: c.camera, rms_px: c.rms_px, std_px: [c.std[0], c.std[1], c.std[2], c.std[3]] }
    }
}

/// One way of calibrating a side's views: its row name and the fit.
type Calibrator<'a> = (String, Box<dyn Fn(&[View]) -> Result<Fitted> + 'a>);

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
            "{:<92} {:>6} {:>8} {:>9} {:>11} {:>22} {:>22} {:>9}",
            "corners, calibration",
            "found",
            "corners",
            "RMS px",
            "held-out px",
            "fx fy (std) px",
            "cx cy (std) px",
            "ms/image"
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
                "{:<92} {:>6} {:>8} {:>9} {:>11} {:>22} {:>22} {:>9.1}",
                s.name,
                format!("{}/{}", s.images_found, self.images.len()),
                s.corners_per_image.iter().sum::<usize>(),
                s.rms_px.map_or("-".into(), |r| format!("{r:.4}")),
                s.held_out_rms_px.map_or("-".into(), |r| format!("{r:.4}")),
                fxy,
                cxy,
                1e3 * s.time_per_image_s
            )?;
            if let Some(e) = &s.calibration_error {
                writeln!(f, "    calibration failed: {e}")?;
            }
        }
        if let Some(line) = self.trust_line() {
            writeln!(f, "{line}")?;
        }
        Ok(())
    }
}

impl Comparison {
    /// The row with the lowest held-out reprojection RMS (the evidence for which corners and
    /// calibration to trust), in words, with how far the focal lengths of the rows lie apart
    /// against their stated standard deviations; `None` when no row was held out.
    pub fn trust_line(&self) -> Option<String> {
        let best =
            self.sides.iter().filter_map(|s| s.held_out_rms_px.map(|r| (s, r))).min_by(|a, b| a.1.total_cmp(&b.1))?;
        let fx: Vec<(f64, f64)> =
            self.sides.iter().filter_map(|s| Some((s.intrinsics_px?[0], s.intrinsics_std_px?[0]))).collect();
        let (lo, hi) = fx.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| (lo.min(x.0), hi.max(x.0)));
        let sd = fx.iter().map(|x| x.1).fold(0.0, f64::max);
        let spread = if fx.len() > 1 && sd > 0.0 {
            format!(
                "; the rows' fx lie {:.2} px apart, {:.1} times the largest stated standard deviation{}",
                hi - lo,
                (hi - lo) / sd,
                if hi - lo > 3.0 * sd {
                    " (the corners, not the noise, make the difference: use the row held out best)"
                } else {
                    ""
                }
            )
        } else {
            String::new()
        };
        Some(format!("held out best: {} ({:.4} px on {} views){spread}", best.0.name, best.1, best.0.held_out_views))
    }
}

/// OpenCV's own recipe: `calibrateCamera` on the views (5 coefficients `k1 k2 p1 p2 k3`, flags
/// 0: OpenCV's own start, its default stopping rule), with its RMS and the standard deviations
/// of `fx fy cx cy` from `calibrateCameraExtended`.
pub fn opencv_calibrate_camera(views: &[View], target: &PlanarTarget) -> Result<Fitted> {
    use opencv::core::{Mat, Point2f, Point3f, Size, TermCriteria, Vector};
    use opencv::prelude::*;
    let cv = |e: opencv::Error| crate::error::VisionError::Backend { library: "opencv", message: e.to_string() };
    let first = views
        .first()
        .ok_or_else(|| crate::error::VisionError::InvalidInput { detail: "no view to calibrate from".into() })?;
    let size = first.image_size;
    let mut object = Vector::<Vector<Point3f>>::new();
    let mut image = Vector::<Vector<Point2f>>::new();
    for v in views {
        let mut o = Vector::<Point3f>::new();
        let mut i = Vector::<Point2f>::new();
        for (id, px) in v.point_ids.iter().zip(&v.corners_px) {
            let p = target.points_m[*id];
            o.push(Point3f::new(p.x as f32, p.y as f32, p.z as f32));
            i.push(Point2f::new(px.x as f32, px.y as f32));
        }
        object.push(o);
        image.push(i);
    }
    let mut k = Mat::default();
    let mut d = Mat::default();
    let (mut rv, mut tv) = (Vector::<Mat>::new(), Vector::<Mat>::new());
    let (mut sd_in, mut sd_ex, mut per_view) = (Mat::default(), Mat::default(), Mat::default());
    let criteria =
        TermCriteria::new(opencv::core::TermCriteria_COUNT + opencv::core::TermCriteria_EPS, 30, f64::EPSILON)
            .map_err(cv)?;
    let rms = opencv::calib3d::calibrate_camera_extended(
        &object,
        &image,
        Size::new(size.width_px as i32, size.height_px as i32),
        &mut k,
        &mut d,
        &mut rv,
        &mut tv,
        &mut sd_in,
        &mut sd_ex,
        &mut per_view,
        0,
        criteria,
    )
    .map_err(cv)?;
    let at = |m: &Mat, r: i32, c: i32| -> Result<f64> { m.at_2d::<f64>(r, c).copied().map_err(cv) };
    let intrinsics = crate::camera::Intrinsics {
        fx_px: at(&k, 0, 0)?,
        fy_px: at(&k, 1, 1)?,
        cx_px: at(&k, 0, 2)?,
        cy_px: at(&k, 1, 2)?,
    };
    let dv: Vec<f64> = (0..5).map(|i| d.at::<f64>(i).copied().map_err(cv)).collect::<Result<_>>()?;
    let distortion = crate::camera::Distortion::Brown5 { k1: dv[0], k2: dv[1], p1: dv[2], p2: dv[3], k3: dv[4] };
    let camera = crate::camera::CameraModel::new(intrinsics, distortion, size)?;
    let sd: Vec<f64> = (0..4).map(|i| sd_in.at::<f64>(i).copied().map_err(cv)).collect::<Result<_>>()?;
    Ok(Fitted { camera, rms_px: rms, std_px: [sd[0], sd[1], sd[2], sd[3]] })
}

/// What one detector returns for one image: `(point id, pixel)` pairs.
type Found = Vec<(usize, Point2<f64>)>;

/// One detector's corners on every image, calibrated by each of `calibrators` (one row each):
/// on all views for the reported camera, and on every second view for the held-out figure.
fn side(
    images: &[(String, GrayImage)],
    target: &PlanarTarget,
    mut detect: impl FnMut(&GrayImage) -> Found,
    calibrators: Vec<Calibrator<'_>>,
) -> Vec<SideReport> {
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
    let train: Vec<View> = views.iter().step_by(2).cloned().collect();
    let test: Vec<View> = views.iter().skip(1).step_by(2).cloned().collect();
    calibrators
        .into_iter()
        .map(|(name, calibrate)| {
            let (rms, k, sd, err) = match calibrate(&views) {
                Ok(c) => {
                    let i = c.camera.intrinsics;
                    (Some(c.rms_px), Some([i.fx_px, i.fy_px, i.cx_px, i.cy_px]), Some(c.std_px), None)
                }
                Err(e) => (None, None, None, Some(e.to_string())),
            };
            let held = (train.len() >= 2 && !test.is_empty())
                .then(|| calibrate(&train).ok())
                .flatten()
                .and_then(|c| held_out_reprojection(&c.camera, target, &test).ok());
            SideReport {
                name,
                images_found: views.len(),
                corners_per_image: counts.clone(),
                rms_px: rms,
                intrinsics_px: k,
                intrinsics_std_px: sd,
                calibration_error: err,
                time_per_image_s: time,
                held_out_rms_px: held.as_ref().and_then(|h| h.rms_px),
                held_out_views: held.map_or(0, |h| h.views.iter().filter(|v| v.rms_px.is_some()).count()),
            }
        })
        .collect()
}

/// The rows of an OpenCV detector: its corners through OpenCV's own `calibrateCamera`, and
/// through ferrocal's adjustment.
fn opencv_rows<'a>(detector: &str, target: &'a PlanarTarget, options: &'a CalibrationOptions) -> Vec<Calibrator<'a>> {
    vec![
        (format!("{detector}, OpenCV calibrateCamera"), Box::new(move |v: &[View]| opencv_calibrate_camera(v, target))),
        (
            format!("{detector}, ferrocal's adjustment"),
            Box::new(move |v: &[View]| calibrate_camera(v, target, options).map(Fitted::from)),
        ),
    ]
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
    let own_fit = |views: &[View]| -> Result<Fitted> {
        let r = radii.take();
        radii.set(r.clone());
        let med = |k: usize| super::median(&r.iter().map(|x| x[k]).collect::<Vec<f64>>());
        let rr = (!r.is_empty()).then(|| [med(0), med(1)]);
        match pattern {
            Pattern::Chessboard { .. } => calibrate_camera(views, &own_target, options).map(Fitted::from),
            _ => calibrate_pattern(views, pattern, rr, options).map(|p| p.calibration.into()),
        }
    };
    sides.extend(side(&images, &own_target, own_detect, vec![(own_name.to_string(), Box::new(own_fit))]));
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
                sides.extend(side(&images, &target, det, opencv_rows(name, &target, options)));
            }
        }
        Pattern::CircleGrid(g) if g.asymmetric => {
            let det = |img: &GrayImage| {
                all(crate::detect::baseline::opencv_find_asymmetric_circles_grid(img, g.cols, g.rows).ok().flatten())
            };
            let name = "OpenCV findCirclesGrid (asymmetric, default blob detector)";
            sides.extend(side(&images, &target, det, opencv_rows(name, &target, options)));
        }
        Pattern::CircleGrid(g) => {
            let det = |img: &GrayImage| all(opencv_find_circles_grid(img, g.cols, g.rows).ok().flatten());
            let name = "OpenCV findCirclesGrid (symmetric, default blob detector)";
            sides.extend(side(&images, &target, det, opencv_rows(name, &target, options)));
        }
        // OpenCV has no AprilTag-board finder: ferrocal's side only.
        Pattern::TagBoard(_) => {}
        Pattern::Chessboard { inner_cols, inner_rows, .. } => {
            // cornerSubPix with an 11 x 11 window, and with OpenCV's sample's (winSize 11: 23 x 23,
            // `camera calibrate --corners opencv`).
            for (half, name) in [
                (5, "OpenCV findChessboardCorners + cornerSubPix (11 x 11)"),
                (11, "OpenCV findChessboardCorners + cornerSubPix (23 x 23, OpenCV's sample)"),
            ] {
                let det = |img: &GrayImage| {
                    all(opencv_find_chessboard(img, inner_cols, inner_rows, Some(half)).ok().flatten())
                };
                sides.extend(side(&images, &target, det, opencv_rows(name, &target, options)));
            }
        }
    }
    Ok(Comparison {
        pattern: pattern.to_string(),
        images: images.into_iter().map(|i| i.0).collect(),
        unreadable,
        sides,
    })
}
