//! The Gantry-Tau plate: five black squares, the dark fields of a 3 x 3 checkerboard (four
//! corners and the centre; 20 sides, 16 distinct corner points).
//!
//! After Dressler (2012, 5.5), in this project's terms:
//! 1. *Background* (optional): the per-pixel median of a sequence ([`crate::detect::median_background`])
//!    is subtracted; candidates are kept only where the frame differs from it (the plate
//!    moves, the scene does not).
//! 2. *Square candidates from spatial derivatives*: the centre square shares its four corners
//!    with the outer squares, so they are X-corners (saddles of the second derivatives,
//!    validated on circles); candidates are grown into grids and every isolated 2 x 2 grid whose
//!    cell is dark is a centre-square candidate.
//! 3. *Validation by the edges*: the plate hypothesised from the candidate (a homography from
//!    the centre square to the 3 x 3 layout) must show the nine fields with the right shades,
//!    a light surround where a chessboard would continue dark, and the edges of all 20 sides
//!    must be found by the sub-pixel fit (at least 12 of the 16 corner points).
//! 4. *Sub-pixel location of all 20 sides* by [`crate::subpix::refine_grid`] (eight lines; each
//!    corner from the two sides that meet there).
//!
//! The plate is symmetric under quarter turns, so its labelling follows the image: square 0 is
//! the outer square at the image's top-left (rows of squares top to bottom as the image is
//! read), corners of each square top-left, top-right, bottom-right, bottom-left, as in
//! `ferrocal_datasets`' renderer for an upright plate.

use image::GrayImage;
use nalgebra::{Matrix3, Point2, Point3, Vector2, Vector3};

use super::grid::{cell_mean, grow_grids};
use super::image::GrayF32;
use super::xcorner::find_xcorners;
use super::{Corner, DetectOptions, Detection};
use crate::error::{Result, VisionError};
use crate::subpix::{refine_grid, CheckerGrid};

/// Homography mapping the four `src` points to `dst` (DLT on exactly four points).
pub(crate) fn homography4(src: &[Vector2<f64>; 4], dst: &[Vector2<f64>; 4]) -> Option<Matrix3<f64>> {
    let mut a = nalgebra::SMatrix::<f64, 8, 8>::zeros();
    let mut b = nalgebra::SVector::<f64, 8>::zeros();
    for k in 0..4 {
        let (x, y) = (src[k].x, src[k].y);
        let (u, v) = (dst[k].x, dst[k].y);
        let r = 2 * k;
        a.set_row(r, &nalgebra::RowSVector::<f64, 8>::from_row_slice(&[x, y, 1.0, 0.0, 0.0, 0.0, -u * x, -u * y]));
        a.set_row(r + 1, &nalgebra::RowSVector::<f64, 8>::from_row_slice(&[0.0, 0.0, 0.0, x, y, 1.0, -v * x, -v * y]));
        b[r] = u;
        b[r + 1] = v;
    }
    let h = a.lu().solve(&b)?;
    Some(Matrix3::new(h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], 1.0))
}

pub(crate) fn apply_h(h: &Matrix3<f64>, x: f64, y: f64) -> Vector2<f64> {
    let v = h * Vector3::new(x, y, 1.0);
    Vector2::new(v.x / v.z, v.y / v.z)
}

