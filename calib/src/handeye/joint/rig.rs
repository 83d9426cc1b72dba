//! The joint adjustment with a rig of cameras: two or more fixed cameras watching a target on
//! the flange (eye-to-hand), or two or more cameras on the flange watching a fixed target
//! (eye-in-hand, a stereo head), in one least-squares problem in pixels.
//!
//! # Model
//! Camera 0 is the reference: its chain is the one of the module [`super`] (`W`, `X`, the
//! robot's parameters, its own intrinsics). Every further camera `k` adds two blocks: its own
//! camera model (intrinsics and lens distortion) and `T_camk_cam0`, the transform from the
//! reference camera's frame into its own (the `Se3` manifold). A corner of camera `k` is the
//! reference chain's point carried into camera `k`:
//!
//! ```text
//! p_camk = T_camk_cam0 · p_cam0      (p_cam0 from the module [`super`]'s chain)
//! ```
//!
//! through the same corner residual as camera 0's (`RobotCorner`, with the fifth block). Every
//! corner of every camera's training images is one whitened pixel residual; the robot
//! parameters are selected as in the single-camera adjustment, on the training images of all
//! cameras. With one camera the problem is exactly the single-camera one
//! ([`super::calibrate_joint`]: same blocks, names, residuals and numbers).
//!
//! # Start
//! Every camera's hand-eye calibration with the nominal robot ([`super::calibrate_hand_eye`],
//! the same options as the single-camera adjustment): `X`, `W` and the camera of camera 0, each
//! further camera's camera, and `T_camk_cam0 = W_k^-1 W_0` (eye-to-hand; `W = T_base_camera`)
//! or `X_k^-1 X_0` (eye-in-hand; `X = T_flange_camera`).
//!
//! # Output
//! The reference camera's result is a [`JointCalibration`] (the robot, its covariance with every
//! other block marginalised, camera 0, `X`, `W`, camera 0's figures); each further camera comes
//! with its camera, `T_camk_cam0` with its covariance and its own chain figures.

use nalgebra::Isometry3;
use serde::Serialize;

use ferrocal_robot::RobotModel;
use ferrocal_vision::camera::CameraModel;

use super::{adjust, check_joints, with_nominal_poses, CamInput, JointCalibration, JointOptions};
use crate::error::{CalibError, Result};
use crate::handeye::{calibrate_hand_eye, ChainFigures, HandEyeData, HandEyeResult, Mount, TransformEstimate};

/// A further camera of a rig (camera `k >= 1`) after the joint adjustment.
#[derive(Clone, Debug, Serialize)]
pub struct RigCamera {
    /// The camera.
    pub camera: CameraModel,
    /// Standard deviations of its parameters (the order of [`CameraModel::parameters`]).
    pub camera_std: Vec<f64>,
    /// `T_camk_cam0` (reference camera's frame into this camera's) with its covariance over
    /// `[t (m), r (rad)]`, the rotation error on the left.
    pub t_cam_cam0: TransformEstimate,
    /// Chain figures of this camera's images with the calibrated robot.
    pub figures: ChainFigures,
    /// This camera's hand-eye calibration with the nominal robot (the start).
    pub start: HandEyeResult,
}

/// The result of [`calibrate_joint_rig`].
#[derive(Clone, Debug, Serialize)]
pub struct RigJointCalibration {
    /// The robot, camera 0 (the reference), `X`, `W` (of camera 0) and camera 0's figures, as
    /// the single-camera adjustment reports them; `s0`, iterations and the termination are the
    /// whole problem's.
    pub reference: JointCalibration,
    /// Cameras 1, 2, ...
    pub cameras: Vec<RigCamera>,
}

/// The joint adjustment of a rig: `data[k]` is camera `k`'s recording (camera 0 the
/// reference; every camera the same mount and target), `joints[k]` the joint readings of its
/// views (one per view, model order; the views' `t_base_flange` are not used). See the module
/// documentation for the method.
///
/// Errors: [`CalibError::Data`] for no camera, mixed mounts, readings that do not match the
/// views or the model, or options with effects; those of [`calibrate_hand_eye`] for any
/// camera's start; [`CalibError::Numeric`] when the solve or the covariance fails.
pub fn calibrate_joint_rig(
    model: &RobotModel,
    data: &[HandEyeData],
    joints: &[Vec<Vec<f64>>],
    options: &JointOptions,
) -> Result<RigJointCalibration> {
    check_rig(model, data, joints)?;
    if !options.kinematic.effects.is_empty() {
        return Err(CalibError::Data("the joint adjustment does not model effects".into()));
    }
    let mut starts = Vec::with_capacity(data.len());
    for (k, (d, q)) in data.iter().zip(joints).enumerate() {
        let nominal = with_nominal_poses(model, d, q)?;
        let start = calibrate_hand_eye(&nominal, &options.hand_eye).map_err(|e| in_camera(k, e))?;
        starts.push(start);
    }
    calibrate_joint_rig_from(model, data, joints, starts, options)
}

