//! Metric target poses with their uncertainty, for kinematic calibration: the pose of a planar
//! target from one calibrated camera (PnP) and from a calibrated rig of two or more cameras
//! (a bundle adjustment of the target pose alone), each with its 6 x 6 covariance.
//!
//! Entry points:
//! - [`estimate_pose`]: `T_cam_target` from one camera: a closed-form start (the plane's
//!   homography of undistorted, normalised corners, [`homography`]) refined by Gauss-Newton
//!   (Levenberg-Marquardt damped) on the reprojection error, weighted by the corner covariances;
//! - [`estimate_pose_rig`]: `T_cam0_target` from every camera of a [`CameraRig`] that sees the
//!   target, with the calibration's own uncertainty propagated when the rig carries its
//!   covariance (as [`crate::calib::StereoCalibration::rig`] does);
//! - [`PoseEstimate`]: the pose (metres, as the conventions want), the position in millimetres,
//!   the rotation vector in degrees, and the covariance in millimetres and radians;
//! - [`so3`]: rotation vectors, their exponential and logarithm and the left Jacobian.
//!
//! # Conventions
//! `T_a_b` maps coordinates in frame `b` into frame `a`. The covariance of a pose is that of
//! `[x_mm, y_mm, z_mm, dtheta_x, dtheta_y, dtheta_z]`: the target origin in the camera (cam0)
//! frame in millimetres, then a rotation error in radians applied on the left in the camera
//! frame, `R_true = exp(dtheta) R_estimated`. Pixel `(0, 0)` is the centre of the top-left
//! pixel. Corner noise is given in pixels.

pub mod homography;
pub mod so3;

#[cfg(test)]
mod tests;

use nalgebra::{
    DMatrix, Isometry3, Matrix2, Matrix2x6, Matrix2xX, Matrix6, Point2, Point3, Rotation3, Translation3,
    UnitQuaternion, Vector2, Vector3, Vector6,
};
use serde::{Deserialize, Serialize};

use crate::camera::CameraModel;
use crate::error::{Result, VisionError};

/// A pose in the form the optimisers use: `T = (exp(w) R_ref, t)` with a small left increment
/// `w` (radians) around a reference rotation; see [`so3`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct LocalPose {
    /// Reference rotation.
    pub r_ref: Rotation3<f64>,
    /// Left increment, radians.
    pub w: Vector3<f64>,
    /// Translation, metres.
    pub t: Vector3<f64>,
}

impl LocalPose {
    pub(crate) fn from_isometry(t: &Isometry3<f64>) -> Self {
        Self { r_ref: t.rotation.to_rotation_matrix(), w: Vector3::zeros(), t: t.translation.vector }
    }

    pub(crate) fn rotation(&self) -> Rotation3<f64> {
        so3::exp(&self.w) * self.r_ref
    }

    pub(crate) fn to_isometry(self) -> Isometry3<f64> {
        Isometry3::from_parts(Translation3::from(self.t), UnitQuaternion::from_rotation_matrix(&self.rotation()))
    }

    /// Folds the increment into the reference rotation.
    pub(crate) fn rebase(&mut self) {
        self.r_ref = self.rotation();
        self.w = Vector3::zeros();
    }

    /// The optimiser's block `[t, w]` (the project's 6-vector order: translation, then rotation).
    pub(crate) fn block(&self) -> [f64; 6] {
        [self.t.x, self.t.y, self.t.z, self.w.x, self.w.y, self.w.z]
    }

    /// The same reference with the block `[t, w]`.
    pub(crate) fn with_block(&self, b: &[f64]) -> Self {
        Self { r_ref: self.r_ref, t: Vector3::new(b[0], b[1], b[2]), w: Vector3::new(b[3], b[4], b[5]) }
    }
}

/// One corner seen by one camera, with the derivatives of its residual
/// `projected - observed` (pixels).
#[derive(Clone, Debug)]
pub(crate) struct Observed {
    pub residual: Vector2<f64>,
    /// With respect to the camera's model parameters (`fx fy cx cy k...`).
    pub d_model: Matrix2xX<f64>,
    /// With respect to `[t, w]` of the camera's extrinsics `T_cam_cam0` (zero for camera 0).
    pub d_ext: Matrix2x6<f64>,
    /// With respect to `[t, w]` of the target pose `T_cam0_target`.
    pub d_view: Matrix2x6<f64>,
}

