//! From a recorded session's images to metric target poses: corners per image, the camera rig
//! calibrated from the same plate views (the source's way: relative orientation and bundle
//! adjustment from the plate's corners), and one target pose with covariance per robot pose,
//! written as a measurement table that the robot calibration reads like a tracker's.
//!
//! Positions are in the frame of the first camera (`cam0`), metres inside, millimetres in the
//! written table. Each row carries the pose estimate's full 6 x 6 covariance
//! ([`PoseMeasurement::covariance`], SI units), which the kinematic calibration weights with;
//! its `sigma` is the RMS of the position standard deviations (what the table can hold).
//! With [`CornerSource::Detector`] the detector's per-corner covariances weight the pose
//! estimate (corners without one get [`MeasureOptions::corner_sigma_px`]).

use std::path::Path;

use ferrocal_calib::{MeasurementSet, PoseCovariance, PoseMeasurement};
use ferrocal_vision::calib::{calibrate_rig, CalibrationOptions, PlanarTarget, RigCalibration, View};
use ferrocal_vision::camera::ImageSize;
use ferrocal_vision::pose::{estimate_pose_rig, CornerNoise, PoseEstimate, RigObservation};
use nalgebra::{Matrix2, Point2, Point3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};

use crate::error::DatasetError;

mod agreement;
use agreement::compare_cameras;
pub use agreement::{disagrees, CameraAgreement, Hypothesis, PoseAgreement};
mod screen;
pub use screen::{screen_reprojection, ReprojectionOutlier, ReprojectionScreen, ReprojectionScreening};

/// Corners of one image with the detector's covariance of each (px^2), when it gave one.
#[derive(Clone, Debug)]
pub(crate) struct ImageCorners {
    pub(crate) px: Vec<Point2<f64>>,
    /// Empty when the source gives no covariances.
    pub(crate) covariance_px2: Vec<Option<Matrix2<f64>>>,
}

/// Corners per image id (`None`: the whole pattern was not seen).
type CornersById = std::collections::HashMap<String, Option<ImageCorners>>;
/// Exact corners per image id, per corner index (`None`: outside the image).
type TruthCorners = std::collections::HashMap<String, Vec<Option<Point2<f64>>>>;
use crate::sim::SessionManifest;

/// Where the corners come from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum CornerSource {
    /// The session's exact corners plus Gaussian noise: isolates everything after detection
    /// (a study of the measuring chain, not a measurement).
    TruthWithNoise {
        /// Standard deviation per image axis, pixels.
        sigma_px: f64,
        /// Seed of the noise.
        seed: u64,
    },
    /// The project's detector with sub-pixel edge refinement on the session's images: the
    /// real measuring chain.
    Detector,
}

/// The detector's pattern for a target.
pub fn detector_pattern(
    target: &crate::render::TargetConfig,
) -> Result<ferrocal_vision::detect::Pattern, DatasetError> {
    use crate::render::TargetConfig;
    use ferrocal_vision::detect::Pattern;
    Ok(match target {
        TargetConfig::Plate { square_m, .. } => Pattern::Plate { square_mm: square_m * 1e3 },
        TargetConfig::Chessboard { inner_cols, inner_rows, square_m, .. } => {
            Pattern::Chessboard { cols: *inner_cols, rows: *inner_rows, square_mm: square_m * 1e3 }
        }
        TargetConfig::Charuco { cols, rows, square_m, marker_m, dictionary, .. } => {
            Pattern::Charuco(ferrocal_vision::detect::CharucoBoard {
                cols: *cols,
                rows: *rows,
                square_mm: square_m * 1e3,
                marker_mm: marker_m * 1e3,
                dictionary: *dictionary,
            })
        }
        TargetConfig::CircleGrid { cols, rows, spacing_m, large_radius_m, asymmetric, .. } => {
            use ferrocal_vision::detect::CircleGrid;
            Pattern::CircleGrid(if *asymmetric {
                CircleGrid::asymmetric(*cols, *rows, spacing_m * 1e3)
            } else {
                CircleGrid::symmetric(*cols, *rows, spacing_m * 1e3, large_radius_m.is_some())
            })
        }
        TargetConfig::AprilTagBoard { .. } => {
            return Err(DatasetError::Input(
                "measuring with AprilTag boards is not supported yet: use the plate or a chessboard".into(),
            ))
        }
    })
}

