//! The geometry of ChArUco boards and circle grids, in the detectors' target frames (origin at
//! the centre, x right, y up as printed, z out of the printed face).

use nalgebra::{Point2, Point3};

use super::target::{dark_cells, rect, TargetCorner, TargetGeometry};
use crate::error::{DatasetError, Result};
use ferrocal_vision::detect::{ArucoDictionary, CharucoBoard, CircleGrid};

/// Vertices of the polygon that stands for a dot: the chord error `r (1 - cos(pi / n))` is
/// below 1e-5 of the radius.
pub const DOT_VERTICES: usize = 720;

/// A ChArUco board (OpenCV 4.6's layout, see `ferrocal_vision::detect::charuco`).
pub(super) fn charuco(
    cols: u32,
    rows: u32,
    square_m: f64,
    marker_m: f64,
    dictionary: ArucoDictionary,
    margin_m: f64,
) -> Result<TargetGeometry> {
    let board = CharucoBoard { cols, rows, square_mm: square_m * 1e3, marker_mm: marker_m * 1e3, dictionary };
    board.validate().map_err(|reason| DatasetError::RenderConfig {
        field: "target".into(),
        value: format!("charuco {cols}x{rows}"),
        reason,
    })?;
    let mut dark = Vec::new();
    let (hx, hy) = (0.5 * cols as f64 * square_m, 0.5 * rows as f64 * square_m);
    for r in 0..rows {
        for c in 0..cols {
            if board.square_is_black(r, c) {
                let x0 = c as f64 * square_m - hx;
                let y1 = hy - r as f64 * square_m;
                dark.push(rect(x0, y1 - square_m, x0 + square_m, y1));
            }
        }
    }
    for (id, (r, c)) in board.marker_squares().into_iter().enumerate() {
        let (n, bits) = ferrocal_vision::detect::aruco::marker_bits(dictionary, id as u32)
            .map_err(|e| DatasetError::Render(format!("marker {id} of {dictionary}: {e}")))?;
        let cell = marker_m / n as f64;
        let o = board.square_centre_m(r, c);
        let (left, top) = (o.x - 0.5 * marker_m, o.y + 0.5 * marker_m);
        dark_cells(&mut dark, &bits, n, (left, top), cell);
    }
    let corners = board
        .target_points_m()
        .into_iter()
        .enumerate()
        .map(|(k, p)| TargetCorner { feature: 0, index: k as u32, p_target_m: p })
        .collect();
    Ok(TargetGeometry {
        outline_m: rect(-hx - margin_m, -hy - margin_m, hx + margin_m, hy + margin_m),
        dark_m: dark,
        corners,
        face_minus_z: false,
    })
}

/// A circle grid (the order and frame of `ferrocal_vision::detect::circles`; an asymmetric
/// grid in OpenCV's frame, origin at dot 0).
pub(super) fn circle_grid(
    grid: &CircleGrid,
    radius_m: f64,
    large_radius_m: Option<f64>,
    margin_m: f64,
) -> Result<TargetGeometry> {
    let spacing_m = grid.spacing_mm * 1e-3;
    let big = large_radius_m.unwrap_or(radius_m);
    // Nearest neighbours: `spacing` apart on a symmetric grid, `sqrt 2 spacing` (diagonal) on an
    // asymmetric one.
    let nearest_m = if grid.asymmetric { std::f64::consts::SQRT_2 * spacing_m } else { spacing_m };
    if 2.0 * radius_m >= nearest_m || radius_m + big >= nearest_m {
        return Err(DatasetError::RenderConfig {
            field: "target.radius_m".into(),
            value: format!("{radius_m} (large {big})"),
            reason: format!("neighbouring dots would touch at a distance of {nearest_m} m"),
        });
    }
    let mut dark = Vec::new();
    let mut corners = Vec::new();
    for (k, p) in grid.target_points_m().into_iter().enumerate() {
        let r = if k == 0 { big } else { radius_m };
        dark.push(
            (0..DOT_VERTICES)
                .map(|v| {
                    let a = 2.0 * std::f64::consts::PI * v as f64 / DOT_VERTICES as f64;
                    Point2::new(p.x + r * a.cos(), p.y + r * a.sin())
                })
                .collect(),
        );
        corners.push(TargetCorner { feature: 0, index: k as u32, p_target_m: Point3::new(p.x, p.y, 0.0) });
    }
    let pts = grid.target_points_m();
    let lo = |f: fn(&Point3<f64>) -> f64| pts.iter().map(f).fold(f64::INFINITY, f64::min) - big - margin_m;
    let hi = |f: fn(&Point3<f64>) -> f64| pts.iter().map(f).fold(f64::NEG_INFINITY, f64::max) + big + margin_m;
    Ok(TargetGeometry {
        outline_m: rect(lo(|p| p.x), lo(|p| p.y), hi(|p| p.x), hi(|p| p.y)),
        dark_m: dark,
        corners,
        face_minus_z: grid.asymmetric,
    })
}