/// Foreground test from a background image: a pixel is foreground when the frame differs from
/// the background by more than `thresh` DN; a candidate is kept when at least 3 % of the pixels
/// within 12 px are foreground.
fn foreground(img: &GrayF32, bg: &GrayImage) -> Result<impl Fn(f64, f64) -> bool> {
    if bg.width() as usize != img.width || bg.height() as usize != img.height {
        return Err(VisionError::BadImage {
            reason: format!("background is {}x{}, image is {}x{}", bg.width(), bg.height(), img.width, img.height),
        });
    }
    let (w, h) = (img.width, img.height);
    let diff: Vec<f32> = img.data.iter().zip(bg.as_raw()).map(|(a, b)| (a - f32::from(*b)).abs()).collect();
    let mut sorted: Vec<f32> = diff.iter().step_by(7).copied().collect();
    sorted.sort_by(f32::total_cmp);
    let median = f64::from(sorted[sorted.len() / 2]);
    let thresh = (4.0 * 1.4826 * median).max(10.0);
    // Integral image of the foreground mask.
    let mut integ = vec![0u32; (w + 1) * (h + 1)];
    for y in 0..h {
        let mut row = 0u32;
        for x in 0..w {
            row += u32::from(f64::from(diff[y * w + x]) > thresh);
            integ[(y + 1) * (w + 1) + x + 1] = integ[y * (w + 1) + x + 1] + row;
        }
    }
    Ok(move |x: f64, y: f64| {
        let r = 12.0;
        let x0 = (x - r).floor().clamp(0.0, w as f64) as usize;
        let x1 = (x + r).ceil().clamp(0.0, w as f64) as usize;
        let y0 = (y - r).floor().clamp(0.0, h as f64) as usize;
        let y1 = (y + r).ceil().clamp(0.0, h as f64) as usize;
        let area = ((x1 - x0) * (y1 - y0)).max(1) as f64;
        let s =
            integ[y1 * (w + 1) + x1] + integ[y0 * (w + 1) + x0] - integ[y0 * (w + 1) + x1] - integ[y1 * (w + 1) + x0];
        f64::from(s) / area >= 0.03
    })
}

/// The plate's 16 grid points `(i, j)`, `i, j = 0..=3`, row by row, from a hypothesis.
type PlateGrid = [[Vector2<f64>; 4]; 4];

fn validate(img: &GrayF32, g: &PlateGrid, min_contrast: f64) -> Option<f64> {
    let mut dark = Vec::new();
    let mut light = Vec::new();
    for r in 0..3 {
        for c in 0..3 {
            let m = cell_mean(img, g[r][c], g[r][c + 1], g[r + 1][c], g[r + 1][c + 1]);
            if (r + c) % 2 == 0 {
                dark.push(m);
            } else {
                light.push(m);
            }
        }
    }
    let dmax = dark.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let lmin = light.iter().copied().fold(f64::INFINITY, f64::min);
    let dmean = dark.iter().sum::<f64>() / dark.len() as f64;
    let lmean = light.iter().sum::<f64>() / light.len() as f64;
    let mid = 0.5 * (dmean + lmean);
    if lmean - dmean < min_contrast || dmax > mid || lmin < mid {
        return None;
    }
    Some(lmean - dmean)
}

