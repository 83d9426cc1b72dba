//! Planar calibration targets and their geometry in the target frame.
//!
//! Target frame: origin at the centre of the pattern, x to the right and y up as the printed
//! face is read, z out of the printed face (towards a camera that sees it). All targets are
//! drawn as a white plate (the outline) carrying non-overlapping black polygons.

use ferrocal_vision::detect::CircleGrid;
use nalgebra::{Point2, Point3};
use serde::{Deserialize, Serialize};

use super::apriltag::TagFamily;
use crate::error::{DatasetError, Result};
use ferrocal_vision::detect::ArucoDictionary;

/// Which target, with its dimensions. Embedded in TOML as e.g.
/// `target = { kind = "plate", square_m = 0.05, margin_m = 0.02 }`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum TargetConfig {
    /// The Gantry-Tau plate: the five black fields of a 3x3 checkerboard (four corners and the
    /// centre; 20 sides), on a white plate.
    Plate {
        /// Side of one square, metres.
        square_m: f64,
        /// White margin around the 3x3 field, metres.
        margin_m: f64,
    },
    /// A chessboard with `inner_cols x inner_rows` inner corners (OpenCV's `patternSize`);
    /// the top-left square is black.
    Chessboard {
        /// Inner corners per row.
        inner_cols: u32,
        /// Inner corners per column.
        inner_rows: u32,
        /// Side of one square, metres.
        square_m: f64,
        /// White margin around the squares, metres.
        margin_m: f64,
    },
    /// A grid of tag36h11 AprilTags.
    #[serde(rename = "apriltag_board")]
    AprilTagBoard {
        /// Tags per row.
        cols: u32,
        /// Tags per column.
        rows: u32,
        /// Side of a tag's black border (the AprilTag library's tag size), metres.
        tag_size_m: f64,
        /// Gap between the black borders of neighbouring tags, metres; at least the two white
        /// border cells (`2 tag_size_m / 8`).
        spacing_m: f64,
        /// Id of the first tag (top-left); the others follow row by row. Ignored when `ids`
        /// is given.
        #[serde(default)]
        first_id: u32,
        /// Explicit ids, row by row from the top-left (`cols * rows` of them).
        #[serde(default)]
        ids: Option<Vec<u32>>,
        /// White margin beyond the outermost black borders, metres; at least one white border
        /// cell (`tag_size_m / 8`).
        margin_m: f64,
    },
    /// A ChArUco board of `cols x rows` squares, laid out as OpenCV 4.6 draws it (top-left
    /// square black, markers in the white squares, ids row by row from the top): the layout of
    /// `ferrocal_vision::detect::charuco`.
    Charuco {
        /// Squares per row.
        cols: u32,
        /// Squares per column.
        rows: u32,
        /// Side of a square, metres.
        square_m: f64,
        /// Side of a marker, metres.
        marker_m: f64,
        /// The markers' dictionary (OpenCV's name, e.g. `DICT_6X6_250`).
        dictionary: ArucoDictionary,
        /// White margin around the squares, metres.
        margin_m: f64,
    },
    /// A grid of `cols x rows` black dots (`ferrocal_vision::detect::circles` order: dot 0 at
    /// the bottom-left, rows along x); with `large_radius_m` dot 0 is that large ("modified").
    CircleGrid {
        /// Dots per row.
        cols: u32,
        /// Dots per column.
        rows: u32,
        /// Distance between neighbouring centres, metres.
        spacing_m: f64,
        /// Radius of the dots, metres.
        radius_m: f64,
        /// Radius of dot 0, metres, for a modified grid.
        #[serde(default)]
        large_radius_m: Option<f64>,
        /// White margin beyond the outermost dots' edges, metres.
        margin_m: f64,
        /// OpenCV's asymmetric grid instead (`spacing_m` is OpenCV's `squareSize`; its frame,
        /// origin at dot 0 and z into the printed face, is `ferrocal_vision`'s
        /// `CircleGrid::point_m`: a pose that shows the printed face turns z away from the
        /// camera).
        #[serde(default)]
        asymmetric: bool,
    },
}

/// One ground-truth corner of a target.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct TargetCorner {
    /// Plate: square index (0 top-left, 1 top-right, 2 centre, 3 bottom-left, 4 bottom-right);
    /// chessboard, ChArUco board, circle grid: 0; AprilTag board: the tag id.
    pub feature: u32,
    /// Plate: corner of the square (0 top-left, 1 top-right, 2 bottom-right, 3 bottom-left);
    /// chessboard: `row * inner_cols + col`, rows from the top; AprilTag: the C library's
    /// corner order (0 bottom-left, 1 bottom-right, 2 top-right, 3 top-left as printed);
    /// ChArUco: the corner id (OpenCV's); circle grid: the dot index (its centre).
    pub index: u32,
    /// Position in the target frame (z = 0), metres.
    pub p_target_m: Point3<f64>,
}

