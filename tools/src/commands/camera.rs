//! `ferrocal camera ...`: calibration of one camera and of a stereo pair from images of a
//! planar pattern (JSON per `shared/spec/cli.md`, optional OpenCV and ROS YAML files).
//!
//! A bad image (unreadable, empty, pattern not found, another image size) is reported on stderr
//! and in the JSON's `skipped` list, and the batch goes on; too few usable views is an error that
//! says how many were usable and why.

use ferrocal_report::say;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Result;
use clap::{Args, Subcommand};
use ferrocal_calib::verdict::commands as verdict;
use ferrocal_datasets::camera::{check_pairs, CameraViews, StereoViews};
use ferrocal_datasets::import::images::expand_image_specs;
use ferrocal_report::camera::{
    camera_outputs, camera_verdict, print_held_out, rectification, stereo_line, stereo_outputs, CameraFiles,
    StereoFiles,
};
use ferrocal_report::report::check_outputs;
use ferrocal_report::verdict::VerdictSettings;
use ferrocal_vision::calib::corners::{CornerMethod, SkippedImage, SubpixWindow};
use ferrocal_vision::calib::{
    compare::compare_with_opencv, CalibrationOptions, CalibrationPattern, CovarianceMethod, RobustLoss,
};
use ferrocal_vision::camera::DistortionKind;

/// `ferrocal camera ...`.
#[derive(Debug, Subcommand)]
pub enum CameraCommand {
    /// Calibrate one camera from images of a planar pattern.
    Calibrate(CalibrateArgs),
    /// Calibrate a stereo pair from simultaneous left and right images of a planar pattern.
    Stereo(StereoArgs),
}

/// Settings shared by both calibrations.
#[derive(Debug, Args)]
pub struct SolveArgs {
    /// The pattern: `chessboard:9x6:25mm` (inner corners, square size),
    /// `charuco:5x7:36.195mm:18.256mm:DICT_6X6_250` (squares), `circlegrid:10x10:25.4mm[:modified]`,
    /// `acircles:4x11:20mm` (OpenCV's asymmetric grid), `aprilboard:6x4:30mm:9mm`,
    /// `aprilgrid:6x6:88mm:0.3` (Kalibr's Aprilgrid).
    #[arg(long)]
    pub pattern: String,
    /// Keep fx = fy (OpenCV's CALIB_FIX_ASPECT_RATIO with ratio 1).
    #[arg(long)]
    pub fix_aspect: bool,
    /// Lens model: brown5 (OpenCV's 5 coefficients k1 k2 p1 p2 k3), rational8 (OpenCV's
    /// rational model, 8 coefficients) or kannala_brandt (OpenCV's fisheye, 4 coefficients).
    #[arg(long, default_value = "brown5", value_parser = DistortionKind::calibrated)]
    pub model: DistortionKind,
    /// Robust loss of the bundle adjustment: none, huber:<px> or cauchy:<px>.
    #[arg(long, default_value = "none")]
    pub loss: String,
    /// Remove outlier views and corners and solve again.
    #[arg(long)]
    pub reject_outliers: bool,
    /// Chessboard corners: `own` (the project's detector and edge-model refinement, the default)
    /// or `opencv` (findChessboardCorners + cornerSubPix, OpenCV's sample recipe: reproduces its
    /// published numbers). ChArUco boards and circle grids are always found by the project's
    /// detectors (`--compare-opencv` runs OpenCV's beside them).
    #[arg(long, default_value = "own", value_parser = CornerMethod::named)]
    pub corners: CornerMethod,
    /// cornerSubPix window with `--corners opencv`: `opencv` (11 x 11 half-size, OpenCV's sample
    /// recipe) or `adaptive` (shrunk where the squares are smaller than the window).
    #[arg(long, default_value = "opencv", value_parser = crate::cli::choice::<SubpixWindow>)]
    pub subpix_window: SubpixWindow,
    /// Covariance of the camera parameters (one camera): `auto` (the jackknife with 8 or more
    /// views, else independent), `independent` (every corner an independent measurement,
    /// s0^2 (J^T J)^-1, as OpenCV), `jackknife` (leave one view out; the corners of a view may
    /// be correlated) or `sandwich` (view-clustered sandwich).
    #[arg(long, default_value = "auto", value_parser = CovarianceMethod::parse)]
    pub covariance: CovarianceMethod,
}

impl SolveArgs {
    fn options(&self) -> Result<(CalibrationPattern, CalibrationOptions, CornerMethod)> {
        let pattern: CalibrationPattern = self.pattern.parse()?;
        let options = CalibrationOptions {
            model: self.model,
            fix_aspect: self.fix_aspect,
            loss: RobustLoss::parse(&self.loss)?,
            reject_outliers: self.reject_outliers,
            covariance: self.covariance,
            ..CalibrationOptions::default()
        };
        options.validate()?;
        Ok((pattern, options, self.corners.with_window(self.subpix_window)))
    }
}

