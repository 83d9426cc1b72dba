//! A user's own recording measured by one camera: a folder of images and the poses table of
//! `ferrocal handeye` (`image`, then joint readings or flange poses, optional `split`;
//! [`crate::handeye::poses`]), any target the detectors know (chessboard, ChArUco, circle grid,
//! ...). No truth files, no session manifest.
//!
//! Every image is matched to its row by file name and searched for the target with the project's
//! detector (in parallel over images, [`crate::handeye::recording::load_recording`]); the camera is
//! the one given, or calibrated from the same views (which then need varied orientations); each
//! view's target pose is estimated with the corners' own covariances
//! ([`ferrocal_vision::pose::estimate_pose_rig`]), the calibration's uncertainty propagated when
//! the camera was calibrated here. Where the corners scatter more than their covariances say
//! (`s0 > 1`), the corner part of the pose covariance is scaled by `s0^2`, so the stated
//! uncertainty is never smaller than the residuals support.
//!
//! What the table holds depends on the mount: with the camera fixed and the target on the flange
//! (eye-to-hand) the camera is the measuring device and each row is `T_cam_target`; with the
//! camera on the flange and the target fixed (eye-in-hand) the target is the device frame and each
//! row is `T_target_cam`, the covariance carried through the inversion to first order.
//! A measurement table needs joint readings; with flange poses only the per-image poses are
//! returned (for the JSON summary).

use std::path::{Path, PathBuf};

use nalgebra::{DMatrix, Isometry3, Matrix6};
use serde::Serialize;

use ferrocal_calib::handeye::{HandEyeData, Mount};
use ferrocal_calib::{MeasurementSet, PoseCovariance, PoseMeasurement, Split};
use ferrocal_vision::calib::{calibrate_camera, CalibrationOptions, PlanarTarget, View};
use ferrocal_vision::camera::CameraModel;
use ferrocal_vision::detect::Pattern;
use ferrocal_vision::pose::{estimate_pose_rig, CameraRig, CornerNoise, PoseEstimate, RigObservation};

use crate::error::{DatasetError, Result};
use crate::handeye::poses::{PosesTable, RobotReading};
use crate::handeye::recording::{load_recording, Skipped};
use crate::measure::{screen_reprojection, ReprojectionScreen, ReprojectionScreening};

/// Settings of [`measure_recording`].
#[derive(Clone, Debug, PartialEq)]
pub struct RecordingOptions {
    /// Where the camera is.
    pub mount: Mount,
    /// The camera, when calibrated beforehand; `None` calibrates it from the recording's views.
    pub camera: Option<CameraModel>,
    /// Options of that calibration.
    pub calibration: CalibrationOptions,
    /// Noise of corners without a usable covariance, pixels.
    pub corner_sigma_px: f64,
}

impl RecordingOptions {
    /// The options of `ferrocal measure --images`: the camera read from the file `intrinsics`
    /// (camera calibrate JSON, OpenCV or ROS YAML) or calibrated from the recording's views with
    /// the default options, `corner_sigma_px` for corners without a covariance.
    pub fn new(mount: Mount, intrinsics: Option<&Path>, corner_sigma_px: f64) -> Result<Self> {
        let camera = intrinsics.map(crate::handeye::read_camera_file).transpose()?;
        Ok(Self { mount, camera, calibration: CalibrationOptions::default(), corner_sigma_px })
    }
}

/// One image's measured pose.
#[derive(Clone, Debug, Serialize)]
pub struct ImagePose {
    /// The image's file name (its row's `image`).
    pub image: String,
    /// The row's split.
    pub split: Split,
    /// `T_cam_target` with its covariance as the estimator gives it (mm, rad; corner part
    /// scaled by `s0^2` where `s0 > 1`).
    pub estimate: PoseEstimate,
    /// What the table holds: `T_cam_target` (eye-to-hand) or `T_target_cam` (eye-in-hand).
    pub measured: Isometry3<f64>,
    /// Covariance of `measured` in the chart of [`ferrocal_vision::pose`] (mm, rad).
    pub measured_covariance_mm_rad: Matrix6<f64>,
}