/// Finds every plate in the image (strongest first).
pub(crate) fn detect_plates(
    img: &GrayF32,
    square_mm: f64,
    background: Option<&GrayImage>,
    options: &DetectOptions,
    pattern_text: &str,
) -> Result<Vec<Detection>> {
    let cands = match background {
        Some(bg) => {
            let keep = foreground(img, bg)?;
            find_xcorners(img, &options.xcorner(), Some(&keep))?
        }
        None => find_xcorners(img, &options.xcorner(), None)?,
    };
    let grids = grow_grids(&cands, 4, 64, 800, (img.width as f64, img.height as f64), None);
    let (w, h) = (img.width as f64, img.height as f64);
    let mut found: Vec<(f64, Detection)> = Vec::new();
    let mut rejected = 0usize;
    for g in grids.iter().filter(|g| g.rows == 2 && g.cols == 2 && g.at.len() == 4) {
        let p = |q| g.point(&cands, q).expect("complete 2x2 grid");
        let (p00, mut p01, mut p10, p11) = (p((0, 0)), p((0, 1)), p((1, 0)), p((1, 1)));
        let (a, b) = (p01 - p00, p10 - p00);
        if a.x * b.y - a.y * b.x < 0.0 {
            std::mem::swap(&mut p01, &mut p10);
        }
        let unit = [Vector2::new(1.0, 1.0), Vector2::new(2.0, 1.0), Vector2::new(1.0, 2.0), Vector2::new(2.0, 2.0)];
        let Some(hm) = homography4(&unit, &[p00, p01, p10, p11]) else { continue };
        let mut grid: PlateGrid = [[Vector2::zeros(); 4]; 4];
        for (i, row) in grid.iter_mut().enumerate() {
            for (j, q) in row.iter_mut().enumerate() {
                *q = apply_h(&hm, j as f64, i as f64);
            }
        }
        if grid.iter().flatten().any(|q| q.x < 0.0 || q.y < 0.0 || q.x > w - 1.0 || q.y > h - 1.0) {
            rejected += 1;
            continue;
        }
        let Some(contrast) = validate(img, &grid, options.min_contrast_dn) else {
            rejected += 1;
            continue;
        };
        // A chessboard would continue with dark fields next to the light ones; the plate has
        // its light surround there.
        let mid_dark = cell_mean(img, grid[1][1], grid[1][2], grid[2][1], grid[2][2]);
        let surround = [(1.5, -0.15), (-0.15, 1.5), (1.5, 3.15), (3.15, 1.5)];
        let too_dark = surround.iter().filter(|(x, y)| {
            let q = apply_h(&hm, *x, *y);
            q.x >= 0.0
                && q.y >= 0.0
                && q.x <= w - 1.0
                && q.y <= h - 1.0
                && img.bilinear(q.x, q.y) < mid_dark + 0.5 * contrast
        });
        if too_dark.count() > 0 {
            rejected += 1;
            continue;
        }
        // Label upright: the rotation whose column axis points most to the right and whose
        // row axis points most down.
        let rot = |k: usize, i: usize, j: usize| -> (usize, usize) {
            match k {
                0 => (i, j),
                1 => (j, 3 - i),
                2 => (3 - i, 3 - j),
                _ => (3 - j, i),
            }
        };
        let best_k = (0..4)
            .max_by(|&k1, &k2| {
                let score = |k: usize| {
                    let at = |i, j| {
                        let (a, b) = rot(k, i, j);
                        grid[a][b]
                    };
                    let cx = at(0, 3) - at(0, 0) + at(3, 3) - at(3, 0);
                    let ry = at(3, 0) - at(0, 0) + at(3, 3) - at(0, 3);
                    cx.x / cx.norm() + ry.y / ry.norm()
                };
                score(k1).total_cmp(&score(k2))
            })
            .unwrap_or(0);
        let mut lab: PlateGrid = [[Vector2::zeros(); 4]; 4];
        for (i, row) in lab.iter_mut().enumerate() {
            for (j, q) in row.iter_mut().enumerate() {
                let (a, b) = rot(best_k, i, j);
                *q = grid[a][b];
            }
        }
        let wanted: Vec<(usize, usize)> = (0..4).flat_map(|i| (0..4).map(move |j| (i, j))).collect();
        let mut refined = vec![None; 16];
        if options.refine {
            let points = wanted.iter().map(|&(i, j)| Some(Point2::new(lab[i][j].x, lab[i][j].y))).collect();
            let mut cg = CheckerGrid::checkerboard(3, 3, true, Some(false), points);
            cg.outside_width_fraction = 0.3;
            let (out, _) = refine_grid(img, &cg, &wanted, &options.refine_options)?;
            let ok = out.iter().filter(|c| c.is_some()).count();
            if ok < 12 {
                rejected += 1;
                continue;
            }
            refined = out;
        }
        let s = square_mm * 1e-3;
        let mut corners = Vec::with_capacity(20);
        for (r, c) in [(0usize, 0usize), (0, 2), (1, 1), (2, 0), (2, 2)] {
            for (i, j) in [(r, c), (r, c + 1), (r + 1, c + 1), (r + 1, c)] {
                let k = i * 4 + j;
                let target = Point3::new((j as f64 - 1.5) * s, (1.5 - i as f64) * s, 0.0);
                let c = match &refined[k] {
                    Some(rc) => Corner {
                        position_px: rc.position_px,
                        covariance_px2: Some(rc.covariance_px2),
                        crb_px2: rc.crb_px2,
                        target_m: Some(target),
                        grid_index: Some([i as u32, j as u32]),
                        point_id: None,
                    },
                    None => Corner {
                        position_px: Point2::new(lab[i][j].x, lab[i][j].y),
                        covariance_px2: None,
                        crb_px2: None,
                        target_m: Some(target),
                        grid_index: Some([i as u32, j as u32]),
                        point_id: None,
                    },
                };
                corners.push(c);
            }
        }
        found.push((contrast, Detection { id: None, corners, complete: true, anchored: true, circle_radii_m: None }));
    }
    if found.is_empty() {
        return Err(VisionError::PatternNotFound {
            pattern: pattern_text.to_string(),
            reason: format!(
                "{} X-corner candidates, {} centre-square hypotheses rejected by the field shades or the edges",
                cands.len(),
                rejected
            ),
        });
    }
    found.sort_by(|a, b| b.0.total_cmp(&a.0));
    Ok(found.into_iter().map(|f| f.1).collect())
}
