//! The simulation study of the camera-based robot calibration against the tracker-calibrated
//! model (the [handeye] issue's comparison; the source, `methods.md` section 4, was 12 times
//! worse with cameras than with its tracker).
//!
//! # The cell
//! A UR5-like arm (`ur5` preset) with true kinematic errors, a fixed camera about 2 m away
//! looking at a chessboard plate on the flange (eye-to-hand), and a laser tracker seeing a
//! reflector on the same flange.
//! - True robot: [`crate::sim::TrueRobot`] with [`crate::sim::GeometricErrors`] offsets on
//!   exactly the model parameters the kinematic calibration's selection keeps free on the
//!   training poses (per-joint correction transforms: lengths with
//!   [`JointStudyConfig::length_sigma_mm`], angles with [`JointStudyConfig::angle_sigma_mrad`]),
//!   and on the joint zero offsets it keeps free (drawn as angles, placed on the true chain's
//!   `joint<k>.theta_offset_rad`, which is the same freedom).
//!   Errors in the other parameters would be absorbed into equivalent combinations of the free
//!   ones: the held-out figures would be the same, but the parameter-against-truth check would
//!   compare different things.
//! - Poses: random joint readings of the nominal model, kept when the whole plate lies in the
//!   image (8 px margin) and faces the camera within [`JointStudyConfig::max_view_angle_deg`];
//!   the training and held-out poses are drawn the same way (the held-out ones are new poses).
//! - Camera: 2448 x 2048 px, `f` = 2400 px, Brown-Conrady with 5 coefficients. Corners are the
//!   true chain's exact projections plus Gaussian noise of [`JointStudyConfig::corner_sigma_px`]
//!   per coordinate, with that covariance handed to the estimators: **the data come from the same
//!   model family as the estimators** (pinhole + Brown-5, a rigid flat plate with its nominal
//!   spacing, rigid robot kinematics of the same error model, no robot repeatability noise, no
//!   detector bias). What the study measures is the information in the two kinds of data and
//!   what each estimator makes of it, not robustness to effects it leaves out.
//! - Tracker: [`crate::sim::TrackerConfig`], 10 µm + 3 µm/m per axis (about 0.015 mm at the
//!   cell's distances), position of a reflector fixed on the flange.
//!
//! # The four models, scored on the held-out tracker poses
//! (a) the tracker-calibrated model: [`ferrocal_calib::kinematic::calibrate`] on the tracker's
//! measurements at the training poses (positions only); (b) the two-step camera path: the camera
//! calibrated from the training images, every image's pose by PnP with its covariance
//! ([`crate::recording::measure_views`], what `ferrocal measure` does), then `calibrate` on that
//! table (positions and orientations, whitened by the pose covariances); (c) the joint adjustment
//! ([`ferrocal_calib::handeye::calibrate_joint`], scored through its calibration file); (d) the
//! nominal model; and (b') the two-step path with the true camera given, which shows what the
//! camera calibration costs it. Every model is scored
//! like `evaluate --refit-frame`: the tracker's frame and the reflector's position on the flange
//! are refitted on the held-out table (9 numbers, [`ferrocal_calib::kinematic::refit_frame`]),
//! every robot parameter kept, then the position errors at the held-out poses.