impl ImagePose {
    /// Standard deviations of the measured position, mm per axis.
    pub fn sigma_position_mm(&self) -> [f64; 3] {
        [0, 1, 2].map(|i| self.measured_covariance_mm_rad[(i, i)].max(0.0).sqrt())
    }

    /// Standard deviations of the measured orientation, degrees per axis.
    pub fn sigma_rotation_deg(&self) -> [f64; 3] {
        [3, 4, 5].map(|i| self.measured_covariance_mm_rad[(i, i)].max(0.0).sqrt().to_degrees())
    }

    /// The RMS of the three position standard deviations, mm.
    pub fn sigma_position_rms_mm(&self) -> f64 {
        (self.sigma_position_mm().iter().map(|s| s * s).sum::<f64>() / 3.0).sqrt()
    }
}

/// The camera a recording was measured with.
#[derive(Clone, Debug, Serialize)]
pub struct RecordingCamera {
    /// The camera.
    pub camera: CameraModel,
    /// Standard deviations of `fx fy cx cy k...` when calibrated here.
    pub std: Option<Vec<f64>>,
    /// Calibration RMS over the views, pixels, when calibrated here.
    pub calibration_rms_px: Option<f64>,
    /// Views the calibration used.
    pub calibration_views: usize,
}

/// The result of [`measure_recording`].
#[derive(Clone, Debug, Serialize)]
pub struct RecordingMeasurement {
    /// The camera.
    pub camera: RecordingCamera,
    /// One pose per usable image, in the order of the images.
    pub poses: Vec<ImagePose>,
    /// The measurement table (rows in the order of `poses`; `pose_id` is the image's file stem),
    /// when the poses table gives joint readings.
    #[serde(skip)]
    pub rows: Option<MeasurementSet>,
    /// Images and rows left out, with the reason.
    pub skipped: Vec<Skipped>,
    /// The data's source and licence from the poses table.
    pub source: Option<String>,
    /// Images whose reprojection RMS is far above the others' ([`screen_reprojection`]); those
    /// left out are also in `skipped`.
    pub reprojection: ReprojectionScreening,
}

fn stem(name: &str) -> String {
    std::path::Path::new(name).file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| name.into())
}

/// The covariance of `T^-1` from that of `T` (chart: position in mm, then a left rotation error
/// in rad): `J = [[-R^T, -R^T [t]x], [0, -R^T]]`.
pub fn inverse_covariance(t: &Isometry3<f64>, cov_mm_rad: &Matrix6<f64>) -> Matrix6<f64> {
    let rt = t.rotation.to_rotation_matrix().matrix().transpose();
    let p = t.translation.vector * 1e3;
    let mut j = Matrix6::zeros();
    j.fixed_view_mut::<3, 3>(0, 0).copy_from(&(-rt));
    j.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-rt * p.cross_matrix()));
    j.fixed_view_mut::<3, 3>(3, 3).copy_from(&(-rt));
    j * cov_mm_rad * j.transpose()
}

