//! ChArUco boards: a chessboard whose white squares carry ArUco markers, so that every corner
//! is identified by the markers around it and partial views are usable.
//!
//! # Layout (OpenCV 4.6's, checked against OpenCV's `CharucoBoard` in the tests)
//! `cols x rows` squares of side `square`; square `(r, c)` (row `r` from the top as printed,
//! column `c` from the left) is black when `r + c` is even (the top-left square is black) and
//! otherwise carries a marker of side `marker` at its centre. Marker ids run from 0 through
//! the white squares row by row from the top, left to right. The `(cols - 1) x (rows - 1)`
//! inner corners have ids `k = i (cols - 1) + j`, row `i` from the top, column `j` from the
//! left (OpenCV's numbering): corner `k` is where squares `(i, j)` to `(i + 1, j + 1)` meet.
//!
//! # Target frame
//! Origin at the centre of the board (of its squares), x to the right along the rows, y up
//! as printed, z out of the printed face (the project's convention for every target). OpenCV's
//! board frame has its origin at the board's top-left outer corner, x right, y *down* and z
//! into the board; ours is that frame turned half a turn about x and moved to the centre.
//! Corner `(i, j)` is at `((j + 1 - cols / 2) square, (rows / 2 - i - 1) square, 0)`.
//!
//! # Detection
//! 1. OpenCV's `detectMarkers` finds and decodes the markers ([`super::aruco`]), coarse to
//!    fine: on the image at half resolution, then around the predicted places of the board's
//!    missing markers at full resolution ([`board_markers`]); markers of other ids, and ids
//!    seen twice, are dropped.
//! 2. Every grid point of the board (inner corners and the board's outer corners) that
//!    touches a square with a decoded marker is predicted through the homography of those
//!    markers' corners (local, so lens distortion matters little).
//! 3. An inner corner is kept when at least `min_markers` (default 2, OpenCV's default) of
//!    its two marker squares were decoded and, with two, their separate predictions agree to
//!    a quarter of a square.
//! 4. The kept corners are refined by the project's edge model
//!    ([`crate::subpix::refine_grid`]) as the saddles of a `rows x cols` checkerboard whose
//!    white squares are uniform only within the margin around their marker, and each comes
//!    with its covariance. A corner whose fit fails, or moves more than a tenth of a square
//!    (at least 3 px) from its prediction, is dropped.

use image::GrayImage;
use nalgebra::{Matrix3, Point2, Point3, Vector2, Vector3};
use serde::{Deserialize, Serialize};

use super::aruco::{detect_markers, half_resolution, ArucoDictionary, Marker, MarkerParams};
use super::image::GrayF32;
use super::{Corner, DetectOptions, Detection, StageTimings};
use crate::error::{Result, VisionError};
use crate::pose::homography::homography_dlt;
use crate::subpix::{refine_grid_timed, CheckerGrid};
use std::time::Instant;

/// A ChArUco board (see the module documentation for its layout and frame).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CharucoBoard {
    /// Squares along x (per row).
    pub cols: u32,
    /// Squares along y (per column).
    pub rows: u32,
    /// Side of a square, millimetres.
    pub square_mm: f64,
    /// Side of a marker (its black border included), millimetres.
    pub marker_mm: f64,
    /// The markers' dictionary.
    pub dictionary: ArucoDictionary,
}

impl CharucoBoard {
    /// Checks the dimensions (the reason, for the pattern parser).
    pub fn validate(&self) -> std::result::Result<(), String> {
        if self.cols < 2 || self.rows < 2 {
            return Err(format!("a ChArUco board needs at least 2x2 squares, got {}x{}", self.cols, self.rows));
        }
        if self.marker_mm.partial_cmp(&self.square_mm) != Some(std::cmp::Ordering::Less) {
            return Err(format!(
                "the marker ({} mm) must be smaller than the square ({} mm)",
                self.marker_mm, self.square_mm
            ));
        }
        if self.n_markers() > self.dictionary.size() {
            return Err(format!(
                "a {}x{} board needs {} markers but {} has {}",
                self.cols,
                self.rows,
                self.n_markers(),
                self.dictionary,
                self.dictionary.size()
            ));
        }
        Ok(())
    }

