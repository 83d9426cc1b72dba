//! The synthetic measurement cell: a true robot, a measurement plan, a laser tracker and
//! cameras photographing a target on the end-effector, written to disk as a recorded session.
//!
//! Configured in TOML ([`CellConfig`]), deterministic for a seed. See `docs/session-format.md`
//! for the layout of a written session; the `simulate` command's edges are in [`session`].
//!
//! Frames: `world` is the reference frame of the robot model (its `base` parameters place the
//! robot in it). The tracker and the cameras are placed in `world`; the target is fixed in the
//! tool frame by `t_tool_target`.

pub mod closed_loop;
pub mod effects;
pub mod humanoid;
pub mod plan;
pub mod planning;
pub mod scenario;
pub mod session;
pub mod temperature;
pub mod torso;
pub mod tracker;
pub mod tree;

use std::path::{Path, PathBuf};

use ferrocal_calib::{MeasurementSet, PoseMeasurement};
use ferrocal_robot::safety::SafetyConfig;
use ferrocal_robot::{Kinematics, Parameterized, RobotModel};
use ferrocal_vision::camera::CameraModel;
use nalgebra::{Isometry3, Rotation3, Translation3, UnitQuaternion, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

pub use effects::{Conditions, Effect, GeometricErrors, TrueRobot};
pub use plan::{make_plan, Plan, PlanConfig};
pub use planning::{random_subsets, DatasetsSimulator};
pub use temperature::Environment;
pub use tracker::{TrackerConfig, TrackerReading};

use crate::error::DatasetError;
use crate::import::measurements::{write_measurements, WriteOptions};
use crate::render::{RenderConfig, Renderer, TargetConfig};

/// The robot of the cell (TOML table `[robot]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RobotSection {
    /// Preset name, URDF path or TOML model path (relative paths: relative to the cell file).
    pub model: String,
    /// Geometric errors of the true robot.
    #[serde(default)]
    pub errors: GeometricErrors,
    /// Non-geometric effects (`[[robot.effect]]`), all off unless listed.
    #[serde(default, rename = "effect")]
    pub effects: Vec<Effect>,
    /// Mass of a parallel robot's moving platform (serial arms use their inertials).
    #[serde(default)]
    pub platform_mass_kg: f64,
}

/// A rigid placement: translation and roll-pitch-yaw (`Rz Ry Rx`, degrees).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Placement {
    /// Translation.
    #[serde(default)]
    pub xyz_m: [f64; 3],
    /// Rotation, roll-pitch-yaw in degrees.
    #[serde(default)]
    pub rpy_deg: [f64; 3],
}

impl Placement {
    /// As a transform.
    pub fn isometry(&self) -> Isometry3<f64> {
        let r = self.rpy_deg.map(f64::to_radians);
        Isometry3::from_parts(
            Translation3::new(self.xyz_m[0], self.xyz_m[1], self.xyz_m[2]),
            UnitQuaternion::from_euler_angles(r[0], r[1], r[2]),
        )
    }
}

/// The target carried by the robot (TOML table `[target]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TargetSection {
    /// The pattern.
    pub pattern: TargetConfig,
    /// `T_tool_target`: the target frame in the tool frame.
    #[serde(default)]
    pub t_tool_target: Placement,
}

/// Image file format of rendered images.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ImageFormat {
    /// Lossless PNG (JPEG artefacts, when wanted, come from the renderer's sensor settings).
    #[default]
    Png,
}

/// One camera of the cell (TOML array `[[camera]]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraSection {
    /// Name (also the image folder's name).
    pub name: String,
    /// The true camera model.
    pub model: CameraModel,
    /// Camera position in the world.
    pub position_m: [f64; 3],
    /// The point the optical axis passes through.
    pub look_at_m: [f64; 3],
    /// World direction that appears up in the image.
    #[serde(default = "default_up")]
    pub up: [f64; 3],
    /// Rendering settings (blur, noise, illumination, ...).
    #[serde(default)]
    pub render: RenderConfig,
}

