//! The calibration study: `camera calibrate`'s default (the project's own chessboard corners,
//! [`ferrocal_vision::calib::calibrate_pattern`]) against OpenCV's `calibrateCamera` on
//! OpenCV's own corners (`findChessboardCorners` + `cornerSubPix` 11 x 11), on independent
//! renders with known truth ([`super::supersampled`], not the renderer the detector was tuned
//! on).
//!
//! For a seed: a truth camera ([`truth_camera`]: fx 0.8-1.1 image widths, fy within 1.5 % of
//! it, principal point off-centre by up to 40 x 30 px at 1280 x 960, Brown-5 with
//! `k1` in -0.2..0.1, `|k2| <= 0.05`, `|p1|, |p2| <= 1e-3`, `k3 = 0`); a 9 x 6 chessboard of
//! 30 mm squares with a 20 mm margin; `views` poses ([`board_poses`]: tilts 15-45 degrees about
//! a random in-plane axis, roll within 30 degrees, the printed sheet's bounding box covering
//! 30-70 % of the image area, a third of the views pushed into an image corner, the whole sheet
//! in view); every view rendered to a PNG file. Both sides then calibrate the 5-coefficient
//! Brown model with `fx` and `fy` free, i.e. the family that generated the data. The result
//! per seed ([`SeedResult`]): the errors of `fx fy cx cy`, their RMS per side, the ratio
//! OpenCV / ours, and whether each truth value lies within 3 reported sigmas; [`summarize`]
//! aggregates over seeds.

use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Point2, Translation3, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use super::supersampled::{PrintedChessboard, SupersampledConfig, SupersampledRenderer};
use crate::error::{DatasetError, Result};
use ferrocal_vision::calib::corners::{
    chessboard_corners_opencv_with, detect_pattern_views, CornerMethod, SubpixWindow,
};
use ferrocal_vision::calib::{calibrate_pattern, CalibrationOptions, CalibrationPattern, CovarianceMethod, View};
use ferrocal_vision::camera::{CameraModel, Distortion, ImageSize, Intrinsics};

/// The study's settings.
#[derive(Clone, Debug, PartialEq)]
pub struct StudySettings {
    /// Views per seed.
    pub views: usize,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// The renderer (sub-samples, blur, noise, JPEG).
    pub render: SupersampledConfig,
    /// The printed chessboard.
    pub board: PrintedChessboard,
    /// Keep a view's PNG file when it already exists instead of rendering it again (for
    /// re-runs of the calibrations on the same renders; see [`render_seed`]).
    pub reuse_renders: bool,
}

impl Default for StudySettings {
    /// 18 views of 1280 x 960, `S = 8`, the renderer's defaults (PSF 0.8 px, shot and read
    /// noise, PNG), a 9 x 6 board of 30 mm squares with a 20 mm margin.
    fn default() -> Self {
        Self {
            views: 18,
            width: 1280,
            height: 960,
            render: SupersampledConfig::default(),
            board: PrintedChessboard { inner_cols: 9, inner_rows: 6, square_m: 0.03, margin_m: 0.02 },
            reuse_renders: false,
        }
    }
}

/// One side's calibration.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SideResult {
    /// Views whose corners were found.
    pub views: usize,
    /// RMS distance of the found corners to the true corners, pixels.
    pub corner_rms_px: f64,
    /// Calibration RMS reprojection error, pixels.
    pub reprojection_rms_px: f64,
    /// Estimated `fx fy cx cy`, pixels.
    pub intrinsics_px: [f64; 4],
    /// Their reported standard deviations, pixels (ours: `camera calibrate`'s default
    /// covariance, [`CalibrationOptions::covariance`]).
    pub std_px: [f64; 4],
    /// Ours only (NaN for OpenCV): the standard deviations with corners taken as independent,
    /// `s0^2 (J^T J)^-1` ([`CovarianceMethod::Independent`]), pixels.
    pub std_independent_px: [f64; 4],
    /// Ours only: the leave-one-view-out jackknife ([`CovarianceMethod::ViewJackknife`]), pixels.
    pub std_jackknife_px: [f64; 4],
    /// Ours only: the view-clustered sandwich ([`CovarianceMethod::ViewSandwich`]), pixels.
    pub std_sandwich_px: [f64; 4],
    /// `|estimate - truth|` of `fx fy cx cy`, pixels.
    pub abs_error_px: [f64; 4],
    /// RMS over the four errors, pixels.
    pub rms_error_px: f64,
    /// Whether each truth value lies within 3 reported sigmas.
    pub within_3_sigma: [bool; 4],
}

