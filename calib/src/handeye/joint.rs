//! The joint adjustment of robot and camera: the robot's kinematic parameters, the camera's
//! intrinsics, `W` and `X` in one least-squares problem in pixels.
//!
//! # Model
//! Every detected corner of a training image is predicted through the robot's forward
//! kinematics at the image's joint readings and the chain of [`super::residual`]:
//!
//! ```text
//! eye-to-hand: p_cam = W^-1 · FK(q + dq; θ) · X · P      X = T_flange_target, W = T_base_camera
//! eye-in-hand: p_cam = X^-1 · FK(q + dq; θ)^-1 · W · P   X = T_flange_camera, W = T_base_target
//! ```
//!
//! and the camera model (intrinsics and lens distortion free), minus the detected pixel,
//! whitened by the corner's covariance. `FK` is the model's forward kinematics (its own base
//! and tool frames included), `θ` the model's parameters and `dq` the joint offsets.
//!
//! # Which robot parameters
//! The same identifiable set as [`crate::kinematic::calibrate`]: the kinematic calibration's
//! candidate layout ([`crate::kinematic::StateLayout`], with the options' model parameters and
//! joint offsets) and its structural selection ([`crate::kinematic::identifiable_candidates`])
//! on a measurement table of the training images (each image's target pose in the device frame
//! from the hand-eye start, with orientation). The layout's device frame and tool are `W^-1`
//! and `X` here; everything else the selection keeps free is a coordinate of the `robot` block.
//!
//! # Start and solve
//! The hand-eye calibration of [`super::calibrate_hand_eye`] with the nominal model's flange
//! poses (closed forms, then the refinement in pixels with the robot poses as noisy
//! measurements, the camera calibrated from the training images) gives `X`, `W` and the camera;
//! the robot starts at its nominal values. Solved with plain least squares, then with a Huber
//! loss at [`super::HandEyeOptions::huber_sigmas`] robust standard deviations of the first
//! solve's whitened residuals (per corner), as the hand-eye refinement does.
//!
//! # Covariance and output
//! `s0^2 (J^T J)^-1` over every free coordinate; the robot block's part is the robot parameters'
//! covariance with the camera, `W` and `X` marginalised. The result converts to the kinematic
//! calibration's [`CalibratedModel`] and its file ([`JointCalibration::file`]), which
//! `ferrocal evaluate` reads: the device frame is `W^-1` (`T_camera_base` eye-to-hand,
//! `T_target_base` eye-in-hand) and the tool `X` (the target's origin, or the camera, on the
//! flange), orientation calibrated.

use std::sync::Arc;

use nalgebra::{DMatrix, Isometry3, Matrix2, Matrix6, Point2, Point3, UnitQuaternion, Vector3};
use serde::Serialize;

use ferrocal_lsq::{so3, BlockId, Loss, LsqError, Problem, Residual};
use ferrocal_robot::{Kinematics, Parameterized, RobotModel};
use ferrocal_vision::camera::CameraModel;

use super::evaluate::{chain_figures, Chain, ChainFigures};
use super::refine::pnp_poses;
use super::residual::{camera_with, chain_point, whitening};
use super::{calibrate_hand_eye, HandEyeData, HandEyeOptions, HandEyeResult, Mount, TransformEstimate};
use crate::error::{CalibError, Result};
use crate::file::CalibrationFile;
use crate::frames::exp6;
use crate::kinematic::{identifiable_candidates, CalibratedModel, KinematicOptions, ParamResult, StateLayout};
use crate::measurement::{PoseMeasurement, Split};
use subspace::Subspace;

mod subspace;

/// Options of [`calibrate_joint`].
#[derive(Clone, Debug)]
pub struct JointOptions {
    /// The robot parameters (model parameters, joint offsets) and the identifiability tolerance,
    /// exactly as the kinematic calibration reads them; frames, tool and effects do not apply
    /// (`W` and `X` take their place; effects are not supported).
    pub kinematic: KinematicOptions,
    /// The hand-eye start, and the fallback corner sigma, Huber threshold and solver of the
    /// joint solve.
    pub hand_eye: HandEyeOptions,
}

