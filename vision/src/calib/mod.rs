//! Camera calibration from views of a planar target: one camera ([`calibrate_camera`]) and a rig
//! of cameras that see the same target poses ([`calibrate_stereo`], [`calibrate_rig`]).
//!
//! Method (one camera):
//! 1. per view, the plane-to-image homography by the normalised DLT
//!    ([`crate::pose::homography`]);
//! 2. Zhang's closed form for `fx fy cx cy` (zero skew, optionally `fx = fy`), with a check that
//!    the views determine them at all (parallel boards do not); the target poses from the
//!    homographies; distortion zero;
//! 3. a bundle adjustment (Ceres, analytic Jacobians, optional Huber / Cauchy loss) of the
//!    camera parameters and every target pose, rotations as left increments around the current
//!    estimate ([`crate::pose::so3`]);
//! 4. per-view RMS, outlier views (RMS and median corner error above
//!    [`CalibrationOptions::outlier_view_factor`] times the median over views) and outlier corners (beyond [`CalibrationOptions::outlier_corner_sigmas`]
//!    robust standard deviations), optionally removed and the problem re-solved;
//! 5. the covariance `s0^2 (J^T J)^-1` of the camera parameters with the poses marginalised
//!    (Schur complement), and from it the standard deviation of every parameter.
//!
//! A rig: every camera calibrated alone as above, `T_cam_cam0` started from the median of the
//! per-view relative poses, then one bundle adjustment of all cameras' parameters, the rig's
//! extrinsics and one target pose per view (shared by the cameras that see it).
//!
//! Entry points: [`calibrate_camera`], [`calibrate_stereo`], [`calibrate_rig`]; the inputs
//! [`PlanarTarget`] (from a [`crate::detect::Pattern`] string: [`PlanarTarget::of_pattern`];
//! the patterns calibration can use: [`CalibrationPattern`], [`calibrate_pattern`]),
//! [`View`], [`CalibrationOptions`]; OpenCV corners for real images in [`corners`]. The bundle
//! adjustment itself, with a bent or mis-printed target, other lens models and a poses-only
//! mode: [`adjust_bundle`] ([`BundleSpec`], [`BundleModel`], [`BundleFit`]).
//!
//! # Conventions
//! Pixel `(0, 0)` is the centre of the top-left pixel. Target points in metres in the target
//! frame (on a plane). `T_a_b` maps frame `b` into frame `a`; a view's pose is
//! `T_cam_target`. Stereo results are `T_right_left` (OpenCV's `R`, `T` of
//! `stereoCalibrate`: `p_right = R p_left + T`). RMS values are the root mean square of the
//! corners' 2D reprojection error lengths, as OpenCV reports them.

mod adjust;
mod bundle;
pub mod circles;
pub mod compare;
pub mod corners;
mod covariance;
mod deform;
pub mod heldout;
mod pattern;
mod stereo;
mod zhang;

#[cfg(test)]
mod tests;

use nalgebra::{DMatrix, DVector, Isometry3, Point2, Point3};
use serde::{Deserialize, Serialize};

pub use adjust::*;
pub use covariance::{CovarianceMethod, MIN_JACKKNIFE_VIEWS};
pub use deform::{Deformed, TargetDeformation};
pub use pattern::CalibrationPattern;
pub use stereo::{
    calibrate_rig, calibrate_stereo, check_pairing, rectified_row_rms_px, PairingCheck, RectifiedCorner,
    RigCalibration, ShiftFit, StereoCalibration,
};

use crate::camera::{CameraModel, Distortion, DistortionKind, ImageSize};
use crate::detect::Pattern;
use crate::error::{Result, VisionError};
use crate::pose::{homography, plane_frame, LocalPose};
use bundle::{Bundle, CameraLayout, Obs};

mod views;
pub use views::median;
pub(crate) use views::{check_views, view_homography};

mod outliers;
pub(crate) use outliers::flag_outliers;

/// Fewest views a calibration accepts.
pub const MIN_VIEWS: usize = 3;

/// Zhang's system is called degenerate below this ratio of its second-smallest to its largest
/// singular value (after normalisation): views of parallel boards give about the corner noise
/// relative to the image size (1e-4 and below), well-tilted views 1e-2 and above.
pub const MIN_ZHANG_CONDITION: f64 = 1.5e-3;

