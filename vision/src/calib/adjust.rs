//! The bundle adjustment of one camera and its target, open to callers that need more than a
//! calibration: the same solver as [`super::calibrate_camera`] (Ceres through the least-squares
//! layer, analytic Jacobians, Schur covariance), with
//!
//! - the lens model to fit ([`BundleSpec::lens`]: Brown5, Rational8, Kannala-Brandt, started
//!   from the given camera by [`crate::camera::Distortion::converted`]);
//! - an optional **target-shape** block shared by all views ([`TargetShape`]): the sags of a
//!   bowl, a saddle and a twist at the target's edge;
//! - an optional **print-scale** block ([`PrintScale`]): the printed spacing scaled by
//!   `(1 + e_x, 1 + e_y)` along the target's x and y axes;
//! - a mode that holds the camera, shape and print scale and refits only each view's pose
//!   ([`BundleMode::PosesOnly`], for views held out of a fit).
//!
//! # The target's model
//! With `(x0, y0)` the centroid of the target's nominal points (which must lie in the target's
//! `z = 0` plane when a shape or print scale is used), `(dx, dy)` a point's offset from it, `h`
//! the half-size (largest `|dx|` or `|dy|`), `u = dx / h`, `v = dy / h`, the camera sees the point
//!
//! ```text
//! (x0 + (1 + e_x) dx,  y0 + (1 + e_y) dy,  b (u^2 + v^2) + s (u^2 - v^2) + t u v)
//! ```
//!
//! **Identifiability of the print scale.** An overall scale of the target trades exactly with
//! the distance of every view, so images alone show only the ratio `(1 + e_x) / (1 + e_y)`. The
//! adjustment estimates `e_x` and holds `e_y` at [`PrintScale::y`] (zero unless the caller knows
//! it from elsewhere, e.g. metric robot or tracker poses): with `e_y = 0` the estimated `e_x` is
//! the printed x spacing relative to the y spacing (`e_x - e_y` to first order).
//!
//! # Conventions
//! Poses are `T_cam_target` of the target's own frame (metres). Residuals are `projected -
//! observed`, pixels. A pose covariance is over `[tx, ty, tz (m), rx, ry, rz (rad)]`, the
//! rotation a left increment in the camera frame (docs/conventions.md).

use nalgebra::{DMatrix, Isometry3, Matrix6, Vector2};
use serde::{Deserialize, Serialize};

mod rig;
pub use rig::{adjust_rig, RigBundleFit, RigBundleModel, RigBundleSpec};

use super::bundle::{loss_weight, Bundle, CameraLayout, Obs};
use super::deform::TargetDeformation;
use super::{check_views, PlanarTarget, RobustLoss, View};
use crate::camera::{CameraModel, DistortionKind};
use crate::error::{Result, VisionError};
use crate::pose::{estimate_pose, observe, CornerNoise, LocalPose};

/// A bent target: the out-of-plane sags at its edge, metres (see the module documentation).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TargetShape {
    /// Bowl, `b (u^2 + v^2)`.
    pub bowl_m: f64,
    /// Saddle, `s (u^2 - v^2)`.
    pub saddle_m: f64,
    /// Twist, `t u v`.
    pub twist_m: f64,
}

/// The target blocks of a bundle that starts from `model`'s shape and print scale: none when
/// the fit neither estimates (`estimate`: shape, print scale) nor holds a departure from the
/// nominal target; each block free only in a full fit that estimates it.
fn target_deformation(
    target: &PlanarTarget,
    model: (TargetShape, PrintScale),
    estimate: (bool, bool),
    full: bool,
) -> Result<Option<TargetDeformation>> {
    let shape = model.0.to_array();
    let scale = [model.1.x, model.1.y];
    if !(estimate.0 || estimate.1 || shape != [0.0; 3] || scale != [0.0; 2]) {
        return Ok(None);
    }
    let mut d = TargetDeformation::of_points(&target.points_m)?;
    d.shape_m = shape;
    d.scale = scale;
    d.shape_free = full && estimate.0;
    d.scale_free = full && estimate.1;
    Ok(Some(d))
}

impl TargetShape {
    fn to_array(self) -> [f64; 3] {
        [self.bowl_m, self.saddle_m, self.twist_m]
    }
    fn from_array(a: [f64; 3]) -> Self {
        Self { bowl_m: a[0], saddle_m: a[1], twist_m: a[2] }
    }
}

