//! The closed loop of a corrected program: a simulated robot whose truth is **not** the
//! calibration's model family is calibrated (from tracker readings, and separately from camera
//! images through the joint adjustment of robot and camera), a program of nominal joint commands
//! is corrected through each calibration file by the `correct` workflow, and the corrected
//! commands are executed on the true robot. What is measured is where they land against where
//! they were wanted, row by row, beside the uncorrected program, and whether each row's
//! predicted landing uncertainty covers its landed error.
//!
//! # What is simulated, and how the truth differs from the estimator
//! - The cell is [`crate::handeye::joint_study`]'s UR5 cell (eye-to-hand camera 2 m away, a
//!   9 x 7 plate on the flange, a position-only laser tracker seeing a reflector on the flange),
//!   with its true geometric errors (0.5 mm, 0.5 mrad on the parameters the selection keeps).
//! - On top, physics the calibration's model does not contain ([`ClosedLoopConfig::effects`]):
//!   the upper arm and the forearm bend under the gravity moment they carry (link compliance),
//!   the shoulder and base gears are eccentric (a once- and twice-per-turn periodic joint error)
//!   and the elbow's axis wobbles as it turns. The calibrations fit rigid geometry only: the
//!   truth is outside the estimator's family, so part of every landed error is model error.
//! - The corners are the true chain's exact projections through the true camera plus 0.1 px
//!   Gaussian noise (no rendering); the tracker adds its own noise (10 µm + 3 µm/m per axis).
//!   The landed positions are the truth's, without noise.
//!
//! # The figures
//! - The calibration's own held-out error: the tracker calibration's RMS position error on 30
//!   held-out tracker poses (tracker noise included); the camera calibration's RMS on the same
//!   poses after refitting only the tracker's frame and reflector (`evaluate --refit-frame`, how a
//!   camera calibration is scored against a tracker).
//! - Landed error: the distance between where the truth puts the measured point (reflector or
//!   plate origin) at the corrected command and the wanted position, in the calibration's device
//!   frame (tracker or camera), RMS over the program.

use std::path::Path;

use nalgebra::{Matrix2, Point2, Point3, Vector3};
use rand_distr::{Distribution, Normal};
use serde::Serialize;

use ferrocal_calib::file::CalibrationFile;
use ferrocal_calib::handeye::{calibrate_joint, HandEyeData, HandEyeView, JointOptions, Mount};
use ferrocal_calib::kinematic::correct::{CorrectOptions, Uncertainty};
use ferrocal_calib::kinematic::{calibrate, KinematicOptions};
use ferrocal_calib::{PoseMeasurement, Split};
use ferrocal_robot::Kinematics;
use ferrocal_vision::pose::{estimate_pose, CornerNoise};

use super::{Conditions, Effect};
use crate::correct::{correct_run, Wanted};
use crate::error::{DatasetError, Result};
use crate::handeye::joint_study::{draw_cell, draw_poses, median, JointStudyConfig};

/// The smallest singular value a program's command keeps from a singularity, m (see
/// [`run_closed_loop`]).
pub const PROGRAM_SIGMA_MIN_M: f64 = 0.02;

/// The study's settings.
#[derive(Clone, Debug, Serialize)]
pub struct ClosedLoopConfig {
    /// The cell (poses, camera, tracker, true geometric errors).
    pub cell: JointStudyConfig,
    /// Commands of the program (drawn like the training poses, so inside the calibrated region).
    pub n_program: usize,
    /// The physics the calibrations leave out.
    pub effects: Vec<Effect>,
}

impl ClosedLoopConfig {
    /// The UR5 cell with 40 training poses, 30 held-out tracker poses and a program of 12
    /// commands; the upper arm bending 2 µrad/N m and the forearm 4 µrad/N m under their
    /// gravity moments, the base gear 40 µrad twice per turn and the shoulder's 40 µrad once per
    /// turn eccentric, the elbow's axis wobbling by 30 µrad.
    pub fn ur5() -> Self {
        let mut cell = JointStudyConfig::ur5();
        (cell.n_train, cell.n_test) = (40, 30);
        let tau = std::f64::consts::TAU;
        Self {
            cell,
            n_program: 12,
            effects: vec![
                Effect::LinkCompliance { link: 2, compliance_si: 2e-6 },
                Effect::LinkCompliance { link: 3, compliance_si: 4e-6 },
                Effect::PeriodicJointError { joint: 1, amplitude_si: 40e-6, period_si: tau / 2.0, phase_rad: 0.3 },
                Effect::PeriodicJointError { joint: 2, amplitude_si: 40e-6, period_si: tau, phase_rad: 1.1 },
                Effect::AxisWobble { joint: 3, tilt_rad: 30e-6, phase_rad: 0.7 },
            ],
        }
    }
}