/// Views whose board normals all lie within this angle (degrees) of each other cannot tell
/// focal length from distance.
pub const MIN_BOARD_ANGLE_DEG: f64 = 5.0;

/// A planar calibration target.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlanarTarget {
    /// The points in the target frame, metres, all on one plane.
    pub points_m: Vec<Point3<f64>>,
    /// Whether reversing the point order is a symmetry of the target (true for a chessboard
    /// grid: a detector may number its corners from either end). Stereo calibration then
    /// makes the numbering of every view consistent between the cameras.
    pub reversible: bool,
}

impl PlanarTarget {
    /// A chessboard's inner corners, OpenCV's object points `(col * square, row * square, 0)`,
    /// row by row from the first detected corner.
    pub fn chessboard(inner_cols: u32, inner_rows: u32, square_m: f64) -> Self {
        let points_m = (0..inner_rows)
            .flat_map(|r| (0..inner_cols).map(move |c| Point3::new(c as f64 * square_m, r as f64 * square_m, 0.0)))
            .collect();
        PlanarTarget { points_m, reversible: true }
    }

    /// The target of a pattern string's pattern: chessboards, ChArUco boards and circle grids
    /// (other patterns are refused, naming the pattern).
    pub fn of_pattern(pattern: &Pattern) -> Result<Self> {
        Ok(CalibrationPattern::of(pattern)?.target())
    }

    /// Checks that there are at least four finite points on a plane.
    pub fn validate(&self) -> Result<()> {
        if self.points_m.len() < 4 {
            return Err(VisionError::InvalidInput {
                detail: format!("a target needs at least 4 points, this one has {}", self.points_m.len()),
            });
        }
        if self.points_m.iter().any(|p| !p.coords.iter().all(|v| v.is_finite())) {
            return Err(VisionError::InvalidInput { detail: "target point not finite".into() });
        }
        plane_frame(&self.points_m).map(|_| ())
    }
}

/// The corners one camera saw of the target in one image.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct View {
    /// A name for messages and reports (usually the image path).
    pub name: String,
    /// The image size.
    pub image_size: ImageSize,
    /// Which target point each corner is.
    pub point_ids: Vec<usize>,
    /// The corners, pixels.
    pub corners_px: Vec<Point2<f64>>,
}

impl View {
    /// A view of all target points, in the target's order.
    pub fn new(name: impl Into<String>, image_size: ImageSize, corners_px: Vec<Point2<f64>>) -> Self {
        let point_ids = (0..corners_px.len()).collect();
        Self { name: name.into(), image_size, point_ids, corners_px }
    }
}

/// A robust loss on the length of a corner's reprojection error.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum RobustLoss {
    /// Plain least squares (as OpenCV).
    #[default]
    None,
    /// Huber: quadratic up to `scale_px`, linear beyond.
    Huber {
        /// Where the loss turns linear, pixels.
        scale_px: f64,
    },
    /// Cauchy: `s^2 log(1 + r^2 / s^2)`.
    Cauchy {
        /// Scale, pixels.
        scale_px: f64,
    },
}

impl RobustLoss {
    /// Parses `none`, `huber:<px>` or `cauchy:<px>`.
    pub fn parse(text: &str) -> Result<Self> {
        let bad = || VisionError::InvalidInput {
            detail: format!("loss '{text}': expected none, huber:<scale px> or cauchy:<scale px>"),
        };
        let t = text.trim().to_ascii_lowercase();
        if t == "none" {
            return Ok(RobustLoss::None);
        }
        let (kind, v) = t.split_once(':').ok_or_else(bad)?;
        let scale_px: f64 = v.trim().trim_end_matches("px").parse().map_err(|_| bad())?;
        if !(scale_px.is_finite() && scale_px > 0.0) {
            return Err(bad());
        }
        match kind {
            "huber" => Ok(RobustLoss::Huber { scale_px }),
            "cauchy" => Ok(RobustLoss::Cauchy { scale_px }),
            _ => Err(bad()),
        }
    }
}