/// Detects `pattern` in every image (`None` entries stay `None`); an image where the whole
/// pattern is not found becomes `None` and a note.
fn detect_images(
    dir: &Path,
    images: &[(String, Option<String>)],
    pattern: &ferrocal_vision::detect::Pattern,
    n_points: usize,
    notes: &mut Vec<String>,
) -> CornersById {
    use ferrocal_vision::detect::{detect, load_gray, DetectOptions};
    let opts = DetectOptions::default();
    images
        .iter()
        .map(|(id, file)| {
            let corners = file.as_ref().and_then(|f| {
                let path = dir.join(f);
                let found = load_gray(&path).and_then(|img| detect(&img, pattern, &opts, None));
                match found {
                    Ok(d) => match d.into_iter().find(|d| d.complete && d.corners.len() == n_points) {
                        Some(d) => Some(ImageCorners {
                            px: d.corners_px(),
                            covariance_px2: d.corners.iter().map(|c| c.covariance_px2).collect(),
                        }),
                        None => {
                            notes.push(format!("{f}: the whole pattern was not found"));
                            None
                        }
                    },
                    Err(e) => {
                        notes.push(format!("{f}: {e}"));
                        None
                    }
                }
            });
            (id.clone(), corners)
        })
        .collect()
}

/// Options of [`measure_session`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MeasureOptions {
    /// Corner source.
    pub corners: CornerSource,
    /// Corner noise assumed by the pose estimation, pixels: for every corner with
    /// [`CornerSource::TruthWithNoise`], and for corners the detector gave no usable covariance
    /// with [`CornerSource::Detector`] (the others are weighted by their own covariance).
    pub corner_sigma_px: f64,
    /// Camera calibration options (lens model, robust loss, ...).
    pub calibration: CalibrationOptions,
}

impl MeasureOptions {
    /// The options of `ferrocal measure --session`: the detector's corners, `corner_sigma_px` for
    /// corners without a covariance (refused unless positive), the default calibration.
    pub fn detector(corner_sigma_px: f64) -> Result<Self, DatasetError> {
        if !(corner_sigma_px.is_finite() && corner_sigma_px > 0.0) {
            return Err(DatasetError::Input(format!(
                "measure: --corner-sigma-px must be positive, got {corner_sigma_px}"
            )));
        }
        Ok(Self { corners: CornerSource::Detector, corner_sigma_px, calibration: CalibrationOptions::default() })
    }
}

/// Refuses a table `out` inside the session folder `session` (a file of the session).
pub fn check_out_of_session(out: &Path, session: &Path) -> Result<(), DatasetError> {
    if let (Ok(out), Ok(session)) = (out.canonicalize(), session.canonicalize()) {
        if out.starts_with(&session) {
            return Err(DatasetError::Input(format!(
                "measure: refusing to overwrite {}, a file of the session",
                out.display()
            )));
        }
    }
    Ok(())
}

/// One robot pose measured by the cameras.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct MeasuredPose {
    /// Pose id (from the joint table).
    pub pose_id: String,
    /// The estimate, `T_cam0_target`.
    pub estimate: PoseEstimate,
    /// Cameras that saw the target.
    pub cameras: Vec<usize>,
    /// Mean image position of the target's corners per camera that saw it.
    pub image_centre_px: Vec<(usize, [f64; 2])>,
}

