//! Detection of the project's patterns, with sub-pixel corners and their covariances.
//!
//! Entry points:
//! - [`Pattern`] (parsed from the `--pattern` strings, see [`pattern`]);
//! - [`detect`]: one image, one pattern, every detection with its corners (pixel-centre
//!   convention), ids for tags, target positions, and per-corner covariance and Cramer-Rao
//!   bound after refinement ([`crate::subpix`]);
//! - [`Detector`]: the same for a batch of image files, one [`ImageResult`] per image (a
//!   failure on one image is reported in its result and the batch goes on);
//! - [`apriltag`]: the AprilTag C library and kornia-apriltag side by side;
//! - [`baseline`]: OpenCV's chessboard detectors and `cornerSubPix`, the reference;
//! - [`load_gray`], [`median_background`], [`GrayF32`]: image input.
//!
//! Detectors: chessboards (full and partial views, [`chessboard`]), the Gantry-Tau plate
//! ([`plate`], optionally with a background image subtracted), AprilTags and AprilTag boards
//! of known layout, ChArUco boards (full and partial, corner ids from OpenCV's ArUco markers,
//! [`charuco`], [`aruco`]) and circle grids (symmetric and modified, [`circles`]). Frames,
//! orders and ids of every target: `docs/targets.md`.
//!
//! # Conventions
//! Pixel `(0, 0)` is the centre of the top-left pixel (`docs/conventions.md`); corners from the
//! AprilTag C library are shifted by -0.5 px to it. Target positions are in metres in the
//! target frame of `ferrocal_datasets::render::TargetConfig` (origin at the pattern's centre, x
//! right, y up as printed, z out of the printed face). A chessboard's corners run row by row
//! from the top-left as printed (`grid_index = [row, col]`); the plate's run per square
//! (top-left, top-right, centre, bottom-left, bottom-right), per corner (top-left, top-right,
//! bottom-right, bottom-left).

pub mod apriltag;
pub mod aruco;
pub mod baseline;
pub mod charuco;
pub mod chessboard;
pub mod circles;
mod grid;
mod image;
pub mod pattern;
pub mod plate;
mod xcorner;

use std::path::Path;

use ::image::GrayImage;
use nalgebra::{Matrix2, Point2, Point3};
use serde::{Deserialize, Serialize};

pub use self::apriltag::{AprilTagDetector, AprilTagOptions, TagBackend, TagDetection, TagRefine};
pub use self::image::{
    check_image_file, jpeg_is_complete, load_gray, median_background, to_gray, GrayF32, MAX_IMAGE_PIXELS,
};
pub use self::pattern::{ArucoDictionary, CharucoBoard, CircleGrid, Pattern, TagFamily};
use crate::error::{Result, VisionError};
use crate::subpix::RefineOptions;

/// One detected corner.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Corner {
    /// Position, pixels (pixel-centre convention).
    pub position_px: Point2<f64>,
    /// Covariance of the position after refinement, px^2 (`None` when not refined).
    pub covariance_px2: Option<Matrix2<f64>>,
    /// Cramer-Rao bound of the position under the noise model, px^2.
    pub crb_px2: Option<Matrix2<f64>>,
    /// Position on the target, metres (when the pattern's size is known).
    pub target_m: Option<Point3<f64>>,
    /// Chessboard: `[row, col]` of the inner corner; plate: `[row, col]` of the 4 x 4 grid point;
    /// ChArUco: `[row, col]` of the inner corner (rows from the top, OpenCV's numbering);
    /// circle grid: `[row, col]` of the dot (rows from the origin dot's row).
    pub grid_index: Option<[u32; 2]>,
    /// Index of the corner in [`Pattern::target_points_m`] (chessboards when anchored, ChArUco
    /// corner ids, circle-grid dot indices); `None` for plates and tags.
    #[serde(default)]
    pub point_id: Option<u32>,
}

