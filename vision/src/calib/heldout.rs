//! Held-out reprojection: a calibrated camera judged on views that no fit has seen. Each
//! held-out view's target pose is estimated with the camera fixed (closed-form start, then
//! Gauss-Newton on the reprojection error, [`crate::pose::estimate_pose`]); what is left is the
//! part of the reprojection error that the camera model does not explain on new views (plus the
//! corner noise). A training RMS can be lowered by free parameters; this one cannot.

use serde::{Deserialize, Serialize};

use super::{PlanarTarget, View};
use crate::camera::CameraModel;
use crate::error::Result;
use crate::pose::{estimate_pose, CornerNoise};

/// One held-out view.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HeldOutView {
    /// The view's name (its image).
    pub name: String,
    /// Corners used.
    pub n_corners: usize,
    /// RMS length of the reprojection errors after the pose fit, pixels (`None` when the pose
    /// could not be estimated, with the reason in `error`).
    pub rms_px: Option<f64>,
    /// Why the pose could not be estimated.
    pub error: Option<String>,
}

/// Every held-out view and the RMS over all their corners.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HeldOut {
    /// Per view, in input order.
    pub views: Vec<HeldOutView>,
    /// RMS over every corner of the views whose pose was estimated, pixels (`None` without any).
    pub rms_px: Option<f64>,
}

/// The reprojection error of `camera` on `views` of `target`, the pose of every view fitted
/// with the camera held fixed (six parameters per view). A view whose pose fails is listed with
/// the reason, not fatal.
pub fn held_out_reprojection(camera: &CameraModel, target: &PlanarTarget, views: &[View]) -> Result<HeldOut> {
    let mut out = Vec::with_capacity(views.len());
    let (mut sum_sq, mut n) = (0.0, 0usize);
    for v in views {
        let noise = CornerNoise::Isotropic { sigma_px: 1.0 };
        match estimate_pose(camera, &target.points_m, &v.point_ids, &v.corners_px, &noise) {
            Ok(p) => {
                sum_sq += p.rms_px * p.rms_px * p.n_corners as f64;
                n += p.n_corners;
                out.push(HeldOutView {
                    name: v.name.clone(),
                    n_corners: p.n_corners,
                    rms_px: Some(p.rms_px),
                    error: None,
                });
            }
            Err(e) => out.push(HeldOutView {
                name: v.name.clone(),
                n_corners: v.corners_px.len(),
                rms_px: None,
                error: Some(e.to_string()),
            }),
        }
    }
    Ok(HeldOut { views: out, rms_px: (n > 0).then(|| (sum_sq / n as f64).sqrt()) })
}
