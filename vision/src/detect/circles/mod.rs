//! Circle grids: `cols x rows` dots on a square lattice, symmetric or "modified" (one larger
//! dot marks the origin).
//!
//! # Target frame and order
//! Dot `k = r cols + c` is in row `r` and column `c`; the target frame has its origin at the
//! centre of the grid, x along the rows (dot `0` towards dot `1`), y along the columns (dot `0`
//! towards dot `cols`), z out of the printed face, so dot `(r, c)` is at
//! `((c - (cols - 1) / 2) s, (r - (rows - 1) / 2) s, 0)`. Seen from the front with dot 0 at the
//! bottom-left, x points right and y up. For a `modified` grid dot 0 is the large dot; this
//! matches the axes printed on the ROS-Industrial targets (X along the large dot's row, Y along
//! its column, Z towards the viewer).
//!
//! # Order, and what is ambiguous
//! The board is seen from its printed side, so the x axis turned towards the y axis turns
//! clockwise in the image (x right, y down). That leaves the grid's rotations: with `modified`
//! the large dot fixes dot 0 and the order is unique. A symmetric grid looks the same after a
//! half turn (and, when square, a quarter turn): no image can tell these apart. The order is
//! then chosen so that the x axis points as much as possible to the right in the image and
//! y up (the chessboard detector's rule). Calibration does not care (the symmetry maps the
//! target onto itself); a pose does: it is defined up to that rotation, and a board seen near
//! 45 degrees may be numbered differently in two images. Use `modified` when the frame matters.
//!
//! # Asymmetric grids
//! OpenCV's asymmetric grid ([`CircleGrid::asymmetric`]) has OpenCV's frame and order
//! ([`CircleGrid::point_m`]); its lattice and numbering: [`order`] (`place_asymmetric`).
//!
//! # Detection
//! 1. Blobs ([`blobs`]): pixels darker (or lighter) than the local mean of a box window,
//!    connected components, filtered by area and by how well their second moments describe a
//!    filled ellipse.
//! 2. Sub-pixel centres ([`ellipse`]): edge points where rays from the blob's centre cross the
//!    level half-way between the dot and the paper around it, and an ellipse fitted to them
//!    (radial distances), with the covariance of its centre from the fit's residuals.
//! 3. The grid ([`order`]): grown from a seed dot by predicting the next dot along rows and
//!    columns (two-step extrapolation and parallelograms, so perspective is followed), a full
//!    `cols x rows` rectangle required, then ordered as above.
//! 4. The dots' radii on the target from the ellipses' areas over the local lattice cell
//!    ([`Detection::circle_radii_m`]).
//!
//! The centre of an ellipse is not the image of the circle's centre under perspective and
//! lens distortion; [`bias`] corrects it once a camera and the board's pose are known (the
//! calibration does it: `crate::calib::circles`).

pub mod bias;
pub mod blobs;
pub mod ellipse;
pub mod order;

use image::GrayImage;
use nalgebra::Point3;
use serde::{Deserialize, Serialize};

use super::image::GrayF32;
use super::{Corner, DetectOptions, Detection};
use crate::error::{Result, VisionError};

/// A grid of dots (see the module documentation for order and frame).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CircleGrid {
    /// Dots per row (along x).
    pub cols: u32,
    /// Dots per column (along y).
    pub rows: u32,
    /// Distance between neighbouring dot centres, millimetres.
    pub spacing_mm: f64,
    /// Whether dot 0 is larger than the others and marks the origin.
    pub modified: bool,
    /// OpenCV's asymmetric grid (`acircles`): row `r` holds `cols` dots `2 s` apart, shifted by
    /// `s` on odd rows, rows `s` apart (`spacing_mm` is `s`, OpenCV's `squareSize`); see
    /// [`CircleGrid::point_m`] for its frame.
    #[serde(default)]
    pub asymmetric: bool,
}

impl CircleGrid {
    /// Number of dots.
    pub fn n_points(&self) -> usize {
        (self.cols * self.rows) as usize
    }

    /// A symmetric grid of `cols x rows` dots `spacing_mm` apart (`modified`: dot 0 is larger).
    pub fn symmetric(cols: u32, rows: u32, spacing_mm: f64, modified: bool) -> Self {
        Self { cols, rows, spacing_mm, modified, asymmetric: false }
    }

    /// OpenCV's asymmetric grid: `cols` dots per row, `rows` rows, `spacing_mm` OpenCV's
    /// `squareSize` (half the distance between neighbours in a row, the distance between rows).
    pub fn asymmetric(cols: u32, rows: u32, spacing_mm: f64) -> Self {
        Self { cols, rows, spacing_mm, modified: false, asymmetric: true }
    }