use nalgebra::{Isometry3, Matrix2, Point2, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::Serialize;

use ferrocal_calib::handeye::{calibrate_joint, calibrate_joint_from, HandEyeData, HandEyeView, JointOptions, Mount};
use ferrocal_calib::kinematic::{
    calibrate, identifiable_candidates, refit_frame, CalibratedModel, KinematicOptions, ParamResult,
};
use ferrocal_calib::{PoseMeasurement, Split};
use ferrocal_robot::{Kinematics, Parameterized, RobotModel};
use ferrocal_vision::calib::CalibrationOptions;
use ferrocal_vision::camera::{CameraModel, Distortion, ImageSize, Intrinsics};

use crate::error::{DatasetError, Result};
use crate::recording::{measure_views, pose_row, RecordingOptions};
use crate::sim::{Conditions, GeometricErrors, TrackerConfig, TrueRobot};

/// The study's settings.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct JointStudyConfig {
    /// The robot preset.
    pub robot: String,
    /// Training poses (images and tracker readings).
    pub n_train: usize,
    /// Held-out poses (tracker readings).
    pub n_test: usize,
    /// Inner corners of the plate (columns, rows).
    pub grid: (u32, u32),
    /// Corner spacing, metres.
    pub spacing_m: f64,
    /// The true camera.
    pub camera: CameraModel,
    /// Where the camera is: eye-to-hand (a fixed camera, the plate on the flange; the study's
    /// main cell) or eye-in-hand (the camera on the flange, the plate fixed in the cell).
    pub mount: Mount,
    /// `T_base_camera` (eye-to-hand).
    pub t_base_camera: Isometry3<f64>,
    /// `T_flange_target` (eye-to-hand; grid origin at the first corner).
    pub t_flange_target: Isometry3<f64>,
    /// `T_flange_camera` (eye-in-hand).
    pub t_flange_camera: Isometry3<f64>,
    /// `T_base_target` (eye-in-hand; grid origin at the first corner).
    pub t_base_target: Isometry3<f64>,
    /// Largest angle between the plate's normal and the direction to the camera, degrees.
    pub max_view_angle_deg: f64,
    /// Standard deviation of each corner coordinate, pixels.
    pub corner_sigma_px: f64,
    /// The tracker.
    pub tracker: TrackerConfig,
    /// Standard deviation of the true robot's length errors, millimetres.
    pub length_sigma_mm: f64,
    /// Standard deviation of the true robot's angle errors, milliradians.
    pub angle_sigma_mrad: f64,
}

/// The camera frame at `eye` looking at `at` (its `z` axis), `up` giving its `-y` side.
pub(crate) fn looking_at(eye: Vector3<f64>, at: Vector3<f64>, up: Vector3<f64>) -> Isometry3<f64> {
    let z = (at - eye).normalize();
    let x = z.cross(&up).normalize();
    let y = z.cross(&x);
    let r = Rotation3::from_basis_unchecked(&[x, y, z]);
    Isometry3::from_parts(Translation3::from(eye), UnitQuaternion::from_rotation_matrix(&r))
}

impl JointStudyConfig {
    /// The UR5 cell of the module documentation: 60 training and 40 held-out poses, a 9 x 7
    /// plate at 30 mm 40 mm off the flange, the camera 2 m from the workspace, 0.1 px corner
    /// noise, true errors of 0.5 mm and 0.5 mrad.
    pub fn ur5() -> Self {
        let (cols, rows, spacing) = (9u32, 7u32, 0.03);
        let centre = Vector3::new((cols - 1) as f64, (rows - 1) as f64, 0.0) * (0.5 * spacing);
        Self {
            robot: "ur5".into(),
            n_train: 60,
            n_test: 40,
            grid: (cols, rows),
            spacing_m: spacing,
            camera: CameraModel {
                intrinsics: Intrinsics { fx_px: 2400.0, fy_px: 2401.5, cx_px: 1230.0, cy_px: 1018.0 },
                distortion: Distortion::Brown5 { k1: -0.11, k2: 0.09, p1: 0.0003, p2: -0.0002, k3: -0.02 },
                image_size: ImageSize { width_px: 2448, height_px: 2048 },
            },
            mount: Mount::EyeToHand,
            t_base_camera: looking_at(
                Vector3::new(2.1, 0.6, 1.1),
                Vector3::new(0.35, 0.0, 0.35),
                Vector3::new(0.0, 0.0, 1.0),
            ),
            t_flange_target: Isometry3::from_parts(
                Translation3::from(Vector3::new(0.0, 0.0, 0.04) - centre),
                UnitQuaternion::identity(),
            ),
            // The camera 60 mm off the flange's axis and 50 mm out, looking along it.
            t_flange_camera: Isometry3::from_parts(
                Translation3::from(Vector3::new(0.0, 0.06, 0.05)),
                UnitQuaternion::identity(),
            ),
            // The plate flat on the table beside the robot, facing up.
            t_base_target: Isometry3::from_parts(
                Translation3::from(Vector3::new(0.45, -0.1, 0.0) - centre),
                UnitQuaternion::identity(),
            ),
            max_view_angle_deg: 60.0,
            corner_sigma_px: 0.1,
            tracker: TrackerConfig {
                position_m: [1.6, -1.6, 0.6],
                rpy_deg: [0.0, 0.0, 135.0],
                sigma_const_um: 10.0,
                sigma_per_m_um: 3.0,
                six_dof: false,
                sigma_angle_mrad: 0.0,
                reflector_in_tool_m: [0.06, 0.05, 0.045],
            },
            length_sigma_mm: 0.5,
            angle_sigma_mrad: 0.5,
        }
    }

