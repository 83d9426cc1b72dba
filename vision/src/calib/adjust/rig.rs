//! The bundle adjustment of a rig of cameras that see one target at the same time (a stereo
//! pair): the same solver as [`super::adjust_bundle`] over several cameras, with
//!
//! - each camera's lens model ([`RigBundleSpec::lenses`]), started from the given camera by
//!   [`crate::camera::Distortion::converted`];
//! - one rigid `T_cam_cam0` per camera `1..`;
//! - the target-shape and print-scale blocks ([`super::TargetShape`], [`super::PrintScale`]) shared by
//!   every camera and view (one physical target);
//! - one `T_cam0_target` per view (target pose), seen by any subset of the cameras;
//! - a mode that holds everything but the views' poses ([`BundleMode::PosesOnly`]: each view
//!   solved alone from the corners of every camera that saw it).
//!
//! The target's model and the identifiability of its print scale are those of the one-camera
//! adjustment (module [`super`]). Residuals are `projected - observed`, pixels.

use nalgebra::{Isometry3, Vector2};
use serde::{Deserialize, Serialize};

use super::super::bundle::{Bundle, CameraLayout, Obs};
use super::super::views::check_views;
use super::{start_pose, target_deformation, BundleMode, PrintScale, TargetShape};
use crate::calib::{PlanarTarget, RobustLoss, View};
use crate::camera::{CameraModel, DistortionKind};
use crate::error::{Result, VisionError};
use crate::pose::LocalPose;

/// The global part of a rig's bundle: the cameras, their placement and the target's departure
/// from nominal.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RigBundleModel {
    /// Every camera (camera 0 the reference).
    pub cameras: Vec<CameraModel>,
    /// `T_cam_cam0` of every camera (the first the identity), metres.
    pub t_cam_cam0: Vec<Isometry3<f64>>,
    /// The target's shape (zero: flat).
    pub shape: TargetShape,
    /// The printed spacing's errors (zero: as nominal).
    pub print_scale: PrintScale,
}

/// What [`adjust_rig`] estimates.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RigBundleSpec {
    /// Lens model to fit per camera (`None`, or a missing entry: the model camera's own).
    pub lenses: Vec<Option<DistortionKind>>,
    /// Estimate the target's shape (bowl, saddle, twist), one for all cameras.
    pub estimate_shape: bool,
    /// Estimate the print scale's `e_x` (`e_y` held), one for all cameras.
    pub estimate_print_scale: bool,
    /// Full adjustment or poses only.
    pub mode: BundleMode,
    /// Ceres iteration limit per solve (0: 200).
    pub max_iterations: usize,
    /// Compute the covariance of the free global parameters (full mode, poses marginalised).
    pub covariance: bool,
}

/// The result of [`adjust_rig`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RigBundleFit {
    /// The rig and target after the adjustment (held values where nothing was estimated).
    pub model: RigBundleModel,
    /// `T_cam0_target` of every view, metres.
    pub t_cam0_target: Vec<Isometry3<f64>>,
    /// Per view, per camera: `projected - observed` of every corner in the view's order, pixels
    /// (empty where the camera did not see the view).
    pub residuals_px: Vec<Vec<Vec<Vector2<f64>>>>,
    /// RMS reprojection error over all cameras' corners, pixels.
    pub rms_px: f64,
    /// Names of the free global parameters (full mode): `cam<k>.<camera parameter>`, then
    /// `t_cam<k>_cam0.{tx_m,ty_m,tz_m,rx_rad,ry_rad,rz_rad}`, then `bowl_sag_m saddle_sag_m
    /// twist_sag_m`, then `print_scale_x`.
    pub parameter_names: Vec<String>,
    /// Standard deviation of each free global parameter (NaN without a covariance).
    pub std: Vec<f64>,
    /// Why there is no covariance although one was asked for.
    pub covariance_note: Option<String>,
}

fn invalid(detail: String) -> VisionError {
    VisionError::InvalidInput { detail }
}

