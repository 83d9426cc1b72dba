//! `ferrocal camera ...`: calibration of one camera and of a stereo pair from images of a
//! planar pattern (JSON per `shared/spec/cli.md`, optional OpenCV and ROS YAML files).
//!
//! A bad image (unreadable, empty, pattern not found, another image size) is reported on stderr
//! and in the JSON's `skipped` list, and the batch goes on; too few usable views is an error that
//! says how many were usable and why.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Result};
use clap::{Args, Subcommand, ValueEnum};
use ferrocal_datasets::import::images::expand_image_specs;
use ferrocal_report::camera::{camera_json, skipped_json, stereo_json};
use ferrocal_report::camera_report::{camera_report, stereo_report, CameraReportInput, StereoReportInput};
use ferrocal_report::report::{check_outputs, write_all_atomic, Provenance};
use ferrocal_report::verdict::{add_verdict, VerdictSettings};
use ferrocal_vision::calib::corners::{
    detect_pattern_views, detect_view_slots, CornerMethod, SkippedImage, SubpixWindow,
};
use ferrocal_vision::calib::heldout::held_out_reprojection;
use ferrocal_vision::calib::{
    calibrate_pattern, calibrate_stereo, compare::compare_with_opencv, rectified_row_rms_px, CalibrationOptions,
    CalibrationPattern, CovarianceMethod, PlanarTarget, RobustLoss, MIN_VIEWS,
};
use ferrocal_vision::camera::{io, DistortionKind};
use serde_json::{json, Value};

/// `ferrocal camera ...`.
#[derive(Debug, Subcommand)]
pub enum CameraCommand {
    /// Calibrate one camera from images of a planar pattern.
    Calibrate(CalibrateArgs),
    /// Calibrate a stereo pair from simultaneous left and right images of a planar pattern.
    Stereo(StereoArgs),
}

/// The lens model.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ModelArg {
    /// OpenCV's 5 coefficients k1 k2 p1 p2 k3.
    #[value(name = "brown5")]
    Brown5,
    /// OpenCV's rational model, 8 coefficients.
    #[value(name = "rational8")]
    Rational8,
    /// Kannala-Brandt (OpenCV fisheye), 4 coefficients.
    #[value(name = "kannala_brandt", alias = "kannala-brandt")]
    KannalaBrandt,
}

impl ModelArg {
    fn kind(self) -> DistortionKind {
        match self {
            ModelArg::Brown5 => DistortionKind::Brown5,
            ModelArg::Rational8 => DistortionKind::Rational8,
            ModelArg::KannalaBrandt => DistortionKind::KannalaBrandt,
        }
    }
}

/// Settings shared by both calibrations.
#[derive(Debug, Args)]
pub struct SolveArgs {
    /// The pattern: `chessboard:9x6:25mm` (inner corners, square size),
    /// `charuco:5x7:36.195mm:18.256mm:DICT_6X6_250` (squares), `circlegrid:10x10:25.4mm[:modified]`.
    #[arg(long)]
    pub pattern: String,
    /// Keep fx = fy (OpenCV's CALIB_FIX_ASPECT_RATIO with ratio 1).
    #[arg(long)]
    pub fix_aspect: bool,
    /// Lens model.
    #[arg(long, value_enum, default_value = "brown5")]
    pub model: ModelArg,
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
    #[arg(long, value_enum, default_value = "own")]
    pub corners: CornersArg,
    /// cornerSubPix window with `--corners opencv`: `opencv` (11 x 11 half-size, OpenCV's sample
    /// recipe) or `adaptive` (shrunk where the squares are smaller than the window).
    #[arg(long, value_enum, default_value = "opencv")]
    pub subpix_window: WindowArg,
    /// Covariance of the camera parameters (one camera): `auto` (the jackknife with 8 or more
    /// views, else independent), `independent` (every corner an independent measurement,
    /// s0^2 (J^T J)^-1, as OpenCV), `jackknife` (leave one view out; the corners of a view may
    /// be correlated) or `sandwich` (view-clustered sandwich).
    #[arg(long, value_enum, default_value = "auto")]
    pub covariance: CovarianceArg,
}

/// How the covariance of the camera parameters is computed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum CovarianceArg {
    /// Corners independent.
    #[value(name = "independent")]
    Independent,
    /// Leave-one-view-out jackknife.
    #[value(name = "jackknife")]
    Jackknife,
    /// View-clustered sandwich.
    #[value(name = "sandwich")]
    Sandwich,
    /// The jackknife with enough views, else independent.
    #[value(name = "auto")]
    Auto,
}