/// Projects target point `x` through `T_cam_cam0 = ext` (identity when `None`) and
/// `T_cam0_target = view` into `camera`, and differentiates the residual analytically.
pub(crate) fn observe(
    camera: &CameraModel,
    ext: Option<&LocalPose>,
    view: &LocalPose,
    x: &Point3<f64>,
    pixel: &Point2<f64>,
) -> Result<Observed> {
    let r_v = view.rotation();
    let rotated_v = r_v * x.coords;
    let p0 = rotated_v + view.t;
    let (pk, r_k, d_ext_rot) = match ext {
        Some(e) => {
            let r_k = e.rotation();
            let rotated_k = r_k * p0;
            (rotated_k + e.t, *r_k.matrix(), Some(so3::d_rotated_d_increment(&e.w, &rotated_k)))
        }
        None => (p0, nalgebra::Matrix3::identity(), None),
    };
    let proj = camera.project_with_jacobians(&Point3::from(pk))?;
    let jp = proj.d_pixel_d_point;
    let mut d_ext = Matrix2x6::zeros();
    if let Some(dr) = d_ext_rot {
        d_ext.fixed_view_mut::<2, 3>(0, 0).copy_from(&jp);
        d_ext.fixed_view_mut::<2, 3>(0, 3).copy_from(&(jp * dr));
    }
    let jp0 = jp * r_k;
    let mut d_view = Matrix2x6::zeros();
    d_view.fixed_view_mut::<2, 3>(0, 0).copy_from(&jp0);
    d_view.fixed_view_mut::<2, 3>(0, 3).copy_from(&(jp0 * so3::d_rotated_d_increment(&view.w, &rotated_v)));
    Ok(Observed { residual: proj.pixel - pixel, d_model: proj.d_pixel_d_params, d_ext, d_view })
}

/// The noise of detected corners, pixels.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CornerNoise {
    /// The same isotropic standard deviation for every corner.
    Isotropic {
        /// Standard deviation per image axis, pixels.
        sigma_px: f64,
    },
    /// One 2 x 2 covariance (pixels squared) per corner, in the order of the corners.
    PerCorner(Vec<Matrix2<f64>>),
}

impl CornerNoise {
    /// The detector's per-corner covariances (px^2, e.g. [`crate::detect::Corner::covariance_px2`]
    /// of a detection, in the order of its corners) as weights: each corner keeps its own where
    /// it is usable (finite, symmetric positive definite), the others get `fallback_sigma_px`
    /// isotropic.
    pub fn from_detected(covariances_px2: &[Option<Matrix2<f64>>], fallback_sigma_px: f64) -> Self {
        let fallback = Matrix2::identity() * (fallback_sigma_px * fallback_sigma_px);
        CornerNoise::PerCorner(
            covariances_px2
                .iter()
                .map(|c| match c {
                    Some(m)
                        if m.iter().all(|v| v.is_finite())
                            && m[(0, 0)] > 0.0
                            && m.determinant() > 0.0
                            && (m[(0, 1)] - m[(1, 0)]).abs() <= 1e-12 * m[(0, 0)].max(m[(1, 1)]) =>
                    {
                        *m
                    }
                    _ => fallback,
                })
                .collect(),
        )
    }

    /// The information matrix (inverse covariance) of corner `i`.
    fn information(&self, i: usize, n: usize) -> Result<Matrix2<f64>> {
        match self {
            CornerNoise::Isotropic { sigma_px } => {
                if !(sigma_px.is_finite() && *sigma_px > 0.0) {
                    return Err(invalid(format!("corner sigma must be positive and finite, got {sigma_px} px")));
                }
                Ok(Matrix2::identity() / (sigma_px * sigma_px))
            }
            CornerNoise::PerCorner(c) => {
                if c.len() != n {
                    return Err(invalid(format!("{} corner covariances for {n} corners", c.len())));
                }
                let m = c[i];
                let ok = m.iter().all(|v| v.is_finite()) && m[(0, 0)] > 0.0 && m.determinant() > 0.0;
                match (ok, m.try_inverse()) {
                    (true, Some(inv)) => Ok(0.5 * (inv + inv.transpose())),
                    _ => Err(invalid(format!("corner {i}: covariance {m:?} is not positive definite"))),
                }
            }
        }
    }
}

