//! A rendered rig recording for the joint adjustment through the binary (`ferrocal handeye
//! simulate --robot ur5 --cameras 2`): the rig study's two-camera UR5 cell
//! ([`super::rig_study`]; eye-to-hand two fixed cameras, eye-in-hand a stereo head on the
//! flange, [`RigStudyConfig::ur5_stereo_head`]) at half resolution with the rendered cell's 9 x 6
//! chessboard ([`super::joint_record::rendered_ur5_cell`]), every view of every camera rendered with the
//! project's renderer (blur, vignetting, sensor noise; the corners then come from the detector),
//! one poses table with the joint readings of every pose, each camera's images in its own folder
//! named after the table's rows, and the held-out poses measured by the study's simulated
//! tracker. The cameras, the chain and the robot's error model are the estimator's own family;
//! the images are not (rendered, detected corners).
//!
//! The rendering of each camera's views and the poses table are the single-camera recorder's
//! (`joint_record::render_camera`, `joint_record::joint_table`).

use std::path::Path;

use nalgebra::Isometry3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use ferrocal_calib::handeye::Mount;
use ferrocal_calib::Split;
use ferrocal_robot::{Kinematics, RobotModel};
use ferrocal_vision::camera::{CameraModel, ImageSize, Intrinsics};

use super::joint_record::{
    joint_table, refuse_existing, render_camera, rendered_ur5_cell, write_heldout, RecordedPose,
};
use super::joint_study::{draw_truth, Cell, JointStudyConfig, Score};
use super::rig_study::{draw_rig_poses, RigStudyConfig};
use crate::error::{DatasetError, Result};
use crate::sim::Conditions;

/// The rig study's two-camera cell for rendering: camera 0 as [`rendered_ur5_cell`] (1224 x
/// 1024 px, f = 1200 px), camera 1 the rig study's second camera at half its resolution (1024 x
/// 768 px, f = 875 px, the same field of view and distortion), the 9 x 6 chessboard at 30 mm.
/// Eye-to-hand: two fixed cameras ([`RigStudyConfig::ur5_two_cameras`]); eye-in-hand: the
/// stereo head on the flange ([`RigStudyConfig::ur5_stereo_head`]), the plate on the table.
pub fn rendered_ur5_rig(mount: Mount, n_train: usize, n_test: usize) -> RigStudyConfig {
    let mut c = match mount {
        Mount::EyeToHand => RigStudyConfig::ur5_two_cameras(),
        Mount::EyeInHand => RigStudyConfig::ur5_stereo_head(),
    };
    c.base = JointStudyConfig { mount, ..rendered_ur5_cell(n_train, n_test) };
    for cam in &mut c.cameras {
        let k = cam.camera.intrinsics;
        let s = cam.camera.image_size;
        cam.camera = CameraModel {
            intrinsics: Intrinsics {
                fx_px: k.fx_px * 0.5,
                fy_px: k.fy_px * 0.5,
                cx_px: (k.cx_px + 0.5) * 0.5 - 0.5,
                cy_px: (k.cy_px + 0.5) * 0.5 - 0.5,
            },
            distortion: cam.camera.distortion,
            image_size: ImageSize { width_px: s.width_px / 2, height_px: s.height_px / 2 },
        };
    }
    c
}

/// A transform as the truth file writes it: millimetres and a unit quaternion, scalar first.
#[derive(Clone, Debug, Serialize)]
pub struct TransformTruth {
    /// Translation, mm.
    pub translation_mm: [f64; 3],
    /// Rotation, `[w, x, y, z]`.
    pub rotation_wxyz: [f64; 4],
}

impl From<&Isometry3<f64>> for TransformTruth {
    fn from(t: &Isometry3<f64>) -> Self {
        let p = t.translation.vector * 1e3;
        let q = t.rotation;
        Self { translation_mm: [p.x, p.y, p.z], rotation_wxyz: [q.w, q.i, q.j, q.k] }
    }
}

