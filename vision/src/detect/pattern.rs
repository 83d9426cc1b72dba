//! Pattern strings: what `--pattern` names.
//!
//! | string | pattern |
//! |---|---|
//! | `chessboard:<cols>x<rows>:<square>mm` | chessboard, `cols x rows` inner corners |
//! | `apriltag:<family>[:<tag size>mm]` | single AprilTags of a family (e.g. `tag36h11`) |
//! | `plate:<square>mm` | the Gantry-Tau plate: five black squares of a 3 x 3 checkerboard |
//! | `aprilboard:<cols>x<rows>:<tag>mm:<spacing>mm[:first_id]` | a grid of tag36h11 tags, ids row by row from the top-left, origin at the centre |
//! | `aprilgrid:<cols>x<rows>:<tag>mm:<spacing>[:first_id]` | Kalibr's Aprilgrid: tag36h11 ids row by row from the bottom-left, origin at the bottom-left corner of the first tag's black border; the spacing is Kalibr's `tagSpacing` (gap over tag size, e.g. `0.3`) or a length (`12mm`) |
//! | `charuco:<cols>x<rows>:<square>mm:<marker>mm:<dictionary>` | a ChArUco board of `cols x rows` squares ([`CharucoBoard`]) |
//! | `circlegrid:<cols>x<rows>:<spacing>mm[:modified]` | a grid of `cols x rows` dots ([`CircleGrid`]); `modified`: one larger dot marks the origin |
//! | `acircles:<cols>x<rows>:<spacing>mm` | OpenCV's asymmetric circle grid: `cols` dots per row, `rows` rows, `spacing` OpenCV's `squareSize` (rows `spacing` apart, dots in a row twice that), dark or light dots |
//!
//! Sizes are millimetres with the unit written (`25mm`, `24.5mm`); the tag size is the side of
//! the tag's black border (the AprilTag library's convention) and the board spacing is the gap
//! between the black borders of neighbouring tags (as in `ferrocal_datasets`'
//! `TargetConfig::AprilTagBoard`). A ChArUco board's dictionary is OpenCV's name
//! (`DICT_6X6_250`, case-insensitive, `DICT_` optional) or number (`10`).

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

pub use super::aruco::ArucoDictionary;
pub use super::charuco::CharucoBoard;
pub use super::circles::CircleGrid;
use crate::error::{Result, VisionError};

/// The AprilTag families of the C library.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TagFamily {
    /// `tag16h5`.
    Tag16h5,
    /// `tag25h9`.
    Tag25h9,
    /// `tag36h11` (the recommended family; the one the renderer draws).
    Tag36h11,
    /// `tagCircle21h7`.
    TagCircle21h7,
    /// `tagCircle49h12`.
    TagCircle49h12,
    /// `tagCustom48h12`.
    TagCustom48h12,
    /// `tagStandard41h12`.
    TagStandard41h12,
    /// `tagStandard52h13`.
    TagStandard52h13,
}

impl TagFamily {
    /// Every family, in the order of [`TagFamily::name`]'s list.
    pub const ALL: [TagFamily; 8] = [
        TagFamily::Tag16h5,
        TagFamily::Tag25h9,
        TagFamily::Tag36h11,
        TagFamily::TagCircle21h7,
        TagFamily::TagCircle49h12,
        TagFamily::TagCustom48h12,
        TagFamily::TagStandard41h12,
        TagFamily::TagStandard52h13,
    ];

    /// The C library's name.
    pub fn name(self) -> &'static str {
        match self {
            TagFamily::Tag16h5 => "tag16h5",
            TagFamily::Tag25h9 => "tag25h9",
            TagFamily::Tag36h11 => "tag36h11",
            TagFamily::TagCircle21h7 => "tagCircle21h7",
            TagFamily::TagCircle49h12 => "tagCircle49h12",
            TagFamily::TagCustom48h12 => "tagCustom48h12",
            TagFamily::TagStandard41h12 => "tagStandard41h12",
            TagFamily::TagStandard52h13 => "tagStandard52h13",
        }
    }

    /// `(width_at_border, total_width)` in cells: the black border square spans
    /// `width_at_border` cells; for the classic families one white cell surrounds it.
    pub fn cells(self) -> (u32, u32) {
        match self {
            TagFamily::Tag16h5 => (6, 8),
            TagFamily::Tag25h9 => (7, 9),
            TagFamily::Tag36h11 => (8, 10),
            TagFamily::TagCircle21h7 => (5, 9),
            TagFamily::TagCircle49h12 => (5, 11),
            TagFamily::TagCustom48h12 => (6, 10),
            TagFamily::TagStandard41h12 => (5, 9),
            TagFamily::TagStandard52h13 => (6, 10),
        }
    }

    /// Whether the tag has the classic layout (a black border square with a white surround),
    /// whose outer edges [`crate::subpix::refine_quad`] can fit.
    pub fn classic_border(self) -> bool {
        matches!(self, TagFamily::Tag16h5 | TagFamily::Tag25h9 | TagFamily::Tag36h11)
    }
}