fn in_camera(k: usize, e: CalibError) -> CalibError {
    match e {
        CalibError::Data(m) => CalibError::Data(format!("camera {k}: {m}")),
        CalibError::TooFew(m) => CalibError::TooFew(format!("camera {k}: {m}")),
        other => other,
    }
}

fn check_rig(model: &RobotModel, data: &[HandEyeData], joints: &[Vec<Vec<f64>>]) -> Result<()> {
    if data.is_empty() {
        return Err(CalibError::Data("a rig needs at least one camera".into()));
    }
    if data.len() != joints.len() {
        return Err(CalibError::Data(format!("{} cameras but joint readings for {}", data.len(), joints.len())));
    }
    if let Some(k) = data.iter().position(|d| d.mount != data[0].mount) {
        return Err(CalibError::Data(format!(
            "camera {k} is {}, camera 0 {}: a rig has one mount",
            data[k].mount.name(),
            data[0].mount.name()
        )));
    }
    for (k, (d, q)) in data.iter().zip(joints).enumerate() {
        check_joints(model, d, q).map_err(|e| in_camera(k, e))?;
    }
    Ok(())
}

/// `T_camk_cam0` from two cameras' hand-eye starts (see the module documentation).
pub fn rig_transform_from_starts(mount: Mount, start0: &HandEyeResult, start_k: &HandEyeResult) -> Isometry3<f64> {
    match mount {
        Mount::EyeToHand => start_k.world.transform.inverse() * start0.world.transform,
        Mount::EyeInHand => start_k.hand_eye.transform.inverse() * start0.hand_eye.transform,
    }
}

/// [`calibrate_joint_rig`] from given hand-eye starts (one per camera, as
/// [`calibrate_hand_eye`] gives them for the nominal robot's flange poses). Camera 0's start
/// fixes the gauge as in [`super::calibrate_joint_from`].
pub fn calibrate_joint_rig_from(
    model: &RobotModel,
    data: &[HandEyeData],
    joints: &[Vec<Vec<f64>>],
    starts: Vec<HandEyeResult>,
    options: &JointOptions,
) -> Result<RigJointCalibration> {
    let transforms = vec![None; starts.len().saturating_sub(1)];
    calibrate_joint_rig_with(model, data, joints, starts, &transforms, options)
}