impl Default for JointOptions {
    /// The kinematic calibration's defaults, and a hand-eye start that takes the nominal robot's
    /// flange poses as noisy measurements (0.1 mm and 0.1 mrad to start, the levels estimated by
    /// variance components): the nominal robot is wrong by its kinematic errors, which the start
    /// must not force into `X`, `W` and the camera.
    fn default() -> Self {
        Self {
            kinematic: KinematicOptions::default(),
            hand_eye: HandEyeOptions {
                robot_sigma_m: 1e-4,
                robot_sigma_rad: 1e-4,
                estimate_noise: true,
                ..HandEyeOptions::default()
            },
        }
    }
}

/// The result of [`calibrate_joint`].
#[derive(Clone, Debug, Serialize)]
pub struct JointCalibration {
    /// The mount.
    pub mount: Mount,
    /// The calibrated robot as the kinematic calibration delivers it (device frame `W^-1`,
    /// tool `X`).
    #[serde(skip)]
    pub calibrated: CalibratedModel,
    /// The camera.
    pub camera: CameraModel,
    /// Standard deviations of the camera's parameters (order of [`CameraModel::parameters`]).
    pub camera_std: Vec<f64>,
    /// `X` with its covariance (chart of the module [`super`]).
    pub hand_eye: TransformEstimate,
    /// `W` with its covariance.
    pub world: TransformEstimate,
    /// The kinematic candidate layout the robot parameters come from.
    #[serde(skip)]
    pub layout: StateLayout,
    /// Every robot candidate (joint offsets and model parameters of the layout; the frame and
    /// tool entries are `W` and `X`): start, value, standard deviation, free or why fixed.
    pub params: Vec<ParamResult>,
    /// Indices into [`JointCalibration::params`] of the free robot parameters (the order of
    /// [`JointCalibration::robot_covariance`]).
    pub free: Vec<usize>,
    /// Covariance of the free robot parameters (SI), the others marginalised.
    #[serde(skip)]
    pub robot_covariance: DMatrix<f64>,
    /// A-posteriori standard deviation of unit weight.
    pub s0: f64,
    /// Chain figures with the calibrated robot (training and held-out images).
    pub figures: ChainFigures,
    /// The hand-eye calibration with the nominal robot that the adjustment started from.
    pub start: HandEyeResult,
    /// Solver iterations over both solves.
    pub iterations: usize,
    /// Why the final solve stopped.
    pub termination: String,
    /// Corners the Huber loss down-weighted.
    pub n_downweighted: usize,
}

impl JointCalibration {
    /// The calibration file `ferrocal evaluate` reads (`robot_spec`: the model as given).
    pub fn file(&self, robot_spec: &str) -> CalibrationFile {
        CalibrationFile::new(robot_spec, &self.calibrated)
    }

    /// Standard deviation of the free robot parameter `name`, when it is free.
    pub fn std_of(&self, name: &str) -> Option<f64> {
        self.params.iter().find(|p| p.name == name).and_then(|p| p.std)
    }
}

/// How the free robot coordinates map onto the model.
struct RobotMap {
    model: RobotModel,
    /// `(robot block coordinate, index in the model's parameter vector)`.
    model_cols: Vec<(usize, usize)>,
    /// `(robot block coordinate, joint)`.
    offset_cols: Vec<(usize, usize)>,
    n: usize,
}

impl RobotMap {
    /// The model with the block's values and the effective joints.
    fn apply(&self, v: &[f64], q: &[f64]) -> ferrocal_lsq::Result<(RobotModel, Vec<f64>)> {
        let mut m = self.model.clone();
        if !self.model_cols.is_empty() {
            let mut vals = m.parameter_values();
            for &(k, pi) in &self.model_cols {
                vals[pi] = v[k];
            }
            m.set_parameter_values(&vals).map_err(LsqError::model)?;
        }
        let mut qq = q.to_vec();
        for &(k, j) in &self.offset_cols {
            qq[j] += v[k];
        }
        Ok((m, qq))
    }