/// One seed of the study.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SeedResult {
    /// The seed.
    pub seed: u64,
    /// The truth camera.
    pub truth: CameraModel,
    /// The project's default (own corners, [`calibrate_pattern`]).
    pub ours: SideResult,
    /// OpenCV (`findChessboardCorners` + `cornerSubPix` 11 x 11, `calibrateCamera`).
    pub opencv: SideResult,
    /// `opencv.rms_error_px / ours.rms_error_px`.
    pub ratio: f64,
}

/// The aggregate over seeds.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Summary {
    /// Seeds.
    pub seeds: usize,
    /// Median of the ratios OpenCV / ours.
    pub median_ratio: f64,
    /// Smallest ratio.
    pub min_ratio: f64,
    /// Fraction of the seeds with a ratio of at least 1.5.
    pub fraction_ratio_at_least_1_5: f64,
    /// Fraction of the 4 x seeds truth values within 3 sigma of ours.
    pub ours_coverage_3_sigma: f64,
    /// The same for OpenCV (for comparison).
    pub opencv_coverage_3_sigma: f64,
    /// RMS over seeds of ours' RMS intrinsic error, pixels.
    pub ours_rms_error_px: f64,
    /// RMS over seeds of OpenCV's RMS intrinsic error, pixels.
    pub opencv_rms_error_px: f64,
    /// Ours' errors against the independent-corner standard deviations.
    pub ours_independent: Coverage,
    /// Ours' errors against the leave-one-view-out jackknife's.
    pub ours_jackknife: Coverage,
    /// Ours' errors against the view-clustered sandwich's.
    pub ours_sandwich: Coverage,
    /// OpenCV's errors against its `stdDeviationsIntrinsics`.
    pub opencv: Coverage,
}

/// How well reported standard deviations describe the errors, over the four intrinsics of
/// every seed.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Coverage {
    /// Values compared (4 per seed).
    pub n: usize,
    /// Truth within 3 sigma.
    pub within_3_sigma: usize,
    /// Truth beyond 2 sigma (about 4.6 % expected).
    pub beyond_2_sigma: usize,
    /// RMS of `error / sigma` (1 when the sigmas are right).
    pub z_rms: f64,
    /// Geometric mean of the sigmas relative to the independent-corner ones (ours; 1 for
    /// OpenCV).
    pub sigma_ratio: f64,
}

/// The coverage of `std` (per seed) against the errors `err` (per seed), and their sizes
/// against `reference`.
pub fn coverage(err: &[[f64; 4]], std: &[[f64; 4]], reference: &[[f64; 4]]) -> Coverage {
    let (mut n, mut w3, mut b2, mut z2, mut lr) = (0, 0, 0, 0.0, 0.0);
    for ((e, s), r) in err.iter().zip(std).zip(reference) {
        for i in 0..4 {
            let z = e[i].abs() / s[i];
            n += 1;
            w3 += usize::from(z <= 3.0);
            b2 += usize::from(z > 2.0);
            z2 += z * z;
            lr += (s[i] / r[i]).ln();
        }
    }
    let nf = n.max(1) as f64;
    Coverage { n, within_3_sigma: w3, beyond_2_sigma: b2, z_rms: (z2 / nf).sqrt(), sigma_ratio: (lr / nf).exp() }
}

/// The truth camera of a seed for a `width x height` image (see the module documentation).
pub fn truth_camera(seed: u64, width: u32, height: u32) -> Result<CameraModel> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed.wrapping_mul(0x9E37_79B9).wrapping_add(17));
    let (w, h) = (f64::from(width), f64::from(height));
    let scale = w / 1280.0;
    let fx = w * rng.random_range(0.8..1.1);
    let fy = fx * (1.0 + rng.random_range(-0.015..0.015));
    let cx = 0.5 * (w - 1.0) + scale * rng.random_range(-40.0..40.0);
    let cy = 0.5 * (h - 1.0) + scale * rng.random_range(-30.0..30.0);
    let distortion = Distortion::Brown5 {
        k1: rng.random_range(-0.2..0.1),
        k2: rng.random_range(-0.05..0.05),
        p1: rng.random_range(-1e-3..1e-3),
        p2: rng.random_range(-1e-3..1e-3),
        k3: 0.0,
    };
    Ok(CameraModel::new(
        Intrinsics { fx_px: fx, fy_px: fy, cx_px: cx, cy_px: cy },
        distortion,
        ImageSize { width_px: width, height_px: height },
    )?)
}