/// Options of a calibration.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CalibrationOptions {
    /// Lens model (default: OpenCV's 5-coefficient Brown model).
    pub model: DistortionKind,
    /// Keep `fx = fy` (OpenCV's `CALIB_FIX_ASPECT_RATIO` with an initial ratio of 1).
    pub fix_aspect: bool,
    /// Robust loss of the bundle adjustment.
    pub loss: RobustLoss,
    /// A view is an outlier when its RMS and its median corner error both exceed this factor
    /// times the median over the views (a single bad corner flags the corner, not the view).
    pub outlier_view_factor: f64,
    /// A corner is an outlier when its error exceeds this many robust standard deviations
    /// (`1.4826 * median` of the absolute residual components).
    pub outlier_corner_sigmas: f64,
    /// Remove outlier views and corners and solve again.
    pub reject_outliers: bool,
    /// Ceres iteration limit per solve.
    pub max_iterations: usize,
    /// How the covariance of the camera parameters is computed (one camera; a rig's joint
    /// adjustment reports the independent-corner covariance).
    pub covariance: CovarianceMethod,
}

impl Default for CalibrationOptions {
    fn default() -> Self {
        Self {
            model: DistortionKind::Brown5,
            fix_aspect: false,
            loss: RobustLoss::None,
            outlier_view_factor: 2.5,
            outlier_corner_sigmas: 5.0,
            reject_outliers: false,
            max_iterations: 200,
            covariance: CovarianceMethod::default(),
        }
    }
}

impl CalibrationOptions {
    /// Checks the values.
    pub fn validate(&self) -> Result<()> {
        let bad = |d: String| Err(VisionError::InvalidInput { detail: d });
        if !(self.outlier_view_factor.is_finite() && self.outlier_view_factor > 1.0) {
            return bad(format!("outlier_view_factor must be > 1, got {}", self.outlier_view_factor));
        }
        if !(self.outlier_corner_sigmas.is_finite() && self.outlier_corner_sigmas > 0.0) {
            return bad(format!("outlier_corner_sigmas must be > 0, got {}", self.outlier_corner_sigmas));
        }
        if self.max_iterations == 0 {
            return bad("max_iterations must be at least 1".into());
        }
        match self.loss {
            RobustLoss::Huber { scale_px } | RobustLoss::Cauchy { scale_px }
                if !(scale_px.is_finite() && scale_px > 0.0) =>
            {
                bad(format!("robust loss scale must be > 0, got {scale_px} px"))
            }
            _ => Ok(()),
        }
    }
}

/// What the calibration found about one view.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ViewReport {
    /// The view's name.
    pub name: String,
    /// RMS reprojection error of its corners, pixels (of the final solution; also for views
    /// that were removed as outliers).
    pub rms_px: f64,
    /// Corners in the view.
    pub n_corners: usize,
    /// Whether the view's RMS marks it as an outlier.
    pub outlier: bool,
    /// Whether it took part in the final solution.
    pub used: bool,
    /// Corners of this view flagged as outliers.
    pub n_outlier_corners: usize,
    /// `T_cam_target` of the view.
    pub t_cam_target: Isometry3<f64>,
}

/// A corner whose reprojection error is an outlier.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CornerOutlier {
    /// The view's name.
    pub view: String,
    /// The target point.
    pub point_id: usize,
    /// Length of its reprojection error, pixels.
    pub residual_px: f64,
    /// Whether it was removed before the final solution.
    pub removed: bool,
}

