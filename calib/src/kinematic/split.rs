//! Training and held-out rows.

use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

use crate::measurement::PoseMeasurement;

/// Splits rows into training and held-out sets: by the `split` column when any row has one,
/// else every second row held out (the source's choice) when `holdout_every_second`.
pub fn split_rows(
    rows: &[PoseMeasurement],
    holdout_every_second: bool,
) -> (Vec<&PoseMeasurement>, Vec<&PoseMeasurement>) {
    if rows.iter().any(|r| r.split.is_some()) {
        let train = rows.iter().filter(|r| r.split != Some(crate::measurement::Split::Test)).collect();
        let test = rows.iter().filter(|r| r.split == Some(crate::measurement::Split::Test)).collect();
        return (train, test);
    }
    if holdout_every_second {
        let train = rows.iter().step_by(2).collect();
        let test = rows.iter().skip(1).step_by(2).collect();
        (train, test)
    } else {
        (rows.iter().collect(), Vec::new())
    }
}

/// A split that is not interleaved: blocks of `block` consecutive rows, every `every`-th block
/// (the last of each group of `every`) held out. Consecutive poses of a recording lie close
/// together in time and space; holding out whole blocks measures how a model does away from its
/// training poses, which every second pose of a grid does not. `None` when `block` or `every` is
/// zero or `every` is 1.
pub fn split_rows_in_blocks(
    rows: &[PoseMeasurement],
    block: usize,
    every: usize,
) -> Option<(Vec<&PoseMeasurement>, Vec<&PoseMeasurement>)> {
    if block == 0 || every < 2 {
        return None;
    }
    let held = |k: usize| (k / block) % every == every - 1;
    let train = rows.iter().enumerate().filter(|(k, _)| !held(*k)).map(|(_, r)| r).collect();
    let test = rows.iter().enumerate().filter(|(k, _)| held(*k)).map(|(_, r)| r).collect();
    Some((train, test))
}

/// The plane of a spatially separated split: rows with `normal . (p - point_m) > 0` are held out.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SplitPlane {
    /// A point of the plane (the median of the positions along the normal), device frame, m.
    pub point_m: Vector3<f64>,
    /// Unit normal: the direction in which the measured positions spread most (the first
    /// principal axis of the positions about their centroid).
    pub normal: Vector3<f64>,
}

/// A held-out split separated in space from the training rows, unlike every second pose of a
/// grid (which sits next to training poses): the rows beyond the plane through the median of the
/// measured positions, normal to their first principal axis, are held out (half the rows, the
/// far half of the workspace), so the held-out error measures extrapolation to a region without
/// training poses. `None` with fewer than 2 rows.
pub fn split_rows_by_plane(
    rows: &[PoseMeasurement],
) -> Option<(Vec<&PoseMeasurement>, Vec<&PoseMeasurement>, SplitPlane)> {
    if rows.len() < 2 {
        return None;
    }
    let n = rows.len() as f64;
    let centroid = rows.iter().fold(Vector3::zeros(), |s, r| s + r.position_m) / n;
    let scatter = rows.iter().fold(Matrix3::zeros(), |s, r| {
        let d = r.position_m - centroid;
        s + d * d.transpose()
    });
    let eig = scatter.symmetric_eigen();
    let k = eig.eigenvalues.imax();
    let mut normal: Vector3<f64> = eig.eigenvectors.column(k).into_owned();
    // A deterministic sign: the largest component positive.
    if normal[normal.iamax()] < 0.0 {
        normal = -normal;
    }
    let mut along: Vec<f64> = rows.iter().map(|r| normal.dot(&(r.position_m - centroid))).collect();
    along.sort_by(f64::total_cmp);
    let m = along.len();
    let median = if m.is_multiple_of(2) { 0.5 * (along[m / 2 - 1] + along[m / 2]) } else { along[m / 2] };
    let point_m = centroid + normal * median;
    let (test, train): (Vec<&PoseMeasurement>, Vec<&PoseMeasurement>) =
        rows.iter().partition(|r| normal.dot(&(r.position_m - point_m)) > 0.0);
    Some((train, test, SplitPlane { point_m, normal }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_plane_split_holds_out_the_far_half_along_the_widest_direction() {
        // A 10 x 3 x 2 grid, widest along y.
        let mut rows = Vec::new();
        for i in 0..3 {
            for j in 0..10 {
                for k in 0..2 {
                    let p = Vector3::new(i as f64 * 0.1, j as f64 * 0.1, k as f64 * 0.1);
                    rows.push(PoseMeasurement::new(format!("{i}{j}{k}"), vec![0.0], p));
                }
            }
        }
        let (train, test, plane) = split_rows_by_plane(&rows).unwrap();
        assert_eq!((train.len(), test.len()), (30, 30));
        assert!((plane.normal - Vector3::y()).norm() < 1e-9, "{:?}", plane.normal);
        assert!(test.iter().all(|r| r.position_m.y > 0.45) && train.iter().all(|r| r.position_m.y < 0.45));
        assert!(split_rows_by_plane(&rows[..1]).is_none());
    }
}