    /// The same cell with the camera on the flange (0.05 m out, 0.06 m off the axis) and the
    /// plate on the table beside the robot, facing up; the tracker still sees a reflector on the
    /// flange.
    pub fn ur5_eye_in_hand() -> Self {
        Self { mount: Mount::EyeInHand, ..Self::ur5() }
    }

    /// `X`: `T_flange_target` (eye-to-hand) or `T_flange_camera` (eye-in-hand).
    pub fn hand_eye(&self) -> Isometry3<f64> {
        match self.mount {
            Mount::EyeToHand => self.t_flange_target,
            Mount::EyeInHand => self.t_flange_camera,
        }
    }

    /// `W`: `T_base_camera` (eye-to-hand) or `T_base_target` (eye-in-hand).
    pub fn world(&self) -> Isometry3<f64> {
        match self.mount {
            Mount::EyeToHand => self.t_base_camera,
            Mount::EyeInHand => self.t_base_target,
        }
    }

    /// The grid's points, metres, plate frame.
    pub(crate) fn points(&self) -> Vec<Point3<f64>> {
        let (cols, rows) = self.grid;
        (0..rows)
            .flat_map(|r| (0..cols).map(move |c| (c, r)))
            .map(|(c, r)| Point3::new(c as f64 * self.spacing_m, r as f64 * self.spacing_m, 0.0))
            .collect()
    }

    /// Whether the plate on `t_base_flange` faces the camera and lies wholly in the image.
    pub(crate) fn visible(&self, t_base_flange: &Isometry3<f64>, points: &[Point3<f64>]) -> bool {
        if self.mount == Mount::EyeInHand {
            return self.visible_in_hand(t_base_flange, points);
        }
        let t_base_target = t_base_flange * self.t_flange_target;
        let normal = t_base_target.rotation * Vector3::z();
        let to_cam = (self.t_base_camera.translation.vector - t_base_target.translation.vector).normalize();
        if normal.dot(&to_cam) < self.max_view_angle_deg.to_radians().cos() || t_base_target.translation.z < 0.05 {
            return false;
        }
        let t_cam_target = self.t_base_camera.inverse() * t_base_target;
        let (w, h) = (f64::from(self.camera.image_size.width_px), f64::from(self.camera.image_size.height_px));
        points.iter().all(|p| {
            self.camera
                .project(&(t_cam_target * p))
                .is_ok_and(|px| px.x > 8.0 && px.y > 8.0 && px.x < w - 8.0 && px.y < h - 8.0)
        })
    }
}

impl JointStudyConfig {
    /// [`JointStudyConfig::visible`] with the camera on the flange: the camera above the floor,
    /// the plate facing it within the largest view angle and wholly in the image.
    fn visible_in_hand(&self, t_base_flange: &Isometry3<f64>, points: &[Point3<f64>]) -> bool {
        let t_base_cam = t_base_flange * self.t_flange_camera;
        let normal = self.t_base_target.rotation * Vector3::z();
        let to_cam = (t_base_cam.translation.vector - self.t_base_target.translation.vector).normalize();
        if normal.dot(&to_cam) < self.max_view_angle_deg.to_radians().cos() || t_base_cam.translation.z < 0.05 {
            return false;
        }
        let t_cam_target = t_base_cam.inverse() * self.t_base_target;
        let (w, h) = (f64::from(self.camera.image_size.width_px), f64::from(self.camera.image_size.height_px));
        points.iter().all(|p| {
            self.camera
                .project(&(t_cam_target * p))
                .is_ok_and(|px| px.x > 8.0 && px.y > 8.0 && px.x < w - 8.0 && px.y < h - 8.0)
        })
    }
}

