//! The `handeye` workflow: a recording (images, the poses table, the target, the mount) loaded
//! ([`HandEyeInput::load`]), the hand-eye calibration with OpenCV's solvers beside it on the
//! same corners ([`HandEyeInput::fit`]) and, with a robot model and joint readings, the joint
//! adjustment of robot and camera ([`HandEyeInput::joint_adjustment`]); and `handeye simulate`'s
//! recordings ([`write_simulated_recording`]). The binary turns its
//! arguments into [`HandEyeRunOptions`]; the report crate turns the results into JSON and HTML.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use ferrocal_calib::handeye::opencv::{opencv_baselines, BaselineReport};
use ferrocal_calib::handeye::physics::{select_chain_physics, ChainPhysicsReport, PhysicsOptions};
use ferrocal_calib::handeye::{
    calibrate_hand_eye_from, calibrate_joint_from, start_poses, HandEyeData, HandEyeOptions, HandEyeResult,
    IntrinsicsMode, JointCalibration, JointOptions, Mount, StartPoses,
};
use ferrocal_lsq::Loss;
use ferrocal_robot::RobotModel;
use ferrocal_vision::calib::corners::SkippedImage;
use ferrocal_vision::calib::CalibrationOptions;
use ferrocal_vision::camera::ImageSize;
use ferrocal_vision::detect::Pattern;

use super::{load_recording, read_camera_file, read_handeye_poses, PosesTable, RobotReading, Skipped};
use crate::error::{DatasetError, Result};
use crate::import::images::expand_image_specs;

/// The inputs and choices of a hand-eye calibration (the arguments of `ferrocal handeye`).
#[derive(Clone, Debug)]
pub struct HandEyeRunOptions {
    /// Images: files, directories or globs.
    pub images: Vec<PathBuf>,
    /// The poses table (`image`, a flange pose or joint readings, optional `split`).
    pub poses: PathBuf,
    /// The target, e.g. `chessboard:9x6:25mm`.
    pub pattern: String,
    /// Where the camera is.
    pub mount: Mount,
    /// Robot model (preset, URDF or TOML) for joint readings.
    pub robot: Option<String>,
    /// Camera file to hold fixed; without it the camera is calibrated from the training images.
    pub intrinsics: Option<PathBuf>,
    /// Fit the printed target's overall scale against the robot's metric poses.
    pub fit_target_scale: bool,
    /// Huber threshold in robust standard deviations (0: plain least squares).
    pub huber_sigmas: f64,
    /// Take the flange poses as measurements with the noise estimated from the data.
    pub robot_poses_as_measurements: bool,
    /// The flange poses' noise, given: mm per coordinate and degrees per axis (not estimated).
    pub robot_sigma_mm_deg: Option<(f64, f64)>,
    /// Take the flange poses as exact (no robot-pose noise); overrides the two above.
    pub exact_robot_poses: bool,
    /// Decide the target's bending and print scale and the lens model on the training images
    /// ([`select_chain_physics`]) before the fit; off: the flat target and the given lens model.
    pub physics: bool,
    /// Detections made elsewhere instead of `images` (`crate::import::observations`), with the
    /// images' size when their files are not beside the observations file.
    pub observations: Option<(PathBuf, Option<ImageSize>)>,
}

impl HandEyeRunOptions {
    /// The options of the method: the camera given or calibrated, the print scale, the robust
    /// loss and the robot poses' noise as asked.
    pub fn hand_eye_options(&self) -> Result<HandEyeOptions> {
        let intrinsics = match &self.intrinsics {
            Some(p) => IntrinsicsMode::Fixed(read_camera_file(p)?),
            None => IntrinsicsMode::Calibrate(CalibrationOptions::default()),
        };
        let mut options = HandEyeOptions {
            intrinsics,
            fit_target_scale: self.fit_target_scale,
            huber_sigmas: self.huber_sigmas,
            ..HandEyeOptions::default()
        };
        if self.robot_poses_as_measurements {
            (options.robot_sigma_m, options.robot_sigma_rad) = HandEyeOptions::MEASURED_POSE_SIGMAS;
        }
        if let Some((mm, deg)) = self.robot_sigma_mm_deg {
            (options.robot_sigma_m, options.robot_sigma_rad, options.estimate_noise) =
                (mm * 1e-3, deg.to_radians(), false);
        }
        if self.exact_robot_poses {
            (options.robot_sigma_m, options.robot_sigma_rad) = (0.0, 0.0);
        }
        Ok(options)
    }
}

