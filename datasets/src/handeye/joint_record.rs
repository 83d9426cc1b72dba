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

use ferrocal_calib::handeye::Mount;
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
    refuse_existing(dir)?;
    let mut cell = draw_cell(config, seed)?;
    let all: Vec<RecordedPose> = cell
        .train_q
        .iter()
        .map(|q| (q, Split::Train))
        .chain(cell.test_q.iter().map(|q| (q, Split::Test)))
        .map(|(q, split)| RecordedPose { q, split, seen: vec![true] })
        .collect();
    render_camera(config, 0, &cell, &all, &dir.join("images"), seed)?;
    let comment = format!(
        "simulated eye-to-hand recording of the joint study's {} cell, seed {seed} (ferrocal handeye simulate)",
        config.robot
    );
    super::poses::write_atomic(
        &dir.join("poses.csv"),
        joint_table(&comment, cell.nominal.dof(), &all).as_bytes(),
        &[],
    )?;
    let yaml = ferrocal_vision::camera::io::to_opencv_yaml(&config.camera)?;
    super::poses::write_atomic(&dir.join("camera.yaml"), yaml.as_bytes(), &[])?;
    let held = write_heldout(config, &mut cell, dir, seed)?;
    let (cols, rows) = config.grid;
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

/// Refuses a folder that already holds a recording (its `poses.csv`).
pub(crate) fn refuse_existing(dir: &Path) -> Result<()> {
    if dir.join("poses.csv").exists() {
        return Err(DatasetError::Input(format!("{} already holds a recording (poses.csv)", dir.display())));
    }
    Ok(())
}

/// One pose of a rendered recording (a row of its poses table, named `jNNN.png` after its
/// index): the joint readings, the split and which cameras see it.
pub(crate) struct RecordedPose<'a> {
    /// Joint readings, model order.
    pub(crate) q: &'a [f64],
    /// Training or held out.
    pub(crate) split: Split,
    /// Per camera: whether it sees the plate (and has an image of the pose).
    pub(crate) seen: Vec<bool>,
}

/// Renders camera `k` (`camera`: its cell, camera and mount) at every pose of `poses` it sees,
/// through `cell`'s true robot, into `images/jNNN.png` (created; image noise seeded by `seed`,
/// the pose and the camera); returns its training and held-out image counts.
pub(crate) fn render_camera(
    camera: &JointStudyConfig,
    k: usize,
    cell: &Cell,
    poses: &[RecordedPose],
    images: &Path,
    seed: u64,
) -> Result<(usize, usize)> {
    use crate::render::{RenderConfig, Renderer, TargetConfig};
    let (cols, rows) = camera.grid;
    let target = TargetConfig::Chessboard {
        inner_cols: cols,
        inner_rows: rows,
        square_m: camera.spacing_m,
        margin_m: camera.spacing_m,
    };
    // The renderer's board is centred; the grid's origin is its first corner.
    let centre = Vector3::new((cols - 1) as f64, (rows - 1) as f64, 0.0) * (0.5 * camera.spacing_m);
    let t_grid_render = Isometry3::from_parts(Translation3::from(centre), UnitQuaternion::identity());
    let renderer = Renderer::new(camera.camera, &target, RenderConfig::default())?;
    std::fs::create_dir_all(images).map_err(|source| DatasetError::Write { path: images.to_path_buf(), source })?;
    let cond = Conditions { temp_c: 20.0, dir: vec![0; cell.nominal.dof()], ..Default::default() };
    let mut counts = (0, 0);
    for (i, pose) in poses.iter().enumerate().filter(|(_, p)| p.seen[k]) {
        let flange = cell.truth.tool_pose(pose.q, &cond)?;
        let t_cam_target = match camera.mount {
            Mount::EyeToHand => camera.t_base_camera.inverse() * flange * camera.t_flange_target,
            Mount::EyeInHand => camera.t_flange_camera.inverse() * flange.inverse() * camera.t_base_target,
        };
        let image_seed = seed.wrapping_mul(1000).wrapping_add(i as u64).wrapping_add(500_000 * k as u64);
        let img = renderer.render(&(t_cam_target * t_grid_render), image_seed)?;
        let path = images.join(format!("j{i:03}.png"));
        img.image.save(&path).map_err(|e| DatasetError::Image { path: path.clone(), reason: e.to_string() })?;
        match pose.split {
            Split::Train => counts.0 += 1,
            Split::Test => counts.1 += 1,
        }
    }
    Ok(counts)
}

/// The poses table of a rendered recording: `# comment`, then `image,q1_rad..q<dof>_rad,split`
/// and a row `jNNN.png` per pose.
pub(crate) fn joint_table(comment: &str, dof: usize, poses: &[RecordedPose]) -> String {
    let mut csv =
        format!("# {comment}\nimage,{},split\n", (1..=dof).map(|j| format!("q{j}_rad")).collect::<Vec<_>>().join(","));
    for (i, pose) in poses.iter().enumerate() {
        let joints: Vec<String> = pose.q.iter().map(|v| format!("{v:.17}")).collect();
        let split = if pose.split == Split::Test { "test" } else { "train" };
        csv.push_str(&format!("j{i:03}.png,{},{split}\n", joints.join(",")));
    }
    csv
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