/// [`calibrate_joint_rig_from`] with given starts of the rig transforms: `t_cam_cam0[k - 1]`,
/// when `Some`, is camera `k`'s `T_camk_cam0` start (a rig file's `R`, `T`, say) instead of the
/// one combined from the hand-eye starts ([`rig_transform_from_starts`]). One entry per further
/// camera.
pub fn calibrate_joint_rig_with(
    model: &RobotModel,
    data: &[HandEyeData],
    joints: &[Vec<Vec<f64>>],
    starts: Vec<HandEyeResult>,
    t_cam_cam0: &[Option<Isometry3<f64>>],
    options: &JointOptions,
) -> Result<RigJointCalibration> {
    check_rig(model, data, joints)?;
    if starts.len() != data.len() {
        return Err(CalibError::Data(format!("{} starts for {} cameras", starts.len(), data.len())));
    }
    if t_cam_cam0.len() + 1 != data.len() {
        return Err(CalibError::Data(format!(
            "{} rig transform starts for {} further cameras",
            t_cam_cam0.len(),
            data.len() - 1
        )));
    }
    let mount = data[0].mount;
    let others0: Vec<(CameraModel, Isometry3<f64>)> = starts[1..]
        .iter()
        .zip(t_cam_cam0)
        .map(|(s, given)| (s.camera, given.unwrap_or_else(|| rig_transform_from_starts(mount, &starts[0], s))))
        .collect();
    let cams: Vec<CamInput> = data.iter().zip(joints).map(|(data, joints)| CamInput { data, joints }).collect();
    let mut starts = starts.into_iter();
    let start0 = starts.next().expect("checked: at least one camera");
    let (reference, others) = adjust(model, &cams, start0, &others0, options)?;
    let cameras = others
        .into_iter()
        .zip(starts)
        .map(|(o, start)| RigCamera {
            camera: o.camera,
            camera_std: o.camera_std,
            t_cam_cam0: o.t_cam_cam0,
            figures: o.figures,
            start,
        })
        .collect();
    Ok(RigJointCalibration { reference, cameras })
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use nalgebra::{Isometry3, Matrix2, Point2, Point3, Vector3};

    use ferrocal_lsq::check::check_residual;
    use ferrocal_lsq::{Euclidean, Manifold, Se3};
    use ferrocal_robot::Parameterized;
    use ferrocal_vision::camera::{CameraModel, Distortion, ImageSize, Intrinsics};

    use super::super::corner::RobotCorner;
    use super::super::maps::{FrameMap, RobotMap};
    use crate::frames::exp6;
    use crate::handeye::residual::whitening;
    use crate::handeye::Mount;

    /// The corner of a further camera (robot block, both frame increments, the camera and
    /// `T_camk_cam0` off the identity) agrees with central differences through the manifolds,
    /// both mounts.
    #[test]
    fn rig_corner_passes_the_gradient_check() {
        let model = ferrocal_robot::presets::preset("ur5").unwrap();
        let params = model.parameters();
        let model_cols: Vec<(usize, usize)> = params
            .iter()
            .enumerate()
            .filter(|(_, p)| p.name.starts_with("joint3.corr_"))
            .map(|(i, _)| i)
            .enumerate()
            .collect();
        let n_m = model_cols.len();
        let map = Arc::new(RobotMap { model: model.clone(), model_cols, offset_cols: vec![(n_m, 1)], n: n_m + 1 });
        let mut v: Vec<f64> = (0..n_m).map(|k| 1e-3 * ((k as f64) * 0.9).sin()).collect();
        v.push(0.003);
        let camera = CameraModel::new(
            Intrinsics { fx_px: 1500.0, fy_px: 1498.0, cx_px: 1020.0, cy_px: 770.0 },
            Distortion::Brown5 { k1: -0.05, k2: 0.02, p1: 0.0002, p2: 0.0001, k3: 0.0 },
            ImageSize { width_px: 2048, height_px: 1536 },
        )
        .unwrap();
        let q = vec![0.2, -1.2, 1.3, -0.5, 1.0, 0.3];
        let (fk, _) = map.pose_jacobian(&v, &q).unwrap();
        // Camera k 0.4 m beside camera 0, turned 20 degrees towards it.
        let t_k0 = Isometry3::new(Vector3::new(-0.4, 0.02, 0.05), Vector3::new(0.01, 0.35, -0.02));
        let t_camk_target = Isometry3::new(Vector3::new(0.03, -0.02, 1.5), Vector3::new(0.1, 2.9, 0.2));
        let t_cam0_target = t_k0.inverse() * t_camk_target;
        for mount in [Mount::EyeInHand, Mount::EyeToHand] {
            let x = Isometry3::new(Vector3::new(0.03, 0.01, 0.09), Vector3::new(0.1, -1.4, 0.3));
            let w = match mount {
                Mount::EyeInHand => fk * x * t_cam0_target,
                Mount::EyeToHand => fk * x * t_cam0_target.inverse(),
            };
            let f = vec![0.001, -0.002, 0.002, 0.02, -0.01, 0.01];
            let t = vec![-0.002, 0.001, 0.001, -0.01, 0.01, 0.02];
            let frames = Arc::new(FrameMap {
                f0: exp6(&f).inverse() * w.inverse(),
                x0: x * exp6(&t).inverse(),
                frame_free: (0..6).collect(),
                tool_free: (0..6).collect(),
            });
            let r = RobotCorner {
                map: map.clone(),
                frames,
                mount,
                q: q.clone(),
                point_m: Point3::new(0.06, 0.02, 0.0),
                detected_px: Point2::new(1000.0, 800.0),
                whiten: whitening(&Matrix2::new(0.04, 0.01, 0.01, 0.09)).unwrap(),
                camera,
            };
            let blocks: Vec<Vec<f64>> =
                vec![v.clone(), f, t, camera.parameter_values(), Se3::from_isometry(&t_k0).to_vec()];
            let views: Vec<&[f64]> = blocks.iter().map(|b| b.as_slice()).collect();
            let manifolds: Vec<Arc<dyn Manifold>> = vec![
                Arc::new(Euclidean { n: map.n }),
                Arc::new(Euclidean { n: 6 }),
                Arc::new(Euclidean { n: 6 }),
                Arc::new(Euclidean { n: 9 }),
                Arc::new(Se3),
            ];
            let scales = vec![
                vec![1e-4; map.n],
                vec![1e-3; 6],
                vec![1e-3; 6],
                vec![1.0, 1.0, 1.0, 1.0, 1e-3, 1e-3, 1e-4, 1e-4, 1e-3],
                vec![1e-3; 6],
            ];
            let report = check_residual(&r, &views, &manifolds, &scales, 1e-3).unwrap();
            report.assert_below(1e-5, &format!("{mount:?} rig corner")).unwrap();
            // The point really is in camera k: the residual of the exact projection is zero.
            let p0 = match mount {
                Mount::EyeToHand => w.inverse() * fk * x * Point3::new(0.06, 0.02, 0.0),
                Mount::EyeInHand => x.inverse() * fk.inverse() * w * Point3::new(0.06, 0.02, 0.0),
            };
            assert!((t_k0 * p0 - t_camk_target * Point3::new(0.06, 0.02, 0.0)).norm() < 1e-12);
        }
    }
}
