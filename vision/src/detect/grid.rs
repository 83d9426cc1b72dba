//! Growing a grid of X-corners: seeds from a candidate and its neighbours along its two edge
//! lines, then repeated prediction of the next grid position (linear extrapolation along
//! rows and columns, mid-points, parallelograms) and acceptance of the nearest unused
//! candidate whose edge directions agree with the local grid.

use std::collections::HashMap;

use nalgebra::Vector2;

use super::image::GrayF32;
use super::xcorner::XCorner;

/// Grid position `(i, j)`: `i` along the second axis ("rows"), `j` along the first.
pub(crate) type Pos = (i32, i32);

/// A grown grid: candidate index per position, indices normalised to start at 0.
#[derive(Clone, Debug)]
pub(crate) struct Grid {
    pub at: HashMap<Pos, usize>,
    pub rows: i32,
    pub cols: i32,
}

impl Grid {
    pub fn point(&self, cands: &[XCorner], q: Pos) -> Option<Vector2<f64>> {
        self.at.get(&q).map(|&k| cands[k].p)
    }
}

pub(crate) struct Buckets {
    cell: f64,
    map: HashMap<(i32, i32), Vec<usize>>,
}

impl Buckets {
    pub(crate) fn new(cands: &[XCorner], cell: f64) -> Self {
        let mut map: HashMap<(i32, i32), Vec<usize>> = HashMap::new();
        for (k, c) in cands.iter().enumerate() {
            map.entry(((c.p.x / cell).floor() as i32, (c.p.y / cell).floor() as i32)).or_default().push(k);
        }
        Self { cell, map }
    }

    fn near(&self, p: Vector2<f64>, r: f64) -> impl Iterator<Item = usize> + '_ {
        let (x0, x1) = (((p.x - r) / self.cell).floor() as i32, ((p.x + r) / self.cell).floor() as i32);
        let (y0, y1) = (((p.y - r) / self.cell).floor() as i32, ((p.y + r) / self.cell).floor() as i32);
        (y0..=y1).flat_map(move |y| (x0..=x1).flat_map(move |x| self.map.get(&(x, y)).into_iter().flatten().copied()))
    }
}

const COS_TOL: f64 = 0.94; // cos(20 deg)

fn aligned(c: &XCorner, v: Vector2<f64>) -> bool {
    let n = v.norm();
    n > 0.0 && c.dirs.iter().any(|d| (d.dot(&v) / n).abs() >= COS_TOL)
}

/// Whether two candidates have a similar contrast (within a factor of two): the corners of one
/// board are lit alike, clutter is not.
fn similar(a: &XCorner, b: &XCorner) -> bool {
    a.contrast <= 2.0 * b.contrast && b.contrast <= 2.0 * a.contrast
}

/// The nearest candidate from `c` along `ray` (unit) whose own lines include that direction.
fn ray_neighbour(cands: &[XCorner], k: usize, ray: Vector2<f64>, max_dist: f64) -> Option<usize> {
    let c = &cands[k];
    let mut best: Option<(usize, f64)> = None;
    for (m, o) in cands.iter().enumerate() {
        if m == k {
            continue;
        }
        let v = o.p - c.p;
        let d = v.norm();
        if d < 4.0 || d > max_dist {
            continue;
        }
        if v.dot(&ray) / d < COS_TOL || !aligned(o, v) || !similar(c, o) {
            continue;
        }
        if best.is_none_or(|(_, bd)| d < bd) {
            best = Some((m, d));
        }
    }
    best.map(|(m, _)| m)
}

/// A grid under construction: `rows x cols` cells of optional candidate indices.
struct Work {
    rows: usize,
    cols: usize,
    cells: Vec<Option<usize>>,
}

impl Work {
    fn get(&self, i: usize, j: usize) -> Option<usize> {
        self.cells[i * self.cols + j]
    }
}