/// The result of [`measure_session`].
#[derive(Clone, Debug)]
pub struct SessionMeasurement {
    /// The calibrated rig.
    pub rig: RigCalibration,
    /// Per measured pose.
    pub poses: Vec<MeasuredPose>,
    /// The measurement rows (cam0 frame), joints from the session's joint table.
    pub rows: MeasurementSet,
    /// Poses not measured, with the reason.
    pub skipped: Vec<String>,
    /// The kinds of the session's joints (the units the table writes them in).
    pub joint_kinds: Vec<ferrocal_robot::JointKind>,
    /// Each camera's own pose of the target against camera 0's (see [`CameraAgreement`]).
    pub agreement: CameraAgreement,
    /// Poses whose reprojection RMS is far above the others' ([`screen_reprojection`]); those
    /// left out are also in `skipped`.
    pub reprojection: ReprojectionScreening,
}

/// The target's corner points in its own frame, in the order of the session's corner files.
pub fn target_points(manifest: &SessionManifest) -> Result<Vec<Point3<f64>>, DatasetError> {
    let pattern = manifest
        .target
        .as_ref()
        .ok_or_else(|| DatasetError::Input("the session has no target: nothing for cameras to measure".into()))?;
    Ok(pattern.build()?.corners.iter().map(|c| c.p_target_m).collect())
}

/// Reads `joints.csv` of a session: pose id, joints (SI), time, temperature, payload, directions;
/// and the joints' kinds from the header (`q<i>_rad`: revolute, `q<i>_m`: prismatic).
pub fn read_session_joints(
    dir: &Path,
    manifest: &SessionManifest,
) -> Result<(Vec<PoseMeasurement>, Vec<ferrocal_robot::JointKind>), DatasetError> {
    let path = dir.join(&manifest.joints);
    let text = std::fs::read_to_string(&path).map_err(|source| DatasetError::Io { path: path.clone(), source })?;
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap_or("").split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name);
    let q_cols: Vec<usize> = header
        .iter()
        .enumerate()
        .filter(|(_, h)| h.starts_with('q') && (h.ends_with("_rad") || h.ends_with("_m")))
        .map(|(i, _)| i)
        .collect();
    let kinds = q_cols
        .iter()
        .map(|&c| {
            if header[c].ends_with("_rad") {
                ferrocal_robot::JointKind::Revolute
            } else {
                ferrocal_robot::JointKind::Prismatic
            }
        })
        .collect();
    let dir_cols: Vec<usize> =
        header.iter().enumerate().filter(|(_, h)| h.starts_with("dir")).map(|(i, _)| i).collect();
    let mut out = Vec::new();
    for (k, line) in lines.enumerate() {
        let f: Vec<&str> = line.split(',').collect();
        let bad = |c: usize| {
            DatasetError::Input(format!("{}: line {}, field {}: not a number", path.display(), k + 2, c + 1))
        };
        let num =
            |c: usize| -> Result<f64, DatasetError> { f.get(c).and_then(|s| s.parse().ok()).ok_or_else(|| bad(c)) };
        let q = q_cols.iter().map(|&c| num(c)).collect::<Result<Vec<_>, _>>()?;
        let mut row = PoseMeasurement::new(f[0], q, nalgebra::Vector3::zeros());
        row.t_s = col("t_s").map(num).transpose()?;
        row.temp_c = col("temp_c").map(num).transpose()?;
        row.payload_kg = col("payload_kg").map(num).transpose()?;
        row.dir = Some(dir_cols.iter().map(|&c| num(c).map(|v| v as i8)).collect::<Result<Vec<_>, _>>()?);
        row.source_line = Some(k as u64 + 2);
        out.push(row);
    }
    Ok((out, kinds))
}

