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
//!
//! # Rigs
//! [`rig::calibrate_joint_rig`] poses the same problem with N cameras: camera 0 is the
//! reference above, each further camera `k` adds its own camera block and `T_camk_cam0`, and
//! its corners go through the same corner residual with the point carried into camera `k`. With
//! one camera it is this module's problem, block for block.

use std::sync::Arc;

use nalgebra::{DMatrix, Isometry3, Matrix2, Matrix6};
use serde::Serialize;

use ferrocal_lsq::{BlockId, Loss, LsqError, Problem, Se3};
use ferrocal_robot::{Kinematics, RobotModel};
use ferrocal_vision::camera::CameraModel;

use super::evaluate::{chain_figures, Chain, ChainFigures};
use super::refine::pnp_poses;
use super::residual::{camera_with, whitening};
use super::{calibrate_hand_eye, HandEyeData, HandEyeOptions, HandEyeResult, HandEyeView, Mount, TransformEstimate};
use crate::error::{CalibError, Result};
use crate::file::CalibrationFile;
#[cfg(test)]
use crate::frames::exp6;
use crate::kinematic::correct::Uncertainty;
use crate::kinematic::{identifiable_candidates, CalibratedModel, KinematicOptions, ParamResult, StateLayout};
use crate::measurement::{PoseMeasurement, Split};
use corner::RobotCorner;
#[cfg(test)]
use ferrocal_robot::Parameterized;
use maps::{FrameMap, RobotMap};
#[cfg(test)]
use nalgebra::{Point2, Point3, Vector3};
use subspace::Subspace;

mod corner;
mod lack_of_fit;
mod maps;
pub mod rig;
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
    /// The covariance of the device frame, the tool and the robot parameters together (with
    /// their cross terms; the camera marginalised), by the kinematic calibration's names: what a
    /// corrected command's landing uncertainty comes from.
    #[serde(skip)]
    pub uncertainty: Uncertainty,
    /// The training views as rows of the device frame: joint readings and the calibrated model's
    /// target position (the region the calibration covers, the poses its nominal frames are
    /// fitted over).
    #[serde(skip)]
    pub train_rows: Vec<PoseMeasurement>,
}

impl JointCalibration {
    /// The calibration file `ferrocal evaluate` reads (`robot_spec`: the model as given).
    pub fn file(&self, robot_spec: &str) -> CalibrationFile {
        let rows: Vec<&PoseMeasurement> = self.train_rows.iter().collect();
        CalibrationFile::delivered(robot_spec, &self.calibrated, &rows, Some(self.uncertainty.clone()))
            .unwrap_or_else(|_| CalibrationFile::new(robot_spec, &self.calibrated))
    }

    /// Standard deviation of the free robot parameter `name`, when it is free.
    pub fn std_of(&self, name: &str) -> Option<f64> {
        self.params.iter().find(|p| p.name == name).and_then(|p| p.std)
    }
}

/// One camera's part of the joint problem: its recording and the joint readings of its views
/// (camera 0, the reference, first).
pub(super) struct CamInput<'a> {
    pub(super) data: &'a HandEyeData,
    pub(super) joints: &'a [Vec<f64>],
}

/// A further camera `k` of a rig as the core solve returns it.
pub(super) struct OtherCamera {
    pub(super) camera: CameraModel,
    pub(super) camera_std: Vec<f64>,
    /// `T_camk_cam0` with its covariance (the `Se3` block's tangent `[t, r]`).
    pub(super) t_cam_cam0: TransformEstimate,
    pub(super) figures: ChainFigures,
}

/// The name of camera `k`'s view `name` in the problem (camera 0's views keep their names).
fn view_key(k: usize, name: &str) -> String {
    if k == 0 {
        name.to_string()
    } else {
        format!("cam{k}.{name}")
    }
}

