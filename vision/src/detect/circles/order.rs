//! The grid order of the dots: a lattice grown from seed dots, a full rectangle, then the
//! board's numbering (see the parent module for the rules and the remaining ambiguity).
//!
//! *Growing.* A seed dot, its nearest neighbour (first axis) and the nearest dot at more than
//! 50 degrees from that axis (second axis) start a lattice. Every empty lattice cell next to a
//! filled one is predicted from the filled cells (two steps along a row or column:
//! `2 p1 - p2`; else a parallelogram `p_a + p_b - p_ab`; else one step with the seed's axis)
//! and takes the nearest unused dot within 0.3 of the local spacing whose radius is within a
//! factor 0.4..2.5 of its neighbour's (the large dot is about twice the others). This is
//! repeated until nothing changes. Seeds are tried in turn (up to 40) until a lattice holds a
//! full `cols x rows` rectangle.

use std::collections::HashMap;

use nalgebra::Vector2;

use super::ellipse::DotFit;
use super::CircleGrid;

/// The dots of a grid in the board's order.
#[derive(Clone, Debug, PartialEq)]
pub struct Ordered {
    /// Index into the fits of dot `k = r cols + c`.
    pub dots: Vec<usize>,
    /// `[small, large]` dot radius over the spacing, from the ellipses' areas over the local
    /// lattice cells (medians; `large` is the origin dot's for a modified grid).
    pub radius_over_spacing: [f64; 2],
}

type Cell = (i32, i32);

fn p(f: &DotFit) -> Vector2<f64> {
    f.centre_px.coords
}

/// Grows a lattice from `seed`; cell -> fit index.
fn grow(fits: &[DotFit], seed: usize, max_cells: usize) -> Option<HashMap<Cell, usize>> {
    let c = p(&fits[seed]);
    let mut near: Vec<(f64, usize)> =
        fits.iter().enumerate().filter(|(k, _)| *k != seed).map(|(k, f)| ((p(f) - c).norm(), k)).collect();
    near.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (d1, n1) = *near.first()?;
    let a = p(&fits[n1]) - c;
    let (_, n2) = *near.iter().take(12).find(|(d, k)| {
        let v = p(&fits[*k]) - c;
        (v.dot(&a) / (v.norm() * d1)).abs() < 0.64 && *d < 2.0 * d1
    })?;
    let b = p(&fits[n2]) - c;
    let mut at: HashMap<Cell, usize> = HashMap::from([((0, 0), seed), ((0, 1), n1), ((1, 0), n2)]);
    let mut used = vec![false; fits.len()];
    for k in [seed, n1, n2] {
        used[k] = true;
    }
    let step_of = |d: Cell| if d.1 != 0 { a * d.1 as f64 } else { b * d.0 as f64 };
    loop {
        let mut added = false;
        let frontier: Vec<Cell> = {
            let mut v: Vec<Cell> = Vec::new();
            for &(i, j) in at.keys() {
                for d in [(0, 1), (0, -1), (1, 0), (-1, 0)] {
                    let q = (i + d.0, j + d.1);
                    if !at.contains_key(&q) && !v.contains(&q) {
                        v.push(q);
                    }
                }
            }
            v.sort();
            v
        };
        for q in frontier {
            let get = |c: Cell| at.get(&c).map(|&k| p(&fits[k]));
            let mut pred = None;
            let mut nb = None;
            for d in [(0, 1), (0, -1), (1, 0), (-1, 0)] {
                let (c1, c2) = ((q.0 - d.0, q.1 - d.1), (q.0 - 2 * d.0, q.1 - 2 * d.1));
                if let (Some(p1), Some(p2)) = (get(c1), get(c2)) {
                    pred = Some((p1 * 2.0 - p2, (p1 - p2).norm()));
                    nb = at.get(&c1).copied();
                    break;
                }
            }
            if pred.is_none() {
                'par: for d1 in [(0, 1), (0, -1)] {
                    for d2 in [(1, 0), (-1, 0)] {
                        let (ca, cb, cab) = (
                            (q.0 - d1.0, q.1 - d1.1),
                            (q.0 - d2.0, q.1 - d2.1),
                            (q.0 - d1.0 - d2.0, q.1 - d1.1 - d2.1),
                        );
                        if let (Some(pa), Some(pb), Some(pab)) = (get(ca), get(cb), get(cab)) {
                            pred = Some((pa + pb - pab, 0.5 * ((pa - pab).norm() + (pb - pab).norm())));
                            nb = at.get(&ca).copied();
                            break 'par;
                        }
                    }
                }
            }
            if pred.is_none() {
                for d in [(0, 1), (0, -1), (1, 0), (-1, 0)] {
                    let c1 = (q.0 - d.0, q.1 - d.1);
                    if let Some(p1) = get(c1) {
                        let s = step_of(d);
                        pred = Some((p1 + s, s.norm()));
                        nb = at.get(&c1).copied();
                        break;
                    }
                }
            }
            let (Some((x, spacing)), Some(nb)) = (pred, nb) else { continue };
            let tol = 0.3 * spacing;
            let best = fits
                .iter()
                .enumerate()
                .filter(|(k, f)| {
                    let ratio = f.radius_px / fits[nb].radius_px;
                    !used[*k] && (p(f) - x).norm() <= tol && (0.4..=2.5).contains(&ratio)
                })
                .min_by(|a, b| (p(a.1) - x).norm().total_cmp(&(p(b.1) - x).norm()));
            if let Some((k, _)) = best {
                used[k] = true;
                at.insert(q, k);
                added = true;
                if at.len() > max_cells {
                    return Some(at);
                }
            }
        }
        if !added {
            return Some(at);
        }
    }
}