impl FromStr for TagFamily {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        let key = s.trim().to_ascii_lowercase();
        let key = key.strip_prefix("tag").unwrap_or(&key).replace(['_', '-'], "");
        TagFamily::ALL
            .into_iter()
            .find(|f| f.name().to_ascii_lowercase().strip_prefix("tag") == Some(key.as_str()))
            .ok_or_else(|| format!("unknown AprilTag family '{s}'"))
    }
}

impl fmt::Display for TagFamily {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A pattern to detect.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Pattern {
    /// A chessboard with `cols x rows` inner corners.
    Chessboard {
        /// Inner corners per row.
        cols: u32,
        /// Inner corners per column.
        rows: u32,
        /// Square side, millimetres.
        square_mm: f64,
    },
    /// Single AprilTags.
    AprilTag {
        /// Family.
        family: TagFamily,
        /// Side of the black border, millimetres, when given.
        tag_mm: Option<f64>,
    },
    /// The Gantry-Tau plate (five black squares, the dark fields of a 3 x 3 checkerboard).
    Plate {
        /// Square side, millimetres.
        square_mm: f64,
    },
    /// A grid of tag36h11 tags with ids row by row from the top-left.
    AprilBoard {
        /// Tags per row.
        cols: u32,
        /// Tags per column.
        rows: u32,
        /// Side of a tag's black border, millimetres.
        tag_mm: f64,
        /// Gap between neighbouring black borders, millimetres.
        spacing_mm: f64,
        /// Id of the first tag (top-left; bottom-left for Kalibr's layout).
        first_id: u32,
        /// Kalibr's Aprilgrid layout: ids row by row from the bottom-left, origin at the
        /// bottom-left corner of the first tag (else ids from the top-left, origin at the
        /// board's centre).
        #[serde(default)]
        kalibr: bool,
    },
    /// A ChArUco board.
    Charuco(CharucoBoard),
    /// A grid of dots, symmetric or modified.
    CircleGrid(CircleGrid),
}

impl Pattern {
    /// The target points that [`super::Corner::point_id`] indexes, metres in the pattern's
    /// target frame (see [`super`]), for the patterns whose corners carry point ids
    /// (chessboards, ChArUco boards, circle grids, AprilTag boards: corner `j` of the board's
    /// `k`-th tag, `k = id - first_id`, is point `4 k + j`); `None` for the others.
    pub fn target_points_m(&self) -> Option<Vec<nalgebra::Point3<f64>>> {
        match self {
            Pattern::Chessboard { cols, rows, square_mm } => Some(
                (0..*rows)
                    .flat_map(|r| {
                        (0..*cols).map(move |c| super::chessboard::target_point(*cols, *rows, *square_mm, r, c))
                    })
                    .collect(),
            ),
            Pattern::Charuco(b) => Some(b.target_points_m()),
            Pattern::CircleGrid(g) => Some(g.target_points_m()),
            Pattern::AprilBoard { cols, rows, .. } => {
                let n = cols * rows;
                let at = super::apriltag::board_target(self)?;
                Some((0..n).flat_map(|k| at(k).into_iter().flatten()).collect())
            }
            _ => None,
        }
    }
}

const EXPECTED: &str = "one of 'chessboard:<cols>x<rows>:<square>mm' (inner corners, e.g. chessboard:9x6:25mm), \
'apriltag:<family>[:<tag size>mm]' (e.g. apriltag:tag36h11:80mm), 'plate:<square>mm' (e.g. plate:50mm), \
'aprilboard:<cols>x<rows>:<tag>mm:<spacing>mm[:first_id]' (e.g. aprilboard:6x4:40mm:10mm:0), \
'charuco:<cols>x<rows>:<square>mm:<marker>mm:<dictionary>' (squares, e.g. charuco:5x7:36.195mm:18.256mm:DICT_6X6_250), \
'circlegrid:<cols>x<rows>:<spacing>mm[:modified]' (dot centres, e.g. circlegrid:10x10:25.4mm:modified), \
'acircles:<cols>x<rows>:<spacing>mm' (OpenCV's asymmetric grid, dots per row x rows, e.g. acircles:4x11:20mm)";

fn syntax(pattern: &str, problem: impl Into<String>) -> VisionError {
    VisionError::PatternSyntax { pattern: pattern.to_string(), problem: problem.into(), expected: EXPECTED.to_string() }
}

/// A length with its unit (`mm`, `cm` or `m`), in millimetres.
fn parse_mm(pattern: &str, what: &str, s: &str) -> Result<f64> {
    let t = s.trim();
    let (num, to_mm) = if let Some(v) = t.strip_suffix("mm") {
        (v, 1.0)
    } else if let Some(v) = t.strip_suffix("cm") {
        (v, 10.0)
    } else if let Some(v) = t.strip_suffix('m') {
        (v, 1e3)
    } else {
        return Err(syntax(pattern, format!("the {what} '{s}' needs its unit (mm, cm or m), e.g. '25mm'")));
    };
    let v: f64 = num
        .trim()
        .parse()
        .map_err(|_| syntax(pattern, format!("the {what} '{s}' is not a number of {}", &t[num.len()..])))?;
    if !(v.is_finite() && v > 0.0) {
        return Err(syntax(pattern, format!("the {what} must be positive, got '{s}'")));
    }
    Ok(v * to_mm)
}

fn parse_dims(pattern: &str, what: &str, s: &str, min: u32) -> Result<(u32, u32)> {
    let bad = || syntax(pattern, format!("the {what} '{s}' must be <cols>x<rows>, e.g. 9x6"));
    let (a, b) = s.trim().split_once(['x', 'X']).ok_or_else(bad)?;
    let a: u32 = a.trim().parse().map_err(|_| bad())?;
    let b: u32 = b.trim().parse().map_err(|_| bad())?;
    if a < min || b < min || a > 1000 || b > 1000 {
        return Err(syntax(pattern, format!("the {what} '{s}' must lie in {min}..=1000 each")));
    }
    Ok((a, b))
}

impl FromStr for Pattern {
    type Err = VisionError;

