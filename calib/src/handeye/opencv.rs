//! OpenCV's closed-form hand-eye calibrations as the baseline, on the same PnP poses of the same
//! corners and the same training images as ours, their chain figures computed by
//! [`super::evaluate::chain_figures`] like ours.
//!
//! - `calibrateHandEye` (Tsai, Park, Horaud, Andreff, Daniilidis) returns `X` only
//!   (eye-in-hand); for eye-to-hand the robot poses are inverted, as OpenCV documents, and it
//!   returns `W`. The other transform is the mean over the training images of what each image
//!   implies (chordal mean of rotations, mean of translations), as users of that function do.
//! - `calibrateRobotWorldHandEye` (Shah, Li) returns both; for eye-to-hand the robot poses are
//!   inverted the same way.
//!
//! OpenCV sees no pixels: its figures are those of its closed form, not refined.

use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};
use opencv::core::{Mat, Vector};
use opencv::prelude::*;
use serde::{Deserialize, Serialize};

use ferrocal_vision::camera::CameraModel;

use super::closed::average_transforms;
use super::evaluate::{chain_figures, Chain, ChainFigures};
use super::refine::{pnp_poses, training_pairs};
use super::{HandEyeData, HandEyeOptions, Mount};
use crate::error::{CalibError, Result};

/// One OpenCV method's result on the recording.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BaselineReport {
    /// `calibrateHandEye` or `calibrateRobotWorldHandEye`.
    pub function: String,
    /// The method flag's name, e.g. `CALIB_HAND_EYE_TSAI`.
    pub method: String,
    /// Its `X`, `W` (scale 1), when it ran.
    pub chain: Option<Chain>,
    /// Its chain figures with the same camera and corners.
    pub figures: Option<ChainFigures>,
    /// OpenCV's error, when it failed.
    pub error: Option<String>,
}

fn cv(e: opencv::Error) -> CalibError {
    CalibError::Numeric(format!("OpenCV: {e}"))
}

fn rotation_mat(t: &Isometry3<f64>) -> Result<Mat> {
    let r = t.rotation.to_rotation_matrix().into_inner();
    Mat::from_slice_2d(&[
        [r[(0, 0)], r[(0, 1)], r[(0, 2)]],
        [r[(1, 0)], r[(1, 1)], r[(1, 2)]],
        [r[(2, 0)], r[(2, 1)], r[(2, 2)]],
    ])
    .map_err(cv)
}

fn translation_mat(t: &Isometry3<f64>) -> Result<Mat> {
    let v = t.translation.vector;
    Mat::from_slice_2d(&[[v.x], [v.y], [v.z]]).map_err(cv)
}

fn to_isometry(r: &Mat, t: &Mat) -> Result<Isometry3<f64>> {
    let mut m = Matrix3::zeros();
    for i in 0..3 {
        for j in 0..3 {
            m[(i, j)] = *r.at_2d::<f64>(i as i32, j as i32).map_err(cv)?;
        }
    }
    let v = Vector3::new(*t.at::<f64>(0).map_err(cv)?, *t.at::<f64>(1).map_err(cv)?, *t.at::<f64>(2).map_err(cv)?);
    if !(m.iter().all(|x| x.is_finite()) && v.iter().all(|x| x.is_finite())) {
        return Err(CalibError::Numeric("OpenCV returned a non-finite transform".into()));
    }
    let r = super::closed::project_to_so3(&m);
    Ok(Isometry3::from_parts(Translation3::from(v), UnitQuaternion::from_rotation_matrix(&Rotation3::from(r))))
}

fn mats(ts: &[Isometry3<f64>]) -> Result<(Vector<Mat>, Vector<Mat>)> {
    let mut r = Vector::new();
    let mut t = Vector::new();
    for x in ts {
        r.push(rotation_mat(x)?);
        t.push(translation_mat(x)?);
    }
    Ok((r, t))
}

/// `calibrateHandEye` with one method flag; returns `(X, W)`.
fn hand_eye(
    mount: Mount,
    flange: &[Isometry3<f64>],
    cam_target: &[Isometry3<f64>],
    method: opencv::calib3d::HandEyeCalibrationMethod,
) -> Result<(Isometry3<f64>, Isometry3<f64>)> {
    let robot: Vec<Isometry3<f64>> = match mount {
        Mount::EyeInHand => flange.to_vec(),
        Mount::EyeToHand => flange.iter().map(Isometry3::inverse).collect(),
    };
    let (rg, tg) = mats(&robot)?;
    let (rt, tt) = mats(cam_target)?;
    let (mut r, mut t) = (Mat::default(), Mat::default());
    opencv::calib3d::calibrate_hand_eye(&rg, &tg, &rt, &tt, &mut r, &mut t, method).map_err(cv)?;
    let out = to_isometry(&r, &t)?;
    match mount {
        Mount::EyeInHand => {
            // out = T_flange_camera; W_i = T_base_flange X T_camera_target.
            let ws: Vec<_> = flange.iter().zip(cam_target).map(|(f, c)| f * out * c).collect();
            Ok((out, average_transforms(&ws)?))
        }
        Mount::EyeToHand => {
            // out = T_base_camera; X_i = T_base_flange^-1 W T_camera_target.
            let xs: Vec<_> = flange.iter().zip(cam_target).map(|(f, c)| f.inverse() * out * c).collect();
            Ok((average_transforms(&xs)?, out))
        }
    }
}

