//! The chain figures: per-image chain reprojection RMS with the robot poses as reported, the
//! training and held-out RMS, and the chain's camera-to-target pose against each image's PnP
//! pose (the acceptance measure of ROS-Industrial's industrial_calibration). One function
//! computes them for every estimate, ours and OpenCV's.

use nalgebra::{Isometry3, Point3, Vector2};
use serde::{Deserialize, Serialize};

use ferrocal_vision::camera::CameraModel;

use super::{HandEyeView, Mount};
use crate::measurement::Split;

/// An estimate of the chain's unknowns.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Chain {
    /// `X`, the hand-eye transform.
    pub x: Isometry3<f64>,
    /// `W`, the world transform.
    pub w: Isometry3<f64>,
    /// The target's print scale (1 when not fitted).
    pub scale: f64,
}

/// The chain reprojection errors `projected - detected` (pixels) of one image's corners;
/// `None` for a corner that does not project (behind the camera).
pub fn chain_residuals_px(
    mount: Mount,
    camera: &CameraModel,
    target_points_m: &[Point3<f64>],
    view: &HandEyeView,
    chain: &Chain,
) -> Vec<Option<Vector2<f64>>> {
    let t = mount.t_camera_target(&chain.x, &chain.w, &view.t_base_flange);
    let scale = chain.scale;
    view.point_ids
        .iter()
        .zip(&view.corners_px)
        .map(|(&id, px)| {
            let p = t * Point3::from(target_points_m[id].coords * scale);
            camera.project(&p).ok().map(|q| q - px)
        })
        .collect()
}

/// One image's chain figures.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ViewFigures {
    /// The image's name.
    pub name: String,
    /// Its split.
    pub split: Split,
    /// Corners.
    pub n_corners: usize,
    /// Chain reprojection RMS (length of the 2D error), pixels; corners that do not project
    /// count as missing (see `n_unprojected`).
    pub rms_px: f64,
    /// Corners that did not project.
    pub n_unprojected: usize,
    /// Distance between the chain's and PnP's target origin in the camera frame, mm (`None`
    /// without a PnP pose).
    pub pnp_position_mm: Option<f64>,
    /// Angle between the chain's and PnP's target orientation, degrees.
    pub pnp_rotation_deg: Option<f64>,
}

/// The chain figures of one estimate.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ChainFigures {
    /// Per image, in input order.
    pub views: Vec<ViewFigures>,
    /// RMS over every training corner, pixels.
    pub train_rms_px: f64,
    /// RMS over every test corner, pixels (`None` without test images).
    pub heldout_rms_px: Option<f64>,
    /// Mean PnP position difference over the training images, mm.
    pub train_pnp_position_mm: Option<f64>,
    /// Mean PnP orientation difference over the training images, degrees.
    pub train_pnp_rotation_deg: Option<f64>,
    /// Mean PnP position difference over the test images, mm.
    pub heldout_pnp_position_mm: Option<f64>,
    /// Mean PnP orientation difference over the test images, degrees.
    pub heldout_pnp_rotation_deg: Option<f64>,
    /// The print scale of the target geometry the PnP poses were computed with: the chain's
    /// own (`Chain::scale`), so that both sides of the agreement use the same target.
    pub pnp_target_scale: f64,
}

fn mean(v: &[f64]) -> Option<f64> {
    (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
}

/// The chain figures of `chain` with `camera` over `views`; `pnp[i]` is view `i`'s PnP
/// `T_camera_target`, when it has one, computed with the same target geometry the chain uses:
/// `target_points_m` scaled by `chain.scale` (see [`scaled_target`]). With the nominal spacing
/// and a fitted scale `s`, PnP would place the target at `1/s` times the chain's depth and the
/// agreement would measure the print-scale error instead of the chain's.
pub fn chain_figures(
    mount: Mount,
    camera: &CameraModel,
    target_points_m: &[Point3<f64>],
    views: &[HandEyeView],
    pnp: &[Option<Isometry3<f64>>],
    chain: &Chain,
) -> ChainFigures {
    let (x, w) = (&chain.x, &chain.w);
    let mut out = Vec::with_capacity(views.len());
    let mut sums = [(0.0, 0usize); 2];
    let mut pos: [Vec<f64>; 2] = [Vec::new(), Vec::new()];
    let mut rot: [Vec<f64>; 2] = [Vec::new(), Vec::new()];
    for (v, p) in views.iter().zip(pnp) {
        let r = chain_residuals_px(mount, camera, target_points_m, v, chain);
        let ok: Vec<f64> = r.iter().flatten().map(|e| e.norm_squared()).collect();
        let k = usize::from(v.split == Split::Test);
        sums[k].0 += ok.iter().sum::<f64>();
        sums[k].1 += ok.len();
        let (dp, dr) = match p {
            Some(pnp) => {
                let t = mount.t_camera_target(x, w, &v.t_base_flange);
                let dp = (t.translation.vector - pnp.translation.vector).norm() * 1e3;
                let dr = (t.rotation * pnp.rotation.inverse()).angle().to_degrees();
                pos[k].push(dp);
                rot[k].push(dr);
                (Some(dp), Some(dr))
            }
            None => (None, None),
        };
        out.push(ViewFigures {
            name: v.name.clone(),
            split: v.split,
            n_corners: r.len(),
            rms_px: if ok.is_empty() { f64::NAN } else { (ok.iter().sum::<f64>() / ok.len() as f64).sqrt() },
            n_unprojected: r.len() - ok.len(),
            pnp_position_mm: dp,
            pnp_rotation_deg: dr,
        });
    }
    let rms = |(s, n): (f64, usize)| (n > 0).then(|| (s / n as f64).sqrt());
    ChainFigures {
        views: out,
        train_rms_px: rms(sums[0]).unwrap_or(f64::NAN),
        heldout_rms_px: rms(sums[1]),
        train_pnp_position_mm: mean(&pos[0]),
        train_pnp_rotation_deg: mean(&rot[0]),
        heldout_pnp_position_mm: mean(&pos[1]),
        heldout_pnp_rotation_deg: mean(&rot[1]),
        pnp_target_scale: chain.scale,
    }
}

/// The target's points at print scale `scale` (metres): the geometry a chain with that scale
/// predicts through, and the one its PnP yardstick must use.
pub fn scaled_target(target_points_m: &[Point3<f64>], scale: f64) -> Vec<Point3<f64>> {
    target_points_m.iter().map(|p| Point3::from(p.coords * scale)).collect()
}