    /// `FK(q + dq; θ)` and its derivative (6 x n, rows `[dt; dw]` in the base frame, the
    /// product chart of [`ferrocal_lsq::Se3`]: `t' = t + dt`, `R' = Exp(dw) R`) with respect to the block's
    /// coordinates: analytic for joint offsets and serial corrections, central differences
    /// for other model parameters.
    fn pose_jacobian(&self, v: &[f64], q: &[f64]) -> ferrocal_lsq::Result<(Isometry3<f64>, DMatrix<f64>)> {
        let (m, qq) = self.apply(v, q)?;
        let t = m.forward(&qq).map_err(LsqError::model)?;
        let p = t.translation.vector;
        let mut jac = DMatrix::zeros(6, self.n);
        let mut put = |col: usize, dt: Vector3<f64>, dw: Vector3<f64>| {
            jac.fixed_view_mut::<3, 1>(0, col).copy_from(&dt);
            jac.fixed_view_mut::<3, 1>(3, col).copy_from(&dw);
        };
        if !self.offset_cols.is_empty() {
            let jg = m.jacobian(&qq).map_err(LsqError::model)?;
            for &(k, j) in &self.offset_cols {
                put(
                    k,
                    Vector3::new(jg[(0, j)], jg[(1, j)], jg[(2, j)]),
                    Vector3::new(jg[(3, j)], jg[(4, j)], jg[(5, j)]),
                );
            }
        }
        let names = self.model.parameters();
        let frames = match &m {
            RobotModel::Serial(chain) => Some((chain, chain.frames(&qq).map_err(LsqError::model)?)),
            _ => None,
        };
        for &(k, pi) in &self.model_cols {
            let name = &names[pi].name;
            let corr = frames.as_ref().and_then(|(chain, fr)| {
                let joint = chain.joint_of_parameter(name)?;
                let comp =
                    ferrocal_robot::serial::CORRECTION_NAMES.iter().position(|c| name.ends_with(&format!(".{c}")))?;
                let c = chain.joints.get(joint)?.correction;
                let cr = Vector3::new(c[3], c[4], c[5]);
                let link = fr.links[joint];
                let r_a = link.rotation * UnitQuaternion::from_scaled_axis(cr).inverse();
                Some(if comp < 3 {
                    (r_a * Vector3::ith(comp, 1.0), Vector3::zeros())
                } else {
                    let w = r_a * so3::left_jacobian(&cr).column(comp - 3).into_owned();
                    (w.cross(&(p - link.translation.vector)), w)
                })
            });
            let (dt, dw) = match corr {
                Some(d) => d,
                None => {
                    let h = 1e-7;
                    let mut vp = v.to_vec();
                    vp[k] += h;
                    let (mp, qp) = self.apply(&vp, q)?;
                    let tp = mp.forward(&qp).map_err(LsqError::model)?;
                    vp[k] -= 2.0 * h;
                    let (mm, qm) = self.apply(&vp, q)?;
                    let tm = mm.forward(&qm).map_err(LsqError::model)?;
                    (
                        (tp.translation.vector - tm.translation.vector) / (2.0 * h),
                        (tp.rotation * tm.rotation.inverse()).scaled_axis() / (2.0 * h),
                    )
                }
            };
            put(k, dt, dw);
        }
        Ok((t, jac))
    }
}

/// The device frame's increment `f` and the tool's `t` as in the kinematic calibration
/// (`F = exp6(f) F0`, `X = X0 exp6(t)`), with `W = F^-1`, and the derivatives of `W` and `X` in
/// the [`ferrocal_lsq::Se3`] chart with respect to `f` and `t` (6 x 6 each).
struct FrameMap {
    f0: Isometry3<f64>,
    x0: Isometry3<f64>,
    /// The free coordinates of `f` (the block's tangent; a residual's Jacobian has these columns).
    frame_free: Vec<usize>,
    /// The free coordinates of `t`.
    tool_free: Vec<usize>,
}