fn default_up() -> [f64; 3] {
    [0.0, 0.0, 1.0]
}

impl CameraSection {
    /// `T_world_cam` from the position, the look-at point and the up direction (camera z
    /// forward, x right, y down).
    pub fn t_world_cam(&self) -> Result<Isometry3<f64>, DatasetError> {
        let pos = Vector3::from(self.position_m);
        let z = Vector3::from(self.look_at_m) - pos;
        let up = Vector3::from(self.up);
        if z.norm() < 1e-9 || z.cross(&up).norm() < 1e-9 * z.norm() * up.norm().max(1e-300) {
            return Err(DatasetError::Config(format!(
                "camera '{}': look_at_m must differ from position_m and not lie along up",
                self.name
            )));
        }
        let z = z.normalize();
        let x = z.cross(&up).normalize();
        let y = z.cross(&x);
        let rot = Rotation3::from_basis_unchecked(&[x, y, z]);
        Ok(Isometry3::from_parts(Translation3::from(pos), UnitQuaternion::from_rotation_matrix(&rot)))
    }
}

/// A calibration board shown to the cameras before the robot moves (TOML table
/// `[calibration_board]`): the usual way to calibrate the cameras' intrinsics and their
/// relative pose, since the plate on a constant-orientation robot is always seen from the same
/// angle (all its views are parallel: focal length and distance cannot be told apart).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoardSection {
    /// The board (a chessboard or an AprilTag board).
    pub pattern: TargetConfig,
    /// Number of board poses (each photographed by every camera at once).
    pub views: usize,
    /// Where the board is held (world), its centre.
    pub centre_m: [f64; 3],
    /// Random offset of the board centre, per axis, up to this.
    #[serde(default = "default_spread")]
    pub spread_m: f64,
    /// Tilt of the board away from facing the cameras, degrees `[min, max]`.
    #[serde(default = "default_tilt")]
    pub tilt_deg: [f64; 2],
}

fn default_spread() -> f64 {
    0.3
}
fn default_tilt() -> [f64; 2] {
    [15.0, 40.0]
}

/// A complete simulated cell.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CellConfig {
    /// Name shown in reports.
    #[serde(default)]
    pub name: String,
    /// Seed of every random choice.
    #[serde(default)]
    pub seed: u64,
    /// The robot.
    pub robot: RobotSection,
    /// Temperature and payload.
    #[serde(default)]
    pub environment: Environment,
    /// The measurement plan.
    pub plan: PlanConfig,
    /// The laser tracker, if any.
    #[serde(default)]
    pub tracker: Option<TrackerConfig>,
    /// The target on the end-effector (needed when there are cameras).
    #[serde(default)]
    pub target: Option<TargetSection>,
    /// The cameras.
    #[serde(default, rename = "camera")]
    pub cameras: Vec<CameraSection>,
    /// Safety zones the plan must respect.
    #[serde(default)]
    pub safety: Option<SafetyConfig>,
    /// Calibration board views for the cameras (written before the robot's poses).
    #[serde(default)]
    pub calibration_board: Option<BoardSection>,
    /// Write the camera images (off: only the exact corners, for fast studies of everything
    /// after detection).
    #[serde(default = "default_true")]
    pub render_images: bool,
}

fn default_true() -> bool {
    true
}

impl CellConfig {
    /// Reads a cell file; errors name the file, line and column.
    pub fn from_file(path: &Path) -> Result<Self, DatasetError> {
        let text =
            std::fs::read_to_string(path).map_err(|source| DatasetError::Io { path: path.to_path_buf(), source })?;
        let mut cfg = Self::from_toml_str(&text, path)?;
        // Model files are relative to the cell file.
        let m = Path::new(&cfg.robot.model);
        if (m.extension().is_some()) && m.is_relative() {
            if let Some(dir) = path.parent() {
                let cand = dir.join(m);
                if cand.exists() {
                    cfg.robot.model = cand.display().to_string();
                }
            }
        }
        Ok(cfg)
    }