/// One command of the program on the true robot.
#[derive(Clone, Debug, Serialize)]
pub struct LandedRow {
    /// The command's id.
    pub pose_id: String,
    /// Distance of the corrected command's landing from the wanted position, mm.
    pub landed_mm: f64,
    /// The same for the uncorrected (nominal) command, mm.
    pub uncorrected_mm: f64,
    /// The predicted landing uncertainty (68 % radius), mm.
    pub sigma_mm: f64,
    /// Distance of the corrected command's landing from the wanted position in the true device
    /// frame, mm (the same as `landed_mm` for the tracker).
    pub landed_true_mm: f64,
    /// The smallest singular value of the command's task Jacobian, m.
    pub sigma_min_m: f64,
}

/// One calibration's corrected program on the true robot.
#[derive(Clone, Debug, Serialize)]
pub struct PathResult {
    /// The calibration's own held-out RMS error, mm (see the module documentation).
    pub held_out_rms_mm: f64,
    /// RMS landed error of the corrected program as the calibration's own device measures it
    /// (noise-free), mm.
    pub landed_rms_mm: f64,
    /// RMS landed error in the true device frame, mm.
    pub landed_true_rms_mm: f64,
    /// Largest landed error, mm.
    pub landed_max_mm: f64,
    /// RMS error of the uncorrected program, mm.
    pub uncorrected_rms_mm: f64,
    /// RMS error of the uncorrected program in the true device frame, mm.
    pub uncorrected_true_rms_mm: f64,
    /// Rows whose landed error is within their predicted landing uncertainty.
    pub covered: usize,
    /// Per command.
    pub rows: Vec<LandedRow>,
    /// The same wanted poses given as targets (`correct --targets`, no start joints: the
    /// solution branch found from the nominal model's inverse kinematics), landed RMS in the
    /// true device frame, mm; and the rows so reached.
    pub targets_landed_true_rms_mm: f64,
    /// Target rows that no command reached (named by `correct`, not written).
    pub targets_unreached: usize,
}

impl PathResult {
    /// Landed RMS over the calibration's own held-out RMS, both as its device measures them.
    pub fn ratio(&self) -> f64 {
        self.landed_rms_mm / self.held_out_rms_mm
    }
}

/// One seed of the study.
#[derive(Clone, Debug, Serialize)]
pub struct ClosedLoopRun {
    /// The seed.
    pub seed: u64,
    /// The tracker-calibrated robot.
    pub tracker: PathResult,
    /// The camera-calibrated robot (the joint adjustment of robot and camera in pixels).
    pub camera: PathResult,
    /// RMS over the program of what the left-out physics alone moves the reflector, mm (the
    /// size of the model error).
    pub left_out_rms_mm: f64,
}

/// One command's positions: wanted, landed (corrected) and uncorrected as the device measures
/// them, m; the landing in the true device frame, m; its predicted radius, mm; its singular
/// value, m.
struct Raw {
    id: String,
    want: Vector3<f64>,
    at: Vector3<f64>,
    nominal: Vector3<f64>,
    at_true: Vector3<f64>,
    nominal_true: Vector3<f64>,
    sigma_mm: f64,
    sigma_min_m: f64,
}

