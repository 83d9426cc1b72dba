//! Sub-pixel corners from edges: every side of a square (or each half of the two edge lines
//! through a chessboard X-corner) is fitted with a model of the blurred step, neighbouring
//! lines are intersected, and every corner comes with its 2x2 covariance and its Cramer-Rao
//! bound.
//!
//! Entry points:
//! - [`refine_grid`]: the corners of a [`CheckerGrid`] (chessboards, the Gantry-Tau plate, any
//!   pattern of dark and light fields between straight grid lines);
//! - [`refine_quad`]: the four corners of one dark quadrilateral on a light ground (AprilTag
//!   borders);
//! - [`RefineOptions`] (line support, lens model, noise model), [`RefinedCorner`],
//!   [`RefineSummary`];
//! - [`edge_offset_crb_px`]: the closed-form bound of one edge's position.
//!
//! # The edge model
//! A straight edge `n . x = d` with `n = (cos phi, sin phi)`, blurred by the optics and
//! integrated over the pixel, is modelled on each segment `k` of the line by
//!
//! ```text
//! I(x) = a_k + b_k Phi((n . x - d) / s_k)
//! ```
//!
//! (`Phi` the standard normal distribution; `a_k` the level on the side `n . x < d`, `b_k` the
//! signed step, `s_k` the blur: a Gaussian PSF of `sigma` and the pixel's box give
//! `s^2 ~ sigma^2 + 1/12`, and any profile that is odd about the edge leaves `d` unbiased).
//! Segments of one line share `phi, d` and may have opposite polarity (the two halves of a
//! chessboard line through an X-corner). The parameters are fitted by Levenberg-Marquardt on
//! the pixels of a band `|n . x - d| <= w` along each segment, `w ~ 2.5 s + 2` px (kept clear of
//! the parallel edges), leaving out a neighbourhood of each segment end where the crossing
//! edge would enter the band: `r = (3 s + 1 + w |cos alpha|) / sin alpha` for lines crossing at
//! `alpha`. Two lines through a corner are intersected: `[n1; n2] p = [d1; d2]`.
//!
//! *Line support.* With [`LineSupport::Local`] (default) each corner gets its own two lines,
//! fitted on the segments that end at it (up to `max_segment_px` long): this is the right
//! choice when lens distortion bends the grid lines and no camera model is given. A line with
//! a segment on either side of the corner is then fitted as a parabola with its vertex at the
//! corner (`n . x - d - kappa (t . x)^2 / 2`, one curvature per line), so that `(phi, d)` is its
//! tangent at the corner rather than the chord, which would pass the corner at the mean
//! sagitta (see `line`); with a camera model the lines stay straight. With
//! [`LineSupport::Global`] every grid line is fitted once over its whole length and corners
//! are intersections of whole lines: far more pixels per corner, but only valid for straight
//! lines, i.e. an undistorted image or a camera model in [`RefineOptions::camera`] (the fit then
//! runs in undistorted pixel coordinates `fx x_n + cx`, `fy y_n + cy` and the corners are
//! projected back through the lens).
//!
//! # Noise, covariance and the Cramer-Rao bound
//! Pixel noise is modelled as `Var[I] = offset + slope max(I, 0)` (read noise plus shot noise;
//! [`NoiseModel`]). With [`NoiseSpec::Estimate`] (default) a first, unweighted pass fits every
//! line, the two coefficients are regressed from the pooled squared residuals (corrected for
//! the degrees of freedom), and a second pass refits with weights `1 / Var[I]` (one Gauss-Newton
//! step from the unweighted fit, which the weights move by a fraction of its uncertainty). The Fisher
//! information of one line's parameters `theta = (phi, d, a_k, b_k, ln s_k)` under Gaussian
//! noise is
//!
//! ```text
//! F = sum_pixels (1 / Var[I_p]) grad_theta m_p grad_theta m_p^T
//! dm/dphi = g (t . x),  dm/dd = -g,  dm/da = 1,  dm/db = Phi(z),  dm/dln s = -b phi(z) z
//! g = b phi(z) / s,  z = (n . x - d) / s,  t = (-sin phi, cos phi)
//! ```
//!
//! (the information carried by the signal dependence of the variance itself is neglected; it
//! is below 1 % here). The bound on `(phi, d)` is the corresponding 2x2 block of `F^-1`; it is
//! propagated to the corner through the intersection: with `N = [n1; n2]`,
//! `dp/dd_i = N^-1 e_i` and `dp/dphi_i = -N^-1 e_i (t_i . (p - o_i))`, so
//! `CRB(p) = sum_i J_i F_i^-1 J_i^T` (the two lines use disjoint pixels). For a straight edge of
//! length `L`, step `b`, blur `s` and noise `sigma`, the offset alone gives the closed form
//! `Var[d] = 2 sqrt(pi) sigma^2 s / (L b^2)` ([`edge_offset_crb_px`]).
//! The reported covariance is the same propagation of `chi^2 / (n - p) F^-1` (the fit's residual
//! variance); [`RefinedCorner::crb_px2`] is `F^-1` propagated with the noise model (the known one,
//! or the estimated one).
//!
//! # Conventions
//! Pixel `(0, 0)` is the centre of the top-left pixel (see `docs/conventions.md`).

