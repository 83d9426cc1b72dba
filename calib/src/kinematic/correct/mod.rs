//! Corrected joint commands: what to send the robot so that the calibrated model puts the
//! measured point where it is wanted.
//!
//! # What is wanted
//! A wanted pose is `T_device_target` in the calibration's device frame. It is given directly
//! (`ferrocal correct --targets`), or as a nominal joint command (`--program`): the pose the
//! nominal model gives the command, `F_nom · FK_nom(q) · T_nom`, where `F_nom` and `T_nom`
//! ([`NominalFrames`]) are the device frame and tool with which the nominal model agrees best
//! with the calibrated one over the calibration's own poses. They are fixed once, when the
//! calibration is made, and stored in its file: a command's wanted pose, and so its corrected
//! command, depends on that command alone, never on the other commands of the program (fitting
//! the frames over the program made the same pose move by millimetres from one program to the
//! next, and refused programs of a few moves).
//!
//! # The command
//! The corrected command is the one whose pose under the calibrated model (joint offsets and
//! every effect included, under the row's conditions: approach directions, temperature,
//! payload) is the wanted pose: Levenberg-Marquardt on central-difference Jacobians (a few
//! joints), from the nominal command, a given start or the nominal model's inverse kinematics,
//! with every joint kept inside its limits. A command that no joint vector within the limits
//! brings to its pose is reported as not reached; the smallest singular value of the task
//! Jacobian at the command says how near a singularity it is.
//!
//! # Its uncertainty
//! [`Uncertainty`] propagates the calibration's parameter covariance to the landing position
//! and adds the position scatter the calibrated model leaves unexplained on its own poses.

use ferrocal_robot::{JointKind, Kinematics};
use nalgebra::{DMatrix, DVector, Isometry3, Point3, Vector3};
use serde::{Deserialize, Serialize};

use super::{device_and_tool, start_rms, CalibratedModel};
use crate::dynamics::design::radical_inverse;
use crate::error::{CalibError, Result};
use crate::frames::fit_rigid;
use crate::measurement::PoseMeasurement;

mod uncertainty;
pub use uncertainty::{perturbed, radius_68, Uncertainty};

#[cfg(test)]
mod tests;

/// A command is reached when the calibrated model puts it within this of its wanted position, m.
pub const REACHED_M: f64 = 1e-6;

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
        Self { use_orientation: true, orientation_scale_m: 0.1, max_iterations: 100, tolerance_m: 1e-10 }
    }
}

/// A device frame and a tool, `(T_device_base, T_flange_target)`.
type Frames = (Isometry3<f64>, Isometry3<f64>);

/// Where the nominal frames came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FramesSource {
    /// Fitted over the calibration's own poses when it was made (stored in its file).
    CalibrationPoses,
    /// Fitted over a fixed sample of the joint space (a calibration file written before the
    /// frames were stored): still the same for every program.
    JointSpaceSample,
}

/// The device frame and tool in which the nominal model means a joint command:
/// `T_device_target = device_frame · FK_nom(q) · tool`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct NominalFrames {
    /// `T_device_base` of the nominal model.
    pub device_frame: Isometry3<f64>,
    /// `T_flange_target` of the nominal model.
    pub tool: Isometry3<f64>,
    /// Poses the frames were fitted over.
    pub n_poses: usize,
    /// RMS distance between the nominal and the calibrated model over those poses, mm: what
    /// the calibration changes in the robot's own geometry.
    pub rms_mm: f64,
    /// Where they came from.
    pub source: FramesSource,
}

impl NominalFrames {
    /// Fitted over `rows` (the calibration's poses): the closed form of `AX = ZB` on the
    /// nominal flange poses against the calibrated model's target poses, or, when that fits the
    /// positions worse (a robot whose orientation does not vary), a rigid registration of the
    /// positions with the calibrated tool.
    pub fn fit(cal: &CalibratedModel, rows: &[&PoseMeasurement]) -> Result<Self> {
        Self::fit_with(cal, rows, FramesSource::CalibrationPoses)
    }