/// Points along the printed sheet's outline, board frame.
fn sheet_outline(board: &PrintedChessboard) -> Vec<nalgebra::Point3<f64>> {
    let c = board.sheet_corners();
    let mut pts = Vec::new();
    for k in 0..4 {
        let (a, b) = (c[k], c[(k + 1) % 4]);
        for s in 0..16 {
            pts.push(a + (b - a) * (s as f64 / 16.0));
        }
    }
    pts
}

/// Bounding box `(left, top, right, bottom)` of the sheet's image, or `None` when a point does
/// not project.
fn sheet_bbox(r: &SupersampledRenderer, outline: &[nalgebra::Point3<f64>], pose: &Isometry3<f64>) -> Option<[f64; 4]> {
    let mut bb = [f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY];
    for p in outline {
        let q: Point2<f64> = r.project(pose, p)?;
        bb = [bb[0].min(q.x), bb[1].min(q.y), bb[2].max(q.x), bb[3].max(q.y)];
    }
    Some(bb)
}

/// One random pose satisfying the study's constraints, or `None` when the draw cannot be
/// placed (the caller draws again).
fn try_pose(
    rng: &mut ChaCha8Rng,
    r: &SupersampledRenderer,
    outline: &[nalgebra::Point3<f64>],
) -> Option<Isometry3<f64>> {
    const SAFETY_PX: f64 = 6.0;
    let cam = r.camera();
    let (w, h) = (f64::from(cam.image_size.width_px), f64::from(cam.image_size.height_px));
    let k = cam.intrinsics;
    let tilt = rng.random_range(15f64..45.0).to_radians();
    let phi = rng.random_range(0.0..std::f64::consts::TAU);
    let roll = rng.random_range(-30f64..30.0).to_radians();
    let axis = nalgebra::Unit::new_normalize(Vector3::new(phi.cos(), phi.sin(), 0.0));
    let rot = UnitQuaternion::from_axis_angle(&axis, tilt) * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), roll);
    let fill = rng.random_range(0.3..0.7);
    let (fx, fy) = if rng.random_bool(1.0 / 3.0) {
        (f64::from(rng.random_range(0..2u8)), f64::from(rng.random_range(0..2u8)))
    } else {
        (rng.random_range(0.0..1.0), rng.random_range(0.0..1.0))
    };
    let (bw, bh) = r.board().squares_size_m();
    let m = r.board().margin_m;
    let sheet_area = (bw + 2.0 * m) * (bh + 2.0 * m);
    let centre = nalgebra::Point3::new(0.5 * bw, 0.5 * bh, 0.0);
    let mut z = k.fx_px * (sheet_area / (fill * w * h)).sqrt();
    let (mut xn, mut yn) = (0.0, 0.0);
    let pose_of = |z: f64, xn: f64, yn: f64| {
        let t = Vector3::new(xn * z, yn * z, z) - rot * centre.coords;
        Isometry3::from_parts(Translation3::from(t), rot)
    };
    for _ in 0..40 {
        let bb = sheet_bbox(r, outline, &pose_of(z, xn, yn))?;
        let (sw, sh) = (bb[2] - bb[0], bb[3] - bb[1]);
        if sw > w - 2.0 * SAFETY_PX || sh > h - 2.0 * SAFETY_PX {
            z *= 1.05;
            continue;
        }
        z *= (sw * sh / (fill * w * h)).sqrt().clamp(0.8, 1.25);
        let left = SAFETY_PX + fx * (w - 2.0 * SAFETY_PX - sw);
        let top = SAFETY_PX + fy * (h - 2.0 * SAFETY_PX - sh);
        xn += 0.8 * (left - bb[0]) / k.fx_px;
        yn += 0.8 * (top - bb[1]) / k.fy_px;
    }
    let pose = pose_of(z, xn, yn);
    let bb = sheet_bbox(r, outline, &pose)?;
    let inside =
        bb[0] >= SAFETY_PX - 1.0 && bb[1] >= SAFETY_PX - 1.0 && bb[2] <= w - SAFETY_PX && bb[3] <= h - SAFETY_PX;
    let area = (bb[2] - bb[0]) * (bb[3] - bb[1]) / (w * h);
    (inside && (area / fill - 1.0).abs() < 0.1).then_some(pose)
}

