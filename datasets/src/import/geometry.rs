//! Geometry the importers need: the Euler-angle conventions of published recordings and a rigid
//! registration of point sets (Kabsch / Horn) with residuals.

use nalgebra::{Isometry3, Matrix3, Translation3, UnitQuaternion, Vector3};

use crate::error::{DatasetError, Result};

/// Rotation from extrinsic (fixed-axis) `x`, `y`, `z` angles, as ROS and URDF write
/// roll-pitch-yaw: first `roll` about the fixed x axis, then `pitch` about the fixed y axis, then
/// `yaw` about the fixed z axis, i.e. `R = Rz(yaw) Ry(pitch) Rx(roll)`.
pub fn quat_from_extrinsic_xyz(roll_rad: f64, pitch_rad: f64, yaw_rad: f64) -> UnitQuaternion<f64> {
    let rx = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), roll_rad);
    let ry = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), pitch_rad);
    let rz = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw_rad);
    rz * ry * rx
}

/// Rotation from intrinsic (moving-axis) `X`, `Y`, `Z` angles, as Leica tracker software writes
/// `Rx, Ry, Rz`: first `a` about x, then `b` about the new y, then `c` about the newest z, i.e.
/// `R = Rx(a) Ry(b) Rz(c)`.
pub fn quat_from_intrinsic_xyz(a_rad: f64, b_rad: f64, c_rad: f64) -> UnitQuaternion<f64> {
    let rx = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), a_rad);
    let ry = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), b_rad);
    let rz = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), c_rad);
    rx * ry * rz
}

/// Extrinsic `x`, `y`, `z` angles `[roll, pitch, yaw]` of a rotation (inverse of
/// [`quat_from_extrinsic_xyz`]; pitch in `[-pi/2, pi/2]`; at pitch = +-pi/2 yaw is set to zero).
pub fn extrinsic_xyz_from_quat(q: &UnitQuaternion<f64>) -> [f64; 3] {
    let r = q.to_rotation_matrix();
    let m = r.matrix();
    let s = (-m[(2, 0)]).clamp(-1.0, 1.0);
    let pitch = s.asin();
    if s.abs() > 1.0 - 1e-12 {
        // Gimbal lock: only roll -+ yaw is defined; with yaw = 0, m01 = sin(pitch) sin(roll).
        let roll = (m[(0, 1)] * s.signum()).atan2(m[(1, 1)]);
        [roll, pitch, 0.0]
    } else {
        [m[(2, 1)].atan2(m[(2, 2)]), pitch, m[(1, 0)].atan2(m[(0, 0)])]
    }
}

/// Intrinsic `X`, `Y`, `Z` angles `[a, b, c]` of a rotation (inverse of
/// [`quat_from_intrinsic_xyz`]; `b` in `[-pi/2, pi/2]`; at `b` = +-pi/2 `c` is set to zero).
pub fn intrinsic_xyz_from_quat(q: &UnitQuaternion<f64>) -> [f64; 3] {
    let r = q.to_rotation_matrix();
    let m = r.matrix();
    let s = m[(0, 2)].clamp(-1.0, 1.0);
    let b = s.asin();
    if s.abs() > 1.0 - 1e-12 {
        [m[(2, 1)].atan2(m[(1, 1)]), b, 0.0]
    } else {
        [(-m[(1, 2)]).atan2(m[(2, 2)]), b, (-m[(0, 1)]).atan2(m[(0, 0)])]
    }
}

/// The rigid transform `T` that maps `from[i]` closest to `to[i]` in the least-squares sense
/// (`to[i] ~ T * from[i]`), by the SVD method of Kabsch and Horn, with a reflection guard.
/// Needs at least three points that do not lie on a line.
pub fn fit_rigid(from: &[Vector3<f64>], to: &[Vector3<f64>]) -> Result<Isometry3<f64>> {
    if from.len() != to.len() {
        return Err(DatasetError::Input(format!(
            "rigid fit: {} source points but {} target points",
            from.len(),
            to.len()
        )));
    }
    if from.len() < 3 {
        return Err(DatasetError::Input(format!("rigid fit: needs at least 3 point pairs, got {}", from.len())));
    }
    if from.iter().chain(to).any(|p| !p.iter().all(|v| v.is_finite())) {
        return Err(DatasetError::Input("rigid fit: non-finite coordinates".into()));
    }
    let n = from.len() as f64;
    let ca = from.iter().sum::<Vector3<f64>>() / n;
    let cb = to.iter().sum::<Vector3<f64>>() / n;
    let mut h = Matrix3::zeros();
    let mut spread = Matrix3::zeros();
    for (a, b) in from.iter().zip(to) {
        let da = a - ca;
        h += da * (b - cb).transpose();
        spread += da * da.transpose();
    }
    let mut ev: Vec<f64> = spread.symmetric_eigenvalues().iter().copied().collect();
    ev.sort_by(|x, y| y.total_cmp(x));
    let (s0, s1) = (ev[0], ev[1]);
    if s0 <= 0.0 || s1 <= 1e-12 * s0 {
        return Err(DatasetError::Input(
            "rigid fit: the source points are (nearly) collinear or coincident; the rotation is not determined".into(),
        ));
    }
    let svd = h.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Err(DatasetError::Input("rigid fit: singular value decomposition failed".into()));
    };
    let v = v_t.transpose();
    let d = (v * u.transpose()).determinant().signum();
    let r = v * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * u.transpose();
    let rot = ferrocal_robot::geometry::rotation_from_orthonormal(&r).ok_or_else(|| {
        DatasetError::Input("rigid fit: the rotation is not finite (huge or non-finite points?)".into())
    })?;
    let t = cb - rot * ca;
    Ok(Isometry3::from_parts(Translation3::from(t), rot))
}