    fn fit_with(cal: &CalibratedModel, rows: &[&PoseMeasurement], source: FramesSource) -> Result<Self> {
        if rows.len() < 3 {
            return Err(CalibError::TooFew(format!("the nominal frames need at least 3 poses, got {}", rows.len())));
        }
        let mut flange = Vec::with_capacity(rows.len());
        let mut predicted = Vec::with_capacity(rows.len());
        for r in rows {
            flange.push(cal.load_model.forward(&r.q)?);
            predicted.push(cal.predict_row(r).or_else(|_| cal.predict(&r.q))?);
        }
        let points: Vec<Point3<f64>> = predicted.iter().map(|t| Point3::from(t.translation.vector)).collect();
        let mut best: Option<(Frames, f64)> = None;
        let mut consider = |c: Frames| {
            let rms = start_rms(&flange, &points, &c);
            if rms.is_finite() && best.as_ref().is_none_or(|(_, b)| rms < *b) {
                best = Some((c, rms));
            }
        };
        if let Ok(c) = device_and_tool(&flange, &predicted) {
            consider(c);
        }
        let from: Vec<Point3<f64>> = flange.iter().map(|f| Point3::from((f * cal.tool).translation.vector)).collect();
        if let Ok(f) = fit_rigid(&from, &points) {
            consider((f, cal.tool));
        }
        let ((device_frame, tool), rms) = best.ok_or_else(|| {
            CalibError::Numeric("the nominal model's frames cannot be fitted to the calibrated model".into())
        })?;
        Ok(Self { device_frame, tool, n_poses: rows.len(), rms_mm: rms * 1e3, source })
    }

    /// Fitted over a fixed sample of 64 joint vectors spread over the limits (revolute joints
    /// within one turn): for a calibration file that does not carry its frames. The sample does
    /// not depend on any program.
    pub fn over_joint_space(cal: &CalibratedModel) -> Result<Self> {
        let rows = joint_space_sample(cal, 64);
        let refs: Vec<&PoseMeasurement> = rows.iter().collect();
        Self::fit_with(cal, &refs, FramesSource::JointSpaceSample)
    }

    /// The pose the nominal model means by the joint command `q`, `T_device_target`.
    pub fn intended(&self, cal: &CalibratedModel, q: &[f64]) -> Result<Isometry3<f64>> {
        Ok(self.device_frame * cal.load_model.forward(q)? * self.tool)
    }
}

/// `n` joint vectors spread over the model's limits by a Halton sequence (revolute joints within
/// one turn, prismatic ones within their limits or 0.5 m), as rows without conditions.
fn joint_space_sample(cal: &CalibratedModel, n: usize) -> Vec<PoseMeasurement> {
    const PRIMES: [usize; 12] = [2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37];
    let limits = cal.load_model.joint_limits();
    let kinds = cal.load_model.joint_kinds();
    (0..n)
        .map(|k| {
            let q = limits
                .iter()
                .zip(&kinds)
                .enumerate()
                .map(|(j, (l, kind))| {
                    let span = match kind {
                        JointKind::Revolute => std::f64::consts::PI,
                        JointKind::Prismatic => 0.5,
                    };
                    let (lo, hi) = (l.lower.max(-span), l.upper.min(span));
                    let (lo, hi) = if lo < hi { (lo, hi) } else { (l.lower, l.upper) };
                    lo + (hi - lo) * radical_inverse(k + 1, PRIMES[j % PRIMES.len()])
                })
                .collect();
            PoseMeasurement::new(format!("sample{k}"), q, Vector3::zeros())
        })
        .collect()
}

/// The region of joint space and of the device frame that a calibration's poses cover.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Coverage {
    /// Smallest reading of each joint (rad or m).
    pub joint_lower: Vec<f64>,
    /// Largest reading of each joint.
    pub joint_upper: Vec<f64>,
    /// Smallest measured coordinate of the target, device frame, m.
    pub position_lower_m: [f64; 3],
    /// Largest measured coordinate of the target, device frame, m.
    pub position_upper_m: [f64; 3],
    /// Poses it was taken over.
    pub n_poses: usize,
}

/// How far a command lies outside a calibration's [`Coverage`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Outside {
    /// The joint (1-based) furthest beyond the range the calibration's poses covered, with how
    /// far (rad or m), when any is beyond it.
    pub joint: Option<(usize, f64)>,
    /// How far the wanted position lies outside the box of the calibration's positions, m.
    pub position_m: f64,
}

impl Coverage {
    /// The region `rows` cover; `None` without rows.
    pub fn of_rows(rows: &[&PoseMeasurement]) -> Option<Self> {
        let first = rows.first()?;
        let n = first.q.len();
        let mut c = Self {
            joint_lower: vec![f64::INFINITY; n],
            joint_upper: vec![f64::NEG_INFINITY; n],
            position_lower_m: [f64::INFINITY; 3],
            position_upper_m: [f64::NEG_INFINITY; 3],
            n_poses: rows.len(),
        };
        for r in rows.iter().filter(|r| r.q.len() == n) {
            for (j, v) in r.q.iter().enumerate() {
                c.joint_lower[j] = c.joint_lower[j].min(*v);
                c.joint_upper[j] = c.joint_upper[j].max(*v);
            }
            for a in 0..3 {
                c.position_lower_m[a] = c.position_lower_m[a].min(r.position_m[a]);
                c.position_upper_m[a] = c.position_upper_m[a].max(r.position_m[a]);
            }
        }
        Some(c)
    }