/// One detection: a chessboard, a plate or one tag.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Detection {
    /// Tag id (`None` for chessboards and plates).
    pub id: Option<u32>,
    /// Corners in the pattern's documented order.
    pub corners: Vec<Corner>,
    /// Whether every corner of the pattern is present (false for a partial chessboard).
    pub complete: bool,
    /// Whether the corners' indices are the board's own (false for a partial chessboard whose
    /// visible part does not show which rows and columns it is; indices are then relative).
    pub anchored: bool,
    /// Circle grids: the radii of the dots on the target, metres, as the image shows them
    /// (`[small, large]`; the same twice for a symmetric grid), estimated from the ellipses'
    /// axes over the local dot spacing. They serve the perspective-bias correction
    /// ([`circles::bias`]). `None` for other patterns.
    #[serde(default)]
    pub circle_radii_m: Option<[f64; 2]>,
}

impl Detection {
    /// The corner positions.
    pub fn corners_px(&self) -> Vec<Point2<f64>> {
        self.corners.iter().map(|c| c.position_px).collect()
    }
}

/// Options of [`detect`] and [`Detector`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct DetectOptions {
    /// Refine corners with the edge model (chessboards and plates; tags: see
    /// [`AprilTagOptions::refine`]).
    pub refine: bool,
    /// Options of the refinement.
    pub refine_options: RefineOptions,
    /// Accept chessboards of which only a part is visible.
    pub partial: bool,
    /// Least step between dark and light fields, DN.
    pub min_contrast_dn: f64,
    /// AprilTag options.
    pub apriltag: AprilTagOptions,
    /// ChArUco options.
    pub charuco: charuco::CharucoOptions,
    /// Circle-grid options.
    pub circles: circles::CircleOptions,
}

impl Default for DetectOptions {
    fn default() -> Self {
        Self {
            refine: true,
            refine_options: RefineOptions::default(),
            partial: false,
            min_contrast_dn: 12.0,
            apriltag: AprilTagOptions::default(),
            charuco: charuco::CharucoOptions::default(),
            circles: circles::CircleOptions::default(),
        }
    }
}

impl DetectOptions {
    pub(crate) fn xcorner(&self) -> xcorner::XCornerOptions {
        xcorner::XCornerOptions { min_contrast_dn: self.min_contrast_dn, ..Default::default() }
    }
}

/// Detects `pattern` in one image. A pattern that is not there is
/// [`VisionError::PatternNotFound`] with what was seen instead. `background` (the median of
/// the sequence, [`median_background`]) is used by the plate detector only.
pub fn detect(
    img: &GrayImage,
    pattern: &Pattern,
    options: &DetectOptions,
    background: Option<&GrayImage>,
) -> Result<Vec<Detection>> {
    let mut tags = None;
    detect_with(img, pattern, options, background, &mut tags)
}

/// Wall time of each stage of one detection, milliseconds, with the work counts that make
/// the cost per corner and per pixel visible ([`detect_timed`]). Chessboards and ChArUco
/// boards fill every stage; other patterns only [`StageTimings::total_ms`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct StageTimings {
    /// Conversion of the 8-bit image to floating point.
    pub convert_ms: f64,
    /// Candidate search: X-corners (chessboards) or ArUco marker decoding (ChArUco).
    pub candidates_ms: f64,
    /// Grid growth and labelling (chessboards) or corner prediction from the markers (ChArUco).
    pub grid_ms: f64,
    /// Edge-model refinement: band selection and unweighted line fits, every pass.
    pub refine_ms: f64,
    /// Noise estimate, weighted refit, intersections and covariances, every pass.
    pub covariance_ms: f64,
    /// Everything, from the 8-bit image to the detections.
    pub total_ms: f64,
    /// Candidates found (X-corners or markers).
    pub candidates: usize,
    /// Corners returned.
    pub corners: usize,
    /// Line fits (per pass, summed over the passes).
    pub lines: usize,
    /// Pixels in the line fits' bands (summed over the passes).
    pub band_pixels: usize,
    /// Refinement passes (a corner that moves more than 0.5 px starts another).
    pub refine_passes: usize,
    /// Pixels of the image.
    pub image_px: usize,
    /// Reading and decoding the image file ([`Detector::detect_file`] only; not in
    /// [`StageTimings::total_ms`]).
    #[serde(default)]
    pub read_ms: f64,
}

