//! The device frame and the target point on the flange in closed form, from measured positions
//! only: the start of a positions-only calibration whose device frame is far from the base
//! (a tracker across the cell) and whose target is far from the flange (a positioner's table).
//!
//! # Model
//! Per row, with the nominal flange pose `(R_k, x_k)`, the device frame `(R, d)` and the target
//! point `t` on the flange: `p_k = R x_k + R R_k t + d`. Written per measured component `a`,
//! `p_k,a = M_a . x_k + sum_ij (R_k)_ij G_a,ij + d_a` with `M = R` and `G_a,ij = R_ai t_j`:
//! linear in 13 unknowns per component, the three components sharing one design matrix.
//! `R` follows from `M` (the flange origin moves) or from `G` (the target is off the flange:
//! `G_j = R t_j` column-block-wise, so `trace(G_j^T G_k) = 3 t_j t_k` gives `t` up to its sign,
//! the sign that makes `sum_j t_j G_j` a proper rotation), each refined by alternating the
//! rigid fit of `x_k + R_k t` to `p_k` and the linear solve of `t, d` for a given `R`.

use ferrocal_robot::geometry::nearest_rotation;
use nalgebra::{DMatrix, Isometry3, Matrix3, Point3, Translation3, UnitQuaternion, Vector3};

use crate::frames::fit_rigid;

/// Rounds of alternation after the linear solve.
const ALTERNATIONS: usize = 20;

/// `(T_device_base, T_flange_target)` (a translation) with `T_device_base FK_k T_flange_target`
/// placing the target at `measured[k]`, for nominal flange poses `flange`, in closed form (see
/// the module documentation); `None` with fewer than 13 rows or orientations that do not vary
/// enough to separate the unknowns.
pub(crate) fn device_and_point(
    flange: &[Isometry3<f64>],
    measured: &[Point3<f64>],
) -> Option<(Isometry3<f64>, Isometry3<f64>)> {
    let n = flange.len();
    if n < 13 || measured.len() != n {
        return None;
    }
    let design = DMatrix::from_fn(n, 13, |k, c| {
        let fk = &flange[k];
        match c {
            0..=2 => fk.translation.vector[c],
            3..=11 => {
                let (i, j) = ((c - 3) / 3, (c - 3) % 3);
                fk.rotation.to_rotation_matrix().matrix()[(i, j)]
            }
            _ => 1.0,
        }
    });
    let rhs = DMatrix::from_fn(n, 3, |k, a| measured[k].coords[a]);
    let svd = design.svd(true, true);
    let tol = svd.singular_values.max() * 1e-10;
    let sol = svd.solve(&rhs, tol).ok()?;
    // M (rows: components a) and G_j (3 x 3 over a, i) from the solution.
    let m = Matrix3::from_fn(|a, b| sol[(b, a)]);
    let g: Vec<Matrix3<f64>> = (0..3).map(|j| Matrix3::from_fn(|a, i| sol[(3 + 3 * i + j, a)])).collect();
    let mut candidates = Vec::new();
    if let Some(r) = nearest_rotation(&m) {
        candidates.push(r);
    }
    let tt = Matrix3::from_fn(|j, k| (g[j].transpose() * g[k]).trace() / 3.0);
    let eig = tt.symmetric_eigen();
    let (imax, lmax) =
        eig.eigenvalues.iter().enumerate().fold((0, f64::MIN), |b, (i, &v)| if v > b.1 { (i, v) } else { b });
    if lmax > 0.0 {
        let t = eig.eigenvectors.column(imax) * lmax.sqrt();
        let sum: Matrix3<f64> = (0..3).map(|j| g[j] * t[j]).sum::<Matrix3<f64>>() / lmax;
        let signed = if sum.determinant() < 0.0 { -sum } else { sum };
        if let Some(r) = nearest_rotation(&signed) {
            candidates.push(r);
        }
    }
    candidates
        .into_iter()
        .filter_map(|r| refine(flange, measured, r))
        .min_by(|a, b| a.2.total_cmp(&b.2))
        .map(|(f, t, _)| (f, Isometry3::from_parts(Translation3::from(t), UnitQuaternion::identity())))
}

/// From rotation `r`: the linear `t, d`, then [`ALTERNATIONS`] rounds of rigid fit and linear
/// solve. Returns the frame, the point and the RMS (metres).
fn refine(
    flange: &[Isometry3<f64>],
    measured: &[Point3<f64>],
    mut r: UnitQuaternion<f64>,
) -> Option<(Isometry3<f64>, Vector3<f64>, f64)> {
    let mut best: Option<(Isometry3<f64>, Vector3<f64>, f64)> = None;
    for _ in 0..=ALTERNATIONS {
        let (t, d) = point_given_rotation(flange, measured, &r)?;
        let frame = Isometry3::from_parts(Translation3::from(d), r);
        let rms = rms(flange, measured, &frame, &t);
        if best.as_ref().is_some_and(|b| rms >= b.2 * (1.0 - 1e-9)) {
            break;
        }
        best = Some((frame, t, rms));
        let points: Vec<Point3<f64>> = flange.iter().map(|fk| fk * Point3::from(t)).collect();
        r = fit_rigid(&points, measured).ok()?.rotation;
    }
    best
}

