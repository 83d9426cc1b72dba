//! The simulation study of the joint adjustment with a rig of cameras (issue [rigs]): a
//! two-camera eye-to-hand cell with a UR5-like arm, the rig's joint adjustment against each
//! camera's own joint adjustment on the same data and against the tracker-calibrated robot.
//!
//! # The cell
//! The joint study's UR5 cell ([`super::joint_study`]: true robot, plate on the flange,
//! tracker, corner noise) with a second fixed camera ([`RigStudyConfig::ur5_two_cameras`]):
//! camera 0 is the joint study's (2448 x 2048 px, `f` = 2400 px, 2 m in front of the robot),
//! camera 1 another model (2048 x 1536 px, `f` = 1750 px, its own Brown-5 lens) on the robot's
//! right, looking across the workspace. Poses are random joint readings of the nominal model
//! kept when at least one camera sees the whole plate within the view angle; each camera's
//! images are the training poses it sees (some poses both). The held-out poses are drawn the
//! same way and measured by the tracker only.
//!
//! **The data come from the estimators' own model family** (as in the joint study): corners are
//! the true chain's exact projections through pinhole + Brown-5 cameras plus Gaussian noise of
//! the covariance handed to the estimators, a rigid flat plate of nominal spacing, rigid
//! kinematics with errors only on parameters the selection keeps free, no robot repeatability
//! noise. The study measures the information in the data and what each estimator makes of
//! it, not robustness to effects the model leaves out.
//!
//! # What is compared, per seed
//! - the rig's joint adjustment ([`ferrocal_calib::handeye::calibrate_joint_rig`]) over
//!   both cameras' training images;
//! - each camera's own joint adjustment ([`ferrocal_calib::handeye::calibrate_joint`]) on its
//!   images of the same poses; the best single camera is the one with the lower held-out error;
//! - the tracker-calibrated robot ([`ferrocal_calib::kinematic::calibrate`]) on the tracker's
//!   readings at every training pose.
//!
//! The **held-out error is in millimetres**: the RMS position error at the held-out poses,
//! measured by the simulated tracker, after refitting the tracker frame and the reflector on the
//! flange (9 numbers, like `evaluate --refit-frame`; [`super::joint_study`]'s `score`). The
//! robot parameters are compared with the truth in the adjustment's gauge (the same rig
//! adjustment, from the same starts, of the noise-free corners), in standard deviations of their
//! reported covariance; `T_cam1_cam0` against the true one. Beside the tracker-measured error
//! (which includes the tracker's noise at the held-out poses, about 0.03 mm, a floor every model
//! shares), each model's own error: the RMS against the true reflector positions at the
//! held-out poses, frame refitted the same way.

use nalgebra::{Isometry3, Matrix2, Point2, Translation3, UnitQuaternion, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::Serialize;

use ferrocal_calib::handeye::{
    calibrate_joint, calibrate_joint_rig, calibrate_joint_rig_from, HandEyeData, HandEyeView, JointCalibration,
    JointOptions, Mount, RigJointCalibration,
};
use ferrocal_calib::kinematic::{calibrate, CalibratedModel, KinematicOptions};
use ferrocal_calib::{PoseMeasurement, Split};
use ferrocal_robot::{Kinematics, RobotModel};
use ferrocal_vision::camera::{CameraModel, Distortion, ImageSize, Intrinsics};

use super::joint_study::{
    coverage, coverage_raw, draw_truth, looking_at, median, random_joints, score, Coverage, JointStudyConfig, Score,
};
use crate::error::{DatasetError, Result};
use crate::sim::{Conditions, TrackerConfig, TrueRobot};

/// One further camera of the rig: fixed (eye-to-hand, `t_base_camera`) or on the flange
/// beside camera 0 (eye-in-hand, `t_flange_camera`), as the base cell's mount says.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RigCameraConfig {
    /// The true camera.
    pub camera: CameraModel,
    /// `T_base_camera` (eye-to-hand).
    pub t_base_camera: Isometry3<f64>,
    /// `T_flange_camera` (eye-in-hand).
    pub t_flange_camera: Isometry3<f64>,
}