/// One random joint reading in the study's UR5-like ranges.
pub(crate) fn random_joints(rng: &mut ChaCha8Rng) -> Vec<f64> {
    vec![
        rng.random_range(-1.2..1.2),
        rng.random_range(-2.4..-0.4),
        rng.random_range(0.3..2.4),
        rng.random_range(-3.1..3.1),
        rng.random_range(-3.1..3.1),
        rng.random_range(-3.1..3.1),
    ]
}

/// Random joint readings (UR5-like ranges) whose plate the camera sees, for the nominal model.
pub(crate) fn draw_poses(
    config: &JointStudyConfig,
    model: &RobotModel,
    n: usize,
    rng: &mut ChaCha8Rng,
) -> Result<Vec<Vec<f64>>> {
    let points = config.points();
    let mut out = Vec::with_capacity(n);
    let mut tries = 0;
    while out.len() < n {
        tries += 1;
        if tries > 20_000 * n.max(1) {
            return Err(DatasetError::Input("joint study: the camera rarely sees the plate; check the cell".into()));
        }
        let q = random_joints(rng);
        let Ok(t) = model.forward(&q) else { continue };
        if config.visible(&t, &points) {
            out.push(q);
        }
    }
    Ok(out)
}

/// Held-out position errors of one model after the frame refit.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Score {
    /// Mean position error, mm.
    pub mean_mm: f64,
    /// RMS position error, mm.
    pub rms_mm: f64,
    /// Largest position error, mm.
    pub max_mm: f64,
}

/// How many free robot parameters lie within 3 standard deviations of the truth.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Coverage {
    /// Within 3 sigma.
    pub within_3sigma: usize,
    /// Free robot parameters compared.
    pub n: usize,
    /// Largest `|estimate - truth| / sigma`.
    pub max_z: f64,
}

impl Coverage {
    /// The fraction within 3 sigma.
    pub fn fraction(&self) -> f64 {
        self.within_3sigma as f64 / self.n.max(1) as f64
    }
}

/// One seed's figures.
#[derive(Clone, Debug, Serialize)]
pub struct JointStudyRun {
    /// The seed.
    pub seed: u64,
    /// (a) the tracker-calibrated model.
    pub tracker: Score,
    /// (b) the two-step camera path.
    pub two_step: Score,
    /// (b') the two-step path with the true camera given (not calibrated from the images).
    pub two_step_true_camera: Score,
    /// (c) the joint adjustment.
    pub joint: Score,
    /// (d) the nominal model.
    pub nominal: Score,
    /// Noise floor of the held-out table: `sqrt(3) * RMS sigma` of the tracker, mm.
    pub noise_floor_mm: f64,
    /// Robot parameters of (c) against the truth in its gauge (the noise-free adjustment from the
    /// same start).
    pub joint_coverage: Coverage,
    /// Robot parameters of (c) against the truth as drawn (gauge ignored).
    pub joint_raw_coverage: Coverage,
    /// Robot parameters of (b) against the truth as drawn (gauge ignored).
    pub two_step_coverage: Coverage,
    /// Robot parameters of (a) against the truth as drawn (gauge ignored; its own selection:
    /// positions only).
    pub tracker_coverage: Coverage,
    /// Free robot parameters of the joint adjustment and of the tracker calibration.
    pub n_params_joint: usize,
    /// Free robot parameters of the tracker calibration.
    pub n_params_tracker: usize,
    /// Training chain RMS of the joint adjustment, pixels.
    pub joint_train_rms_px: f64,
    /// Its a-posteriori standard deviation of unit weight.
    pub joint_s0: f64,
    /// Training chain RMS of the hand-eye start with the nominal robot, pixels.
    pub start_train_rms_px: f64,
    /// Error of the joint adjustment's focal length, pixels.
    pub joint_fx_error_px: f64,
    /// Its standard deviation, pixels.
    pub joint_fx_std_px: f64,
    /// Error of the focal length the two-step path calibrated from the training images, pixels.
    pub two_step_fx_error_px: f64,
    /// Its standard deviation, pixels.
    pub two_step_fx_std_px: f64,
}

impl JointStudyRun {
    /// RMS of (c) over RMS of (a).
    pub fn joint_ratio(&self) -> f64 {
        self.joint.rms_mm / self.tracker.rms_mm
    }

    /// RMS of (b) over RMS of (a).
    pub fn two_step_ratio(&self) -> f64 {
        self.two_step.rms_mm / self.tracker.rms_mm
    }
}