/// How the calibration went.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CalibrationSummary {
    /// The closed-form camera the bundle adjustment started from.
    pub initial: CameraModel,
    /// Zhang's conditioning (`sigma_{m-1} / sigma_1`, see [`MIN_ZHANG_CONDITION`]).
    pub zhang_condition: f64,
    /// Whether Zhang's solution was unusable and the centred fallback was used instead.
    pub zhang_fallback: bool,
    /// Largest angle between two boards' normals, degrees.
    pub max_board_angle_deg: f64,
    /// Condition number of the correlation-scaled normal matrix of the camera parameters.
    pub normal_condition: f64,
    /// A-posteriori standard error of unit weight (the corner noise the fit implies), pixels.
    pub s0_px: f64,
    /// How [`CameraCalibration::covariance`] was computed.
    #[serde(default)]
    pub covariance_method: CovarianceMethod,
    /// The standard deviations with every corner an independent measurement
    /// ([`CovarianceMethod::Independent`]; equal to [`CameraCalibration::std`] when that is
    /// the method), in the order of [`CameraCalibration::std`].
    #[serde(default)]
    pub std_independent: Vec<f64>,
    /// Corners used in the final solution.
    pub n_corners: usize,
    /// Views removed as outliers.
    pub removed_views: Vec<String>,
    /// Ceres iterations over all solves.
    pub iterations: usize,
    /// Ceres' report of the final solve.
    pub solver_report: String,
    /// Things worth a look that did not stop the calibration.
    pub warnings: Vec<String>,
}

/// A calibrated camera with its uncertainty.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraCalibration {
    /// The camera.
    pub camera: CameraModel,
    /// Standard deviation of every model parameter (`fx fy cx cy k...`, the order of
    /// [`CameraModel::parameters`]); with a fixed aspect ratio `fx` and `fy` share theirs.
    pub std: Vec<f64>,
    /// Covariance of the model parameters, target poses marginalised.
    pub covariance: DMatrix<f64>,
    /// RMS reprojection error over all used corners, pixels.
    pub rms_px: f64,
    /// Every view, in input order.
    pub views: Vec<ViewReport>,
    /// Outlier corners.
    pub outlier_corners: Vec<CornerOutlier>,
    /// Conditioning, solver, outliers.
    pub summary: CalibrationSummary,
}