/// The rig study's settings.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RigStudyConfig {
    /// Camera 0 and everything else: robot, poses, plate, noise, tracker, true errors, the
    /// mount (the study runs eye-to-hand; recordings either mount).
    pub base: JointStudyConfig,
    /// Cameras 1, 2, ...
    pub cameras: Vec<RigCameraConfig>,
}

impl RigStudyConfig {
    /// The two-camera cell of the module documentation (60 training, 40 held-out poses).
    pub fn ur5_two_cameras() -> Self {
        Self {
            base: JointStudyConfig::ur5(),
            cameras: vec![RigCameraConfig {
                camera: CameraModel {
                    intrinsics: Intrinsics { fx_px: 1750.0, fy_px: 1751.0, cx_px: 1018.0, cy_px: 772.0 },
                    distortion: Distortion::Brown5 { k1: -0.08, k2: 0.06, p1: -0.0002, p2: 0.0003, k3: -0.01 },
                    image_size: ImageSize { width_px: 2048, height_px: 1536 },
                },
                t_base_camera: looking_at(
                    Vector3::new(1.0, -1.9, 1.2),
                    Vector3::new(0.35, -0.1, 0.35),
                    Vector3::new(0.0, 0.0, 1.0),
                ),
                t_flange_camera: JointStudyConfig::ur5().t_flange_camera,
            }],
        }
    }

    /// A stereo head on the flange (eye-in-hand): the joint study's eye-in-hand cell
    /// ([`JointStudyConfig::ur5_eye_in_hand`]: camera 0 50 mm out on the flange, 60 mm off its
    /// axis, the plate flat on the table) with camera 1 the second camera of
    /// [`RigStudyConfig::ur5_two_cameras`] 120 mm beside camera 0 and turned 15 degrees towards
    /// its axis (the two axes cross about 0.45 m out).
    pub fn ur5_stereo_head() -> Self {
        let mut c = Self::ur5_two_cameras();
        c.base = JointStudyConfig::ur5_eye_in_hand();
        let x0 = c.base.t_flange_camera;
        c.cameras[0].t_flange_camera = Isometry3::from_parts(
            Translation3::from(x0.translation.vector + Vector3::new(0.12, 0.0, 0.0)),
            UnitQuaternion::from_axis_angle(&Vector3::y_axis(), -15f64.to_radians()) * x0.rotation,
        );
        c
    }

    /// Number of cameras.
    pub fn n_cameras(&self) -> usize {
        1 + self.cameras.len()
    }

    /// Camera `k`'s cell as a single-camera joint study configuration.
    pub fn camera_cell(&self, k: usize) -> JointStudyConfig {
        match k {
            0 => self.base.clone(),
            _ => JointStudyConfig {
                camera: self.cameras[k - 1].camera,
                t_base_camera: self.cameras[k - 1].t_base_camera,
                t_flange_camera: self.cameras[k - 1].t_flange_camera,
                ..self.base.clone()
            },
        }
    }
}

/// Random joint readings whose plate at least one camera sees, with which cameras see it.
pub(crate) fn draw_rig_poses(
    cells: &[JointStudyConfig],
    model: &RobotModel,
    n: usize,
    rng: &mut ChaCha8Rng,
) -> Result<Vec<(Vec<f64>, Vec<bool>)>> {
    let points = cells[0].points();
    let mut out = Vec::with_capacity(n);
    let mut tries = 0;
    while out.len() < n {
        tries += 1;
        if tries > 20_000 * n.max(1) {
            return Err(DatasetError::Input("rig study: the cameras rarely see the plate; check the cell".into()));
        }
        let q = random_joints(rng);
        let Ok(t) = model.forward(&q) else { continue };
        let seen: Vec<bool> = cells.iter().map(|c| c.visible(&t, &points)).collect();
        if seen.iter().any(|&s| s) {
            out.push((q, seen));
        }
    }
    Ok(out)
}