    /// How far joint vector `q` with wanted position `p` (device frame, m) lies outside.
    pub fn outside(&self, q: &[f64], p: &Vector3<f64>) -> Outside {
        let mut joint: Option<(usize, f64)> = None;
        for (j, v) in q.iter().enumerate().take(self.joint_lower.len()) {
            let beyond = (self.joint_lower[j] - v).max(v - self.joint_upper[j]);
            if beyond > 0.0 && joint.is_none_or(|(_, b)| beyond > b) {
                joint = Some((j + 1, beyond));
            }
        }
        let d =
            Vector3::from_fn(|a, _| (self.position_lower_m[a] - p[a]).max(p[a] - self.position_upper_m[a]).max(0.0));
        Outside { joint, position_m: d.norm() }
    }
}

/// One corrected command.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CorrectedCommand {
    /// The command to send (model units: rad, m).
    pub q: Vec<f64>,
    /// The wanted pose, `T_device_target`.
    pub intended: Isometry3<f64>,
    /// How far the calibrated model's pose at the corrected command remains from it, metres.
    pub residual_m: f64,
    /// The nominal command's error under the calibrated model (what the correction removes), m.
    pub nominal_error_m: f64,
    /// Smallest singular value of the task Jacobian at the command (position rows in metres,
    /// orientation rows times the options' `orientation_scale_m`), metres per joint unit: near
    /// zero at a singularity.
    pub sigma_min: f64,
    /// Joints (1-based) the command holds at a limit.
    pub at_limit: Vec<usize>,
}

