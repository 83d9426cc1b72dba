//! ArUco markers through OpenCV's contrib `aruco` module (OpenCV 4.6): the predefined
//! dictionaries by their OpenCV names, marker detection and decoding, the markers' bit
//! patterns (for drawing boards), and OpenCV's own ChArUco corners (`interpolateCornersCharuco`,
//! the baseline the project's ChArUco corners are compared with).
//!
//! Marker corners come back in OpenCV's order (clockwise in the image as printed: top-left,
//! top-right, bottom-right, bottom-left of the marker) with this project's pixel convention
//! (OpenCV's: pixel `(0, 0)` is the centre of the top-left pixel).

use std::fmt;
use std::str::FromStr;

use image::GrayImage;
use nalgebra::Point2;
use opencv::aruco::{BoardTraitConst, CharucoBoard, DetectorParametersTrait, Dictionary, DictionaryTraitConst};
use opencv::core::{Mat, Point2f, Ptr, Vector};
use opencv::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::{Result, VisionError};

/// The predefined ArUco dictionaries, by their OpenCV names (`DICT_6X6_250`, ...).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum ArucoDictionary {
    /// `DICT_4X4_50`.
    #[serde(rename = "DICT_4X4_50")]
    Dict4x4_50,
    /// `DICT_4X4_100`.
    #[serde(rename = "DICT_4X4_100")]
    Dict4x4_100,
    /// `DICT_4X4_250`.
    #[serde(rename = "DICT_4X4_250")]
    Dict4x4_250,
    /// `DICT_4X4_1000`.
    #[serde(rename = "DICT_4X4_1000")]
    Dict4x4_1000,
    /// `DICT_5X5_50`.
    #[serde(rename = "DICT_5X5_50")]
    Dict5x5_50,
    /// `DICT_5X5_100`.
    #[serde(rename = "DICT_5X5_100")]
    Dict5x5_100,
    /// `DICT_5X5_250`.
    #[serde(rename = "DICT_5X5_250")]
    Dict5x5_250,
    /// `DICT_5X5_1000`.
    #[serde(rename = "DICT_5X5_1000")]
    Dict5x5_1000,
    /// `DICT_6X6_50`.
    #[serde(rename = "DICT_6X6_50")]
    Dict6x6_50,
    /// `DICT_6X6_100`.
    #[serde(rename = "DICT_6X6_100")]
    Dict6x6_100,
    /// `DICT_6X6_250`.
    #[serde(rename = "DICT_6X6_250")]
    Dict6x6_250,
    /// `DICT_6X6_1000`.
    #[serde(rename = "DICT_6X6_1000")]
    Dict6x6_1000,
    /// `DICT_7X7_50`.
    #[serde(rename = "DICT_7X7_50")]
    Dict7x7_50,
    /// `DICT_7X7_100`.
    #[serde(rename = "DICT_7X7_100")]
    Dict7x7_100,
    /// `DICT_7X7_250`.
    #[serde(rename = "DICT_7X7_250")]
    Dict7x7_250,
    /// `DICT_7X7_1000`.
    #[serde(rename = "DICT_7X7_1000")]
    Dict7x7_1000,
    /// `DICT_ARUCO_ORIGINAL`.
    #[serde(rename = "DICT_ARUCO_ORIGINAL")]
    ArucoOriginal,
    /// `DICT_APRILTAG_16h5`.
    #[serde(rename = "DICT_APRILTAG_16h5")]
    AprilTag16h5,
    /// `DICT_APRILTAG_25h9`.
    #[serde(rename = "DICT_APRILTAG_25h9")]
    AprilTag25h9,
    /// `DICT_APRILTAG_36h10`.
    #[serde(rename = "DICT_APRILTAG_36h10")]
    AprilTag36h10,
    /// `DICT_APRILTAG_36h11`.
    #[serde(rename = "DICT_APRILTAG_36h11")]
    AprilTag36h11,
}

impl ArucoDictionary {
    /// Every dictionary, in OpenCV's enumeration order (`PREDEFINED_DICTIONARY_NAME`).
    pub const ALL: [ArucoDictionary; 21] = [
        Self::Dict4x4_50,
        Self::Dict4x4_100,
        Self::Dict4x4_250,
        Self::Dict4x4_1000,
        Self::Dict5x5_50,
        Self::Dict5x5_100,
        Self::Dict5x5_250,
        Self::Dict5x5_1000,
        Self::Dict6x6_50,
        Self::Dict6x6_100,
        Self::Dict6x6_250,
        Self::Dict6x6_1000,
        Self::Dict7x7_50,
        Self::Dict7x7_100,
        Self::Dict7x7_250,
        Self::Dict7x7_1000,
        Self::ArucoOriginal,
        Self::AprilTag16h5,
        Self::AprilTag25h9,
        Self::AprilTag36h10,
        Self::AprilTag36h11,
    ];