impl std::fmt::Display for StageTimings {
    /// One line: `read 21.0 ms / candidates 12.3 ms (17) / grid 0.3 ms / refinement 20.1 ms
    /// (1 pass, 48 lines, 51072 px) / covariance 7.2 ms / total 41.0 ms`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "read {:.1} ms / convert {:.1} ms / candidates {:.1} ms ({}) / grid {:.1} ms / refinement {:.1} ms \
             ({} pass{}, {} lines, {} px) / covariance {:.1} ms / total {:.1} ms",
            self.read_ms,
            self.convert_ms,
            self.candidates_ms,
            self.candidates,
            self.grid_ms,
            self.refine_ms,
            self.refine_passes,
            if self.refine_passes == 1 { "" } else { "es" },
            self.lines,
            self.band_pixels,
            self.covariance_ms,
            self.total_ms
        )
    }
}

impl StageTimings {
    pub(crate) fn add_since(slot: &mut f64, t0: std::time::Instant) {
        *slot += t0.elapsed().as_secs_f64() * 1e3;
    }
}

/// [`detect`] with the wall time of each stage ([`StageTimings`]); the detections are the
/// same as [`detect`]'s.
pub fn detect_timed(
    img: &GrayImage,
    pattern: &Pattern,
    options: &DetectOptions,
    background: Option<&GrayImage>,
) -> (Result<Vec<Detection>>, StageTimings) {
    let mut t = StageTimings { image_px: img.width() as usize * img.height() as usize, ..Default::default() };
    let t0 = std::time::Instant::now();
    let mut tags = None;
    let out = detect_inner(img, pattern, options, background, &mut tags, Some(&mut t));
    StageTimings::add_since(&mut t.total_ms, t0);
    if let Ok(d) = &out {
        t.corners = d.iter().map(|d| d.corners.len()).sum();
    }
    (out, t)
}

fn detect_with(
    img: &GrayImage,
    pattern: &Pattern,
    options: &DetectOptions,
    background: Option<&GrayImage>,
    tags: &mut Option<AprilTagDetector>,
) -> Result<Vec<Detection>> {
    detect_inner(img, pattern, options, background, tags, None)
}

fn detect_inner(
    img: &GrayImage,
    pattern: &Pattern,
    options: &DetectOptions,
    background: Option<&GrayImage>,
    tags: &mut Option<AprilTagDetector>,
    timings: Option<&mut StageTimings>,
) -> Result<Vec<Detection>> {
    options.refine_options.validate()?;
    let text = pattern.to_string();
    match pattern {
        Pattern::Chessboard { cols, rows, square_mm } => {
            let t0 = std::time::Instant::now();
            let f = GrayF32::from_gray8(img)?;
            let mut timings = timings;
            if let Some(t) = timings.as_deref_mut() {
                StageTimings::add_since(&mut t.convert_ms, t0);
            }
            Ok(vec![chessboard::detect_chessboard(&f, *cols, *rows, *square_mm, options, &text, timings)?])
        }
        Pattern::Plate { square_mm } => {
            let f = GrayF32::from_gray8(img)?;
            plate::detect_plates(&f, *square_mm, background, options, &text)
        }
        Pattern::AprilTag { family, tag_mm } => {
            let det = tag_detector(tags, *family, options)?;
            let found = det.detect(img)?;
            if found.is_empty() {
                return Err(VisionError::PatternNotFound { pattern: text, reason: "no tag decoded".into() });
            }
            Ok(apriltag::to_detections(&found, apriltag::single_tag_target(*tag_mm)))
        }
        Pattern::AprilBoard { cols, rows, first_id, .. } => {
            let det = tag_detector(tags, TagFamily::Tag36h11, options)?;
            let at = apriltag::board_target(pattern).expect("an AprilTag board");
            let target = |id: u32| id.checked_sub(*first_id).and_then(&at);
            let found: Vec<TagDetection> = det.detect(img)?.into_iter().filter(|t| target(t.id).is_some()).collect();
            if found.is_empty() {
                return Err(VisionError::PatternNotFound {
                    pattern: text,
                    reason: format!("no tag36h11 tag with an id in {}..{}", first_id, first_id + cols * rows),
                });
            }
            let mut found = apriltag::to_detections(&found, target);
            // Point ids: corner j of the board's k-th tag is point 4 k + j.
            for d in &mut found {
                let k = d.id.map_or(0, |id| id - first_id);
                for (j, c) in d.corners.iter_mut().enumerate() {
                    c.point_id = Some(4 * k + j as u32);
                }
            }
            Ok(found)
        }
        Pattern::Charuco(board) => Ok(vec![charuco::detect_charuco(img, board, options, &text, timings)?]),
        Pattern::CircleGrid(grid) => Ok(vec![circles::detect_circle_grid(img, grid, options, &text)?]),
    }
}