fn invalid(detail: impl Into<String>) -> VisionError {
    VisionError::InvalidInput { detail: detail.into() }
}

/// A target pose with its uncertainty.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PoseEstimate {
    /// `T_cam_target` (single camera) or `T_cam0_target` (rig), metres.
    pub t_cam_target: Isometry3<f64>,
    /// The target origin in the camera (cam0) frame, millimetres.
    pub position_mm: Vector3<f64>,
    /// The target orientation as a rotation vector, degrees.
    pub rotation_vector_deg: Vector3<f64>,
    /// Covariance of `[x_mm, y_mm, z_mm, dtheta_x_rad, dtheta_y_rad, dtheta_z_rad]` (see the
    /// module conventions): corner noise plus, when the rig carried its covariance, the
    /// calibration's uncertainty.
    pub covariance: Matrix6<f64>,
    /// The part of [`PoseEstimate::covariance`] due to the corner noise alone.
    pub covariance_corners: Matrix6<f64>,
    /// Root-mean-square reprojection error over the corners (length of the 2D error), pixels.
    pub rms_px: f64,
    /// A-posteriori standard error of unit weight: about 1 when the stated corner noise is
    /// right, larger when the corners are noisier than stated.
    pub s0: f64,
    /// Corners used (over all cameras).
    pub n_corners: usize,
    /// Gauss-Newton iterations.
    pub iterations: usize,
}

impl PoseEstimate {
    fn new(
        t: Isometry3<f64>,
        cov_state: Matrix6<f64>,
        cov_corner_state: Matrix6<f64>,
        rms_px: f64,
        s0: f64,
        n_corners: usize,
        iterations: usize,
    ) -> Self {
        // state [t (m), w (rad)] -> output [t (mm), w (rad)]
        let mut m = Matrix6::zeros();
        for i in 0..3 {
            m[(i, i)] = 1e3;
            m[(3 + i, 3 + i)] = 1.0;
        }
        Self {
            t_cam_target: t,
            position_mm: t.translation.vector * 1e3,
            rotation_vector_deg: so3::log(&t.rotation.to_rotation_matrix()).map(f64::to_degrees),
            covariance: m * cov_state * m.transpose(),
            covariance_corners: m * cov_corner_state * m.transpose(),
            rms_px,
            s0,
            n_corners,
            iterations,
        }
    }

    /// Standard deviations of the position, millimetres.
    pub fn sigma_position_mm(&self) -> Vector3<f64> {
        Vector3::new(self.covariance[(0, 0)].sqrt(), self.covariance[(1, 1)].sqrt(), self.covariance[(2, 2)].sqrt())
    }

    /// Standard deviations of the rotation error about the camera axes, degrees.
    pub fn sigma_rotation_deg(&self) -> Vector3<f64> {
        Vector3::new(
            self.covariance[(3, 3)].sqrt().to_degrees(),
            self.covariance[(4, 4)].sqrt().to_degrees(),
            self.covariance[(5, 5)].sqrt().to_degrees(),
        )
    }
}

/// Calibrated cameras with their poses relative to camera 0.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraRig {
    /// The cameras.
    pub cameras: Vec<CameraModel>,
    /// `T_cam_cam0` of every camera (the first is the identity).
    pub t_cam_cam0: Vec<Isometry3<f64>>,
    /// Covariance of the rig's parameters, when known: every camera's model parameters
    /// (`fx fy cx cy k...` in the order of [`CameraModel::parameters`]), camera after camera,
    /// then `[t (m), dtheta (rad)]` of `T_cam_cam0` for cameras 1.. (translation, then the
    /// rotation error on the left, in the camera's frame: the project's 6-vector order). Propagated into [`PoseEstimate::covariance`].
    pub covariance: Option<DMatrix<f64>>,
}

impl CameraRig {
    /// Length of the parameter vector that [`CameraRig::covariance`] describes.
    pub fn n_parameters(&self) -> usize {
        self.cameras.iter().map(CameraModel::n_parameters).sum::<usize>() + 6 * self.cameras.len().saturating_sub(1)
    }

