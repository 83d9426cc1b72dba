//! Refitting only the frames of a calibrated model on another device's table
//! (`ferrocal evaluate --refit-frame`).
//!
//! A model calibrated from one device (a camera system) carries that device's frame and its own
//! measured point on the tool (the target's origin); a laser tracker sees a reflector elsewhere
//! on the tool, in its own frame. To score the robot model itself against the tracker, only the
//! device-to-base frame `T_device_base` and the measured point's translation on the tool are
//! refitted on the tracker's table (9 unknowns); every kinematic parameter, joint offset and
//! effect stays as calibrated.
//!
//! # Problem
//! Per row, the measured position against
//! `p = R_F s (R_C (R_fk t_tool + t_fk) + t_C) + t_F = R_F s (A t_tool + b) + t_F`,
//! with `F = T_device_base` (an SE(3) block, left rotation increments), `(R_fk, t_fk)` the
//! flange pose of the calibrated model at the row's effective joints, `(R_C, t_C)` the pose
//! correction of link-compliance effects, `s` the effects' length scale and `t_tool` the
//! measured point in the flange frame (a Euclidean block). The tool's rotation does not move a
//! point and is kept. Residuals are divided by each row's position standard deviation. Solved by
//! the least-squares layer's dense back end from a rigid registration (Horn/Kabsch) of the
//! predicted base-frame points to the measured ones.

use std::sync::Arc;

use ferrocal_lsq::{Problem, Residual, Se3, SolverOptions};
use ferrocal_robot::Kinematics;
use nalgebra::{DMatrix, Isometry3, Matrix3, Point3, Translation3, Vector3};
use serde::Serialize;

use super::model::row_error;
use super::CalibratedModel;
use crate::error::{CalibError, Result};
use crate::frames::fit_rigid;
use crate::measurement::PoseMeasurement;

/// The refitted frames and how well they fit.
#[derive(Clone, Debug, Serialize)]
pub struct FrameRefit {
    /// `T_device_base` before (as calibrated), translation mm and rotation vector deg.
    pub device_frame_before: ([f64; 3], [f64; 3]),
    /// `T_device_base` refitted on the table.
    pub device_frame_after: ([f64; 3], [f64; 3]),
    /// The measured point on the tool (flange frame, mm) before and after.
    pub tool_point_before_mm: [f64; 3],
    /// After.
    pub tool_point_after_mm: [f64; 3],
    /// Standard deviations of the 9 refitted numbers (`tx ty tz` mm, `rx ry rz` deg of the
    /// frame, then the tool point in mm), scaled by `s0`.
    pub std: [f64; 9],
    /// A-posteriori standard deviation of unit weight.
    pub s0: f64,
    /// Why the solver stopped.
    pub termination: String,
}

/// One row's position residual over `[F (SE(3)), t_tool (3)]`, whitened by `sigma_m`.
struct PointResidual {
    /// `s A` (3 x 3): how the tool point maps to the base frame.
    a: Matrix3<f64>,
    /// `s b`: the rest of the base-frame point.
    b: Vector3<f64>,
    measured: Vector3<f64>,
    sigma_m: f64,
}

impl Residual for PointResidual {
    fn n_residuals(&self) -> usize {
        3
    }

    fn evaluate(
        &self,
        params: &[&[f64]],
        residuals: &mut [f64],
        jacobians: Option<&mut [Option<DMatrix<f64>>]>,
    ) -> ferrocal_lsq::Result<()> {
        let f = Se3::to_isometry(params[0]);
        let t = Vector3::new(params[1][0], params[1][1], params[1][2]);
        let local = self.a * t + self.b;
        let rotated = f.rotation * local;
        let r = (self.measured - (rotated + f.translation.vector)) / self.sigma_m;
        residuals.copy_from_slice(r.as_slice());
        if let Some(jac) = jacobians {
            if let Some(d) = &mut jac[0] {
                // dr/d(dt) = -I; a left rotation dw moves the point by dw x (R_F local).
                for i in 0..3 {
                    d[(i, i)] = -1.0 / self.sigma_m;
                }
                let k = ferrocal_lsq::so3::skew(&rotated) / self.sigma_m;
                d.view_mut((0, 3), (3, 3)).copy_from(&k);
            }
            if let Some(d) = &mut jac[1] {
                let m = -(f.rotation.to_rotation_matrix().matrix() * self.a) / self.sigma_m;
                d.copy_from(&m);
            }
        }
        Ok(())
    }