/// `n` board poses (`T_cam_board`, board frame of [`super::supersampled`]) for the renderer's
/// camera and board, deterministic for `seed` (see the module documentation).
pub fn board_poses(r: &SupersampledRenderer, n: usize, seed: u64) -> Result<Vec<Isometry3<f64>>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed.wrapping_mul(0xA24B_AED4_963E_E407).wrapping_add(3));
    let outline = sheet_outline(r.board());
    let mut poses = Vec::with_capacity(n);
    let mut tries = 0;
    while poses.len() < n {
        tries += 1;
        if tries > 200 * n.max(1) {
            return Err(DatasetError::Render(format!("calibration study: only {} of {n} poses placed", poses.len())));
        }
        if let Some(p) = try_pose(&mut rng, r, &outline) {
            poses.push(p);
        }
    }
    Ok(poses)
}

/// RMS of the distances of `found` to their nearest point of `truth`.
fn corner_rms(found: &[Point2<f64>], truth: &[Point2<f64>]) -> f64 {
    let sq: Vec<f64> =
        found.iter().map(|p| truth.iter().map(|t| (p - t).norm_squared()).fold(f64::INFINITY, f64::min)).collect();
    if sq.is_empty() {
        f64::NAN
    } else {
        (sq.iter().sum::<f64>() / sq.len() as f64).sqrt()
    }
}

fn side(
    truth: &Intrinsics,
    est: [f64; 4],
    std: [f64; 4],
    views: usize,
    corner_rms_px: f64,
    reprojection_rms_px: f64,
) -> SideResult {
    let t = [truth.fx_px, truth.fy_px, truth.cx_px, truth.cy_px];
    let abs_error_px: [f64; 4] = std::array::from_fn(|i| (est[i] - t[i]).abs());
    let rms_error_px = (abs_error_px.iter().map(|e| e * e).sum::<f64>() / 4.0).sqrt();
    let within_3_sigma = std::array::from_fn(|i| abs_error_px[i] <= 3.0 * std[i]);
    SideResult {
        views,
        corner_rms_px,
        reprojection_rms_px,
        intrinsics_px: est,
        std_px: std,
        std_independent_px: [f64::NAN; 4],
        std_jackknife_px: [f64::NAN; 4],
        std_sandwich_px: [f64::NAN; 4],
        abs_error_px,
        rms_error_px,
        within_3_sigma,
    }
}