    /// Checks the shapes.
    pub fn validate(&self) -> Result<()> {
        if self.cameras.is_empty() || self.cameras.len() != self.t_cam_cam0.len() {
            return Err(invalid(format!(
                "a rig needs at least one camera and one T_cam_cam0 per camera ({} cameras, {} poses)",
                self.cameras.len(),
                self.t_cam_cam0.len()
            )));
        }
        for c in &self.cameras {
            c.validate()?;
        }
        if let Some(cov) = &self.covariance {
            let n = self.n_parameters();
            if cov.nrows() != n || cov.ncols() != n || cov.iter().any(|v| !v.is_finite()) {
                return Err(invalid(format!(
                    "rig covariance is {}x{} (or not finite), expected {n}x{n}",
                    cov.nrows(),
                    cov.ncols()
                )));
            }
        }
        Ok(())
    }
}

/// The corners one camera of a rig saw of the target.
#[derive(Clone, Debug, PartialEq)]
pub struct RigObservation {
    /// Index of the camera in the rig.
    pub camera: usize,
    /// Index of each corner in the target's point list.
    pub point_ids: Vec<usize>,
    /// The corners, pixels.
    pub corners_px: Vec<Point2<f64>>,
    /// Their noise.
    pub noise: CornerNoise,
}

/// Gauss-Newton stops when the step is below this (radians, metres).
const POSE_STEP_STOP: f64 = 1e-12;
/// Maximum Gauss-Newton iterations.
const POSE_MAX_ITERATIONS: usize = 100;

/// The target's pose in one camera from its corners: closed-form start, then Gauss-Newton on
/// the weighted reprojection error, with the covariance `(J^T W J)^-1` of the corner noise
/// (`W` the corners' information matrices).
///
/// `target_points_m` are the target's points in its own frame (metres, on a plane);
/// `point_ids[i]` says which point `corners_px[i]` is. At least four corners.
pub fn estimate_pose(
    camera: &CameraModel,
    target_points_m: &[Point3<f64>],
    point_ids: &[usize],
    corners_px: &[Point2<f64>],
    noise: &CornerNoise,
) -> Result<PoseEstimate> {
    let rig = CameraRig { cameras: vec![*camera], t_cam_cam0: vec![Isometry3::identity()], covariance: None };
    let obs = RigObservation {
        camera: 0,
        point_ids: point_ids.to_vec(),
        corners_px: corners_px.to_vec(),
        noise: noise.clone(),
    };
    estimate_pose_rig(&rig, target_points_m, std::slice::from_ref(&obs))
}