/// The full `n_i x n_j` rectangles (top-left cell) inside a lattice.
fn rectangles(at: &HashMap<Cell, usize>, n_i: i32, n_j: i32) -> Vec<Cell> {
    let (i0, i1) = (at.keys().map(|c| c.0).min().unwrap_or(0), at.keys().map(|c| c.0).max().unwrap_or(0));
    let (j0, j1) = (at.keys().map(|c| c.1).min().unwrap_or(0), at.keys().map(|c| c.1).max().unwrap_or(0));
    let mut out = Vec::new();
    for i in i0..=i1 - n_i + 1 {
        for j in j0..=j1 - n_j + 1 {
            if (0..n_i).all(|di| (0..n_j).all(|dj| at.contains_key(&(i + di, j + dj)))) {
                out.push((i, j));
            }
        }
    }
    out
}

/// Orders the dots of `grid`, or says why not.
pub fn order_grid(fits: &[DotFit], grid: &CircleGrid) -> Result<Ordered, String> {
    let n = grid.n_points();
    if fits.len() < n {
        return Err(format!("{} dots found, the grid has {n}", fits.len()));
    }
    let mut radii: Vec<f64> = fits.iter().map(|f| f.radius_px).collect();
    radii.sort_by(f64::total_cmp);
    // Seeds: dots of typical size first (the grid's dots are the most common size).
    let med = radii[radii.len() / 2];
    let mut seeds: Vec<usize> = (0..fits.len()).collect();
    seeds.sort_by(|&a, &b| (fits[a].radius_px / med).ln().abs().total_cmp(&(fits[b].radius_px / med).ln().abs()));
    let mut largest = 0usize;
    let mut last_err = String::new();
    for &seed in seeds.iter().take(40) {
        let Some(at) = grow(fits, seed, 4 * n) else { continue };
        largest = largest.max(at.len());
        if at.len() < n {
            continue;
        }
        if grid.asymmetric {
            match place_asymmetric(fits, &at, grid) {
                Ok(o) => return Ok(o),
                Err(e) => {
                    last_err = e;
                    continue;
                }
            }
        }
        let (c, r) = (grid.cols as i32, grid.rows as i32);
        let mut found = Vec::new();
        for (ni, nj) in [(r, c), (c, r)] {
            for tl in rectangles(&at, ni, nj) {
                found.push((ni, nj, tl));
            }
            if r == c {
                break;
            }
        }
        if found.len() != 1 {
            if found.len() > 1 {
                last_err =
                    format!("the lattice of {} dots holds {} candidate {}x{} grids", at.len(), found.len(), c, r);
            }
            continue;
        }
        let (ni, nj, tl) = found[0];
        let cells: HashMap<Cell, usize> = (0..ni)
            .flat_map(|i| (0..nj).map(move |j| (i, j)))
            .map(|(i, j)| ((i, j), at[&(tl.0 + i, tl.1 + j)]))
            .collect();
        match number(fits, &cells, ni, nj, grid) {
            Ok(o) => return Ok(o),
            Err(e) => last_err = e,
        }
    }
    if last_err.is_empty() {
        Err(format!("the largest lattice holds {largest} dots, a {}x{} grid has {n}", grid.cols, grid.rows))
    } else {
        Err(last_err)
    }
}

