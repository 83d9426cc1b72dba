//! The view-level lack of fit of a joint calibration of robot and camera.
//!
//! The corners' noise is what the adjustment's covariance knows. Physics the robot model leaves
//! out (a link that bends, an eccentric gear) moves the whole target of a view by a few tens of
//! micrometres, below one corner's noise but not below a whole view's: each view's PnP pose
//! (63 corners through the calibrated camera) pins the target's position across the optical
//! axis to about that size. The chain's pose of each training view against its PnP pose, as χ²
//! in the PnP covariance, over its degrees of freedom (6 per view less the chain's free
//! parameters), is 1 when the model misses nothing the views can see; above 1, the parameters
//! are pulled by what it misses as they would be by noise that size, and the covariance that
//! `correct` carries to a landing is scaled by it (measured: the closed-loop study of
//! `datasets::sim::closed_loop`, where the truth bends and wobbles, and its rigid twin).

use nalgebra::{Isometry3, Point3, Vector6};

use ferrocal_vision::camera::CameraModel;
use ferrocal_vision::pose::{estimate_pose, CornerNoise};

use crate::handeye::evaluate::Chain;
use crate::handeye::{HandEyeView, Mount};
use crate::measurement::Split;

/// χ² per degree of freedom of the training views' chain poses against their PnP poses, and
/// the number of views it is over; `None` when fewer views than `n_params / 6 + 1` have a PnP
/// pose with an invertible covariance.
///
/// `views` carry the calibrated chain's flange poses (`t_base_flange`); `n_params` is the
/// number of the chain's free parameters (robot, device frame, tool).
pub(crate) fn view_lack_of_fit(
    mount: Mount,
    camera: &CameraModel,
    target_points_m: &[Point3<f64>],
    views: &[HandEyeView],
    chain: &Chain,
    fallback_px: f64,
    n_params: usize,
) -> Option<(f64, usize)> {
    let mut chi2 = 0.0;
    let mut n = 0usize;
    for v in views.iter().filter(|v| v.split == Split::Train) {
        let noise = CornerNoise::from_detected(&v.covariances_px2, fallback_px);
        let Ok(pnp) = estimate_pose(camera, target_points_m, &v.point_ids, &v.corners_px, &noise) else {
            continue;
        };
        let Some(info) = pnp.covariance.try_inverse() else {
            continue;
        };
        let t: Isometry3<f64> = mount.t_camera_target(&chain.x, &chain.w, &v.t_base_flange);
        let dp_mm = (t.translation.vector - pnp.t_cam_target.translation.vector) * 1e3;
        let dr = (t.rotation * pnp.t_cam_target.rotation.inverse()).scaled_axis();
        let d = Vector6::new(dp_mm.x, dp_mm.y, dp_mm.z, dr.x, dr.y, dr.z);
        chi2 += d.dot(&(info * d));
        n += 1;
    }
    let dof = (6 * n).checked_sub(n_params).filter(|&d| d > 0)?;
    Some((chi2 / dof as f64, n))
}