fn landed(rows: &[Raw], held_out_rms_mm: f64) -> PathResult {
    let rms =
        |f: &dyn Fn(&Raw) -> f64| (rows.iter().map(|r| f(r).powi(2)).sum::<f64>() / rows.len().max(1) as f64).sqrt();
    let out: Vec<LandedRow> = rows
        .iter()
        .map(|r| LandedRow {
            pose_id: r.id.clone(),
            landed_mm: (r.at - r.want).norm() * 1e3,
            uncorrected_mm: (r.nominal - r.want).norm() * 1e3,
            sigma_mm: r.sigma_mm,
            landed_true_mm: (r.at_true - r.want).norm() * 1e3,
            sigma_min_m: r.sigma_min_m,
        })
        .collect();
    PathResult {
        held_out_rms_mm,
        landed_rms_mm: rms(&|r| (r.at - r.want).norm() * 1e3),
        landed_true_rms_mm: rms(&|r| (r.at_true - r.want).norm() * 1e3),
        landed_max_mm: out.iter().map(|r| r.landed_mm).fold(0.0, f64::max),
        uncorrected_rms_mm: rms(&|r| (r.nominal - r.want).norm() * 1e3),
        uncorrected_true_rms_mm: rms(&|r| (r.nominal_true - r.want).norm() * 1e3),
        covered: out.iter().filter(|r| r.landed_true_mm <= r.sigma_mm).count(),
        rows: out,
        targets_landed_true_rms_mm: f64::NAN,
        targets_unreached: 0,
    }
}

/// Writes the wanted poses of `run`'s rows to `path` as a targets table (positions in mm, the
/// orientation when `with_orientation`, no joint columns).
fn write_targets(path: &Path, run: &crate::correct::CorrectRun, with_orientation: bool) -> Result<()> {
    let mut s = String::from("pose_id,x_mm,y_mm,z_mm");
    if with_orientation {
        s.push_str(",qw,qx,qy,qz");
    }
    s.push('\n');
    for o in &run.rows {
        let p = o.command.intended.translation.vector * 1e3;
        s.push_str(&format!("{},{:e},{:e},{:e}", o.pose_id, p.x, p.y, p.z));
        if with_orientation {
            let q = o.command.intended.rotation;
            s.push_str(&format!(",{:e},{:e},{:e},{:e}", q.w, q.i, q.j, q.k));
        }
        s.push('\n');
    }
    std::fs::write(path, s).map_err(|e| DatasetError::Input(format!("{}: {e}", path.display())))
}

/// The targets pass of one calibration: `run`'s wanted poses corrected as targets through the
/// same file, landed on the truth by `land` (position in the true device frame, m).
fn targets_pass(
    result: &mut PathResult,
    run: &crate::correct::CorrectRun,
    correct: &dyn Fn(&Path) -> Result<crate::correct::CorrectRun>,
    path: &Path,
    with_orientation: bool,
    land: &mut dyn FnMut(&[f64]) -> Result<Vector3<f64>>,
) -> Result<()> {
    write_targets(path, run, with_orientation)?;
    let t = correct(path)?;
    let mut sum = 0.0;
    let mut n = 0usize;
    for o in &t.rows {
        if o.unreached.is_some() {
            result.targets_unreached += 1;
            continue;
        }
        sum += (land(&o.command.q)? - o.command.intended.translation.vector).norm_squared();
        n += 1;
    }
    result.targets_landed_true_rms_mm = (sum / n.max(1) as f64).sqrt() * 1e3;
    Ok(())
}

/// Writes the program `qs` (nominal commands, radians) to `path`.
fn write_program(path: &Path, qs: &[Vec<f64>]) -> Result<()> {
    let n = qs.first().map_or(0, Vec::len);
    let mut s = String::from("pose_id");
    for i in 1..=n {
        s.push_str(&format!(",q{i}_rad"));
    }
    s.push('\n');
    for (k, q) in qs.iter().enumerate() {
        s.push_str(&format!("p{k:02}"));
        for v in q {
            s.push_str(&format!(",{v:e}"));
        }
        s.push('\n');
    }
    std::fs::write(path, s).map_err(|e| DatasetError::Input(format!("{}: {e}", path.display())))
}