/// `calibrateRobotWorldHandEye` with one method flag; returns `(X, W)`.
fn robot_world(
    mount: Mount,
    flange: &[Isometry3<f64>],
    cam_target: &[Isometry3<f64>],
    method: opencv::calib3d::RobotWorldHandEyeCalibrationMethod,
) -> Result<(Isometry3<f64>, Isometry3<f64>)> {
    // OpenCV: T_cam_world_i T_world_base = T_cam_gripper T_gripper_base_i, world = the target.
    let robot: Vec<Isometry3<f64>> = match mount {
        Mount::EyeInHand => flange.iter().map(Isometry3::inverse).collect(),
        Mount::EyeToHand => flange.to_vec(),
    };
    let (rw, tw) = mats(cam_target)?;
    let (rb, tb) = mats(&robot)?;
    let (mut r1, mut t1, mut r2, mut t2) = (Mat::default(), Mat::default(), Mat::default(), Mat::default());
    opencv::calib3d::calibrate_robot_world_hand_eye(&rw, &tw, &rb, &tb, &mut r1, &mut t1, &mut r2, &mut t2, method)
        .map_err(cv)?;
    let base2world = to_isometry(&r1, &t1)?;
    let gripper2cam = to_isometry(&r2, &t2)?;
    Ok(match mount {
        // base2world = T_target_base, gripper2cam = T_camera_flange.
        Mount::EyeInHand => (gripper2cam.inverse(), base2world.inverse()),
        // base2world = T_target_flange, gripper2cam = T_camera_base.
        Mount::EyeToHand => (base2world.inverse(), gripper2cam.inverse()),
    })
}

/// Runs every OpenCV method on the training images' PnP poses (with `camera`, the camera an
/// OpenCV user would have: the given one, or the calibration from the training images) and
/// scores each on every image with the chain figures.
pub fn opencv_baselines(data: &HandEyeData, options: &HandEyeOptions, camera: &CameraModel) -> Vec<BaselineReport> {
    use opencv::calib3d::{HandEyeCalibrationMethod as H, RobotWorldHandEyeCalibrationMethod as R};
    let views: Vec<_> = data.views.iter().filter(|v| v.corners_px.len() >= options.min_corners).cloned().collect();
    let pnp = pnp_poses(camera, &data.target_points_m, &views, options.fallback_corner_sigma_px);
    let pairs = training_pairs(data.mount, &views, &pnp);
    let flange: Vec<_> = pairs.iter().map(|p| p.t_base_flange).collect();
    let cam_target: Vec<_> = pairs.iter().map(|p| data.mount.closed_form_c(&p.c)).collect();
    let mut out = Vec::new();
    let mut push = |function: &str, method: &str, r: Result<(Isometry3<f64>, Isometry3<f64>)>| {
        let (chain, figures, error) = match r {
            Ok((x, w)) => {
                let chain = Chain { x, w, scale: 1.0 };
                let f = chain_figures(data.mount, camera, &data.target_points_m, &views, &pnp, &chain);
                (Some(chain), Some(f), None)
            }
            Err(e) => (None, None, Some(e.to_string())),
        };
        out.push(BaselineReport { function: function.into(), method: method.into(), chain, figures, error });
    };
    for (name, m) in [
        ("CALIB_HAND_EYE_TSAI", H::CALIB_HAND_EYE_TSAI),
        ("CALIB_HAND_EYE_PARK", H::CALIB_HAND_EYE_PARK),
        ("CALIB_HAND_EYE_HORAUD", H::CALIB_HAND_EYE_HORAUD),
        ("CALIB_HAND_EYE_ANDREFF", H::CALIB_HAND_EYE_ANDREFF),
        ("CALIB_HAND_EYE_DANIILIDIS", H::CALIB_HAND_EYE_DANIILIDIS),
    ] {
        push("calibrateHandEye", name, hand_eye(data.mount, &flange, &cam_target, m));
    }
    for (name, m) in [
        ("CALIB_ROBOT_WORLD_HAND_EYE_SHAH", R::CALIB_ROBOT_WORLD_HAND_EYE_SHAH),
        ("CALIB_ROBOT_WORLD_HAND_EYE_LI", R::CALIB_ROBOT_WORLD_HAND_EYE_LI),
    ] {
        push("calibrateRobotWorldHandEye", name, robot_world(data.mount, &flange, &cam_target, m));
    }
    out
}

/// The OpenCV result with the lowest held-out chain RMS (training RMS without test images).
pub fn best_baseline(reports: &[BaselineReport]) -> Option<&BaselineReport> {
    let key = |r: &BaselineReport| r.figures.as_ref().map(|f| f.heldout_rms_px.unwrap_or(f.train_rms_px));
    let k = |r: &BaselineReport| key(r).unwrap_or(f64::INFINITY);
    reports.iter().filter(|r| k(r).is_finite()).min_by(|a, b| k(a).total_cmp(&k(b)))
}
