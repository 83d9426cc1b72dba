//! Plane-to-image homographies by the normalised direct linear transform (Hartley's DLT), and
//! the closed-form pose of a plane from a homography of normalised image coordinates.

use nalgebra::{DMatrix, Isometry3, Matrix3, Point2, Rotation3, Translation3, UnitQuaternion, Vector3};

/// Similarity that moves the points' centroid to the origin and their mean distance from it to
/// `sqrt(2)`; `None` when all points coincide.
fn normalising_transform(points: &[Point2<f64>]) -> Option<Matrix3<f64>> {
    let n = points.len() as f64;
    let c = points.iter().fold(Vector3::zeros(), |a, p| a + Vector3::new(p.x, p.y, 0.0)) / n;
    let mean_dist = points.iter().map(|p| (p.x - c.x).hypot(p.y - c.y)).sum::<f64>() / n;
    if !(mean_dist > 0.0 && mean_dist.is_finite()) {
        return None;
    }
    let s = std::f64::consts::SQRT_2 / mean_dist;
    Some(Matrix3::new(s, 0.0, -s * c.x, 0.0, s, -s * c.y, 0.0, 0.0, 1.0))
}

/// The homography `H` with `dst ~ H src` (at least four point pairs, no three of the first four
/// collinear), by the normalised DLT: both point sets are normalised (centroid at the origin,
/// mean distance `sqrt(2)`), the 2n x 9 system is solved by SVD, and the result is
/// de-normalised and scaled to unit Frobenius norm. `None` for fewer than four points,
/// non-finite input, or a configuration whose solution is not unique (collinear points: the
/// two smallest singular values of the system are too close).
pub fn homography_dlt(src: &[Point2<f64>], dst: &[Point2<f64>]) -> Option<Matrix3<f64>> {
    if src.len() != dst.len() || src.len() < 4 {
        return None;
    }
    if src.iter().chain(dst).any(|p| !(p.x.is_finite() && p.y.is_finite())) {
        return None;
    }
    let ts = normalising_transform(src)?;
    let td = normalising_transform(dst)?;
    let n = src.len();
    let mut a = DMatrix::<f64>::zeros(2 * n, 9);
    for (i, (s, d)) in src.iter().zip(dst).enumerate() {
        let ps = ts * Vector3::new(s.x, s.y, 1.0);
        let pd = td * Vector3::new(d.x, d.y, 1.0);
        let (x, y) = (ps.x, ps.y);
        let (u, v) = (pd.x, pd.y);
        let r0 = [-x, -y, -1.0, 0.0, 0.0, 0.0, u * x, u * y, u];
        let r1 = [0.0, 0.0, 0.0, -x, -y, -1.0, v * x, v * y, v];
        for c in 0..9 {
            a[(2 * i, c)] = r0[c];
            a[(2 * i + 1, c)] = r1[c];
        }
    }
    // The null vector of A: eigenvector of A^T A with the smallest eigenvalue (A^T A is 9 x 9
    // and well scaled after the normalisation).
    let ata = a.transpose() * &a;
    let eig = nalgebra::SymmetricEigen::new(ata);
    let mut order: Vec<usize> = (0..9).collect();
    order.sort_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]));
    let (l1, l8) = (eig.eigenvalues[order[1]], eig.eigenvalues[order[8]]);
    if l8.is_nan() || l8 <= 0.0 || l1 <= 1e-12 * l8 {
        // A second (near-)null direction: the points do not fix a unique homography.
        return None;
    }
    let h = eig.eigenvectors.column(order[0]);
    let hn = Matrix3::new(h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], h[8]);
    let td_inv = td.try_inverse()?;
    let hm = td_inv * hn * ts;
    let norm = hm.norm();
    if !(norm > 0.0 && norm.is_finite()) {
        return None;
    }
    Some(hm / norm)
}

/// The pose `T_cam_plane` of the plane `z = 0` from a homography `H` that maps plane points
/// `(x, y)` (metres) to *normalised* image coordinates (`K^-1` applied, distortion removed):
/// `[r1 r2 t] = lambda H`, `lambda = 2 / (|h1| + |h2|)` with the sign that puts the plane in
/// front of the camera, `r3 = r1 x r2`, and the nearest rotation by SVD. `None` when `H` is
/// degenerate.
pub fn pose_from_homography(h: &Matrix3<f64>) -> Option<Isometry3<f64>> {
    let h1 = h.column(0).into_owned();
    let h2 = h.column(1).into_owned();
    let h3 = h.column(2).into_owned();
    let s = h1.norm() + h2.norm();
    if !(s > 0.0 && s.is_finite()) {
        return None;
    }
    let mut lambda = 2.0 / s;
    if h3.z * lambda < 0.0 {
        lambda = -lambda;
    }
    let r1 = h1 * lambda;
    let r2 = h2 * lambda;
    let r3 = r1.cross(&r2);
    let t = h3 * lambda;
    let m = Matrix3::from_columns(&[r1, r2, r3]);
    let svd = m.svd(true, true);
    let (u, vt) = (svd.u?, svd.v_t?);
    let mut r = u * vt;
    if r.determinant() < 0.0 {
        let mut u2 = u;
        u2.column_mut(2).neg_mut();
        r = u2 * vt;
    }
    let rot = Rotation3::from_matrix_unchecked(r);
    Some(Isometry3::from_parts(Translation3::from(t), UnitQuaternion::from_rotation_matrix(&rot)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dlt_recovers_an_exact_homography() {
        let h_true = Matrix3::new(520.0, 12.0, 300.0, -8.0, 515.0, 240.0, 0.05, -0.03, 1.0);
        let src: Vec<Point2<f64>> =
            (0..20).map(|i| Point2::new((i % 5) as f64 * 0.03 - 0.06, (i / 5) as f64 * 0.03 - 0.04)).collect();
        let dst: Vec<Point2<f64>> = src
            .iter()
            .map(|p| {
                let q = h_true * Vector3::new(p.x, p.y, 1.0);
                Point2::new(q.x / q.z, q.y / q.z)
            })
            .collect();
        let h = homography_dlt(&src, &dst).unwrap();
        let h = h * (h_true[(2, 2)] / h[(2, 2)]);
        assert!((h - h_true).norm() / h_true.norm() < 1e-9, "{h} vs {h_true}");
        // Collinear points have no unique homography.
        let line: Vec<Point2<f64>> = (0..6).map(|i| Point2::new(i as f64, 2.0 * i as f64)).collect();
        assert!(homography_dlt(&line, &line).is_none());
    }

    #[test]
    fn pose_from_an_exact_homography() {
        let t = Isometry3::new(Vector3::new(0.1, -0.05, 0.8), Vector3::new(0.3, -0.2, 0.1));
        let r = t.rotation.to_rotation_matrix();
        let h = Matrix3::from_columns(&[
            r.matrix().column(0).into_owned(),
            r.matrix().column(1).into_owned(),
            t.translation.vector,
        ]) * -3.0;
        let p = pose_from_homography(&h).unwrap();
        assert!((p.translation.vector - t.translation.vector).norm() < 1e-12);
        assert!(p.rotation.angle_to(&t.rotation) < 1e-12);
    }
}