    fn row_names(&self) -> Vec<String> {
        vec!["x".into(), "y".into(), "z".into()]
    }
}

/// The tool-point map of `row` under `cm`: `(s A, s b)` with the base-frame point `s (A t + b)`.
fn point_map(cm: &CalibratedModel, row: &PoseMeasurement) -> Result<(Matrix3<f64>, Vector3<f64>)> {
    let (q, scale) = cm.effective(row)?;
    let flange = super::model_for_row(&cm.model, row)?.forward(&q)?;
    let mut correction = Isometry3::identity();
    for (e, theta) in &cm.effects {
        if e.corrects_pose() {
            correction = e.pose_correction(&cm.load_model, row, &q, theta)? * correction;
        }
    }
    let t = correction * flange;
    let a = t.rotation.to_rotation_matrix().into_inner() * scale;
    let b = t.translation.vector * scale;
    Ok((a, b))
}

/// Refits `T_device_base` and the measured point on the tool of `cm` on `rows` (positions),
/// everything else fixed. `sigma_m` weights rows without their own `sigma_m`. Returns the
/// refitted model and the record of what changed.
pub fn refit_frame(
    cm: &CalibratedModel,
    rows: &[&PoseMeasurement],
    sigma_m: f64,
) -> Result<(CalibratedModel, FrameRefit)> {
    if rows.len() < 4 {
        return Err(CalibError::TooFew(format!(
            "refitting the device frame and the tool point needs at least 4 poses, the table has {}",
            rows.len()
        )));
    }
    if !(sigma_m.is_finite() && sigma_m > 0.0) {
        return Err(CalibError::Data("the default position standard deviation must be positive".into()));
    }
    let mut maps = Vec::with_capacity(rows.len());
    for r in rows {
        maps.push(point_map(cm, r).map_err(|e| row_error(r, e))?);
    }
    let t0 = cm.tool.translation.vector;
    // Start: the rigid registration of the predicted base-frame points to the measured ones.
    let predicted: Vec<Point3<f64>> = maps.iter().map(|(a, b)| Point3::from(a * t0 + b)).collect();
    let measured: Vec<Point3<f64>> = rows.iter().map(|r| Point3::from(r.position_m)).collect();
    let f0 = fit_rigid(&predicted, &measured)?;

    let mut problem = Problem::new();
    let lsq = |e: ferrocal_lsq::LsqError| CalibError::Numeric(format!("refitting the frame: {e}"));
    let frame = problem.add_block("device_frame", Se3::from_isometry(&f0).to_vec(), Arc::new(Se3)).map_err(lsq)?;
    problem.set_scales(frame, vec![1e-3, 1e-3, 1e-3, 1e-3, 1e-3, 1e-3]).map_err(lsq)?;
    let tool = problem.add_euclidean("tool_point", vec![t0.x, t0.y, t0.z]).map_err(lsq)?;
    problem.set_scales(tool, vec![1e-3; 3]).map_err(lsq)?;
    for (r, (a, b)) in rows.iter().zip(&maps) {
        let sigma = r.sigma_m.unwrap_or(sigma_m);
        if !(sigma.is_finite() && sigma > 0.0) {
            return Err(row_error(r, "sigma must be positive"));
        }
        let residual = PointResidual { a: *a, b: *b, measured: r.position_m, sigma_m: sigma };
        problem
            .add_residual(
                &format!("pose {}", r.pose_id),
                Box::new(residual),
                &[frame, tool],
                ferrocal_lsq::Loss::Squared,
            )
            .map_err(lsq)?;
    }
    let opts = SolverOptions { max_iterations: 100, ..SolverOptions::default() };
    let solution = problem.solve(&opts).map_err(lsq)?;
    let cov = problem.covariance().map_err(lsq)?;
    let f = Se3::to_isometry(&problem.block(frame).values);
    let tv = &problem.block(tool).values;
    let t_new = Vector3::new(tv[0], tv[1], tv[2]);
    let std = cov.std();
    let mut std9 = [0.0; 9];
    for (i, s) in std.iter().take(9).enumerate() {
        std9[i] = if (3..6).contains(&i) { s.to_degrees() } else { s * 1e3 };
    }
    let mm_deg = |t: &Isometry3<f64>| super::frame_mm_deg(t);
    let record = FrameRefit {
        device_frame_before: mm_deg(&cm.device_frame),
        device_frame_after: mm_deg(&f),
        tool_point_before_mm: [t0.x * 1e3, t0.y * 1e3, t0.z * 1e3],
        tool_point_after_mm: [t_new.x * 1e3, t_new.y * 1e3, t_new.z * 1e3],
        std: std9,
        s0: cov.s0,
        termination: format!("{:?}", solution.summary.termination),
    };
    let mut out = cm.clone();
    out.device_frame = f;
    out.tool = Isometry3::from_parts(Translation3::from(t_new), cm.tool.rotation);
    Ok((out, record))
}