/// The input files of a hand-eye run: the poses table, the camera file, the robot model's file
/// (a preset name is checked as a path too, and names none) and the image specifications.
pub fn run_inputs<'a>(
    poses: &'a Path,
    intrinsics: Option<&'a Path>,
    robot: Option<&'a str>,
    images: &'a [PathBuf],
) -> Vec<&'a Path> {
    let mut inputs = vec![poses];
    inputs.extend(intrinsics);
    inputs.extend(robot.map(Path::new));
    inputs.extend(images.iter().map(PathBuf::as_path));
    inputs
}

/// A loaded recording: the corners of every usable image with its flange pose.
#[derive(Clone, Debug)]
pub struct HandEyeInput {
    /// The target.
    pub pattern: Pattern,
    /// The poses table.
    pub table: PosesTable,
    /// The robot model, when joint readings are to be turned into flange poses.
    pub robot: Option<RobotModel>,
    /// The image files the specifications named.
    pub paths: Vec<PathBuf>,
    /// Specifications that named no image.
    pub skipped_images: Vec<SkippedImage>,
    /// Images (or table rows) left out while loading, with the reason.
    pub skipped: Vec<Skipped>,
    /// The recording.
    pub data: HandEyeData,
    /// The robot's motions against the camera's, once [`HandEyeInput::check_motion`] ran.
    pub motion: Option<super::MotionCheck>,
}

/// A hand-eye calibration with OpenCV's solvers on the same corners.
#[derive(Clone, Debug)]
pub struct HandEyeFit {
    /// The options the method ran with.
    pub options: HandEyeOptions,
    /// The calibration.
    pub result: HandEyeResult,
    /// OpenCV's hand-eye solvers, with the camera the calibration started from.
    pub baselines: Vec<BaselineReport>,
    /// The target's and lens's physics decided on the training images, when asked for.
    pub physics: Option<ChainPhysicsReport>,
}

impl HandEyeInput {
    /// Reads the poses table, the robot model and the images of `o`, and detects the target.
    pub fn load(o: &HandEyeRunOptions) -> Result<Self> {
        let pattern: Pattern = o.pattern.parse()?;
        let table = read_handeye_poses(&o.poses)?;
        let robot = o.robot.as_deref().map(RobotModel::load).transpose()?;
        let flange = table.flange_poses(robot.as_ref())?;
        let mut skipped_images = Vec::new();
        let (paths, (data, skipped)) = match &o.observations {
            Some((file, size)) => {
                let obs = crate::import::observations::read_observations(file)?;
                let size = match size {
                    Some(s) => *s,
                    None => crate::import::observations::image_size_beside(&obs, file).ok_or_else(|| {
                        DatasetError::Input(format!(
                            "{}: none of its images is readable beside it to tell their size; give --image-size <width>x<height>",
                            file.display()
                        ))
                    })?,
                };
                let paths = obs.images.iter().map(|i| PathBuf::from(&i.image)).collect();
                (paths, super::recording::load_observed(&obs, file, size, &table, &flange, &pattern, o.mount)?)
            }
            None => {
                let paths = expand_image_specs(&o.images, &mut skipped_images);
                let loaded = load_recording(&paths, &table, &flange, &pattern, o.mount)?;
                (paths, loaded)
            }
        };
        Ok(Self { pattern, table, robot, paths, skipped_images, skipped, data, motion: None })
    }

    /// Every image left out while loading, with the reason: those no specification found, then
    /// those (or the table rows) that could not be used.
    pub fn skipped_lines(&self) -> Vec<String> {
        let images = self.skipped_images.iter().map(ToString::to_string);
        images.chain(self.skipped.iter().map(|s| format!("{}: {}", s.what, s.reason))).collect()
    }

    /// The hand-eye calibration of the recording with `options`, and OpenCV's solvers beside it.
    pub fn fit(&self, options: HandEyeOptions) -> Result<HandEyeFit> {
        self.fit_from(options, None)
    }

    fn context(&self, e: impl Into<DatasetError>) -> DatasetError {
        e.into().context(format!("handeye: {} usable image(s) of {}", self.data.views.len(), self.paths.len()))
    }