/// Numbers a full `ni x nj` rectangle of cells as the board's dots.
fn number(
    fits: &[DotFit],
    cells: &HashMap<Cell, usize>,
    ni: i32,
    nj: i32,
    grid: &CircleGrid,
) -> Result<Ordered, String> {
    let at = |i: i32, j: i32| p(&fits[cells[&(i, j)]]);
    // The 8 symmetries of the rectangle: (r, c) -> cell.
    let (cols, rows) = (grid.cols as i32, grid.rows as i32);
    let mut best: Option<(f64, Vec<usize>)> = None;
    // Radius over spacing per cell, r / s = sqrt(a b / |det[ax, ay]|) from the local lattice
    // cell (perspective makes near dots look larger; this ratio does not change with it).
    let ratio = |i: i32, j: i32| -> f64 {
        let (j0, j1) = (if j > 0 { j - 1 } else { j }, if j + 1 < nj { j + 1 } else { j });
        let (i0, i1) = (if i > 0 { i - 1 } else { i }, if i + 1 < ni { i + 1 } else { i });
        let ax = (at(i, j1) - at(i, j0)) / (j1 - j0) as f64;
        let ay = (at(i1, j) - at(i0, j)) / (i1 - i0) as f64;
        let area = (ax.x * ay.y - ax.y * ay.x).abs().max(1e-9);
        let (a, b) = fits[cells[&(i, j)]].ellipse.semi_axes_px();
        (a * b / area).sqrt()
    };
    let ratios: HashMap<Cell, f64> = cells.keys().map(|&(i, j)| ((i, j), ratio(i, j))).collect();
    let mut big = None;
    if grid.modified {
        let mut rs: Vec<f64> = ratios.values().copied().collect();
        rs.sort_by(f64::total_cmp);
        let med = rs[rs.len() / 2];
        let large: Vec<Cell> = ratios.iter().filter(|(_, &r)| r > 1.4 * med).map(|(c, _)| *c).collect();
        if large.len() != 1 {
            return Err(format!("a modified grid needs one large dot, found {}", large.len()));
        }
        big = Some(large[0]);
    }
    for transpose in [false, true] {
        for flip_i in [false, true] {
            for flip_j in [false, true] {
                let map = |r: i32, c: i32| -> Option<Cell> {
                    let (mut i, mut j) = if transpose { (c, r) } else { (r, c) };
                    if flip_i {
                        i = ni - 1 - i;
                    }
                    if flip_j {
                        j = nj - 1 - j;
                    }
                    (i >= 0 && j >= 0 && i < ni && j < nj).then_some((i, j))
                };
                let (ci, cj) = if transpose { (cols, rows) } else { (rows, cols) };
                if (ci, cj) != (ni, nj) {
                    continue;
                }
                let cell = |r: i32, c: i32| map(r, c).expect("inside");
                // Mean axis vectors in the image.
                let (mut ax, mut ay) = (Vector2::zeros(), Vector2::zeros());
                for r in 0..rows {
                    for c in 0..cols {
                        let q = cell(r, c);
                        if c + 1 < cols {
                            let q2 = cell(r, c + 1);
                            ax += at(q2.0, q2.1) - at(q.0, q.1);
                        }
                        if r + 1 < rows {
                            let q2 = cell(r + 1, c);
                            ay += at(q2.0, q2.1) - at(q.0, q.1);
                        }
                    }
                }
                // Seen from the printed side: x turned towards y turns clockwise in the image.
                if ax.x * ay.y - ax.y * ay.x >= 0.0 {
                    continue;
                }
                if let Some(b) = big {
                    if cell(0, 0) != b {
                        continue;
                    }
                }
                let upright = ax.x / ax.norm().max(1e-12) - ay.y / ay.norm().max(1e-12);
                let dots: Vec<usize> =
                    (0..rows).flat_map(|r| (0..cols).map(move |c| (r, c))).map(|(r, c)| cells[&cell(r, c)]).collect();
                if best.as_ref().is_none_or(|(u, _)| upright > *u) {
                    best = Some((upright, dots));
                }
            }
        }
    }
    let Some((_, dots)) = best else {
        return Err(if big.is_some() {
            format!(
                "the large dot is not at the corner where a {}x{} grid seen from its printed side starts (is it {}x{}?)",
                cols, rows, rows, cols
            )
        } else {
            format!("no numbering of the {}x{} dots is seen from the printed side", cols, rows)
        });
    };
    let cell_of: HashMap<usize, Cell> = cells.iter().map(|(c, &k)| (k, *c)).collect();
    let ratio = |r: i32, c: i32| ratios[&cell_of[&dots[(r * cols + c) as usize]]];
    let mut small: Vec<f64> = Vec::new();
    for r in 0..rows {
        for c in 0..cols {
            if !(grid.modified && r == 0 && c == 0) {
                small.push(ratio(r, c));
            }
        }
    }
    small.sort_by(f64::total_cmp);
    let s = small[small.len() / 2];
    let l = if grid.modified { ratio(0, 0) } else { s };
    Ok(Ordered { dots, radius_over_spacing: [s, l] })
}