/// The seed: the candidate, its neighbours along both lines, and the diagonal corners found
/// by the parallelogram rule; 3 x 3 when the candidate has neighbours on all four sides,
/// otherwise 2 x 2.
fn seed_grid(
    cands: &[XCorner],
    buckets: &Buckets,
    seed: usize,
    used: &[bool],
    max_dist: f64,
    allow_small: bool,
) -> Option<Work> {
    let c = &cands[seed];
    let mut nb = [[None; 2]; 2];
    for (slot, dir) in nb.iter_mut().zip(c.dirs) {
        for (s, sign) in [(0, 1.0), (1, -1.0)] {
            slot[s] = ray_neighbour(cands, seed, dir * sign, max_dist).filter(|&k| !used[k]);
        }
    }
    let diag = |p: Vector2<f64>, q: Vector2<f64>, taken: &[usize]| -> Option<usize> {
        let pred = p + q - c.p;
        let sp = 0.5 * ((p - c.p).norm() + (q - c.p).norm());
        nearest(cands, buckets, pred, 0.3 * sp, used, taken)
    };
    let full = nb.iter().all(|a| a.iter().all(|k| k.is_some()));
    if full {
        let (l, r, u, d) = (nb[0][1]?, nb[0][0]?, nb[1][1]?, nb[1][0]?);
        let mut taken = vec![seed, l, r, u, d];
        let corner = |p: usize, q: usize, taken: &mut Vec<usize>| {
            let k = diag(cands[p].p, cands[q].p, taken);
            if let Some(k) = k {
                taken.push(k);
            }
            k
        };
        let ul = corner(u, l, &mut taken);
        let ur = corner(u, r, &mut taken);
        let dl = corner(d, l, &mut taken);
        let dr = corner(d, r, &mut taken);
        if let (Some(ul), Some(ur), Some(dl), Some(dr)) = (ul, ur, dl, dr) {
            return Some(Work {
                rows: 3,
                cols: 3,
                cells: vec![Some(ul), Some(u), Some(ur), Some(l), Some(seed), Some(r), Some(dl), Some(d), Some(dr)],
            });
        }
    }
    if !allow_small {
        return None;
    }
    // 2 x 2 from the nearer neighbour on each line, at similar distances.
    let dist = |k: usize| (cands[k].p - c.p).norm();
    let pick = |pair: [Option<usize>; 2]| match pair {
        [Some(x), Some(y)] => Some(if dist(x) <= dist(y) { x } else { y }),
        [x, y] => x.or(y),
    };
    let a = pick(nb[0])?;
    let b = pick(nb[1])?;
    if a == b || dist(a) > 2.0 * dist(b) || dist(b) > 2.0 * dist(a) {
        return None;
    }
    let d = diag(cands[a].p, cands[b].p, &[seed, a, b])?;
    Some(Work { rows: 2, cols: 2, cells: vec![Some(seed), Some(a), Some(b), Some(d)] })
}

/// The nearest unused candidate within `radius` of `p`, not in `taken`.
fn nearest(
    cands: &[XCorner],
    buckets: &Buckets,
    p: Vector2<f64>,
    radius: f64,
    used: &[bool],
    taken: &[usize],
) -> Option<usize> {
    let mut best: Option<(usize, f64)> = None;
    for m in buckets.near(p, radius) {
        if used[m] || taken.contains(&m) {
            continue;
        }
        let d = (cands[m].p - p).norm();
        if d <= radius && similar(&cands[m], &cands[taken[0]]) && best.is_none_or(|(_, bd)| d < bd) {
            best = Some((m, d));
        }
    }
    best.map(|b| b.0)
}