    /// Number of markers (white squares).
    pub fn n_markers(&self) -> u32 {
        self.cols * self.rows / 2
    }

    /// Number of inner corners.
    pub fn n_corners(&self) -> u32 {
        (self.cols - 1) * (self.rows - 1)
    }

    /// Whether square `(r, c)` (row from the top) is black.
    pub fn square_is_black(&self, r: u32, c: u32) -> bool {
        (r + c).is_multiple_of(2)
    }

    /// The square `(row from the top, col)` of every marker, in id order.
    pub fn marker_squares(&self) -> Vec<(u32, u32)> {
        let mut out = Vec::with_capacity(self.n_markers() as usize);
        for r in 0..self.rows {
            for c in 0..self.cols {
                if !self.square_is_black(r, c) {
                    out.push((r, c));
                }
            }
        }
        out
    }

    /// Centre of square `(r, c)` in the target frame, metres.
    pub fn square_centre_m(&self, r: u32, c: u32) -> Point2<f64> {
        let s = self.square_mm * 1e-3;
        Point2::new((c as f64 + 0.5 - 0.5 * self.cols as f64) * s, (0.5 * self.rows as f64 - r as f64 - 0.5) * s)
    }

    /// The four corners of the marker in square `(r, c)`, in OpenCV's order (top-left,
    /// top-right, bottom-right, bottom-left as printed), target frame, metres.
    pub fn marker_corners_m(&self, r: u32, c: u32) -> [Point2<f64>; 4] {
        let o = self.square_centre_m(r, c);
        let h = 0.5 * self.marker_mm * 1e-3;
        [
            Point2::new(o.x - h, o.y + h),
            Point2::new(o.x + h, o.y + h),
            Point2::new(o.x + h, o.y - h),
            Point2::new(o.x - h, o.y - h),
        ]
    }

    /// Inner corner `(i, j)` (row from the top) in the target frame, metres.
    pub fn corner_m(&self, i: u32, j: u32) -> Point3<f64> {
        let s = self.square_mm * 1e-3;
        Point3::new((j as f64 + 1.0 - 0.5 * self.cols as f64) * s, (0.5 * self.rows as f64 - i as f64 - 1.0) * s, 0.0)
    }

    /// Every inner corner in id order, metres.
    pub fn target_points_m(&self) -> Vec<Point3<f64>> {
        (0..self.rows - 1).flat_map(|i| (0..self.cols - 1).map(move |j| self.corner_m(i, j))).collect()
    }

    /// Grid point `(gi, gj)` of the checkerboard counted from the *top* (rows `0..=rows`) in the
    /// target frame, metres.
    fn grid_point_m(&self, gi: u32, gj: u32) -> Point2<f64> {
        let s = self.square_mm * 1e-3;
        Point2::new((gj as f64 - 0.5 * self.cols as f64) * s, (0.5 * self.rows as f64 - gi as f64) * s)
    }
}

/// Options of the ChArUco detector.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct CharucoOptions {
    /// How many of a corner's two marker squares must be decoded (1 or 2).
    pub min_markers: u32,
    /// OpenCV's marker detection parameters.
    pub markers: MarkerParams,
    /// Decode the markers on the image at half resolution first (a quarter of the pixels) and
    /// look for the board's missing markers at full resolution only around the places the
    /// decoded ones predict ([`board_markers`]); `false` decodes the whole image at full
    /// resolution. Images whose shorter side is below [`HALF_RESOLUTION_MIN_SIDE_PX`] are
    /// always decoded at full resolution.
    pub half_resolution_first: bool,
}

impl Default for CharucoOptions {
    fn default() -> Self {
        Self { min_markers: 2, markers: MarkerParams::Tolerant, half_resolution_first: true }
    }
}