    /// OpenCV's enumeration value (`DICT_6X6_250` = 10, as in OpenCV's and the ROS-Industrial
    /// configuration files).
    pub fn opencv_id(self) -> i32 {
        Self::ALL.iter().position(|d| *d == self).expect("listed") as i32
    }

    /// OpenCV's name.
    pub fn name(self) -> &'static str {
        const NAMES: [&str; 21] = [
            "DICT_4X4_50",
            "DICT_4X4_100",
            "DICT_4X4_250",
            "DICT_4X4_1000",
            "DICT_5X5_50",
            "DICT_5X5_100",
            "DICT_5X5_250",
            "DICT_5X5_1000",
            "DICT_6X6_50",
            "DICT_6X6_100",
            "DICT_6X6_250",
            "DICT_6X6_1000",
            "DICT_7X7_50",
            "DICT_7X7_100",
            "DICT_7X7_250",
            "DICT_7X7_1000",
            "DICT_ARUCO_ORIGINAL",
            "DICT_APRILTAG_16h5",
            "DICT_APRILTAG_25h9",
            "DICT_APRILTAG_36h10",
            "DICT_APRILTAG_36h11",
        ];
        NAMES[self.opencv_id() as usize]
    }

    /// Number of markers in the dictionary.
    pub fn size(self) -> u32 {
        match self.opencv_id() {
            k @ 0..=15 => [50, 100, 250, 1000][(k % 4) as usize],
            16 => 1024,
            17 => 30,
            18 => 35,
            19 => 2320,
            _ => 587,
        }
    }

    /// OpenCV's dictionary object.
    pub(crate) fn opencv(self) -> Result<Ptr<Dictionary>> {
        opencv::aruco::get_predefined_dictionary_i32(self.opencv_id()).map_err(cv_err)
    }
}

impl FromStr for ArucoDictionary {
    type Err = String;
    /// OpenCV's name, case-insensitive, with or without the `DICT_` prefix (`DICT_6X6_250`,
    /// `6x6_250`), or OpenCV's number (`10`).
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        let t = s.trim();
        if let Ok(k) = t.parse::<usize>() {
            return Self::ALL.get(k).copied().ok_or_else(|| format!("no ArUco dictionary number {k} (0..=20)"));
        }
        let key = t.to_ascii_uppercase();
        let key = key.strip_prefix("DICT_").unwrap_or(&key);
        Self::ALL
            .into_iter()
            .find(|d| d.name().to_ascii_uppercase().strip_prefix("DICT_") == Some(key))
            .ok_or_else(|| format!("unknown ArUco dictionary '{s}'"))
    }
}

impl fmt::Display for ArucoDictionary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

pub(crate) fn cv_err(e: opencv::Error) -> VisionError {
    VisionError::Backend { library: "opencv", message: e.to_string() }
}

pub(crate) fn to_mat(img: &GrayImage) -> Result<Mat> {
    if img.width() == 0 || img.height() == 0 {
        return Err(VisionError::BadImage { reason: "the image has no pixels".into() });
    }
    let flat = Mat::from_slice(img.as_raw()).map_err(cv_err)?;
    flat.reshape(1, img.height() as i32).map_err(cv_err)?.try_clone().map_err(cv_err)
}

/// One decoded marker.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Marker {
    /// Its id in the dictionary.
    pub id: u32,
    /// Its four outer corners, pixels, in OpenCV's order (top-left, top-right, bottom-right,
    /// bottom-left as printed).
    pub corners_px: [Point2<f64>; 4],
}

/// Which `DetectorParameters` OpenCV's marker detection runs with.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MarkerParams {
    /// OpenCV's defaults.
    OpenCv,
    /// The bits read from the middle of each cell (`perspectiveRemovePixelPerCell` 8,
    /// `perspectiveRemoveIgnoredMarginPerCell` 0.3) and a more tolerant bit correction
    /// (`errorCorrectionRate` 0.8): blurred or small markers, whose cells bleed into each
    /// other, decode far more often (on the ROS-Industrial ChArUco set 265 of 272 markers
    /// against 232 with OpenCV's defaults). A wrongly decoded id is caught by the ChArUco
    /// detector's check that a corner's two markers agree.
    #[default]
    Tolerant,
}

fn detector_params(params: MarkerParams) -> Result<Ptr<opencv::aruco::DetectorParameters>> {
    let mut p = opencv::aruco::DetectorParameters::create().map_err(cv_err)?;
    if params == MarkerParams::Tolerant {
        p.set_perspective_remove_pixel_per_cell(8);
        p.set_perspective_remove_ignored_margin_per_cell(0.3);
        p.set_error_correction_rate(0.8);
    }
    Ok(p)
}

