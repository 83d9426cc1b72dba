//! Hand-eye calibration: a camera on the robot's flange and a fixed target (eye-in-hand), or a
//! fixed camera and a target on the flange (eye-to-hand), from detected target corners and the
//! robot's flange poses.
//!
//! Method ([`calibrate_hand_eye`]):
//! 1. the camera: given (intrinsics fixed), or calibrated from the training images alone
//!    (`ferrocal_vision::calib::calibrate_camera`) and then refined jointly in step 4;
//! 2. every image's target pose by PnP with the detector's corner covariances
//!    (`ferrocal_vision::pose::estimate_pose`);
//! 3. closed-form starts from the training images ([`closed`]: Tsai-Lenz and Park-Martin for
//!    `AX = XB`, Shah for `AX = ZB`); the start with the lowest chain RMS over the training
//!    corners wins;
//! 4. the refinement in pixels through `ferrocal-lsq`: every training corner predicted through
//!    its image's robot pose, the two unknown transforms and the camera model ([`residual`]),
//!    whitened by its covariance, first with plain least squares, then with a Huber loss at
//!    [`HandEyeOptions::huber_sigmas`] robust standard deviations; optionally the target's print
//!    scale; the reported robot poses are measurements with their own noise
//!    ([`HandEyeOptions::robot_sigma_m`]) unless taken as exact; the noise levels (a factor on
//!    the detector's corner covariances, the robot's position and orientation sigmas) are
//!    estimated from the data by variance components unless given
//!    ([`HandEyeOptions::estimate_noise`]);
//! 5. the covariance of both transforms (and of the camera and the scale when free) with the
//!    robot-pose blocks marginalised, scaled by the a-posteriori variance factor `s0^2`;
//! 6. the figures ([`evaluate`]): per-image chain RMS with the robot poses as reported, the
//!    training and held-out RMS (`test` images are used for nothing else), and the camera-to-
//!    target pose of the chain against each image's PnP pose.
//!
//! [`opencv`] runs OpenCV's `calibrateHandEye` and `calibrateRobotWorldHandEye` on the same
//! PnP poses for the side-by-side comparison; their chain figures come from the same code.
//!
//! # Conventions
//! `T_a_b` maps frame-`b` coordinates into frame `a`. `X` (the hand-eye transform) is
//! `T_flange_camera` (eye-in-hand) or `T_flange_target` (eye-to-hand); `W` (the world transform)
//! is `T_base_target` or `T_base_camera`. Covariances of a transform are over its `Se3` tangent
//! `[t (m), r (rad)]`, the rotation error applied on the left (`R_true = Exp(r) R_estimated`),
//! in frame `a` of `T_a_b`.

pub mod agreement;
pub mod closed;
pub mod evaluate;
pub mod geometry;
pub mod joint;
pub mod opencv;
pub mod physics;
mod refine;
pub mod residual;

use nalgebra::{Isometry3, Matrix2, Matrix6, Point2, Point3, Vector3};
use serde::{Deserialize, Serialize};

use ferrocal_lsq::{Loss, SolverOptions};
use ferrocal_vision::calib::{CalibrationOptions, CameraCalibration};
use ferrocal_vision::camera::{CameraModel, ImageSize};

pub use closed::{ClosedForm, PosePair};
pub use evaluate::{chain_figures, chain_residuals_px, Chain, ChainFigures, ViewFigures};
pub use geometry::{MotionGeometry, MIN_ROTATION_DEG};
pub use joint::rig::{
    calibrate_joint_rig, calibrate_joint_rig_from, calibrate_joint_rig_with, rig_transform_from_starts, RigCamera,
    RigJointCalibration,
};
pub use joint::{calibrate_joint, calibrate_joint_from, JointCalibration, JointOptions};
pub use refine::{
    calibrate_hand_eye, calibrate_hand_eye_from, check_camera_size, start_poses, StartPoses, MAX_NOISE_ITERATIONS,
    MIN_TRAIN_VIEWS, NOISE_TOLERANCE,
};

use crate::measurement::Split;

/// Where the camera is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Mount {
    /// The camera on the flange, the target fixed in the cell.
    #[serde(rename = "eye-in-hand")]
    EyeInHand,
    /// The camera fixed in the cell, the target on the flange.
    #[serde(rename = "eye-to-hand")]
    EyeToHand,
}

