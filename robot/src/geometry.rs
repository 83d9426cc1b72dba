//! Small geometric helpers shared by the models.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3, Vector6};

/// Rigid transform `T_a_b` (see `docs/conventions.md`).
pub type Pose = Isometry3<f64>;

/// Rotation about x by `angle_rad`.
pub fn rot_x(angle_rad: f64) -> Pose {
    Isometry3::from_parts(Translation3::identity(), UnitQuaternion::from_axis_angle(&Vector3::x_axis(), angle_rad))
}

/// Rotation about y by `angle_rad`.
pub fn rot_y(angle_rad: f64) -> Pose {
    Isometry3::from_parts(Translation3::identity(), UnitQuaternion::from_axis_angle(&Vector3::y_axis(), angle_rad))
}

/// Rotation about z by `angle_rad`.
pub fn rot_z(angle_rad: f64) -> Pose {
    Isometry3::from_parts(Translation3::identity(), UnitQuaternion::from_axis_angle(&Vector3::z_axis(), angle_rad))
}

/// Translation by `(x, y, z)` metres.
pub fn trans(x_m: f64, y_m: f64, z_m: f64) -> Pose {
    Isometry3::translation(x_m, y_m, z_m)
}

/// URDF roll-pitch-yaw: `Rz(yaw) Ry(pitch) Rx(roll)`.
pub fn rpy(roll_rad: f64, pitch_rad: f64, yaw_rad: f64) -> UnitQuaternion<f64> {
    UnitQuaternion::from_euler_angles(roll_rad, pitch_rad, yaw_rad)
}

/// A pose as its position in millimetres and its roll, pitch, yaw in degrees (the inverse of
/// [`rpy`]: `Rz(yaw) Ry(pitch) Rx(roll)`), as programs and tables print it.
pub fn position_mm_rpy_deg(pose: &Pose) -> ([f64; 3], [f64; 3]) {
    let p = pose.translation.vector * 1e3;
    let (r, pi, y) = pose.rotation.euler_angles();
    ([p.x, p.y, p.z], [r.to_degrees(), pi.to_degrees(), y.to_degrees()])
}

/// The rotation of a matrix that is already orthonormal with determinant +1 (an SVD's product,
/// a frame built from unit axes), converted exactly and without iteration. `None` when an entry
/// is not finite. nalgebra's `Rotation3::from_matrix` projects iteratively instead: slow far from
/// its guess, inexact when it stops early, and endless on a non-finite matrix; use
/// [`nearest_rotation`] for a matrix that is only nearly orthonormal.
pub fn rotation_from_orthonormal(m: &nalgebra::Matrix3<f64>) -> Option<UnitQuaternion<f64>> {
    if !m.iter().all(|v| v.is_finite()) {
        return None;
    }
    Some(UnitQuaternion::from_rotation_matrix(&nalgebra::Rotation3::from_matrix_unchecked(*m)))
}

/// The rotation nearest to `m` in the Frobenius norm (`U diag(1, 1, det) V^T` of its SVD), for a
/// matrix read from a file that is orthonormal only to its printed digits. Direct, no iteration;
/// `None` when an entry is not finite or the SVD fails.
pub fn nearest_rotation(m: &nalgebra::Matrix3<f64>) -> Option<UnitQuaternion<f64>> {
    if !m.iter().all(|v| v.is_finite()) {
        return None;
    }
    let svd = m.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    let d = (u * v_t).determinant().signum();
    let r = u * nalgebra::Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * v_t;
    rotation_from_orthonormal(&r)
}

/// Pose from a translation and a rotation vector (axis times angle).
pub fn pose_from_vectors(t_m: &Vector3<f64>, rotvec_rad: &Vector3<f64>) -> Pose {
    Isometry3::from_parts(Translation3::from(*t_m), UnitQuaternion::from_scaled_axis(*rotvec_rad))
}

