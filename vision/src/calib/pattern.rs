//! The patterns camera calibration can use, out of the pattern strings of
//! [`crate::detect::Pattern`] (the one parser): chessboards (found by OpenCV's recipe,
//! [`super::corners`]), ChArUco boards and circle grids (found by the project's own detectors,
//! [`crate::detect`], whose corners carry their ids so that partial views calibrate too).

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
            _ => Err(VisionError::InvalidInput {
                detail: format!(
                    "pattern '{pattern}': camera calibration supports chessboard:<cols>x<rows>:<square>mm (inner corners), charuco:<cols>x<rows>:<square>mm:<marker>mm:<dictionary> and circlegrid:<cols>x<rows>:<spacing>mm[:modified]; AprilTag boards and plates are not supported by it yet"
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
        }
    }

    /// The pattern as a pattern string's value.
    pub fn pattern(&self) -> Pattern {
        match *self {
            Self::Chessboard { inner_cols, inner_rows, square_m } => {
                Pattern::Chessboard { cols: inner_cols, rows: inner_rows, square_mm: square_m * 1e3 }
            }
            Self::Charuco(b) => Pattern::Charuco(b),
            Self::CircleGrid(g) => Pattern::CircleGrid(g),
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