/// Measures every image of a recording (see the module documentation). `images` are the image
/// files, `table` the poses table naming them.
pub fn measure_recording(
    images: &[PathBuf],
    table: &PosesTable,
    pattern: &Pattern,
    opts: &RecordingOptions,
) -> Result<RecordingMeasurement> {
    if !(opts.corner_sigma_px.is_finite() && opts.corner_sigma_px > 0.0) {
        return Err(DatasetError::Input(format!("corner sigma must be positive, got {}", opts.corner_sigma_px)));
    }
    // The flange poses are not needed to measure: identity placeholders.
    let flange = vec![Isometry3::identity(); table.rows.len()];
    let (data, mut skipped) = load_recording(images, table, &flange, pattern, opts.mount)?;
    let (camera, measured, more) = measure_views(&data, opts)?;
    skipped.extend(more);
    // Images whose corners do not fit one view of the target: named, left out up to a cap.
    let (names, rms): (Vec<String>, Vec<f64>) =
        measured.iter().map(|(_, p)| (p.image.clone(), p.estimate.rms_px)).unzip();
    let reprojection = screen_reprojection(&names, &rms, &ReprojectionScreen::default());
    let by_image: std::collections::HashMap<&str, usize> =
        table.rows.iter().enumerate().map(|(i, r)| (r.image.as_str(), i)).collect();
    let mut poses = Vec::new();
    let mut rows = Vec::new();
    for (k, pose) in measured {
        let v = &data.views[k];
        if reprojection.left_out(&pose.image) {
            let o = reprojection.flagged.iter().find(|o| o.what == pose.image).expect("flagged");
            skipped.push(Skipped { what: v.name.clone(), reason: o.describe(reprojection.median_rms_px) });
            continue;
        }
        let row = &table.rows[by_image[v.name.as_str()]];
        if let RobotReading::Joints(q) = &row.robot {
            let mut m = pose_row(&pose, q);
            m.pose_id = stem(&v.name);
            m.split = Some(row.split);
            m.source_line = Some(row.line);
            rows.push(m);
        }
        poses.push(pose);
    }
    if poses.is_empty() {
        return Err(DatasetError::Input(format!(
            "no image of {} could be measured ({} left out; the first: {})",
            table.file.display(),
            skipped.len(),
            skipped.first().map(|s| format!("{}: {}", s.what, s.reason)).unwrap_or_default()
        )));
    }
    let rows = (!table.joint_units.is_empty()).then(|| MeasurementSet {
        source: format!("camera measurement of the images of {}", table.file.display()),
        rows,
    });
    Ok(RecordingMeasurement { camera, poses, rows, skipped, source: table.source.clone(), reprojection })
}

/// The measurement-table row of one measured view with joint readings `q`: the measured pose
/// with its full covariance (SI), `sigma_m` / `sigma_rad` the RMS of the position and rotation
/// standard deviations; `pose_id` is the image's name, no split.
pub fn pose_row(pose: &ImagePose, q: &[f64]) -> PoseMeasurement {
    let cov = &pose.measured_covariance_mm_rad;
    let sigma_mm = ((cov[(0, 0)] + cov[(1, 1)] + cov[(2, 2)]) / 3.0).sqrt();
    let sigma_rad = ((cov[(3, 3)] + cov[(4, 4)] + cov[(5, 5)]) / 3.0).sqrt();
    PoseMeasurement {
        orientation: Some(pose.measured.rotation),
        sigma_m: Some(sigma_mm * 1e-3),
        sigma_rad: Some(sigma_rad),
        covariance: Some(PoseCovariance::from_mm_rad(cov)),
        ..PoseMeasurement::new(pose.image.clone(), q.to_vec(), pose.measured.translation.vector)
    }
}

/// What [`measure_views`] returns: the camera, `(view index, pose)` for every view measured,
/// and the views left out.
pub type MeasuredViews = (RecordingCamera, Vec<(usize, ImagePose)>, Vec<Skipped>);