    fn from_str(text: &str) -> Result<Self> {
        let parts: Vec<&str> = text.trim().split(':').collect();
        let kind = parts[0].trim().to_ascii_lowercase();
        let n = parts.len();
        match kind.as_str() {
            "chessboard" | "checkerboard" => {
                if n != 3 {
                    return Err(syntax(text, format!("a chessboard has 3 fields, found {n}")));
                }
                let (cols, rows) = parse_dims(text, "inner-corner count", parts[1], 2)?;
                let square_mm = parse_mm(text, "square size", parts[2])?;
                Ok(Pattern::Chessboard { cols, rows, square_mm })
            }
            "apriltag" => {
                if !(2..=3).contains(&n) {
                    return Err(syntax(text, format!("an AprilTag pattern has 2 or 3 fields, found {n}")));
                }
                let family: TagFamily = parts[1].parse().map_err(|e: String| {
                    syntax(text, format!("{e}; known: {}", TagFamily::ALL.map(|f| f.name()).join(", ")))
                })?;
                let tag_mm = if n == 3 { Some(parse_mm(text, "tag size", parts[2])?) } else { None };
                Ok(Pattern::AprilTag { family, tag_mm })
            }
            "plate" => {
                if n != 2 {
                    return Err(syntax(text, format!("a plate has 2 fields, found {n}")));
                }
                Ok(Pattern::Plate { square_mm: parse_mm(text, "square size", parts[1])? })
            }
            "aprilboard" | "apriltag_board" | "aprilgrid" => {
                let kalibr = kind == "aprilgrid";
                if !(4..=5).contains(&n) {
                    return Err(syntax(text, format!("an AprilTag board has 4 or 5 fields, found {n}")));
                }
                let (cols, rows) = parse_dims(text, "tag count", parts[1], 1)?;
                let tag_mm = parse_mm(text, "tag size", parts[2])?;
                // Kalibr's `tagSpacing` is the gap over the tag size; a length is taken too.
                let ratio = parts[3].trim().parse::<f64>().ok().filter(|_| kalibr);
                let spacing_mm = match ratio {
                    Some(r) if r.is_finite() && r >= 0.0 => r * tag_mm,
                    Some(_) => return Err(syntax(text, format!("the tag spacing '{}' must be >= 0", parts[3]))),
                    None => parse_mm(text, "spacing", parts[3])?,
                };
                let first_id = if n == 5 {
                    parts[4]
                        .trim()
                        .parse()
                        .map_err(|_| syntax(text, format!("the first id '{}' is not a whole number", parts[4])))?
                } else {
                    0
                };
                Ok(Pattern::AprilBoard { cols, rows, tag_mm, spacing_mm, first_id, kalibr })
            }
            "charuco" => {
                if n != 5 {
                    return Err(syntax(text, format!("a ChArUco board has 5 fields, found {n}")));
                }
                let (cols, rows) = parse_dims(text, "square count", parts[1], 2)?;
                let square_mm = parse_mm(text, "square size", parts[2])?;
                let marker_mm = parse_mm(text, "marker size", parts[3])?;
                let dictionary: ArucoDictionary = parts[4].parse().map_err(|e: String| {
                    syntax(text, format!("{e}; known: {}", ArucoDictionary::ALL.map(|d| d.name()).join(", ")))
                })?;
                let board = CharucoBoard { cols, rows, square_mm, marker_mm, dictionary };
                board.validate().map_err(|e| syntax(text, e))?;
                Ok(Pattern::Charuco(board))
            }
            "circlegrid" => {
                if !(3..=4).contains(&n) {
                    return Err(syntax(text, format!("a circle grid has 3 or 4 fields, found {n}")));
                }
                let (cols, rows) = parse_dims(text, "dot count", parts[1], 2)?;
                let spacing_mm = parse_mm(text, "dot spacing", parts[2])?;
                let modified = match parts.get(3).map(|s| s.trim().to_ascii_lowercase()) {
                    None => false,
                    Some(m) if m == "modified" => true,
                    Some(m) if m == "symmetric" => false,
                    Some(_) => {
                        return Err(syntax(
                            text,
                            format!(
                                "the last field '{}' must be 'modified' (or 'symmetric', the default); OpenCV's asymmetric grid is acircles:<cols>x<rows>:<spacing>mm",
                                parts[3]
                            ),
                        ))
                    }
                };
                Ok(Pattern::CircleGrid(CircleGrid::symmetric(cols, rows, spacing_mm, modified)))
            }
            "acircles" | "asymmetric_circles" => {
                if n != 3 {
                    return Err(syntax(text, format!("an asymmetric circle grid has 3 fields, found {n}")));
                }
                let (cols, rows) = parse_dims(text, "dot count", parts[1], 2)?;
                let spacing_mm = parse_mm(text, "spacing", parts[2])?;
                Ok(Pattern::CircleGrid(CircleGrid::asymmetric(cols, rows, spacing_mm)))
            }
            "" => Err(syntax(text, "the pattern is empty")),
            other => Err(syntax(text, format!("unknown pattern kind '{other}'"))),
        }
    }
}

impl fmt::Display for Pattern {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Pattern::Chessboard { cols, rows, square_mm } => write!(f, "chessboard:{cols}x{rows}:{square_mm}mm"),
            Pattern::AprilTag { family, tag_mm: Some(t) } => write!(f, "apriltag:{family}:{t}mm"),
            Pattern::AprilTag { family, tag_mm: None } => write!(f, "apriltag:{family}"),
            Pattern::Plate { square_mm } => write!(f, "plate:{square_mm}mm"),
            Pattern::AprilBoard { cols, rows, tag_mm, spacing_mm, first_id, kalibr } => {
                let kind = if *kalibr { "aprilgrid" } else { "aprilboard" };
                write!(f, "{kind}:{cols}x{rows}:{tag_mm}mm:{spacing_mm}mm:{first_id}")
            }
            Pattern::Charuco(b) => {
                write!(f, "charuco:{}x{}:{}mm:{}mm:{}", b.cols, b.rows, b.square_mm, b.marker_mm, b.dictionary)
            }
            Pattern::CircleGrid(g) if g.asymmetric => write!(f, "acircles:{}x{}:{}mm", g.cols, g.rows, g.spacing_mm),
            Pattern::CircleGrid(g) => {
                write!(
                    f,
                    "circlegrid:{}x{}:{}mm{}",
                    g.cols,
                    g.rows,
                    g.spacing_mm,
                    if g.modified { ":modified" } else { "" }
                )
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_every_kind_and_round_trips() {
        for s in [
            "chessboard:9x6:25mm",
            "apriltag:tag36h11",
            "apriltag:tagStandard41h12:80mm",
            "plate:50mm",
            "aprilboard:6x4:40mm:10mm:3",
            "charuco:5x7:36.195mm:18.256mm:DICT_6X6_250",
            "circlegrid:10x10:25.4mm:modified",
            "circlegrid:4x11:20mm",
        ] {
            let p: Pattern = s.parse().unwrap();
            assert_eq!(p.to_string().parse::<Pattern>().unwrap(), p, "{s}");
        }
        assert_eq!(
            "chessboard:9x6:24.5mm".parse::<Pattern>().unwrap(),
            Pattern::Chessboard { cols: 9, rows: 6, square_mm: 24.5 }
        );
        // Lengths in cm or m are converted to millimetres.
        assert_eq!(
            "chessboard:7X5:3cm".parse::<Pattern>().unwrap(),
            Pattern::Chessboard { cols: 7, rows: 5, square_mm: 30.0 }
        );
        assert_eq!("plate:0.05m".parse::<Pattern>().unwrap(), Pattern::Plate { square_mm: 50.0 });
        assert_eq!(
            "aprilboard:2x3:30mm:9mm".parse::<Pattern>().unwrap(),
            Pattern::AprilBoard { cols: 2, rows: 3, tag_mm: 30.0, spacing_mm: 9.0, first_id: 0, kalibr: false }
        );
        assert_eq!(
            "aprilgrid:6x6:88mm:0.25".parse::<Pattern>().unwrap(),
            Pattern::AprilBoard { cols: 6, rows: 6, tag_mm: 88.0, spacing_mm: 22.0, first_id: 0, kalibr: true }
        );
        for s in ["aprilgrid:6x6:88mm:26.4mm:3", "acircles:4x11:20mm", "aprilboard:2x3:30mm:9mm:0"] {
            let p = s.parse::<Pattern>().unwrap();
            assert_eq!(p.to_string().parse::<Pattern>().unwrap(), p, "{s}");
        }
        assert_eq!(
            "apriltag:36h11".parse::<Pattern>().unwrap(),
            Pattern::AprilTag { family: TagFamily::Tag36h11, tag_mm: None }
        );
        assert_eq!(
            "charuco:5x7:36.195mm:18.256mm:6x6_250".parse::<Pattern>().unwrap(),
            Pattern::Charuco(CharucoBoard {
                cols: 5,
                rows: 7,
                square_mm: 36.195,
                marker_mm: 18.256,
                dictionary: ArucoDictionary::Dict6x6_250
            })
        );
        assert_eq!(
            "circlegrid:10x10:25.4mm:modified".parse::<Pattern>().unwrap(),
            Pattern::CircleGrid(CircleGrid::symmetric(10, 10, 25.4, true))
        );
    }

    #[test]
    fn bad_strings_name_the_string_and_the_expected_forms() {
        for s in [
            "",
            "chessboard",
            "chessboard:9x6",
            "chessboard:9x6:25",
            "chessboard:9by6:25mm",
            "chessboard:1x6:25mm",
            "plate:-5mm",
            "apriltag:tag99h1",
            "aprilboard:2x2:30mm",
            "circles:4x11:20mm",
            "chessboard:9x6:abcmm",
            "charuco:5x7:36mm:18mm",
            "charuco:5x7:36mm:40mm:DICT_6X6_250",
            "charuco:5x7:36mm:18mm:DICT_6X6_7",
            "charuco:30x30:36mm:18mm:DICT_4X4_50",
            "charuco:1x7:36mm:18mm:DICT_6X6_250",
            "circlegrid:10x10:25.4mm:mod",
            "circlegrid:10x10:25.4",
            "circlegrid:1x10:25.4mm",
        ] {
            let e = s.parse::<Pattern>().unwrap_err().to_string();
            assert!(
                e.contains(&format!("'{s}'")) && e.contains("expected") && e.contains("chessboard:<cols>x<rows>"),
                "{s}: {e}"
            );
        }
    }
}