/// One camera of a rig recording.
#[derive(Clone, Debug, Serialize)]
pub struct RigRecordingCamera {
    /// Its name and folder under the recording (`cam0`, `cam1`, ...; images in `<name>/images`).
    pub name: String,
    /// The true camera (also `<name>/camera.yaml`).
    pub camera: CameraModel,
    /// `T_base_camera` (eye-to-hand: the fixed camera).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub t_base_camera: Option<TransformTruth>,
    /// `T_flange_camera` (eye-in-hand: the camera on the flange).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub t_flange_camera: Option<TransformTruth>,
    /// `T_camk_cam0`: the reference camera's frame into this camera's (identity for camera 0).
    pub t_cam_cam0: TransformTruth,
    /// Training images rendered (the training poses this camera sees).
    pub n_train_images: usize,
    /// Held-out images rendered.
    pub n_test_images: usize,
}

/// What [`write_rig_recording`] wrote, and the truth (`truth.json`).
#[derive(Clone, Debug, Serialize)]
pub struct RigRecording {
    /// The pattern string of the rendered chessboard.
    pub pattern: String,
    /// The mount (`eye-to-hand` or `eye-in-hand`).
    pub mount: String,
    /// The robot preset.
    pub robot: String,
    /// The cameras, the reference first.
    pub cameras: Vec<RigRecordingCamera>,
    /// `T_flange_target` (eye-to-hand: the plate on the flange, grid origin at the first corner).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub t_flange_target: Option<TransformTruth>,
    /// `T_base_target` (eye-in-hand: the plate on the table, grid origin at the first corner).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub t_base_target: Option<TransformTruth>,
    /// The true robot's parameters that differ from the nominal (name, true value, nominal).
    pub robot_errors: Vec<(String, f64, f64)>,
    /// The nominal model scored on `heldout.csv` like `evaluate --refit-frame`, mm.
    pub nominal_heldout: Score,
    /// The true robot scored the same way (the tracker's noise floor), mm.
    pub truth_heldout: Score,
    /// Training poses (rows of poses.csv marked train).
    pub n_train: usize,
    /// Held-out poses (rows marked test, and tracker rows).
    pub n_test: usize,
}