/// Runs one seed; the calibration files and the program are written under `dir`.
pub fn run_closed_loop(config: &ClosedLoopConfig, seed: u64, dir: &Path) -> Result<ClosedLoopRun> {
    let fail = |e: ferrocal_calib::CalibError| DatasetError::Input(format!("closed-loop study, seed {seed}: {e}"));
    let cfg = &config.cell;
    if cfg.mount != Mount::EyeToHand {
        return Err(DatasetError::Config("the closed-loop study's camera path is eye-to-hand".into()));
    }
    let mut cell = draw_cell(cfg, seed)?;
    // The program: poses like the training ones, away from singularities as a programmer keeps
    // them (the nominal flange Jacobian's smallest singular value, orientation rows counted at
    // the correction's 0.1 m per rad, above `PROGRAM_SIGMA_MIN_M`): near one, a command that
    // matches the orientation may lie far away or nowhere (`correct` names such rows; see
    // tests/tests/correct.rs).
    let far_from_singular = |q: &Vec<f64>| {
        cell.nominal.jacobian(q).is_ok_and(|mut j| {
            j.rows_mut(3, 3).scale_mut(CorrectOptions::default().orientation_scale_m);
            j.singular_values().min() > PROGRAM_SIGMA_MIN_M
        })
    };
    let program_q: Vec<Vec<f64>> = draw_poses(cfg, &cell.nominal, 4 * config.n_program, &mut cell.rng)?
        .into_iter()
        .filter(far_from_singular)
        .take(config.n_program)
        .collect();
    if program_q.len() < config.n_program {
        return Err(DatasetError::Input(format!("closed-loop study, seed {seed}: too few program poses")));
    }
    let rigid = cell.truth.clone();
    cell.truth.effects.extend(config.effects.iter().cloned());
    let truth = &cell.truth;
    let cond = Conditions { temp_c: 20.0, dir: vec![0; cell.nominal.dof()], ..Default::default() };
    let tracker = &cfg.tracker;
    let t_tracker_world = tracker.t_world_tracker().inverse();
    let reflector = Point3::from(Vector3::from(tracker.reflector_in_tool_m));
    let reflector_at = |t: &TrueRobotRef, q: &[f64]| -> Result<Vector3<f64>> {
        Ok((t_tracker_world * t.tool_pose(q, &cond)? * reflector).coords)
    };
    let left_out_rms_mm = {
        let mut s = 0.0;
        for q in &program_q {
            s += (reflector_at(truth, q)? - reflector_at(&rigid, q)?).norm_squared();
        }
        (s / program_q.len().max(1) as f64).sqrt() * 1e3
    };
    let mut tracker_rows = |qs: &[Vec<f64>], tag: &str| -> Result<Vec<PoseMeasurement>> {
        qs.iter()
            .enumerate()
            .map(|(k, q)| {
                let r = tracker.measure(&truth.tool_pose(q, &cond)?, &mut cell.rng);
                let mut m = PoseMeasurement::new(format!("{tag}{k:03}"), q.clone(), r.position_m);
                m.sigma_m = Some(r.sigma_m);
                Ok(m)
            })
            .collect()
    };
    let train = tracker_rows(&cell.train_q, "train")?;
    let test = tracker_rows(&cell.test_q, "test")?;
    let train_refs: Vec<&PoseMeasurement> = train.iter().collect();
    let test_refs: Vec<&PoseMeasurement> = test.iter().collect();
    let program = dir.join(format!("program_{seed}.csv"));
    write_program(&program, &program_q)?;
    let correct_through = |file: &CalibrationFile, name: &str| -> Result<crate::correct::CorrectRun> {
        let path = dir.join(format!("{name}_{seed}.json"));
        std::fs::write(&path, serde_json::to_string_pretty(file)?)
            .map_err(|e| DatasetError::Input(format!("{}: {e}", path.display())))?;
        correct_run(&cfg.robot, &path, Wanted::Program(&program), false)
    };
    let targets_through = |name: &str| {
        let calibration = dir.join(format!("{name}_{seed}.json"));
        move |targets: &Path| correct_run(&cfg.robot, &calibration, Wanted::Targets(targets), false)
    };

    // The tracker path.
    let cal = calibrate(&cell.nominal, &train_refs, &KinematicOptions::default()).map_err(fail)?;
    let held_out = cal.calibrated.evaluate(&test_refs).map_err(fail)?.rms_mm;
    let uncertainty = Uncertainty::from_kinematic(&cal, &train_refs).map_err(fail)?;
    let file = CalibrationFile::delivered(&cfg.robot, &cal.calibrated, &train_refs, Some(uncertainty)).map_err(fail)?;
    let run = correct_through(&file, "tracker_calibration")?;
    let mut rows = Vec::new();
    for (o, q) in run.rows.iter().zip(&program_q) {
        if let Some(why) = &o.unreached {
            return Err(DatasetError::Input(format!("seed {seed}, tracker path, {}: {why}", o.pose_id)));
        }
        let want = o.command.intended.translation.vector;
        rows.push(Raw {
            id: o.pose_id.clone(),
            want,
            at: reflector_at(truth, &o.command.q)?,
            nominal: reflector_at(truth, q)?,
            at_true: reflector_at(truth, &o.command.q)?,
            nominal_true: reflector_at(truth, q)?,
            sigma_mm: o.landing_sigma_mm.unwrap_or(f64::NAN),
            sigma_min_m: o.command.sigma_min,
        });
    }
    let mut tracker_result = landed(&rows, held_out);
    targets_pass(
        &mut tracker_result,
        &run,
        &targets_through("tracker_calibration"),
        &dir.join(format!("tracker_targets_{seed}.csv")),
        false,
        &mut |q| reflector_at(truth, q),
    )?;

    // The camera path: corners of the training poses through the true chain and camera.
    let points = cfg.points();
    let x = cfg.hand_eye();
    let w_inv = cfg.world().inverse();
    let noise = Normal::new(0.0, cfg.corner_sigma_px).map_err(|e| DatasetError::Input(e.to_string()))?;
    let cov = Matrix2::identity() * cfg.corner_sigma_px.powi(2);
    let mut views = Vec::new();
    for (k, q) in cell.train_q.iter().enumerate() {
        let t_cam_target = w_inv * truth.tool_pose(q, &cond)? * x;
        let mut corners = Vec::with_capacity(points.len());
        for p in &points {
            let px = cfg.camera.project(&(t_cam_target * p)).map_err(|e| DatasetError::Input(e.to_string()))?;
            corners.push(Point2::new(px.x + noise.sample(&mut cell.rng), px.y + noise.sample(&mut cell.rng)));
        }
        views.push(HandEyeView {
            name: format!("img{k:03}"),
            split: Split::Train,
            t_base_flange: cell.nominal.forward(q).map_err(|e| DatasetError::Input(e.to_string()))?,
            image_size: cfg.camera.image_size,
            point_ids: (0..points.len()).collect(),
            covariances_px2: vec![Some(cov); points.len()],
            corners_px: corners,
        });
    }
    let data = HandEyeData { mount: Mount::EyeToHand, target_points_m: points, views };
    let joint = calibrate_joint(&cell.nominal, &data, &cell.train_q, &JointOptions::default()).map_err(fail)?;
    let file = joint.file(&cfg.robot);
    let joint_model = file.apply(&cell.nominal).map_err(fail)?;
    // What the calibrated camera measures of the plate at `q`: the true chain's corners through
    // the true camera (with the study's noise or without), the plate's pose by PnP through the
    // calibrated camera.
    let ids: Vec<usize> = (0..data.target_points_m.len()).collect();
    let corner_noise = CornerNoise::Isotropic { sigma_px: cfg.corner_sigma_px };
    let mut seen = |q: &[f64], noisy: bool| -> Result<Vector3<f64>> {
        let t_cam_target = w_inv * truth.tool_pose(q, &cond)? * x;
        let mut corners = Vec::with_capacity(ids.len());
        for p in &data.target_points_m {
            let px = cfg.camera.project(&(t_cam_target * p)).map_err(|e| DatasetError::Input(e.to_string()))?;
            let (dx, dy) = if noisy { (noise.sample(&mut cell.rng), noise.sample(&mut cell.rng)) } else { (0.0, 0.0) };
            corners.push(Point2::new(px.x + dx, px.y + dy));
        }
        let est = estimate_pose(&joint.camera, &data.target_points_m, &ids, &corners, &corner_noise)
            .map_err(|e| DatasetError::Input(format!("closed-loop study, seed {seed}: PnP: {e}")))?;
        Ok(est.t_cam_target.translation.vector)
    };
    let mut sum = 0.0;
    for q in &cell.test_q {
        sum += (seen(q, true)? - joint_model.predict(q).map_err(fail)?.translation.vector).norm_squared();
    }
    let held_out = (sum / cell.test_q.len().max(1) as f64).sqrt() * 1e3;
    let run = correct_through(&file, "camera_calibration")?;
    let plate_at =
        |q: &[f64]| -> Result<Vector3<f64>> { Ok((w_inv * truth.tool_pose(q, &cond)? * x).translation.vector) };
    let mut rows = Vec::new();
    for (o, q) in run.rows.iter().zip(&program_q) {
        if let Some(why) = &o.unreached {
            return Err(DatasetError::Input(format!(
                "seed {seed}, camera path, {}: {why} (sigma_min {:.4} m)",
                o.pose_id, o.command.sigma_min
            )));
        }
        let want = o.command.intended.translation.vector;
        rows.push(Raw {
            id: o.pose_id.clone(),
            want,
            at: seen(&o.command.q, false)?,
            nominal: seen(q, false)?,
            at_true: plate_at(&o.command.q)?,
            nominal_true: plate_at(q)?,
            sigma_mm: o.landing_sigma_mm.unwrap_or(f64::NAN),
            sigma_min_m: o.command.sigma_min,
        });
    }
    let mut camera_result = landed(&rows, held_out);
    targets_pass(
        &mut camera_result,
        &run,
        &targets_through("camera_calibration"),
        &dir.join(format!("camera_targets_{seed}.csv")),
        true,
        &mut |q| plate_at(q),
    )?;
    Ok(ClosedLoopRun { seed, tracker: tracker_result, camera: camera_result, left_out_rms_mm })
}

