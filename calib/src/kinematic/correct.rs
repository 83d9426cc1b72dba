//! Corrected joint commands: what to send the robot so that the calibrated model puts the
//! target where the program meant it. A program's joint commands mean the poses the nominal
//! model gives them in the cell's frame with the tool, both as a user teaches them on the nominal
//! controller: here the device frame and tool that make the nominal model agree best with the
//! calibrated one over the program (the closed form of `AX = ZB`), so that the correction removes
//! the geometry's errors and not a frame or tool offset that the calibration's parameters share
//! among themselves. The corrected command is the one whose pose under the calibrated model
//! (joint offsets and every effect included, under the program's conditions) is that pose. Solved per command by
//! Levenberg-Marquardt from the nominal command, on central-difference Jacobians of the
//! calibrated prediction (a few joints, so numeric derivatives cost nothing that matters).

use ferrocal_robot::Kinematics;
use nalgebra::{DMatrix, DVector, Isometry3};
use serde::{Deserialize, Serialize};

use super::CalibratedModel;
use crate::error::{CalibError, Result};
use crate::measurement::PoseMeasurement;

/// Options of [`correct_command`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CorrectOptions {
    /// Match the orientation too (else the position only, the smallest joint change doing so).
    pub use_orientation: bool,
    /// Metres that one radian of orientation error counts as.
    pub orientation_scale_m: f64,
    /// Largest number of iterations.
    pub max_iterations: usize,
    /// Stop when the remaining position error is below this, metres.
    pub tolerance_m: f64,
}

impl Default for CorrectOptions {
    fn default() -> Self {
        Self { use_orientation: true, orientation_scale_m: 0.1, max_iterations: 50, tolerance_m: 1e-9 }
    }
}

/// One corrected command.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CorrectedCommand {
    /// The command to send (model units: rad, m).
    pub q: Vec<f64>,
    /// The pose the program meant, `T_device_target`.
    pub intended: Isometry3<f64>,
    /// How far the calibrated model's pose at the corrected command remains from it, metres.
    pub residual_m: f64,
    /// The nominal command's error under the calibrated model (what the correction removes), m.
    pub nominal_error_m: f64,
}

/// The device frame and tool, `(T_device_base, T_flange_target)`, with which the nominal model
/// (`cal.load_model`) agrees best with the calibrated model over `rows` (at least 3 commands
/// whose orientations differ about two axes).
pub fn nominal_frames(cal: &CalibratedModel, rows: &[PoseMeasurement]) -> Result<(Isometry3<f64>, Isometry3<f64>)> {
    let mut flange = Vec::with_capacity(rows.len());
    let mut predicted = Vec::with_capacity(rows.len());
    for r in rows {
        flange.push(cal.load_model.forward(&r.q)?);
        predicted.push(cal.predict_row(r)?);
    }
    super::device_and_tool(&flange, &predicted)
}

/// Every command of a program corrected (see the module documentation).
pub fn correct_program(
    cal: &CalibratedModel,
    rows: &[PoseMeasurement],
    opts: &CorrectOptions,
) -> Result<Vec<CorrectedCommand>> {
    let (frame, tool) = nominal_frames(cal, rows)?;
    // A calibration without measured orientations knows nothing of the target's orientation.
    let opts = &CorrectOptions { use_orientation: opts.use_orientation && cal.orientation_calibrated, ..*opts };
    rows.iter()
        .map(|r| {
            let want = frame * cal.load_model.forward(&r.q)? * tool;
            correct_command(cal, r, &want, opts)
        })
        .collect()
}

fn residual(
    cal: &CalibratedModel,
    row: &PoseMeasurement,
    q: &[f64],
    want: &Isometry3<f64>,
    o: &CorrectOptions,
) -> Result<DVector<f64>> {
    let mut r = row.clone();
    r.q = q.to_vec();
    let t = cal.predict_row(&r)?;
    let dp = want.translation.vector - t.translation.vector;
    if o.use_orientation {
        let w = (want.rotation * t.rotation.inverse()).scaled_axis() * o.orientation_scale_m;
        Ok(DVector::from_iterator(6, dp.iter().chain(w.iter()).copied()))
    } else {
        Ok(DVector::from_column_slice(dp.as_slice()))
    }
}

/// The command that brings the calibrated model's target to `want` (`T_device_target`),
/// starting from the program's command `row.q` (its conditions, approach directions, temperature
/// and payload, are the ones the effects see).
pub fn correct_command(
    cal: &CalibratedModel,
    row: &PoseMeasurement,
    want: &Isometry3<f64>,
    opts: &CorrectOptions,
) -> Result<CorrectedCommand> {
    let want = *want;
    let mut q = row.q.clone();
    let mut r = residual(cal, row, &q, &want, opts)?;
    let nominal_error_m = r.rows(0, 3).norm();
    let mut lambda = 1e-6;
    let n = q.len();
    for _ in 0..opts.max_iterations {
        if r.rows(0, 3).norm() < opts.tolerance_m {
            break;
        }
        let h = 1e-6;
        let mut j = DMatrix::zeros(r.len(), n);
        for k in 0..n {
            let (mut qp, mut qm) = (q.clone(), q.clone());
            qp[k] += h;
            qm[k] -= h;
            let d = (residual(cal, row, &qp, &want, opts)? - residual(cal, row, &qm, &want, opts)?) / (2.0 * h);
            j.set_column(k, &d);
        }
        let jt = j.transpose();
        let mut improved = false;
        for _ in 0..10 {
            let mut a = &jt * &j;
            for k in 0..n {
                a[(k, k)] += lambda * (1.0 + a[(k, k)]);
            }
            let Some(step) = a.cholesky().map(|c| c.solve(&(-&jt * &r))) else {
                lambda *= 10.0;
                continue;
            };
            let cand: Vec<f64> = q.iter().zip(step.iter()).map(|(a, b)| a + b).collect();
            let rc = residual(cal, row, &cand, &want, opts)?;
            if rc.norm() < r.norm() {
                (q, r) = (cand, rc);
                lambda = (lambda * 0.1).max(1e-12);
                improved = true;
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    let residual_m = r.rows(0, 3).norm();
    if !residual_m.is_finite() {
        return Err(CalibError::Numeric(format!("pose {}: the correction diverged", row.pose_id)));
    }
    Ok(CorrectedCommand { q, intended: want, residual_m, nominal_error_m })
}
