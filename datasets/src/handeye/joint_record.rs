//! A rendered recording for the joint adjustment through the binary (`ferrocal handeye simulate
//! --robot ur5`): the joint study's UR5 cell ([`super::joint_study`]) with its true robot, every
//! view rendered with the project's renderer (blur, vignetting, sensor noise; the corners then come
//! from the detector), the joint readings in the poses table, and the held-out poses measured by
//! the study's simulated tracker, the table `ferrocal evaluate --refit-frame` scores a calibration
//! on. The camera, the chain and the robot's error model are the estimator's own family; the
//! images are not (rendered, detected corners).

use std::path::Path;

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use serde::Serialize;

use ferrocal_calib::kinematic::CalibratedModel;
use ferrocal_calib::{MeasurementSet, PoseMeasurement, Split};
use ferrocal_robot::{Kinematics, Parameterized};
use ferrocal_vision::camera::{CameraModel, ImageSize, Intrinsics};

use super::joint_study::{draw_cell, score, Cell, JointStudyConfig, Score};
use crate::error::{DatasetError, Result};
use crate::import::measurements::{write_measurements, WriteOptions};
use crate::sim::Conditions;

/// The joint study's UR5 cell for rendering: the camera at half the resolution (1224 x 1024 px,
/// f = 1200 px, the same field of view and distortion) and a 9 x 6 chessboard (30 mm), whose
/// corner numbering the detector cannot confuse with its 180-degree turn.
pub fn rendered_ur5_cell(n_train: usize, n_test: usize) -> JointStudyConfig {
    let mut c = JointStudyConfig::ur5();
    let k = c.camera.intrinsics;
    c.camera = CameraModel {
        intrinsics: Intrinsics { fx_px: k.fx_px * 0.5, fy_px: k.fy_px * 0.5, cx_px: 615.0, cy_px: 509.0 },
        distortion: c.camera.distortion,
        image_size: ImageSize { width_px: 1224, height_px: 1024 },
    };
    c.grid = (9, 6);
    let centre = Vector3::new(8.0, 5.0, 0.0) * (0.5 * c.spacing_m);
    c.t_flange_target =
        Isometry3::from_parts(Translation3::from(Vector3::new(0.0, 0.0, 0.04) - centre), UnitQuaternion::identity());
    c.n_train = n_train;
    c.n_test = n_test;
    c
}

/// What [`write_joint_recording`] wrote, and the truth (`truth.json`).
#[derive(Clone, Debug, Serialize)]
pub struct JointRecording {
    /// The pattern string of the rendered chessboard.
    pub pattern: String,
    /// The robot preset.
    pub robot: String,
    /// The true camera.
    pub camera: CameraModel,
    /// `T_base_camera` of the true robot's base.
    pub t_base_camera: Isometry3<f64>,
    /// The true robot's parameters that differ from the nominal (name, true value, nominal
    /// value).
    pub robot_errors: Vec<(String, f64, f64)>,
    /// The nominal model scored on `heldout.csv` like `evaluate --refit-frame`, mm.
    pub nominal_heldout: Score,
    /// The true robot scored the same way (the tracker's noise floor), mm.
    pub truth_heldout: Score,
    /// Training and held-out images written.
    pub n_train: usize,
    /// Held-out images (and tracker rows).
    pub n_test: usize,
}

