//! OpenCV, the baseline every vision result is compared with: its chessboard detectors,
//! `cornerSubPix` and `findCirclesGrid`, called the way OpenCV users call them (OpenCV's
//! ChArUco corners are in [`super::aruco`]). OpenCV's corner coordinates use the
//! same convention as this project (pixel `(0, 0)` is the centre of the top-left pixel).

use image::GrayImage;
use nalgebra::Point2;
use opencv::core::{Mat, Point2f, Size, TermCriteria, Vector};
use opencv::prelude::*;

use crate::error::{Result, VisionError};

fn cv_err(e: opencv::Error) -> VisionError {
    VisionError::Backend { library: "opencv", message: e.to_string() }
}

fn to_mat(img: &GrayImage) -> Result<Mat> {
    if img.width() == 0 || img.height() == 0 {
        return Err(VisionError::BadImage { reason: "the image has no pixels".into() });
    }
    let flat = Mat::from_slice(img.as_raw()).map_err(cv_err)?;
    flat.reshape(1, img.height() as i32).map_err(cv_err)?.try_clone().map_err(cv_err)
}

fn to_points(v: &Vector<Point2f>) -> Vec<Point2<f64>> {
    v.iter().map(|p| Point2::new(f64::from(p.x), f64::from(p.y))).collect()
}

/// Stopping rule of `cornerSubPix`: 30 iterations or a step below `eps` pixels.
fn criteria(eps: f64) -> Result<TermCriteria> {
    TermCriteria::new(opencv::core::TermCriteria_COUNT + opencv::core::TermCriteria_EPS, 30, eps).map_err(cv_err)
}

/// `cornerSubPix` with a `(2 half_window + 1)^2` window (5 gives OpenCV users' usual 11 x 11),
/// no dead zone, 30 iterations or a step below `eps` px, started from `corners`.
pub fn opencv_corner_subpix(
    img: &GrayImage,
    corners: &[Point2<f64>],
    half_window: i32,
    eps: f64,
) -> Result<Vec<Point2<f64>>> {
    let mat = to_mat(img)?;
    let mut v: Vector<Point2f> = corners.iter().map(|p| Point2f::new(p.x as f32, p.y as f32)).collect();
    if v.is_empty() {
        return Ok(Vec::new());
    }
    opencv::imgproc::corner_sub_pix(
        &mat,
        &mut v,
        Size::new(half_window, half_window),
        Size::new(-1, -1),
        criteria(eps)?,
    )
    .map_err(cv_err)?;
    Ok(to_points(&v))
}

/// `findChessboardCorners` (adaptive threshold, normalised image) followed, when
/// `subpix_half_window` is given, by `cornerSubPix` with that half window (eps 0.01): the
/// classic OpenCV recipe. `None` when OpenCV does not find the board.
pub fn opencv_find_chessboard(
    img: &GrayImage,
    cols: u32,
    rows: u32,
    subpix_half_window: Option<i32>,
) -> Result<Option<Vec<Point2<f64>>>> {
    let mat = to_mat(img)?;
    let mut v: Vector<Point2f> = Vector::new();
    let found = opencv::calib3d::find_chessboard_corners(
        &mat,
        Size::new(cols as i32, rows as i32),
        &mut v,
        opencv::calib3d::CALIB_CB_ADAPTIVE_THRESH | opencv::calib3d::CALIB_CB_NORMALIZE_IMAGE,
    )
    .map_err(cv_err)?;
    if !found {
        return Ok(None);
    }
    if let Some(hw) = subpix_half_window {
        opencv::imgproc::corner_sub_pix(&mat, &mut v, Size::new(hw, hw), Size::new(-1, -1), criteria(0.01)?)
            .map_err(cv_err)?;
    }
    Ok(Some(to_points(&v)))
}

/// `findChessboardCornersSB` (normalised image, exhaustive search, and with `accuracy` the
/// up-sampled accurate mode). `None` when OpenCV does not find the board.
pub fn opencv_find_chessboard_sb(
    img: &GrayImage,
    cols: u32,
    rows: u32,
    accuracy: bool,
) -> Result<Option<Vec<Point2<f64>>>> {
    let mat = to_mat(img)?;
    let mut v: Vector<Point2f> = Vector::new();
    let mut flags = opencv::calib3d::CALIB_CB_NORMALIZE_IMAGE | opencv::calib3d::CALIB_CB_EXHAUSTIVE;
    if accuracy {
        flags |= opencv::calib3d::CALIB_CB_ACCURACY;
    }
    let found = opencv::calib3d::find_chessboard_corners_sb(&mat, Size::new(cols as i32, rows as i32), &mut v, flags)
        .map_err(cv_err)?;
    Ok(found.then(|| to_points(&v)))
}

/// `findCirclesGrid` with OpenCV's defaults (`CALIB_CB_SYMMETRIC_GRID`, the default
/// `SimpleBlobDetector`: dark blobs): the dot centres of a `cols x rows` grid in OpenCV's
/// order, `None` when OpenCV does not find the grid.
pub fn opencv_find_circles_grid(img: &GrayImage, cols: u32, rows: u32) -> Result<Option<Vec<Point2<f64>>>> {
    let mat = to_mat(img)?;
    let mut v: Vector<Point2f> = Vector::new();
    let found =
        opencv::calib3d::find_circles_grid_def(&mat, Size::new(cols as i32, rows as i32), &mut v).map_err(cv_err)?;
    Ok((found && v.len() == (cols * rows) as usize).then(|| to_points(&v)))
}

/// OpenCV's `findCirclesGrid` with `CALIB_CB_ASYMMETRIC_GRID` and the default blob detector
/// (dark dots): `cols` dots per row, `rows` rows, in OpenCV's order; `None` when not found.
/// Light dots on a dark ground are found by passing the inverted image, as OpenCV's users do.
pub fn opencv_find_asymmetric_circles_grid(img: &GrayImage, cols: u32, rows: u32) -> Result<Option<Vec<Point2<f64>>>> {
    let mat = to_mat(img)?;
    let mut v: Vector<Point2f> = Vector::new();
    let blobs: opencv::core::Ptr<opencv::features2d::Feature2D> =
        opencv::features2d::SimpleBlobDetector::create_def().map_err(cv_err)?.into();
    let found = opencv::calib3d::find_circles_grid(
        &mat,
        Size::new(cols as i32, rows as i32),
        &mut v,
        opencv::calib3d::CALIB_CB_ASYMMETRIC_GRID,
        Some(&blobs),
    )
    .map_err(cv_err)?;
    Ok((found && v.len() == (cols * rows) as usize).then(|| to_points(&v)))
}