type CvMarkers = (Vector<Vector<Point2f>>, Vector<i32>);

fn cv_detect(mat: &Mat, dictionary: ArucoDictionary, params: MarkerParams) -> Result<CvMarkers> {
    let dict = dictionary.opencv()?;
    let p = detector_params(params)?;
    let mut corners: Vector<Vector<Point2f>> = Vector::new();
    let mut ids: Vector<i32> = Vector::new();
    let mut rejected: Vector<Vector<Point2f>> = Vector::new();
    opencv::aruco::detect_markers(mat, &dict, &mut corners, &mut ids, &p, &mut rejected).map_err(cv_err)?;
    Ok((corners, ids))
}

/// Detects and decodes the markers of `dictionary` with OpenCV's `detectMarkers`.
pub fn detect_markers(img: &GrayImage, dictionary: ArucoDictionary, params: MarkerParams) -> Result<Vec<Marker>> {
    let mat = to_mat(img)?;
    let (corners, ids) = cv_detect(&mat, dictionary, params)?;
    let mut out = Vec::with_capacity(ids.len());
    for (id, c) in ids.iter().zip(corners.iter()) {
        if id < 0 || c.len() != 4 {
            continue;
        }
        let p = |k: usize| {
            let q = c.get(k).unwrap_or_default();
            Point2::new(f64::from(q.x), f64::from(q.y))
        };
        out.push(Marker { id: id as u32, corners_px: [p(0), p(1), p(2), p(3)] });
    }
    Ok(out)
}

/// The 8-bit image at half resolution: the mean of each 2 x 2 block (an odd last row or column
/// is dropped). Pixel `(x, y)` of the result covers `(2x, 2y)` to `(2x + 1, 2y + 1)` of the
/// source, so its centre is at `(2x + 0.5, 2y + 0.5)` there.
pub fn half_resolution(img: &GrayImage) -> GrayImage {
    let (w, h) = (img.width() / 2, img.height() / 2);
    let src = img.as_raw();
    let sw = img.width() as usize;
    let mut out = vec![0u8; w as usize * h as usize];
    if w > 0 {
        for (y, dst) in out.chunks_exact_mut(w as usize).enumerate() {
            let (r0, r1) = (&src[2 * y * sw..(2 * y + 1) * sw], &src[(2 * y + 1) * sw..(2 * y + 2) * sw]);
            // Exact chunks without bounds checks: the compiler vectorizes the row.
            for ((d, a), b) in dst.iter_mut().zip(r0.chunks_exact(2)).zip(r1.chunks_exact(2)) {
                let s = u16::from(a[0]) + u16::from(a[1]) + u16::from(b[0]) + u16::from(b[1]);
                *d = ((s + 2) / 4) as u8;
            }
        }
    }
    GrayImage::from_raw(w, h, out).expect("w * h values")
}

/// The bits of marker `id` of `dictionary` as printed, row by row from the top-left,
/// including the one-cell black border (`true` = white): `(n + 2)^2` values for an `n x n`
/// code. From OpenCV's `drawMarker` (for drawing boards in simulations).
pub fn marker_bits(dictionary: ArucoDictionary, id: u32) -> Result<(usize, Vec<bool>)> {
    let dict = dictionary.opencv()?;
    if id >= dictionary.size() {
        return Err(VisionError::InvalidInput {
            detail: format!("marker {id} is not in {dictionary} ({} markers)", dictionary.size()),
        });
    }
    let n = dict.marker_size() as usize + 2;
    let side = 10 * n;
    let mut img = Mat::default();
    dict.draw_marker(id as i32, side as i32, &mut img, 1).map_err(cv_err)?;
    let mut bits = Vec::with_capacity(n * n);
    for r in 0..n {
        for c in 0..n {
            let v = *img.at_2d::<u8>((10 * r + 5) as i32, (10 * c + 5) as i32).map_err(cv_err)?;
            bits.push(v > 127);
        }
    }
    Ok((n, bits))
}

/// OpenCV's ChArUco layout for a board of `squares_x x squares_y` squares: marker ids with
/// the centres of their squares in OpenCV's board frame (origin at a board corner, metres
/// when the lengths are), and the chessboard corners in id order. For checking the project's
/// layout against OpenCV's.
pub struct OpencvCharucoLayout {
    /// `(marker id, centre of its four object points)`.
    pub markers: Vec<(u32, [f64; 2])>,
    /// Chessboard corners in id order.
    pub corners: Vec<[f64; 2]>,
}

fn charuco_board(
    squares_x: u32,
    squares_y: u32,
    square: f64,
    marker: f64,
    dictionary: ArucoDictionary,
) -> Result<Ptr<CharucoBoard>> {
    let dict = dictionary.opencv()?;
    CharucoBoard::create(squares_x as i32, squares_y as i32, square as f32, marker as f32, &dict).map_err(cv_err)
}