/// The drawable geometry and the corners of a target, in the target frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TargetGeometry {
    /// The plate outline, counter-clockwise seen from the front (x right, y up), metres.
    pub outline_m: Vec<Point2<f64>>,
    /// Black regions, counter-clockwise, pairwise non-overlapping, inside the outline.
    pub dark_m: Vec<Vec<Point2<f64>>>,
    /// Ground-truth corners in the documented order: plate per square, per corner;
    /// chessboard row by row from the top-left; AprilTag board per tag (row by row from the
    /// top-left), per corner in the C library's order.
    pub corners: Vec<TargetCorner>,
    /// Whether the printed face looks along -z (OpenCV's frames, z into the board: the
    /// asymmetric circle grid) instead of +z: a camera must then be on the -z side.
    #[serde(default)]
    pub face_minus_z: bool,
}

impl TargetGeometry {
    /// The geometry as printed by a printer whose scale is off by `scale_x` and `scale_y`
    /// (relative, e.g. `0.005` for 0.5 %) along the target's x and y axes: every outline vertex,
    /// black polygon and corner moves from `(x, y)` to `((1 + scale_x) x, (1 + scale_y) y)`
    /// about the pattern's centre (the target frame's origin). The corners of the result are
    /// where the printed pattern really has them (the renderer's ground truth); the nominal
    /// geometry is what a calibration assumes.
    pub fn printed(&self, scale_x: f64, scale_y: f64) -> Result<TargetGeometry> {
        for (field, v) in [("print_scale_x", scale_x), ("print_scale_y", scale_y)] {
            if !(v.is_finite() && v.abs() < 0.5) {
                return Err(DatasetError::RenderConfig {
                    field: format!("target.{field}"),
                    value: v.to_string(),
                    reason: "must be finite and within +-0.5 (a relative scale error)".into(),
                });
            }
        }
        let (fx, fy) = (1.0 + scale_x, 1.0 + scale_y);
        let map = |p: &Point2<f64>| Point2::new(fx * p.x, fy * p.y);
        Ok(TargetGeometry {
            outline_m: self.outline_m.iter().map(map).collect(),
            dark_m: self.dark_m.iter().map(|poly| poly.iter().map(map).collect()).collect(),
            corners: self
                .corners
                .iter()
                .map(|c| TargetCorner {
                    p_target_m: Point3::new(fx * c.p_target_m.x, fy * c.p_target_m.y, c.p_target_m.z),
                    ..*c
                })
                .collect(),
            face_minus_z: self.face_minus_z,
        })
    }
}

pub(super) fn rect(x0: f64, y0: f64, x1: f64, y1: f64) -> Vec<Point2<f64>> {
    vec![Point2::new(x0, y0), Point2::new(x1, y0), Point2::new(x1, y1), Point2::new(x0, y1)]
}

/// The black cells of a `t` x `t` code (`white[k * t + l]`: row `k` from the top, column `l`,
/// white or not) of cell size `cell` whose top left corner is at `(left, top)`, merged into
/// horizontal runs, added to `dark`.
pub(super) fn dark_cells(
    dark: &mut Vec<Vec<Point2<f64>>>,
    white: &[bool],
    t: usize,
    (left, top): (f64, f64),
    cell: f64,
) {
    for k in 0..t {
        let mut l = 0;
        while l < t {
            if white[k * t + l] {
                l += 1;
                continue;
            }
            let start = l;
            while l < t && !white[k * t + l] {
                l += 1;
            }
            let y1 = top - k as f64 * cell;
            dark.push(rect(left + start as f64 * cell, y1 - cell, left + l as f64 * cell, y1));
        }
    }
}

fn check_length(field: &str, v: f64, allow_zero: bool) -> Result<()> {
    let ok = v.is_finite() && (v > 0.0 || (allow_zero && v == 0.0));
    if ok {
        Ok(())
    } else {
        Err(DatasetError::RenderConfig {
            field: format!("target.{field}"),
            value: v.to_string(),
            reason: if allow_zero { "must be finite and >= 0" } else { "must be finite and > 0" }.into(),
        })
    }
}