/// Adjusts the rig `model` (and the target poses) to `views[k][i]`, what camera `k` saw of
/// target pose `i` (`None`: not seen), as `spec` says. `poses` are starting `T_cam0_target`, one
/// per target pose; without them each pose starts from the closed-form pose of the first camera
/// that saw it. Every target pose must be seen by at least one camera, and every camera's corner
/// numbering must be that of the target (a reversed chessboard renumbered by the caller). Errors
/// name the view or camera at fault.
pub fn adjust_rig(
    views: &[Vec<Option<View>>],
    target: &PlanarTarget,
    model: &RigBundleModel,
    poses: Option<&[Isometry3<f64>]>,
    spec: &RigBundleSpec,
) -> Result<RigBundleFit> {
    let nc = model.cameras.len();
    if nc == 0 || views.len() != nc || model.t_cam_cam0.len() != nc {
        return Err(invalid(format!(
            "{} cameras, {} view lists and {} placements: give one of each per camera",
            nc,
            views.len(),
            model.t_cam_cam0.len()
        )));
    }
    let nv = views[0].len();
    if views.iter().any(|v| v.len() != nv) {
        return Err(invalid("every camera needs one entry per target pose".into()));
    }
    target.validate()?;
    let mut cameras = model.cameras.clone();
    for (k, cam) in cameras.iter_mut().enumerate() {
        cam.validate()?;
        let refs: Vec<&View> = views[k].iter().flatten().collect();
        if !refs.is_empty() {
            let size = check_views(&refs, target)?;
            if size != cam.image_size {
                return Err(invalid(format!(
                    "camera {k}: the views are {}x{} px, the camera {}x{} px",
                    size.width_px, size.height_px, cam.image_size.width_px, cam.image_size.height_px
                )));
            }
        }
        if let Some(Some(kind)) = spec.lenses.get(k) {
            cam.distortion = cam.distortion.converted(*kind);
        }
    }
    if let Some(i) = (0..nv).find(|&i| views.iter().all(|v| v[i].is_none())) {
        return Err(invalid(format!("target pose {i} is seen by no camera")));
    }
    if let Some(p) = poses {
        if p.len() != nv {
            return Err(invalid(format!("{} starting poses for {nv} target poses", p.len())));
        }
    }
    let full = spec.mode == BundleMode::Full;
    let estimate = (spec.estimate_shape, spec.estimate_print_scale);
    let deform = target_deformation(target, (model.shape, model.print_scale), estimate, full)?;
    let layouts: Vec<CameraLayout> = cameras
        .iter()
        .map(|c| CameraLayout { kind: c.distortion.kind(), fix_aspect: false, aspect: 1.0, image_size: c.image_size })
        .collect();
    let starts: Vec<Isometry3<f64>> = match poses {
        Some(p) => p.to_vec(),
        None => (0..nv)
            .map(|i| {
                let k = (0..nc).find(|&k| views[k][i].is_some()).expect("checked: seen by a camera");
                let v = views[k][i].as_ref().expect("checked");
                Ok(model.t_cam_cam0[k].inverse() * start_pose(&cameras[k], target, v)?)
            })
            .collect::<Result<_>>()?,
    };
    let max_iterations = if spec.max_iterations == 0 { 200 } else { spec.max_iterations };
    let groups: Vec<Vec<usize>> = if full { vec![(0..nv).collect()] } else { (0..nv).map(|i| vec![i]).collect() };
    let mut residuals_px: Vec<Vec<Vec<Vector2<f64>>>> = vec![vec![Vec::new(); nc]; nv];
    let mut t_cam0_target = starts.clone();
    let mut solved = None;
    for idx in &groups {
        let mut obs = Vec::new();
        for (j, &i) in idx.iter().enumerate() {
            for (k, cam_views) in views.iter().enumerate() {
                let Some(v) = &cam_views[i] else { continue };
                for (pid, px) in v.point_ids.iter().zip(&v.corners_px) {
                    obs.push(Obs { cam: k, view: j, point_id: *pid, point: target.points_m[*pid], pixel: *px });
                }
            }
        }
        let mut bundle = Bundle {
            layouts: layouts.clone(),
            cameras: layouts.iter().zip(&cameras).map(|(l, c)| l.free_from_model(c)).collect(),
            extrinsics: model.t_cam_cam0[1..].iter().map(LocalPose::from_isometry).collect(),
            views: idx.iter().map(|&i| LocalPose::from_isometry(&starts[i])).collect(),
            obs,
            loss: RobustLoss::None,
            deform,
            fixed_globals: !full,
        };
        bundle.solve(max_iterations).map_err(|e| match (e, idx.as_slice()) {
            (VisionError::SolverFailed { stage, detail }, [i]) => {
                VisionError::SolverFailed { stage, detail: format!("target pose {i}: {detail}") }
            }
            (e, _) => e,
        })?;
        let residuals = bundle.residuals()?;
        for (o, r) in bundle.obs.iter().zip(&residuals) {
            let i = idx[o.view];
            let r = r.ok_or_else(|| VisionError::SolverFailed {
                stage: "rig bundle adjustment".into(),
                detail: format!("target pose {i}, camera {}: point {} cannot be projected", o.cam, o.point_id),
            })?;
            residuals_px[i][o.cam].push(r);
        }
        for (j, &i) in idx.iter().enumerate() {
            t_cam0_target[i] = bundle.views[j].to_isometry();
        }
        solved = Some(bundle);
    }
    let bundle = solved.ok_or_else(|| invalid("no target poses were given".into()))?;
    let (sq, n) =
        residuals_px.iter().flatten().flatten().fold((0.0, 0usize), |(s, n), r| (s + r.norm_squared(), n + 1));
    let mut out_model = model.clone();
    if full {
        out_model.cameras = (0..nc).map(|k| bundle.camera_model(k)).collect::<Result<_>>()?;
        out_model.t_cam_cam0 =
            std::iter::once(Isometry3::identity()).chain(bundle.extrinsics.iter().map(|e| e.to_isometry())).collect();
        if let Some(d) = bundle.deform {
            out_model.shape = TargetShape { bowl_m: d.shape_m[0], saddle_m: d.shape_m[1], twist_m: d.shape_m[2] };
            out_model.print_scale = PrintScale { x: d.scale[0], y: d.scale[1] };
        }
    } else {
        out_model.cameras = cameras;
    }
    let mut parameter_names = Vec::new();
    if full {
        for (k, c) in out_model.cameras.iter().enumerate() {
            parameter_names.extend(c.parameters().iter().map(|p| format!("cam{k}.{}", p.name)));
        }
        for k in 1..nc {
            for a in ["tx_m", "ty_m", "tz_m", "rx_rad", "ry_rad", "rz_rad"] {
                parameter_names.push(format!("t_cam{k}_cam0.{a}"));
            }
        }
        if spec.estimate_shape {
            parameter_names.extend(["bowl_sag_m", "saddle_sag_m", "twist_sag_m"].map(String::from));
        }
        if spec.estimate_print_scale {
            parameter_names.push("print_scale_x".into());
        }
    }
    let mut std = vec![f64::NAN; parameter_names.len()];
    let mut covariance_note = None;
    if full && spec.covariance {
        match bundle.global_covariance() {
            Ok(c) => std = (0..c.covariance.nrows()).map(|i| c.covariance[(i, i)].max(0.0).sqrt()).collect(),
            Err(VisionError::DegenerateViews { detail }) | Err(VisionError::TooFewViews { detail, .. }) => {
                covariance_note = Some(detail)
            }
            Err(e) => return Err(e),
        }
    }
    Ok(RigBundleFit {
        model: out_model,
        t_cam0_target,
        residuals_px,
        rms_px: (sq / n.max(1) as f64).sqrt(),
        parameter_names,
        std,
        covariance_note,
    })
}
