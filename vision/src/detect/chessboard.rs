//! Chessboards, full and partial views.
//!
//! X-corner candidates (saddles of the second derivatives, validated on circles) are grown
//! into grids a whole row or column at a time; the largest grid whose cells alternate
//! dark/light is labelled with board indices:
//!
//! 1. *Handedness*: the board is seen from its printed side, so the column axis turned towards
//!    the row axis must turn clockwise in the image (x right, y down); otherwise the grid is
//!    transposed.
//! 2. *Rotation* (four choices): the grid must fit in the board (`rows x cols` inner corners)
//!    and the dark cells must be those of the board: inner corner `(r, c)` has the dark square
//!    at its top-left when `r + c` is even (the top-left square of the board is dark, as in
//!    `ferrocal_datasets`' renderer). A board with `rows + cols` odd (e.g. 9 x 6) is therefore
//!    labelled without ambiguity; otherwise the rotation whose column axis points most to the
//!    right of the image (and row axis most downwards) is taken.
//! 3. *Partial views*: an axis along which fewer corners are seen than the board has is
//!    anchored by a visible board edge: beyond the last row of corners the board has one row
//!    of squares and then the margin, so the "cells" two steps out are uniform and light (above
//!    the mean of the border squares between), whereas a board cut by the image border or by
//!    occlusion continues (the next row would be outside the image or alternating) or is hidden
//!    by something that is not the board's light margin. An axis without a visible edge keeps relative indices (from 0,
//!    or 1 where the colours need it) and the detection says `anchored = false`.
//!
//! Corners are then refined by [`crate::subpix::refine_grid`] (the board is a checkerboard of
//! `(rows + 1) x (cols + 1)` fields; border squares are used, the margin is not).

use nalgebra::{Matrix2, Point2, Point3, Vector2};

use super::grid::{cell_mean, cell_parity, grow_grids, Grid, Pos};
use super::image::GrayF32;
use super::xcorner::{find_xcorners, XCorner};
use super::{Corner, DetectOptions, Detection, StageTimings};
use crate::error::{Result, VisionError};
use crate::subpix::{refine_grid_timed, CheckerGrid};
use std::time::Instant;

/// A labelled grid: board index `(row, col)` and coarse position of every corner.
#[derive(Clone, Debug)]
pub(crate) struct Labelled {
    pub corners: Vec<((u32, u32), Vector2<f64>)>,
    pub anchored: bool,
    pub complete: bool,
}

#[derive(Clone, Copy, Debug, Default)]
struct Sides {
    top: bool,
    bottom: bool,
    left: bool,
    right: bool,
}

/// Whether the board visibly ends beyond the side of the grid reached by stepping `step`
/// from the grid line `(line fixed)`: the cells two steps out do not alternate and are
/// lighter than the local mid level (the board's light margin).
fn side_closed(img: &GrayF32, cands: &[XCorner], g: &Grid, outward: Pos, contrast: f64) -> bool {
    // Corners on the outermost line of that side, with their inner neighbours.
    let mut edge: Vec<(i32, Vector2<f64>, Vector2<f64>)> = Vec::new();
    for (&(i, j), &k) in &g.at {
        let (ni, nj) = (i + outward.0, j + outward.1);
        if g.at.contains_key(&(ni, nj)) {
            continue;
        }
        let inner = (i - outward.0, j - outward.1);
        if let Some(q) = g.point(cands, inner) {
            // Position along the side.
            let along = if outward.0 != 0 { j } else { i };
            edge.push((along, cands[k].p, q));
        }
    }
    edge.sort_by_key(|e| e.0);
    let (w, h) = (img.width as f64, img.height as f64);
    let mut vals: [Vec<f64>; 2] = [Vec::new(), Vec::new()];
    let mut border = Vec::new();
    for pair in edge.windows(2) {
        let (a, b) = (&pair[0], &pair[1]);
        if b.0 != a.0 + 1 {
            continue;
        }
        // Points one and two steps outward.
        let a1 = a.1 * 2.0 - a.2;
        let b1 = b.1 * 2.0 - b.2;
        let a2 = a.1 * 3.0 - a.2 * 2.0;
        let b2 = b.1 * 3.0 - b.2 * 2.0;
        let inside = |p: Vector2<f64>| p.x >= 1.0 && p.y >= 1.0 && p.x <= w - 2.0 && p.y <= h - 2.0;
        if !(inside(a2) && inside(b2) && inside(a1) && inside(b1)) {
            continue;
        }
        // Middle of the cell two steps out (0.25..0.75 of the way from the 1-step line).
        let m =
            cell_mean(img, a1 * 0.75 + a2 * 0.25, b1 * 0.75 + b2 * 0.25, a1 * 0.25 + a2 * 0.75, b1 * 0.25 + b2 * 0.75);
        vals[(a.0.rem_euclid(2)) as usize].push(m);
        // The row of border squares between: alternating, its mean is the local mid level.
        border.push(cell_mean(img, a.1, b.1, a1, b1));
    }
    if vals[0].is_empty() || vals[1].is_empty() {
        return false;
    }
    let mean = |v: &Vec<f64>| v.iter().sum::<f64>() / v.len() as f64;
    // Uniform, and light like a printed board's margin: a dark or grey object hiding the
    // board (or the background beyond the image of a cut board) does not end it.
    (mean(&vals[0]) - mean(&vals[1])).abs() < 0.3 * contrast && 0.5 * (mean(&vals[0]) + mean(&vals[1])) > mean(&border)
}