/// The least-squares `t, d` of `p_k = R x_k + R R_k t + d` for a given `R`.
fn point_given_rotation(
    flange: &[Isometry3<f64>],
    measured: &[Point3<f64>],
    r: &UnitQuaternion<f64>,
) -> Option<(Vector3<f64>, Vector3<f64>)> {
    let n = flange.len();
    let rm = r.to_rotation_matrix().into_inner();
    let mut a = DMatrix::zeros(3 * n, 6);
    let mut b = DMatrix::zeros(3 * n, 1);
    for (k, (fk, p)) in flange.iter().zip(measured).enumerate() {
        let rr = rm * fk.rotation.to_rotation_matrix().into_inner();
        let rhs = p.coords - rm * fk.translation.vector;
        for row in 0..3 {
            for c in 0..3 {
                a[(3 * k + row, c)] = rr[(row, c)];
            }
            a[(3 * k + row, 3 + row)] = 1.0;
            b[(3 * k + row, 0)] = rhs[row];
        }
    }
    let svd = a.svd(true, true);
    let tol = svd.singular_values.max() * 1e-10;
    let x = svd.solve(&b, tol).ok()?;
    Some((Vector3::new(x[0], x[1], x[2]), Vector3::new(x[3], x[4], x[5])))
}

fn rms(flange: &[Isometry3<f64>], measured: &[Point3<f64>], frame: &Isometry3<f64>, t: &Vector3<f64>) -> f64 {
    let sum: f64 =
        flange.iter().zip(measured).map(|(fk, p)| ((frame * fk * Point3::from(*t)) - p).norm_squared()).sum();
    (sum / flange.len().max(1) as f64).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use ferrocal_robot::{Kinematics, RobotModel};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A UR5 seen by a device rotated 90 deg about an oblique axis and 1.2 m away, the target
    /// 40 mm off the flange: recovered to rounding (noise-free positions).
    #[test]
    fn recovers_a_far_device_frame_and_the_target_point() {
        let model = RobotModel::load("ur5").unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let flange: Vec<Isometry3<f64>> = (0..30)
            .map(|_| {
                let q: Vec<f64> = (0..6).map(|_| rng.random_range(-1.5..1.5)).collect();
                model.forward(&q).unwrap()
            })
            .collect();
        let axis = nalgebra::Unit::new_normalize(Vector3::new(0.3, -0.5, 0.8));
        let frame = Isometry3::from_parts(
            Translation3::new(0.9, -0.7, 0.4),
            UnitQuaternion::from_axis_angle(&axis, std::f64::consts::FRAC_PI_2),
        );
        let t = Vector3::new(0.01, -0.02, 0.035);
        let measured: Vec<Point3<f64>> = flange.iter().map(|fk| frame * fk * Point3::from(t)).collect();
        let (f, tool) = device_and_point(&flange, &measured).unwrap();
        assert!((f.translation.vector - frame.translation.vector).norm() < 1e-9, "{f:?}");
        assert!(f.rotation.angle_to(&frame.rotation) < 1e-9);
        assert!((tool.translation.vector - t).norm() < 1e-9, "{tool:?}");
        assert!(device_and_point(&flange[..12], &measured[..12]).is_none());
    }

    /// Positions-only calibration of a UR5 (zero-offset errors of 1-3 mrad, 10 um noise, a target
    /// 0.25 m off the flange) seen from a device rotated 90 deg and 1.1 m away, against the same
    /// table in the base frame: the start fits to the robot's error (a few mm; the rigid
    /// registration of the flange origins alone leaves about 100 mm) and both reach the same RMS
    /// (to 1e-4 mm).
    #[test]
    fn a_far_device_frame_converges_like_a_good_start() {
        use crate::kinematic::{calibrate, KinematicOptions};
        use crate::measurement::PoseMeasurement;
        use rand_distr::{Distribution, Normal};
        let model = RobotModel::load("ur5").unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let noise = Normal::new(0.0, 10e-6).unwrap();
        let dq = [1e-3, -2e-3, 1.5e-3, 3e-3, -1e-3, 2e-3];
        let tool = Point3::new(0.04, -0.03, 0.25);
        let frame = Isometry3::from_parts(
            Translation3::new(1.1, 0.3, -0.2),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::FRAC_PI_2),
        );
        let (mut near, mut far) = (Vec::new(), Vec::new());
        for k in 0..60 {
            let q: Vec<f64> = (0..6).map(|_| rng.random_range(-1.5..1.5)).collect();
            let q_true: Vec<f64> = q.iter().zip(dq).map(|(a, b)| a + b).collect();
            let e = Vector3::from_fn(|_, _| noise.sample(&mut rng));
            let p_base = model.forward(&q_true).unwrap() * tool + e;
            near.push(PoseMeasurement::new(format!("p{k}"), q.clone(), p_base.coords));
            far.push(PoseMeasurement::new(format!("p{k}"), q, (frame * p_base).coords));
        }
        let opts = KinematicOptions::default();
        let good = calibrate(&model, &near.iter().collect::<Vec<_>>(), &opts).unwrap();
        let cal = calibrate(&model, &far.iter().collect::<Vec<_>>(), &opts).unwrap();
        let (a, b) = (good.train_after.rms_mm, cal.train_after.rms_mm);
        assert!((a - b).abs() < 1e-4, "RMS {b} mm from the far frame, {a} mm from the base frame");
        assert!(cal.train_before.rms_mm < 10.0, "start RMS {} mm", cal.train_before.rms_mm);
        assert!(a < 0.03, "RMS {a} mm against 10 um noise");
        let t = cal.calibrated.tool.translation.vector;
        assert!((t - tool.coords).norm() < 1e-3, "tool {t:?}");
    }
}