/// Shorter image side below which [`CharucoOptions::half_resolution_first`] is not used, pixels.
pub const HALF_RESOLUTION_MIN_SIDE_PX: u32 = 800;

/// Smallest predicted marker side for which a missing marker is looked for, pixels (below it
/// OpenCV's decoding does not find it anyway).
const MIN_MARKER_SIDE_PX: f64 = 8.0;

/// Markers decoded at half resolution whose side (full-resolution pixels) is below this are
/// decoded again in their full-resolution window: their outlines at half resolution (cells of
/// 2.5 px or less) are too coarse to predict the corners from.
const REDECODE_BELOW_SIDE_PX: f64 = 30.0;

/// Mean side of a quadrilateral, pixels.
fn mean_side(q: &[Vector2<f64>]) -> f64 {
    0.25 * (0..4).map(|k| (q[k] - q[(k + 1) % 4]).norm()).sum::<f64>()
}

/// The board's markers, coarse to fine: OpenCV's decoding on the image at half resolution;
/// then, for every marker of the board not decoded there (or decoded twice, or smaller than
/// [`REDECODE_BELOW_SIDE_PX`], whose outline is then taken from the window), the homography
/// of the (up to four) nearest decoded markers predicts its outline, and OpenCV decodes the
/// full-resolution window around that outline (half a marker side of margin). A marker is
/// taken from the window only with the id expected there, and only when its predicted outline
/// lies inside the image. With fewer than two distinct board markers at half resolution, the
/// whole image is decoded at full resolution (what `half_resolution_first: false` does).
/// Returns every decoded marker (other ids included) and the number of windows decoded.
pub fn board_markers(img: &GrayImage, board: &CharucoBoard, options: &CharucoOptions) -> Result<(Vec<Marker>, usize)> {
    if !options.half_resolution_first || img.width().min(img.height()) < HALF_RESOLUTION_MIN_SIDE_PX {
        return Ok((detect_markers(img, board.dictionary, options.markers)?, 0));
    }
    let half = half_resolution(img);
    let mut found: Vec<Marker> = detect_markers(&half, board.dictionary, options.markers)?
        .into_iter()
        .map(|m| Marker { id: m.id, corners_px: m.corners_px.map(|p| Point2::new(2.0 * p.x + 0.5, 2.0 * p.y + 0.5)) })
        .collect();
    let n = board.n_markers() as usize;
    let mut seen = vec![0usize; n];
    for m in &found {
        if let Some(k) = seen.get_mut(m.id as usize) {
            *k += 1;
        }
    }
    let squares = board.marker_squares();
    let unique: Vec<(&Marker, (u32, u32))> =
        found.iter().filter(|m| seen.get(m.id as usize) == Some(&1)).map(|m| (m, squares[m.id as usize])).collect();
    if unique.len() < 2 {
        return Ok((detect_markers(img, board.dictionary, options.markers)?, 0));
    }
    let small: Vec<usize> = unique
        .iter()
        .filter(|(m, _)| {
            let q: Vec<Vector2<f64>> = m.corners_px.iter().map(|p| p.coords).collect();
            mean_side(&q) < REDECODE_BELOW_SIDE_PX
        })
        .map(|(m, _)| m.id as usize)
        .collect();
    let (w, h) = (f64::from(img.width()), f64::from(img.height()));
    let mut extra = Vec::new();
    let mut windows = 0;
    for id in (0..n).filter(|&k| seen[k] != 1 || small.contains(&k)) {
        let (r, c) = squares[id];
        let mut near = unique.clone();
        let d2 = |s: (u32, u32)| (i64::from(s.0) - i64::from(r)).pow(2) + (i64::from(s.1) - i64::from(c)).pow(2);
        near.sort_by_key(|(_, s)| d2(*s));
        near.truncate(4);
        let Some(hm) = markers_homography(board, &near) else { continue };
        let quad: Option<Vec<Vector2<f64>>> = board.marker_corners_m(r, c).iter().map(|p| apply(&hm, *p)).collect();
        let Some(quad) = quad else { continue };
        let side = mean_side(&quad);
        let inside = quad.iter().all(|q| q.x >= 1.0 && q.y >= 1.0 && q.x <= w - 2.0 && q.y <= h - 2.0);
        if side.is_nan() || side < MIN_MARKER_SIDE_PX || !inside {
            continue;
        }
        let margin = 0.5 * side + 4.0;
        let lo = |f: fn(&Vector2<f64>) -> f64| quad.iter().map(f).fold(f64::INFINITY, f64::min) - margin;
        let hi = |f: fn(&Vector2<f64>) -> f64| quad.iter().map(f).fold(f64::NEG_INFINITY, f64::max) + margin;
        let (x0, y0) = (lo(|q| q.x).max(0.0).floor(), lo(|q| q.y).max(0.0).floor());
        let (x1, y1) = (hi(|q| q.x).min(w - 1.0).ceil(), hi(|q| q.y).min(h - 1.0).ceil());
        let (cw, ch) = (x1 - x0 + 1.0, y1 - y0 + 1.0);
        // A prediction this large is extrapolated too far to be worth a window.
        if cw * ch > 0.25 * w * h {
            continue;
        }
        let crop = image::imageops::crop_imm(img, x0 as u32, y0 as u32, cw as u32, ch as u32).to_image();
        windows += 1;
        if let Some(m) =
            detect_markers(&crop, board.dictionary, options.markers)?.into_iter().find(|m| m.id as usize == id)
        {
            extra.push(Marker { id: m.id, corners_px: m.corners_px.map(|p| Point2::new(p.x + x0, p.y + y0)) });
        }
    }
    // A marker decoded at half resolution (twice, or small) and again in its window: the
    // window's wins.
    let replaced: Vec<u32> = extra.iter().map(|m| m.id).filter(|&id| seen[id as usize] >= 1).collect();
    found.retain(|m| !replaced.contains(&m.id));
    found.extend(extra);
    Ok((found, windows))
}

