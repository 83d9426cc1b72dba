//! Pattern strings of the command line (`chessboard:<cols>x<rows>:<square>mm`) and the planar
//! targets they describe.

use nalgebra::Point3;

use super::PlanarTarget;
use crate::error::{Result, VisionError};

/// A calibration pattern.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Pattern {
    /// A chessboard with `inner_cols x inner_rows` inner corners (OpenCV's `patternSize`).
    Chessboard {
        /// Inner corners per row.
        inner_cols: u32,
        /// Inner corners per column.
        inner_rows: u32,
        /// Side of a square, metres.
        square_m: f64,
    },
}

const FORMS: &str = "expected chessboard:<cols>x<rows>:<square>mm (inner corners, e.g. chessboard:9x6:25mm; \
                     the square may also be given in m or cm)";

impl Pattern {
    /// Parses `chessboard:<cols>x<rows>:<square><unit>` with unit `mm`, `cm` or `m`.
    pub fn parse(text: &str) -> Result<Self> {
        let err = |reason: String| VisionError::PatternSpec { text: text.to_string(), reason };
        let parts: Vec<&str> = text.trim().split(':').collect();
        match parts.first().map(|s| s.to_ascii_lowercase()).as_deref() {
            Some("chessboard") | Some("checkerboard") => {}
            Some("apriltag") => {
                return Err(err(format!("AprilTag boards are not supported by camera calibration yet; {FORMS}")))
            }
            _ => return Err(err(FORMS.to_string())),
        }
        if parts.len() != 3 {
            return Err(err(FORMS.to_string()));
        }
        let dims: Vec<&str> = parts[1].split(['x', 'X']).collect();
        if dims.len() != 2 {
            return Err(err(format!("'{}' is not <cols>x<rows>; {FORMS}", parts[1])));
        }
        let count = |s: &str, what: &str| -> Result<u32> {
            let v: u32 = s.trim().parse().map_err(|_| err(format!("{what} '{s}' is not a whole number; {FORMS}")))?;
            if !(2..=1000).contains(&v) {
                return Err(err(format!("{what} must lie in 2..=1000 (inner corners), got {v}")));
            }
            Ok(v)
        };
        let inner_cols = count(dims[0], "columns")?;
        let inner_rows = count(dims[1], "rows")?;
        let size = parts[2].trim().to_ascii_lowercase();
        let (number, scale) = if let Some(v) = size.strip_suffix("mm") {
            (v, 1e-3)
        } else if let Some(v) = size.strip_suffix("cm") {
            (v, 1e-2)
        } else if let Some(v) = size.strip_suffix('m') {
            (v, 1.0)
        } else {
            return Err(err(format!("square size '{}' needs a unit (mm, cm or m); {FORMS}", parts[2])));
        };
        let v: f64 = number.trim().parse().map_err(|_| err(format!("square size '{}' is not a number", parts[2])))?;
        if !(v.is_finite() && v > 0.0) {
            return Err(err(format!("square size must be positive, got '{}'", parts[2])));
        }
        Ok(Pattern::Chessboard { inner_cols, inner_rows, square_m: v * scale })
    }

    /// The target's points in its own frame: for a chessboard, OpenCV's object points
    /// `(col * square, row * square, 0)`, row by row from the first detected corner.
    pub fn target(&self) -> PlanarTarget {
        match *self {
            Pattern::Chessboard { inner_cols, inner_rows, square_m } => {
                let points_m = (0..inner_rows)
                    .flat_map(|r| {
                        (0..inner_cols).map(move |c| Point3::new(c as f64 * square_m, r as f64 * square_m, 0.0))
                    })
                    .collect();
                PlanarTarget { points_m, reversible: true }
            }
        }
    }
}

impl std::fmt::Display for Pattern {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Pattern::Chessboard { inner_cols, inner_rows, square_m } => {
                write!(f, "chessboard:{inner_cols}x{inner_rows}:{}mm", square_m * 1e3)
            }
        }
    }
}

impl std::str::FromStr for Pattern {
    type Err = VisionError;
    fn from_str(s: &str) -> Result<Self> {
        Pattern::parse(s)
    }
}