    /// Parses cell TOML text.
    pub fn from_toml_str(text: &str, path: &Path) -> Result<Self, DatasetError> {
        toml::from_str(text).map_err(|e| {
            let (line, column) = e.span().map_or((1, 1), |s| ferrocal_robot::error::line_col(text, s.start));
            DatasetError::Config(format!("{}:{line}:{column}: {}", path.display(), e.message()))
        })
    }

    /// The cell as TOML text.
    pub fn to_toml(&self) -> Result<String, DatasetError> {
        toml::to_string_pretty(self).map_err(|e| DatasetError::Config(format!("cannot write the cell as TOML: {e}")))
    }
}

/// Per-pose ground truth.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct PoseTruth {
    /// Pose id.
    pub pose_id: String,
    /// Commanded joints (what the joint table says).
    pub q_cmd: Vec<f64>,
    /// Effective joints after the joint effects.
    pub q_eff: Vec<f64>,
    /// Conditions.
    pub conditions: Conditions,
    /// `T_world_tool` of the true robot.
    pub t_world_tool: Isometry3<f64>,
}

/// Everything the simulator knows and a calibration must find (written to `truth/truth.json`).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SessionTruth {
    /// The cell file that produced the session.
    pub cell: CellConfig,
    /// Parameter names of the model.
    pub parameter_names: Vec<String>,
    /// Nominal parameter values.
    pub nominal_parameters: Vec<f64>,
    /// True parameter values (before condition-dependent effects).
    pub true_parameters: Vec<f64>,
    /// `T_world_tracker`, when there is a tracker.
    pub t_world_tracker: Option<Isometry3<f64>>,
    /// `T_world_cam` per camera.
    pub t_world_cam: Vec<(String, Isometry3<f64>)>,
    /// `T_tool_target`.
    pub t_tool_target: Option<Isometry3<f64>>,
    /// Per pose.
    pub poses: Vec<PoseTruth>,
}

/// What [`simulate`] wrote.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SessionManifest {
    /// Format identifier.
    pub format: String,
    /// Cell name.
    pub name: String,
    /// Robot model (as given in the cell file).
    pub robot_model: String,
    /// Number of poses.
    pub n_poses: usize,
    /// Joint readings per pose (measurement-table format without positions: `joints.csv`).
    pub joints: String,
    /// Tracker table (measurement CSV), if a tracker was simulated.
    pub tracker: Option<String>,
    /// Images per camera.
    pub cameras: Vec<ManifestCamera>,
    /// The target's pattern, when cameras photograph one.
    pub target: Option<TargetConfig>,
    /// The calibration board's pattern, when the cell shows one.
    #[serde(default)]
    pub calibration_board: Option<TargetConfig>,
    /// Ground truth (kept apart: a calibration must not read it).
    pub truth: String,
    /// Poses the plan left out and images not written, with reasons.
    pub notes: Vec<String>,
}

/// One camera's images in a session.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ManifestCamera {
    /// Camera name.
    pub name: String,
    /// Image size, pixels.
    pub width_px: u32,
    /// Image size, pixels.
    pub height_px: u32,
    /// Image files, one per pose (`None` where the target was not in view).
    pub images: Vec<Option<String>>,
    /// Exact corner positions (truth folder).
    pub corners_truth: String,
    /// Calibration board images, one per board view (`None` where it was not in view).
    #[serde(default)]
    pub board_images: Vec<Option<String>>,
    /// Exact board corner positions (truth folder), pose ids `b001`, `b002`, ...
    #[serde(default)]
    pub board_corners_truth: Option<String>,
}