impl Mount {
    /// `eye-in-hand` or `eye-to-hand`.
    pub fn name(self) -> &'static str {
        match self {
            Mount::EyeInHand => "eye-in-hand",
            Mount::EyeToHand => "eye-to-hand",
        }
    }

    /// What `X` is, e.g. `T_flange_camera`.
    pub fn hand_eye_name(self) -> &'static str {
        match self {
            Mount::EyeInHand => "T_flange_camera",
            Mount::EyeToHand => "T_flange_target",
        }
    }

    /// What `W` is, e.g. `T_base_target`.
    pub fn world_name(self) -> &'static str {
        match self {
            Mount::EyeInHand => "T_base_target",
            Mount::EyeToHand => "T_base_camera",
        }
    }

    /// `T_camera_target` of one image from the chain.
    pub fn t_camera_target(
        self,
        x: &Isometry3<f64>,
        w: &Isometry3<f64>,
        t_base_flange: &Isometry3<f64>,
    ) -> Isometry3<f64> {
        match self {
            Mount::EyeInHand => x.inverse() * t_base_flange.inverse() * w,
            Mount::EyeToHand => w.inverse() * t_base_flange * x,
        }
    }

    /// `C_i` of the closed forms ([`closed`]) from an image's `T_camera_target`.
    pub fn closed_form_c(self, t_camera_target: &Isometry3<f64>) -> Isometry3<f64> {
        match self {
            Mount::EyeInHand => *t_camera_target,
            Mount::EyeToHand => t_camera_target.inverse(),
        }
    }
}

impl std::str::FromStr for Mount {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.trim().to_ascii_lowercase().replace('_', "-").as_str() {
            "eye-in-hand" => Ok(Mount::EyeInHand),
            "eye-to-hand" => Ok(Mount::EyeToHand),
            _ => Err(format!("mount '{s}': expected eye-in-hand or eye-to-hand")),
        }
    }
}

/// One image: the robot's pose when it was taken and the target corners detected in it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HandEyeView {
    /// The image's name (file name).
    pub name: String,
    /// Whether the image takes part in the fit (`Train`) or only in the held-out figures.
    pub split: Split,
    /// `T_base_flange` as the robot reported it.
    pub t_base_flange: Isometry3<f64>,
    /// The image size.
    pub image_size: ImageSize,
    /// Which target point each corner is (an index into [`HandEyeData::target_points_m`]).
    pub point_ids: Vec<usize>,
    /// The detected corners, pixels (pixel-centre convention).
    pub corners_px: Vec<Point2<f64>>,
    /// The detector's covariance of each corner, px^2 (`None`: the options' fallback sigma).
    pub covariances_px2: Vec<Option<Matrix2<f64>>>,
}

/// A hand-eye recording.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HandEyeData {
    /// The mount.
    pub mount: Mount,
    /// The target's points in its own frame, metres (nominal spacing).
    pub target_points_m: Vec<Point3<f64>>,
    /// The images.
    pub views: Vec<HandEyeView>,
}

/// How the camera's intrinsics are obtained.
#[derive(Clone, Debug, PartialEq)]
pub enum IntrinsicsMode {
    /// Given and held fixed.
    Fixed(CameraModel),
    /// Calibrated from the training images with these options, then refined jointly.
    Calibrate(CalibrationOptions),
}

/// Options of [`calibrate_hand_eye`].
#[derive(Clone, Debug, PartialEq)]
pub struct HandEyeOptions {
    /// Intrinsics fixed or free.
    pub intrinsics: IntrinsicsMode,
    /// Fit an overall scale of the printed target (its spacing against the nominal one);
    /// visible only against metric robot poses. Off by default.
    pub fit_target_scale: bool,
    /// Standard deviation of each coordinate of the reported flange positions, metres (the
    /// starting value when [`HandEyeOptions::estimate_noise`] is on). With
    /// [`HandEyeOptions::robot_sigma_rad`] positive, every image's robot pose becomes a
    /// parameter with the reported pose as its measurement; both zero (the default): poses
    /// taken as exact. On the real recordings of industrial_calibration the exact poses predict
    /// held-out images better (the robots' errors there are systematic, not per-pose noise, and
    /// with the print scale free the estimated robot noise grows until the poses absorb the
    /// scale); measurements suit controllers whose reported poses scatter from pose to pose.
    pub robot_sigma_m: f64,
    /// Standard deviation of each rotation-vector coordinate of the reported flange
    /// orientations, radians.
    pub robot_sigma_rad: f64,
    /// Estimate the noise levels from the data by variance components (Förstner): the corner
    /// covariances' common factor and, when the robot poses are measurements, the robot's
    /// position and orientation sigmas, each from its group's residuals and redundancy.
    pub estimate_noise: bool,
    /// Standard deviation (px, isotropic) of corners that come without a covariance.
    pub fallback_corner_sigma_px: f64,
    /// The Huber threshold of the second solve, in robust standard deviations of the first
    /// solve's whitened residuals (`0`: plain least squares only).
    pub huber_sigmas: f64,
    /// Fewest corners an image needs to take part.
    pub min_corners: usize,
    /// The solver (default: the Ceres back end).
    pub solver: SolverOptions,
    /// The target's bending and anisotropic print scale as blocks of the refinement (both off
    /// by default; [`physics::select_chain_physics`] decides them on the training images).
    pub target_physics: TargetPhysics,
}