/// Labels a grid with board indices, or `None` when it cannot be this board.
pub(crate) fn label(img: &GrayF32, cands: &[XCorner], grid: &Grid, cols: u32, rows: u32) -> Option<Labelled> {
    let (dark_parity, contrast) = cell_parity(img, cands, grid)?;
    // Handedness.
    let mut a = Vector2::zeros();
    let mut b = Vector2::zeros();
    for (&(i, j), &k) in &grid.at {
        if let Some(q) = grid.point(cands, (i, j + 1)) {
            a += q - cands[k].p;
        }
        if let Some(q) = grid.point(cands, (i + 1, j)) {
            b += q - cands[k].p;
        }
    }
    let mut g = grid.clone();
    if a.x * b.y - a.y * b.x < 0.0 {
        g.at = g.at.iter().map(|(&(i, j), &k)| ((j, i), k)).collect();
        std::mem::swap(&mut g.rows, &mut g.cols);
    }
    let (r_ext, c_ext) = (g.rows, g.cols);
    let sides = Sides {
        top: side_closed(img, cands, &g, (-1, 0), contrast),
        bottom: side_closed(img, cands, &g, (1, 0), contrast),
        left: side_closed(img, cands, &g, (0, -1), contrast),
        right: side_closed(img, cands, &g, (0, 1), contrast),
    };
    let (rows_i, cols_i) = (rows as i32, cols as i32);
    let mut best: Option<(i32, f64, Labelled)> = None;
    for k in 0..4 {
        let (nr, nc) = if k % 2 == 0 { (r_ext, c_ext) } else { (c_ext, r_ext) };
        if nr > rows_i || nc > cols_i {
            continue;
        }
        let map = |(i, j): Pos| -> Pos {
            match k {
                0 => (i, j),
                1 => (j, r_ext - 1 - i),
                2 => (r_ext - 1 - i, c_ext - 1 - j),
                _ => (c_ext - 1 - j, i),
            }
        };
        let p_new = match k {
            0 => dark_parity,
            1 => (dark_parity + r_ext) % 2,
            2 => (dark_parity + r_ext + c_ext) % 2,
            _ => (dark_parity + c_ext) % 2,
        };
        let s = match k {
            0 => sides,
            1 => Sides { top: sides.left, bottom: sides.right, left: sides.bottom, right: sides.top },
            2 => Sides { top: sides.bottom, bottom: sides.top, left: sides.right, right: sides.left },
            _ => Sides { top: sides.right, bottom: sides.left, left: sides.top, right: sides.bottom },
        };
        let anchor = |n: i32, total: i32, lo: bool, hi: bool| -> std::result::Result<Option<i32>, ()> {
            if n == total {
                Ok(Some(0))
            } else if lo && hi {
                Err(())
            } else if lo {
                Ok(Some(0))
            } else if hi {
                Ok(Some(total - n))
            } else {
                Ok(None)
            }
        };
        let Ok(or) = anchor(nr, rows_i, s.top, s.bottom) else { continue };
        let Ok(oc) = anchor(nc, cols_i, s.left, s.right) else { continue };
        let anchored_axes = or.is_some() as i32 + oc.is_some() as i32;
        // Colour: (p_new + or + oc) even.
        let (or, oc) = match (or, oc) {
            (Some(r), Some(c)) => {
                if (p_new + r + c) % 2 != 0 {
                    continue;
                }
                (r, c)
            }
            (Some(r), None) => {
                let c = (p_new + r) % 2;
                if c > cols_i - nc {
                    continue;
                }
                (r, c)
            }
            (None, Some(c)) => {
                let r = (p_new + c) % 2;
                if r > rows_i - nr {
                    continue;
                }
                (r, c)
            }
            (None, None) => {
                let c = p_new % 2;
                if c > cols_i - nc {
                    if rows_i - nr >= 1 {
                        (1, 0)
                    } else {
                        continue;
                    }
                } else {
                    (0, c)
                }
            }
        };
        // Upright score: new column axis along +x, new row axis along +y.
        let mut ax = Vector2::zeros();
        let mut ay = Vector2::zeros();
        for (&q, &kk) in &g.at {
            let nq = map(q);
            for (&q2, &k2) in &g.at {
                let n2 = map(q2);
                if n2 == (nq.0, nq.1 + 1) {
                    ax += cands[k2].p - cands[kk].p;
                }
                if n2 == (nq.0 + 1, nq.1) {
                    ay += cands[k2].p - cands[kk].p;
                }
            }
        }
        let upright = ax.x / ax.norm().max(1e-9) + ay.y / ay.norm().max(1e-9);
        let mut corners: Vec<((u32, u32), Vector2<f64>)> =
            g.at.iter()
                .map(|(&q, &kk)| {
                    let n = map(q);
                    (((n.0 + or) as u32, (n.1 + oc) as u32), cands[kk].p)
                })
                .collect();
        corners.sort_by_key(|c| c.0);
        let complete = corners.len() == (rows * cols) as usize;
        let lab = Labelled { corners, anchored: anchored_axes == 2, complete };
        if best.as_ref().is_none_or(|(ba, bu, _)| anchored_axes > *ba || (anchored_axes == *ba && upright > *bu + 1e-9))
        {
            best = Some((anchored_axes, upright, lab));
        }
    }
    best.map(|b| b.2)
}