pub(crate) mod erf;
mod grid;
mod line;

use nalgebra::{Matrix2, Point2};
use serde::{Deserialize, Serialize};

use crate::camera::CameraModel;
use crate::detect::GrayF32;
use crate::error::{Result, VisionError};
pub use grid::refine_grid;
pub(crate) use grid::refine_grid_timed;

/// Which pixels support the lines through a corner.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LineSupport {
    /// Each corner's own two lines, from the segments that end at it (distortion-tolerant).
    #[default]
    Local,
    /// Whole grid lines (straight lines only: undistorted images or a camera model).
    Global,
}

/// Pixel noise as a function of intensity: `Var[I] = offset_dn2 + slope_dn max(I, 0)`, in
/// digital numbers (DN).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct NoiseModel {
    /// Variance at zero intensity (read noise, quantisation, dark level), DN^2.
    pub offset_dn2: f64,
    /// Increase of the variance per DN of signal (shot noise: `1 / gain`), DN.
    pub slope_dn: f64,
}

impl NoiseModel {
    /// The variance at intensity `i_dn`, never below 1e-3 DN^2.
    pub fn variance_dn2(&self, i_dn: f64) -> f64 {
        (self.offset_dn2 + self.slope_dn * i_dn.max(0.0)).max(1e-3)
    }

    /// The model of a linear sensor, `DN = e / gain + black`:
    /// `Var = (S + read^2) / gain^2 + 1/12` (the last term from rounding) with the signal
    /// `S = gain (DN - black)` when `shot_noise` is on.
    pub fn from_sensor(gain_e_per_dn: f64, read_noise_e: f64, black_level_dn: f64, shot_noise: bool) -> Self {
        let read = (read_noise_e / gain_e_per_dn).powi(2) + 1.0 / 12.0;
        if shot_noise {
            Self { offset_dn2: read - black_level_dn / gain_e_per_dn, slope_dn: 1.0 / gain_e_per_dn }
        } else {
            Self { offset_dn2: read, slope_dn: 0.0 }
        }
    }
}

/// How the pixels are weighted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum NoiseSpec {
    /// Estimate a [`NoiseModel`] from the residuals of a first pass, then refit with weights.
    #[default]
    Estimate,
    /// Use this model for the weights and the Cramer-Rao bound.
    Known(NoiseModel),
    /// One pass, equal weights, no Cramer-Rao bound.
    Unweighted,
}

/// Options of [`refine_grid`] and [`refine_quad`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct RefineOptions {
    /// Which pixels support the lines.
    pub support: LineSupport,
    /// A lens model: fit in undistorted coordinates (straight lines) and project back.
    pub camera: Option<CameraModel>,
    /// Noise model.
    pub noise: NoiseSpec,
    /// Longest part of a segment used next to a corner with [`LineSupport::Local`], pixels.
    pub max_segment_px: f64,
    /// Upper limit of the band half-width, pixels (e.g. an AprilTag's border cell).
    pub max_band_px: Option<f64>,
    /// Blur assumed before the first fit, pixels.
    pub initial_blur_px: f64,
    /// Levenberg-Marquardt iterations per pass.
    pub max_iterations: usize,
    /// Segments whose step is below this (DN) are not used.
    pub min_contrast_dn: f64,
}

impl Default for RefineOptions {
    fn default() -> Self {
        Self {
            support: LineSupport::Local,
            camera: None,
            noise: NoiseSpec::Estimate,
            max_segment_px: 80.0,
            max_band_px: None,
            initial_blur_px: 1.0,
            max_iterations: 40,
            min_contrast_dn: 6.0,
        }
    }
}