/// The measurement table the parameter selection runs on: every training image's target pose
/// in the device frame (`W^-1 FK X`, the reference camera's `W`) from the hand-eye start, with
/// the options' sigmas; the training images of every camera of a rig.
fn selection_rows(
    model: &RobotModel,
    cams: &[CamInput],
    start: &HandEyeResult,
    opts: &KinematicOptions,
) -> Result<Vec<PoseMeasurement>> {
    let w_inv = start.world.transform.inverse();
    let mut rows = Vec::new();
    for (k, cam) in cams.iter().enumerate() {
        for (v, q) in cam.data.views.iter().zip(cam.joints).filter(|(v, _)| v.split == Split::Train) {
            let t = w_inv * model.forward(q)? * start.hand_eye.transform;
            let mut r = PoseMeasurement::new(view_key(k, &v.name), q.clone(), t.translation.vector);
            r.orientation = Some(t.rotation);
            r.sigma_m = Some(opts.sigma_position_m);
            r.sigma_rad = Some(opts.sigma_orientation_rad);
            rows.push(r);
        }
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
    /// Per further camera: its camera block and its `T_camk_cam0` block.
    others: Vec<(BlockId, BlockId)>,
}

/// What every build of the problem shares.
struct Setup<'a> {
    map: Arc<RobotMap>,
    frames: Arc<FrameMap>,
    scales: Vec<f64>,
    cams: &'a [CamInput<'a>],
    options: &'a HandEyeOptions,
}

/// The values of the blocks.
struct State {
    robot: Vec<f64>,
    frame: Vec<f64>,
    tool: Vec<f64>,
    camera: CameraModel,
    /// Per further camera: the camera and `T_camk_cam0` (`Se3` values).
    others: Vec<(CameraModel, Vec<f64>)>,
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
    let add_camera = |p: &mut Problem, name: &str, camera: &CameraModel| -> Result<BlockId> {
        let cam = p.add_euclidean(name, camera.parameter_values()).map_err(lsq_error)?;
        p.set_scales(cam, (0..camera.n_parameters()).map(|i| if i < 4 { 1.0 } else { 1e-3 }).collect())
            .map_err(lsq_error)?;
        Ok(cam)
    };
    let cam = add_camera(&mut p, "camera", &state.camera)?;
    let fallback = whitening(&(Matrix2::identity() * setup.options.fallback_corner_sigma_px.powi(2)))
        .ok_or_else(|| CalibError::Data("the fallback corner sigma must be positive".into()))?;
    // Camera 0's corners, then each further camera's blocks and corners.
    let mut others = Vec::new();
    for (k, input) in setup.cams.iter().enumerate() {
        let (camera, rig) = if k == 0 {
            (state.camera, None)
        } else {
            let (camera, t_k0) = &state.others[k - 1];
            let c = add_camera(&mut p, &format!("camera{k}"), camera)?;
            let r = p.add_block(&format!("cam{k}_cam0"), t_k0.clone(), Arc::new(Se3)).map_err(lsq_error)?;
            p.set_scales(r, vec![1e-3; 6]).map_err(lsq_error)?;
            others.push((c, r));
            (*camera, Some((c, r)))
        };
        let data = input.data;
        for (v, q) in data.views.iter().zip(input.joints).filter(|(v, _)| v.split == Split::Train) {
            for ((&id, px), cov) in v.point_ids.iter().zip(&v.corners_px).zip(&v.covariances_px2) {
                let r = RobotCorner {
                    map: setup.map.clone(),
                    frames: setup.frames.clone(),
                    mount: data.mount,
                    q: q.clone(),
                    point_m: data.target_points_m[id],
                    detected_px: *px,
                    whiten: cov.and_then(|c| whitening(&c)).unwrap_or(fallback),
                    camera,
                };
                let name = format!("{}.c{id}", view_key(k, &v.name));
                match rig {
                    None => p.add_residual(&name, Box::new(r), &[rb, frame, tool, cam], loss),
                    Some((c, t)) => p.add_residual(&name, Box::new(r), &[rb, frame, tool, c, t], loss),
                }
                .map_err(lsq_error)?;
            }
        }
    }
    Ok((p, Blocks { robot: rb, frame, tool, camera: cam, others }))
}