/// The words [`squares_hint`] starts with; `camera calibrate` finds the hint among the reasons
/// of its skipped images by them.
pub const SQUARES_HINT_WORDS: &str = "; the pattern looks given by its squares";

/// The hint that a chessboard was given by its squares, not its inner corners, when the grid
/// found holds exactly `(cols - 1) x (rows - 1)` corners (a board of 10 x 7 squares has 9 x 6
/// inner corners; `chessboard:10x7` finds 54 of 70): empty otherwise.
pub fn squares_hint(cols: u32, rows: u32, square_mm: f64, found: usize) -> String {
    if cols < 3 || rows < 3 || found != ((cols - 1) * (rows - 1)) as usize {
        return String::new();
    }
    format!(
        "{SQUARES_HINT_WORDS} ({cols}x{rows}), not its inner corners: a board of {cols}x{rows} squares has {}x{} inner corners; try chessboard:{}x{}:{square_mm}mm",
        cols - 1,
        rows - 1,
        cols - 1,
        rows - 1
    )
}

/// Finds a chessboard of `cols x rows` inner corners.
pub(crate) fn detect_chessboard(
    img: &GrayF32,
    cols: u32,
    rows: u32,
    square_mm: f64,
    options: &DetectOptions,
    pattern_text: &str,
    mut timings: Option<&mut StageTimings>,
) -> Result<Detection> {
    let t0 = Instant::now();
    let cands = find_xcorners(img, &options.xcorner(), None)?;
    let t1 = Instant::now();
    if let Some(t) = timings.as_deref_mut() {
        StageTimings::add_since(&mut t.candidates_ms, t0);
        t.candidates = cands.len();
    }
    let grids = grow_grids(&cands, 4, 12, 300, (img.width as f64, img.height as f64), Some((cols * rows) as usize));
    let mut best: Option<Labelled> = None;
    let mut largest = 0usize;
    for g in &grids {
        largest = largest.max(g.at.len());
        let Some(l) = label(img, &cands, g, cols, rows) else { continue };
        let better = match &best {
            None => true,
            Some(b) => (l.complete && !b.complete) || (l.complete == b.complete && l.corners.len() > b.corners.len()),
        };
        if better {
            best = Some(l);
        }
        if best.as_ref().is_some_and(|b| b.complete) {
            break;
        }
    }
    if let Some(t) = timings.as_deref_mut() {
        StageTimings::add_since(&mut t.grid_ms, t1);
    }
    let not_found = |reason: String| VisionError::PatternNotFound { pattern: pattern_text.to_string(), reason };
    let Some(lab) = best else {
        return Err(not_found(if grids.is_empty() {
            format!("no grid of X-corners ({} candidates)", cands.len())
        } else {
            format!(
                "the largest grid of X-corners ({largest} corners) does not fit a {cols}x{rows} board{}",
                squares_hint(cols, rows, square_mm, largest)
            )
        }));
    };
    if !lab.complete && !options.partial {
        return Err(not_found(format!(
            "only {} of {} corners visible (partial views are off){}",
            lab.corners.len(),
            rows * cols,
            squares_hint(cols, rows, square_mm, lab.corners.len())
        )));
    }
    let refined = if options.refine {
        refine_chessboard(img, &lab, cols, rows, options, timings)?
    } else {
        vec![None; lab.corners.len()]
    };
    let corners = lab
        .corners
        .iter()
        .zip(refined)
        .map(|(((r, c), p), rc)| {
            let (pos, cov, crb) = match rc {
                Some((q, cov, crb)) => (q, Some(cov), crb),
                None => (Point2::new(p.x, p.y), None, None),
            };
            Corner {
                position_px: pos,
                covariance_px2: cov,
                crb_px2: crb,
                target_m: Some(target_point(cols, rows, square_mm, *r, *c)),
                grid_index: Some([*r, *c]),
                point_id: lab.anchored.then_some(r * cols + c),
            }
        })
        .collect();
    Ok(Detection { id: None, corners, complete: lab.complete, anchored: lab.anchored, circle_radii_m: None })
}