pub(crate) fn score(cm: &CalibratedModel, test: &[&PoseMeasurement]) -> Result<Score> {
    let fail = |e: ferrocal_calib::CalibError| DatasetError::Input(format!("joint study: {e}"));
    let (refit, _) = refit_frame(cm, test, 2e-5).map_err(fail)?;
    let s = refit.evaluate(test).map_err(fail)?;
    Ok(Score { mean_mm: s.mean_mm, rms_mm: s.rms_mm, max_mm: s.max_mm })
}

/// The free robot parameters of `params` against the same parameters of `truth` (the
/// noise-free adjustment in the same gauge).
pub(crate) fn coverage(params: &[ParamResult], truth: &[ParamResult]) -> Coverage {
    let mut c = Coverage::default();
    for p in params.iter().filter(|p| p.free) {
        let (Some(sd), Some(t)) = (p.std, truth.iter().find(|t| t.name == p.name)) else { continue };
        let z = (p.value - t.value).abs() / sd;
        c.n += 1;
        c.within_3sigma += usize::from(z <= 3.0);
        c.max_z = c.max_z.max(z);
    }
    c
}

/// The free robot parameters of `params` (model parameters and joint offsets) against the true
/// robot's values as drawn (`truth` by model parameter name; a joint offset is compared with
/// the true chain's `joint<k>.theta_offset_rad`, whose nominal value is zero in the `ur5`
/// preset), without regard to the gauge: parameters redundant with a frame or tool coordinate
/// held at its start value differ from these by the start's error.
pub(crate) fn coverage_raw(params: &[ParamResult], truth: &[(String, f64)]) -> Coverage {
    let mut c = Coverage::default();
    for p in params.iter().filter(|p| p.free && !p.name.starts_with("frame.") && !p.name.starts_with("target_tool.")) {
        let Some(sd) = p.std else { continue };
        let t = if let Some(k) = p.name.strip_prefix("offset.q").and_then(|r| r.strip_suffix("_rad")) {
            let name = format!("joint{k}.theta_offset_rad");
            truth.iter().find(|(n, _)| *n == name).map_or(0.0, |(_, v)| *v)
        } else {
            match truth.iter().find(|(n, _)| *n == p.name) {
                Some((_, v)) => *v,
                None => continue,
            }
        };
        let z = (p.value - t).abs() / sd;
        c.n += 1;
        c.within_3sigma += usize::from(z <= 3.0);
        c.max_z = c.max_z.max(z);
    }
    c
}

/// One seed's cell: the nominal model, the true robot, the training and held-out joint readings
/// and the random state after them (the rest of the seed's draws continue from it).
pub(crate) struct Cell {
    pub(crate) nominal: RobotModel,
    pub(crate) truth: TrueRobot,
    pub(crate) truth_values: Vec<(String, f64)>,
    pub(crate) train_q: Vec<Vec<f64>>,
    pub(crate) test_q: Vec<Vec<f64>>,
    pub(crate) rng: ChaCha8Rng,
}

/// Draws the cell of `seed` (poses, then the true robot's errors on the parameters the
/// selection keeps free on the training poses).
pub(crate) fn draw_cell(config: &JointStudyConfig, seed: u64) -> Result<Cell> {
    let nominal = RobotModel::load(&config.robot).map_err(|e| DatasetError::Config(e.to_string()))?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let train_q = draw_poses(config, &nominal, config.n_train, &mut rng)?;
    let test_q = draw_poses(config, &nominal, config.n_test, &mut rng)?;
    let (truth, truth_values) = draw_truth(config, &nominal, &train_q, &mut rng).map_err(|e| match e {
        DatasetError::Input(m) => DatasetError::Input(format!("joint study, seed {seed}: {m}")),
        other => other,
    })?;
    Ok(Cell { nominal, truth, truth_values, train_q, test_q, rng })
}