/// The doubled coordinates `(2 c + r mod 2, r)` of an asymmetric grid's dot `k = r cols + c`.
fn asymmetric_xy(grid: &CircleGrid, k: usize) -> (i32, i32) {
    let (r, c) = ((k as u32 / grid.cols) as i32, (k as u32 % grid.cols) as i32);
    (2 * c + r % 2, r)
}

/// Places an asymmetric grid on a grown lattice. The dots of an asymmetric grid are the points
/// `(x, y)` with `x + y` even of a square lattice of step `s` (OpenCV's `squareSize`); the
/// grown lattice's two axes are two of that lattice's short vectors (a diagonal neighbour at
/// `sqrt 2 s`, or a row or column neighbour at `2 s` when a tilt foreshortens the diagonals),
/// so every pair of them that spans it (area 2) is tried, every translation that puts the
/// whole grid on dots is kept, and of the numberings left the one seen from the printed side
/// (x turned towards y turns clockwise in the image, as OpenCV numbers the grid) is taken; a
/// grid with an even number of rows looks the same after a half turn, and then the numbering
/// whose x axis points most to the right is taken.
fn place_asymmetric(fits: &[DotFit], at: &HashMap<Cell, usize>, grid: &CircleGrid) -> Result<Ordered, String> {
    let n = grid.n_points();
    let pattern: Vec<(i32, i32)> = (0..n).map(|k| asymmetric_xy(grid, k)).collect();
    const SHORT: [(i32, i32); 8] = [(1, 1), (1, -1), (-1, 1), (-1, -1), (2, 0), (-2, 0), (0, 2), (0, -2)];
    let mut placements: Vec<Vec<usize>> = Vec::new();
    for a in SHORT {
        for b in SHORT {
            if (a.0 * b.1 - a.1 * b.0).abs() != 2 {
                continue;
            }
            let mapped: HashMap<(i32, i32), usize> =
                at.iter().map(|(&(u, v), &f)| ((u * a.0 + v * b.0, u * a.1 + v * b.1), f)).collect();
            for &t in mapped.keys() {
                let dots: Option<Vec<usize>> =
                    pattern.iter().map(|&(x, y)| mapped.get(&(x + t.0, y + t.1)).copied()).collect();
                if let Some(d) = dots {
                    if !placements.contains(&d) {
                        placements.push(d);
                    }
                }
            }
        }
    }
    if placements.is_empty() {
        return Err(format!(
            "the lattice of {} dots holds no {}x{} asymmetric grid (are cols and rows swapped?)",
            at.len(),
            grid.cols,
            grid.rows
        ));
    }
    let mut seen: Vec<Vec<usize>> = placements.iter().map(|d| sorted(d)).collect();
    seen.dedup();
    if seen.len() > 1 {
        return Err(format!(
            "the lattice of {} dots holds {} candidate {}x{} asymmetric grids",
            at.len(),
            seen.len(),
            grid.cols,
            grid.rows
        ));
    }
    let index: HashMap<(i32, i32), usize> = pattern.iter().enumerate().map(|(k, &xy)| (xy, k)).collect();
    let mut best: Option<(f64, Vec<usize>)> = None;
    for dots in placements {
        let (ax, ay) = mean_axes(fits, &dots, &pattern, &index);
        if ax.x * ay.y - ax.y * ay.x <= 0.0 {
            continue;
        }
        let upright = ax.x / ax.norm().max(1e-12) + ay.y / ay.norm().max(1e-12);
        if best.as_ref().is_none_or(|(u, _)| upright > *u) {
            best = Some((upright, dots));
        }
    }
    let (_, dots) =
        best.ok_or_else(|| "no numbering of the asymmetric grid is seen from the printed side".to_string())?;
    let mut ratios: Vec<f64> = (0..n).map(|k| radius_over_step(fits, &dots, &pattern, &index, k)).collect();
    ratios.sort_by(f64::total_cmp);
    let r = ratios[n / 2];
    Ok(Ordered { dots, radius_over_spacing: [r, r] })
}

