//! Corners for calibration. By default every pattern is found by the project's own detectors
//! ([`crate::detect`]: X-corners grown into a grid, then the edge-model refinement with a
//! covariance per corner; ChArUco boards and circle grids likewise), with point ids, so a
//! partial but anchored view is a view of the corners it shows ([`CornerMethod::Own`]).
//! Chessboards can instead be found with OpenCV's recipe ([`CornerMethod::OpenCv`]:
//! `findChessboardCorners` + `cornerSubPix`, 11 x 11 window, stop at 30 iterations or a move
//! below 0.1 px), the recipe that reproduces OpenCV's published calibration of its stereo
//! sample; the window shrinks on boards whose squares are smaller than the window when asked
//! ([`SubpixWindow::Adaptive`]). Images are processed in parallel (rayon), one detector per
//! worker thread; the results keep the input order.

use std::path::{Path, PathBuf};

use nalgebra::Point2;

use crate::camera::ImageSize;
use crate::error::{Result, VisionError};

/// The corners found in one image, row by row (OpenCV's order), pixel-centre convention.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageCorners {
    /// The image file.
    pub image: PathBuf,
    /// Its size.
    pub image_size: ImageSize,
    /// The inner corners, pixels.
    pub corners_px: Vec<Point2<f64>>,
}

fn unusable(path: &Path, reason: impl Into<String>) -> VisionError {
    VisionError::ImageUnusable { image: path.to_path_buf(), reason: reason.into() }
}

/// The `cornerSubPix` window.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SubpixWindow {
    /// OpenCV's sample recipe: half-size 11 (23 x 23 px) whatever the square size; reproduces
    /// OpenCV's published calibrations.
    #[default]
    #[serde(rename = "opencv")]
    OpenCv,
    /// Half-size 11 shrunk to 40 % of the smallest corner spacing where the squares are smaller
    /// ([`subpix_half_window`]), so the window never reaches the neighbouring corners.
    Adaptive,
}

/// Reads an image (greyscale) and finds a chessboard of `inner_cols x inner_rows` inner corners
/// with OpenCV's sample recipe ([`SubpixWindow::OpenCv`]). Errors name the image: missing or
/// unreadable file, empty file, empty image, chessboard not found.
pub fn chessboard_corners_opencv(path: &Path, inner_cols: u32, inner_rows: u32) -> Result<ImageCorners> {
    chessboard_corners_opencv_with(path, inner_cols, inner_rows, SubpixWindow::OpenCv)
}

/// [`chessboard_corners_opencv`] with a choice of the `cornerSubPix` window.
pub fn chessboard_corners_opencv_with(
    path: &Path,
    inner_cols: u32,
    inner_rows: u32,
    window: SubpixWindow,
) -> Result<ImageCorners> {
    use opencv::prelude::*;
    let meta = std::fs::metadata(path).map_err(|e| unusable(path, format!("cannot open: {e}")))?;
    if meta.len() == 0 {
        return Err(unusable(path, "empty file (0 bytes)"));
    }
    // Dimensions, format and completeness checked before OpenCV decodes (it only warns on a
    // truncated JPEG and returns the grey-filled image).
    crate::detect::check_image_file(path).map_err(|reason| unusable(path, reason))?;
    let img = opencv::imgcodecs::imread(path, opencv::imgcodecs::IMREAD_GRAYSCALE)
        .map_err(|e| unusable(path, format!("cannot decode: {e}")))?;
    if img.empty() || img.cols() <= 0 || img.rows() <= 0 {
        return Err(unusable(path, "cannot decode: not an image OpenCV can read, or truncated"));
    }
    let image_size = ImageSize { width_px: img.cols() as u32, height_px: img.rows() as u32 };
    let corners =
        find_in_mat(&img, inner_cols, inner_rows, window).map_err(|e| unusable(path, format!("OpenCV: {e}")))?;
    match corners {
        Some(corners_px) => Ok(ImageCorners { image: path.to_path_buf(), image_size, corners_px }),
        None => Err(unusable(
            path,
            format!(
                "chessboard with {inner_cols}x{inner_rows} inner corners not found (is the whole board in view, \
                 and are cols x rows the inner corners?)"
            ),
        )),
    }
}