    /// The robot's motions against the camera's before the fit
    /// ([`super::motion_check::check_motion`]): refuses a recording whose motions disagree,
    /// naming the likely cause; images whose robot pose is far off are taken out of the
    /// recording (the check says which and why). Returns the check and, when no image was taken
    /// out, the fit's first steps for [`HandEyeInput::fit_from`] (the same numbers as without
    /// the check).
    pub fn check_motion(&mut self, options: &HandEyeOptions) -> Result<(&super::MotionCheck, Option<StartPoses>)> {
        let start = start_poses(&self.data, options).map_err(|e| self.context(e))?;
        let check = super::check_motion(self.data.mount, &start, &self.table, self.robot.as_ref())?;
        let dropped: Vec<&str> = check.flagged.iter().filter(|f| f.dropped).map(|f| f.image.as_str()).collect();
        let start = if dropped.is_empty() {
            Some(start)
        } else {
            self.data.views.retain(|v| !dropped.contains(&v.name.as_str()));
            for f in check.flagged.iter().filter(|f| f.dropped) {
                self.skipped.push(Skipped { what: f.image.clone(), reason: f.reason.clone() });
            }
            None
        };
        Ok((self.motion.insert(check), start))
    }

    /// [`HandEyeInput::fit`] from the fit's first steps when given (of this recording and
    /// `options`).
    pub fn fit_from(&self, options: HandEyeOptions, start: Option<StartPoses>) -> Result<HandEyeFit> {
        let start = match start {
            Some(s) => s,
            None => start_poses(&self.data, &options).map_err(|e| self.context(e))?,
        };
        let result = calibrate_hand_eye_from(&self.data, &options, start).map_err(|e| self.context(e))?;
        let opencv_camera = result.initial_camera.as_ref().map_or(result.camera, |c| c.camera);
        let baselines = opencv_baselines(&self.data, &options, &opencv_camera);
        Ok(HandEyeFit { options, result, baselines, physics: None })
    }

    /// [`HandEyeInput::fit_from`] after deciding the target's bending and print scale and the
    /// lens model on the training images ([`select_chain_physics`]) when `physics` is given: the
    /// fit then runs with the variant the selection chose (from new first steps when the lens
    /// model changed), and carries the selection's report.
    pub fn fit_with_physics(
        &self,
        options: HandEyeOptions,
        start: Option<StartPoses>,
        physics: Option<&PhysicsOptions>,
    ) -> Result<HandEyeFit> {
        let Some(p) = physics else { return self.fit_from(options, start) };
        let report = select_chain_physics(&self.data, &options, p)
            .map_err(|e| self.context(e).context("the target's and lens's physics on the training images"))?;
        let chosen = report.chosen.options(&options);
        let start = if chosen.intrinsics == options.intrinsics { start } else { None };
        let mut fit = self.fit_from(chosen, start)?;
        fit.physics = Some(report);
        Ok(fit)
    }

    /// The robot model and the joint readings of every view (the joint adjustment's input);
    /// an error names the image without joint readings.
    pub fn joint_readings(&self) -> Result<(&RobotModel, Vec<Vec<f64>>)> {
        let Some(model) = &self.robot else {
            return Err(DatasetError::Input("handeye --out: the joint adjustment needs --robot".into()));
        };
        let rows: HashMap<&str, &super::PoseRow> = self.table.rows.iter().map(|r| (r.image.as_str(), r)).collect();
        let joints = self
            .data
            .views
            .iter()
            .map(|v| match rows.get(v.name.as_str()).map(|r| &r.robot) {
                Some(RobotReading::Joints(q)) => Ok(q.clone()),
                _ => Err(DatasetError::Input(format!(
                    "handeye --out: image {} has no joint readings in the poses table",
                    v.name
                ))),
            })
            .collect::<Result<Vec<_>>>()?;
        Ok((model, joints))
    }

    /// The joint adjustment of the robot's kinematic parameters with the camera and the
    /// hand-eye transforms, started from `fit`, with the target held at the print scale the
    /// hand-eye fit found; every image needs joint readings and the input a robot model.
    pub fn joint_adjustment(&self, fit: &HandEyeFit) -> Result<JointCalibration> {
        let (model, joints) = self.joint_readings()?;
        let joint_options = JointOptions { hand_eye: fit.options.clone(), ..JointOptions::default() };
        // The target as the hand-eye fit found it (bent, printed with its x and y scales),
        // held at that geometry.
        let mut scaled = self.data.clone();
        if let Some(form) = &fit.result.target_form {
            scaled.target_points_m = form.points(&self.data.target_points_m);
        }
        if let Some((scale, _)) = fit.result.target_scale {
            scaled.target_points_m = ferrocal_calib::handeye::evaluate::scaled_target(&scaled.target_points_m, scale);
        }
        calibrate_joint_from(model, &scaled, &joints, fit.result.clone(), &joint_options)
            .map_err(|e| DatasetError::from(e).context("handeye: the joint adjustment of robot and camera"))
    }
}