fn read_back(p: &Problem, b: &Blocks, templates: &[CameraModel]) -> Result<State> {
    let mut others = Vec::new();
    for (&(c, r), template) in b.others.iter().zip(&templates[1..]) {
        others.push((camera_with(template, &p.block(c).values)?, p.block(r).values.clone()));
    }
    Ok(State {
        robot: p.block(b.robot).values.clone(),
        frame: p.block(b.frame).values.clone(),
        tool: p.block(b.tool).values.clone(),
        camera: camera_with(&templates[0], &p.block(b.camera).values)?,
        others,
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

/// Checks one camera's joint readings against its views and the model.
pub(super) fn check_joints(model: &RobotModel, data: &HandEyeData, joints: &[Vec<f64>]) -> Result<()> {
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
    Ok(())
}

/// `data` with the nominal robot's flange poses at `joints`.
pub(super) fn with_nominal_poses(model: &RobotModel, data: &HandEyeData, joints: &[Vec<f64>]) -> Result<HandEyeData> {
    let mut nominal = data.clone();
    for (v, q) in nominal.views.iter_mut().zip(joints) {
        v.t_base_flange = model.forward(q).map_err(|e| CalibError::Data(format!("image {}: {e}", v.name)))?;
    }
    Ok(nominal)
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
    check_joints(model, data, joints)?;
    if !options.kinematic.effects.is_empty() {
        return Err(CalibError::Data("the joint adjustment does not model effects".into()));
    }
    // 1. The hand-eye start with the nominal model's flange poses.
    let nominal = with_nominal_poses(model, data, joints)?;
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
    with_nominal_poses(model, data, joints)?;
    let (joint, _) = adjust(model, &[CamInput { data, joints }], start, &[], options)?;
    Ok(joint)
}

/// The core of [`calibrate_joint_from`] and of the rig's [`rig::calibrate_joint_rig_from`]:
/// camera 0 (the reference) with its hand-eye start, and each further camera with its starting
/// camera and `T_camk_cam0` (`others0`, one per camera after the first).
pub(super) fn adjust(
    model: &RobotModel,
    cams: &[CamInput],
    start: HandEyeResult,
    others0: &[(CameraModel, Isometry3<f64>)],
    options: &JointOptions,
) -> Result<(JointCalibration, Vec<OtherCamera>)> {
    let data = cams[0].data;
    // 2. The robot parameters: the kinematic calibration's own selection.
    let kin = KinematicOptions {
        estimate_device_frame: true,
        fixed_device_frame: None,
        estimate_tool: true,
        use_orientation: true,
        ..options.kinematic.clone()
    };
    let rows = selection_rows(model, cams, &start, &kin)?;
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
        cams,
        options: &options.hand_eye,
    };
    let hopts = &options.hand_eye;
    let templates: Vec<CameraModel> = std::iter::once(start.camera).chain(others0.iter().map(|o| o.0)).collect();
    let state0 = State {
        robot: robot0,
        frame: vec![0.0; 6],
        tool: vec![0.0; 6],
        camera: start.camera,
        others: others0.iter().map(|(c, t)| (*c, Se3::from_isometry(t).to_vec())).collect(),
    };
    let (mut p, b) = build(&setup, &state0, Loss::Squared)?;
    let first = p.solve(&hopts.solver).map_err(lsq_error)?;
    let mut iterations = first.summary.iterations;
    let mut summary = first.summary;
    if let Some(loss) = hopts.second_loss(robust_sigma(&p)?) {
        let state = read_back(&p, &b, &templates)?;
        let (p2, _) = build(&setup, &state, loss)?;
        p = p2;
        let second = p.solve(&hopts.solver).map_err(lsq_error)?;
        iterations += second.summary.iterations;
        summary = second.summary;
    }
    // 4. Covariance (the full inverse; each block's part is its marginal covariance).
    let cov = p.covariance().map_err(lsq_error)?;
    let block = |id| cov.block(id).ok_or_else(|| CalibError::Numeric("covariance block missing".into()));
    let state = read_back(&p, &b, &templates)?;
    let robot = state.robot.clone();
    let robot_cov = block(b.robot)?;
    let cam_cov = block(b.camera)?;
    let (w, x) = setup.frames.w_and_x(&state.frame, &state.tool);
    let (m_w, m_x) = setup.frames.jacobians(&state.frame, &state.tool);
    let world_cov = chart_covariance(&m_w, &setup.frames.frame_free, cov.block(b.frame));
    let hand_eye_cov = chart_covariance(&m_x, &setup.frames.tool_free, cov.block(b.tool));
    let mut uncertainty = {
        const AXES: [&str; 6] = ["x_m", "y_m", "z_m", "rx_rad", "ry_rad", "rz_rad"];
        let mut names = Vec::new();
        let mut idx = Vec::new();
        for (id, free, prefix) in
            [(b.frame, &setup.frames.frame_free, "frame."), (b.tool, &setup.frames.tool_free, "target_tool.")]
        {
            if let Some(o) = cov.index.offset(id) {
                for (k, &c) in free.iter().enumerate() {
                    names.push(format!("{prefix}{}", AXES[c]));
                    idx.push(o + k);
                }
            }
        }
        if let Some(o) = cov.index.offset(b.robot) {
            for (k, &i) in robot_idx.iter().enumerate() {
                names.push(layout.names[i].clone());
                idx.push(o + k);
            }
        }
        let covariance = idx.iter().map(|&i| idx.iter().map(|&j| cov.matrix[(i, j)]).collect()).collect();
        Uncertainty { names, covariance, unmodelled_sigma_m: 0.0, lack_of_fit_scale: 1.0 }
    };
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
    let fallback = hopts.fallback_corner_sigma_px;
    let chain_views = |input: &CamInput| -> Result<Vec<HandEyeView>> {
        let mut views = input.data.views.clone();
        for (v, q) in views.iter_mut().zip(input.joints) {
            v.t_base_flange = calibrated.device_frame.inverse() * calibrated.predict(q)? * x.inverse();
        }
        Ok(views)
    };
    let figures_of = |input: &CamInput, views: &[HandEyeView], camera: &CameraModel, chain: &Chain| {
        let pnp = pnp_poses(camera, &input.data.target_points_m, views, fallback);
        chain_figures(input.data.mount, camera, &input.data.target_points_m, views, &pnp, chain)
    };
    let chain0 = Chain { x, w, scale: 1.0 };
    let views0 = chain_views(&cams[0])?;
    let figures = figures_of(&cams[0], &views0, &camera, &chain0);
    // The landing covariance scaled by what whole views show the model missing.
    let lack = lack_of_fit::view_lack_of_fit(
        cams[0].data.mount,
        &camera,
        &cams[0].data.target_points_m,
        &views0,
        &chain0,
        fallback,
        uncertainty.names.len(),
    );
    if let Some((factor, _)) = lack {
        uncertainty.scale_by_lack_of_fit(factor);
    }
    let mut others = Vec::new();
    for (k, ((cam_k, t_k0), &(_, rig_id))) in state.others.iter().zip(&b.others).enumerate() {
        let t_k0 = Se3::to_isometry(t_k0);
        let chain = match data.mount {
            Mount::EyeToHand => Chain { x, w: w * t_k0.inverse(), scale: 1.0 },
            Mount::EyeInHand => Chain { x: x * t_k0.inverse(), w, scale: 1.0 },
        };
        let c_cov = block(b.others[k].0)?;
        let r_cov = block(rig_id)?;
        others.push(OtherCamera {
            camera: *cam_k,
            camera_std: (0..c_cov.nrows()).map(|i| c_cov[(i, i)].max(0.0).sqrt()).collect(),
            t_cam_cam0: TransformEstimate { transform: t_k0, covariance: Matrix6::from_fn(|i, j| r_cov[(i, j)]) },
            figures: figures_of(&cams[k + 1], &chain_views(&cams[k + 1])?, cam_k, &chain),
        });
    }
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
    let joint = JointCalibration {
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
        uncertainty,
        train_rows: Vec::new(),
    };
    let mut joint = joint;
    for cam in cams.iter() {
        for (v, q) in cam.data.views.iter().zip(cam.joints) {
            if v.split == Split::Test {
                continue;
            }
            let p = joint.calibrated.predict(q)?.translation.vector;
            let mut row = PoseMeasurement::new(v.name.clone(), q.clone(), p);
            row.split = Some(Split::Train);
            joint.train_rows.push(row);
        }
    }
    Ok((joint, others))
}

#[cfg(test)]
mod tests;