/// `ferrocal camera calibrate`.
#[derive(Debug, Args)]
pub struct CalibrateArgs {
    /// Images: files, directories or glob patterns (quoted), any number.
    #[arg(long, required_unless_present = "observations", num_args = 1..)]
    pub images: Vec<PathBuf>,
    /// Detections made elsewhere instead of images: a CSV of `image, camera, point_id, u_px,
    /// v_px` (optionally `sigma_px`), the point ids those of `--pattern`'s points, or mrcal's
    /// corners file (`# filename x y level`, the chessboard's corners in order).
    #[arg(long, conflicts_with_all = ["images", "compare_opencv"])]
    pub observations: Option<PathBuf>,
    /// The size of the observed images, `<width>x<height>` pixels (read from the image files
    /// when they exist beside the observations file).
    #[arg(long, value_name = "WxH", requires = "observations")]
    pub image_size: Option<String>,
    /// Write the detections the calibration used as an observations CSV to this file.
    #[arg(long)]
    pub save_observations: Option<PathBuf>,
    /// Solver settings.
    #[command(flatten)]
    pub solve: SolveArgs,
    /// Write the report as JSON to this file.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Write the camera as OpenCV FileStorage YAML to this file.
    #[arg(long)]
    pub opencv_yaml: Option<PathBuf>,
    /// Write the camera as ROS camera_info YAML to this file.
    #[arg(long)]
    pub ros_yaml: Option<PathBuf>,
    /// Camera name in the ROS file.
    #[arg(long, default_value = "camera")]
    pub camera_name: String,
    /// Also run OpenCV's detector on the same images and print both calibrations side by side.
    #[arg(long)]
    pub compare_opencv: bool,
    /// Hold out every K-th image (the K-th, 2K-th, ... in sorted order) from the calibration and
    /// report the reprojection error on them (each held-out view's pose fitted, camera fixed).
    #[arg(long, value_name = "K")]
    pub test_every: Option<usize>,
    /// Write an HTML report: per-view errors, residual vectors and coverage over the image, the
    /// target poses, the projection uncertainty across the image.
    #[arg(long)]
    pub report: Option<PathBuf>,
}

/// `ferrocal camera stereo`.
#[derive(Debug, Args)]
pub struct StereoArgs {
    /// Left images (files, directories or quoted globs); paired with the right ones by sorted order.
    #[arg(long, required = true, num_args = 1..)]
    pub left: Vec<PathBuf>,
    /// Right images, as many as left ones.
    #[arg(long, required = true, num_args = 1..)]
    pub right: Vec<PathBuf>,
    /// Solver settings.
    #[command(flatten)]
    pub solve: SolveArgs,
    /// Write the report as JSON to this file.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Write the left camera as OpenCV FileStorage YAML.
    #[arg(long)]
    pub left_opencv_yaml: Option<PathBuf>,
    /// Write the right camera as OpenCV FileStorage YAML.
    #[arg(long)]
    pub right_opencv_yaml: Option<PathBuf>,
    /// Write the left camera as ROS camera_info YAML, with the stereo rectification
    /// (rectification_matrix = R1, projection_matrix = P1), as ROS' stereo calibrator does.
    #[arg(long, alias = "ros-left")]
    pub left_ros_yaml: Option<PathBuf>,
    /// Write the right camera as ROS camera_info YAML, with the stereo rectification
    /// (rectification_matrix = R2, projection_matrix = P2 with P2[0][3] = -fx' * baseline in
    /// metres).
    #[arg(long, alias = "ros-right")]
    pub right_ros_yaml: Option<PathBuf>,
    /// Write the pair as one OpenCV FileStorage YAML file with the names of OpenCV's
    /// stereo_calib sample: M1 D1 M2 D2 R T E F R1 R2 P1 P2 Q (T in metres).
    #[arg(long)]
    pub opencv_stereo_yaml: Option<PathBuf>,
    /// Write an HTML report: per camera the per-view errors, residual vectors, coverage and
    /// projection uncertainty; the rig and the board poses in 3-D; the rectification check.
    #[arg(long)]
    pub report: Option<PathBuf>,
}

/// Runs a camera command.
pub fn run(cmd: CameraCommand, vs: &VerdictSettings) -> Result<ExitCode> {
    match cmd {
        CameraCommand::Calibrate(a) => calibrate(&a, vs),
        CameraCommand::Stereo(a) => stereo(&a, vs),
    }
}

/// The file name of a view's name (its image path).
fn file_name(name: &str) -> String {
    Path::new(name).file_name().map_or_else(|| name.to_string(), |f| f.to_string_lossy().into_owned())
}

fn report_skipped(skipped: &[SkippedImage]) {
    for s in skipped {
        eprintln!("ferrocal: skipped {s}");
    }
}