impl RefineOptions {
    /// Checks the values.
    pub fn validate(&self) -> Result<()> {
        let bad = |name: &'static str, v: f64, reason: &str| VisionError::BadOption {
            name,
            value: v.to_string(),
            reason: reason.to_string(),
        };
        if !(self.max_segment_px.is_finite() && self.max_segment_px >= 4.0) {
            return Err(bad("max_segment_px", self.max_segment_px, "must be finite and >= 4"));
        }
        if let Some(b) = self.max_band_px {
            if !(b.is_finite() && b >= 1.0) {
                return Err(bad("max_band_px", b, "must be finite and >= 1"));
            }
        }
        if !(self.initial_blur_px.is_finite() && (0.1..=15.0).contains(&self.initial_blur_px)) {
            return Err(bad("initial_blur_px", self.initial_blur_px, "must lie in 0.1..=15"));
        }
        if self.max_iterations == 0 {
            return Err(bad("max_iterations", 0.0, "must be at least 1"));
        }
        if !(self.min_contrast_dn.is_finite() && self.min_contrast_dn >= 0.0) {
            return Err(bad("min_contrast_dn", self.min_contrast_dn, "must be finite and >= 0"));
        }
        if let NoiseSpec::Known(m) = self.noise {
            if !(m.offset_dn2.is_finite() && m.slope_dn.is_finite() && m.slope_dn >= 0.0) {
                return Err(bad("noise", m.offset_dn2, "offset and slope must be finite, slope >= 0"));
            }
        }
        if let Some(c) = &self.camera {
            c.validate()?;
        }
        Ok(())
    }
}

/// One refined corner.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct RefinedCorner {
    /// Position (pixel-centre convention).
    pub position_px: Point2<f64>,
    /// Covariance from the fit: `chi^2 / (n - p) F^-1` propagated to the corner, px^2.
    pub covariance_px2: Matrix2<f64>,
    /// Cramer-Rao bound under the noise model (`None` when unweighted), px^2.
    pub crb_px2: Option<Matrix2<f64>>,
    /// Mean fitted blur `s` of the segments used, pixels.
    pub blur_px: f64,
    /// Mean absolute step of the segments used, DN.
    pub contrast_dn: f64,
    /// Pixels used by the two lines.
    pub pixels: usize,
}

/// What the refinement of one grid did besides the corners.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct RefineSummary {
    /// The noise model used for the weights (`None` when unweighted).
    pub noise: Option<NoiseModel>,
    /// Lines fitted.
    pub lines_fitted: usize,
    /// Lines that could not be fitted (too few pixels, no contrast, diverged).
    pub lines_failed: usize,
    /// Pixel-weighted mean of `chi^2 / (n - p)` over the lines (near 1 when the noise model
    /// fits).
    pub reduced_chi2: f64,
}

/// A pattern of dark and light fields between straight grid lines: `field_rows x field_cols`
/// fields, `(field_rows + 1) x (field_cols + 1)` grid points. The segment between two
/// neighbouring grid points is an edge when the fields on either side have known, different
/// colours; fields beyond the grid have the colour `outside_dark` (unknown: `None`).
///
/// A chessboard with `c x r` inner corners is `(r + 1) x (c + 1)` fields, dark where
/// `(row + col)` is even, `outside_dark = None` (the margin is not used), and its inner corner
/// `(i, j)` is grid point `(i + 1, j + 1)`. The Gantry-Tau plate is the same with 3 x 3 fields
/// and a light outside.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CheckerGrid {
    /// Number of field rows.
    pub field_rows: usize,
    /// Number of field columns.
    pub field_cols: usize,
    /// Field colours row by row (`Some(true)` dark, `None` unknown).
    pub fields_dark: Vec<Option<bool>>,
    /// Colour beyond the fields.
    pub outside_dark: Option<bool>,
    /// Width of the outside band as a fraction of a field (limits the fit band there).
    pub outside_width_fraction: f64,
    /// Initial pixel positions of the grid points, row by row (`None` when unknown; a missing
    /// point is extrapolated from its neighbours where a segment needs it).
    pub points_px: Vec<Option<Point2<f64>>>,
    /// How far from its sides a light field is uniform, as a fraction of the field (1 for a
    /// chessboard; a ChArUco board's white squares carry a marker, uniform only over
    /// `(square - marker) / (2 square)` from each side): limits the fit band there.
    pub light_uniform_fraction: f64,
}