/// Reads the exact corners of one camera: per pose id, the pixels of every corner index.
fn read_truth_corners(dir: &Path, file: &str, n_points: usize) -> Result<TruthCorners, DatasetError> {
    let path = dir.join(file);
    let text = std::fs::read_to_string(&path).map_err(|source| DatasetError::Io { path: path.clone(), source })?;
    let mut out: TruthCorners = Default::default();
    let mut counter: std::collections::HashMap<String, usize> = Default::default();
    for (k, line) in text.lines().enumerate().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        if f.len() < 6 {
            return Err(DatasetError::Input(format!("{}: line {}: expected 6 fields", path.display(), k + 1)));
        }
        let parse = |s: &str| -> Result<f64, DatasetError> {
            s.parse()
                .map_err(|_| DatasetError::Input(format!("{}: line {}: '{s}' is not a number", path.display(), k + 1)))
        };
        let id = f[0].to_string();
        let i = counter.entry(id.clone()).or_insert(0);
        let slot = out.entry(id).or_insert_with(|| vec![None; n_points]);
        if *i < n_points && f[5].trim() == "1" {
            slot[*i] = Some(Point2::new(parse(f[3])?, parse(f[4])?));
        }
        *i += 1;
    }
    Ok(out)
}

/// Corners of every image of one camera from `file` (the session's exact corners), by pose id;
/// `None` for an image where not every corner is in view.
#[allow(clippy::too_many_arguments)]
fn corners_for(
    dir: &Path,
    file: &str,
    n_points: usize,
    source: &CornerSource,
    camera: &str,
    images: &[(String, Option<String>)],
    pattern: &crate::render::TargetConfig,
    notes: &mut Vec<String>,
) -> Result<CornersById, DatasetError> {
    if let CornerSource::Detector = source {
        let p = detector_pattern(pattern)?;
        return Ok(detect_images(dir, images, &p, n_points, notes));
    }
    let truth = read_truth_corners(dir, file, n_points)?;
    match source {
        CornerSource::Detector => unreachable!("handled above"),
        CornerSource::TruthWithNoise { sigma_px, seed } => {
            let noise =
                Normal::new(0.0, *sigma_px).map_err(|e| DatasetError::Input(format!("camera {camera}: {e}")))?;
            // One generator per file, seeded by the file name too, so every image gets its own noise.
            let salt = file.bytes().fold(0u64, |h, b| h.wrapping_mul(131).wrapping_add(b as u64));
            let mut rng = ChaCha8Rng::seed_from_u64(seed ^ salt);
            let mut keys: Vec<&String> = truth.keys().collect();
            keys.sort();
            Ok(keys
                .into_iter()
                .map(|id| {
                    let c = &truth[id];
                    let v = if c.iter().any(|p| p.is_none()) {
                        None
                    } else {
                        Some(ImageCorners {
                            px: c
                                .iter()
                                .map(|p| {
                                    let p = p.expect("checked");
                                    Point2::new(p.x + noise.sample(&mut rng), p.y + noise.sample(&mut rng))
                                })
                                .collect(),
                            covariance_px2: Vec::new(),
                        })
                    };
                    (id.clone(), v)
                })
                .collect())
        }
    }
}

/// `measure --session`'s workflow: the session measured (each image left out reported through
/// `skipped`), refused when no pose could be measured or when its data contradict themselves
/// (swapped or shifted image lists, a square size in the wrong unit; `limits`), and compared
/// with a tracker's table of the same poses (`tracker`: the table and the robot model) when
/// given.
pub fn measure_session_checked(
    dir: &Path,
    opts: &MeasureOptions,
    limits: &ferrocal_calib::verdict::MeasureLimits,
    tracker: Option<(&Path, &str)>,
    skipped: &dyn Fn(&str),
) -> Result<(SessionMeasurement, Option<TrackerComparison>), DatasetError> {
    let m = measure_session(dir, opts)?;
    m.skipped.iter().for_each(|s| skipped(s));
    if m.rows.rows.is_empty() {
        let n = m.skipped.len();
        return Err(DatasetError::Input(format!("no pose of the session could be measured ({n} skipped)")));
    }
    m.check_consistent(limits)?;
    let comparison = tracker.map(|(t, robot)| m.compare_with_tracker_table(t, robot)).transpose()?;
    Ok((m, comparison))
}