/// The target's pose `T_cam0_target` from every camera of a calibrated rig that sees it: a
/// bundle adjustment of the six pose parameters over all cameras' corners (each camera's
/// projection is exact, no triangulation step), started from the PnP solution of the camera
/// that sees the most corners. The covariance is that of the corner noise, plus, when
/// `rig.covariance` is given, the calibration's uncertainty propagated to first order
/// (`dx/dc Sigma_c dx/dc^T` with `dx/dc = -(J^T W J)^-1 J^T W J_c`).
pub fn estimate_pose_rig(
    rig: &CameraRig,
    target_points_m: &[Point3<f64>],
    observations: &[RigObservation],
) -> Result<PoseEstimate> {
    rig.validate()?;
    let mut total = 0;
    for o in observations {
        if o.camera >= rig.cameras.len() {
            return Err(invalid(format!("observation of camera {} in a rig of {}", o.camera, rig.cameras.len())));
        }
        if o.point_ids.len() != o.corners_px.len() {
            return Err(invalid(format!(
                "camera {}: {} point ids for {} corners",
                o.camera,
                o.point_ids.len(),
                o.corners_px.len()
            )));
        }
        if let Some(&bad) = o.point_ids.iter().find(|&&i| i >= target_points_m.len()) {
            return Err(invalid(format!("point id {bad} but the target has {} points", target_points_m.len())));
        }
        if o.corners_px.iter().any(|p| !(p.x.is_finite() && p.y.is_finite())) {
            return Err(invalid(format!("camera {}: non-finite corner", o.camera)));
        }
        total += o.corners_px.len();
    }
    if total < 4 {
        return Err(invalid(format!("{total} corners in all; a pose needs at least 4")));
    }
    // Start: PnP of the camera with the most corners, moved into cam0.
    let best = observations.iter().max_by_key(|o| o.corners_px.len()).ok_or_else(|| invalid("no observations"))?;
    let cam = &rig.cameras[best.camera];
    let pts: Vec<Point3<f64>> = best.point_ids.iter().map(|&i| target_points_m[i]).collect();
    let t_cam_target = pnp_start(cam, &pts, &best.corners_px)?;
    let start = rig.t_cam_cam0[best.camera].inverse() * t_cam_target;

    let exts: Vec<Option<LocalPose>> =
        rig.t_cam_cam0.iter().enumerate().map(|(k, t)| (k > 0).then(|| LocalPose::from_isometry(t))).collect();
    let info: Vec<Vec<Matrix2<f64>>> = observations
        .iter()
        .map(|o| (0..o.corners_px.len()).map(|i| o.noise.information(i, o.corners_px.len())).collect::<Result<_>>())
        .collect::<Result<_>>()?;

    let mut pose = LocalPose::from_isometry(&start);
    // Normal equations and cost at the current pose.
    let eval = |pose: &LocalPose| -> Result<(Matrix6<f64>, Vector6<f64>, f64)> {
        let mut n = Matrix6::zeros();
        let mut g = Vector6::zeros();
        let mut cost = 0.0;
        for (o, w) in observations.iter().zip(&info) {
            let camera = &rig.cameras[o.camera];
            for ((pid, px), wi) in o.point_ids.iter().zip(&o.corners_px).zip(w) {
                let ob = observe(camera, exts[o.camera].as_ref(), pose, &target_points_m[*pid], px)?;
                let jw = ob.d_view.transpose() * wi;
                n += jw * ob.d_view;
                g += jw * ob.residual;
                cost += (ob.residual.transpose() * wi * ob.residual)[(0, 0)];
            }
        }
        Ok((n, g, cost))
    };
    let (mut n, mut g, mut cost) = eval(&pose)?;
    let mut lambda = 1e-6;
    let mut iterations = 0;
    while iterations < POSE_MAX_ITERATIONS {
        iterations += 1;
        let mut a = n;
        for i in 0..6 {
            a[(i, i)] += lambda * n[(i, i)].max(1e-12);
        }
        let Some(step) = a.cholesky().map(|c| c.solve(&(-g))) else {
            lambda *= 10.0;
            continue;
        };
        let cand = LocalPose {
            r_ref: so3::exp(&Vector3::new(step[3], step[4], step[5])) * pose.rotation(),
            w: Vector3::zeros(),
            t: pose.t + Vector3::new(step[0], step[1], step[2]),
        };
        match eval(&cand) {
            Ok((n2, g2, c2)) if c2 <= cost => {
                let small = step.norm() < POSE_STEP_STOP * (1.0 + pose.t.norm());
                let flat = cost - c2 <= 1e-15 * cost.max(1e-300);
                pose = cand;
                n = n2;
                g = g2;
                cost = c2;
                lambda = (lambda * 0.1).max(1e-12);
                if small || flat {
                    break;
                }
            }
            _ => {
                lambda *= 10.0;
                if lambda > 1e12 {
                    break;
                }
            }
        }
    }
    let cov_corners = n.try_inverse().ok_or_else(|| VisionError::DegenerateViews {
        detail: "the corners do not determine the target pose (singular normal matrix)".into(),
    })?;
    let cov_corners = 0.5 * (cov_corners + cov_corners.transpose());
    let dof = (2 * total).saturating_sub(6).max(1) as f64;
    let s0 = (cost / dof).sqrt();
    let mut sq = 0.0;
    let mut cov = cov_corners;
    if let Some(cov_c) = &rig.covariance {
        // Residual derivatives with respect to the rig parameters.
        let offsets: Vec<usize> = rig
            .cameras
            .iter()
            .scan(0, |acc, c| {
                let o = *acc;
                *acc += c.n_parameters();
                Some(o)
            })
            .collect();
        let n_model: usize = rig.cameras.iter().map(CameraModel::n_parameters).sum();
        let nc = rig.n_parameters();
        let mut b = DMatrix::<f64>::zeros(6, nc);
        for (o, w) in observations.iter().zip(&info) {
            let camera = &rig.cameras[o.camera];
            for ((pid, px), wi) in o.point_ids.iter().zip(&o.corners_px).zip(w) {
                let ob = observe(camera, exts[o.camera].as_ref(), &pose, &target_points_m[*pid], px)?;
                let jw = ob.d_view.transpose() * wi;
                let bm = jw * &ob.d_model;
                let off = offsets[o.camera];
                let mut view = b.view_mut((0, off), (6, bm.ncols()));
                view += &bm;
                if o.camera > 0 {
                    let off = n_model + 6 * (o.camera - 1);
                    let be = jw * ob.d_ext;
                    let mut view = b.view_mut((0, off), (6, 6));
                    view += be;
                }
            }
        }
        let dx_dc = -(DMatrix::from_column_slice(6, 6, cov_corners.as_slice()) * &b);
        let add = &dx_dc * cov_c * dx_dc.transpose();
        cov += Matrix6::from_column_slice(add.as_slice());
        cov = 0.5 * (cov + cov.transpose());
    }
    for (o, _) in observations.iter().zip(&info) {
        let camera = &rig.cameras[o.camera];
        for (pid, px) in o.point_ids.iter().zip(&o.corners_px) {
            let ob = observe(camera, exts[o.camera].as_ref(), &pose, &target_points_m[*pid], px)?;
            sq += ob.residual.norm_squared();
        }
    }
    let rms_px = (sq / total as f64).sqrt();
    Ok(PoseEstimate::new(pose.to_isometry(), cov, cov_corners, rms_px, s0, total, iterations))
}