/// The same on an 8-bit greyscale image in memory (`None` when the board is not found).
pub fn chessboard_corners_opencv_gray(
    image: &image::GrayImage,
    inner_cols: u32,
    inner_rows: u32,
    window: SubpixWindow,
) -> Result<Option<Vec<Point2<f64>>>> {
    use opencv::core::{Mat, CV_8UC1};
    use opencv::prelude::*;
    let (w, h) = image.dimensions();
    let to_err = |e: opencv::Error| VisionError::InvalidInput { detail: format!("OpenCV: {e}") };
    let mut mat =
        Mat::new_rows_cols_with_default(h as i32, w as i32, CV_8UC1, opencv::core::Scalar::all(0.0)).map_err(to_err)?;
    mat.data_bytes_mut().map_err(to_err)?.copy_from_slice(image.as_raw());
    find_in_mat(&mat, inner_cols, inner_rows, window).map_err(to_err)
}

/// Half-size of the `cornerSubPix` window: OpenCV's 11 (a 23 x 23 px window) unless the
/// closest two corners are nearer than 2.5 times that; then 40 % of their distance (at least 2).
pub fn subpix_half_window(corner_spacing_px: f64) -> i32 {
    if !(corner_spacing_px.is_finite()) || corner_spacing_px >= 27.5 {
        11
    } else {
        ((0.4 * corner_spacing_px).floor() as i32).clamp(2, 11)
    }
}

fn find_in_mat(
    img: &opencv::core::Mat,
    inner_cols: u32,
    inner_rows: u32,
    window: SubpixWindow,
) -> opencv::Result<Option<Vec<Point2<f64>>>> {
    use opencv::core::{Point2f, Size, TermCriteria, Vector};
    let size = Size::new(inner_cols as i32, inner_rows as i32);
    let mut corners: Vector<Point2f> = Vector::new();
    let found = opencv::calib3d::find_chessboard_corners(
        img,
        size,
        &mut corners,
        opencv::calib3d::CALIB_CB_ADAPTIVE_THRESH | opencv::calib3d::CALIB_CB_NORMALIZE_IMAGE,
    )?;
    if !found || corners.len() != (inner_cols * inner_rows) as usize {
        return Ok(None);
    }
    // OpenCV's 11 x 11 half-window (23 x 23 px), shrunk where the squares are smaller so that
    // the window never reaches the neighbouring corners.
    let pts: Vec<(f64, f64)> = corners.iter().map(|p| (f64::from(p.x), f64::from(p.y))).collect();
    let dist = |a: (f64, f64), b: (f64, f64)| (a.0 - b.0).hypot(a.1 - b.1);
    let mut spacing = f64::INFINITY;
    for r in 0..inner_rows as usize {
        for c in 0..inner_cols as usize {
            let i = r * inner_cols as usize + c;
            if c + 1 < inner_cols as usize {
                spacing = spacing.min(dist(pts[i], pts[i + 1]));
            }
            if r + 1 < inner_rows as usize {
                spacing = spacing.min(dist(pts[i], pts[i + inner_cols as usize]));
            }
        }
    }
    let half = match window {
        SubpixWindow::OpenCv => 11,
        SubpixWindow::Adaptive => subpix_half_window(spacing),
    };
    let criteria = TermCriteria::new(opencv::core::TermCriteria_COUNT + opencv::core::TermCriteria_EPS, 30, 0.1)?;
    opencv::imgproc::corner_sub_pix(img, &mut corners, Size::new(half, half), Size::new(-1, -1), criteria)?;
    Ok(Some(corners.iter().map(|p| Point2::new(f64::from(p.x), f64::from(p.y))).collect()))
}

/// Which corners a calibration is computed from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CornerMethod {
    /// The project's detectors and edge-model refinement (every pattern kind).
    #[default]
    Own,
    /// Chessboards: OpenCV's `findChessboardCorners` + `cornerSubPix` with this window (other
    /// patterns are still found by the project's detectors).
    #[serde(rename = "opencv")]
    OpenCv(SubpixWindow),
    /// Detections made elsewhere, read from an observations file (`--observations`).
    Observations,
}