impl CovarianceArg {
    fn method(self) -> CovarianceMethod {
        match self {
            CovarianceArg::Independent => CovarianceMethod::Independent,
            CovarianceArg::Jackknife => CovarianceMethod::ViewJackknife,
            CovarianceArg::Sandwich => CovarianceMethod::ViewSandwich,
            CovarianceArg::Auto => CovarianceMethod::Auto,
        }
    }
}

/// Where the chessboard corners come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum CornersArg {
    /// The project's detector and edge-model refinement.
    #[value(name = "own")]
    Own,
    /// OpenCV's findChessboardCorners + cornerSubPix.
    #[value(name = "opencv")]
    OpenCv,
}

/// The cornerSubPix window.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum WindowArg {
    /// OpenCV's sample recipe.
    #[value(name = "opencv")]
    OpenCv,
    /// Shrunk to the squares.
    #[value(name = "adaptive")]
    Adaptive,
}

impl WindowArg {
    fn window(self) -> SubpixWindow {
        match self {
            WindowArg::OpenCv => SubpixWindow::OpenCv,
            WindowArg::Adaptive => SubpixWindow::Adaptive,
        }
    }
}

impl SolveArgs {
    fn corner_method(&self) -> CornerMethod {
        match self.corners {
            CornersArg::Own => CornerMethod::Own,
            CornersArg::OpenCv => CornerMethod::OpenCv(self.subpix_window.window()),
        }
    }

    fn options(&self) -> Result<(CalibrationPattern, PlanarTarget, CalibrationOptions)> {
        let pattern: CalibrationPattern = self.pattern.parse()?;
        let target = pattern.target();
        let options = CalibrationOptions {
            model: self.model.kind(),
            fix_aspect: self.fix_aspect,
            loss: RobustLoss::parse(&self.loss)?,
            reject_outliers: self.reject_outliers,
            covariance: self.covariance.method(),
            ..CalibrationOptions::default()
        };
        options.validate()?;
        Ok((pattern, target, options))
    }
}

/// `ferrocal camera calibrate`.
#[derive(Debug, Args)]
pub struct CalibrateArgs {
    /// Images: files, directories or glob patterns (quoted), any number.
    #[arg(long, required = true, num_args = 1..)]
    pub images: Vec<PathBuf>,
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

fn report_skipped(skipped: &[SkippedImage]) {
    for s in skipped {
        eprintln!("ferrocal: skipped {s}");
    }
}

fn too_few(what: &str, usable: usize, total: usize, skipped: &[SkippedImage]) -> anyhow::Error {
    let reasons: Vec<String> = skipped.iter().map(ToString::to_string).collect();
    anyhow::anyhow!(
        "{what}: {usable} usable view(s) of {total} image(s), at least {MIN_VIEWS} needed{}",
        if reasons.is_empty() { String::new() } else { format!("; skipped: {}", reasons.join("; ")) }
    )
}

/// The outputs of one command, composed first and written together (`write_all_atomic`): a
/// failure on the way writes none of them.
#[derive(Default)]
struct Outputs(Vec<(PathBuf, Vec<u8>)>);

impl Outputs {
    fn json(&mut self, path: &Path, v: &Value) -> Result<()> {
        self.0.push((path.to_path_buf(), serde_json::to_string_pretty(v)?.into_bytes()));
        Ok(())
    }

    fn text(&mut self, path: &Path, text: &str) {
        self.0.push((path.to_path_buf(), text.as_bytes().to_vec()));
    }