/// The Huber threshold of the hand-eye fit for a `--loss` string: `none` (plain least squares,
/// 0) or `huber:<sigmas>` (robust standard deviations of the first solve).
pub fn huber_sigmas_of_loss(loss: &str) -> Result<f64> {
    match crate::calibration::parse_loss(loss)? {
        Loss::Squared => Ok(0.0),
        Loss::Huber { delta } => Ok(delta),
        _ => Err(DatasetError::Input(format!("--loss {loss}: the hand-eye fit takes none or huber:<sigmas>"))),
    }
}

/// The most images one simulated recording renders (about 1 MB each).
pub const MAX_SIMULATED_IMAGES: usize = 2000;

/// Refuses a simulated recording of more than [`MAX_SIMULATED_IMAGES`] images, before anything
/// is allocated.
pub fn check_simulated_images(train: usize, test: usize) -> Result<()> {
    if train + test > MAX_SIMULATED_IMAGES {
        return Err(DatasetError::Input(format!(
            "handeye simulate: --train {train} and --test {test} ask for {} images; at most {MAX_SIMULATED_IMAGES} are rendered",
            train + test
        )));
    }
    Ok(())
}

/// Writes a simulated recording with rendered chessboard images into `dir`: `train` + `test`
/// images of the default cell of `mount`, or with `robot` (`ur5`, eye-to-hand only) the joint
/// study's UR5 with true kinematic errors; with `cameras` 2 (`robot` `ur5` or none: the rig is
/// always the UR5 cell) the rig study's two fixed cameras (eye-to-hand) or its stereo head on the
/// flange (eye-in-hand) ([`super::rig_record`]). Returns what was written, in words, naming the
/// folder as `shown` (where `dir` will be moved).
pub fn write_simulated_recording(
    mount: Mount,
    robot: Option<&str>,
    cameras: usize,
    (train, test, seed): (usize, usize, u64),
    dir: &Path,
    shown: &Path,
) -> Result<String> {
    if cameras != 1 {
        if cameras != 2 || robot.is_some_and(|r| r != "ur5") {
            return Err(DatasetError::Input(format!(
                "handeye simulate --cameras {cameras}: rig recordings are simulated for two cameras in the ur5 cell (--cameras 2 --robot ur5, --mount eye-to-hand or eye-in-hand)"
            )));
        }
        let config = super::rig_record::rendered_ur5_rig(mount, train, test);
        let r = super::rig_record::write_rig_recording(&config, dir, seed)?;
        let per_camera: Vec<String> =
            r.cameras.iter().map(|c| format!("{} {} + {} images", c.name, c.n_train_images, c.n_test_images)).collect();
        return Ok(format!(
            "{} + {} poses written to {} ({}; pattern {}); nominal {} held out: mean {:.4} mm after the frame refit",
            r.n_train,
            r.n_test,
            shown.display(),
            per_camera.join(", "),
            r.pattern,
            r.robot,
            r.nominal_heldout.mean_mm
        ));
    }
    if let Some(robot) = robot {
        if robot != "ur5" || mount != Mount::EyeToHand {
            return Err(DatasetError::Input(format!(
                "handeye simulate --robot: only the ur5 cell, eye-to-hand, is simulated (got {robot})"
            )));
        }
        let config = super::joint_record::rendered_ur5_cell(train, test);
        let r = super::joint_record::write_joint_recording(&config, dir, seed)?;
        return Ok(format!(
            "{} + {} images written to {} (pattern {}); nominal {} held out: mean {:.4} mm after the frame refit",
            r.n_train,
            r.n_test,
            shown.display(),
            r.pattern,
            r.robot,
            r.nominal_heldout.mean_mm
        ));
    }
    let mut config = super::HandEyeSimConfig::default_for(mount);
    config.n_train = train;
    config.n_test = test;
    let r = super::write_rendered_recording(&config, dir, seed)?;
    Ok(format!("{} images written to {} (pattern {})", r.n_images, shown.display(), r.pattern))
}