/// An X-corner candidate (a saddle where two dark and two light fields meet).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct XCornerCandidate {
    /// Position, pixels.
    pub position_px: Point2<f64>,
    /// Directions of the two edge lines through it (unit vectors, up to sign).
    pub directions: [[f64; 2]; 2],
    /// Light minus dark level around it, DN.
    pub contrast_dn: f64,
}

fn tag_detector<'a>(
    slot: &'a mut Option<AprilTagDetector>,
    family: TagFamily,
    options: &DetectOptions,
) -> Result<&'a mut AprilTagDetector> {
    if slot.as_ref().is_none_or(|d| d.family() != family) {
        *slot = Some(AprilTagDetector::new(family, options.apriltag.clone())?);
    }
    Ok(slot.as_mut().expect("set above"))
}

/// One detection as written to JSON (`ferrocal detect`): the contract's `id` and `corners_px`,
/// plus optional extras.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DetectionRecord {
    /// Tag id, or `null`.
    pub id: Option<u32>,
    /// Corners `[x, y]`, pixels, in the pattern's order.
    pub corners_px: Vec<[f64; 2]>,
    /// `[row, col]` per corner for chessboards and plates.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub grid_index: Option<Vec<[u32; 2]>>,
    /// The corners' ids (indices into the pattern's target points, e.g. ChArUco corner ids)
    /// when not every corner of the pattern is seen (`complete` false).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub corner_ids: Option<Vec<u32>>,
    /// Circle grids: the dots' radii on the target `[small, large]`, millimetres, as measured.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub circle_radii_mm: Option<[f64; 2]>,
    /// Covariance per corner `[xx, xy, yy]`, px^2, when refined.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub covariance_px2: Option<Vec<[f64; 3]>>,
    /// Target positions per corner `[x, y, z]`, millimetres, when the pattern's size is known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target_mm: Option<Vec<[f64; 3]>>,
    /// False for a partial chessboard.
    pub complete: bool,
    /// False when a partial chessboard's indices are relative.
    pub anchored: bool,
}

impl From<&Detection> for DetectionRecord {
    fn from(d: &Detection) -> Self {
        let all = |f: &dyn Fn(&Corner) -> bool| d.corners.iter().all(f);
        DetectionRecord {
            id: d.id,
            corners_px: d.corners.iter().map(|c| [c.position_px.x, c.position_px.y]).collect(),
            grid_index: all(&|c| c.grid_index.is_some())
                .then(|| d.corners.iter().filter_map(|c| c.grid_index).collect()),
            corner_ids: (!d.complete && all(&|c| c.point_id.is_some()))
                .then(|| d.corners.iter().filter_map(|c| c.point_id).collect()),
            circle_radii_mm: d.circle_radii_m.map(|r| [r[0] * 1e3, r[1] * 1e3]),
            covariance_px2: all(&|c| c.covariance_px2.is_some()).then(|| {
                d.corners.iter().filter_map(|c| c.covariance_px2).map(|m| [m[(0, 0)], m[(0, 1)], m[(1, 1)]]).collect()
            }),
            target_mm: all(&|c| c.target_m.is_some()).then(|| {
                d.corners.iter().filter_map(|c| c.target_m).map(|p| [p.x * 1e3, p.y * 1e3, p.z * 1e3]).collect()
            }),
            complete: d.complete,
            anchored: d.anchored,
        }
    }
}