type TrueRobotRef = super::TrueRobot;

impl ClosedLoopRun {
    /// One line with the seed's figures, mm.
    pub fn summary_line(&self) -> String {
        let path = |name: &str, p: &PathResult| {
            format!(
                "{name}: held-out {:.4}, landed {:.4} (true frame {:.4}), uncorrected {:.4} (true frame {:.4}), covered {}/{}; as targets {:.4} ({} unreached)",
                p.held_out_rms_mm,
                p.landed_rms_mm,
                p.landed_true_rms_mm,
                p.uncorrected_rms_mm,
                p.uncorrected_true_rms_mm,
                p.covered,
                p.rows.len(),
                p.targets_landed_true_rms_mm,
                p.targets_unreached
            )
        };
        format!(
            "seed {}: left-out physics {:.4} mm; {}; {}",
            self.seed,
            self.left_out_rms_mm,
            path("tracker", &self.tracker),
            path("camera", &self.camera)
        )
    }
}

/// The study over seeds.
#[derive(Clone, Debug, Serialize)]
pub struct ClosedLoopSummary {
    /// Seeds that ran.
    pub runs: Vec<ClosedLoopRun>,
    /// Median over seeds of landed RMS over held-out RMS: tracker, camera.
    pub median_ratio: [f64; 2],
    /// Fraction of all rows whose landed error is within the predicted 68 % radius: tracker,
    /// camera.
    pub coverage: [f64; 2],
    /// Median over seeds of the uncorrected program's RMS over the corrected one's: tracker,
    /// camera.
    pub median_improvement: [f64; 2],
    /// The same in the true device frame (for the camera, where its frame's own error along
    /// the optical axis counts).
    pub median_true_improvement: [f64; 2],
    /// Median over seeds of the targets pass's landed RMS over the program's, both in the true
    /// device frame.
    pub median_targets_ratio: [f64; 2],
}

