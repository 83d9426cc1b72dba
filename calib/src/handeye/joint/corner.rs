//! The joint adjustment's corner residual: one detected corner predicted through the robot's
//! kinematics, the chain of [`crate::handeye::residual`] and the camera model.
//!
//! [`RobotCorner`] is a corner of the reference camera (camera 0) or, given one more block,
//! `T_camk_cam0` (the `Se3` manifold), of a further camera `k` of a rig (with that camera's lens
//! model): the reference camera's point is carried into camera `k` (`p_k = T_k0 · p_0`,
//! [`crate::handeye::residual::ChainPoint`]) before the projection.

use std::sync::Arc;

use nalgebra::{DMatrix, Matrix2, Point2, Point3};

use ferrocal_lsq::{LsqError, Residual, Se3};
use ferrocal_robot::Kinematics;
use ferrocal_vision::camera::CameraModel;

use super::maps::{FrameMap, RobotMap};
use crate::handeye::residual::{camera_with, chain_point, fill, reproject};
use crate::handeye::Mount;

/// One corner predicted through the robot's kinematics (see the module documentation). Blocks:
/// the robot coordinates (Euclidean), the device frame increment `f` and the tool increment `t`
/// ([`FrameMap`]), the camera (Euclidean) and, for a corner of a further camera of a rig,
/// `T_camk_cam0` (`Se3`).
pub(super) struct RobotCorner {
    pub(super) map: Arc<RobotMap>,
    pub(super) frames: Arc<FrameMap>,
    pub(super) mount: Mount,
    pub(super) q: Vec<f64>,
    pub(super) point_m: Point3<f64>,
    pub(super) detected_px: Point2<f64>,
    pub(super) whiten: Matrix2<f64>,
    pub(super) camera: CameraModel,
}

impl Residual for RobotCorner {
    fn n_residuals(&self) -> usize {
        2
    }

    /// The residual and Jacobians; a fifth block (whose Jacobian is `jacobians[4]`) is
    /// `T_camk_cam0`, the corner then being of a further camera.
    fn evaluate(
        &self,
        params: &[&[f64]],
        residuals: &mut [f64],
        jacobians: Option<&mut [Option<DMatrix<f64>>]>,
    ) -> ferrocal_lsq::Result<()> {
        let rig = params.get(4);
        let (w, x) = self.frames.w_and_x(params[1], params[2]);
        let camera = camera_with(&self.camera, params[3])?;
        let want_robot = jacobians.as_ref().is_some_and(|j| j[0].is_some());
        let (t, j_pose) = if want_robot {
            let (t, j) = self.map.pose_jacobian(params[0], &self.q)?;
            (t, Some(j))
        } else {
            let (m, qq) = self.map.apply(params[0], &self.q)?;
            (m.forward(&qq).map_err(LsqError::model)?, None)
        };
        let mut c = chain_point(self.mount, &x, &w, &t, 1.0, &self.point_m);
        let d_rig = rig.map(|v| c.move_to_camera(&Se3::to_isometry(v)));
        let Some((jacs, sp)) = reproject(&camera, &c.p_cam, (&self.detected_px, &self.whiten), residuals, jacobians)?
        else {
            return Ok(());
        };
        if let (Some(j), Some(jp)) = (&mut jacs[0], &j_pose) {
            let d = DMatrix::from_column_slice(2, 6, (sp * c.d_robot).as_slice()) * jp;
            j.copy_from(&d);
        }
        let (m_w, m_x) = self.frames.jacobians(params[1], params[2]);
        let pick = |j: &mut Option<DMatrix<f64>>, full: nalgebra::Matrix2x6<f64>, free: &[usize]| {
            if let Some(j) = j {
                for (k, &i) in free.iter().enumerate() {
                    j[(0, k)] = full[(0, i)];
                    j[(1, k)] = full[(1, i)];
                }
            }
        };
        pick(&mut jacs[1], sp * c.d_w * m_w, &self.frames.frame_free);
        pick(&mut jacs[2], sp * c.d_x * m_x, &self.frames.tool_free);
        if let Some(d) = d_rig {
            fill(&mut jacs[4], (sp * d).as_slice());
        }
        Ok(())
    }

    fn row_names(&self) -> Vec<String> {
        vec!["x".into(), "y".into()]
    }
}