/// Calibrates one camera from views of a planar target (see the module documentation).
///
/// Errors: [`VisionError::TooFewViews`] (fewer than [`MIN_VIEWS`] usable views, with the reason
/// for each unusable one), [`VisionError::ImageSizeMismatch`] (naming the images of each size),
/// [`VisionError::DegenerateViews`] (e.g. all boards near-parallel, with the angles),
/// [`VisionError::InvalidInput`], [`VisionError::SolverFailed`].
pub fn calibrate_camera(
    views: &[View],
    target: &PlanarTarget,
    options: &CalibrationOptions,
) -> Result<CameraCalibration> {
    options.validate()?;
    target.validate()?;
    let refs: Vec<&View> = views.iter().collect();
    let size = check_views(&refs, target)?;
    let t_target_plane = plane_frame(&target.points_m)?;
    let t_plane_target = t_target_plane.inverse();

    let mut usable: Vec<(usize, nalgebra::Matrix3<f64>)> = Vec::new();
    let mut reasons = Vec::new();
    for (i, v) in views.iter().enumerate() {
        match view_homography(v, target, &t_plane_target) {
            Ok(h) => usable.push((i, h)),
            Err(r) => reasons.push(format!("{}: {r}", v.name)),
        }
    }
    if usable.len() < MIN_VIEWS {
        let mut detail =
            format!("a full calibration needs views of the target from at least {MIN_VIEWS} different orientations");
        if !reasons.is_empty() {
            detail.push_str(&format!("; unusable: {}", reasons.join("; ")));
        }
        return Err(VisionError::TooFewViews { usable: usable.len(), needed: MIN_VIEWS, detail });
    }
    let hs: Vec<nalgebra::Matrix3<f64>> = usable.iter().map(|(_, h)| *h).collect();
    let z = zhang::zhang_intrinsics(&hs, size, options.fix_aspect);
    // Board orientations, for the explanation of degenerate sets.
    let intr = z.intrinsics;
    let poses_plane: Vec<Isometry3<f64>> =
        hs.iter().filter_map(|h| zhang::extrinsics_from_homography(h, &intr)).collect();
    let max_angle = zhang::max_normal_angle_deg(&poses_plane);
    if z.condition < MIN_ZHANG_CONDITION {
        return Err(VisionError::DegenerateViews {
            detail: format!(
                "the {} boards are nearly parallel (largest angle between board normals {max_angle:.1} deg; \
                 Zhang's constraint system has condition {:.1e} < {MIN_ZHANG_CONDITION:.1e}), so the focal \
                 length and principal point are not determined; tilt the board by 20 to 45 deg about \
                 different axes between views",
                usable.len(),
                z.condition
            ),
        });
    }
    let layout = CameraLayout { kind: options.model, fix_aspect: options.fix_aspect, aspect: 1.0, image_size: size };
    let mut initial = CameraModel {
        intrinsics: intr,
        distortion: Distortion::from_coefficients(options.model, &vec![0.0; options.model.coefficient_names().len()])?,
        image_size: size,
    };
    if options.fix_aspect {
        let f = 0.5 * (initial.intrinsics.fx_px + initial.intrinsics.fy_px);
        initial.intrinsics.fx_px = f;
        initial.intrinsics.fy_px = f;
    }
    let mut view_poses = Vec::new();
    for (i, h) in &usable {
        let t_cam_plane = zhang::extrinsics_from_homography(h, &initial.intrinsics).ok_or_else(|| {
            VisionError::DegenerateViews { detail: format!("{}: no pose from its homography", views[*i].name) }
        })?;
        view_poses.push(LocalPose::from_isometry(&(t_cam_plane * t_plane_target)));
    }
    let mut obs = Vec::new();
    for (k, (i, _)) in usable.iter().enumerate() {
        let v = &views[*i];
        for (pid, px) in v.point_ids.iter().zip(&v.corners_px) {
            obs.push(Obs { cam: 0, view: k, point_id: *pid, point: target.points_m[*pid], pixel: *px });
        }
    }
    let all_obs = obs.clone();
    let mut bundle = Bundle {
        layouts: vec![layout],
        cameras: vec![layout.free_from_model(&initial)],
        extrinsics: Vec::new(),
        views: view_poses,
        obs,
        loss: options.loss,
        deform: None,
        fixed_globals: false,
    };
    let (mut report, mut iterations) = bundle.solve(options.max_iterations)?;
    let mut flags = flag_outliers(&bundle, &all_obs, options)?;
    let mut removed_views = Vec::new();
    if options.reject_outliers && (flags.any_view() || !flags.corners.is_empty()) {
        let keep_views: Vec<bool> = flags.view_outlier.clone();
        let n_keep = keep_views.iter().filter(|o| !**o).count();
        let drop_views = n_keep >= MIN_VIEWS;
        let bad_corner: std::collections::HashSet<usize> = flags.corners.iter().map(|c| c.obs).collect();
        bundle.obs.clear();
        for (oi, o) in all_obs.iter().copied().enumerate() {
            let view_out = drop_views && keep_views[o.view];
            if !view_out && !bad_corner.contains(&oi) {
                bundle.obs.push(o);
            }
        }
        if drop_views {
            for (k, out) in keep_views.iter().enumerate() {
                if *out {
                    removed_views.push(views[usable[k].0].name.clone());
                }
            }
        }
        let (r, it) = bundle.solve(options.max_iterations)?;
        report = r;
        iterations += it;
        // Report the final residuals of every view, but keep the first pass's flags.
        let used_obs = bundle.obs.clone();
        let over_used = flag_outliers(&bundle, &used_obs, options)?;
        let over_all = flag_outliers(&bundle, &all_obs, options)?;
        flags.view_rms = over_used
            .view_rms
            .iter()
            .zip(&over_all.view_rms)
            .map(|(u, a)| if u.is_finite() { *u } else { *a })
            .collect();
        flags.removed_obs = bad_corner;
        flags.dropped_views = drop_views;
    }
    let refined: Vec<Isometry3<f64>> = bundle.views.iter().map(|v| v.to_isometry()).collect();
    let max_angle = zhang::max_normal_angle_deg(&refined);
    if max_angle < MIN_BOARD_ANGLE_DEG {
        return Err(VisionError::DegenerateViews {
            detail: format!(
                "the {} boards are nearly parallel (largest angle between board normals {max_angle:.1} deg < \
                 {MIN_BOARD_ANGLE_DEG} deg), so focal length and distance cannot be told apart; tilt the board \
                 by 20 to 45 deg about different axes between views",
                refined.len()
            ),
        });
    }
    let m = layout.free_to_model();
    let mut warnings: Vec<String> = reasons.iter().map(|r| format!("view skipped: {r}")).collect();
    let mut method = options.covariance;
    let (cov_model, cov_independent, s0_px, normal_condition) = match bundle.global_covariance() {
        Ok(cov) => {
            let independent = &m * &cov.covariance * m.transpose();
            method = match options.covariance {
                CovarianceMethod::Auto if bundle.views.len() >= MIN_JACKKNIFE_VIEWS => CovarianceMethod::ViewJackknife,
                CovarianceMethod::Auto => {
                    warnings.push(format!(
                        "{} views: standard deviations with every corner independent, which is optimistic when \
                         corner errors correlate within a view; {MIN_JACKKNIFE_VIEWS} or more views give the \
                         leave-one-view-out jackknife",
                        bundle.views.len()
                    ));
                    CovarianceMethod::Independent
                }
                other => other,
            };
            let chosen = match method {
                CovarianceMethod::Independent | CovarianceMethod::Auto => independent.clone(),
                CovarianceMethod::ViewSandwich => &m * cov.view_sandwich() * m.transpose(),
                CovarianceMethod::ViewJackknife => {
                    &m * view_jackknife(&bundle, options.max_iterations)? * m.transpose()
                }
            };
            (chosen, independent, cov.s0_px, cov.condition)
        }
        Err(VisionError::DegenerateViews { detail }) => {
            warnings.push(format!(
                "no covariance: {detail} (the lens model has more coefficients than these views determine; \
                 standard deviations are reported as NaN)"
            ));
            let n = m.nrows();
            let nan = DMatrix::from_element(n, n, f64::NAN);
            (nan.clone(), nan, f64::NAN, f64::INFINITY)
        }
        Err(e) => return Err(e),
    };
    let camera = bundle.camera_model(0)?;
    camera.validate()?;
    let std_of = |c: &DMatrix<f64>| -> Vec<f64> {
        (0..c.nrows()).map(|i| if c[(i, i)].is_nan() { f64::NAN } else { c[(i, i)].max(0.0).sqrt() }).collect()
    };
    let std = std_of(&cov_model);
    let std_independent = std_of(&cov_independent);

    // Reports.
    let all_res = bundle.residuals()?;
    let (mut sq, mut n_used) = (0.0, 0usize);
    for r in all_res.iter().flatten() {
        sq += r.norm_squared();
        n_used += 1;
    }
    let rms_px = if n_used > 0 { (sq / n_used as f64).sqrt() } else { 0.0 };
    let mut reports: Vec<ViewReport> = Vec::with_capacity(views.len());
    let k_of = |i: usize| usable.iter().position(|(j, _)| *j == i);
    for (i, v) in views.iter().enumerate() {
        match k_of(i) {
            Some(k) => {
                let t = bundle.views[k].to_isometry();
                let rms = flags.view_rms[k];
                let used = !(flags.dropped_views && flags.view_outlier[k]);
                let n_out = flags.corners.iter().filter(|c| c.view == k).count();
                reports.push(ViewReport {
                    name: v.name.clone(),
                    rms_px: rms,
                    n_corners: v.corners_px.len(),
                    outlier: flags.view_outlier[k],
                    used,
                    n_outlier_corners: n_out,
                    t_cam_target: t,
                });
            }
            None => reports.push(ViewReport {
                name: v.name.clone(),
                rms_px: f64::NAN,
                n_corners: v.corners_px.len(),
                outlier: false,
                used: false,
                n_outlier_corners: 0,
                t_cam_target: Isometry3::identity(),
            }),
        }
    }
    let outlier_corners = flags
        .corners
        .iter()
        .map(|c| CornerOutlier {
            view: views[usable[c.view].0].name.clone(),
            point_id: c.point_id,
            residual_px: c.residual_px,
            removed: flags.removed_obs.contains(&c.obs),
        })
        .collect();
    for r in reports.iter().filter(|r| r.outlier) {
        warnings.push(format!(
            "outlier view {}: RMS {:.3} px > {} x median {:.3} px{}",
            r.name,
            r.rms_px,
            options.outlier_view_factor,
            flags.median_rms,
            if r.used { "" } else { " (removed)" }
        ));
    }
    if z.fallback {
        warnings.push(
            "Zhang's closed form gave an implausible camera (strong distortion?); started from a centred principal point"
                .into(),
        );
    }
    for (name, i) in [("fx", 0), ("fy", 1)] {
        if std[i] > 0.05 * camera.parameters()[i].value {
            warnings.push(format!(
                "{name} is poorly determined ({:.1} % standard deviation): add tilted views",
                100.0 * std[i] / camera.parameters()[i].value
            ));
        }
    }
    Ok(CameraCalibration {
        camera,
        std,
        covariance: cov_model,
        rms_px,
        views: reports,
        outlier_corners,
        summary: CalibrationSummary {
            initial,
            zhang_condition: z.condition,
            zhang_fallback: z.fallback,
            max_board_angle_deg: max_angle,
            normal_condition,
            s0_px,
            covariance_method: method,
            std_independent,
            n_corners: n_used,
            removed_views,
            iterations,
            solver_report: report,
            warnings,
        },
    })
}