fn sorted(v: &[usize]) -> Vec<usize> {
    let mut s = v.to_vec();
    s.sort_unstable();
    s
}

/// Mean image vectors of one step `s` along the grid's x and y axes.
fn mean_axes(
    fits: &[DotFit],
    dots: &[usize],
    pattern: &[(i32, i32)],
    index: &HashMap<(i32, i32), usize>,
) -> (Vector2<f64>, Vector2<f64>) {
    let (mut ax, mut ay) = (Vector2::zeros(), Vector2::zeros());
    for (k, &(x, y)) in pattern.iter().enumerate() {
        if let Some(&j) = index.get(&(x + 2, y)) {
            ax += p(&fits[dots[j]]) - p(&fits[dots[k]]);
        }
        if let Some(&j) = index.get(&(x + 1, y + 1)) {
            ay += p(&fits[dots[j]]) - p(&fits[dots[k]]);
        }
        if let Some(&j) = index.get(&(x - 1, y + 1)) {
            ay += p(&fits[dots[j]]) - p(&fits[dots[k]]);
        }
    }
    (ax, ay)
}

/// A dot's radius over the step `s`, from its ellipse's area over the local image area of one
/// `s x s` cell (the 2 x 2 map from grid to image fitted to its neighbours' offsets).
fn radius_over_step(
    fits: &[DotFit],
    dots: &[usize],
    pattern: &[(i32, i32)],
    index: &HashMap<(i32, i32), usize>,
    k: usize,
) -> f64 {
    let (x, y) = pattern[k];
    let (mut img_grid, mut grid_grid) = (nalgebra::Matrix2::<f64>::zeros(), nalgebra::Matrix2::<f64>::zeros());
    for d in [(2, 0), (-2, 0), (1, 1), (-1, 1), (1, -1), (-1, -1)] {
        if let Some(&j) = index.get(&(x + d.0, y + d.1)) {
            let di = p(&fits[dots[j]]) - p(&fits[dots[k]]);
            let dg = Vector2::new(d.0 as f64, d.1 as f64);
            img_grid += di * dg.transpose();
            grid_grid += dg * dg.transpose();
        }
    }
    let area = grid_grid.try_inverse().map(|inv| (img_grid * inv).determinant().abs()).unwrap_or(f64::NAN);
    let (a, b) = fits[dots[k]].ellipse.semi_axes_px();
    (a * b / area.max(1e-9)).sqrt()
}