/// OpenCV's layout of a ChArUco board (see [`OpencvCharucoLayout`]).
pub fn opencv_charuco_layout(
    squares_x: u32,
    squares_y: u32,
    square: f64,
    marker: f64,
    dictionary: ArucoDictionary,
) -> Result<OpencvCharucoLayout> {
    use opencv::aruco::CharucoBoardTraitConst;
    let board = charuco_board(squares_x, squares_y, square, marker, dictionary)?;
    let ids = board.ids();
    let obj = board.obj_points();
    let mut markers = Vec::new();
    for (id, pts) in ids.iter().zip(obj.iter()) {
        let (mut x, mut y) = (0.0, 0.0);
        for p in pts.iter() {
            x += f64::from(p.x) / 4.0;
            y += f64::from(p.y) / 4.0;
        }
        markers.push((id as u32, [x, y]));
    }
    let corners = board.chessboard_corners().iter().map(|p| [f64::from(p.x), f64::from(p.y)]).collect();
    Ok(OpencvCharucoLayout { markers, corners })
}

/// OpenCV's ChArUco corners: `detectMarkers` (with `params`) and `interpolateCornersCharuco`
/// without a camera model (local homographies from the markers, then OpenCV's own
/// `cornerSubPix` inside that function), at least `min_markers` adjacent markers per corner.
/// `(corner id, position)` pairs in OpenCV's order.
pub fn opencv_charuco_corners(
    img: &GrayImage,
    board: &super::CharucoBoard,
    params: MarkerParams,
    min_markers: i32,
) -> Result<Vec<(u32, Point2<f64>)>> {
    let mat = to_mat(img)?;
    let cv_board =
        charuco_board(board.cols, board.rows, board.square_mm * 1e-3, board.marker_mm * 1e-3, board.dictionary)?;
    let (corners, ids) = cv_detect(&mat, board.dictionary, params)?;
    if ids.is_empty() {
        return Ok(Vec::new());
    }
    let mut ch_corners: Vector<Point2f> = Vector::new();
    let mut ch_ids: Vector<i32> = Vector::new();
    opencv::aruco::interpolate_corners_charuco(
        &corners,
        &ids,
        &mat,
        &cv_board,
        &mut ch_corners,
        &mut ch_ids,
        &opencv::core::no_array(),
        &opencv::core::no_array(),
        min_markers,
    )
    .map_err(cv_err)?;
    Ok(ch_ids
        .iter()
        .zip(ch_corners.iter())
        .map(|(id, p)| (id as u32, Point2::new(f64::from(p.x), f64::from(p.y))))
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dictionaries_parse_by_name_and_number() {
        assert_eq!("DICT_6X6_250".parse::<ArucoDictionary>().unwrap(), ArucoDictionary::Dict6x6_250);
        assert_eq!("6x6_250".parse::<ArucoDictionary>().unwrap(), ArucoDictionary::Dict6x6_250);
        assert_eq!("10".parse::<ArucoDictionary>().unwrap(), ArucoDictionary::Dict6x6_250);
        assert_eq!("dict_apriltag_36h11".parse::<ArucoDictionary>().unwrap(), ArucoDictionary::AprilTag36h11);
        assert_eq!(ArucoDictionary::Dict6x6_250.opencv_id(), 10);
        assert_eq!(ArucoDictionary::AprilTag36h11.opencv_id(), 20);
        assert!("DICT_6X6_251".parse::<ArucoDictionary>().is_err());
        assert!("21".parse::<ArucoDictionary>().is_err());
        for d in ArucoDictionary::ALL {
            assert_eq!(d.name().parse::<ArucoDictionary>().unwrap(), d);
        }
    }

    #[test]
    fn half_resolution_is_the_mean_of_each_2x2_block() {
        let img = GrayImage::from_fn(5, 3, |x, y| image::Luma([(10 * x + 100 * y) as u8]));
        let half = half_resolution(&img);
        assert_eq!((half.width(), half.height()), (2, 1));
        // Block (0, 0): 0, 10, 100, 110; block (1, 0): 20, 30, 120, 130.
        assert_eq!(half.as_raw(), &vec![55, 75]);
    }

    #[test]
    fn opencv_knows_every_dictionary_and_its_size() {
        for d in ArucoDictionary::ALL {
            let dict = d.opencv().unwrap();
            assert_eq!(dict.bytes_list().rows() as u32, d.size(), "{d}");
        }
        let (n, bits) = marker_bits(ArucoDictionary::Dict6x6_250, 0).unwrap();
        assert_eq!(n, 8);
        // The border is black.
        assert!((0..8).all(|k| !bits[k] && !bits[56 + k] && !bits[8 * k] && !bits[8 * k + 7]));
        assert!(bits.iter().any(|b| *b));
    }
}
