//! The joint adjustment's corner residual: one detected corner predicted through the robot's
//! kinematics, the chain of [`crate::handeye::residual`] and the camera model.
//!
//! [`RobotCorner`] is a corner of the reference camera (camera 0); [`RigCorner`] is the same
//! residual for a corner of a further camera `k` of a rig, with one more block, `T_camk_cam0`
//! (the `Se3` manifold): the reference camera's point is carried into camera `k`
//! (`p_k = T_k0 · p_0`, [`crate::handeye::residual::ChainPoint`]) before the projection. Both
//! run the same code ([`RobotCorner::evaluate_in`]).

use std::sync::Arc;

use nalgebra::{DMatrix, Matrix2, Point2, Point3};

use ferrocal_lsq::{LsqError, Residual, Se3};
use ferrocal_robot::Kinematics;
use ferrocal_vision::camera::CameraModel;

use super::maps::{FrameMap, RobotMap};
use crate::handeye::residual::{camera_with, chain_point};
use crate::handeye::Mount;

/// One corner predicted through the robot's kinematics (see the module documentation). Blocks:
/// the robot coordinates (Euclidean), the device frame increment `f` and the tool increment `t`
/// ([`FrameMap`]), the camera (Euclidean).
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

impl RobotCorner {
    /// The residual and Jacobians; `rig`: the values of the `T_camk_cam0` block (the fifth
    /// block, whose Jacobian is `jacobians[4]`) when the corner is of a further camera.
    fn evaluate_in(
        &self,
        params: &[&[f64]],
        rig: Option<&[f64]>,
        residuals: &mut [f64],
        jacobians: Option<&mut [Option<DMatrix<f64>>]>,
    ) -> ferrocal_lsq::Result<()> {
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
        let proj = camera.project_with_jacobians(&Point3::from(c.p_cam)).map_err(LsqError::model)?;
        let r = self.whiten * (proj.pixel - self.detected_px);
        residuals[0] = r.x;
        residuals[1] = r.y;
        let Some(jacs) = jacobians else { return Ok(()) };
        let sp = self.whiten * proj.d_pixel_d_point;
        if let (Some(j), Some(jp)) = (&mut jacs[0], &j_pose) {
            let d = DMatrix::from_column_slice(2, 6, (sp * c.d_robot).as_slice()) * jp;
            j.copy_from(&d);
        }
        let fill = |j: &mut Option<DMatrix<f64>>, m: &[f64]| {
            if let Some(j) = j {
                j.copy_from_slice(m);
            }
        };
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
        fill(&mut jacs[3], (self.whiten * &proj.d_pixel_d_params).as_slice());
        if let Some(d) = d_rig {
            fill(&mut jacs[4], (sp * d).as_slice());
        }
        Ok(())
    }
}

impl Residual for RobotCorner {
    fn n_residuals(&self) -> usize {
        2
    }

    fn evaluate(
        &self,
        params: &[&[f64]],
        residuals: &mut [f64],
        jacobians: Option<&mut [Option<DMatrix<f64>>]>,
    ) -> ferrocal_lsq::Result<()> {
        self.evaluate_in(params, None, residuals, jacobians)
    }

    fn row_names(&self) -> Vec<String> {
        vec!["x".into(), "y".into()]
    }
}

/// A corner of a further camera `k` of a rig: [`RobotCorner`] with the camera `k`'s lens model
/// and a fifth block, `T_camk_cam0` (`Se3`; see the module documentation).
pub(super) struct RigCorner(pub(super) RobotCorner);

impl Residual for RigCorner {
    fn n_residuals(&self) -> usize {
        2
    }

    fn evaluate(
        &self,
        params: &[&[f64]],
        residuals: &mut [f64],
        jacobians: Option<&mut [Option<DMatrix<f64>>]>,
    ) -> ferrocal_lsq::Result<()> {
        self.0.evaluate_in(params, Some(params[4]), residuals, jacobians)
    }

    fn row_names(&self) -> Vec<String> {
        vec!["x".into(), "y".into()]
    }
}