#[cfg(test)]
mod tests {
    use super::*;
    use ferrocal_lsq::check::check_residual;
    use ferrocal_lsq::{Euclidean, Manifold};
    use nalgebra::UnitQuaternion;

    #[test]
    fn point_residual_passes_the_gradient_checker() {
        let a = Matrix3::new(0.3, -0.8, 0.5, 0.9, 0.2, -0.1, -0.2, 0.6, 0.7) * 1.0002;
        let residual =
            PointResidual { a, b: Vector3::new(0.4, -0.2, 0.9), measured: Vector3::new(1.1, 0.3, -0.4), sigma_m: 2e-5 };
        let f = Isometry3::from_parts(
            Translation3::new(1.2, -0.4, 0.3),
            UnitQuaternion::from_scaled_axis(Vector3::new(0.4, -1.9, 0.7)),
        );
        let x_f = Se3::from_isometry(&f);
        let x_t = [0.01, -0.02, 0.15];
        let manifolds: Vec<Arc<dyn Manifold>> = vec![Arc::new(Se3), Arc::new(Euclidean { n: 3 })];
        let report =
            check_residual(&residual, &[&x_f, &x_t], &manifolds, &[vec![1e-3; 6], vec![1e-3; 3]], 1e-3).unwrap();
        report.assert_below(1e-7, "frame refit residual").unwrap();
    }

    /// A table made by the calibrated model itself, seen from another device frame and through
    /// another point on the tool: the refit recovers both exactly, and the model's prediction
    /// errors vanish. The data are made with the same model family the fit uses.
    #[test]
    fn refit_recovers_another_devices_frame_and_tool_point() {
        let ur5 = ferrocal_robot::presets::preset("ur5").unwrap();
        let cm = CalibratedModel::nominal(ur5.clone());
        let f_true = Isometry3::from_parts(
            Translation3::new(2.1, -0.7, 0.4),
            UnitQuaternion::from_scaled_axis(Vector3::new(0.3, 0.2, 2.5)),
        );
        let tool_true = Vector3::new(0.012, -0.03, 0.081);
        let rows: Vec<PoseMeasurement> = (0..30)
            .map(|i| {
                let s = i as f64;
                let q = vec![
                    0.3 * s.sin(),
                    -1.2 + 0.4 * (0.7 * s).cos(),
                    1.0 + 0.3 * (1.3 * s).sin(),
                    -0.5,
                    0.8 * (0.4 * s).cos(),
                    0.2 * s,
                ];
                let p = f_true * ur5.forward(&q).unwrap() * Point3::from(tool_true);
                PoseMeasurement::new(format!("p{i}"), q, p.coords)
            })
            .collect();
        let refs: Vec<&PoseMeasurement> = rows.iter().collect();
        let before = cm.evaluate(&refs).unwrap();
        let (refit, record) = refit_frame(&cm, &refs, 2e-5).unwrap();
        let after = refit.evaluate(&refs).unwrap();
        assert!(before.mean_mm > 100.0, "{}", before.mean_mm);
        assert!(after.max_mm < 1e-6, "{}", after.max_mm);
        assert!((refit.tool.translation.vector - tool_true).norm() < 1e-9);
        assert!((refit.device_frame.translation.vector - f_true.translation.vector).norm() < 1e-9);
        assert!(refit.device_frame.rotation.angle_to(&f_true.rotation) < 1e-9);
        assert!(record.std.iter().all(|s| s.is_finite()));
    }
}
