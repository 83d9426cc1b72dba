//! Zhang's closed-form intrinsics from plane homographies (Zhang 2000, section 3.1) with zero
//! skew (and optionally `fx = fy`) built into the unknowns, and a check of how well the views
//! determine them.
//!
//! Each homography `H = [h1 h2 h3] ~ K [r1 r2 t]` gives two linear constraints on the
//! symmetric `B = K^-T K^-1`: `h1^T B h2 = 0` and `h1^T B h1 - h2^T B h2 = 0`. With zero skew
//! `B12 = 0`, so the unknowns are `b = (B11, B22, B13, B23, B33)` (four degrees of freedom up to
//! scale), or `(B11 = B22, B13, B23, B33)` with a fixed aspect ratio of 1 (three). To make the
//! system well scaled, every homography is first mapped by the inverse of a nominal camera
//! `K0` (focal length = the larger image side, principal point at the image centre) and scaled
//! to unit norm; the solution is mapped back.
//!
//! Conditioning: the solution is the right singular vector of the smallest singular value of
//! the stacked system `A`; it is determined only when the *second smallest* singular value is
//! clearly above zero. Views of parallel planes (whatever their distance or roll) all give the
//! same two constraints (parallel planes share their vanishing line and circular points), so
//! with such views `sigma_{m-1} / sigma_1` collapses towards the noise level.

use nalgebra::{DMatrix, Matrix3, Vector3};

use crate::camera::{ImageSize, Intrinsics};

/// The closed-form estimate and how well-posed it was.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct ZhangEstimate {
    /// Focal lengths and principal point.
    pub intrinsics: Intrinsics,
    /// `sigma_{m-1} / sigma_1` of the normalised constraint system: near 0 when the views do not
    /// determine the intrinsics.
    pub condition: f64,
    /// Whether Zhang's solution was unusable (e.g. not positive definite because of lens
    /// distortion) and the fallback (principal point at the image centre, focal length by
    /// least squares, as OpenCV initialises) was used.
    pub fallback: bool,
}

/// The nominal camera `K0` used for normalisation.
pub(crate) fn nominal_k(size: ImageSize) -> Matrix3<f64> {
    let (w, h) = (f64::from(size.width_px), f64::from(size.height_px));
    let f0 = w.max(h);
    Matrix3::new(f0, 0.0, 0.5 * (w - 1.0), 0.0, f0, 0.5 * (h - 1.0), 0.0, 0.0, 1.0)
}

/// `v_ij` of Zhang's paper for `B = (B11, B12, B22, B13, B23, B33)`.
fn v(h: &Matrix3<f64>, i: usize, j: usize) -> [f64; 6] {
    let (hi, hj) = (h.column(i), h.column(j));
    [
        hi[0] * hj[0],
        hi[0] * hj[1] + hi[1] * hj[0],
        hi[1] * hj[1],
        hi[2] * hj[0] + hi[0] * hj[2],
        hi[2] * hj[1] + hi[1] * hj[2],
        hi[2] * hj[2],
    ]
}

/// Projects a `v` row onto the unknowns (zero skew, optionally `B11 = B22`).
fn reduce(row: [f64; 6], fix_aspect: bool) -> Vec<f64> {
    if fix_aspect {
        vec![row[0] + row[2], row[3], row[4], row[5]]
    } else {
        vec![row[0], row[2], row[3], row[4], row[5]]
    }
}

/// Homographies (pixels from target-plane metres) normalised by `K0^-1` and to unit norm.
pub(crate) fn normalised_homographies(hs: &[Matrix3<f64>], size: ImageSize) -> Vec<Matrix3<f64>> {
    let k0_inv = nominal_k(size).try_inverse().unwrap_or_else(Matrix3::identity);
    hs.iter()
        .map(|h| {
            let hn = k0_inv * h;
            // Columns 1 and 2 carry the rotation; scale so that their mean norm is 1.
            let s = 0.5 * (hn.column(0).norm() + hn.column(1).norm());
            if s > 0.0 {
                hn / s
            } else {
                hn
            }
        })
        .collect()
}