/// Summarises runs.
pub fn summarise_closed_loop(runs: Vec<ClosedLoopRun>) -> ClosedLoopSummary {
    let path = |r: &ClosedLoopRun, k: usize| if k == 0 { r.tracker.clone() } else { r.camera.clone() };
    let med =
        |f: &dyn Fn(&PathResult) -> f64, k: usize| median(&runs.iter().map(|r| f(&path(r, k))).collect::<Vec<_>>());
    let cover = |k: usize| {
        let (c, n) = runs.iter().map(|r| path(r, k)).fold((0, 0), |(c, n), p| (c + p.covered, n + p.rows.len()));
        c as f64 / n.max(1) as f64
    };
    ClosedLoopSummary {
        median_ratio: [med(&|p| p.ratio(), 0), med(&|p| p.ratio(), 1)],
        coverage: [cover(0), cover(1)],
        median_improvement: [
            med(&|p| p.uncorrected_rms_mm / p.landed_rms_mm, 0),
            med(&|p| p.uncorrected_rms_mm / p.landed_rms_mm, 1),
        ],
        median_true_improvement: [
            med(&|p| p.uncorrected_true_rms_mm / p.landed_true_rms_mm, 0),
            med(&|p| p.uncorrected_true_rms_mm / p.landed_true_rms_mm, 1),
        ],
        median_targets_ratio: [
            med(&|p| p.targets_landed_true_rms_mm / p.landed_true_rms_mm, 0),
            med(&|p| p.targets_landed_true_rms_mm / p.landed_true_rms_mm, 1),
        ],
        runs,
    }
}