/// Draws the cell of `seed`, renders every training and held-out view, and writes into `dir`
/// (created; an existing `poses.csv` is an error): `images/jNNN.png`, `poses.csv` (image, the
/// joint readings `q1_rad..q6_rad`, split), `camera.yaml`, `heldout.csv` (the tracker's
/// readings of a reflector on the flange at the held-out poses) and `truth.json`.
pub fn write_joint_recording(config: &JointStudyConfig, dir: &Path, seed: u64) -> Result<JointRecording> {
    use crate::render::{RenderConfig, Renderer, TargetConfig};
    if dir.join("poses.csv").exists() {
        return Err(DatasetError::Input(format!("{} already holds a recording (poses.csv)", dir.display())));
    }
    let mut cell = draw_cell(config, seed)?;
    let (cols, rows) = config.grid;
    let target = TargetConfig::Chessboard {
        inner_cols: cols,
        inner_rows: rows,
        square_m: config.spacing_m,
        margin_m: config.spacing_m,
    };
    let renderer = Renderer::new(config.camera, &target, RenderConfig::default())?;
    let centre = Vector3::new((cols - 1) as f64, (rows - 1) as f64, 0.0) * (0.5 * config.spacing_m);
    let t_grid_render = Isometry3::from_parts(Translation3::from(centre), UnitQuaternion::identity());
    let images = dir.join("images");
    std::fs::create_dir_all(&images).map_err(|source| DatasetError::Write { path: images.clone(), source })?;
    let cond = Conditions { temp_c: 20.0, dir: vec![0; cell.nominal.dof()], ..Default::default() };
    let w_inv = config.t_base_camera.inverse();
    let n = cell.nominal.dof();
    let mut csv = format!(
        "# simulated eye-to-hand recording of the joint study's {} cell, seed {seed} (ferrocal handeye simulate)\nimage,{},split\n",
        config.robot,
        (1..=n).map(|j| format!("q{j}_rad")).collect::<Vec<_>>().join(",")
    );
    let all: Vec<(&Vec<f64>, Split)> =
        cell.train_q.iter().map(|q| (q, Split::Train)).chain(cell.test_q.iter().map(|q| (q, Split::Test))).collect();
    for (k, (q, split)) in all.iter().enumerate() {
        let t_cam_target = w_inv * cell.truth.tool_pose(q, &cond)? * config.t_flange_target;
        let img = renderer.render(&(t_cam_target * t_grid_render), seed.wrapping_mul(1000).wrapping_add(k as u64))?;
        let name = format!("j{k:03}.png");
        let path = images.join(&name);
        img.image.save(&path).map_err(|e| DatasetError::Image { path: path.clone(), reason: e.to_string() })?;
        let joints: Vec<String> = q.iter().map(|v| format!("{v:.17}")).collect();
        let split = if *split == Split::Test { "test" } else { "train" };
        csv.push_str(&format!("{name},{},{split}\n", joints.join(",")));
    }
    super::poses::write_atomic(&dir.join("poses.csv"), csv.as_bytes(), &[])?;
    let yaml = ferrocal_vision::camera::io::to_opencv_yaml(&config.camera)?;
    super::poses::write_atomic(&dir.join("camera.yaml"), yaml.as_bytes(), &[])?;
    let held = write_heldout(config, &mut cell, dir, seed)?;
    let out = JointRecording {
        pattern: format!("chessboard:{cols}x{rows}:{}mm", config.spacing_m * 1e3),
        robot: config.robot.clone(),
        camera: config.camera,
        t_base_camera: config.t_base_camera,
        robot_errors: held.robot_errors,
        nominal_heldout: held.nominal_heldout,
        truth_heldout: held.truth_heldout,
        n_train: cell.train_q.len(),
        n_test: cell.test_q.len(),
    };
    super::poses::write_atomic(&dir.join("truth.json"), serde_json::to_string_pretty(&out)?.as_bytes(), &[])?;
    Ok(out)
}

/// What [`write_heldout`] measured: the true robot's errors and the held-out scores.
pub(crate) struct Heldout {
    /// The true robot's parameters that differ from the nominal (name, true value, nominal).
    pub(crate) robot_errors: Vec<(String, f64, f64)>,
    /// The nominal model scored on `heldout.csv`, mm.
    pub(crate) nominal_heldout: Score,
    /// The true robot scored the same way (the tracker's noise floor), mm.
    pub(crate) truth_heldout: Score,
}

/// Writes `heldout.csv` into `dir`: the tracker's readings (of `cell`'s random state) of a
/// reflector on the flange at `cell`'s held-out poses; returns the true robot's errors and the
/// nominal and true robots scored on it.
pub(crate) fn write_heldout(config: &JointStudyConfig, cell: &mut Cell, dir: &Path, seed: u64) -> Result<Heldout> {
    let cond = Conditions { temp_c: 20.0, dir: vec![0; cell.nominal.dof()], ..Default::default() };
    let n = cell.nominal.dof();
    let mut heldout = Vec::with_capacity(cell.test_q.len());
    for (k, q) in cell.test_q.iter().enumerate() {
        let t = cell.truth.tool_pose(q, &cond)?;
        let r = config.tracker.measure(&t, &mut cell.rng);
        let mut m = PoseMeasurement::new(format!("test{k:03}"), q.clone(), r.position_m);
        m.sigma_m = Some(r.sigma_m);
        m.split = Some(Split::Test);
        heldout.push(m);
    }
    let set = MeasurementSet { source: "simulated tracker".into(), rows: heldout };
    let mut opts = WriteOptions::revolute(n);
    opts.comments = vec![format!("simulated tracker readings of the held-out poses, seed {seed}")];
    write_measurements(dir.join("heldout.csv"), &set, &opts)?;
    let refs: Vec<&PoseMeasurement> = set.rows.iter().collect();
    let nominal_values: Vec<(String, f64)> =
        cell.nominal.parameters().into_iter().map(|p| (p.name.clone(), p.value)).collect();
    let robot_errors = cell
        .truth_values
        .iter()
        .zip(&nominal_values)
        .filter(|((_, t), (_, v))| t != v)
        .map(|((name, t), (_, v))| (name.clone(), *t, *v))
        .collect();
    Ok(Heldout {
        robot_errors,
        nominal_heldout: score(&CalibratedModel::nominal(cell.nominal.clone()), &refs)?,
        truth_heldout: score(&CalibratedModel::nominal(cell.truth.truth.clone()), &refs)?,
    })
}