/// One seed's figures (held-out errors in mm, see the module documentation).
#[derive(Clone, Debug, Serialize)]
pub struct RigStudyRun {
    /// The seed.
    pub seed: u64,
    /// Training images per camera.
    pub n_images: Vec<usize>,
    /// Training poses seen by more than one camera.
    pub n_shared: usize,
    /// The tracker-calibrated robot.
    pub tracker: Score,
    /// The rig's joint adjustment.
    pub rig: Score,
    /// Each camera's own joint adjustment (`None` when it failed, with too few images, say).
    pub single: Vec<Option<Score>>,
    /// The models' own held-out error: RMS against the true reflector positions at the
    /// held-out poses (a noise-free tracker, frame refitted), mm; the tracker-calibrated robot.
    pub tracker_model_rms_mm: f64,
    /// The same for the rig.
    pub rig_model_rms_mm: f64,
    /// The same for the rig adjustment of the noise-free corners (the truth in its gauge): near
    /// zero when the model reaches the truth from these starts.
    pub rig_noise_free_model_rms_mm: f64,
    /// The same for each camera alone.
    pub single_model_rms_mm: Vec<Option<f64>>,
    /// The rig's free robot parameters against the truth in its gauge.
    pub rig_coverage: Coverage,
    /// The same against the drawn values (gauge ignored).
    pub rig_raw_coverage: Coverage,
    /// Each camera's own adjustment's parameters against the drawn values.
    pub single_raw_coverage: Vec<Option<Coverage>>,
    /// Free robot parameters of the rig.
    pub n_params_rig: usize,
    /// The rig's a-posteriori standard deviation of unit weight.
    pub rig_s0: f64,
    /// Training chain RMS of the rig per camera, pixels.
    pub rig_train_rms_px: Vec<f64>,
    /// Error of each further camera's `T_camk_cam0`: translation (mm), rotation (degrees), and
    /// the largest of its six coordinates' errors in standard deviations.
    pub rig_transform_error: Vec<(f64, f64, f64)>,
    /// The nominal robot.
    pub nominal: Score,
}

impl RigStudyRun {
    /// The lowest held-out RMS of the cameras' own adjustments, mm (`NaN` when all failed).
    pub fn best_single_rms_mm(&self) -> f64 {
        self.single.iter().flatten().map(|s| s.rms_mm).fold(f64::NAN, f64::min)
    }

    /// Rig RMS over the best single camera's.
    pub fn rig_to_best_single(&self) -> f64 {
        self.rig.rms_mm / self.best_single_rms_mm()
    }

    /// Rig RMS over the tracker-calibrated robot's.
    pub fn rig_to_tracker(&self) -> f64 {
        self.rig.rms_mm / self.tracker.rms_mm
    }

    /// The lowest model error (against the true positions) of the cameras alone, mm.
    pub fn best_single_model_rms_mm(&self) -> f64 {
        self.single_model_rms_mm.iter().flatten().copied().fold(f64::NAN, f64::min)
    }
}

/// A camera-calibrated robot through its calibration file (what `evaluate` reads).
fn through_file(joint: &JointCalibration, robot: &str, nominal: &RobotModel) -> Result<CalibratedModel> {
    let json = serde_json::to_string(&joint.file(robot))?;
    serde_json::from_str::<ferrocal_calib::file::CalibrationFile>(&json)?
        .apply(nominal)
        .map_err(|e| DatasetError::Input(format!("rig study: {e}")))
}

/// The error of an estimated `T_camk_cam0` against the truth: translation (mm), rotation
/// (degrees), largest coordinate error in standard deviations (the `Se3` product chart).
fn transform_error(est: &ferrocal_calib::handeye::TransformEstimate, truth: &Isometry3<f64>) -> (f64, f64, f64) {
    let dt = truth.translation.vector - est.transform.translation.vector;
    let dr = (truth.rotation * est.transform.rotation.inverse()).scaled_axis();
    let d = [dt.x, dt.y, dt.z, dr.x, dr.y, dr.z];
    let z = (0..6).map(|i| d[i].abs() / est.covariance[(i, i)].max(1e-300).sqrt()).fold(0.0, f64::max);
    (dt.norm() * 1e3, dr.norm().to_degrees(), z)
}