fn apply(h: &Matrix3<f64>, p: Point2<f64>) -> Option<Vector2<f64>> {
    let q = h * Vector3::new(p.x, p.y, 1.0);
    (q.z.abs() > 1e-12).then(|| Vector2::new(q.x / q.z, q.y / q.z))
}

/// Homography from the target plane (metres) to pixels through the corners of some markers.
fn markers_homography(board: &CharucoBoard, markers: &[(&Marker, (u32, u32))]) -> Option<Matrix3<f64>> {
    let mut src = Vec::with_capacity(4 * markers.len());
    let mut dst = Vec::with_capacity(4 * markers.len());
    for (m, (r, c)) in markers {
        src.extend(board.marker_corners_m(*r, *c));
        dst.extend(m.corners_px);
    }
    homography_dlt(&src, &dst)
}

/// Finds a ChArUco board; one detection whose corners carry their ids (ascending).
pub(crate) fn detect_charuco(
    img: &GrayImage,
    board: &CharucoBoard,
    options: &DetectOptions,
    pattern_text: &str,
    mut timings: Option<&mut StageTimings>,
) -> Result<Detection> {
    let not_found = |reason: String| VisionError::PatternNotFound { pattern: pattern_text.to_string(), reason };
    let squares = board.marker_squares();
    let t0 = Instant::now();
    let (mut markers, _windows) = board_markers(img, board, &options.charuco)?;
    let decoded = markers.len();
    let t1 = Instant::now();
    if let Some(t) = timings.as_deref_mut() {
        StageTimings::add_since(&mut t.candidates_ms, t0);
        t.candidates = decoded;
    }
    markers.retain(|m| m.id < board.n_markers());
    let mut by_id: std::collections::HashMap<u32, Vec<Marker>> = std::collections::HashMap::new();
    for m in markers {
        by_id.entry(m.id).or_default().push(m);
    }
    // Square (row from the top, col) -> its marker, for ids seen exactly once.
    let mut at: std::collections::HashMap<(u32, u32), Marker> = std::collections::HashMap::new();
    for (id, ms) in &by_id {
        if ms.len() == 1 {
            at.insert(squares[*id as usize], ms[0]);
        }
    }
    if at.is_empty() {
        return Err(not_found(format!(
            "no marker of {} with an id below {} ({decoded} markers of the dictionary decoded)",
            board.dictionary,
            board.n_markers()
        )));
    }
    let (rows, cols) = (board.rows, board.cols);
    // Grid points (gi, gj), gi in 0..=rows from the top: square (r, c) has the grid points
    // (r, c) at its top-left and (r + 1, c + 1) at its bottom-right.
    let np = ((rows + 1) * (cols + 1)) as usize;
    let mut points: Vec<Option<Point2<f64>>> = vec![None; np];
    let squares_at = |gi: u32, gj: u32| -> Vec<(u32, u32)> {
        let mut v = Vec::new();
        for dr in 0..2u32 {
            for dc in 0..2u32 {
                let (ti, cj) = (gi as i64 - 1 + dr as i64, gj as i64 - 1 + dc as i64);
                if ti >= 0 && cj >= 0 && ti < rows as i64 && cj < cols as i64 {
                    v.push((ti as u32, cj as u32));
                }
            }
        }
        v
    };
    for gi in 0..=rows {
        for gj in 0..=cols {
            let seen: Vec<(&Marker, (u32, u32))> =
                squares_at(gi, gj).into_iter().filter_map(|s| at.get(&s).map(|m| (m, s))).collect();
            if seen.is_empty() {
                continue;
            }
            if let Some(h) = markers_homography(board, &seen) {
                points[(gi * (cols + 1) + gj) as usize] =
                    apply(&h, board.grid_point_m(gi, gj)).map(|v| Point2::new(v.x, v.y));
            }
        }
    }
    // Inner corners with enough consistent markers.
    let mut wanted: Vec<(u32, u32)> = Vec::new(); // (i, j) from the top-left
    for i in 0..rows - 1 {
        for j in 0..cols - 1 {
            let (gi, gj) = (i + 1, j + 1);
            let seen: Vec<(&Marker, (u32, u32))> =
                squares_at(gi, gj).into_iter().filter_map(|s| at.get(&s).map(|m| (m, s))).collect();
            if (seen.len() as u32) < options.charuco.min_markers.clamp(1, 2) {
                continue;
            }
            if seen.len() == 2 {
                let p: Vec<Option<Vector2<f64>>> = seen
                    .iter()
                    .map(|s| {
                        markers_homography(board, std::slice::from_ref(s))
                            .and_then(|h| apply(&h, board.grid_point_m(gi, gj)))
                    })
                    .collect();
                // A marker's side in pixels (mean diagonal / sqrt 2), scaled to the square.
                let side = |m: &Marker| {
                    0.5 * ((m.corners_px[0] - m.corners_px[2]).norm() + (m.corners_px[1] - m.corners_px[3]).norm())
                        / std::f64::consts::SQRT_2
                };
                let square_px = 0.5 * (side(seen[0].0) + side(seen[1].0)) * board.square_mm / board.marker_mm;
                match (p[0], p[1]) {
                    (Some(a), Some(b)) if (a - b).norm() <= 0.25 * square_px => {}
                    _ => continue,
                }
            }
            if points[(gi * (cols + 1) + gj) as usize].is_some() {
                wanted.push((i, j));
            }
        }
    }
    if wanted.is_empty() {
        return Err(not_found(format!(
            "{} board markers decoded, but no corner has {} of its marker squares decoded",
            at.len(),
            options.charuco.min_markers.clamp(1, 2)
        )));
    }
    let grid_of = |(i, j): (u32, u32)| ((i + 1) as usize, (j + 1) as usize);
    let index = |(gi, gj): (usize, usize)| gi * (cols as usize + 1) + gj;
    // Distance from a grid point to its nearest predicted neighbour, pixels.
    let spacing_at = |points: &[Option<Point2<f64>>], (gi, gj): (usize, usize)| -> f64 {
        let start = points[index((gi, gj))].expect("wanted corners are predicted");
        [(0isize, 1isize), (1, 0), (0, -1), (-1, 0)]
            .iter()
            .filter_map(|(di, dj)| {
                let (a, b) = (gi as isize + di, gj as isize + dj);
                (a >= 0 && b >= 0 && a <= rows as isize && b <= cols as isize)
                    .then(|| points[index((a as usize, b as usize))])
                    .flatten()
                    .map(|q| (q - start).norm())
            })
            .fold(f64::INFINITY, f64::min)
    };
    if let Some(t) = timings.as_deref_mut() {
        StageTimings::add_since(&mut t.grid_ms, t1);
    }
    let mut corners = Vec::with_capacity(wanted.len());
    if options.refine {
        let t2 = Instant::now();
        let imgf = GrayF32::from_gray8(img)?;
        if let Some(t) = timings.as_deref_mut() {
            StageTimings::add_since(&mut t.convert_ms, t2);
        }
        let mut fields_dark = Vec::with_capacity((rows * cols) as usize);
        for ti in 0..rows {
            for c in 0..cols {
                fields_dark.push(Some(board.square_is_black(ti, c)));
            }
        }
        let grid = CheckerGrid {
            field_rows: rows as usize,
            field_cols: cols as usize,
            fields_dark,
            outside_dark: None,
            outside_width_fraction: 0.3,
            points_px: points.clone(),
            light_uniform_fraction: (board.square_mm - board.marker_mm) / (2.0 * board.square_mm),
        };
        // Start every corner at the saddle near its prediction (the predictions through the
        // markers are off by a pixel or more, which would cost the edge model a second pass).
        let mut grid = grid;
        for &w in &wanted {
            let k = index(grid_of(w));
            let (Some(p), spacing) = (points[k], spacing_at(&points, grid_of(w))) else { continue };
            if let Some(q) = saddle_start(&imgf, p, (0.2 * spacing).clamp(3.0, 25.0)) {
                grid.points_px[k] = Some(q);
            }
        }
        let targets: Vec<(usize, usize)> = wanted.iter().map(|&w| grid_of(w)).collect();
        let (refined, _) = refine_grid_timed(&imgf, &grid, &targets, &options.refine_options, timings)?;
        for (&(i, j), rc) in wanted.iter().zip(refined) {
            let Some(rc) = rc else { continue };
            let (gi, gj) = grid_of((i, j));
            let start = points[index((gi, gj))].expect("wanted corners are predicted");
            let spacing = spacing_at(&points, (gi, gj));
            if (rc.position_px - start).norm() > (0.1 * spacing).max(3.0) {
                continue;
            }
            corners.push(corner(board, i, j, rc.position_px, Some(rc.covariance_px2), rc.crb_px2));
        }
        if corners.is_empty() {
            return Err(not_found(format!("{} corners predicted from the markers, none refined", wanted.len())));
        }
    } else {
        for &(i, j) in &wanted {
            let (gi, gj) = grid_of((i, j));
            let p = points[gi * (cols as usize + 1) + gj].expect("wanted corners are predicted");
            corners.push(corner(board, i, j, p, None, None));
        }
    }
    let complete = corners.len() == board.n_corners() as usize;
    Ok(Detection { id: None, corners, complete, anchored: true, circle_radii_m: None })
}