/// The true robot of a cell: errors on the parameters the selection keeps free on the training
/// poses `train_q` (the camera's table of the nominal chain, with orientations).
pub(crate) fn draw_truth(
    config: &JointStudyConfig,
    nominal: &RobotModel,
    train_q: &[Vec<f64>],
    rng: &mut ChaCha8Rng,
) -> Result<(TrueRobot, Vec<(String, f64)>)> {
    let fail = |e: ferrocal_calib::CalibError| DatasetError::Input(e.to_string());
    // The true robot: errors on the parameters the selection keeps free on the training poses
    // (the camera's table of the nominal chain, with orientations: `W^-1 FK X`, the layout of
    // the joint adjustment for either mount).
    let x = config.hand_eye();
    let w_inv = config.world().inverse();
    let sel_rows: Vec<PoseMeasurement> = train_q
        .iter()
        .enumerate()
        .map(|(k, q)| {
            let t = w_inv * nominal.forward(q).expect("drawn with this model") * x;
            let mut r = PoseMeasurement::new(format!("{k}"), q.clone(), t.translation.vector);
            r.orientation = Some(t.rotation);
            r
        })
        .collect();
    let refs: Vec<&PoseMeasurement> = sel_rows.iter().collect();
    let (layout, free, _) = identifiable_candidates(nominal, &refs, &KinematicOptions::default()).map_err(fail)?;
    let params = nominal.parameters();
    let mut errors = GeometricErrors::default();
    let len = Normal::new(0.0, config.length_sigma_mm * 1e-3).map_err(|e| DatasetError::Input(e.to_string()))?;
    let ang = Normal::new(0.0, config.angle_sigma_mrad * 1e-3).map_err(|e| DatasetError::Input(e.to_string()))?;
    // Joint zero offsets the selection keeps: the true chain's DH angle offsets (the same freedom).
    let revolute_offsets = free.iter().filter(|&&i| layout.offsets.contains(&i) && layout.names[i].ends_with("_rad"));
    for &i in revolute_offsets {
        let k = i - layout.offsets.start + 1;
        let name = format!("joint{k}.theta_offset_rad");
        if params.iter().any(|p| p.name == name) {
            errors.offsets.insert(name, ang.sample(rng));
        }
    }
    for &i in free.iter().filter(|&&i| layout.model.contains(&i)) {
        let p = &params[layout.model_index[i - layout.model.start]];
        let v = match p.unit {
            ferrocal_robot::Unit::Metre => len.sample(rng),
            _ => ang.sample(rng),
        };
        errors.offsets.insert(p.name.clone(), v);
    }
    let truth = TrueRobot::new(nominal.clone(), &errors, vec![], 0.0, rng)?;
    let truth_values: Vec<(String, f64)> =
        truth.truth.parameters().into_iter().map(|p| (p.name.clone(), p.value)).collect();
    Ok((truth, truth_values))
}