impl CornerMethod {
    /// The method named `own` or `opencv` (the command line's `--corners`; OpenCV's with its
    /// sample's window); any other name is refused with the two choices.
    pub fn named(name: &str) -> std::result::Result<Self, String> {
        match name {
            "own" => Ok(CornerMethod::Own),
            "opencv" => Ok(CornerMethod::OpenCv(SubpixWindow::OpenCv)),
            _ => Err(format!("'{name}' is not a corner source; use own or opencv")),
        }
    }

    /// The same method with OpenCV's `cornerSubPix` window `window` (the own method has none).
    pub fn with_window(self, window: SubpixWindow) -> Self {
        match self {
            CornerMethod::Own => CornerMethod::Own,
            CornerMethod::OpenCv(_) => CornerMethod::OpenCv(window),
            CornerMethod::Observations => CornerMethod::Observations,
        }
    }
}

/// An image left out of a calibration, and why.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SkippedImage {
    /// The image file.
    pub image: PathBuf,
    /// Why it was left out.
    pub reason: String,
}

impl std::fmt::Display for SkippedImage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.image.display(), self.reason)
    }
}

/// The views found in a batch of images.
#[derive(Clone, Debug, PartialEq)]
pub struct PatternViews {
    /// One slot per path (`None` where the image is unusable).
    pub slots: Vec<Option<super::View>>,
    /// The unusable images with their reasons.
    pub skipped: Vec<SkippedImage>,
    /// Circle grids: the dots' radii on the target, metres (`[small, large]`, medians over the
    /// views), for the perspective-bias correction.
    pub circle_radii_m: Option<[f64; 2]>,
}

/// Finds the pattern in every image, one slot per path (`None` where the image is unusable).
/// A bad image (missing, empty, undecodable, pattern not found) never stops the batch: it is
/// listed in the second result with the reason. Images whose size differs from the most common
/// size (ties: the first seen) are left out too, with the sizes in the reason.
pub fn detect_view_slots(
    paths: &[PathBuf],
    pattern: &super::CalibrationPattern,
    method: CornerMethod,
) -> (Vec<Option<super::View>>, Vec<SkippedImage>) {
    let v = detect_pattern_views(paths, pattern, method);
    (v.slots, v.skipped)
}

/// [`detect_view_slots`] with what the detector measured besides the corners. Chessboards are
/// found by the project's detector or with OpenCV's recipe ([`chessboard_corners_opencv_with`])
/// as `method` says, ChArUco boards and circle grids by the project's detectors
/// ([`crate::detect`]; their corners carry point ids, so a partial ChArUco view is a view of
/// the corners it shows). The images are read and searched in parallel.
pub fn detect_pattern_views(
    paths: &[PathBuf],
    pattern: &super::CalibrationPattern,
    method: CornerMethod,
) -> PatternViews {
    use rayon::prelude::*;
    let own = match (pattern, method) {
        (super::CalibrationPattern::Chessboard { .. }, CornerMethod::OpenCv(_)) => None,
        _ => Some(pattern.pattern()),
    };
    let found: Vec<Result<(super::View, Option<[f64; 2]>)>> = paths
        .par_iter()
        .map_init(
            || own.map(|p| crate::detect::Detector::new(p, pattern.detect_options(), None)),
            |detector, p| match (detector, *pattern, method) {
                (
                    None,
                    super::CalibrationPattern::Chessboard { inner_cols, inner_rows, .. },
                    CornerMethod::OpenCv(w),
                ) => chessboard_corners_opencv_with(p, inner_cols, inner_rows, w)
                    .map(|c| (super::View::new(p.display().to_string(), c.image_size, c.corners_px), None)),
                (Some(Ok(det)), _, _) => own_view(det, p),
                (Some(Err(e)), _, _) => Err(unusable(p, e.to_string())),
                (None, _, _) => Err(unusable(p, "no detector for this pattern")),
            },
        )
        .collect();
    let mut slots = Vec::with_capacity(paths.len());
    let mut skipped = Vec::new();
    let mut radii: Vec<[f64; 2]> = Vec::new();
    for (p, f) in paths.iter().zip(found) {
        match f {
            Ok((v, r)) => {
                radii.extend(r);
                slots.push(Some(v));
            }
            Err(VisionError::ImageUnusable { image, reason }) => {
                skipped.push(SkippedImage { image, reason });
                slots.push(None);
            }
            Err(e) => {
                skipped.push(SkippedImage { image: p.clone(), reason: e.to_string() });
                slots.push(None);
            }
        }
    }
    keep_main_size(&mut slots, paths, &mut skipped);
    let circle_radii_m = (!radii.is_empty()).then(|| {
        let med = |k: usize| super::median(&radii.iter().map(|r| r[k]).collect::<Vec<f64>>());
        [med(0), med(1)]
    });
    PatternViews { slots, skipped, circle_radii_m }
}