/// Model positions registered to measured positions by a rigid fit, with the residual of every
/// row.
#[derive(Clone, Debug, PartialEq)]
pub struct PositionRegistration {
    /// `T_device_model`: maps model-frame positions (e.g. the robot base frame) to the device.
    pub t_device_model: Isometry3<f64>,
    /// Every row's model position mapped into the device frame, metres.
    pub predicted_m: Vec<Vector3<f64>>,
    /// Every row's distance between predicted and measured position, metres.
    pub residual_m: Vec<f64>,
    /// Whether each row took part in the fit (the others are held out).
    pub fitted: Vec<bool>,
}

impl PositionRegistration {
    /// RMS and maximum residual over the rows that took part in the fit (`fitted = true`) or
    /// over the held-out rows (`fitted = false`); `None` when there are no such rows.
    pub fn stats_m(&self, fitted: bool) -> Option<(f64, f64)> {
        let r: Vec<f64> =
            self.residual_m.iter().zip(&self.fitted).filter(|(_, f)| **f == fitted).map(|(r, _)| *r).collect();
        rms_max(&r)
    }

    /// RMS and maximum residual over all rows.
    pub fn all_stats_m(&self) -> (f64, f64) {
        rms_max(&self.residual_m).unwrap_or((0.0, 0.0))
    }
}

fn rms_max(r: &[f64]) -> Option<(f64, f64)> {
    if r.is_empty() {
        return None;
    }
    let rms = (r.iter().map(|v| v * v).sum::<f64>() / r.len() as f64).sqrt();
    let max = r.iter().copied().fold(0.0, f64::max);
    Some((rms, max))
}

/// Registers `model_m` (positions in a model frame) to `measured_m` (the same points as a
/// device measured them) with a rigid fit over the rows where `fit_row(i)` is true, and reports
/// the residual of every row.
pub fn register_positions(
    model_m: &[Vector3<f64>],
    measured_m: &[Vector3<f64>],
    fit_row: impl Fn(usize) -> bool,
) -> Result<PositionRegistration> {
    if model_m.len() != measured_m.len() {
        return Err(DatasetError::Input(format!(
            "registration: {} model positions but {} measured positions",
            model_m.len(),
            measured_m.len()
        )));
    }
    let fitted: Vec<bool> = (0..model_m.len()).map(fit_row).collect();
    let (a, b): (Vec<_>, Vec<_>) =
        model_m.iter().zip(measured_m).zip(&fitted).filter(|(_, f)| **f).map(|((a, b), _)| (*a, *b)).unzip();
    let t = fit_rigid(&a, &b)?;
    let predicted_m: Vec<Vector3<f64>> =
        model_m.iter().map(|p| t * nalgebra::Point3::from(*p)).map(|p| p.coords).collect();
    let residual_m = predicted_m.iter().zip(measured_m).map(|(p, m)| (p - m).norm()).collect();
    Ok(PositionRegistration { t_device_model: t, predicted_m, residual_m, fitted })
}

/// A rigid registration that also identifies a constant offset of the measured point in the
/// moving frame (e.g. a tracker probe's position in the robot flange frame).
#[derive(Clone, Debug, PartialEq)]
pub struct OffsetRegistration {
    /// The registration of the model positions `t_model_moving * offset` to the measurements.
    pub registration: PositionRegistration,
    /// The identified offset of the measured point in the moving frame, metres.
    pub offset_m: Vector3<f64>,
    /// Alternation steps used.
    pub iterations: usize,
}

/// Registers measured positions of a point fixed to a moving frame: finds `T_device_model` and
/// the point's offset `d` in the moving frame such that `measured[i] ~ T_device_model *
/// t_model_moving[i] * d`, by alternating a rigid fit ([`fit_rigid`]) with the linear
/// least-squares solution for `d`, starting from `initial_offset_m`, over the rows where
/// `fit_row(i)` is true. Stops when `d` changes by less than a nanometre (at most 10,000 steps).
pub fn register_with_offset(
    t_model_moving: &[Isometry3<f64>],
    measured_m: &[Vector3<f64>],
    initial_offset_m: Vector3<f64>,
    fit_row: impl Fn(usize) -> bool,
) -> Result<OffsetRegistration> {
    if t_model_moving.len() != measured_m.len() {
        return Err(DatasetError::Input(format!(
            "registration: {} poses but {} measured positions",
            t_model_moving.len(),
            measured_m.len()
        )));
    }
    let fitted: Vec<bool> = (0..measured_m.len()).map(&fit_row).collect();
    let model_points = |d: &Vector3<f64>| -> Vec<Vector3<f64>> {
        t_model_moving.iter().map(|t| (t * nalgebra::Point3::from(*d)).coords).collect()
    };
    let mut d = initial_offset_m;
    let mut iterations = 0;
    loop {
        iterations += 1;
        let reg = register_positions(&model_points(&d), measured_m, |i| fitted[i])?;
        let inv = reg.t_device_model.inverse();
        let mut acc = Vector3::zeros();
        let mut n = 0usize;
        for ((t, m), f) in t_model_moving.iter().zip(measured_m).zip(&fitted) {
            if *f {
                let local = inv * nalgebra::Point3::from(*m);
                acc += t.rotation.inverse() * (local.coords - t.translation.vector);
                n += 1;
            }
        }
        let next = acc / n.max(1) as f64;
        let step = (next - d).norm();
        d = next;
        if !step.is_finite() {
            return Err(DatasetError::Input("registration with offset diverged".into()));
        }
        if step < 1e-9 || iterations >= 10_000 {
            let registration = register_positions(&model_points(&d), measured_m, |i| fitted[i])?;
            return Ok(OffsetRegistration { registration, offset_m: d, iterations });
        }
    }
}