/// Proposes a new line of the grid beyond one side: per position, the linear extrapolation
/// from the two nearest points of its column (or row), and the nearest suitable candidate.
/// Returns the line (with holes) when at least 75 % of the predictions inside the image are
/// found, and at least two.
fn propose(
    cands: &[XCorner],
    buckets: &Buckets,
    w: &Work,
    side: usize,
    used: &[bool],
    in_taken: &std::collections::HashSet<usize>,
    size: (f64, f64),
) -> Option<Vec<Option<usize>>> {
    // side 0: before row 0; 1: after the last row; 2: before col 0; 3: after the last col.
    let along = if side < 2 { w.cols } else { w.rows };
    let depth = if side < 2 { w.rows } else { w.cols };
    let at = |k: usize, d: usize| -> Option<usize> {
        // d = distance from the side (0 = outermost line).
        match side {
            0 => w.get(d, k),
            1 => w.get(w.rows - 1 - d, k),
            2 => w.get(k, d),
            _ => w.get(k, w.cols - 1 - d),
        }
    };
    let mut line = vec![None; along];
    let mut inside = 0usize;
    let mut found = 0usize;
    let mut taken: Vec<usize> = Vec::new();
    for k in 0..along {
        let pts: Vec<(usize, Vector2<f64>)> =
            (0..depth).filter_map(|d| at(k, d).map(|c| (d, cands[c].p))).take(2).collect();
        if pts.len() < 2 {
            continue;
        }
        let ((d0, p0), (d1, p1)) = (pts[0], pts[1]);
        let step = (p0 - p1) / (d1 - d0) as f64;
        let pred = p0 + step * (d0 as f64 + 1.0);
        let sp = step.norm();
        let margin = 0.3 * sp;
        if pred.x < margin || pred.y < margin || pred.x > size.0 - 1.0 - margin || pred.y > size.1 - 1.0 - margin {
            continue;
        }
        inside += 1;
        // Candidates near the prediction whose lines follow the grid.
        let neighbour_along = [k.checked_sub(1), Some(k + 1)]
            .into_iter()
            .flatten()
            .filter(|&kk| kk < along)
            .find_map(|kk| at(kk, d0).map(|c| cands[c].p - p0));
        let mut best: Option<(usize, f64)> = None;
        for m in buckets.near(pred, 0.3 * sp) {
            if used[m] || in_taken.contains(&m) || taken.contains(&m) {
                continue;
            }
            let d = (cands[m].p - pred).norm();
            if d > 0.3 * sp {
                continue;
            }
            let v = cands[m].p - p0;
            if !aligned(&cands[m], v)
                || !neighbour_along.is_none_or(|a| aligned(&cands[m], a))
                || !similar(&cands[m], &cands[at(k, d0).unwrap_or(m)])
            {
                continue;
            }
            // Step length consistent with the column's.
            let ratio = v.norm() / (sp * (d0 as f64 + 1.0));
            if !(0.6..=1.5).contains(&ratio) {
                continue;
            }
            if best.is_none_or(|(_, bd)| d < bd) {
                best = Some((m, d));
            }
        }
        if let Some((m, _)) = best {
            line[k] = Some(m);
            taken.push(m);
            found += 1;
        }
    }
    (found >= 2 && found * 4 >= inside * 3).then_some(line)
}

fn add_line(w: &mut Work, side: usize, line: Vec<Option<usize>>) {
    match side {
        0 | 1 => {
            let mut cells = Vec::with_capacity((w.rows + 1) * w.cols);
            if side == 0 {
                cells.extend(line);
                cells.extend(w.cells.iter().copied());
            } else {
                cells.extend(w.cells.iter().copied());
                cells.extend(line);
            }
            w.cells = cells;
            w.rows += 1;
        }
        _ => {
            let mut cells = Vec::with_capacity(w.rows * (w.cols + 1));
            for (i, new) in line.iter().enumerate().take(w.rows) {
                if side == 2 {
                    cells.push(*new);
                }
                cells.extend(w.cells[i * w.cols..(i + 1) * w.cols].iter().copied());
                if side == 3 {
                    cells.push(*new);
                }
            }
            w.cells = cells;
            w.cols += 1;
        }
    }
}