/// One seed of the study (see the module documentation).
pub fn run_joint_study(config: &JointStudyConfig, seed: u64) -> Result<JointStudyRun> {
    let fail = |e: ferrocal_calib::CalibError| DatasetError::Input(format!("joint study, seed {seed}: {e}"));
    let Cell { nominal, truth, truth_values, train_q, test_q, mut rng } = draw_cell(config, seed)?;
    let points = config.points();
    let x = config.hand_eye();
    let w_inv = config.world().inverse();
    let cond = Conditions { temp_c: 20.0, dir: vec![0; nominal.dof()], ..Default::default() };
    // Images of the training poses (exact projections plus noise) and tracker readings of all.
    let noise = Normal::new(0.0, config.corner_sigma_px).map_err(|e| DatasetError::Input(e.to_string()))?;
    let cov = Matrix2::identity() * config.corner_sigma_px.powi(2);
    let mut views = Vec::new();
    let mut exact_corners = Vec::new();
    let tracker_rows = |qs: &[Vec<f64>], rng: &mut ChaCha8Rng, tag: &str| -> Result<Vec<PoseMeasurement>> {
        qs.iter()
            .enumerate()
            .map(|(k, q)| {
                let t = truth.tool_pose(q, &cond)?;
                let r = config.tracker.measure(&t, rng);
                let mut m = PoseMeasurement::new(format!("{tag}{k:03}"), q.clone(), r.position_m);
                m.sigma_m = Some(r.sigma_m);
                Ok(m)
            })
            .collect()
    };
    let train_tracker = tracker_rows(&train_q, &mut rng, "train")?;
    let test_tracker = tracker_rows(&test_q, &mut rng, "test")?;
    for (k, q) in train_q.iter().enumerate() {
        let t_cam_target = match config.mount {
            Mount::EyeToHand => w_inv * truth.tool_pose(q, &cond)? * x,
            Mount::EyeInHand => x.inverse() * truth.tool_pose(q, &cond)?.inverse() * config.world(),
        };
        let mut corners = Vec::with_capacity(points.len());
        let mut exact = Vec::with_capacity(points.len());
        for p in &points {
            let px = config.camera.project(&(t_cam_target * p)).map_err(|e| DatasetError::Input(e.to_string()))?;
            exact.push(px);
            corners.push(Point2::new(px.x + noise.sample(&mut rng), px.y + noise.sample(&mut rng)));
        }
        exact_corners.push(exact);
        views.push(HandEyeView {
            name: format!("img{k:03}"),
            split: Split::Train,
            t_base_flange: nominal.forward(q).map_err(|e| DatasetError::Input(e.to_string()))?,
            image_size: config.camera.image_size,
            point_ids: (0..points.len()).collect(),
            covariances_px2: vec![Some(cov); points.len()],
            corners_px: corners,
        });
    }
    let data = HandEyeData { mount: config.mount, target_points_m: points, views };
    let test: Vec<&PoseMeasurement> = test_tracker.iter().collect();
    // (a) The tracker calibration.
    let train_refs: Vec<&PoseMeasurement> = train_tracker.iter().collect();
    let tracker_cal = calibrate(&nominal, &train_refs, &KinematicOptions::default()).map_err(fail)?;
    // (b) The two-step path: camera from the training images, PnP with covariance, calibrate.
    let rec_opts = RecordingOptions {
        mount: config.mount,
        camera: None,
        calibration: CalibrationOptions::default(),
        corner_sigma_px: config.corner_sigma_px,
    };
    let (two_step_camera, measured, _) = measure_views(&data, &rec_opts)?;
    let cam_rows: Vec<PoseMeasurement> = measured.iter().map(|(k, pose)| pose_row(pose, &train_q[*k])).collect();
    let cam_refs: Vec<&PoseMeasurement> = cam_rows.iter().collect();
    let two_step = calibrate(&nominal, &cam_refs, &KinematicOptions::default()).map_err(fail)?;
    // (b') The same with the true camera given: what the camera calibration costs the two-step.
    let (_, measured, _) = measure_views(&data, &RecordingOptions { camera: Some(config.camera), ..rec_opts })?;
    let cam_rows: Vec<PoseMeasurement> = measured.iter().map(|(k, pose)| pose_row(pose, &train_q[*k])).collect();
    let cam_refs: Vec<&PoseMeasurement> = cam_rows.iter().collect();
    let two_step_true = calibrate(&nominal, &cam_refs, &KinematicOptions::default()).map_err(fail)?;
    // (c) The joint adjustment.
    let options = JointOptions::default();
    let joint = calibrate_joint(&nominal, &data, &train_q, &options).map_err(fail)?;
    // The truth in the joint adjustment's gauge: the same adjustment, from the same start, of
    // the noise-free corners. Robot parameters that are redundant with a frame or tool
    // coordinate the selection holds at its start value (the last joint's correction and the
    // target on the flange, say) are defined only relative to that start.
    let mut exact_data = data.clone();
    for (v, c) in exact_data.views.iter_mut().zip(exact_corners) {
        v.corners_px = c;
    }
    let truth_gauge =
        calibrate_joint_from(&nominal, &exact_data, &train_q, joint.start.clone(), &options).map_err(fail)?;
    // The joint adjustment is scored through its calibration file (what `evaluate` reads).
    let file = joint.file(&config.robot);
    let json = serde_json::to_string(&file)?;
    let joint_model =
        serde_json::from_str::<ferrocal_calib::file::CalibrationFile>(&json)?.apply(&nominal).map_err(fail)?;
    let floor = (test.iter().map(|r| 3.0 * r.sigma_m.unwrap_or(0.0).powi(2)).sum::<f64>() / test.len() as f64).sqrt();
    Ok(JointStudyRun {
        seed,
        tracker: score(&tracker_cal.calibrated, &test)?,
        two_step: score(&two_step.calibrated, &test)?,
        two_step_true_camera: score(&two_step_true.calibrated, &test)?,
        joint: score(&joint_model, &test)?,
        nominal: score(&CalibratedModel::nominal(nominal.clone()), &test)?,
        noise_floor_mm: floor * 1e3,
        joint_coverage: coverage(&joint.params, &truth_gauge.params),
        joint_raw_coverage: coverage_raw(&joint.params, &truth_values),
        two_step_coverage: coverage_raw(&two_step.params, &truth_values),
        tracker_coverage: coverage_raw(&tracker_cal.params, &truth_values),
        n_params_joint: joint.free.len(),
        n_params_tracker: tracker_cal
            .free
            .iter()
            .filter(|&&i| tracker_cal.layout.model.contains(&i) || tracker_cal.layout.offsets.contains(&i))
            .count(),
        joint_train_rms_px: joint.figures.train_rms_px,
        joint_s0: joint.s0,
        start_train_rms_px: joint.start.figures.train_rms_px,
        joint_fx_error_px: joint.camera.intrinsics.fx_px - config.camera.intrinsics.fx_px,
        joint_fx_std_px: joint.camera_std[0],
        two_step_fx_error_px: two_step_camera.camera.intrinsics.fx_px - config.camera.intrinsics.fx_px,
        two_step_fx_std_px: two_step_camera.std.as_ref().map_or(f64::NAN, |s| s[0]),
    })
}