/// Measures every view of `data` (see the module documentation): the camera given or
/// calibrated from all of `data`'s views, and each view's pose with its covariance. Returns the
/// camera, `(view index, pose)` for every view measured, and the views left out.
pub fn measure_views(data: &HandEyeData, opts: &RecordingOptions) -> Result<MeasuredViews> {
    let target = PlanarTarget { points_m: data.target_points_m.clone(), reversible: false };
    if let Some(c) = &opts.camera {
        ferrocal_calib::handeye::check_camera_size(c, &data.views)?;
    }
    let (camera, covariance) = match &opts.camera {
        Some(c) => (RecordingCamera { camera: *c, std: None, calibration_rms_px: None, calibration_views: 0 }, None),
        None => calibrate_from_views(data, &target, &opts.calibration)?,
    };
    let rig = CameraRig { cameras: vec![camera.camera], t_cam_cam0: vec![Isometry3::identity()], covariance };
    let mut out = Vec::new();
    let mut skipped = Vec::new();
    for (k, v) in data.views.iter().enumerate() {
        let obs = RigObservation {
            camera: 0,
            point_ids: v.point_ids.clone(),
            corners_px: v.corners_px.clone(),
            noise: CornerNoise::from_detected(&v.covariances_px2, opts.corner_sigma_px),
        };
        let mut est = match estimate_pose_rig(&rig, &data.target_points_m, std::slice::from_ref(&obs)) {
            Ok(e) => e,
            Err(e) => {
                skipped.push(Skipped { what: v.name.clone(), reason: format!("pose not estimated: {e}") });
                continue;
            }
        };
        if est.s0 > 1.0 {
            let extra = est.covariance_corners * (est.s0 * est.s0 - 1.0);
            est.covariance += extra;
            est.covariance_corners += extra;
        }
        let (measured, cov) = match opts.mount {
            Mount::EyeToHand => (est.t_cam_target, est.covariance),
            Mount::EyeInHand => (est.t_cam_target.inverse(), inverse_covariance(&est.t_cam_target, &est.covariance)),
        };
        out.push((
            k,
            ImagePose {
                image: v.name.clone(),
                split: v.split,
                estimate: est,
                measured,
                measured_covariance_mm_rad: cov,
            },
        ));
    }
    Ok((camera, out, skipped))
}

fn views_of(data: &HandEyeData) -> Vec<View> {
    data.views
        .iter()
        .map(|v| View {
            name: v.name.clone(),
            image_size: v.image_size,
            point_ids: v.point_ids.clone(),
            corners_px: v.corners_px.clone(),
        })
        .collect()
}

/// The camera calibrated from the recording's views, with the covariance of its parameters
/// (propagated into the poses).
fn calibrate_from_views(
    data: &HandEyeData,
    target: &PlanarTarget,
    options: &CalibrationOptions,
) -> Result<(RecordingCamera, Option<DMatrix<f64>>)> {
    let cal = calibrate_camera(&views_of(data), target, options).map_err(|e| {
        DatasetError::Input(format!(
            "the camera could not be calibrated from the recording's {} views ({e}); give it with --intrinsics",
            data.views.len()
        ))
    })?;
    let camera = RecordingCamera {
        camera: cal.camera,
        std: Some(cal.std.clone()),
        calibration_rms_px: Some(cal.rms_px),
        calibration_views: cal.views.iter().filter(|v| v.used).count(),
    };
    // With a fixed aspect ratio the covariance has one row fewer than the model's parameters:
    // not propagated then (the corners' part stays).
    let cov = (cal.covariance.nrows() == cal.camera.n_parameters()).then_some(cal.covariance);
    Ok((camera, cov))
}

/// What a row of a recording's measurement table is for `mount`: the target in the camera's
/// frame (eye-to-hand) or the camera in the fixed target's frame (eye-in-hand).
pub fn frame_note(mount: Mount) -> &'static str {
    match mount {
        Mount::EyeToHand => "positions and orientations of the target in the camera's frame",
        Mount::EyeInHand => "positions and orientations of the camera in the fixed target's frame",
    }
}