/// Measures every pose of a session with its cameras.
pub fn measure_session(dir: &Path, opts: &MeasureOptions) -> Result<SessionMeasurement, DatasetError> {
    let manifest: SessionManifest = serde_json::from_str(
        &std::fs::read_to_string(dir.join("manifest.json"))
            .map_err(|source| DatasetError::Io { path: dir.join("manifest.json"), source })?,
    )?;
    if manifest.cameras.is_empty() {
        return Err(DatasetError::Input(format!("{}: the session has no cameras", dir.display())));
    }
    let points = target_points(&manifest)?;
    let (joints, joint_kinds) = read_session_joints(dir, &manifest)?;
    let n = points.len();
    // Corners per camera and pose.
    let mut notes = Vec::new();
    let target_pattern = manifest.target.clone().expect("checked by target_points");
    let mut corners: Vec<Vec<Option<ImageCorners>>> = Vec::new();
    for (ci, cam) in manifest.cameras.iter().enumerate() {
        let source = match &opts.corners {
            CornerSource::TruthWithNoise { sigma_px, seed } => {
                CornerSource::TruthWithNoise { sigma_px: *sigma_px, seed: seed.wrapping_add(1000 * ci as u64) }
            }
            CornerSource::Detector => CornerSource::Detector,
        };
        let images: Vec<(String, Option<String>)> =
            joints.iter().zip(&cam.images).map(|(r, f)| (r.pose_id.clone(), f.clone())).collect();
        let m = corners_for(dir, &cam.corners_truth, n, &source, &cam.name, &images, &target_pattern, &mut notes)?;
        corners.push(joints.iter().map(|row| m.get(&row.pose_id).cloned().flatten()).collect());
    }
    // Rig calibration: from the calibration board when the session has one (the usual way),
    // else from the plate views themselves (which needs plate views in varied orientations).
    let rig = match &manifest.calibration_board {
        Some(board) => {
            let board_points: Vec<Point3<f64>> = board.build()?.corners.iter().map(|c| c.p_target_m).collect();
            let nb = board_points.len();
            let mut per_cam = Vec::new();
            for cam in &manifest.cameras {
                let file = cam.board_corners_truth.as_ref().ok_or_else(|| {
                    DatasetError::Input(format!(
                        "camera {}: the session lists a calibration board but no board corners",
                        cam.name
                    ))
                })?;
                let images: Vec<(String, Option<String>)> =
                    cam.board_images.iter().enumerate().map(|(k, f)| (format!("b{:03}", k + 1), f.clone())).collect();
                per_cam.push(corners_for(dir, file, nb, &opts.corners, cam.name.as_str(), &images, board, &mut notes)?);
            }
            let mut ids: Vec<String> = per_cam.iter().flat_map(|m| m.keys().cloned()).collect();
            ids.sort();
            ids.dedup();
            let views: Vec<Vec<Option<View>>> = manifest
                .cameras
                .iter()
                .zip(&per_cam)
                .map(|(cam, m)| {
                    let size = ImageSize { width_px: cam.width_px, height_px: cam.height_px };
                    ids.iter()
                        .map(|id| {
                            m.get(id)
                                .cloned()
                                .flatten()
                                .map(|c| View::new(format!("{} board {id}", cam.name), size, c.px))
                        })
                        .collect()
                })
                .collect();
            calibrate_rig(&views, &PlanarTarget { points_m: board_points, reversible: false }, &opts.calibration)?
        }
        None => {
            let target = PlanarTarget { points_m: points.clone(), reversible: false };
            let views: Vec<Vec<Option<View>>> = manifest
                .cameras
                .iter()
                .zip(&corners)
                .map(|(cam, per_pose)| {
                    let size = ImageSize { width_px: cam.width_px, height_px: cam.height_px };
                    per_pose
                        .iter()
                        .zip(&joints)
                        .map(|(c, row)| {
                            c.as_ref()
                                .map(|c| View::new(format!("{} pose {}", cam.name, row.pose_id), size, c.px.clone()))
                        })
                        .collect()
                })
                .collect();
            calibrate_rig(&views, &target, &opts.calibration)?
        }
    };
    let camera_rig = rig.rig();
    // One pose per robot pose.
    let ids: Vec<usize> = (0..n).collect();
    let mut poses = Vec::new();
    let mut rows = Vec::new();
    let mut skipped = Vec::new();
    for (k, row) in joints.iter().enumerate() {
        let obs: Vec<RigObservation> = corners
            .iter()
            .enumerate()
            .filter_map(|(c, per_pose)| {
                per_pose[k].as_ref().map(|ic| RigObservation {
                    camera: c,
                    point_ids: ids.clone(),
                    corners_px: ic.px.clone(),
                    noise: if ic.covariance_px2.is_empty() {
                        CornerNoise::Isotropic { sigma_px: opts.corner_sigma_px }
                    } else {
                        CornerNoise::from_detected(&ic.covariance_px2, opts.corner_sigma_px)
                    },
                })
            })
            .collect();
        if obs.is_empty() {
            skipped.push(format!("pose {}: no camera saw the whole target", row.pose_id));
            continue;
        }
        match estimate_pose_rig(&camera_rig, &points, &obs) {
            Ok(est) => {
                let mut m = row.clone();
                m.position_m = est.t_cam_target.translation.vector;
                m.orientation = Some(est.t_cam_target.rotation);
                let s = est.sigma_position_mm();
                m.sigma_m = Some((s.norm_squared() / 3.0).sqrt() * 1e-3);
                let r = est.sigma_rotation_deg();
                m.sigma_rad = Some((r.norm_squared() / 3.0).sqrt().to_radians());
                // The whole 6 x 6 (mm, rad) in SI; the same chart as the kinematic residual.
                m.covariance = Some(PoseCovariance::from_mm_rad(&est.covariance));
                rows.push(m);
                let centres = obs
                    .iter()
                    .map(|o| {
                        let c = o.corners_px.iter().fold(Point2::origin().coords, |s, p| s + p.coords)
                            / o.corners_px.len() as f64;
                        (o.camera, [c.x, c.y])
                    })
                    .collect();
                poses.push(MeasuredPose {
                    pose_id: row.pose_id.clone(),
                    estimate: est,
                    cameras: obs.iter().map(|o| o.camera).collect(),
                    image_centre_px: centres,
                });
            }
            Err(e) => skipped.push(format!("pose {}: {e}", row.pose_id)),
        }
    }
    // Poses whose corners do not fit one view of the target in every camera: named, left out
    // up to a cap (`poses` and `rows` are parallel).
    let names: Vec<String> = poses.iter().map(|p: &MeasuredPose| format!("pose {}", p.pose_id)).collect();
    let rms: Vec<f64> = poses.iter().map(|p| p.estimate.rms_px).collect();
    let reprojection = screen_reprojection(&names, &rms, &ReprojectionScreen::default());
    let keep: Vec<bool> = names.iter().map(|n| !reprojection.left_out(n)).collect();
    let mut kept = keep.iter();
    rows.retain(|_| *kept.next().expect("parallel"));
    let mut kept = keep.iter();
    poses.retain(|_| *kept.next().expect("parallel"));
    skipped.extend(reprojection.flagged.iter().filter(|o| o.left_out).map(|o| o.describe(reprojection.median_rms_px)));
    skipped.extend(notes);
    let agreement = {
        let pose_ids: Vec<String> = joints.iter().map(|r| r.pose_id.clone()).collect();
        let cmp = |c: usize, c0: &[Option<ImageCorners>], cc: &[Option<ImageCorners>], offset: i64| {
            compare_cameras(&camera_rig, &points, &pose_ids, c, c0, cc, offset, opts.corner_sigma_px)
        };
        let mut poses = Vec::new();
        let mut hypotheses = Vec::new();
        for c in 1..corners.len() {
            // The hypotheses cost one single-camera pose per image each (cheap beside detection).
            hypotheses.push((Hypothesis::Swapped(c), cmp(c, &corners[c], &corners[0], 0)));
            for o in [1, -1] {
                hypotheses.push((Hypothesis::Shifted(c, o), cmp(c, &corners[0], &corners[c], o)));
            }
            poses.extend(cmp(c, &corners[0], &corners[c], 0));
        }
        CameraAgreement {
            poses,
            hypotheses,
            images: manifest.cameras.iter().map(|c| c.images.clone()).collect(),
            camera_names: manifest.cameras.iter().map(|c| c.name.clone()).collect(),
        }
    };
    Ok(SessionMeasurement {
        agreement,
        reprojection,
        rig,
        poses,
        rows: MeasurementSet { source: format!("cameras of {}", dir.display()), rows },
        skipped,
        joint_kinds,
    })
}