/// The X-corner near `p`: the point to which the image gradients in a window of half-width
/// `half_px` around it are orthogonal (every gradient on the two edge lines through a corner is
/// orthogonal to the ray from the corner), iterated from `p`, Gaussian-weighted. `None` when
/// the window holds no corner (the gradients do not fix a point) or the point leaves the
/// window.
fn saddle_start(img: &GrayF32, p: Point2<f64>, half_px: f64) -> Option<Point2<f64>> {
    let (w, h) = (img.width as isize, img.height as isize);
    let r = half_px.ceil() as isize;
    let inv_2s2 = 1.0 / (2.0 * (0.5 * half_px).powi(2));
    let mut q = p;
    for _ in 0..6 {
        let (cx, cy) = (q.x.round() as isize, q.y.round() as isize);
        if cx - r < 1 || cy - r < 1 || cx + r >= w - 1 || cy + r >= h - 1 {
            return None;
        }
        let (mut a, mut b, mut c, mut bx, mut by) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for y in cy - r..=cy + r {
            for x in cx - r..=cx + r {
                let (dx, dy) = (x as f64 - q.x, y as f64 - q.y);
                let d2 = dx * dx + dy * dy;
                if d2 > half_px * half_px {
                    continue;
                }
                let (xu, yu) = (x as usize, y as usize);
                let gx = 0.5 * f64::from(img.get(xu + 1, yu) - img.get(xu - 1, yu));
                let gy = 0.5 * f64::from(img.get(xu, yu + 1) - img.get(xu, yu - 1));
                let wgt = (-d2 * inv_2s2).exp();
                let (gxx, gxy, gyy) = (wgt * gx * gx, wgt * gx * gy, wgt * gy * gy);
                a += gxx;
                b += gxy;
                c += gyy;
                bx += gxx * x as f64 + gxy * y as f64;
                by += gxy * x as f64 + gyy * y as f64;
            }
        }
        let det = a * c - b * b;
        // Both gradient directions must be present (a corner, not an edge).
        if det.is_nan() || det <= 1e-3 * (a + c) * (a + c) {
            return None;
        }
        let next = Point2::new((c * bx - b * by) / det, (a * by - b * bx) / det);
        if (next - p).norm() > half_px {
            return None;
        }
        let step = (next - q).norm();
        q = next;
        if step < 0.02 {
            break;
        }
    }
    Some(q)
}