    /// Dot `(r, c)` in the target frame, metres.
    ///
    /// Symmetric grids: the centred frame of the module documentation. Asymmetric grids:
    /// OpenCV's object points `((2 c + r mod 2) s, r s, 0)`: origin at dot 0, x along the
    /// rows, y from row to row; seen from the printed side x turned towards y turns
    /// clockwise (x right, y down), so z points into the board, as in OpenCV's samples.
    pub fn point_m(&self, r: u32, c: u32) -> Point3<f64> {
        let s = self.spacing_mm * 1e-3;
        if self.asymmetric {
            return Point3::new((2 * c + r % 2) as f64 * s, r as f64 * s, 0.0);
        }
        Point3::new(
            (c as f64 - 0.5 * (self.cols as f64 - 1.0)) * s,
            (r as f64 - 0.5 * (self.rows as f64 - 1.0)) * s,
            0.0,
        )
    }

    /// Every dot in index order, metres.
    pub fn target_points_m(&self) -> Vec<Point3<f64>> {
        (0..self.rows).flat_map(|r| (0..self.cols).map(move |c| self.point_m(r, c))).collect()
    }
}

/// Which dots to look for.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Polarity {
    /// Dark dots on a light ground, else light dots on a dark ground.
    #[default]
    Auto,
    /// Dark dots on a light ground.
    Dark,
    /// Light dots on a dark ground.
    Light,
}

/// Options of the circle-grid detector.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct CircleOptions {
    /// Dots to look for.
    pub polarity: Polarity,
    /// Smallest blob, pixels of area.
    pub min_area_px: f64,
    /// Largest blob as a fraction of the image area.
    pub max_area_fraction: f64,
    /// Side of the box window of the local mean, as a fraction of the image's shorter side.
    pub window_fraction: f64,
    /// How much darker (lighter) than the local mean a dot pixel must be, DN.
    pub threshold_dn: f64,
}

impl Default for CircleOptions {
    fn default() -> Self {
        Self {
            polarity: Polarity::Auto,
            min_area_px: 7.0,
            max_area_fraction: 0.02,
            window_fraction: 0.125,
            threshold_dn: 6.0,
        }
    }
}

/// Finds a circle grid: one detection whose corners are the dot centres in index order.
pub(crate) fn detect_circle_grid(
    img: &GrayImage,
    grid: &CircleGrid,
    options: &DetectOptions,
    pattern_text: &str,
) -> Result<Detection> {
    let imgf = GrayF32::from_gray8(img)?;
    let not_found = |reason: String| VisionError::PatternNotFound { pattern: pattern_text.to_string(), reason };
    let polarities: &[bool] = match options.circles.polarity {
        Polarity::Auto => &[true, false],
        Polarity::Dark => &[true],
        Polarity::Light => &[false],
    };
    let mut reasons = Vec::new();
    // The local mean needs a window a few dots wide: a second, wider window for large dots.
    let windows = [options.circles.window_fraction, (2.5 * options.circles.window_fraction).min(0.5)];
    for (&dark, &window_fraction) in polarities.iter().flat_map(|d| windows.iter().map(move |w| (d, w))) {
        let blob_options = CircleOptions { window_fraction, ..options.circles };
        let found = blobs::find_blobs(&imgf, dark, &blob_options);
        let fits: Vec<ellipse::DotFit> = found.iter().filter_map(|b| ellipse::fit_dot(&imgf, b, dark)).collect();
        match order::order_grid(&fits, grid) {
            Ok(ordered) => return Ok(to_detection(grid, &fits, &ordered)),
            Err(e) => reasons.push(format!(
                "{} dots, window {:.2}: {} blobs, {} ellipses: {e}",
                if dark { "dark" } else { "light" },
                window_fraction,
                found.len(),
                fits.len()
            )),
        }
    }
    Err(not_found(reasons.join("; ")))
}

fn to_detection(grid: &CircleGrid, fits: &[ellipse::DotFit], ordered: &order::Ordered) -> Detection {
    let corners = ordered
        .dots
        .iter()
        .enumerate()
        .map(|(k, &f)| {
            let (r, c) = (k as u32 / grid.cols, k as u32 % grid.cols);
            Corner {
                position_px: fits[f].centre_px,
                covariance_px2: Some(fits[f].centre_cov_px2),
                crb_px2: None,
                target_m: Some(grid.point_m(r, c)),
                grid_index: Some([r, c]),
                point_id: Some(k as u32),
            }
        })
        .collect();
    let s = grid.spacing_mm * 1e-3;
    let small = ordered.radius_over_spacing[0] * s;
    let large = if grid.modified { ordered.radius_over_spacing[1] * s } else { small };
    Detection { id: None, corners, complete: true, anchored: true, circle_radii_m: Some([small, large]) }
}