/// Relative errors of the printed pattern's spacing along the target's x and y axes
/// (dimensionless; `0.001` is 1000 ppm). Only `x` is ever estimated (see the module documentation).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PrintScale {
    /// `e_x`.
    pub x: f64,
    /// `e_y` (held).
    pub y: f64,
}

/// The global part of a one-camera bundle: the camera and the target's departure from nominal.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct BundleModel {
    /// The camera.
    pub camera: CameraModel,
    /// The target's shape (zero: flat).
    pub shape: TargetShape,
    /// The printed spacing's errors (zero: as nominal).
    pub print_scale: PrintScale,
}

impl BundleModel {
    /// A camera with a flat, nominally printed target.
    pub fn new(camera: CameraModel) -> Self {
        Self { camera, shape: TargetShape::default(), print_scale: PrintScale::default() }
    }
}

/// Which blocks move.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BundleMode {
    /// The camera (and the target's blocks the spec names) with every view's pose.
    #[default]
    Full,
    /// Only each view's pose; the camera, shape and print scale are held at the model's values.
    /// Views are solved one by one, so a view's result does not depend on the others given.
    PosesOnly,
}

/// What [`adjust_bundle`] estimates.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BundleSpec {
    /// Lens model to fit (`None`: the model camera's own).
    pub lens: Option<DistortionKind>,
    /// Hold `fy / fx` at the model camera's ratio.
    pub fix_aspect: bool,
    /// Estimate the target's shape (bowl, saddle, twist).
    pub estimate_shape: bool,
    /// Estimate the print scale's `e_x` (`e_y` held).
    pub estimate_print_scale: bool,
    /// Full adjustment or poses only.
    pub mode: BundleMode,
    /// Robust loss.
    pub loss: RobustLoss,
    /// Ceres iteration limit per solve.
    pub max_iterations: usize,
    /// Compute the covariance: of the free global parameters (full mode, the poses
    /// marginalised) or of each view's pose (poses only).
    pub covariance: bool,
}

impl Default for BundleSpec {
    fn default() -> Self {
        Self {
            lens: None,
            fix_aspect: false,
            estimate_shape: false,
            estimate_print_scale: false,
            mode: BundleMode::Full,
            loss: RobustLoss::None,
            max_iterations: 200,
            covariance: false,
        }
    }
}

/// One view after the adjustment.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ViewFit {
    /// The view's name.
    pub name: String,
    /// `T_cam_target`, metres.
    pub t_cam_target: Isometry3<f64>,
    /// `projected - observed` of every corner, in the view's order, pixels.
    pub residuals_px: Vec<Vector2<f64>>,
    /// RMS of the corners' reprojection error lengths, pixels.
    pub rms_px: f64,
    /// Poses-only mode with [`BundleSpec::covariance`]: the pose's covariance over
    /// `[tx, ty, tz (m), rx, ry, rz (rad)]` given the held camera and target, scaled by the
    /// view's own `s0^2`.
    pub covariance: Option<Matrix6<f64>>,
}

/// The result of [`adjust_bundle`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BundleFit {
    /// The camera and target after the adjustment (held values where nothing was estimated).
    pub model: BundleModel,
    /// Every view, in input order.
    pub views: Vec<ViewFit>,
    /// RMS reprojection error over all corners, pixels.
    pub rms_px: f64,
    /// Names of the free global parameters (`fx_px ... k..`, or `f_px cx_px cy_px k..` with a
    /// fixed aspect, then `bowl_sag_m saddle_sag_m twist_sag_m`, then `print_scale_x`); empty in
    /// poses-only mode.
    pub parameter_names: Vec<String>,
    /// Covariance over [`BundleFit::parameter_names`] (full mode with
    /// [`BundleSpec::covariance`], when the views determine every parameter).
    pub covariance: Option<DMatrix<f64>>,
    /// Standard deviation of each free global parameter (NaN without a covariance).
    pub std: Vec<f64>,
    /// A-posteriori standard error of unit weight, pixels (NaN without a covariance).
    pub s0_px: f64,
    /// Why there is no covariance although one was asked for.
    pub covariance_note: Option<String>,
    /// Ceres iterations over all solves.
    pub iterations: usize,
    /// Ceres' brief report of the last solve.
    pub solver_report: String,
}

fn invalid(detail: String) -> VisionError {
    VisionError::InvalidInput { detail }
}