/// OpenCV's `calibrateCamera` (flags 0: Brown-5, fx and fy free; its default stop criteria)
/// on OpenCV's corners: (`fx fy cx cy`, their standard deviations, RMS).
fn opencv_calibrate(views: &[View], board: &PrintedChessboard, size: ImageSize) -> Result<([f64; 4], [f64; 4], f64)> {
    use opencv::core::{Mat, Point2f, Point3f, Size, TermCriteria, Vector, CV_64F};
    use opencv::prelude::*;
    let cv = |e: opencv::Error| DatasetError::Render(format!("OpenCV calibrateCamera: {e}"));
    let s = board.square_m as f32;
    let one: Vector<Point3f> = (0..board.inner_rows)
        .flat_map(|r| (0..board.inner_cols).map(move |c| Point3f::new(c as f32 * s, r as f32 * s, 0.0)))
        .collect();
    let obj: Vector<Vector<Point3f>> = views.iter().map(|_| one.clone()).collect();
    let img: Vector<Vector<Point2f>> =
        views.iter().map(|v| v.corners_px.iter().map(|p| Point2f::new(p.x as f32, p.y as f32)).collect()).collect();
    let mut camera = Mat::eye(3, 3, CV_64F).map_err(cv)?.to_mat().map_err(cv)?;
    let mut dist = Mat::zeros(5, 1, CV_64F).map_err(cv)?.to_mat().map_err(cv)?;
    let (mut rvecs, mut tvecs): (Vector<Mat>, Vector<Mat>) = (Vector::new(), Vector::new());
    let (mut std_i, mut std_e, mut per_view) = (Mat::default(), Mat::default(), Mat::default());
    let criteria =
        TermCriteria::new(opencv::core::TermCriteria_COUNT + opencv::core::TermCriteria_EPS, 30, f64::EPSILON)
            .map_err(cv)?;
    let rms = opencv::calib3d::calibrate_camera_extended(
        &obj,
        &img,
        Size::new(size.width_px as i32, size.height_px as i32),
        &mut camera,
        &mut dist,
        &mut rvecs,
        &mut tvecs,
        &mut std_i,
        &mut std_e,
        &mut per_view,
        0,
        criteria,
    )
    .map_err(cv)?;
    let at = |m: &Mat, r: i32, c: i32| m.at_2d::<f64>(r, c).copied().map_err(cv);
    let k = [at(&camera, 0, 0)?, at(&camera, 1, 1)?, at(&camera, 0, 2)?, at(&camera, 1, 2)?];
    let sd = [
        *std_i.at::<f64>(0).map_err(cv)?,
        *std_i.at::<f64>(1).map_err(cv)?,
        *std_i.at::<f64>(2).map_err(cv)?,
        *std_i.at::<f64>(3).map_err(cv)?,
    ];
    Ok((k, sd, rms))
}

/// A seed's rendered views ([`render_seed`]).
#[derive(Clone, Debug)]
pub struct RenderedSeed {
    /// The seed.
    pub seed: u64,
    /// The truth camera.
    pub truth: CameraModel,
    /// `T_cam_board` of every view (board frame of [`super::supersampled`]).
    pub poses: Vec<Isometry3<f64>>,
    /// The PNG file of every view.
    pub paths: Vec<PathBuf>,
    /// The true image positions of every view's inner corners, row by row from the board's
    /// top-left ([`PrintedChessboard::inner_corners`]), pixels.
    pub truth_px: Vec<Vec<Point2<f64>>>,
}

/// Renders a seed's views into `dir` (PNG files `seedSSS_viewVV.png`); with
/// [`StudySettings::reuse_renders`] a file that already exists is kept (it must come from the
/// same settings: the file name holds only the seed and the view).
pub fn render_seed(settings: &StudySettings, seed: u64, dir: &Path) -> Result<RenderedSeed> {
    let truth = truth_camera(seed, settings.width, settings.height)?;
    let renderer = SupersampledRenderer::new(truth, settings.board, settings.render.clone())?;
    let poses = board_poses(&renderer, settings.views, seed)?;
    std::fs::create_dir_all(dir).map_err(|source| DatasetError::Write { path: dir.to_path_buf(), source })?;
    let mut paths = Vec::new();
    let mut truth_px: Vec<Vec<Point2<f64>>> = Vec::new();
    for (k, pose) in poses.iter().enumerate() {
        let path = dir.join(format!("seed{seed:03}_view{k:02}.png"));
        if !(settings.reuse_renders && path.is_file()) {
            let img = renderer.render(pose, seed.wrapping_mul(1_000_003).wrapping_add(k as u64))?;
            img.save(&path).map_err(|e| DatasetError::Render(format!("{}: {e}", path.display())))?;
        }
        paths.push(path);
        let corners = settings.board.inner_corners();
        truth_px.push(corners.iter().filter_map(|c| renderer.project(pose, c)).collect());
    }
    Ok(RenderedSeed { seed, truth, poses, paths, truth_px })
}

impl RenderedSeed {
    /// The index of the view whose file is `name`.
    pub fn view_index(&self, name: &str) -> Option<usize> {
        self.paths.iter().position(|p| p.display().to_string() == name)
    }

    /// RMS distance of the views' corners to their nearest true corner, pixels.
    pub fn corner_error_rms(&self, views: &[View]) -> f64 {
        let (mut sq, mut n) = (0.0, 0usize);
        for v in views {
            if let Some(i) = self.view_index(&v.name) {
                let e = corner_rms(&v.corners_px, &self.truth_px[i]);
                sq += e * e * v.corners_px.len() as f64;
                n += v.corners_px.len();
            }
        }
        (sq / n.max(1) as f64).sqrt()
    }
}