/// Runs the cell and writes the session to `out` (created; must not exist unless `force`).
/// Everything is written into a temporary sibling folder first and moved into place at the end,
/// so an interrupted run leaves no half-written session. `progress` is called once per pose.
pub fn simulate(
    cfg: &CellConfig,
    out: &Path,
    force: bool,
    mut progress: impl FnMut(usize, usize),
) -> Result<SessionManifest, DatasetError> {
    if out.exists() && !force {
        return Err(DatasetError::Config(format!(
            "{} exists; choose another folder or pass --force to replace it",
            out.display()
        )));
    }
    if let Some(t) = &cfg.tracker {
        t.validate().map_err(DatasetError::Config)?;
    }
    let nominal = RobotModel::load(&cfg.robot.model)
        .map_err(|e| DatasetError::Config(format!("robot model '{}': {e}", cfg.robot.model)))?;
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
    let robot = TrueRobot::new(
        nominal.clone(),
        &cfg.robot.errors,
        cfg.robot.effects.clone(),
        cfg.robot.platform_mass_kg,
        &mut rng,
    )?;
    let plan = make_plan(&cfg.plan, &nominal, cfg.safety.as_ref(), &mut rng)?;
    let dirs = plan.directions();
    let n = plan.poses.len();
    if !cfg.cameras.is_empty() && cfg.target.is_none() {
        return Err(DatasetError::Config("cameras need a [target] on the end-effector".into()));
    }

    let tmp = sibling_tmp(out)?;
    let result = (|| -> Result<SessionManifest, DatasetError> {
        std::fs::create_dir_all(tmp.join("truth"))
            .map_err(|source| DatasetError::Write { path: tmp.clone(), source })?;
        let t_tool_target = cfg.target.as_ref().map(|t| t.t_tool_target.isometry());
        let mut renderers = Vec::new();
        for cam in &cfg.cameras {
            let target = &cfg.target.as_ref().expect("checked above").pattern;
            let r = Renderer::new(cam.model, target, cam.render.clone())?;
            std::fs::create_dir_all(tmp.join("images").join(&cam.name))
                .map_err(|source| DatasetError::Write { path: tmp.join("images"), source })?;
            renderers.push((cam, cam.t_world_cam()?, r));
        }
        let mut truth_poses = Vec::with_capacity(n);
        let mut tracker_rows = Vec::new();
        let mut joints_rows = Vec::new();
        let mut cam_images: Vec<Vec<Option<String>>> = vec![Vec::new(); renderers.len()];
        let mut corner_csv: Vec<String> =
            vec!["pose_id,feature,index,u_px,v_px,in_image\n".to_string(); renderers.len()];
        let mut notes: Vec<String> = plan.left_out.clone();
        let dt = cfg.plan.seconds_per_pose();
        for (k, q) in plan.poses.iter().enumerate() {
            progress(k, n);
            let pose_id = format!("{:04}", k + 1);
            let t_s = k as f64 * dt;
            let cond = Conditions {
                t_s,
                temp_c: cfg.environment.temperature_c(t_s),
                payload_kg: cfg.environment.payload_kg,
                dir: dirs[k].clone(),
            };
            let model = robot.model_at(q, &cond)?;
            let q_eff = robot.effective_joints(&model, q, &cond)?;
            let t_world_tool = model
                .forward(&q_eff)
                .map_err(|e| DatasetError::Config(format!("pose {pose_id}: true forward kinematics failed: {e}")))?;
            let mut row = PoseMeasurement::new(pose_id.clone(), q.clone(), Vector3::zeros());
            row.t_s = Some(t_s);
            row.temp_c = Some(cond.temp_c);
            row.payload_kg = Some(cond.payload_kg);
            row.dir = Some(cond.dir.clone());
            joints_rows.push(row.clone());
            if let Some(tr) = &cfg.tracker {
                let r = tr.measure(&t_world_tool, &mut rng);
                let mut m = row.clone();
                m.position_m = r.position_m;
                m.orientation = r.orientation;
                m.sigma_m = Some(r.sigma_m);
                tracker_rows.push(m);
            }
            for (ci, (cam, t_world_cam, renderer)) in renderers.iter().enumerate() {
                let t_cam_target = t_world_cam.inverse() * t_world_tool * t_tool_target.expect("checked");
                let image_seed = cfg.seed ^ ((k as u64 + 1) << 20) ^ ((ci as u64 + 1) << 52);
                if !cfg.render_images {
                    let truth = renderer.ground_truth(&t_cam_target)?;
                    for c in &truth.corners {
                        if let Some(p) = c.pixel {
                            corner_csv[ci].push_str(&format!(
                                "{pose_id},{},{},{:.9},{:.9},{}\n",
                                c.corner.feature, c.corner.index, p.x, p.y, c.in_image as u8
                            ));
                        }
                    }
                    cam_images[ci].push(None);
                    continue;
                }
                match renderer.render(&t_cam_target, image_seed) {
                    Ok(img) => {
                        let rel = format!("images/{}/pose_{pose_id}.png", cam.name);
                        img.image
                            .save(tmp.join(&rel))
                            .map_err(|e| DatasetError::Config(format!("cannot write {rel}: {e}")))?;
                        for c in &img.truth.corners {
                            if let Some(p) = c.pixel {
                                corner_csv[ci].push_str(&format!(
                                    "{pose_id},{},{},{:.9},{:.9},{}\n",
                                    c.corner.feature, c.corner.index, p.x, p.y, c.in_image as u8
                                ));
                            }
                        }
                        cam_images[ci].push(Some(rel));
                    }
                    Err(e) => {
                        notes.push(format!("pose {pose_id}, camera {}: no image ({e})", cam.name));
                        cam_images[ci].push(None);
                    }
                }
            }
            truth_poses.push(PoseTruth { pose_id, q_cmd: q.clone(), q_eff, conditions: cond, t_world_tool });
        }
        progress(n, n);
        // The calibration board, photographed by every camera at once.
        let mut board_images: Vec<Vec<Option<String>>> = vec![Vec::new(); renderers.len()];
        let mut board_csv: Vec<String> =
            vec!["pose_id,feature,index,u_px,v_px,in_image\n".to_string(); renderers.len()];
        if let Some(board) = &cfg.calibration_board {
            let board_renderers = renderers
                .iter()
                .map(|(cam, _, _)| Renderer::new(cam.model, &board.pattern, cam.render.clone()))
                .collect::<Result<Vec<_>, _>>()?;
            let look_from = renderers.iter().fold(Vector3::zeros(), |s, (_, t, _)| s + t.translation.vector)
                / renderers.len().max(1) as f64;
            for v in 0..board.views {
                let t_world_board = board_pose(board, &look_from, &mut rng);
                let id = format!("b{:03}", v + 1);
                for (ci, ((cam, t_world_cam, _), br)) in renderers.iter().zip(&board_renderers).enumerate() {
                    let t_cam_board = t_world_cam.inverse() * t_world_board;
                    let seed = cfg.seed ^ ((v as u64 + 1) << 30) ^ ((ci as u64 + 1) << 56);
                    let truth = if cfg.render_images {
                        match br.render(&t_cam_board, seed) {
                            Ok(img) => {
                                let rel = format!("images/{}/board_{id}.png", cam.name);
                                img.image
                                    .save(tmp.join(&rel))
                                    .map_err(|e| DatasetError::Config(format!("cannot write {rel}: {e}")))?;
                                board_images[ci].push(Some(rel));
                                img.truth
                            }
                            Err(e) => {
                                notes.push(format!("board view {id}, camera {}: no image ({e})", cam.name));
                                board_images[ci].push(None);
                                continue;
                            }
                        }
                    } else {
                        board_images[ci].push(None);
                        match br.ground_truth(&t_cam_board) {
                            Ok(t) => t,
                            Err(_) => continue,
                        }
                    };
                    for c in &truth.corners {
                        if let Some(p) = c.pixel {
                            board_csv[ci].push_str(&format!(
                                "{id},{},{},{:.9},{:.9},{}\n",
                                c.corner.feature, c.corner.index, p.x, p.y, c.in_image as u8
                            ));
                        }
                    }
                }
            }
        }
        let kinds = nominal.joint_kinds();
        // Joint readings: the measurement-table columns without a device position.
        write_joints_table(&tmp.join("joints.csv"), &joints_rows, &kinds)?;
        let tracker_file = if cfg.tracker.is_some() {
            let set = MeasurementSet { source: "simulated laser tracker".into(), rows: tracker_rows };
            let mut opts = WriteOptions::si(&kinds);
            opts.length_unit = crate::import::units::LengthUnit::Mm;
            opts.comments = vec![format!(
                "simulated by ferrocal {} from cell '{}' (seed {})",
                env!("CARGO_PKG_VERSION"),
                cfg.name,
                cfg.seed
            )];
            write_measurements(tmp.join("tracker.csv"), &set, &opts)?;
            Some("tracker.csv".to_string())
        } else {
            None
        };
        let mut cameras = Vec::new();
        for (ci, (cam, _, _)) in renderers.iter().enumerate() {
            let rel = format!("truth/corners_{}.csv", cam.name);
            write_file(&tmp.join(&rel), corner_csv[ci].as_bytes())?;
            let size = cam.model.image_size;
            let board_corners_truth = if cfg.calibration_board.is_some() {
                let rel_b = format!("truth/board_corners_{}.csv", cam.name);
                write_file(&tmp.join(&rel_b), board_csv[ci].as_bytes())?;
                Some(rel_b)
            } else {
                None
            };
            cameras.push(ManifestCamera {
                name: cam.name.clone(),
                width_px: size.width_px,
                height_px: size.height_px,
                images: cam_images[ci].clone(),
                corners_truth: rel,
                board_images: board_images[ci].clone(),
                board_corners_truth,
            });
        }
        let truth = SessionTruth {
            cell: cfg.clone(),
            parameter_names: nominal.parameters().into_iter().map(|p| p.name).collect(),
            nominal_parameters: nominal.parameter_values(),
            true_parameters: robot.truth.parameter_values(),
            t_world_tracker: cfg.tracker.as_ref().map(|t| t.t_world_tracker()),
            t_world_cam: renderers.iter().map(|(c, t, _)| (c.name.clone(), *t)).collect(),
            t_tool_target,
            poses: truth_poses,
        };
        write_file(&tmp.join("truth/truth.json"), serde_json::to_string_pretty(&truth)?.as_bytes())?;
        write_file(&tmp.join("cell.toml"), cfg.to_toml()?.as_bytes())?;
        let manifest = SessionManifest {
            format: "ferrocal-session/1".into(),
            name: cfg.name.clone(),
            robot_model: cfg.robot.model.clone(),
            n_poses: n,
            joints: "joints.csv".into(),
            tracker: tracker_file,
            cameras,
            target: cfg.target.as_ref().map(|t| t.pattern.clone()),
            calibration_board: cfg.calibration_board.as_ref().map(|b| b.pattern.clone()),
            truth: "truth/truth.json".into(),
            notes,
        };
        write_file(&tmp.join("manifest.json"), serde_json::to_string_pretty(&manifest)?.as_bytes())?;
        Ok(manifest)
    })();
    match result {
        Ok(m) => {
            // The commit: an existing folder is moved aside first and removed after the new one
            // is in place, so a kill at any moment leaves the old session or the new one.
            crate::pause_before_commit();
            let old = tmp.with_file_name(format!(".{}.old-{}", folder_name(out), std::process::id()));
            let had = out.exists();
            if had {
                std::fs::rename(out, &old).map_err(|source| DatasetError::Write { path: out.to_path_buf(), source })?;
            }
            std::fs::rename(&tmp, out).map_err(|source| DatasetError::Write { path: out.to_path_buf(), source })?;
            if had {
                let _ = std::fs::remove_dir_all(&old);
            }
            Ok(m)
        }
        Err(e) => {
            let _ = std::fs::remove_dir_all(&tmp);
            Err(e)
        }
    }
}