/// Which of the target's departures from its nominal geometry the refinement fits, beyond the
/// overall print scale ([`HandEyeOptions::fit_target_scale`]); see
/// `ferrocal_vision::calib::TargetDeformation` for the model.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct TargetPhysics {
    /// The target bends: sags of a bowl, a saddle and a twist at its edge (metres).
    pub shape: bool,
    /// Its printed x spacing differs from its y spacing by the factor `1 + e_x`.
    pub print_x: bool,
}

impl TargetPhysics {
    /// Whether anything beyond the flat, nominally printed target is fitted.
    pub fn any(self) -> bool {
        self.shape || self.print_x
    }
}

/// The target's fitted bending and anisotropic print scale (present when either was fitted).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct TargetForm {
    /// The model and its values (`shape_m` = `[b, s, t]`, `scale[0]` = `e_x`; the free flags
    /// say which were fitted).
    pub deformation: ferrocal_vision::calib::TargetDeformation,
    /// Standard deviations of `[b, s, t]`, metres, when fitted.
    pub shape_std_m: Option<[f64; 3]>,
    /// Standard deviation of `e_x`, when fitted.
    pub scale_x_std: Option<f64>,
}

impl TargetForm {
    /// The target's points as the chain sees them (deformed, before the overall scale).
    pub fn points(&self, nominal_m: &[Point3<f64>]) -> Vec<Point3<f64>> {
        nominal_m.iter().map(|p| self.deformation.point(p)).collect()
    }
}

impl Default for HandEyeOptions {
    fn default() -> Self {
        Self {
            intrinsics: IntrinsicsMode::Calibrate(CalibrationOptions::default()),
            fit_target_scale: false,
            robot_sigma_m: 0.0,
            robot_sigma_rad: 0.0,
            estimate_noise: true,
            fallback_corner_sigma_px: 0.1,
            huber_sigmas: 3.0,
            min_corners: 6,
            solver: SolverOptions { backend: ferrocal_lsq::Backend::Ceres, ..SolverOptions::default() },
            target_physics: TargetPhysics::default(),
        }
    }
}

impl HandEyeOptions {
    /// Starting noise of reported robot poses taken as measurements: position (m) and
    /// orientation (rad) per coordinate, refined by variance components.
    pub const MEASURED_POSE_SIGMAS: (f64, f64) = (1e-4, 1e-4);

    /// The default options with the robot poses as measurements (noise estimated from the data).
    pub fn robot_poses_as_measurements() -> Self {
        let (m, rad) = Self::MEASURED_POSE_SIGMAS;
        Self { robot_sigma_m: m, robot_sigma_rad: rad, ..Self::default() }
    }

    /// Checks the values.
    pub fn validate(&self) -> crate::Result<()> {
        let bad = |m: String| Err(crate::CalibError::Data(format!("hand-eye options: {m}")));
        for (name, v) in [("robot_sigma_m", self.robot_sigma_m), ("robot_sigma_rad", self.robot_sigma_rad)] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(format!("{name} must be finite and >= 0, got {v}"));
            }
        }
        if (self.robot_sigma_m > 0.0) != (self.robot_sigma_rad > 0.0) {
            return bad("give both robot sigmas (position and rotation) or neither".into());
        }
        if !(self.fallback_corner_sigma_px.is_finite() && self.fallback_corner_sigma_px > 0.0) {
            return bad(format!("fallback_corner_sigma_px must be > 0, got {}", self.fallback_corner_sigma_px));
        }
        if !(self.huber_sigmas.is_finite() && self.huber_sigmas >= 0.0) {
            return bad(format!("huber_sigmas must be >= 0, got {}", self.huber_sigmas));
        }
        if self.min_corners < 4 {
            return bad(format!("min_corners must be at least 4, got {}", self.min_corners));
        }
        self.solver.validate().map_err(crate::CalibError::from)
    }

    pub(crate) fn second_loss(&self, robust_sigma: f64) -> Option<Loss> {
        (self.huber_sigmas > 0.0).then(|| Loss::Huber { delta: (self.huber_sigmas * robust_sigma).max(1e-6) })
    }
}

