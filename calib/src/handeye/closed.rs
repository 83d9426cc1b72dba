//! Closed-form hand-eye solutions: `AX = XB` (Tsai-Lenz, Park-Martin) and `AX = ZB` (Shah's
//! Kronecker method), from per-image robot and target poses.
//!
//! Both mounts are written as one relation between the unknown hand-eye transform `X`, the
//! unknown world transform `W`, the robot's `T_base_flange_i` and a per-image camera pose `C_i`:
//!
//! ```text
//! T_base_flange_i · X · C_i = W
//! eye-in-hand: X = T_flange_camera, W = T_base_target, C_i = T_camera_target_i
//! eye-to-hand: X = T_flange_target, W = T_base_camera, C_i = T_target_camera_i
//! ```
//!
//! so that for two images `A X = X B` with `A = T_base_flange_i^-1 T_base_flange_j` and
//! `B = C_i C_j^-1`, and for each image `A X = Z B` with `A = T_base_flange_i`, `Z = W`,
//! `B = C_i^-1`.

use nalgebra::{DMatrix, DVector, Isometry3, Matrix3, Rotation3, SMatrix, Translation3, UnitQuaternion, Vector3};

use crate::error::{CalibError, Result};

/// A closed-form method.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ClosedForm {
    /// Tsai and Lenz (1989), `AX = XB`: rotation from the modified Rodrigues vectors of all
    /// image pairs, translation by linear least squares; `W` averaged over the images.
    TsaiLenz,
    /// Park and Martin (1994), `AX = XB`: rotation as the orthogonal Procrustes solution of the
    /// pairs' rotation vectors (`α = R_X β`), translation by linear least squares; `W` averaged.
    ParkMartin,
    /// Shah (2013), `AX = ZB`: both rotations from the dominant singular vectors of
    /// `Σ R_B ⊗ R_A`, then both translations by one linear least-squares system.
    Shah,
}

impl ClosedForm {
    /// Every method, in the order they are tried.
    pub const ALL: [ClosedForm; 3] = [ClosedForm::TsaiLenz, ClosedForm::ParkMartin, ClosedForm::Shah];

    /// The method's name in reports.
    pub fn name(self) -> &'static str {
        match self {
            ClosedForm::TsaiLenz => "tsai_lenz",
            ClosedForm::ParkMartin => "park_martin",
            ClosedForm::Shah => "shah",
        }
    }
}

/// One image's robot pose and camera pose in the form of the module documentation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PosePair {
    /// `T_base_flange` as the robot reported it.
    pub t_base_flange: Isometry3<f64>,
    /// `C_i`: `T_camera_target` (eye-in-hand) or `T_target_camera` (eye-to-hand).
    pub c: Isometry3<f64>,
}

fn too_few(n: usize) -> CalibError {
    CalibError::TooFew(format!("hand-eye closed form: {n} image(s); at least 3 with distinct rotations are needed"))
}

/// The rotation nearest to `m` in the Frobenius norm.
pub fn project_to_so3(m: &Matrix3<f64>) -> Rotation3<f64> {
    let svd = m.svd(true, true);
    let (u, vt) = (svd.u.expect("asked for"), svd.v_t.expect("asked for"));
    let d = (u * vt).determinant().signum();
    let r = u * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * vt;
    Rotation3::from_matrix_unchecked(r)
}

/// Linear least squares `min |A x - b|` by SVD; fails when `A` has not full column rank.
fn least_squares(a: &DMatrix<f64>, b: &DVector<f64>, what: &str) -> Result<DVector<f64>> {
    let svd = a.clone().svd(true, true);
    let smax = svd.singular_values.max();
    let smin = svd.singular_values.min();
    if smax.is_nan() || smax <= 0.0 || smin < 1e-10 * smax {
        return Err(CalibError::Numeric(format!(
            "hand-eye closed form: the {what} is not determined by these poses (rotations about one axis only?)"
        )));
    }
    svd.solve(b, 1e-12 * smax).map_err(|e| CalibError::Numeric(format!("hand-eye closed form: {e}")))
}

/// The mean of rigid transforms: chordal mean of the rotations, mean of the translations.
pub fn average_transforms(ts: &[Isometry3<f64>]) -> Result<Isometry3<f64>> {
    if ts.is_empty() {
        return Err(CalibError::TooFew("no transforms to average".into()));
    }
    let mut m = Matrix3::zeros();
    let mut t = Vector3::zeros();
    for x in ts {
        m += x.rotation.to_rotation_matrix().matrix();
        t += x.translation.vector;
    }
    let r = project_to_so3(&m);
    Ok(Isometry3::from_parts(Translation3::from(t / ts.len() as f64), UnitQuaternion::from_rotation_matrix(&r)))
}

/// `W` from `X`: the mean of `T_base_flange_i X C_i` over the images.
pub fn world_from_hand_eye(pairs: &[PosePair], x: &Isometry3<f64>) -> Result<Isometry3<f64>> {
    let ws: Vec<Isometry3<f64>> = pairs.iter().map(|p| p.t_base_flange * x * p.c).collect();
    average_transforms(&ws)
}

