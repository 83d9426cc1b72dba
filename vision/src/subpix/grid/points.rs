//! The grid's points: lookup with projective extrapolation beyond the found corners, and the segment between two neighbouring points.

use super::*;

/// Grid point lookup with extrapolation along a direction.
pub(super) struct Points<'a> {
    /// The grid.
    pub(super) grid: &'a CheckerGrid,
    /// The fitted point of each grid node, row by row.
    pub(super) fit: Vec<Option<Vector2<f64>>>,
}

impl Points<'_> {
    pub(super) fn get(&self, i: isize, j: isize) -> Option<Vector2<f64>> {
        let (r, c) = (self.grid.field_rows as isize + 1, self.grid.field_cols as isize + 1);
        if i < 0 || j < 0 || i >= r || j >= c {
            return None;
        }
        self.fit[(i * c + j) as usize]
    }

    /// The point, or its extrapolation from the next ones along `(di, dj)` (either
    /// direction): projective from three ([`extrapolate_projective`]), linear from two.
    pub(super) fn get_or_extrapolate(&self, i: isize, j: isize, di: isize, dj: isize) -> Option<Vector2<f64>> {
        if let Some(p) = self.get(i, j) {
            return Some(p);
        }
        for s in [1, -1] {
            if let (Some(p1), Some(p2)) = (self.get(i + s * di, j + s * dj), self.get(i + 2 * s * di, j + 2 * s * dj)) {
                let p3 = self.get(i + 3 * s * di, j + 3 * s * dj);
                return Some(p3.and_then(|p3| extrapolate_projective(p1, p2, p3)).unwrap_or(p1 * 2.0 - p2));
            }
        }
        None
    }

    /// Unit direction of the grid line crossing point `(i, j)` along `(di, dj)`.
    pub(super) fn direction(&self, i: isize, j: isize, di: isize, dj: isize) -> Option<Vector2<f64>> {
        let c = self.get_or_extrapolate(i, j, di, dj)?;
        let fwd = self.get_or_extrapolate(i + di, j + dj, di, dj);
        let back = self.get_or_extrapolate(i - di, j - dj, di, dj);
        let v = match (fwd, back) {
            (Some(f), Some(b)) => f - b,
            (Some(f), None) => f - c,
            (None, Some(b)) => c - b,
            (None, None) => return None,
        };
        let n = v.norm();
        (n > 1e-9).then(|| v / n)
    }

    /// Distance between neighbouring parallel lines at point `(i, j)` across direction
    /// `(di, dj)` (i.e. to the points one step along the crossing direction), both sides.
    pub(super) fn room(
        &self,
        i: isize,
        j: isize,
        seg_dir: (isize, isize),
        field_a: (isize, isize),
        field_b: (isize, isize),
    ) -> f64 {
        let (di, dj) = (seg_dir.1, seg_dir.0); // crossing direction
        let c = self.get_or_extrapolate(i, j, di, dj);
        let mut room = f64::INFINITY;
        let g = self.grid;
        for (s, f) in [(-1isize, field_a), (1, field_b)] {
            let along = self.get_or_extrapolate(i + s * di, j + s * dj, di, dj);
            let dist = match (c, along) {
                (Some(c), Some(a)) => (a - c).norm(),
                _ => f64::INFINITY,
            };
            let width = if g.inside(f.0, f.1) {
                if g.dark(f.0, f.1) == Some(false) {
                    dist * g.light_uniform_fraction.min(1.0)
                } else {
                    dist
                }
            } else {
                // Beyond the fields: the outside band's width relative to the neighbouring field.
                let other = self.get_or_extrapolate(i - s * di, j - s * dj, di, dj);
                match (c, other) {
                    (Some(c), Some(o)) => g.outside_width_fraction * (o - c).norm(),
                    _ => f64::INFINITY,
                }
            };
            room = room.min(width);
        }
        room
    }
}

/// The point one step before `p1` on a line of equally spaced points `p1, p2, p3` seen in
/// perspective: along the line the 1D homography `x(k) = (a k + b) / (c k + 1)` through the
/// three (a board's squares shrink or grow from one to the next in a tilted view, so the
/// linear extrapolation `2 p1 - p2` misplaces the board's outer grid points by up to several
/// pixels), on the line through `p1` and `p2`. `None` when the three do not determine a plausible point (the
/// caller extrapolates linearly).
pub(super) fn extrapolate_projective(p1: Vector2<f64>, p2: Vector2<f64>, p3: Vector2<f64>) -> Option<Vector2<f64>> {
    let d = p2 - p1;
    let len = d.norm();
    if len < 1e-9 {
        return None;
    }
    let u = d / len;
    let x = [0.0, len, u.dot(&(p3 - p1))];
    // a k + b - c k x_k = x_k for k = 1, 2, 3.
    let m = nalgebra::Matrix3::from_fn(|r, c| {
        let k = (r + 1) as f64;
        [k, 1.0, -k * x[r]][c]
    });
    let sol = m.lu().solve(&nalgebra::Vector3::new(x[0], x[1], x[2]))?;
    let b = sol[1]; // x(0), relative to p1
                    // The linear step is -len; a plausible perspective step lies within a factor of 2 of it.
    if !(b.is_finite() && b < -0.5 * len && b > -2.0 * len) {
        return None;
    }
    Some(p1 + u * b)
}

pub(super) fn segment_job(pts: &Points, i: isize, j: isize, dir: usize) -> Option<SegJob> {
    // Segment from (i, j) to (i, j+1) (dir 0) or (i+1, j) (dir 1).
    let (di, dj) = if dir == 0 { (0, 1) } else { (1, 0) };
    let a = pts.get_or_extrapolate(i, j, di, dj)?;
    let b = pts.get_or_extrapolate(i + di, j + dj, di, dj)?;
    let (ci, cj) = (dj, di);
    let cross_a = pts.direction(i, j, ci, cj).unwrap_or_else(|| perp(b - a));
    let cross_b = pts.direction(i + di, j + dj, ci, cj).unwrap_or_else(|| perp(b - a));
    let (fa, fb) = if dir == 0 { ((i - 1, j), (i, j)) } else { ((i, j - 1), (i, j)) };
    let room = pts.room(i, j, (di, dj), fa, fb).min(pts.room(i + di, j + dj, (di, dj), fa, fb));
    Some(SegJob { a, b, cross_a, cross_b, room_px: room })
}

pub(super) fn perp(v: Vector2<f64>) -> Vector2<f64> {
    let n = v.norm().max(1e-12);
    Vector2::new(-v.y / n, v.x / n)
}