/// Adjusts `model` (and the views' poses) to the corners of `views` of `target` as `spec` says.
///
/// `poses` are starting `T_cam_target`, one per view; without them each view starts from the
/// closed-form pose of the model camera on the nominal target. Errors name the view that cannot
/// be placed or projected, and the input that is inconsistent.
pub fn adjust_bundle(
    views: &[View],
    target: &PlanarTarget,
    model: &BundleModel,
    poses: Option<&[Isometry3<f64>]>,
    spec: &BundleSpec,
) -> Result<BundleFit> {
    if spec.max_iterations == 0 {
        return Err(invalid("max_iterations must be at least 1".into()));
    }
    if let RobustLoss::Huber { scale_px } | RobustLoss::Cauchy { scale_px } = spec.loss {
        if !(scale_px.is_finite() && scale_px > 0.0) {
            return Err(invalid(format!("robust loss scale must be > 0, got {scale_px} px")));
        }
    }
    target.validate()?;
    let refs: Vec<&View> = views.iter().collect();
    let size = check_views(&refs, target)?;
    let mut camera = model.camera;
    camera.validate()?;
    if size != camera.image_size {
        return Err(invalid(format!(
            "the views are {}x{} px, the camera {}x{} px",
            size.width_px, size.height_px, camera.image_size.width_px, camera.image_size.height_px
        )));
    }
    if let Some(p) = poses {
        if p.len() != views.len() {
            return Err(invalid(format!("{} starting poses for {} views", p.len(), views.len())));
        }
    }
    if let Some(kind) = spec.lens {
        camera.distortion = camera.distortion.converted(kind);
    }
    let full = spec.mode == BundleMode::Full;
    let estimate = (spec.estimate_shape, spec.estimate_print_scale);
    let deform = target_deformation(target, (model.shape, model.print_scale), estimate, full)?;
    let aspect = if spec.fix_aspect { camera.intrinsics.fy_px / camera.intrinsics.fx_px } else { 1.0 };
    let layout = CameraLayout { kind: camera.distortion.kind(), fix_aspect: spec.fix_aspect, aspect, image_size: size };
    let starts: Vec<Isometry3<f64>> = match poses {
        Some(p) => p.to_vec(),
        None => views.iter().map(|v| start_pose(&camera, target, v)).collect::<Result<_>>()?,
    };
    let bundle_of = |idx: &[usize]| -> Bundle {
        let mut obs = Vec::new();
        for (k, &i) in idx.iter().enumerate() {
            let v = &views[i];
            for (pid, px) in v.point_ids.iter().zip(&v.corners_px) {
                obs.push(Obs { cam: 0, view: k, point_id: *pid, point: target.points_m[*pid], pixel: *px });
            }
        }
        Bundle {
            layouts: vec![layout],
            cameras: vec![layout.free_from_model(&camera)],
            extrinsics: Vec::new(),
            views: idx.iter().map(|&i| LocalPose::from_isometry(&starts[i])).collect(),
            obs,
            loss: spec.loss,
            deform,
            fixed_globals: !full,
        }
    };
    let groups: Vec<Vec<usize>> =
        if full { vec![(0..views.len()).collect()] } else { (0..views.len()).map(|i| vec![i]).collect() };
    let mut view_fits: Vec<Option<ViewFit>> = vec![None; views.len()];
    let (mut iterations, mut solver_report) = (0, String::new());
    let mut solved = None;
    for idx in &groups {
        let mut bundle = bundle_of(idx);
        let (report, it) = bundle.solve(spec.max_iterations).map_err(|e| name_views(e, idx, views))?;
        iterations += it;
        solver_report = report;
        let residuals = bundle.residuals()?;
        for (k, &i) in idx.iter().enumerate() {
            let mut r = Vec::with_capacity(views[i].corners_px.len());
            for (o, res) in bundle.obs.iter().zip(&residuals).filter(|(o, _)| o.view == k) {
                r.push(res.ok_or_else(|| VisionError::SolverFailed {
                    stage: "bundle adjustment".into(),
                    detail: format!(
                        "{}: target point {} cannot be projected at the solution",
                        views[i].name, o.point_id
                    ),
                })?);
            }
            let covariance =
                if spec.covariance && !full { Some(pose_covariance(&bundle, k, &views[i])?) } else { None };
            let rms_px = (r.iter().map(|v| v.norm_squared()).sum::<f64>() / r.len().max(1) as f64).sqrt();
            view_fits[i] = Some(ViewFit {
                name: views[i].name.clone(),
                t_cam_target: bundle.views[k].to_isometry(),
                residuals_px: r,
                rms_px,
                covariance,
            });
        }
        solved = Some(bundle);
    }
    let views_out: Vec<ViewFit> = view_fits.into_iter().map(|v| v.expect("every view solved")).collect();
    let (sq, n) =
        views_out.iter().flat_map(|v| &v.residuals_px).fold((0.0, 0usize), |(s, n), r| (s + r.norm_squared(), n + 1));
    let bundle = solved.ok_or_else(|| invalid("no views were given".into()))?;
    let camera_out = if full { bundle.camera_model(0)? } else { camera };
    let d_out = bundle.deform.unwrap_or(TargetDeformation {
        centre_m: [0.0; 2],
        half_m: 1.0,
        shape_m: model.shape.to_array(),
        scale: [model.print_scale.x, model.print_scale.y],
        shape_free: false,
        scale_free: false,
    });
    let mut parameter_names = Vec::new();
    if full {
        parameter_names = camera_out.parameters().iter().map(|p| p.name.to_string()).collect();
        if spec.fix_aspect {
            parameter_names.splice(0..2, ["f_px".to_string()]);
        }
        if spec.estimate_shape {
            parameter_names.extend(["bowl_sag_m", "saddle_sag_m", "twist_sag_m"].map(String::from));
        }
        if spec.estimate_print_scale {
            parameter_names.push("print_scale_x".into());
        }
    }
    let (mut covariance, mut s0_px, mut covariance_note) = (None, f64::NAN, None);
    if full && spec.covariance {
        match bundle.global_covariance() {
            Ok(c) => {
                s0_px = c.s0_px;
                covariance = Some(c.covariance);
            }
            Err(VisionError::DegenerateViews { detail }) | Err(VisionError::TooFewViews { detail, .. }) => {
                covariance_note = Some(detail)
            }
            Err(e) => return Err(e),
        }
    }
    let std = match &covariance {
        Some(c) => (0..c.nrows()).map(|i| c[(i, i)].max(0.0).sqrt()).collect(),
        None => vec![f64::NAN; parameter_names.len()],
    };
    Ok(BundleFit {
        model: BundleModel {
            camera: camera_out,
            shape: TargetShape::from_array(d_out.shape_m),
            print_scale: PrintScale { x: d_out.scale[0], y: d_out.scale[1] },
        },
        views: views_out,
        rms_px: (sq / n.max(1) as f64).sqrt(),
        parameter_names,
        covariance,
        std,
        s0_px,
        covariance_note,
        iterations,
        solver_report,
    })
}