/// The aggregate over seeds.
#[derive(Clone, Debug, Serialize)]
pub struct JointStudySummary {
    /// Seeds that ran.
    pub n_runs: usize,
    /// Seeds that failed, with the reason.
    pub failed: Vec<(u64, String)>,
    /// Median RMS of (a), (b), (c), (d), (b'), mm.
    pub median_rms_mm: [f64; 5],
    /// Median ratio of (b) to (a).
    pub median_two_step_ratio: f64,
    /// Median ratio of (c) to (a).
    pub median_joint_ratio: f64,
    /// Largest ratio of (c) to (a).
    pub max_joint_ratio: f64,
    /// Fraction of the joint adjustment's robot parameters within 3 sigma of the truth in its
    /// gauge, over all seeds.
    pub joint_within_3sigma: f64,
    /// The same against the truth as drawn (gauge ignored).
    pub joint_raw_within_3sigma: f64,
    /// The same for the two-step path.
    pub two_step_within_3sigma: f64,
    /// The same for the tracker calibration.
    pub tracker_within_3sigma: f64,
    /// Seeds on which every robot parameter of the joint adjustment is within 3 sigma.
    pub joint_all_within_seeds: usize,
}

/// Median of a slice (NaN when empty).
pub(crate) fn median(v: &[f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    ferrocal_vision::calib::median(v)
}

/// Summarises runs.
pub fn summarise_joint_study(runs: &[JointStudyRun], failed: Vec<(u64, String)>) -> JointStudySummary {
    let med = |f: &dyn Fn(&JointStudyRun) -> f64| median(&runs.iter().map(f).collect::<Vec<_>>());
    let frac = |f: &dyn Fn(&JointStudyRun) -> Coverage| {
        let (a, b) = runs.iter().map(f).fold((0, 0), |(a, b), c| (a + c.within_3sigma, b + c.n));
        a as f64 / b.max(1) as f64
    };
    JointStudySummary {
        n_runs: runs.len(),
        failed,
        median_rms_mm: [
            med(&|r| r.tracker.rms_mm),
            med(&|r| r.two_step.rms_mm),
            med(&|r| r.joint.rms_mm),
            med(&|r| r.nominal.rms_mm),
            med(&|r| r.two_step_true_camera.rms_mm),
        ],
        median_two_step_ratio: med(&|r| r.two_step_ratio()),
        median_joint_ratio: med(&|r| r.joint_ratio()),
        max_joint_ratio: runs.iter().map(|r| r.joint_ratio()).fold(f64::NAN, f64::max),
        joint_within_3sigma: frac(&|r| r.joint_coverage),
        joint_raw_within_3sigma: frac(&|r| r.joint_raw_coverage),
        two_step_within_3sigma: frac(&|r| r.two_step_coverage),
        tracker_within_3sigma: frac(&|r| r.tracker_coverage),
        joint_all_within_seeds: runs.iter().filter(|r| r.joint_coverage.within_3sigma == r.joint_coverage.n).count(),
    }
}