/// The camera system against a laser tracker on the same robot poses (the source's Fig. 5.19
/// experiment), and the models calibrated from each device on the same held-out tracker poses.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct TrackerComparison {
    /// Poses measured by both devices.
    pub n_common: usize,
    /// `T_tracker_cam0` from the training poses (rigid registration of the positions).
    pub t_tracker_cam0: nalgebra::Isometry3<f64>,
    /// Camera position errors against the tracker after registration, mm, per common pose.
    pub camera_errors_mm: Vec<f64>,
    /// Mean of [`TrackerComparison::camera_errors_mm`].
    pub camera_mean_mm: f64,
    /// Distance of each common pose from camera 0, m.
    pub distance_m: Vec<f64>,
    /// Mean image position of the target in camera 0 per common pose, px.
    pub image_centre_px: Vec<[f64; 2]>,
    /// Held-out tracker errors of the model calibrated from the tracker.
    pub tracker_model: ferrocal_calib::kinematic::ErrorStats,
    /// Held-out tracker errors of the model calibrated from the cameras.
    pub camera_model: ferrocal_calib::kinematic::ErrorStats,
    /// Held-out tracker errors of the nominal model (frames registered).
    pub nominal_model: ferrocal_calib::kinematic::ErrorStats,
}

/// Runs the comparison: `camera` rows in the cam0 frame, `tracker` rows in the tracker frame,
/// matched by pose id; every second common pose trains, the others are held out.
pub fn compare_with_tracker(
    model: &ferrocal_robot::RobotModel,
    camera: &MeasurementSet,
    tracker: &MeasurementSet,
    poses: &[MeasuredPose],
    opts: &ferrocal_calib::kinematic::KinematicOptions,
) -> Result<TrackerComparison, DatasetError> {
    use ferrocal_calib::kinematic::{calibrate, KinematicOptions, ModelParams};
    let by_id: std::collections::HashMap<&str, &PoseMeasurement> =
        tracker.rows.iter().map(|r| (r.pose_id.as_str(), r)).collect();
    let pairs: Vec<(&PoseMeasurement, &PoseMeasurement)> =
        camera.rows.iter().filter_map(|c| by_id.get(c.pose_id.as_str()).map(|t| (c, *t))).collect();
    if pairs.len() < 10 {
        return Err(DatasetError::Input(format!(
            "only {} poses measured by both devices; at least 10 needed",
            pairs.len()
        )));
    }
    let train: Vec<usize> = (0..pairs.len()).step_by(2).collect();
    let test: Vec<usize> = (1..pairs.len()).step_by(2).collect();
    let cal_err = |e: ferrocal_calib::CalibError| DatasetError::Input(e.to_string());
    let from: Vec<Point3<f64>> = train.iter().map(|&i| Point3::from(pairs[i].0.position_m)).collect();
    let to: Vec<Point3<f64>> = train.iter().map(|&i| Point3::from(pairs[i].1.position_m)).collect();
    let t_tracker_cam0 = ferrocal_calib::frames::fit_rigid(&from, &to).map_err(cal_err)?;
    let camera_errors_mm: Vec<f64> = pairs
        .iter()
        .map(|(c, t)| (t_tracker_cam0 * Point3::from(c.position_m) - Point3::from(t.position_m)).norm() * 1e3)
        .collect();
    let camera_mean_mm = camera_errors_mm.iter().sum::<f64>() / camera_errors_mm.len() as f64;
    let pose_by_id: std::collections::HashMap<&str, &MeasuredPose> =
        poses.iter().map(|p| (p.pose_id.as_str(), p)).collect();
    let distance_m = pairs.iter().map(|(c, _)| c.position_m.norm()).collect();
    let image_centre_px = pairs
        .iter()
        .map(|(c, _)| {
            pose_by_id.get(c.pose_id.as_str()).and_then(|p| p.image_centre_px.first()).map_or([f64::NAN; 2], |x| x.1)
        })
        .collect();
    // Positions only: the tracker measures a reflector.
    let pos_opts = KinematicOptions { use_orientation: false, ..opts.clone() };
    let tracker_train: Vec<&PoseMeasurement> = train.iter().map(|&i| pairs[i].1).collect();
    let tracker_test: Vec<&PoseMeasurement> = test.iter().map(|&i| pairs[i].1).collect();
    let camera_train: Vec<&PoseMeasurement> = train.iter().map(|&i| pairs[i].0).collect();
    let tracker_cal = calibrate(model, &tracker_train, &pos_opts).map_err(cal_err)?;
    let camera_cal = calibrate(model, &camera_train, &pos_opts).map_err(cal_err)?;
    let nominal = calibrate(
        model,
        &tracker_train,
        &KinematicOptions { model_params: ModelParams::None, joint_offsets: false, ..pos_opts.clone() },
    )
    .map_err(cal_err)?;
    // The camera-calibrated model predicts in cam0: bring it to the tracker frame.
    let mut camera_model = camera_cal.calibrated.clone();
    camera_model.device_frame = t_tracker_cam0 * camera_model.device_frame;
    Ok(TrackerComparison {
        n_common: pairs.len(),
        t_tracker_cam0,
        camera_errors_mm,
        camera_mean_mm,
        distance_m,
        image_centre_px,
        tracker_model: tracker_cal.calibrated.evaluate(&tracker_test).map_err(cal_err)?,
        camera_model: camera_model.evaluate(&tracker_test).map_err(cal_err)?,
        nominal_model: nominal.calibrated.evaluate(&tracker_test).map_err(cal_err)?,
    })
}