/// The calibration pattern of the study's board.
pub fn study_pattern(board: &PrintedChessboard) -> CalibrationPattern {
    CalibrationPattern::Chessboard {
        inner_cols: board.inner_cols,
        inner_rows: board.inner_rows,
        square_m: board.square_m,
    }
}

/// The project's own corners of every view where the board was found
/// (`detect_pattern_views(.., CornerMethod::Own)`, the default of `camera calibrate`).
pub fn own_views(settings: &StudySettings, rendered: &RenderedSeed) -> Vec<View> {
    let found = detect_pattern_views(&rendered.paths, &study_pattern(&settings.board), CornerMethod::Own);
    found.slots.into_iter().flatten().collect()
}

/// OpenCV's corners (`findChessboardCorners` + `cornerSubPix` 11 x 11) of every view where
/// the board was found.
pub fn opencv_views(settings: &StudySettings, rendered: &RenderedSeed) -> Vec<View> {
    let b = &settings.board;
    rendered
        .paths
        .iter()
        .filter_map(|p| chessboard_corners_opencv_with(p, b.inner_cols, b.inner_rows, SubpixWindow::OpenCv).ok())
        .map(|c| View::new(c.image.display().to_string(), c.image_size, c.corners_px))
        .collect()
}

/// The options of `camera calibrate`'s default with the given covariance.
fn options_with(covariance: CovarianceMethod) -> CalibrationOptions {
    CalibrationOptions { covariance, ..CalibrationOptions::default() }
}

/// Runs one seed: renders the views into `dir` (PNG files), calibrates both ways, compares
/// with the truth.
pub fn run_seed(settings: &StudySettings, seed: u64, dir: &Path) -> Result<SeedResult> {
    let rendered = render_seed(settings, seed, dir)?;
    let truth = rendered.truth;
    let b = &settings.board;
    let pattern = study_pattern(b);
    let t = truth.intrinsics;

    // (a) The project's default: own corners, calibrate_pattern.
    let ours_views = own_views(settings, &rendered);
    let pc = calibrate_pattern(&ours_views, &pattern, None, &CalibrationOptions::default())?;
    let c = &pc.calibration;
    let k = c.camera.intrinsics;
    let mut ours = side(
        &t,
        [k.fx_px, k.fy_px, k.cx_px, k.cy_px],
        [c.std[0], c.std[1], c.std[2], c.std[3]],
        ours_views.len(),
        rendered.corner_error_rms(&ours_views),
        c.rms_px,
    );
    for (method, out) in [
        (CovarianceMethod::Independent, &mut ours.std_independent_px),
        (CovarianceMethod::ViewJackknife, &mut ours.std_jackknife_px),
        (CovarianceMethod::ViewSandwich, &mut ours.std_sandwich_px),
    ] {
        let s = if method == CalibrationOptions::default().covariance {
            c.std.clone()
        } else {
            calibrate_pattern(&ours_views, &pattern, None, &options_with(method))?.calibration.std
        };
        *out = [s[0], s[1], s[2], s[3]];
    }

    // (b) OpenCV: findChessboardCorners + cornerSubPix 11 x 11, calibrateCamera.
    let cv_views = opencv_views(settings, &rendered);
    if cv_views.len() < 3 {
        return Err(DatasetError::Render(format!("seed {seed}: OpenCV found the board in {} views", cv_views.len())));
    }
    let (cv_k, cv_std, cv_rms) = opencv_calibrate(&cv_views, b, truth.image_size)?;
    let opencv = side(&t, cv_k, cv_std, cv_views.len(), rendered.corner_error_rms(&cv_views), cv_rms);
    let ratio = opencv.rms_error_px / ours.rms_error_px;
    Ok(SeedResult { seed, truth, ours, opencv, ratio })
}