impl FrameMap {
    fn w_and_x(&self, f: &[f64], t: &[f64]) -> (Isometry3<f64>, Isometry3<f64>) {
        ((exp6(f) * self.f0).inverse(), self.x0 * exp6(t))
    }

    /// `(dW/df, dX/dt)` in the `Se3` chart.
    fn jacobians(&self, f: &[f64], t: &[f64]) -> (Matrix6<f64>, Matrix6<f64>) {
        let big_f = exp6(f) * self.f0;
        let rf = big_f.rotation.to_rotation_matrix().into_inner();
        let tf = big_f.translation.vector;
        let jl_f = so3::left_jacobian(&Vector3::new(f[3], f[4], f[5]));
        // F in its chart: dt_F = df_t + (J_l df_r) x (t_F - f_t), dr_F = J_l df_r.
        let mut m_f = Matrix6::identity();
        let lever = tf - Vector3::new(f[0], f[1], f[2]);
        m_f.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-lever.cross_matrix() * jl_f));
        m_f.fixed_view_mut::<3, 3>(3, 3).copy_from(&jl_f);
        // W = F^-1: dt_W = -R^T dt_F - R^T [t_F]x dr_F, dr_W = -R^T dr_F.
        let mut m_inv = Matrix6::zeros();
        m_inv.fixed_view_mut::<3, 3>(0, 0).copy_from(&(-rf.transpose()));
        m_inv.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-rf.transpose() * tf.cross_matrix()));
        m_inv.fixed_view_mut::<3, 3>(3, 3).copy_from(&(-rf.transpose()));
        // X = X0 exp6(t): dt_X = R0 dt_t, dr_X = R0 J_l(t_r) dr_t.
        let r0 = self.x0.rotation.to_rotation_matrix().into_inner();
        let mut m_x = Matrix6::zeros();
        m_x.fixed_view_mut::<3, 3>(0, 0).copy_from(&r0);
        m_x.fixed_view_mut::<3, 3>(3, 3).copy_from(&(r0 * so3::left_jacobian(&Vector3::new(t[3], t[4], t[5]))));
        (m_inv * m_f, m_x)
    }
}

/// One corner predicted through the robot's kinematics (see the module documentation). Blocks:
/// the robot coordinates (Euclidean), the device frame increment `f` and the tool increment `t`
/// ([`FrameMap`]), the camera (Euclidean).
struct RobotCorner {
    map: Arc<RobotMap>,
    frames: Arc<FrameMap>,
    mount: Mount,
    q: Vec<f64>,
    point_m: Point3<f64>,
    detected_px: Point2<f64>,
    whiten: Matrix2<f64>,
    camera: CameraModel,
}

impl Residual for RobotCorner {
    fn n_residuals(&self) -> usize {
        2
    }