/// One seed of the study (see the module documentation).
pub fn run_rig_study(config: &RigStudyConfig, seed: u64) -> Result<RigStudyRun> {
    let fail = |e: ferrocal_calib::CalibError| DatasetError::Input(format!("rig study, seed {seed}: {e}"));
    if config.base.mount != Mount::EyeToHand {
        return Err(DatasetError::Config("rig study: the cell is eye-to-hand".into()));
    }
    let cells: Vec<JointStudyConfig> = (0..config.n_cameras()).map(|k| config.camera_cell(k)).collect();
    let nominal = RobotModel::load(&config.base.robot).map_err(|e| DatasetError::Config(e.to_string()))?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let train = draw_rig_poses(&cells, &nominal, config.base.n_train, &mut rng)?;
    let test = draw_rig_poses(&cells, &nominal, config.base.n_test, &mut rng)?;
    let train_q: Vec<Vec<f64>> = train.iter().map(|(q, _)| q.clone()).collect();
    let (truth, truth_values): (TrueRobot, _) = draw_truth(&config.base, &nominal, &train_q, &mut rng)?;
    let cond = Conditions { temp_c: 20.0, dir: vec![0; nominal.dof()], ..Default::default() };
    let tracker_rows = |qs: &mut dyn Iterator<Item = &Vec<f64>>, rng: &mut ChaCha8Rng, tag: &str| {
        qs.enumerate()
            .map(|(k, q)| {
                let r = config.base.tracker.measure(&truth.tool_pose(q, &cond)?, rng);
                let mut m = PoseMeasurement::new(format!("{tag}{k:03}"), q.clone(), r.position_m);
                m.sigma_m = Some(r.sigma_m);
                Ok(m)
            })
            .collect::<Result<Vec<PoseMeasurement>>>()
    };
    let train_tracker = tracker_rows(&mut train.iter().map(|(q, _)| q), &mut rng, "train")?;
    let test_tracker = tracker_rows(&mut test.iter().map(|(q, _)| q), &mut rng, "test")?;
    // Every camera's images of the training poses it sees: exact projections plus noise.
    let noise = Normal::new(0.0, config.base.corner_sigma_px).map_err(|e| DatasetError::Input(e.to_string()))?;
    let cov = Matrix2::identity() * config.base.corner_sigma_px.powi(2);
    let points = config.base.points();
    let x = config.base.t_flange_target;
    let n_cam = cells.len();
    let mut data: Vec<HandEyeData> = (0..n_cam)
        .map(|_| HandEyeData { mount: Mount::EyeToHand, target_points_m: points.clone(), views: Vec::new() })
        .collect();
    let mut exact = data.clone();
    let mut joints: Vec<Vec<Vec<f64>>> = vec![Vec::new(); n_cam];
    for (i, (q, seen)) in train.iter().enumerate() {
        let t_base_target = truth.tool_pose(q, &cond)? * x;
        for (k, cell) in cells.iter().enumerate().filter(|(k, _)| seen[*k]) {
            let t_cam_target = cell.t_base_camera.inverse() * t_base_target;
            let mut view = HandEyeView {
                name: format!("img{i:03}"),
                split: Split::Train,
                t_base_flange: nominal.forward(q).map_err(|e| DatasetError::Input(e.to_string()))?,
                image_size: cell.camera.image_size,
                point_ids: (0..points.len()).collect(),
                covariances_px2: vec![Some(cov); points.len()],
                corners_px: Vec::with_capacity(points.len()),
            };
            let mut exact_view = view.clone();
            for p in &points {
                let px = cell.camera.project(&(t_cam_target * p)).map_err(|e| DatasetError::Input(e.to_string()))?;
                exact_view.corners_px.push(px);
                view.corners_px.push(Point2::new(px.x + noise.sample(&mut rng), px.y + noise.sample(&mut rng)));
            }
            data[k].views.push(view);
            exact[k].views.push(exact_view);
            joints[k].push(q.clone());
        }
    }
    let test_refs: Vec<&PoseMeasurement> = test_tracker.iter().collect();
    // The held-out poses' true reflector positions (a noise-free tracker; its own random state,
    // which draws nothing that matters): the models' own error, without the tracker's floor.
    let exact_tracker = TrackerConfig { sigma_const_um: 0.0, sigma_per_m_um: 0.0, ..config.base.tracker.clone() };
    let mut zero_rng = ChaCha8Rng::seed_from_u64(0);
    let test_true = test
        .iter()
        .enumerate()
        .map(|(k, (q, _))| {
            let r = exact_tracker.measure(&truth.tool_pose(q, &cond)?, &mut zero_rng);
            let mut m = PoseMeasurement::new(format!("true{k:03}"), q.clone(), r.position_m);
            m.sigma_m = Some(1e-5);
            Ok(m)
        })
        .collect::<Result<Vec<PoseMeasurement>>>()?;
    let true_refs: Vec<&PoseMeasurement> = test_true.iter().collect();
    let model_rms_mm = |cm: &CalibratedModel| -> Result<f64> { Ok(score(cm, &true_refs)?.rms_mm) };
    let train_refs: Vec<&PoseMeasurement> = train_tracker.iter().collect();
    // The tracker-calibrated robot.
    let tracker_cal = calibrate(&nominal, &train_refs, &KinematicOptions::default()).map_err(fail)?;
    // The rig, and its truth in its gauge (the same adjustment of the noise-free corners from
    // the same starts).
    let options = JointOptions::default();
    let rig: RigJointCalibration = calibrate_joint_rig(&nominal, &data, &joints, &options).map_err(fail)?;
    let starts =
        std::iter::once(rig.reference.start.clone()).chain(rig.cameras.iter().map(|c| c.start.clone())).collect();
    let truth_gauge = calibrate_joint_rig_from(&nominal, &exact, &joints, starts, &options).map_err(fail)?;
    let robot = &config.base.robot;
    let rig_model = through_file(&rig.reference, robot, &nominal)?;
    // Each camera alone on its own images.
    let mut single = Vec::new();
    let mut single_model_rms_mm = Vec::new();
    let mut single_raw_coverage = Vec::new();
    for (d, q) in data.iter().zip(&joints) {
        match calibrate_joint(&nominal, d, q, &options) {
            Ok(j) => {
                let model = through_file(&j, robot, &nominal)?;
                single.push(Some(score(&model, &test_refs)?));
                single_model_rms_mm.push(Some(model_rms_mm(&model)?));
                single_raw_coverage.push(Some(coverage_raw(&j.params, &truth_values)));
            }
            Err(_) => {
                single.push(None);
                single_model_rms_mm.push(None);
                single_raw_coverage.push(None);
            }
        }
    }
    let t_cam0 = cells[0].t_base_camera;
    let rig_transform_error = rig
        .cameras
        .iter()
        .zip(&cells[1..])
        .map(|(c, cell)| transform_error(&c.t_cam_cam0, &(cell.t_base_camera.inverse() * t_cam0)))
        .collect();
    let mut rig_train_rms_px = vec![rig.reference.figures.train_rms_px];
    rig_train_rms_px.extend(rig.cameras.iter().map(|c| c.figures.train_rms_px));
    Ok(RigStudyRun {
        seed,
        n_images: data.iter().map(|d| d.views.len()).collect(),
        n_shared: train.iter().filter(|(_, s)| s.iter().filter(|&&v| v).count() > 1).count(),
        tracker: score(&tracker_cal.calibrated, &test_refs)?,
        rig: score(&rig_model, &test_refs)?,
        single,
        tracker_model_rms_mm: model_rms_mm(&tracker_cal.calibrated)?,
        rig_model_rms_mm: model_rms_mm(&rig_model)?,
        rig_noise_free_model_rms_mm: model_rms_mm(&through_file(&truth_gauge.reference, robot, &nominal)?)?,
        single_model_rms_mm,
        rig_coverage: coverage(&rig.reference.params, &truth_gauge.reference.params),
        rig_raw_coverage: coverage_raw(&rig.reference.params, &truth_values),
        single_raw_coverage,
        n_params_rig: rig.reference.free.len(),
        rig_s0: rig.reference.s0,
        rig_train_rms_px,
        rig_transform_error,
        nominal: score(&CalibratedModel::nominal(nominal.clone()), &test_refs)?,
    })
}