fn folder_name(out: &Path) -> &str {
    out.file_name().and_then(|n| n.to_str()).unwrap_or("session")
}

fn sibling_tmp(out: &Path) -> Result<PathBuf, DatasetError> {
    let parent = out.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    std::fs::create_dir_all(parent).map_err(|source| DatasetError::Write { path: parent.to_path_buf(), source })?;
    let tmp = parent.join(format!(".{}.partial-{}", folder_name(out), std::process::id()));
    if tmp.exists() {
        std::fs::remove_dir_all(&tmp).map_err(|source| DatasetError::Write { path: tmp.clone(), source })?;
    }
    Ok(tmp)
}

fn write_file(path: &Path, bytes: &[u8]) -> Result<(), DatasetError> {
    std::fs::write(path, bytes).map_err(|source| DatasetError::Write { path: path.to_path_buf(), source })
}

/// Writes the joint readings: `pose_id, q<i>_<rad|m>, t_s, temp_c, payload_kg, dir<i>`.
fn write_joints_table(
    path: &Path,
    rows: &[PoseMeasurement],
    kinds: &[ferrocal_robot::JointKind],
) -> Result<(), DatasetError> {
    let mut s = String::from("pose_id");
    for (i, k) in kinds.iter().enumerate() {
        let u = match k {
            ferrocal_robot::JointKind::Revolute => "rad",
            ferrocal_robot::JointKind::Prismatic => "m",
        };
        s.push_str(&format!(",q{}_{u}", i + 1));
    }
    s.push_str(",t_s,temp_c,payload_kg");
    for i in 0..kinds.len() {
        s.push_str(&format!(",dir{}", i + 1));
    }
    s.push('\n');
    for r in rows {
        s.push_str(&r.pose_id);
        for v in &r.q {
            s.push_str(&format!(",{v:?}"));
        }
        s.push_str(&format!(
            ",{:?},{:?},{:?}",
            r.t_s.unwrap_or(0.0),
            r.temp_c.unwrap_or(20.0),
            r.payload_kg.unwrap_or(0.0)
        ));
        for d in r.dir.as_deref().unwrap_or(&[]) {
            s.push_str(&format!(",{d}"));
        }
        s.push('\n');
    }
    write_file(path, s.as_bytes())
}