impl CorrectedCommand {
    /// Whether the calibrated model reaches the wanted pose within [`REACHED_M`].
    pub fn reached(&self) -> bool {
        self.residual_m <= REACHED_M
    }
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

fn jacobian(
    cal: &CalibratedModel,
    row: &PoseMeasurement,
    q: &[f64],
    want: &Isometry3<f64>,
    o: &CorrectOptions,
    m: usize,
) -> Result<DMatrix<f64>> {
    let h = 1e-6;
    let mut j = DMatrix::zeros(m, q.len());
    for k in 0..q.len() {
        let (mut qp, mut qm) = (q.to_vec(), q.to_vec());
        qp[k] += h;
        qm[k] -= h;
        let d = (residual(cal, row, &qp, want, o)? - residual(cal, row, &qm, want, o)?) / (2.0 * h);
        j.set_column(k, &d);
    }
    Ok(j)
}

/// The command that brings the calibrated model's target to `want` (`T_device_target`),
/// starting from `start` and kept within the joint limits; `row` carries the conditions the
/// effects see (approach directions, temperature, payload; its joints are not used).
pub fn correct_command(
    cal: &CalibratedModel,
    row: &PoseMeasurement,
    start: &[f64],
    want: &Isometry3<f64>,
    opts: &CorrectOptions,
) -> Result<CorrectedCommand> {
    let limits = cal.model.joint_limits();
    let clamp = |q: &mut [f64]| {
        for (v, l) in q.iter_mut().zip(&limits) {
            *v = v.clamp(l.lower, l.upper);
        }
    };
    let mut q = start.to_vec();
    let nominal_error_m = residual(cal, row, &q, want, opts)?.rows(0, 3).norm();
    clamp(&mut q);
    let mut r = residual(cal, row, &q, want, opts)?;
    let mut lambda = 1e-6;
    let n = q.len();
    for _ in 0..opts.max_iterations {
        if r.norm() < opts.tolerance_m {
            break;
        }
        let j = jacobian(cal, row, &q, want, opts, r.len())?;
        let jt = j.transpose();
        let mut improved = false;
        for _ in 0..12 {
            let mut a = &jt * &j;
            for k in 0..n {
                a[(k, k)] += lambda * (1.0 + a[(k, k)]);
            }
            let Some(step) = a.cholesky().map(|c| c.solve(&(-&jt * &r))) else {
                lambda *= 10.0;
                continue;
            };
            let mut cand: Vec<f64> = q.iter().zip(step.iter()).map(|(a, b)| a + b).collect();
            clamp(&mut cand);
            let rc = residual(cal, row, &cand, want, opts)?;
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
    let j = jacobian(cal, row, &q, want, opts, r.len())?;
    let sigma_min = j.singular_values().iter().copied().fold(f64::INFINITY, f64::min);
    let at_limit = q
        .iter()
        .zip(&limits)
        .enumerate()
        .filter(|(_, (v, l))| **v <= l.lower || **v >= l.upper)
        .map(|(k, _)| k + 1)
        .collect();
    Ok(CorrectedCommand { q, intended: *want, residual_m, nominal_error_m, sigma_min, at_limit })
}

/// A program's joint command `row.q` corrected: its wanted pose is what the nominal model in
/// `frames` gives it; the search starts from the command itself.
pub fn correct_program_row(
    cal: &CalibratedModel,
    frames: &NominalFrames,
    row: &PoseMeasurement,
    opts: &CorrectOptions,
) -> Result<CorrectedCommand> {
    let want = frames.intended(cal, &row.q)?;
    correct_command(cal, row, &row.q, &want, opts)
}

/// Every command of a program corrected, each on its own ([`correct_program_row`]).
pub fn correct_program(
    cal: &CalibratedModel,
    frames: &NominalFrames,
    rows: &[PoseMeasurement],
    opts: &CorrectOptions,
) -> Result<Vec<CorrectedCommand>> {
    let opts = &effective_options(cal, opts);
    rows.iter().map(|r| correct_program_row(cal, frames, r, opts)).collect()
}

/// The options as a calibration can honour them: a calibration without measured orientations
/// knows nothing of the target's orientation, so only positions are matched.
pub fn effective_options(cal: &CalibratedModel, opts: &CorrectOptions) -> CorrectOptions {
    CorrectOptions { use_orientation: opts.use_orientation && cal.orientation_calibrated, ..*opts }
}

/// The command for a wanted pose `want` (`T_device_target`; its orientation is matched when
/// `opts.use_orientation`). The nominal model (in `frames`) is solved first, from `row.q` when
/// the row gives a start (the solution branch), else from the nominal model's inverse kinematics
/// (orientation wanted) and a fixed list of starts spread over the joint space, the first that
/// reaches the pose within the limits; the calibrated model is then solved from that nominal
/// command, whose error under the calibrated model is what the correction removes. `row` carries
/// the conditions the effects see. The starts depend on nothing but the model, so the command
/// depends on this row alone.
pub fn command_for_target(
    cal: &CalibratedModel,
    frames: &NominalFrames,
    row: &PoseMeasurement,
    want: &Isometry3<f64>,
    opts: &CorrectOptions,
) -> Result<CorrectedCommand> {
    let n = cal.load_model.dof();
    let mut starts: Vec<Vec<f64>> = Vec::new();
    if row.q.len() == n {
        starts.push(row.q.clone());
    } else {
        let limits = cal.load_model.joint_limits();
        let mid: Vec<f64> = limits
            .iter()
            .map(|l| if l.lower.is_finite() && l.upper.is_finite() { 0.5 * (l.lower + l.upper) } else { 0.0 })
            .collect();
        let mut seeds = vec![mid];
        seeds.extend(joint_space_sample(cal, 16).into_iter().map(|r| r.q));
        if opts.use_orientation {
            // The nominal model's inverse kinematics from each seed: its solution is a start.
            let base_tool = frames.device_frame.inverse() * want * frames.tool.inverse();
            for s in &seeds {
                if let Ok(q) = cal.load_model.inverse(&base_tool, s) {
                    starts.push(q);
                }
            }
        }
        starts.extend(seeds);
    }
    let nominal = CalibratedModel {
        model: cal.load_model.clone(),
        device_frame: frames.device_frame,
        tool: frames.tool,
        joint_offsets: vec![0.0; n],
        orientation_calibrated: cal.orientation_calibrated,
        effects: Vec::new(),
        load_model: cal.load_model.clone(),
    };
    let mut best: Option<CorrectedCommand> = None;
    for s in &starts {
        let nom = correct_command(&nominal, row, s, want, opts)?;
        let c = correct_command(cal, row, &nom.q, want, opts)?;
        if c.reached() {
            return Ok(c);
        }
        if best.as_ref().is_none_or(|b| c.residual_m < b.residual_m) {
            best = Some(c);
        }
    }
    best.ok_or_else(|| CalibError::Data(format!("pose {}: no start for the search", row.pose_id)))
}