/// Removes outer lines that are much emptier than the fullest parallel line (a line added
/// while the grid was still small can turn out to be clutter once the grid has grown).
fn prune(w: &mut Work) {
    loop {
        let row_count = |w: &Work, i: usize| (0..w.cols).filter(|&j| w.get(i, j).is_some()).count();
        let col_count = |w: &Work, j: usize| (0..w.rows).filter(|&i| w.get(i, j).is_some()).count();
        let max_row = (0..w.rows).map(|i| row_count(w, i)).max().unwrap_or(0);
        let max_col = (0..w.cols).map(|j| col_count(w, j)).max().unwrap_or(0);
        let sparse = |n: usize, max: usize| (n as f64) < 0.6 * max as f64;
        if w.rows > 2 && sparse(row_count(w, 0), max_row) {
            w.cells.drain(0..w.cols);
            w.rows -= 1;
        } else if w.rows > 2 && sparse(row_count(w, w.rows - 1), max_row) {
            w.cells.truncate((w.rows - 1) * w.cols);
            w.rows -= 1;
        } else if w.cols > 2 && (sparse(col_count(w, 0), max_col) || sparse(col_count(w, w.cols - 1), max_col)) {
            let drop = if sparse(col_count(w, 0), max_col) { 0 } else { w.cols - 1 };
            let cells = (0..w.rows)
                .flat_map(|i| (0..w.cols).filter(move |&j| j != drop).map(move |j| (i, j)))
                .map(|(i, j)| w.get(i, j))
                .collect();
            w.cells = cells;
            w.cols -= 1;
        } else {
            return;
        }
    }
}

/// Grows one grid from seed candidate `seed`, a whole line at a time on the side where the
/// most predicted corners are found; `used` marks candidates already in a grid.
pub(crate) fn grow(
    cands: &[XCorner],
    buckets: &Buckets,
    seed: usize,
    used: &[bool],
    max_dist: f64,
    size: (f64, f64),
    allow_small: bool,
) -> Option<Grid> {
    let mut w = seed_grid(cands, buckets, seed, used, max_dist, allow_small)?;
    loop {
        let taken: std::collections::HashSet<usize> = w.cells.iter().flatten().copied().collect();
        let mut best: Option<(usize, usize, Vec<Option<usize>>)> = None;
        for side in 0..4 {
            if let Some(line) = propose(cands, buckets, &w, side, used, &taken, size) {
                let n = line.iter().flatten().count();
                if best.as_ref().is_none_or(|b| n > b.1) {
                    best = Some((side, n, line));
                }
            }
        }
        match best {
            Some((side, _, line)) => add_line(&mut w, side, line),
            None => break,
        }
        if w.rows * w.cols > 100_000 {
            break;
        }
    }
    prune(&mut w);
    if w.rows < 2 || w.cols < 2 {
        return None;
    }
    let mut at = HashMap::new();
    for i in 0..w.rows {
        for j in 0..w.cols {
            if let Some(k) = w.get(i, j) {
                at.insert((i as i32, j as i32), k);
            }
        }
    }
    Some(Grid { at, rows: w.rows as i32, cols: w.cols as i32 })
}

/// Grows grids from the strongest unused candidates; returns them largest first. Each grid has
/// at least `min_corners` corners and at least one complete cell.
///
/// `size` is the image size (predictions outside it are not expected to be found); growth
/// stops early once a grid has `stop_at` corners.
pub(crate) fn grow_grids(
    cands: &[XCorner],
    min_corners: usize,
    max_grids: usize,
    max_seeds: usize,
    size: (f64, f64),
    stop_at: Option<usize>,
) -> Vec<Grid> {
    let buckets = Buckets::new(cands, 32.0);
    let mut used = vec![false; cands.len()];
    let mut grids: Vec<Grid> = Vec::new();
    let max_dist = 0.5 * size.0.max(size.1);
    // Seeds with neighbours on all four sides first, then 2 x 2 seeds (e.g. the plate).
    let order =
        (0..cands.len().min(max_seeds)).map(|s| (s, false)).chain((0..cands.len().min(max_seeds)).map(|s| (s, true)));
    for (seed, allow_small) in order {
        if used[seed] {
            continue;
        }
        let Some(g) = grow(cands, &buckets, seed, &used, max_dist, size, allow_small) else { continue };
        if g.at.len() < min_corners || !has_cell(&g) {
            continue;
        }
        for &k in g.at.values() {
            used[k] = true;
        }
        grids.push(g);
        if grids.len() >= max_grids || stop_at.is_some_and(|n| grids.last().is_some_and(|g| g.at.len() >= n)) {
            break;
        }
    }
    grids.sort_by_key(|g| std::cmp::Reverse(g.at.len()));
    grids
}