/// The leave-one-view-out jackknife covariance of the bundle's free camera parameters (one
/// camera): the adjustment re-solved without each view in turn, started from the solution
/// (at most 30 iterations each), `(G - 1) / G sum_v (p_v - mean)(p_v - mean)^T`.
fn view_jackknife(bundle: &Bundle, max_iterations: usize) -> Result<DMatrix<f64>> {
    let nv = bundle.views.len();
    let active: Vec<usize> = (0..nv).filter(|&v| bundle.obs.iter().any(|o| o.view == v)).collect();
    let g = active.len();
    if g < MIN_VIEWS + 1 {
        return Err(VisionError::TooFewViews {
            usable: g,
            needed: MIN_VIEWS + 1,
            detail: "the jackknife covariance leaves one view out and needs a calibration from the rest".into(),
        });
    }
    let mut estimates: Vec<DVector<f64>> = Vec::with_capacity(g);
    for &left_out in &active {
        let mut b = bundle.clone();
        b.views.remove(left_out);
        b.obs.retain(|o| o.view != left_out);
        for o in &mut b.obs {
            if o.view > left_out {
                o.view -= 1;
            }
        }
        b.solve(max_iterations.min(30))?;
        estimates.push(DVector::from_column_slice(&b.cameras[0]));
    }
    let n = estimates[0].len();
    let mean = estimates.iter().fold(DVector::zeros(n), |a, e| a + e) / g as f64;
    let mut cov = DMatrix::zeros(n, n);
    for e in &estimates {
        let d = e - &mean;
        cov += &d * d.transpose();
    }
    Ok(cov * ((g as f64 - 1.0) / g as f64))
}