/// Zhang's closed form on homographies `H` (pixels from target-plane metres).
pub(crate) fn zhang_intrinsics(hs: &[Matrix3<f64>], size: ImageSize, fix_aspect: bool) -> ZhangEstimate {
    let k0 = nominal_k(size);
    let hn = normalised_homographies(hs, size);
    let m = if fix_aspect { 4 } else { 5 };
    let mut a = DMatrix::<f64>::zeros(2 * hn.len(), m);
    for (i, h) in hn.iter().enumerate() {
        let v12 = reduce(v(h, 0, 1), fix_aspect);
        let v11 = v(h, 0, 0);
        let v22 = v(h, 1, 1);
        let diff = reduce(std::array::from_fn(|k| v11[k] - v22[k]), fix_aspect);
        for c in 0..m {
            a[(2 * i, c)] = v12[c];
            a[(2 * i + 1, c)] = diff[c];
        }
    }
    let (condition, b) = null_vector(&a);
    let from_b = b.and_then(|b| {
        let (b11, b22, b13, b23, b33) =
            if fix_aspect { (b[0], b[0], b[1], b[2], b[3]) } else { (b[0], b[1], b[2], b[3], b[4]) };
        let s = if b11 < 0.0 { -1.0 } else { 1.0 };
        let (b11, b22, b13, b23, b33) = (s * b11, s * b22, s * b13, s * b23, s * b33);
        if !(b11 > 0.0 && b22 > 0.0) {
            return None;
        }
        let cx = -b13 / b11;
        let cy = -b23 / b22;
        let lambda = b33 - (b13 * b13 / b11 + b23 * b23 / b22);
        if lambda.is_nan() || lambda <= 0.0 {
            return None;
        }
        let fx = (lambda / b11).sqrt();
        let fy = (lambda / b22).sqrt();
        let k = k0 * Matrix3::new(fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0);
        let intr = Intrinsics { fx_px: k[(0, 0)], fy_px: k[(1, 1)], cx_px: k[(0, 2)], cy_px: k[(1, 2)] };
        // Accept only a plausible camera: principal point within the image, focal length
        // between a tenth and a hundred times the larger image side.
        let (w, hgt) = (f64::from(size.width_px), f64::from(size.height_px));
        let plausible = intr.cx_px > -0.5
            && intr.cx_px < w - 0.5
            && intr.cy_px > -0.5
            && intr.cy_px < hgt - 0.5
            && fx > 0.1
            && fx < 100.0
            && fy > 0.1
            && fy < 100.0
            && [intr.fx_px, intr.fy_px, intr.cx_px, intr.cy_px].iter().all(|x| x.is_finite());
        plausible.then_some(intr)
    });
    match from_b {
        Some(intrinsics) => ZhangEstimate { intrinsics, condition, fallback: false },
        None => ZhangEstimate { intrinsics: centred_focal(&hn, &k0), condition, fallback: true },
    }
}

/// Fallback: principal point at the image centre, one focal length from both constraints of
/// every view by least squares (`B = diag(1/f^2, 1/f^2, 1)` in normalised coordinates).
fn centred_focal(hn: &[Matrix3<f64>], k0: &Matrix3<f64>) -> Intrinsics {
    // Rows a * B11 + b * B33 = 0 with B11 = 1/f^2, B33 = 1.
    let (mut saa, mut sab) = (0.0, 0.0);
    for h in hn {
        for row in [v(h, 0, 1), {
            let (v11, v22) = (v(h, 0, 0), v(h, 1, 1));
            std::array::from_fn(|k| v11[k] - v22[k])
        }] {
            let a = row[0] + row[2];
            let b = row[5];
            saa += a * a;
            sab += a * b;
        }
    }
    let inv_f2 = -sab / saa;
    let f = if inv_f2 > 0.0 && inv_f2.is_finite() { (1.0 / inv_f2).sqrt() } else { 1.0 };
    let f = f.clamp(0.1, 100.0);
    Intrinsics { fx_px: f * k0[(0, 0)], fy_px: f * k0[(1, 1)], cx_px: k0[(0, 2)], cy_px: k0[(1, 2)] }
}

/// `sigma_{m-1} / sigma_1` of `a` and its right singular vector of the smallest singular value.
fn null_vector(a: &DMatrix<f64>) -> (f64, Option<Vec<f64>>) {
    let m = a.ncols();
    if a.nrows() < m - 1 {
        return (0.0, None);
    }
    let ata = a.transpose() * a;
    let eig = nalgebra::SymmetricEigen::new(ata);
    let mut order: Vec<usize> = (0..m).collect();
    order.sort_by(|&i, &j| eig.eigenvalues[j].total_cmp(&eig.eigenvalues[i]));
    let s1 = eig.eigenvalues[order[0]].max(0.0).sqrt();
    let s_m1 = eig.eigenvalues[order[m - 2]].max(0.0).sqrt();
    let condition = if s1 > 0.0 { s_m1 / s1 } else { 0.0 };
    let b: Vec<f64> = eig.eigenvectors.column(order[m - 1]).iter().copied().collect();
    (condition, b.iter().all(|x| x.is_finite()).then_some(b))
}

/// Pose `T_cam_target` of a plane from its homography (pixels from plane metres) and `K`.
pub(crate) fn extrinsics_from_homography(h: &Matrix3<f64>, k: &Intrinsics) -> Option<nalgebra::Isometry3<f64>> {
    let kinv =
        Matrix3::new(1.0 / k.fx_px, 0.0, -k.cx_px / k.fx_px, 0.0, 1.0 / k.fy_px, -k.cy_px / k.fy_px, 0.0, 0.0, 1.0);
    crate::pose::homography::pose_from_homography(&(kinv * h))
}

/// The largest angle (degrees) between the normals of any two boards.
pub(crate) fn max_normal_angle_deg(poses: &[nalgebra::Isometry3<f64>]) -> f64 {
    let normals: Vec<Vector3<f64>> = poses.iter().map(|p| p.rotation * Vector3::z()).collect();
    let mut best: f64 = 0.0;
    for i in 0..normals.len() {
        for j in i + 1..normals.len() {
            best = best.max(normals[i].dot(&normals[j]).clamp(-1.0, 1.0).acos().to_degrees());
        }
    }
    best
}