    fn evaluate(
        &self,
        params: &[&[f64]],
        residuals: &mut [f64],
        jacobians: Option<&mut [Option<DMatrix<f64>>]>,
    ) -> ferrocal_lsq::Result<()> {
        let (w, x) = self.frames.w_and_x(params[1], params[2]);
        let camera = camera_with(&self.camera, params[3])?;
        let want_robot = jacobians.as_ref().is_some_and(|j| j[0].is_some());
        let (t, j_pose) = if want_robot {
            let (t, j) = self.map.pose_jacobian(params[0], &self.q)?;
            (t, Some(j))
        } else {
            let (m, qq) = self.map.apply(params[0], &self.q)?;
            (m.forward(&qq).map_err(LsqError::model)?, None)
        };
        let c = chain_point(self.mount, &x, &w, &t, 1.0, &self.point_m);
        let proj = camera.project_with_jacobians(&Point3::from(c.p_cam)).map_err(LsqError::model)?;
        let r = self.whiten * (proj.pixel - self.detected_px);
        residuals[0] = r.x;
        residuals[1] = r.y;
        let Some(jacs) = jacobians else { return Ok(()) };
        let sp = self.whiten * proj.d_pixel_d_point;
        if let (Some(j), Some(jp)) = (&mut jacs[0], &j_pose) {
            let d = DMatrix::from_column_slice(2, 6, (sp * c.d_robot).as_slice()) * jp;
            j.copy_from(&d);
        }
        let fill = |j: &mut Option<DMatrix<f64>>, m: &[f64]| {
            if let Some(j) = j {
                j.copy_from_slice(m);
            }
        };
        let (m_w, m_x) = self.frames.jacobians(params[1], params[2]);
        let pick = |j: &mut Option<DMatrix<f64>>, full: nalgebra::Matrix2x6<f64>, free: &[usize]| {
            if let Some(j) = j {
                for (k, &i) in free.iter().enumerate() {
                    j[(0, k)] = full[(0, i)];
                    j[(1, k)] = full[(1, i)];
                }
            }
        };
        pick(&mut jacs[1], sp * c.d_w * m_w, &self.frames.frame_free);
        pick(&mut jacs[2], sp * c.d_x * m_x, &self.frames.tool_free);
        fill(&mut jacs[3], (self.whiten * &proj.d_pixel_d_params).as_slice());
        Ok(())
    }

    fn row_names(&self) -> Vec<String> {
        vec!["x".into(), "y".into()]
    }
}

/// The measurement table the parameter selection runs on: every training image's target pose
/// in the device frame (`W^-1 FK X`) from the hand-eye start, with the options' sigmas.
fn selection_rows(
    model: &RobotModel,
    data: &HandEyeData,
    joints: &[Vec<f64>],
    start: &HandEyeResult,
    opts: &KinematicOptions,
) -> Result<Vec<PoseMeasurement>> {
    let w_inv = start.world.transform.inverse();
    let mut rows = Vec::new();
    for (v, q) in data.views.iter().zip(joints).filter(|(v, _)| v.split == Split::Train) {
        let t = w_inv * model.forward(q)? * start.hand_eye.transform;
        let mut r = PoseMeasurement::new(v.name.clone(), q.clone(), t.translation.vector);
        r.orientation = Some(t.rotation);
        r.sigma_m = Some(opts.sigma_position_m);
        r.sigma_rad = Some(opts.sigma_orientation_rad);
        rows.push(r);
    }
    Ok(rows)
}

fn lsq_error(e: LsqError) -> CalibError {
    CalibError::from(e)
}

/// The blocks of the joint problem.
struct Blocks {
    robot: BlockId,
    frame: BlockId,
    tool: BlockId,
    camera: BlockId,
}

/// What every build of the problem shares.
struct Setup<'a> {
    map: Arc<RobotMap>,
    frames: Arc<FrameMap>,
    scales: Vec<f64>,
    data: &'a HandEyeData,
    joints: &'a [Vec<f64>],
    options: &'a HandEyeOptions,
}

/// The values of the blocks.
struct State {
    robot: Vec<f64>,
    frame: Vec<f64>,
    tool: Vec<f64>,
    camera: CameraModel,
}