/// The closed-form pose of a view on the nominal (flat) target.
fn start_pose(camera: &CameraModel, target: &PlanarTarget, view: &View) -> Result<Isometry3<f64>> {
    estimate_pose(
        camera,
        &target.points_m,
        &view.point_ids,
        &view.corners_px,
        &CornerNoise::Isotropic { sigma_px: 1.0 },
    )
    .map(|e| e.t_cam_target)
    .map_err(|e| VisionError::DegenerateViews { detail: format!("{}: no starting pose: {e}", view.name) })
}

/// A solver failure of a one-view problem names the view.
fn name_views(e: VisionError, idx: &[usize], views: &[View]) -> VisionError {
    match (e, idx) {
        (VisionError::SolverFailed { stage, detail }, [i]) => {
            VisionError::SolverFailed { stage, detail: format!("{}: {detail}", views[*i].name) }
        }
        (e, _) => e,
    }
}

/// `s0^2 (J^T W J)^-1` of view `k`'s pose with everything else held (the solver's pose block
/// is already `[t, r]`).
fn pose_covariance(bundle: &Bundle, k: usize, view: &View) -> Result<Matrix6<f64>> {
    let camera = bundle.camera_model(0)?;
    let (mut n, mut sum_wr2, mut m) = (Matrix6::zeros(), 0.0, 0usize);
    for o in bundle.obs.iter().filter(|o| o.view == k) {
        let point = bundle.deform.map_or(o.point, |d| d.point(&o.point));
        let ob = observe(&camera, None, &bundle.views[k], &point, &o.pixel)?;
        let s = ob.residual.norm_squared();
        let w = loss_weight(bundle.loss, s);
        n += w * ob.d_view.transpose() * ob.d_view;
        sum_wr2 += w * s;
        m += 2;
    }
    let inv = n.try_inverse().filter(|_| m > 6).ok_or_else(|| VisionError::DegenerateViews {
        detail: format!("{}: its corners do not determine its pose", view.name),
    })?;
    Ok(inv * (sum_wr2 / (m - 6) as f64))
}