/// The motion pairs `(A, B)` of `AX = XB` over all image pairs.
fn motions(pairs: &[PosePair]) -> Vec<(Isometry3<f64>, Isometry3<f64>)> {
    let mut out = Vec::new();
    for i in 0..pairs.len() {
        for j in i + 1..pairs.len() {
            let a = pairs[i].t_base_flange.inverse() * pairs[j].t_base_flange;
            let b = pairs[i].c * pairs[j].c.inverse();
            out.push((a, b));
        }
    }
    out
}

/// The translation of `X` from `(R_A - I) t_X = R_X t_B - t_A` over all motions.
fn ax_xb_translation(m: &[(Isometry3<f64>, Isometry3<f64>)], r_x: &Rotation3<f64>) -> Result<Vector3<f64>> {
    let mut a = DMatrix::zeros(3 * m.len(), 3);
    let mut b = DVector::zeros(3 * m.len());
    for (k, (ma, mb)) in m.iter().enumerate() {
        let ra = ma.rotation.to_rotation_matrix().into_inner() - Matrix3::identity();
        a.view_mut((3 * k, 0), (3, 3)).copy_from(&ra);
        let rhs = r_x * mb.translation.vector - ma.translation.vector;
        b.rows_mut(3 * k, 3).copy_from(&rhs);
    }
    let t = least_squares(&a, &b, "hand-eye translation")?;
    Ok(Vector3::new(t[0], t[1], t[2]))
}

/// Tsai-Lenz rotation of `X` from the motions.
fn tsai_rotation(m: &[(Isometry3<f64>, Isometry3<f64>)]) -> Result<Rotation3<f64>> {
    // Modified Rodrigues vector 2 sin(θ/2) k = 2 (qx, qy, qz) with qw >= 0.
    let rodrigues = |q: &UnitQuaternion<f64>| {
        let s = if q.w < 0.0 { -2.0 } else { 2.0 };
        Vector3::new(q.i, q.j, q.k) * s
    };
    let mut a = DMatrix::zeros(3 * m.len(), 3);
    let mut b = DVector::zeros(3 * m.len());
    for (k, (ma, mb)) in m.iter().enumerate() {
        let pa = rodrigues(&ma.rotation);
        let pb = rodrigues(&mb.rotation);
        a.view_mut((3 * k, 0), (3, 3)).copy_from(&(pa + pb).cross_matrix());
        b.rows_mut(3 * k, 3).copy_from(&(pb - pa));
    }
    let p = least_squares(&a, &b, "hand-eye rotation")?;
    let pp = Vector3::new(p[0], p[1], p[2]);
    let px = 2.0 * pp / (1.0 + pp.norm_squared()).sqrt();
    let n2 = px.norm_squared();
    let r = Matrix3::identity() * (1.0 - 0.5 * n2)
        + 0.5 * (px * px.transpose() + (4.0 - n2).max(0.0).sqrt() * px.cross_matrix());
    Ok(project_to_so3(&r))
}

/// Park-Martin rotation of `X`: `α_k = R_X β_k` for the rotation vectors of every motion,
/// solved as an orthogonal Procrustes problem.
fn park_rotation(m: &[(Isometry3<f64>, Isometry3<f64>)]) -> Result<Rotation3<f64>> {
    let mut h = Matrix3::zeros();
    for (ma, mb) in m {
        h += ma.rotation.scaled_axis() * mb.rotation.scaled_axis().transpose();
    }
    let sv = h.svd(false, false).singular_values;
    if sv[1] < 1e-9 * sv[0].max(1e-300) {
        return Err(CalibError::Numeric(
            "hand-eye closed form: the robot rotated about one axis only; X's rotation is not determined".into(),
        ));
    }
    Ok(project_to_so3(&h))
}

/// `AX = XB` by Tsai-Lenz or Park-Martin; returns `(X, W)` with `W` averaged over the images.
pub fn solve_ax_xb(pairs: &[PosePair], method: ClosedForm) -> Result<(Isometry3<f64>, Isometry3<f64>)> {
    if pairs.len() < 3 {
        return Err(too_few(pairs.len()));
    }
    let m = motions(pairs);
    let r_x = match method {
        ClosedForm::TsaiLenz => tsai_rotation(&m)?,
        ClosedForm::ParkMartin => park_rotation(&m)?,
        ClosedForm::Shah => return solve_ax_zb(pairs),
    };
    let t_x = ax_xb_translation(&m, &r_x)?;
    let x = Isometry3::from_parts(Translation3::from(t_x), UnitQuaternion::from_rotation_matrix(&r_x));
    let w = world_from_hand_eye(pairs, &x)?;
    Ok((x, w))
}