/// A rigid transform with its covariance.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct TransformEstimate {
    /// The transform.
    pub transform: Isometry3<f64>,
    /// Covariance over `[t (m), r (rad)]` (see the module conventions).
    pub covariance: Matrix6<f64>,
}

impl TransformEstimate {
    /// Standard deviations of the translation, millimetres.
    pub fn translation_std_mm(&self) -> Vector3<f64> {
        Vector3::from_fn(|i, _| self.covariance[(i, i)].max(0.0).sqrt() * 1e3)
    }

    /// Standard deviations of the rotation error about the frame's axes, degrees.
    pub fn rotation_std_deg(&self) -> Vector3<f64> {
        Vector3::from_fn(|i, _| self.covariance[(3 + i, 3 + i)].max(0.0).sqrt().to_degrees())
    }
}

/// One closed-form start and how well its chain fits the training corners.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StartReport {
    /// The method.
    pub method: ClosedForm,
    /// Chain RMS over the training corners, pixels (`None` when the method failed).
    pub train_rms_px: Option<f64>,
    /// Why it failed, when it did.
    pub error: Option<String>,
    /// Whether the refinement started from it.
    pub chosen: bool,
}

/// An image left out of the calibration, and why.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SkippedView {
    /// The image's name.
    pub name: String,
    /// Why.
    pub reason: String,
}

/// The noise levels of a solve.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct NoiseLevels {
    /// Factor on every corner covariance of the detector (1: as detected).
    pub corner_variance_factor: f64,
    /// Robot position sigma per coordinate, metres (0: poses exact).
    pub robot_sigma_m: f64,
    /// Robot orientation sigma per axis, radians (0: poses exact).
    pub robot_sigma_rad: f64,
    /// Whether they were estimated by variance components.
    pub estimated: bool,
    /// Variance-component iterations.
    pub iterations: usize,
}

/// The result of [`calibrate_hand_eye`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HandEyeResult {
    /// The mount.
    pub mount: Mount,
    /// The camera (refined when the intrinsics were free).
    pub camera: CameraModel,
    /// Standard deviation of every camera parameter (the order of
    /// [`CameraModel::parameters`]) when the intrinsics were free.
    pub camera_std: Option<Vec<f64>>,
    /// The calibration from the training images alone that the refinement started from, when
    /// the intrinsics were free.
    pub initial_camera: Option<CameraCalibration>,
    /// `X` with its covariance.
    pub hand_eye: TransformEstimate,
    /// `W` with its covariance.
    pub world: TransformEstimate,
    /// The target's print scale and its standard deviation, when fitted.
    pub target_scale: Option<(f64, f64)>,
    /// The target's bending and anisotropic print scale, when fitted
    /// ([`HandEyeOptions::target_physics`]).
    #[serde(default)]
    pub target_form: Option<TargetForm>,
    /// Chain figures per image and overall (robot poses as reported).
    pub figures: ChainFigures,
    /// Every closed-form start.
    pub starts: Vec<StartReport>,
    /// Images left out (too few corners, no PnP pose), with the reason.
    pub skipped: Vec<SkippedView>,
    /// The noise levels the final solve used (estimated or as given).
    pub noise: NoiseLevels,
    /// A-posteriori standard deviation of unit weight of the final solve.
    pub s0: f64,
    /// Solver iterations over both solves.
    pub iterations: usize,
    /// Why the final solve stopped.
    pub termination: String,
    /// Residual blocks (corners) the final solve's loss down-weighted.
    pub n_downweighted: usize,
    /// How much the flange rotated over the training images.
    pub motion: MotionGeometry,
    /// What the recording leaves undetermined, in words (empty when nothing).
    pub warnings: Vec<String>,
}