/// Inner corner `(r, c)` of a chessboard in the target frame (origin at the centre, x right,
/// y up as printed, rows from the top), metres.
pub(crate) fn target_point(cols: u32, rows: u32, square_mm: f64, r: u32, c: u32) -> Point3<f64> {
    let square_m = square_mm * 1e-3;
    Point3::new(
        (c as f64 - 0.5 * (cols as f64 - 1.0)) * square_m,
        (0.5 * (rows as f64 - 1.0) - r as f64) * square_m,
        0.0,
    )
}

type Refined = Option<(Point2<f64>, Matrix2<f64>, Option<Matrix2<f64>>)>;

/// Refines labelled corners with the edge model; a corner whose fit fails or moves more than
/// 3 px keeps its coarse position (and no covariance).
pub(crate) fn refine_chessboard(
    img: &GrayF32,
    lab: &Labelled,
    cols: u32,
    rows: u32,
    options: &DetectOptions,
    timings: Option<&mut StageTimings>,
) -> Result<Vec<Refined>> {
    let (fr, fc) = (rows as usize + 1, cols as usize + 1);
    let mut points = vec![None; (fr + 1) * (fc + 1)];
    for ((r, c), p) in &lab.corners {
        points[(*r as usize + 1) * (fc + 1) + *c as usize + 1] = Some(Point2::new(p.x, p.y));
    }
    let grid = CheckerGrid::checkerboard(fr, fc, true, None, points);
    let wanted: Vec<(usize, usize)> =
        lab.corners.iter().map(|((r, c), _)| (*r as usize + 1, *c as usize + 1)).collect();
    let (out, _) = refine_grid_timed(img, &grid, &wanted, &options.refine_options, timings)?;
    Ok(out
        .into_iter()
        .zip(&lab.corners)
        .map(|(rc, (_, p0))| {
            let rc = rc?;
            let d = Vector2::new(rc.position_px.x, rc.position_px.y) - p0;
            (d.norm() <= 3.0).then_some((rc.position_px, rc.covariance_px2, rc.crb_px2))
        })
        .collect())
}

#[cfg(test)]
mod squares_tests {
    use super::squares_hint;

    #[test]
    fn a_board_given_by_its_squares_is_named_only_at_the_inner_corner_count() {
        let h = squares_hint(10, 7, 25.0, 54);
        assert!(h.starts_with(super::SQUARES_HINT_WORDS), "{h}");
        assert!(h.ends_with("a board of 10x7 squares has 9x6 inner corners; try chessboard:9x6:25mm"), "{h}");
        assert_eq!(squares_hint(10, 7, 25.0, 53), "");
        assert_eq!(squares_hint(10, 7, 25.0, 70), "");
        assert_eq!(squares_hint(2, 7, 25.0, 6), "");
        assert!(squares_hint(8, 6, 30.5, 35).contains("try chessboard:7x5:30.5mm"));
    }
}