fn check_count(field: &str, v: u32, min: u32) -> Result<()> {
    if v >= min && v <= 1000 {
        Ok(())
    } else {
        Err(DatasetError::RenderConfig {
            field: format!("target.{field}"),
            value: v.to_string(),
            reason: format!("must lie in {min}..=1000"),
        })
    }
}

impl TargetConfig {
    /// Checks the dimensions and builds the geometry.
    pub fn build(&self) -> Result<TargetGeometry> {
        match self {
            TargetConfig::Plate { square_m, margin_m } => plate(*square_m, *margin_m),
            TargetConfig::Chessboard { inner_cols, inner_rows, square_m, margin_m } => {
                chessboard(*inner_cols, *inner_rows, *square_m, *margin_m)
            }
            TargetConfig::AprilTagBoard { cols, rows, tag_size_m, spacing_m, first_id, ids, margin_m } => {
                apriltag_board(*cols, *rows, *tag_size_m, *spacing_m, *first_id, ids.as_deref(), *margin_m)
            }
            TargetConfig::Charuco { cols, rows, square_m, marker_m, dictionary, margin_m } => {
                check_count("cols", *cols, 2)?;
                check_count("rows", *rows, 2)?;
                check_length("square_m", *square_m, false)?;
                check_length("marker_m", *marker_m, false)?;
                check_length("margin_m", *margin_m, true)?;
                super::boards::charuco(*cols, *rows, *square_m, *marker_m, *dictionary, *margin_m)
            }
            TargetConfig::CircleGrid { cols, rows, spacing_m, radius_m, large_radius_m, margin_m, asymmetric } => {
                check_count("cols", *cols, 2)?;
                check_count("rows", *rows, 2)?;
                check_length("spacing_m", *spacing_m, false)?;
                check_length("radius_m", *radius_m, false)?;
                check_length("margin_m", *margin_m, true)?;
                if let Some(l) = large_radius_m {
                    check_length("large_radius_m", *l, false)?;
                }
                let grid = if *asymmetric {
                    if large_radius_m.is_some() {
                        return Err(DatasetError::RenderConfig {
                            field: "target.large_radius_m".into(),
                            value: format!("{large_radius_m:?}"),
                            reason: "an asymmetric circle grid has no large dot".into(),
                        });
                    }
                    CircleGrid::asymmetric(*cols, *rows, spacing_m * 1e3)
                } else {
                    CircleGrid::symmetric(*cols, *rows, spacing_m * 1e3, large_radius_m.is_some())
                };
                super::boards::circle_grid(&grid, *radius_m, *large_radius_m, *margin_m)
            }
        }
    }
}

fn plate(s: f64, margin: f64) -> Result<TargetGeometry> {
    check_length("square_m", s, false)?;
    check_length("margin_m", margin, true)?;
    let half = 1.5 * s + margin;
    let mut dark = Vec::new();
    let mut corners = Vec::new();
    // Fields (row, col) of the 3x3 checkerboard whose (row + col) is even, row by row.
    for (feature, (r, c)) in [(0, 0), (0, 2), (1, 1), (2, 0), (2, 2)].into_iter().enumerate() {
        let xc = (c as f64 - 1.0) * s;
        let yc = (1.0 - r as f64) * s;
        let (x0, x1, y0, y1) = (xc - 0.5 * s, xc + 0.5 * s, yc - 0.5 * s, yc + 0.5 * s);
        dark.push(rect(x0, y0, x1, y1));
        for (index, (x, y)) in [(x0, y1), (x1, y1), (x1, y0), (x0, y0)].into_iter().enumerate() {
            corners.push(TargetCorner {
                feature: feature as u32,
                index: index as u32,
                p_target_m: Point3::new(x, y, 0.0),
            });
        }
    }
    Ok(TargetGeometry { outline_m: rect(-half, -half, half, half), dark_m: dark, corners, face_minus_z: false })
}

fn chessboard(cols: u32, rows: u32, s: f64, margin: f64) -> Result<TargetGeometry> {
    check_count("inner_cols", cols, 1)?;
    check_count("inner_rows", rows, 1)?;
    check_length("square_m", s, false)?;
    check_length("margin_m", margin, true)?;
    let (nc, nr) = (cols as f64, rows as f64);
    let mut dark = Vec::new();
    // Square (R, C), R from the top, spans x in [(C - (cols+1)/2) s, +s] and
    // y in [((rows+1)/2 - R - 1) s, +s]; black when R + C is even.
    for r in 0..=rows {
        for c in 0..=cols {
            if (r + c) % 2 == 0 {
                let x0 = (c as f64 - 0.5 * (nc + 1.0)) * s;
                let y1 = (0.5 * (nr + 1.0) - r as f64) * s;
                dark.push(rect(x0, y1 - s, x0 + s, y1));
            }
        }
    }
    let mut corners = Vec::new();
    for r in 0..rows {
        for c in 0..cols {
            corners.push(TargetCorner {
                feature: 0,
                index: r * cols + c,
                p_target_m: Point3::new((c as f64 - 0.5 * (nc - 1.0)) * s, (0.5 * (nr - 1.0) - r as f64) * s, 0.0),
            });
        }
    }
    let hx = 0.5 * (nc + 1.0) * s + margin;
    let hy = 0.5 * (nr + 1.0) * s + margin;
    Ok(TargetGeometry { outline_m: rect(-hx, -hy, hx, hy), dark_m: dark, corners, face_minus_z: false })
}