impl SessionMeasurement {
    /// The measurement table of the session in `session` as text: lengths in mm, each pose's
    /// covariance in the `cov_*` columns, with comments that say where it came from.
    pub fn table_text(&self, session: &Path) -> Result<String, DatasetError> {
        let mut wopts = crate::import::WriteOptions::si(&self.joint_kinds);
        wopts.length_unit = crate::import::LengthUnit::Mm;
        wopts.comments = vec![
            format!("measured by ferrocal {} from {}", env!("CARGO_PKG_VERSION"), session.display()),
            "positions and orientations of the target in the first camera's frame; cov_*: each pose's covariance"
                .into(),
        ];
        crate::import::measurements_to_string(&self.rows, &wopts)
    }

    /// The median of the rows' position standard deviations, mm (NaN without any).
    pub fn median_sigma_mm(&self) -> f64 {
        let mut s: Vec<f64> = self.rows.rows.iter().filter_map(|r| r.sigma_m.map(|s| s * 1e3)).collect();
        s.sort_by(f64::total_cmp);
        s.get(s.len() / 2).copied().unwrap_or(f64::NAN)
    }

    /// [`compare_with_tracker`] against the tracker's measurement table `tracker` with the robot
    /// model `robot` (preset, URDF or TOML) and the default calibration options.
    pub fn compare_with_tracker_table(&self, tracker: &Path, robot: &str) -> Result<TrackerComparison, DatasetError> {
        let tracker = crate::import::read_measurements(tracker)?.set;
        let model = ferrocal_robot::RobotModel::load(robot)?;
        let kopts = ferrocal_calib::kinematic::KinematicOptions::default();
        compare_with_tracker(&model, &self.rows, &tracker, &self.poses, &kopts)
    }
}