    fn write(&self) -> Result<()> {
        write_all_atomic(&self.0.iter().map(|(p, b)| (p.as_path(), b.as_slice())).collect::<Vec<_>>())?;
        Ok(())
    }
}

fn calibrate(a: &CalibrateArgs, vs: &VerdictSettings) -> Result<ExitCode> {
    let (pattern, _, options) = a.solve.options()?;
    let mut skipped = Vec::new();
    let paths = expand_image_specs(&a.images, &mut skipped);
    let outputs: Vec<&Path> =
        [&a.json, &a.opencv_yaml, &a.ros_yaml, &a.report].into_iter().flatten().map(PathBuf::as_path).collect();
    check_outputs(&outputs, &paths.iter().map(PathBuf::as_path).collect::<Vec<_>>())?;
    let mut out = Outputs::default();
    let found = detect_pattern_views(&paths, &pattern, a.solve.corner_method());
    skipped.extend(found.skipped);
    report_skipped(&skipped);
    let k = match a.test_every {
        Some(0) => bail!("camera calibrate: --test-every must be at least 1"),
        Some(k) => k,
        None => usize::MAX,
    };
    let (mut views, mut test_views) = (Vec::new(), Vec::new());
    for (i, slot) in found.slots.into_iter().enumerate() {
        match slot {
            Some(v) if (i + 1) % k == 0 => test_views.push(v),
            Some(v) => views.push(v),
            None => {}
        }
    }
    if views.len() < MIN_VIEWS {
        return Err(too_few("camera calibrate", views.len(), paths.len(), &skipped));
    }
    let pc = calibrate_pattern(&views, &pattern, found.circle_radii_m, &options).map_err(|e| {
        anyhow::anyhow!("camera calibrate: {e} ({} usable views of {} images)", views.len(), paths.len())
    })?;
    let cal = &pc.calibration;
    ferrocal_report::camera::print_camera("camera", cal);
    if let Some(b) = &pc.circle_bias {
        println!("{b}");
    }
    let held_out = match a.test_every {
        Some(_) => {
            let h = held_out_reprojection(&cal.camera, &pattern.target(), &test_views)?;
            match h.rms_px {
                Some(r) => println!("held out: RMS {r:.4} px over {} views", test_views.len()),
                None => println!("held out: no view usable ({} held out)", test_views.len()),
            }
            for v in h.views.iter().filter(|v| v.error.is_some()) {
                eprintln!("ferrocal: held-out view {}: {}", v.name, v.error.as_deref().unwrap_or(""));
            }
            Some(h)
        }
        None => None,
    };
    if a.compare_opencv {
        println!("{}", compare_with_opencv(&paths, &pattern, &options)?);
    }
    let n_used = cal.views.iter().filter(|v| v.used).count();
    let verdict = ferrocal_calib::verdict::commands::camera(
        &vs.thresholds.camera,
        cal.rms_px,
        n_used,
        held_out.as_ref().and_then(|h| h.rms_px),
    );
    if let Some(p) = &a.json {
        let mut v = camera_json(cal);
        add_verdict(&mut v, &verdict);
        v["circle_bias"] = json!(pc.circle_bias);
        v["pattern"] = json!(pattern.to_string());
        v["fix_aspect"] = json!(a.solve.fix_aspect);
        v["corners"] = json!(a.solve.corner_method());
        v["held_out"] = json!(held_out);
        v["skipped"] = skipped_json(&skipped);
        out.json(p, &v)?;
    }
    if let Some(p) = &a.opencv_yaml {
        out.text(p, &io::to_opencv_yaml(&cal.camera)?);
    }
    if let Some(p) = &a.ros_yaml {
        out.text(p, &io::to_ros_yaml(&cal.camera, &a.camera_name)?);
    }
    if let Some(p) = &a.report {
        let mut prov = Provenance::new(json!({"pattern": pattern.to_string(), "corners": a.solve.corner_method(),
            "fix_aspect": a.solve.fix_aspect, "model": format!("{:?}", a.solve.model), "test_every": a.test_every}));
        paths.iter().for_each(|i| prov.add_input(i));
        let input = CameraReportInput {
            pattern: &pattern.to_string(),
            views: &views,
            target: &pattern.target(),
            held_out: held_out.as_ref(),
            provenance: prov,
        };
        let mut rep = camera_report(cal, input);
        rep.verdict = Some(verdict.clone());
        out.text(p, &rep.to_html());
    }
    out.write()?;
    Ok(vs.conclude(&verdict))
}

fn stereo(a: &StereoArgs, vs: &VerdictSettings) -> Result<ExitCode> {
    let (pattern, target, options) = a.solve.options()?;
    let mut skipped = Vec::new();
    let left_paths = expand_image_specs(&a.left, &mut skipped);
    let right_paths = expand_image_specs(&a.right, &mut skipped);
    if left_paths.len() != right_paths.len() {
        report_skipped(&skipped);
        bail!(
            "camera stereo: {} left and {} right images; the pairs are formed by sorted order, so give as many of each",
            left_paths.len(),
            right_paths.len()
        );
    }
    let inputs: Vec<&PathBuf> = left_paths.iter().chain(&right_paths).collect();
    let outputs: Vec<&PathBuf> = [
        &a.json,
        &a.left_opencv_yaml,
        &a.right_opencv_yaml,
        &a.left_ros_yaml,
        &a.right_ros_yaml,
        &a.opencv_stereo_yaml,
        &a.report,
    ]
    .into_iter()
    .flatten()
    .collect();
    check_outputs(
        &outputs.iter().map(|p| p.as_path()).collect::<Vec<_>>(),
        &inputs.iter().map(|p| p.as_path()).collect::<Vec<_>>(),
    )?;
    let mut out = Outputs::default();
    let method = a.solve.corner_method();
    let (left, ls) = detect_view_slots(&left_paths, &pattern, method);
    let (right, rs) = detect_view_slots(&right_paths, &pattern, method);
    skipped.extend(ls);
    skipped.extend(rs);
    report_skipped(&skipped);
    let n_left = left.iter().flatten().count();
    let n_right = right.iter().flatten().count();
    if n_left < MIN_VIEWS || n_right < MIN_VIEWS {
        let (side, n, total) =
            if n_left < MIN_VIEWS { ("left", n_left, left_paths.len()) } else { ("right", n_right, right_paths.len()) };
        return Err(too_few(&format!("camera stereo ({side} camera)"), n, total, &skipped));
    }
    let n_pairs = left.iter().zip(&right).filter(|(l, r)| l.is_some() && r.is_some()).count();
    if n_pairs == 0 {
        bail!("camera stereo: the pattern was never found in both images of a pair");
    }
    let st = calibrate_stereo(&left, &right, &target, &options).map_err(|e| anyhow::anyhow!("camera stereo: {e}"))?;
    ferrocal_report::camera::print_camera("left", st.left());
    ferrocal_report::camera::print_camera("right", st.right());
    println!(
        "T_right_left: rotation {:.4?} deg (std {:.4?}), translation {:.3?} mm (std {:.3?}), baseline {:.3} +- {:.3} mm; RMS {:.4} px ({n_pairs} pairs)",
        st.rotation_deg.as_slice(),
        st.rotation_std_deg.as_slice(),
        st.translation_mm.as_slice(),
        st.translation_std_mm.as_slice(),
        st.baseline_mm,
        st.baseline_std_mm,
        st.calibration.rms_px
    );
    // The rectification; a pair that cannot be rectified (a wide fisheye whose image corners
    // lie beyond 90 degrees) is an error only for the outputs that need it.
    let needs_rectification =
        a.left_ros_yaml.is_some() || a.right_ros_yaml.is_some() || a.opencv_stereo_yaml.is_some() || a.report.is_some();
    let pair = match st.pair() {
        Ok(p) => Some(p),
        Err(e) if !needs_rectification => {
            eprintln!("ferrocal: warning: the pair cannot be rectified: {e}");
            None
        }
        Err(e) => bail!(
            "camera stereo: the pair cannot be rectified ({e}); the ROS and OpenCV stereo files and the report need it"
        ),
    };
    let (corners, row_rms_px) = match &pair {
        Some(pair) => {
            let rect = pair.rectification;
            let corners = st.rectified_corners(&rect, &left, &right, &target);
            let rms = rectified_row_rms_px(&corners, rect.vertical());
            println!(
                "rectified: f' {:.3} px, baseline {:.3} mm, row difference RMS {rms:.4} px over {} corner pairs",
                rect.focal_px(),
                rect.baseline() * 1e3,
                corners.len()
            );
            (corners, rms)
        }
        None => (Vec::new(), f64::NAN),
    };
    let verdict = ferrocal_calib::verdict::commands::stereo(
        &vs.thresholds,
        st.calibration.rms_px,
        n_pairs,
        pair.as_ref().map(|_| row_rms_px),
    );
    if let Some(p) = &a.json {
        let mut v = stereo_json(&st, n_pairs, &pattern.pattern(), a.solve.fix_aspect, &skipped);
        add_verdict(&mut v, &verdict);
        v["rectification"] = pair
            .as_ref()
            .map_or(Value::Null, |pair| ferrocal_report::camera::rectification_json(pair, row_rms_px, corners.len()));
        out.json(p, &v)?;
    }
    for (cal, path) in [(st.left(), &a.left_opencv_yaml), (st.right(), &a.right_opencv_yaml)] {
        if let Some(p) = path {
            out.text(p, &io::to_opencv_yaml(&cal.camera)?);
        }
    }
    let Some(pair) = &pair else {
        out.write()?;
        return Ok(vs.conclude(&verdict));
    };
    if a.left_ros_yaml.is_some() || a.right_ros_yaml.is_some() {
        let (l, r) = io::to_ros_stereo_yaml(pair, "left", "right")?;
        for (text, path) in [(l, &a.left_ros_yaml), (r, &a.right_ros_yaml)] {
            if let Some(p) = path {
                out.text(p, &text);
            }
        }
    }
    if let Some(p) = &a.opencv_stereo_yaml {
        out.text(p, &io::to_opencv_stereo_yaml(pair)?);
    }
    if let Some(p) = &a.report {
        let mut prov = Provenance::new(json!({"pattern": pattern.to_string(), "corners": a.solve.corner_method(),
            "fix_aspect": a.solve.fix_aspect, "model": format!("{:?}", a.solve.model)}));
        inputs.iter().for_each(|i| prov.add_input(i));
        let input = StereoReportInput {
            pattern: &pattern.to_string(),
            left: &left,
            right: &right,
            target: &target,
            pair,
            corners: &corners,
            provenance: prov,
        };
        let mut rep = stereo_report(&st, input);
        rep.verdict = Some(verdict.clone());
        out.text(p, &rep.to_html());
    }
    out.write()?;
    Ok(vs.conclude(&verdict))
}