/// A calibration from a pattern's views ([`calibrate_pattern`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PatternCalibration {
    /// The camera.
    pub calibration: CameraCalibration,
    /// Circle grids: what the perspective-bias correction did.
    pub circle_bias: Option<circles::CircleBiasReport>,
}

/// Calibrates one camera from views of `pattern`: [`calibrate_camera`] on the pattern's target,
/// and for circle grids with the dots' radii known (`circle_radii_m`, `[small, large]` metres,
/// as [`corners::detect_pattern_views`] measures them) the perspective bias of the centres
/// corrected ([`circles::calibrate_circle_grid`]).
pub fn calibrate_pattern(
    views: &[View],
    pattern: &CalibrationPattern,
    circle_radii_m: Option<[f64; 2]>,
    options: &CalibrationOptions,
) -> Result<PatternCalibration> {
    match (pattern, circle_radii_m) {
        (CalibrationPattern::CircleGrid(g), Some(r)) => {
            let (calibration, bias) = circles::calibrate_circle_grid(views, g, r, options)?;
            Ok(PatternCalibration { calibration, circle_bias: Some(bias) })
        }
        _ => {
            let mut calibration = calibrate_camera(views, &pattern.target(), options)?;
            if matches!(pattern, CalibrationPattern::CircleGrid(_)) {
                calibration
                    .summary
                    .warnings
                    .push("the dots' radii are unknown: centres not corrected for the perspective bias".into());
            }
            Ok(PatternCalibration { calibration, circle_bias: None })
        }
    }
}
