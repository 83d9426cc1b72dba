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

/// Corner of two fitted lines, in fit coordinates, with the Jacobian blocks.
pub(super) fn intersect(l1: &FittedLine, l2: &FittedLine) -> Option<(Vector2<f64>, [nalgebra::Matrix2<f64>; 2])> {
    let (n1, n2) = (l1.state.normal(), l2.state.normal());
    let m = Matrix2::new(n1.x, n1.y, n2.x, n2.y);
    let det = m.determinant();
    if det.abs() < 0.2 {
        // Lines closer than ~11.5 degrees to parallel.
        return None;
    }
    let minv = m.try_inverse()?;
    let c = Vector2::new(n1.dot(&l1.origin) + l1.state.d, n2.dot(&l2.origin) + l2.state.d);
    let mut p = minv * c;
    // Bent lines: the point of each parabola at the corner's tangential coordinate (a
    // correction of kappa t^2 / 2, well below 1e-3 px for corners within a pixel of the origin).
    if l1.state.kappa != 0.0 || l2.state.kappa != 0.0 {
        let sag =
            |l: &FittedLine, p: Vector2<f64>| 0.5 * l.state.kappa * l.state.tangent().dot(&(p - l.origin)).powi(2);
        p = minv * (c + Vector2::new(sag(l1, p), sag(l2, p)));
    }
    let mut blocks = [Matrix2::zeros(); 2];
    for (i, l) in [l1, l2].into_iter().enumerate() {
        let e = minv.column(i).into_owned();
        let tp = l.state.tangent().dot(&(p - l.origin));
        // Columns: d/dphi, d/dd.
        blocks[i] = Matrix2::from_columns(&[-e * tp, e]);
    }
    Some((p, blocks))
}

impl FittedLine {
    pub(super) fn state_h_inv(&self) -> Matrix2<f64> {
        self.fit.h_inv_line
    }
}

#[cfg(test)]
mod extrapolation_tests {
    use super::*;

    #[test]
    fn the_outer_grid_point_is_extrapolated_in_perspective() {
        // Equally spaced board points under a 1D homography: x(k) = (60 k + 5) / (0.08 k + 1)
        // pixels along a tilted line; the step shrinks from 60 to about 40 px.
        let x = |k: f64| (60.0 * k + 5.0) / (0.08 * k + 1.0);
        let u = Vector2::new(0.6, 0.8);
        let o = Vector2::new(100.0, 50.0);
        let at = |k: f64| o + u * x(k);
        let p = extrapolate_projective(at(1.0), at(2.0), at(3.0)).unwrap();
        assert!((p - at(0.0)).norm() < 1e-9, "{:?} vs {:?}", p, at(0.0));
        // The linear extrapolation is several pixels off here.
        assert!((at(1.0) * 2.0 - at(2.0) - at(0.0)).norm() > 3.0);
        // Implausible input: the linear fallback.
        assert!(extrapolate_projective(at(1.0), at(1.0), at(3.0)).is_none());
    }
}