/// The result for one image of a batch.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ImageResult {
    /// The image path as given.
    pub image: String,
    /// What was found (empty on failure).
    pub detections: Vec<DetectionRecord>,
    /// Why the image failed (unreadable, empty, pattern not found), when it did.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
    /// Wall time of each stage, when asked for ([`Detector::with_timings`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub timings: Option<StageTimings>,
}

impl ImageResult {
    /// A failed entry.
    pub fn failed(image: impl Into<String>, error: impl Into<String>) -> Self {
        Self { image: image.into(), detections: Vec::new(), error: Some(error.into()), timings: None }
    }
}

/// Detects one pattern in a batch of images, reusing what can be reused (the AprilTag
/// decoding tables).
#[derive(Debug)]
pub struct Detector {
    pattern: Pattern,
    options: DetectOptions,
    background: Option<GrayImage>,
    tags: Option<AprilTagDetector>,
    timed: bool,
}

impl Detector {
    /// A detector for `pattern`; `background` is the median background for the plate.
    pub fn new(pattern: Pattern, options: DetectOptions, background: Option<GrayImage>) -> Result<Self> {
        options.refine_options.validate()?;
        Ok(Self { pattern, options, background, tags: None, timed: false })
    }

    /// With `on`, [`Detector::detect_file`] measures every stage ([`StageTimings`], the file's
    /// reading included) and returns the times in [`ImageResult::timings`].
    pub fn with_timings(mut self, on: bool) -> Self {
        self.timed = on;
        self
    }

    /// The pattern.
    pub fn pattern(&self) -> &Pattern {
        &self.pattern
    }

    /// Detects in an image held in memory.
    pub fn detect(&mut self, img: &GrayImage) -> Result<Vec<Detection>> {
        detect_with(img, &self.pattern, &self.options, self.background.as_ref(), &mut self.tags)
    }

    /// Reads and detects one file; every failure is reported in the result, never raised.
    pub fn detect_file(&mut self, path: &Path) -> ImageResult {
        let name = path.display().to_string();
        let t0 = std::time::Instant::now();
        let img = match load_gray(path) {
            Ok(i) => i,
            Err(e) => return ImageResult::failed(name, e.to_string()),
        };
        let mut timings = self.timed.then(|| StageTimings {
            image_px: img.width() as usize * img.height() as usize,
            read_ms: t0.elapsed().as_secs_f64() * 1e3,
            ..Default::default()
        });
        let t1 = std::time::Instant::now();
        let found = detect_inner(
            &img,
            &self.pattern,
            &self.options,
            self.background.as_ref(),
            &mut self.tags,
            timings.as_mut(),
        );
        if let Some(t) = timings.as_mut() {
            StageTimings::add_since(&mut t.total_ms, t1);
            t.corners = found.as_ref().map_or(0, |d| d.iter().map(|d| d.corners.len()).sum());
        }
        let mut r = match found {
            Ok(d) => ImageResult {
                image: name,
                detections: d.iter().map(DetectionRecord::from).collect(),
                error: None,
                timings: None,
            },
            Err(e) => ImageResult::failed(name, e.to_string()),
        };
        r.timings = timings;
        r
    }
}

/// Procedural images with exact truth, shared by the unit tests.
#[cfg(test)]
#[path = "../../tests/support/synth.rs"]
pub(crate) mod synth;
#[cfg(test)]
mod tests;