impl CheckerGrid {
    /// A checkerboard of `field_rows x field_cols` fields, dark where `(row + col)` is even
    /// when `top_left_dark`, with the given grid points.
    pub fn checkerboard(
        field_rows: usize,
        field_cols: usize,
        top_left_dark: bool,
        outside_dark: Option<bool>,
        points_px: Vec<Option<Point2<f64>>>,
    ) -> Self {
        let fields_dark = (0..field_rows * field_cols)
            .map(|k| Some((k / field_cols + k % field_cols).is_multiple_of(2) == top_left_dark))
            .collect();
        Self {
            field_rows,
            field_cols,
            fields_dark,
            outside_dark,
            outside_width_fraction: 0.3,
            points_px,
            light_uniform_fraction: 1.0,
        }
    }

    fn check(&self) -> Result<()> {
        let bad = |reason: String| VisionError::BadOption {
            name: "grid",
            value: format!("{}x{}", self.field_rows, self.field_cols),
            reason,
        };
        if self.field_rows == 0 || self.field_cols == 0 {
            return Err(bad("needs at least one field".into()));
        }
        if self.fields_dark.len() != self.field_rows * self.field_cols {
            return Err(bad(format!("{} field colours given", self.fields_dark.len())));
        }
        if self.points_px.len() != (self.field_rows + 1) * (self.field_cols + 1) {
            return Err(bad(format!("{} grid points given", self.points_px.len())));
        }
        if !(self.outside_width_fraction.is_finite() && self.outside_width_fraction > 0.0) {
            return Err(bad("outside_width_fraction must be > 0".into()));
        }
        if !(self.light_uniform_fraction.is_finite() && self.light_uniform_fraction > 0.0) {
            return Err(bad("light_uniform_fraction must be > 0".into()));
        }
        Ok(())
    }

    fn dark(&self, r: isize, c: isize) -> Option<bool> {
        if r < 0 || c < 0 || r >= self.field_rows as isize || c >= self.field_cols as isize {
            self.outside_dark
        } else {
            self.fields_dark[r as usize * self.field_cols + c as usize]
        }
    }

    fn inside(&self, r: isize, c: isize) -> bool {
        r >= 0 && c >= 0 && r < self.field_rows as isize && c < self.field_cols as isize
    }

    /// Whether the segment from grid point `(i, j)` one step along `dir` (0: along the row,
    /// 1: along the column) is an edge.
    fn is_edge(&self, i: isize, j: isize, dir: usize) -> bool {
        let (f1, f2) = if dir == 0 { ((i - 1, j), (i, j)) } else { ((i, j - 1), (i, j)) };
        matches!((self.dark(f1.0, f1.1), self.dark(f2.0, f2.1)), (Some(x), Some(y)) if x != y)
    }
}

/// Refines the four corners of a dark quadrilateral on a light ground (e.g. the outer border
/// of an AprilTag), given in cyclic order; the corners come back in the same order.
pub fn refine_quad(
    image: &GrayF32,
    corners_px: &[Point2<f64>; 4],
    options: &RefineOptions,
) -> Result<(Vec<Option<RefinedCorner>>, RefineSummary)> {
    let pts = vec![Some(corners_px[0]), Some(corners_px[1]), Some(corners_px[3]), Some(corners_px[2])];
    let mut grid = CheckerGrid::checkerboard(1, 1, true, Some(false), pts);
    grid.outside_width_fraction = 1.0;
    refine_grid(image, &grid, &[(0, 0), (0, 1), (1, 1), (1, 0)], options)
}

/// Closed-form Cramer-Rao bound (standard deviation, pixels) of the position of a straight edge
/// of length `length_px`, step `contrast_dn`, blur `blur_px` under white noise `noise_dn`:
/// `sqrt(2 sqrt(pi) sigma^2 s / (L b^2))` (offset alone, intensities and blur known; the band
/// must be a few `s` wide).
pub fn edge_offset_crb_px(length_px: f64, contrast_dn: f64, blur_px: f64, noise_dn: f64) -> f64 {
    (2.0 * std::f64::consts::PI.sqrt() * noise_dn * noise_dn * blur_px / (length_px * contrast_dn * contrast_dn)).sqrt()
}

#[cfg(test)]
mod tests;