/// `Exp` of a pose 6-vector `[tx, ty, tz, rx, ry, rz]` (metres, rotation vector in radians; the
/// project's one 6-vector order, `docs/conventions.md`): the pose with that translation and
/// rotation. Reads the first six values of `d`.
pub fn exp6(d: &[f64]) -> Pose {
    Isometry3::from_parts(
        Translation3::new(d[0], d[1], d[2]),
        UnitQuaternion::from_scaled_axis(Vector3::new(d[3], d[4], d[5])),
    )
}

/// The 6-vector `[t, rotation vector]` of a pose, the inverse of [`exp6`].
pub fn log6(pose: &Pose) -> Vector6<f64> {
    pose_to_vector(pose)
}

/// The 6-vector `(t, rotation vector)` of a pose.
pub fn pose_to_vector(pose: &Pose) -> Vector6<f64> {
    let t = pose.translation.vector;
    let r = pose.rotation.scaled_axis();
    Vector6::new(t.x, t.y, t.z, r.x, r.y, r.z)
}

/// Pose error `(position, orientation)` of `actual` relative to `target`, expressed in the frame
/// both poses are given in: `dp = p_target - p_actual`, `dr = log(R_target R_actual^T)`.
/// Applying a small motion `(dp, dr)` to `actual` yields `target` to first order.
pub fn pose_error(target: &Pose, actual: &Pose) -> Vector6<f64> {
    let dp = target.translation.vector - actual.translation.vector;
    let dr = (target.rotation * actual.rotation.inverse()).scaled_axis();
    Vector6::new(dp.x, dp.y, dp.z, dr.x, dr.y, dr.z)
}

/// Wraps an angle to `(-pi, pi]`.
pub fn wrap_angle(angle_rad: f64) -> f64 {
    let two_pi = std::f64::consts::TAU;
    let mut a = angle_rad % two_pi;
    if a <= -std::f64::consts::PI {
        a += two_pi;
    } else if a > std::f64::consts::PI {
        a -= two_pi;
    }
    a
}

/// Skew-symmetric (cross-product) matrix of `v` (nalgebra's `cross_matrix`; the robot crate
/// depends on nothing of ours, so it does not take `ferrocal_lsq::so3::skew`).
pub fn skew(v: &Vector3<f64>) -> nalgebra::Matrix3<f64> {
    v.cross_matrix()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rpy_matches_urdf_definition() {
        let (r, p, y) = (0.3, -0.7, 1.1);
        let q = rpy(r, p, y);
        let expect = rot_z(y).rotation * rot_y(p).rotation * rot_x(r).rotation;
        assert!(q.angle_to(&expect) < 1e-14);
    }

    #[test]
    fn wrap_angle_range() {
        for k in -20..20 {
            let a = 0.37 * k as f64;
            let w = wrap_angle(a);
            assert!(w > -std::f64::consts::PI && w <= std::f64::consts::PI);
            assert!(
                ((a - w) / std::f64::consts::TAU).fract().abs() < 1e-9
                    || ((a - w) / std::f64::consts::TAU).fract().abs() > 1.0 - 1e-9
            );
        }
    }

    #[test]
    fn rotation_conversions_are_exact_direct_and_refuse_non_finite() {
        let q = UnitQuaternion::from_scaled_axis(Vector3::new(0.3, -2.9, 0.4));
        let m = *q.to_rotation_matrix().matrix();
        assert!(rotation_from_orthonormal(&m).unwrap().angle_to(&q) < 1e-12);
        assert!(nearest_rotation(&m).unwrap().angle_to(&q) < 1e-12);
        // A matrix orthonormal to 6 printed digits: the nearest rotation is within 1e-6 rad.
        let rounded = m.map(|v| (v * 1e6).round() / 1e6);
        assert!(nearest_rotation(&rounded).unwrap().angle_to(&q) < 2e-6);
        let mut bad = m;
        bad[(1, 2)] = f64::NAN;
        assert!(rotation_from_orthonormal(&bad).is_none());
        assert!(nearest_rotation(&bad).is_none());
        bad[(1, 2)] = f64::INFINITY;
        assert!(nearest_rotation(&bad).is_none());
    }
}