/// One image through the project's detector: the view of its corners with point ids.
fn own_view(det: &mut crate::detect::Detector, path: &Path) -> Result<(super::View, Option<[f64; 2]>)> {
    let img = crate::detect::load_gray(path).map_err(|e| unusable(path, e.to_string()))?;
    let size = ImageSize { width_px: img.width(), height_px: img.height() };
    let found = det.detect(&img).map_err(|e| unusable(path, e.to_string()))?;
    // An AprilTag board gives one detection per tag: their corners together are the view.
    let tag_board = matches!(det.pattern(), crate::detect::Pattern::AprilBoard { .. });
    let d = if tag_board {
        let Some(mut first) = found.first().cloned() else {
            return Err(unusable(path, "pattern not found"));
        };
        first.corners = found.into_iter().flat_map(|d| d.corners).collect();
        first
    } else {
        let Some(d) = found.into_iter().max_by_key(|d| d.corners.len()) else {
            return Err(unusable(path, "pattern not found"));
        };
        d
    };
    let (ids, px): (Vec<usize>, Vec<Point2<f64>>) =
        d.corners.iter().filter_map(|c| c.point_id.map(|i| (i as usize, c.position_px))).unzip();
    if !d.anchored {
        return Err(unusable(
            path,
            format!(
                "partial view of {} corners whose rows and columns cannot be told (no board edge in view)",
                d.corners.len()
            ),
        ));
    }
    if ids.len() < 4 {
        return Err(unusable(path, format!("only {} corners with ids, a view needs at least 4", ids.len())));
    }
    let mut v = super::View::new(path.display().to_string(), size, px);
    v.point_ids = ids;
    Ok((v, d.circle_radii_m))
}

/// Leaves out the views whose image size is not the most common one (ties: the first seen).
fn keep_main_size(slots: &mut [Option<super::View>], paths: &[PathBuf], skipped: &mut Vec<SkippedImage>) {
    let mut counts: Vec<(ImageSize, usize)> = Vec::new();
    for v in slots.iter().flatten() {
        match counts.iter_mut().find(|(s, _)| *s == v.image_size) {
            Some((_, n)) => *n += 1,
            None => counts.push((v.image_size, 1)),
        }
    }
    if counts.len() > 1 {
        let (main, n_main) = counts.iter().fold(counts[0], |best, c| if c.1 > best.1 { *c } else { best });
        for (slot, path) in slots.iter_mut().zip(paths) {
            if let Some(v) = slot {
                if v.image_size != main {
                    skipped.push(SkippedImage {
                        image: path.clone(),
                        reason: format!(
                            "image is {}x{} but {n_main} other image(s) are {}x{}: one calibration needs one image size \
                             (calibrate each camera and resolution separately)",
                            v.image_size.width_px, v.image_size.height_px, main.width_px, main.height_px
                        ),
                    });
                    *slot = None;
                }
            }
        }
    }
}

/// [`detect_view_slots`] without the empty slots.
pub fn detect_views(
    paths: &[PathBuf],
    pattern: &super::CalibrationPattern,
    method: CornerMethod,
) -> (Vec<super::View>, Vec<SkippedImage>) {
    let (slots, skipped) = detect_view_slots(paths, pattern, method);
    (slots.into_iter().flatten().collect(), skipped)
}
