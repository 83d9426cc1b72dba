//! The patterns camera calibration can use, out of the pattern strings of
//! [`crate::detect::Pattern`] (the one parser): chessboards (found by OpenCV's recipe,
//! [`super::corners`]), ChArUco boards and circle grids (found by the project's own detectors,
//! [`crate::detect`], whose corners carry their ids so that partial views calibrate too),
//! AprilTag boards (every decoded tag's four corners, with ids).

use super::PlanarTarget;
use crate::detect::{CharucoBoard, CircleGrid, Pattern};
use crate::error::{Result, VisionError};

/// A pattern camera calibration can use (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CalibrationPattern {
    /// A chessboard with `inner_cols x inner_rows` inner corners (OpenCV's `patternSize`).
    Chessboard {
        /// Inner corners per row.
        inner_cols: u32,
        /// Inner corners per column.
        inner_rows: u32,
        /// Side of a square, metres.
        square_m: f64,
    },
    /// A ChArUco board (target frame and corner ids: [`crate::detect::charuco`]).
    Charuco(CharucoBoard),
    /// A circle grid (target frame and order: [`crate::detect::circles`]).
    CircleGrid(CircleGrid),
    /// An AprilTag board (`aprilboard:` or Kalibr's `aprilgrid:`, always a
    /// [`Pattern::AprilBoard`]): every tag's four corners, with ids, so partial views work.
    TagBoard(Pattern),
}

impl CalibrationPattern {
    /// The calibration pattern of a parsed pattern string; other targets (AprilTags, the plate)
    /// are refused by name.
    pub fn of(pattern: &Pattern) -> Result<Self> {
        match *pattern {
            Pattern::Chessboard { cols, rows, square_mm } => {
                Ok(Self::Chessboard { inner_cols: cols, inner_rows: rows, square_m: square_mm * 1e-3 })
            }
            Pattern::Charuco(b) => Ok(Self::Charuco(b)),
            Pattern::CircleGrid(g) => Ok(Self::CircleGrid(g)),
            Pattern::AprilBoard { .. } => Ok(Self::TagBoard(*pattern)),
            _ => Err(VisionError::InvalidInput {
                detail: format!(
                    "pattern '{pattern}': camera calibration needs a board with many points: chessboard:<cols>x<rows>:<square>mm (inner corners), charuco:<cols>x<rows>:<square>mm:<marker>mm:<dictionary>, circlegrid:<cols>x<rows>:<spacing>mm[:modified], acircles:<cols>x<rows>:<spacing>mm, aprilboard:<cols>x<rows>:<tag>mm:<spacing>mm or aprilgrid:<cols>x<rows>:<tag>mm:<spacing>; single AprilTags and the plate are not calibration targets"
                ),
            }),
        }
    }

    /// Parses a pattern string ([`crate::detect::Pattern`]'s syntax) and keeps what calibration
    /// can use.
    pub fn parse(text: &str) -> Result<Self> {
        Self::of(&text.parse::<Pattern>()?)
    }

    /// The target's points in its own frame: for a chessboard, OpenCV's object points
    /// `(col * square, row * square, 0)`, row by row from the first detected corner.
    pub fn target(&self) -> PlanarTarget {
        match *self {
            Self::Chessboard { inner_cols, inner_rows, square_m } => {
                PlanarTarget::chessboard(inner_cols, inner_rows, square_m)
            }
            Self::Charuco(b) => PlanarTarget { points_m: b.target_points_m(), reversible: false },
            Self::CircleGrid(g) => PlanarTarget { points_m: g.target_points_m(), reversible: false },
            Self::TagBoard(p) => PlanarTarget { points_m: p.target_points_m().unwrap_or_default(), reversible: false },
        }
    }

    /// The target's points in the frame the detector reports them in (`Corner::target_m`), in
    /// the order of [`CalibrationPattern::target`]. The same points for every pattern but the
    /// chessboard, whose calibration target follows OpenCV (origin at the first corner, x along
    /// a row, y along a column) while the detector puts the origin at the board's centre, y up:
    /// the frame a hand-eye transform is expressed in.
    pub fn detector_points_m(&self) -> Vec<nalgebra::Point3<f64>> {
        match *self {
            Self::Chessboard { inner_cols, inner_rows, square_m } => (0..inner_rows)
                .flat_map(|r| {
                    (0..inner_cols).map(move |c| {
                        crate::detect::chessboard::target_point(inner_cols, inner_rows, square_m * 1e3, r, c)
                    })
                })
                .collect(),
            _ => self.target().points_m,
        }
    }

    /// The detector's options for calibration: the defaults, with the tags' corners of an
    /// AprilTag board refined by the edge model (sub-pixel, with covariances; the C library's
    /// quad corners are several times less accurate).
    pub fn detect_options(&self) -> crate::detect::DetectOptions {
        let mut o = crate::detect::DetectOptions::default();
        if matches!(self, Self::TagBoard(_)) {
            o.apriltag.refine = crate::detect::apriltag::TagRefine::EdgeModel;
        }
        o
    }

    /// The pattern as a pattern string's value.
    pub fn pattern(&self) -> Pattern {
        match *self {
            Self::Chessboard { inner_cols, inner_rows, square_m } => {
                Pattern::Chessboard { cols: inner_cols, rows: inner_rows, square_mm: square_m * 1e3 }
            }
            Self::Charuco(b) => Pattern::Charuco(b),
            Self::CircleGrid(g) => Pattern::CircleGrid(g),
            Self::TagBoard(p) => p,
        }
    }
}

impl std::fmt::Display for CalibrationPattern {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.pattern())
    }
}

impl std::str::FromStr for CalibrationPattern {
    type Err = VisionError;
    fn from_str(s: &str) -> Result<Self> {
        Self::parse(s)
    }
}