/// `AX = ZB` by Shah's method; returns `(X, W)`.
pub fn solve_ax_zb(pairs: &[PosePair]) -> Result<(Isometry3<f64>, Isometry3<f64>)> {
    if pairs.len() < 3 {
        return Err(too_few(pairs.len()));
    }
    // R_A R_X R_B^T = R_Z  =>  (R_B ⊗ R_A) vec(R_X) = vec(R_Z) (column-major vec).
    let mut k = SMatrix::<f64, 9, 9>::zeros();
    for p in pairs {
        let ra = p.t_base_flange.rotation.to_rotation_matrix().into_inner();
        let rb = p.c.inverse().rotation.to_rotation_matrix().into_inner();
        k += rb.kronecker(&ra);
    }
    let svd = k.svd(true, true);
    let (u, vt) = (svd.u.expect("asked for"), svd.v_t.expect("asked for"));
    let imax = svd.singular_values.imax();
    let vx = Matrix3::from_column_slice(vt.row(imax).transpose().as_slice());
    let uz = Matrix3::from_column_slice(u.column(imax).as_slice());
    let sign = vx.determinant().signum();
    let r_x = project_to_so3(&(vx * sign));
    let r_z = project_to_so3(&(uz * sign));
    // R_A t_X - t_Z = R_Z t_B - t_A.
    let n = pairs.len();
    let mut a = DMatrix::zeros(3 * n, 6);
    let mut b = DVector::zeros(3 * n);
    for (i, p) in pairs.iter().enumerate() {
        let ra = p.t_base_flange.rotation.to_rotation_matrix().into_inner();
        a.view_mut((3 * i, 0), (3, 3)).copy_from(&ra);
        a.view_mut((3 * i, 3), (3, 3)).copy_from(&(-Matrix3::identity()));
        let tb = p.c.inverse().translation.vector;
        b.rows_mut(3 * i, 3).copy_from(&(r_z * tb - p.t_base_flange.translation.vector));
    }
    let t = least_squares(&a, &b, "hand-eye and world translations")?;
    let x = Isometry3::from_parts(Translation3::new(t[0], t[1], t[2]), UnitQuaternion::from_rotation_matrix(&r_x));
    let w = Isometry3::from_parts(Translation3::new(t[3], t[4], t[5]), UnitQuaternion::from_rotation_matrix(&r_z));
    Ok((x, w))
}

/// `(X, W)` by one closed-form method.
pub fn solve(pairs: &[PosePair], method: ClosedForm) -> Result<(Isometry3<f64>, Isometry3<f64>)> {
    match method {
        ClosedForm::Shah => solve_ax_zb(pairs),
        m => solve_ax_xb(pairs, m),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pose(t: [f64; 3], r: [f64; 3]) -> Isometry3<f64> {
        Isometry3::new(Vector3::from(t), Vector3::from(r))
    }

    /// Exact, noise-free poses: every method recovers X and W to rounding.
    #[test]
    fn closed_forms_recover_exact_transforms() {
        let x = pose([0.03, -0.05, 0.12], [2.2, 0.4, -0.9]);
        let w = pose([0.9, 0.2, -0.1], [0.1, 3.0, 0.2]);
        let flanges = [
            pose([0.5, 0.1, 0.6], [0.3, -0.2, 0.1]),
            pose([0.4, -0.2, 0.7], [-0.4, 0.5, 0.9]),
            pose([0.6, 0.3, 0.5], [1.1, 0.2, -0.6]),
            pose([0.5, 0.0, 0.8], [0.2, 1.0, 0.4]),
            pose([0.3, 0.2, 0.6], [-0.8, -0.6, 0.3]),
        ];
        // T_bf X C = W  =>  C = X^-1 T_bf^-1 W.
        let pairs: Vec<PosePair> =
            flanges.iter().map(|f| PosePair { t_base_flange: *f, c: x.inverse() * f.inverse() * w }).collect();
        for m in ClosedForm::ALL {
            let (xe, we) = solve(&pairs, m).unwrap();
            let dx = (xe.inverse() * x).to_homogeneous() - nalgebra::Matrix4::identity();
            let dw = (we.inverse() * w).to_homogeneous() - nalgebra::Matrix4::identity();
            assert!(dx.norm() < 1e-8 && dw.norm() < 1e-8, "{m:?}: {} {}", dx.norm(), dw.norm());
        }
    }

    /// Rotations about one axis only leave X's rotation undetermined: an error, not a guess.
    #[test]
    fn one_axis_motion_is_an_error() {
        let x = pose([0.03, -0.05, 0.12], [0.2, 0.4, -0.9]);
        let w = pose([0.9, 0.2, -0.1], [0.1, 0.3, 0.2]);
        let pairs: Vec<PosePair> = (0..5)
            .map(|k| {
                let f = pose([0.5, 0.1 * k as f64, 0.6], [0.0, 0.0, 0.3 * k as f64]);
                PosePair { t_base_flange: f, c: x.inverse() * f.inverse() * w }
            })
            .collect();
        assert!(solve(&pairs, ClosedForm::ParkMartin).is_err());
    }
}