/// The aggregate over seeds.
#[derive(Clone, Debug, Serialize)]
pub struct RigStudySummary {
    /// Seeds that ran.
    pub n_runs: usize,
    /// Seeds that failed, with the reason.
    pub failed: Vec<(u64, String)>,
    /// Fraction of the rig's robot parameters within 3 sigma of the truth (its gauge), all seeds.
    pub rig_within_3sigma: f64,
    /// Parameters compared over all seeds, and how many were outside 3 sigma.
    pub rig_params_compared: usize,
    /// Parameters outside 3 sigma over all seeds.
    pub rig_params_outside: usize,
    /// Largest `|estimate - truth| / sigma` over all seeds.
    pub rig_max_z: f64,
    /// Seeds with every rig parameter within 3 sigma.
    pub rig_all_within_seeds: usize,
    /// Seeds where the rig's held-out RMS is below the best single camera's.
    pub rig_beats_best_single_seeds: usize,
    /// Median and largest rig / best single camera held-out RMS.
    pub rig_to_best_single: (f64, f64),
    /// Median and largest rig / tracker held-out RMS.
    pub rig_to_tracker: (f64, f64),
    /// Seeds where the rig is within 1.2 times the tracker-calibrated robot.
    pub rig_within_1_2_tracker_seeds: usize,
    /// Median held-out RMS, mm: tracker, rig, best single camera, camera 0 alone, nominal.
    pub median_rms_mm: [f64; 5],
    /// Seeds where the rig's model error (against the true positions) is below the best single
    /// camera's.
    pub rig_beats_best_single_model_seeds: usize,
    /// Median and largest rig / best single camera model error.
    pub rig_to_best_single_model: (f64, f64),
    /// Median and largest rig / tracker model error.
    pub rig_to_tracker_model: (f64, f64),
    /// Median model error, mm: tracker, rig, best single camera.
    pub median_model_rms_mm: [f64; 3],
}