fn build(setup: &Setup, state: &State, loss: Loss) -> Result<(Problem, Blocks)> {
    let mut p = Problem::new();
    let rb = p.add_euclidean("robot", state.robot.clone()).map_err(lsq_error)?;
    p.set_scales(rb, setup.scales.clone()).map_err(lsq_error)?;
    let mut subspace = |name: &str, values: &[f64], free: &[usize]| -> Result<BlockId> {
        let id =
            p.add_block(name, values.to_vec(), Arc::new(Subspace { n: 6, free: free.to_vec() })).map_err(lsq_error)?;
        if free.is_empty() {
            p.set_constant(id, true).map_err(lsq_error)?;
        } else {
            p.set_scales(id, vec![1e-3; free.len()]).map_err(lsq_error)?;
        }
        Ok(id)
    };
    let frame = subspace("device_frame", &state.frame, &setup.frames.frame_free)?;
    let tool = subspace("tool", &state.tool, &setup.frames.tool_free)?;
    let camera = &state.camera;
    let cam = p.add_euclidean("camera", camera.parameter_values()).map_err(lsq_error)?;
    p.set_scales(cam, (0..camera.n_parameters()).map(|i| if i < 4 { 1.0 } else { 1e-3 }).collect())
        .map_err(lsq_error)?;
    let fallback = whitening(&(Matrix2::identity() * setup.options.fallback_corner_sigma_px.powi(2)))
        .ok_or_else(|| CalibError::Data("the fallback corner sigma must be positive".into()))?;
    let data = setup.data;
    for (v, q) in data.views.iter().zip(setup.joints).filter(|(v, _)| v.split == Split::Train) {
        for ((&id, px), cov) in v.point_ids.iter().zip(&v.corners_px).zip(&v.covariances_px2) {
            let r = RobotCorner {
                map: setup.map.clone(),
                frames: setup.frames.clone(),
                mount: data.mount,
                q: q.clone(),
                point_m: data.target_points_m[id],
                detected_px: *px,
                whiten: cov.and_then(|c| whitening(&c)).unwrap_or(fallback),
                camera: *camera,
            };
            p.add_residual(&format!("{}.c{id}", v.name), Box::new(r), &[rb, frame, tool, cam], loss)
                .map_err(lsq_error)?;
        }
    }
    Ok((p, Blocks { robot: rb, frame, tool, camera: cam }))
}

fn read_back(p: &Problem, b: &Blocks, template: &CameraModel) -> Result<State> {
    Ok(State {
        robot: p.block(b.robot).values.clone(),
        frame: p.block(b.frame).values.clone(),
        tool: p.block(b.tool).values.clone(),
        camera: camera_with(template, &p.block(b.camera).values)?,
    })
}

/// The 6 x 6 covariance in the `Se3` chart of a transform whose increment coordinates `free`
/// have covariance `c` and derivative `m` (6 x 6 over all increment coordinates).
fn chart_covariance(m: &Matrix6<f64>, free: &[usize], c: Option<DMatrix<f64>>) -> Matrix6<f64> {
    let Some(c) = c else { return Matrix6::zeros() };
    let sub = DMatrix::from_fn(6, free.len(), |i, k| m[(i, free[k])]);
    let full = &sub * c * sub.transpose();
    Matrix6::from_fn(|i, j| full[(i, j)])
}

/// `1.4826 * median |r|` over the whitened residual components.
fn robust_sigma(p: &Problem) -> Result<f64> {
    let mut a: Vec<f64> = p.residuals().map_err(lsq_error)?.iter().map(|v| v.abs()).collect();
    if a.is_empty() {
        return Ok(0.0);
    }
    a.sort_by(f64::total_cmp);
    Ok(1.4826 * a[a.len() / 2])
}

/// The joint adjustment of a recording with joint readings `joints` (one per view of `data`,
/// in model order; the views' `t_base_flange` are not used) and the nominal robot `model` (see
/// the module documentation for the method).
///
/// Errors: those of [`calibrate_hand_eye`] for the start, [`CalibError::Data`] for readings
/// that do not match the views or the model, or options with effects, [`CalibError::Numeric`]
/// when the solve or the covariance fails.
pub fn calibrate_joint(
    model: &RobotModel,
    data: &HandEyeData,
    joints: &[Vec<f64>],
    options: &JointOptions,
) -> Result<JointCalibration> {
    if joints.len() != data.views.len() {
        return Err(CalibError::Data(format!("{} joint readings for {} images", joints.len(), data.views.len())));
    }
    if let Some((v, q)) = data.views.iter().zip(joints).find(|(_, q)| q.len() != model.dof()) {
        return Err(CalibError::Data(format!(
            "image {}: {} joint values, the model '{}' has {}",
            v.name,
            q.len(),
            model.name(),
            model.dof()
        )));
    }
    if !options.kinematic.effects.is_empty() {
        return Err(CalibError::Data("the joint adjustment does not model effects".into()));
    }
    // 1. The hand-eye start with the nominal model's flange poses.
    let mut nominal = data.clone();
    for (v, q) in nominal.views.iter_mut().zip(joints) {
        v.t_base_flange = model.forward(q).map_err(|e| CalibError::Data(format!("image {}: {e}", v.name)))?;
    }
    let start = calibrate_hand_eye(&nominal, &options.hand_eye)?;
    calibrate_joint_from(model, data, joints, start, options)
}