fn corner(
    board: &CharucoBoard,
    i: u32,
    j: u32,
    p: Point2<f64>,
    cov: Option<nalgebra::Matrix2<f64>>,
    crb: Option<nalgebra::Matrix2<f64>>,
) -> Corner {
    Corner {
        position_px: p,
        covariance_px2: cov,
        crb_px2: crb,
        target_m: Some(board.corner_m(i, j)),
        grid_index: Some([i, j]),
        point_id: Some(i * (board.cols - 1) + j),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::aruco::opencv_charuco_layout;

    #[test]
    fn layout_is_opencvs_up_to_the_centring() {
        for (cols, rows) in [(5u32, 7u32), (6, 4), (3, 3)] {
            let b =
                CharucoBoard { cols, rows, square_mm: 40.0, marker_mm: 30.0, dictionary: ArucoDictionary::Dict6x6_250 };
            let cv = opencv_charuco_layout(cols, rows, 0.04, 0.03, b.dictionary).unwrap();
            let (ox, oy) = (0.5 * cols as f64 * 0.04, 0.5 * rows as f64 * 0.04);
            let squares = b.marker_squares();
            assert_eq!(cv.markers.len(), squares.len());
            for (id, c) in &cv.markers {
                let (r, cc) = squares[*id as usize];
                let m = b.square_centre_m(r, cc);
                assert!(
                    (m.x - (c[0] - ox)).abs() < 1e-6 && (m.y - (oy - c[1])).abs() < 1e-6,
                    "{cols}x{rows} marker {id}"
                );
            }
            let ours = b.target_points_m();
            assert_eq!(ours.len(), cv.corners.len());
            for (k, (p, c)) in ours.iter().zip(&cv.corners).enumerate() {
                assert!(
                    (p.x - (c[0] - ox)).abs() < 1e-6 && (p.y - (oy - c[1])).abs() < 1e-6,
                    "{cols}x{rows} corner {k}"
                );
            }
        }
    }
}