fn apriltag_board(
    cols: u32,
    rows: u32,
    tag_size: f64,
    spacing: f64,
    first_id: u32,
    ids: Option<&[u32]>,
    margin: f64,
) -> Result<TargetGeometry> {
    check_count("cols", cols, 1)?;
    check_count("rows", rows, 1)?;
    check_length("tag_size_m", tag_size, false)?;
    check_length("spacing_m", spacing, true)?;
    check_length("margin_m", margin, true)?;
    let family = TagFamily::tag36h11()?;
    let n = (cols * rows) as usize;
    let ids: Vec<u32> = match ids {
        Some(ids) => {
            if ids.len() != n {
                return Err(DatasetError::RenderConfig {
                    field: "target.ids".into(),
                    value: format!("{} ids", ids.len()),
                    reason: format!("a {cols}x{rows} board needs {n} ids"),
                });
            }
            ids.to_vec()
        }
        None => (0..n as u32).map(|i| first_id.saturating_add(i)).collect(),
    };
    let cell = tag_size / family.width_at_border as f64;
    let border_cells = (family.total_width - family.width_at_border) as f64 / 2.0;
    if spacing < 2.0 * border_cells * cell * (1.0 - 1e-12) {
        return Err(DatasetError::RenderConfig {
            field: "target.spacing_m".into(),
            value: spacing.to_string(),
            reason: format!(
                "neighbouring tags would cover each other's white border; use at least {} m",
                2.0 * border_cells * cell
            ),
        });
    }
    if margin < border_cells * cell * (1.0 - 1e-12) {
        return Err(DatasetError::RenderConfig {
            field: "target.margin_m".into(),
            value: margin.to_string(),
            reason: format!("the plate edge would cut the tags' white border; use at least {} m", border_cells * cell),
        });
    }
    let t = family.total_width as usize;
    let pitch = tag_size + spacing;
    let (nc, nr) = (cols as f64, rows as f64);
    let mut dark = Vec::new();
    let mut corners = Vec::new();
    for (i, id) in ids.iter().enumerate() {
        let (r, c) = ((i / cols as usize) as f64, (i % cols as usize) as f64);
        let xc = (c - 0.5 * (nc - 1.0)) * pitch;
        let yc = (0.5 * (nr - 1.0) - r) * pitch;
        let cells = family.tag_cells(*id)?;
        let left = xc - 0.5 * t as f64 * cell;
        let top = yc + 0.5 * t as f64 * cell;
        dark_cells(&mut dark, &cells, t, (left, top), cell);
        let h = 0.5 * tag_size;
        for (index, (x, y)) in
            [(xc - h, yc - h), (xc + h, yc - h), (xc + h, yc + h), (xc - h, yc + h)].into_iter().enumerate()
        {
            corners.push(TargetCorner { feature: *id, index: index as u32, p_target_m: Point3::new(x, y, 0.0) });
        }
    }
    let hx = 0.5 * ((nc - 1.0) * pitch + tag_size) + margin;
    let hy = 0.5 * ((nr - 1.0) * pitch + tag_size) + margin;
    Ok(TargetGeometry { outline_m: rect(-hx, -hy, hx, hy), dark_m: dark, corners, face_minus_z: false })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn area(p: &[Point2<f64>]) -> f64 {
        (0..p.len())
            .map(|i| {
                let (a, b) = (p[i], p[(i + 1) % p.len()]);
                a.x * b.y - b.x * a.y
            })
            .sum::<f64>()
            / 2.0
    }

    #[test]
    fn plate_has_five_squares_twenty_corners_ccw() {
        let g = TargetConfig::Plate { square_m: 0.04, margin_m: 0.01 }.build().unwrap();
        assert_eq!(g.dark_m.len(), 5);
        assert_eq!(g.corners.len(), 20);
        for p in g.dark_m.iter().chain([&g.outline_m]) {
            assert!(area(p) > 0.0);
        }
        assert!((area(&g.outline_m) - 0.14f64.powi(2)).abs() < 1e-15);
        // The centre square's top-left corner is the top-left square's bottom-right corner.
        assert_eq!(g.corners[8].p_target_m, g.corners[2].p_target_m);
        assert_eq!(g.corners[0].p_target_m, Point3::new(-0.06, 0.06, 0.0));
    }

    #[test]
    fn chessboard_corners_row_by_row_from_top_left() {
        let g =
            TargetConfig::Chessboard { inner_cols: 9, inner_rows: 6, square_m: 0.025, margin_m: 0.0 }.build().unwrap();
        assert_eq!(g.corners.len(), 54);
        assert_eq!(g.dark_m.len(), 35);
        let c0 = g.corners[0].p_target_m;
        let c1 = g.corners[1].p_target_m;
        let c9 = g.corners[9].p_target_m;
        assert!((c1.x - c0.x - 0.025).abs() < 1e-15 && (c9.y - c0.y + 0.025).abs() < 1e-15);
        let dark_area: f64 = g.dark_m.iter().map(|p| area(p)).sum();
        assert!((dark_area - 35.0 * 0.025f64.powi(2)).abs() < 1e-12);
    }

    #[test]
    fn apriltag_board_ids_and_validation() {
        let cfg = TargetConfig::AprilTagBoard {
            cols: 3,
            rows: 2,
            tag_size_m: 0.08,
            spacing_m: 0.024,
            first_id: 10,
            ids: None,
            margin_m: 0.02,
        };
        let g = cfg.build().unwrap();
        assert_eq!(g.corners.len(), 24);
        assert_eq!(g.corners[4].feature, 11);
        let bad = TargetConfig::AprilTagBoard {
            cols: 3,
            rows: 2,
            tag_size_m: 0.08,
            spacing_m: 0.01,
            first_id: 0,
            ids: None,
            margin_m: 0.02,
        };
        assert!(matches!(bad.build(), Err(DatasetError::RenderConfig { .. })));
        let too_high = TargetConfig::AprilTagBoard {
            cols: 1,
            rows: 1,
            tag_size_m: 0.08,
            spacing_m: 0.02,
            first_id: 0,
            ids: Some(vec![600]),
            margin_m: 0.02,
        };
        assert!(too_high.build().is_err());
        assert!(TargetConfig::Plate { square_m: -1.0, margin_m: 0.0 }.build().is_err());
        assert!(TargetConfig::Plate { square_m: f64::NAN, margin_m: 0.0 }.build().is_err());
    }

    #[test]
    fn a_printed_geometry_is_scaled_per_axis_about_the_centre() {
        let nominal =
            TargetConfig::Chessboard { inner_cols: 9, inner_rows: 6, square_m: 0.025, margin_m: 0.01 }.build().unwrap();
        let printed = nominal.printed(0.005, -0.001).unwrap();
        // Corner spacing along x and y.
        let dx = printed.corners[1].p_target_m.x - printed.corners[0].p_target_m.x;
        let dy = printed.corners[0].p_target_m.y - printed.corners[9].p_target_m.y;
        assert!((dx - 0.025 * 1.005).abs() < 1e-15 && (dy - 0.025 * 0.999).abs() < 1e-15);
        // Areas scale by the product; orientation and order are kept.
        let ratio = area(&printed.dark_m[3]) / area(&nominal.dark_m[3]);
        assert!((ratio - 1.005 * 0.999).abs() < 1e-12);
        assert_eq!(printed.corners.len(), nominal.corners.len());
        assert!(nominal.printed(f64::NAN, 0.0).is_err() && nominal.printed(0.0, 0.7).is_err());
    }

    #[test]
    fn target_config_reads_from_toml() {
        let t: TargetConfig = toml::from_str(
            "kind = \"apriltag_board\"\ncols = 2\nrows = 2\ntag_size_m = 0.05\nspacing_m = 0.015\nmargin_m = 0.01\n",
        )
        .unwrap();
        assert!(matches!(t, TargetConfig::AprilTagBoard { first_id: 0, ids: None, .. }));
        let p: TargetConfig = toml::from_str("kind = \"plate\"\nsquare_m = 0.05\nmargin_m = 0.02\n").unwrap();
        assert_eq!(p, TargetConfig::Plate { square_m: 0.05, margin_m: 0.02 });
        assert!(toml::from_str::<TargetConfig>("kind = \"plate\"\nsquare_m = 0.05\nmargin = 0.02\n").is_err());
    }
}