/// [`calibrate_joint`] from a given hand-eye start (`X`, `W` and the camera of `start`, as
/// [`calibrate_hand_eye`] gives it for the nominal robot's flange poses). The start also fixes
/// the gauge: frame and tool coordinates the selection holds stay at the start's values, so
/// two adjustments from the same start (of a noisy recording and of its noise-free truth, say)
/// have comparable robot parameters.
pub fn calibrate_joint_from(
    model: &RobotModel,
    data: &HandEyeData,
    joints: &[Vec<f64>],
    start: HandEyeResult,
    options: &JointOptions,
) -> Result<JointCalibration> {
    if joints.len() != data.views.len() {
        return Err(CalibError::Data(format!("{} joint readings for {} images", joints.len(), data.views.len())));
    }
    let mut nominal = data.clone();
    for (v, q) in nominal.views.iter_mut().zip(joints) {
        v.t_base_flange = model.forward(q).map_err(|e| CalibError::Data(format!("image {}: {e}", v.name)))?;
    }
    // 2. The robot parameters: the kinematic calibration's own selection.
    let kin = KinematicOptions {
        estimate_device_frame: true,
        fixed_device_frame: None,
        estimate_tool: true,
        use_orientation: true,
        ..options.kinematic.clone()
    };
    let rows = selection_rows(model, &nominal, joints, &start, &kin)?;
    let refs: Vec<&PoseMeasurement> = rows.iter().collect();
    let (layout, free_all, _) = identifiable_candidates(model, &refs, &kin)?;
    let robot_idx: Vec<usize> =
        free_all.iter().copied().filter(|i| layout.offsets.contains(i) || layout.model.contains(i)).collect();
    let start_values = layout.start_values(model);
    let mut model_cols = Vec::new();
    let mut offset_cols = Vec::new();
    for (k, &i) in robot_idx.iter().enumerate() {
        if layout.offsets.contains(&i) {
            offset_cols.push((k, i - layout.offsets.start));
        } else {
            model_cols.push((k, layout.model_index[i - layout.model.start]));
        }
    }
    let map = Arc::new(RobotMap { model: model.clone(), model_cols, offset_cols, n: robot_idx.len() });
    let robot0: Vec<f64> = robot_idx.iter().map(|&i| start_values[i]).collect();
    let scales: Vec<f64> = robot_idx.iter().map(|&i| layout.scales[i]).collect();
    // 3. The solve: plain least squares, then the Huber loss.
    let sub = |r: &std::ops::Range<usize>| -> Vec<usize> {
        free_all.iter().filter(|&&i| r.contains(&i)).map(|i| i - r.start).collect()
    };
    let setup = Setup {
        map: map.clone(),
        frames: Arc::new(FrameMap {
            f0: start.world.transform.inverse(),
            x0: start.hand_eye.transform,
            frame_free: sub(&layout.frame),
            tool_free: sub(&layout.tool),
        }),
        scales,
        data,
        joints,
        options: &options.hand_eye,
    };
    let hopts = &options.hand_eye;
    let state0 = State { robot: robot0, frame: vec![0.0; 6], tool: vec![0.0; 6], camera: start.camera };
    let (mut p, b) = build(&setup, &state0, Loss::Squared)?;
    let first = p.solve(&hopts.solver).map_err(lsq_error)?;
    let mut iterations = first.summary.iterations;
    let mut summary = first.summary;
    if let Some(loss) = hopts.second_loss(robust_sigma(&p)?) {
        let state = read_back(&p, &b, &start.camera)?;
        let (p2, _) = build(&setup, &state, loss)?;
        p = p2;
        let second = p.solve(&hopts.solver).map_err(lsq_error)?;
        iterations += second.summary.iterations;
        summary = second.summary;
    }
    // 4. Covariance (the full inverse; each block's part is its marginal covariance).
    let cov = p.covariance().map_err(lsq_error)?;
    let block = |id| cov.block(id).ok_or_else(|| CalibError::Numeric("covariance block missing".into()));
    let state = read_back(&p, &b, &start.camera)?;
    let robot = state.robot.clone();
    let robot_cov = block(b.robot)?;
    let cam_cov = block(b.camera)?;
    let (w, x) = setup.frames.w_and_x(&state.frame, &state.tool);
    let (m_w, m_x) = setup.frames.jacobians(&state.frame, &state.tool);
    let world_cov = chart_covariance(&m_w, &setup.frames.frame_free, cov.block(b.frame));
    let hand_eye_cov = chart_covariance(&m_x, &setup.frames.tool_free, cov.block(b.tool));
    let camera = state.camera;
    // 5. The calibrated model and the figures.
    let (m, _) = map.apply(&robot, &vec![0.0; model.dof()]).map_err(lsq_error)?;
    let mut joint_offsets = vec![0.0; model.dof()];
    for &(k, j) in &map.offset_cols {
        joint_offsets[j] = robot[k];
    }
    let calibrated = CalibratedModel {
        model: m,
        device_frame: w.inverse(),
        tool: x,
        joint_offsets,
        orientation_calibrated: true,
        effects: Vec::new(),
        load_model: model.clone(),
    };
    let mut views = data.views.clone();
    for (v, q) in views.iter_mut().zip(joints) {
        v.t_base_flange = calibrated.device_frame.inverse() * calibrated.predict(q)? * x.inverse();
    }
    let fallback = hopts.fallback_corner_sigma_px;
    let pnp = pnp_poses(&camera, &data.target_points_m, &views, fallback);
    let figures = chain_figures(data.mount, &camera, &data.target_points_m, &views, &pnp, &Chain { x, w, scale: 1.0 });
    let mut params = Vec::new();
    let mut free = Vec::new();
    for (i, &start_value) in start_values.iter().enumerate().take(layout.model.end).skip(layout.offsets.start) {
        let k = robot_idx.iter().position(|&r| r == i);
        let std = k.map(|k| robot_cov[(k, k)].max(0.0).sqrt());
        let value = k.map_or(start_value, |k| robot[k]);
        if k.is_some() {
            free.push(params.len());
        }
        params.push(ParamResult {
            name: layout.names[i].clone(),
            unit: layout.units[i],
            start: start_value,
            value,
            std,
            free: k.is_some(),
            fixed_because: k.is_none().then(|| {
                if options.kinematic.joint_offsets || !layout.offsets.contains(&i) {
                    "not identifiable from these measurements (redundant with the kept parameters)".to_string()
                } else {
                    "joint offsets not identified (option)".to_string()
                }
            }),
            nu: std.map(|s| (value - start_value).abs() / s),
        });
    }
    Ok(JointCalibration {
        mount: data.mount,
        calibrated,
        camera,
        camera_std: (0..cam_cov.nrows()).map(|i| cam_cov[(i, i)].max(0.0).sqrt()).collect(),
        hand_eye: TransformEstimate { transform: x, covariance: hand_eye_cov },
        world: TransformEstimate { transform: w, covariance: world_cov },
        layout,
        params,
        free,
        robot_covariance: robot_cov,
        s0: cov.s0,
        figures,
        start,
        iterations,
        termination: summary.termination.clone(),
        n_downweighted: summary.downweighted_blocks,
    })
}

#[cfg(test)]
mod tests;