fn has_cell(g: &Grid) -> bool {
    g.at.keys().any(|&(i, j)| {
        g.at.contains_key(&(i + 1, j)) && g.at.contains_key(&(i, j + 1)) && g.at.contains_key(&(i + 1, j + 1))
    })
}

/// Mean intensity in the middle of the quadrilateral `p00, p01, p11, p10` (bilinear cell
/// coordinates 0.3..0.7).
pub(crate) fn cell_mean(
    img: &GrayF32,
    p00: Vector2<f64>,
    p01: Vector2<f64>,
    p10: Vector2<f64>,
    p11: Vector2<f64>,
) -> f64 {
    let mut s = 0.0;
    let mut n = 0.0;
    for a in [0.3, 0.5, 0.7] {
        for b in [0.3, 0.5, 0.7] {
            let p = p00 * ((1.0 - a) * (1.0 - b)) + p01 * ((1.0 - a) * b) + p10 * (a * (1.0 - b)) + p11 * (a * b);
            s += img.bilinear(p.x, p.y);
            n += 1.0;
        }
    }
    s / n
}

/// Dark/light of every complete cell `(i, j)` (between corners `(i, j)` and `(i + 1, j + 1)`):
/// returns the parity `(i + j) % 2` of the dark cells when the cells alternate (at most 10 %
/// exceptions), with the mean step between the two classes.
pub(crate) fn cell_parity(img: &GrayF32, cands: &[XCorner], g: &Grid) -> Option<(i32, f64)> {
    let mut vals: [Vec<f64>; 2] = [Vec::new(), Vec::new()];
    for (&(i, j), _) in g.at.iter() {
        let (Some(a), Some(b), Some(c), Some(d)) = (
            g.point(cands, (i, j)),
            g.point(cands, (i, j + 1)),
            g.point(cands, (i + 1, j)),
            g.point(cands, (i + 1, j + 1)),
        ) else {
            continue;
        };
        vals[((i + j) % 2) as usize].push(cell_mean(img, a, b, c, d));
    }
    if vals[0].is_empty() && vals[1].is_empty() {
        return None;
    }
    let mean = |v: &Vec<f64>| if v.is_empty() { f64::NAN } else { v.iter().sum::<f64>() / v.len() as f64 };
    let (m0, m1) = (mean(&vals[0]), mean(&vals[1]));
    // With a single class present, compare with the X-corner contrast.
    let (dark_parity, lo, hi) =
        if vals[1].is_empty() || (!vals[0].is_empty() && m0 < m1) { (0, m0, m1) } else { (1, m1, m0) };
    if vals[0].is_empty() || vals[1].is_empty() {
        // Only one class: decide dark/light against the corner sectors' mid level.
        let c = g.at.values().map(|&k| cands[k].contrast).sum::<f64>() / g.at.len() as f64;
        let single = if vals[0].is_empty() { m1 } else { m0 };
        let parity = if vals[0].is_empty() { 1 } else { 0 };
        let mid = mid_level(img, cands, g);
        return if single < mid { Some((parity, c)) } else { Some((1 - parity, c)) };
    }
    let mid = 0.5 * (lo + hi);
    let total = vals[0].len() + vals[1].len();
    let wrong = vals[dark_parity as usize].iter().filter(|v| **v > mid).count()
        + vals[1 - dark_parity as usize].iter().filter(|v| **v < mid).count();
    if (wrong as f64) > 0.1 * total as f64 || hi - lo < 5.0 {
        return None;
    }
    Some((dark_parity, hi - lo))
}

/// Mean image value at the corners (the mid level between dark and light).
fn mid_level(img: &GrayF32, cands: &[XCorner], g: &Grid) -> f64 {
    g.at.values().map(|&k| img.bilinear(cands[k].p.x, cands[k].p.y)).sum::<f64>() / g.at.len() as f64
}