/// A random board pose: centred near `board.centre_m`, facing `look_from` (the cameras), tilted
/// by an angle in `board.tilt_deg` about a random in-plane axis, turned randomly in its plane.
fn board_pose(board: &BoardSection, look_from: &Vector3<f64>, rng: &mut impl rand::Rng) -> Isometry3<f64> {
    let c = Vector3::from(board.centre_m)
        + Vector3::new(
            rng.random_range(-1.0..1.0) * board.spread_m,
            rng.random_range(-1.0..1.0) * board.spread_m,
            rng.random_range(-1.0..1.0) * board.spread_m,
        );
    // Board z (out of the printed face) towards the cameras.
    let z = (look_from - c).normalize();
    let helper = if z.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
    let x = helper.cross(&z).normalize();
    let y = z.cross(&x);
    let facing = UnitQuaternion::from_rotation_matrix(&Rotation3::from_basis_unchecked(&[x, y, z]));
    let tilt = rng.random_range(board.tilt_deg[0]..=board.tilt_deg[1]).to_radians();
    let axis_angle = rng.random_range(0.0..std::f64::consts::TAU);
    let axis = Vector3::new(axis_angle.cos(), axis_angle.sin(), 0.0);
    let spin = rng.random_range(-0.5..0.5);
    let r =
        facing * UnitQuaternion::from_scaled_axis(axis * tilt) * UnitQuaternion::from_scaled_axis(Vector3::z() * spin);
    Isometry3::from_parts(Translation3::from(c), r)
}