/// The views of an observations file; the image size from `size` (`WxH`) or from the first
/// image file found beside the observations file.
fn observed_views(file: &Path, size: Option<&str>, pattern: &CalibrationPattern) -> Result<CameraViews> {
    let obs = ferrocal_datasets::import::observations::read_observations(file)?;
    if obs.images.iter().any(|i| i.sigma_px.iter().any(Option::is_some)) {
        eprintln!(
            "ferrocal: {}: camera calibrate weighs every point alike; its sigma_px column is not used",
            file.display()
        );
    }
    let image_size = match size {
        Some(s) => ferrocal_datasets::import::observations::parse_image_size(s)?,
        None => match ferrocal_datasets::import::observations::image_size_beside(&obs, file) {
            Some(size) => size,
            None => anyhow::bail!(
                "{}: none of its images is readable beside it to tell their size; give --image-size <width>x<height>",
                file.display()
            ),
        },
    };
    Ok(CameraViews::from_observations(&obs, file, pattern, image_size)?)
}

fn calibrate(a: &CalibrateArgs, vs: &VerdictSettings) -> Result<ExitCode> {
    let (pattern, options, corners) = a.solve.options()?;
    let mut skipped = Vec::new();
    let paths = expand_image_specs(&a.images, &mut skipped);
    let files = CameraFiles {
        json: a.json.as_deref(),
        opencv_yaml: a.opencv_yaml.as_deref(),
        ros_yaml: a.ros_yaml.as_deref(),
        report: a.report.as_deref(),
        camera_name: &a.camera_name,
    };
    let mut inputs: Vec<&Path> = paths.iter().map(PathBuf::as_path).collect();
    inputs.extend(a.observations.as_deref());
    let mut outputs = files.all();
    outputs.extend(a.save_observations.as_deref());
    check_outputs(&outputs, &inputs)?;
    let found = match &a.observations {
        Some(file) => observed_views(file, a.image_size.as_deref(), &pattern)?,
        None => CameraViews::detect(paths, skipped, &pattern, corners),
    };
    report_skipped(&found.skipped);
    if let Some(out) = &a.save_observations {
        let csv = ferrocal_datasets::import::observations::observations_to_csv(&found.observations("camera"));
        ferrocal_report::report::write_atomic(out, csv.as_bytes())?;
    }
    let run = found.calibrate(&pattern, &options, a.test_every)?;
    ferrocal_report::camera::print_camera("camera", &run.fit.calibration);
    if let Some(b) = &run.fit.circle_bias {
        say!("{b}");
    }
    let held_out = a.test_every.map(|_| run.held_out()).transpose()?;
    held_out.iter().for_each(|h| print_held_out(h, run.test_views.len()));
    if a.compare_opencv {
        say!("{}", compare_with_opencv(&run.paths, &pattern, &options)?);
    }
    let verdict = camera_verdict(&vs.thresholds, &run, held_out.as_ref());
    camera_outputs(&run, held_out.as_ref(), a.test_every, &verdict, &files)?.write()?;
    Ok(vs.conclude(&verdict))
}

fn stereo(a: &StereoArgs, vs: &VerdictSettings) -> Result<ExitCode> {
    let (pattern, options, corners) = a.solve.options()?;
    let mut skipped = Vec::new();
    let left_paths = expand_image_specs(&a.left, &mut skipped);
    let right_paths = expand_image_specs(&a.right, &mut skipped);
    if left_paths.len() != right_paths.len() {
        report_skipped(&skipped);
    }
    check_pairs(left_paths.len(), right_paths.len())?;
    let files = StereoFiles {
        json: a.json.as_deref(),
        left_opencv_yaml: a.left_opencv_yaml.as_deref(),
        right_opencv_yaml: a.right_opencv_yaml.as_deref(),
        left_ros_yaml: a.left_ros_yaml.as_deref(),
        right_ros_yaml: a.right_ros_yaml.as_deref(),
        opencv_stereo_yaml: a.opencv_stereo_yaml.as_deref(),
        report: a.report.as_deref(),
    };
    let inputs: Vec<&Path> = left_paths.iter().chain(&right_paths).map(PathBuf::as_path).collect();
    check_outputs(&files.all(), &inputs)?;
    let found = StereoViews::detect(left_paths, right_paths, skipped, &pattern, corners);
    report_skipped(&found.skipped);
    let run = found.calibrate(&pattern, &options, &vs.thresholds.stereo)?;
    let st = &run.calibration;
    ferrocal_report::camera::print_camera("left", st.left());
    ferrocal_report::camera::print_camera("right", st.right());
    say!("{}", stereo_line(st, run.n_pairs));
    let rectified = rectification(&run, files.need_rectification())?;
    let row_rms = rectified.as_ref().map(|r| r.row_rms_px);
    let pairing = verdict::StereoPairing {
        right_in_left_mm: st.t_right_left.inverse().translation.vector * 1e3,
        n_pairs: run.pairing.n_pairs,
        disagreeing: run.pairing.disagreeing.iter().map(|n| file_name(n)).collect(),
    };
    let verdict = verdict::stereo(&vs.thresholds, st.calibration.rms_px, run.n_pairs, row_rms, &pairing);
    stereo_outputs(&run, rectified.as_ref(), &verdict, &files)?.write()?;
    Ok(vs.conclude(&verdict))
}