/// Draws the rig cell of `seed` (poses at least one camera sees, then the true robot), renders
/// every pose each camera sees, and writes into `dir` (an existing `poses.csv` is an error):
/// `poses.csv` (image, the joint readings `q1_rad..q6_rad`, split; one row per pose),
/// `flange_poses.csv` (the same rows with the true robot's flange poses, `x_mm..qz`),
/// `cam<k>/images/jNNN.png` (the row's name; a camera that does not see a pose has no image of
/// it), `cam<k>/camera.yaml` (the true camera, OpenCV), `heldout.csv` (the tracker's readings of
/// the held-out poses) and `truth.json` ([`RigRecording`]).
pub fn write_rig_recording(config: &RigStudyConfig, dir: &Path, seed: u64) -> Result<RigRecording> {
    refuse_existing(dir)?;
    let base = &config.base;
    let cells: Vec<_> = (0..config.n_cameras()).map(|k| config.camera_cell(k)).collect();
    let nominal = RobotModel::load(&base.robot).map_err(|e| DatasetError::Config(e.to_string()))?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let train = draw_rig_poses(&cells, &nominal, base.n_train, &mut rng)?;
    let test = draw_rig_poses(&cells, &nominal, base.n_test, &mut rng)?;
    let train_q: Vec<Vec<f64>> = train.iter().map(|(q, _)| q.clone()).collect();
    let (truth, truth_values) = draw_truth(base, &nominal, &train_q, &mut rng)?;
    let test_q = test.iter().map(|(q, _)| q.clone()).collect();
    let mut cell = Cell { nominal, truth, truth_values, train_q, test_q, rng };
    let (cols, rows) = base.grid;
    let cond = Conditions { temp_c: 20.0, dir: vec![0; cell.nominal.dof()], ..Default::default() };
    let all: Vec<RecordedPose> = train
        .iter()
        .map(|(q, s)| (q, s, Split::Train))
        .chain(test.iter().map(|(q, s)| (q, s, Split::Test)))
        .map(|(q, seen, split)| RecordedPose { q, split, seen: seen.clone() })
        .collect();
    let mut counts = Vec::with_capacity(cells.len());
    for (k, c) in cells.iter().enumerate() {
        let images = dir.join(format!("cam{k}")).join("images");
        counts.push(render_camera(c, k, &cell, &all, &images, seed)?);
        let yaml = ferrocal_vision::camera::io::to_opencv_yaml(&c.camera)?;
        super::poses::write_atomic(&dir.join(format!("cam{k}")).join("camera.yaml"), yaml.as_bytes(), &[])?;
    }
    let comment = format!(
        "simulated {} recording of the rig study's {} cell with {} cameras, seed {seed} (ferrocal handeye simulate); each camera's images in cam<k>/images",
        base.mount.name(),
        base.robot,
        cells.len(),
    );
    let csv = joint_table(&comment, cell.nominal.dof(), &all);
    // The same rows with the true robot's flange poses: what a controller of an exactly
    // calibrated robot would report (for the rig without a robot model).
    let mut flange_csv = format!(
        "# the true flange poses of the rig recording's rows (an exactly calibrated robot), seed {seed}\nimage,x_mm,y_mm,z_mm,qw,qx,qy,qz,split\n"
    );
    for (i, pose) in all.iter().enumerate() {
        let split = if pose.split == Split::Test { "test" } else { "train" };
        let t = cell.truth.tool_pose(pose.q, &cond)?;
        let (p, r) = (t.translation.vector * 1e3, t.rotation);
        flange_csv.push_str(&format!(
            "j{i:03}.png,{:.17},{:.17},{:.17},{:.17},{:.17},{:.17},{:.17},{split}\n",
            p.x, p.y, p.z, r.w, r.i, r.j, r.k
        ));
    }
    super::poses::write_atomic(&dir.join("poses.csv"), csv.as_bytes(), &[])?;
    super::poses::write_atomic(&dir.join("flange_poses.csv"), flange_csv.as_bytes(), &[])?;
    let held = write_heldout(base, &mut cell, dir, seed)?;
    // T_camk_cam0 = W_k^-1 W_0 of the fixed cameras, X_k^-1 X_0 of a head on the flange.
    let in_hand = base.mount == Mount::EyeInHand;
    let mounted = |c: &JointStudyConfig| if in_hand { c.t_flange_camera } else { c.t_base_camera };
    let t_cam0 = mounted(&cells[0]);
    let cameras = cells
        .iter()
        .zip(&counts)
        .enumerate()
        .map(|(k, (c, &(n_train_images, n_test_images)))| RigRecordingCamera {
            name: format!("cam{k}"),
            camera: c.camera,
            t_base_camera: (!in_hand).then(|| (&c.t_base_camera).into()),
            t_flange_camera: in_hand.then(|| (&c.t_flange_camera).into()),
            t_cam_cam0: (&(mounted(c).inverse() * t_cam0)).into(),
            n_train_images,
            n_test_images,
        })
        .collect();
    let out = RigRecording {
        pattern: format!("chessboard:{cols}x{rows}:{}mm", base.spacing_m * 1e3),
        mount: base.mount.name().into(),
        robot: base.robot.clone(),
        cameras,
        t_flange_target: (!in_hand).then(|| (&base.t_flange_target).into()),
        t_base_target: in_hand.then(|| (&base.t_base_target).into()),
        robot_errors: held.robot_errors,
        nominal_heldout: held.nominal_heldout,
        truth_heldout: held.truth_heldout,
        n_train: train.len(),
        n_test: test.len(),
    };
    super::poses::write_atomic(&dir.join("truth.json"), serde_json::to_string_pretty(&out)?.as_bytes(), &[])?;
    Ok(out)
}