/// Median of a slice (NaN when empty).
fn median(v: &[f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    ferrocal_vision::calib::median(v)
}

/// The aggregate over seeds.
pub fn summarize(results: &[SeedResult]) -> Summary {
    let ratios: Vec<f64> = results.iter().map(|r| r.ratio).collect();
    let n = results.len().max(1) as f64;
    let cover = |f: &dyn Fn(&SeedResult) -> [bool; 4]| {
        results.iter().map(|r| f(r).iter().filter(|w| **w).count()).sum::<usize>() as f64 / (4.0 * n)
    };
    let rms = |f: &dyn Fn(&SeedResult) -> f64| (results.iter().map(|r| f(r).powi(2)).sum::<f64>() / n).sqrt();
    let of = |f: &dyn Fn(&SeedResult) -> [f64; 4]| results.iter().map(f).collect::<Vec<_>>();
    let err = of(&|r| r.ours.abs_error_px);
    let indep = of(&|r| r.ours.std_independent_px);
    Summary {
        seeds: results.len(),
        median_ratio: median(&ratios),
        min_ratio: ratios.iter().copied().fold(f64::INFINITY, f64::min),
        fraction_ratio_at_least_1_5: ratios.iter().filter(|r| **r >= 1.5).count() as f64 / n,
        ours_coverage_3_sigma: cover(&|r| r.ours.within_3_sigma),
        opencv_coverage_3_sigma: cover(&|r| r.opencv.within_3_sigma),
        ours_rms_error_px: rms(&|r| r.ours.rms_error_px),
        opencv_rms_error_px: rms(&|r| r.opencv.rms_error_px),
        ours_independent: coverage(&err, &indep, &indep),
        ours_jackknife: coverage(&err, &of(&|r| r.ours.std_jackknife_px), &indep),
        ours_sandwich: coverage(&err, &of(&|r| r.ours.std_sandwich_px), &indep),
        opencv: coverage(&of(&|r| r.opencv.abs_error_px), &of(&|r| r.opencv.std_px), &of(&|r| r.opencv.std_px)),
    }
}

/// The per-seed results and the summary as Markdown tables.
pub fn markdown(results: &[SeedResult], summary: &Summary) -> String {
    let mut s = String::from(
        "| seed | views ours/cv | corner RMS ours / cv (px) | ours abs err fx fy cx cy (px) | OpenCV abs err fx fy cx cy (px) | RMS ours / cv (px) | ratio | ours 3-sigma | ours std fx fy cx cy (px) |\n\
         |---|---|---|---|---|---|---|---|---|\n",
    );
    let four = |v: [f64; 4]| format!("{:.2} {:.2} {:.2} {:.2}", v[0], v[1], v[2], v[3]);
    for r in results {
        let ok = r.ours.within_3_sigma.iter().filter(|w| **w).count();
        s.push_str(&format!(
            "| {} | {}/{} | {:.3} / {:.3} | {} | {} | {:.2} / {:.2} | {:.2} | {ok}/4 | {} |\n",
            r.seed,
            r.ours.views,
            r.opencv.views,
            r.ours.corner_rms_px,
            r.opencv.corner_rms_px,
            four(r.ours.abs_error_px),
            four(r.opencv.abs_error_px),
            r.ours.rms_error_px,
            r.opencv.rms_error_px,
            r.ratio,
            four(r.ours.std_px),
        ));
    }
    s.push_str(
        "\n| seed | ours abs err fx fy cx cy (px) | std independent | std jackknife | std sandwich | within 3 sigma indep / jack / sandwich |\n|---|---|---|---|---|---|\n",
    );
    for r in results {
        let o = &r.ours;
        let count = |std: [f64; 4]| (0..4).filter(|&i| o.abs_error_px[i] <= 3.0 * std[i]).count();
        s.push_str(&format!(
            "| {} | {} | {} | {} | {} | {}/4 {}/4 {}/4 |\n",
            r.seed,
            four(o.abs_error_px),
            four(o.std_independent_px),
            four(o.std_jackknife_px),
            four(o.std_sandwich_px),
            count(o.std_independent_px),
            count(o.std_jackknife_px),
            count(o.std_sandwich_px),
        ));
    }
    let cov = |c: &Coverage| {
        format!(
            "{}/{} within 3 sigma, {} beyond 2 sigma, RMS error/sigma {:.2}, sigma x{:.2} of independent",
            c.within_3_sigma, c.n, c.beyond_2_sigma, c.z_rms, c.sigma_ratio
        )
    };
    s.push_str(&format!(
        "\ncoverage ours independent: {}\ncoverage ours jackknife: {}\ncoverage ours sandwich: {}\ncoverage OpenCV: {}\n",
        cov(&summary.ours_independent),
        cov(&summary.ours_jackknife),
        cov(&summary.ours_sandwich),
        cov(&summary.opencv)
    ));
    s.push_str(&format!(
        "\nseeds {}: median ratio {:.2} (min {:.2}), ratio >= 1.5 in {:.0} % of the seeds; RMS intrinsic error ours {:.3} px, OpenCV {:.3} px; 3-sigma coverage ours {:.1} % (OpenCV {:.1} %)\n",
        summary.seeds,
        summary.median_ratio,
        summary.min_ratio,
        100.0 * summary.fraction_ratio_at_least_1_5,
        summary.ours_rms_error_px,
        summary.opencv_rms_error_px,
        100.0 * summary.ours_coverage_3_sigma,
        100.0 * summary.opencv_coverage_3_sigma,
    ));
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn truth_cameras_and_poses_follow_the_settings() {
        let s = StudySettings { width: 640, height: 480, ..StudySettings::default() };
        let cam = truth_camera(4, 640, 480).unwrap();
        let k = cam.intrinsics;
        assert!((512.0..704.0).contains(&k.fx_px) && (k.fy_px / k.fx_px - 1.0).abs() <= 0.015);
        assert!((k.cx_px - 319.5).abs() <= 20.0 && (k.cy_px - 239.5).abs() <= 15.0);
        let r = SupersampledRenderer::new(cam, s.board, s.render.clone()).unwrap();
        let poses = board_poses(&r, 12, 4).unwrap();
        assert_eq!(poses, board_poses(&r, 12, 4).unwrap());
        let outline = sheet_outline(&s.board);
        for p in &poses {
            let bb = sheet_bbox(&r, &outline, p).unwrap();
            assert!(bb[0] >= 4.0 && bb[1] >= 4.0 && bb[2] <= 636.0 && bb[3] <= 476.0, "{bb:?}");
            let area = (bb[2] - bb[0]) * (bb[3] - bb[1]) / (640.0 * 480.0);
            assert!((0.26..0.78).contains(&area), "{area}");
            // Tilt: the board normal against the optical axis.
            let n = p.rotation * Vector3::z();
            let tilt = n.z.acos().to_degrees();
            assert!((14.9..45.1).contains(&tilt), "{tilt}");
        }
    }

    #[test]
    fn the_summary_counts_ratios_and_coverage() {
        let cam = truth_camera(1, 640, 480).unwrap();
        let t = cam.intrinsics;
        let mk = |err: f64, std: f64| side(&t, [t.fx_px + err, t.fy_px, t.cx_px, t.cy_px], [std; 4], 10, 0.1, 0.1);
        let r = |seed, ours: f64, cv: f64| SeedResult {
            seed,
            truth: cam,
            ours: mk(ours, 1.0),
            opencv: mk(cv, 1.0),
            ratio: cv / ours,
        };
        let s = summarize(&[r(0, 1.0, 2.0), r(1, 4.0, 4.0), r(2, 1.0, 3.0)]);
        assert!((s.median_ratio - 2.0).abs() < 1e-12 && (s.min_ratio - 1.0).abs() < 1e-12);
        assert!((s.fraction_ratio_at_least_1_5 - 2.0 / 3.0).abs() < 1e-12);
        // fx of seed 1 is 4 sigma off: 11 of 12 within 3 sigma.
        assert!((s.ours_coverage_3_sigma - 11.0 / 12.0).abs() < 1e-12);
        assert!(markdown(&[r(0, 1.0, 2.0)], &s).contains("| 0 | 10/10 |"));
        // Coverage: one value 3.5 sigma off, three 1 sigma off; sigmas twice the reference.
        let c = coverage(&[[3.5, 1.0, 1.0, 1.0]], &[[1.0; 4]], &[[0.5; 4]]);
        assert_eq!((c.n, c.within_3_sigma, c.beyond_2_sigma), (4, 3, 1));
        assert!((c.z_rms - ((3.5f64 * 3.5 + 3.0) / 4.0).sqrt()).abs() < 1e-12);
        assert!((c.sigma_ratio - 2.0).abs() < 1e-12);
    }
}