/// Summarises runs.
pub fn summarise_rig_study(runs: &[RigStudyRun], failed: Vec<(u64, String)>) -> RigStudySummary {
    let med = |f: &dyn Fn(&RigStudyRun) -> f64| median(&runs.iter().map(f).collect::<Vec<_>>());
    let max = |f: &dyn Fn(&RigStudyRun) -> f64| runs.iter().map(f).fold(f64::NAN, f64::max);
    let (inside, n) = runs.iter().fold((0, 0), |(a, b), r| (a + r.rig_coverage.within_3sigma, b + r.rig_coverage.n));
    RigStudySummary {
        n_runs: runs.len(),
        failed,
        rig_within_3sigma: inside as f64 / n.max(1) as f64,
        rig_params_compared: n,
        rig_params_outside: n - inside,
        rig_max_z: max(&|r| r.rig_coverage.max_z),
        rig_all_within_seeds: runs.iter().filter(|r| r.rig_coverage.within_3sigma == r.rig_coverage.n).count(),
        rig_beats_best_single_seeds: runs.iter().filter(|r| r.rig.rms_mm < r.best_single_rms_mm()).count(),
        rig_to_best_single: (med(&|r| r.rig_to_best_single()), max(&|r| r.rig_to_best_single())),
        rig_to_tracker: (med(&|r| r.rig_to_tracker()), max(&|r| r.rig_to_tracker())),
        rig_within_1_2_tracker_seeds: runs.iter().filter(|r| r.rig_to_tracker() <= 1.2).count(),
        median_rms_mm: [
            med(&|r| r.tracker.rms_mm),
            med(&|r| r.rig.rms_mm),
            med(&|r| r.best_single_rms_mm()),
            med(&|r| r.single[0].map_or(f64::NAN, |s| s.rms_mm)),
            med(&|r| r.nominal.rms_mm),
        ],
        rig_beats_best_single_model_seeds: runs
            .iter()
            .filter(|r| r.rig_model_rms_mm < r.best_single_model_rms_mm())
            .count(),
        rig_to_best_single_model: (
            med(&|r| r.rig_model_rms_mm / r.best_single_model_rms_mm()),
            max(&|r| r.rig_model_rms_mm / r.best_single_model_rms_mm()),
        ),
        rig_to_tracker_model: (
            med(&|r| r.rig_model_rms_mm / r.tracker_model_rms_mm),
            max(&|r| r.rig_model_rms_mm / r.tracker_model_rms_mm),
        ),
        median_model_rms_mm: [
            med(&|r| r.tracker_model_rms_mm),
            med(&|r| r.rig_model_rms_mm),
            med(&|r| r.best_single_model_rms_mm()),
        ],
    }
}