/// Closed-form pose of a planar point set from one camera: the points' plane, the corners
/// undistorted to normalised coordinates, the plane-to-image homography and its decomposition.
fn pnp_start(camera: &CameraModel, points_m: &[Point3<f64>], corners_px: &[Point2<f64>]) -> Result<Isometry3<f64>> {
    let t_target_plane = plane_frame(points_m)?;
    let t_plane_target = t_target_plane.inverse();
    let mut src = Vec::new();
    let mut dst = Vec::new();
    for (p, c) in points_m.iter().zip(corners_px) {
        if let Ok(n) = camera.unproject_normalized(c) {
            let q = t_plane_target * p;
            src.push(Point2::new(q.x, q.y));
            dst.push(n);
        }
    }
    let h = homography::homography_dlt(&src, &dst).ok_or_else(|| VisionError::DegenerateViews {
        detail: format!(
            "no homography from {} usable corners (fewer than 4, or collinear): cannot start the pose",
            src.len()
        ),
    })?;
    let t_cam_plane = homography::pose_from_homography(&h)
        .ok_or_else(|| VisionError::DegenerateViews { detail: "degenerate homography".into() })?;
    Ok(t_cam_plane * t_plane_target)
}

/// A frame whose `z = 0` plane holds the points (`T_target_plane`); an error when they are not
/// on a plane (relative out-of-plane spread above 1e-6) or span no plane.
pub(crate) fn plane_frame(points_m: &[Point3<f64>]) -> Result<Isometry3<f64>> {
    let n = points_m.len();
    if n < 3 {
        return Err(invalid(format!("{n} points do not span a plane")));
    }
    let c = points_m.iter().fold(Vector3::zeros(), |a, p| a + p.coords) / n as f64;
    let mut m = nalgebra::Matrix3::zeros();
    for p in points_m {
        let d = p.coords - c;
        m += d * d.transpose();
    }
    if points_m.iter().all(|p| p.z == 0.0) {
        return Ok(Isometry3::identity());
    }
    let eig = m.symmetric_eigen();
    let mut order = [0usize, 1, 2];
    order.sort_by(|&i, &j| eig.eigenvalues[j].total_cmp(&eig.eigenvalues[i]));
    let (l0, l1, l2) = (eig.eigenvalues[order[0]], eig.eigenvalues[order[1]], eig.eigenvalues[order[2]]);
    if l1.is_nan() || l1 <= 1e-12 * l0 {
        return Err(invalid("the target points are collinear"));
    }
    if l2.max(0.0).sqrt() > 1e-6 * l0.sqrt() {
        return Err(invalid(format!(
            "the target points are not planar (out-of-plane spread {:.3e} m); the closed-form start needs a planar target",
            l2.max(0.0).sqrt() / (n as f64).sqrt()
        )));
    }
    let ex = eig.eigenvectors.column(order[0]).into_owned();
    let ez = eig.eigenvectors.column(order[2]).into_owned();
    let ey = ez.cross(&ex);
    let r = Rotation3::from_matrix_unchecked(nalgebra::Matrix3::from_columns(&[ex, ey, ez]));
    Ok(Isometry3::from_parts(Translation3::from(c), UnitQuaternion::from_rotation_matrix(&r)))
}