/// The measurement table of `rows` as `ferrocal measure --out` writes it: joints in SI (rad, m)
/// whatever units the poses table `table` used (the values are SI inside), lengths in mm, with
/// comments naming the images' table `poses`, the frame of `mount` and the data's source.
pub fn recording_table_text(
    rows: &MeasurementSet,
    table: &PosesTable,
    mount: Mount,
    poses: &std::path::Path,
    source: Option<&str>,
) -> Result<String> {
    use crate::import::{measurements_to_string, JointUnit, LengthUnit, WriteOptions};
    let mut wopts = WriteOptions::revolute(table.joint_units.len());
    wopts.joint_units = table
        .joint_units
        .iter()
        .map(|u| match u {
            JointUnit::Rad | JointUnit::Deg => JointUnit::Rad,
            JointUnit::M | JointUnit::Mm => JointUnit::M,
        })
        .collect();
    wopts.length_unit = LengthUnit::Mm;
    wopts.comments = vec![
        format!("measured by ferrocal {} from the images of {}", env!("CARGO_PKG_VERSION"), poses.display()),
        format!("{}; cov_*: each pose's covariance", frame_note(mount)),
    ];
    if let Some(s) = source {
        wopts.comments.push(format!("source: {s}"));
    }
    measurements_to_string(rows, &wopts)
}

/// The inputs of `ferrocal measure --images ... --poses ... --pattern ...`, read: the target,
/// the poses table and the image files.
#[derive(Clone, Debug)]
pub struct RecordingInput {
    /// The target.
    pub pattern: Pattern,
    /// The poses table file.
    pub poses: PathBuf,
    /// The poses table.
    pub table: PosesTable,
    /// The image files the specifications named.
    pub paths: Vec<PathBuf>,
    /// Specifications that named no image.
    pub skipped_images: Vec<ferrocal_vision::calib::corners::SkippedImage>,
}

impl RecordingInput {
    /// Reads the pattern string `pattern`, the poses table `poses` and the images of `images`
    /// (files, directories or globs); with `table_out` (a measurement table is to be written)
    /// a table of flange poses is refused: the table needs joint readings.
    pub fn load(images: &[PathBuf], poses: &Path, pattern: &str, table_out: bool) -> Result<Self> {
        let pattern: Pattern = pattern.parse()?;
        let table = crate::handeye::read_handeye_poses(poses)?;
        if table_out && table.joint_units.is_empty() {
            return Err(DatasetError::Input(format!(
                "measure: {} gives flange poses, but a measurement table needs joint readings (q1_<unit>, ...); \
                 leave out --out to get the per-image poses in --json, or use `ferrocal handeye` for the hand-eye transform",
                poses.display()
            )));
        }
        let mut skipped_images = Vec::new();
        let paths = crate::import::images::expand_image_specs(images, &mut skipped_images);
        Ok(Self { pattern, poses: poses.to_path_buf(), table, paths, skipped_images })
    }

    /// The input files: the images, then the poses table.
    pub fn inputs(&self) -> Vec<&Path> {
        self.paths.iter().map(PathBuf::as_path).chain([self.poses.as_path()]).collect()
    }

    /// Refuses an output that is an input (the same file, through any path).
    pub fn refuse_overwrite(&self, outputs: &[&Path]) -> Result<()> {
        for o in outputs {
            if let Ok(o) = o.canonicalize() {
                if self.inputs().iter().any(|p| p.canonicalize().is_ok_and(|p| p == o)) {
                    return Err(DatasetError::Input(format!(
                        "measure: refusing to overwrite {}, an input",
                        o.display()
                    )));
                }
            }
        }
        Ok(())
    }

    /// Every image left out, with the reason: those no specification found, then those the
    /// measurement `m` could not use.
    pub fn skipped_lines(&self, m: &RecordingMeasurement) -> Vec<String> {
        let images = self.skipped_images.iter().map(ToString::to_string);
        images.chain(m.skipped.iter().map(|s| format!("{}: {}", s.what, s.reason))).collect()
    }

    /// Measures every image ([`measure_recording`]).
    pub fn measure(&self, opts: &RecordingOptions) -> Result<RecordingMeasurement> {
        measure_recording(&self.paths, &self.table, &self.pattern, opts)
    }

    /// The measurement table of `rows` ([`recording_table_text`]).
    pub fn table_text(&self, rows: &MeasurementSet, mount: Mount, source: Option<&str>) -> Result<String> {
        recording_table_text(rows, &self.table, mount, &self.poses, source)
    }
}
